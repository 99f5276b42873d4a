"""A design with declared effects: `acl sweep` gives the force, snap-in, deflection, latch and `require`
columns (issue 23: they were left out), and each equals an independent loop of `acl.analyze` on the same
point (the design loaded with the point's parameter as an override, not the sweep's materialised one), to
1e-6 relative."""
from __future__ import annotations

import math
import os

import numpy as np

import acl
from acl.design.resolve import load_design
from example_designs import first_principles_path

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data")
RTOL = 1e-6


def _close(a, b) -> bool:
    if b is None or (isinstance(b, float) and math.isnan(b)):
        return bool(np.isnan(a))
    if isinstance(b, bool):
        return bool(a) == b
    return abs(float(a) - float(b)) <= RTOL * max(abs(float(b)), 1e-300)


def _loop(path, name, values, at):
    """acl.analyze of the design at each value of parameter ``name`` (SI metres)."""
    return [acl.analyze(load_design(path, overrides={name: f"{v * 1e6!r} um"}), at=at) for v in values]


def test_a_pair_with_effects_has_its_forces_snap_in_and_deflections():
    path = os.path.join(DATA, "sweep_effects_pair.acl")
    at = "125 kHz @ 2 V"
    t = acl.sweep(path, vary={"gap": "36um,44um"}, at=at)
    assert not any("declares effects" in n for n in t.notes), t.notes
    for row, a in zip(t.data, _loop(path, "gap", [36e-6, 44e-6], at)):
        pf = a.pairs[0]
        assert _close(row["force_left_right_125khz_n"], pf["force_n"])
        assert _close(row["snap_in_left_right_125khz_v"], pf["snap_in_voltage_v"])
        assert _close(row["critical_distance_left_right_125khz_m"], pf["critical_distance_eq3_m"])
        assert a.equilibrium["status"] == "ok" and row["equilibrium_ok"]
        for beam, v in a.equilibrium["deflections_m"].items():
            assert _close(row[f"tip_deflection_{beam}_m"], v)
    # the effects act: 1.3 x Bjerknes and a softer beam snap in lower than the example without its calibration
    plain = acl.analyze(load_design(str(first_principles_path("fig4_facing_pair")), overrides={"gap": "36 um"}))
    assert t.data["snap_in_left_right_125khz_v"][0] < plain.pairs[0]["snap_in_voltage_v"]


def test_a_calibrated_cantilever_has_its_deflection():
    path = os.path.join(DATA, "fit_cantilever.calibrated.acl")
    at = "125 kHz @ 2 V"
    t = acl.sweep(path, vary={"length": "48um,52um"}, at=at)
    defl = [c for c in t.columns if c.startswith("tip_deflection_")]
    assert defl
    for row, a in zip(t.data, _loop(path, "length", [48e-6, 52e-6], at)):
        for beam, v in a.equilibrium["deflections_m"].items():
            assert _close(row[f"tip_deflection_{beam}_m"], v)


def test_a_latch_with_effects_has_its_forces_margins_and_requires():
    path = os.path.join(DATA, "sweep_effects_latch.acl")
    t = acl.sweep(path, vary={"z": "34um,36um"})
    assert "switching_force_l_n" in t.columns and "margin_l_toggle_1" in t.columns
    for row, a in zip(t.data, _loop(path, "z", [34e-6, 36e-6], None)):
        lt = a.latches[0]
        assert _close(row["switching_force_l_n"], lt["switching_force_n"])
        assert _close(row["release_force_l_n"], lt["release_force_n"])
        assert bool(row["bistable_l"]) == bool(lt["bistable"])
        for m in lt["margins"]:
            assert _close(row[f"margin_l_{m['program']}_{m['step']}"], m["margin"])
        for i, r in enumerate(a.requires, 1):
            assert bool(row[f"require_{i}_pass"]) == bool(r["ok"])


def test_a_spring_with_effects_has_its_gap_require_and_extension():
    path = os.path.join(DATA, "sweep_effects_spring.acl")
    at = "125 kHz @ 10 V"
    t = acl.sweep(path, vary={"gap": "39um,41um"}, at=at)
    gaps = [i for i, r in enumerate(load_design(path).requires, 1) if r.kind == "gap"]
    assert gaps
    for row, a in zip(t.data, _loop(path, "gap", [39e-6, 41e-6], at)):
        for i in gaps:
            assert _close(row[f"require_{i}_value"], a.requires[i - 1]["value"])
        assert _close(row["snap_in_top_bottom_125khz_v"], a.pairs[0]["snap_in_voltage_v"])
        if a.equilibrium["status"] == "ok":
            for name, v in a.equilibrium["deflections_m"].items():
                col = next(c for c in t.columns if c.endswith(f"deflection_{name}_m"))
                assert _close(row[col], v)


def test_left_out_names_only_what_is_still_left_out():
    from acl.sweep.driver import left_out

    notes = " ".join(left_out(load_design(os.path.join(DATA, "sweep_effects_pair.acl")), "125 kHz @ 2 V"))
    assert "snap_in" not in notes and "tip_deflection" not in notes and "force" not in notes.split("lint")[0]
    assert "lint_acl201" in notes                       # still left out, with its reason

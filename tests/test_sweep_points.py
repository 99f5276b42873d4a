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

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "samples")
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
    assert notes == ""                                  # every effect batched: nothing left out at a drive


def _no_point_loop(monkeypatch):
    """Fail if any column is computed point by point (acl.sweep.points): the declared effects must be batched."""
    import acl.sweep.points as SP

    def boom(*_a, **_k):
        raise AssertionError("a column was computed point by point")

    monkeypatch.setattr(SP, "evaluate_points", boom)


def test_the_calibrated_fig4_pair_is_batched_and_equals_analyze(monkeypatch):
    """The shipped Fig. 4 pair declares the calibration `bjerknes_scale { factor, gap_exponent, gap_ref }`: every
    force, snap-in and deflection column comes from the batched engine (no point-by-point analysis) and equals a
    loop of `acl.analyze` to 1e-6."""
    path = os.path.join(os.path.dirname(DATA), "examples", "fig4_facing_pair.acl")
    at = "125 kHz @ 2 V"
    _no_point_loop(monkeypatch)
    t = acl.sweep(path, vary={"gap": "30um,40um,52um"}, at=at)
    assert not any("point by point" in n for n in t.notes), t.notes
    loop = _loop(path, "gap", [30e-6, 40e-6, 52e-6], at)
    for row, a in zip(t.data, loop):
        pf = a.pairs[0]
        assert _close(row["force_left_right_125khz_n"], pf["force_n"])
        assert _close(row["snap_in_left_right_125khz_v"], pf["snap_in_voltage_v"])
        assert _close(row["critical_distance_left_right_125khz_m"], pf["critical_distance_eq3_m"])
        ok = a.equilibrium["status"] == "ok"          # 30 and 40 um snap in below 2 V: NaN deflections then
        assert bool(row["equilibrium_ok"]) == ok
        for beam, v in a.equilibrium["deflections_m"].items():
            assert _close(row[f"tip_deflection_{beam}_m"], v if ok else float("nan"))
    assert [bool(r["equilibrium_ok"]) for r in t.data] == [False, False, True]
    # the calibration acts: the first-principles pair snaps in higher
    plain = acl.analyze(load_design(str(first_principles_path("fig4_facing_pair")), overrides={"gap": "40 um"}))
    assert t.data["snap_in_left_right_125khz_v"][1] < plain.pairs[0]["snap_in_voltage_v"]


def test_a_swept_effect_coefficient_is_read_per_point(monkeypatch, tmp_path):
    """An effect coefficient set by a swept parameter (bjerknes_scale's factor, stiffness_scale's e_scale, an alias:
    drive_saturation's v_sat) varies
    per point in the batched engine, as in a loop of `acl.analyze` with the parameter overridden (1e-6)."""
    src = open(os.path.join(DATA, "sweep_effects_pair.acl")).read()
    src = src.replace("effect stiffness_scale { e_scale = 0.9 }", "param soft = 0.9\neffect stiffness_scale { e_scale = soft }")
    src = src.replace("effect bjerknes_scale { factor = 1.3 }", "param k = 1.3\neffect bjerknes_scale { factor = k }")
    src += "\nparam vs = 6 V\neffect drive_saturation { v_sat = vs }   # an alias: inv_vsat2 = 1/v_sat^2 per point\n"
    path = tmp_path / "pair.acl"
    path.write_text(src)
    at = "125 kHz @ 2 V"
    _no_point_loop(monkeypatch)
    t = acl.sweep(str(path), vary={"k": "1.0,1.6", "soft": "0.8,1.1", "vs": "3V,9V"}, at=at)
    snaps = []
    for row in t.data:
        a = acl.analyze(load_design(str(path), overrides={"k": repr(float(row["k"])), "soft": repr(float(row["soft"])),
                                                          "vs": f"{float(row['vs'])!r} V"}), at=at)
        assert _close(row["force_left_right_125khz_n"], a.pairs[0]["force_n"])
        assert _close(row["snap_in_left_right_125khz_v"], a.pairs[0]["snap_in_voltage_v"])
        ok = a.equilibrium["status"] == "ok"
        assert bool(row["equilibrium_ok"]) == ok
        for beam, v in a.equilibrium["deflections_m"].items():
            assert _close(row[f"tip_deflection_{beam}_m"], v if ok else float("nan"))
        snaps.append(float(row["snap_in_left_right_125khz_v"]))
    finite = [v for v in snaps if np.isfinite(v)]       # v_sat = 3 V can hold a soft pair below its fold: NaN
    assert len(snaps) == 8 and len(set(finite)) == len(finite) >= 6, snaps   # each point its own coefficients


PRESSURE_AND_WALL = ("effect transducer_gain { gain_slope = 0.6, f_ref = 120 kHz, gain = 1.15 }\n"
                     "effect transducer_resonance { inv_f_ratio = 0.8, gain_q = 3, f_ref = 120 kHz }\n"
                     "effect substrate_proximity { h_substrate = 20 um }\n"
                     "effect bjerknes_scale { factor = 1.2 }\n")


BEAM_LAWS = ("effect stiffness_gradient { e_gradient = 0.7 }\n"
             "effect large_deflection { elastica_weight = 0.5 }\n"
             "effect stiffness_scale { e_scale = 0.8 }\n")


SATURATION = "effect drive_saturation { v_sat = 3 V }\n"


def test_pressure_and_substrate_effects_are_batched_and_equal_analyze(monkeypatch, tmp_path):
    """transducer_gain, transducer_resonance and substrate_proximity act on the drive pressure, the thrust and the
    pairs inside the batched engine, neighbour_drag on the forces at displaced positions, stiffness_gradient and
    large_deflection on the beams (paper Eq. (1) blended with the elastica, inverted per point), drive_saturation
    (snap-in searched in V^2 sat(V)^2): the Fig. 4 pair's forces, snap-in and deflections (with and without
    neighbour_drag, the beam laws, the saturation) and the three-capsule Fig. 5a gripper's equal a loop of
    `acl.analyze` to 1e-6, with no point-by-point analysis."""
    from example_designs import first_principles_text

    _no_point_loop(monkeypatch)
    at = "125 kHz @ 2 V"
    for example, name, values, extra in (("fig4_facing_pair", "gap", ("45um", "60um"), ""),
                                         ("fig4_facing_pair", "gap", ("40um", "55um"),
                                          "effect neighbour_drag { plateau = 8 um }\n"),
                                         ("fig5a_gripper", "gap", ("28um", "34um"), ""),
                                         ("fig4_facing_pair", "gap", ("42um", "58um"), BEAM_LAWS),
                                         ("fig5a_gripper", "gap", ("28um", "34um"), BEAM_LAWS),
                                         ("fig4_facing_pair", "gap", ("42um", "58um"), SATURATION),
                                         ("fig5a_gripper", "gap", ("28um", "34um"), SATURATION)):
        path = tmp_path / f"{example}.acl"
        path.write_text(first_principles_text(example) + "\n" + PRESSURE_AND_WALL + extra)
        t = acl.sweep(str(path), vary={name: ",".join(values)}, at=at)
        snap = [c for c in t.columns if c.startswith("snap_in_")]
        force = [c for c in t.columns if c.startswith("force_")]
        assert snap and force and not any("point by point" in n for n in t.notes), (t.columns, t.notes)
        for row, v in zip(t.data, values):
            a = acl.analyze(load_design(str(path), overrides={name: v.replace("um", " um")}), at=at)
            for pf in a.pairs:
                tag = f"{pf['a']}_{pf['b']}_125khz"
                assert _close(row[f"force_{tag}_n"], pf["force_n"]), (example, tag)
                assert _close(row[f"snap_in_{tag}_v"], pf["snap_in_voltage_v"]), (example, tag)
            ok = a.equilibrium["status"] == "ok"
            assert bool(row["equilibrium_ok"]) == ok
            for el, x in a.equilibrium["deflections_m"].items():
                col = next(c for c in t.columns if c.endswith(f"deflection_{el}_m"))
                assert _close(row[col], x if ok else float("nan")), (example, el)
            # the effects act: the design without them has other forces
            plain = acl.analyze(load_design(str(first_principles_path(example)), overrides={name: v.replace("um", " um")}))
            assert abs(plain.pairs[0]["force_n"] / a.pairs[0]["force_n"] - 1) > 0.05


def test_the_point_by_point_fallback_equals_the_batched_engine(monkeypatch):
    """An effect the batched engine would not model takes its families from analyze point by point
    (acl.sweep.points, the fallback for an effect added to the table later): on the Fig. 5c spring with
    bjerknes_scale taken out of BATCHED_EFFECTS, every column equals the batched one to 1e-6."""
    from acl.sweep import columns

    path = os.path.join(DATA, "sweep_effects_spring.acl")
    at = "125 kHz @ 10 V"
    batched = acl.sweep(path, vary={"gap": "39um,41um"}, at=at)
    monkeypatch.setattr(columns, "BATCHED_EFFECTS", columns.BATCHED_EFFECTS - {"bjerknes_scale"})
    slow = acl.sweep(path, vary={"gap": "39um,41um"}, at=at)
    assert any("point by point" in n for n in slow.notes) and not any("point by point" in n for n in batched.notes)
    assert set(slow.columns) <= set(batched.columns)
    for col in slow.columns:
        for a, b in zip(slow.data[col], batched.data[col]):
            if isinstance(a, (bool, np.bool_, str, np.str_)):      # pass/fail, a point's diagnostic code
                assert a == b, col
            elif col.startswith("phase_"):                          # in phase: round-off about 0 deg
                assert abs(float(a) - float(b)) <= 1e-9, col
            else:
                assert _close(b, float(a)), col

"""Batched evaluation (acl.sweep.evaluate) equals `acl analyze` on materialised points of the shipped examples.

Every comparison runs the scalar analysis (acl.analysis.report.analyze, what `acl analyze
--output-format json` prints) on ``materialize(batch, i)`` of nominal and perturbed points, and
states its tolerance:

* modes, Q, pair forces, phases, d_c, eps/R: relative 1e-9 (same equations, round-off only);
* snap-in voltage: relative 1e-6 (the scalar continuation refines the fold by Brent on det K_T, the
  batched search by golden section on V^2 of the branch);
* beam deflections at a drive: relative 1e-7 (Eq. (1) inverted by Newton in both);
* latch switching force and margins: relative 1e-3, and never below the scalar value: the scalar
  landscape takes the maximum over a 2001-point grid, which lies below the model's maximum when it
  sits at the buckling kink; the batched value refines it by golden section.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import acl
from acl.analysis.report import analyze
from acl.design.drives import drive_from_text
from acl.sweep.evaluate import QUANTITIES, QuantityError, evaluate, supported
from acl.sweep.perturb import FieldBatch, cavity_volume, field_batch, materialize

ROOT = Path(__file__).resolve().parents[1]
EX = ROOT / "examples"


def _batch(design, fields: dict, valid=None) -> FieldBatch:
    fields = {k: np.asarray(v, float) for k, v in fields.items()}
    n = len(next(iter(fields.values())))
    valid = np.ones(n, bool) if valid is None else np.asarray(valid, bool)
    return FieldBatch(design=design, n=n, fields=fields, valid=valid, code=np.where(valid, "", "E401"))


def _rel(a, b):
    return abs(a - b) / abs(b)


@pytest.fixture(scope="module")
def cantilever():
    """Table S1 capsule on a cantilever: nominal + 4 points varying orifice radius, cavity height (volume kept consistent) and E."""
    d = acl.load(str(EX / "fig2_vertical_cantilever.acl"))
    rng = np.random.default_rng(11)
    n = 5
    radius = 10e-6 + 0.4e-6 * rng.standard_normal(n)
    height = 33.15e-6 * (1 + 0.05 * rng.standard_normal(n))
    e = 13e6 * (1 + 0.1 * rng.standard_normal(n))
    radius[0], height[0], e[0] = 10e-6, d.capsule("act").cavity.height, d.beam("arm").youngs_modulus
    b = _batch(d, {"capsules.act.orifices.jet.radius": radius, "capsules.act.cavity.height": height,
                   "capsules.act.cavity.volume": cavity_volume("cylinder", radius=25e-6, height=height),
                   "beams.arm.youngs_modulus": e})
    at = "125 kHz @ 6 V"
    cols = evaluate(b, at=at)
    reps = [analyze(materialize(b, i), at=drive_from_text(at)).as_dict() for i in range(n)]
    return b, cols, reps


def test_cantilever_modes_deflection_requires_equal_analyze(cantilever):
    b, cols, reps = cantilever
    assert len({round(r["capsules"][0]["modes"][0]["frequency_hz"]) for r in reps}) == b.n   # points differ
    for i, rep in enumerate(reps):
        mode = rep["capsules"][0]["modes"][0]
        assert _rel(cols["resonance_act_1_hz"][i], mode["frequency_hz"]) < 1e-9
        assert _rel(cols["q_act_1"][i], mode["q"]) < 1e-9
        assert _rel(cols["tip_deflection_arm_m"][i], rep["equilibrium"]["deflections_m"]["arm"]) < 1e-7
        assert cols["equilibrium_ok"][i] == (rep["equilibrium"]["status"] == "ok")
        req = rep["requires"][0]
        assert _rel(cols["require_1_value"][i], req["value"]) < 1e-9
        assert cols["require_1_pass"][i] == req["ok"]
        assert cols["requires_pass"][i] == all(r["ok"] for r in rep["requires"])


@pytest.fixture(scope="module")
def pair():
    """Fig. 4 facing pair: nominal + points varying both orifice radii, one beam's E and the `gap` parameter."""
    d = acl.load(str(EX / "fig4_facing_pair.acl"))
    rng = np.random.default_rng(5)
    n = 6
    params = {"gap": np.array([40e-6, 30e-6, 38e-6, 45e-6, 62e-6, 42e-6])}
    pb = field_batch(d, params)
    fields = dict(pb.fields)
    r_left = 10e-6 + 0.3e-6 * rng.standard_normal(n)
    e_right = 13e6 * (1 + 0.1 * rng.standard_normal(n))
    r_left[0], e_right[0] = 10e-6, 13e6
    fields["capsules.left.orifices.jet.radius"] = r_left
    fields["beams.right_arm.youngs_modulus"] = e_right
    b = FieldBatch(design=d, n=n, fields=fields, valid=pb.valid, code=pb.code)
    at = "125 kHz @ 3 V"
    cols = evaluate(b, at=at)
    reps = [analyze(materialize(b, i), at=drive_from_text(at)).as_dict() for i in range(n)]
    return b, cols, reps


def test_pair_forces_and_snap_in_equal_analyze(pair):
    b, cols, reps = pair
    tag = "left_right_125khz"
    snapped = 0
    for i, rep in enumerate(reps):
        p = rep["pairs"][0]
        assert p["frequency_hz"] == 125e3
        assert _rel(cols[f"force_{tag}_n"][i], p["force_n"]) < 1e-9
        assert cols[f"attract_{tag}"][i] == p["attract"]
        assert abs(cols[f"phase_{tag}_deg"][i] - p["phase_difference_deg"]) < 1e-9 * 180
        if p["critical_distance_m"] is None:
            assert math.isnan(cols[f"critical_distance_{tag}_m"][i])
        else:
            assert _rel(cols[f"critical_distance_{tag}_m"][i], p["critical_distance_m"]) < 1e-9
        if p["snap_in_voltage_v"] is None:
            assert math.isnan(cols[f"snap_in_{tag}_v"][i]), (i, p["sweep_status"])
        else:
            snapped += 1
            assert _rel(cols[f"snap_in_{tag}_v"][i], p["snap_in_voltage_v"]) < 1e-6
        for m in rep["capsules"]:
            k = m["name"]
            assert _rel(cols[f"resonance_{k}_1_hz"][i], m["modes"][0]["frequency_hz"]) < 1e-9
    assert 0 < snapped < b.n           # the sample holds pairs that snap and pairs pushed apart


def test_pair_deflections_at_a_drive_equal_analyze(pair):
    b, cols, reps = pair
    for i, rep in enumerate(reps):
        eq = rep["equilibrium"]
        assert cols["equilibrium_ok"][i] == (eq["status"] == "ok")
        for beam in ("left_arm", "right_arm"):
            if eq["status"] == "ok":
                assert _rel(cols[f"tip_deflection_{beam}_m"][i], eq["deflections_m"][beam]) < 1e-7
            else:                       # snapped in before the drive: no equilibrium there
                assert math.isnan(cols[f"tip_deflection_{beam}_m"][i])


def test_latch_margins_equal_analyze():
    d = acl.load(str(EX / "fig6_bistable_latch.acl"))
    rng = np.random.default_rng(3)
    n = 4
    theta = np.deg2rad(45) + np.deg2rad(8) * rng.standard_normal(n)
    radius = 10e-6 + 0.3e-6 * rng.standard_normal(n)
    theta[0], radius[0] = np.deg2rad(45), 10e-6
    b = _batch(d, {"latches.snap.angle": theta, "capsules.act.orifices.jet.radius": radius})
    cols = evaluate(b)
    for i in range(n):
        rep = analyze(materialize(b, i)).as_dict()
        lt = rep["latches"][0]
        fs = cols["switching_force_snap_n"][i]
        assert lt["switching_force_n"] * (1 - 1e-12) <= fs < lt["switching_force_n"] * (1 + 1e-3)
        assert cols["bistable_snap"][i] == lt["bistable"]
        for m in lt["margins"]:
            got = cols[f"margin_snap_{m['program']}_{m['step']}"][i]
            assert _rel(got, m["margin"]) < 1e-3 and got <= m["margin"] * (1 + 1e-12)
        req = rep["requires"][0]
        assert _rel(cols["require_1_value"][i], req["value"]) < 1e-3
        assert cols["require_1_pass"][i] == req["ok"]


def test_three_orifice_module_modes_and_requires_equal_analyze():
    d = acl.load(str(EX / "fig3_three_orifice.acl"))
    cap = d.capsules[0]
    rng = np.random.default_rng(8)
    n = 4
    fields = {f"capsules.{cap.name}.orifices.{o.name}.radius": o.radius + 0.3e-6 * rng.standard_normal(n)
              for o in cap.orifices}
    b = _batch(d, fields)
    cols = evaluate(b)
    for i in range(n):
        rep = analyze(materialize(b, i), snap_in=False).as_dict()
        modes = rep["capsules"][0]["modes"]
        assert len(modes) == 3
        for k, m in enumerate(modes, 1):
            assert _rel(cols[f"resonance_{cap.name}_{k}_hz"][i], m["frequency_hz"]) < 1e-9
            assert _rel(cols[f"q_{cap.name}_{k}"][i], m["q"]) < 1e-9
        for j, r in enumerate(rep["requires"], 1):
            assert _rel(cols[f"require_{j}_value"][i], r["value"]) < 1e-9
            assert cols[f"require_{j}_pass"][i] == r["ok"]


@pytest.mark.parametrize("example", ["fig2_vertical_cantilever", "fig3_three_orifice"])
def test_lint_columns_equal_the_rules(example):
    from acl.lint.rules import acoustics, fabrication

    d = acl.load(str(EX / f"{example}.acl"))
    cap = d.capsules[0]
    rng = np.random.default_rng(4)
    n = 4
    fields = {f"capsules.{cap.name}.orifices.{o.name}.radius": o.radius * (1 + 0.2 * rng.standard_normal(n))
              for o in cap.orifices}
    b = _batch(d, fields)
    cols = evaluate(b, [f"lint_{c}_pass" for c in ("acl101", "acl105", "acl503", "acl504")])
    from acl.lint.config import load_config
    from acl.lint.context import Context
    from acl.lint.registry import load_rules

    rules = load_rules()
    fns = {"acl101": acoustics.resonance_outside_band, "acl105": acoustics.bubble_beyond_linear,
           "acl503": fabrication.orifice_too_small, "acl504": fabrication.orifice_too_large}
    seen = set()
    for i in range(n):
        di = materialize(b, i)
        for code, fn in fns.items():
            found = list(fn(Context(di, load_config(None, rules), None)) or ())
            assert cols[f"lint_{code}_pass"][i] == (not found), (i, code)
            seen.add((code, bool(found)))
    assert ("acl105", True) in seen and ("acl105", False) in seen     # both outcomes exercised


def test_invalid_points_are_nan_or_false_and_do_not_disturb_the_others():
    d = acl.load(str(EX / "fig4_facing_pair.acl"))
    r = np.array([10e-6, -1e-6, 10.2e-6])
    b = _batch(d, {"capsules.left.orifices.jet.radius": r}, valid=[True, False, True])
    cols = evaluate(b)
    good = evaluate(_batch(d, {"capsules.left.orifices.jet.radius": r[[0, 2]]}))
    for name, col in cols.items():
        if col.dtype == bool:
            assert not col[1], name
        else:
            assert math.isnan(col[1]), name
        np.testing.assert_array_equal(col[[0, 2]], good[name], err_msg=name)


def test_unknown_and_unsupported_quantities_are_diagnosed():
    d = acl.load(str(EX / "fig2_vertical_cantilever.acl"))
    b = _batch(d, {"capsules.act.orifices.jet.radius": [10e-6]})
    with pytest.raises(QuantityError) as exc:
        evaluate(b, ["resonance_nope_1_hz"])
    assert exc.value.code == "E-SWEEP-Q01"
    with pytest.raises(QuantityError) as exc:
        evaluate(b, ["tip_deflection_arm_m"])          # needs `at`
    assert exc.value.code in ("E-SWEEP-Q01", "E-SWEEP-Q02")
    grip = acl.load(str(EX / "fig5a_gripper.acl"))
    names, missing = supported(grip, "125 kHz @ 5 V")
    assert not any(n.startswith("tip_deflection") for n in names)
    assert "tip_deflection" in missing or "snap_in" in missing


def test_every_column_family_is_documented():
    import re

    pats = [re.compile("^" + re.sub(r"<[^>]+>", ".+", q.pattern) + "$") for q in QUANTITIES]
    for ex in ("fig2_vertical_cantilever", "fig3_three_orifice", "fig4_facing_pair", "fig6_bistable_latch"):
        names, _ = supported(acl.load(str(EX / f"{ex}.acl")), "125 kHz @ 3 V")
        for n in names:
            assert any(p.match(n) for p in pats), n

"""Batched evaluation (acl.sweep.evaluate) equals `acl analyze` on materialised points of the shipped examples.

Every comparison runs the scalar analysis (acl.analysis.report.analyze, what `acl analyze
--output-format json` prints) on ``materialize(batch, i)`` of nominal and perturbed points, and
states its tolerance:

* modes, Q, pair forces, phases, d_c, eps/R: relative 1e-9 (same equations, round-off only);
* snap-in voltage: relative 1e-6 (the scalar continuation refines the fold by Brent on det K_T, the
  batched search by golden section on V^2 of the branch);
* beam deflections at a drive: relative 1e-7 (Eq. (1) inverted by Newton in both);
* latch switching and release forces: relative 2e-3, and never below the scalar value (margins never
  above): the scalar landscape takes the extremes over a 2001-point grid, which lie below the model's
  where they sit at a kink of the force law (buckling); the batched values refine them by golden
  section (tests/test_sweep_evaluate_physics.py checks them against a dense scan).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import acl
from example_designs import first_principles_text, load_first_principles
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
    d = load_first_principles("fig4_facing_pair")
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
        if p["critical_distance_eq3_m"] is None:
            assert math.isnan(cols[f"critical_distance_{tag}_m"][i])
        else:
            assert _rel(cols[f"critical_distance_{tag}_m"][i], p["critical_distance_eq3_m"]) < 1e-9
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


@pytest.mark.parametrize("state", ["a", "b"])
def test_latch_margins_equal_analyze(state):
    src = (EX / "fig6_bistable_latch.acl").read_text().replace("state = a", f"state = {state}")
    d = acl.loads(src, filename=str(EX / "fig6_bistable_latch.acl"))
    assert d.latch("snap").state == state
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
        if lt["release_force_n"] is None:
            assert math.isnan(cols["release_force_snap_n"][i])
        else:
            rel = cols["release_force_snap_n"][i]
            assert lt["release_force_n"] * (1 - 1e-12) <= rel < lt["release_force_n"] * (1 + 2e-3)
        for m in lt["margins"]:
            got = cols[f"margin_snap_{m['program']}_{m['step']}"][i]
            assert _rel(got, m["margin"]) < 2e-3
            assert abs(got) <= abs(m["margin"]) * (1 + 1e-12)          # never optimistic
        req = rep["requires"][0]
        assert _rel(cols["require_1_value"][i], req["value"]) < 2e-3
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
    fields[f"capsules.{cap.name}.cavity.wall"] = np.array([2e-6, 0.5e-6, 2e-6, 0.3e-6])      # 0.5 um: within 2x 0.2 um
    fields[f"capsules.{cap.name}.center.2"] = cap.center[2] + np.array([0.0, -20e-6, 30e-6, 5e-6])
    b = _batch(d, fields)
    cols = evaluate(b, [f"lint_{c}_pass" for c in ("acl101", "acl105", "acl501", "acl502", "acl503", "acl504")])
    from acl.lint.config import load_config
    from acl.lint.context import Context
    from acl.lint.registry import load_rules

    rules = load_rules()
    fns = {"acl101": acoustics.resonance_outside_band, "acl105": acoustics.bubble_beyond_linear,
           "acl503": fabrication.orifice_too_small, "acl504": fabrication.orifice_too_large,
           "acl501": fabrication.marginal_feature, "acl502": fabrication.substrate_proximity}
    seen = set()
    for i in range(n):
        di = materialize(b, i)
        for code, fn in fns.items():
            found = list(fn(Context(di, load_config(None, rules), None)) or ())
            assert cols[f"lint_{code}_pass"][i] == (not found), (i, code)
            seen.add((code, bool(found)))
    for code in ("acl105", "acl501", "acl502"):
        assert (code, True) in seen and (code, False) in seen, code       # both outcomes exercised


def test_invalid_points_are_nan_or_false_and_do_not_disturb_the_others():
    d = load_first_principles("fig4_facing_pair")
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
    assert exc.value.code == "E-SWEEP-Q02" and "at" in str(exc.value)
    # a declared effect on the drive pressure: the equilibria come point by point from analyze's engine
    # (acl.sweep.points), equal to analyze of the point
    truth = acl.load(str(EX / "fig2_stroke_truth.acl"))
    names, missing = supported(truth, "125 kHz @ 5 V")
    assert "tip_deflection_arm_m" in names and "tip_deflection" not in missing
    col = evaluate(_batch(truth, {"beams.arm.length": [truth.beams[0].length]}), ["tip_deflection_arm_m"], "125 kHz @ 5 V")
    want = acl.analyze(truth, at="125 kHz @ 5 V").equilibrium["deflections_m"]["arm"]
    assert abs(col["tip_deflection_arm_m"][0] / want - 1) <= 1e-12


def test_every_column_family_is_documented():
    import re

    pats = [re.compile("^" + re.sub(r"<[^>]+>", ".+", q.pattern) + "$") for q in QUANTITIES]
    for ex in ("fig2_vertical_cantilever", "fig3_three_orifice", "fig4_facing_pair", "fig6_bistable_latch",
               "fig5c_linear_spring", "fig6e_reversible_latch", "figS6_flextensional"):
        names, _ = supported(acl.load(str(EX / f"{ex}.acl")), "125 kHz @ 3 V")
        for n in names:
            assert any(p.match(n) for p in pats), n


def test_require_gap_of_a_pair_equals_analyze():
    """require gap: smallest orifice distance over rest and each program step's equilibrium (0 after snap-in), relative 1e-7."""
    src = first_principles_text("fig4_facing_pair")
    src = src[:src.index("# Fig. 4e: 125 kHz")] + (
        "program gentle {\n  drive 125 kHz @ 2 V for dwell\n  drive 125 kHz @ 3.5 V for dwell\n}\n"
        "require gap(left.jet, right.jet) >= 34 um\n")
    d = acl.loads(src, filename=str(EX / "fig4_facing_pair.acl"))
    rng = np.random.default_rng(3)
    n = 6
    b = _batch(d, {"capsules.left.orifices.jet.radius": 10e-6 + 0.4e-6 * rng.standard_normal(n),
                   "beams.right_arm.youngs_modulus": 13e6 * (1 + 0.2 * rng.standard_normal(n))})
    cols = evaluate(b, ["require_2_value", "require_2_pass"])
    outcomes = set()
    for i in range(n):
        r = analyze(materialize(b, i)).as_dict()["requires"][1]
        assert r["kind"] == "gap"
        if r["value"] == 0.0:
            assert cols["require_2_value"][i] == 0.0
        else:
            assert _rel(cols["require_2_value"][i], r["value"]) < 1e-7
        assert cols["require_2_pass"][i] == r["ok"]
        outcomes.add((r["ok"], r["value"] == 0.0))
    assert len(outcomes) >= 2


def test_pair_with_a_lateral_force_moves_in_both_planes():
    """Capsules offset sideways: forces at rest push out of the pair's line, so the one-axis branch does not apply; the
    snap-in and the deflections come from continuation on both beams' planes of motion (snap-in relative 1e-5: the fold
    is bisected in V on stable Newton solves; deflections 1e-7)."""
    d = load_first_principles("fig4_facing_pair")
    right = d.capsule("right")
    dy = np.array([0.0, 3e-6, 8e-6])
    b = _batch(d, {"capsules.right.center.1": right.center[1] + dy,
                   "capsules.right.orifices.jet.center.1": right.orifices[0].center[1] + dy})
    at = "125 kHz @ 3 V"
    cols = evaluate(b, ["snap_in_left_right_125khz_v", "force_left_right_125khz_n", "tip_deflection_left_arm_m",
                        "tip_deflection_right_arm_m", "equilibrium_ok"], at)
    for i in range(b.n):
        rep = analyze(materialize(b, i), at=drive_from_text(at)).as_dict()
        p, eq = rep["pairs"][0], rep["equilibrium"]
        assert _rel(cols["force_left_right_125khz_n"][i], p["force_n"]) < 1e-9
        assert _rel(cols["snap_in_left_right_125khz_v"][i], p["snap_in_voltage_v"]) < 1e-5
        assert cols["equilibrium_ok"][i] == (eq["status"] == "ok")
        for beam in ("left_arm", "right_arm"):
            assert _rel(cols[f"tip_deflection_{beam}_m"][i], eq["deflections_m"][beam]) < 1e-7


def test_latch_columns_in_blocks_equal_one_block():
    from acl.physics.batch import latch_switching_force

    rng = np.random.default_rng(2)
    n = 50
    args = (np.deg2rad(rng.uniform(30, 60, n)), np.full(n, 50e-6), np.full(n, 1e-6), np.full(n, 1.7e-6), np.full(n, 13e6))
    one = latch_switching_force(*args)
    blocks = latch_switching_force(*args, block=7)
    for a, b in zip(one, blocks):
        np.testing.assert_array_equal(a, b)


def _expected(rep: dict) -> dict:
    """The analyze JSON of one design as sweep columns (what QUANTITIES says each column equals)."""
    from acl.sweep.evaluate import _fkey

    nan = float("nan")
    out = {}
    for c in rep["capsules"]:
        for k, m in enumerate(c["modes"], 1):
            out[f"resonance_{c['name']}_{k}_hz"] = m["frequency_hz"]
            out[f"q_{c['name']}_{k}"] = m["q"]
    for p in rep["pairs"]:
        tag = f"{p['a']}_{p['b']}_{_fkey(p['frequency_hz'])}"
        out[f"force_{tag}_n"] = p["force_n"]
        out[f"attract_{tag}"] = p["attract"]
        out[f"phase_{tag}_deg"] = p["phase_difference_deg"]
        out[f"critical_distance_{tag}_m"] = nan if p["critical_distance_eq3_m"] is None else p["critical_distance_eq3_m"]
        out[f"snap_in_{tag}_v"] = nan if p["snap_in_voltage_v"] is None else p["snap_in_voltage_v"]
    for lt in rep["latches"]:
        out[f"switching_force_{lt['name']}_n"] = lt["switching_force_n"]
        out[f"release_force_{lt['name']}_n"] = nan if lt["release_force_n"] is None else lt["release_force_n"]
        out[f"bistable_{lt['name']}"] = lt["bistable"]
        for m in lt["margins"]:
            out[f"margin_{lt['name']}_{m['program']}_{m['step']}"] = m["margin"]
    eq = rep["equilibrium"]
    if eq is not None:
        out["equilibrium_ok"] = eq["status"] == "ok"
        beams = set(rep.get("_beams", ()))
        for name, v in eq["deflections_m"].items():
            col = "tip_deflection" if name in beams else "deflection"
            out[f"{col}_{name}_m"] = v if eq["status"] == "ok" else nan
    for i, r in enumerate(rep["requires"], 1):
        out[f"require_{i}_value"] = nan if r["value"] is None else r["value"]
        out[f"require_{i}_pass"] = r["ok"]
    out["requires_pass"] = all(r["ok"] for r in rep["requires"])
    # the model-form force uncertainty past the soft validity limits (acl.physics.validity) over the program steps
    # (eps/R at rest, the capsule's largest Q; 1 past the hemisphere) and the pairs at rest (monopole distance)
    from acl.physics import validity as VA

    q = {c["name"]: max((m["q"] for m in c["modes"]), default=10.0) for c in rep["capsules"]}
    rel = 0.0
    for dr in rep["drives"]:
        if dr.get("basis") != "step" or "sweep's worst frequency" in dr["drive"]:
            continue                           # a `sweep` step's worst frequency: not in the column (acl.sweep.model_form)
        for key, x in dr["interface_amplitude_over_radius"].items():
            if x > VA.AMPLITUDE.value:
                rel = max(rel, 1.0 if x > VA.AMPLITUDE_MEANING.value else float(VA.amplitude_model_form(x, q[key.split(".")[0]])))
    for p in rep["pairs"]:
        rel = max(rel, p["monopole_model_form_rel"])
    out["model_form_rel"] = rel
    return out


TOL = {"snap_in": 1e-6, "tip_deflection": 1e-7, "switching_force": 2e-3, "release_force": 2e-3, "margin": 2e-3}


@pytest.mark.parametrize("example", sorted(p.stem for p in EX.glob("*.acl")))
def test_every_example_nominal_equals_analyze(example):
    """Each shipped example at its nominal point: every batched column equals the analyze field QUANTITIES names (tolerances of the module doc)."""
    d = acl.load(str(EX / f"{example}.acl"))
    at = "125 kHz @ 2 V"
    b = FieldBatch(design=d, n=1, fields={}, valid=np.ones(1, bool), code=np.full(1, ""))
    names, _ = supported(d, at)
    cols = evaluate(b, [n for n in names if not n.startswith("lint_") and n != "model_form_uncertain"
                        and not n.startswith("model_form_pair_")], at)   # the sweep's own (tests/test_pair_scale_spread.py)
    exp = _expected({**analyze(d, at=drive_from_text(at)).as_dict(), "_beams": [b.name for b in d.beams]})
    checked = 0
    for name, col in cols.items():
        assert name in exp, name
        got, want = col[0], exp[name]
        if isinstance(want, bool):
            assert bool(got) == want, name
        elif math.isnan(want) or math.isinf(want):
            assert (math.isnan(got) and math.isnan(want)) or got == want, (name, got, want)
        else:
            tol = next((v for k, v in TOL.items() if name.startswith(k)), 1e-9)
            if name.startswith("require_") and name.endswith("_value") and d.requires[int(name.split("_")[1]) - 1].kind == "margin":
                tol = TOL["margin"]
            absolute = 1e-7 if name.startswith("phase_") else 1e-300         # degrees: phases near 0
            if "deflection_" in name:       # a truss-tied capsule: 0 up to the round-off of each one's null space
                absolute = 1e-15
            if name.startswith("snap_in_") and d.latches:
                tol = 1e-5      # a kink fold of the latch law: tests/test_sweep_mechanism.py (never above the model's fold)
            elif name.startswith("snap_in_"):
                assert got <= want * (1 + 1e-12), name             # a smooth fold: never above analyze
            assert got == pytest.approx(want, rel=tol, abs=absolute), name
        checked += 1
    assert checked >= 2


def test_a_fold_close_to_rest_near_the_critical_distance():
    """Near d_c (one capsule pulled, one pushed) the branch folds within 0.3 um of rest: the batched search finds the
    saddle-node (smallest eigenvalue of K_T -> 0 there, no stable equilibrium just above) and equals `acl analyze`
    (relative 1e-6; before the mechanics changes merged at 18:10 the scalar continuation stepped over this fold and
    reported 6.475 V)."""
    from acl.sweep.evaluate import _Evaluator

    d = load_first_principles("fig4_facing_pair")
    right = d.capsule("right")
    dx = 9.421300890004399e-05 - right.center[0]
    b = _batch(d, {"capsules.left.orifices.jet.radius": [1.0341683731893399e-05],
                   "capsules.right.orifices.jet.radius": [9.808323936833488e-06],
                   "beams.left_arm.youngs_modulus": [13121302.104411649],
                   "capsules.right.center.0": [right.center[0] + dx],
                   "capsules.right.orifices.jet.center.0": [right.orifices[0].center[0] + dx]})
    v = evaluate(b, ["snap_in_left_right_125khz_v"])["snap_in_left_right_125khz_v"][0]
    scalar = analyze(materialize(b, 0)).as_dict()["pairs"][0]["snap_in_voltage_v"]
    assert 6.2 < v < 6.3
    assert _rel(v, scalar) < 1e-6
    ev = _Evaluator(b, None)
    q = np.zeros((1, 4))
    mevs = []
    for volts in np.linspace(0.5, v * (1 - 1e-6), 40):
        q, conv, mev = ev.plane_solve(q, np.array([volts * volts]), (125e3,), (1.0,))
        assert conv[0] and mev[0] > 0
        mevs.append(mev[0])
    assert mevs[-1] < 0.05 * mevs[0]                        # the tangent stiffness vanishes at the fold
    _, conv, mev = ev.plane_solve(q, np.array([(v * 1.001) ** 2]), (125e3,), (1.0,))
    assert not (conv[0] and mev[0] > 0)                      # no stable equilibrium next to the branch above it


def test_pair_with_one_capsule_fixed_equals_analyze():
    d0 = load_first_principles("fig4_facing_pair")
    c = d0.capsule("right").center
    src = first_principles_text("fig4_facing_pair").replace("mount right on right_arm.tip", "fix right").replace(
        "capsule right like capsules.design1 {",
        "capsule right like capsules.design1 {\n  center = (%r um, %r um, %r um)" % (c[0] * 1e6, c[1] * 1e6, c[2] * 1e6))
    d = acl.loads(src, filename=str(EX / "fig4_facing_pair.acl"))
    rng = np.random.default_rng(1)
    n = 3
    b = _batch(d, {"capsules.left.orifices.jet.radius": 10e-6 + 0.3e-6 * rng.standard_normal(n)})
    at = "125 kHz @ 3 V"
    cols = evaluate(b, ["snap_in_left_right_125khz_v", "tip_deflection_left_arm_m"], at)
    for i in range(n):
        rep = analyze(materialize(b, i), at=drive_from_text(at)).as_dict()
        assert _rel(cols["snap_in_left_right_125khz_v"][i], rep["pairs"][0]["snap_in_voltage_v"]) < 1e-6
        assert _rel(cols["tip_deflection_left_arm_m"][i], rep["equilibrium"]["deflections_m"]["left_arm"]) < 1e-7

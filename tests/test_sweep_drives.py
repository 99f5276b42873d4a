"""Sweeps that move drive voltages, limits and transducer values: checked and evaluated per point, vectorised.

* Validity: every point's code equals the first error `acl check` gives the same design (``acl.load``
  with the point's parameters), over random points of samples/sweep_drives.acl whose spreads reach
  every drive and transducer check (E401, E413, E320, E502, E503, E505, and valid points).
* Columns: forces, d_c, snap-in voltages, `require gap`, latch margins and the lint columns of a
  point equal `acl analyze` / `acl lint` of the same design (tolerances of tests/test_sweep_evaluate.py:
  relative 1e-9 for forces and d_c, 1e-6 for snap-in, 2e-3 and never optimistic for latch margins).
"""
from __future__ import annotations

import math
import warnings
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

import acl
from example_designs import first_principles_path, load_first_principles
from acl.analysis.report import analyze
from acl.diagnostics import DiagnosticError

from test_sweep_evaluate import TOL, _expected

ROOT = Path(__file__).resolve().parents[1]
DRIVES = ROOT / "samples" / "sweep_drives.acl"
EX = ROOT / "examples"

WIDE = {"volts": "normal(0, 3 V)", "limit": "normal(0, 4 V)", "vmax": "normal(0, 8 V)", "g125": "normal(0, 200 Pa/V)",
        "unc": "uniform(-0.5, 10.3)", "margin": "normal(0, 1)", "bound": "normal(0, 10 um)", "dwell": "normal(0, 150 ms)"}


def _first_error(path, overrides) -> str:
    try:
        acl.load(str(path), overrides=overrides)
        return ""
    except DiagnosticError as exc:
        return next(d.code for d in exc.diagnostics if d.is_error)


def test_drive_and_transducer_checks_give_the_code_acl_check_gives():
    t = acl.sweep(str(DRIVES), tolerance=WIDE, n=150, seed=5, quantities=["resonance_left_1_hz"])
    assert not any("resolved exactly" in n for n in t.notes)                # nothing re-resolved per point
    codes = Counter()
    for i in range(len(t)):
        want = _first_error(DRIVES, {k: float(t[k][i]) for k in WIDE})
        assert t["code"][i] == want, (i, {k: float(t[k][i]) for k in WIDE})
        codes[want] += 1
    assert {"", "E401", "E413", "E320", "E502", "E503", "E505"} <= set(codes), codes


def test_a_sweep_of_drive_fields_resolves_the_design_no_more_than_the_map_needs(monkeypatch):
    """The map is found by a few resolutions; the points themselves are never resolved (the old way
    loaded the design once per unique drive value, ~8 s per 5,000 samples)."""
    import acl.sweep.perturb as P

    calls = []
    real = P._load
    monkeypatch.setattr(P, "_load", lambda *a, **k: calls.append(1) or real(*a, **k))
    d = acl.load(str(DRIVES))
    from acl.sweep.spec import build_spec

    spec = build_spec(d, tolerance=None, samples=3000, seed=1)
    fmap = P.field_map(d, spec.names, spec.box())
    before = len(calls)
    from acl.sweep.sample import chunk_points

    b = P.field_batch(d, chunk_points(spec, 0, spec.chunk_size), fmap)
    assert len(calls) == before and b.n == 3000


def _compare(cols: dict, rep: dict, i: int, skip=("lint_",)) -> int:
    exp = _expected(rep)
    checked = 0
    for name, col in cols.items():
        if name.startswith(skip) or name not in exp:
            continue
        got, want = col[i], exp[name]
        if isinstance(want, bool):
            assert bool(got) == want, (i, name)
        elif math.isnan(want):
            assert math.isnan(got), (i, name, got)
        else:
            tol = next((v for k, v in TOL.items() if name.startswith(k)), 1e-9)
            assert got == pytest.approx(want, rel=tol, abs=1e-7 if name.startswith("phase_") else 1e-300), (i, name)
        checked += 1
    return checked


@pytest.fixture(scope="module")
def drives():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t = acl.sweep(str(DRIVES), n=8, seed=2)          # the declared spreads: volts, limit, vmax, g125
    return t


def test_columns_use_each_points_drive_and_gain_and_equal_analyze(drives):
    t = drives
    assert not any("left out" in n for n in t.notes)
    for c in ("force_left_right_125khz_n", "snap_in_left_right_125khz_v", "require_2_value", "lint_acl105_pass"):
        assert c in t.columns, c
    assert np.ptp(t["force_left_right_125khz_n"][t["valid"]]) > 0          # the columns do move per point
    checked = 0
    for i in range(len(t)):
        ov = {k: float(t[k][i]) for k in ("volts", "limit", "vmax", "g125")}
        if not t["valid"][i]:
            assert _first_error(DRIVES, ov) == t["code"][i]
            continue
        rep = analyze(acl.load(str(DRIVES), overrides=ov)).as_dict()
        checked += _compare({c: t[c] for c in t.columns}, rep, i)
    assert checked >= 40


def test_lint_columns_follow_each_points_drive(drives):
    """ACL101 (band) and ACL105 (eps/R at the drive) read the point's transducer and amplitudes."""
    from acl.lint.config import load_config
    from acl.lint.context import Context
    from acl.lint.registry import load_rules
    from acl.lint.rules import acoustics

    rules = load_rules()
    t = drives
    seen = set()
    for i in np.flatnonzero(t["valid"]):
        d = acl.load(str(DRIVES), overrides={k: float(t[k][i]) for k in ("volts", "limit", "vmax", "g125")})
        for code, fn in (("acl101", acoustics.resonance_outside_band), ("acl105", acoustics.bubble_beyond_linear)):
            found = list(fn(Context(d, load_config(None, rules), None)) or ())
            assert t[f"lint_{code}_pass"][i] == (not found), (i, code)
            seen.add((code, bool(found)))
    assert ("acl105", True) in seen and ("acl105", False) in seen


def test_latch_margins_follow_the_limit_of_a_switch_step():
    """fig6: `switch ..., limit vmax` drives at the point's limit; the margins equal analyze (2e-3, never above)."""
    t = acl.sweep(str(EX / "fig6_bistable_latch.acl"), vary={"vmax": "40V..100V:4"})
    assert not any("left out" in n for n in t.notes)
    margins = [c for c in t.columns if c.startswith("margin_")]
    assert margins
    for i in range(len(t)):
        rep = analyze(acl.load(str(EX / "fig6_bistable_latch.acl"), overrides={"vmax": float(t["vmax"][i])})).as_dict()
        for m in rep["latches"][0]["margins"]:
            got = t[f"margin_snap_{m['program']}_{m['step']}"][i]
            assert abs(got - m["margin"]) <= 2e-3 * abs(m["margin"]) and abs(got) <= abs(m["margin"]) * (1 + 1e-12)
    col = t[margins[0]]
    assert len(set(np.round(col, 12))) == 4                                   # the margin moves with the limit


def test_a_parameter_moving_a_tone_frequency_still_leaves_the_program_columns_out(tmp_path):
    src = DRIVES.read_text().replace("drive 125 kHz @ volts for dwell", "drive f1 @ volts for dwell")
    src = src.replace("param dwell = 200 ms", "param dwell = 200 ms\nparam f1 = 125 kHz")
    path = tmp_path / "freq.acl"
    path.write_text(src)
    t = acl.sweep(str(path), vary={"f1": "120kHz..130kHz:3"})
    assert not [c for c in t.columns if c.startswith(("force_", "snap_in_", "lint_"))]
    assert any("programs' frequencies" in n for n in t.notes)
    assert list(t["code"]) == ["", "", ""]


def _rule_verdicts(design, fns) -> dict:
    from acl.lint.config import load_config
    from acl.lint.context import Context
    from acl.lint.registry import load_rules

    ctx = Context(design, load_config(None, load_rules()), None)
    return {code: not list(fn(ctx) or ()) for code, fn in fns.items()}


def test_lint_acl102_and_acl103_columns_equal_the_rules_on_perturbed_points():
    """ACL102 (low gain at a mode) and ACL103 (modes of separately driven capsules overlapping) are batched:
    the verdict of each perturbed point equals the rule's on the materialised design, both outcomes hit."""
    from acl.lint.rules import acoustics
    from acl.sweep.evaluate import evaluate
    from acl.sweep.perturb import FieldBatch, materialize

    d = acl.load(str(EX / "fig1f_selective_beams.acl"))
    rng = np.random.default_rng(8)
    n = 24
    fields = {}
    for cap in d.capsules:
        for o in cap.orifices:
            fields[f"capsules.{cap.name}.orifices.{o.name}.radius"] = o.radius * np.exp(0.35 * rng.standard_normal(n))
    b = FieldBatch(design=d, n=n, fields=fields, valid=np.ones(n, bool), code=np.full(n, ""))
    cols = evaluate(b, ["lint_acl102_pass", "lint_acl103_pass"])
    fns = {"acl102": acoustics.low_transducer_gain, "acl103": acoustics.mode_crosstalk}
    seen = set()
    for i in range(n):
        want = _rule_verdicts(materialize(b, i), fns)
        for code, ok in want.items():
            assert cols[f"lint_{code}_pass"][i] == ok, (i, code)
            seen.add((code, ok))
    assert seen == {(c, v) for c in fns for v in (True, False)}, seen


def test_lint_acl102_follows_each_points_transducer_table():
    from acl.lint.rules import acoustics

    t = acl.sweep(str(DRIVES), tolerance={"g125": "normal(0, 300 Pa/V)"}, n=40, seed=9,
                  quantities=["lint_acl102_pass"])
    seen = set()
    for i in np.flatnonzero(t["valid"]):
        d = acl.load(str(DRIVES), overrides={k: float(t[k][i]) for k in ("volts", "limit", "vmax", "g125")})
        ok = _rule_verdicts(d, {"acl102": acoustics.low_transducer_gain})["acl102"]
        assert t["lint_acl102_pass"][i] == ok, i
        seen.add(ok)
    assert seen == {True, False}


def test_lint_acl201_column_equals_the_rule_across_the_critical_distance():
    """ACL201 (Eq. 3 criterion, lint's default) per point: the Fig. 4 pair below and above d_c (~50 um),
    with its thrust coefficient spread; verdicts equal lint.rules.forces.snap_in on each point's design."""
    from acl.lint.rules import forces

    path = first_principles_path("fig4_facing_pair")      # batched forces: the model's own pair law (no calibration)
    t = acl.sweep(str(path), vary={"gap": "20um..80um:7"}, tolerance={"gamma": "30 %"}, n=3, seed=4,
                  quantities=["lint_acl201_pass"])
    seen = set()
    for i in range(len(t)):
        d = acl.load(str(path), overrides={"gap": float(t["gap"][i]), "gamma": float(t["gamma"][i])})
        ok = _rule_verdicts(d, {"acl201": forces.snap_in})["acl201"]
        assert t["lint_acl201_pass"][i] == ok, (i, float(t["gap"][i]))
        seen.add(ok)
    assert seen == {True, False}


def test_lint_acl201_is_not_offered_with_a_sweep_step_and_says_why():
    from acl.sweep.evaluate import supported

    names, missing = supported(acl.load(str(DRIVES)))
    assert "lint_acl201_pass" not in names and "sweep" in missing["lint_acl201"]


@pytest.mark.parametrize("example", sorted(p.stem for p in EX.glob("*.acl")))
def test_every_batched_lint_column_equals_its_rule_on_each_example(example):
    from acl.lint.rules import acoustics, beams, fabrication, forces
    from acl.sweep.evaluate import evaluate, supported
    from acl.sweep.perturb import FieldBatch

    d = acl.load(str(EX / f"{example}.acl"))
    fns = {"acl101": acoustics.resonance_outside_band, "acl102": acoustics.low_transducer_gain,
           "acl103": acoustics.mode_crosstalk, "acl105": acoustics.bubble_beyond_linear, "acl201": forces.snap_in,
           "acl401": beams.beam_strain, "acl402": beams.beam_large_deflection,
           "acl501": fabrication.marginal_feature, "acl502": fabrication.substrate_proximity,
           "acl503": fabrication.orifice_too_small, "acl504": fabrication.orifice_too_large}
    names, _ = supported(d)
    wanted = [f"lint_{c}_pass" for c in fns if f"lint_{c}_pass" in names]
    b = FieldBatch(design=d, n=1, fields={}, valid=np.ones(1, bool), code=np.full(1, ""))
    cols = evaluate(b, wanted)
    want = _rule_verdicts(d, {c: fn for c, fn in fns.items() if f"lint_{c}_pass" in wanted})
    assert {c: bool(cols[f"lint_{c}_pass"][0]) for c in want} == want


@pytest.mark.parametrize("example", ["fig4_facing_pair", "fig4h_unequal_pair", "fig1f_selective_beams", "figS6_flextensional"])
def test_lint_acl401_and_acl402_columns_equal_the_rules_on_softer_and_thinner_beams(example):
    """Beam strain and Eq. (1) validity from each program's worst load, per point: beams made softer
    (Young's modulus down to 1/300) and thinner until both rules fire; verdicts equal the rules."""
    from acl.lint.rules import beams
    from acl.sweep.evaluate import evaluate
    from acl.sweep.perturb import FieldBatch, materialize

    d = load_first_principles(example)                   # batched forces: the model's own pair law
    scale = np.array([1.0, 0.3, 0.1, 0.03, 0.01, 0.0033])
    fields = {f"beams.{b.name}.youngs_modulus": b.youngs_modulus * scale for b in d.beams}
    b = FieldBatch(design=d, n=scale.size, fields=fields, valid=np.ones(scale.size, bool), code=np.full(scale.size, ""))
    cols = evaluate(b, ["lint_acl401_pass", "lint_acl402_pass"])
    seen = set()
    for i in range(scale.size):
        want = _rule_verdicts(materialize(b, i), {"acl401": beams.beam_strain, "acl402": beams.beam_large_deflection})
        for code, ok in want.items():
            assert cols[f"lint_{code}_pass"][i] == ok, (i, code)
            seen.add((code, ok))
    assert ("acl402", False) in seen and ("acl402", True) in seen, seen

"""Issue 24 in a sweep: beyond a soft validity limit a point's forces carry the model-form uncertainty that grows
past the limit (acl.physics.validity), in the column ``model_form_rel``, and the yield's interval counts the points
whose margin or gap verdict it could flip both ways (``model_form_uncertain``), with a note."""
from __future__ import annotations

import os

import numpy as np

import acl
from acl.design.resolve import load_design
from acl.physics import validity as VA
from acl.sweep.table import clopper_pearson
from example_designs import first_principles_path

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PAIR = str(first_principles_path("fig4_facing_pair"))   # without its calibration (with it: the last test)
SPRING = os.path.join(ROOT, "benchmarks", "designs", "sweep_spring.acl")


def _expected(analysis) -> float:
    """The largest model-form force uncertainty analyze reports over the program steps (eps/R at rest with the
    capsule's Q) and the pairs at rest (monopole): an independent computation from analyze's own fields."""
    q = {c.name: max(m.q for m in c.modes) for c in analysis.capsules}
    rel = 0.0
    for d in analysis.drives:
        if d["basis"] != "step":
            continue
        for key, x in ({} if "sweep's worst frequency" in d["drive"] else d["interface_amplitude_over_radius"]).items():
            if x > VA.AMPLITUDE_MEANING.value:
                rel = max(rel, 1.0)
            elif x > VA.AMPLITUDE.value:
                rel = max(rel, float(VA.amplitude_model_form(x, q[key.split(".")[0]])))
    for p in analysis.pairs:
        rel = max(rel, p["monopole_model_form_rel"])
    return rel


def test_model_form_rel_equals_analyze_past_the_amplitude_and_monopole_limits():
    t = acl.sweep(PAIR, vary={"gap": "24um,40um,60um"}, quantities=["model_form_rel"])
    for row, gap in zip(t.data, ("24 um", "40 um", "60 um")):
        want = _expected(acl.analyze(load_design(PAIR, overrides={"gap": gap}), snap_in=False))
        assert want > 0.0                                 # the 8 V and 15 V steps are past eps/R = 0.25
        assert abs(row["model_form_rel"] - want) <= 1e-6 * want, (gap, row["model_form_rel"], want)
    # closer than twice the orifice radii (24 um < 2 x 20 um): the monopole term (20/24)^2 dominates
    assert abs(t.data["model_form_rel"][0] - (20 / 24) ** 2) <= 1e-9


def _declared_pair(tmp_path) -> str:
    """SPRING with its first-principles pair force declared as such (`bjerknes_scale { factor = 1 }`): the same
    forces, without the pair-scale spread a first-principles pair adds to the interval (tests/test_pair_scale_spread.py)."""
    path = tmp_path / "sweep_spring_declared.acl"
    path.write_text(open(SPRING).read() + "\neffect bjerknes_scale { factor = 1 }\n")
    return str(path)


def test_the_yield_interval_widens_by_the_points_whose_verdict_could_flip(tmp_path):
    t = acl.sweep(_declared_pair(tmp_path), n=120, seed=2, search_paths=(ROOT,))
    y = t.yields()["all"]
    rel = t.data["model_form_rel"]
    assert np.all(rel[t.data["valid"]] > 0)
    (i,) = [k for k, r in enumerate(load_design(SPRING).requires, 1) if r.kind == "gap"]
    v, ok, valid = t.data[f"require_{i}_value"], t.data[f"require_{i}_pass"], t.data["valid"]
    bound = load_design(SPRING).requires[i - 1].lower
    flip = valid & np.where(ok, v * (1 - rel) < bound, v * (1 + rel) >= bound)
    assert 0 < flip.sum() < len(t) and y.widened == int(flip.sum())
    assert np.array_equal(t.data["model_form_uncertain"] & valid, flip)
    plain = clopper_pearson(y.passed, y.total)
    up = int((flip & t.passed).sum())
    assert y.lower == clopper_pearson(y.passed - up, y.total)[0] < plain[0]
    assert y.upper == clopper_pearson(y.passed + int(flip.sum()) - up, y.total)[1] >= plain[1]
    assert "interval widened by" in t.summary_line()
    assert any("past a soft validity limit" in n for n in t.notes)


def test_naming_the_columns_without_it_says_the_interval_is_not_widened(tmp_path):
    t = acl.sweep(_declared_pair(tmp_path), n=20, seed=2, quantities=["requires_pass"], search_paths=(ROOT,))
    assert "model_form_uncertain" not in t.columns and t.yields()["all"].widened == 0
    assert any("not widened by the model-form uncertainty" in n for n in t.notes)


def test_model_form_rel_under_declared_effects_equals_analyze(tmp_path):
    """With declared effects on the drive pressure (transducer_gain, drive_saturation) and the pair law (the
    calibration), eps/R takes the effects' pressure, as analyze's: model_form_rel equals analyze (1e-6)."""
    path = tmp_path / "pair.acl"
    path.write_text(open(PAIR).read() + "\neffect transducer_gain { gain = 1.3 }\neffect drive_saturation { v_sat = 12 V }\n"
                    "effect bjerknes_scale { factor = 1.5 }\n")
    t = acl.sweep(str(path), vary={"gap": "24um,40um,60um"}, quantities=["model_form_rel"])
    plain = acl.sweep(PAIR, vary={"gap": "24um,40um,60um"}, quantities=["model_form_rel"])
    for row, gap in zip(t.data, ("24 um", "40 um", "60 um")):
        want = _expected(acl.analyze(load_design(str(path), overrides={"gap": gap}), snap_in=False))
        assert want > 0.0
        assert abs(row["model_form_rel"] - want) <= 1e-6 * want, (gap, row["model_form_rel"], want)
    assert not np.allclose(t.data["model_form_rel"][1:], plain.data["model_form_rel"][1:])   # the effects act

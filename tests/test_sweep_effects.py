"""Declared physical effects in a sweep: each column family is given where no declared effect changes it, and
equals `acl analyze` of the design with its effects.  The effects acl.sweep.columns.BATCHED_EFFECTS names are applied
in the batched engine (tests/test_sweep_points.py); the others' families are given point by point by analyze's
engine (acl.sweep.points) and equal analyze exactly.

Forces at rest are unchanged by effects on beams (large_deflection, stiffness_gradient, stiffness_scale) and
by neighbour_drag (its factor is 1 at zero displacement); latch margins also by all but stiffness_scale
(mechanics.latch_geometry).  Tolerances as tests/test_sweep_evaluate.py: forces 1e-9, latch margins 2e-3 and
never above analyze.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import acl
from example_designs import first_principles_text
from acl.analysis.report import analyze
from acl.sweep.evaluate import QuantityError, evaluate, supported
from acl.sweep.perturb import FieldBatch, materialize

ROOT = Path(__file__).resolve().parents[1]
EX = ROOT / "examples"


def _design(example: str, effects: str):
    src = first_principles_text(example) + "\n" + effects + "\n"   # the model's own pair law (no stdlib calibration)
    return acl.loads(src, filename=str(EX / f"{example}.acl"))


def _batch(design, fields: dict) -> FieldBatch:
    fields = {k: np.asarray(v, float) for k, v in fields.items()}
    n = len(next(iter(fields.values())))
    return FieldBatch(design=design, n=n, fields=fields, valid=np.ones(n, bool), code=np.full(n, ""))


def test_pair_forces_with_beam_and_drag_effects_equal_analyze():
    d = _design("fig4_facing_pair", "effect large_deflection { elastica_weight = 0.5 }\n"
                                    "effect neighbour_drag { plateau = 20 um }\n"
                                    "observe g = gap(left.jet, right.jet)")
    names, missing = supported(d, "125 kHz @ 3 V")
    tag = "left_right_125khz"
    assert f"force_{tag}_n" in names and f"critical_distance_{tag}_m" in names and "lint_acl105_pass" in names
    # changed by these effects: given point by point by analyze's engine (acl.sweep.points), not left out
    assert f"snap_in_{tag}_v" in names and "tip_deflection_left_arm_m" in names
    assert "snap_in_" not in missing and "tip_deflection" not in missing
    b = _batch(d, {"capsules.left.orifices.jet.radius": [10e-6, 9.7e-6, 10.4e-6]})
    cols = evaluate(b, [f"force_{tag}_n", f"phase_{tag}_deg", f"critical_distance_{tag}_m"])
    for i in range(b.n):
        p = analyze(materialize(b, i), snap_in=False).as_dict()["pairs"][0]
        assert abs(cols[f"force_{tag}_n"][i] - p["force_n"]) <= 1e-9 * abs(p["force_n"])
        assert abs(cols[f"phase_{tag}_deg"][i] - p["phase_difference_deg"]) <= 1e-7
        if p["critical_distance_eq3_m"] is None:
            assert math.isnan(cols[f"critical_distance_{tag}_m"][i])
        else:
            assert abs(cols[f"critical_distance_{tag}_m"][i] - p["critical_distance_eq3_m"]) <= 1e-9 * p["critical_distance_eq3_m"]
    snap = evaluate(b, [f"snap_in_{tag}_v"])[f"snap_in_{tag}_v"]
    for i in range(b.n):
        v = analyze(materialize(b, i)).as_dict()["pairs"][0]["snap_in_voltage_v"]
        assert abs(snap[i] - v) <= 1e-6 * v
    with pytest.raises(QuantityError) as exc:
        evaluate(b, ["snap_in_nobody_125khz_v"])
    assert exc.value.code == "E-SWEEP-Q01"


def test_latch_margins_with_a_stiffness_gradient_equal_analyze_and_stiffness_scale_is_batched():
    d = _design("fig6_bistable_latch", "effect stiffness_gradient { e_gradient = 0.2 }")
    names, missing = supported(d, None)
    assert "switching_force_snap_n" in names and "require_1_value" in names
    b = _batch(d, {"latches.snap.angle": np.deg2rad([45.0, 43.0, 48.0])})
    cols = evaluate(b, ["switching_force_snap_n", "margin_snap_switch_1", "require_1_value", "require_1_pass"])
    for i in range(b.n):
        rep = analyze(materialize(b, i), snap_in=False).as_dict()
        lt = rep["latches"][0]
        fsw = cols["switching_force_snap_n"][i]
        assert lt["switching_force_n"] * (1 - 1e-12) <= fsw <= lt["switching_force_n"] * (1 + 2e-3)
        m = next(x["margin"] for x in lt["margins"] if x["program"] == "switch")
        assert m * (1 - 2e-3) <= cols["margin_snap_switch_1"][i] <= m * (1 + 1e-12)    # never above analyze
        assert cols["require_1_pass"][i] == rep["requires"][0]["ok"]
    # stiffness_scale changes the latch law: E x e_scale in the batched engine (acl.sweep.columns.BATCHED_EFFECTS)
    scaled = _design("fig6_bistable_latch", "effect stiffness_scale { e_scale = 0.8 }")
    names, missing = supported(scaled, None)
    assert "switching_force_snap_n" in names and "require_1_value" in names and "margin_" not in missing
    assert "resonance_act_1_hz" in names
    b = _batch(scaled, {"latches.snap.angle": np.deg2rad([45.0, 48.0])})
    cols = evaluate(b, ["switching_force_snap_n", "require_1_value"])
    for i in range(b.n):
        rep = analyze(materialize(b, i), snap_in=False).as_dict()
        assert abs(cols["switching_force_snap_n"][i] / rep["latches"][0]["switching_force_n"] - 1) <= 1e-12
        assert abs(cols["require_1_value"][i] / rep["requires"][0]["value"] - 1) <= 1e-12


def test_lint_acl105_under_pressure_effects_equals_the_rule():
    """ACL105 (eps/R past the linear limit) with transducer_gain and drive_saturation (the factor at each drive's
    total amplitude, interfaces.interface_amplitudes_batch): the Fig. 2 stroke example's sweep-step drive and a
    drive step, voltages spread across the limit; each point's verdict equals the rule on its design."""
    from acl.lint.rules import acoustics
    from acl.sweep.perturb import field_value, flatten
    from test_sweep_drives import _rule_verdicts

    d = acl.load(str(EX / "fig2_stroke_truth.acl"))
    names, missing = supported(d, "125 kHz @ 2 V")
    assert "lint_acl105_pass" in names and "tip_deflection_arm_m" in names and "lint_acl105" not in missing
    paths = [k for k in flatten(d) if k.startswith("programs.") and k.endswith("amplitude")]
    assert paths
    scale = np.array([0.2, 0.5, 1.0, 2.0, 4.0, 8.0])
    b = _batch(d, {k: field_value(d, k) * scale for k in paths})
    cols = evaluate(b, ["lint_acl105_pass"])
    seen = set()
    for i in range(b.n):
        ok = _rule_verdicts(materialize(b, i), {"acl105": acoustics.bubble_beyond_linear})["acl105"]
        assert cols["lint_acl105_pass"][i] == ok, i
        seen.add(ok)
    assert seen == {True, False}


ALL_EFFECTS = ("effect bjerknes_scale { factor = 1.4 }\n"
               "effect stiffness_scale { e_scale = 0.8 }\n"
               "effect large_deflection { elastica_weight = 0.5 }\n"
               "effect transducer_gain { gain = 1.2 }\n"
               "effect drive_saturation { v_sat = 20 V }\n")


def test_lint_acl201_acl401_acl402_columns_under_effects_equal_the_rules():
    """Under declared effects the program lint columns come from the batched forces with every effect (lint's own
    beam law: paper Eq. (1) with the declared modulus): the Fig. 4 pair with five effects, beams made softer and
    the gap moved across d_c, each point's verdicts equal the rules on its design, both outcomes of each hit."""
    from acl.lint.rules import beams, forces
    from test_sweep_drives import _rule_verdicts

    d = _design("fig4_facing_pair", ALL_EFFECTS)
    names, missing = supported(d)
    assert {"lint_acl201_pass", "lint_acl401_pass", "lint_acl402_pass"} <= set(names)
    assert "lint_acl105_pass" in names and set(missing) == {"tip_deflection"}      # needs a drive: nothing else
    scale = np.array([1.0, 0.1, 0.01, 0.0033, 1.0, 1.0])
    x = d.capsule("right").center[0] + np.array([0.0, 0.0, 0.0, 0.0, -25e-6, 40e-6])
    ox = d.capsule("right").orifices[0].center[0] + (x - d.capsule("right").center[0])
    fields = {f"beams.{bm.name}.youngs_modulus": bm.youngs_modulus * scale for bm in d.beams}
    fields |= {"capsules.right.center.0": x, "capsules.right.orifices.jet.center.0": ox}
    b = _batch(d, fields)
    cols = evaluate(b, ["lint_acl201_pass", "lint_acl401_pass", "lint_acl402_pass"])
    seen = set()
    for i in range(b.n):
        want = _rule_verdicts(materialize(b, i), {"acl201": forces.snap_in, "acl401": beams.beam_strain,
                                                  "acl402": beams.beam_large_deflection})
        for code, ok in want.items():
            assert cols[f"lint_{code}_pass"][i] == ok, (i, code)
            seen.add((code, ok))
    assert {("acl201", True), ("acl201", False), ("acl402", True), ("acl402", False)} <= seen, seen

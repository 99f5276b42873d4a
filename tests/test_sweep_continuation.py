"""The batched continuation's adaptive step (acl.sweep.mechanism.Mechanism._march) on a long walk.

Fig. 6f (examples/fig6f_control_module.acl): at 125 kHz the arm bends 260 um at 40 V and 1.8 mm by 100 V
without a fold.  Steps predicted along the branch's tangent must land on analyze's branch: the deflections
at 125 kHz @ 40 V equal `acl analyze`'s (pseudo-arclength in 2.5 um steps) to 1e-7 relative, on the
nominal design and two perturbed points.  The walk to 100 V takes at most 120 steps for three points
(2.5 um steps took 1,396 for two: the cost this step control removes).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

import acl
from acl.analysis.report import analyze
from acl.design.drives import drive_from_text
from acl.sweep import mechanism as SM
from acl.sweep.evaluate import evaluate
from acl.sweep.perturb import FieldBatch, materialize

EX = Path(__file__).resolve().parents[1] / "examples" / "fig6f_control_module.acl"


def _batch():
    d = acl.load(str(EX))
    radius = d.capsule("arm_cap").orifices[0].radius
    e = {b.name: b for b in d.beams}["arm"].youngs_modulus
    fields = {"capsules.arm_cap.orifices.jet.radius": np.array([radius, radius + 150e-9, radius - 120e-9]),
              "beams.arm.youngs_modulus": np.array([e, 0.95 * e, 1.04 * e])}
    return FieldBatch(design=d, n=3, fields=fields, valid=np.ones(3, bool), code=np.full(3, ""))


def test_long_walk_lands_on_analyze_branch():
    b = _batch()
    at = "125 kHz @ 40 V"
    cols = evaluate(b, ["tip_deflection_arm_m", "deflection_ctl_m", "equilibrium_ok"], at)
    for i in range(b.n):
        eq = analyze(materialize(b, i), at=drive_from_text(at, "<at>"), snap_in=False).as_dict()["equilibrium"]
        assert eq["status"] == "ok" and bool(cols["equilibrium_ok"][i])
        want = eq["deflections_m"]["arm"]
        assert want > 200e-6                                   # a long walk: 80 maximal steps of 2.5 um
        assert abs(cols["tip_deflection_arm_m"][i] - want) <= 1e-7 * want, (i, cols["tip_deflection_arm_m"][i], want)
        want = eq["deflections_m"]["ctl"]
        assert abs(cols["deflection_ctl_m"][i] - want) <= 1e-7 * abs(want), (i, cols["deflection_ctl_m"][i], want)


def test_walk_to_100_v_takes_few_steps(monkeypatch):
    b = _batch()
    calls = []
    solve = SM.Mechanism.solve

    def counted(self, *a, **k):
        calls.append(self.n)
        return solve(self, *a, **k)

    monkeypatch.setattr(SM.Mechanism, "solve", counted)
    cols = evaluate(b, ["snap_in_arm_cap_partner_125khz_v"], "125 kHz @ 4 V")
    assert np.isnan(cols["snap_in_arm_cap_partner_125khz_v"]).all()          # no fold up to the 100 V transducer
    assert 10 < len(calls) <= 120, len(calls)

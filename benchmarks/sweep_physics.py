"""Throughput of the batched evaluation (acl.sweep.evaluate) per quantity family, on one core.

Evaluates FieldBatches of perturbed points directly (no sampling, no table): what `acl sweep`
spends in physics.  Points are Table S1 design-1 capsules on the 50 um cantilever
(examples/fig2_vertical_cantilever.acl: orifice radius +-150 nm, cavity height +-3 %, E +-5 %), the
Fig. 4 facing pair (examples/fig4_facing_pair.acl: both orifice radii +-150 nm, the left beam's E
+-5 %, the right capsule's x +-1 um) and the Fig. 6 latch (angle +-1 deg, orifice radius +-150 nm).
Prints CPU seconds (process time; the machine is shared) and points per CPU second.

    python benchmarks/sweep_physics.py [--n 100000] [--pair-n 20000] [--latch-n 20000]
"""
from __future__ import annotations

import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sweep_setup import ROOT, field_batch as _batch, options  # noqa: E402

import numpy as np  # noqa: E402


def timed(batch, quantities, at=None):
    from acl.sweep.evaluate import evaluate

    c0 = time.process_time()
    cols = evaluate(batch, quantities, at)
    return cols, time.process_time() - c0


def main(argv=None) -> int:
    args = options(argv, n=100_000, pair_n=20_000, latch_n=20_000)
    import acl
    from acl.sweep.perturb import cavity_volume

    rng = np.random.default_rng(0)
    d = acl.load(os.path.join(ROOT, "examples", "fig2_vertical_cantilever.acl"))
    n = args.n
    h = 33.15e-6 * (1 + 0.03 * rng.standard_normal(n))
    b = _batch(d, {"capsules.act.orifices.jet.radius": 10e-6 + 150e-9 * rng.standard_normal(n),
                   "capsules.act.cavity.height": h,
                   "capsules.act.cavity.volume": cavity_volume("cylinder", radius=25e-6, height=h),
                   "beams.arm.youngs_modulus": 13e6 * (1 + 0.05 * rng.standard_normal(n))})
    timed(_batch(d, {"beams.arm.length": np.full(4, 50e-6)}), None, "125 kHz @ 2 V")        # warm caches
    print(f"cantilever (fig2), {n} points, one core:")
    total = 0.0
    for qs in (["resonance_act_1_hz", "q_act_1"], ["tip_deflection_arm_m"], ["require_1_pass"],
               ["lint_acl105_pass"]):
        _, t = timed(b, qs, "125 kHz @ 2 V")
        total += t if qs[0] != "lint_acl105_pass" else 0.0
        print(f"  {', '.join(qs):40s} {t:7.3f} s CPU  {n / t:12.4g} points/s")
    _, t = timed(b, ["resonance_act_1_hz", "q_act_1", "tip_deflection_arm_m", "require_1_pass"], "125 kHz @ 2 V")
    print(f"  {'resonance + Q + deflection + require':40s} {t:7.3f} s CPU  {n / t:12.4g} points/s"
          f"  -> 1e6 points: {1e6 / (n / t):.2f} s")

    d = acl.load(os.path.join(ROOT, "examples", "fig4_facing_pair.acl"))
    n = args.pair_n
    x = d.capsule("right").center[0] + 1e-6 * rng.standard_normal(n)
    ox = d.capsule("right").orifices[0].center[0] + (x - d.capsule("right").center[0])
    b = _batch(d, {"capsules.left.orifices.jet.radius": 10e-6 + 150e-9 * rng.standard_normal(n),
                   "capsules.right.orifices.jet.radius": 10e-6 + 150e-9 * rng.standard_normal(n),
                   "beams.left_arm.youngs_modulus": 13e6 * (1 + 0.05 * rng.standard_normal(n)),
                   "capsules.right.center.0": x, "capsules.right.orifices.jet.center.0": ox})
    print(f"facing pair (fig4), {n} points, one core:")
    for qs in (["resonance_left_1_hz", "resonance_right_1_hz"],
               ["force_left_right_125khz_n", "critical_distance_left_right_125khz_m", "phase_left_right_125khz_deg"],
               ["snap_in_left_right_125khz_v"], ["tip_deflection_left_arm_m", "tip_deflection_right_arm_m"]):
        cols, t = timed(b, qs, "125 kHz @ 3 V")
        extra = ""
        if qs[0].startswith("snap"):
            extra = f"  -> 1e5 points: {1e5 / (n / t):.1f} s ({np.isnan(cols[qs[0]]).mean():.1%} without snap-in)"
        print(f"  {', '.join(qs)[:40]:40s} {t:7.3f} s CPU  {n / t:12.4g} points/s{extra}")

    d = acl.load(os.path.join(ROOT, "examples", "fig6_bistable_latch.acl"))
    n = args.latch_n
    b = _batch(d, {"latches.snap.angle": np.deg2rad(45 + rng.standard_normal(n)),
                   "capsules.act.orifices.jet.radius": 10e-6 + 150e-9 * rng.standard_normal(n)})
    print(f"bistable latch (fig6), {n} points, one core:")
    for qs in (["switching_force_snap_n"], ["margin_snap_switch_1", "require_1_pass"]):
        _, t = timed(b, qs)
        print(f"  {', '.join(qs):40s} {t:7.3f} s CPU  {n / t:12.4g} points/s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

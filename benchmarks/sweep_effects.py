"""Sweep of a calibrated design against a loop of `acl analyze` (issue 23), on one core.

* The calibrated Fig. 4 pair (examples/fig4_facing_pair.acl: stdlib calibrations' ``bjerknes_scale`` with its
  gap shape) with a fitted ``stiffness_scale`` added (as `acl fit --calibrated` writes it): forces at rest,
  d_c, snap-in and both tip deflections at 125 kHz @ 2 V, over points with the gap, both orifice radii
  (+-150 nm) and the left beam's E (+-5 %) perturbed.
* The Fig. 6f control module (examples/fig6f_control_module.acl: a latch carrying one capsule, a capsule on a
  beam, a fixed partner): every column the sweep offers at 125 kHz @ 4 V.

Each is timed as the batched evaluation (acl.sweep.evaluate) and as a loop of ``acl.analysis.report.analyze``
over the same materialised points (a subset; its rate is per point).  Prints CPU seconds (process time; the
machine is shared), points per CPU second and the ratio.

    python benchmarks/sweep_effects.py [--n 2000] [--loop 20] [--latch-n 200]
"""
from __future__ import annotations

import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from sweep_setup import ROOT, field_batch as _batch, options  # noqa: E402

import numpy as np  # noqa: E402


def _compare(label, batch, quantities, at, loop_n):
    from acl.analysis.report import analyze
    from acl.design.drives import drive_from_text
    from acl.sweep.evaluate import evaluate
    from acl.sweep.perturb import materialize

    evaluate(_batch(batch.design, {k: v[:2] for k, v in batch.fields.items()}), quantities, at)     # warm caches
    c0 = time.process_time()
    evaluate(batch, quantities, at)
    t_sweep = time.process_time() - c0
    drive = drive_from_text(at, "<at>")
    c0 = time.process_time()
    for i in range(loop_n):
        analyze(materialize(batch, i), drive, snap_in=True)
    t_loop = (time.process_time() - c0) / loop_n
    rate = batch.n / t_sweep
    print(f"{label}: sweep {batch.n} points {t_sweep:7.3f} s CPU ({rate:10.4g} points/s); "
          f"loop of analyze {1 / t_loop:8.4g} points/s ({loop_n} points); sweep / loop {rate * t_loop:7.1f}x")


def main(argv=None) -> int:
    args = options(argv, n=2000, loop=20, latch_n=200)
    from acl.design.resolve import load_design
    from acl.sweep.perturb import flatten

    rng = np.random.default_rng(0)
    path = os.path.join(ROOT, "examples", "fig4_facing_pair.acl")
    src = open(path).read() + "\neffect stiffness_scale { e_scale = 0.9 }  # as `acl fit --calibrated` writes it\n"
    tmp = os.path.join(os.path.dirname(path), ".bench_calibrated_pair.acl")
    with open(tmp, "w") as fh:
        fh.write(src)
    try:
        d = load_design(tmp)
    finally:
        os.unlink(tmp)
    n = args.n
    flat = flatten(d)
    dx = 1e-6 * rng.standard_normal(n)
    fields = {"capsules.left.orifices.jet.radius": flat["capsules.left.orifices.jet.radius"] + 150e-9 * rng.standard_normal(n),
              "capsules.right.orifices.jet.radius": flat["capsules.right.orifices.jet.radius"] + 150e-9 * rng.standard_normal(n),
              "beams.left_arm.youngs_modulus": flat["beams.left_arm.youngs_modulus"] * (1 + 0.05 * rng.standard_normal(n)),
              "capsules.right.center.0": flat["capsules.right.center.0"] + dx,
              "capsules.right.orifices.jet.center.0": flat["capsules.right.orifices.jet.center.0"] + dx}
    qs = ["force_left_right_125khz_n", "critical_distance_left_right_125khz_m", "snap_in_left_right_125khz_v",
          "tip_deflection_left_arm_m", "tip_deflection_right_arm_m"]
    _compare("calibrated Fig. 4 pair (bjerknes_scale + stiffness_scale)", _batch(d, fields), qs, "125 kHz @ 2 V",
             args.loop)

    d = load_design(os.path.join(ROOT, "examples", "fig6f_control_module.acl"))
    flat = flatten(d)
    n = args.latch_n
    fields = {"capsules.arm_cap.orifices.jet.radius": flat["capsules.arm_cap.orifices.jet.radius"] + 150e-9 * rng.standard_normal(n),
              "beams.arm.youngs_modulus": flat["beams.arm.youngs_modulus"] * (1 + 0.05 * rng.standard_normal(n))}
    _compare("Fig. 6f control module (every column)", _batch(d, fields), None, "125 kHz @ 4 V", min(args.loop, n))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

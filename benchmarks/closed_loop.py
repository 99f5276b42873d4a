"""Closed loop over seeded truths (issue 9, done-when bullet 2): prints the figures docs/fit.md quotes.

    python benchmarks/closed_loop.py [--seeds 20] [--band-samples 20]

Each seed draws a truth from examples/fig2_stroke.acl (acl.fit.loop.seeded_truth: a per-tone gain
tilt so the 110 and 140 kHz tones differ by up to 30 %, a level 0.85-1.15 and an undeclared drive
saturation V_s 5-10 V), then runs compile -> play (noise 0.05 um) -> fit -> recompile -> play.
Reported per seed: tracking error before / after calibration / floor (compiled on the truth), the
calibrated compile's predicted error and 95 % band, and whether the band covers the re-simulated error.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import numpy as np  # noqa: E402

from acl.fit.loop import run_loop, seeded_truth  # noqa: E402

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--band-samples", type=int, default=20)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in ("fig2_vertical_cantilever.acl", "fig2_stroke.acl"):
            shutil.copy(os.path.join(HERE, name), tmp)
        for seed in range(args.seeds):
            rng = np.random.default_rng(1000 + seed)
            truth = os.path.join(tmp, f"truth{seed}.acl")
            with open(truth, "w") as fh:
                fh.write(seeded_truth("", rng, "fig2_stroke.acl"))
            work = os.path.join(tmp, f"w{seed}")
            os.makedirs(work)
            t0 = time.perf_counter()
            r = run_loop(os.path.join(tmp, "fig2_stroke.acl"), truth, "stroke", work, seed=seed,
                         band_samples=args.band_samples)
            rows.append(r)
            print(f"seed {seed:2d}: before {r.before_rms_m * 1e6:.3f} um, after {r.after_rms_m * 1e6:.3f} um, "
                  f"floor {r.floor_rms_m * 1e6:.3f} um, after/floor {r.after_rms_m / r.floor_rms_m:.2f}; "
                  f"predicted {r.predicted_rms_m * 1e6:.3f}, band p95 {r.band_rms_p95_m * 1e6:.3f} / "
                  f"max {r.band_max_p95_m * 1e6:.3f} um (after max {r.after_max_m * 1e6:.3f}); "
                  f"covered {r.covered}; effects {r.effects}; {time.perf_counter() - t0:.0f} s", flush=True)
    ratio = np.array([r.after_rms_m / r.floor_rms_m for r in rows])
    cover = np.mean([r.covered for r in rows])
    print(f"{len(rows)} truths: before {np.median([r.before_rms_m for r in rows]) * 1e6:.3f} um RMS (median), "
          f"after {np.median([r.after_rms_m for r in rows]) * 1e6:.3f} um, floor "
          f"{np.median([r.floor_rms_m for r in rows]) * 1e6:.3f} um; after/floor max {ratio.max():.2f} "
          f"(<= 3 in {np.mean(ratio <= 3) * 100:.0f} %); band covers the re-simulated error in {cover * 100:.0f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())

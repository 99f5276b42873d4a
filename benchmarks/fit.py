"""Benchmark: `acl fit` of a ~1,000-row synthetic data set with the whole effect library (target < 30 s).

Data: the Fig. 2 cantilever (tests/data/fit_cantilever.acl) with three beam lengths x three pedestal
heights x three frequencies x 11 voltages, repeated 4 times over time (1,188 rows), drive saturation
planted, noise 0.2 um.  Prints the row count, the time of each stage and the effects selected.
Run: python benchmarks/fit.py
"""
from __future__ import annotations

import os
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DESIGN = os.path.join(HERE, "..", "tests", "data", "fit_cantilever.acl")


def main() -> int:
    from acl.fit import run_fit
    from acl.fit.synth import Experiment, generate, write_csv

    ex = Experiment(frequencies=(110e3, 125e3, 140e3), voltages=tuple(np.linspace(0, 10, 11)),
                    sets={"length": ["40 um", "50 um", "60 um"], "pedestal": ["0 um", "30 um", "60 um"]},
                    repeats=4, interval=0.5)
    t0 = time.perf_counter()
    data, _ = generate(DESIGN, ex, {"drive_saturation": {"v_sat": 7.0}}, noise=0.2e-6, seed=7)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "bench.csv")
        write_csv(data, path)
        t1 = time.perf_counter()
        out = run_fit(DESIGN, [path], free=["gamma"])
        t2 = time.perf_counter()
    r = out.report
    print(f"rows: {r['rows']}")
    print(f"synthesize: {t1 - t0:.2f} s")
    print(f"fit (base + {len(r['effects_tried'])} effect trials, CV, residual tests): {t2 - t1:.2f} s")
    print(f"effects selected: {r['effects_selected']}; rmse {r['rmse_before'] * 1e6:.3f} um -> "
          f"{r['rmse_after'] * 1e6:.3f} um (noise 0.2 um)")
    return 0 if t2 - t1 < 30 else 1


if __name__ == "__main__":
    sys.exit(main())

"""Benchmark: recovery of fitted coefficients on synthetic truths, for the mechanisms of issue 9 item 1.

Each case draws ``--seeds`` data sets from a truth whose coefficients differ from the design's (the fit's
start), noise 0.1 um, fits them (effect search on or off) and prints, per coefficient, how often the 95 %
interval covered the truth, the median |fitted/truth - 1|, the effects claimed and the time per fit.

1. planar: Fig. 3 three-orifice capsule (examples/fig3_three_orifice.acl), x and y at 5 frequencies, 0-6 V,
   gamma 0.8x; clean (search on: nothing may be claimed) and with drive saturation V_s = 4 V planted.
2. trussed latch body: Fig. 6e (examples/fig6e_reversible_latch.acl), shuttle at 85 / 170 kHz, 0-90 V, gamma 1.2x.
3. group: three capsules in a row + calibration cantilever (samples/fit_group3.acl), ramps through the a-b
   snap-in (0-6 V), gamma 1.2x, alpha 0.7x.
   group-large: the same at 5 frequencies, 13 voltages, twice, and the calibration beam 4 times (570 rows).
4. latch state: samples/fit_latch_state.acl, 10 ramps at each of 17 voltages, spread 0.08, gamma 1.25x,
   gamma and spread free.
Run: python benchmarks/fit_mechanisms.py [--seeds N] [--cases planar,truss,group,state]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..")
sys.path.insert(0, ROOT)


def cases():
    from acl.fit.synth import Experiment

    ex3 = Experiment(frequencies=(80e3, 100e3, 125e3, 150e3, 170e3), voltages=tuple(np.linspace(0, 6, 7)))
    group = [Experiment(frequencies=(115e3, 125e3, 135e3), voltages=tuple(np.linspace(0, 6, 7)),
                        observables=("d_ab", "d_bc", "tip_c"), label="group"),
             Experiment(frequencies=(115e3, 125e3, 135e3), voltages=tuple(np.linspace(0, 8, 9)),
                        observables=("bend",), label="calibration")]
    return {
        "planar": ("examples/fig3_three_orifice.acl", ex3, {"gamma": 0.8}, ["gamma"], {}, True),
        "planar+saturation": ("examples/fig3_three_orifice.acl", ex3, {"gamma": 0.8}, ["gamma"],
                              {"drive_saturation": {"v_sat": 4.0}}, True),
        "truss": ("examples/fig6e_reversible_latch.acl",
                  Experiment(frequencies=(85e3, 170e3), voltages=tuple(np.linspace(0, 90, 19))),
                  {"gamma": 1.2}, ["gamma"], {}, False),
        "group": ("samples/fit_group3.acl", group, {"gamma": 1.2, "alpha": 0.7}, ["gamma", "alpha"], {}, False),
        "group-large": ("samples/fit_group3.acl",
                        [Experiment(frequencies=(110e3, 120e3, 125e3, 130e3, 140e3), voltages=tuple(np.linspace(0, 6, 13)),
                                    observables=("d_ab", "d_bc", "tip_c"), repeats=2, label="group"),
                         Experiment(frequencies=(110e3, 120e3, 125e3, 130e3, 140e3), voltages=tuple(np.linspace(0, 8, 9)),
                                    observables=("bend",), repeats=4, label="calibration")],
                        {"gamma": 1.2, "alpha": 0.7}, ["gamma", "alpha"], {}, False),
        "state": ("samples/fit_latch_state.acl",
                  Experiment(frequencies=(125e3,), voltages=tuple(np.linspace(30, 46, 17)), repeats=10,
                             observables=("switched",)),
                  {"gamma": 1.25, "spread": 0.08}, ["gamma", "spread"], {}, False),
    }


def run(name, spec, seeds, tmp):
    from acl.fit.problem import load_problem
    from acl.fit.select import select_effects
    from acl.fit.synth import generate, write_csv

    design, ex, factors, free, effects, search = spec
    design = os.path.join(ROOT, design)
    _, P0 = generate(design, ex)
    truth = {k: (f * getattr(P0, k + "0") if k in ("gamma", "alpha") else f) for k, f in factors.items()}
    cover = {k: 0 for k in truth}
    errors = {k: [] for k in truth}
    claims, times = [], []
    for seed in range(seeds):
        data, _ = generate(design, ex, effects, noise=0.1e-6, seed=seed, coeffs=truth)
        path = os.path.join(tmp, f"{name}.csv")
        write_csv(data, path)
        t0 = time.process_time()
        sel = select_effects(load_problem(design, [path], free=free), candidates=None if search else [], seed=seed)
        times.append(time.process_time() - t0)
        f = sel.final
        for k, c in enumerate(f.coefs):
            if c.name in truth:
                lo, hi = f.ci[k]
                cover[c.name] += bool(lo <= truth[c.name] <= hi)
                errors[c.name].append(abs(f.values[k] / truth[c.name] - 1))
        claims.append("+".join(sel.selected) or "none")
    n = data.n
    parts = [f"{k}: covered {cover[k]}/{seeds}, median |err| {np.median(errors[k]):.2%}" for k in truth]
    print(f"{name:18s} {n:4d} rows  {'; '.join(parts)};  claimed {', '.join(f'{c} x{claims.count(c)}' for c in sorted(set(claims)))}; "
          f"{np.median(times):.1f} s CPU/fit", flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--cases", default=",".join(cases()))
    args = ap.parse_args()
    all_cases = cases()
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.cases.split(","):
            run(name, all_cases[name], args.seeds, tmp)


if __name__ == "__main__":
    main()

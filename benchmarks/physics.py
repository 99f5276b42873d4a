"""Benchmark of the physics (issue 3): resonance evaluations per second over 10^6 single-orifice
designs with the full Rayleigh-Ritz model (the paper's Fig. 1e surface), and the time of
`acl analyze` on each example (in process, after start-up; with and without the snap-in sweeps).

    python benchmarks/physics.py [--n 1000] [--examples examples/] [--skip-examples]

Figures are printed; targets: >= 5e5 designs/s.  Times depend on the machine's load: the load
average is printed beside them.
"""
from __future__ import annotations

import argparse
import glob
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.dirname(__file__))

TARGET = 5e5


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000, help="grid points per axis (n^2 designs)")
    ap.add_argument("--examples", default=os.path.join(os.path.dirname(__file__), "..", "examples"))
    ap.add_argument("--skip-examples", action="store_true")
    args = ap.parse_args(argv)

    from physics_resonance import sweep
    from acl.physics.constants import DEFAULT_MEMBRANE_MODES

    print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}")
    sweep(50, DEFAULT_MEMBRANE_MODES)                       # warm caches
    best = float("inf")
    for _ in range(3):
        t = time.perf_counter()
        _, _, f = sweep(args.n, DEFAULT_MEMBRANE_MODES)
        best = min(best, time.perf_counter() - t)
    rate = args.n ** 2 / best
    print(f"resonance sweep: {args.n ** 2:,} designs ({DEFAULT_MEMBRANE_MODES} membrane shapes each) in "
          f"{best:.3f} s = {rate:,.0f} designs/s -> {'ok' if rate >= TARGET else 'BELOW'} target {TARGET:,.0f}")
    if args.skip_examples:
        return 0

    import acl
    from acl.analysis.report import analyze

    print("\nacl analyze per example (in process; snap-in sweeps on / off):")
    for path in sorted(glob.glob(os.path.join(args.examples, "*.acl"))):
        design = acl.load(path)
        t = time.perf_counter()
        analyze(design, snap_in=False)
        quick = time.perf_counter() - t
        t = time.perf_counter()
        rep = analyze(design)
        full = time.perf_counter() - t
        print(f"  {os.path.basename(path):34s} {full:6.2f} s / {quick:5.2f} s   "
              f"({len(design.capsules)} capsules, {len(rep.frequencies_hz)} program frequencies)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Benchmark: first natural frequency of 10^6 single-orifice capsules (the paper's Fig. 1e surface).

Full Rayleigh-Ritz model (acl.physics.resonance.single_orifice_frequencies, default number of
membrane shapes): the shape integrals are exact and precomputed once, the per-design matrices are
stacked and solved with one batched numpy ``eigvalsh``.  Prints designs per second; with
``--plot DIR`` also writes DIR/fig1e_surface.png.

    python benchmarks/physics_resonance.py [--n 1000] [--repeat 3] [--plot out/]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from acl.physics.constants import DEFAULT_MEMBRANE_MODES, WATER_20C as W  # noqa: E402
from acl.physics.resonance import single_orifice_frequencies  # noqa: E402


def sweep(n: int, n_modes: int):
    volume = np.linspace(2e4, 2e5, n) * 1e-18          # m^3 (Fig. 1e range, um^3 2e4..2e5)
    radius = np.linspace(5.0, 20.0, n) * 1e-6          # m
    vv, rr = np.meshgrid(volume, radius, indexing="ij")
    f = single_orifice_frequencies(vv, rr, W.density, W.surface_tension, W.ambient_pressure,
                                   W.polytropic_index, n_modes=n_modes)
    return vv, rr, f


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000, help="grid points per axis (n^2 designs)")
    ap.add_argument("--modes", type=int, default=DEFAULT_MEMBRANE_MODES, help="membrane shapes per interface")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--plot", metavar="DIR", help="write the Fig. 1e surface as DIR/fig1e_surface.png")
    args = ap.parse_args(argv)

    sweep(10, args.modes)                                 # warm-up (cached shape matrices)
    best = float("inf")
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        vv, rr, f = sweep(args.n, args.modes)
        best = min(best, time.perf_counter() - t0)
    n = vv.size
    print(f"designs: {n:,}  membrane shapes: {args.modes}  best of {args.repeat}: {best:.3f} s")
    print(f"resonance evaluations per second: {n / best:,.0f}")
    print(f"frequency range over the grid: {f.min() / 1e3:.1f} .. {f.max() / 1e3:.1f} kHz")

    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        os.makedirs(args.plot, exist_ok=True)
        fig = plt.figure(figsize=(6, 4.5))
        ax = fig.add_subplot(projection="3d")
        step = max(1, args.n // 100)
        ax.plot_surface(rr[::step, ::step] * 1e6, vv[::step, ::step] * 1e18 / 1e5,
                        f[::step, ::step] / 1e3, cmap="viridis", linewidth=0)
        ax.set_xlabel("orifice radius R (um)")
        ax.set_ylabel("bubble volume (1e5 um^3)")
        ax.set_zlabel("first natural frequency (kHz)")
        path = os.path.join(args.plot, "fig1e_surface.png")
        fig.savefig(path, dpi=120, bbox_inches="tight")
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

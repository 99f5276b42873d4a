"""Mechanics figures: accuracy against the paper and speed of each model.  Run: python benchmarks/physics_mechanics.py"""
from __future__ import annotations

import time

import numpy as np


def _timed(fn, repeat=3):
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return out, best


def main() -> None:
    from acl.physics import beams, equilibrium, latch

    L, l, EI = 50e-6, 25e-6, 13e6 * np.pi * (2e-6) ** 4 / 64
    P = np.linspace(0, 2e-8, 1_000_000)
    _, t = _timed(lambda: beams.eq1_deflection(P, L, l, EI))
    print(f"Eq. (1) deflection      : {P.size / t / 1e6:8.1f} M loads/s")
    d = beams.eq1_deflection(P[1:1001], L, l, EI)
    _, t = _timed(lambda: beams.eq1_force(d, L, l, EI))
    print(f"Eq. (1) inverse (Newton): {d.size / t / 1e6:8.2f} M deflections/s")
    sol, t = _timed(lambda: beams.elastica(EI / L**2, L, 0.0, EI), repeat=2)
    print(f"elastica p=1, l=0       : delta/L = {sol.deflection[0] / L:.5f} (classical 0.3017), {t * 1e3:.0f} ms")
    for lam in (0.0, 0.25, 0.5):
        print(f"Eq. (1) 5% limit, l={lam:.2f}L: {beams.eq1_validity_limit(1.0, lam):.3f} L")

    target = {30: 32.53, 45: 40.5, 60: 47.76}
    for a, ref in target.items():
        land, t = _timed(lambda: latch.latch_landscape(np.radians(a), 50e-6, 1e-6, 1.7e-6, 13e6))
        print(f"latch {a} deg: switching {land.switching_force * 1e9:6.2f} nN (Table S2 sim {ref}: "
              f"{land.switching_force * 1e9 / ref - 1:+.1%}), release {land.release_force * 1e9:6.2f} nN, "
              f"barrier {land.barrier * 1e12:.3f} pJ, state b {land.state_b * 1e6:.1f} um, {t * 1e3:.0f} ms")

    k, alpha, d0 = 0.7563e-3, 1.745e-19, 30e-6
    branch, t = _timed(lambda: equilibrium.continuation(
        lambda q: (k * q, np.array([[k]])), lambda q, V: np.array([alpha * V**2 / (d0 - q[0]) ** 2]),
        [0.0], 20.0, admissible=lambda q: d0 - q[0] > 0))
    gap = (d0 - branch.snap.q[0]) / d0
    print(f"1-DOF snap-in: gap/d0 = {gap:.9f} (2/3), {branch.voltage.size} points, {t * 1e3:.0f} ms")

    from acl.analysis import mechanics as M
    import importlib.util
    import pathlib
    import sys

    path = pathlib.Path(__file__).resolve().parents[1] / "tests" / "test_analysis_mechanics.py"
    spec = importlib.util.spec_from_file_location("_mech_tests", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules["_mech_tests"] = mod
    spec.loader.exec_module(mod)
    for g in (20, 30, 40, 50):
        sweep, t = _timed(lambda: M.sweep_voltage(mod.fig2_pair(g * 1e-6), mod.UNIT_DRIVE, 20.0, mod.EQ3), repeat=1)
        ref, _ = mod.independent_snap_voltage(g * 1e-6)
        print(f"Fig. 2 pair, gap {g} um: snap-in {sweep.snap_voltage:.4f} V (1-D check {ref:.4f} V), "
              f"{sweep.voltage.size} points, {t * 1e3:.0f} ms")


if __name__ == "__main__":
    main()

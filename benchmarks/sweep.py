"""Benchmark of issue 13's done-when figures: Monte Carlo sweeps on one core, and a 2-worker cluster.

1. 1,000,000 print-tolerance samples of a Table S1 capsule (design 1) on the 50 um cantilever
   (benchmarks/designs/sweep_cantilever.acl): resonance, Q, tip deflection at 125 kHz @ 2 V and
   the require's pass/fail. Target: under 5 s on one core.
2. 100,000 samples of the Fig. 4 facing pair (examples/fig4_facing_pair.acl) with the snap-in
   voltage at 125 kHz, the gap and the thrust coefficient spread. Target: under 20 s on one core.
4. 5,000 samples of the Fig. 4 pair with spread drive voltages, step limit, amplifier maximum and
   transducer gain (samples/sweep_drives.acl): the per-point drive and transducer checks alone
   (acl.sweep.validity.check_drives; at 286b796 each unique value was re-resolved: 5.13 s CPU for
   these 5,000 points), then the whole sweep with forces, snap-in and `require gap` at each point's
   drive (at 286b796 those columns were left out).
5. 100,000 samples of the Fig. 5c spring actuator (benchmarks/designs/sweep_spring.acl: gap +-1 um,
   stiffness +-10 %): snap-in voltage at 125 kHz, the flexure's extension at 125 kHz @ 10 V and
   `require gap` at the 14 V hold (acl.sweep.mechanism: the branch as the curve V^2(z) of the one
   coordinate; before, these columns were left out).
6. 5,000 samples of the Fig. 6e latch (benchmarks/designs/sweep_latch.acl: angle +-1 deg, width
   +-50 nm, thickness +-5 %): the switching voltage (snap-in of the pair on the shuttle at 85 kHz, by
   continuation across the latch's buckling kink) and the margin require at 32 V.
3. The same sweep (1.) on a dask LocalCluster of 2 worker processes and in one process: the tables
   must be equal bit for bit (acl.sweep.run.map_chunks; needs the acl[scale] extra).

"One core": the process is pinned to one CPU (os.sched_setaffinity) and the BLAS threads to one,
so the local scheduler runs the chunks one after another in this process. Prints wall time and
the process's CPU time (on a shared machine the CPU time is the steadier figure).

    python benchmarks/sweep.py [--samples 1000000] [--pair-samples 100000] [--cluster-samples 200000]
                               [--drive-samples 5000] [--spring-samples 100000] [--latch-samples 5000]
                               [--skip-cluster]
"""
from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, ROOT)

CANTILEVER = os.path.join(ROOT, "benchmarks", "designs", "sweep_cantilever.acl")
PAIR = os.path.join(ROOT, "examples", "fig4_facing_pair.acl")
CANTILEVER_Q = ["resonance_act_1_hz", "q_act_1", "tip_deflection_arm_m", "requires_pass"]
CANTILEVER_AT = "125 kHz @ 2 V"
PAIR_Q = ["snap_in_left_right_125khz_v", "requires_pass"]
PAIR_TOL = ["gap=normal(0, 1 um)", "gamma=10 %"]
DRIVES = os.path.join(ROOT, "samples", "sweep_drives.acl")
SPRING = os.path.join(ROOT, "benchmarks", "designs", "sweep_spring.acl")
SPRING_Q = ["snap_in_top_bottom_125khz_v", "deflection_flexure_m", "require_1_value", "requires_pass"]
SPRING_AT = "125 kHz @ 10 V"
LATCH = os.path.join(ROOT, "benchmarks", "designs", "sweep_latch.acl")
LATCH_Q = ["snap_in_forward_backward_85khz_v", "switching_force_l_n", "require_1_value", "requires_pass"]
DRIVES_Q = ["force_left_right_125khz_n", "snap_in_left_right_125khz_v", "require_2_value", "requires_pass"]


def one_core() -> str:
    """Pin this process to one CPU; returns what was done."""
    try:
        cpu = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpu})
        return f"pinned to CPU {cpu}"
    except (AttributeError, OSError):
        return "not pinned (no sched_setaffinity); the local scheduler may use threads"


def timed(fn):
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w0, time.process_time() - c0


def run(path, n, seed, quantities, at=None, tolerance=None, scheduler=None):
    from acl.sweep.driver import sweep

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sweep(path, tolerance=tolerance, n=n, seed=seed, quantities=quantities, at=at, scheduler=scheduler)


def same_bits(a, b) -> bool:
    """Two structured tables equal bit for bit (NaN included): same fields, dtypes and bytes."""
    return a.dtype == b.dtype and a.shape == b.shape and all(
        np.asarray(a[f]).tobytes() == np.asarray(b[f]).tobytes() for f in a.dtype.names)


def drives(n: int, seed: int) -> None:
    """Case 4: spreads on the drive and the transducer (module docstring)."""
    import acl
    from acl.sweep.perturb import field_batch, field_map
    from acl.sweep.sample import chunk_points
    from acl.sweep.spec import build_spec

    d = acl.load(DRIVES)
    spec = build_spec(d, samples=n, seed=seed)
    fmap = field_map(d, spec.names, spec.box())
    pts = chunk_points(spec, 0, spec.chunk_size)
    b, wall, cpu = timed(lambda: field_batch(d, pts, fmap))
    print(f"4. drive/transducer spreads (Fig. 4 pair), {n:,} samples: checks {wall:.3f} s wall, {cpu:.3f} s CPU "
          f"(286b796 re-resolved each unique value: 5.13 s CPU); {int((~b.valid).sum())} invalid "
          f"({', '.join(f'{c} {k}' for c, k in zip(*np.unique(b.code[~b.valid], return_counts=True)))})")
    run(DRIVES, 100, seed, DRIVES_Q)
    t, wall, cpu = timed(lambda: run(DRIVES, n, seed, DRIVES_Q))
    v = t["snap_in_left_right_125khz_v"]
    print(f"   with forces, snap-in and require gap at each point's drive: {wall:.2f} s wall, {cpu:.2f} s CPU; "
          f"snap-in {np.nanmedian(v):.3f} V median, {np.isnan(v[t['valid']]).sum()} valid points "
          f"without snap-in (a low gain: the declared thrust wins); {t.summary_line()}")


def mechanisms(n_spring: int, n_latch: int, seed: int) -> None:
    """Cases 5 and 6: the general batched mechanism (springs, latches) in a Monte Carlo."""
    run(SPRING, 1000, seed, SPRING_Q, SPRING_AT)
    t, wall, cpu = timed(lambda: run(SPRING, n_spring, seed, SPRING_Q, SPRING_AT))
    v = t["snap_in_top_bottom_125khz_v"]
    x = t["deflection_flexure_m"]
    print(f"5. Fig. 5c spring actuator, {n_spring:,} samples: {wall:.2f} s wall, {cpu:.2f} s CPU; "
          f"{n_spring / cpu:,.0f} points per CPU second")
    print(f"   snap-in {np.nanmedian(v):.3f} V median, [{np.nanpercentile(v, 5):.3f}, {np.nanpercentile(v, 95):.3f}] V "
          f"5-95 %; extension at {SPRING_AT} {np.nanmean(x) * 1e6:.3f} +- {np.nanstd(x) * 1e6:.3f} um; "
          f"{t.summary_line()}")
    run(LATCH, 200, seed, LATCH_Q)
    t, wall, cpu = timed(lambda: run(LATCH, n_latch, seed, LATCH_Q))
    v = t["snap_in_forward_backward_85khz_v"]
    print(f"6. Fig. 6e latch switching voltage, {n_latch:,} samples: {wall:.2f} s wall, {cpu:.2f} s CPU; "
          f"{n_latch / cpu:,.0f} points per CPU second")
    print(f"   switching voltage {np.nanmedian(v):.2f} V median, [{np.nanpercentile(v, 5):.2f}, "
          f"{np.nanpercentile(v, 95):.2f}] V 5-95 %, {np.isnan(v).sum()} without a switch below 100 V; {t.summary_line()}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1_000_000)
    ap.add_argument("--pair-samples", type=int, default=100_000)
    ap.add_argument("--cluster-samples", type=int, default=200_000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--drive-samples", type=int, default=5000)
    ap.add_argument("--spring-samples", type=int, default=100_000)
    ap.add_argument("--latch-samples", type=int, default=5_000)
    ap.add_argument("--skip-cluster", action="store_true")
    args = ap.parse_args(argv)
    import acl  # noqa: F401  (import time is not part of a sweep)
    from acl.sweep.run import local_workers

    print(f"one core: {one_core()}; local scheduler threads for 16 chunks: {local_workers(16)}")
    run(CANTILEVER, 1000, args.seed, CANTILEVER_Q, CANTILEVER_AT)          # warm-up (imports, caches)
    t, wall, cpu = timed(lambda: run(CANTILEVER, args.samples, args.seed, CANTILEVER_Q, CANTILEVER_AT))
    f = t["resonance_act_1_hz"]
    print(f"1. cantilever + Table S1 capsule, {args.samples:,} samples: {wall:.2f} s wall, {cpu:.2f} s CPU "
          f"(target < 5 s); {args.samples / wall:,.0f} points/s")
    print(f"   resonance {np.nanmean(f) / 1e3:.2f} +- {np.nanstd(f) / 1e3:.2f} kHz, Q {np.nanmean(t['q_act_1']):.2f}, "
          f"tip deflection {np.nanmean(t['tip_deflection_arm_m']) * 1e6:.3f} um at {CANTILEVER_AT}; {t.summary_line()}")
    run(PAIR, 1000, args.seed, PAIR_Q, tolerance=PAIR_TOL)
    p, wall, cpu = timed(lambda: run(PAIR, args.pair_samples, args.seed, PAIR_Q, tolerance=PAIR_TOL))
    v = p["snap_in_left_right_125khz_v"]
    print(f"2. Fig. 4 pair snap-in, {args.pair_samples:,} samples: {wall:.2f} s wall, {cpu:.2f} s CPU (target < 20 s)")
    print(f"   snap-in {np.nanmedian(v):.3f} V median, [{np.nanpercentile(v, 5):.3f}, {np.nanpercentile(v, 95):.3f}] V "
          f"5-95 %, {np.isnan(v).sum()} without snap-in; {p.summary_line()}")
    drives(args.drive_samples, args.seed)
    mechanisms(args.spring_samples, args.latch_samples, args.seed)
    if args.skip_cluster:
        return 0
    try:
        from distributed import LocalCluster
    except ImportError:
        print("3. cluster: skipped, dask.distributed is not installed (pip install 'acl[scale]')")
        return 0
    single = run(CANTILEVER, args.cluster_samples, args.seed, CANTILEVER_Q, CANTILEVER_AT)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        c, wall, _ = timed(lambda: run(CANTILEVER, args.cluster_samples, args.seed, CANTILEVER_Q, CANTILEVER_AT,
                                       scheduler=cluster.scheduler_address))
    equal = same_bits(single.data, c.data)
    print(f"3. 2-worker LocalCluster, {args.cluster_samples:,} samples ({single.spec.n_chunks} chunks): {wall:.2f} s; "
          f"equal to the single-process table bit for bit: {equal}")
    return 0 if equal else 1


if __name__ == "__main__":
    sys.exit(main())

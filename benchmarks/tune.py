"""Benchmark of `acl tune` on the Fig. 3 robust-radii example (docs/tune.md) on each scheduler.

Runs the same tune (examples/fig3_robust_radii.acl, --samples/--validate 1000, Nelder-Mead, 86-ish
trials) in one process with one thread, on local threads (one per usable core), and on a dask
LocalCluster of 2 worker processes, and checks that the three results are equal bit for bit
(chosen values, every trial of the search, the yields). Prints wall and CPU time of each.

    python benchmarks/tune.py [--samples 1000] [--max-evals 200] [--method nelder-mead] [--skip-cluster]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, ROOT)

FIG3 = os.path.join(ROOT, "examples", "fig3_robust_radii.acl")


def timed(fn):
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w0, time.process_time() - c0


def same(a, b) -> bool:
    return (a.chosen.tobytes() == b.chosen.tobytes() and a.after == b.after and a.before == b.before
            and len(a.search.history) == len(b.search.history)
            and all(x.tobytes() == y.tobytes() and s == t for (x, s, _), (y, t, _) in zip(a.search.history, b.search.history)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1000)
    ap.add_argument("--max-evals", type=int, default=200)
    ap.add_argument("--method", default="nelder-mead")
    ap.add_argument("--skip-cluster", action="store_true")
    args = ap.parse_args(argv)
    import acl
    import acl.sweep.run as R

    kw = dict(n=args.samples, validate=args.samples, max_evals=args.max_evals, method=args.method)
    acl.tune(FIG3, n=100, max_evals=5)                                     # warm-up (imports)
    cores = R.local_workers(64)
    real = R.local_workers
    R.local_workers = lambda n: 1                                            # one thread in this process
    try:
        one, wall, cpu = timed(lambda: acl.tune(FIG3, **kw))
    finally:
        R.local_workers = real
    print(f"one thread: {wall:.2f} s wall, {cpu:.2f} s CPU; {one.search.evaluations} trials; {one!r}")
    threads, wall, cpu = timed(lambda: acl.tune(FIG3, scheduler="local", **kw))
    print(f"local, {cores} thread(s): {wall:.2f} s wall, {cpu:.2f} s CPU; equal bit for bit: {same(one, threads)}")
    ok = same(one, threads)
    if not args.skip_cluster:
        try:
            from distributed import LocalCluster
        except ImportError:
            print("cluster: skipped, dask.distributed is not installed (pip install 'acl[scale]')")
            return 0 if ok else 1
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
            remote, wall, cpu = timed(lambda: acl.tune(FIG3, scheduler=cluster.scheduler_address, **kw))
        print(f"2-worker LocalCluster: {wall:.2f} s wall, {cpu:.2f} s CPU in this process; "
              f"equal bit for bit: {same(one, remote)}")
        ok &= same(one, remote)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

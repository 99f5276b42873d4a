"""Set-up shared by the sweep benchmarks (sweep_physics.py, sweep_effects.py): one core, one BLAS thread.

Importing this module (before numpy) sets the BLAS thread counts to 1 and puts this checkout's acl first on
the path (unless ACL_BENCH_NO_PATH is set: to time another checkout, with its acl on PYTHONPATH).
"""
from __future__ import annotations

import argparse
import os
import sys

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import numpy as np  # noqa: E402

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
if "ACL_BENCH_NO_PATH" not in os.environ:
    sys.path.insert(0, ROOT)


def options(argv, **counts: int) -> argparse.Namespace:
    """Parse ``--name N`` integer options (``pair_n=20000`` -> ``--pair-n``) and pin the process to one CPU."""
    ap = argparse.ArgumentParser()
    for name, default in counts.items():
        ap.add_argument("--" + name.replace("_", "-"), type=int, default=default)
    args = ap.parse_args(argv)
    try:
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    except (AttributeError, OSError):
        pass
    return args


def field_batch(design, fields: dict):
    """A FieldBatch of ``design`` with these per-point fields, every point valid."""
    from acl.sweep.perturb import FieldBatch

    n = len(next(iter(fields.values())))
    return FieldBatch(design=design, n=n, fields=fields, valid=np.ones(n, bool), code=np.full(n, ""))

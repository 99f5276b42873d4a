"""Design space at scale (issue 13): sweeps, print-tolerance Monte Carlo, yield, robust design.

A stage beside the analyses, data flowing one way::

    resolved Design (resolved once)
      -> spec.py      what varies: grids (--vary) and distributions (--tolerance, or declared in the
                      design with `param x = v +- ...`), parsed with units at the edge, SI inside
      -> sample.py    points of one chunk: {param name: SI array}; chunk k of seed s is the same
                      whatever runs it (a seed sequence keyed on (seed, k)), so a cluster equals
                      one process bit for bit
      -> perturb.py   the design's float fields for those points (a FieldBatch: base Design plus
                      {field path: array}), with a validity mask and a diagnostic code per invalid
                      point: no per-point re-resolution
      -> evaluate.py  batched physics (acl.physics, vectorised over points): one column per quantity
      -> run.py       chunks as tasks: in process, or on dask (acl[scale]) for --scheduler
      -> table.py     one row per point (numpy structured array; .to_pandas()/.to_arrow()),
                      CSV/Parquet written atomically, yield with a binomial interval
    tune.py           robust design: choose `free` parameters to maximise yield under tolerances

Physics never imports this package; the CLI (acl/commands/sweep.py, tune.py) is thin.
"""

from acl._callable import make_callable as _make_callable  # noqa: E402

# `acl.sweep(...)` is the API function (acl._sweep) and this package: importing the package keeps it callable.
_make_callable(__name__)

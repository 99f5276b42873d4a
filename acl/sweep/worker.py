"""The dask worker setting acl ships: ``dask worker ADDRESS --preload-nanny acl.sweep.worker``.

dask's nanny sets ``MALLOC_TRIM_THRESHOLD_=65536`` in the worker's environment before it starts
(``distributed.nanny.pre-spawn-environ``), to hand freed memory back to the system sooner.  Setting
any of glibc's ``MALLOC_*_`` tunables turns off glibc's dynamic mmap threshold, so every array over
128 KiB that a chunk allocates is mapped and unmapped afresh: page faults and system time multiply
(issue 28 measured 9x the page faults and 5.5x the system time per chunk of a sweep).  A sweep's
chunk allocates and frees the same arrays over and over, the case glibc's default serves best.

This module, preloaded into the nanny, removes the variable before the worker process is spawned, so
the worker runs with glibc's defaults.  The same in a dask configuration file
(``~/.config/dask/acl.yaml``)::

    distributed:
      nanny:
        pre-spawn-environ:
          MALLOC_TRIM_THRESHOLD_: null
"""
from __future__ import annotations

TUNABLE = "MALLOC_TRIM_THRESHOLD_"


def dask_setup(nanny) -> None:
    """Called by the nanny (``--preload-nanny acl.sweep.worker``) before it spawns its worker."""
    for env in (getattr(nanny, "pre_spawn_env", None), getattr(nanny, "env", None)):
        if isinstance(env, dict):
            env.pop(TUNABLE, None)

"""Chunks of points as tasks: in this process, on a thread pool, or on a dask.distributed cluster.

A chunk is the unit of work of a sweep (``task(k)`` evaluates chunk ``k``; its points come from a
random stream keyed on (seed, k), :mod:`acl.sweep.sample`), so whichever executor runs it, on
whichever worker, the chunk's numbers are the same and the results come back in chunk order: a
cluster run equals a single-process run bit for bit (tested with a LocalCluster of 2 workers).

``scheduler``:

* ``None`` or ``"local"``: this machine. One chunk runs in this process; more run on a thread
  pool (numpy releases the GIL inside its array loops; no pickling, no start-up cost). Needs
  nothing beyond numpy: dask is not imported.
* ``"tcp://HOST:PORT"`` (or ``tls://``): the scheduler of a dask.distributed cluster (the
  ``acl[scale]`` extra). Missing dask is E-USAGE, an unreachable scheduler E-CLUSTER (after
  :data:`CONNECT_TIMEOUT_S`), both located at ``<--scheduler>`` (exit 2).
"""
from __future__ import annotations

import os
import re
from typing import Callable, TypeVar

from acl.diagnostics import DiagnosticError, Span, error

T = TypeVar("T")

CONNECT_TIMEOUT_S = 10.0
WORKER_TIMEOUT_S = 60.0          # how long a cluster run waits with no worker before E-CLUSTER (--timeout)
POLL_S = 1.0                     # how often a cluster run looks at its workers while no chunk finishes
_ADDRESS = re.compile(r"^(tcp|tls)://(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})$")
_WHERE = Span(file="<--scheduler>", line=1, column=1)


def map_chunks(task: Callable[[int], T], n_chunks: int, scheduler: str | None = None,
               progress: Callable[[int, int], None] | None = None, timeout: float | None = None,
               notify: Callable[[str], None] | None = None) -> list[T]:
    """``[task(0), ..., task(n_chunks - 1)]``, computed where ``scheduler`` says; results in chunk order.

    ``progress(done, total)`` is called in this process after each chunk finishes (any order).
    Exceptions raised by a task (e.g. a DiagnosticError) propagate unchanged.  On a cluster,
    ``timeout`` is how long to wait with no worker (default :data:`WORKER_TIMEOUT_S`) and
    ``notify(text)`` hears when the cluster has none (see :func:`_on_cluster`).
    """
    if n_chunks < 0:
        raise ValueError("n_chunks must be >= 0")
    with Executor(scheduler, connect=n_chunks > 0, timeout=timeout, notify=notify) as ex:
        return ex.map(task, n_chunks, progress)


class Executor:
    """Where tasks run, kept open across several :meth:`map` calls (``acl tune`` maps one batch of
    trials after another on the same cluster connection)::

        with Executor("tcp://10.0.0.5:8786") as ex:
            first = ex.map(task, 8)
            second = ex.map(other, 4)

    ``scheduler`` as :func:`map_chunks`; a cluster is connected on entering (``connect=False``:
    only when a map has work), and closed on exit.
    """

    def __init__(self, scheduler: str | None = None, connect: bool = True, timeout: float | None = None,
                 notify: Callable[[str], None] | None = None):
        self.kind = scheduler_kind(scheduler)
        self.address = scheduler
        self.timeout = WORKER_TIMEOUT_S if timeout is None else float(timeout)
        self.notify = notify
        self._connect = connect
        self._client = None
        self._levels: dict = {}

    def __enter__(self) -> "Executor":
        if self.kind == "cluster":
            self._levels = _quiet_dask()
            if self._connect:
                self._client = _client(self.address)
        return self

    def __exit__(self, *exc) -> None:
        if self._client is not None:
            try:
                self._client.close(timeout=2)
            except Exception:                           # noqa: BLE001 (a scheduler already gone: nothing to close)
                pass
            self._client = None
        _restore(self._levels)
        self._levels = {}

    def map(self, task: Callable[[int], T], n: int, progress: Callable[[int, int], None] | None = None) -> list[T]:
        """``[task(0), ..., task(n - 1)]`` in order."""
        if self.kind == "cluster":
            if n == 0:
                return []
            if self._client is None:
                self._client = _client(self.address)
            return _on_cluster(self._client, task, n, progress, self.timeout, self.address, self.notify)
        return _on_this_machine(task, n, progress)


def scheduler_kind(scheduler: str | None) -> str:
    """``"local"`` or ``"cluster"``; anything else is E-USAGE at ``<--scheduler>``."""
    if scheduler is None or scheduler == "local":
        return "local"
    m = _ADDRESS.match(scheduler.strip())
    if m and 0 < int(m.group(3)) < 65536:
        return "cluster"
    raise DiagnosticError([error(
        "E-USAGE", f"--scheduler {scheduler!r}: expected `local` or the address of a dask scheduler, tcp://HOST:PORT",
        _WHERE, "e.g. --scheduler tcp://10.0.0.5:8786 (start one with `dask scheduler` and `dask worker ADDRESS`)")])


def local_workers(n_chunks: int) -> int:
    """Threads used on this machine: one per usable core, never more than there are chunks."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return max(1, min(n_chunks, cores))


def _on_this_machine(task, n_chunks, progress) -> list:
    workers = local_workers(n_chunks)
    if workers <= 1:
        out = []
        for k in range(n_chunks):
            out.append(task(k))
            if progress is not None:
                progress(k + 1, n_chunks)
        return out
    from concurrent.futures import FIRST_EXCEPTION, ThreadPoolExecutor, wait

    results: list = [None] * n_chunks
    with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="acl-chunk") as pool:
        futures = {pool.submit(task, k): k for k in range(n_chunks)}
        pending, done_count = set(futures), 0
        try:
            while pending:
                done, pending = wait(pending, return_when=FIRST_EXCEPTION)
                for f in done:
                    results[futures[f]] = f.result()      # re-raises a task's exception here
                    done_count += 1
                    if progress is not None:
                        progress(done_count, n_chunks)
        except BaseException:
            for f in pending:
                f.cancel()
            raise
    return results


def _quiet_dask() -> dict:
    """Silence dask's own log lines while acl talks to a cluster (a lost scheduler logged "Failed to
    reconnect ..." and tracebacks on stderr before acl's diagnostic); returns the levels to restore."""
    import logging

    try:
        import distributed  # noqa: F401  (its import sets its loggers' levels: silence them after it)
    except ImportError:
        return {}
    names = ["distributed", *(n for n in logging.root.manager.loggerDict if n.startswith("distributed."))]
    levels = {}
    for n in names:
        lg = logging.getLogger(n)
        levels[n] = lg.level
        lg.setLevel(logging.CRITICAL + 1)
    return levels


def _restore(levels: dict) -> None:
    import logging

    for n, level in levels.items():
        logging.getLogger(n).setLevel(level)


def _client(address: str):
    """A dask.distributed Client on ``address``, or a located diagnostic (dask missing, unreachable)."""
    try:
        from distributed import Client
    except ImportError:
        raise DiagnosticError([error(
            "E-USAGE", f"--scheduler {address}: running on a cluster needs dask.distributed, which is not installed",
            _WHERE, "install the scale extra: pip install 'acl[scale]' (from a checkout: pip install '.[scale]'), "
                    "or use --scheduler local")]) from None
    try:
        return Client(address, timeout=f"{CONNECT_TIMEOUT_S:g}s", set_as_default=False)
    except (OSError, TimeoutError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise DiagnosticError([error(
            "E-CLUSTER", f"--scheduler {address}: cannot reach the dask scheduler within {CONNECT_TIMEOUT_S:g} s ({reason})",
            _WHERE, "start one (`dask scheduler`, then `dask worker ADDRESS` on each machine), check the address "
                    "and the firewall, or use --scheduler local")]) from None


def _lost(address: str, what: str, hint: str) -> DiagnosticError:
    return DiagnosticError([error("E-CLUSTER", f"--scheduler {address}: {what}", _WHERE, hint)])


def _scheduler_info(client) -> dict:
    """The scheduler's identity, with at most one worker's details where dask can limit them."""
    try:
        return client.scheduler_info(n_workers=1)
    except TypeError:                                  # an older distributed: no n_workers
        return client.scheduler_info()


def _on_cluster(client, task, n_chunks, progress, timeout: float = WORKER_TIMEOUT_S, address: str = "",
                notify: Callable[[str], None] | None = None) -> list:
    """Chunks on the cluster, in order.  The cluster going away is a located E-CLUSTER, never a hang:

    * the scheduler lost (its process killed, the network gone): dask cancels every future once its
      client has failed to reconnect (about 10 s); that is E-CLUSTER "lost the connection to the scheduler";
    * every worker lost: the futures wait for a worker that may never come; ``notify`` is told once, and
      after ``timeout`` seconds with no worker, E-CLUSTER "no worker left";
    * a chunk that killed the workers running it (dask's KilledWorker: out of memory, a crash): E-CLUSTER.
    """
    import concurrent.futures as cf
    import time

    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    # pure=False: a task is keyed by its chunk, never deduplicated or cached across runs
    futures = client.map(task, range(n_chunks), pure=False)
    index = {f.key: k for k, f in enumerate(futures)}
    results: list = [None] * n_chunks
    ready = as_completed(futures, loop=client.loop)
    done_count = 0
    alone_since, told, looked = None, False, time.monotonic()
    try:
        while done_count < n_chunks:
            done = ready.next_batch(block=False)
            for f in done:
                results[index[f.key]] = f.result()     # re-raises a task's exception here
                done_count += 1
                if progress is not None:
                    progress(done_count, n_chunks)
            if done:
                alone_since, looked = None, time.monotonic()
                continue
            time.sleep(0.02)
            if time.monotonic() - looked < POLL_S:
                continue
            looked = time.monotonic()
            if client.status != "running":
                continue                               # reconnecting: the futures are cancelled if it fails
            try:
                workers = len(_scheduler_info(client).get("workers", {}))
            except (OSError, TimeoutError, cf.TimeoutError):
                continue
            if workers:
                alone_since = None
                continue
            now = time.monotonic()
            if alone_since is None:
                alone_since = now
            if not told and notify is not None:
                notify(f"the dask cluster at {address} has no worker: waiting up to {timeout:g} s for one to join "
                       f"({done_count} of {n_chunks} chunks done)")
                told = True
            if now - alone_since >= timeout:
                raise _lost(address, f"no worker left on the cluster for {timeout:g} s; {done_count} of {n_chunks} chunks "
                            "were done and nothing was written",
                            "start workers (`dask worker ADDRESS`) and run again, or give a longer --timeout "
                            "for workers that restart")
    except cf.CancelledError:
        raise _lost(address, f"lost the connection to the dask scheduler; {done_count} of {n_chunks} chunks were done "
                    "and nothing was written", "check that the scheduler still runs (`dask scheduler`) and is reachable, "
                    "then run again, or use --scheduler local") from None
    except KilledWorker as exc:
        raise _lost(address, f"a chunk killed every worker that ran it ({str(exc).splitlines()[0][:200]})",
                    "a worker ran out of memory or crashed: give the workers more memory (`dask worker "
                    "--memory-limit`), or use --scheduler local") from None
    finally:
        if done_count < n_chunks:
            try:
                client.cancel([f for f in futures if not f.done()])
            except Exception:                           # noqa: BLE001 (the connection is gone: nothing to cancel)
                pass
    return results

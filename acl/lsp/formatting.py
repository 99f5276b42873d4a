"""Formatting: the whole document through `acl fmt` (:func:`acl.fmt.format_source`), as one edit.

A document with syntax errors is left alone (its diagnostics already say why), as `acl fmt` does.
`acl fmt` takes about 0.17 s on 1,000 lines and 0.9 s on 5,000 (it parses twice to check its
output): its result is kept per text (the last few), so formatting, range formatting and
organize imports on the same text format it once. It runs in a formatting process (niced, so the
server's own thread and the GIL stay free for other requests); a request waits for it at most
:data:`WAIT_SECONDS`, then answers that formatting is still running (:data:`BUSY`). The run goes
on, and the next request for the same text is answered from its result.
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from concurrent.futures import Future

from acl.diagnostics import DiagnosticError
from acl.lsp.document import Snapshot

_CACHE: "OrderedDict[tuple[str, str], str | None]" = OrderedDict()
_LOCK = threading.Lock()
_KEEP = 8

#: how long a request waits for `acl fmt` before answering that it is still running
WAIT_SECONDS = 0.12
BUSY = ("E-LSP-BUSY: acl fmt is still formatting this document (a large design: about 1 s for "
        "5,000 lines); ask again in a moment")

#: documents with more lines are formatted in the formatting process; smaller ones on a thread
#: (no process to start; they take at most about 0.2 s)
PROCESS_LINES = 1500

_POOL = None
_THREADS = None
_JOBS: "dict[tuple[str, str], Future]" = {}


class StillFormatting(Exception):
    """`acl fmt` did not end within the wait (it goes on; its result is kept)."""


def format_text(text: str, path: str) -> str | None:
    """`acl fmt`'s text for ``text``, None when it does not parse (run in the formatting process)."""
    from acl.fmt import format_source

    try:
        return format_source(text, path)
    except DiagnosticError:
        return None


def _executor():
    global _POOL
    if _POOL is None:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        from acl.lsp.lint import lower_priority

        _POOL = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"),
                                    initializer=lower_priority)
    return _POOL


def _threads():
    global _THREADS
    if _THREADS is None:
        from concurrent.futures import ThreadPoolExecutor

        _THREADS = ThreadPoolExecutor(max_workers=1, thread_name_prefix="acl-fmt")
    return _THREADS


def warm_up() -> None:
    """Start the formatting process (and its imports) before the first request of a large design."""
    if _POOL is None:
        _executor().submit(format_text, "", "<warm-up>")


def start(text: str, path: str) -> Future:
    """A future of `acl fmt`'s text for ``text`` (from the cache when seen; one run per text)."""
    key = (path, text)
    with _LOCK:
        if key in _CACHE:
            _CACHE.move_to_end(key)
            fut: Future = Future()
            fut.set_result(_CACHE[key])
            return fut
        if key in _JOBS:
            return _JOBS[key]
        for k in [k for k in _JOBS if k[0] == path]:     # an older text of the document: not needed any more
            if _JOBS[k].cancel():
                del _JOBS[k]
        try:
            big = text.count("\n") > PROCESS_LINES
            fut = (_executor() if big else _threads()).submit(format_text, text, path)
        except RuntimeError:                   # the pool was shut down (the server is stopping)
            fut = Future()
            fut.set_result(format_text(text, path))
        _JOBS[key] = fut
    fut.add_done_callback(lambda f, key=key: _done(key, f))
    return fut


def _done(key: tuple[str, str], fut: Future) -> None:
    with _LOCK:
        if _JOBS.get(key) is fut:
            del _JOBS[key]
        if fut.cancelled():
            return
        try:
            new = fut.result()
        except Exception:               # the process died (the server is stopping): nothing to keep
            return
        _CACHE[key] = new
        while len(_CACHE) > _KEEP:
            _CACHE.popitem(last=False)


def formatted(text: str, path: str, wait: float | None = WAIT_SECONDS) -> str | None:
    """`acl fmt`'s text for ``text`` (None when it does not parse), waiting at most ``wait``
    seconds (None: as long as it takes); StillFormatting when it is not done by then."""
    from concurrent.futures import TimeoutError as FutureTimeout

    fut = start(text, path)
    try:
        return fut.result(timeout=wait)
    except FutureTimeout:
        raise StillFormatting(BUSY) from None


def stop() -> None:
    global _POOL
    pool, _POOL = _POOL, None
    if pool is not None:
        workers = list(getattr(pool, "_processes", {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for w in workers:
            if w.is_alive():
                w.terminate()


_HUNKS: "OrderedDict[tuple[str, str], tuple]" = OrderedDict()


def hunks_of(text: str, path: str, wait: float | None = WAIT_SECONDS):
    """(old lines, new lines, hunks) of `acl fmt` on ``text`` (None when it does not parse); each hunk
    (i1, i2, j1, j2) replaces old lines i1..i2 by new lines j1..j2. Changed lines are split one by
    one where `acl fmt` keeps their number, so a range takes only its own lines. Kept per text."""
    import difflib

    key = (path, text)
    with _LOCK:
        if key in _HUNKS:
            return _HUNKS[key]
    new = formatted(text, path, wait)
    if new is None:
        return None
    old_lines, new_lines = text.split("\n"), new.split("\n")
    hunks = []
    for op, i1, i2, j1, j2 in difflib.SequenceMatcher(None, old_lines, new_lines).get_opcodes():
        if op == "replace" and i2 - i1 == j2 - j1:
            hunks.extend((i1 + k, i1 + k + 1, j1 + k, j1 + k + 1) for k in range(i2 - i1))
        elif op != "equal":
            prev = hunks[-1] if hunks else None
            # a deletion and an insertion at most one unchanged line apart are one change (a moved or
            # rewritten line): one hunk, so a range that touches either takes both
            if prev is not None and i1 - prev[1] <= 1 and ((prev[2] == prev[3]) != (j1 == j2)) and \
                    (prev[0] == prev[1]) != (i1 == i2):
                hunks[-1] = (prev[0], i2, prev[2], j2)
            else:
                hunks.append((i1, i2, j1, j2))
    got = (old_lines, new_lines, hunks)
    with _LOCK:
        _HUNKS[key] = got
        while len(_HUNKS) > _KEEP:
            _HUNKS.popitem(last=False)
    return got


def format_edits(snap: Snapshot, wait: float | None = WAIT_SECONDS) -> list[tuple[tuple[int, int, int, int], str]] | None:
    """[(range, new text)] replacing the document with its canonical layout; [] if already formatted;
    StillFormatting when `acl fmt` takes longer than ``wait`` seconds."""
    new = formatted(snap.text, snap.path, wait)
    if new is None:
        return None
    if new == snap.text:
        return []
    lines = snap.text.split("\n")
    return [((0, 0, len(lines) - 1, len(lines[-1])), new)]

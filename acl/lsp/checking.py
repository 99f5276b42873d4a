"""Checking documents off the server's event loop: one background thread, newest text first.

A document's text is checked (parse, resolve, design assembly and checks: :func:`check_text`) on a
single checking thread, so the event loop keeps reading and answering messages while a large
design is assembled (0.1-0.3 s at 5,000 lines).  Each request for a text returns a future:

- a text already checked answers at once; a text being checked shares the running check;
- a check still queued when a newer text of the same document arrives is skipped (its future
  gives None), so a burst of edits costs at most the running check and the newest one;
- each document keeps its :class:`~acl.lsp.incremental.IncrementalParser`, used only on the
  checking thread.

Requests read :meth:`Checks.snapshot`: it waits for the current text's check at most ``wait``
seconds on a large document (:data:`SMALL_WAIT_SECONDS` on one of at most :data:`SMALL_LINES`
lines), then answers from the last text checked, or says that the server is still checking.
"""
from __future__ import annotations

import threading
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout

from acl.lsp.document import Snapshot, check_text

#: how long a request waits for the check of the current text of a large document before
#: answering without it; a document of at most SMALL_LINES lines (checked in tens of ms, or
#: longer only while the server is still importing) is waited for up to SMALL_WAIT_SECONDS
WAIT_SECONDS = 0.15
SMALL_LINES = 1500
SMALL_WAIT_SECONDS = 5.0

BUSY = ("E-LSP-BUSY: still checking the latest edit of this document (a large design): "
        "ask again in a moment")


class Checks:
    def __init__(self, path_of, on_checked=None, wait: float = WAIT_SECONDS, pause_gc: bool = False) -> None:
        self.path_of = path_of
        # pause_gc: the young-object collections that land inside a check (10 ms of the 90 ms CPU of
        # a 5,000-line design's check) are put off until the caller has published its diagnostics
        # and calls resume_gc(); the server does so after each publish and in each idle collection
        self.pause_gc = pause_gc
        self.on_checked = on_checked            # (uri, snapshot), called on the checking thread
        self.wait = wait
        self.snapshots: dict[str, Snapshot] = {}
        self._lock = threading.Lock()
        self._jobs: dict[str, tuple[str, Future]] = {}      # uri -> (text, future) of its newest check
        self._parsers: dict[str, object] = {}
        self._pool: ThreadPoolExecutor | None = None
        self.skipped = 0                         # queued checks of older texts never run

    def start(self, uri: str, text: str, version: int | None = None) -> Future:
        """A future of the snapshot of ``text`` (None when a newer text superseded it before it ran)."""
        with self._lock:
            snap = self.snapshots.get(uri)
            if snap is not None and snap.text == text:
                fut: Future = Future()
                fut.set_result(snap)
                return fut
            job = self._jobs.get(uri)
            if job is not None and job[0] == text:
                return job[1]
            if self._pool is None:
                self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="acl-check")
            fut = self._pool.submit(self._run, uri, text, version)
            self._jobs[uri] = (text, fut)
            return fut

    def _run(self, uri: str, text: str, version: int | None) -> Snapshot | None:
        from acl.lsp.incremental import IncrementalParser

        with self._lock:
            job = self._jobs.get(uri)
            if job is None or job[0] != text:     # a newer text (or the document closed) came meanwhile
                self.skipped += 1
                return None
            parser = self._parsers.setdefault(uri, IncrementalParser())
        if self.pause_gc:
            import gc

            gc.disable()
        snap = check_text(text, self.path_of(uri), version, parser=parser)
        with self._lock:
            job = self._jobs.get(uri)
            if job is None:                        # closed meanwhile
                return snap
            if job[0] == text:
                self._jobs.pop(uri, None)
            old = self.snapshots.get(uri)
            # keep it unless a newer text is already checked (versions only grow; None: a test's text)
            if old is None or version is None or old.version is None or version >= old.version:
                self.snapshots[uri] = snap
        if self.on_checked is not None:
            self.on_checked(uri, snap)
        return snap

    def snapshot(self, uri: str, text: str, version: int | None, fresh: bool = False) -> Snapshot:
        """The snapshot of ``text``, waiting at most ``wait`` seconds; else the last one checked
        (unless ``fresh``); else RequestFailed (:data:`BUSY`)."""
        fut = self.start(uri, text, version)
        wait = self.wait if text.count("\n") > SMALL_LINES else max(self.wait, SMALL_WAIT_SECONDS)
        try:
            snap = fut.result(timeout=wait)
        except FutureTimeout:
            snap = None
        if snap is not None:
            return snap
        last = self.snapshots.get(uri)
        if last is not None and not fresh:
            return last
        from acl.lsp.protocol import RequestFailed

        raise RequestFailed(BUSY)

    @staticmethod
    def resume_gc() -> None:
        """Collections on again after a check (see ``pause_gc``)."""
        import gc

        gc.enable()

    def forget(self, uri: str) -> None:
        with self._lock:
            self._jobs.pop(uri, None)
            self._parsers.pop(uri, None)
            self.snapshots.pop(uri, None)

    def stop(self) -> None:
        pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=False, cancel_futures=True)

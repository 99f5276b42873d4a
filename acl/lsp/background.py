"""Long analyses off the server's event loop, in one worker process, cancelled by newer edits.

A capsule's hover on a large design (its coupled modes with every other capsule: 13 s for 393
capsules) and code lenses' requirement values run here.  The worker receives the document's text
(never reads a document from disk; imports are read by the loader under the rules of `acl check`)
and returns plain text or data.  Work is keyed by (document URI, text); an edit that changes the
text cancels queued work for the older text and stops the worker if it is busy with it (a process
can be stopped, a thread cannot), so the editor never waits for a result it no longer needs.
Meanwhile requests answer at once with what is quick and say the rest is being computed.
"""
from __future__ import annotations

import hashlib
import threading
from concurrent.futures import Future
from concurrent.futures.process import BrokenProcessPool

PENDING_NOTE = "*computing in the background (a large design): hover again in a moment*"


def text_key(text: str) -> str:
    return hashlib.sha1(text.encode("utf-8", "surrogatepass")).hexdigest()


class Worker:
    """One spawned process; results cached per (uri, text key, what)."""

    def __init__(self, max_results: int = 256) -> None:
        self._pool = None
        self._lock = threading.RLock()
        self._jobs: dict[tuple, Future] = {}
        self._results: dict[tuple, object] = {}
        self._max = max_results
        self.cancelled = 0            # jobs cancelled by newer edits (queued or running)
        self.restarts = 0

    def _executor(self):
        if self._pool is None:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor

            from acl.lsp.lint import lower_priority

            self._pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"),
                                             initializer=lower_priority)
        return self._pool

    def get(self, key: tuple, fn, *args):
        """The result for ``key`` if ready; else start ``fn(*args)`` (once) and return None."""
        with self._lock:
            if key in self._results:
                return self._results[key]
            if key in self._jobs:
                return None
            fut = self._executor().submit(fn, *args)
            self._jobs[key] = fut
        fut.add_done_callback(lambda f, key=key: self._done(key, f))
        return None

    def peek(self, key: tuple):
        """The result for ``key`` if ready (None otherwise); starts nothing."""
        with self._lock:
            return self._results.get(key)

    def future(self, key: tuple) -> Future | None:
        with self._lock:
            return self._jobs.get(key)

    def _done(self, key: tuple, fut: Future) -> None:
        with self._lock:
            self._jobs.pop(key, None)
            if fut.cancelled():
                return
            try:
                result = fut.result()
            except BrokenProcessPool:     # stopped by a newer edit: nothing to keep (asked again, it reruns)
                return
            except Exception as exc:      # a bug in the analysis: said once, not retried for this text
                result = f"(unavailable: {type(exc).__name__}: {exc})"
            self._results[key] = result
            while len(self._results) > self._max:
                self._results.pop(next(iter(self._results)))

    def cancel(self, key: tuple) -> None:
        """Drop the job for ``key`` (the client cancelled it): dequeued, or the worker stopped if it
        is running it."""
        with self._lock:
            fut = self._jobs.pop(key, None)
            if fut is None or fut.done():
                return
            self.cancelled += 1
        if not fut.cancel():
            self.stop()
            self.restarts += 1

    def forget(self, uri: str, keep: str | None = None) -> None:
        """Drop work and results of ``uri`` whose text key is not ``keep``; stop the worker if it is
        running such work."""
        with self._lock:
            for k in [k for k in self._results if k[0] == uri and k[1] != keep]:
                del self._results[k]
            old = [(k, f) for k, f in self._jobs.items() if k[0] == uri and k[1] != keep]
            for k, _ in old:
                self._jobs.pop(k, None)
            self.cancelled += len(old)
        busy = False
        for _, f in old:           # outside the lock: cancel() runs the done callbacks in this thread
            if not f.cancel():
                busy = True
        if busy:
            self.stop()
            self.restarts += 1

    def stop(self) -> None:
        pool, self._pool = self._pool, None
        if pool is None:
            return
        workers = list(getattr(pool, "_processes", {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for w in workers:
            if w.is_alive():
                w.terminate()
        for w in workers:                      # a worker still starting may miss SIGTERM: then SIGKILL
            w.join(1.0)
            if w.is_alive():
                w.kill()
        with self._lock:
            left = list(self._jobs.values())
            self._jobs.clear()
            # what warmed the stopped process (its imports, a document's parse and analyses) is gone with it: the
            # server's next warm-up request (after its next publish) warms the new one
            for k in [k for k in self._results if k[:1] == ("warm",)]:
                del self._results[k]
        for f in left:
            f.cancel()


_CHECKED: dict[tuple[str, str], object] = {}     # (path, text key) -> Snapshot, in the worker
_PARSERS: dict[str, object] = {}                 # path -> IncrementalParser, in the worker
_TWINS: dict = {}                                # physics content key -> the first design with it
_TWIN_OF: list = []                              # [(design, its twin)]: the last two asked


def checked(path: str, text: str):
    """The worker's snapshot of ``text`` (kept for the last two texts): every job on one text uses
    one design object, so the analyses' per-design caches (acl.analysis.acoustics) serve the
    second capsule's hover from the first one's work (the coupled modes of all capsules). Texts
    of one path go through one incremental parser (statements not edited are not parsed again:
    0.5 s of lark on 5,000 lines)."""
    from acl.lsp.document import check_text
    from acl.lsp.incremental import IncrementalParser

    key = (path, text_key(text))
    snap = _CHECKED.get(key)
    if snap is None:
        if path not in _PARSERS:
            _PARSERS.clear()                     # one document's at a time (the last one hovered)
            _PARSERS[path] = IncrementalParser()
        snap = check_text(text, path, parser=_PARSERS[path])
        while len(_CHECKED) >= 2:
            _CHECKED.pop(next(iter(_CHECKED)))
        _CHECKED[key] = snap
    return snap


def content_key(value):
    """A hashable key of ``value`` (a design or any part of it) that leaves out source locations
    (spans) and cached attributes: two designs with equal keys are the same physics, so one's
    analyses serve the other. Raises TypeError on a value it cannot key."""
    from pydantic import BaseModel

    from acl.diagnostics import Span

    atoms = (str, float, int, bool, type(None))

    def key(v):
        t = type(v)
        if t in atoms:
            return v
        if t is tuple or t is list:
            return tuple([key(x) for x in v])
        if isinstance(v, BaseModel):
            return (t.__qualname__,) + tuple([(k, key(x)) for k, x in v.__dict__.items()
                                              if k[0] != "_" and type(x) is not Span])
        if t is dict:
            return ("dict",) + tuple(sorted((key(k), key(x)) for k, x in v.items()))
        raise TypeError(f"no content key for {t.__name__}")

    return key(value)


def physics_twin(design):
    """The design of an earlier text (of the last two physics this worker saw) equal to ``design``
    in everything but its source locations, else ``design`` itself. A hover uses it for the
    analyses, so an edit that changes no physics (Enter, a comment, a line moved) finds the
    coupled modes of all capsules already computed for the earlier text."""
    if design is None:
        return None
    for d, twin in _TWIN_OF:                 # asked again for the same design: no key to compute
        if d is design:
            return twin
    try:
        key = content_key(design)
    except TypeError:
        key = None
    twin = _TWINS.get(key, design) if key is not None else design
    if key is not None and twin is design:
        while len(_TWINS) >= 2:
            _TWINS.pop(next(iter(_TWINS)))
        _TWINS[key] = design
    _TWIN_OF[:] = ([(design, twin)] + _TWIN_OF)[:2]
    return twin


def hover_text(path: str, text: str, line: int, character: int) -> str | None:
    """The full hover at (line, character) of ``text`` (run in the worker); its analyses run on
    the :func:`physics_twin` of the text's design (the text's own locations are kept)."""
    import dataclasses

    from acl.lsp.hover import hover
    from acl.syntax.parser import paused_gc

    with paused_gc():       # collections over the worker's large heap: 0.15-0.3 s of each hover
        snap = checked(path, text)
        twin = physics_twin(snap.design)
        if twin is not snap.design:
            snap = dataclasses.replace(snap, design=twin)
        got = hover(snap, line, character)
    return None if got is None else got[0]


def warm_document(path: str, text: str) -> bool:
    """Before the first hover on a large document (run in the worker): check ``text`` (the worker's incremental
    parser then holds its statements, so a later text parses only what was edited) and compute what a capsule's full
    hover on it needs (the coupled modes of all capsules, the response at the program's frequencies)."""
    from acl.analysis import acoustics as AC
    from acl.analysis.report import program_frequencies
    from acl.lsp.hover import PHASE_FREQUENCIES
    from acl.syntax.parser import paused_gc

    with paused_gc():
        snap = checked(path, text)
        design = physics_twin(snap.design)
        if design is None or len(design.capsules) < 2:
            return False
        AC.coupled_modes_of(design, design.capsules[0])
        freqs = program_frequencies(design)[:PHASE_FREQUENCIES]
        if freqs:
            AC.rest_response(design, freqs)
    return True


def requirement_values(path: str, text: str) -> list[dict]:
    """Each `require` of the design: its line, pass or fail, value and unit (run in the worker)."""
    from acl.analysis.report import analyze

    from acl.syntax.parser import paused_gc

    with paused_gc():
        snap = checked(path, text)
        if snap.design is None or not getattr(snap.design, "requires", None):
            return []
        rep = analyze(snap.design)
    return [{"line": r.get("line"), "ok": r["ok"], "value": r["value"], "unit": r["unit"], "text": r["text"],
             "detail": r["detail"]} for r in rep.requires]


def warm_up() -> bool:
    """Import the analyses in the worker before the first real request."""
    import acl.analysis.acoustics  # noqa: F401
    import acl.lsp.hover  # noqa: F401

    return True

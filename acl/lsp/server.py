"""The acl language server (pygls 2): a thin protocol layer over :mod:`acl.lsp` features.

Diagnostics: on open and after each change (once typing pauses for ``debounce`` seconds, 0 by
default), the document is checked with the stages of `acl check` on a background thread
(:mod:`acl.lsp.checking`) and its diagnostics are published as soon as the check ends; the
event loop keeps answering meanwhile, and a newer edit makes queued checks of older texts
skip. Lint findings (the rules of `acl lint`) follow from a worker process and replace them.
Options (``initializationOptions``): ``{"debounce": 0, "lint": true, "lint_delay": 0.3}``.
"""
from __future__ import annotations

import asyncio
import logging
import os
import sys

from lsprotocol import types as T
from pygls.lsp.server import LanguageServer
from pygls.uris import from_fs_path, to_fs_path

from acl import __version__
from acl.diagnostics import Diagnostic, Severity
from acl.lsp.document import Snapshot

#: seconds without a finished check before the full garbage collection (:meth:`collect_when_idle`)
IDLE_COLLECT_SECONDS = 2.0

_SEVERITY = {Severity.ERROR: T.DiagnosticSeverity.Error, Severity.WARNING: T.DiagnosticSeverity.Warning,
             Severity.INFO: T.DiagnosticSeverity.Information}


SHUTDOWN_WAIT_S = 10.0    # longest a `shutdown` waits for the diagnostics already asked for


class AclLanguageServer(LanguageServer):
    def __init__(self) -> None:
        from acl.lsp.protocol import AclProtocol

        super().__init__("acl", __version__, text_document_sync_kind=T.TextDocumentSyncKind.Incremental,
                         protocol_cls=AclProtocol)
        self.debounce = 0.0
        self.lint_enabled = True
        self.lint_delay = 0.3
        self.resolved: dict[str, Snapshot] = {}       # last snapshot whose text parsed (names for completion)
        self.lint_findings: dict[str, tuple[str, list[Diagnostic]]] = {}
        self._pending: dict[str, asyncio.Task] = {}
        self._diagnosing: set[asyncio.Task] = set()    # every check not yet published (shutdown lets them finish)
        self._lint_tasks: dict[str, asyncio.Task] = {}
        self._executor = None
        from acl.lsp.checking import Checks

        self.checks = Checks(self.path_of, self._checked)
        self.snapshots: dict[str, Snapshot] = self.checks.snapshots     # uri -> its latest checked text
        self._lint_running: set[str] = set()
        self._collect_task: asyncio.Task | None = None
        self.collections = 0              # full garbage collections run in pauses
        from acl.lsp.background import Worker

        self.worker = Worker()            # long analyses (a large design's capsule hover), cancellable
        self._progress_seq = 0
        self.progress_started = 0         # background jobs shown as $/progress

    # ---------------------------------------------------------------------------------- state
    def path_of(self, uri: str) -> str:
        return to_fs_path(uri) or uri

    def document(self, uri: str):
        """The open document ``uri``; RequestFailed when the client has not opened it.

        Only documents the client opened are served (their text is the client's): a URI never opened
        is never read from disk (it could name a FIFO, /dev/zero or a file outside the workspace).
        Files a design imports are read by the loader under the rules of `acl check` (regular files
        under the design's folder, the stdlib or a search path, size-limited)."""
        from urllib.parse import unquote

        from acl.lsp.protocol import RequestFailed

        doc = self.workspace.text_documents.get(unquote(uri)) if isinstance(uri, str) else None
        if doc is None:
            shown = uri if len(uri) <= 200 else uri[:200] + "…"
            raise RequestFailed(f"E-LSP-DOCUMENT: `{shown}` is not open: the server answers only on documents "
                                "the editor opened (textDocument/didOpen)")
        return doc

    def is_open(self, uri: str) -> bool:
        from urllib.parse import unquote

        return unquote(uri) in self.workspace.text_documents

    def snapshot(self, uri: str, fresh: bool = False) -> Snapshot:
        """The checked state of the document's current text.

        The check runs on the checking thread; this waits for it at most ``checks.wait`` seconds
        (the event loop answers nothing meanwhile, so the wait is short). If it is not done by then,
        the last checked text answers (``fresh=False``: reading requests such as hover or symbols),
        or the request fails saying the server is still checking (``fresh=True``: requests whose
        answer edits the text must not be computed on an older one)."""
        doc = self.document(uri)
        return self.checks.snapshot(uri, doc.source, doc.version, fresh)

    def _checked(self, uri: str, snap: Snapshot) -> None:
        """A check ended (on the checking thread): the names of a text that parsed serve completion
        while later texts do not parse."""
        if not self.is_open(uri):
            return
        if snap.parsed and snap.env is not None:
            self.resolved[uri] = snap

    # ---------------------------------------------------------------------------------- diagnostics
    def schedule(self, uri: str, delay: float) -> None:
        old = self._pending.pop(uri, None)
        if old is not None:
            old.cancel()
        task = self._pending[uri] = asyncio.get_running_loop().create_task(self._diagnose(uri, delay))
        self._diagnosing.add(task)
        task.add_done_callback(self._diagnosing.discard)

    async def finish_checks(self, timeout: float = SHUTDOWN_WAIT_S) -> None:
        """Let the checks already asked for publish their diagnostics (at most ``timeout`` seconds): a document
        opened just before `shutdown` is still answered, as the client asked."""
        waiting = [t for t in self._diagnosing if not t.done()]
        if waiting:
            await asyncio.wait(waiting, timeout=timeout)

    async def _diagnose(self, uri: str, delay: float) -> None:
        if delay > 0:
            await asyncio.sleep(delay)
        self._pending.pop(uri, None)
        if not self.is_open(uri):          # closed meanwhile
            return
        doc = self.document(uri)
        try:
            snap = await asyncio.wrap_future(self.checks.start(uri, doc.source, doc.version))
            if snap is None or not self.is_open(uri) or snap.text != self.document(uri).source:
                return             # superseded by a newer text: its own check publishes
            self.publish(uri, snap, snap.diagnostics)
            self._warm_worker(snap)
            self.collect_when_idle()
        except Exception as exc:       # a bug must cost this document's diagnostics, not the server
            logging.getLogger("pygls").error("checking %s failed: %s: %s", uri, type(exc).__name__, exc)
            return
        finally:
            self.checks.resume_gc()    # the check's collections, now that its diagnostics are out
        if self.lint_enabled:
            self.schedule_lint(uri)

    def collect_when_idle(self, delay: float | None = None) -> None:
        """A full garbage collection once no check has ended for ``delay`` seconds.

        :func:`serve` turns automatic full collections off: with a large design open, each scans
        every object of its syntax tree and design (130 ms at 5,000 lines) and landed inside
        whichever request was running (documentSymbol took 30 or 160 ms). Young objects are still
        collected as usual; the old ones here, in a pause of the editing."""
        old = self._collect_task
        if old is not None:
            old.cancel()
        self._collect_task = asyncio.get_running_loop().create_task(
            self._collect(IDLE_COLLECT_SECONDS if delay is None else delay))

    async def _collect(self, delay: float) -> None:
        import gc

        await asyncio.sleep(delay)
        self._collect_task = None
        self.checks.resume_gc()          # in case a check ran with no publish waiting for it
        gc.collect()
        self.collections += 1

    def _warm_worker(self, snap: Snapshot) -> None:
        """Start the background worker (0.3 s to spawn, more to import) before the first hover
        that needs it: when a design is large enough to need it."""
        from acl.lsp.hover import INLINE_CAPSULES

        if snap.design is None or len(getattr(snap.design, "capsules", ())) <= INLINE_CAPSULES:
            return
        import threading

        from acl.lsp import formatting
        from acl.lsp.background import warm_document, warm_up

        def warm() -> None:
            if snap.text.count("\n") > formatting.PROCESS_LINES:
                formatting.warm_up()                   # the formatting process
            warm_up()                                  # this process's imports (the quick hover's)
            self.worker.get(("warm",), warm_up)        # and the worker's
            # the document's first text in the worker: its parse (later texts parse only their edits) and the
            # coupled modes a capsule's hover needs; once per path (an edit never cancels it)
            self.worker.get(("warm", snap.path), warm_document, snap.path, snap.text)

        threading.Thread(target=warm, daemon=True).start()

    def in_background(self, key: tuple, title: str, fn, *args):
        """``fn(*args)``'s result for ``key`` from the background worker if ready, else None, having
        started it (once). A job started here is shown as ``$/progress`` (begin, then end when it
        finishes or a newer edit cancels it) when the client supports ``window.workDoneProgress``."""
        worker = self.worker
        new = worker.future(key) is None and worker.peek(key) is None
        got = worker.get(key, fn, *args)
        fut = worker.future(key) if got is None and new else None
        if fut is None or not self._progress_supported():
            return got
        self._progress_seq += 1
        token = f"acl-background-{self._progress_seq}"
        loop = asyncio.get_running_loop()
        state = {"begun": False, "ended": None}

        def begin(*_args) -> None:           # the client accepted the token
            if state["ended"] is not None:   # finished (or cancelled) before the client answered
                return
            state["begun"] = True
            self.work_done_progress.begin(token, T.WorkDoneProgressBegin(title=title, message=args[0] if args else None,
                                                                         cancellable=False))

        def end(f) -> None:
            from concurrent.futures.process import BrokenProcessPool

            exc = None if f.cancelled() else f.exception()
            stopped = f.cancelled() or isinstance(exc, BrokenProcessPool)      # a newer edit stopped the worker
            state["ended"] = "cancelled (the document changed)" if stopped else "failed" if exc else "done"
            if state["begun"]:
                self.work_done_progress.end(token, T.WorkDoneProgressEnd(message=state["ended"]))

        try:
            self.work_done_progress.create(token, callback=begin)
        except Exception:                    # a client that cannot take it: the work goes on without
            return got
        fut.add_done_callback(lambda f: loop.call_soon_threadsafe(end, f))
        self.progress_started += 1
        return got

    def _progress_supported(self) -> bool:
        caps = getattr(self.client_capabilities, "window", None)
        return bool(caps is not None and getattr(caps, "work_done_progress", False))

    def report_server_error(self, error: Exception, source) -> None:
        """Errors outside a request's reply: one line on stderr (no pop-up in the editor); a failed
        request's reply says why, and pygls has logged it already."""
        from pygls.exceptions import FeatureRequestError

        if source is not FeatureRequestError:
            logging.getLogger("pygls").error("%s: %s", type(error).__name__, error)

    def publish(self, uri: str, snap: Snapshot, diags: list[Diagnostic]) -> None:
        self.text_document_publish_diagnostics(T.PublishDiagnosticsParams(
            uri=uri, version=snap.version, diagnostics=[to_lsp(d, snap) for d in diags]))

    def schedule_lint(self, uri: str) -> None:
        if uri in self._lint_running:
            return                # the running lint starts again when it sees the text changed
        old = self._lint_tasks.get(uri)
        if old is not None and not old.done():
            old.cancel()
        self._lint_tasks[uri] = asyncio.get_running_loop().create_task(self._lint(uri))

    async def _lint(self, uri: str) -> None:
        await asyncio.sleep(self.lint_delay)
        snap = self.snapshots.get(uri)
        if snap is None:
            return
        from acl.lsp.lint import lint_text

        loop = asyncio.get_running_loop()
        self._lint_running.add(uri)
        try:
            findings = await loop.run_in_executor(self._lint_executor(), lint_text, snap.path, snap.text)
        except Exception as exc:  # a broken worker must not take the server down
            self.window_log_message(T.LogMessageParams(type=T.MessageType.Warning,
                                                       message=f"acl lint failed: {type(exc).__name__}: {exc}"))
            return
        finally:
            self._lint_running.discard(uri)
        current = self.snapshots.get(uri)
        if current is None:
            return
        if current.text == snap.text:
            self.lint_findings[uri] = (snap.text, findings)
            self.publish(uri, current, findings)
        else:
            self._lint_tasks[uri] = loop.create_task(self._lint(uri))

    def _lint_executor(self):
        if self._executor is None:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor

            from acl.lsp.lint import lower_priority

            self._executor = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"),
                                                 initializer=lower_priority)
        return self._executor

    def close(self) -> None:
        from acl.lsp import formatting

        self.worker.stop()
        self.checks.stop()
        formatting.stop()
        if self._collect_task is not None:
            self._collect_task.cancel()
        for t in list(self._pending.values()) + list(self._lint_tasks.values()):
            t.cancel()
        if self._executor is not None:
            workers = list(getattr(self._executor, "_processes", {}).values())
            self._executor.shutdown(wait=False, cancel_futures=True)
            for w in workers:       # a rule run can take seconds: do not make the editor wait for it
                if w.is_alive():
                    w.terminate()
            self._executor = None

    def all_diagnostics(self, uri: str, snap: Snapshot) -> list[Diagnostic]:
        lint = self.lint_findings.get(uri)
        return lint[1] if lint and lint[0] == snap.text else snap.diagnostics


# ------------------------------------------------------------------------------------------------
# Conversions
# ------------------------------------------------------------------------------------------------

def to_lsp(d: Diagnostic, snap: Snapshot) -> T.Diagnostic:
    """An acl diagnostic as LSP: same code, range from its span, the hint appended as `help:`."""
    s = d.span
    message = d.message
    if s is not None and _same_file(s.file, snap.path):
        ln = max(0, s.line - 1)
        col = max(0, s.column - 1)
        if s.end_line is not None and s.end_column is not None and (s.end_line, s.end_column) > (s.line, s.column):
            end = (s.end_line - 1, s.end_column - 1)
        else:
            end = (ln, max(col + 1, len(snap.line(ln).rstrip())))
        rng = _range((ln, col, *end), snap.lines)
    else:       # in an imported file (or on the command line): shown on the import that reads it
        rng = _import_range(snap, s.file if s is not None else None)
        if s is not None:
            message = f"{s}: {message}"
    if d.hint:
        message += f"\nhelp: {d.hint}"
    for n in d.notes:
        message += f"\nnote: {n}"
    return T.Diagnostic(range=rng, message=message, severity=_SEVERITY.get(d.severity, T.DiagnosticSeverity.Error),
                        code=d.code, source="acl", data={"hint": d.hint} if d.hint else None,
                        code_description=_rule_doc(d.code))


def _rule_doc(code: str) -> T.CodeDescription | None:
    """A link to the rule's section of docs/rules.md (shipped with acl) for ACL codes."""
    if not code.startswith("ACL"):
        return None
    try:
        from acl._resources import shipped_dir

        return T.CodeDescription(href=from_fs_path(os.path.join(shipped_dir("docs"), "rules.md")) + "#" + code.lower())
    except (FileNotFoundError, ImportError):
        return None


def _import_range(snap: Snapshot, file: str | None) -> T.Range:
    """The range of the document's import (or extends) that leads to ``file``; else line 1."""
    from acl.lsp.structure import import_targets

    if file is not None:
        for st, target, _ in import_targets(snap):
            if _same_file(target.file, file):
                ln = st.span.line - 1
                return _range((ln, st.span.column - 1, ln, len(snap.line(ln).rstrip())), snap.lines)
    return T.Range(start=T.Position(line=0, character=0), end=T.Position(line=0, character=0))


def _same_file(a: str, b: str) -> bool:
    return a == b or (os.path.exists(a) and os.path.exists(b) and os.path.samefile(a, b))


def _no_names(snap: Snapshot) -> bool:
    """True when the snapshot knows no names (then the last one that parsed serves)."""
    return snap.env is None or (not snap.parsed and not snap.env.module.statements)


# Positions: acl counts characters (code points); LSP clients count in the negotiated encoding
# (UTF-16 unless the client offers another). Lines of ASCII need no conversion.
_ENCODING = "utf-16"


def _units(text: str) -> int:
    if _ENCODING == "utf-32" or text.isascii():
        return len(text)
    if _ENCODING == "utf-8":      # lone surrogates (JSON allows `\ud800`) count as the 3 bytes WTF-8 gives them
        return len(text.encode("utf-8", "surrogatepass"))
    return len(text.encode("utf-16-le", "surrogatepass")) // 2


def col_out(lines, line: int, col: int) -> int:
    """Code-point column ``col`` of ``line`` in the client's units."""
    text = lines[line] if 0 <= line < len(lines) else ""
    return col if text.isascii() else _units(text[:col])


def col_in(lines, line: int, units: int) -> int:
    """Client-unit column ``units`` of ``line`` as a code-point column."""
    text = lines[line] if 0 <= line < len(lines) else ""
    if text.isascii() or _ENCODING == "utf-32":
        return units
    n = 0
    for i, ch in enumerate(text):
        if n >= units:
            return i
        n += _units(ch)
    return len(text)


def at(snap: Snapshot, pos: T.Position) -> tuple[int, int]:
    """A client position as (line, code-point column), clamped into the document (a position past
    the end, line 2147483647 say, means its end, as the protocol says)."""
    lines = snap.lines or [""]
    line = min(max(pos.line, 0), len(lines) - 1)
    if pos.line >= len(lines):
        return line, len(lines[line])
    return line, min(col_in(lines, line, max(pos.character, 0)), len(lines[line]))


def _range(t, lines=None) -> T.Range:
    """(line, char, end_line, end_char) in code points -> an LSP Range (client units when ``lines`` given)."""
    a, b, c, d = t
    if lines is not None:
        b, d = col_out(lines, a, b), col_out(lines, c, d)
    return T.Range(start=T.Position(line=a, character=b), end=T.Position(line=c, character=d))


# ------------------------------------------------------------------------------------------------
# Features
# ------------------------------------------------------------------------------------------------

server = AclLanguageServer()

_COMPLETION_KIND = {"keyword": T.CompletionItemKind.Keyword, "key": T.CompletionItemKind.Property,
                    "unit": T.CompletionItemKind.Unit, "name": T.CompletionItemKind.Variable,
                    "module": T.CompletionItemKind.Module, "member": T.CompletionItemKind.Field,
                    "function": T.CompletionItemKind.Function}


#: initializationOptions: name -> (check, what it must be)
_OPTIONS = {
    "debounce": (lambda v: _seconds(v), "a number of seconds from 0 to 10"),
    "lint": (lambda v: isinstance(v, bool), "true or false"),
    "lint_delay": (lambda v: _seconds(v), "a number of seconds from 0 to 10"),
}


def _seconds(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and 0 <= v <= 10


def read_options(opts) -> tuple[dict, list[str]]:
    """The valid ``initializationOptions`` and a warning for each one ignored (never an error:
    a bad option must not fail ``initialize``)."""
    if opts is None:
        return {}, []
    if not isinstance(opts, dict):
        return {}, [f"initializationOptions must be an object, not {type(opts).__name__}: ignored"]
    good, warnings = {}, []
    for k, v in opts.items():
        rule = _OPTIONS.get(k)
        if rule is None:
            warnings.append(f"initializationOptions: unknown option `{k}` ignored (known: {', '.join(_OPTIONS)})")
        elif not rule[0](v):
            shown = repr(v) if len(repr(v)) <= 40 else repr(v)[:40] + "…"
            warnings.append(f"initializationOptions: `{k}` must be {rule[1]}, not {shown}: the default is used")
        else:
            good[k] = v
    return good, warnings


@server.feature(T.INITIALIZE)
def _initialize(ls: AclLanguageServer, params: T.InitializeParams) -> None:
    global _ENCODING
    enc = ls.workspace.position_encoding
    _ENCODING = str(getattr(enc, "value", enc) or "utf-16").lower()
    opts, warnings = read_options(params.initialization_options)
    ls.debounce = float(opts.get("debounce", ls.debounce))
    ls.lint_enabled = bool(opts.get("lint", ls.lint_enabled))
    ls.lint_delay = float(opts.get("lint_delay", ls.lint_delay))
    for w in warnings:
        logging.getLogger("pygls").warning("%s", w)
        ls.window_log_message(T.LogMessageParams(type=T.MessageType.Warning, message=f"acl lsp: {w}"))


@server.feature(T.SHUTDOWN)
async def _shutdown(ls: AclLanguageServer, *args) -> None:
    await ls.finish_checks()
    ls.close()


@server.feature(T.TEXT_DOCUMENT_DID_OPEN)
async def _did_open(ls: AclLanguageServer, params: T.DidOpenTextDocumentParams) -> None:
    ls.schedule(params.text_document.uri, 0.0)


@server.feature(T.TEXT_DOCUMENT_DID_CHANGE)
async def _did_change(ls: AclLanguageServer, params: T.DidChangeTextDocumentParams) -> None:
    from acl.lsp.background import text_key

    uri = params.text_document.uri
    if ls.is_open(uri):        # a newer text: older background work is cancelled
        ls.worker.forget(uri, keep=text_key(ls.document(uri).source))
    ls.schedule(uri, ls.debounce)


@server.feature(T.TEXT_DOCUMENT_DID_SAVE)
async def _did_save(ls: AclLanguageServer, params: T.DidSaveTextDocumentParams) -> None:
    ls.schedule(params.text_document.uri, 0.0)


@server.feature(T.TEXT_DOCUMENT_DID_CLOSE)
def _did_close(ls: AclLanguageServer, params: T.DidCloseTextDocumentParams) -> None:
    uri = params.text_document.uri
    ls.worker.forget(uri)
    ls.checks.forget(uri)
    for store in (ls.snapshots, ls.resolved, ls.lint_findings):
        store.pop(uri, None)
    for tasks in (ls._pending, ls._lint_tasks):
        t = tasks.pop(uri, None)
        if t is not None:
            t.cancel()
    ls.text_document_publish_diagnostics(T.PublishDiagnosticsParams(uri=uri, diagnostics=[]))


@server.feature(T.TEXT_DOCUMENT_HOVER)
def _hover(ls: AclLanguageServer, params: T.HoverParams) -> T.Hover | None:
    from acl.lsp.hover import hover

    snap = ls.snapshot(params.text_document.uri)
    if _no_names(snap):
        snap = ls.resolved.get(params.text_document.uri, snap)
    pos = params.position
    line, col = at(snap, pos)
    got = hover(snap, line, col, quick=True)
    if got is None:
        return None
    text, (ln, a, b) = got
    from acl.lsp.background import PENDING_NOTE, hover_text, text_key

    if text.endswith(PENDING_NOTE):    # the rest comes from the worker; answer now with what is quick
        full = ls.in_background((params.text_document.uri, text_key(snap.text), "hover", ln, a),
                                "acl: coupled modes", hover_text, snap.path, snap.text, line, col)
        if full is not None:
            text = full
    return T.Hover(contents=T.MarkupContent(kind=T.MarkupKind.Markdown, value=text),
                   range=_range((ln, a, ln, b), snap.lines))


@server.feature(T.TEXT_DOCUMENT_DEFINITION)
def _definition(ls: AclLanguageServer, params: T.DefinitionParams) -> T.Location | None:
    from acl.lsp.definition import definition

    snap = ls.snapshot(params.text_document.uri)
    if _no_names(snap):
        snap = ls.resolved.get(params.text_document.uri, snap)
    pos = params.position
    got = definition(snap, *at(snap, pos))
    if got is None:
        return None
    path, rng, lines = got
    return T.Location(uri=from_fs_path(path) or path, range=_range(rng, lines))


@server.feature(T.TEXT_DOCUMENT_COMPLETION, T.CompletionOptions(trigger_characters=["."], resolve_provider=True))
def _completion(ls: AclLanguageServer, params: T.CompletionParams) -> T.CompletionList:
    import re

    from acl.lsp.completion import complete

    uri = params.text_document.uri
    snap = ls.snapshot(uri, fresh=True)
    names = snap if not _no_names(snap) else ls.resolved.get(uri)
    line, col = at(snap, params.position)
    items = complete(snap, names, line, col)
    # each item replaces the word being typed (a unit's letters, a name after the last `.`)
    typed = re.search(r"[A-Za-z_\u00b5][\w\u00b5]*$", snap.line(line)[:col])
    start = typed.start() if typed else col
    rng = _range((line, start, line, col), snap.lines)
    out = []
    for label, kind, detail in items:
        new = f"{label} = " if kind == "key" else label
        out.append(T.CompletionItem(label=label, kind=_COMPLETION_KIND[kind], detail=detail,
                                    text_edit=T.TextEdit(range=rng, new_text=new),
                                    data={"uri": uri, "kind": kind, "label": label}))
    return T.CompletionList(is_incomplete=False, items=out)


@server.feature(T.COMPLETION_ITEM_RESOLVE)
def _completion_resolve(ls: AclLanguageServer, item: T.CompletionItem) -> T.CompletionItem:
    """The item's documentation, computed when the editor shows it (a unit's SI factor and
    dimension, a kind's role, a function's signature, a name's declaration)."""
    from acl.lsp.completion import documentation

    data = item.data if isinstance(item.data, dict) else {}
    uri = data.get("uri")
    snap = None
    if isinstance(uri, str) and ls.is_open(uri):
        snap = ls.snapshot(uri)
        if _no_names(snap):
            snap = ls.resolved.get(uri, snap)
    text = documentation(snap, str(data.get("kind", "")), str(data.get("label", item.label)))
    if text:
        item.documentation = T.MarkupContent(kind=T.MarkupKind.Markdown, value=text)
    return item


@server.feature(T.TEXT_DOCUMENT_DOCUMENT_SYMBOL)
def _symbols(ls: AclLanguageServer, params: T.DocumentSymbolParams) -> list[T.DocumentSymbol]:
    from acl.lsp.symbols import outline

    uri = params.text_document.uri
    snap = ls.snapshot(uri)
    if _no_names(snap):
        snap = ls.resolved.get(uri, snap)

    def conv(s: dict) -> T.DocumentSymbol:
        return T.DocumentSymbol(name=s["name"], detail=s["detail"], kind=T.SymbolKind(s["kind"]),
                                range=_range(s["range"], snap.lines), selection_range=_range(s["selection"], snap.lines),
                                children=[conv(c) for c in s["children"]])

    return [conv(s) for s in outline(snap)]


@server.feature(T.TEXT_DOCUMENT_CODE_ACTION, T.CodeActionOptions(
    code_action_kinds=[T.CodeActionKind.QuickFix, T.CodeActionKind.SourceOrganizeImports]))
def _code_action(ls: AclLanguageServer, params: T.CodeActionParams) -> list[T.CodeAction]:
    from acl.lsp.actions import fix
    from acl.syntax import ast as A

    uri = params.text_document.uri
    snap = ls.snapshot(uri, fresh=True)
    wanted = params.range
    # Only the server's own diagnostics are fixed, never a range the client sends back: a client may
    # count columns in another unit (Neovim 0.7 sent bytes) and a fix built on it corrupts the text.
    # The client's diagnostics, matched to ours by code and range, only select among them.
    sent = {(str(d.code), _key(d.range)) for d in (params.context.diagnostics or [])}
    own, seen = [], set()
    for d in ls.all_diagnostics(uri, snap):
        ld = to_lsp(d, snap)
        k = (str(ld.code), _key(ld.range))
        if k in seen:
            continue
        seen.add(k)
        if k in sent or _overlaps(ld.range, wanted):
            own.append(ld)
    candidates = own
    only = params.context.only
    wants = (lambda kind: not only or any(kind == k or kind.startswith(k + ".") for k in only))
    actions = []
    if not wants(T.CodeActionKind.QuickFix):
        candidates = []
    for d in candidates:
        hint = d.data.get("hint") if isinstance(d.data, dict) else None
        if hint is None and "\nhelp: " in d.message:
            hint = d.message.split("\nhelp: ", 1)[1].split("\n")[0]
        r = d.range
        if r.start.line != r.end.line:
            continue
        ln = r.start.line
        got = fix(snap.line(ln), col_in(snap.lines, ln, r.start.character), col_in(snap.lines, ln, r.end.character), hint)
        if got is None:
            continue
        a, b, new = got
        edit = T.TextEdit(range=_range((ln, a, ln, b), snap.lines), new_text=new)
        actions.append(T.CodeAction(title=f"Replace `{snap.line(r.start.line)[a:b]}` with `{new}` ({d.code})",
                                    kind=T.CodeActionKind.QuickFix, diagnostics=[d], is_preferred=True,
                                    edit=T.WorkspaceEdit(changes={uri: [edit]})))
    # organize imports formats the file (0.6 s on 1,000 lines): only when asked for source actions
    # or when the range touches an import (the lightbulb asks on every cursor move)
    on_import = snap.env is not None and any(
        isinstance(st, A.Import) and wanted.start.line <= st.span.line - 1 <= wanted.end.line
        for st in snap.env.module.statements)
    if wants(T.CodeActionKind.SourceOrganizeImports) and (only or on_import):
        from acl.lsp.features import organize_imports

        got = organize_imports(snap, uri)
        if got is not None:
            actions.append(got)
    return actions


def _key(r: T.Range) -> tuple[int, int, int, int]:
    return r.start.line, r.start.character, r.end.line, r.end.character


def _overlaps(a: T.Range, b: T.Range) -> bool:
    """Whether ranges ``a`` and ``b`` share a line (a quick fix is offered anywhere on its line)."""
    return a.start.line <= b.end.line and b.start.line <= a.end.line


@server.feature(T.TEXT_DOCUMENT_FORMATTING)
async def _formatting(ls: AclLanguageServer, params: T.DocumentFormattingParams) -> list[T.TextEdit] | None:
    from acl.lsp.formatting import format_edits

    from acl.lsp.features import formatted_soon

    snap = ls.snapshot(params.text_document.uri, fresh=True)
    await formatted_soon(snap)             # acl fmt, in the formatting process: 0.9 s on 5,000 lines
    got = format_edits(snap, wait=None)
    if got is None:
        return None
    return [T.TextEdit(range=_range(r, snap.lines), new_text=t) for r, t in got]


class _OneLine(logging.Handler):
    """pygls's own log records (a message it cannot read, a handler that raised) as one coded line
    each on stderr, located at the body of the latest message read (``<stdin>:line:1``); the
    exception's type and text replace its traceback (`acl -v lsp` shows everything)."""

    def __init__(self, stream) -> None:
        super().__init__(logging.WARNING)
        self.stream = stream

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = record.getMessage()
            if text.startswith("Unable to deserialize message"):
                return          # pygls logs "Unable to handle message" next, with the same cause
            text = text.split("Traceback (most recent call last)", 1)[0]
            exc = record.exc_info[1] if record.exc_info else None
            if exc is not None:
                text += f": {type(exc).__name__}: {exc}"
                cause = exc.__cause__
                if cause is not None:
                    text += f" ({type(cause).__name__}: {cause})"
            text = " ".join(text.split())
            if len(text) > 400:
                text = text[:400] + "…"
            code = "E-LSP-MESSAGE" if record.levelno >= logging.ERROR else "W-LSP-MESSAGE"
            kind = "error" if record.levelno >= logging.ERROR else "warning"
            print(f"acl lsp: {self.stream.location()}: {kind}[{code}]: {text}", file=sys.stderr, flush=True)
        except Exception:       # logging must never take the server down
            pass


def serve(verbose: bool = False) -> None:
    """Speak LSP over stdin/stdout until the client exits (input checked by :mod:`acl.lsp.stream`)."""
    from acl.lsp.stream import FramedInput, LockedOutput

    out = LockedOutput(sys.stdout.buffer)
    stream = FramedInput(sys.stdin.buffer, reply=out.send)
    if not verbose:      # pygls, asyncio and futures log tracebacks: one coded line each instead
        for name in ("pygls", "asyncio", "concurrent.futures"):
            log = logging.getLogger(name)
            log.handlers[:] = [_OneLine(stream)]
            log.propagate = False
    import gc

    gc.collect()
    gc.freeze()                          # the imported modules: never scanned again
    th = gc.get_threshold()
    gc.set_threshold(th[0], th[1], 1 << 30)   # full collections only in pauses (collect_when_idle)
    server.checks.pause_gc = True        # and none inside a check: after its diagnostics are published
    try:
        server.start_io(stream, out)
    finally:
        server.close()

from acl.lsp import features as _features  # noqa: E402,F401  (registers the requests of issue 27)
from acl.lsp import lenses as _lenses  # noqa: E402,F401  (code lenses and commands)

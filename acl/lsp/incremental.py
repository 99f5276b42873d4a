"""Incremental parsing for the editor: re-parse only the top-level statements whose text changed.

A document is cut into top-level statements with the parser's own statement chunker (the one its
error recovery uses); each chunk is parsed at its real line offset, so spans are exactly those of
a whole-file parse, and cached by its text with the line it was parsed at.  A keystroke re-parses
one statement instead of the file; a line inserted or deleted (Enter, Backspace at a line's start,
a paste of lines, a statement moved) moves the statements after it, whose cached trees are then
shifted by the lines it added (:func:`acl.syntax.ast.shift_lines`, 7x cheaper than parsing them
again) instead of being parsed again.  When any chunk does not parse,
:meth:`IncrementalParser.parse` returns None and the caller parses the whole file the usual way
(which reports the syntax errors).  The result is handed to the loader through its parse cache, so
resolution is unchanged.
"""
from __future__ import annotations

from acl.diagnostics import DiagnosticError
from acl.syntax import ast as A


class IncrementalParser:
    def __init__(self) -> None:
        # chunk text -> (the line it was parsed at, its statements): a chunk met again at another
        # line (the lines above it inserted or deleted, or the statement moved) is shifted
        # (:func:`acl.syntax.ast.shift_lines`), not parsed again
        self._cache: dict[str, tuple[int, tuple]] = {}
        self._deltas: dict[str, int] = {}        # line text -> bracket depth change (parser.depth_delta)
        # the last text that parsed whole: its lines and its chunks [(start, end, text, statements)]
        self._last: tuple[list[str], list[tuple]] | None = None
        self.stats = {"parsed": 0, "shifted": 0, "kept": 0}     # chunks, in the last parse

    def _chunks(self, lines: list[str]):
        """The parser's statement chunks (:func:`acl.syntax.parser.statement_chunks`), with the
        bracket depth of each line text remembered between edits; the boundaries are the same."""
        from acl.syntax import parser as P

        deltas = self._deltas
        if len(deltas) > 200_000:
            deltas.clear()

        def delta(line: str) -> int:
            d = deltas.get(line)
            if d is None:
                d = deltas[line] = P.depth_delta(line)
            return d

        yield from P.statement_chunks(lines, delta)

    def parse(self, text: str, file: str) -> A.Module | None:
        """The syntax tree of ``text`` (equal to :func:`acl.syntax.parser.parse_module`'s), or None."""
        return self._parse(text, file, partial=False)

    def parse_partial(self, text: str, file: str) -> A.Module | None:
        """The statements of ``text`` that parse, skipping broken ones: names for editor features
        while the user is typing (never used for diagnostics)."""
        return self._parse(text, file, partial=True)

    def _parse(self, text: str, file: str, partial: bool) -> A.Module | None:
        if file != getattr(self, "_file", file):
            self._cache, self._last = {}, None    # spans carry the file name
        self._file = file
        stats = {"parsed": 0, "shifted": 0, "kept": 0}
        try:
            from lark.exceptions import UnexpectedInput

            from acl.syntax import parser as P

            # the parser's limits (:func:`acl.syntax.parser.check_limits`): size and NUL on the whole
            # text; nesting per statement chunk, when it is parsed (a chunk that parses has balanced
            # brackets, so each starts at depth 0 as in the whole-file scan, which took 18 ms on
            # 5,000 lines at every edit). Over a limit: the whole-file parse reports it.
            if "\x00" in text or len(text.encode("utf-8", errors="replace")) > P.MAX_SOURCE_BYTES:
                return None
            src = text if text.endswith("\n") else text + "\n"
            lines = src.split("\n")
            fresh: dict[str, tuple[int, tuple]] = {}
            stmts: list = []
            chunks: list[tuple] = []
            head, tail, resume = self._unchanged(lines)
            for c in head:                         # the chunks before the edit, as they were
                fresh[c[2]] = (c[0], c[3])
                stmts.extend(c[3])
            chunks.extend(head)
            stats["kept"] = len(head)
            for start, end in self._chunks_from(lines, resume):
                if tail is not None and start in tail:
                    rest = tail.moved(start, end)
                    if rest is not None:           # past the edit, cut where it was: the same chunks,
                        for c in rest:             # moved by the lines the edit added or removed
                            fresh[c[2]] = (c[0], c[3])
                            stmts.extend(c[3])
                        chunks.extend(rest)
                        stats["shifted" if tail.delta else "kept"] += len(rest)
                        break
                chunk = "\n".join(lines[start:end])
                hit = self._cache.get(chunk)
                got = None
                if hit is not None:                # the same statement text, parsed at another line
                    try:
                        got = A.shift_lines(hit[1], start - hit[0])
                        stats["shifted" if start != hit[0] else "kept"] += 1
                    except TypeError:              # pragma: no cover - a tree value shift_lines does not know
                        got = None
                if got is None:
                    try:
                        P.check_limits(chunk, file)
                        tree = P.lark_parser().parse("\n" * start + chunk + "\n", start="start")
                        got = P.build_module(tree, file, text)
                        stats["parsed"] += 1
                    except (UnexpectedInput, DiagnosticError):
                        if not partial:
                            raise
                        continue
                fresh[chunk] = (start, got)
                stmts.extend(got)
                chunks.append((start, end, chunk, got))
        except (UnexpectedInput, DiagnosticError, AttributeError, ImportError, TypeError):
            return None           # syntax errors (or a parser without these helpers): whole-file parse
        self._cache = fresh
        self.stats = stats
        if not partial:
            self._last = (lines, chunks)
        return A.Module(file, tuple(stmts), text)

    def _chunks_from(self, lines: list[str], resume: int):
        """The chunks of ``lines`` from line ``resume`` (a chunk start of the last text, with the
        same lines before it: the chunker starts there at depth 0, as it would have)."""
        if resume == 0:
            yield from self._chunks(lines)
            return
        for start, end in self._chunks(lines[resume:]):
            yield start + resume, end + resume

    def _unchanged(self, lines: list[str]):
        """What the last text that parsed gives this one without re-chunking: (the chunks wholly
        before the first changed line, the later chunks past the last changed line (a :class:`_Tail`,
        moved by the lines the edit added or removed), the line to resume chunking at).

        A chunk ends where its brackets close, without looking at the next line (one that parses
        has balanced brackets), so a chunk ending before the first changed line is cut the same way;
        after the edit, once a chunk starts and ends where one did in the last text (counting the
        lines added or removed), with the same lines from there on, the rest are cut the same way
        too. Joining and hashing every chunk's text was 20-30 ms of each 5,000-line check."""
        last = self._last
        if last is None:
            return [], None, 0
        old_lines, old_chunks = last
        n = min(len(lines), len(old_lines))
        p = 0
        while p < n and lines[p] == old_lines[p]:
            p += 1
        head = []
        for c in old_chunks:
            if c[1] > p:
                break
            head.append(c)
        resume = head[-1][1] if head else 0
        q = 0                                      # lines equal from the end (not into the first p)
        while q < n - p and lines[-1 - q] == old_lines[-1 - q]:
            q += 1
        delta = len(lines) - len(old_lines)
        first = len(old_lines) - q                 # the first line of the equal end, in the last text
        tail = _Tail([c for c in old_chunks[len(head):] if c[0] >= first], delta)
        return head, tail, resume


class _Tail:
    """The last text's chunks after an edit, looked up by where they start in the new text
    (their start in the last text plus ``delta``, the lines the edit added)."""

    def __init__(self, chunks: list[tuple], delta: int) -> None:
        self.chunks = chunks
        self.delta = delta
        self.index = {c[0] + delta: i for i, c in enumerate(chunks)}

    def __contains__(self, start: int) -> bool:
        return start in self.index

    def moved(self, start: int, end: int) -> list[tuple] | None:
        """The chunks from the one starting at line ``start`` of the new text, if that one ends at
        ``end`` there too, each moved to its line in the new text; else None."""
        i = self.index[start]
        rest = self.chunks[i:]
        d = self.delta
        if rest[0][1] + d != end:
            return None
        if not d:
            return rest
        return [(s + d, e + d, t, A.shift_lines(st, d)) for s, e, t, st in rest]


def prime(module: A.Module, text: str, file: str) -> None:
    """Hand a parsed module to the loader's parse cache (:func:`acl.design.modules._parse_cached`)."""
    from acl.design import modules

    if len(modules.PARSED_MODULES) > 512:
        modules.PARSED_MODULES.clear()
    modules.PARSED_MODULES[(file, text)] = module


def partial_env(parser: IncrementalParser, text: str, file: str, search_paths=()):
    """A module environment (names, imports) of the statements of ``text`` that parse, or None.

    Loaded under a key the real check never uses (the text plus a NUL), so it cannot leak into
    diagnostics; the loader's own diagnostics are discarded.
    """
    from acl.design.modules import Loader
    from acl.diagnostics import DiagnosticBag

    module = parser.parse_partial(text, file)
    if module is None:
        return None
    key = text + "\x00"
    prime(module, key, file)
    try:
        return Loader(DiagnosticBag(), search_paths).load_text(key, file)
    except DiagnosticError:
        return None

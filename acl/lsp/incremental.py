"""Incremental parsing for the editor: re-parse only the top-level statements whose text changed.

A document is cut into top-level statements with the parser's own statement chunker (the one its
error recovery uses); each chunk is parsed at its real line offset, so spans are exactly those of
a whole-file parse, and cached by (first line, text).  A keystroke re-parses one statement instead
of the file.  When any chunk does not parse, :meth:`IncrementalParser.parse` returns None and the
caller parses the whole file the usual way (which reports the syntax errors).  The result is handed
to the loader through its parse cache, so resolution is unchanged.
"""
from __future__ import annotations

from acl.diagnostics import DiagnosticError
from acl.syntax import ast as A


class IncrementalParser:
    def __init__(self) -> None:
        self._cache: dict[tuple[int, str], tuple] = {}
        self._deltas: dict[str, int] = {}        # line text -> bracket depth change (parser._depth_delta)

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
                d = deltas[line] = P._depth_delta(line)
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
            self._cache = {}                      # spans carry the file name
        self._file = file
        try:
            from lark.exceptions import UnexpectedInput

            from acl.syntax import parser as P

            # the parser's limits (:func:`acl.syntax.parser._check_limits`): size and NUL on the whole
            # text; nesting per statement chunk, when it is parsed (a chunk that parses has balanced
            # brackets, so each starts at depth 0 as in the whole-file scan, which took 18 ms on
            # 5,000 lines at every edit). Over a limit: the whole-file parse reports it.
            if "\x00" in text or len(text.encode("utf-8", errors="replace")) > P.MAX_SOURCE_BYTES:
                return None
            src = text if text.endswith("\n") else text + "\n"
            lines = src.split("\n")
            fresh: dict[tuple[int, str], tuple] = {}
            stmts: list = []
            for start, end in self._chunks(lines):
                chunk = "\n".join(lines[start:end])
                key = (start, chunk)
                hit = self._cache.get(key)
                if hit is None:
                    try:
                        P._check_limits(chunk, file)
                        tree = P._lark().parse("\n" * start + chunk + "\n", start="start")
                        hit = P._build(tree, file, text)
                    except (UnexpectedInput, DiagnosticError):
                        if not partial:
                            raise
                        continue
                fresh[key] = hit
                stmts.extend(hit)
        except (UnexpectedInput, DiagnosticError, AttributeError, ImportError):
            return None           # syntax errors (or a parser without these helpers): whole-file parse
        self._cache = fresh
        return A.Module(file, tuple(stmts), text)


def prime(module: A.Module, text: str, file: str) -> None:
    """Hand a parsed module to the loader's parse cache (:func:`acl.design.modules._parse_cached`)."""
    from acl.design import modules

    if len(modules._PARSED) > 512:
        modules._PARSED.clear()
    modules._PARSED[(file, text)] = module


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

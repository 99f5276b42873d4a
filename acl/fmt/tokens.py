"""Source text -> the parser's own token stream, with the comments and line breaks between tokens.

The tokens come from acl's grammar driven by its LALR parser (lark's contextual lexer), so a
formatter working on them sees exactly what the parser sees: `-x` is a direction where the parser
reads one and a minus elsewhere, `2.1e-5 m^2/s` is one quantity.  Everything the grammar ignores
(spaces, comments, backslash continuations) and newlines lie in the gaps between tokens; a small
exact scan of each gap recovers them.
"""
from __future__ import annotations

import bisect
import re
from dataclasses import dataclass

from acl.diagnostics import DiagnosticError, Span, error

# What may lie between two tokens: only what the grammar ignores, and newlines.
_GAP = re.compile(r"(?P<cont>\\[ \t\f]*\r?\n)|(?P<comment>#[^\n]*)|(?P<nl>\r?\n)|(?P<ws>[ \t\f]+)")


@dataclass(frozen=True)
class Tok:
    """One token: `type` is the grammar's terminal name, or COMMENT, NL, CONT for gap items."""

    type: str
    text: str
    line: int      # 1-based
    column: int    # 1-based


def tokenize(source: str, file: str = "<stdin>") -> list[Tok]:
    """The token stream of a source text that parses, with gap items (COMMENT, NL, CONT) in place.

    The text must already parse (call :func:`acl.syntax.parser.parse_module` first): a parse
    error here raises the parser's diagnostics.
    """
    from lark.exceptions import UnexpectedInput

    from acl.syntax.parser import _lark, parse_module

    text = source if source.endswith("\n") else source + "\n"
    try:
        ip = _lark().parse_interactive(text, start="start")
        raw = ip.exhaust_lexer()
        ip.feed_eof(raw[-1] if raw else None)
    except UnexpectedInput:
        parse_module(source, file)   # raises the located diagnostics
        raise  # pragma: no cover - parse_module accepted what lark rejected
    newlines = [i for i, ch in enumerate(text) if ch == "\n"]
    out: list[Tok] = []
    pos = 0
    for t in raw:
        if t.type == "_NL":   # newlines are taken from the gaps, with the comments between them
            continue
        _gap(text, pos, t.start_pos, out, file, newlines)
        out.append(Tok(t.type, t.value, t.line, t.column))
        pos = t.end_pos
    _gap(text, pos, len(text), out, file, newlines)
    return out


_KINDS = {"cont": "CONT", "comment": "COMMENT", "nl": "NL"}


def _gap(text: str, start: int, end: int, out: list[Tok], file: str, newlines: list[int]) -> None:
    pos = start
    while pos < end:
        m = _GAP.match(text, pos, end)
        line = bisect.bisect_left(newlines, pos) + 1
        col = pos - (newlines[line - 2] + 1 if line >= 2 else 0) + 1
        if m is None or m.end() == pos:   # pragma: no cover - the grammar ignores nothing else
            raise DiagnosticError([error("E190", f"internal formatter error: cannot place {text[pos]!r}",
                                         Span(file=file, line=line, column=col), "please report it")])
        if m.lastgroup != "ws":
            out.append(Tok(_KINDS[m.lastgroup], m.group(), line, col))
        pos = m.end()

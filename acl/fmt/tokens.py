"""Source text -> the parser's own tokens, with the comments and line breaks between them.

The tokens come from acl's grammar driven by its LALR parser (lark's contextual lexer): every
named terminal (names, numbers, quantities, strings, directions, comparisons, `..`, `log`) is a
leaf of the parse tree, so a formatter sees exactly what the parser saw: `-x` is a direction
where the parser read one and a minus elsewhere, `at` is a key in `at = (0, 0, z)` and a keyword
in `follow ... at 10 um/s`, `2.1e-5 m^2/s` is one quantity. Between two leaves lie only what the
grammar ignores (spaces, comments, backslash continuations), newlines, and its keywords and
punctuation, which one small exact scan recovers.
"""
from __future__ import annotations

import bisect
import re
from dataclasses import dataclass

from acl.diagnostics import DiagnosticError, Span, error

# What may lie between two leaves of the parse tree.
_GAP = re.compile(r"(?P<cont>\\[ \t\f]*\r?\n)|(?P<comment>#[^\n]*)|(?P<nl>\r?\n)|(?P<ws>[ \t\f]+)"
                  r"|(?P<word>[A-Za-z_][A-Za-z0-9_]*)|(?P<punct>\.\.|\+-|±|[{}()\[\],.=+\-*/^@])")
_KINDS = {"cont": "CONT", "comment": "COMMENT", "nl": "NL", "word": "KEYWORD"}
_PUNCT = {"{": "LBRACE", "}": "RBRACE", "(": "LPAR", ")": "RPAR", "[": "LSQB", "]": "RSQB", ",": "COMMA",
          ".": "DOT", "=": "EQUAL", "+": "PLUS", "-": "MINUS", "*": "STAR", "/": "SLASH", "^": "CIRCUMFLEX",
          "@": "AT", "..": "RANGE", "+-": "PM", "±": "PM"}   # `+-`/`±`: the grammar's filtered _PM terminal


@dataclass(frozen=True)
class Tok:
    """One token. `type` is the grammar's terminal name for named terminals (NAME, QUANTITY,
    NUMBER, STRING, DIRECTION, CMP, RANGE, LOG), KEYWORD for other words, a punctuation name
    (LBRACE, LPAR, MINUS, ...), or COMMENT, NL, CONT for what lies between tokens."""

    type: str
    text: str
    line: int      # 1-based
    column: int    # 1-based


def tokenize(source: str, file: str = "<stdin>", tree=None) -> list[Tok]:
    """The token stream of a source text, with comments, newlines and continuations in place.

    ``tree``: the lark tree of ``source`` when the caller has it (:func:`acl.syntax.parser.parse_module_tree`),
    else it is parsed here. Text that does not parse raises the parser's located diagnostics (DiagnosticError).
    """
    from lark import Token, Tree
    from lark.exceptions import UnexpectedInput

    from acl.syntax.parser import lark_parser, parse_module

    text = source if source.endswith("\n") else source + "\n"
    if tree is None:
        try:
            tree = lark_parser().parse(text, start="start")
        except UnexpectedInput:
            parse_module(source, file)   # raises the located diagnostics
            raise DiagnosticError([error("E190", "internal formatter error: the parser and the formatter disagree",
                                         Span(file=file, line=1, column=1), "please report it")]) from None
    newlines = [m.start() for m in re.finditer("\n", text)]
    out: list[Tok] = []
    pos = 0
    stack = [tree]
    while stack:   # the leaves in source order, without recursion (nesting may be deep)
        node = stack.pop()
        if isinstance(node, Tree):
            stack.extend(reversed(node.children))
        elif isinstance(node, Token) and node.type != "_NL":
            _gap(text, pos, node.start_pos, out, file, newlines)
            out.append(Tok(node.type, node.value, node.line, node.column))
            pos = node.end_pos
    _gap(text, pos, len(text), out, file, newlines)
    return out


def _gap(text: str, start: int, end: int, out: list[Tok], file: str, newlines: list[int]) -> None:
    pos = start
    while pos < end:
        m = _GAP.match(text, pos, end)
        line = bisect.bisect_left(newlines, pos) + 1
        col = pos - (newlines[line - 2] + 1 if line >= 2 else 0) + 1
        if m is None or m.end() == pos:   # pragma: no cover - nothing else lies between tokens
            raise DiagnosticError([error("E190", f"internal formatter error: cannot place {text[pos]!r}",
                                         Span(file=file, line=line, column=col), "please report it")])
        kind = m.lastgroup
        if kind == "punct":
            out.append(Tok(_PUNCT[m.group()], m.group(), line, col))
        elif kind != "ws":
            out.append(Tok(_KINDS[kind], m.group(), line, col))
        pos = m.end()

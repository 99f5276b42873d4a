"""Token stream -> canonical text: the one layout of an acl file.

Line breaks are the author's (as gofmt keeps them); everything else is canonical:

* indentation: 2 spaces per `{ }` level; inside `( )`/`[ ]` a wrapped line lines up after the
  bracket, or, when the bracket ends its line, sits 2 spaces in from that line; a line continued
  with `\\` is indented 4 spaces from its statement;
* spacing: one space between tokens and around `=`, `..`, `@`, comparisons and the binary
  operators `+ - * /`; none inside brackets, before `,`, around `.` and `^`, after a unary
  minus, or between a function name and its `(`; a quantity is its number, one space, its unit;
* blank lines: at most one in a row, none at the start or end of the file or just inside a
  bracket or block; a top-level block that spans several lines (a declaration or a program) has
  one blank line before it (above the comments that introduce it) and one after it;
* imports: each run of consecutive single-line imports is sorted (stdlib and module imports by
  dotted name, then file imports by path);
* comments: kept, each on its line, with a space after the `#` (`#note` becomes `# note`;
  `#!`, `#:` and `##` are left alone); own-line comments take their line's indentation; the
  trailing comments of consecutive lines line up, two spaces after the longest code.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

from acl.fmt.tokens import Tok

INDENT = 2          # per { } level
HANG = 2            # a bracket's content when the bracket ends its line
CONTINUATION = 4    # a line continued with a backslash, from its statement's indentation
COMMENT_GAP = 2     # spaces between code and a trailing comment

_OPERAND_END = {"NAME", "NUMBER", "QUANTITY", "STRING", "DIRECTION", "RPAR", "RSQB"}
_NUMBER = re.compile(r"(\d+\.\d+|\d+\.(?!\.)|\.\d+|\d+)([eE][+-]?\d+)?")
_IMPORT = re.compile(r'import\s+("[^"]*"|[A-Za-z0-9_.]+)(?:\s+as\s+([A-Za-z0-9_]+))?')


@dataclass
class _Line:
    indent: int = 0
    code: str = ""
    comment: str | None = None
    stmt: int | None = None          # the top-level statement the line belongs to
    top_comment: bool = False        # a comment on its own line between top-level statements
    blank_before: bool = False


@dataclass
class _Bracket:
    col: int                  # output column of the bracket
    base: int                 # indentation of the line it opens on
    after: int                # length of that line's code just after the bracket
    hanging: bool | None = None


@dataclass
class _Stmt:
    first: int
    last: int
    block: bool = False
    is_import: bool = False


class _Builder:
    def __init__(self) -> None:
        self.lines: list[_Line] = []
        self.stmts: list[_Stmt] = []
        self.cur: _Line | None = None
        self.blank = False            # a blank line seen since the last line
        self.depth = 0                # open { }
        self.brackets: list[_Bracket] = []
        self.cont = False             # the previous line ended with a backslash
        self.stmt_indent = 0
        self.prev: Tok | None = None
        self.prev_unary = False
        self.pow_spaced = False       # the last `^` is spaced (after a quantity)

    # ---- gap items
    def newline(self) -> None:
        if self.cur is not None:
            self.flush()
        elif self.cont:   # `\` joined its line to an empty one, which ends the statement: drop it
            self.lines[-1].code = self.lines[-1].code[:-2]
            self.cont = False
        else:
            self.blank = True

    def comment(self, text: str) -> None:
        if self.cur is not None:
            self.cur.comment = text
            return
        inside = self.depth > 0 or bool(self.brackets) or self.cont
        self.cur = _Line(self.indent_for(None), comment=text,
                         stmt=len(self.stmts) - 1 if inside and self.stmts else None, top_comment=not inside)

    def continuation(self) -> None:
        if self.cur is not None and self.cur.code:
            self.cur.code += " \\"
            self.flush()
            self.cont = True

    # ---- tokens
    def token(self, t: Tok) -> None:
        if self.cur is None:
            indent = self.indent_for(t)
            starts = not self.brackets and not self.cont
            if starts:
                self.stmt_indent = indent
                if self.depth == 0:
                    self.stmts.append(_Stmt(len(self.lines), len(self.lines), is_import=t.type == "KEYWORD" and t.text == "import"))
            self.cur = _Line(indent, stmt=len(self.stmts) - 1 if self.stmts else None)
            sep = ""
        else:
            sep = self.space(t)
        line = self.cur
        line.code += sep + self.text(t)
        kind = t.type
        if kind in ("LPAR", "LSQB"):
            self.brackets.append(_Bracket(line.indent + len(line.code) - 1, line.indent, len(line.code)))
        elif kind in ("RPAR", "RSQB") and self.brackets:
            self.brackets.pop()
        elif kind == "LBRACE":
            self.depth += 1
            if self.stmts:
                self.stmts[-1].block = True
        elif kind == "RBRACE":
            self.depth = max(0, self.depth - 1)
        if kind == "CIRCUMFLEX":
            self.pow_spaced = sep == " "
        self.prev_unary = kind == "MINUS" and (self.prev is None or self.prev.type not in _OPERAND_END)
        self.prev = t

    def indent_for(self, t: Tok | None) -> int:
        if self.brackets:
            b = self.brackets[-1]
            if t is not None and t.type in ("RPAR", "RSQB"):
                return b.base if b.hanging else b.col
            return b.base + HANG if b.hanging else b.col + 1
        if self.cont:
            return self.stmt_indent + CONTINUATION
        return INDENT * max(0, self.depth - (1 if t is not None and t.type == "RBRACE" else 0))

    def space(self, t: Tok) -> str:
        a, b = self.prev.type if self.prev else None, t.type
        if a in ("LPAR", "LSQB") or b in ("RPAR", "RSQB", "COMMA"):
            return ""
        if a == "DOT" or b == "DOT" or (a == "NAME" and b == "LPAR"):
            return ""
        if b == "CIRCUMFLEX":   # `3 um ^ 2` keeps its space: `3 um^2` would be one quantity
            return " " if a == "QUANTITY" else ""
        if a == "CIRCUMFLEX":
            return " " if self.pow_spaced else ""
        if self.prev_unary:     # `- x` keeps its space: `-x` would be a direction
            return " " if b == "NAME" and t.text in ("x", "y", "z") else ""
        return " "

    @staticmethod
    def text(t: Tok) -> str:
        if t.type == "QUANTITY":
            m = _NUMBER.match(t.text)
            unit = t.text[m.end():].strip() if m else ""
            return f"{m.group(0)} {unit}" if unit else t.text
        return t.text

    def flush(self) -> None:
        line, self.cur = self.cur, None
        for b in self.brackets:
            if b.hanging is None:
                b.hanging = len(line.code) == b.after
        line.blank_before, self.blank = self.blank, False
        self.lines.append(line)
        if line.stmt is not None and line.code:
            self.stmts[line.stmt].last = len(self.lines) - 1
        self.cont = False


def layout(tokens: list[Tok]) -> str:
    """Canonical text of a token stream from :func:`acl.fmt.tokens.tokenize`."""
    b = _Builder()
    for t in tokens:
        if t.type == "NL":
            b.newline()
        elif t.type == "COMMENT":
            b.comment(_comment(t.text))
        elif t.type == "CONT":
            b.continuation()
        else:
            b.token(t)
    if b.cur is not None:
        b.flush()
    lines = b.lines
    _sort_imports(lines, b.stmts)
    _blank_lines(lines, b.stmts)
    _align_comments(lines)
    return "".join(_render(line) for line in lines)


def _comment(text: str) -> str:
    """`#note` becomes `# note`; `#!`, `#:`, `##...` and comments already spaced are kept."""
    text = text.rstrip()
    return "# " + text[1:] if len(text) > 1 and text[1] not in " \t#!:" else text


def _import_key(code: str):
    m = _IMPORT.match(code)
    if m is None:   # pragma: no cover - the grammar admits no other import
        return (2, code, "")
    what, alias = m.group(1), m.group(2) or ""
    return (1, what, alias) if what.startswith('"') else (0, what.lower(), what, alias)


def _sort_imports(lines: list[_Line], stmts: list[_Stmt]) -> None:
    def single_import(line: _Line) -> bool:
        if line.stmt is None or not line.code:
            return False
        s = stmts[line.stmt]
        return s.is_import and s.first == s.last and lines[s.first] is line
    i = 0
    while i < len(lines):
        if not single_import(lines[i]):
            i += 1
            continue
        j = i + 1
        while j < len(lines) and single_import(lines[j]) and not lines[j].blank_before:
            j += 1
        run = lines[i:j]
        flags = [line.blank_before for line in run]
        run.sort(key=lambda line: _import_key(line.code))
        for line, flag in zip(run, flags):
            line.blank_before = flag
        lines[i:j] = run
        i = j


def _blank_lines(lines: list[_Line], stmts: list[_Stmt]) -> None:
    for i, line in enumerate(lines):
        if i == 0 or line.code.startswith(("}", ")", "]")):
            line.blank_before = False
        elif lines[i - 1].code.endswith(("{", "(", "[")):
            line.blank_before = False
    for s in stmts:
        if not s.block or s.first == s.last:
            continue
        g = s.first
        while g > 0 and lines[g - 1].top_comment and not lines[g].blank_before:
            g -= 1
        if g > 0:
            lines[g].blank_before = True
        if s.last + 1 < len(lines):
            lines[s.last + 1].blank_before = True


def _align_comments(lines: list[_Line]) -> None:
    group: list[_Line] = []

    def close() -> None:
        if group:
            col = max(line.indent + len(line.code) for line in group) + COMMENT_GAP
            for line in group:
                line.comment = " " * (col - line.indent - len(line.code)) + line.comment
            group.clear()

    for line in lines:
        if line.blank_before or not (line.code and line.comment is not None):
            close()
        if line.code and line.comment is not None:
            group.append(line)
    close()


def _render(line: _Line) -> str:
    blank = "\n" if line.blank_before else ""
    if not line.code:
        return f"{blank}{' ' * line.indent}{line.comment}\n"
    return f"{blank}{' ' * line.indent}{line.code}{line.comment or ''}\n"

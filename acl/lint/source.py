"""Raw source text as lint sees it: comments, suppressions, block extents, declarations and uses.

The parser drops comments, so lint reads the text itself with a small lexical scan (strings, the
``#`` comments, braces and names).  It never needs the syntax tree: names the design declares and
where they are mentioned are enough for the declaration rules.

Suppression syntax: ``# acl: ignore[ACL101, ACL202] reason`` on a line applies to findings on that
line; on the line that opens a block (``capsule c {``, ``program p {``) to the whole block.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

SUPPRESSION = re.compile(r"acl\s*:\s*ignore\s*\[([^\]]*)\]\s*(.*)$", re.I)
NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
# the grammar's quantity token (a number and a unit, keywords excluded): its unit is not a name
QUANTITY = re.compile(
    r"(?<![A-Za-z0-9_.])(\d+\.\d+|\d+\.(?!\.)|\.\d+|\d+)([eE][+-]?\d+)?[ \t]*"
    r"(?!(for|in|to|at|on|with|free|limit|slew|margin|using|along|above|phase|like|as|log)\b)"
    r"[A-Za-z\u00b5\u03bc\u00b0\u2126%][A-Za-z0-9\u00b5\u03bc\u00b0\u2126%]*(\^-?\d+)?"
    r"([*/\u00b7][A-Za-z\u00b5\u03bc\u00b0\u2126%][A-Za-z0-9\u00b5\u03bc\u00b0\u2126%]*(\^-?\d+)?)*")
NUMBER_ONLY = re.compile(r"^\s*[-+]?(\d+\.\d*|\.\d+|\d+)([eE][+-]?\d+)?\s*$")
DECL_KINDS = ("medium", "material", "transducer", "generator", "amplifier", "capsule", "beam", "spring", "truss",
              "latch", "anchor")


@dataclass(frozen=True)
class Suppression:
    line: int                      # line of the comment
    column: int
    codes: tuple[str, ...]
    reason: str
    first: int                     # lines covered, inclusive
    last: int


@dataclass(frozen=True)
class Declaration:
    kind: str                      # a DECL_KINDS entry, "param", "import" or "program"
    name: str
    line: int
    column: int
    value: str = ""                # param: the expression text


@dataclass(frozen=True)
class Use:
    name: str
    line: int
    column: int
    block: str | None              # kind of the innermost enclosing block (``capsule``, ``cavity``, ``program``)
    key: str | None                # key of the assignment the name appears in, if any
    statement: str                 # first word of the statement (``param``, ``require``, ``drive``...)
    statement_name: str | None     # for ``param NAME = ...``: NAME
    before: str                    # code text before the name on its line


@dataclass
class SourceFile:
    path: str
    text: str
    lines: list[str] = field(default_factory=list)
    code: list[str] = field(default_factory=list)   # lines with comments and string contents blanked
    suppressions: list[Suppression] = field(default_factory=list)
    blocks: dict[int, int] = field(default_factory=dict)   # opening line -> closing line (outermost)
    declarations: list[Declaration] = field(default_factory=list)
    uses: list[Use] = field(default_factory=list)


def scan(path: str, text: str) -> SourceFile:
    src = SourceFile(path, text, text.splitlines())
    comments: list[tuple[int, int, str]] = []
    for i, line in enumerate(src.lines, 1):
        code, comment, col = _split(line)
        src.code.append(code)
        if comment is not None:
            comments.append((i, col, comment))
    _blocks(src)
    for line, col, comment in comments:
        m = SUPPRESSION.search(comment)
        if not m:
            continue
        codes = tuple(c.strip().upper() for c in m.group(1).split(",") if c.strip())
        last = src.blocks.get(line, line)
        src.suppressions.append(Suppression(line, col, codes, m.group(2).strip(), line, last))
    _names(src)
    return src


def _split(line: str) -> tuple[str, str | None, int]:
    """(code with string contents blanked, comment text or None, comment column)."""
    if '"' not in line:                 # no string: the code ends at the first '#'
        j = line.find("#")
        return (line, None, 0) if j < 0 else (line[:j], line[j + 1:], j + 1)
    out = []
    in_str = False
    for j, ch in enumerate(line):
        if in_str:
            out.append('"' if ch == '"' else " ")
            in_str = ch != '"'
            continue
        if ch == '"':
            in_str = True
            out.append(ch)
        elif ch == "#":
            return "".join(out), line[j + 1:], j + 1
        else:
            out.append(ch)
    return "".join(out), None, 0


def _blocks(src: SourceFile) -> None:
    stack: list[int] = []
    for i, code in enumerate(src.code, 1):
        for ch in code:
            if ch == "{":
                stack.append(i)
            elif ch == "}" and stack:
                opened = stack.pop()
                if opened != i:
                    src.blocks[opened] = max(src.blocks.get(opened, i), i)


_PARAM = re.compile(r"^\s*param\s+([A-Za-z_]\w*)\s*=(?!=)\s*(.*?)\s*(?:free\b.*)?$")
_IMPORT = re.compile(r"^\s*import\s+(?:([\w.]+)|\"[^\"]*\")(?:\s+as\s+([A-Za-z_]\w*))?")
_DECL = re.compile(r"^\s*([A-Za-z_]\w*)\s+([A-Za-z_]\w*)\s*(?:like\s+[\w.]+\s*)?\{")
_PROGRAM = re.compile(r"^\s*program\s+([A-Za-z_]\w*)\s*\{")
_KEY = re.compile(r"([A-Za-z_]\w*)\s*=(?!=)")
_BRACE = re.compile(r"[{}]")


def _names(src: SourceFile) -> None:
    """Top-level declarations and every mention of a name (outside comments, strings and units)."""
    depth = 0
    kinds: list[str] = []          # kinds of open blocks
    statement, stmt_name = "", None
    for i, code in enumerate(src.code, 1):
        skip: set[int] = set()     # columns (0-based) of declaring names on this line
        if depth == 0:
            stripped = code.strip()
            m = _PARAM.match(code)
            if m:
                src.declarations.append(Declaration("param", m.group(1), i, code.index(m.group(1)) + 1, m.group(2)))
                skip.add(code.index(m.group(1)))
            m2 = _IMPORT.match(code)
            if m2:
                alias = m2.group(2) or (m2.group(1).split(".")[-1] if m2.group(1) else None)
                if alias:
                    src.declarations.append(Declaration("import", alias, i, 1))
                skip.update(range(len(code)))          # nothing on an import line is a use
            m3 = _PROGRAM.match(code) or None
            if m3:
                src.declarations.append(Declaration("program", m3.group(1), i, code.index(m3.group(1)) + 1))
                skip.add(code.index(m3.group(1), code.index("program") + 7))
            else:
                m4 = _DECL.match(code)
                if m4 and m4.group(1) in DECL_KINDS:
                    col = code.index(m4.group(2), m4.end(1))
                    src.declarations.append(Declaration(m4.group(1), m4.group(2), i, col + 1))
                    skip.add(col)
            if stripped:
                first = NAME.match(stripped)
                statement = first.group(0) if first else ""
                pm = _PARAM.match(code)
                stmt_name = pm.group(1) if pm else None
        masked = QUANTITY.sub(lambda m: " " * len(m.group(0)), code)
        braces = [b.start() for b in _BRACE.finditer(masked)]      # only braces change the block context
        nb = 0
        for m in NAME.finditer(masked):
            start = m.start()
            # braces before this name change the block context
            while nb < len(braces) and braces[nb] < start:
                depth = _brace(masked, braces[nb], depth, kinds)
                nb += 1
            if start in skip:
                continue
            before = masked[:start].rstrip()
            after = masked[m.end():].lstrip()
            if before.endswith("."):
                continue                                    # member: arm.tip, pbs.water
            if after.startswith("=") and not after.startswith("=="):
                continue                                    # a key or a declared name
            if m.group(0) in ("like",) or (m.group(0) in ("x", "y", "z") and masked[start - 1:start] in ("+", "-")):
                continue                                    # a keyword, or a direction such as +x
            keys = list(_KEY.finditer(masked[:start]))
            src.uses.append(Use(m.group(0), i, start + 1, kinds[-1] if kinds else None,
                                keys[-1].group(1) if keys else None, statement, stmt_name, masked[:start]))
        for j in braces[nb:]:
            depth = _brace(masked, j, depth, kinds)


def _brace(line: str, j: int, depth: int, kinds: list[str]) -> int:
    """Track block nesting at ``line[j]``; a block's kind is the first word of its opening statement."""
    ch = line[j]
    if ch == "{":
        head = re.split(r"[{},]", line[:j])[-1]
        m = re.match(r"\s*([A-Za-z_]\w*)", head)
        kinds.append(m.group(1) if m else "")
        return depth + 1
    if ch == "}":
        if kinds:
            kinds.pop()
        return max(0, depth - 1)
    return depth

"""Requests on a document's structure: folding and selection ranges, document links for imports,
signature help, semantic tokens and inlay hints. Pure functions of a :class:`Snapshot`; ranges in
code points, 0-based (the server converts them to the client's units)."""
from __future__ import annotations

import functools
import os
import re

from acl.lsp.document import NAME_RE, Snapshot, code_part, resolve_name
from acl.syntax import ast as A

# ------------------------------------------------------------------------------------------------
# Folding and selection
# ------------------------------------------------------------------------------------------------


def _nodes(snap: Snapshot):
    """(node, depth) of statements, nested blocks and program steps, outermost first."""
    if snap.env is None:
        return

    def walk(node, depth):
        yield node, depth
        if isinstance(node, A.Block):
            for e in node.entries:
                yield from walk(e, depth + 1)
        elif isinstance(node, A.ProgramDecl):
            for s in node.steps:
                yield from walk(s, depth + 1)
        elif isinstance(node, A.UncertaintyDecl):
            for e in node.entries:
                yield from walk(e, depth + 1)

    for st in snap.env.module.statements:
        yield from walk(st, 0)


def _span_range(span) -> tuple[int, int, int, int]:
    end_line = (span.end_line or span.line) - 1
    end_col = (span.end_column - 1) if span.end_column is not None else span.column
    return span.line - 1, span.column - 1, end_line, end_col


def folding(snap: Snapshot) -> list[tuple[int, int, str | None]]:
    """(start line, end line, kind) of each block, program, run of comments and run of imports."""
    out = []
    for node, _ in _nodes(snap):
        span = getattr(node, "span", None)
        if span is not None and (span.end_line or span.line) > span.line:
            out.append((span.line - 1, span.end_line - 1, None))
    run = None
    for i, text in enumerate(snap.lines + [""]):
        if text.lstrip().startswith("#"):
            run = i if run is None else run
            continue
        if run is not None and i - 1 > run:
            out.append((run, i - 1, "comment"))
        run = None
    if snap.env is not None:
        imports = [st.span.line - 1 for st in snap.env.module.statements if isinstance(st, A.Import)]
        if len(imports) > 1 and imports[-1] > imports[0]:
            out.append((imports[0], imports[-1], "imports"))
    return sorted(set(out))


def selection(snap: Snapshot, line: int, character: int) -> list[tuple[int, int, int, int]]:
    """Ranges containing (line, character), innermost first: the word, the dotted name, each
    enclosing entry, block or statement, the whole document."""
    ranges = []
    code = code_part(snap.line(line))
    for m in re.finditer(r"[A-Za-z_][A-Za-z0-9_]*", code):
        if m.start() <= character <= m.end():
            ranges.append((line, m.start(), line, m.end()))
            break
    for m in NAME_RE.finditer(code):
        if m.start() <= character <= m.end():
            ranges.append((line, m.start(), line, m.end()))
            break
    stack = []
    for node, depth in _nodes(snap):
        span = getattr(node, "span", None)
        if span is None:
            continue
        r = _span_range(span)
        if r[:2] <= (line, character) <= r[2:]:
            stack.append((depth, r))
    for _, r in sorted(stack, key=lambda x: -x[0]):
        ranges.append(r)
    last = len(snap.lines) - 1
    ranges.append((0, 0, last, len(snap.line(last))))
    out = []
    for r in ranges:          # each must contain the previous one
        if not out or (r[:2] <= out[-1][:2] and out[-1][2:] <= r[2:] and r != out[-1]):
            out.append(r)
    return out


def declared_names(env, lines: list[str]) -> list[tuple[str, str, tuple[int, int, int]]]:
    """(name, kind, (line, a, b)) of each top-level declaration of ``env`` (params, blocks,
    programs, observations), for workspace symbols."""
    from acl.lsp.document import name_position

    out = []
    for st in env.module.statements:
        name = getattr(st, "name", None)
        if not name or not hasattr(st, "span"):
            continue
        kind = (st.kind if isinstance(st, A.Block) else "param" if isinstance(st, A.ParamDecl)
                else "program" if isinstance(st, A.ProgramDecl) else "observe" if isinstance(st, A.ObserveDecl) else "")
        if kind:
            out.append((name, kind, name_position(lines, st.span, name)))
    return out


# ------------------------------------------------------------------------------------------------
# Document links
# ------------------------------------------------------------------------------------------------

def import_targets(snap: Snapshot):
    """(statement, the module it resolved to, the text naming it) of each import and `extends` of the document
    whose target resolved."""
    env = snap.env
    if env is None:
        return
    for st in env.module.statements:
        if isinstance(st, A.Import):
            alias = st.alias or (st.module[-1] if st.module else None)
            tgt = env.imports.get(alias) if alias else None
            target = tgt[0] if isinstance(tgt, tuple) else tgt
            shown = f'"{st.file}"' if st.file is not None else ".".join(st.module or ())
        elif isinstance(st, A.Extends):
            target, shown = env.base, f'"{st.file}"'
        else:
            continue
        if target is not None:
            yield st, target, shown


def links(snap: Snapshot) -> list[tuple[tuple[int, int, int, int], str]]:
    """(range of the module name or quoted file, path) of each import and `extends` that resolved."""
    out = []
    for st, target, shown in import_targets(snap):
        if target.file.startswith("<"):
            continue
        ln = st.span.line - 1
        text = snap.line(ln)
        at = text.find(shown, st.span.column - 1)
        if at < 0:
            continue
        out.append(((ln, at, ln, at + len(shown)), os.path.abspath(target.file)))
    return out


# ------------------------------------------------------------------------------------------------
# Signature help
# ------------------------------------------------------------------------------------------------

#: function -> (parameters, what it gives); from acl/design/assemble.py (_observes, _requires)
#: and acl/design/programs.py (_path)
SIGNATURES = {
    "displacement": (("element", "direction"), "observe: displacement of a beam, capsule, latch or spring along +x/-y/..."),
    "position": (("capsule", "x|y|z"), "observe: one coordinate of a capsule's center"),
    "gap": (("a.orifice", "b.orifice"), "observe / require: distance between two orifices (m)"),
    "state": (("latch",), "observe: the state of a latch (a or b)"),
    "resonance": (("capsule", "mode = 1"), "require: a capsule's resonance (Hz); mode numbered from 1"),
    "separation": (("capsule", "capsule"), "require: distance between the first modes of two capsules (Hz), "
                                           "or between adjacent modes of one"),
    "margin": (("latch", "mode = 1"), "require: a latch's snap margin"),
    "line": (("(x, y)", "(x, y)"), "follow path: a straight line between two points"),
    "polyline": (("(x, y)", "(x, y)", "..."), "follow path: through at least two points"),
    "rectangle": (("width = ...", "height = ...", "center = (0, 0)"), "follow path: a rectangle"),
    "circle": (("radius = ...", "center = (0, 0)"), "follow path: a circle"),
    "text": (('"TEXT"', "height = ...", "center = (0, 0)"), "follow path: letters A-Z, digits, space, '-', '.'"),
    "csv": (('"file.csv"',), "follow path: x, y columns in lengths"),
}


def signature(snap: Snapshot, line: int, character: int) -> tuple[str, list[str], int, str] | None:
    """(label, parameter labels, active parameter, documentation) of the call around the cursor."""
    code = code_part(snap.line(line))[:character]
    depth, commas = 0, 0
    for i in range(len(code) - 1, -1, -1):
        ch = code[i]
        if ch in ")]":
            depth += 1
        elif ch in "([":
            if depth == 0:
                if ch == "[":
                    return None
                m = re.search(r"([A-Za-z_][A-Za-z0-9_]*)\s*$", code[:i])
                if m is None or m.group(1) not in SIGNATURES:
                    return None
                name = m.group(1)
                params, doc = SIGNATURES[name]
                keyword = re.search(r"([A-Za-z_]+)\s*=[^=,]*$", code[i + 1:])
                active = commas
                if keyword is not None:
                    for j, p in enumerate(params):
                        if p.startswith(keyword.group(1) + " ="):
                            active = j
                return f"{name}({', '.join(params)})", list(params), min(active, len(params) - 1), doc
            depth -= 1
        elif ch == "," and depth == 0:
            commas += 1
    return None


# ------------------------------------------------------------------------------------------------
# Semantic tokens
# ------------------------------------------------------------------------------------------------

TOKEN_TYPES = ["namespace", "class", "function", "variable", "property", "keyword", "number", "string",
               "comment", "operator", "type", "enumMember", "macro"]
TOKEN_MODIFIERS = ["declaration", "readonly", "defaultLibrary"]
_T = {t: i for i, t in enumerate(TOKEN_TYPES)}

_LEX = re.compile(r"""
    (?P<comment>\#.*)
  | (?P<string>"[^"\n]*"?)
  | (?P<dir>(?<![A-Za-z0-9_)\]])[+-][xyz]\b)
  | (?P<number>(?:\d+\.\d+|\d+\.(?!\.)|\.\d+|\d+)(?:[eE][+-]?\d+)?)(?P<unit>[ \t]*(?:[A-Za-z\u00b5\u03bc\u00b0\u2126%][A-Za-z0-9\u00b5\u03bc\u00b0\u2126%^*/·.-]*))?
  | (?P<name>[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)*)
  | (?P<op>\+-|±|\.\.|==|>=|<=|[-+*/^=<>@])
""", re.VERBOSE)


def _keywords() -> frozenset[str]:
    from acl.design.resolve import DECL_KINDS
    from acl.lsp.completion import STATEMENTS, STEPS

    return frozenset((*DECL_KINDS, *STATEMENTS, *STEPS, "like", "on", "as", "free", "for", "in", "at", "to",
                      "using", "limit", "slew", "margin", "log", "phase", "from"))


def semantic_tokens(snap: Snapshot) -> list[tuple[int, int, int, int, int]]:
    """(line, start, length, type index, modifier bits) of each token, in order."""
    from acl.units import UnitError, parse_unit

    keywords = _keywords()
    env = snap.env
    out = []
    known_units: dict[str, bool] = {}
    resolved: dict[tuple[str, ...], tuple[int, int]] = {}      # a name resolves once per request
    for ln, text in enumerate(snap.lines):
        for m in _LEX.finditer(text):
            kind = m.lastgroup if m.lastgroup != "unit" else "number"
            a = m.start()
            if m.group("comment") is not None:
                out.append((ln, a, len(m.group(0)), _T["comment"], 0))
            elif m.group("string") is not None:
                out.append((ln, a, len(m.group(0)), _T["string"], 0))
            elif m.group("dir") is not None:
                out.append((ln, a, 2, _T["enumMember"], 0))
            elif m.group("number") is not None:
                num = m.group("number")
                out.append((ln, a, len(num), _T["number"], 0))
                unit = (m.group("unit") or "").strip().rstrip(".")
                if unit and unit not in keywords:
                    if unit not in known_units:
                        try:
                            parse_unit(unit)
                            known_units[unit] = True
                        except (UnitError, ValueError, Exception):
                            known_units[unit] = False
                    if known_units[unit]:
                        out.append((ln, m.start("unit") + (len(m.group("unit")) - len(m.group("unit").lstrip())),
                                    len(unit), _T["type"], 0))
            elif m.group("name") is not None:
                out.extend(_name_tokens(env, ln, a, m.group(0), text, m.end(), keywords, resolved))
            elif kind == "op":
                out.append((ln, a, len(m.group(0)), _T["operator"], 0))
    return out


def _name_tokens(env, ln, start, dotted, text, end, keywords, resolved):
    parts = dotted.split(".")
    if len(parts) == 1 and dotted in keywords:
        return [(ln, start, len(dotted), _T["keyword"], 0)]
    after = text[end:].lstrip()
    if len(parts) == 1 and after.startswith("("):
        return [(ln, start, len(dotted), _T["function"], 4)]
    if len(parts) == 1 and re.match(r"=(?!=)", after) and not re.match(r"\s*(param|observe)\b", text):
        return [(ln, start, len(dotted), _T["property"], 0)]
    out, offset = [], start
    for k, p in enumerate(parts):
        key = tuple(parts[:k + 1])
        if key not in resolved:
            resolved[key] = _classify(env, list(key), k)
        typ, mods = resolved[key]
        out.append((ln, offset, len(p), typ, mods))
        offset += len(p) + 1
    return out


def _classify(env, parts: list[str], k: int) -> tuple[int, int]:
    """(token type, modifiers) of the name ``parts`` (its last part)."""
    t = resolve_name(env, parts) if env is not None else None
    if t is None:
        return (_T["property"], 0) if k else (_T["variable"], 0)
    if t.what == "module":
        typ, mods = _T["namespace"], 0
    elif t.what == "param":
        typ, mods = _T["variable"], 2
    elif t.what == "program":
        typ, mods = _T["function"], 0
    elif t.what == "point":
        typ, mods = _T["property"], 0
    else:
        typ, mods = _T["class"], 0
    if t.env is not env and _in_stdlib(t.env.file):
        mods |= 4
    return typ, mods


@functools.lru_cache(maxsize=256)
def _in_stdlib(path: str) -> bool:
    from acl.design.modules import stdlib_root

    return os.path.realpath(path).startswith(os.path.realpath(stdlib_root()) + os.sep)


# ------------------------------------------------------------------------------------------------
# Inlay hints
# ------------------------------------------------------------------------------------------------

MAX_RESONANCE_HINTS = 50       # capsules whose first resonance is shown (each is one small eigenproblem)


def inlay_hints(snap: Snapshot, first: int, last: int) -> list[tuple[int, int, str, str]]:
    """(line, character, label, tooltip) between lines ``first`` and ``last``: each param's SI value
    after its declaration, each capsule's first resonance after its name."""
    design = snap.design
    env = snap.env
    if design is None or env is None:
        return []
    out = []
    params = {p.name: p for p in design.params}
    capsules = {c.name: c for c in design.capsules}
    shown = 0
    for st in env.module.statements:
        ln = st.span.line - 1
        if not first <= ln <= last:
            continue
        end_ln = (st.span.end_line or st.span.line) - 1
        if isinstance(st, A.ParamDecl) and st.name in params:
            p = params[st.name]
            text = code_part(snap.line(end_ln)).rstrip()
            label = f" = {p.value:.6g} {p.unit}".rstrip()
            out.append((end_ln, len(text), label, "SI value (as the design resolves it)"))
        elif isinstance(st, A.Block) and st.kind == "capsule" and st.name in capsules and shown < MAX_RESONANCE_HINTS:
            shown += 1
            try:
                from acl.analysis import acoustics as AC

                modes = AC.capsule_modes(design, capsules[st.name])
            except Exception:
                continue
            if modes:
                text = snap.line(ln)
                at = re.search(r"\b" + re.escape(st.name) + r"\b", text)
                col = at.end() if at else len(text)
                out.append((ln, col, f" f1 = {modes[0].frequency_hz / 1e3:.1f} kHz",
                            "first predicted mode (as `acl analyze`)"))
    return out

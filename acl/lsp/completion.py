"""Completion: declaration kinds, keys of the block at the cursor, units of the key's dimension,
names in scope, members of a module or declaration, stdlib modules after `import`.

The context comes from the text before the cursor (the open blocks and the current line), so it
works while the document does not parse; names come from the last snapshot that resolved.
"""
from __future__ import annotations

import os
import re

from acl.lsp.document import Snapshot, code_part

STATEMENTS = ("import", "extends", "param", "use", "mount", "fix", "link", "observe", "require", "program",
              "uncertainty")
STEPS = ("drive", "sweep", "pause", "follow", "switch", "hold", "cross")
FUNCTIONS = ("displacement", "position", "gap", "state", "resonance", "separation", "margin",   # observe / require
             "circle", "rect", "csv",                                                  # sections, tables
             "line", "polyline", "rectangle", "text")                                  # follow paths
NESTED = {"capsule": ("cavity", "orifice")}
POINTS = {"beam": ("tip",), "latch": ("shuttle",), "spring": ("end",)}

_HEADER = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)[^{}]*$")


def enclosing_blocks(lines: list[str], line: int, character: int) -> list[str]:
    """Kinds of the blocks open at (line, character), outermost first (`program` for programs)."""
    stack: list[str] = []
    for n in range(0, line + 1):
        text = code_part(lines[n] if n < len(lines) else "")
        if n == line:
            text = text[:character]
        i = 0
        seg_start = 0
        while i < len(text):
            ch = text[i]
            if ch == '"':
                j = text.find('"', i + 1)
                i = len(text) if j < 0 else j + 1
                continue
            if ch == "{":
                header = text[seg_start:i].strip().lstrip(",").strip()
                m = re.match(r"[A-Za-z_][A-Za-z0-9_]*", header)
                stack.append(m.group(0) if m else "")
                seg_start = i + 1
            elif ch == "}":
                if stack:
                    stack.pop()
                seg_start = i + 1
            elif ch == ",":
                seg_start = i + 1
            i += 1
    return stack


def _units_of(unit: str | None) -> list[str]:
    from acl._unit_table import TABLE
    from acl.units import parse_unit_static

    want = parse_unit_static(unit) if unit is not None else None
    out = [u for u, (_f, d) in TABLE.items() if u.isascii() and (want is None or d == want)]
    return out


def _module_names() -> list[str]:
    from acl.design.modules import stdlib_modules

    return sorted("stdlib." + m for m in stdlib_modules())


def complete(snap: Snapshot, names_snap: Snapshot | None, line: int, character: int) -> list[tuple[str, str, str]]:
    """Candidates (label, kind, detail); kind is one of keyword, key, unit, name, module, member, function."""
    from acl.design.resolve import DECL_KINDS, SCHEMAS

    text = snap.line(line)
    before = text[:character]
    if len(code_part(before)) < len(before):
        return []                                            # in a comment
    env = (names_snap or snap).env
    stack = enclosing_blocks(snap.lines, line, character)
    top = stack[-1] if stack else None

    m = re.match(r"^\s*import\s+([\w.]*)$", before)
    if m:
        here = os.path.dirname(os.path.abspath(snap.path))
        sibs = []
        if os.path.isdir(here):
            sibs = sorted(f[:-4] for f in os.listdir(here)
                          if f.endswith(".acl") and os.path.join(here, f) != os.path.abspath(snap.path))
        return [(n, "module", "stdlib module") for n in _module_names()] + [(s, "module", "file next to this one") for s in sibs]
    if re.match(r"^\s*use\s+\w*$", before):
        return [("medium", "keyword", "use medium NAME"), ("transducer", "keyword", "use transducer NAME")]
    m = re.match(r"^\s*use\s+(medium|transducer)\s+[\w.]*$", before)
    if m:
        return _of_kind(env, m.group(1))
    m = re.search(r"([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*)\.(\w*)$", before)
    if m and not re.search(r"(?<![\w.])\d+\.\w*$", before):       # `12.` is a number, `c1.` a name
        return _members(env, m.group(1).split("."))
    # a unit after a number: of the key's dimension when the key is known
    m = re.search(r"(?:^|[^\w.])(\d+\.?\d*(?:[eE][+-]?\d+)?)\s*([A-Za-z\u00b5]*)$", before)
    if m:
        unit = None
        km = re.match(r"^\s*(?:[^=]*[,{]\s*)?(\w+)\s*=", before)
        if km and top in SCHEMAS and km.group(1) in SCHEMAS[top]:
            unit = SCHEMAS[top][km.group(1)].unit
        try:
            units = _units_of(unit)
        except KeyError:
            units = _units_of(None)
        return [(u, "unit", unit or "unit") for u in units]
    at_start = re.match(r"^\s*\w*$", before) or re.search(r"[{,]\s*\w*$", before)
    if at_start:
        if top is None:
            return [(k, "keyword", "declaration") for k in DECL_KINDS] + [(k, "keyword", "statement") for k in STATEMENTS]
        if top == "program":
            return [(k, "keyword", "program step") for k in STEPS]
        if top in SCHEMAS:
            keys = SCHEMAS[top]
            out = [(k, "key", _key_detail(v)) for k, v in keys.items()]
            out += [(k, "keyword", f"block in {top}") for k in NESTED.get(top, ())]
            return out
    return _scope(env)


def _key_detail(k) -> str:
    unit = f" [{k.unit or '1'}]" if k.unit is not None else ""
    return f"{k.kind}{unit}" + (" (required)" if k.required else "")


def _scope(env) -> list[tuple[str, str, str]]:
    out = []
    if env is not None:
        for alias, tgt in env.imports.items():
            out.append((alias, "module", "module" if not isinstance(tgt, tuple) else "imported declaration"))
        out += [(n, "name", "param") for n in env.params]
        out += [(n, "name", b.kind) for n, b in env.decls.items()]
        out += [(n, "name", "program") for n in env.programs]
    out += [(f, "function", "function") for f in FUNCTIONS]
    return out


def _of_kind(env, kind: str) -> list[tuple[str, str, str]]:
    out = []
    if env is None:
        return out
    out += [(n, "name", kind) for n, b in env.decls.items() if b.kind == kind]
    for alias, tgt in env.imports.items():
        if not isinstance(tgt, tuple):
            out += [(f"{alias}.{n}", "name", kind) for n, b in tgt.decls.items() if b.kind == kind]
    return out


def _members(env, parts: list[str]) -> list[tuple[str, str, str]]:
    from acl.lsp.document import resolve_name

    t = resolve_name(env, parts)
    if t is None:
        return []
    if t.what == "module":
        return [(n, "member", b.kind) for n, b in t.env.decls.items()] + [(n, "member", "param") for n in t.env.params]
    if t.what == "decl":
        blk = t.node
        if blk.kind == "capsule":
            return [(n, "member", "orifice") for n in _orifices(t.env, blk)]
        return [(p, "member", "point") for p in POINTS.get(blk.kind, ())]
    return []


def _orifices(env, blk, depth: int = 0) -> list[str]:
    """Orifice names of a capsule declaration, its `like` bases' included (base first)."""
    from acl.lsp.document import resolve_name

    names: list[str] = []
    if blk.like is not None and depth < 16:
        base = resolve_name(env, list(blk.like.parts))
        if base is not None and base.what == "decl":
            names = _orifices(base.env, base.node, depth + 1)
    for b in blk.blocks():
        if b.kind == "orifice" and b.name and b.name not in names:
            names.append(b.name)
    return names


def documentation(snap: Snapshot | None, kind: str, label: str) -> str | None:
    """Markdown shown beside a completion item (see the server's ``completionItem/resolve``)."""
    from acl.lsp.hover import KIND_DOCS

    if kind == "unit":
        from acl.lsp.hover import _quantity_text

        return _quantity_text(f"1 {label}")
    if kind == "function":
        from acl.lsp.structure import SIGNATURES

        if label in SIGNATURES:
            params, doc = SIGNATURES[label]
            return f"```acl\n{label}({', '.join(params)})\n```\n\n{doc}"
    if kind == "keyword" and label in KIND_DOCS:
        return f"**{label}**: {KIND_DOCS[label]}"
    if kind in ("name", "module", "member") and snap is not None and snap.env is not None:
        from acl.lsp.document import declaration_text, resolve_name

        t = resolve_name(snap.env, label.split("."))
        if t is not None and t.node is not None:
            return f"```acl\n{declaration_text(t.env, t.node)}\n```"
        if t is not None and t.what == "module":
            return f"module `{t.env.file}`"
    if kind == "key" and snap is not None:
        return None
    return None

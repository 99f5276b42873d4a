"""Go to definition: a name (through imports, into the stdlib), an import to its file, a
`like` base to its declaration, `arm.tip` to `arm`."""
from __future__ import annotations

import os

from acl.lsp.document import NAME_RE, Snapshot, code_part, name_position, part_at, resolve_name, source_lines, word_at
from acl.syntax import ast as A


def definition(snap: Snapshot, line: int, character: int) -> tuple[str, tuple[int, int, int, int], list[str]] | None:
    """(file path, (line, char, end_line, end_char), that file's lines) of the declaration under the cursor."""
    env = snap.env
    if env is None:
        return None
    code = code_part(snap.line(line))
    imp = _import_at(env, line)
    if imp is not None:
        alias = imp.alias or (imp.module[-1] if imp.module else None)
        tgt = env.imports.get(alias) if alias else None
        if tgt is not None:
            if isinstance(tgt, tuple):
                t = resolve_name(env, [alias])
                return _location(t) if t else None
            return tgt.file, (0, 0, 0, 0), []
        return None
    w = word_at(code, character, NAME_RE)
    if w is None:
        return None
    dotted, start, _ = w
    parts = dotted.split(".")
    upto = part_at(dotted, start, character) + 1
    t = resolve_name(env, parts[:upto])
    if t is None:
        return None
    if t.what == "module":
        return t.env.file, (0, 0, 0, 0), []
    return _location(t)


def _import_at(env, line: int):
    for st in env.module.statements:
        if isinstance(st, A.Import) and st.span.line - 1 <= line <= (st.span.end_line or st.span.line) - 1:
            return st
    return None


def _location(t) -> tuple[str, tuple[int, int, int, int], list[str]]:
    node = t.node
    name = t.name.split(".")[0]
    lines = source_lines(t.env)
    ln, a, b = name_position(lines, node.span, name)
    return os.path.abspath(t.env.file) if not t.env.file.startswith("<") else t.env.file, (ln, a, ln, b), lines

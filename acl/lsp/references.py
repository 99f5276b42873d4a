"""References, rename and highlights: every place a name resolves to the same declaration.

A declaration is identified by its file (real path), its kind and its name. Each name in a file is
resolved the way hover and definition resolve it (:func:`acl.lsp.document.resolve_name`, through
imports), part by part of a dotted name, so ``lib.gap`` in one file and ``gap`` in ``lib.acl``
are the same parameter, and ``arm`` in ``arm.tip`` is the beam ``arm``. Keys (``length = ...``
inside a block) and strings are not names.
"""
from __future__ import annotations

import os
import re

from acl.lsp.document import NAME_RE, Target, code_part, name_position, part_at, resolve_name, word_at

IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_KEY_AFTER = re.compile(r"\s*=(?!=)")


def target_at(env, lines: list[str], line: int, character: int) -> tuple[Target, tuple[int, int, int]] | None:
    """The declaration named at (line, character) and the range of that name part: (target, (line, a, b))."""
    if env is None or not 0 <= line < len(lines):
        return None
    code = code_part(lines[line])
    w = word_at(code, character, NAME_RE)
    if w is None or _in_string(code, w[1]):
        return None
    dotted, start, _ = w
    parts = dotted.split(".")
    k = part_at(dotted, start, character)
    t = resolve_name(env, parts[:k + 1])
    if t is None or t.what == "module":
        return None
    if t.what == "point":
        t = resolve_name(env, parts[:k + 1][:1] if len(parts) == 1 else parts[:k]) or t
        if t.what == "point":
            return None
    a = start + sum(len(p) + 1 for p in parts[:k])
    return t, (line, a, a + len(parts[k]))


def key(t: Target) -> tuple[str, str, str]:
    """What identifies a declaration across separate loads of its file."""
    f = t.env.file
    real = os.path.realpath(f) if not f.startswith("<") else f
    return real, t.what, t.name.split(".")[0]


def declaration(t: Target) -> tuple[str, tuple[int, int, int]]:
    """(file, (line, a, b)) of the declared name."""
    lines = t.env.module.source.split("\n") if t.env.module.source else []
    return t.env.file, name_position(lines, t.node.span, t.name.split(".")[0])


def occurrences(env, lines: list[str], want: tuple[str, str, str]) -> list[tuple[int, int, int]]:
    """(line, a, b) of every name in ``lines`` (the text of ``env``) that resolves to ``want``."""
    name = want[2]
    out = []
    for ln, text in enumerate(lines):
        if name not in text:
            continue
        code = code_part(text)
        for m in NAME_RE.finditer(code):
            if name not in m.group(0) or _in_string(code, m.start()):
                continue
            parts = m.group(0).split(".")
            offset = m.start()
            for k, p in enumerate(parts):
                if p == name:
                    t = resolve_name(env, parts[:k + 1])
                    if t is not None and t.what != "module" and key(t) == want:
                        if not (len(parts) == 1 and _KEY_AFTER.match(code, m.end()) and not _declares(code, m.start())):
                            out.append((ln, offset, offset + len(p)))
                        break
                offset += len(p) + 1
    return out


def _declares(code: str, start: int) -> bool:
    """Whether the name at ``start`` is declared there (``param x =``), not a key (``x = ...`` in a block)."""
    return bool(re.match(r"\s*(?:param(?:\s+free)?|observe)\s+$", code[:start]))


def _in_string(code: str, at: int) -> bool:
    return code.count('"', 0, at) % 2 == 1


def valid_new_name(new: str) -> str | None:
    """Why ``new`` cannot be a name (None when it can)."""
    from acl.design.resolve import DECL_KINDS
    from acl.lsp.completion import STATEMENTS, STEPS

    if not IDENT.fullmatch(new or ""):
        return f"`{new}` is not a name (letters, digits and `_`, not starting with a digit)"
    if new in (*DECL_KINDS, *STATEMENTS, *STEPS, "like", "on", "as", "free", "for", "to", "at", "by", "with", "in"):
        return f"`{new}` is a keyword"
    return None

"""Formatting: the whole document through `acl fmt` (:func:`acl.fmt.format_source`), as one edit.

A document with syntax errors is left alone (its diagnostics already say why), as `acl fmt` does.
`acl fmt` takes about 0.6 s on 1,000 lines: its result is kept per text (the last few), so
formatting, range formatting and organize imports on the same text format it once, and the
server runs it off the event loop.
"""
from __future__ import annotations

import threading
from collections import OrderedDict

from acl.diagnostics import DiagnosticError
from acl.lsp.document import Snapshot

_CACHE: "OrderedDict[tuple[str, str], str | None]" = OrderedDict()
_LOCK = threading.Lock()
_KEEP = 8


def formatted(text: str, path: str) -> str | None:
    """`acl fmt`'s text for ``text`` (None when it does not parse), from the cache when seen."""
    from acl.fmt import format_source

    key = (path, text)
    with _LOCK:
        if key in _CACHE:
            _CACHE.move_to_end(key)
            return _CACHE[key]
    try:
        new = format_source(text, path)
    except DiagnosticError:
        new = None
    with _LOCK:
        _CACHE[key] = new
        while len(_CACHE) > _KEEP:
            _CACHE.popitem(last=False)
    return new


_HUNKS: "OrderedDict[tuple[str, str], tuple]" = OrderedDict()


def hunks_of(text: str, path: str):
    """(old lines, new lines, hunks) of `acl fmt` on ``text`` (None when it does not parse); each hunk
    (i1, i2, j1, j2) replaces old lines i1..i2 by new lines j1..j2. Changed lines are split one by
    one where `acl fmt` keeps their number, so a range takes only its own lines. Kept per text."""
    import difflib

    key = (path, text)
    with _LOCK:
        if key in _HUNKS:
            return _HUNKS[key]
    new = formatted(text, path)
    if new is None:
        return None
    old_lines, new_lines = text.split("\n"), new.split("\n")
    hunks = []
    for op, i1, i2, j1, j2 in difflib.SequenceMatcher(None, old_lines, new_lines).get_opcodes():
        if op == "replace" and i2 - i1 == j2 - j1:
            hunks.extend((i1 + k, i1 + k + 1, j1 + k, j1 + k + 1) for k in range(i2 - i1))
        elif op != "equal":
            hunks.append((i1, i2, j1, j2))
    got = (old_lines, new_lines, hunks)
    with _LOCK:
        _HUNKS[key] = got
        while len(_HUNKS) > _KEEP:
            _HUNKS.popitem(last=False)
    return got


def format_edits(snap: Snapshot) -> list[tuple[tuple[int, int, int, int], str]] | None:
    """[(range, new text)] replacing the document with its canonical layout; [] if already formatted."""
    new = formatted(snap.text, snap.path)
    if new is None:
        return None
    if new == snap.text:
        return []
    lines = snap.text.split("\n")
    return [((0, 0, len(lines) - 1, len(lines[-1])), new)]

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


def format_edits(snap: Snapshot) -> list[tuple[tuple[int, int, int, int], str]] | None:
    """[(range, new text)] replacing the document with its canonical layout; [] if already formatted."""
    new = formatted(snap.text, snap.path)
    if new is None:
        return None
    if new == snap.text:
        return []
    lines = snap.text.split("\n")
    return [((0, 0, len(lines) - 1, len(lines[-1])), new)]

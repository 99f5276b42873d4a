"""Formatting: the whole document through `acl fmt` (:func:`acl.fmt.format_source`), as one edit.

A document with syntax errors is left alone (its diagnostics already say why), as `acl fmt` does.
"""
from __future__ import annotations

from acl.diagnostics import DiagnosticError
from acl.lsp.document import Snapshot


def format_edits(snap: Snapshot) -> list[tuple[tuple[int, int, int, int], str]] | None:
    """[(range, new text)] replacing the document with its canonical layout; [] if already formatted."""
    from acl.fmt import format_source

    try:
        new = format_source(snap.text, snap.path)
    except DiagnosticError:
        return None
    if new == snap.text:
        return []
    lines = snap.text.split("\n")
    return [((0, 0, len(lines) - 1, len(lines[-1])), new)]

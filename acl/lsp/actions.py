"""Code actions: a quick fix for every "did you mean `X`?" hint of a diagnostic.

The fix replaces, inside the diagnostic's range, the word closest to the suggestion (a range may
cover a whole dotted name such as `capsules.desing1`, of which only `desing1` is wrong).
"""
from __future__ import annotations

import difflib
import re

DID_YOU_MEAN = re.compile(r"did you mean `([^`]+)`\?")
_WORD = re.compile(r"[A-Za-z_\u00b5\u03bc][A-Za-z0-9_\u00b5\u03bc^/*]*")


def suggestion(hint: str | None) -> str | None:
    """The single replacement a hint proposes (None for hints such as "`MHz` (or `mHz`?)")."""
    m = DID_YOU_MEAN.search(hint or "")
    if not m or not re.fullmatch(r"[^\s`]+", m.group(1)):
        return None
    return m.group(1)


def fix(line_text: str, start: int, end: int, hint: str | None) -> tuple[int, int, str] | None:
    """(start, end, new text) on ``line_text`` that applies the hint's suggestion, or None."""
    new = suggestion(hint)
    if new is None:
        return None
    segment = line_text[start:end]
    words = list(_WORD.finditer(segment)) if segment else []
    if not words:
        return None
    if "." in new and new.replace(".", "") and segment.strip() and "." in segment:
        best = None       # a dotted suggestion replaces the whole dotted name
    else:
        best = max(words, key=lambda m: difflib.SequenceMatcher(None, m.group(0), new).ratio())
    if best is None:
        return start, end, new
    return start + best.start(), start + best.end(), new

"""A unified diff of a file and its formatted text that stays near-linear on large files.

difflib's SequenceMatcher looks for the longest common block by comparing every line of one
range with every line of the other: on a 10,000-line design where most lines change (indent,
spacing) that is quadratic (9.4 s of `acl fmt --check`).  Here the lines that occur exactly once
in both texts anchor the match (patience diff: longest increasing run of anchors, n log n); the
common prefix and suffix of each stretch between anchors are matched directly, and difflib
matches only the stretches left, when they are small.  The output is difflib's unified format.
"""
from __future__ import annotations

import bisect
import difflib
from collections import Counter

SMALL = 40_000     # difflib on a stretch of a x b lines only when a*b is at most this


class _AnchoredMatcher(difflib.SequenceMatcher):
    def get_matching_blocks(self):
        if self.matching_blocks is not None:
            return self.matching_blocks
        a, b = self.a, self.b
        found: list[tuple[int, int, int]] = []
        stack = [(0, len(a), 0, len(b))]
        while stack:
            alo, ahi, blo, bhi = stack.pop()
            while alo < ahi and blo < bhi and a[alo] == b[blo]:        # common prefix
                found.append((alo, blo, 1))
                alo, blo = alo + 1, blo + 1
            while alo < ahi and blo < bhi and a[ahi - 1] == b[bhi - 1]:  # common suffix
                ahi, bhi = ahi - 1, bhi - 1
                found.append((ahi, bhi, 1))
            if alo == ahi or blo == bhi:
                continue
            anchors = _anchors(a, alo, ahi, b, blo, bhi)
            if anchors:
                prev_a, prev_b = alo, blo
                for i, j in anchors:
                    found.append((i, j, 1))
                    stack.append((prev_a, i, prev_b, j))
                    prev_a, prev_b = i + 1, j + 1
                stack.append((prev_a, ahi, prev_b, bhi))
            elif (ahi - alo) * (bhi - blo) <= SMALL:
                sub = difflib.SequenceMatcher(None, a[alo:ahi], b[blo:bhi], autojunk=False)
                found.extend((alo + i, blo + j, n) for i, j, n in sub.get_matching_blocks() if n)
            # else: a large stretch with no line in common once: shown as replaced
        found.sort()
        merged: list[tuple[int, int, int]] = []
        for i, j, n in found:
            if merged and merged[-1][0] + merged[-1][2] == i and merged[-1][1] + merged[-1][2] == j:
                pi, pj, pn = merged[-1]
                merged[-1] = (pi, pj, pn + n)
            else:
                merged.append((i, j, n))
        merged.append((len(a), len(b), 0))
        self.matching_blocks = [difflib.Match(*m) for m in merged]
        return self.matching_blocks


def _anchors(a, alo, ahi, b, blo, bhi) -> list[tuple[int, int]]:
    """Pairs (i, j) of lines unique in both stretches and equal, in the longest run increasing in both."""
    ca = Counter(a[alo:ahi])
    cb = Counter(b[blo:bhi])
    where_b = {b[j]: j for j in range(blo, bhi) if cb[b[j]] == 1 and ca.get(b[j]) == 1}
    pairs = [(i, where_b[a[i]]) for i in range(alo, ahi) if a[i] in where_b]
    if not pairs:
        return []
    # longest increasing subsequence of the b positions (patience sorting)
    tails: list[int] = []        # smallest b position ending a run of each length
    tail_at: list[int] = []      # index into pairs of that run's end
    back = [-1] * len(pairs)
    for k, (_, j) in enumerate(pairs):
        pos = bisect.bisect_left(tails, j)
        if pos == len(tails):
            tails.append(j)
            tail_at.append(k)
        else:
            tails[pos] = j
            tail_at[pos] = k
        back[k] = tail_at[pos - 1] if pos else -1
    out = []
    k = tail_at[-1]
    while k != -1:
        out.append(pairs[k])
        k = back[k]
    return out[::-1]


def _range(start: int, stop: int) -> str:
    """A hunk's line range in unified format (as difflib writes it)."""
    length = stop - start
    first = start + 1
    if length == 1:
        return f"{first}"
    if not length:
        first -= 1
    return f"{first},{length}"


def unified_diff(a: list[str], b: list[str], fromfile: str, tofile: str, n: int = 3):
    """The lines of difflib.unified_diff(a, b, fromfile, tofile), matched by :class:`_AnchoredMatcher`."""
    started = False
    for group in _AnchoredMatcher(None, a, b, autojunk=False).get_grouped_opcodes(n):
        if not started:
            started = True
            yield f"--- {fromfile}\n"
            yield f"+++ {tofile}\n"
        first, last = group[0], group[-1]
        yield f"@@ -{_range(first[1], last[2])} +{_range(first[3], last[4])} @@\n"
        for tag, i1, i2, j1, j2 in group:
            if tag == "equal":
                yield from (" " + line for line in a[i1:i2])
                continue
            if tag in ("replace", "delete"):
                yield from ("-" + line for line in a[i1:i2])
            if tag in ("replace", "insert"):
                yield from ("+" + line for line in b[j1:j2])

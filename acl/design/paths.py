"""Path sampling: a :class:`~acl.design.model.PathSpec` -> evenly spaced planar waypoints.

Coordinates are metres relative to the followed capsule's rest position (as in PathSpec).  Text
paths use a small stroke font (A-Z, 0-9, a few signs) of polylines on a 4 x 6 grid; the pen cannot
lift (a capsule is always somewhere), so strokes are joined by travel moves, flagged
``drawn=False`` in the sampled path.  Pure numpy, no acl stage below design.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acl.design.model import PathSpec

# --------------------------------------------------------------------------------------------
# Stroke font: each glyph is a list of strokes, each stroke "x,y x,y ...", on a 4-wide, 6-high
# grid (baseline y = 0, cap height y = 6).  Letters advance by 6 units (4 + 2 spacing).
# --------------------------------------------------------------------------------------------

_O = "1,0 0,1 0,5 1,6 3,6 4,5 4,1 3,0 1,0"
_P = "0,0 0,6 3,6 4,5 4,4 3,3 0,3"
_GLYPHS_SRC: dict[str, tuple[str, ...]] = {
    "A": ("0,0 0,4 2,6 4,4 4,0", "0,3 4,3"),
    "B": ("0,0 0,6 3,6 4,5 4,4 3,3 0,3", "3,3 4,2 4,1 3,0 0,0"),
    "C": ("4,5 3,6 1,6 0,5 0,1 1,0 3,0 4,1",),
    "D": ("0,0 0,6 2,6 4,4 4,2 2,0 0,0",),
    "E": ("4,6 0,6 0,0 4,0", "0,3 3,3"),
    "F": ("4,6 0,6 0,0", "0,3 3,3"),
    "G": ("4,5 3,6 1,6 0,5 0,1 1,0 3,0 4,1 4,3 2,3",),
    "H": ("0,0 0,6", "0,3 4,3", "4,6 4,0"),
    "I": ("1,6 3,6", "2,6 2,0", "1,0 3,0"),
    "J": ("4,6 4,1 3,0 1,0 0,1",),
    "K": ("0,6 0,0", "4,6 0,2", "1,3 4,0"),
    "L": ("0,6 0,0 4,0",),
    "M": ("0,0 0,6 2,3 4,6 4,0",),
    "N": ("0,0 0,6 4,0 4,6",),
    "O": (_O,),
    "P": (_P,),
    "Q": (_O, "2,2 4,0"),
    "R": (_P, "2,3 4,0"),
    "S": ("4,5 3,6 1,6 0,5 0,4 1,3 3,3 4,2 4,1 3,0 1,0 0,1",),
    "T": ("0,6 4,6", "2,6 2,0"),
    "U": ("0,6 0,1 1,0 3,0 4,1 4,6",),
    "V": ("0,6 2,0 4,6",),
    "W": ("0,6 1,0 2,3 3,0 4,6",),
    "X": ("0,6 4,0", "4,6 0,0"),
    "Y": ("0,6 2,3 4,6", "2,3 2,0"),
    "Z": ("0,6 4,6 0,0 4,0",),
    "0": (_O, "0,1 4,5"),
    "1": ("1,5 2,6 2,0", "1,0 3,0"),
    "2": ("0,5 1,6 3,6 4,5 4,4 0,0 4,0",),
    "3": ("0,5 1,6 3,6 4,5 4,4 3,3 4,2 4,1 3,0 1,0 0,1", "1,3 3,3"),
    "4": ("3,0 3,6 0,2 4,2",),
    "5": ("4,6 0,6 0,3 3,3 4,2 4,1 3,0 0,0",),
    "6": ("4,5 3,6 1,6 0,5 0,1 1,0 3,0 4,1 4,2 3,3 0,3",),
    "7": ("0,6 4,6 1,0",),
    "8": ("1,3 0,4 0,5 1,6 3,6 4,5 4,4 3,3 1,3 0,2 0,1 1,0 3,0 4,1 4,2 3,3",),
    "9": ("4,3 1,3 0,4 0,5 1,6 3,6 4,5 4,1 3,0 1,0 0,1",),
    "-": ("1,3 3,3",),
    "+": ("0,3 4,3", "2,1 2,5"),
    ".": ("2,0 2,0.5",),
    "/": ("0,0 4,6",),
    " ": (),
}
GLYPH_WIDTH = 4.0
GLYPH_HEIGHT = 6.0
GLYPH_ADVANCE = 6.0


def _parse_stroke(src: str) -> np.ndarray:
    return np.array([[float(v) for v in p.split(",")] for p in src.split()], dtype=float)


GLYPHS: dict[str, tuple[np.ndarray, ...]] = {
    ch: tuple(_parse_stroke(s) for s in strokes) for ch, strokes in _GLYPHS_SRC.items()
}


def supported_characters() -> str:
    return "".join(sorted(GLYPHS))


def text_strokes(text: str, height: float, center: tuple[float, float] = (0.0, 0.0)) -> list[np.ndarray]:
    """The strokes (polylines, metres) of ``text`` with cap height ``height``, centred on ``center``.

    Raises KeyError naming the first character the font does not have (lower case is upper-cased).
    """
    scale = height / GLYPH_HEIGHT
    text = text.upper()
    width = (len(text) - 1) * GLYPH_ADVANCE + GLYPH_WIDTH if text else 0.0
    origin = np.array([center[0] - width * scale / 2, center[1] - height / 2])
    strokes: list[np.ndarray] = []
    for i, ch in enumerate(text):
        if ch not in GLYPHS:
            raise KeyError(ch)
        for s in GLYPHS[ch]:
            strokes.append(origin + (s + [i * GLYPH_ADVANCE, 0.0]) * scale)
    return strokes


# --------------------------------------------------------------------------------------------
# Shapes -> polylines -> evenly spaced samples
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class SampledPath:
    """Waypoints (N, 2) in m and whether each lies on a drawn stroke (False on travel moves)."""

    points: np.ndarray
    drawn: np.ndarray

    @property
    def length(self) -> float:
        return float(np.sum(np.linalg.norm(np.diff(self.points, axis=0), axis=1)))


class PathError(ValueError):
    """A path that cannot be sampled; the message says why (the caller attaches the span)."""


def path_polylines(spec: PathSpec) -> list[np.ndarray]:
    """The drawn polylines of a path, in order (metres)."""
    cx, cy = spec.center
    if spec.shape in ("line", "polyline", "csv"):
        if len(spec.points) < 2:
            raise PathError(f"a {spec.shape} path needs at least 2 points, got {len(spec.points)}")
        return [np.asarray(spec.points, dtype=float)]
    if spec.shape == "rectangle":
        if not spec.width or not spec.height or spec.width <= 0 or spec.height <= 0:
            raise PathError("a rectangle path needs a positive width and height")
        w, h = spec.width / 2, spec.height / 2
        return [np.array([[cx - w, cy - h], [cx + w, cy - h], [cx + w, cy + h], [cx - w, cy + h],
                          [cx - w, cy - h]])]
    if spec.shape == "circle":
        if not spec.radius or spec.radius <= 0:
            raise PathError("a circle path needs a positive radius")
        a = np.linspace(0.0, 2 * np.pi, 257)
        return [np.column_stack([cx + spec.radius * np.cos(a), cy + spec.radius * np.sin(a)])]
    if spec.shape == "text":
        if not spec.text or not spec.height or spec.height <= 0:
            raise PathError("a text path needs text and a positive height")
        try:
            return text_strokes(spec.text, spec.height, spec.center)
        except KeyError as exc:
            raise PathError(f"the stroke font has no glyph for {exc.args[0]!r} "
                            f"(supported: A-Z, 0-9 and {''.join(c for c in '-+./ ')!r})") from None
    raise PathError(f"unknown path shape {spec.shape!r}")


def sample_polylines(polylines: list[np.ndarray], n: int) -> SampledPath:
    """``n`` points evenly spaced by arc length along the polylines joined by travel moves."""
    if n < 2:
        raise PathError("a path needs at least 2 samples")
    verts, drawn_seg = [], []
    for i, pl in enumerate(polylines):
        if len(pl) == 0:
            continue
        if verts:
            drawn_seg.append(False)             # travel move from the previous stroke's end
        verts.extend(pl)
        drawn_seg.extend([True] * (len(pl) - 1))
    v = np.asarray(verts, dtype=float)
    seg_len = np.linalg.norm(np.diff(v, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    total = cum[-1]
    if total <= 0:
        raise PathError("the path has zero length")
    s = np.linspace(0.0, total, n)
    idx = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg_len) - 1)
    # skip zero-length segments at the sample's arc position
    frac = np.divide(s - cum[idx], seg_len[idx], out=np.zeros_like(s), where=seg_len[idx] > 0)
    pts = v[idx] + frac[:, None] * (v[idx + 1] - v[idx])
    drawn = np.asarray(drawn_seg, dtype=bool)[idx]
    return SampledPath(points=pts, drawn=drawn)


def sample_path(spec: PathSpec, n: int) -> SampledPath:
    """Sample ``spec`` at ``n`` waypoints evenly spaced by arc length (closed shapes end where they start)."""
    return sample_polylines(path_polylines(spec), n)


def path_length(spec: PathSpec) -> float:
    """Total length (m) including travel moves between strokes."""
    pls = [p for p in path_polylines(spec) if len(p)]
    v = np.concatenate(pls)
    return float(np.sum(np.linalg.norm(np.diff(v, axis=0), axis=1)))

"""Choosing the tones of a path goal from a gain table (model prediction or measured sweep).

A :class:`GainTable` holds, per frequency, the planar displacement per V^2 of the followed
capsule.  With per-tone power ``u >= 0`` and the total budget ``sum u <= Vmax^2 / K`` of the path
program, the displacements reachable with tones ``S`` are the polygon ``conv{0, g_i Vmax^2/K}``.
For each candidate triple we compute its *margin*: the smallest, over the path's waypoints, of
(reach of the polygon along the waypoint's direction) / (waypoint distance) -- >= 1 means every
waypoint is reachable, and a direction outside the cone of the gain vectors gives 0.  The score
is ``margin * (1 + 0.25 * sigma_min/sigma_max)`` of the column-normalised gain matrix: reach first
(the strongest tones that surround the path: least drive, as the paper's choice of the largest
deflections), then conditioning (well separated directions) as a factor of at most 1.25, so that
a tiny margin never wins by conditioning alone.
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np


@dataclass(frozen=True)
class GainTable:
    """frequencies (F,) Hz, strictly increasing; gains (F, 2) m/V^2; source: where it came from."""

    frequencies: np.ndarray
    gains: np.ndarray
    source: str = "model"

    def at(self, frequencies) -> np.ndarray:
        """Gains (2, K) at the given frequencies (linear interpolation inside the table)."""
        f = np.asarray(frequencies, dtype=float)
        gx = np.interp(f, self.frequencies, self.gains[:, 0])
        gy = np.interp(f, self.frequencies, self.gains[:, 1])
        return np.vstack([gx, gy])


class ToneError(ValueError):
    """No tone set can be chosen; ``help`` says what to change (acl.schedule.steps reports it as E-SCHED-TONES)."""

    def __init__(self, message: str, help: str | None = None):
        super().__init__(message)
        self.help = help


def one_line(table: GainTable, rel: float = 1e-6) -> np.ndarray | None:
    """The unit direction every gain of ``table`` points along (the way most of them push), or None when the gains
    span the plane."""
    g = np.asarray(table.gains, dtype=float)
    if not g.size or not np.all(np.isfinite(g)):
        return None
    _, s, vt = np.linalg.svd(g, full_matrices=False)
    if not (s[0] > 0 and (s.size < 2 or s[1] <= rel * s[0])):
        return None
    return -vt[0] if np.sum(g @ vt[0]) < 0 else vt[0]


def _too_few(table: GainTable, targets: np.ndarray, n: int, k: int) -> ToneError:
    """Why fewer than k candidate tones are left: a capsule that moves along one line, told to leave it, is said so."""
    u = one_line(table)
    if u is not None:
        off = float(np.max(np.abs(targets @ np.array([-u[1], u[0]])), initial=0.0))
        ux, uy = np.round(u, 3) + 0.0                          # + 0.0: no "-0"
        along = f"({ux:.3g}, {uy:.3g})"
        if off > 1e-9:
            return ToneError(f"the capsule moves along one line only: at every frequency its drive pushes it along "
                             f"{along} (x, y), and the path leaves that line by up to {off * 1e6:.3g} um, which no "
                             f"drive can follow",
                             "follow a path on that line (as `polyline([(0, 0), (-5 um, 0)])` for a capsule pushed "
                             "along -x), or give the capsule orifices facing different ways (as the three-orifice "
                             "module of paper Fig. 3) to move it in the plane")
        return ToneError(f"the gain table has {n} usable frequenc{'y' if n == 1 else 'ies'} (the capsule moves along "
                         f"{along} only, so every tone pushes the same way); {k} tones are needed",
                         "pin the tones with `, using [110 kHz, 125 kHz, 140 kHz]` on the follow step")
    return ToneError(f"the gain table has {n} usable frequenc{'y' if n == 1 else 'ies'}; {k} tones are needed")


@dataclass(frozen=True)
class ToneChoice:
    frequencies: tuple[float, ...]
    gains: np.ndarray          # (2, K) m/V^2
    margin: float              # >= 1: every waypoint reachable within the conservative budget
    conditioning: float        # sigma_min / sigma_max of the column-normalised gain matrix
    score: float


def reach(vectors: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Distance from 0 to the boundary of conv{0, v_1..v_k} along each unit direction.

    vectors (M, k, 2), directions (D, 2) unit -> (M, D); 0 where the direction is outside the cone.
    """
    M, k, _ = vectors.shape
    best = np.zeros((M, directions.shape[0]))
    dx, dy = directions[:, 0][None, :], directions[:, 1][None, :]
    for i, j in combinations(range(k), 2):
        gi, gj = vectors[:, i, :], vectors[:, j, :]
        e = gi - gj                                              # segment g_j + a e, a in [0, 1]
        det = dx * e[:, 1:2] - dy * e[:, 0:1]                    # d x e
        gj_x_e = gj[:, 0:1] * e[:, 1:2] - gj[:, 1:2] * e[:, 0:1]
        d_x_gj = dx * gj[:, 1:2] - dy * gj[:, 0:1]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = gj_x_e / det
            a = -d_x_gj / det
        ok = (np.abs(det) > 1e-30) & (a >= -1e-12) & (a <= 1 + 1e-12) & (t > 0)
        best = np.maximum(best, np.where(ok, t, 0.0))
    for i in range(k):                                           # rays along a single gain vector
        g = vectors[:, i, :]
        n = np.linalg.norm(g, axis=1, keepdims=True)
        cos = (g[:, 0:1] * dx + g[:, 1:2] * dy) / np.where(n > 0, n, 1)
        best = np.maximum(best, np.where(cos > 1 - 1e-9, n, 0.0))
    return best


def score_sets(vectors: np.ndarray, targets: np.ndarray, budget: float) -> tuple[np.ndarray, np.ndarray]:
    """(margin, conditioning) of each candidate set; vectors (M, k, 2) per V^2, targets (N, 2)."""
    r = np.linalg.norm(targets, axis=1)
    keep = r > 1e-3 * (r.max() if r.size else 0.0)
    if not np.any(keep):
        d = np.column_stack([np.cos(np.linspace(0, 2 * np.pi, 36, endpoint=False)),
                             np.sin(np.linspace(0, 2 * np.pi, 36, endpoint=False))])
        need = np.full(36, 1e-30)
    else:
        d, need = targets[keep] / r[keep, None], r[keep]
        if d.shape[0] > 256:                                     # a subsample keeps it cheap
            idx = np.linspace(0, d.shape[0] - 1, 256).astype(int)
            d, need = d[idx], need[idx]
    margin = np.min(reach(vectors * budget, d) / need[None, :], axis=1)
    norms = np.linalg.norm(vectors, axis=2, keepdims=True)
    unit = vectors / np.where(norms > 0, norms, 1)
    sv = np.linalg.svd(np.transpose(unit, (0, 2, 1)), compute_uv=False)   # (M, 2)
    cond = sv[:, -1] / np.where(sv[:, 0] > 0, sv[:, 0], 1)
    return margin, cond


def candidate_indices(table: GainTable, max_candidates: int = 36) -> np.ndarray:
    """Frequencies worth trying: local maxima of |gain| and the strongest per direction sector."""
    mag = np.linalg.norm(table.gains, axis=1)
    F = mag.size
    if F <= max_candidates:
        return np.arange(F)
    peaks = [i for i in range(F) if mag[i] > 0 and (i == 0 or mag[i] >= mag[i - 1])
             and (i == F - 1 or mag[i] >= mag[i + 1])]
    ang = np.arctan2(table.gains[:, 1], table.gains[:, 0])
    sector = ((ang + np.pi) / (2 * np.pi) * 24).astype(int) % 24
    for s in range(24):
        idx = np.flatnonzero(sector == s)
        if idx.size:
            peaks.append(int(idx[np.argmax(mag[idx])]))
    cand = np.unique(peaks)
    if cand.size > max_candidates:
        cand = cand[np.argsort(mag[cand])[::-1][:max_candidates]]
    return np.sort(cand)


def choose_tones(table: GainTable, targets: np.ndarray, max_voltage: float, k: int = 3,
                 pinned: tuple[float, ...] = (), measured: tuple[float, ...] = ()) -> ToneChoice:
    """The k tones of ``table`` with the best score for ``targets`` (N, 2) m; pinned tones are kept as given.

    ``measured``: tones whose gain a calibration measured (``measured(gain)``, acl.schedule.bands.pinned).  The set
    with the most measured tones that reaches every waypoint (margin >= 1) is chosen, the best score among those:
    elsewhere the table keeps its prior, and a tone the model merely prefers there would trade a measured gain for
    a guessed one.  When no set with a measured tone reaches, the whole table decides."""
    budget = max_voltage ** 2 / max(k, len(pinned) or k)
    targets = np.asarray(targets, dtype=float).reshape(-1, 2)
    if pinned:
        g = table.at(pinned)
        margin, cond = score_sets(g.T[None], targets, budget)
        return ToneChoice(tuple(float(f) for f in pinned), g, float(margin[0]), float(cond[0]),
                          float(_score(margin, cond)[0]))
    if measured:
        got = _with_measured(table, targets, budget, k, measured)
        if got is not None:
            return got
    cand = candidate_indices(table)
    if cand.size < k:
        raise _too_few(table, targets, int(cand.size), k)
    triples = np.array(list(combinations(cand, k)))
    vectors = table.gains[triples]                              # (M, k, 2)
    margin, cond = score_sets(vectors, targets, budget)
    score = _score(margin, cond)
    best = int(np.argmax(score))
    freqs = tuple(float(table.frequencies[i]) for i in triples[best])
    return ToneChoice(freqs, table.gains[triples[best]].T, float(margin[best]), float(cond[best]),
                      float(score[best]))


def measured_choice(table: GainTable, targets: np.ndarray, max_voltage: float, k: int, measured,
                    at_least: int = 1) -> ToneChoice | None:
    """The best-scoring set of k tones with as many ``measured`` tones (at least ``at_least``) as can reach every
    waypoint by the outer bound of the drive's reach (``conv{0, g_i Vmax^2}``: any drive whose summed amplitude is
    at most Vmax lies inside, so a set outside it is infeasible), the rest from the table's candidates; None when
    none can.  Its ``margin`` is that outer one: the path plan decides (acl.schedule.steps.follow tries it first and
    falls back to :func:`choose_tones` when it is infeasible)."""
    return _with_measured(table, np.asarray(targets, float).reshape(-1, 2), max_voltage ** 2, k, measured, at_least)


def measured_count(choice: ToneChoice, measured) -> int:
    """How many of ``choice``'s tones are ``measured`` (relative 1e-6)."""
    return sum(any(abs(f - m) <= 1e-6 * m for m in measured) for f in choice.frequencies)


def _with_measured(table: GainTable, targets: np.ndarray, budget: float, k: int, measured,
                   at_least: int = 1) -> ToneChoice | None:
    """The best-scoring set of k tones with as many ``measured`` tones as reach every waypoint (margin >= 1 at
    ``budget``), the rest from the table's candidates; None when no set with ``at_least`` measured tones reaches."""
    fs = np.array(sorted({float(f) for f in measured}))
    others = [float(table.frequencies[i]) for i in candidate_indices(table)
              if not np.any(np.abs(fs - table.frequencies[i]) <= 1e-6 * table.frequencies[i])]
    for m in range(min(k, fs.size), max(at_least, 1) - 1, -1):
        sets = [tuple(fs[list(a)]) + b for a in combinations(range(fs.size), m) for b in combinations(others, k - m)]
        if not sets:
            continue
        freqs = np.array(sets)                                       # (M, k)
        vectors = np.transpose(table.at(freqs.ravel()), (1, 0)).reshape(len(sets), k, 2)
        margin, cond = score_sets(vectors, targets, budget)
        score = np.where(margin >= 1.0, _score(margin, cond), -np.inf)
        best = int(np.argmax(score))
        if np.isfinite(score[best]):
            order = np.argsort(freqs[best])
            return ToneChoice(tuple(float(f) for f in freqs[best][order]), vectors[best][order].T,
                              float(margin[best]), float(cond[best]), float(score[best]))
    return None


def _score(margin: np.ndarray, cond: np.ndarray) -> np.ndarray:
    return margin * (1.0 + 0.25 * cond)

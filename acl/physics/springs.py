"""Linear flexures: stiffness from geometry, combination in series and parallel, force law.

All SI.  The paper gives the Fig. 5c spring's stiffness directly (0.7563 nN/um, from its FEM,
Fig. S8); these formulas let a design derive a stiffness from flexure geometry instead.
"""
from __future__ import annotations

import numpy as np


def rect_second_moment(width: float, thickness: float) -> float:
    """Second moment of a rectangle bent across ``width``: t w^3 / 12 (Gere & Timoshenko, Mechanics of Materials)."""
    return thickness * width**3 / 12.0


def guided_beam_stiffness(E: float, I: float, L: float) -> float:
    """Transverse stiffness of a clamped-guided beam, 12 E I / L^3 (Gere & Timoshenko, fixed-guided case)."""
    return 12.0 * E * I / L**3


def cantilever_stiffness(E: float, I: float, L: float) -> float:
    """Tip stiffness of a clamped-free beam, 3 E I / L^3 (Gere & Timoshenko, cantilever with end load)."""
    return 3.0 * E * I / L**3


def in_series(*k: float) -> float:
    """Springs in series: 1/k = sum 1/k_i (Hooke's law)."""
    return 1.0 / sum(1.0 / ki for ki in k)


def in_parallel(*k: float) -> float:
    """Springs in parallel: k = sum k_i (Hooke's law)."""
    return float(sum(k))


def folded_flexure_stiffness(E: float, I: float, L: float, n_parallel: int = 2, n_series: int = 2) -> float:
    """Folded-beam suspension: guided beams, n_series per fold in series, n_parallel folds (Tang, Nguyen, Howe 1989)."""
    return guided_beam_stiffness(E, I, L) * n_parallel / n_series


def serpentine_stiffness(E: float, I: float, span: float, n_meanders: int) -> float:
    """Serpentine flexure along its axis: 2 n guided spans of length ``span`` in series, connectors rigid (Fedder 1994, thesis, limit of stiff connectors)."""
    return guided_beam_stiffness(E, I, span) / (2 * n_meanders)


def spring_force(k: float, extension):
    """Restoring force -k x of a linear spring (Hooke's law)."""
    return -k * np.asarray(extension, dtype=float)

"""Public entry points of the force model for stages that evaluate it over many rows (acl fit, issue 23).

The force engine of :mod:`acl.analysis.acoustics` (one design under one drive, vectorised over configurations), the
layout of its capsules and orifices, the medium and a capsule's outer radius, under public names, so that a stage
that batches data rows calls the analysis' own model instead of reaching into its private helpers.
"""
from __future__ import annotations

from acl.analysis import acoustics as _ac
from acl.design.model import Capsule, Design, Drive


def force_engine(design: Design, drive: Drive, cached: bool = True):
    """The analysis' force engine of ``design`` under ``drive`` (``forces(centres)``, ``response``, ``consts``,
    ``lay``, ``f``): the one :func:`acl.analysis.acoustics.force_model` evaluates; ``cached``: the last one built
    for the same objects is reused."""
    return _ac._engine(design, drive) if cached else _ac._compute_engine(design, drive)


def layout(design: Design):
    """Capsules, orifices (labels, body index, offsets, normals, radii) and rest centres the force engine uses."""
    return _ac._layout(design)


def medium(design: Design):
    """The medium constants (density, sound speed, viscosity, ...) the analysis uses for ``design``."""
    return _ac.medium_constants(design)


def outer_radius(capsule: Capsule) -> float:
    """The radius a neighbour's jet drags (equal-volume sphere plus wall), as the force model uses it."""
    return _ac._outer_radius(capsule)

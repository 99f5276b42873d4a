"""Batched evaluation of a sweep: one column (n,) per quantity for every point of a FieldBatch, no loop over points.

The design is resolved once (``batch.design``); every float the physics reads comes from
``batch.get(path)`` (the varying array, or the nominal value broadcast), and
:mod:`acl.physics.batch` evaluates the same models as `acl analyze` (acl/analysis/report.py,
acoustics.py, mechanics.py) vectorised along the points.  :data:`QUANTITIES` lists every column
family, its unit and the `acl analyze --output-format json` field it equals; tests compare both on
materialised points of the shipped examples.

The evaluation is split by idea: :mod:`acl.sweep.columns` (what a design supports, the column names),
:mod:`acl.sweep.acoustic_state` (capsules, modes, drives, forces at rest), :mod:`acl.sweep.pair_mechanics`
(snap-in, equilibria, deflections), :mod:`acl.sweep.checks` (latch margins, requires, the lint copies),
:mod:`acl.sweep.model_form` (the model-form uncertainty past the soft validity limits),
:mod:`acl.sweep.points` (families that declared effects change: analyze's engine point by point).

What is batched and how (the scalar code it equals):

* modes and Q of each capsule alone, coupled to its own interfaces and to the substrate's images
  (acoustics.capsule_modes: bare Rayleigh-Ritz modes, then the mutual-mass eigenproblem, then each
  interface's fundamental);
* forces at rest at each program frequency (acoustics.pair_forces: coupled volumes of all
  interfaces, thrust with a declared thrust coefficient's scale, Bjerknes, jet drag);
* snap-in voltage of a pair of capsules each on its own beam (mechanics.sweep_voltage).  Where the
  drive pulls both capsules together along their line, the stable branch of ``P_a(x_a) = V^2
  F_a(x)``, ``P_b(x_b) = V^2 F_b(x)`` (paper Eq. (1) beams, the full force model at displaced
  positions) is traced in the closure ``s`` of the gap, the split between the two beams solved at
  each ``s`` (secant), and the fold is the first maximum of ``V^2(s)`` (grid, then golden
  section).  Where one capsule is pulled and the other pushed (near d_c), or the forces at rest
  have a component across the line: continuation in V on both beams' planes of motion (Newton,
  finite-difference tangent stiffness, stable while its eigenvalues have positive real parts), the
  step halved where the branch is lost (a fold within a fraction of a micrometre of rest near d_c
  is found: tests/test_sweep_evaluate.py).  Both pushed apart: no snap-in (NaN);
* tip deflection at ``at`` of a capsule on a cantilever (the Eq. (1) deflection under the force at
  the displaced position, a fixed point) or of a pair (the same branches at V = 1, NaN after
  snap-in); ``require gap`` from the equilibrium of every program step;
* every other mechanism (springs, latches at rest in state a or b, trusses, three or more moving
  capsules, mixes of them): snap-in, deflections at ``at`` (``tip_deflection_<beam>_m``,
  ``deflection_<latch|spring>_m``) and ``require gap`` by :mod:`acl.sweep.mechanism`, the batched
  mechanics.build_mechanism: one smooth coordinate (a capsule on a spring) as the curve V^2(z) =
  R(z)/G(z) and its first maximum; otherwise continuation in V with Newton on all coordinates, the
  fold bracketed from below (at a latch's buckling kink within 1.3e-6 of the model's fold, which
  analyze's continuation stops up to 9.1e-6 short of: tests/test_sweep_mechanism.py);
* latch margins per program step (mechanics.latch_margins, latches at rest in state a or b), the
  switching and release forces refined by golden section (acl.physics.batch.latch_switching_force;
  the scalar landscape takes the extremes of a 2001-point grid, lower by up to 2e-3 where they
  sit at a kink of the force law, so its margins are optimistic by as much);
* every ``require`` (report._require) and the lint rules ACL101, ACL102 (gain at each mode against the
  band's best), ACL103 (overlapping modes of capsules driven separately), ACL105 (program drive and
  sweep steps), ACL201 (the Eq. 3 criterion under each program drive, lint's default without
  ``mechanics``; not for designs with a `sweep` step), ACL501, ACL502, ACL503, ACL504, ACL603, before
  suppressions and with the default thresholds (tests/test_sweep_drives.py: equal to the rules on
  perturbed points and on every example).

Drives and transducer per point: a swept parameter that moves a drive amplitude, a step's limit, the
transducer's maximum, band or gain table is read per point (the forces take each point's pressure,
amplitude times the point's interpolated gain; snap-in is cut at the point's maximum); a parameter
that moves a tone's frequency is not (the frequency names the columns: acl.sweep.driver leaves the
program columns out).

Declared effects: every effect of the table (acl.sweep.columns.BATCHED_EFFECTS) is applied in the batched
arrays, per point when a parameter moves a coefficient (acl.sweep.acoustic_state.PointAcoustics: coefficients,
pressure, substrate, pair_law, neighbour_drag, beam_law; snap-in under drive_saturation:
acl.sweep.pair_mechanics.PairMechanics.snap_in).  An effect outside that list would have the families it
changes given point by point by `acl analyze`'s engine (:mod:`acl.sweep.points`, with every effect applied).

Not batched (not offered as quantities, :func:`supported` says why): under an effect the batch would not model,
the lint rules ACL105, ACL201, ACL401 and ACL402 and the model-form columns; and these lint rules, each for its
reason:

* ACL104 (unintended excitation): each capsule's thrust relative to its own peak over a selectivity
  grid refined around each point's modes (acl.lint.context.thrust_grid: ~200 + 41 per mode
  frequencies, deduplicated), so the grid differs per point in values and length, and a chunk would
  hold ~300 coupled responses per point;
* ACL202 (force sign change): the same per-point grid (sweep_frequencies adds each point's modes
  inside the program's range) with the Bjerknes force at every frequency;
* ACL201 with a `sweep` step: the sweep's tones include each point's modes (same reason);
* ACL301, ACL302 (latch switch/hold against the switching and release forces): lint takes them from
  the scalar landscape (latch.latch_landscape: a 2001-point grid, its extremes refined), the batched
  columns from a coarser grid refined the same way, higher by up to 2e-3 where the extreme sits at a
  kink (tests/test_sweep_evaluate.py).  With them ACL301 (a step that may flip a latch: push x
  factor >= the force needed) could pass points lint flags, an optimistic verdict on a safety check,
  and ACL302 could differ from `acl lint` near its threshold; the batched margins (``margin_*``
  columns, ``require margin``) give the switch's figure;
* ACL401, ACL402 (beam strain, large deflection): the worst load over every program step, a `follow`
  step's excursion included, which comes from the path the compiler plans, not from the design's
  numbers alone;
* ACL601, ACL602 (unused declarations, parameters without units): about the source text, the same at
  every point of a sweep.
"""
from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np

from acl.sweep.model_form import ModelForm
from acl.sweep.columns import (  # noqa: F401 (re-exported)
    LINT_RULES,
    QUANTITIES,
    STATIC_EFFECTS,
    Quantity,
    QuantityError,
    _closed_form,
    _fkey,
    _ident,
    per_point_columns,
    per_point_names,
    supported,
)

# ----------------------------------------------------------------------------------------------
# Entry point
# ----------------------------------------------------------------------------------------------


def evaluate(batch, quantities: Sequence[str] | None = None, at: str | None = None) -> dict[str, np.ndarray]:
    """One column (n,) per quantity (None: every quantity the design supports); ``at`` a drive like "125 kHz @ 6 V".

    Invalid points (``batch.valid`` False) get NaN, or False for pass/fail columns.  Raises
    :class:`QuantityError` (code E-SWEEP-Q01 unknown, E-SWEEP-Q02 not batched for this design) for a
    quantity it cannot give.
    """
    design = batch.design
    names, missing = supported(design, at)
    if quantities is None:
        wanted = names
    else:
        wanted = list(quantities)
        for q in wanted:
            if q not in names:
                why = next((v for k, v in missing.items()
                            if q.startswith(k) and (k.endswith("_") or q[len(k):len(k) + 1] in ("", "_"))), None)
                if why is not None:
                    raise QuantityError("E-SWEEP-Q02", f"quantity `{q}` is not available for this design: {why}")
                raise QuantityError("E-SWEEP-Q01", f"quantity `{q}` is not defined for this design "
                                    f"(available: {', '.join(names) or 'none'})")
    ev = _Evaluator(batch, at)
    out = {}
    slow = per_point_names(design, at)
    combined = {"requires_pass", "lint_acl603_pass"} if slow & {f"require_{i}_pass" for i in range(1, len(design.requires) + 1)} else set()
    need = [q for q in wanted if q in slow]
    if combined & set(wanted):
        need += [f"require_{i}_pass" for i in range(1, len(design.requires) + 1)
                 if f"require_{i}_pass" in slow and f"require_{i}_pass" not in need]
    if need:
        from acl.sweep.points import evaluate_points

        with np.errstate(all="ignore"):
            pp = evaluate_points(batch, need, at)
    with np.errstate(all="ignore"):
        for q in wanted:
            if q in slow:
                out[q] = pp[q]
                continue
            if q in combined:        # every require, batched or point by point (lint ACL603 is the same test)
                col = np.ones(batch.n, bool)
                for i in range(1, len(design.requires) + 1):
                    c = f"require_{i}_pass"
                    col &= pp[c] if c in slow else np.broadcast_to(np.asarray(ev.column(c)), (batch.n,))
                out[q] = col & ev.valid
                continue
            col = np.asarray(ev.column(q))
            col = np.broadcast_to(col, (batch.n,)).copy()
            if col.dtype == bool:
                col &= ev.valid
            else:
                col = col.astype(float)
                col[~ev.valid] = np.nan
            out[q] = col
    return out


class _Evaluator(ModelForm):
    """Every column of a FieldBatch, computed lazily by groups (acl.sweep.acoustic_state, pair_mechanics, checks)."""

    def column(self, q: str):
        from acl.analysis.report import program_frequencies

        idx = {_ident(c.name): k for k, c in enumerate(self.caps)}
        m = re.fullmatch(r"resonance_(.+)_(\d+)_hz", q)
        if m:
            return self.modes(idx[m.group(1)])[0][:, int(m.group(2)) - 1]
        m = re.fullmatch(r"q_(.+)_(\d+)", q)
        if m and m.group(1) in idx:
            return self.modes(idx[m.group(1)])[1][:, int(m.group(2)) - 1]
        for f in program_frequencies(self.design):
            if q.endswith(f"_{_fkey(f)}_v") and q.startswith("snap_in_"):
                return self.snap_in(f)
            cols = None
            if _fkey(f) in q and q.split("_")[0] in ("force", "attract", "phase", "critical"):
                cols = self.pair_quantities(f)
                if q in cols:
                    return cols[q]
        m = re.fullmatch(r"(tip_)?deflection_(.+)_m", q)
        if m or q == "equilibrium_ok":
            from acl.design.drives import drive_from_text

            drive = drive_from_text(self.at, "<at>")
            if not _closed_form(self.design)[1]:
                cols = self.once(("at", self.at), lambda: self.general_deflection(drive))
            else:
                cols = self.once(("at", self.at), lambda: self.single_deflection(drive) if len(self.caps) == 1
                                 else self.pair_deflection(drive))
            return cols[q]
        for lt in self.design.latches:
            key = _ident(lt.name)
            if q == f"switching_force_{key}_n":
                return self.latch(lt.name)["switching"]
            if q == f"release_force_{key}_n":
                return self.latch(lt.name)["release"]
            if q == f"bistable_{key}":
                return self.latch(lt.name)["bistable"]
            if q.startswith(f"margin_{key}_"):
                for (pname, i), col in self.latch(lt.name)["margins"].items():
                    if q == f"margin_{key}_{_ident(pname)}_{i + 1}":
                        return col
        m = re.fullmatch(r"require_(\d+)_(value|pass)", q)
        if m:
            value, ok = self.once(("require", int(m.group(1))), lambda: self.require(int(m.group(1))))
            return value if m.group(2) == "value" else ok
        if q == "requires_pass":
            ok = np.ones(self.n, bool)
            for i in range(1, len(self.design.requires) + 1):
                ok &= self.once(("require", i), lambda i=i: self.require(i))[1]
            return ok
        if q in ("model_form_rel", "model_form_uncertain"):
            return self.model_form()[q]
        if q in ("model_form_pair_uncertain", "model_form_pair_median_pass"):
            return self.pair_scale_columns()[q]
        m = re.fullmatch(r"lint_(acl\d+)_pass", q)
        if m:
            return self.once(("lint", m.group(1)), lambda: self.lint(m.group(1)))
        raise QuantityError("E-SWEEP-Q01", f"unknown quantity `{q}`")

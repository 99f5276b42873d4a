"""Batched evaluation of a sweep: one column (n,) per quantity for every point of a FieldBatch, no loop over points.

The design is resolved once (``batch.design``); every float the physics reads comes from
``batch.get(path)`` (the varying array, or the nominal value broadcast), and
:mod:`acl.physics.batch` evaluates the same models as `acl analyze` (acl/analysis/report.py,
acoustics.py, mechanics.py) vectorised along the points.  :data:`QUANTITIES` lists every column
family, its unit and the `acl analyze --output-format json` field it equals; tests compare both on
materialised points of the shipped examples.

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

Not batched (not offered as quantities, :func:`supported` says why): designs declaring effects that
change the column (per family: forces at rest, latch law, equilibria; :func:`supported` names the
effects), and these lint rules, each for its reason:

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

import math
import re
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from acl.design import model as M
from acl.physics import batch as PB
from acl.physics import constants as C
from acl.physics.effect_table import EFFECT_TABLE
from acl.physics.forces import jet_drag, thrust_magnitude
from acl.physics.transducer import pressure_per_volt_rows
from acl.physics.ties import TIE_RTOL, first_max


class QuantityError(ValueError):
    """A requested quantity the design does not have or the batched evaluation cannot give; ``code`` names the diagnostic."""

    def __init__(self, code: str, message: str):
        super().__init__(message)
        self.code = code


@dataclass(frozen=True)
class Quantity:
    pattern: str       # column name pattern, <...> filled from the design
    unit: str          # SI unit ("" dimensionless, "bool" pass/fail)
    meaning: str
    analyze: str       # the `acl analyze --output-format json` field it equals


QUANTITIES: tuple[Quantity, ...] = (
    Quantity("resonance_<capsule>_<k>_hz", "Hz", "k-th reported mode of the capsule alone (liquid and substrate coupling)",
             "capsules[name=<capsule>].modes[k-1].frequency_hz"),
    Quantity("q_<capsule>_<k>", "", "its quality factor (a declared quality_factor replaces it)",
             "capsules[name=<capsule>].modes[k-1].q"),
    Quantity("force_<a>_<b>_<f>khz_n", "N", "attraction-positive Bjerknes force of the pair at rest, program amplitude at f",
             "pairs[a,b,frequency_hz=f].force_n"),
    Quantity("attract_<a>_<b>_<f>khz", "bool", "the pair attracts at f", "pairs[a,b,frequency_hz=f].attract"),
    Quantity("phase_<a>_<b>_<f>khz_deg", "deg", "phase difference of the dominant interfaces at f",
             "pairs[a,b,frequency_hz=f].phase_difference_deg"),
    Quantity("critical_distance_<a>_<b>_<f>khz_m", "m", "d_c of paper Eq. 3 (NaN: no attraction or no thrust apart)",
             "pairs[a,b,frequency_hz=f].critical_distance_eq3_m"),
    Quantity("snap_in_<a>_<b>_<f>khz_v", "V", "snap-in voltage of a 1 V tone at f scaled up to the transducer's max (NaN: none)",
             "pairs[a,b,frequency_hz=f].snap_in_voltage_v"),
    Quantity("switching_force_<latch>_n", "N", "force that switches the latch a -> b (model maximum, refined)",
             "latches[name].switching_force_n"),
    Quantity("release_force_<latch>_n", "N", "force that releases the latch b -> a (NaN: monostable)",
             "latches[name].release_force_n"),
    Quantity("bistable_<latch>", "bool", "the latch has a second stable state", "latches[name].bistable"),
    Quantity("margin_<latch>_<program>_<step>", "", "available / required force on the latch at a program step",
             "latches[name].margins[program,step].margin"),
    Quantity("tip_deflection_<beam>_m", "m", "load-point deflection of the beam at the drive `at`",
             "equilibrium.deflections_m[<beam>]"),
    Quantity("deflection_<element>_m", "m", "latch shuttle travel, spring extension or spring-link extension at the drive `at` (mechanics)",
             "equilibrium.deflections_m[<element>]"),
    Quantity("equilibrium_ok", "bool", "a stable equilibrium is reached at `at` without snap-in",
             "equilibrium.status == \"ok\""),
    Quantity("require_<i>_value", "(the require's)", "measured value of the i-th require (1-based, file order)",
             "requires[i-1].value"),
    Quantity("require_<i>_pass", "bool", "the i-th require holds", "requires[i-1].ok"),
    Quantity("requires_pass", "bool", "every require holds", "all(requires[].ok)"),
    Quantity("lint_<rule>_pass", "bool", "the lint rule finds nothing (rule's own test, before suppressions)",
             "`acl lint` finding of <rule> absent"),
)

STATIC_EFFECTS = {e.name for e in EFFECT_TABLE.values() if e.static_note}   # the one table (acl.physics.effects)
LINT_RULES = ("acl101", "acl102", "acl103", "acl105", "acl201", "acl401", "acl402", "acl501", "acl502", "acl503",
              "acl504", "acl603")
_PROGRAM_LINT = ("acl201", "acl401", "acl402")      # rules over each program's drives (lint's step_drives)
SNAP_GRID = 12            # closure grid of the snap-in search
SNAP_GOLDEN = 14          # golden-section steps on the fold
SPLIT_ITER = 5            # secant steps for the split of the closure between the two beams


def _fkey(f: float) -> str:
    return f"{f / 1e3:g}khz".replace(".", "p")


def _ident(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]", "_", name)


# ----------------------------------------------------------------------------------------------
# What a design supports
# ----------------------------------------------------------------------------------------------


def _mechanism(design: M.Design) -> str:
    """'beams' (every capsule on its own beam or fixed, no links/springs/latches), 'latch' or 'other'."""
    if design.springs or design.trusses or any(j.kind == "link" for j in design.joints):
        return "other"
    kinds = []
    targets = []
    for c in design.capsules:
        j = design.mount_of(c.name)
        if j is None:
            return "other"
        kinds.append("fix" if j.kind == "fix" else j.target_kind)
        if j.kind == "mount":
            targets.append(j.target)
    if len(set(targets)) != len(targets):
        return "other"
    if set(kinds) <= {"beam", "fix"}:
        return "beams"
    if set(kinds) <= {"latch", "fix"}:
        return "latch"
    return "other"


def _closed_form(design: M.Design) -> tuple[bool, bool]:
    """(snap-in, deflections) given by the closed forms: a pair of capsules on beams, one or two capsules on beams."""
    mech = _mechanism(design)
    moving = [c for c in design.capsules if (design.mount_of(c.name) or M.Fix(capsule="", span=c.span)).kind == "mount"]
    return (mech == "beams" and len(design.capsules) == 2 and len(moving) >= 1,
            mech == "beams" and 1 <= len(design.capsules) <= 2)


def _general(design: M.Design) -> str | None:
    """Why the general batched mechanism (acl.sweep.mechanism) does not cover ``design``; None if it does."""
    from acl.sweep.mechanism import not_batched

    return not_batched(design)


def _physical_effects(design: M.Design) -> list[str]:
    return [e.name for e in design.effects if e.name not in STATIC_EFFECTS]


# Declared effects that leave the forces at rest as they are (acl.analysis.acoustics applies them to
# beams or to displaced capsules only: neighbour_drag's factor is 1 at zero displacement), and those of
# them that also leave the latch law as it is (mechanics.latch_geometry scales E by stiffness_scale only).
REST_NEUTRAL_EFFECTS = {e.name for e in EFFECT_TABLE.values() if e.rest_neutral and not e.static_note}
LATCH_NEUTRAL_EFFECTS = {e.name for e in EFFECT_TABLE.values() if e.latch_neutral and not e.static_note}


def _effect_blocks(design: M.Design) -> dict[str, list[str]]:
    """{'rest': effects that change the forces at rest, 'latch': ... the latch margins, 'motion': ... the
    equilibria (every physical effect: the batched beams, springs and forces at displaced positions
    model none of them)}."""
    eff = _physical_effects(design)
    return {"rest": [e for e in eff if e not in REST_NEUTRAL_EFFECTS],
            "latch": [e for e in eff if e not in LATCH_NEUTRAL_EFFECTS],
            "motion": eff}


def _effects_note(names: list[str], what: str) -> str:
    return f"the design declares effects ({', '.join(names)}) that change {what}, which the batched evaluation does not model"


def supported(design: M.Design, at: str | None = None) -> tuple[list[str], dict[str, str]]:
    """(column names the batched evaluation gives for ``design``, {quantity family: why it is not given})."""
    from acl.analysis.report import program_frequencies, step_drives

    names: list[str] = []
    missing: dict[str, str] = {}
    effects = _physical_effects(design)
    blocks = _effect_blocks(design)
    for cap in design.capsules:
        for k in range(1, len(cap.orifices) + 1):
            names += [f"resonance_{_ident(cap.name)}_{k}_hz", f"q_{_ident(cap.name)}_{k}"]
    if blocks["rest"]:
        for fam in ("force_", "attract_", "phase_", "critical_distance_"):
            missing[fam] = _effects_note(blocks["rest"], "the acoustic forces")
    if blocks["latch"]:
        for fam in ("switching_force_", "release_force_", "bistable_", "margin_"):
            missing[fam] = _effects_note(blocks["latch"], "the forces or the latch law")
    if blocks["motion"]:
        for fam in ("snap_in_", "tip_deflection", "deflection_", "equilibrium_ok"):
            missing[fam] = _effects_note(blocks["motion"], "the equilibria (forces at displaced positions, beams)")
    mech = _mechanism(design)
    moving = [c for c in design.capsules if (design.mount_of(c.name) or M.Fix(capsule="", span=c.span)).kind == "mount"]
    freqs = program_frequencies(design) or []
    pairs = _pairs(design)
    if not blocks["rest"]:
        for f in freqs:
            for a, b in pairs:
                tag = f"{_ident(a)}_{_ident(b)}_{_fkey(f)}"
                names += [f"force_{tag}_n", f"attract_{tag}", f"phase_{tag}_deg", f"critical_distance_{tag}_m"]
    if not blocks["latch"]:
        for lt in design.latches:
            names += [f"switching_force_{_ident(lt.name)}_n", f"release_force_{_ident(lt.name)}_n",
                      f"bistable_{_ident(lt.name)}"]
            names += [f"margin_{_ident(lt.name)}_{_ident(p.name)}_{i + 1}" for p, i, _st, _d in step_drives(design)]
    if not effects:
        closed_snap, closed_eq = _closed_form(design)
        general = None if closed_snap and closed_eq else _general(design)
        if pairs and freqs:
            if closed_snap or general is None:
                names += [f"snap_in_{_ident(a)}_{_ident(b)}_{_fkey(f)}_v" for f in freqs for a, b in pairs]
            else:
                missing["snap_in_"] = f"batched snap-in does not cover this mechanism: {general}"
        if at is None:
            if any((design.mount_of(c.name) or M.Fix(capsule="", span=c.span)).kind == "mount" for c in design.capsules):
                missing["tip_deflection"] = "deflections need a drive: give `at` (like `acl analyze --at`)"
        else:
            if closed_eq:
                names += [f"tip_deflection_{_ident(j.target)}_m" for c in design.capsules
                          for j in [design.mount_of(c.name)] if j.kind == "mount"] + ["equilibrium_ok"]
            elif general is None:
                names += [f"{'tip_deflection' if kind == 'beam' else 'deflection'}_{_ident(el)}_m"
                          for el, kind in _elements(design)] + ["equilibrium_ok"]
            else:
                missing["tip_deflection"] = missing["deflection_"] = \
                    f"batched equilibria do not cover this mechanism: {general}"
    for i, r in enumerate(design.requires, 1):
        if _require_supported(design, r, effects):
            names += [f"require_{i}_value", f"require_{i}_pass"]
        elif r.kind == "margin" and blocks["latch"]:
            missing[f"require_{i}"] = f"`{r.text}`: " + _effects_note(blocks["latch"], "the forces or the latch law")
        elif r.kind == "gap" and effects:
            missing[f"require_{i}"] = f"`{r.text}`: " + _effects_note(effects, "the equilibria")
        else:
            missing[f"require_{i}"] = f"`{r.text}` is not batched for this design"
    if design.requires and all(f"require_{i}_pass" in names for i in range(1, len(design.requires) + 1)):
        names.append("requires_pass")
    sweeps = any(st.kind == "sweep" for p in design.programs for st in p.steps)
    names += [f"lint_{code}_pass" for code in LINT_RULES
              if (code != "acl105" or not blocks["rest"]) and (code not in _PROGRAM_LINT or not effects)
              and (code not in _PROGRAM_LINT or not sweeps)]
    if "lint_acl603_pass" in names and "requires_pass" not in names and design.requires:
        names.remove("lint_acl603_pass")
    if blocks["rest"]:
        missing["lint_acl105"] = "eps/R with declared effects on the drive pressure is not batched"
    if effects:
        for code in _PROGRAM_LINT:
            missing[f"lint_{code}"] = "forces with declared effects are not batched"
    elif sweeps:
        for code in _PROGRAM_LINT:
            missing[f"lint_{code}"] = ("a `sweep` step's tones include each point's own modes "
                                       "(acl.lint.context.sweep_frequencies): not one set of frequencies for all points")
    return names, missing


def _require_supported(design, r, effects) -> bool:
    if r.kind in ("resonance", "separation"):
        return True
    if r.kind == "margin":
        return any(lt.name == r.args[0] for lt in design.latches) and not _effect_blocks(design)["latch"]
    if effects:
        return False
    # gap: the equilibrium at every program step: a pair of capsules on two beams, or the general mechanism
    return (_mechanism(design) == "beams" and len(design.capsules) == 2) or _general(design) is None


def _elements(design) -> list[tuple[str, str]]:
    """(name, kind) of the mechanism's deflections, as mechanics._deflections reports them (elements, then spring links)."""
    from acl.analysis import mechanics as ME

    mech = ME.build_mechanism(design)
    out = [(el.name, el.kind) for el in mech.elements]
    out += [(name, "link") for (_k, _n, _a, _b, name) in mech.links if name not in {n for n, _ in out}]
    return out


def _uses_general(design) -> bool:
    closed_snap, closed_eq = _closed_form(design)
    return not (closed_snap and closed_eq) and _general(design) is None


def _pairs(design):
    names = [c.name for c in design.capsules]
    return [(a, b) for i, a in enumerate(names) for b in names[i + 1:]]


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
    with np.errstate(all="ignore"):
        for q in wanted:
            col = np.asarray(ev.column(q))
            col = np.broadcast_to(col, (batch.n,)).copy()
            if col.dtype == bool:
                col &= ev.valid
            else:
                col = col.astype(float)
                col[~ev.valid] = np.nan
            out[q] = col
    return out


# ----------------------------------------------------------------------------------------------
# The evaluator: lazily computed groups of columns
# ----------------------------------------------------------------------------------------------


def _nominal(design, path: str) -> float:
    from acl.sweep.perturb import field_value

    return field_value(design, path)


class _Rows:
    """A FieldBatch restricted to some rows (same design, same fields)."""

    def __init__(self, batch, rows):
        self.design = batch.design
        self.rows = rows
        self.n = int(rows.size)
        self.valid = np.asarray(batch.valid, bool)[rows]
        self.fields = batch.fields            # which fields vary (membership only; values through get)
        self._batch = batch

    def get(self, path: str) -> np.ndarray:
        return np.broadcast_to(np.asarray(self._batch.get(path), float), (self._batch.n,))[self.rows]


class _Evaluator:
    def __init__(self, batch, at: str | None):
        from acl.analysis.acoustics import _medium

        self.batch = batch
        self.design = batch.design
        self.n = int(batch.n)
        self.valid = np.asarray(batch.valid, bool)
        self.at = at
        self.cache: dict = {}
        med = _medium(self.design)
        self.heat_ratio = med.gas_heat_capacity_ratio
        if self.design.medium is None:
            self.medium = {k: np.full(self.n, getattr(med, k)) for k in
                           ("density", "viscosity", "sound_speed", "surface_tension", "ambient_pressure",
                            "polytropic_index", "gas_thermal_diffusivity")}
        else:
            self.medium = {k: self.get(f"medium.{k}") for k in
                           ("density", "viscosity", "sound_speed", "surface_tension", "ambient_pressure",
                            "polytropic_index", "gas_thermal_diffusivity")}
        self.caps = list(self.design.capsules)

    # -- inputs ---------------------------------------------------------------------------------
    def get(self, path: str) -> np.ndarray:
        """The field over the points, invalid points replaced by the nominal value (the physics stays finite)."""
        arr = np.asarray(self.batch.get(path), float)
        arr = np.broadcast_to(arr, (self.n,))
        if not self.valid.all():
            arr = np.where(self.valid, arr, _nominal(self.design, path))
        return arr

    def get_opt(self, path: str) -> np.ndarray:
        """A field that may be None in the design (NaN then)."""
        try:
            nominal = _nominal(self.design, path)
        except (TypeError, AttributeError):
            return np.full(self.n, np.nan)
        arr = np.broadcast_to(np.asarray(self.batch.get(path), float), (self.n,))
        return np.where(self.valid, arr, nominal) if not self.valid.all() else arr

    def vec(self, path: str) -> np.ndarray:
        return np.stack([self.get(f"{path}.{k}") for k in range(3)], axis=-1)

    def once(self, key, fn):
        if key not in self.cache:
            self.cache[key] = fn()
        return self.cache[key]

    # -- capsule geometry ---------------------------------------------------------------------------
    def capsule(self, c: int) -> dict:
        def build():
            cap = self.caps[c]
            base = f"capsules.{cap.name}"
            cav = cap.cavity
            vol = self.get(f"{base}.cavity.volume")
            if cav.shape == "cylinder" and cav.radius and cav.height:
                r, h = self.get(f"{base}.cavity.radius"), self.get(f"{base}.cavity.height")
                rth = 3 * vol / (2 * np.pi * r**2 + 2 * np.pi * r * h)
            elif cav.shape == "prism" and cav.side and cav.height:
                s, h = self.get(f"{base}.cavity.side"), self.get(f"{base}.cavity.height")
                rth = 3 * vol / (math.sqrt(3) / 2 * s**2 + 3 * s * h)
            else:
                rth = (3 * vol / (4 * np.pi)) ** (1 / 3)
            radii = np.stack([self.get(f"{base}.orifices.{o.name}.radius") for o in cap.orifices], axis=1) \
                if cap.orifices else np.zeros((self.n, 0))
            pts = np.stack([self.vec(f"{base}.orifices.{o.name}.center") for o in cap.orifices], axis=1) \
                if cap.orifices else np.zeros((self.n, 0, 3))
            nrm = np.stack([self.vec(f"{base}.orifices.{o.name}.normal") for o in cap.orifices], axis=1) \
                if cap.orifices else np.zeros((self.n, 0, 3))
            nrm = nrm / np.linalg.norm(nrm, axis=-1, keepdims=True)
            qf = self.get_opt(f"{base}.quality_factor") if cap.quality_factor is not None else None
            gam = self.get_opt(f"{base}.thrust_coefficient") if cap.thrust_coefficient is not None else None
            wall = self.get(f"{base}.cavity.wall")
            return {"volume": vol, "rth": rth, "radii": radii, "points": pts, "normals": nrm,
                    "center": self.vec(f"{base}.center"), "q_declared": qf, "gamma": gam,
                    "outer": (3 * vol / (4 * np.pi)) ** (1 / 3) + wall}
        return self.once(("capsule", c), build)

    def bare(self, c: int) -> tuple:
        """Bare modes (omega, Q with a declared quality_factor, orifice volume) of capsule c."""
        def build():
            g = self.capsule(c)
            m = self.medium
            if g["radii"].shape[1] == 0:
                z = np.zeros((self.n, 0))
                return z, z, np.zeros((self.n, 0, 0))
            return PB.capsule_modes(g["volume"], g["radii"], m["density"], m["surface_tension"],
                                    m["ambient_pressure"], m["polytropic_index"], m["viscosity"], m["sound_speed"],
                                    g["rth"], self.heat_ratio, m["gas_thermal_diffusivity"],
                                    quality_override=g["q_declared"])
        return self.once(("bare", c), build)

    def modes(self, c: int) -> tuple[np.ndarray, np.ndarray]:
        """Reported modes of capsule c alone (acoustics.capsule_modes): frequency (N, P) Hz and Q (N, P), NaN-padded."""
        def build():
            g = self.capsule(c)
            om, q, vol = self.bare(c)
            p = g["radii"].shape[1]
            if p == 0:
                return np.zeros((self.n, 0)), np.zeros((self.n, 0))
            if p == 1:                               # one interface: the secular equation, its lowest root
                w, _, cq = PB.lowest_single_interface_mode(vol[:, 0], om, om / q, g["points"][:, 0], g["radii"][:, 0],
                                                           self.medium["density"], self.medium["sound_speed"],
                                                           C.SUBSTRATE_REFLECTION)
                f = (w / (2 * np.pi))[:, None]
                qq = cq[:, None] if g["q_declared"] is None else g["q_declared"][:, None]
                return f, qq
            body = np.zeros(p, int)
            w, cvol, cq = PB.coupled_modes(vol, om, om / q, g["points"], g["radii"], body,
                                           self.medium["density"], self.medium["sound_speed"], C.SUBSTRATE_REFLECTION)
            picked = _fundamentals(cvol)                                    # (N, P) mode index, -1 padded
            rows = np.arange(self.n)[:, None]
            safe = np.maximum(picked, 0)
            f = np.where(picked >= 0, w[rows, safe] / (2 * np.pi), np.nan)
            qq = np.where(picked >= 0, cq[rows, safe], np.nan)
            if g["q_declared"] is not None:
                qq = np.where(picked >= 0, g["q_declared"][:, None], np.nan)
            return f, qq
        return self.once(("modes", c), build)

    # -- the acoustic force engine ------------------------------------------------------------------
    def layout(self) -> dict:
        def build():
            body, radii, pts, nrm, phis, oms, dmps = [], [], [], [], [], [], []
            for c in range(len(self.caps)):
                g = self.capsule(c)
                om, q, vol = self.bare(c)
                p = g["radii"].shape[1]
                body += [c] * p
                radii.append(g["radii"])
                pts.append(g["points"])
                nrm.append(g["normals"])
                phis.append(vol)
                oms.append(om)
                dmps.append(om / q)
            nint = len(body)
            mtot = sum(o.shape[1] for o in oms)
            phi = np.zeros((self.n, nint, mtot))
            i0 = m0 = 0
            for ph in phis:
                pi_, mi = ph.shape[1], ph.shape[2]
                phi[:, i0:i0 + pi_, m0:m0 + mi] = ph
                i0, m0 = i0 + pi_, m0 + mi
            centres = np.stack([self.capsule(c)["center"] for c in range(len(self.caps))], axis=1)
            pts = np.concatenate(pts, axis=1)
            body = np.asarray(body, int)
            return {"body": body, "radii": np.concatenate(radii, axis=1), "offsets": pts - centres[:, body],
                    "normals": np.concatenate(nrm, axis=1), "phi": phi,
                    "omega": np.concatenate(oms, axis=1), "damping": np.concatenate(dmps, axis=1),
                    "rest": centres, "onehot": (body[:, None] == np.arange(len(self.caps))[None]).astype(float),
                    "outer": np.stack([self.capsule(c)["outer"] for c in range(len(self.caps))], axis=1)}
        return self.once("layout", build)

    # -- drives: the programs' amplitudes and the transducer's values per point -----------------------
    def moving(self, path: str) -> bool:
        """Whether field ``path`` varies over the points."""
        return path in self.batch.fields

    def transducer_moves(self) -> bool:
        return self.design.transducer is not None and any(p.startswith("transducer.") for p in self.batch.fields)

    def gain(self, f) -> np.ndarray:
        """Transducer gain (Pa/V) at the tones ``f`` (T,): (T,) from the design's table, or (N, T) from each
        point's table when a swept parameter moves the transducer (paper Fig. S1, linear interpolation)."""
        from acl.analysis.acoustics import drive_gain

        if not self.transducer_moves():
            return drive_gain(self.design, f)[0]
        fs, gs = self.gain_table()
        return pressure_per_volt_rows(np.broadcast_to(np.asarray(f, float), (self.n, np.size(f))), fs, gs)

    def gain_rows(self, f: np.ndarray) -> np.ndarray:
        """Gain (Pa/V) at one frequency per point ``f`` (N,)."""
        from acl.analysis.acoustics import drive_gain

        if not self.transducer_moves():
            return drive_gain(self.design, f)[0]
        fs, gs = self.gain_table()
        return pressure_per_volt_rows(np.asarray(f, float)[:, None], fs, gs)[:, 0]

    def gain_table(self) -> tuple[np.ndarray, np.ndarray]:
        def build():
            t = self.design.transducer
            fs = np.stack([self.get(f"transducer.gain_frequencies.{k}") for k in range(len(t.gain_frequencies))], axis=1)
            gs = np.stack([self.get(f"transducer.gain_pa_per_v.{k}") for k in range(len(t.gain_pa_per_v))], axis=1)
            return fs, gs
        return self.once("gain_table", build)

    def volt(self, path: str, nominal: float, divisor: int = 1):
        """One tone's amplitude: the float ``nominal`` (computed as the scalar code does) when ``path`` does
        not vary, else a key (path, divisor) that :meth:`volts` reads per point (hashable: cache keys)."""
        return ("field", path, divisor) if self.moving(path) else nominal

    def volts(self, volts: tuple) -> np.ndarray:
        """Tone amplitudes (T,) of a drive whose amplitudes are floats, else (N, T) per point."""
        if all(isinstance(v, (int, float)) for v in volts):
            return np.asarray(volts, float)
        return np.stack([self._volt(v) for v in volts], axis=1) if volts else np.zeros((self.n, 0))

    def _volt(self, v) -> np.ndarray:
        if isinstance(v, (int, float)):
            return np.full(self.n, float(v))
        if v[0] == "field":
            return self.get(v[1]) / v[2] if v[2] != 1 else self.get(v[1]).copy()
        # ("max", elements): the largest amplitude applied at a frequency, 0 -> the reference (report._amplitude_at)
        from acl.analysis.report import DEFAULT_V

        best = np.zeros(self.n)
        for e in v[1]:
            best = np.maximum(best, self._volt(e))
        return np.where(best > 0, best, DEFAULT_V)

    def pressure(self, freqs, volts: tuple) -> np.ndarray:
        """Drive pressure amplitude (Pa) of each tone: (T,), or (N, T) when amplitudes or gains vary per point."""
        return self.volts(volts) * self.gain(np.asarray(freqs, float))

    def limit_volt(self, p, i: int, st):
        """The voltage limit of a follow/switch/hold step: its own `limit`, else the transducer's maximum
        (None: neither; report.step_drives then uses the reference voltage)."""
        if st.limits.max_voltage is not None:
            return self.volt(f"programs.{p.name}.steps.{i}.limits.max_voltage", st.limits.max_voltage)
        if self.design.transducer is not None:
            return self.volt("transducer.max_voltage", self.design.transducer.max_voltage)
        return None

    def step_drives(self) -> list:
        """(program, step index, step, frequencies, amplitudes) of every step with a definite drive
        (report.step_drives), the amplitudes per point where a swept parameter moves them."""
        def build():
            from acl.analysis.report import step_drives

            out = []
            for p, i, st, drive in step_drives(self.design):
                freqs = tuple(t.frequency for t in drive.tones)
                if st.kind == "drive":
                    volts = tuple(self.volt(f"programs.{p.name}.steps.{i}.drive.tones.{j}.amplitude", t.amplitude)
                                  for j, t in enumerate(drive.tones))
                else:
                    lim = self.limit_volt(p, i, st)
                    volts = tuple(t.amplitude if not isinstance(lim, tuple) else ("field", lim[1], len(st.tones))
                                  for t in drive.tones)
                out.append((p, i, st, freqs, volts))
            return out
        return self.once("step_drives", build)

    def amplitude_at(self, f: float):
        """The largest amplitude the programs apply at f (report._amplitude_at), per point when it moves."""
        from acl.analysis.report import _amplitude_at

        elems, moving = [], False
        for p in self.design.programs:
            for i, st in enumerate(p.steps):
                if st.kind == "drive":
                    for j, t in enumerate(st.drive.tones):
                        if t.frequency == f:
                            e = self.volt(f"programs.{p.name}.steps.{i}.drive.tones.{j}.amplitude", t.amplitude)
                            elems.append(e)
                            moving |= isinstance(e, tuple)
                elif st.kind in ("follow", "switch", "hold") and f in st.tones:
                    e = self.limit_volt(p, i, st)
                    if e is not None:
                        elems.append(e)
                        moving |= isinstance(e, tuple)
        return ("max", tuple(elems)) if moving else _amplitude_at(self.design, f)

    def thrust_scale(self) -> np.ndarray:
        """(N, C) declared thrust coefficient / the capsule's own thrust per V^2 at its first reported mode (acoustics._thrust_scale)."""
        def build():
            out = np.ones((self.n, len(self.caps)))
            for c in range(len(self.caps)):
                g = self.capsule(c)
                if g["gamma"] is None or g["radii"].shape[1] == 0:
                    continue
                om, q, vol = self.bare(c)
                f1 = self.modes(c)[0][:, 0]
                p = g["radii"].shape[1]
                body = np.zeros(p, int)
                h0 = PB.uncoupled_response(vol, om, om / q, body, f1[:, None])
                u = PB.coupled_response(h0, g["points"], g["radii"], body, f1[:, None], self.medium["density"],
                                        self.medium["sound_speed"], C.SUBSTRATE_REFLECTION)[:, 0]
                u = u * self.gain_rows(f1)[:, None]
                per = thrust_magnitude(u, g["radii"], 2 * np.pi * f1[:, None], self.medium["viscosity"][:, None],
                                       C.STREAMING_CONSTANT)
                total = np.linalg.norm((per[..., None] * -g["normals"]).sum(axis=1), axis=-1)
                out[:, c] = np.where(total > 0, g["gamma"] / np.where(total > 0, total, 1.0), 1.0)
            return out
        return self.once("thrust_scale", build)

    def h0(self, freqs: tuple) -> np.ndarray:
        lay = self.layout()
        return self.once(("h0", freqs), lambda: PB.uncoupled_response(
            lay["phi"], lay["omega"], lay["damping"], lay["body"], np.asarray(freqs, float)[None, :]))

    def forces(self, centres, freqs: tuple, volts, parts: bool = False):
        """Total acoustic force (N, C, 3) at capsule centres (N, C, 3) for tones (freqs, volts) (acoustics._Engine.forces)."""
        lay = self.layout()
        f = np.asarray(freqs, float)
        pressure = self.pressure(f, volts)                                # (T,) or (N, T) per point
        pts = centres[:, lay["body"]] + lay["offsets"]                    # (N, n, 3)
        if not parts and f.size == 1 and lay["body"].tolist() == [0, 1]:  # two one-orifice capsules, one tone
            h = self.h0(tuple(freqs))[:, 0]
            return PB.two_bubble_forces(np.stack([h[:, 0, 0], h[:, 1, 1]], axis=1), pts, lay["radii"], lay["normals"],
                                        centres, lay["outer"], self.thrust_scale(), 2 * np.pi * f[0], pressure[..., 0],
                                        self.medium["density"], self.medium["sound_speed"], self.medium["viscosity"],
                                        C.STREAMING_CONSTANT, C.SUBSTRATE_REFLECTION)
        u = PB.coupled_response(self.h0(tuple(freqs)), pts, lay["radii"], lay["body"], f[None, :],
                                self.medium["density"], self.medium["sound_speed"], C.SUBSTRATE_REFLECTION)
        u = u * (pressure[None, :, None] if pressure.ndim == 1 else pressure[:, :, None])   # (N, T, n)
        w = 2 * np.pi * f
        thr = thrust_magnitude(u, lay["radii"][:, None, :], w[None, :, None], self.medium["viscosity"][:, None, None],
                               C.STREAMING_CONSTANT).sum(axis=1) * self.thrust_scale()[:, lay["body"]]   # (N, n)
        f_thr = np.einsum("bn,bnk,nc->bck", thr, -lay["normals"], lay["onehot"])
        sep = pts[:, None, :, :] - pts[:, :, None, :]                     # p_j - p_i
        other = lay["body"][:, None] != lay["body"][None, :]
        d = np.where(other, np.linalg.norm(sep, axis=-1), 1.0)
        prod = np.einsum("t,bti,btj->bij", w**2, u, np.conj(u)).real
        att = self.medium["density"][:, None, None] * prod / (8 * np.pi * d**2) * other
        f_bj = np.einsum("bij,bijk,ic->bck", att / d, sep, lay["onehot"])
        x = centres[:, None, :, :] - pts[:, :, None, :]                    # (N, n, C, 3)
        dist = np.linalg.norm(x, axis=-1)
        cos = np.einsum("bnck,bnk->bnc", x, lay["normals"]) / dist
        mask = lay["body"][:, None] != np.arange(len(self.caps))[None, :]
        drag = jet_drag(thr[:, :, None], np.where(mask, dist, 1.0), cos, lay["outer"][:, None, :]) * mask
        f_dr = np.einsum("bnc,bnk->bck", drag, lay["normals"])
        total = f_thr + f_bj + f_dr
        if parts:
            return total, u, thr, att, pts
        return total

    # -- pairs at the program frequencies -------------------------------------------------------------
    def pair_quantities(self, f: float) -> dict:
        def build():
            lay = self.layout()
            v = self.amplitude_at(f)
            centres = lay["rest"]
            _, u, thr, att, pts = self.forces(centres, (f,), (v,), parts=True)
            thrust_vec = np.einsum("bn,bnk,nc->bck", thr, -lay["normals"], lay["onehot"])
            out = {}
            for a, b in _pairs(self.design):
                ia_, ib_ = self.caps.index(self.design.capsule(a)), self.caps.index(self.design.capsule(b))
                ia, ib = np.flatnonzero(lay["body"] == ia_), np.flatnonzero(lay["body"] == ib_)
                sep = pts[:, ib][:, None, :, :] - pts[:, ia][:, :, None, :]
                dd = np.linalg.norm(sep, axis=-1)
                fa = np.einsum("bij,bijk->bk", att[:, ia][:, :, ib] / dd, sep)
                line = centres[:, ib_] - centres[:, ia_]
                dist = np.linalg.norm(line, axis=-1)
                unit = line / np.where(dist > 0, dist, 1.0)[:, None]
                attraction = np.einsum("bk,bk->b", fa, unit)
                va, vb = u[:, 0, ia], u[:, 0, ib]
                rows = np.arange(self.n)
                ja, jb = first_max(np.abs(va), axis=1), first_max(np.abs(vb), axis=1)   # ties: acoustics.pair_table
                dphi = np.angle(va[rows, ja] * np.conj(vb[rows, jb]))
                gap = np.linalg.norm(pts[rows, ib[jb]] - pts[rows, ia[ja]], axis=-1)
                gamma2 = np.einsum("bk,bk->b", thrust_vec[:, ia_], -unit) + np.einsum("bk,bk->b", thrust_vec[:, ib_], unit)
                alpha = attraction * gap**2
                dc = np.where((alpha > 0) & (gamma2 > 0), np.sqrt(np.abs(alpha / np.where(gamma2 != 0, gamma2, 1.0))), np.nan)
                tag = f"{_ident(a)}_{_ident(b)}_{_fkey(f)}"
                out[f"force_{tag}_n"] = attraction
                out[f"attract_{tag}"] = attraction > 0
                out[f"phase_{tag}_deg"] = np.degrees(dphi)
                out[f"critical_distance_{tag}_m"] = dc
            return out
        return self.once(("pairs", f), build)

    # -- mechanics: a capsule on a beam, a pair on two beams ------------------------------------------
    def beam_of(self, c: int):
        j = self.design.mount_of(self.caps[c].name)
        if j is None or j.kind != "mount" or j.target_kind != "beam":
            return None
        beam = self.design.beam(j.target)
        base = f"beams.{beam.name}"
        sec = beam.section
        if sec.shape == "circle":
            i2 = np.pi * self.get(f"{base}.section.diameter") ** 4 / 64
        else:
            a_, b_ = self.get(f"{base}.section.width"), self.get(f"{base}.section.thickness")
            lo, hi = np.minimum(a_, b_), np.maximum(a_, b_)
            i2 = hi * lo**3 / 12
        axis = self.vec(f"{base}.axis")
        axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
        return {"name": beam.name, "L": self.get(f"{base}.length"), "l": self.get(f"{base}.rigid_length"),
                "EI": self.get(f"{base}.youngs_modulus") * i2, "axis": axis}

    def single_deflection(self, drive: M.Drive) -> dict:
        """Load-point deflection of every beam carrying a lone capsule under ``drive`` (fixed point of Eq. (1) under the force at the displaced position)."""
        f = tuple(t.frequency for t in drive.tones)
        v = tuple(t.amplitude for t in drive.tones)
        lay = self.layout()
        out = {}
        (c,) = [i for i in range(len(self.caps)) if self.beam_of(i) is not None]
        bm = self.beam_of(c)
        ax = bm["axis"]
        proj = np.eye(3)[None] - ax[:, :, None] * ax[:, None, :]
        x = np.zeros((self.n, 3))
        delta = np.zeros(self.n)
        # one capsule on a beam along z moves parallel to the substrate: its force (own interfaces and
        # their images) does not depend on the deflection, so the first evaluation is the fixed point
        still = len(self.caps) == 1 and bool(np.all(np.abs(ax[:, 2]) == 1.0))
        for _ in range(1 if still else 30):
            centres = lay["rest"].copy()
            centres[:, c] = centres[:, c] + x
            F = np.einsum("bij,bj->bi", proj, self.forces(centres, f, v)[:, c])
            P = np.linalg.norm(F, axis=-1)
            new = PB_eq1_deflection(P, bm)
            x_new = F / np.where(P > 0, P, 1.0)[:, None] * new[:, None]
            done = np.all(np.abs(new - delta) <= 1e-13 * np.maximum(new, 1e-300))
            x, delta = x_new, new
            if done:
                break
        out[f"tip_deflection_{_ident(bm['name'])}_m"] = delta
        out["equilibrium_ok"] = np.isfinite(delta)
        return out

    def pair_setup(self):
        """Closure geometry of the pair on two beams: directions, projections, beam data."""
        def build():
            lay = self.layout()
            a, b = 0, 1
            ca, cb = self.caps[a], self.caps[b]
            # closest orifices at rest, as mechanics._closest_orifices (nominal choice)
            best = min(((np.linalg.norm(np.subtract(ob.center, oa.center)), ia, ib)
                        for ia, oa in enumerate(ca.orifices) for ib, ob in enumerate(cb.orifices)))
            ia = int(np.flatnonzero(lay["body"] == a)[best[1]])
            ib = int(np.flatnonzero(lay["body"] == b)[best[2]])
            pts = lay["rest"][:, lay["body"]] + lay["offsets"]
            line = pts[:, ib] - pts[:, ia]
            g0 = np.linalg.norm(line, axis=-1)
            nrm = line / g0[:, None]
            beams = [self.beam_of(a), self.beam_of(b)]
            dirs, cosines = [], []
            for k, (bm, sgn) in enumerate(zip(beams, (1.0, -1.0))):
                if bm is None:
                    dirs.append(np.zeros((self.n, 3)))
                    cosines.append(np.zeros(self.n))
                    continue
                ax = bm["axis"]
                e = sgn * (nrm - ax * np.einsum("bk,bk->b", nrm, ax)[:, None])
                en = np.linalg.norm(e, axis=-1)
                e = e / np.where(en > 0, en, 1.0)[:, None]
                dirs.append(e)
                cosines.append(np.einsum("bk,bk->b", e, sgn * nrm))
            return {"beams": beams, "dirs": dirs, "cos": cosines, "gap": g0, "n": nrm, "ia": ia, "ib": ib}
        return self.once("pair_setup", build)

    def pair_eval(self, xa, xb, freqs, volts):
        """Drive forces along each capsule's closing direction (fa, fb) and Eq. (1) beam loads (Pa, Pb) at deflections xa, xb."""
        ps = self.pair_setup()
        lay = self.layout()
        centres = lay["rest"].copy()
        for k, x in ((0, xa), (1, xb)):
            centres[:, k] = centres[:, k] + x[:, None] * ps["dirs"][k]
        F = self.forces(centres, freqs, volts)
        out = []
        for k, x in ((0, xa), (1, xb)):
            bm = ps["beams"][k]
            out.append(np.einsum("bk,bk->b", F[:, k], ps["dirs"][k]))
            out.append(PB.eq1_force(x, bm["L"], bm["l"], bm["EI"]) if bm is not None else np.zeros_like(x))
        return out

    def pair_closure(self, s, t, freqs, volts):
        """V^2 balance at closure s and split t: (h residual, V^2 of beam a, V^2 of beam b, xa, xb)."""
        ps = self.pair_setup()
        xs = []
        for k, sgn in ((0, 1.0), (1, -1.0)):
            c = ps["cos"][k]
            xs.append(np.where(c > 0, (s + sgn * t) / (2 * np.where(c > 0, c, 1.0)), 0.0))
        if ps["beams"][0] is None:
            xs = [np.zeros_like(s), s / ps["cos"][1]]
        if ps["beams"][1] is None:
            xs = [s / ps["cos"][0], np.zeros_like(s)]
        fa, Pa, fb, Pb = self.pair_eval(xs[0], xs[1], freqs, volts)
        if ps["beams"][0] is None:
            return np.zeros_like(s), Pb / fb, Pb / fb, xs[0], xs[1]
        if ps["beams"][1] is None:
            return np.zeros_like(s), Pa / fa, Pa / fa, xs[0], xs[1]
        return Pa * fb - Pb * fa, Pa / fa, Pb / fb, xs[0], xs[1]

    def plane_setup(self):
        """Moving capsules (on beams) and an orthonormal basis (N, 3, 2) of each one's plane of motion (mechanics._perp_basis)."""
        def build():
            out = []
            for c in range(len(self.caps)):
                bm = self.beam_of(c)
                if bm is None:
                    continue
                ax = bm["axis"]
                trial = np.where((np.abs(ax[:, 0]) < 0.9)[:, None], np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
                e1 = trial - ax * np.einsum("bk,bk->b", trial, ax)[:, None]
                e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
                e2 = np.cross(ax, e1)
                out.append((c, bm, np.stack([e1, e2], axis=2)))
            return out
        return self.once("plane_setup", build)

    def plane_residual(self, q, lam, freqs, volts):
        """Equilibrium residual (N, m) of the in-plane displacements q (N, m): Eq. (1) restoring force - V^2 x drive force, per moving capsule."""
        lay = self.layout()
        moving = self.plane_setup()
        centres = lay["rest"].copy()
        for j, (c, _bm, basis) in enumerate(moving):
            centres[:, c] = centres[:, c] + np.einsum("bkj,bj->bk", basis, q[:, 2 * j:2 * j + 2])
        F = self.forces(centres, freqs, volts)
        res = np.empty_like(q)
        for j, (c, bm, basis) in enumerate(moving):
            qj = q[:, 2 * j:2 * j + 2]
            delta = np.linalg.norm(qj, axis=-1)
            P = PB.eq1_force(delta, bm["L"], bm["l"], bm["EI"])
            from acl.physics.beams import eq1_small_force_stiffness

            k0 = eq1_small_force_stiffness(bm["L"], bm["l"], bm["EI"])
            ratio = np.where(delta > 1e-15 * bm["L"], P / np.where(delta > 0, delta, 1.0), k0)
            res[:, 2 * j:2 * j + 2] = ratio[:, None] * qj - lam[:, None] * np.einsum("bkj,bk->bj", basis, F[:, c])
        return res

    def plane_solve(self, q, lam, freqs, volts, iterations: int = 20, h: float = 1e-11):
        """Newton from q at drive scale lam (finite-difference Jacobian): (q, converged, smallest real eigenvalue of K_T)."""
        m = q.shape[1]
        conv = np.zeros(self.n, bool)
        lost = np.zeros(self.n, bool)            # Newton not contracting: no equilibrium near q (past a fold)
        mev = np.full(self.n, np.nan)
        prev = np.full(self.n, np.inf)
        for it in range(iterations):
            r = self.plane_residual(q, lam, freqs, volts)
            J = np.empty((self.n, m, m))
            for k in range(m):
                dq = q.copy()
                dq[:, k] += h
                J[:, :, k] = (self.plane_residual(dq, lam, freqs, volts) - r) / h
            try:
                step = np.linalg.solve(J, -r[..., None])[..., 0]
            except np.linalg.LinAlgError:
                step = np.full_like(q, np.nan)
            q = q + np.where((conv | lost)[:, None], 0.0, step)
            size = np.linalg.norm(step, axis=-1)
            small = size <= 1e-10 * np.linalg.norm(q, axis=-1) + 1e-18
            conv |= small & np.isfinite(step).all(axis=1) & ~lost
            if it >= 3:
                lost |= ~conv & ~(size < 0.5 * prev)
            prev = np.where(conv | lost, prev, size)
            mev = np.linalg.eigvals(np.where(np.isfinite(J), J, 0.0)).real.min(axis=1)
            if (conv | lost).all():
                break
        return q, conv & np.isfinite(q).all(axis=1), mev

    def plane_equilibrium(self, freqs, volts, steps: int = 8):
        """In-plane equilibrium at drive scale 1 by natural continuation in V^2 from rest: (q, ok); not ok after a lost or unstable step (snap-in)."""
        m = 2 * len(self.plane_setup())
        q = np.zeros((self.n, m))
        ok = np.ones(self.n, bool)
        for lam in np.linspace(0.0, 1.0, steps + 1)[1:]:
            q, conv, mev = self.plane_solve(q, np.full(self.n, lam), freqs, volts)
            ok &= conv & (mev > 0)
        return q, ok

    def plane_snap(self, freqs, volts, v_max: float, steps: int = 12, rtol: float = 1e-8) -> np.ndarray:
        """Snap-in voltage by continuation in V from 0 to v_max, Newton at each step, the step halved where the stable branch is lost (NaN: none below v_max)."""
        m = 2 * len(self.plane_setup())
        q = np.zeros((self.n, m))
        v = np.zeros(self.n)
        dv = np.full(self.n, v_max / steps)
        done = np.zeros(self.n, bool)
        snap = np.full(self.n, np.nan)
        failed = np.zeros(self.n, bool)          # once a step failed, steps only shrink (bisection of the fold)
        for _ in range(40 * steps):
            live = ~done
            if not live.any():
                break
            v_try = np.minimum(v + dv, v_max)
            qn, conv, mev = self.plane_solve(q, v_try * v_try, freqs, volts, iterations=12)
            good = conv & (mev > 0) & live
            q = np.where(good[:, None], qn, q)
            v = np.where(good, v_try, v)
            # grow after two successes in a row, halve after a failure (near the fold: a bisection)
            dv = np.where(good, np.where(failed, dv, np.minimum(dv * 1.5, v_max / steps)), np.where(live, dv / 2, dv))
            failed = live & ~good
            reached = good & (v >= v_max)
            folded = live & ~good & (dv < rtol * v_max)
            snap = np.where(folded, v, snap)
            done |= reached | folded
        return snap

    def pair_v2(self, s, t0, freqs, volts, slope=None):
        """V^2 on the equilibrium branch at closure s, the split t solved by secant from t0 (first step Newton with ``slope`` dh/dt when given).

        Returns (V^2, t, slope) with the last secant slope, to start the next closure.
        """
        ps = self.pair_setup()
        if ps["beams"][0] is None or ps["beams"][1] is None:
            _, va, _, _, _ = self.pair_closure(s, np.zeros_like(s), freqs, volts)
            return va, np.zeros_like(s), None
        h0, va, vb, _, _ = self.pair_closure(s, t0, freqs, volts)
        if slope is None:
            t1 = t0 + 1e-3 * s + 1e-15
        else:
            t1 = t0 - np.where(slope != 0, h0 / np.where(slope != 0, slope, 1.0), 0.0)
            t1 = np.clip(t1, t0 - 0.5 * s, t0 + 0.5 * s)
        h1, va1, vb1, _, _ = self.pair_closure(s, t1, freqs, volts)
        sl = slope
        for _ in range(SPLIT_ITER):
            den = h1 - h0
            ok = (den != 0) & (t1 != t0)
            sl = np.where(ok, den / np.where(t1 != t0, t1 - t0, 1.0), sl if sl is not None else 0.0)
            step = np.where(ok, -h1 / np.where(ok, sl, 1.0), 0.0)
            step = np.clip(step, -0.5 * s, 0.5 * s)
            if not np.any(np.abs(step) > 1e-10 * np.maximum(s, 1e-300)):      # NaN rows count as done
                break
            t0, h0 = t1, h1
            t1 = t1 + step
            h1, va1, vb1, _, _ = self.pair_closure(s, t1, freqs, volts)
        return 0.5 * (va1 + vb1), t1, sl

    def subset(self, rows: np.ndarray) -> "_Evaluator":
        """An evaluator over the points ``rows`` only (the expensive branch searches skip the others)."""
        sub = _Rows(self.batch, rows)
        return _Evaluator(sub, self.at)

    def rest_checks(self, freqs: tuple, volts: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(closing, lateral, opening) at rest: the drive pulls both capsules towards each other; a lateral force the reduced branch ignores; it pushes both apart."""
        ps = self.pair_setup()
        lay = self.layout()
        F0 = self.forces(lay["rest"], freqs, volts)
        lateral = np.zeros(self.n, bool)
        for k in range(2):
            bm = ps["beams"][k]
            if bm is None:
                continue
            ax = bm["axis"]
            fperp = F0[:, k] - ax * np.einsum("bk,bk->b", F0[:, k], ax)[:, None]
            along = np.einsum("bk,bk->b", fperp, ps["dirs"][k])
            side = np.linalg.norm(fperp - along[:, None] * ps["dirs"][k], axis=-1)
            lateral |= side > 1e-6 * np.maximum(np.abs(along), 1e-300)
        # both moving capsules pulled towards each other: the closure parametrises the branch; both pushed
        # apart: the gap only grows (thrust against a Bjerknes pull that weakens with distance), no snap-in
        closing = np.ones(self.n, bool)
        opening = np.ones(self.n, bool)
        for k in range(2):
            if ps["beams"][k] is not None:
                along = np.einsum("bk,bk->b", F0[:, k], ps["dirs"][k])
                closing &= along > 0
                opening &= along <= 0
        return closing, lateral, opening

    def fold(self, freqs: tuple, volts: tuple) -> dict:
        """First maximum of V^2 along the closure (grid of SNAP_GRID, then golden section): V^2 and s there, and whether one was found."""
        gap = self.pair_setup()["gap"]
        grid = np.linspace(0.0, 1.0, SNAP_GRID + 1)[1:]
        v2 = np.empty((self.n, grid.size))
        ts = np.empty((self.n, grid.size))
        t = np.zeros(self.n)
        slope = None
        prev = None
        for k, frac in enumerate(grid):
            s = frac * gap * 0.999
            guess = t if prev is None else t * (frac / prev)
            v2[:, k], t, slope = self.pair_v2(s, guess, freqs, volts, slope)
            ts[:, k] = t
            prev = frac
        pos = np.where(np.isfinite(v2) & (v2 > 0), v2, -np.inf)
        falls = pos[:, :-1] > pos[:, 1:]
        has = falls.any(axis=1)
        k = np.where(has, np.argmax(falls, axis=1), grid.size - 1)
        rows = np.arange(self.n)
        lo = np.where(k > 0, grid[np.maximum(k - 1, 0)], 0.0) * gap * 0.999
        hi = grid[np.minimum(k + 1, grid.size - 1)] * gap * 0.999
        tguess = ts[rows, k]
        g = (np.sqrt(5.0) - 1) / 2
        x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
        f1, t1, sl1 = self.pair_v2(x1, tguess, freqs, volts, slope)
        f2, t2, _ = self.pair_v2(x2, tguess, freqs, volts, sl1)
        for _ in range(SNAP_GOLDEN):
            left = f1 >= f2
            hi = np.where(left, x2, hi)
            lo = np.where(left, lo, x1)
            nx = np.where(left, hi - g * (hi - lo), lo + g * (hi - lo))
            nf, nt, _ = self.pair_v2(nx, np.where(left, t1, t2), freqs, volts, sl1)
            x2, f2, t2, x1, f1, t1 = (np.where(left, x1, nx), np.where(left, f1, nf), np.where(left, t1, nt),
                                      np.where(left, nx, x2), np.where(left, nf, f2), np.where(left, nt, t2))
        best = np.maximum(np.maximum(f1, f2), pos[rows, k])
        return {"v2": best, "s": np.where(f1 >= f2, x1, x2), "has": has}

    def pair_branch(self, freqs: tuple, volts: tuple) -> dict:
        """The fold (snap-in) of the pair's stable branch in the drive scale, searched only where the drive closes the pair."""
        def build():
            closing, lateral, opening = self.rest_checks(freqs, volts)
            rows = np.flatnonzero(closing & ~lateral)
            v2 = np.full(self.n, np.nan)
            s = np.full(self.n, np.nan)
            has = np.zeros(self.n, bool)
            if rows.size:
                sub = self if rows.size == self.n else self.subset(rows)
                with np.errstate(all="ignore"):
                    fo = sub.fold(freqs, volts)
                v2[rows] = np.where(fo["has"], fo["v2"], np.nan)
                s[rows], has[rows] = fo["s"], fo["has"]
            return {"v2_fold": v2, "s_fold": s, "lateral": lateral, "closing": closing, "opening": opening & ~lateral,
                    "has_fold": has}
        return self.once(("branch", freqs, volts), build)

    def snap_in(self, f: float) -> np.ndarray:
        vmax = self.design.transducer.max_voltage if self.design.transducer else 20.0
        if self.design.transducer is not None and self.moving("transducer.max_voltage"):
            vmax = self.get("transducer.max_voltage")          # each point's amplifier limit
        if not _closed_form(self.design)[0]:                   # springs, latches, trusses, 3+ capsules
            def general():
                with np.errstate(all="ignore"):
                    return self.mechanism().snap_in((f,), (1.0,), vmax)
            return self.once(("general_snap", f), general)
        br = self.pair_branch((f,), (1.0,))
        v = np.sqrt(br["v2_fold"])
        out = np.where(v <= vmax, v, np.nan)
        # one pulled and one pushed, or a lateral force: both planes of motion, continuation in V
        rows = np.flatnonzero(~br["closing"] & ~br["opening"] | br["lateral"])
        if rows.size:
            with np.errstate(all="ignore"):
                out[rows] = self.subset(rows).plane_snap((f,), (1.0,), vmax if np.ndim(vmax) == 0 else vmax[rows])
        return out

    def closing_equilibrium(self, freqs, volts, hi):
        """(xa, xb) where V^2(s) = 1 on the ascending branch, s in (0, hi): regula falsi (Illinois), V^2(0) = 0."""
        f_hi, t_hi, _ = self.pair_v2(hi, np.zeros(self.n), freqs, volts)

        def f(x, t_warm):
            v2, t, _ = self.pair_v2(x, t_warm, freqs, volts)
            return v2 - 1.0, t

        s, fs, t = PB.illinois_ascending(f, np.zeros(self.n), hi, -np.ones(self.n), f_hi - 1.0, 30, 1e-12, 1e-13,
                                         state=t_hi)
        _, _, _, xa, xb = self.pair_closure(s, t, freqs, volts)
        bad = ~(np.abs(fs) <= 1e-9)                  # no root bracketed (or not converged): not an equilibrium
        return np.where(bad, np.nan, xa), np.where(bad, np.nan, xb)

    def pair_deflection(self, drive: M.Drive) -> dict:
        """Beam deflections of the pair at drive scale 1 on the stable branch from rest (mechanics.equilibrium): NaN after snap-in."""
        disp, ok = self.pair_equilibrium(tuple(t.frequency for t in drive.tones), tuple(t.amplitude for t in drive.tones))
        out = {"equilibrium_ok": ok}
        for c in range(len(self.caps)):
            bm = self.beam_of(c)
            if bm is not None:
                out[f"tip_deflection_{_ident(bm['name'])}_m"] = np.where(ok, np.linalg.norm(disp[:, c], axis=-1), np.nan)
        return out

    def mechanism(self):
        """The general batched mechanism (acl.sweep.mechanism) of these points."""
        from acl.sweep.mechanism import Mechanism, MechanismError

        def build():
            try:
                return Mechanism(self)
            except MechanismError as exc:
                raise QuantityError("E-SWEEP-Q02", f"the mechanism is not batched for these points: {exc}") from None
        return self.once("mechanism", build)

    def general_equilibrium(self, freqs: tuple, volts: tuple):
        """(displacement (N, C, 3), ok, deflections {element: (N,)}) of the general mechanism at a drive (mechanics.equilibrium)."""
        def build():
            me = self.mechanism()
            if not freqs:
                z, ok = np.zeros((self.n, me.m)), np.ones(self.n, bool)
            else:
                with np.errstate(all="ignore"):
                    z, ok = me.equilibrium(freqs, volts)
            return me.displacements(z), ok, me.deflections(z)
        return self.once(("general_eq", freqs, volts), build)

    def general_deflection(self, drive: M.Drive) -> dict:
        """Deflection columns of the general mechanism at ``drive`` (NaN after snap-in)."""
        _, ok, defl = self.general_equilibrium(tuple(t.frequency for t in drive.tones),
                                               tuple(t.amplitude for t in drive.tones))
        out = {"equilibrium_ok": ok}
        for name, kind in _elements(self.design):
            col = "tip_deflection" if kind == "beam" else "deflection"
            out[f"{col}_{_ident(name)}_m"] = np.where(ok, defl[name], np.nan)
        return out

    def pair_equilibrium(self, freqs: tuple, volts: tuple):
        """(displacement (N, C, 3), ok) of the pair's capsules at ``drive`` (mechanics.equilibrium from rest); not ok after snap-in.

        A pair the drive pulls together along its line: regula falsi on V^2(s) = 1 below the fold of
        the reduced branch; any other (pushed apart, one pushed and one pulled, a lateral force):
        natural continuation in V^2 with Newton on both beams' planes of motion.
        """
        return self.once(("pair_eq", freqs, volts), lambda: self._pair_equilibrium(freqs, volts))

    def _pair_equilibrium(self, freqs, volts):
        disp = np.zeros((self.n, len(self.caps), 3))
        if not freqs:
            return disp, np.ones(self.n, bool)
        br = self.pair_branch(freqs, volts)
        ps = self.pair_setup()
        closing, lateral = br["closing"], br["lateral"]
        ok = np.zeros(self.n, bool)
        reach = closing & ~lateral & ~(br["v2_fold"] <= 1.0)       # no fold below the drive
        rows = np.flatnonzero(reach)
        if rows.size:
            sub = self.subset(rows)
            hi = np.where(br["has_fold"][rows], br["s_fold"][rows], ps["gap"][rows] * 0.999)
            with np.errstate(all="ignore"):
                xa, xb = sub.closing_equilibrium(freqs, volts, hi)
            for k, x in ((0, xa), (1, xb)):
                disp[rows, k] = x[:, None] * ps["dirs"][k][rows]
            ok[rows] = np.isfinite(xa) & np.isfinite(xb)
        rows = np.flatnonzero(~closing | lateral)
        if rows.size:
            sub = self.subset(rows)
            with np.errstate(all="ignore"):
                q, good = sub.plane_equilibrium(freqs, volts)
            for j, (c, _bm, basis) in enumerate(sub.plane_setup()):
                disp[rows, c] = np.einsum("bkj,bj->bk", basis, q[:, 2 * j:2 * j + 2])
            ok[rows] = good
        return disp, ok

    def gap_over_steps(self, a: str, b: str) -> np.ndarray:
        """require gap: the smallest distance of orifices a, b over rest and the equilibrium of every program step, 0 after snap-in (report._require)."""
        lay = self.layout()
        (ca, oa), (cb, ob) = a.split("."), b.split(".")
        names = [c.name for c in self.caps]

        def point(cap, orf, disp):
            k = names.index(cap)
            o = [x.name for x in self.caps[k].orifices].index(orf)
            i = int(np.flatnonzero(lay["body"] == k)[o])
            return lay["rest"][:, k] + lay["offsets"][:, i] + disp[:, k]

        zero = np.zeros((self.n, len(self.caps), 3))
        gap = np.linalg.norm(point(cb, ob, zero) - point(ca, oa, zero), axis=-1)
        general = _uses_general(self.design) and not (_mechanism(self.design) == "beams" and len(self.caps) == 2)
        for _p, _i, _st, freqs, volts in self.step_drives():
            if general:
                disp, ok, _ = self.general_equilibrium(freqs, volts)
            else:
                disp, ok = self.pair_equilibrium(freqs, volts)
            g = np.linalg.norm(point(cb, ob, disp) - point(ca, oa, disp), axis=-1)
            gap = np.minimum(gap, np.where(ok, g, 0.0))
        return gap

    # -- latches ------------------------------------------------------------------------------------
    def latch(self, name: str) -> dict:
        """Switching and release forces of latch ``name`` per point and its margin at every program step
        (mechanics.latch_margins as analyze calls it: the shuttle's capsules and those trussed to them, every latch in
        the state the program's earlier steps leave it, per point)."""
        return self.latches_all()[name]

    def latches_all(self) -> dict:
        def build():
            from acl.analysis.mechanics import latch_carried
            from acl.physics.latch import latch_landscape

            lats = {}
            for lt in self.design.latches:
                base = f"latches.{lt.name}"
                geo = [self.get(f"{base}.{k}") for k in ("angle", "length", "width", "thickness", "youngs_modulus")]
                fsw, rel, bistable = PB.latch_switching_force(*geo)
                axis = np.asarray(lt.axis, float)
                lats[lt.name] = {"switching": fsw, "release": rel, "bistable": bistable, "margins": {},
                                 "geo": [np.broadcast_to(np.asarray(g, float), (self.n,)) for g in geo],
                                 "axis": axis / np.linalg.norm(axis), "travel": None,
                                 "carried": [self.caps.index(self.design.capsule(c)) for c in latch_carried(self.design, lt)]}
            lay = self.layout()
            program, flipped = None, {}
            for p, i, _st, freqs, volts in self.step_drives():
                if p is not program:           # each program starts from the declared states
                    program, flipped = p, {lt.name: np.zeros(self.n, bool) for lt in self.design.latches}
                pos = lay["rest"]
                for lt in self.design.latches:
                    lat = lats[lt.name]
                    if not flipped[lt.name].any():
                        continue
                    if lat["travel"] is None:   # state b travel per point (latch_landscape, as analyze)
                        tr = [latch_landscape(*(float(g[k]) for g in lat["geo"])).state_b for k in range(self.n)]
                        lat["travel"] = np.array([np.nan if x is None else x for x in tr], float)
                    shift = np.where(flipped[lt.name] & np.isfinite(lat["travel"]), np.nan_to_num(lat["travel"]), 0.0)
                    shift = shift * (1.0 if lt.state == "a" else -1.0)
                    pos = np.array(pos, float, copy=True)
                    for c in lat["carried"]:
                        pos[:, c] = pos[:, c] + shift[:, None] * lat["axis"]
                F = self.forces(pos, freqs, volts)
                for lt in self.design.latches:
                    lat = lats[lt.name]
                    push = sum((F[:, c] @ lat["axis"] for c in lat["carried"]), np.zeros(self.n))
                    in_a = (lt.state == "a") != flipped[lt.name]
                    required = np.where(in_a, lat["switching"],
                                        np.where(lat["bistable"], np.nan_to_num(lat["release"]), 0.0))
                    avail = np.where(in_a, push, -push)
                    m = np.where(required > 0, avail / np.where(required > 0, required, 1.0), np.inf)
                    lat["margins"][(p.name, i)] = m
                    flipped[lt.name] = flipped[lt.name] ^ (m >= 1.0)
            return lats
        return self.once(("latches",), build)

    # -- requires and lint ------------------------------------------------------------------------------
    def require(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        from acl.analysis.report import step_drives

        r = self.design.requires[i - 1]
        idx = {c.name: k for k, c in enumerate(self.caps)}
        if r.kind == "resonance":
            f = self.modes(idx[r.args[0]])[0]
            value = f[:, r.mode] if r.mode < f.shape[1] else np.full(self.n, np.nan)
        elif r.kind == "separation" and len(r.args) == 1:      # closest adjacent modes of one capsule
            f = np.sort(self.modes(idx[r.args[0]])[0], axis=1)     # NaN (mode not reported) sorts last
            if f.shape[1] < 2:
                value = np.full(self.n, np.nan)
            else:
                gaps = np.diff(f, axis=1)
                gaps = np.where(np.isfinite(gaps), gaps, np.inf).min(axis=1)
                value = np.where(np.isfinite(gaps), gaps, np.nan)
        elif r.kind == "separation":
            value = np.abs(self.modes(idx[r.args[0]])[0][:, 0] - self.modes(idx[r.args[1]])[0][:, 0])
        elif r.kind == "margin":
            lat = self.latch(r.args[0])
            steps = list(step_drives(self.design))
            intended = [lat["margins"][(p.name, k)] for p, k, st, _d in steps
                        if st.kind == "switch" and st.latch == r.args[0]]
            allm = [lat["margins"][(p.name, k)] for p, k, _st, _d in steps]
            if intended:
                value = np.min(intended, axis=0)
            elif allm:
                value = np.max(allm, axis=0)
            else:
                value = np.full(self.n, np.nan)
        elif r.kind == "gap":
            value = self.gap_over_steps(r.args[0], r.args[1])
        else:
            raise QuantityError("E-SWEEP-Q02", f"`{r.text}` is not batched")
        ok = np.isfinite(value) | np.isinf(value)
        ok &= ~np.isnan(value)
        if r.lower is not None:      # bounds may follow a swept parameter (`in f0 - 5 kHz .. f0 + 5 kHz`)
            ok &= value >= self.get(f"requires.{i - 1}.lower")
        if r.upper is not None:
            ok &= value <= self.get(f"requires.{i - 1}.upper")
        return value, ok

    def lint(self, code: str) -> np.ndarray:
        from acl.lint.registry import THRESHOLDS

        thr = {k: t.default for k, t in THRESHOLDS.items()}
        ok = np.ones(self.n, bool)
        if code == "acl101":
            t = self.design.transducer
            if t is None:
                return ok
            lo, hi = (self.get(f"transducer.band.{k}") for k in (0, 1)) if self.transducer_moves() else t.band
            for c in range(len(self.caps)):
                f = self.modes(c)[0]
                ok &= np.all(np.isnan(f) | ((f >= lo) & (f <= hi)), axis=1)
            return ok
        if code == "acl501":
            return self.marginal_features_ok(thr["print_margin"])
        if code == "acl502":
            fixed = {j.capsule for j in self.design.joints if j.kind == "fix"}
            limit = thr["substrate_clearance"]
            for c, cap in enumerate(self.caps):
                if cap.name in fixed:
                    continue
                low = self.capsule(c)["center"][:, 2] - self.half_height(c)
                ok &= ~(low < limit - 1e-9)
            return ok
        if code == "acl503":
            for c in range(len(self.caps)):
                ok &= np.all(self.capsule(c)["radii"] >= thr["orifice_min_radius"], axis=1)
            return ok
        if code == "acl504":
            for c in range(len(self.caps)):
                g = self.capsule(c)
                caps = (2 / 3 * np.pi * g["radii"] ** 3).sum(axis=1)
                ok &= ~((caps > 0) & (g["volume"] < thr["cap_volume_ratio"] * caps))
            return ok
        if code == "acl603":
            for i in range(1, len(self.design.requires) + 1):
                ok &= self.require(i)[1]
            return ok
        if code == "acl105":
            return self.linear_ok(thr["linear_amplitude"], int(thr["sweep_samples"]))
        if code == "acl201":
            return self.snap_in_ok(thr["snap_margin"])
        if code == "acl102":
            return self.gain_ok(thr["gain_ratio"])
        if code in ("acl401", "acl402"):
            return self.beam_lint(thr["strain_limit"], thr["eq1_tolerance"])[code]
        if code == "acl103":
            return self.crosstalk_ok(thr["bandwidth_overlap"])
        raise QuantityError("E-SWEEP-Q01", f"lint rule {code} is not batched")

    def lint_drives(self, p) -> list:
        """(step, frequencies, amplitudes) of each drive lint knows for the steps of program ``p``
        (acl.lint.context.Context._step_drives): a drive step's tones; each pinned tone of a
        follow/switch/hold alone at the step's limit (or the transducer's maximum); sweeps excluded."""
        out = []
        for i, st in enumerate(p.steps):
            if st.kind == "drive":
                out.append((st, tuple(t.frequency for t in st.drive.tones),
                            tuple(self.volt(f"programs.{p.name}.steps.{i}.drive.tones.{j}.amplitude", t.amplitude)
                                  for j, t in enumerate(st.drive.tones))))
            elif st.kind in ("follow", "switch", "hold") and st.tones:
                v = self.limit_volt(p, i, st)
                if v is not None:
                    out += [(st, (f,), (v,)) for f in st.tones]
        return out

    def snap_in_ok(self, margin: float) -> np.ndarray:
        """ACL201 (the Eq. 3 criterion; lint's default, without `mechanics`): no pair, outside the pairs a
        program's `hold`/`cross` governs and not both fixed, is closer than margin x d_c under a drive of
        the program while each capsule's thrust pushes it away from the other
        (lint.rules.forces.snap_in; acoustics.pair_table's dominant interfaces at the strongest tone)."""
        from acl.lint.rules.forces import _managed

        ok = np.ones(self.n, bool)
        if len(self.caps) < 2:
            return ok
        lay = self.layout()
        names = [c.name for c in self.caps]
        fixed = {j.capsule for j in self.design.joints if j.kind == "fix"}
        rows = np.arange(self.n)
        for p in self.design.programs:
            crossing = _managed(p)
            for _st, freqs, volts in self.lint_drives(p):
                if not freqs:
                    continue
                _, u, thr, att, pts = self.forces(lay["rest"], freqs, volts, parts=True)
                thrust_vec = np.einsum("bn,bnk,nc->bck", thr, -lay["normals"], lay["onehot"])
                mag = np.abs(u)                                                          # (N, T, n)
                for a, b in _pairs(self.design):
                    if tuple(sorted((a, b))) in crossing or (a in fixed and b in fixed):
                        continue
                    ca, cb = names.index(a), names.index(b)
                    ia, ib = np.flatnonzero(lay["body"] == ca), np.flatnonzero(lay["body"] == cb)
                    if not (ia.size and ib.size):
                        continue
                    sep = pts[:, ib][:, None, :, :] - pts[:, ia][:, :, None, :]
                    dd = np.linalg.norm(sep, axis=-1)
                    fa = np.einsum("bij,bijk->bk", att[:, ia][:, :, ib] / dd, sep)
                    line = lay["rest"][:, cb] - lay["rest"][:, ca]
                    dist = np.linalg.norm(line, axis=-1)
                    unit = line / np.where(dist > 0, dist, 1.0)[:, None]
                    attraction = np.einsum("bk,bk->b", fa, unit)
                    # dominant interfaces at the strongest tone (first maxima, as numpy's argmax)
                    t = np.argmax(mag[:, :, ia].max(axis=2) * mag[:, :, ib].max(axis=2), axis=1)
                    ja = ia[np.argmax(mag[rows, t][:, ia], axis=1)]
                    jb = ib[np.argmax(mag[rows, t][:, ib], axis=1)]
                    gap = np.linalg.norm(pts[rows, jb] - pts[rows, ja], axis=-1)
                    gamma2 = (np.einsum("bk,bk->b", thrust_vec[:, ca], -unit)
                              + np.einsum("bk,bk->b", thrust_vec[:, cb], unit))
                    alpha = attraction * gap**2
                    dc = np.where((alpha > 0) & (gamma2 > 0), np.sqrt(np.abs(alpha / np.where(gamma2 != 0, gamma2, 1.0))),
                                  np.nan)
                    pushed = (np.einsum("bk,bk->b", thrust_vec[:, ca], -unit) > 0) & \
                             (np.einsum("bk,bk->b", thrust_vec[:, cb], unit) > 0)
                    ok &= ~((gap < margin * dc) & pushed)
        return ok

    def beam_lint(self, strain_limit: float, tolerance: float) -> dict:
        """ACL401 (clamp strain P (L + l) c / (E I) over the limit) and ACL402 (deflection beyond Eq. (1)'s
        validity) from each program's worst load on each beam carrying a capsule (lint.rules.beams.beam_loads:
        the first strongest drive of a step at rest, perpendicular to the beam; a `follow` path's reach)."""
        def build():
            from acl.lint.rules.beams import SAFE_RATIO, _linked, _path_extent, eq1_limit_ratio
            from acl.physics.beams import eq1_deflection

            ok401, ok402 = np.ones(self.n, bool), np.ones(self.n, bool)
            lay = self.layout()
            names = [c.name for c in self.caps]
            for beam in self.design.beams:
                cap = next((j.capsule for j in self.design.joints if j.kind == "mount" and j.target == beam.name), None)
                if cap is None or _linked(self, cap):     # linked: lint checks it only with mechanics
                    continue
                ci = names.index(cap)
                bm = self.beam_of(ci)
                if bm is None:
                    continue
                L, l, EI, axis = bm["L"], bm["l"], bm["EI"], bm["axis"]
                base = f"beams.{beam.name}.section"
                c = self.get(f"{base}.diameter") / 2 if beam.section.shape == "circle" else \
                    np.minimum(self.get(f"{base}.width"), self.get(f"{base}.thickness")) / 2
                for p in self.design.programs:
                    worst_p = np.full(self.n, np.nan)
                    worst_d = np.full(self.n, np.nan)
                    drives = {id(st): [] for st in p.steps}
                    for st, freqs, volts in self.lint_drives(p):
                        drives[id(st)].append((freqs, volts))
                    for st in p.steps:
                        if st.kind == "follow":
                            if st.capsule != cap:
                                continue
                            ext = _path_extent(st)
                            if ext is None:
                                continue
                            P, defl = PB.eq1_force(np.full(self.n, ext), L, l, EI), np.full(self.n, ext)
                        elif st.kind == "hold" and st.mode == "cross" and cap in (st.a.split(".")[0], st.b.split(".")[0]):
                            continue
                        else:
                            if not drives[id(st)]:
                                continue
                            P = None
                            for freqs, volts in drives[id(st)]:       # the first strongest drive
                                F = self.forces(lay["rest"], freqs, volts)[:, ci]
                                load = np.linalg.norm(F - np.einsum("bk,bk->b", F, axis)[:, None] * axis, axis=-1)
                                P = load if P is None else np.where(load > P, load, P)
                            defl = eq1_deflection(P, L, l, EI)
                        better = np.isnan(worst_p) | (P > worst_p)
                        worst_p, worst_d = np.where(better, P, worst_p), np.where(better, defl, worst_d)
                    has = np.isfinite(worst_p)
                    strain = worst_p * (L + l) * c / EI
                    ok401 &= ~(has & (strain > strain_limit))
                    rigid = np.array([round(float(v), 2) for v in (l / L)]) if self.n else np.zeros(0)
                    ratio = np.ones(self.n)
                    for r in np.unique(rigid):
                        ratio[rigid == r] = eq1_limit_ratio(float(r), tolerance)
                    skip = (tolerance >= 0.05) & (worst_d < SAFE_RATIO * L)
                    ok402 &= ~(has & ~skip & (worst_d > ratio * L))
            return {"acl401": ok401, "acl402": ok402}
        return self.once(("beam_lint", strain_limit, tolerance), build)

    def gain_ok(self, ratio: float) -> np.ndarray:
        """ACL102: the transducer's gain at every in-band mode is at least ``ratio`` x its best gain over
        a 400-point grid of the band (lint.rules.acoustics.low_transducer_gain), per point's band and table."""
        ok = np.ones(self.n, bool)
        t = self.design.transducer
        if t is None:
            return ok
        moves = self.transducer_moves()
        if moves:
            lo, hi = self.get("transducer.band.0"), self.get("transducer.band.1")
            step = (hi - lo) / 399                            # np.linspace(lo, hi, 400), row by row, same bits
            grid = np.arange(400)[None, :] * step[:, None] + lo[:, None]
            grid[:, -1] = hi
            fs, gs = self.gain_table()
            best = pressure_per_volt_rows(grid, fs, gs).max(axis=1)
        else:
            lo, hi = t.band
            best = np.full(self.n, float(self.gain(np.linspace(lo, hi, 400)).max()))
        lo_, hi_ = np.broadcast_to(lo, (self.n,))[:, None], np.broadcast_to(hi, (self.n,))[:, None]
        for c in range(len(self.caps)):
            f = self.modes(c)[0]                                          # (N, P), NaN padded
            if f.shape[1] == 0:
                continue
            if moves:
                g = pressure_per_volt_rows(np.where(np.isfinite(f), f, 0.0), *self.gain_table())
            else:
                g = self.gain(np.where(np.isfinite(f), f, 0.0).ravel()).reshape(f.shape)
            inband = (lo_ <= f) & (f <= hi_)
            ok &= ~np.any(inband & (g < ratio * best[:, None]) & (best[:, None] > 0), axis=1)
        return ok

    def crosstalk_ok(self, k: float) -> np.ndarray:
        """ACL103: no two modes of capsules meant to be driven separately overlap within k x their mean
        half-bandwidth (lint.rules.acoustics.mode_crosstalk), modes and Q of each point."""
        from acl.lint.rules.acoustics import _separate_pairs

        class _Steps:                       # what _separate_pairs reads: the design and its program steps
            design = self.design

            @staticmethod
            def steps():
                return ((p, st) for p in self.design.programs for st in p.steps)

        ok = np.ones(self.n, bool)
        idx = {c.name: i for i, c in enumerate(self.caps)}
        for (a, b) in _separate_pairs(_Steps()):
            fa, qa = self.modes(idx[a])
            fb, qb = self.modes(idx[b])
            f1, q1 = fa[:, :, None], qa[:, :, None]
            f2, q2 = fb[:, None, :], qb[:, None, :]
            half = (f1 / q1 + f2 / q2) / 2
            ok &= ~np.any(np.abs(f1 - f2) < k * half, axis=(1, 2))
        return ok

    def half_height(self, c: int) -> np.ndarray:
        """Extent of capsule c's outer body below its centre (geometry.half_extent along -z)."""
        cap = self.caps[c]
        base = f"capsules.{cap.name}.cavity"
        cav = cap.cavity
        wall = self.get(f"{base}.wall")
        if cav.shape in ("cylinder", "prism"):
            ax = self.vec(f"{base}.axis")
            ca = np.abs(ax[:, 2]) / np.linalg.norm(ax, axis=-1)
            across = self.get(f"{base}.radius") if cav.shape == "cylinder" else self.get(f"{base}.side") / math.sqrt(3)
            return ca * self.get(f"{base}.height") / 2 + across * np.sqrt(np.maximum(0.0, 1 - ca * ca)) + wall
        return (3 * self.get(f"{base}.volume") / (4 * np.pi)) ** (1 / 3) + wall

    def marginal_features_ok(self, k: float) -> np.ndarray:
        """ACL501: no printed feature within k x the print resolution (lint.rules.fabrication._features)."""
        from acl.design.checks import PRINT_AXIAL, PRINT_LATERAL

        ok = np.ones(self.n, bool)

        def check(size, axial):
            res = PRINT_AXIAL if axial else PRINT_LATERAL
            return ~((res <= size) & (size < k * res))

        for cap in self.caps:
            ok &= check(self.get(f"capsules.{cap.name}.cavity.wall"), False)
            for o in cap.orifices:
                ok &= check(2 * self.get(f"capsules.{cap.name}.orifices.{o.name}.radius"), False)
        for b in self.design.beams:
            vertical = abs(b.axis[2]) > 0.7
            base = f"beams.{b.name}.section"
            if b.section.shape == "circle":
                ok &= check(self.get(f"{base}.diameter"), not vertical)
            else:
                ok &= check(self.get(f"{base}.width"), False) & check(self.get(f"{base}.thickness"), not vertical)
        for lt in self.design.latches:
            ok &= check(self.get(f"latches.{lt.name}.width"), False) & check(self.get(f"latches.{lt.name}.thickness"), True)
        return ok

    def linear_ok(self, limit: float, samples: int) -> np.ndarray:
        """ACL105: eps/R of every interface at every drive step and sampled sweep frequency within the limit (acoustics.interface_amplitudes)."""
        from acl.physics.forces import interface_centre_amplitude

        lay = self.layout()
        ok = np.ones(self.n, bool)
        for p in self.design.programs:
            for i, st in enumerate(p.steps):
                base = f"programs.{p.name}.steps.{i}."
                if st.kind == "drive":
                    drives = [(tuple(t.frequency for t in st.drive.tones),
                               tuple(self.volt(f"{base}drive.tones.{j}.amplitude", t.amplitude)
                                     for j, t in enumerate(st.drive.tones)))]
                elif st.kind == "sweep":
                    amp = self.volt(base + "amplitude", st.amplitude)
                    drives = [((float(f),), (amp,)) for f in np.linspace(st.f_start, st.f_stop, samples)]
                else:
                    continue
                for freqs, volts in drives:
                    f = np.array(freqs)
                    if f.size == 0:
                        continue
                    pts = lay["rest"][:, lay["body"]] + lay["offsets"]
                    u = PB.coupled_response(self.h0(tuple(f)), pts, lay["radii"], lay["body"], f[None, :],
                                            self.medium["density"], self.medium["sound_speed"], C.SUBSTRATE_REFLECTION)
                    pr = self.pressure(f, volts)
                    u = u * (pr[None, :, None] if pr.ndim == 1 else pr[:, :, None])
                    eps = interface_centre_amplitude(np.abs(u).sum(axis=1), lay["radii"])
                    ok &= np.all(eps / lay["radii"] <= limit, axis=1)
        return ok

    # -- dispatch ---------------------------------------------------------------------------------------
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
        m = re.fullmatch(r"lint_(acl\d+)_pass", q)
        if m:
            return self.once(("lint", m.group(1)), lambda: self.lint(m.group(1)))
        raise QuantityError("E-SWEEP-Q01", f"unknown quantity `{q}`")


def PB_eq1_deflection(P, bm) -> np.ndarray:
    """Paper Eq. (1) load-point deflection with per-point beam geometry."""
    from acl.physics.beams import eq1_deflection

    return eq1_deflection(P, bm["L"], bm["l"], bm["EI"])


def _fundamentals(vol: np.ndarray) -> np.ndarray:
    """Each interface's own fundamental per point (acoustics._fundamentals), sorted, duplicates dropped: (N, P) mode indices, -1 padded.

    ``vol`` (N, P, K) outward volume of each interface in each coupled mode.
    """
    a = np.abs(vol)
    tot = a.sum(axis=1, keepdims=True)
    share = np.divide(a, tot, out=np.zeros_like(a), where=tot > 0)                    # (N, P, K)
    net = np.abs(vol.sum(axis=1)) / np.maximum(tot[:, 0], 1e-300)                       # (N, K)
    driven = net > 1e-3
    top = share >= share.max(axis=1, keepdims=True) * (1 - TIE_RTOL)                        # (N, P, K)
    cand = top & driven[:, None, :]
    has = cand.any(axis=2)
    first = np.argmax(cand, axis=2)                                                     # (N, P)
    # fallback: the largest-share driven mode (or any mode when none is driven)
    pool = np.where(driven.any(axis=1)[:, None, None], driven[:, None, :], True)
    alt = first_max(np.where(pool, share, -1.0), axis=2)
    picked = np.where(has, first, alt)
    picked = np.sort(picked, axis=1)
    dup = np.zeros_like(picked, bool)
    dup[:, 1:] = picked[:, 1:] == picked[:, :-1]
    picked = np.where(dup, np.iinfo(picked.dtype).max, picked)
    picked = np.sort(picked, axis=1)
    return np.where(picked == np.iinfo(picked.dtype).max, -1, picked)

"""What a sweep can give for a design: the column families (QUANTITIES), the mechanisms the batched evaluation
covers, the declared effects that take a family from it (given point by point instead: acl.sweep.points)."""
from __future__ import annotations

import re
from dataclasses import dataclass

from acl.design import model as M
from acl.physics.effect_table import EFFECT_TABLE


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
    Quantity("model_form_rel", "", "largest relative force uncertainty past a soft validity limit (interface amplitude, "
             "monopole distance) over the program's drive steps at rest (acl.sweep.model_form)",
             "max(validity[].model_form_force_rel, pairs[].monopole_model_form_rel)"),
    Quantity("model_form_uncertain", "bool", "a margin or gap require's verdict could flip within model_form_rel "
             "or within the first-principles pair-scale spread (widens the yield's interval)", "(none: the sweep's)"),
    Quantity("model_form_pair_uncertain", "bool", "a margin or gap require's verdict differs at the 2.5 or 97.5 % "
             "quantile of the first-principles pair-scale spread, where no bjerknes_scale calibrates the pair forces "
             "(acl.sweep.model_form)", "(none: the sweep's)"),
    Quantity("model_form_pair_median_pass", "bool", "every margin and gap require holds with the Bjerknes force at the median of "
             "the first-principles pair-scale spread (4.49x), where no bjerknes_scale calibrates the pair forces",
             "(none: the sweep's; analyze's pairs[].snap_in_voltage_median_pair_scale_v)"),
    Quantity("lint_<rule>_pass", "bool", "the lint rule finds nothing (rule's own test, before suppressions)",
             "`acl lint` finding of <rule> absent"),
)

STATIC_EFFECTS = {e.name for e in EFFECT_TABLE.values() if e.static_note}   # the one table (acl.physics.effect_table)
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


# Declared effects the batched evaluation applies itself, point by point in its arrays, as analyze does: those the
# one table (acl.physics.effect_table) gives a ``sweep`` place (acl.sweep.acoustic_state.PointAcoustics: the
# pair law, E and the beams' law, the drive pressure and its saturation, the substrate, the neighbour drag).  No
# family is given point by point for them; an effect without one (added later) takes them from acl.sweep.points.
BATCHED_EFFECTS = frozenset(e.name for e in EFFECT_TABLE.values() if e.sweep)


def _unbatched_effects(design: M.Design) -> list[str]:
    """The physical effects of ``design`` the batched evaluation does not model (their families: acl.sweep.points)."""
    return [e for e in _physical_effects(design) if e not in BATCHED_EFFECTS]


# Declared effects that leave the forces at rest as they are (acl.analysis.acoustics applies them to
# beams or to displaced capsules only: neighbour_drag's factor is 1 at zero displacement), and those of
# them that also leave the latch law as it is (mechanics.latch_geometry scales E by stiffness_scale only).
REST_NEUTRAL_EFFECTS = {e.name for e in EFFECT_TABLE.values() if e.rest_neutral and not e.static_note}
LATCH_NEUTRAL_EFFECTS = {e.name for e in EFFECT_TABLE.values() if e.latch_neutral and not e.static_note}


def _effect_blocks(design: M.Design) -> dict[str, list[str]]:
    """{'rest': effects that change the forces at rest, 'latch': ... the latch margins, 'motion': ... the
    equilibria (every physical effect but :data:`BATCHED_EFFECTS`: the batched beams, springs and forces at
    displaced positions model none of the others)}."""
    eff = _unbatched_effects(design)
    return {"rest": [e for e in eff if e not in REST_NEUTRAL_EFFECTS],
            "latch": [e for e in eff if e not in LATCH_NEUTRAL_EFFECTS],
            "motion": eff}


def _effects_note(names: list[str], what: str) -> str:
    return f"the design declares effects ({', '.join(names)}) that change {what}, which the batched evaluation does not model"


def supported(design: M.Design, at: str | None = None) -> tuple[list[str], dict[str, str]]:
    """(column names the batched evaluation gives for ``design``, {quantity family: why it is not given})."""
    from acl.analysis.effects import first_principles_pairs
    from acl.analysis.report import program_frequencies, step_drives

    names: list[str] = []
    missing: dict[str, str] = {}
    blocks = _effect_blocks(design)
    for cap in design.capsules:
        for k in range(1, len(cap.orifices) + 1):
            names += [f"resonance_{_ident(cap.name)}_{k}_hz", f"q_{_ident(cap.name)}_{k}"]
    # families that declared effects change: given point by point by analyze's engine (acl.sweep.points)
    for cols in per_point_columns(design, at).values():
        names += cols
    if blocks["motion"] and at is None and any((design.mount_of(c.name) or M.Fix(capsule="", span=c.span)).kind == "mount"
                                               for c in design.capsules):
        missing["tip_deflection"] = "deflections need a drive: give `at` (like `acl analyze --at`)"
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
    if not blocks["motion"]:
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
        if _require_supported(design, r, blocks["motion"]) or _require_per_point(design, r, blocks):
            names += [f"require_{i}_value", f"require_{i}_pass"]
        else:
            missing[f"require_{i}"] = f"`{r.text}` is not batched for this design"
    if design.requires and all(f"require_{i}_pass" in names for i in range(1, len(design.requires) + 1)):
        names.append("requires_pass")
    if design.capsules and not blocks["motion"]:     # eps/R at the drive pressure with every effect
        names += ["model_form_rel", "model_form_uncertain"]
        if first_principles_pairs(design):          # the pair-scale spread's share of it (acl.sweep.model_form)
            names.append("model_form_pair_uncertain")
            if any(r.kind in ("margin", "gap") for r in design.requires):
                names.append("model_form_pair_median_pass")
    elif design.capsules:
        missing["model_form_"] = ("the model-form uncertainty past the validity limits with declared effects "
                                  f"({', '.join(blocks['motion'])}) is not batched: `acl analyze --at` gives it at a drive")
    sweeps = any(st.kind == "sweep" for p in design.programs for st in p.steps)
    names += [f"lint_{code}_pass" for code in LINT_RULES
              if (code != "acl105" or not blocks["rest"]) and (code not in _PROGRAM_LINT or not blocks["motion"])
              and (code not in _PROGRAM_LINT or not sweeps)]
    if "lint_acl603_pass" in names and "requires_pass" not in names and design.requires:
        names.remove("lint_acl603_pass")
    if blocks["rest"]:
        missing["lint_acl105"] = f"eps/R with declared effects on the drive pressure ({', '.join(blocks['rest'])}) is not batched"
    if blocks["motion"]:
        for code in _PROGRAM_LINT:
            missing[f"lint_{code}"] = (f"the rule's forces with declared effects ({', '.join(blocks['motion'])}) are "
                                       "not batched (run `acl lint` on a point)")
    elif sweeps:
        for code in _PROGRAM_LINT:
            missing[f"lint_{code}"] = ("a `sweep` step's tones include each point's own modes "
                                       "(acl.lint.context.sweep_frequencies): not one set of frequencies for all points")
    return names, missing


def per_point_columns(design: M.Design, at: str | None = None) -> dict[str, list[str]]:
    """{family: columns} that declared effects take from the batched evaluation and that
    :mod:`acl.sweep.points` gives point by point (the `require`s among them: :func:`per_point_names`)."""
    from acl.sweep.points import columns

    return columns(design, _effect_blocks(design), at)


def _require_per_point(design, r, blocks) -> bool:
    """A `require margin` under effects on the latch law, or a `require gap` under effects on the equilibria."""
    if r.kind == "margin":
        return bool(blocks["latch"]) and any(lt.name == r.args[0] for lt in design.latches)
    return r.kind == "gap" and bool(blocks["motion"])


def per_point_names(design: M.Design, at: str | None = None) -> set[str]:
    """Every column :mod:`acl.sweep.points` gives for ``design`` (families and `require`s)."""
    blocks = _effect_blocks(design)
    out = {c for cols in per_point_columns(design, at).values() for c in cols}
    for i, r in enumerate(design.requires, 1):
        if not _require_supported(design, r, blocks["motion"]) and _require_per_point(design, r, blocks):
            out |= {f"require_{i}_value", f"require_{i}_pass"}
    return out


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

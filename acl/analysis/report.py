"""Design -> analysis report: what `acl analyze` prints (tables) and emits (`--json`, documented in docs/analyze.md).

Modes of every capsule, a selectivity matrix over the program frequencies, every bubble pair at every
program frequency (attract/repel, phase, d_c, snap-in voltage), latch margins per program step, the
equilibrium at a chosen drive, and the design's `require` statements evaluated.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from acl.design import model as M
from acl.design.drives import describe_drive
from acl.physics.ties import first_max

CROSSTALK_THRESHOLD = 0.3     # relative response of a non-target capsule flagged as crosstalk
SELECTIVITY_SWEEP = (20e3, 400e3, 761)   # Hz grid used to find each capsule's thrust peak
DEFAULT_V = 1.0               # V, reference amplitude when a program gives none


@dataclass
class Report:
    file: str
    notes: list = field(default_factory=list)
    capsules: list = field(default_factory=list)
    frequencies_hz: list = field(default_factory=list)
    selectivity: list = field(default_factory=list)
    pairs: list = field(default_factory=list)
    latches: list = field(default_factory=list)
    equilibrium: dict | None = None
    requires: list = field(default_factory=list)
    coupled_modes: list = field(default_factory=list)
    drives: list = field(default_factory=list)

    @property
    def requires_ok(self) -> bool:
        return all(r["ok"] for r in self.requires)

    def as_dict(self) -> dict:
        return {"version": 1, "file": self.file, "notes": self.notes, "capsules": self.capsules,
                "frequencies_hz": self.frequencies_hz, "selectivity": self.selectivity, "pairs": self.pairs,
                "latches": self.latches, "equilibrium": self.equilibrium, "requires": self.requires,
                "coupled_modes": self.coupled_modes, "drives": self.drives}


def _loc(span) -> dict:
    return {"file": span.file, "line": span.line, "column": span.column}


def program_frequencies(design: M.Design) -> list[float]:
    """Every frequency a program uses (tones, sweep ends, pinned goal tones), sorted."""
    fs = set()
    for p in design.programs:
        for st in p.steps:
            if st.kind == "drive":
                fs.update(t.frequency for t in st.drive.tones)
            elif st.kind == "sweep":
                fs.update((st.f_start, st.f_stop))
            elif st.kind in ("follow", "switch", "hold"):
                fs.update(st.tones)
    return sorted(fs)


def amplitude_at(design: M.Design, f: float) -> float:
    """Largest amplitude the programs apply at frequency f (V), else the reference 1 V (DEFAULT_V: 0 from _program_amplitude)."""
    return _program_amplitude(design, f) or DEFAULT_V


def _program_amplitude(design: M.Design, f: float) -> float:
    """Largest amplitude the programs apply at frequency f (V); 0 when none does."""
    best = 0.0
    for p in design.programs:
        for st in p.steps:
            if st.kind == "drive":
                best = max([best] + [t.amplitude for t in st.drive.tones if t.frequency == f])
            elif st.kind in ("follow", "switch", "hold") and f in st.tones:
                lim = st.limits.max_voltage or (design.transducer.max_voltage if design.transducer else None)
                if lim:
                    best = max(best, lim)
    return best


def step_drives(design: M.Design):
    """(program, step index, step, Drive) for every step that applies a definite drive."""
    for p in design.programs:
        for i, st in enumerate(p.steps):
            if st.kind == "drive":
                yield p, i, st, st.drive
            elif st.kind in ("switch", "hold", "follow") and st.tones:
                v = st.limits.max_voltage or (design.transducer.max_voltage if design.transducer else DEFAULT_V)
                per = v / len(st.tones)
                yield p, i, st, M.Drive(tones=tuple(M.Tone(frequency=f, amplitude=per) for f in st.tones))


def analyze(design: M.Design, at: M.Drive | None = None, snap_in: bool = True, progress=None) -> Report:
    from acl.analysis import acoustics as AC
    from acl.analysis import interfaces as IF
    from acl.analysis import mechanics as ME
    from acl.analysis.selectivity import selectivity
    from acl.analysis.pairs import net_critical_distance, pair_notes, scale_note
    from acl.physics.forces import PAPER_DRAG_FRACTION

    from acl.analysis.effects import notes as effect_notes

    rep = Report(file=design.file, notes=list(AC.defaults_used(design)) + effect_notes(design))
    modes = {}
    for c in design.capsules:
        ms = AC.capsule_modes(design, c)
        modes[c.name] = ms
        rep.capsules.append({"name": c.name, **_loc(c.span), "volume_m3": c.cavity.volume,
                             "modes": [{"frequency_hz": m.frequency_hz, "q": m.q, "q_declared": m.q_declared,
                                        "q_predicted": m.q_predicted, "dominant_orifice": m.dominant_orifice,
                                        "share": m.share, "shares": m.shares} for m in ms]})
    if len(design.capsules) > 1:
        rep.coupled_modes = [{"frequency_hz": m.frequency_hz, "q": m.q, "q_declared": m.q_declared,
                              "q_predicted": m.q_predicted, "dominant_orifice": m.dominant_orifice,
                              "share": m.share, "shares": m.shares, "phases_deg": m.phases}
                             for m in AC.coupled_modes(design)]
    freqs = program_frequencies(design) or sorted({ms[0].frequency_hz for ms in modes.values() if ms})
    rep.frequencies_hz = freqs
    if design.capsules and freqs:
        grid = np.linspace(*SELECTIVITY_SWEEP)
        sweep = selectivity(design, grid)
        peak = sweep.thrust_per_v2.max(axis=1)
        at_f = selectivity(design, freqs)
        for j, f in enumerate(freqs):
            rel = np.divide(at_f.thrust_per_v2[:, j], peak, out=np.zeros_like(peak), where=peak > 0)
            best = at_f.capsules[first_max(rel)]            # ties: the first declared (acl.physics.ties)
            for i, name in enumerate(at_f.capsules):
                # capsules tuned like the best-responding one (first modes within 2 %) are meant to move together
                target = _same_tuning(modes.get(name), modes.get(best))
                rep.selectivity.append({"frequency_hz": f, "capsule": name, "relative_response": float(rel[i]),
                                        "target": bool(target),
                                        "crosstalk": bool(not target and rel[i] >= CROSSTALK_THRESHOLD)})
    # ---- pairs at each program frequency
    fm = AC.force_model_for(design)
    snaps: dict[float, tuple[float | None, str]] = {}
    snaps_scaled: dict[float, float | None] = {}
    scaled = _median_pair_scale(design) if snap_in else None
    vmax = design.transducer.max_voltage if design.transducer else 20.0
    for j, f in enumerate(freqs):
        v = amplitude_at(design, f)
        drive = M.Drive(tones=(M.Tone(frequency=f, amplitude=v),))
        pfs = AC.pair_forces(design, drive)
        if snap_in and pfs:
            if progress:
                progress(f"snap-in sweep at {f / 1e3:g} kHz")
            sw = ME.sweep_voltage(design, M.Drive(tones=(M.Tone(frequency=f, amplitude=1.0),)), vmax, fm)
            snaps[f] = (sw.snap_voltage, sw.status)
            if scaled is not None:      # the same sweep with the pair force the paper's measured pairs have
                sw = ME.sweep_voltage(scaled, M.Drive(tones=(M.Tone(frequency=f, amplitude=1.0),)), vmax, fm)
                snaps_scaled[f] = sw.snap_voltage
        amps = IF.interface_amplitudes(design, drive)
        # what this drive is for: the pair table (two or more capsules), else only the frequency's
        # largest program amplitude (or the 1 V reference where no program sets one)
        basis = "pairs" if pfs else ("largest_program_amplitude" if _program_amplitude(design, f) else "reference")
        worst = max(amps, key=amps.get, default=None)     # located at the capsule of its largest interface amplitude
        span = design.capsule(worst.split(".")[0]).span if worst else None
        rep.drives.append(_drive_entry(None, None, describe_drive(drive), amps, span.line if span else None, basis,
                                       span.file if span else None))
        for pf in pfs:
            study = _q_study(design, pf, f) if _unequal(modes, pf) else {}
            rep.pairs.append({
                "a": pf.a, "b": pf.b, "frequency_hz": f, "voltage_v": v, "force_n": pf.attraction,
                "attract": bool(pf.attract), "phase_difference_deg": math.degrees(pf.phase_difference),
                # d_c where the full force model's net closing force changes sign (acl.analysis.pairs), and the
                # reduced paper Eq. 3 value sqrt(alpha / 2 gamma) at rest (2 gamma: the two thrusts)
                "critical_distance_m": net_critical_distance(design, drive, pf.a, pf.b),
                "critical_distance_paper_drag_m": net_critical_distance(design, drive, pf.a, pf.b,
                                                                        drag_fraction=PAPER_DRAG_FRACTION),
                "critical_distance_eq3_m": pf.critical_distance, "gap_m": pf.distance,
                # point-monopole validity at rest (acl.physics.validity.MONOPOLE_DISTANCE): gap / (R_a + R_b)
                **_monopole(design, pf),
                "snap_in_voltage_v": snaps.get(f, (None, ""))[0],
                "sweep_status": snaps.get(f, (None, "not computed"))[1],
                # an uncalibrated pair force (no bjerknes_scale): the snap-in with the force the paper's measured
                # pairs have at the median of their ratio to first principles (note N-PAIR-SCALE)
                **({"snap_in_voltage_median_pair_scale_v": snaps_scaled.get(f)} if f in snaps_scaled else {}),
                "q_predicted": [modes[pf.a][0].q_predicted if modes[pf.a] else None,
                                modes[pf.b][0].q_predicted if modes[pf.b] else None],
                "attract_with_predicted_q": study.get("attract_with_predicted_q", bool(pf.attract)
                                                      if not any(c.quality_factor for c in design.capsules
                                                                 if c.name in (pf.a, pf.b)) else None),
                "phase_difference_predicted_q_deg": study.get("phase_difference_predicted_q_deg"),
                "repel_from_q": study.get("repel_from_q"),
                "interface_amplitude_over_radius": {k: v for k, v in amps.items()
                                                    if k.split(".")[0] in (pf.a, pf.b)},
            })
            rep.pairs[-1]["notes"] = pair_notes(design, rep.pairs[-1])
        first = next((p for p in rep.pairs if p["frequency_hz"] == f and p["attract"]), None)
        if first is not None:       # the design's snap-in at the paper's pair-force scale: once per frequency
            first["notes"] += scale_note(design, first)
    for p, i, st, drive in step_drives(design):
        rep.drives.append(_drive_entry(p.name, i + 1, describe_drive(drive), IF.interface_amplitudes(design, drive),
                                       st.span.line, file=st.span.file))
    mode_fs = np.array([m.frequency_hz for ms in modes.values() for m in ms], float)
    for p in design.programs:
        for i, st in enumerate(p.steps):
            if st.kind == "sweep" and design.capsules:
                rep.drives.append(_sweep_entry(design, p.name, i, st, mode_fs))
    # ---- latches
    if design.latches:
        per_latch = {lt.name: {"name": lt.name, **_loc(lt.span), "state": lt.state, "margins": []} for lt in design.latches}
        intended = {(p.name, st.latch) for p in design.programs for st in p.steps if st.kind == "switch"}
        first = None
        states: dict = {}          # the latch states the program's earlier steps leave ({latch: "a" | "b"})
        program = None
        for p, i, st, drive in step_drives(design):
            if p is not program:
                program, states = p, {}
            lm = ME.latch_margins(design, drive, fm, states)
            for name, m in lm.items():
                first = first or m
                want = st.kind == "switch" and st.latch == name
                per_latch[name]["margins"].append({
                    "program": p.name, "step": i + 1, "line": st.span.line, "drive": describe_drive(drive),
                    "state_before": m.state, "margin": m.margin, "available_force_n": m.available,
                    "switches": bool(m.margin >= 1.0),
                    "intended": bool(want), "required_margin": st.margin if want else None,
                    "unintended": bool(m.margin >= 1.0 and not want and (p.name, name) not in intended)})
                if m.margin >= 1.0:
                    states[name] = "b" if m.state == "a" else "a"
        for lt in design.latches:
            m0 = ME.latch_margins(design, M.Drive(tones=()), fm)[lt.name]
            per_latch[lt.name].update({"bistable": bool(m0.bistable), "switching_force_n": m0.switching_force,
                                       "release_force_n": m0.release_force, "barrier_j": m0.barrier})
        rep.latches = list(per_latch.values())
    # ---- equilibrium at a chosen drive
    if at is not None and at.tones:
        st = ME.equilibrium(design, at, fm)
        rep.equilibrium = {
            "drive": describe_drive(at), "status": st.status, "stable": bool(st.stable),
            # no residual without an equilibrium (snap_in, no_convergence: NaN inside): null, never NaN in JSON
            "residual_n": float(st.residual) if np.isfinite(st.residual) else None,
            "capsules": [{"name": k, "displacement_m": [float(x) for x in v]} for k, v in st.displacements.items()],
            "deflections_m": {k: float(np.linalg.norm(v)) if np.ndim(v) else float(v) for k, v in st.deflections.items()},
            "deflection_over_eq1_limit": _eq1_ratios(design, st.deflections),
            "interface_amplitude_over_radius": IF.interface_amplitudes(design, at, st.positions),
            "gaps": [_gap(design, a, b, st.positions) for a, b in _pairs(design)],
            "warnings": [d.message for d in st.diagnostics],
        }
        rep.equilibrium["validity"] = validity_at(design, at, st, modes)
    rep.requires = [_require(design, r, modes, rep) for r in design.requires]
    return rep


def _monopole(design: M.Design, pf) -> dict:
    """``monopole_distance_ratio`` gap / (R_a + R_b) of a pair at rest (largest orifice of each capsule) and the
    ``monopole_model_form_rel`` ((R_a + R_b)/gap)^2 its forces carry below the limit (0 above; acl.physics.validity)."""
    from acl.physics import validity as VA

    rsum = max(o.radius for o in design.capsule(pf.a).orifices) + max(o.radius for o in design.capsule(pf.b).orifices)
    ratio = pf.distance / rsum
    rel = float(VA.monopole_model_form(pf.distance, rsum)) if ratio < VA.MONOPOLE_DISTANCE.value else 0.0
    return {"monopole_distance_ratio": float(ratio), "monopole_model_form_rel": rel}


def validity_at(design: M.Design, drive: M.Drive, st, modes: dict) -> list[dict]:
    """Located findings at an equilibrium ``st`` under ``drive``, one per limit crossed (acl.physics.validity):
    interface amplitude (soft 0.25, hard: the hemisphere), streaming Reynolds number, point-monopole distance, and
    paper Eq. (1)'s deflection range (W-MECH-001 of the mechanics).  Each: code, severity, message, evidence,
    file/line/column, the value and the limit, and (amplitude) the model-form force uncertainty."""
    from acl.analysis import interfaces as IF
    from acl.physics import validity as VA

    out = []
    from acl.physics.constants import WATER_20C
    from acl.physics.forces import streaming_reynolds

    med = design.medium or WATER_20C        # the same default as the acoustics (acl.physics.constants)
    amps = IF.interface_amplitudes(design, drive, st.positions)
    w_top = 2 * np.pi * max(t.frequency for t in drive.tones)
    for key, x in amps.items():
        cap, ori = key.split(".")
        c = design.capsule(cap)
        if x > VA.AMPLITUDE.value:
            q = max((m.q for m in modes.get(cap, ())), default=10.0)
            rel = float(VA.amplitude_model_form(x, q))
            hard = x > VA.AMPLITUDE_MEANING.value
            msg = (f"interface `{key}` reaches eps/R = {x:.3g}, " +
                   (f"past the hemisphere (eps/R = {VA.AMPLITUDE_MEANING.value:g}): the bubble model has no meaning there"
                    if hard else f"beyond the linear bubble model (eps/R <= {VA.AMPLITUDE.value:g}): forces carry a "
                    f"model-form uncertainty of {rel:.0%} (Q {q:.3g})"))
            out.append({"code": VA.AMPLITUDE.code, "severity": "warning", "message": msg, **_loc(c.span),
                        "value": x, "limit": VA.AMPLITUDE_MEANING.value if hard else VA.AMPLITUDE.value,
                        "model_form_force_rel": 1.0 if hard else rel,
                        "evidence": (VA.AMPLITUDE_MEANING if hard else VA.AMPLITUDE).evidence})
        r = c.orifice(ori).radius
        rs = float(streaming_reynolds(x * r, w_top, med.density, med.viscosity))
        if rs > VA.STREAMING_REYNOLDS.value:
            out.append({"code": VA.STREAMING_REYNOLDS.code, "severity": "warning", **_loc(c.span),
                        "message": f"interface `{key}` reaches streaming Reynolds number {rs:.3g}, beyond the thrust "
                                   f"law's Stokes outer flow (R_s <= {VA.STREAMING_REYNOLDS.value:g})",
                        "value": rs, "limit": VA.STREAMING_REYNOLDS.value,
                        "evidence": VA.STREAMING_REYNOLDS.evidence})
    for a, b in _pairs(design):
        g = _gap(design, a, b, st.positions)
        ra = design.capsule(a).orifice(g["a"].split(".")[1]).radius
        rb = design.capsule(b).orifice(g["b"].split(".")[1]).radius
        ratio = g["gap_m"] / (ra + rb)
        if ratio < VA.MONOPOLE_DISTANCE.value:
            rel = float(VA.monopole_model_form(g["gap_m"], ra + rb))
            out.append({"code": VA.MONOPOLE_DISTANCE.code, "severity": "warning", **_loc(design.capsule(a).span),
                        "message": f"orifices `{g['a']}` and `{g['b']}` are {g['gap_m'] * 1e6:.3g} um apart, "
                                   f"{ratio:.3g} x the sum of their radii (point monopoles need >= "
                                   f"{VA.MONOPOLE_DISTANCE.value:g}): pair forces carry a model-form uncertainty of {rel:.0%}",
                        "value": ratio, "limit": VA.MONOPOLE_DISTANCE.value, "model_form_force_rel": rel,
                        "evidence": VA.MONOPOLE_DISTANCE.evidence})
    for d in st.diagnostics:
        if d.code == "W-MECH-001":
            out.append({"code": d.code, "severity": "warning", "message": d.message,
                        **(_loc(d.span) if d.span else {"file": design.file, "line": 1, "column": 1}),
                        "evidence": "paper Eq. (1) vs the dead-load elastica (Bisshopp & Drucker 1945): 5 % apart at the "
                                    "limit (docs/explanation/structures.md section 2)"})
    return out


def _eq1_ratios(design: M.Design, deflections: dict) -> dict:
    """Beam deflection / the deflection where paper Eq. (1) departs 5 % from the elastica (docs/explanation/structures.md section 2); > 1: outside Eq. (1)."""
    from acl.physics.beams import eq1_validity_limit

    out = {}
    for b in design.beams:
        if b.name in deflections:
            v = deflections[b.name]
            d = float(np.linalg.norm(v)) if np.ndim(v) else float(v)
            out[b.name] = d / eq1_validity_limit(b.length, b.rigid_length)
    return out


SWEEP_SAMPLES = 21        # log-spaced frequencies across a sweep, plus every mode inside it (as acl lint: sweep_samples)


def _sweep_entry(design: M.Design, program: str, i: int, st, mode_fs: np.ndarray) -> dict:
    """Linear-regime check of a sweep step at its worst frequency (interfaces.sweep_worst_amplitude, every mode inside)."""
    from acl.analysis import interfaces as IF

    _, f, amps = IF.sweep_worst_amplitude(design, st.f_start, st.f_stop, st.amplitude, mode_fs, SWEEP_SAMPLES)
    drive = M.Drive(tones=(M.Tone(frequency=f, amplitude=st.amplitude),))
    return _drive_entry(program, i + 1, describe_drive(drive) + " (the sweep's worst frequency)", amps, st.span.line,
                        file=st.span.file)


def _median_pair_scale(design: M.Design) -> M.Design | None:
    """``design`` with its Bjerknes force at the median measured / first-principles ratio of the paper's pairs
    (acl.physics.constants.FIRST_PRINCIPLES_PAIR_SCALE_MEDIAN), or None where a bjerknes_scale is declared (a
    calibration or a declared spread) or there is no pair."""
    from acl.analysis.effects import first_principles_pairs, with_pair_scale
    from acl.physics.constants import FIRST_PRINCIPLES_PAIR_SCALE_MEDIAN

    if not first_principles_pairs(design):
        return None
    return with_pair_scale(design, FIRST_PRINCIPLES_PAIR_SCALE_MEDIAN)


def _drive_entry(program, step, drive_text, amps: dict, line=None, basis: str = "step", file=None) -> dict:
    """Linear-regime check of one drive: eps/R of every interface against LINEAR_AMPLITUDE_LIMIT.

    ``basis``: "step" (a program step's drive), "pairs" (the drive of the pair table at one program
    frequency), "largest_program_amplitude" (a frequency's largest program amplitude, no pair to
    analyse), "reference" (the 1 V reference at a frequency no program sets an amplitude for).
    """
    from acl.physics.constants import LINEAR_AMPLITUDE_LIMIT

    worst = max(amps.values(), default=0.0)
    return {"program": program, "step": step, "file": file, "line": line, "drive": drive_text, "basis": basis,
            "interface_amplitude_over_radius": amps, "max_amplitude_over_radius": worst,
            "linear_limit": LINEAR_AMPLITUDE_LIMIT, "linear": bool(worst <= LINEAR_AMPLITUDE_LIMIT)}


def _unequal(modes, pf, tol: float = 0.005) -> bool:
    ma, mb = modes.get(pf.a), modes.get(pf.b)
    return bool(ma and mb and abs(ma[0].frequency_hz - mb[0].frequency_hz) > tol * mb[0].frequency_hz)


REPEL_Q_GRID = (3.0, 4.0, 5.0, 7.0, 10.0, 14.0, 20.0, 28.0, 40.0, 57.0, 80.0, 113.0, 160.0, 226.0, 320.0, 640.0, 1000.0)


def _with_q(design: M.Design, names, q):
    caps = tuple(c.model_copy(update={"quality_factor": q}) if c.name in names else c for c in design.capsules)
    return design.model_copy(update={"capsules": caps})


def _q_study(design: M.Design, pf, f: float) -> dict:
    """Sign of an unequal pair's Bjerknes force at f with the predicted damping, and the smallest Q (declared on both) that makes it repel.

    What the damping would need for the repulsion of paper Fig. 4f-h; ``repel_from_q`` None if no Q up
    to 1000 repels (strong coupling: docs/physics.md part A section 6).
    """
    from acl.analysis import acoustics as AC

    drive = M.Drive(tones=(M.Tone(frequency=f, amplitude=1.0),))

    def pair_at(q):
        d = _with_q(design, (pf.a, pf.b), q)
        return next(x for x in AC.pair_forces(d, drive) if (x.a, x.b) == (pf.a, pf.b))

    pred = pair_at(None)
    repel_q = next((q for q in REPEL_Q_GRID if not pair_at(q).attract), None)
    return {"attract_with_predicted_q": bool(pred.attract),
            "phase_difference_predicted_q_deg": math.degrees(pred.phase_difference),
            "repel_from_q": repel_q}


def _same_tuning(ma, mb, tol: float = 0.02) -> bool:
    if not ma or not mb:
        return False
    return abs(ma[0].frequency_hz - mb[0].frequency_hz) <= tol * mb[0].frequency_hz


def _pairs(design):
    names = [c.name for c in design.capsules]
    return [(a, b) for i, a in enumerate(names) for b in names[i + 1:]]


def _gap(design, a, b, positions) -> dict:
    """The closest pair of orifices of capsules a and b at ``positions``."""
    d, oa, ob = min((orifice_gap(design, f"{a}.{x.name}", f"{b}.{y.name}", positions), x.name, y.name)
                    for x in design.capsule(a).orifices for y in design.capsule(b).orifices)
    return {"a": f"{a}.{oa}", "b": f"{b}.{ob}", "gap_m": d}


def orifice_gap(design, a: str, b: str, positions) -> float:
    ca, oa = a.split(".")
    cb, ob = b.split(".")
    pa = np.asarray(design.capsule(ca).orifice(oa).center) + np.asarray(positions[ca]) - np.asarray(design.capsule(ca).center)
    pb = np.asarray(design.capsule(cb).orifice(ob).center) + np.asarray(positions[cb]) - np.asarray(design.capsule(cb).center)
    return float(np.linalg.norm(pb - pa))


def _require(design, r: M.Require, modes, rep: Report) -> dict:
    from acl.analysis import acoustics as AC
    from acl.analysis import mechanics as ME

    value, unit, detail = None, "", ""
    if r.kind == "resonance":
        ms = modes.get(r.args[0], [])
        value = ms[r.mode].frequency_hz if r.mode < len(ms) else None
        unit = "Hz"
        detail = f"mode {r.mode + 1} of {r.args[0]}"
    elif r.kind == "separation" and len(r.args) == 1:
        fs = sorted(m.frequency_hz for m in modes.get(r.args[0], []))
        value = min(b - a for a, b in zip(fs, fs[1:])) if len(fs) >= 2 else None
        unit = "Hz"
        detail = f"closest adjacent modes of {r.args[0]} ({len(fs)} mode(s))"
    elif r.kind == "separation":
        fa, fb = modes.get(r.args[0], []), modes.get(r.args[1], [])
        value = abs(fa[0].frequency_hz - fb[0].frequency_hz) if fa and fb else None
        unit = "Hz"
        detail = f"first modes of {r.args[0]} and {r.args[1]}"
    elif r.kind == "margin":
        margins = [m["margin"] for lt in rep.latches if lt["name"] == r.args[0] for m in lt["margins"] if m["intended"]]
        if not margins:
            margins = [m["margin"] for lt in rep.latches if lt["name"] == r.args[0] for m in lt["margins"]]
            detail = "best margin over program steps (no switch step targets it)"
        else:
            detail = "smallest margin over its switch steps"
            margins = [min(margins)]
        value = max(margins) if margins else None
    elif r.kind == "gap":
        gaps = []
        rest = {c.name: c.center for c in design.capsules}
        gaps.append(orifice_gap(design, r.args[0], r.args[1], rest))
        for _p, _i, _st, drive in step_drives(design):
            st = ME.equilibrium(design, drive, AC.force_model_for(design))
            gaps.append(0.0 if st.status != "ok" else orifice_gap(design, r.args[0], r.args[1], st.positions))
        value = min(gaps)
        unit = "m"
        detail = "smallest gap over rest and every program step (0 after snap-in)"
    ok = value is not None and (r.lower is None or value >= r.lower) and (r.upper is None or value <= r.upper)
    return {"text": r.text, "kind": r.kind, "ok": bool(ok), "value": value, "unit": unit,
            "lower": r.lower, "upper": r.upper, "detail": detail, **_loc(r.span)}

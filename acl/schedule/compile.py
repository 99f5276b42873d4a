"""Program -> Schedule: every step becomes segments of tones; goals are solved as convex programs.

Entry point: :func:`compile_program`.  Steps map as follows (see docs/schedule.md):

* drive  -> one segment with the given tones;     sweep -> one chirp segment;  pause -> silence
* follow -> one segment per waypoint from ONE path program (:mod:`acl.schedule.path`)
* switch -> one segment from the latch LP (:mod:`acl.schedule.latch`)
* hold   -> one segment from the snap-in LP (:mod:`acl.schedule.hold`)

After solving, each follow goal is re-simulated through a forward model (injected, default
:func:`gains.model_forward`) and its predicted tracking error is reported.  Multi-tone
phases are chosen for a low peak (:mod:`acl.schedule.phases`).  Problems become diagnostics.

The compiler is a list of passes (:data:`PASSES`) run in order over one :class:`CompileState`; each pass
lives in its own module and only reads and writes that state (data flows one way, lowest first):

* :mod:`acl.schedule.state`        the state, the options and the helpers every pass shares
* :mod:`acl.schedule.latch_state`  the state of each bistable latch when a step starts
* :mod:`acl.schedule.reach`        how far each goal moves the capsules (the calibrated range is checked)
* :mod:`acl.schedule.verify`       re-simulation and 95 % error bands of each goal
* :mod:`acl.schedule.safety`       numbers, peaks, slews, contact, calibration after a latch moved
* :mod:`acl.schedule.validity`     the linear model's validity limits at each step (acl.physics.validity)
* :mod:`acl.schedule.fades`        crossfades between steps
* :mod:`acl.schedule.steps`, :mod:`acl.schedule.switching`  one pass over the program's steps
"""
from __future__ import annotations

import functools
from types import MappingProxyType

from acl.design.model import Design, Program
from acl.diagnostics import DiagnosticError, error
from acl.schedule import fades as FD
from acl.schedule import latch_state as LS
from acl.schedule import reach as RE
from acl.schedule import safety as SF
from acl.schedule import steps as ST
from acl.schedule import switching as SW
from acl.schedule import validity as VD
from acl.schedule.fades import segment_slews  # noqa: F401  (re-exported)
from acl.schedule.model import Schedule
from acl.schedule.phases import choose_all_phases
from acl.schedule.state import (  # noqa: F401  (re-exported: the compiler's public constants and options)
    CALIBRATION_STATE_CODE,
    CALIBRATION_STATE_RTOL,
    CONTACT_CODE,
    CROSSFADE_CODE,
    DEFAULT_MAX_VOLTAGE,
    DRIVEN_KINDS,
    FADE_GOAL,
    FLIP_KINDS,
    LATCH_FLIP_CODE,
    LATCH_STATE_CODE,
    LATCH_STATE_MARGIN,
    MAX_PROGRAM_S,
    MAX_ROBUST_SPREAD,
    MAX_WAYPOINTS,
    SLEW_RANGE,
    TRACKING_CODE,
    VOLTAGE_RANGE,
    CompileOptions,
    CompileState,
    auto_sample_rate,
    diag,
    drive_limit,
)

_choose_all_phases = choose_all_phases   # the name tests/test_emit_fft.py uses

STEP_PASSES = MappingProxyType({"drive": ST.drive, "sweep": ST.sweep, "pause": ST.pause, "follow": ST.follow,
                                "hold": ST.hold, "switch": SW.switch})   # step kind -> its pass (read only)


def compile_program(design: Design, program: str | Program, options: CompileOptions | None = None) -> Schedule:
    """Compile ``program`` of ``design`` into a :class:`Schedule`; raise DiagnosticError on failure."""
    opts = options or CompileOptions()
    prog = design.program(program) if isinstance(program, str) else program
    comp = CompileState(design, prog, opts)
    for _, run in PASSES:
        run(comp)
    return comp.schedule


def plan_steps(comp: CompileState) -> None:
    """Each step in order: contact left by an earlier step, the step's segments and goals, the crossfade into it."""
    from acl.schedule.solve import SolverFailure

    for i, step in enumerate(comp.program.steps):
        try:
            if step.kind in ("hold", "follow"):
                SF.contact_check(comp, i, step)
            k = len(comp.segments)
            STEP_PASSES[step.kind](comp, i, step)
            FD.crossfade(comp, i, k)
        except SolverFailure as exc:   # every step, not only follow: a located error, never E-INTERNAL
            raise diag("E-SCHED-SOLVER", f"step {i + 1}: {exc}", step.span,
                       "no solver could handle this step's convex program: check its margin, limit and "
                       "slew for absurd values") from None
    if not comp.segments:
        raise DiagnosticError([error("E-SCHED-EMPTY", f"program `{comp.program.name}` has no steps",
                                     comp.program.span)])


def track_flips(comp: CompileState) -> None:
    """A path or hold that may switch a latch: warned (W-SCHED-LATCH-FLIP; :func:`latch_state.latch_track`)."""
    flips = [k for k, st in enumerate(comp.program.steps) if st.kind in FLIP_KINDS]
    if flips and comp.design.latches:
        LS.latch_track(comp, flips[-1] + 1)


def assemble(comp: CompileState) -> None:
    """The schedule: its segments and goals, voltage, full scale, sample rate, drive chain and step warnings."""
    vmax = max(comp.vmax_seen) if comp.vmax_seen else drive_limit(comp.design, None, comp.opts)[0]
    full_scale, source = SF.full_scale(comp, vmax)
    fs = comp.opts.sample_rate_hz or auto_sample_rate(
        max((t.max_frequency_hz for s in comp.segments for t in s.tones), default=1e3))
    sched = Schedule(program=comp.program.name, segments=comp.segments, goals=comp.goals,
                     max_voltage_v=vmax, full_scale_v=full_scale, ramp_s=comp.opts.ramp_s,
                     source=comp.design.file, notes=comp.notes, full_scale_source=source)
    sched.sample_rate_hz = fs
    gen, amp = comp.design.generator, comp.design.amplifier
    if gen is not None or amp is not None:      # the declared drive chain, for `acl play` (docs/bench.md)
        sched.chain = {k: v.model_dump(exclude={"span"}) for k, v in (("generator", gen), ("amplifier", amp))
                       if v is not None}
    for w in comp.step_warnings:
        sched.warnings.append(w)
        comp.notes.append(f"warning: {w.message}")
    comp.schedule = sched


def coverage(comp: CompileState) -> None:
    """Each goal's reach against the calibrated range (acl.schedule.bands.coverage_warnings)."""
    from acl.schedule.bands import coverage_warnings

    sched = comp.schedule
    for w in coverage_warnings(comp.design, sched, [st.span for st in comp.program.steps],
                               functools.partial(RE.reach, comp), extra=comp.inner_goals):
        sched.warnings.append(w)
        comp.notes.append(f"warning: {w.message}")


PAIR_SCALE_CODE = "N-PAIR-SCALE"


def pair_scale_notes(comp: CompileState) -> None:
    """A located note (N-PAIR-SCALE) at each step whose band drew the first-principles pair force's spread
    (acl.schedule.bands.pair_details): the design's pair forces are acl's first-principles values, every measured
    pair of the paper attracted harder, and the band says how much of its spread that is."""
    from acl.diagnostics import Diagnostic, Severity

    for g in comp.goals:
        band = (g.details or {}).get("band")
        pair = band.get("pair_scale") if isinstance(band, dict) else None
        if not pair or not 0 <= g.step < len(comp.program.steps):
            continue
        cause = band.get("cause") if isinstance(band.get("cause"), dict) else {}
        share = cause.get("pair_force_share", pair.get("variance_share"))
        how = "of its variance (linearised)" if "pair_force_share" in cause else "(squared rank correlation over the draws)"
        rows = "; ".join(f"{r['source']}: {r['ratio']:.3g}" for r in pair["rows"])
        what = ("band" if g.rms_error_p95_m is not None else "margin band")
        msg = (f"{g.name}: the {what} draws the {pair['source']}: no bjerknes_scale calibrates this design's pair forces, "
               f"and the paper's measured pairs attracted {min(r['ratio'] for r in pair['rows']):.3g}-"
               f"{max(r['ratio'] for r in pair['rows']):.3g}x harder ({rows}); drawn from the "
               f"{pair['distribution']}, median {pair['median']:.3g}, 95 % {pair['range_95'][0]:.2g}-{pair['range_95'][1]:.3g}x"
               + (f"; its share of the spread {share:.0%} {how}" if share is not None else ""))
        comp.schedule.warnings.append(Diagnostic(
            PAIR_SCALE_CODE, Severity.INFO, msg, comp.program.steps[g.step].span,
            "calibrate the pair force on measured pairs (acl fit; effect bjerknes_scale, stdlib/calibrations.acl)"))
    from acl.analysis.pairs import drive_step_scale_note    # a drive step has no band: its pairs' net sign instead

    for k, st in enumerate(comp.program.steps, 1):
        n = drive_step_scale_note(comp.design, st.drive, st.span, f"step {k}") if st.kind == "drive" else None
        if n:
            comp.schedule.warnings.append(Diagnostic(PAIR_SCALE_CODE, Severity.INFO, n["message"], st.span,
                "calibrate the pair force on measured pairs (acl fit; effect bjerknes_scale, stdlib/calibrations.acl)"))


PASSES = (
    ("numbers", SF.check_numbers),
    ("steps", plan_steps),
    ("latch flips", track_flips),
    ("assemble", assemble),
    ("coverage", coverage),
    ("phases", lambda comp: choose_all_phases(comp.schedule, comp.schedule.sample_rate_hz)),
    ("peaks", lambda comp: SF.check_peaks(comp, comp.schedule)),
    ("slews", lambda comp: SF.check_slews(comp, comp.schedule)),
    ("validity", lambda comp: VD.check_linear(comp, comp.schedule)),
    ("pair scale", pair_scale_notes),
)

"""The state every compile pass reads and writes (:class:`CompileState`), its options, and the helpers they share."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from acl.design.model import Design, Limits, Program
from acl.diagnostics import DiagnosticError, Span, error
from acl.schedule.model import GoalReport, Schedule, Segment
from acl.schedule.path import UM

DEFAULT_MAX_VOLTAGE = 10.0
MAX_ROBUST_SPREAD = 100.0          # --robust: 1-sigma gain spread sqrt(|Q|) at most this many times |G0| (E-SCHED-UNCERTAINTY)
MAX_PROGRAM_S = 86_400.0          # a program longer than a day is refused (E-SCHED-DURATION)
MAX_WAYPOINTS = 20_000            # per follow goal (E-SCHED-PATH): raise --waypoint-dt
VOLTAGE_RANGE = (1e-3, 1e4)       # V: a `limit` outside it is refused (E-SCHED-LIMIT)
SLEW_RANGE = (1e-6, 1e12)         # V/s
LATCH_STATE_MARGIN = 1.2          # a drive pushing a latch within this factor of the force that switches it leaves its
                                  # state uncertain: the switch step's default margin (what a switch or a keep promises)
LATCH_STATE_CODE = "W-SCHED-LATCH-STATE"
LATCH_FLIP_CODE = "W-SCHED-LATCH-FLIP"   # a follow or hold step's drive switches a latch (or may): docs/schedule.md
TRACKING_CODE = "W-SCHED-TRACKING"       # the re-simulated path misses by more than the tolerance: docs/schedule.md
CALIBRATION_STATE_CODE = "W-SCHED-CALIBRATION-STATE"   # a measured table used where a latch moved capsules: docs/schedule.md
CALIBRATION_STATE_RTOL = 0.1              # model gain change (of their size) beyond which that table is not trusted
CONTACT_CODE = "W-SCHED-CONTACT"         # a step starts with a pair an earlier drive snapped in: docs/schedule.md
CROSSFADE_CODE = "W-SCHED-CROSSFADE"     # a crossfade between steps pushes a latch or pair past its margin, and no fade
                                         # through silence can replace it (a slew limit): docs/schedule.md
FADE_GOAL = "fade through silence"       # goal suffix of the silent segment inserted between two steps (fades.crossfade)
DRIVEN_KINDS = ("drive", "sweep", "follow", "hold")     # steps whose played drive can push a latch (latch_state.latch_track)
FLIP_KINDS = ("follow", "hold")           # ... whose purpose is not the latch: a switch under them is warned



@dataclass(frozen=True)
class CompileOptions:
    sample_rate_hz: float | None = None          # None: >= 10x the highest tone (rounded up)
    waypoint_dt_s: float = 0.01                  # time between waypoints of a follow goal
    tolerance_m: float = 0.5 * UM                # tracking tolerance of the path program
    ramp_s: float = 1e-3                         # raised-cosine crossfade between segments
    calibration: object | None = None            # GainTable from a measured sweep, or None
    gain_provider: Callable | None = None        # (design, capsule) -> GainTable; default model
    forward_provider: Callable | None = None     # (design, capsule, freqs) -> (forward, name)
    latch_provider: Callable | None = None       # (design, freqs) -> (forces, to_b, to_a)
    snap_provider: Callable | None = None        # (design, a, b, freqs, vmax, bound) -> (K,) V | None
    critical_provider: Callable | None = None    # (design, a, b, [(f, V)], s_max, bound) -> scale | None
    max_voltage: float | None = None             # overrides every other limit if given
    full_scale_v: float | None = None            # WAV full scale; default: the transducer's max voltage
    lam: float = 1e-3
    slew_model: str = "auto"
    refine: int = 0
    resim_points: int = 100                      # waypoints re-simulated per goal (evenly spaced)
    tones_per_path: int = 3
    robust: bool = False                         # path program with the declared uncertainty (acl.schedule.robust)
    robust_mode: str = "mean"                    # "mean" (expected squared error, QP) | "worst" (1-sigma ellipsoid, SOC)
    band_samples: int = 0                        # draws of the declared uncertainty for the 95 % band (0: none)
    band_seed: int = 0
    reload: Callable | None = None               # {param: "v unit"} -> Design, to sample uncertain params
    nonlinear_passes: int = 0                    # re-plan against the nonlinear model (acl.schedule.correct)
    allow_nonlinear: bool = False                # plan drives beyond the linear bubble model (eps/R > limit)
    reading_noise_m: float | None = None         # noise of one proposed bench reading (m, per axis; None:
                                                 # acl.schedule.experiment.READING_NOISE_M)



@dataclass
class CompileState:
    """What the passes share: the program being compiled, the segments and goals so far, memos."""

    design: Design
    program: Program
    opts: CompileOptions
    segments: list[Segment] = field(default_factory=list)
    goals: list[GoalReport] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    t: float = 0.0
    vmax_seen: list[float] = field(default_factory=list)
    states_memo: dict = field(default_factory=dict)     # step -> {latch: (state, certain, why)} (:func:`latch_state.latch_track`)
    switch_outcome: dict = field(default_factory=dict)  # switch step -> (state, certain, why) of its latch after it
    push_memo: dict = field(default_factory=dict)       # driven step -> its push on each latch (_push_ratios)
    step_warnings: list = field(default_factory=list)  # W-SCHED-LATCH-STATE (at a switch), -FLIP (a follow or hold),
    #                                                     W-SCHED-TRACKING (a follow's re-simulated miss)
    settled: dict = field(default_factory=dict)         # (tones, latch states) -> :func:`latch_state.settle`'s answer
    branch_memo: dict = field(default_factory=dict)     # (tones, latch states, latch, to) -> :func:`latch_state._branch_pushes`
    inner_goals: list = field(default_factory=list)     # goal records checked for coverage, not in schedule.json (sweeps)
    forward_now: Callable | None = None                 # the current follow goal's forward provider (:func:`steps._models_for`)
    many_now: Callable | None = None                    # (designs, capsule, freqs, u) -> [prediction]: one batch, or None
    many_tones_now: Callable | None = None              # (designs, capsule, freqs, u (K, N)) -> each tone alone, or None
    gains_now: Callable | None = None                   # and its gain provider ((design, capsule, freqs) -> GainTable)
    cure_readings: tuple | None = None                  # (goal name, [(tone Hz, V)]): the first goal's proposed readings
    #                                                     (acl.schedule.experiment.explain promises the later goals'
    #                                                     bands on them too)

    modes_hz: np.ndarray | None = None                  # :func:`mode_frequencies`' cache
    schedule: Schedule | None = None                    # assembled once every step is planned


def mode_frequencies(comp: CompileState) -> np.ndarray:
    """Every capsule's mode frequencies (Hz) and the coupled modes' (two or more capsules): a chirp's peaks."""
    if comp.modes_hz is None:
        from acl.analysis import acoustics as AC

        fs = [m.frequency_hz for c in comp.design.capsules for m in AC.capsule_modes(comp.design, c)]
        if len(comp.design.capsules) > 1:
            fs += [m.frequency_hz for m in AC.coupled_modes(comp.design)]
        comp.modes_hz = np.array(fs, float)
    return comp.modes_hz


def add(comp: CompileState, duration, tones, step, goal=None):
    if not comp.t + duration <= MAX_PROGRAM_S:
        raise diag("E-SCHED-DURATION", f"step {step + 1}: the program would last "
                    f"{comp.t + duration:.4g} s, more than {MAX_PROGRAM_S:g} s",
                    comp.program.steps[step].span, "split it into several programs")
    comp.segments.append(Segment(comp.t, comp.t + duration, tuple(tones), step, goal))
    comp.t += duration


def drive_limit(design: Design, limits: Limits | None, opts: CompileOptions) -> tuple[float, float | None]:
    if opts.max_voltage is not None:
        vmax = opts.max_voltage
    else:
        amp, gen = design.amplifier, design.generator       # the declared drive chain caps the drive too
        cands = [v for v in ((limits.max_voltage if limits else None),
                             design.transducer.max_voltage if design.transducer else None,
                             amp.max_voltage if amp else None,
                             gen.max_voltage * (amp.gain if amp else 1.0) if gen else None) if v]
        vmax = min(cands) if cands else DEFAULT_MAX_VOLTAGE
    return vmax, (limits.slew_rate if limits else None)


def is_fade(seg: Segment) -> bool:
    """Whether ``seg`` is a silent segment inserted between two steps (:func:`fades.crossfade`)."""
    return not seg.tones and (seg.goal or "").endswith(FADE_GOAL)


def diag(code: str, message: str, span: Span | None, hint: str | None = None) -> DiagnosticError:
    return DiagnosticError([error(code, message, span, hint)])


def auto_sample_rate(max_frequency_hz: float, factor: float = 10.0, grid_hz: float = 1e3) -> float:
    """At least ``factor`` x the highest tone, rounded up to a multiple of ``grid_hz``."""
    return float(max(np.ceil(factor * max_frequency_hz / grid_hz) * grid_hz, grid_hz))

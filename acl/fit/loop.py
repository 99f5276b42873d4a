"""The closed loop in one place: compile on the nominal design -> play on a truth -> fit -> recompile -> play.

What a lab does with acl, with a synthetic "truth" design standing in for the device
(docs/explanation/closed-loop.md).  Every stage is the one the commands run:

1. ``acl compile NOMINAL --program P``            (acl.schedule.compile_program)
2. ``acl synth TRUTH --schedule schedule.json``  (acl.fit.synth.replay, with measurement noise)
3. ``acl fit NOMINAL run.csv --free gamma``      (acl.fit.run_fit) -> the calibrated design
4. ``acl compile CALIBRATED --program P``        with the fit's covariance: nominal error + 95 % band
5. ``acl synth TRUTH --schedule ...``            noise-free: the tracking error after calibration

and, for reference, the *floor*: the program compiled on the truth itself and played on it (what
perfect knowledge of the device achieves with the same compiler options).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np


@dataclass
class LoopResult:
    before_rms_m: float            # nominal program played on the truth (noise-free)
    before_max_m: float
    after_rms_m: float             # calibrated program played on the truth (noise-free)
    after_max_m: float
    floor_rms_m: float             # truth-compiled program played on the truth
    floor_max_m: float
    predicted_rms_m: float         # what the calibrated compile predicts (nominal)
    band_rms_p95_m: float          # ... and its 95 % band
    band_max_p95_m: float
    effects: list = field(default_factory=list)      # effects the fit selected
    calibrated: str = ""                              # path of the calibrated design
    notes: list = field(default_factory=list)

    @property
    def covered(self) -> bool:
        """The reported 95 % band bounds the error the truth really shows (RMS and max)."""
        return self.after_rms_m <= self.band_rms_p95_m and self.after_max_m <= self.band_max_p95_m


def _compile(path, program, opts, search_paths=()):
    import acl
    from acl.schedule.compile import compile_program

    return compile_program(acl.load(path, search_paths=search_paths), program, opts)


def _play(truth, schedule, noise=0.0, seed=0, observables=()):
    from acl.fit.synth import Target, Waypoint, replay

    waypoints, count = [], {}
    for seg in schedule.segments:
        if any(t.sweep for t in seg.tones):
            continue
        g = seg.goal or ""
        waypoints.append(Waypoint(seg.start_s, tuple((t.frequency_hz, t.amplitude_v) for t in seg.tones
                                                     if t.amplitude_v > 0), g, seg.step, count.get(g, 0)))
        count[g] = count.get(g, 0) + 1
    targets = {g.name: Target(g.capsule, g.target_m) for g in schedule.goals if g.kind == "follow" and g.capsule}
    return replay(truth, waypoints, observables, noise, seed, targets=targets)


def run_loop(nominal: str, truth: str, program: str, workdir: str, *, noise: float = 0.05e-6, seed: int = 0,
             free=("gamma",), observables=(), band_samples: int = 20, nonlinear_passes: int = 3,
             waypoint_dt: float = 0.01, allow_nonlinear: bool = False) -> LoopResult:
    """Run the loop for one follow goal (the first of ``program``); files go to ``workdir``."""
    import acl
    from acl.fit import run_fit
    from acl.fit.synth import write_csv
    from acl.schedule.compile import CompileOptions

    truth_design = acl.load(truth)
    base = CompileOptions(waypoint_dt_s=waypoint_dt, nonlinear_passes=nonlinear_passes,
                          allow_nonlinear=allow_nonlinear)
    s0 = _compile(nominal, program, base)
    first = _play(truth_design, s0, noise=noise, seed=seed, observables=observables)
    data_path = os.path.join(workdir, "run_before.csv")
    write_csv(first.data, data_path)
    cal_path = os.path.join(workdir, os.path.basename(nominal)[:-4] + ".calibrated.acl")
    out = run_fit(nominal, [data_path], free=free, seed=seed, calibrated_path=cal_path)
    with open(cal_path, "w", encoding="utf-8") as fh:
        fh.write(out.calibrated)

    paths = [os.path.dirname(os.path.abspath(nominal))]       # the calibrated file extends the nominal one

    def reload(ov):
        return acl.load(cal_path, overrides=ov, search_paths=paths)

    opts = CompileOptions(waypoint_dt_s=waypoint_dt, nonlinear_passes=nonlinear_passes,
                          band_samples=band_samples, band_seed=seed, reload=reload, allow_nonlinear=allow_nonlinear)
    s1 = _compile(cal_path, program, opts, paths)
    after = _play(truth_design, s1)
    floor = _play(truth_design, _compile(truth, program, base))
    goal = next(g for g in s1.goals if g.kind == "follow")
    b, a, f = (next(iter(r.tracking.values())) for r in (first, after, floor))
    return LoopResult(b["rms_m"], b["max_m"], a["rms_m"], a["max_m"], f["rms_m"], f["max_m"],
                      goal.rms_error_m, goal.rms_error_p95_m, goal.max_error_p95_m,
                      list(out.selection.selected), cal_path, list(s1.notes))


def seeded_truth(nominal_text: str, rng: np.random.Generator, extends: str, *,
                 span_hz: tuple[float, float] = (110e3, 140e3), v_sat: tuple[float, float] = (5.0, 10.0)) -> str:
    """A truth: the nominal design with a per-tone gain tilt (the tones at the ends of ``span_hz``
    differ by up to 30 %), a pressure scale 0.85-1.15 and one undeclared effect (drive saturation,
    V_s uniform in ``v_sat``), drawn from ``rng``."""
    lo, hi = span_hz
    slope = rng.uniform(-1.0, 1.0) * np.log(1.3) * 125e3 / (hi - lo)   # |gain(hi)/gain(lo) - 1| <= 30 %
    gain = rng.uniform(0.85, 1.15)
    vs = rng.uniform(*v_sat)
    return (f'extends "{extends}"\n'
            f"effect transducer_gain {{ gain_slope = {slope:.6g}, f_ref = 125 kHz, gain = {gain:.6g} }}\n"
            f"effect drive_saturation {{ v_sat = {vs:.6g} V }}\n")

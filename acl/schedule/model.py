"""The schedule: what the compiler hands to the emitters.

A schedule is a list of segments on one time axis.  Within a segment every tone has a constant
frequency (or a linear/log chirp), amplitude (V peak) and phase; the emitters blend consecutive
segments with raised-cosine crossfades of ``ramp_s``.  Phases refer to the global time axis, so a
tone that continues from one segment to the next with the same phase is phase-continuous.
Goal reports carry the predicted tracking error and margins per goal.  Plain dataclasses and
numpy arrays: no solver, no I/O.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

SCHEDULE_VERSION = "1.2"           # 1.2: steps counted from 1 (1.1 and earlier: from 0)


@dataclass(frozen=True)
class ScheduledTone:
    frequency_hz: float
    amplitude_v: float
    phase_rad: float = 0.0
    frequency_end_hz: float | None = None      # set for chirps (sweep steps)
    sweep: str | None = None                   # "linear" | "log" for chirps
    phase_fixed: bool = False                  # given by the user: the crest-factor search keeps it

    @property
    def max_frequency_hz(self) -> float:
        return max(self.frequency_hz, self.frequency_end_hz or 0.0)


@dataclass(frozen=True)
class Segment:
    start_s: float
    end_s: float
    tones: tuple[ScheduledTone, ...]
    step: int = 0                              # index of the program step it realises
    goal: str | None = None                    # goal name, e.g. "step 2: follow arm"
    peak_v: float | None = None                # analog peak bound (acl.schedule.phases.analog_peaks)

    @property
    def duration_s(self) -> float:
        return self.end_s - self.start_s

    def amplitude_sum(self) -> float:
        return float(sum(t.amplitude_v for t in self.tones))


@dataclass
class GoalReport:
    """What the compiler promises for one goal, and how the forward model re-simulated it."""

    name: str
    kind: str                                  # "follow" | "switch" | "hold" | "drive" | ...
    step: int
    start_s: float
    end_s: float
    frequencies_hz: tuple[float, ...] = ()
    model: str = ""                            # which forward model predicted the error
    rms_error_m: float | None = None
    max_error_m: float | None = None
    linear_rms_error_m: float | None = None    # error of the convex plan under the linear gains
    rms_error_p95_m: float | None = None       # 95th percentile over the declared uncertainty (acl.schedule.bands)
    max_error_p95_m: float | None = None
    capsule: str | None = None                 # follow: the capsule that follows the path
    details: dict = field(default_factory=dict)
    # arrays for plots (not serialised): times, target, predicted, amplitudes (N, K)
    times_s: np.ndarray | None = None
    target_m: np.ndarray | None = None
    predicted_m: np.ndarray | None = None
    amplitudes_v: np.ndarray | None = None
    band_plot: dict | None = None              # the band around the path (acl.schedule.experiment.explain's "plot")

    def as_dict(self) -> dict:
        d = {
            # steps counted from 1 in every output, as the CLI, segments.csv and analyze count them (self.step: index)
            "name": self.name, "kind": self.kind, "step": self.step + 1,
            "start_s": self.start_s, "end_s": self.end_s,
            "frequencies_hz": list(self.frequencies_hz), "model": self.model,
            "rms_error_um": None if self.rms_error_m is None else self.rms_error_m * 1e6,
            "max_error_um": None if self.max_error_m is None else self.max_error_m * 1e6,
            "linear_rms_error_um": (None if self.linear_rms_error_m is None
                                    else self.linear_rms_error_m * 1e6),
            "rms_error_p95_um": None if self.rms_error_p95_m is None else self.rms_error_p95_m * 1e6,
            "max_error_p95_um": None if self.max_error_p95_m is None else self.max_error_p95_m * 1e6,
        }
        if self.kind == "follow" and self.capsule and self.target_m is not None:
            # the path, one point per waypoint segment (so a replay can measure the tracking error)
            d["capsule"] = self.capsule
            d["target_um"] = [[round(float(x) * 1e6, 6), round(float(y) * 1e6, 6)] for x, y in self.target_m]
        if self.details:
            d["details"] = self.details
        return d


@dataclass
class Schedule:
    program: str
    segments: list[Segment]
    goals: list[GoalReport]
    max_voltage_v: float                       # the amplifier / transducer limit (V peak)
    full_scale_v: float                        # waveform files: sample = volts / full_scale_v
    ramp_s: float = 1e-3                       # raised-cosine crossfade between segments
    sample_rate_hz: float = 0.0                # the rate the phases/peaks were computed for
    source: str = ""
    version: str = SCHEDULE_VERSION
    notes: list[str] = field(default_factory=list)
    full_scale_source: str = ""                # where full_scale_v came from (option, transducer, limit)
    warnings: list = field(default_factory=list)   # located warnings (acl.diagnostics.Diagnostic), also in notes
    chain: dict | None = None                  # the design's generator and amplifier (schedule.json "chain"; acl play)

    @property
    def duration_s(self) -> float:
        return self.segments[-1].end_s if self.segments else 0.0

    @property
    def max_frequency_hz(self) -> float:
        return max((t.max_frequency_hz for s in self.segments for t in s.tones), default=0.0)

    def frequencies_hz(self) -> list[float]:
        return sorted({t.frequency_hz for s in self.segments for t in s.tones if t.sweep is None})

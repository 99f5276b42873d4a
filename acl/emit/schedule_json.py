"""schedule.json (versioned, schema in ``schedule.schema.json``) and the segments.csv table."""
from __future__ import annotations

import json
import math
from importlib import resources

from acl.schedule.model import Schedule

SCHEMA_FILE = "schedule.schema.json"


def _num(x):
    return None if x is None or (isinstance(x, float) and not math.isfinite(x)) else x


def _clean(obj):
    """JSON-safe copy: numpy scalars to Python, non-finite floats to null."""
    import numpy as np

    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _clean(obj.tolist())
    if isinstance(obj, np.generic):
        return _clean(obj.item())
    if isinstance(obj, float):
        return _num(obj)
    return obj


def schedule_dict(schedule: Schedule, sample_rate: float, stats=None, files: dict | None = None) -> dict:
    from acl import __version__

    segs = []
    for s in schedule.segments:
        tones = []
        for t in s.tones:
            d = {"frequency_hz": t.frequency_hz, "amplitude_v": t.amplitude_v, "phase_rad": wrapped_phase(t.phase_rad)}
            if t.sweep:
                d["frequency_end_hz"] = t.frequency_end_hz
                d["sweep"] = t.sweep
            tones.append(d)
        segs.append({"start_s": s.start_s, "end_s": s.end_s, "step": s.step + 1, "goal": s.goal,
                     "peak_v": s.peak_v, "tones": tones})
    out = {
        "version": schedule.version,
        "generator": f"acl {__version__}",
        "program": schedule.program,
        "source": schedule.source,
        "sample_rate_hz": float(sample_rate),
        "duration_s": schedule.duration_s,
        "max_voltage_v": schedule.max_voltage_v,
        "full_scale_v": schedule.full_scale_v,
        "full_scale_source": schedule.full_scale_source,
        "sample_scale": "wav samples are volts / full_scale_v (float32, +-1 = full scale); "
                        "npy and csv hold volts",
        "ramp_s": schedule.ramp_s,
        "segments": segs,
        "goals": [g.as_dict() for g in schedule.goals],
        "notes": list(schedule.notes),
    }
    if getattr(schedule, "chain", None):
        out["chain"] = schedule.chain
    if stats is not None:
        out["waveform"] = {"samples": stats.samples, "peak_v": stats.peak_v, "rms_v": stats.rms_v,
                           "max_sample_jump_v": stats.max_jump_v,
                           "analog_peak_v": max((s.peak_v or 0.0 for s in schedule.segments), default=0.0)}
    if files:
        out["files"] = files
    return _clean(out)


def write_schedule_json(path: str, data: dict) -> None:
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(data, fh, indent=1, allow_nan=False)
        fh.write("\n")


def load_schema() -> dict:
    return json.loads(resources.files("acl.emit").joinpath(SCHEMA_FILE).read_text(encoding="utf-8"))


def write_segments_csv(path: str, schedule: Schedule) -> int:
    """One row per tone of each run of identical consecutive segments; returns the row count.

    Columns: step, start_s, duration_s, frequency_hz, amplitude_v, phase_rad, frequency_end_hz,
    sweep.  A silent run has one row with empty tone fields.
    """
    rows = 0
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write("step,start_s,duration_s,frequency_hz,amplitude_v,phase_rad,frequency_end_hz,sweep\n")
        segs = schedule.segments
        i = 0
        while i < len(segs):
            j = i
            while j + 1 < len(segs) and segs[j + 1].tones == segs[i].tones and segs[j + 1].step == segs[i].step:
                j += 1
            s = segs[i]
            dur = segs[j].end_s - s.start_s
            if not s.tones:
                fh.write(f"{s.step + 1},{s.start_s:.9g},{dur:.9g},,,,,\n")
                rows += 1
            for t in s.tones:
                fe = "" if t.frequency_end_hz is None else f"{t.frequency_end_hz:.9g}"
                fh.write(f"{s.step + 1},{s.start_s:.9g},{dur:.9g},{t.frequency_hz:.9g},"
                         f"{t.amplitude_v:.9g},{wrapped_phase(t.phase_rad):.9g},{fe},{t.sweep or ''}\n")
                rows += 1
            i = j + 1
    return rows


def wrapped_phase(phase: float) -> float:
    """A tone's phase in [0, 2 pi) rad, with a value within 1e-9 rad below 2 pi written as 0 (the same tone: the
    phase optimiser may leave 2 pi, which segments.csv showed as 6.28318531)."""
    import math

    p = math.fmod(float(phase), 2 * math.pi)
    if p < 0:
        p += 2 * math.pi
    return 0.0 if 2 * math.pi - p < 1e-9 or p < 1e-12 else p

"""Reading a compiled schedule (schedule.json of `acl compile`) for the bench, every fault located.

E-PLAY-SCHEDULE: missing, unreadable, not JSON, not a schedule (a field missing or of the wrong
kind, a segment out of order); located at ``file:line:column`` (the JSON parser's, or the line of
the segment at fault).
"""
from __future__ import annotations

import json
import math
import os
import re

from acl.diagnostics import DiagnosticError, Span, error
from acl.emit.seq import Drive, merge

MAX_BYTES = 256 * 2 ** 20


def _fail(path, message, line=1, column=1, hint=None):
    raise DiagnosticError([error("E-PLAY-SCHEDULE", message, Span(file=path, line=line, column=column), hint)])


def _segment_lines(text: str) -> list[tuple[int, int]]:
    """Line and column of every segment in the file (its ``"start_s"`` key, counted after
    ``"segments"``)."""
    at = text.find('"segments"')
    out = []
    if at < 0:
        return out
    line, last = 1 + text.count("\n", 0, at), at
    nl = text.rfind("\n", 0, at)
    for m in re.finditer(r'"start_s"', text[at:]):
        pos = at + m.start()
        line += text.count("\n", last, pos)
        if text.count("\n", last, pos):
            nl = text.rfind("\n", last, pos)
        last = pos
        out.append((line, pos - nl))
    return out


def _at(lines, i):
    return lines[i] if i < len(lines) else (1, 1)


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def load(path: str) -> tuple[list[Drive], dict]:
    """(drives, the schedule's header fields) of ``path``; DiagnosticError (E-PLAY-SCHEDULE) otherwise."""
    hint = "give the schedule.json written by `acl compile FILE --program NAME -o OUT/`"
    if not os.path.exists(path):
        _fail(path, f"cannot read {path!r}: no such file", hint=hint)
    if not os.path.isfile(path):
        _fail(path, f"cannot read {path!r}: not a regular file", hint=hint)
    try:
        if os.path.getsize(path) > MAX_BYTES:
            _fail(path, f"{path!r} is larger than {MAX_BYTES // 2 ** 20} MB: not a schedule", hint=hint)
        with open(path, "rb") as fh:
            raw = fh.read()
    except OSError as exc:
        _fail(path, f"cannot read {path!r}: {exc.strerror or exc}", hint=hint)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        _fail(path, "not UTF-8 text: not a schedule.json", line, exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1,
              hint)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        _fail(path, f"not valid JSON: {exc.msg}", exc.lineno, exc.colno, hint)
    except RecursionError:
        _fail(path, "not a schedule: nested too deeply", hint=hint)
    if not isinstance(data, dict) or not isinstance(data.get("segments"), list):
        _fail(path, "not a schedule: no `segments` list", hint=hint)
    version = str(data.get("version", ""))
    if not re.match(r"^1\.[0-9]+$", version):
        _fail(path, f"schedule version {version!r} is not one this acl reads (1.x)", hint=hint)
    segs = []
    end_prev = 0.0
    lines = _segment_lines(text)
    for i, s in enumerate(data["segments"]):
        line, col = _at(lines, i)
        where = f"segments[{i}]"
        if not isinstance(s, dict) or not _number(s.get("start_s")) or not _number(s.get("end_s")) \
                or not isinstance(s.get("tones"), list):
            _fail(path, f"{where}: a segment needs numbers `start_s`, `end_s` and a `tones` list", line, col, hint)
        start, end = float(s["start_s"]), float(s["end_s"])
        if not (0 <= start < end) or start < end_prev - 1e-9:
            _fail(path, f"{where}: segment from {start:g} s to {end:g} s is empty, negative or out of order",
                  line, col, hint)
        end_prev = end
        tones, swept = [], False
        for j, t in enumerate(s["tones"]):
            if not isinstance(t, dict) or not all(_number(t.get(k)) for k in ("frequency_hz", "amplitude_v")):
                _fail(path, f"{where}.tones[{j}]: a tone needs numbers `frequency_hz` and `amplitude_v`",
                      line, col, hint)
            f, a, p = float(t["frequency_hz"]), float(t["amplitude_v"]), float(t.get("phase_rad") or 0.0)
            if f <= 0 or a < 0 or not math.isfinite(p):
                _fail(path, f"{where}.tones[{j}]: frequency {f:g} Hz must be positive and amplitude {a:g} V "
                      "not negative", line, col, hint)
            swept = swept or bool(t.get("sweep"))
            tones.append((f, a, p))
        segs.append((start, end, tones, swept))
    if not segs:
        _fail(path, "the schedule has no segments: nothing to play", hint=hint)
    meta = {k: data.get(k) for k in ("program", "source", "max_voltage_v", "duration_s", "ramp_s")}
    chain = data.get("chain")
    meta["chain"] = chain if isinstance(chain, dict) else {}
    drives = merge(segs)
    first = {}
    for i, (start, *_rest) in enumerate(segs):
        first.setdefault(start, i)
    meta["locations"] = [_at(lines, first.get(d.start_s, 0)) for d in drives]
    meta["path"] = path
    return drives, meta

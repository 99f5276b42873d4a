"""Reading a measured frequency sweep (paper Fig. S4a) into a :class:`GainTable`.

Format (documented in docs/schedule.md)::

    # voltage: 10 V                     <- drive amplitude of the sweep (or a voltage column)
    frequency [kHz], dx [um], dy [um]   <- names with units in [..], (..) or a _suffix
    40.0, 0.12, -0.03
    ...

Displacements are divided by voltage^2 (displacement is quadratic in the drive, paper Fig. 2c).
Any malformed input gives a diagnostic pointing at file:row:column.
"""
from __future__ import annotations

import re

import numpy as np

from acl.diagnostics import DiagnosticError, Span, error
from acl.schedule.tones import GainTable

_UNITS = {
    "frequency": {"hz": 1.0, "khz": 1e3, "mhz": 1e6},
    "dx": {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "micron": 1e-6, "nm": 1e-9},
    "voltage": {"v": 1.0, "mv": 1e-3},
}
_UNITS["dy"] = _UNITS["dx"]
_ALIASES = {"frequency": "frequency", "freq": "frequency", "f": "frequency", "dx": "dx", "x": "dx",
            "dy": "dy", "y": "dy", "voltage": "voltage", "v": "voltage", "amplitude": "voltage"}
_HEAD = re.compile(r"^\s*([A-Za-z]+)\s*(?:[\[(]\s*([^\])]+?)\s*[\])]|_([A-Za-z\u00b5]+))?\s*$")


def _fail(code, msg, path, line, col, hint=None):
    raise DiagnosticError([error(code, msg, Span(file=path, line=line, column=col), hint)])


def _fields(line: str) -> list[tuple[str, int]]:
    """Comma-separated fields with their 1-based start column."""
    out, col = [], 1
    for part in line.split(","):
        lead = len(part) - len(part.lstrip())
        out.append((part.strip(), col + lead))
        col += len(part) + 1
    return out


def read_sweep_csv(path: str) -> GainTable:
    """Parse a sweep CSV into a gain table (m per V^2), or raise DiagnosticError (E-CSV-*)."""
    try:
        with open(path, encoding="utf-8") as fh:
            lines = fh.read().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise DiagnosticError([error("E-CSV-READ", f"cannot read calibration file: {exc}",
                                     Span(file=path, line=1, column=1))]) from None
    voltage = None
    header = None
    rows: list[tuple[int, list[tuple[str, int]]]] = []
    for no, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text:
            continue
        if text.startswith("#"):
            m = re.match(r"#\s*voltage\s*[:=]\s*([-+0-9.eE]+)\s*([a-zA-Z]*)", text)
            if m:
                unit = (m.group(2) or "V").lower()
                if unit not in _UNITS["voltage"]:
                    _fail("E-CSV-UNIT", f"unknown voltage unit {m.group(2)!r}", path, no,
                          raw.index(m.group(2)) + 1, "use V or mV")
                voltage = float(m.group(1)) * _UNITS["voltage"][unit]
            continue
        if header is None:
            header = (no, _fields(raw))
            continue
        rows.append((no, _fields(raw)))
    if header is None:
        _fail("E-CSV-EMPTY", "calibration file has no header row", path, 1, 1,
              "the first row names the columns: frequency [kHz], dx [um], dy [um]")
    hline, hfields = header
    columns: dict[str, tuple[int, float]] = {}
    for idx, (name, col) in enumerate(hfields):
        m = _HEAD.match(name)
        key = _ALIASES.get(m.group(1).lower()) if m else None
        if key is None:
            _fail("E-CSV-HEADER", f"unknown column {name!r}", path, hline, col,
                  "columns are frequency, dx, dy (and optionally voltage), each with a unit")
        unit = (m.group(2) or m.group(3) or "").strip()
        scale = _UNITS[key].get(unit.lower()) if unit else None
        if scale is None:
            _fail("E-CSV-UNIT", f"column {name!r} needs a known unit"
                  + (f" (got {unit!r})" if unit else ""), path, hline, col,
                  f"write e.g. {key} [{next(iter(_UNITS[key]))}]")
        columns[key] = (idx, scale)
    for need in ("frequency", "dx", "dy"):
        if need not in columns:
            _fail("E-CSV-HEADER", f"missing column {need!r}", path, hline, 1,
                  "columns are frequency, dx, dy (and optionally voltage), each with a unit")
    if voltage is None and "voltage" not in columns:
        _fail("E-CSV-VOLTAGE", "the sweep voltage is not given", path, hline, 1,
              "add a line `# voltage: 10 V` or a `voltage [V]` column")
    if not rows:
        _fail("E-CSV-EMPTY", "calibration file has no data rows", path, hline, 1)
    data = np.empty((len(rows), 4))
    for r, (no, fields) in enumerate(rows):
        if len(fields) != len(hfields):
            _fail("E-CSV-ROW", f"row has {len(fields)} fields, the header has {len(hfields)}",
                  path, no, 1)
        for j, key in enumerate(("frequency", "dx", "dy", "voltage")):
            if key not in columns:
                data[r, j] = voltage
                continue
            idx, scale = columns[key]
            text, col = fields[idx]
            try:
                val = float(text)
            except ValueError:
                _fail("E-CSV-VALUE", f"{key} is not a number: {text!r}", path, no, col)
            if not np.isfinite(val):
                _fail("E-CSV-VALUE", f"{key} is not finite: {text!r}", path, no, col)
            data[r, j] = val * scale
        if data[r, 3] <= 0:
            _fail("E-CSV-VALUE", "the sweep voltage must be positive", path, no,
                  fields[columns["voltage"][0]][1] if "voltage" in columns else 1)
        if data[r, 0] <= 0:
            _fail("E-CSV-VALUE", "frequency must be positive", path, no, fields[columns["frequency"][0]][1])
        if r and data[r, 0] <= data[r - 1, 0]:
            _fail("E-CSV-ORDER", "frequencies must be strictly increasing", path, no,
                  fields[columns["frequency"][0]][1], "sort the rows by frequency, without duplicates")
    gains = data[:, 1:3] / data[:, 3:4] ** 2
    return GainTable(frequencies=data[:, 0].copy(), gains=gains, source=f"calibration {path}")

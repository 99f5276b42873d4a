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


MAX_BYTES = 16 * 2**20     # a measured sweep is a few hundred rows; a larger file is refused (E-CSV-READ)


def _read_lines(path: str) -> list[str]:
    """The lines of a calibration file: a regular file (a FIFO or a device would block or never
    end) of at most :data:`MAX_BYTES`, UTF-8 (a bad byte is located at its line:column)."""
    import os
    import stat

    where = Span(file=path or "<--calibration>", line=1, column=1)
    try:
        st = os.stat(path)
        if not stat.S_ISREG(st.st_mode):
            kind = "a folder" if stat.S_ISDIR(st.st_mode) else "a pipe (FIFO)" if stat.S_ISFIFO(st.st_mode) else \
                "a device or socket"
            raise DiagnosticError([error("E-CSV-READ", f"cannot read calibration file: `{path}` is {kind}, not a "
                                         "regular file", where, "give the CSV file of the measured sweep")])
        if st.st_size > MAX_BYTES:
            raise DiagnosticError([error("E-CSV-READ", f"calibration file is larger than {MAX_BYTES // 2**20} MB",
                                         where)])
        with open(path, "rb") as fh:
            raw = fh.read(MAX_BYTES + 1)
    except OSError as exc:
        raise DiagnosticError([error("E-CSV-READ", f"cannot read calibration file: {exc.strerror or exc}",
                                     where)]) from None
    if len(raw) > MAX_BYTES:
        raise DiagnosticError([error("E-CSV-READ", f"calibration file is larger than {MAX_BYTES // 2**20} MB", where)])
    try:
        return raw.decode("utf-8-sig").splitlines()
    except UnicodeDecodeError as exc:
        from acl._files import undecodable

        line, column, byte = undecodable(raw, exc)
        _fail("E-CSV-READ", f"calibration file is not UTF-8 text (byte 0x{byte:02x})", path, line, column,
              "save the file as UTF-8")


MAX_DISPLACEMENT = 1.0     # m: as data files (acl.fit.data.MAX_LENGTH), no displacement of a micro-device


def read_sweep_csv(path: str, band: tuple[float, float] | None = None, transducer: str = "") -> GainTable:
    """Parse a sweep CSV into a gain table (m per V^2), or raise DiagnosticError (E-CSV-*).

    ``band`` (Hz): the transducer's; a row outside it is E501 at its frequency (the schedule would
    play that tone into a transducer that cannot)."""
    lines = _read_lines(path)
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
                col = raw.index(m.group(1)) + 1
                try:
                    voltage = float(m.group(1)) * _UNITS["voltage"][unit]
                except ValueError:
                    _fail("E-CSV-VOLTAGE", f"the sweep voltage is not a number: {m.group(1)!r}", path, no, col,
                          "e.g. `# voltage: 10 V`")
                if not (np.isfinite(voltage) and voltage > 0):
                    _fail("E-CSV-VOLTAGE", f"the sweep voltage must be positive and finite, got {m.group(1)}",
                          path, no, col, "e.g. `# voltage: 10 V`")
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
            sep = next((c for c in (";", "\t") if c in name and len(name.split(c)) >= 3), None)
            if sep is not None:      # a spreadsheet's regional CSV (`;`) or a TSV read as one column
                _fail("E-CSV-HEADER", f"the header is separated by {'`;`' if sep == ';' else 'tabs'}, not commas",
                      path, hline, col, "save the file as comma-separated values (CSV with `,`; decimals with `.`)")
            _fail("E-CSV-HEADER", f"unknown column {name!r}", path, hline, col,
                  "columns are frequency, dx, dy (and optionally voltage), each with a unit")
        unit = (m.group(2) or m.group(3) or "").strip()
        scale = _UNITS[key].get(unit.lower()) if unit else None
        if scale is None:
            _fail("E-CSV-UNIT", f"column {name!r} needs a known unit"
                  + (f" (got {unit!r})" if unit else ""), path, hline, col,
                  f"write e.g. {key} [{next(iter(_UNITS[key]))}]")
        if key in columns:
            _fail("E-CSV-HEADER", f"column {name!r} repeats the {key} column (column "
                  f"{hfields[columns[key][0]][1]})", path, hline, col, "keep one column per quantity")
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
                from acl.units import parse_decimal

                val = parse_decimal(text)       # float() also reads `1_000` and non-ASCII digits
            except ValueError:
                _fail("E-CSV-VALUE", f"{key} is not a number: {text!r}", path, no, col)
            if not (np.isfinite(val) and np.isfinite(val * scale)):
                _fail("E-CSV-VALUE", f"{key} is not finite: {text!r}", path, no, col)
            if key in ("dx", "dy") and abs(val * scale) > MAX_DISPLACEMENT:
                _fail("E-CSV-VALUE", f"{key} = {val * scale:g} m: beyond {MAX_DISPLACEMENT:g} m, no displacement of "
                      "a micro-device", path, no, col, "check the column's unit")
            data[r, j] = val * scale
        if data[r, 3] <= 0:
            _fail("E-CSV-VALUE", "the sweep voltage must be positive", path, no,
                  fields[columns["voltage"][0]][1] if "voltage" in columns else 1)
        if data[r, 0] <= 0:
            _fail("E-CSV-VALUE", "frequency must be positive", path, no, fields[columns["frequency"][0]][1])
        if band is not None and not band[0] <= data[r, 0] <= band[1]:
            _fail("E501", f"frequency {data[r, 0] / 1e3:.6g} kHz is outside the band of transducer "
                  f"`{transducer}` ({band[0] / 1e3:g} .. {band[1] / 1e3:g} kHz)", path, no,
                  fields[columns["frequency"][0]][1], "was the sweep measured with this design's transducer?")
        if r and data[r, 0] <= data[r - 1, 0]:
            _fail("E-CSV-ORDER", "frequencies must be strictly increasing", path, no,
                  fields[columns["frequency"][0]][1], "sort the rows by frequency, without duplicates")
    with np.errstate(all="ignore"):
        gains = data[:, 1:3] / data[:, 3:4] ** 2
    bad = np.flatnonzero(~np.all(np.isfinite(gains), axis=1))
    if bad.size:
        no, fields = rows[int(bad[0])]
        _fail("E-CSV-VALUE", "displacement / voltage^2 is not a finite number (the voltage is too small or the "
              "displacement too large)", path, no, fields[columns["voltage"][0]][1] if "voltage" in columns else 1)
    return GainTable(frequencies=data[:, 0].copy(), gains=gains, source=f"calibration {path}")

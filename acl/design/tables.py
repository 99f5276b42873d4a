"""Small CSV tables the design points to (transducer gain, waypoints): header `name [unit]`, numbers.

Every problem is a diagnostic at file:row:column (row 1 is the header); nothing is dropped silently.
"""
from __future__ import annotations

import csv
import math
import re

from acl.diagnostics import DiagnosticBag, Span
from acl.units import Dims, UnitError, describe, parse_unit

MAX_ROWS = 1_000_000
_HEAD = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_ ]*?)\s*(?:[\[(]\s*([^\])]*)\s*[\])])?\s*$")


def read_table(path: str, bag: DiagnosticBag, columns: list[tuple[str, Dims]], span: Span | None = None):
    """Read columns (by position) converted to SI; returns a list of tuples or None after errors."""
    try:
        fh = open(path, newline="", encoding="utf-8")
    except OSError as exc:
        bag.error("E507", f"cannot read `{path}`: {exc.strerror}", span)
        return None
    with fh:
        try:
            rows = list(csv.reader(_limited(fh)))
        except (csv.Error, UnicodeDecodeError, ValueError) as exc:
            bag.error("E507", f"`{path}` is not a readable CSV file: {exc}", Span(file=path, line=1, column=1))
            return None
    rows = [r for r in rows if any(c.strip() for c in r) and not r[0].lstrip().startswith("#")]
    if not rows:
        bag.error("E507", f"`{path}` is empty", Span(file=path, line=1, column=1))
        return None
    header = rows[0]
    if len(header) < len(columns):
        bag.error("E507", f"`{path}` needs {len(columns)} columns: " + ", ".join(f"{n} [unit]" for n, _ in columns),
                  Span(file=path, line=1, column=1))
        return None
    factors = []
    ok = True
    for j, (name, dims) in enumerate(columns):
        m = _HEAD.match(header[j])
        col = Span(file=path, line=1, column=j + 1)
        unit = (m.group(2) or "").strip() if m else ""
        if not m:
            bag.error("E507", f"header `{header[j]}` is not `name [unit]`", col)
            ok = False
            continue
        try:
            f, d = parse_unit(unit) if unit else (1.0, (0,) * 7)
        except UnitError as exc:
            bag.error("E302", f"column `{header[j]}`: {exc}", col, exc.hint)
            ok = False
            continue
        if d != dims:
            bag.error("E301", f"column `{header[j]}`: expected {describe(dims)}, found {describe(d)}", col,
                      f"write the unit in the header, e.g. `{name} [{_unit_example(dims)}]`")
            ok = False
            continue
        factors.append(f)
    if not ok:
        return None
    out = []
    for i, row in enumerate(rows[1:], start=2):
        vals = []
        for j, f in enumerate(factors):
            cell = row[j].strip() if j < len(row) else ""
            try:
                x = float(cell)
                if not math.isfinite(x):
                    raise ValueError
            except ValueError:
                bag.error("E507", f"row {i}, column {j + 1}: `{cell}` is not a finite number", Span(file=path, line=i, column=j + 1))
                ok = False
                continue
            vals.append(x * f)
        if len(vals) == len(factors):
            out.append(tuple(vals))
    return out if ok else None


def _limited(fh, max_rows: int = MAX_ROWS):
    for i, line in enumerate(fh):
        if i >= max_rows:
            raise ValueError(f"more than {max_rows} rows")
        yield line


def _unit_example(dims) -> str:
    from acl.units import si_unit

    return {"Hz": "kHz", "Pa/V": "kPa/V", "m": "um"}.get(si_unit(dims), si_unit(dims))

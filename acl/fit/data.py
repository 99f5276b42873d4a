"""Measured data: tidy CSV files (docs/data.md) read into one :class:`Dataset`, every bad cell a diagnostic.

One observation per row.  Columns: ``observable`` (a name the design declares with ``observe``),
``value`` and ``unit`` (any unit of the observable's dimension), ``drive`` (acl drive syntax, empty
for none); optional ``time`` (s since start), ``sigma`` (same unit as ``value``) and ``set:NAME``
(override of design parameter NAME for that row, e.g. ``40 um``).  Nothing is dropped silently: a
file with any bad row raises :class:`DiagnosticError` listing every bad cell (file:row:column); a
finding repeated identically on many rows is reported once, at its first row, with a count.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from acl.diagnostics import DiagnosticBag, DiagnosticError, Span, suggest

REQUIRED = ("observable", "value", "unit", "drive")
OPTIONAL = ("time", "sigma", "experiment")
LENGTH = (1, 0, 0, 0, 0, 0, 0)
MAX_ROWS = 2_000_000
MAX_HEADER_ERRORS = 20                 # bad header columns reported one by one; then one E801 for the rest
MAX_BYTES = 256 * 2**20                  # a data file larger than this is refused (E601)
MAX_LENGTH = 1.0                         # m: |value| and sigma beyond this are no measurement of a micro-device
MAX_TIME = 1e9                           # s: about 30 years
MIN_SIGMA = 1e-15                        # m: a standard uncertainty below a femtometre is no measurement's (a weight
                                         # of 1e306 overflowed the least-squares sums: a garbage fit, exit 0)
_NUM_UNIT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")


@dataclass
class Dataset:
    """Rows of measurements in SI; arrays are aligned (length ``n``)."""

    observable: np.ndarray               # (n,) str, names of design observables
    value: np.ndarray                    # (n,) SI
    sigma: np.ndarray                    # (n,) SI, NaN where not given
    time: np.ndarray                     # (n,) s, NaN where not given
    tones: list                          # n tuples of (frequency Hz, amplitude V)
    sets: dict                           # NAME -> (n,) object array of override text ('' = design value)
    set_si: dict                         # NAME -> (n,) float SI value of the override (NaN where '')
    spans: list                          # n Spans (file, line, column 1)
    units: np.ndarray                    # (n,) str, the unit the row was written in
    files: tuple = ()
    columns: dict = field(default_factory=dict)   # column name -> 1-based index, per file (last file)
    experiment: np.ndarray = None        # (n,) str: the row's `experiment` label ('' when not given)

    def __post_init__(self):
        if self.experiment is None:
            self.experiment = np.full(self.value.size, "", dtype=object)

    @property
    def n(self) -> int:
        return int(self.value.size)

    @property
    def has_sigma(self) -> bool:
        return bool(np.all(np.isfinite(self.sigma)))

    @property
    def has_time(self) -> bool:
        """Every row is timed (time effects need a common clock)."""
        return bool(self.time.size and np.all(np.isfinite(self.time)))

    def subset(self, idx) -> "Dataset":
        idx = np.asarray(idx)
        return Dataset(self.observable[idx], self.value[idx], self.sigma[idx], self.time[idx],
                       [self.tones[i] for i in idx], {k: v[idx] for k, v in self.sets.items()},
                       {k: v[idx] for k, v in self.set_si.items()}, [self.spans[i] for i in idx],
                       self.units[idx], self.files, self.columns, self.experiment[idx])

    def override_key(self, i: int) -> tuple:
        return tuple((k, self.sets[k][i]) for k in sorted(self.sets) if self.sets[k][i])


def split_line(line: str) -> list[tuple[str, int]]:
    """Split one CSV line into (field, 1-based column) pairs; double quotes protect commas."""
    out, buf, start, quoted, i = [], [], 1, False, 0
    while i < len(line):
        ch = line[i]
        if quoted:
            if ch == '"' and i + 1 < len(line) and line[i + 1] == '"':
                buf.append('"')
                i += 1
            elif ch == '"':
                quoted = False
            else:
                buf.append(ch)
        elif ch == '"':
            quoted = True
        elif ch == ",":
            out.append(("".join(buf).strip(), start))
            buf, start = [], i + 2
        else:
            buf.append(ch)
        i += 1
    out.append(("".join(buf).strip(), start))
    return out


def _column_key(name: str) -> str:
    """A header cell as a column key: the name in lower case, ``set:NAME`` with NAME as written (parameters are
    case-sensitive) and without blanks around it (`set: gap` kept the blank: "no parameter ` gap`" on every row)."""
    text = name.strip()
    if text.lower().startswith("set:"):
        return "set:" + text[4:].strip()
    return text.lower()


def _open_quote(line: str) -> int | None:
    """The 1-based column of a double quote that opens a cell and is not closed on the line, else None."""
    quoted, at, i = False, None, 0
    while i < len(line):
        if line[i] == '"':
            if quoted and i + 1 < len(line) and line[i + 1] == '"':
                i += 1
            else:
                quoted, at = not quoted, i + 1
        i += 1
    return at if quoted else None


def parse_quantity(text: str) -> tuple[float, tuple]:
    """``'40 um'`` -> (4e-5, length dims).  Raises ValueError / UnitError."""
    from acl.units import parse_unit

    m = _NUM_UNIT.match(text)
    if not m:
        raise ValueError(f"`{text}` is not a number with a unit")
    factor, dims = parse_unit(m.group(2)) if m.group(2) else (1.0, (0,) * 7)
    return float(m.group(1)) * factor, dims


def read_data(paths, design) -> Dataset:
    """Read and check every file against ``design``; raise DiagnosticError with all bad cells."""
    from acl.fit.drive import parse_drive_cell
    from acl.units import UnitError, parse_unit

    bag = DiagnosticBag()
    obs_names = [o.name for o in design.observes]
    state_names = {o.name for o in design.observes if o.kind == "state"}
    param_names = [p.name for p in design.params]
    param_dims = {p.name: _unit_dims(p.unit) for p in design.params}
    cols: dict[str, list] = {k: [] for k in ("observable", "value", "sigma", "time", "tones", "spans", "units",
                                             "experiment")}
    sets: dict[str, list] = {}
    n_before = 0
    band = design.transducer.band if design.transducer is not None else None
    vmax = design.transducer.max_voltage if design.transducer is not None else None
    seen_files: list[str] = []
    for path in paths:
        import os

        twin = next((q for q in seen_files if os.path.exists(path) and os.path.samefile(q, path)), None)
        seen_files.append(path)
        if twin is not None:         # its rows twice would halve every variance: intervals too narrow
            bag.error("E801", f"data file given twice (also as {twin}): its rows would count twice",
                      Span(file=path, line=1, column=1), "give each data file once")
            continue
        text = _read_text(path)
        if isinstance(text, tuple):           # (line, column, byte) of the first byte that is not UTF-8
            line, column, byte = text
            bag.error("E807", f"data file is not UTF-8 text: byte 0x{byte:02x} cannot be decoded",
                      Span(file=path, line=line, column=column),
                      "save the file as UTF-8 (CSV UTF-8 in a spreadsheet); units such as `µm` can be written `um`")
            continue
        lines = text.splitlines()
        head_i = next((i for i, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")), None)
        if head_i is None:
            bag.error("E801", "data file is empty (no header row)", Span(file=path, line=1, column=1),
                      "the header is `observable,value,unit,drive[,time][,sigma][,experiment][,set:NAME...]`")
            continue
        header = split_line(lines[head_i])
        index: dict[str, int] = {}
        header_errors = 0
        for j, (name, col) in enumerate(header):
            sp = Span(file=path, line=head_i + 1, column=col)
            if header_errors == MAX_HEADER_ERRORS:   # one root cause (a wrong file) is not 20,000 errors
                header_errors += 1
                bag.error("E801", f"the header has more bad columns from here on (column {j + 1} of {len(header)}); "
                          "only the first ones are reported", sp, "is this an acl data file? (docs/data.md)")
            if header_errors > MAX_HEADER_ERRORS:
                key = _column_key(name)
                index.setdefault(key, j)
                continue
            before = len(bag.items)
            key = _column_key(name)
            if key in index:
                bag.error("E801", f"column `{name}` appears twice", sp)
            elif key in REQUIRED or key in OPTIONAL:
                index[key] = j
            elif key.startswith("set:"):
                pname = key[4:].strip()
                if pname not in param_names:
                    bag.error("E805", f"`{key}`: the design has no parameter `{pname}`", sp,
                              suggest(pname, param_names) or f"parameters: {', '.join(param_names) or 'none'}")
                index[key] = j
            elif not name.strip():
                bag.error("E801", "a column without a name (a trailing or doubled comma in the header?)", sp,
                          "remove the empty header cell, and the matching cell of every row")
            else:
                sep = next((c for c in (";", "\t", "|") if c in name
                            and any(part.strip().lower() in REQUIRED for part in name.split(c))), None)
                if sep is not None:     # a spreadsheet's regional setting (`;`) or a TSV: say so, not "unknown column"
                    shown = {";": "`;`", "\t": "tabs", "|": "`|`"}[sep]
                    bag.error("E801", f"the header is separated by {shown}, not commas: it reads as one unknown column",
                              sp, "save the file as comma-separated values (CSV with `,`; decimals with `.`)")
                else:
                    bag.error("E801", f"unknown column `{name}`", sp,
                              suggest(key, [*REQUIRED, *OPTIONAL]) or "columns: observable, value, unit, drive, time, sigma, set:NAME")
            header_errors += len(bag.items) > before
        missing = [k for k in REQUIRED if k not in index]
        if missing:
            bag.error("E801", f"missing column(s) {', '.join(missing)}", Span(file=path, line=head_i + 1, column=1),
                      "the header is `observable,value,unit,drive[,time][,sigma][,experiment][,set:NAME...]`")
            continue
        set_keys = [k for k in index if k.startswith("set:")]
        for k in set_keys:
            sets.setdefault(k[4:], [""] * n_before)
        n_file = 0
        first_row_diag = len(bag.items)
        for li in range(head_i + 1, len(lines)):
            raw = lines[li]
            if not raw.strip() or raw.lstrip().startswith("#"):
                continue
            if n_before + n_file >= MAX_ROWS:
                bag.error("E801", f"more than {MAX_ROWS} rows", Span(file=path, line=li + 1, column=1))
                break
            cells = split_line(raw)
            line = li + 1
            if len(cells) != len(header):
                quote = _open_quote(raw)
                if quote is not None:        # the rest of the row went into one cell: say why
                    bag.error("E801", "a quote opened here is not closed on this row (the rest of the row became one "
                              f"cell: {len(cells)} cells, the header has {len(header)})",
                              Span(file=path, line=line, column=quote), 'close it, or double it (`""`) inside a cell')
                else:
                    bag.error("E801", f"row has {len(cells)} cells, the header has {len(header)}",
                              Span(file=path, line=line, column=1))
                continue

            def cell(key):
                return cells[index[key]]

            def sp(key):
                return Span(file=path, line=line, column=cell(key)[1])

            ok = True
            name = cell("observable")[0]
            if name not in obs_names:
                bag.error("E803", f"unknown observable `{name}`" if name else "missing observable", sp("observable"),
                          suggest(name, obs_names) or f"the design observes: {', '.join(obs_names) or 'nothing'}")
                ok = False
            unit = cell("unit")[0]
            factor = None
            state = name in state_names
            try:
                factor, dims = parse_unit(unit) if unit or state else (None, None)
                if state and dims != (0,) * 7:
                    bag.error("E804", f"unit `{unit}`: `{name}` is a latch state, a pure number (write `1` or leave "
                              "the unit empty)", sp("unit"))
                    ok = False
                elif state:
                    pass
                elif factor is None:
                    bag.error("E804", "missing unit", sp("unit"), "every observable is a length: write e.g. `um`")
                    ok = False
                elif dims != LENGTH:
                    from acl.units import describe
                    bag.error("E804", f"unit `{unit}` is a {describe(dims)}, the observable is a length", sp("unit"))
                    ok = False
            except UnitError as exc:
                bag.error("E804", str(exc), sp("unit"), exc.hint)
                ok = False
            value = _number(bag, cell("value")[0], sp("value"), "value", required=True)
            # an optional column, once present, is needed on every row (a mix would be silently inconsistent)
            sigma = _number(bag, cell("sigma")[0], sp("sigma"), "sigma", required=True, positive=True) \
                if "sigma" in index else math.nan
            time = _number(bag, cell("time")[0], sp("time"), "time", required=True) if "time" in index else math.nan
            if value is None or sigma is None or time is None:
                ok = False
            try:
                tones = parse_drive_cell(cell("drive")[0], path, line, cell("drive")[1])
            except DiagnosticError as exc:
                for d in exc.diagnostics:
                    bag.add(d)
                ok = False
            else:
                ok = _drive_in_range(bag, tones, band, vmax, design, sp("drive")) and ok
            row_sets = {}
            for k in set_keys:
                text = cell(k)[0]
                if text:
                    try:
                        _, dims = parse_quantity(text)
                    except (ValueError, UnitError) as exc:
                        bag.error("E805", f"`{k}` = `{text}`: {exc}", sp(k), "write a number with a unit, e.g. `40 um`")
                        ok = False
                    else:      # at the cell, not later as the design's `--set` error (its hint named `<--set>:1:1`)
                        want = param_dims.get(k[4:])
                        if want is not None and dims != want:
                            from acl.design.core import example
                            from acl.units import describe

                            bag.error("E805", f"`{k}` = `{text}` is {'a plain number' if not any(dims) else 'a ' + describe(dims)}"
                                      f"; parameter `{k[4:]}` is a {describe(want)}", sp(k),
                                      f"write it with a unit, e.g. `{example(want)}`")
                            ok = False
                row_sets[k[4:]] = text
            if ok and state and value not in (0.0, 1.0):
                bag.error("E806", f"value {cell('value')[0]}: a latch state is 0 (state a, as printed) or 1 (state b, "
                          "snapped through)", sp("value"))
                ok = False
            if ok and factor is not None and not state:
                for what, x in (("value", value), ("sigma", sigma)):
                    if math.isfinite(x) and abs(x * factor) > MAX_LENGTH:
                        bag.error("E806", f"{what} {cell(what)[0]} {unit} is beyond {MAX_LENGTH:g} m: not a "
                                  "displacement of a micro-device", sp(what), "check the unit column")
                        ok = False
                if math.isfinite(sigma) and sigma * factor < MIN_SIGMA:
                    bag.error("E806", f"sigma {cell('sigma')[0]} {unit} is below {MIN_SIGMA:g} m: not the uncertainty "
                              "of a measurement", sp("sigma"), "check the unit column")
                    ok = False
            if not ok or factor is None:
                continue
            cols["observable"].append(name)
            cols["value"].append(value * factor)
            cols["sigma"].append(sigma * factor)
            cols["time"].append(time)
            cols["tones"].append(tones)
            cols["spans"].append(Span(file=path, line=line, column=1))
            cols["units"].append(unit)
            cols["experiment"].append(cell("experiment")[0] if "experiment" in index else "")
            for k in sets:
                sets[k].append(row_sets.get(k, ""))
            n_file += 1
        n_before += n_file
        bag.items[first_row_diag:] = _collapse_repeats(bag.items[first_row_diag:])
        if n_file == 0 and not bag.has_errors:
            bag.error("E801", "data file has no rows", Span(file=path, line=head_i + 1, column=1))
    sig = np.isfinite(np.array(cols["sigma"], float))
    if sig.any() and not sig.all():
        first = cols["spans"][int(np.argmin(sig))]
        bag.error("E801", "some files give sigma and others do not: the weights would be inconsistent",
                  Span(file=first.file, line=1, column=1), "give a sigma column in every file, or in none")
    bag.raise_if_errors()
    sets_arr = {k: np.array(v, dtype=object) for k, v in sets.items()}
    set_si = {k: np.array([parse_quantity(t)[0] if t else np.nan for t in v], float) for k, v in sets.items()}
    return Dataset(np.array(cols["observable"], dtype=object), np.array(cols["value"], float),
                   np.array(cols["sigma"], float), np.array(cols["time"], float), cols["tones"], sets_arr,
                   set_si, cols["spans"], np.array(cols["units"], dtype=object), tuple(paths), {},
                   np.array(cols["experiment"], dtype=object))


def _unit_dims(unit: str):
    """The dimensions of a parameter's SI unit string, or None when it cannot be read (no check then)."""
    from acl.units import UnitError, parse_unit

    try:
        return parse_unit(unit or "1")[1]
    except (UnitError, ValueError):
        return None


def _collapse_repeats(diags: list) -> list:
    """One diagnostic per root cause: rows repeating an identical finding become the first row's
    diagnostic with a note "and N more rows" (18 rows naming one wrong observable are one E803)."""
    from dataclasses import replace

    groups: dict[tuple, list] = {}
    for d in diags:
        groups.setdefault((d.code, d.severity, d.message, d.hint, d.span.file if d.span else None), []).append(d)
    out = []
    for group in groups.values():
        first, rest = group[0], group[1:]
        if rest:
            lines = [str(d.span.line) for d in rest[:5] if d.span is not None]
            where = f" (line{'s' if len(rest) > 1 else ''} {', '.join(lines)}{', ...' if len(rest) > 5 else ''})"
            first = replace(first, notes=(*first.notes, f"and {len(rest)} more row{'s' if len(rest) > 1 else ''}"
                                                      f"{where if lines else ''}"))
        out.append(first)
    return out


def _read_text(path):
    """The text of a data file, or (line, column, byte) of its first byte that is not UTF-8.

    Only regular files are read (a FIFO or a device would block or never end: E601), up to
    :data:`MAX_BYTES`.  Raises DiagnosticError for files that cannot be read.
    """
    import os
    import stat

    try:
        st = os.stat(path)
        if not stat.S_ISREG(st.st_mode):
            kind = "a folder" if stat.S_ISDIR(st.st_mode) else "a pipe (FIFO)" if stat.S_ISFIFO(st.st_mode) else \
                "a device or socket"
            raise DiagnosticError([_io_msg(path, f"not a regular file: `{path}` is {kind}",
                                           "give a CSV file; a pipe can be saved to a file first")])
        if st.st_size > MAX_BYTES:
            raise DiagnosticError([_io_msg(path, f"data file is larger than {MAX_BYTES // 2**20} MB")])
        with open(path, "rb") as fh:
            raw = fh.read(MAX_BYTES + 1)
    except OSError as exc:
        raise DiagnosticError([_io(path, exc)])
    if len(raw) > MAX_BYTES:
        raise DiagnosticError([_io_msg(path, f"data file is larger than {MAX_BYTES // 2**20} MB")])
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        from acl._files import undecodable

        return undecodable(raw, exc)


def _drive_in_range(bag, tones, band, vmax, design, span) -> bool:
    """Drives outside the transducer's band or above its maximum voltage are not data the model covers."""
    ok = True
    for f, v in tones:
        if band is not None and not band[0] <= f <= band[1]:
            bag.error("E501", f"drive frequency {f / 1e3:.6g} kHz is outside the band of transducer "
                      f"`{design.transducer.name}` ({band[0] / 1e3:g} .. {band[1] / 1e3:g} kHz)", span,
                      "the model knows the transducer only within its declared band")
            ok = False
        if vmax is not None and v > vmax:
            bag.error("E502", f"drive amplitude {v:.6g} V is above the maximum of transducer "
                      f"`{design.transducer.name}` ({vmax:g} V)", span)
            ok = False
    return ok


def _number(bag, text, span, what, required, positive=False):
    if not text:
        if required:
            bag.error("E806", f"missing {what}", span,
                      None if what == "value" else f"the file has a `{what}` column: give it on every row, or drop the column")
            return None
        return math.nan
    try:
        from acl.units import parse_decimal

        x = parse_decimal(text)             # Python's float() also reads `1_000` and non-ASCII digits (`١٢`)
    except ValueError:
        bag.error("E806", f"{what} `{text}` is not a number", span,
                  "write the number alone; its unit goes in the `unit` column" if what in ("value", "sigma") else None)
        return None
    if not math.isfinite(x):
        bag.error("E806", f"{what} `{text}` is not finite", span)
        return None
    if positive and x <= 0:
        bag.error("E806", f"{what} must be positive, got {text}", span)
        return None
    if what == "time" and abs(x) > MAX_TIME:
        bag.error("E806", f"time `{text}` s is beyond {MAX_TIME:g} s", span)
        return None
    return x


def _io_msg(path, message, hint=None):
    from acl.diagnostics import error

    return error("E601", message, Span(file=str(path), line=1, column=1), hint)


def _io(path, exc):
    from acl.diagnostics import error

    return error("E601", f"cannot read data file: {exc.strerror or exc}", Span(file=str(path), line=1, column=1))

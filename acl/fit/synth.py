"""Synthetic measurements from the fit's own forward model, with chosen effects and Gaussian noise.

The same model `acl fit` uses (acl.fit.forward), so a user can check that an analysis finds an
effect planted in data shaped like their experiment.  The experiment is the cartesian product of
override sets x frequencies x voltages, repeated ``repeats`` times; rows are timed ``interval``
apart in that order; every declared observable (or the chosen ones) is measured on every row.
"""
from __future__ import annotations

import functools
import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from acl.diagnostics import DiagnosticError, Span, error, suggest
from acl.physics.effect_table import EFFECT_TABLE

# user-facing effect parameters and the fitted coordinate each sets (the one table, acl.physics.effects)
ALIASES = {c.name: (c.alias_of, c.to_internal) for e in EFFECT_TABLE.values() for c in e.coefficients if c.alias_of}
ALIAS_UNITS = {c.name: c.unit for e in EFFECT_TABLE.values() for c in e.coefficients if c.alias_of}   # SI unit of each


def param_unit(eid: str, name: str) -> str | None:
    """The SI unit (acl.fit.effects) of parameter ``name`` of effect ``eid``, aliases included
    ('' for a plain number); None when the effect or the parameter is unknown."""
    from acl.fit.effects import EFFECTS

    if eid not in EFFECTS:
        return None
    units = {p.name: p.unit for p in EFFECTS[eid].params}
    if name in ALIASES and ALIASES[name][0] in units:
        return ALIAS_UNITS[name]
    return units.get(name)


@dataclass
class Experiment:
    frequencies: tuple = (125e3,)           # Hz
    voltages: tuple = tuple(np.linspace(0, 8, 9))   # V peak
    sets: dict | None = None                # NAME -> list of override strings
    repeats: int = 1
    interval: float = 1.0                   # s between rows
    observables: tuple = ()                 # empty: every declared observable
    label: str = ""                         # `experiment` column of its rows (several experiments, one data set)


def effect_inputs(spec: dict) -> dict:
    """{effect: {param: SI value}} with aliases (v_sat, plateau) turned into fitted coordinates; checked."""
    from acl.fit.effects import EFFECTS

    out = {}
    for eid, params in spec.items():
        if eid not in EFFECTS:
            raise DiagnosticError([error("E-USAGE", f"unknown effect `{eid}`", Span(file="<--effect>", line=1, column=1),
                                         suggest(eid, EFFECTS) or f"effects: {', '.join(EFFECTS)}")])
        eff = EFFECTS[eid]
        names = [p.name for p in eff.params]
        vals = {p.name: (p.null if p.null == p.null else p.start) for p in eff.params}
        for k, v in params.items():
            if k in ALIASES and ALIASES[k][0] in names:
                vals[ALIASES[k][0]] = ALIASES[k][1](v)
            elif k in names:
                vals[k] = v
            else:
                raise DiagnosticError([error("E-USAGE", f"effect `{eid}` has no parameter `{k}`",
                                             Span(file="<--effect>", line=1, column=1),
                                             f"parameters: {', '.join(names + [a for a, (t, _) in ALIASES.items() if t in names])}")])
        out[eid] = vals
    return out


def generate(design_path, experiment, effects: dict | None = None, noise: float = 0.0,
             seed: int = 0, coeffs: dict | None = None, search_paths=(), coupled: bool = False,
             model: str = "coupled"):
    """Return (Dataset, Prepared) of synthetic rows (values in SI, sigma = noise).

    ``model``: the force model of a simple pair, ``coupled`` (the analysis', default) or ``eq3`` (paper Eq. 3, the
    reduced model; acl.fit.mechanism.build_instance).

    ``coupled``: every design through the group model with the analysis' full force model
    (acl.fit.mechanism.build_instance), lone actuators and pairs included.

    ``experiment``: one :class:`Experiment` or a list of them (run one after the other, in one data set,
    rows tagged with each experiment's ``label``: e.g. a pair and its calibration beam)."""
    import acl
    from acl.fit.data import Dataset
    from acl.fit.mechanism import build_instance

    design = acl.load(design_path, search_paths=search_paths)
    experiments = [experiment] if isinstance(experiment, Experiment) else list(experiment)
    set_names = sorted({k for ex in experiments for k in (ex.sets or {})})
    rows, times = [], []
    t = 0.0
    for ex in experiments:
        obs = list(ex.observables) or [o.name for o in design.observes]
        for name in obs:
            design.observe(name)
        sets = ex.sets or {}
        names = sorted(sets)
        combos = list(itertools.product(*[sets[k] for k in names])) or [()]
        for _ in range(max(1, ex.repeats)):
            for combo in combos:
                cell = dict(zip(names, combo))
                for f in ex.frequencies:
                    for v in ex.voltages:
                        for name in obs:
                            rows.append((name, tuple(cell.get(k, "") for k in set_names),
                                         ((float(f), float(v)),) if v > 0 else (), ex.label))
                            times.append(t)
                            t += float(ex.interval)
    n = len(rows)
    if n == 0:
        where = design.capsules[0].span if design.capsules else Span(file=str(design_path), line=1, column=1)
        raise DiagnosticError([error("E810", "the design declares no `observe`: there is nothing to synthesize",
                                     where, "declare what the experiment measures, e.g. "
                                     "`observe bend = displacement(arm, +x)` (docs/language.md)")])
    from acl.fit.data import parse_quantity

    set_arr = {k: np.array([r[1][j] for r in rows], dtype=object) for j, k in enumerate(set_names)}
    quantity = functools.lru_cache(maxsize=4096)(lambda x: parse_quantity(x)[0] if x else np.nan)
    set_si = {k: np.array([quantity(x) for x in set_arr[k]], float) for k in set_names}
    data = Dataset(np.array([r[0] for r in rows], dtype=object), np.zeros(n), np.full(n, float(noise) or np.nan),
                   np.array(times, float), [r[2] for r in rows], set_arr, set_si,
                   RowSpans(n), np.full(n, "um", dtype=object),
                   experiment=np.array([r[3] for r in rows], dtype=object))
    del rows, times
    cache: dict = {}

    def load_instance(key):
        if key not in cache:
            cache[key] = build_instance(acl.load(design_path, overrides=dict(key), search_paths=search_paths)
                                        if key else design, model, coupled=coupled)
        return cache[key]

    # coefficients in ``coeffs`` (gamma, alpha) refer to f_ref of these rows: the most common frequency; a design
    # parameter `gamma` declared as some capsules' `thrust` is what gamma scales (as acl fit and the analysis do)
    gamma_caps = None
    if coeffs and "gamma" in coeffs and any(p.name == "gamma" for p in design.params):
        from acl.fit.problem import thrust_capsules

        gamma_caps = thrust_capsules(design_path, design, "gamma", search_paths) or None
    y, P = _predict_in_chunks(data, load_instance, gamma_caps, dict(coeffs or {}), effect_inputs(effects or {}))
    rng = np.random.default_rng(seed)
    data.value = y + rng.normal(0.0, noise, n) if noise > 0 else y
    if np.any(P.state):
        # a latch state is 0 or 1: drawn with the model's switching probability (noise-free: the likelier state)
        st = P.state
        draw = rng.uniform(size=n) < y if noise > 0 else y >= 0.5
        data.value = np.where(st, draw.astype(float), data.value)
        data.sigma = np.where(st, 0.5 if noise > 0 else np.nan, data.sigma)
        data.units = np.where(st, "1", data.units).astype(object)
    return data, P


#: rows predicted at once: the model's intermediates take about 2 kB a row (2,000,000 rows peaked at 6.4 GB)
CHUNK_ROWS = 20_000


class RowSpans(Sequence):
    """The spans of generated rows (``<synth>``, line i + 2), made when asked for: a list of two million
    Span objects took about 600 MB."""

    def __init__(self, n: int):
        self.n = n

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(self.n))]
        i = int(i)
        if i < 0:
            i += self.n
        if not 0 <= i < self.n:
            raise IndexError(i)
        return Span(file="<synth>", line=i + 2, column=1)


def _predict_in_chunks(data, load_instance, gamma_caps, coeffs, effects):
    """(the model's value of every row, the Prepared rows of the last chunk with ``state`` for all rows): the rows
    in chunks of :data:`CHUNK_ROWS`, each prepared and predicted alone (a row's prediction depends on that row
    only), so memory stays bounded whatever the row count."""
    from acl.fit.forward import predict, prepare

    if data.n <= CHUNK_ROWS:
        P = prepare(data, load_instance, gamma_caps=gamma_caps)
        return predict(P, coeffs, effects), P
    y = np.empty(data.n)
    state = np.zeros(data.n, bool)
    for start in range(0, data.n, CHUNK_ROWS):
        idx = np.arange(start, min(data.n, start + CHUNK_ROWS))
        P = prepare(data.subset(idx), load_instance, gamma_caps=gamma_caps)
        y[idx] = predict(P, coeffs, effects)
        state[idx] = P.state
    return y, _Rows(state)


@dataclass(frozen=True)
class _Rows:
    """What :func:`generate`'s callers read of the Prepared rows when they were predicted in chunks."""

    state: np.ndarray


def write_csv(data, path, unit: str = "um") -> None:
    """Write a data set in the documented CSV format (atomically)."""
    import os

    from acl.fit.drive import format_drive
    from acl.units import parse_unit

    factor, _ = parse_unit(unit)
    set_names = sorted(data.sets)
    with_sigma = bool(np.all(np.isfinite(data.sigma)))     # noise-free data have no sigma column
    with_exp = bool(np.any(data.experiment != ""))
    head = ["observable", "value", "unit", "drive", "time", *(["sigma"] if with_sigma else []),
            *(["experiment"] if with_exp else []), *[f"set:{k}" for k in set_names]]

    def rows():
        yield ",".join(head) + "\n"
        block = []
        for i in range(data.n):
            block.append(row(i))
            if len(block) >= 10_000:
                yield "\n".join(block) + "\n"
                block = []
        if block:
            yield "\n".join(block) + "\n"

    def row(i):
        dimensionless = data.units[i] == "1"          # a latch state (0/1) is a pure number
        f_i, u_i = (1.0, "1") if dimensionless else (factor, unit)
        cells = [data.observable[i], f"{data.value[i] / f_i:.6g}", u_i, format_drive(data.tones[i]),
                 f"{data.time[i]:.6g}", *([f"{data.sigma[i] / f_i:.6g}"] if with_sigma else []),
                 *([data.experiment[i]] if with_exp else []),
                 *[data.sets[k][i] for k in set_names]]
        return ",".join(cells)

    if path == "-":   # `-o -`: standard output, as everywhere (it wrote a file named `-`)
        import sys

        for text in rows():
            sys.stdout.write(text)
        return
    if not path or os.path.isdir(path):
        raise IsADirectoryError(21, "a folder, not a file" if path else "an empty path", path)
    from acl._files import write_chunks_atomic

    # one rename; the temporary file is removed when it fails (`-o DIR` left DIR.tmpPID behind)
    write_chunks_atomic(path, rows())


# ------------------------------------------------------------------------------------------------
# Replaying a compiled schedule on a design (`acl synth TRUTH.acl --schedule schedule.json`)
# ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Waypoint:
    """One constant-drive segment of a schedule: its start time, tones ((Hz, V peak), ...) and goal."""

    time: float
    tones: tuple
    goal: str
    step: int
    index: int = 0                          # position among its goal's segments


@dataclass(frozen=True)
class Target:
    """A follow goal of the schedule: the capsule and its path, one point (m) per waypoint segment."""

    capsule: str
    points: object                          # (N, 2) m


MAX_SCHEDULE_BYTES = 64 * 2**20     # a schedule.json larger than this is refused (parsed, ~8x in memory)
MAX_REPLAY_SEGMENTS = 20_000        # constant-drive segments one replay plays (--max-segments raises it)
MAX_REPLAY_LIMIT = 200_000          # the highest --max-segments (each segment is an equilibrium solve, ~1-10 ms)


def _segment_position(text: str, index: int, key_name: str = "segments") -> tuple[int, int]:
    """(line, column) of element ``index`` of the top-level ``segments`` array (or ``key_name``'s) of a JSON text,
    or (1, 1).

    Walks the top level with the JSON decoder (only the elements before ``index`` are decoded)."""
    import json

    dec = json.JSONDecoder()
    ws = " \t\n\r"

    def skip(i):
        while i < len(text) and text[i] in ws:
            i += 1
        return i

    def where(i):
        line = text.count("\n", 0, i) + 1
        return line, i - (text.rfind("\n", 0, i) + 1) + 1

    try:
        i = skip(text.startswith("\ufeff") and 1 or 0)
        if text[i] != "{":
            return 1, 1
        i, found = skip(i + 1), None
        while i < len(text) and text[i] != "}":
            key, i = dec.raw_decode(text, i)
            i = skip(skip(i) + 1)             # past the colon
            if key == key_name and text[i] == "[":
                found = i
            _, i = dec.raw_decode(text, i)
            i = skip(i)
            if text[i] == ",":
                i = skip(i + 1)
        if found is None:
            return 1, 1
        i = skip(found + 1)
        for _ in range(index):
            _, i = dec.raw_decode(text, i)
            i = skip(skip(i) + 1)             # past the comma
        return where(i)
    except (ValueError, IndexError, RecursionError):
        return 1, 1


MAX_TARGET_M = 1.0       # a follow goal's target farther than 1 m from rest is not a micro-mechanism's


def read_schedule(path: str, max_segments: int = MAX_REPLAY_SEGMENTS) -> tuple[list[Waypoint], int, dict]:
    """The constant-drive segments of a schedule.json, how many chirp segments were skipped, and the
    follow goals' targets {goal name: Target} (schedule 1.1+).

    Raises DiagnosticError (E-SYNTH-SCHEDULE) at file:line:column for anything malformed, for a
    file over :data:`MAX_SCHEDULE_BYTES`, and for more than ``max_segments`` constant-drive
    segments (located at the first one beyond).
    """
    import json
    import math

    def bad(msg, line=1, col=1, hint=None):
        return DiagnosticError([error("E-SYNTH-SCHEDULE", msg, Span(file=path, line=line, column=col), hint)])

    import os

    MAX_BYTES = MAX_SCHEDULE_BYTES

    if not os.path.isfile(path):   # never open a FIFO or a device: it would block or never end
        raise DiagnosticError([error("E601", f"cannot read the schedule `{path}`: "
                                     + ("no such file" if not os.path.lexists(path) else "not a regular file"),
                                     Span(file=path or "<--schedule>", line=1, column=1))])
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_BYTES + 1)
    except OSError as exc:
        raise bad(f"cannot read the schedule: {exc.strerror or exc}") from None
    if len(raw) > MAX_BYTES:
        raise bad(f"the schedule is larger than {MAX_BYTES // 2**20} MB")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        from acl._files import undecodable

        line, col, byte = undecodable(raw, exc)
        raise bad(f"not UTF-8 text (byte 0x{byte:02x})", line, col,
                  "give the schedule.json `acl compile` wrote") from None
    from acl._files import MAX_INT_DIGITS, overlong_integer

    long_int = overlong_integer(text)
    if long_int is not None:
        raise bad(f"a number of more than {MAX_INT_DIGITS} digits", *long_int,
                  "give the schedule.json `acl compile` wrote")
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise bad(f"not JSON: {exc.msg}", exc.lineno, exc.colno, "give the schedule.json `acl compile` wrote") from None
    except RecursionError:
        raise bad("not an acl schedule: JSON nested too deeply", hint="give the schedule.json `acl compile` wrote") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("segments"), list) or not str(doc.get("version", "")).startswith("1."):
        raise bad("not an acl schedule (version 1.x with a list of segments)", hint="give the schedule.json `acl compile` wrote")
    def num(x, what):
        """A JSON number (not a boolean, string or null), finite."""
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            raise ValueError(f"{what} is {json.dumps(x)[:40]}, not a number")
        v = float(x)
        if not math.isfinite(v):
            raise ValueError(f"{what} is not finite")
        return v

    out, chirps, count = [], 0, {}
    prev_start, prev_end = -math.inf, -math.inf
    for i, seg in enumerate(doc["segments"]):
        where = f"segments[{i}]"
        try:
            if not isinstance(seg, dict):             # was "'str' object has no attribute 'get'"
                raise ValueError(f"a segment is an object, not {json.dumps(seg)[:40]}")
            missing = [k for k in ("start_s", "tones") if k not in seg]
            if missing:                               # a segment without `tones` was replayed as a pause
                raise ValueError(f"no {' and no '.join(missing)}")
            step = seg.get("step", 0)
            if isinstance(step, bool) or not isinstance(step, int) or not 0 <= step < 2**31:
                raise ValueError(f"step is {json.dumps(step)[:40]}, not a step index")
            start = num(seg["start_s"], "start_s")
            end = num(seg["end_s"], "end_s") if "end_s" in seg else start
            if end < start:
                raise ValueError(f"end_s {end:g} s is before start_s {start:g} s")
            slack = 1e-9 * max(1.0, abs(prev_end))
            if start < prev_start or start < prev_end - slack:
                raise ValueError(f"starts at {start:g} s, before the previous segment ends ({prev_end:g} s): "
                                 "segments follow one another in time")
            prev_start, prev_end = start, end
            tones = []
            seen = set()
            chirp = False
            if not isinstance(seg["tones"], list):
                raise ValueError("tones is not a list")
            for k, t in enumerate(seg["tones"]):
                if not isinstance(t, dict):               # was "string indices must be integers, not 'str'"
                    raise ValueError(f"tones[{k}] is {json.dumps(t)[:40]}, not an object")
                lacking = [key for key in ("frequency_hz", "amplitude_v") if key not in t]
                if lacking:                               # was "('amplitude_v')", a KeyError's text
                    raise ValueError(f"tones[{k}] has no {' and no '.join(lacking)}")
                f, v = num(t["frequency_hz"], "frequency_hz"), num(t["amplitude_v"], "amplitude_v")
                if not (f > 0 and v >= 0):
                    raise ValueError(f"tone {f!r} Hz @ {v!r} V")
                if t.get("phase_rad") is not None:
                    num(t["phase_rad"], "phase_rad")
                if t.get("frequency_end_hz") is not None and not num(t["frequency_end_hz"], "frequency_end_hz") > 0:
                    raise ValueError("frequency_end_hz is not a positive frequency")
                chirp = chirp or t.get("frequency_end_hz") is not None
                if v > 0:
                    if f in seen:       # rows `acl fit` refuses (E802), as a design's drive (E504); a set: a
                        raise ValueError(f"tones[{k}] repeats frequency_hz {f:g}")   # 50,000-tone segment was O(n^2)
                    seen.add(f)
                    tones.append((f, v))
        except (KeyError, TypeError, ValueError, OverflowError, AttributeError) as exc:
            raise bad(f"{where}: malformed segment ({exc})", *_segment_position(text, i),
                      hint="each segment has start_s and tones [{frequency_hz, amplitude_v}]") from None
        if chirp:
            chirps += 1
            continue
        if len(out) >= max_segments:
            raise bad(f"{where}: more than {max_segments:,} constant-drive segments ({len(doc['segments']):,} segments "
                      f"in all); a replay plays at most {max_segments:,} (each is an equilibrium solve)",
                      *_segment_position(text, i),
                      hint=f"replay a shorter program, compile with a larger --waypoint-dt, or raise --max-segments "
                           f"(at most {MAX_REPLAY_LIMIT:,})")
        goal = str(seg.get("goal") or "")
        out.append(Waypoint(start, tuple(tones), goal, step, count.get(goal, 0)))
        count[goal] = count.get(goal, 0) + 1
    if not out:
        raise bad("the schedule has no constant-drive segment to replay")
    import numpy as np

    targets = {}
    goals = doc.get("goals") or []
    if not isinstance(goals, list):
        raise bad("goals: expected a list", hint="give the schedule.json `acl compile` wrote")
    for j, g in enumerate(goals):
        if isinstance(g, dict) and g.get("kind") == "follow" and g.get("capsule") and g.get("target_um") is not None:
            at = _segment_position(text, j, "goals")
            if not g.get("name"):
                raise bad(f"goals[{j}]: a follow goal without a name", *at)
            for key in ("name", "capsule"):     # `"capsule": 5` was exit 1, "the truth has no capsule `5`"
                if not isinstance(g[key], str):
                    raise bad(f"goals[{j}].{key} is {json.dumps(g[key])[:40]}, not a string", *at,
                              hint="give the schedule.json `acl compile` wrote")
            try:
                pts = np.asarray(g["target_um"], float).reshape(-1, 2) * 1e-6
            except (TypeError, ValueError):
                raise bad(f"goals[{j}].target_um: expected a list of [x, y] in um", *at) from None
            if not (np.all(np.isfinite(pts)) and np.all(np.abs(pts) <= MAX_TARGET_M)):
                raise bad(f"goals[{j}].target_um: a target beyond {MAX_TARGET_M * 1e6:g} um (or not finite)", *at,
                          hint="give the schedule.json `acl compile` wrote")
            # one target per waypoint of the goal: with fewer, the tracking error was computed over those alone
            # (5 of 200 waypoints: RMS 0.04 um for a program 0.67 um off), with none it was E-INTERNAL
            n_way = count.get(str(g["name"]), 0)
            if len(pts) != n_way:
                raise bad(f"goals[{j}] `{g['name']}`: {len(pts)} target point{'s' if len(pts) != 1 else ''} for "
                          f"{n_way} constant-drive segment{'s' if n_way != 1 else ''} of that goal (one per waypoint)",
                          *at, hint="give the schedule.json `acl compile` wrote, unedited")
            targets[str(g["name"])] = Target(str(g["capsule"]), pts)
    return out, chirps, targets


def observe_value(design, obs, state) -> float:
    """The value (m) of observable ``obs`` at a mechanism state (acl.analysis.mechanics.MechanismState).

    displacement: the capsule's (or the capsule carried by the beam's) displacement along the axis;
    position: a coordinate of the capsule centre; gap: distance between the two orifice centres.
    """
    import numpy as np

    from acl.analysis.report import orifice_gap

    if obs.kind == "gap":
        return orifice_gap(design, obs.a, obs.b, state.positions)
    if obs.kind == "state":      # past the unstable point of the latch landscape: state b (acl.physics.latch)
        from acl.analysis.mechanics import latch_geometry
        from acl.physics.latch import latch_landscape

        land = latch_landscape(*latch_geometry(design.latch(obs.target), design))
        return float(land.bistable and state.deflections[obs.target] > land.unstable)
    cap = obs.target
    if cap not in state.displacements:
        held = [j.capsule for j in design.joints if j.kind == "mount" and j.target == obs.target]
        if not held:
            raise KeyError(f"observable `{obs.name}`: no capsule is carried by `{obs.target}`")
        cap = held[0]
    if obs.kind == "displacement":
        axis = np.asarray(obs.axis, float)
        return float(np.asarray(state.displacements[cap], float) @ (axis / np.linalg.norm(axis)))
    return float(np.asarray(state.positions[cap], float)["xyz".index(obs.component)])


def _latch_far_sides(design) -> list:
    """For every latch: the displacement (m, 3-vector) of its carried capsules from the as-printed state to the
    other stable state of its landscape (acl.physics.latch); empty for a design without a bistable latch."""
    import numpy as np

    from acl.analysis.mechanics import latch_geometry
    from acl.physics.latch import latch_landscape

    out = []
    for lt in design.latches:
        land = latch_landscape(*latch_geometry(lt, design))
        if not land.bistable:
            continue
        axis = np.asarray(lt.axis, float) / np.linalg.norm(lt.axis)
        sign = 1.0 if lt.state == "a" else -1.0
        carried = [j.capsule for j in design.joints if j.kind == "mount" and j.target == lt.name]
        out.append((carried, sign * land.state_b * axis))
    return out


def _after_snap(design, drive, fm, flipped, snapped):
    """Equilibrium after a snap-in of a latch: from the snap configuration with each latch's capsules moved to its
    far state (the state they snap to); the snap state itself (a loss) if none is stable."""
    import numpy as np

    from acl.analysis import mechanics as mech

    base = {c.name: np.asarray(c.center, float) for c in design.capsules}
    for carried, shift in flipped:
        start = dict(base)
        for c in carried:
            start[c] = base[c] + shift
        st = mech.equilibrium(design, drive, fm, start=start)
        if st.status == "ok" and st.stable:
            return st
    return snapped


@dataclass
class Replay:
    data: object                            # Dataset: every observable at every waypoint
    lost: int                               # waypoints without a stable equilibrium (no rows but a contact)
    tracking: dict                          # follow goal -> {"rms_m", "max_m", "n", "lost", "errors_m"}
    contacts: int = 0                       # of those, snap-ins written as a gap of 0 (the pair in contact)


def replay(design, waypoints: list[Waypoint], observables=(), noise: float = 0.0, seed: int = 0, progress=None,
           targets: dict | None = None) -> Replay:
    """Equilibrium of ``design`` under every waypoint's drive (warm-started in order).

    The full nonlinear model of the analysis (acl.analysis.mechanics with the design's declared
    effects).  ``lost`` counts waypoints with no stable equilibrium (snap-in): what a lab sees there
    is the pair in contact, so the ``gap`` observable that closed (the smallest gap at the snap) is
    written as 0, as the fit's pair model predicts past snap-in (``contacts``); the other observables
    of such a waypoint get no row (where the capsules rest in contact is not modelled).  With ``targets`` (from :func:`read_schedule`), the tracking error of each follow goal:
    the distance in the plane between the capsule's displacement and the target (noise-free), a
    lost waypoint counting as missed by the path's extent.
    """
    import numpy as np

    from acl.analysis import acoustics
    from acl.analysis import mechanics as mech
    from acl.design.model import Drive, Tone
    from acl.fit.data import Dataset

    names = list(observables) or [o.name for o in design.observes]
    obs = [design.observe(n) for n in names]
    fm = acoustics.force_model_for(design)
    targets = {k: t for k, t in (targets or {}).items() if t.capsule in {c.name for c in design.capsules}}
    errors = {k: np.full(len(t.points), np.nan) for k, t in targets.items()}
    rows, start, lost, contacts = [], None, 0, 0
    flipped = _latch_far_sides(design)
    for i, w in enumerate(waypoints):
        drive = Drive(tones=tuple(Tone(frequency=f, amplitude=v) for f, v in w.tones))
        st = mech.equilibrium(design, drive, fm, start=start)
        if st.status != "ok" and start is not None:
            st = mech.equilibrium(design, drive, fm)
        if st.status == "snap_in" and flipped:
            # a latch snapping through is its switch, not a loss: look for the equilibrium on the far side
            st = _after_snap(design, drive, fm, flipped, st)
        if st.status != "ok":
            lost += 1
            start = None
            closed = _closed_gap(design, obs, st) if st.status == "snap_in" else None
            if closed is not None:
                rows.append((closed, 0.0, w.time, w.tones))
                contacts += 1
        else:
            start = st.positions
            for o in obs:
                rows.append((o.name, observe_value(design, o, st), w.time, w.tones))
            t = targets.get(w.goal)
            if t is not None and w.index < len(t.points):
                d = np.asarray(st.displacements[t.capsule], float)[:2]
                errors[w.goal][w.index] = float(np.linalg.norm(d - t.points[w.index]))
        if progress is not None:
            progress(i + 1, len(waypoints))
    n = len(rows)
    value = np.array([r[1] for r in rows], float)
    state = np.array([design.observe(r[0]).kind == "state" for r in rows], bool)
    if noise > 0:       # a latch state (0/1) is read without noise; the other rows get the Gaussian noise
        value = np.where(state, value, value + np.random.default_rng(seed).normal(0.0, noise, n))
    sigma = np.where(state, 0.5, float(noise)) if noise > 0 else np.full(n, np.nan)
    data = Dataset(np.array([r[0] for r in rows], dtype=object), value, sigma,
                   np.array([r[2] for r in rows], float), [r[3] for r in rows], {}, {},
                   [Span(file="<synth>", line=i + 2, column=1) for i in range(n)],
                   np.where(state, "1", "um").astype(object))
    tracking = {}
    for k, e in errors.items():
        pts = targets[k].points
        missed = ~np.isfinite(e)
        e = np.where(missed, float(np.ptp(pts, axis=0).max() + np.abs(pts).max()), e)
        tracking[k] = {"rms_m": float(np.sqrt(np.mean(e ** 2))), "max_m": float(e.max()), "n": int(e.size),
                       "lost": int(missed.sum()), "errors_m": e}
    return Replay(data, lost, tracking, contacts)


def _closed_gap(design, obs, state) -> str | None:
    """The ``gap`` observable (of ``obs``) that closed at a snap-in: the smallest at the snap positions."""
    gaps = [o for o in obs if o.kind == "gap"]
    if not gaps:
        return None
    try:
        values = [observe_value(design, o, state) for o in gaps]
    except (KeyError, ValueError):
        return None
    return gaps[min(range(len(gaps)), key=lambda k: values[k])].name

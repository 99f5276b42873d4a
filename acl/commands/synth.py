"""`acl synth DESIGN --effect NAME=... --noise ... -o data.csv`: synthetic data from the fit's forward model.

`acl synth TRUTH.acl --schedule out/schedule.json -o run.csv` instead plays a compiled schedule on a
design (the analysis' nonlinear model with the design's declared effects) and writes every
observable at every waypoint (docs/explanation/closed-loop.md).
"""
from __future__ import annotations

import math
import re

from acl.commands._common import add_output_format, exit_code, one_design, quantity_text, report, seed


def add_parser(p) -> None:
    p.add_argument("design", metavar="DESIGN", help="design file (.acl), or a folder holding one design")
    p.add_argument("-o", "--output", required=True, metavar="CSV", help="output CSV (docs/data.md format)")
    p.add_argument("--effect", action="append", default=[], metavar="NAME[=P:V,...]",
                   help="plant an effect, e.g. drive_saturation=v_sat:8V or offset_drift=offset:0.5um,drift:10nm/s "
                        "(repeatable; ids in docs/fit.md)")
    p.add_argument("--noise", default="0 um", metavar="SIGMA", help="Gaussian noise, a length (default 0 um)")
    p.add_argument("--frequencies", default="125 kHz", metavar="F,...", help="drive frequencies, e.g. 85kHz,125kHz")
    p.add_argument("--voltages", default="0 V..8 V:9", metavar="LO..HI:N", help="voltage ramp (peak), e.g. 0V..10V:11")
    p.add_argument("--sweep", action="append", default=[], metavar="P=V1,V2,...",
                   help="parameter values to sweep (set:P columns), e.g. gap=20um,30um,40um (repeatable)")
    p.add_argument("--repeats", type=int, default=1, help="repeat the whole experiment N times (default 1)")
    p.add_argument("--interval", default="1 s", help="time between rows (default 1 s)")
    p.add_argument("--seed", type=seed, default=0, help="noise seed (default 0)")
    from acl.commands.fit import _model

    p.add_argument("--model", type=_model, default="coupled", metavar="MODEL",
                   help="force model of a simple pair: coupled (default: the force model of acl analyze) or eq3 "
                        "(paper Eq. 3, the reduced model `acl fit --model eq3` fits; docs/fit.md)")
    p.add_argument("--observe", default="", metavar="NAMES", help="observables to write (default: all declared)")
    p.add_argument("--schedule", metavar="JSON",
                   help="play this compiled schedule (schedule.json of `acl compile`) on DESIGN and write every "
                        "observable at every waypoint; DESIGN may declare effects the compiling design lacks")
    p.add_argument("--max-segments", type=_max_segments, default=None, metavar="N",
                   help="with --schedule: the most constant-drive segments to replay (default 20,000; at most 200,000)")
    p.add_argument("--path", action="append", default=[], metavar="DIR", help="extra folder imports may read from")
    add_output_format(p)   # json: {"output", "rows", "planted"} on stdout


def _max_segments(text: str) -> int:
    """argparse type of --max-segments: a whole number in 1 .. MAX_REPLAY_LIMIT."""
    import argparse

    from acl.fit.synth import MAX_REPLAY_LIMIT

    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 1 <= value <= MAX_REPLAY_LIMIT:
        raise argparse.ArgumentTypeError(f"{text!r}: give 1 .. {MAX_REPLAY_LIMIT:,}")
    return value


def _located(code, where, msg, hint=None):
    from acl.diagnostics import Span, error

    report([error(code, msg, Span(file=where, line=1, column=1), hint)])
    return 2


def _as_sweep(d):
    """A --sweep value the design refuses is reported by the loader as an override (``<--set>``, ``--set
    gapp: ...``): the user wrote --sweep, so it is located and worded at ``<--sweep>``."""
    import dataclasses

    if d.span is None or not d.span.file.startswith("<--set"):
        return d
    return dataclasses.replace(d, span=d.span.model_copy(update={"file": "<--sweep" + d.span.file[len("<--set"):]}),
                               message=d.message.replace("--set ", "--sweep ", 1),
                               hint=d.hint.replace("--set ", "--sweep ") if d.hint else d.hint)


def _overwrites_input(args, design, *more) -> int:
    """E-USAGE (exit 2) when -o names an input (the design, a file it reads, the schedule); else 0.
    Before, `acl synth D.acl -o D.acl` wrote the CSV over the design."""
    from acl._files import input_named

    hit = input_named(args.output, [*getattr(design, "sources", ()), args.design, *more])
    if hit:
        return _usage(f"--output {args.output}: names the input {hit}; writing would destroy it",
                      "give another path", where="<--output>")
    return 0


def _usage(msg, hint=None, where=None, code="E-USAGE"):
    """E-USAGE (or ``code``) at the option the message starts with (``--voltages ...`` -> ``<--voltages>:1:1``)."""
    import re

    from acl.diagnostics import Span, error

    if where is None:
        m = re.match(r"(--[a-z][a-z-]*)", msg)
        where = f"<{m.group(1)}>" if m else "<command line>"
    report([error(code, msg, Span(file=where, line=1, column=1), hint)])
    return 2


def _example(eid: str) -> str:
    from acl.physics.effect_table import EFFECT_TABLE     # the one table of effects

    spec = EFFECT_TABLE.get(eid)
    return f"{eid}={(spec.example if spec and spec.example else 'PARAM:VALUE')}"


def _param_names(eid: str) -> str:
    from acl.fit.effects import EFFECTS
    from acl.fit.synth import ALIASES

    if eid not in EFFECTS:
        return "see docs/fit.md"
    names = [p.name for p in EFFECTS[eid].params]
    return ", ".join(names + [a for a, (t, _) in ALIASES.items() if t in names])


def _planted(effects: dict) -> list[str]:
    """The effects that differ from their null value (checked names; DiagnosticError otherwise)."""
    from acl.fit.effects import EFFECTS
    from acl.fit.synth import effect_inputs

    values = effect_inputs(effects)
    return [eid for eid, vals in values.items() if any(vals[p.name] != p.null for p in EFFECTS[eid].params)]


class _EffectUnitError(Exception):
    def __init__(self, diagnostic):
        super().__init__(diagnostic.message)
        self.diagnostic = diagnostic


def _effect_value(eid: str, key: str, text: str, item: str, column: int) -> float:
    """The SI value of one ``--effect`` parameter, its unit checked against the unit the effect
    declares (acl.fit.effects): `v_sat:8um` is refused, not planted as 8e-6 V.  Unknown effects and
    parameters are left to :func:`acl.fit.synth.effect_inputs`, which names them."""
    from acl.diagnostics import Span, error
    from acl.fit.data import parse_quantity
    from acl.fit.synth import param_unit
    from acl.units import DIMENSIONLESS, describe, parse_unit

    from acl.units import UnitError

    try:
        value, dims = parse_quantity(quantity_text(text))
    except (ValueError, UnitError) as exc:      # was reported at `<command line>`, the option unnamed
        raise _EffectUnitError(error("E-USAGE", f"--effect {item!r}: `{key}`: {exc}",
                                     Span(file="<--effect>", line=1, column=column),
                                     f"e.g. {_example(eid)}")) from None
    unit = param_unit(eid, key)
    if unit is not None:
        want = parse_unit(unit)[1] if unit else DIMENSIONLESS
        if dims != want:
            got = "a plain number" if dims == DIMENSIONLESS else f"a {describe(dims)}"
            need = "a plain number" if not unit else f"a {describe(want)}, e.g. `{key}:{_unit_example(unit)}`"
            raise _EffectUnitError(error(
                "E-USAGE", f"--effect {item!r}: `{key}` is {got}; effect {eid} declares it as {need}",
                Span(file="<--effect>", line=1, column=column),
                f"`{key}` is in {unit}" if unit else f"`{key}` has no unit"))
    from acl.design.core import EFFECT_RANGES

    rng = EFFECT_RANGES.get((eid, key))      # the range a declared `effect` accepts (E401 there)
    if rng is not None and not rng.lo <= value <= rng.hi:
        shown = f"{value:g}" + (f" {unit}" if unit else "")
        sign = " must be positive:" if rng.lo > 0 and not value > 0 else ""
        raise _EffectUnitError(error(
            "E-USAGE", f"--effect {item!r}: `{key}` = {shown}{sign} is outside its physical range "
            f"{rng.lo:g} .. {rng.hi:g}" + (f" {unit}" if unit else ""),
            Span(file="<--effect>", line=1, column=column), rng.why))
    return value


def _unit_example(unit: str) -> str:
    return {"V": "8V", "m": "5um", "m/s": "10nm/s", "1/s": "0.01Hz", "1/m": "1e5 1/m", "1/V^2": "0.01 1/V^2"}.get(unit, f"1 {unit}")


def _qty(text, dims_name, option):
    """``text`` as an SI value of ``dims_name``; a wrong or missing unit names ``option`` and an example."""
    from acl.fit.data import parse_quantity
    from acl.units import DIMENSIONLESS, describe, parse_unit_static

    text = quantity_text(text)
    value, dims = parse_quantity(text)
    want = parse_unit_static(dims_name)
    if dims != want:
        got = "a plain number" if dims == DIMENSIONLESS else f"a {describe(dims)}"
        example = {"m": "0.05um", "Hz": "125kHz", "V": "2V", "s": "1s"}.get(dims_name, f"1 {dims_name}")
        raise ValueError(f"{option} `{text}` is {got}: give a {describe(want)}, e.g. {example}")
    return value


def run(args) -> int:
    import numpy as np

    from acl.diagnostics import DiagnosticError
    from acl.fit.data import MAX_LENGTH, MAX_ROWS
    from acl.fit.synth import Experiment, generate, write_csv
    from acl.units import UnitError

    try:
        noise = _qty(args.noise, "m", "--noise")
        freqs = tuple(_qty(f, "Hz", "--frequencies") for f in args.frequencies.split(",") if f.strip())
        m = re.match(r"^\s*(.+?)\s*\.\.\s*(.+?)\s*:\s*(\d+)\s*$", args.voltages)
        if not m:
            return _usage(f"--voltages {args.voltages!r}: expected LO..HI:N, e.g. 0V..10V:11")
        n_volts = int(m.group(3))
        if not 1 <= n_volts <= MAX_ROWS:
            return _usage(f"--voltages {args.voltages!r}: {n_volts} voltages; between 1 and {MAX_ROWS:,} "
                          "(the most rows `acl fit` reads)")
        volts = tuple(np.linspace(_qty(m.group(1), "V", "--voltages"), _qty(m.group(2), "V", "--voltages"), n_volts))
        interval = _qty(args.interval, "s", "--interval")
        effects = {}
        for item in args.effect:
            name, _, rest = item.partition("=")
            if not rest.strip():
                return _usage(f"--effect {item!r}: give the effect's size, e.g. {_example(name.strip())}",
                              "an effect at its null value plants nothing; parameters: " + _param_names(name.strip()))
            params = {}
            for found in re.finditer(r"[^,]+", rest):
                part = found.group()
                if not part.strip():
                    continue
                k, sep, v = part.partition(":")
                if not sep:
                    return _usage(f"--effect {item!r}: parameters are NAME:VALUE, e.g. drive_saturation=v_sat:8V")
                column = len(name) + 2 + found.start() + len(k) + 1 + (len(v) - len(v.lstrip()))
                if k.strip() in params:          # `v_sat:8V,v_sat:9V`: the second silently replaced the first
                    return _usage(f"--effect {item!r}: `{k.strip()}` given twice: give each parameter once")
                params[k.strip()] = _effect_value(name.strip(), k.strip(), v, item, column)
            if name.strip() in effects:        # the second silently replaced the first
                return _usage(f"--effect {name.strip()} given twice: give its parameters once, e.g. "
                              f"{_example(name.strip())}")
            effects[name.strip()] = params
        sets = {}
        for item in args.sweep:
            k, sep, vals = item.partition("=")
            if not sep:
                return _usage(f"--sweep {item!r}: expected P=V1,V2,...")
            if k.strip() in sets:              # the second silently replaced the first
                return _usage(f"--sweep {k.strip()} given twice: list its values once, P=V1,V2,...")
            sets[k.strip()] = [quantity_text(v)
                               for v in vals.split(",") if v.strip()]
            if not k.strip() or not sets[k.strip()]:
                return _usage(f"--sweep {item!r}: expected P=V1,V2,... with at least one value")
            from acl.fit.data import parse_quantity

            for v in sets[k.strip()]:      # `gap=gap*2`, `(50um)`, `50um+1um` were internal errors
                try:
                    parse_quantity(v)
                except (ValueError, UnitError) as exc:
                    return _usage(f"--sweep {k.strip()}: `{v}` is not a value ({exc})",
                                  "give numbers with units, e.g. --sweep gap=20um,30um,40um (no expressions)")
    except _EffectUnitError as exc:
        report([exc.diagnostic])
        return 2
    except (ValueError, UnitError) as exc:
        return _usage(str(exc))
    try:
        planted = _planted(effects)
    except DiagnosticError as exc:
        report(exc.diagnostics)
        return 2
    except ArithmeticError:
        return _usage(f"--effect: {', '.join(args.effect)}: v_sat and plateau must be positive and finite")
    for eid, params in effects.items():
        if eid not in planted:
            return _usage(f"--effect {eid}: every parameter is at the effect's null value, so it plants nothing",
                          "give a value that differs from the null, e.g. " + _example(eid))
    from acl.fit.data import MIN_SIGMA

    # each option at its own name (they were one message at `<command line>`, or `<--noise>` for a bad --interval);
    # the noise is checked before --schedule too: a replay with `--noise 5m` wrote rows that `acl fit` refuses (E806)
    if args.repeats < 1:
        return _usage(f"--repeats {args.repeats}: at least 1")
    if not freqs:
        return _usage(f"--frequencies {args.frequencies!r}: give one frequency at least, e.g. 125kHz")
    if not math.isfinite(noise) or noise < 0 or noise > MAX_LENGTH or 0 < noise < MIN_SIGMA:
        return _usage(f"--noise {args.noise}: the noise is 0 or from {MIN_SIGMA:g} m to {MAX_LENGTH:g} m (the sigma "
                      "`acl fit` reads)")
    if args.max_segments is not None and args.schedule is None:
        return _usage("--max-segments applies to --schedule only")
    if args.schedule is not None:
        if effects or sets:
            return _usage("--schedule plays on the design as declared: declare effects in it (`effect ID { ... }`) "
                          "instead of --effect; --sweep does not apply")
        return _replay(args, noise)
    if not all(math.isfinite(x) for x in freqs):
        return _usage(f"--frequencies {args.frequencies}: every frequency must be finite")
    if not all(math.isfinite(x) for x in volts):
        return _usage(f"--voltages {args.voltages}: the voltages must be finite")
    if not (math.isfinite(interval) and interval > 0):
        return _usage(f"--interval {args.interval}: a positive, finite time, e.g. 1s")
    design = one_design(args.design)
    if design is None:
        return 2
    import acl

    try:
        resolved = acl.load(design, search_paths=args.path)
    except DiagnosticError as exc:
        report(exc.diagnostics)
        return exit_code(exc.diagnostics)
    hit = _overwrites_input(args, resolved)
    if hit:
        return hit
    listed = [s.strip() for s in args.observe.split(",") if s.strip()]
    if len(set(listed)) < len(listed):          # each row written twice: counted as two measurements by acl fit
        twice = next(n for i, n in enumerate(listed) if n in listed[:i])
        return _usage(f"--observe {twice} given twice: each observable once", where="<--observe>")
    n_obs = len(listed) or len(resolved.observes)
    n_rows = args.repeats * len(freqs) * len(volts) * max(1, n_obs) * math.prod(len(v) for v in sets.values())
    if n_rows > MAX_ROWS:
        return _usage(f"the experiment has {n_rows:,} rows; `acl fit` reads at most {MAX_ROWS:,}",
                      "fewer voltages, frequencies, sweep values, repeats or observables")
    from acl.fit.data import MAX_TIME

    if (n_rows - 1) * interval > MAX_TIME:      # written as 1e+308 and inf: a file acl fit refuses (E806)
        return _usage(f"--interval {args.interval}: {n_rows:,} rows at this interval reach "
                      f"{(n_rows - 1) * interval:.3g} s, beyond the {MAX_TIME:g} s a data file may hold",
                      "a shorter interval, or fewer rows")
    tr = resolved.transducer
    if tr is not None:
        bad_f = [f for f in freqs if not tr.band[0] <= f <= tr.band[1]]
        if bad_f:
            return _located("E501", "<--frequencies>", f"drive frequency {bad_f[0] / 1e3:g} kHz is outside the band "
                            f"of transducer `{tr.name}` ({tr.band[0] / 1e3:g} .. {tr.band[1] / 1e3:g} kHz)")
        if max(volts) > tr.max_voltage or min(volts) < 0:
            return _located("E502", "<--voltages>", f"drive amplitudes must lie in 0 .. {tr.max_voltage:g} V "
                            f"(transducer `{tr.name}`), got {min(volts):g} .. {max(volts):g} V")
    ex = Experiment(frequencies=freqs, voltages=volts, sets=sets, repeats=args.repeats, interval=interval,
                    observables=tuple(s.strip() for s in args.observe.split(",") if s.strip()))
    try:
        data, _ = generate(design, ex, effects, noise=noise, seed=args.seed, search_paths=args.path,
                           model=args.model)
    except DiagnosticError as exc:
        diags = [_as_sweep(d) for d in exc.diagnostics]
        report(diags)
        return exit_code(diags)
    except KeyError as exc:
        return _usage(f"--observe: {exc.args[0]}")
    bad = _first_unreadable(data)
    if bad is not None:      # `drift:1e300 um/s` wrote values of 1e300 um (exit 0): data `acl fit` refuses (E806)
        return _usage(f"--effect {', '.join(args.effect) or '(none)'}: row {bad + 2} would hold "
                      f"{data.value[bad]:.3g} m, beyond the {MAX_LENGTH:g} m `acl fit` reads (E806)",
                      "give the effect a smaller size", where="<--effect>" if args.effect else "<command line>")
    try:
        write_csv(data, args.output)
    except OSError as exc:
        return _usage(f"cannot write {args.output!r}: {exc.strerror or exc}", where="<--output>",
                      code="E-USAGE" if isinstance(exc, IsADirectoryError) else "E601")
    if args.output_format == "json":
        import json
        import sys

        sys.stdout.write(json.dumps({"output": args.output, "rows": data.n,
                                     "planted": {e: effects[e] for e in planted}}, indent=2) + "\n")
    elif not args.quiet:
        from acl._console import make_console

        con = make_console(stderr=True, highlight=False)
        from acl.design.core import EFFECT_UNITS
        from acl.units import shown_unit

        def text(v, unit):
            k, unit = shown_unit(unit)
            return f"{v * k:g} {unit}".strip()

        for eid in planted:
            units = EFFECT_UNITS.get(eid, {})
            given = ", ".join(f"{k} = {text(v, units.get(k, ('',))[0])}" for k, v in effects[eid].items())
            con.print(f"planted {eid}: {given}")
        con.print(f"wrote {data.n} rows to {args.output}")
    return 0


def _outside_transducer(design, waypoints, path: str) -> list:
    """E501/E502 for drives of the schedule outside the design's transducer band or maximum voltage
    (as in data files: the model knows the transducer only there); one diagnostic per kind."""
    from acl.diagnostics import Span, error

    tr = design.transducer
    band, vmax = (tr.band, tr.max_voltage) if tr is not None else (None, None)
    out, seen = [], set()
    for k, w in enumerate(waypoints):
        for f, v in w.tones:
            if "E501" not in seen and band is not None and not band[0] <= f <= band[1]:
                seen.add("E501")
                out.append(error("E501", f"waypoint {k} (t = {w.time:g} s) drives {f / 1e3:.6g} kHz, outside the band of "
                                 f"transducer `{tr.name}` ({band[0] / 1e3:g} .. {band[1] / 1e3:g} kHz)",
                                 Span(file=path, line=1, column=1), "was the schedule compiled for this design?"))
            if "E502" not in seen and vmax is not None and v > vmax:
                seen.add("E502")
                out.append(error("E502", f"waypoint {k} (t = {w.time:g} s) drives {v:.6g} V, above the maximum "
                                 f"of transducer `{tr.name}` ({vmax:g} V)", Span(file=path, line=1, column=1),
                                 "was the schedule compiled for this design?"))
    return out


def _first_unreadable(data) -> int | None:
    """The first row whose value `acl fit` would refuse (not finite, or beyond 1 m: acl.fit.data, E806), else None."""
    import numpy as np

    from acl.fit.data import MAX_LENGTH

    bad = np.flatnonzero(~np.isfinite(data.value) | (np.abs(data.value) > MAX_LENGTH))
    return int(bad[0]) if bad.size else None


def _replay(args, noise) -> int:
    from acl._console import make_console
    from acl.commands._common import load_or_report
    from acl.diagnostics import DiagnosticError
    from acl.fit.synth import read_schedule, replay, write_csv

    console = make_console(stderr=True)
    try:
        waypoints, chirps, targets = read_schedule(args.schedule, **(
            {"max_segments": args.max_segments} if args.max_segments is not None else {}))
    except DiagnosticError as exc:
        report(exc.diagnostics)
        return 2
    design, code = load_or_report(args.design, args)
    if design is None:
        return code
    bad = _outside_transducer(design, waypoints, args.schedule)
    caps = {c.name for c in design.capsules}
    for goal, t in targets.items():
        if t.capsule not in caps:      # a follow goal of another design (or a tampered file)
            from acl.diagnostics import Span, error

            bad.append(error("E-SYNTH-SCHEDULE", f"goal `{goal}` follows capsule `{t.capsule}`, which {args.design} "
                             "does not have", Span(file=args.schedule, line=1, column=1),
                             "replay a schedule compiled from this design (or its calibrated twin)"))
            break
    if bad:
        report(bad)
        return 1
    names = [s.strip() for s in args.observe.split(",") if s.strip()]
    if len(set(names)) < len(names):
        twice = next(n for i, n in enumerate(names) if n in names[:i])
        return _usage(f"--observe {twice} given twice: each observable once", where="<--observe>")
    hit = _overwrites_input(args, design, args.schedule)
    if hit:
        return hit
    known = [o.name for o in design.observes]
    for n in names:
        if n not in known:
            return _usage(f"--observe: the design has no observable `{n}`", "observables: " + (", ".join(known) or "none"))
    if not (names or known):
        return _usage("the design declares no `observe`: nothing to write")
    if len(waypoints) > 200 and console.is_terminal:
        from rich.progress import BarColumn, Progress

        with Progress("replaying", BarColumn(), "{task.completed}/{task.total} waypoints", console=console,
                      transient=True) as bar:
            task = bar.add_task("replay", total=len(waypoints))
            res = replay(design, waypoints, names, noise, args.seed,
                         progress=lambda done, total: bar.update(task, completed=done), targets=targets)
    else:
        res = replay(design, waypoints, names, noise, args.seed, targets=targets)
    data, lost = res.data, res.lost
    if data.n == 0:
        from acl.diagnostics import Span, error

        report([error("E-SYNTH-REPLAY", f"no waypoint of {args.schedule} has a stable equilibrium on {args.design}",
                      Span(file=args.schedule, line=1, column=1), "lower the drive or check the design")])
        return 1
    bad = _first_unreadable(data)
    if bad is not None:      # an effect the truth declares drove a value beyond what `acl fit` reads (E806)
        from acl.diagnostics import Span, error

        report([error("E806", f"the replay on {args.design} reaches {data.value[bad]:.3g} m at t = "
                      f"{data.time[bad]:g} s, beyond the 1 m `acl fit` reads: nothing written",
                      Span(file=args.design, line=1, column=1), "check the effects the truth declares")])
        return 1
    try:
        write_csv(data, args.output)
    except OSError as exc:
        return _usage(f"cannot write {args.output!r}: {exc.strerror or exc}", where="<--output>",
                      code="E-USAGE" if isinstance(exc, IsADirectoryError) else "E601")
    if not getattr(args, "quiet", False):      # -q: warnings only (the CSV is the result)
        console.print(f"wrote {data.n} rows ({len(waypoints) - lost} waypoints x {len(names or known)} observables"
                      + (f", {res.contacts} gaps in contact at snap-ins" if res.contacts else "") + f") to {args.output}")
        for goal, t in res.tracking.items():
            console.print(f"{goal}: tracking error on {args.design} RMS {t['rms_m'] * 1e6:.4g} um, "
                          f"max {t['max_m'] * 1e6:.4g} um over {t['n']} waypoints (noise-free)"
                          + (f", {t['lost']} lost" if t["lost"] else ""))
        if chirps:
            console.print(f"note: {chirps} sweep segments skipped (a chirp has no static equilibrium)")
    if lost:
        console.print(f"warning: {lost} waypoints have no stable equilibrium on this design (snap-in?): "
                      + (f"{res.contacts} written as a gap of 0 (contact), no other rows" if res.contacts else "no rows"))
    return 0

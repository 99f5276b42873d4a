"""`acl synth DESIGN --effect NAME=... --noise ... -o data.csv`: synthetic data from the fit's forward model.

`acl synth TRUTH.acl --schedule out/schedule.json -o run.csv` instead plays a compiled schedule on a
design (the analysis' nonlinear model with the design's declared effects) and writes every
observable at every waypoint (docs/fit.md, closing the loop).
"""
from __future__ import annotations

import re

from acl.commands._common import exit_code, parse_sets, report


def add_parser(p) -> None:
    p.add_argument("design", metavar="DESIGN", help="design file (.acl)")
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
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    p.add_argument("--observe", default="", metavar="NAMES", help="observables to write (default: all declared)")
    p.add_argument("--schedule", metavar="JSON",
                   help="play this compiled schedule (schedule.json of `acl compile`) on DESIGN and write every "
                        "observable at every waypoint; DESIGN may declare effects the compiling design lacks")
    p.add_argument("--path", action="append", default=[], metavar="DIR", help="extra folder imports may read from")


def _usage(msg, hint=None):
    from acl.diagnostics import Span, error

    report([error("E-USAGE", msg, Span(file="<command line>", line=1, column=1), hint)])
    return 2


def _qty(text, dims_name):
    from acl.fit.data import parse_quantity
    from acl.units import parse_unit_static

    text = re.sub(r"^([0-9.eE+-]+)([A-Za-z\u00b5])", r"\1 \2", text.strip())
    value, dims = parse_quantity(text)
    if dims != parse_unit_static(dims_name):
        raise ValueError(f"`{text}` is not in {dims_name}")
    return value


def run(args) -> int:
    import numpy as np

    from acl.diagnostics import DiagnosticError
    from acl.fit.synth import Experiment, generate, write_csv
    from acl.units import UnitError

    try:
        noise = _qty(args.noise, "m")
        freqs = tuple(_qty(f, "Hz") for f in args.frequencies.split(",") if f.strip())
        m = re.match(r"^\s*(.+?)\s*\.\.\s*(.+?)\s*:\s*(\d+)\s*$", args.voltages)
        if not m:
            return _usage(f"--voltages {args.voltages!r}: expected LO..HI:N, e.g. 0V..10V:11")
        volts = tuple(np.linspace(_qty(m.group(1), "V"), _qty(m.group(2), "V"), int(m.group(3))))
        interval = _qty(args.interval, "s")
        effects = {}
        for item in args.effect:
            name, _, rest = item.partition("=")
            params = {}
            for part in filter(None, (s.strip() for s in rest.split(","))):
                k, sep, v = part.partition(":")
                if not sep:
                    return _usage(f"--effect {item!r}: parameters are NAME:VALUE, e.g. drive_saturation=v_sat:8V")
                v = re.sub(r"^([0-9.eE+-]+)([A-Za-z\u00b5/])", r"\1 \2", v.strip())
                from acl.fit.data import parse_quantity
                params[k.strip()] = parse_quantity(v)[0]
            effects[name.strip()] = params
        sets = {}
        for item in args.sweep:
            k, sep, vals = item.partition("=")
            if not sep:
                return _usage(f"--sweep {item!r}: expected P=V1,V2,...")
            sets[k.strip()] = [re.sub(r"^([0-9.eE+-]+)([A-Za-z\u00b5])", r"\1 \2", v.strip())
                               for v in vals.split(",") if v.strip()]
    except (ValueError, UnitError) as exc:
        return _usage(str(exc))
    if noise < 0 or args.repeats < 1 or not freqs:
        return _usage("noise must not be negative, repeats at least 1, and one frequency at least")
    if args.schedule:
        if effects or sets:
            return _usage("--schedule plays on the design as declared: declare effects in it (`effect ID { ... }`) "
                          "instead of --effect; --sweep does not apply")
        return _replay(args, noise)
    ex = Experiment(frequencies=freqs, voltages=volts, sets=sets, repeats=args.repeats, interval=interval,
                    observables=tuple(s.strip() for s in args.observe.split(",") if s.strip()))
    try:
        data, _ = generate(args.design, ex, effects, noise=noise, seed=args.seed, search_paths=args.path)
    except DiagnosticError as exc:
        report(exc.diagnostics)
        return exit_code(exc.diagnostics)
    except KeyError as exc:
        return _usage(f"--observe: {exc.args[0]}")
    try:
        write_csv(data, args.output)
    except OSError as exc:
        return _usage(f"cannot write {args.output}: {exc.strerror or exc}")
    from rich.console import Console

    Console(stderr=True, highlight=False).print(f"wrote {data.n} rows to {args.output}")
    return 0


def _replay(args, noise) -> int:
    from rich.console import Console

    from acl.commands._common import load_or_report
    from acl.diagnostics import DiagnosticError
    from acl.fit.synth import read_schedule, replay, write_csv

    console = Console(stderr=True, highlight=False)
    try:
        waypoints, chirps, targets = read_schedule(args.schedule)
    except DiagnosticError as exc:
        report(exc.diagnostics)
        return 2
    design, code = load_or_report(args.design, args)
    if design is None:
        return code
    names = [s.strip() for s in args.observe.split(",") if s.strip()]
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
    try:
        write_csv(data, args.output)
    except OSError as exc:
        return _usage(f"cannot write {args.output}: {exc.strerror or exc}")
    console.print(f"wrote {data.n} rows ({len(waypoints) - lost} waypoints x {len(names or known)} observables) "
                  f"to {args.output}")
    for goal, t in res.tracking.items():
        console.print(f"{goal}: tracking error on {args.design} RMS {t['rms_m'] * 1e6:.4g} um, "
                      f"max {t['max_m'] * 1e6:.4g} um over {t['n']} waypoints (noise-free)"
                      + (f", {t['lost']} lost" if t["lost"] else ""))
    if chirps:
        console.print(f"note: {chirps} sweep segments skipped (a chirp has no static equilibrium)")
    if lost:
        console.print(f"warning: {lost} waypoints have no stable equilibrium on this design (snap-in?): no rows")
    return 0

"""`acl play SCHEDULE.json --resource VISA_ADDRESS [--dry-run]`: play a compiled schedule on a generator.

Thin: read the schedule (acl.bench.schedule), plan the command stream for the declared chain
(acl.bench.plan), print it (--dry-run) or send it with every setting read back (acl.bench.player).
Exit codes: 0 played (or printed); 1 the chain cannot play the schedule; 2 bad input, no instrument,
a read-back that differs, or an interruption (the output is off in every case).  docs/bench.md.
"""
from __future__ import annotations

import sys

from acl.commands._common import report
from acl.diagnostics import DiagnosticError, Span, error


def add_parser(p) -> None:
    from acl.bench.chain import AMPLIFIERS, GENERATORS

    p.add_argument("schedule", metavar="SCHEDULE.json", help="schedule.json written by `acl compile`")
    p.add_argument("--resource", metavar="VISA_ADDRESS",
                   help="the generator's VISA address, e.g. USB0::0x2184::0x0049::GEQ000001::INSTR "
                        "(not needed with --dry-run)")
    p.add_argument("--dry-run", action="store_true", help="print the command stream; no instrument")
    p.add_argument("--instrument", choices=sorted(GENERATORS), default=None,
                   help="the generator (default: from its *IDN? answer; afg2225, the paper's, with --dry-run)")
    p.add_argument("--amplifier", choices=sorted(AMPLIFIERS), default=None,
                   help="the amplifier between generator and transducer (default: the design's `use amplifier`, "
                        "recorded in schedule.json, else hva200, the paper's)")
    p.add_argument("--form", choices=("auto", "sequence", "steps"), default="auto",
                   help="sequence (looped segments, instrument-timed) or steps (one channel per tone, "
                        "host-timed); default: sequence where the generator has it")
    p.add_argument("--visa-library", default="", metavar="LIB",
                   help="PyVISA backend, e.g. @py, or FILE.yaml@sim for a simulated instrument (pyvisa-sim)")


def declared_chain(meta: dict, instrument: str | None, amplifier: str | None):
    """(generator profile key or None, Amplifier) from the options, else the design's declared chain
    (schedule.json ``chain``): its amplifier as declared, its generator's profile by name, capped at
    its declared output."""
    from acl.bench.chain import AMPLIFIERS, Amplifier

    chain = meta.get("chain") or {}
    amp = AMPLIFIERS[amplifier or "hva200"]
    a = chain.get("amplifier")
    if amplifier is None and isinstance(a, dict):
        try:
            amp = Amplifier("declared", f"{a.get('name', 'amplifier')} (declared)", gain=float(a["gain"]),
                            max_output_v=float(a["max_voltage"]),
                            bandwidth_hz=float(a.get("bandwidth") or float("inf")), max_input_v=float("inf"),
                            source="the design's `use amplifier`")
        except (KeyError, TypeError, ValueError):
            pass
    g = chain.get("generator") if isinstance(chain.get("generator"), dict) else {}
    key = instrument
    if key is None and g:
        name = str(g.get("name", "")).lower()
        key = "afg2225" if "afg" in name else "33522b" if ("335" in name or "keysight" in name) else None
    cap = g.get("max_voltage") if g else None
    return key, amp, (float(cap) if isinstance(cap, (int, float)) else None)


def _cap(gen, cap):
    """The generator profile with the declared output limit (peak) if that is lower."""
    import dataclasses

    return gen if cap is None or 2 * cap >= gen.max_vpp else dataclasses.replace(gen, max_vpp=2 * cap)


def _which(idn: str) -> str | None:
    u = idn.upper()
    if ("INSTEK" in u or "GW" in u) and "AFG-22" in u:
        return "afg2225"
    if ("KEYSIGHT" in u or "AGILENT" in u) and "335" in u:
        return "33522b"
    return None


def run(args) -> int:
    from acl.bench import schedule as sched
    from acl.bench.chain import GENERATORS
    from acl.bench.plan import plan

    if not args.dry_run and not args.resource:
        report([error("E-USAGE", "--resource is required (the generator's VISA address), or give --dry-run",
                      Span(file="<--resource>", line=1, column=1))])
        return 2
    try:
        drives, meta = sched.load(args.schedule)
    except DiagnosticError as exc:
        report(exc.diagnostics)
        return 2
    declared_key, amp, cap = declared_chain(meta, args.instrument, args.amplifier)
    form = None if args.form == "auto" else args.form
    if args.dry_run:
        gen = _cap(GENERATORS[declared_key or "afg2225"], cap)
        try:
            p = plan(drives, meta, gen, amp, form)
        except DiagnosticError as exc:
            report(exc.diagnostics)
            return 1
        sys.stdout.write(p.stream())
        return 0
    from acl.bench import player

    try:
        player.check_address(args.resource)
        inst = player.open_resource(args.resource, args.visa_library)
    except DiagnosticError as exc:
        report(exc.diagnostics)
        return 2
    try:
        idn = player.identify(inst)
        key = _which(idn)
        if args.instrument and key and key != args.instrument or not (args.instrument or key):
            raise DiagnosticError([error("E-PLAY-INSTRUMENT", f"the instrument at {args.resource} is {idn[:80]!r}"
                                         + (f", not a {GENERATORS[args.instrument].name}" if args.instrument else
                                            ": not a generator acl knows"), player.WHERE,
                                         "choose --instrument " + " or ".join(sorted(GENERATORS)))])
        gen = _cap(GENERATORS[args.instrument or key], cap)
        try:
            p = plan(drives, meta, gen, amp, form)
        except DiagnosticError as exc:
            report(exc.diagnostics)
            return 1
        if not args.quiet:
            sys.stderr.write(f"acl play: {gen.name} ({idn[:60]}), {p.form}, {p.duration_s:.6g} s\n")
        result = player.play(p, inst)
    except DiagnosticError as exc:
        report(exc.diagnostics)
        return 2
    finally:
        try:
            inst.close()
        except Exception:
            pass
    if not args.quiet:
        sys.stderr.write(f"acl play: done: {len(result.sent)} messages, {len(result.readbacks)} settings read "
                         f"back equal; latest step {result.late_s * 1e3:.3g} ms late\n")
    return 0

"""`acl analyze FILE [--at DRIVE] [--set P=V] [--output-format json] [--plot DIR]`: predictions as tables, JSON, figures."""
from __future__ import annotations

import json
import sys

from acl.commands._common import (add_design_options, add_output_format, load_or_report,
                                  plotting_missing, report)
from acl.diagnostics import DiagnosticError, Span, error

# what a drive that is no program step was analysed for (acl.analysis.report._drive_entry "basis")
_ANALYSIS_DRIVE = {"pairs": "pair analysis",
                   "largest_program_amplitude": "the largest amplitude the programs apply at this frequency",
                   "reference": "the 1 V reference drive (no drive or goal step sets an amplitude at this frequency)"}


def add_parser(p) -> None:
    p.add_argument("file", metavar="FILE", help="design file (.acl), or a folder holding one design")
    p.add_argument("--at", metavar="DRIVE", help='equilibrium under a drive, e.g. --at "125 kHz @ 6 V"')
    add_output_format(p, old=("--json",))
    p.add_argument("--plot", metavar="DIR", help="write PNG figures into DIR")
    p.add_argument("--no-snap", action="store_true", help="skip the snap-in voltage sweeps (faster)")
    p.add_argument("--sign-draws", metavar="N", type=int, default=None,
                   help="draws of the declared uncertainty for each pair's P(other sign) (default 200 when the design "
                        "declares any; 0: none)")
    add_design_options(p)


def run(args) -> int:
    fmt = args.output_format
    as_json = fmt == "json"
    at = None
    if args.at is not None:
        from acl.design.drives import drive_from_text

        try:
            at = drive_from_text(args.at, "<--at>")
        except DiagnosticError as exc:
            report(exc.diagnostics, fmt)
            return 2
    if args.plot is not None and not args.plot.strip():      # "" is no folder, not "no figures"
        report([error("E-USAGE", f"--plot {args.plot!r}: an empty path", Span(file="<--plot>", line=1, column=1),
                      "give a folder, or leave the option out")], fmt)
        return 2
    if args.plot and plotting_missing("--plot", fmt):
        return 2
    design, code = load_or_report(args.file, args, fmt)
    if design is None:
        return code
    if at is not None and design.transducer is not None:
        lo, hi = design.transducer.band
        bad = [t for t in at.tones if not lo <= t.frequency <= hi] + [t for t in at.tones if t.amplitude > design.transducer.max_voltage]
        if bad:
            report([error("E501", f"--at {args.at}: outside transducer `{design.transducer.name}` "
                          f"({lo / 1e3:g}..{hi / 1e3:g} kHz, max {design.transducer.max_voltage:g} V)",
                          Span(file="<--at>", line=1, column=1))], fmt)
            return 2
    from acl.analysis.report import analyze

    if as_json or args.quiet:
        rep = analyze(design, at, snap_in=not args.no_snap)
    elif args.verbose:
        import time

        t0 = time.perf_counter()
        rep = analyze(design, at, snap_in=not args.no_snap,
                      progress=lambda m: sys.stderr.write(f"[{time.perf_counter() - t0:7.2f} s] {m}\n"))
    else:
        from acl._console import make_console

        con = make_console(stderr=True)
        with con.status("analyzing...") as status:
            rep = analyze(design, at, snap_in=not args.no_snap, progress=lambda m: status.update(m))
    draws = args.sign_draws
    if draws is not None and draws < 0:
        report([error("E-USAGE", f"--sign-draws {draws}: a negative number of draws",
                      Span(file="<--sign-draws>", line=1, column=1), "give 0 (none) or more")], fmt)
        return 2
    from acl.sweep.signs import annotate_pairs

    annotate_pairs(design, rep.pairs, draws)    # P(other sign) under the declared uncertainty (acl.sweep.signs)
    if args.plot:
        from acl.emit.analysis_figures import write_figures

        from acl._files import write_figures_atomically

        try:                      # all the figures or none (a later one failing left the first ones behind)
            written = write_figures_atomically(args.plot, lambda tmp: write_figures(design, rep, tmp))
        except OSError as exc:
            report([error("E601", f"cannot write figures to `{args.plot}`: {exc.strerror or exc}",
                          Span(file="<--plot>", line=1, column=1))], fmt)
            return 2
    if as_json:
        sys.stdout.write(json.dumps(rep.as_dict(), indent=2, default=_json_default) + "\n")
    else:
        print_report(design, rep)
        if args.plot and not args.quiet:
            from acl._console import make_console

            make_console().print(f"wrote {len(written)} figure(s) to {args.plot}")
    return 0 if rep.requires_ok else 1


def _json_default(o):
    import numpy as np

    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o).__name__)


def _k(hz):
    return f"{hz / 1e3:.1f}"


def print_report(design, rep) -> None:
    from acl._console import make_console
    from acl._console import print_table
    from acl._console import table as Table
    from rich.markup import escape

    from acl.physics.ties import first_max_item

    con = make_console(highlight=False)
    for n in rep.notes:
        con.print(f"[yellow]note:[/yellow] {n}")
    t = Table(title="Capsule modes", title_justify="left")
    for col in ("capsule", "mode", "f (kHz)", "Q", "dominant orifice", "share", "declared at"):
        t.add_column(col)
    for c in rep.capsules:
        for i, m in enumerate(c["modes"]):
            qtxt = f"{m['q']:.1f}"
            if m["q_declared"]:
                qtxt += f" (declared; predicted {m['q_predicted']:.1f})" if m.get("q_predicted") else " (declared)"
            t.add_row(c["name"] if i == 0 else "", str(i + 1), _k(m["frequency_hz"]), qtxt, m["dominant_orifice"],
                      f"{m['share']:.0%}", f"{c['file']}:{c['line']}" if i == 0 else "")
    print_table(con, t)
    if rep.selectivity:
        caps = [c["name"] for c in rep.capsules]
        t = Table(title=f"Selectivity: response relative to each capsule's peak (crosstalk >= {30}% flagged)", title_justify="left")
        t.add_column("f (kHz)")
        for c in caps:
            t.add_column(c)
        for f in rep.frequencies_hz:
            row = [_k(f)]
            for c in caps:
                cell = next(s for s in rep.selectivity if s["frequency_hz"] == f and s["capsule"] == c)
                txt = f"{cell['relative_response']:.0%}"
                if cell["target"]:
                    txt = f"[bold green]{txt}[/bold green]"
                elif cell["crosstalk"]:
                    txt = f"[bold red]{txt} crosstalk[/bold red]"
                row.append(txt)
            t.add_row(*row)
        print_table(con, t)
    if rep.coupled_modes:
        t = Table(title="Coupled modes (all bubbles as one system: mutual radiation mass, substrate images)",
                  title_justify="left")
        for col in ("mode", "f (kHz)", "Q", "Q predicted", "interfaces: share (phase)"):
            t.add_column(col)
        for i, m in enumerate(rep.coupled_modes):
            parts = ", ".join(f"{k} {v:.0%}" + (" (anti)" if m["phases_deg"].get(k) else "")
                              for k, v in m["shares"].items() if v >= 0.05)
            t.add_row(str(i + 1), _k(m["frequency_hz"]), f"{m['q']:.1f}", f"{m['q_predicted']:.1f}", parts)
        print_table(con, t)
    nonlinear = [d for d in rep.drives if not d["linear"]]
    for d in nonlinear:
        where = (f"program {d['program']} step {d['step']} (line {d['line']})" if d["program"] else
                 _ANALYSIS_DRIVE.get(d.get("basis"), "analysis drive"))
        worst = first_max_item(d["interface_amplitude_over_radius"])      # ties: the first declared
        past = (" and past the hemisphere (eps/R = 1), where the bubble model has no meaning and `acl compile` refuses"
                if worst[1] > 1.0 else "")
        loc = f"{escape(d['file'])}:{d['line']}:1: " if d.get("file") and d.get("line") else ""   # a step: located
        con.print(f"{loc}[red]warning\\[W-ACOUSTIC-AMPLITUDE]:[/red] {where}: {d['drive']} drives {worst[0]} to eps/R = "
                  f"{worst[1]:.6g}, beyond the linear bubble model (eps/R <= {d['linear_limit']:g}; docs/physics.md){past}")
    if rep.pairs:
        t = Table(title="Bubble pairs (Bjerknes force at rest, attraction positive)", title_justify="left")
        for col in ("pair", "f (kHz)", "V", "force (nN)", "", "phase diff (deg)", "gap (um)", "d_c (um)", "snap-in V",
                    "with predicted Q", "repels from Q", "P(other sign)"):
            t.add_column(col)
        for p in rep.pairs:
            dc = f"{p['critical_distance_m'] * 1e6:.1f}" if p["critical_distance_m"] else "-"
            d1 = p.get("critical_distance_paper_drag_m")       # the other end of the drag law's model form
            if p["critical_distance_m"] and d1 and f"{d1 * 1e6:.1f}" != dc:
                dc += f" ({d1 * 1e6:.1f})"
            sv = f"{p['snap_in_voltage_v']:.2f}" if p["snap_in_voltage_v"] else ("none" if p["sweep_status"] == "ok" else p["sweep_status"])
            t.add_row(f"{p['a']}-{p['b']}", _k(p["frequency_hz"]), f"{p['voltage_v']:g}", f"{p['force_n'] * 1e9:.3g}",
                      "[green]attract[/green]" if p["attract"] else "[magenta]repel[/magenta]",
                      f"{round(p['phase_difference_deg'], 1) + 0.0:.1f}", f"{p['gap_m'] * 1e6:.1f}", dc, sv,
                      {True: "attract", False: "repel", None: "-"}[p.get("attract_with_predicted_q")],
                      f"{p['repel_from_q']:g}" if p.get("repel_from_q") else "-",
                      f"{p['p_other_sign']:.2f}" if p.get("p_other_sign") is not None else "-")
        print_table(con, t)
        for p in rep.pairs:           # located notes: d_c's drag-law interval, signs resting on an implausible Q
            for n in p.get("notes", ()):
                con.print(f"{escape(n['file'])}:{n['line']}:{n['column']}: [yellow]note\\[{n['code']}]:[/yellow] "
                          f"{escape(n['message'])}")      # wrapped at the terminal's width, location first
    for lt in rep.latches:
        t = Table(title=f"Latch {lt['name']} ({lt['file']}:{lt['line']}): "
                        f"{'bistable' if lt['bistable'] else 'MONOSTABLE'}, switching force {lt['switching_force_n'] * 1e9:.3g} nN, "
                        f"state {lt['state']}", title_justify="left")
        for col in ("program", "step", "drive", "margin", "switches", "intended"):
            t.add_column(col)
        for m in lt["margins"]:
            flag = "[red]UNINTENDED[/red]" if m["unintended"] else ("yes" if m["intended"] else "")
            short = m["intended"] and m["required_margin"] and m["margin"] < m["required_margin"]
            t.add_row(m["program"], f"{m['step']} (line {m['line']})", m["drive"],
                      f"[red]{m['margin']:.2f}[/red]" if short else f"{m['margin']:.2f}", "yes" if m["switches"] else "no", flag)
        print_table(con, t)
    if rep.equilibrium:
        e = rep.equilibrium
        t = Table(title=f"Equilibrium at {e['drive']}: {e['status']}", title_justify="left")
        t.add_column("capsule")
        t.add_column("displacement (um)")
        for c in e["capsules"]:
            t.add_row(c["name"], "(" + ", ".join(f"{x * 1e6:.3f}" for x in c["displacement_m"]) + ")")
        for g in e["gaps"]:
            t.add_row(f"gap {g['a']}-{g['b']}", f"{g['gap_m'] * 1e6:.2f}")
        print_table(con, t)
        located = {v["message"] for v in e.get("validity", ())}
        for w in e["warnings"]:
            if w not in located:                # printed below with its code and location
                con.print(f"[yellow]warning:[/yellow] {escape(w)}")
        for v in e.get("validity", ()):       # the limits crossed at this drive (acl.physics.validity), located
            con.print(f"{escape(v['file'])}:{v['line']}:{v['column']}: [yellow]warning\\[{v['code']}]:[/yellow] "
                      f"{escape(v['message'])}", soft_wrap=True)
    if rep.requires:
        t = Table(title="Requirements", title_justify="left")
        for col in ("requirement", "value", "ok", "at"):
            t.add_column(col)
        for r in rep.requires:
            v = r["value"]
            if v is None:
                vs = "n/a"
            elif r["unit"] == "Hz":
                vs = f"{v / 1e3:.2f} kHz"
            elif r["unit"] == "m":
                vs = f"{v * 1e6:.2f} um"
            else:
                vs = f"{v:.3g}"
            t.add_row(r["text"], vs, "[green]ok[/green]" if r["ok"] else "[red]FAILED[/red]", f"{r['file']}:{r['line']}")
        print_table(con, t)

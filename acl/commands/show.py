"""`acl show FILE`: the resolved design as a rich tree, or `--json`."""
from __future__ import annotations

import sys

from acl.commands._common import add_design_options, add_output_format, load_or_report, report


def add_parser(p) -> None:
    p.add_argument("file", metavar="FILE", help="design file (.acl), or a folder holding one design")
    add_output_format(p, old=("--json",))
    p.add_argument("--plot", metavar="PNG|DIR/", help="also draw the design (isometric and three orthographic views) "
                   "into this PNG, or as DIR/<design>.png into a folder (as analyze and compile --plot DIR; "
                   "needs acl[plot])")
    add_design_options(p)


def run(args) -> int:
    import os

    fmt = args.output_format
    # a folder (an existing one, or a path ending in /) takes DESIGN.png, as `analyze --plot DIR` takes its figures
    folder = args.plot if args.plot is not None and (args.plot.endswith(("/", os.sep)) or os.path.isdir(args.plot)) \
        else None
    if args.plot is not None:
        from acl.commands._common import plotting_missing

        if folder is None and not _output_ok(args.plot, args.file, fmt):
            return 2
        if plotting_missing("--plot", fmt):
            return 2
    design, code = load_or_report(args.file, args, fmt)
    if design is None:
        return code
    if folder is not None:
        from acl.diagnostics import Span, error

        try:
            os.makedirs(folder, exist_ok=True)
        except OSError as exc:
            why = "a file of that name exists" if os.path.isfile(folder.rstrip("/" + os.sep)) else exc.strerror or exc
            report([error("E601", f"--plot {folder}: cannot make the folder: {why}",
                          Span(file="<--plot>", line=1, column=1), "give a folder or a .png path")], fmt)
            return 2
        args.plot = os.path.join(folder, os.path.splitext(os.path.basename(design.file))[0] + ".png")
        if not _output_ok(args.plot, args.file, fmt):
            return 2
    if args.plot is not None:
        code = _plot(design, args.plot, fmt)
        if code:
            return code
    if fmt == "json":
        try:
            text = design.model_dump_json(indent=2)
        except ValueError:       # a file name that is not UTF-8 (surrogate escapes): JSON's \u escapes instead
            import json

            text = json.dumps(design.model_dump(mode="json"), indent=2)
        sys.stdout.write(text + "\n")
        return 0
    from acl._console import make_console

    make_console(highlight=False).print(design_tree(design))
    return 0


def _output_ok(path: str, source: str, fmt: str) -> bool:
    """``path`` may take the PNG (acl.export.files.check_output); reported otherwise."""
    from acl.diagnostics import DiagnosticError
    from acl.export.files import check_output

    try:
        check_output(path, "--plot", (".png",), [source])
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        return False
    return True


def _plot(design, path: str, fmt: str) -> int:
    """The design's figure (acl.emit.design_figure) into ``path``, atomically; 0, or 2 on an error."""
    import os
    import tempfile

    from acl._files import as_umask, input_named
    from acl.diagnostics import Span, error
    from acl.emit.design_figure import plot_design

    hit = input_named(path, [*design.sources, design.file])
    if hit:
        report([error("E-USAGE", f"--plot {path}: names the input {hit}; writing would destroy it",
                      Span(file="<--plot>", line=1, column=1), "give another path")], fmt)
        return 2
    fd, tmp = tempfile.mkstemp(prefix=".acl-show-", suffix=".tmp", dir=os.path.dirname(os.path.abspath(path)))
    os.close(fd)
    try:
        plot_design(design, tmp)
        as_umask(tmp, directory=False)
        os.replace(tmp, path)
    except OSError as exc:
        report([error("E601", f"cannot write `{path}`: {exc.strerror or exc}", Span(file="<--plot>", line=1, column=1))], fmt)
        return 2
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return 0


def _fmt(v: float, unit: str) -> str:
    from acl.units import format_si

    return format_si(v, unit)


def _spread(p) -> str:
    """``normal(0, 150 nm)``, ``uniform(-0.5 um, 0.5 um)``, ``3 %`` (docs/sweep.md, section 2)."""
    sp = p.spread
    if sp.relative:
        if sp.kind == "normal" and sp.a == 0:
            return f"{sp.b * 100:g} %"
        return f"{sp.kind}({sp.a * 100:g} %, {sp.b * 100:g} %)"
    return f"{sp.kind}({_fmt(sp.a, p.unit) if sp.a else 0}, {_fmt(sp.b, p.unit)})"


def design_tree(design):
    from rich.tree import Tree

    t = Tree(f"[bold]{design.file}[/bold]: {design.summary()}")
    if design.params:
        n = t.add("params")
        for p in design.params:
            free = f" [cyan]free[/cyan] in {_fmt(p.lower, p.unit)} .. {_fmt(p.upper, p.unit)}" if p.free and p.lower is not None else (" [cyan]free[/cyan]" if p.free else "")
            sd = f" +- {_spread(p)}" if p.spread is not None else (f" +- {_fmt(p.stddev, p.unit)}" if p.stddev else "")
            n.add(f"{p.name} = {_fmt(p.value, p.unit)}{sd}{free}")
    if design.medium:
        m = design.medium
        t.add(f"medium [bold]{m.name}[/bold]: rho {m.density:g} kg/m^3, sigma {_fmt(m.surface_tension, 'N/m')}, "
              f"p0 {_fmt(m.ambient_pressure, 'Pa')}, kappa {m.polytropic_index:g}")
    if design.transducer:
        tr = design.transducer
        t.add(f"transducer [bold]{tr.name}[/bold]: {_fmt(tr.band[0], 'Hz')} .. {_fmt(tr.band[1], 'Hz')}, "
              f"max {tr.max_voltage:g} V, {len(tr.gain_frequencies)}-point gain table")
    for c in design.capsules:
        n = t.add(f"capsule [bold]{c.name}[/bold] ({c.cavity.shape}, V = {c.cavity.volume * 1e18:.4g} um^3) at {_pt(c.center)}")
        for o in c.orifices:
            n.add(f"orifice {o.name}: R = {o.radius * 1e6:.4g} um, normal {_dir(o.normal)}, centre {_pt(o.center)}")
    for b in design.beams:
        s = b.section
        sec = f"circle({s.diameter * 1e6:.3g} um)" if s.shape == "circle" else f"rect({s.width * 1e6:.3g} um, {s.thickness * 1e6:.3g} um)"
        t.add(f"beam [bold]{b.name}[/bold]: L = {b.length * 1e6:.4g} um, {sec}, E = {_fmt(b.youngs_modulus, 'Pa')}, "
              f"clamp {_pt(b.clamp)} -> tip {_pt(b.tip)}, rigid l = {b.rigid_length * 1e6:.3g} um")
    for s in design.springs:
        t.add(f"spring [bold]{s.name}[/bold]: k = {_fmt(s.stiffness, 'N/m')} along {_dir(s.axis)}")
    for l in design.latches:
        t.add(f"latch [bold]{l.name}[/bold]: theta = {l.angle * 57.29577951:.3g} deg, L = {l.length * 1e6:.3g} um, "
              f"w = {l.width * 1e6:.3g} um, t = {l.thickness * 1e6:.3g} um, state {l.state}")
    for a in design.anchors:
        t.add(f"anchor [bold]{a.name}[/bold] at {_pt(a.position)}")
    if design.joints:
        n = t.add("joints")
        for j in design.joints:
            if j.kind == "mount":
                n.add(f"mount {j.capsule} on {j.target} ({j.target_kind})")
            elif j.kind == "fix":
                n.add(f"fix {j.capsule}")
            else:
                n.add(f"link {j.a} to {j.b} with {j.element_kind} {j.element}")
    for o in design.observes:
        t.add(f"observe [bold]{o.name}[/bold]: {o.kind}({', '.join(x for x in (o.target, o.a, o.b, o.component) if x)})")
    for r in design.requires:
        t.add(source_text(r.text))
    for p in design.programs:
        n = t.add(f"program [bold]{p.name}[/bold] ({len(p.steps)} steps)")
        for s in p.steps:
            n.add(_step(s))
    return t


def source_text(code: str):
    """A line of acl source as rich Text, coloured by acl's Pygments lexer when pygments is there
    (rich writes the colours only to a terminal)."""
    from rich.text import Text

    try:
        from rich.syntax import Syntax

        from acl.editor.pygments_lexer import AclLexer
    except ImportError:   # pygments is optional (acl[highlight])
        return Text(code)
    text = Syntax(code, AclLexer(), theme="ansi_dark", background_color="default").highlight(code)
    text.rstrip()
    return text


def _step(s) -> str:
    if s.kind == "drive":
        tones = " + ".join(f"{t.frequency / 1e3:g} kHz @ {t.amplitude:g} V" for t in s.drive.tones)
        return f"drive {tones} for {s.duration * 1e3:g} ms"
    if s.kind == "sweep":
        return f"sweep {s.f_start / 1e3:g} -> {s.f_stop / 1e3:g} kHz @ {s.amplitude:g} V in {s.duration:g} s"
    if s.kind == "pause":
        return f"pause {s.duration * 1e3:g} ms"
    if s.kind == "follow":
        return f"follow {s.capsule} along {s.path.shape}" + (f" in {s.duration:g} s" if s.duration else f" at {s.speed * 1e6:g} um/s")
    if s.kind == "switch":
        return f"switch {s.latch} to {s.state} (margin {s.margin:g})"
    return f"{'hold' if s.mode == 'above' else 'cross'} gap({s.a}, {s.b}) for {s.duration:g} s"


def _pt(p) -> str:
    return "(" + ", ".join(f"{x * 1e6:.4g}" for x in p) + ") um"


def _dir(d) -> str:
    names = {(1, 0, 0): "+x", (-1, 0, 0): "-x", (0, 1, 0): "+y", (0, -1, 0): "-y", (0, 0, 1): "+z", (0, 0, -1): "-z"}
    key = tuple(int(round(x)) if abs(abs(x) - round(abs(x))) < 1e-9 else None for x in d)
    return names.get(key, "(" + ", ".join(f"{x:.3g}" for x in d) + ")")

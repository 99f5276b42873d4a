"""`acl export DESIGN -o PATH`: the printable solid of a design (.stl, .3mf, .obj), checked against it.

docs/export.md.  Needs the `cad` extra (manifold3d, trimesh); `--preview` the `plot` extra too.
"""
from __future__ import annotations

import itertools
import json
import os
import sys

from acl.commands._common import add_design_options, add_output_format, load_or_report, plotting_missing, report
from acl.diagnostics import DiagnosticError, Span, error

SUFFIXES = (".stl", ".3mf", ".obj")


def add_parser(p) -> None:
    p.add_argument("file", metavar="DESIGN", help="design file (.acl), or a folder holding one design")
    p.add_argument("-o", "--output", required=True, metavar="PATH",
                   help="print file; the format by its suffix: .stl (binary), .3mf, .obj")
    p.add_argument("--unit", choices=("um", "mm", "m"), default="um",
                   help="length unit of the file (default um, what two-photon slicers expect)")
    p.add_argument("--preview", metavar="PNG", help="also render the exported solid to this PNG (needs acl[plot])")
    p.add_argument("--vary", action="append", default=[], metavar="NAME=LO..HI:N",
                   help="print variants: one file per value (repeatable: the grid of all), named by the values, "
                        "and an arrangement file placing them on one substrate")
    add_output_format(p)
    add_design_options(p)


def cad_missing(fmt: str) -> bool:
    """Report E-EXPORT-CAD and return True when manifold3d or trimesh (the `cad` extra) cannot be imported."""
    missing = []
    for name in ("manifold3d", "trimesh"):
        try:
            __import__(name)
        except Exception as exc:          # not installed, or a broken installation
            missing.append(f"{name} ({'not installed' if isinstance(exc, ModuleNotFoundError) else type(exc).__name__})")
    if missing:
        report([error("E-EXPORT-CAD", f"acl export builds solids with manifold3d and trimesh: {', '.join(missing)}",
                      Span(file="<export>", line=1, column=1),
                      "install the cad extra: pip install 'acl[cad]' (from a checkout: pip install '.[cad]')")], fmt)
    return bool(missing)


def _variants(design, texts, sets: dict) -> list[tuple[dict, dict]]:
    """[(values {name: (SI, unit)}, overrides {name: text})] of the --vary grid (one entry without it)."""
    if not texts:
        return [({}, dict(sets))]
    from acl.sweep.spec import parse_vary

    axes = [parse_vary(t, design) for t in texts]
    names = [a.name for a in axes]
    if len(set(names)) != len(names):
        raise DiagnosticError([error("E-USAGE", "--vary names a parameter twice", Span(file="<--vary>", line=1, column=1))])
    clash = [n for n in names if n in sets]
    if clash:
        raise DiagnosticError([error("E-USAGE", f"--vary {clash[0]} and --set {clash[0]}: give a parameter one of them",
                                     Span(file="<--vary>", line=1, column=1))])
    grid = list(itertools.product(*[list(a.values) for a in axes]))
    if len(grid) > 1000:
        raise DiagnosticError([error("E-USAGE", f"--vary asks for {len(grid)} print files; acl export writes at most 1000",
                                     Span(file="<--vary>", line=1, column=1), "use fewer points")])
    out = []
    for combo in grid:
        values = {a.name: (float(v), a.unit) for a, v in zip(axes, combo)}
        over = dict(sets)
        over.update({n: f"{v!r} {u}".strip() for n, (v, u) in values.items()})
        out.append((values, over))
    return out


def run(args) -> int:
    fmt = args.output_format
    from acl.export import files as F

    try:
        F.check_output(args.output, "--output", SUFFIXES, [args.file])
        if args.preview is not None:
            F.check_output(args.preview, "--preview", (".png",), [args.file])
            if os.path.abspath(args.preview) == os.path.abspath(args.output):
                raise DiagnosticError([error("E-USAGE", "--preview names the --output file", Span(file="<--preview>", line=1, column=1))])
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        return 2
    if cad_missing(fmt) or (args.preview and plotting_missing("--preview", fmt)):
        return 2
    design, code = load_or_report(args.file, args, fmt)
    if design is None:
        return code
    from acl._files import input_named
    from acl.commands._common import parse_sets

    inputs = [*design.sources, design.file]
    for option, path in (("--output", args.output), ("--preview", args.preview)):
        hit = input_named(path, inputs) if path else None
        if hit:
            report([error("E-USAGE", f"{option} {path}: names the input {hit}; writing would destroy it",
                          Span(file=f"<{option}>", line=1, column=1), "give another path")], fmt)
            return 2
    sets, _ = parse_sets(args.set or [])
    try:
        variants = _variants(design, args.vary, sets)
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        return 2
    try:
        return _export(args, design, variants, fmt)
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        from acl.commands._common import exit_code

        return max(exit_code(exc.diagnostics), 1)


def _export(args, design, variants, fmt) -> int:
    import io

    import trimesh

    from acl.design.resolve import load_design
    from acl.export import files as F
    from acl.export.arrange import arrangement, equivalent_radius, variant_label
    from acl.export.measure import check, part_checks
    from acl.export.solid import build

    suffix = os.path.splitext(args.output)[1].lower()
    kind = F.FORMATS[suffix]
    stem = os.path.splitext(args.output)[0]
    scale = F.UNITS[args.unit]
    results, diags, staged = [], [], []
    try:
        for values, overrides in variants:
            d = design if not values else load_design(args.file if not os.path.isdir(args.file) else design.file,
                                                      overrides=overrides, search_paths=args.path or [])
            b = build(d)
            diags.extend(b.diagnostics)
            meshes = F.meshes(b.parts, args.unit)
            data = F.encode(meshes, [p.name for p in b.parts], kind, args.unit)
            back = trimesh.load(io.BytesIO(data), file_type=kind, force=None)
            back_parts = list(back.geometry.values()) if isinstance(back, trimesh.Scene) else list(back.split(only_watertight=False))
            for m in back_parts:
                m.apply_scale(1.0 / scale)
            label = variant_label(values)
            target = args.output if not values else f"{stem}-{label}{suffix}"
            bad = [i for i, m in enumerate(back_parts) if not m.is_volume]
            if bad or len(back_parts) != len(b.parts):
                diags.append(error("E-EXPORT-SOLID", f"{target}: {len(bad) or 'some'} part(s) of {len(b.parts)} do not read "
                                   "back as closed, consistently oriented volumes", Span(file=d.file, line=1, column=1)))
            measurements, mdiags = check(d, trimesh.util.concatenate(back_parts), b.latch_beams)
            diags.extend(mdiags)
            diags.extend(part_checks(d, b.parts))
            lo = [min(m.bounds[0][k] for m in back_parts) for k in range(2)]
            hi = [max(m.bounds[1][k] for m in back_parts) for k in range(2)]
            results.append({"file": target, "values": {n: v for n, (v, _) in values.items()},
                            "units": {n: u for n, (_, u) in values.items()},
                            "parts": [{"name": p.name, "elements": sorted(set(p.elements)), "triangles": len(m.faces),
                                       "volume": float(m.volume) * scale ** 3} for p, m in zip(b.parts, meshes)],
                            "measurements": [x.as_dict() for x in measurements],
                            "bounds": (lo, hi), "bubble": max((equivalent_radius(c.cavity.volume) for c in d.capsules), default=0.0),
                            "_data": data, "_meshes": meshes})
        if any(x.is_error for x in diags):
            report(diags, fmt)
            return 1
        if len(results) > 1:          # the names the variants make must be writable as -o is
            inputs = [*design.sources, design.file]
            for target in [r["file"] for r in results] + [f"{stem}-array{suffix}"]:
                F.check_output(target, "--output", SUFFIXES, inputs)
            F.check_output(f"{stem}-arrangement.json", "--output", (".json",), inputs)
        for r in results:
            staged.append((F.stage(r["file"], r.pop("_data")), r["file"]))
        arr = None
        if len(results) > 1:
            arr = arrangement([{"bounds": r["bounds"], "bubble": r["bubble"]} for r in results], scale)
            for r, off in zip(results, arr["offsets"]):
                r["offset"] = off
            array_meshes = []
            for r in results:
                for m in r["_meshes"]:
                    mm = m.copy()
                    mm.apply_translation([r["offset"][0], r["offset"][1], 0.0])
                    mm.metadata["name"] = f"{os.path.basename(r['file'])}:{m.metadata.get('name', '')}"
                    array_meshes.append(mm)
            arr_file = f"{stem}-array{suffix}"
            staged.append((F.stage(arr_file, F.encode(array_meshes, [m.metadata["name"] for m in array_meshes], kind, args.unit)), arr_file))
            layout = {"generator": "acl export", "design": design.file, "unit": args.unit, "array": arr_file,
                      **{k: v for k, v in arr.items() if k != "offsets"},
                      "variants": [{"file": r["file"], "values": r["values"], "value_units": r["units"], "offset": r["offset"]}
                                   for r in results]}
            arr_json = f"{stem}-arrangement.json"
            staged.append((F.stage(arr_json, (json.dumps(layout, indent=2) + "\n").encode()), arr_json))
        if args.preview:
            from acl.export.preview import render

            import tempfile

            fd, tmp = tempfile.mkstemp(prefix=".acl-export-", suffix=".tmp", dir=os.path.dirname(os.path.abspath(args.preview)))
            os.close(fd)
            staged.append((tmp, args.preview))
            shown = results[0]["_meshes"] if len(results) == 1 else array_meshes
            render(shown, tmp, title=f"{os.path.basename(design.file)} -> {os.path.basename(args.output)}", unit=args.unit)
            from acl._files import as_umask

            as_umask(tmp, directory=False)
        F.publish(staged)
        staged = []
    except OSError as exc:
        F.discard(staged)
        report([error("E601", f"cannot write `{args.output}`: {exc.strerror or exc}", Span(file="<--output>", line=1, column=1))], fmt)
        return 2
    except BaseException:
        F.discard(staged)
        raise
    for r in results:
        r.pop("_meshes", None)
        r.pop("bounds", None)
        r.pop("bubble", None)
    if fmt == "json":
        out = {"design": design.file, "output": args.output, "unit": args.unit, "files": results,
               "diagnostics": [x.as_dict() for x in diags]}
        if len(results) > 1:
            out["arrangement"] = f"{stem}-arrangement.json"
        if args.preview:
            out["preview"] = args.preview
        sys.stdout.write(json.dumps(out, indent=2) + "\n")
        return 0
    if diags:
        report(diags, fmt)
    if not args.quiet:
        _print(results, args, len(results) > 1 and f"{stem}-arrangement.json")
    return 0


def _small(x: float) -> str:
    """An error as one significant digit, or `below 0.001` (rounding noise is not a figure)."""
    return "below 0.001" if x < 1e-3 else f"within {x:.1g}"


def _print(results, args, arrangement_file) -> None:
    for r in results:
        ms = r["measurements"]
        worst = {}
        for m in ms:
            if m["measured"] is None:
                continue
            rel = m["unit"] != "um" or m["quantity"] == "orifice radius"
            err = abs(m["measured"] - m["declared"]) / m["declared"] * 100 if rel else abs(m["measured"] - m["declared"])
            key = m["quantity"]
            for old in ("beam diameter", "beam width", "beam thickness"):
                key = key.replace(old, "beam section")
            worst[key] = max(worst.get(key, 0.0), err)
        checks = ", ".join(f"{k} {_small(v)} {'%' if k in ('cavity volume', 'orifice radius') else 'um'}"
                           for k, v in worst.items())
        tris = sum(p["triangles"] for p in r["parts"])
        sys.stdout.write(f"wrote {r['file']}: {len(r['parts'])} part{'s' * (len(r['parts']) != 1)}, {tris:,} triangles, "
                         f"in {args.unit}" + (f"; measured on the file: {checks}" if checks else "") + "\n")
    if arrangement_file:
        sys.stdout.write(f"wrote {arrangement_file} and the array of all variants on one substrate\n")
    if args.preview:
        sys.stdout.write(f"wrote {args.preview}\n")

"""`acl check FILE...`: parse and type-check designs. Never imports scipy, cvxpy or matplotlib."""
from __future__ import annotations

import json
import sys

from acl.commands._common import (STDIN, add_design_options, add_output_format, add_stdin_option, check_paths,
                                  design_files, exit_code, parse_sets, read_stdin, report)


def add_parser(p) -> None:
    p.add_argument("files", nargs="+", metavar="PATH",
                   help="design files (.acl) or folders (searched for *.acl); `-` reads standard input")
    add_stdin_option(p)
    add_output_format(p, old=("--format",))
    add_design_options(p)


def run(args) -> int:
    from acl.design.resolve import check_design

    fmt = args.output_format
    overrides, diags = parse_sets(args.set)
    diags += check_paths(args.path)
    files = design_files(args.files)
    if diags:
        report(diags, fmt)
        return 2
    all_diags = []
    ok_files = []
    worst = 0
    sources: dict[str, str] = {}
    for f in files:
        if f == STDIN:
            f = args.stdin_filename
            text, diags = read_stdin(f)
            if text is not None:
                sources[f] = text
                design, diags = check_design(f, overrides=overrides, search_paths=args.path, text=text)
            else:
                design = None
        else:
            design, diags = check_design(f, overrides=overrides, search_paths=args.path)
        all_diags.extend(diags)
        worst = max(worst, exit_code(diags))
        if design is not None:
            ok_files.append((f, design))
    if fmt == "json":
        sys.stdout.write(json.dumps({"files": [args.stdin_filename if f == STDIN else f for f in files],
                                     "ok": worst == 0,
                                     "diagnostics": [d.as_dict() for d in all_diags]}, indent=2) + "\n")
        return worst
    if all_diags:
        report(all_diags, sources=sources)
    from acl._console import make_console

    con = make_console(stderr=True, highlight=False)
    if args.quiet:
        return worst
    for f, design in ok_files:
        con.print(f"[green]ok[/green] {f}: {design.summary()}")
    n_err = sum(d.is_error for d in all_diags)
    n_warn = len(all_diags) - n_err
    if not files:
        con.print(f"no .acl files under {', '.join(args.files)}")
    if n_err or n_warn:
        con.print(f"{n_err} error(s), {n_warn} warning(s)")
    return worst

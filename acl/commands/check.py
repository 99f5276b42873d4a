"""`acl check FILE...`: parse and type-check designs. Never imports scipy, cvxpy or matplotlib."""
from __future__ import annotations

import json
import sys

from acl.commands._common import (STDIN, add_design_options, add_stdin_option, check_paths, exit_code, parse_sets,
                                  read_stdin, report)


def add_parser(p) -> None:
    p.add_argument("files", nargs="+", metavar="FILE", help="design files (.acl); `-` reads standard input")
    add_stdin_option(p)
    p.add_argument("--format", choices=["text", "json"], default="text", help="diagnostics as text (default) or JSON")
    add_design_options(p)


def run(args) -> int:
    from acl.design.resolve import check_design

    overrides, diags = parse_sets(args.set)
    diags += check_paths(args.path)
    if diags:
        report(diags, args.format)
        return 2
    all_diags = []
    worst = 0
    ok_files = []
    sources: dict[str, str] = {}
    for f in args.files:
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
    if args.format == "json":
        sys.stdout.write(json.dumps({"files": [args.stdin_filename if f == STDIN else f for f in args.files], "ok": worst == 0,
                                     "diagnostics": [d.as_dict() for d in all_diags]}, indent=2) + "\n")
        return worst
    if all_diags:
        report(all_diags, sources=sources)
    from rich.console import Console

    con = Console(stderr=True, highlight=False)
    for f, design in ok_files:
        con.print(f"[green]ok[/green] {f}: {design.summary()}")
    n_err = sum(d.is_error for d in all_diags)
    n_warn = len(all_diags) - n_err
    if n_err or n_warn:
        con.print(f"{n_err} error(s), {n_warn} warning(s)")
    return worst

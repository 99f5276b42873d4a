"""`acl lint PATH...`: design rules for CI (codes, configuration, machine-readable output).

Exit codes: 0 clean (warnings allowed), 1 findings at error severity (including designs that do
not resolve), 2 usage or configuration error.  Never imports cvxpy or matplotlib.
"""
from __future__ import annotations

import sys

from acl.commands._common import (STDIN, add_design_options, add_output_format, add_stdin_option, add_verbosity,
                                  in_option, parse_sets, read_stdin)
from acl.diagnostics import Span, error

FORMATS = ("full", "concise", "json", "sarif", "github", "junit", "text")   # text: the same as full


def add_parser(p) -> None:
    p.add_argument("paths", nargs="*", default=["."], metavar="PATH",
                   help="design files or folders (folders are searched for *.acl); `-` reads standard input; default: .")
    add_stdin_option(p)
    add_output_format(p, choices=FORMATS, default="full", old=("--format",))
    p.add_argument("--select", action="append", default=[], metavar="CODES",
                   help="only these rules: codes or prefixes, comma-separated (replaces the configuration's)")
    p.add_argument("--ignore", action="append", default=[], metavar="CODES",
                   help="also skip these rules: codes or prefixes, comma-separated")
    p.add_argument("--config", metavar="PATH", help="acl.toml or pyproject.toml to use (default: found by walking up)")
    p.add_argument("--statistics", action="store_true", help="print the number of findings per rule")
    p.add_argument("--list-rules", action="store_true", help="list every rule and exit")
    p.add_argument("--mechanics", action="store_true",
                   help="confirm snap-in (ACL201) and evaluate `require gap` (ACL603) with the quasi-static "
                        "equilibrium (about a second per drive)")
    add_verbosity(p)   # -v: say which rules could not run and time each one
    add_design_options(p)


def _fail(diags) -> int:
    from acl._console import make_console

    from acl.diagnostics import render

    render(diags, make_console(stderr=True, highlight=False, soft_wrap=True))
    return 2


def _codes(items: list[str], flag: str, rules) -> tuple[tuple[str, ...], list]:
    from acl.lint.config import CHECK_CODE
    from acl.lint.registry import match_codes

    out, diags = [], []
    for item in items:
        if flag == "--select" and not any(c.strip() for c in item.split(",")):
            # `--select ""` (an empty CI variable) selected no rule: "All checks passed", exit 0, nothing checked
            diags.append(error("E-USAGE", f"{flag} {item!r}: no rule codes, so no rule would run",
                               Span(file=f"<{flag}>", line=1, column=1),
                               "give codes or prefixes (e.g. ACL1,ACL201), ALL, or leave the option out"))
        for code in filter(None, (c.strip() for c in item.split(","))):
            if flag == "--ignore" and CHECK_CODE.match(code.upper()):
                out.append(code.upper())
                continue
            found = match_codes(code, rules)
            if not found:
                from acl.diagnostics import suggest

                diags.append(error("E-USAGE", f"{flag}: unknown rule code `{code}`", Span(file=f"<{flag}>", line=1, column=1),
                                   suggest(code.upper(), rules) or "see `acl lint --list-rules`"))
            out.extend(found)
    return tuple(dict.fromkeys(out)), diags


def run(args) -> int:
    from acl.lint import ConfigError, collect_files, find_config, lint_file, load_config, load_rules
    from acl.lint.formats import WRITERS, statistics

    rules = load_rules()
    if args.list_rules:
        for code, r in sorted(rules.items()):
            sys.stdout.write(f"{code}  {r.name:<26} {r.severity.value:<8} {r.summary}\n")
        return 0
    overrides, diags = parse_sets(args.set)
    select, d1 = _codes(args.select, "--select", rules)
    ignore, d2 = _codes(args.ignore, "--ignore", rules)
    if args.config is not None and not args.config.strip():   # "" fell back to the configuration found by search
        diags.append(error("E-USAGE", f"--config {args.config!r}: an empty path", Span(file="<--config>", line=1, column=1),
                           "give a path, or leave the option out (the configuration is then found by walking up)"))
    if diags or d1 or d2:
        return _fail(diags + d1 + d2)
    stdin_text = None
    if STDIN in args.paths:
        stdin_text, d3 = read_stdin(args.stdin_filename)
        if d3:
            return _fail(d3)
    files, missing = collect_files([p for p in args.paths if p != STDIN])
    if stdin_text is not None:
        files.insert(args.paths.index(STDIN), STDIN)
    if missing:
        return _fail([error("E-USAGE", f"no such file or folder: `{m}`", Span(file=m, line=1, column=1)) for m in missing])
    configs: dict[str | None, object] = {}

    def config_for(path: str):
        where = args.config if args.config else find_config(path)
        if where not in configs:
            cfg = load_config(where, rules)
            if args.select:
                cfg.select = select
            cfg.ignore = tuple(dict.fromkeys(cfg.ignore + ignore))
            cfg.mechanics = cfg.mechanics or args.mechanics
            configs[where] = cfg
        return configs[where]

    reports = []
    try:
        if args.config:
            config_for(args.config)
        for f in files:
            if f == STDIN:
                name = args.stdin_filename
                reports.append(lint_file(name, config_for(name), overrides, args.path, verbose=args.verbose, text=stdin_text))
            else:
                reports.append(lint_file(f, config_for(f), overrides, args.path, verbose=args.verbose))
    except ConfigError as exc:
        return _fail(exc.diagnostics)
    if not files:
        sys.stderr.write(f"acl lint: no .acl files under {', '.join(args.paths)}\n")
    fmt = "full" if args.output_format == "text" else args.output_format
    WRITERS[fmt](reports, sys.stdout, **({"summary": False} if args.quiet and fmt in ("full", "concise") else {}))
    if args.statistics and reports:
        sys.stdout.write(statistics(reports) + "\n") if fmt in ("full", "concise") else \
            sys.stderr.write(statistics(reports) + "\n")
    if args.verbose:
        for r in reports:
            sys.stderr.write(f"{r.path}: {r.seconds * 1e3:.1f} ms\n")
            for n in r.notes:
                sys.stderr.write(f"  {n}\n")
    if any(r.unreadable for r in reports) or any(in_option(d) for r in reports for d in r.findings):
        return 2     # an unreadable file, or a bad --set value (`<--set>:1:1`): usage or I/O, as every command
    return 1 if any(d.is_error for r in reports for d in r.findings) else 0

"""`acl fmt [--check|--diff] PATHS|-`: rewrite designs in the canonical layout (acl.fmt)."""
from __future__ import annotations

import sys

from acl.commands._common import STDIN, add_stdin_option, design_files, exit_code, read_stdin, report
from acl.diagnostics import DiagnosticError, Span, error


def add_parser(p) -> None:
    p.add_argument("paths", nargs="+", metavar="PATH",
                   help="design files, folders (every .acl file below them), or - to read stdin and write stdout")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--check", action="store_true",
                      help="write nothing; print a diff and exit 1 if any file is not formatted (for CI)")
    mode.add_argument("--diff", action="store_true", help="write nothing; print a diff of the changes")
    add_stdin_option(p)


def run(args) -> int:
    from acl.fmt import format_file, format_source
    from acl.fmt.diff import unified_diff

    files = design_files(args.paths)
    diags, sources = [], {}
    changed = unchanged = 0
    for path in files:
        name = args.stdin_filename if path == STDIN else path
        try:
            if path == STDIN:
                text, bad = read_stdin(name)
                if text is None:
                    diags.extend(bad)
                    continue
                sources[name] = text
                new = format_source(text, name)
            else:
                text, new = format_file(path)
        except DiagnosticError as exc:
            diags.extend(exc.diagnostics)
            continue
        if new == text:
            unchanged += 1
        else:
            changed += 1
        if args.check or args.diff:
            sys.stdout.writelines(unified_diff(text.splitlines(keepends=True), new.splitlines(keepends=True),
                                                       f"{name} (original)", f"{name} (formatted)"))
        elif path == STDIN:
            sys.stdout.write(new)
        elif new != text:
            from acl.emit.atomic import write_text_atomic

            try:
                write_text_atomic(path, new)
            except OSError as exc:
                diags.append(error("E601", f"cannot write `{path}`: {exc.strerror or exc}", Span(file=path, line=1, column=1)))
                changed -= 1
    if diags:
        report(diags, sources=sources)
    if not args.quiet and files != [STDIN]:
        verb = "would be reformatted" if args.check or args.diff else "reformatted"
        failed = len({d.span.file for d in diags if d.span})
        sys.stderr.write(f"{changed} file(s) {verb}, {unchanged} unchanged" + (f", {failed} with errors" if failed else "")
                         + ("" if files else f" (no .acl files under {', '.join(args.paths)})") + "\n")
    code = exit_code(diags) if diags else 0
    if args.check and changed:
        code = max(code, 1)
    return code

"""`acl fmt [--check|--diff] PATHS|-`: rewrite designs in the canonical layout (acl.fmt)."""
from __future__ import annotations

import difflib
import os
import sys

from acl.commands._common import exit_code, report
from acl.diagnostics import DiagnosticError, Span, error


def add_parser(p) -> None:
    p.add_argument("paths", nargs="+", metavar="PATH",
                   help="design files, folders (every .acl file below them), or - to read stdin and write stdout")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--check", action="store_true",
                      help="write nothing; print a diff and exit 1 if any file is not formatted (for CI)")
    mode.add_argument("--diff", action="store_true", help="write nothing; print a diff of the changes")


def run(args) -> int:
    files, diags = _collect(args.paths)
    changed = unchanged = 0
    for path in files:
        try:
            if path == "-":
                text = _read_stdin()
                new = _format(text, "<stdin>")
            else:
                from acl.fmt import format_file

                text, new = format_file(path)
        except DiagnosticError as exc:
            diags.extend(exc.diagnostics)
            continue
        if new == text:
            unchanged += 1
            if path == "-" and not (args.check or args.diff):
                sys.stdout.write(new)
            continue
        changed += 1
        if args.check or args.diff:
            name = "<stdin>" if path == "-" else path
            sys.stdout.writelines(difflib.unified_diff(text.splitlines(keepends=True), new.splitlines(keepends=True),
                                                       f"{name} (original)", f"{name} (formatted)"))
        elif path == "-":
            sys.stdout.write(new)
        else:
            from acl.emit.atomic import write_text_atomic

            try:
                write_text_atomic(path, new)
            except OSError as exc:
                diags.append(error("E601", f"cannot write `{path}`: {exc.strerror or exc}", Span(file=path, line=1, column=1)))
                changed -= 1
    if diags:
        report(diags)
    if "-" not in files or len(files) > 1:
        verb = "would be reformatted" if args.check or args.diff else "reformatted"
        sys.stderr.write(f"{changed} file(s) {verb}, {unchanged} unchanged"
                         + (f", {len({d.span.file for d in diags if d.span})} with errors" if diags else "") + "\n")
    code = exit_code(diags) if diags else 0
    if args.check and changed:
        code = max(code, 1)
    return code


def _format(text: str, name: str) -> str:
    from acl.fmt import format_source

    return format_source(text, name)


def _read_stdin() -> str:
    raw = sys.stdin.buffer.read() if hasattr(sys.stdin, "buffer") else sys.stdin.read().encode("utf-8")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DiagnosticError([error("E103", f"cannot read `<stdin>`: not UTF-8 text (byte {exc.start})",
                                     Span(file="<stdin>", line=1, column=1))]) from None


def _collect(paths: list[str]):
    """Files to format: given files as they are, folders searched for .acl files (hidden ones skipped)."""
    files, diags = [], []
    for p in paths:
        if p == "-":
            files.append(p)
        elif os.path.isdir(p):
            found = []
            for root, dirs, names in os.walk(p):
                dirs[:] = sorted(d for d in dirs if not d.startswith("."))
                found += [os.path.join(root, n) for n in sorted(names) if n.endswith(".acl")]
            files += found
        elif os.path.exists(p):
            files.append(p)
        else:
            diags.append(error("E601", f"cannot read `{p}`: no such file or folder", Span(file=p, line=1, column=1)))
    return files, diags

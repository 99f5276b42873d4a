"""Shared CLI helpers: --set parsing, --path, loading a design with diagnostics rendered."""
from __future__ import annotations

import json
import re
import sys

from acl.diagnostics import Diagnostic, DiagnosticError, Span, diagnostics_to_json, error, render

_SET = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*(.+?)\s*$")


# A leading number: digits with an optional fraction and an optional exponent (`2.0e1`, `2e-5`).
_LEADING_NUMBER = re.compile(r"\s*([+-]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][+-]?\d+)?)\s*(.*?)\s*$", re.S)


def quantity_text(text: str) -> str:
    """A value from the command line as acl text: `60um` -> `60 um`, `2.0e1um` -> `2.0e1 um`.

    The one place the CLI splits a number from its unit (--set, synth's --noise, --sweep, --effect):
    scientific notation stays one number, never a number followed by the unit `e`.
    """
    m = _LEADING_NUMBER.fullmatch(text)
    if not m:
        return text.strip()
    number, unit = m.groups()
    return f"{number} {unit}" if unit else number


def add_design_options(p, sets: bool = True) -> None:
    if sets:
        p.add_argument("--set", action="append", default=[], metavar="P=V",
                       help="override a parameter, e.g. --set gap=60um (repeatable)")
    p.add_argument("--path", action="append", default=[], metavar="DIR",
                   help="extra folder imports may read from (repeatable)")


def parse_sets(items: list[str]) -> tuple[dict[str, str], list[Diagnostic]]:
    out: dict[str, str] = {}
    diags = []
    for item in items:
        m = _SET.match(item)
        if not m:
            diags.append(error("E-USAGE", f"--set {item!r}: expected NAME=VALUE, e.g. --set gap=60um",
                               Span(file="<--set>", line=1, column=1)))
            continue
        out[m.group(1)] = quantity_text(m.group(2))
    return out, diags


def check_paths(paths) -> list[Diagnostic]:
    """--path folders must exist: a typo would silently change what imports resolve to."""
    import os

    return [error("E-USAGE", f"--path {p!r}: no such folder", Span(file="<--path>", line=1, column=1))
            for p in paths or [] if not os.path.isdir(p)]


def load_or_report(path: str, args, fmt: str = "text"):
    """Load a design; on errors render them and return (None, exit_code)."""
    from acl.design.resolve import load_design

    overrides, diags = parse_sets(getattr(args, "set", []) or [])
    diags += check_paths(getattr(args, "path", []))
    if diags:
        report(diags, fmt)
        return None, 2
    try:
        return load_design(path, overrides=overrides, search_paths=getattr(args, "path", []) or []), 0
    except DiagnosticError as exc:
        report(exc.diagnostics, fmt)
        return None, exit_code(exc.diagnostics)


def exit_code(diags) -> int:
    if any(d.code in ("E601", "E-USAGE") for d in diags):
        return 2
    return 1 if any(d.is_error for d in diags) else 0


def report(diags, fmt: str = "text", sources: dict[str, str] | None = None) -> None:
    if fmt == "json":
        sys.stdout.write(diagnostics_to_json(diags) + "\n")
    else:
        render(diags, sources=sources)


STDIN = "-"


def add_stdin_option(p) -> None:
    p.add_argument("--stdin-filename", metavar="NAME", default="<stdin>",
                   help="the name (and folder, for imports) of the design read from standard input (`-`)")


def read_stdin(name: str) -> tuple[str | None, list[Diagnostic]]:
    """The design on standard input (`-`): UTF-8 text, at most the design size limit."""
    from acl.design.modules import MAX_BYTES

    raw = sys.stdin.buffer.read(MAX_BYTES + 1)
    span = Span(file=name, line=1, column=1)
    if len(raw) > MAX_BYTES:
        return None, [error("E601", f"cannot read standard input: larger than {MAX_BYTES // 1_000_000} MB", span)]
    try:
        return raw.decode("utf-8"), []
    except UnicodeDecodeError as exc:
        return None, [error("E103", f"cannot read standard input: not UTF-8 text (byte {exc.start})", span)]

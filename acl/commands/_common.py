"""Shared CLI helpers: --set parsing, --path, loading a design with diagnostics rendered."""
from __future__ import annotations

import json
import re
import sys

from acl.diagnostics import Diagnostic, DiagnosticError, Span, diagnostics_to_json, error, render

_SET = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*(.+?)\s*$")


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
        value = m.group(2)
        # allow `60um` as well as `60 um`
        value = re.sub(r"^([0-9.eE+-]+)([A-Za-z\u00b5\u03bc])", r"\1 \2", value)
        out[m.group(1)] = value
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


def report(diags, fmt: str = "text") -> None:
    if fmt == "json":
        sys.stdout.write(diagnostics_to_json(diags) + "\n")
    else:
        render(diags)


def plotting_missing(option: str, fmt: str = "text") -> bool:
    """Report E-PLOT and return True when matplotlib (the `plot` extra) is not installed."""
    import importlib.util

    try:
        found = importlib.util.find_spec("matplotlib") is not None
    except (ImportError, ValueError):
        found = False
    if not found:
        report([error("E-PLOT", f"{option} draws figures with matplotlib, which is not installed",
                      Span(file=f"<{option}>", line=1, column=1),
                      "install the plotting extra: pip install 'acl[plot]'")], fmt)
    return not found

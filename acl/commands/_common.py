"""Shared CLI helpers: --set parsing, --path, loading a design with diagnostics rendered."""
from __future__ import annotations

import os
import re
import sys

from acl.diagnostics import Diagnostic, DiagnosticError, Span, clip, diagnostics_to_json, error, render

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


def seed(text: str) -> int:
    """argparse type of a random seed: a non-negative integer (numpy refuses negative seeds)."""
    import argparse

    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: a seed is a non-negative integer")
    return value


def jobs(text: str) -> int:
    """argparse type of --jobs: a positive number of worker processes, or ``auto`` (one per core)."""
    import argparse

    if text.strip() == "auto":
        return max(os.cpu_count() or 1, 1)
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of processes (a positive integer, or auto)") \
            from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: at least one process (or auto: one per core)")
    return value


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
        if m.group(1) in out:        # the last value silently won
            diags.append(error("E-USAGE", f"--set {m.group(1)} given twice ({out[m.group(1)]!r}, then "
                               f"{quantity_text(m.group(2))!r})", Span(file="<--set>", line=1, column=1),
                               "give each parameter once"))
            continue
        out[m.group(1)] = quantity_text(m.group(2))
    return out, diags


def check_paths(paths) -> list[Diagnostic]:
    """--path folders must exist: a typo would silently change what imports resolve to."""
    import os

    return [error("E-USAGE", f"--path {p!r}: no such folder", Span(file="<--path>", line=1, column=1))
            for p in paths or [] if not os.path.isdir(p)]


def load_or_report(path: str, args, fmt: str = "text"):
    """Load a design (a file, or a folder holding one: :func:`one_design`); on errors render them
    and return (None, exit_code)."""
    from acl.design.resolve import load_design

    path = one_design(path, fmt)
    if path is None:
        return None, 2
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


def in_option(d) -> bool:
    """An error located in a command-line option (``<--set>:1:1``, ``<--set gap>:1:20``, ``<-o>``)."""
    return d.is_error and d.span is not None and d.span.file.startswith("<-")


def exit_code(diags) -> int:
    """0 clean, 1 errors in a design or its data, 2 usage or I/O errors (cli.py, docs/language.md).

    An error in an option's value is a usage error whatever its code: `--set gap=3V` (E301) exits 2
    as `--vary gap=3V..4V:2` (E301) and `--at "3 V @ 5 kHz"` do; an override that makes the design
    itself wrong (`--set gap=1um`: capsules overlap, E403 in the file) is an error in the design, 1.
    """
    if any(d.code in ("E601", "E602", "E-USAGE") or in_option(d) for d in diags):
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

    span = Span(file=name, line=1, column=1)
    if sys.stdin is None:          # `acl check - <&-`
        return None, [error("E601", "cannot read standard input: it is closed", span,
                            "give the design on standard input (`acl check - < design.acl`) or name the file")]
    try:
        raw = sys.stdin.buffer.read(MAX_BYTES + 1)
    except OSError as exc:
        return None, [error("E601", f"cannot read standard input: {exc.strerror or exc}", span)]
    if len(raw) > MAX_BYTES:
        return None, [error("E601", f"cannot read standard input: larger than {MAX_BYTES // 1_000_000} MB", span)]
    try:
        return raw.decode("utf-8"), []
    except UnicodeDecodeError as exc:
        from acl._files import undecodable

        line, column, byte = undecodable(raw, exc)
        return None, [error("E103", f"cannot read standard input: not UTF-8 text (byte 0x{byte:02x} cannot be decoded)",
                            Span(file=name, line=line, column=column))]


def plotting_missing(option: str, fmt: str = "text", instead: str = "") -> bool:
    """Report E-PLOT and return True when matplotlib (the `plot` extra) cannot draw; ``instead``: a way without figures.

    Called before any work (a fit can take minutes): matplotlib is imported here as the figure writers
    import it (the Agg backend, then pyplot), so an installation that is found but cannot be imported
    (a missing shared library, a half-removed package) stops the command now, not after the work as
    an internal error.
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot  # noqa: F401
        why = None
    except ModuleNotFoundError as exc:
        why = "which is not installed" if (exc.name or "").split(".")[0] == "matplotlib" else \
            f"which cannot be imported ({exc})"
    except ImportError as exc:
        # sys.modules["matplotlib"] = None (blocked) is "not installed" too; anything else is a broken install
        why = "which is not installed" if "matplotlib" in sys.modules and sys.modules["matplotlib"] is None else \
            f"which cannot be imported ({type(exc).__name__}: {exc})"
    except Exception as exc:       # a broken installation fails in many ways; no traceback, and before the work
        why = f"which cannot be imported ({type(exc).__name__}: {exc})"
    if why:
        report([error("E-PLOT", clip(f"{option} draws figures with matplotlib, {why}"),
                      Span(file=f"<{option}>", line=1, column=1),
                      "install the plotting extra: pip install 'acl[plot]' (from a checkout: pip install '.[plot]')"
                      + (f"; {instead}" if instead else ""))], fmt)
    return why is not None


# -- one machine-output option for every command (ruff's `--output-format`) -----------------------

def _deprecated_alias(replacement: str, const=None):
    """An argparse action for an old spelling of an option: it still works, and the command line
    prints a one-line deprecation warning naming the new spelling (unless -q)."""
    import argparse

    class Alias(argparse.Action):
        def __call__(self, parser, namespace, values, option_string=None):
            setattr(namespace, self.dest, const if const is not None else values)
            notes = list(getattr(namespace, "deprecated_options", None) or [])
            notes.append(f"`{option_string}` is deprecated: use `{replacement}`")
            namespace.deprecated_options = notes

    return Alias


def add_output_format(p, choices=("text", "json"), default: str = "text", old=()) -> None:
    """``--output-format`` (dest ``output_format``), and the old spellings in ``old`` as hidden,
    deprecated aliases: ``--json`` (a flag meaning json) or an option taking the same values."""
    import argparse

    p.add_argument("--output-format", choices=choices, default=default, metavar="FORMAT",
                   help=f"output format: {', '.join(choices)} (default {default})")
    for spelling in old:
        if spelling == "--json":
            p.add_argument("--json", dest="output_format", nargs=0, help=argparse.SUPPRESS,
                           action=_deprecated_alias("--output-format json", const="json"))
        else:
            p.add_argument(spelling, dest="output_format", choices=choices, help=argparse.SUPPRESS,
                           action=_deprecated_alias("--output-format"))


def add_verbosity(p) -> None:
    """-q/--quiet and -v/--verbose, the same on every command."""
    if "--quiet" in p._option_string_actions or "--verbose" in p._option_string_actions:
        return
    g = p.add_mutually_exclusive_group()
    g.add_argument("-q", "--quiet", action="store_true",
                   help="print results and diagnostics only: no summaries, progress or notes")
    g.add_argument("-v", "--verbose", action="store_true",
                   help="also print what each stage did and how long it took (stderr)")


# -- designs named by file or folder ---------------------------------------------------------------



def design_files(paths) -> list[str]:
    """Expand folders into the ``*.acl`` designs under them (recursively, sorted; hidden folders,
    links leading out of the folder and entries that are not regular files, such as a FIFO named
    ``*.acl``, skipped, as ``acl lint`` does); anything else is kept as given (the loader reports a
    missing or unreadable file, and a FIFO named explicitly as E601)."""
    import os

    from acl._files import designs_under

    files = []
    for p in paths:
        files.extend(designs_under(p) if os.path.isdir(p) else [p])
    return list(dict.fromkeys(files))


def one_design(path: str, fmt: str = "text") -> str | None:
    """The design a single-design command works on: ``path`` itself, or the one design in a folder.
    A folder with none or several designs is reported (E-USAGE, naming them) and gives None."""
    import os

    if not os.path.isdir(path):
        return path
    files = design_files([path])
    if len(files) == 1:
        return files[0]
    found = ", ".join(files[:8]) + (", ..." if len(files) > 8 else "")
    report([error("E-USAGE", f"folder `{path}` holds {len(files) or 'no'} design{'s' * (len(files) != 1)}; "
                  "this command works on one", Span(file=path, line=1, column=1),
                  f"name one: {found}" if files else "give a .acl file")], fmt)
    return None


def seconds(text: str) -> float:
    """An option's value as a positive, finite number of seconds (argparse type; `--timeout`)."""
    import argparse
    import math

    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"{text!r}: give a number of seconds > 0")
    return v

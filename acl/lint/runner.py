"""Lint one design file: check stage, rules, configuration, suppressions -> a FileReport.

Input: a path, a :class:`~acl.lint.config.LintConfig`; output: the findings as
:class:`~acl.diagnostics.Diagnostic` values (check-stage E/W codes and ACL rule codes), sorted.
"""
from __future__ import annotations

import contextlib
import os
import time
from dataclasses import dataclass, field, replace

from acl._files import designs_under
from acl.diagnostics import Diagnostic, Severity, Span
from acl.lint.config import CHECK_CODE, LintConfig
from acl.lint.context import Context, Unavailable
from acl.lint.registry import RULES, load_rules
from acl.lint.source import SourceFile, scan

UNREADABLE = ("E601", "E103")
# folders never searched when a directory is linted (hidden folders are skipped too)


@dataclass
class FileReport:
    path: str
    findings: list[Diagnostic]
    notes: list[str] = field(default_factory=list)
    resolved: bool = True
    seconds: float = 0.0
    check_seconds: float = 0.0      # of which the check stage (parse, resolve, checks)

    @property
    def unreadable(self) -> bool:
        return any(d.code in UNREADABLE for d in self.findings)


def collect_files(paths: list[str]) -> tuple[list[str], list[str]]:
    """Design files under ``paths`` (directories recurse for *.acl, sorted) and the paths that do not exist."""
    files, missing = [], []
    for p in paths:
        if os.path.isdir(p):
            files.extend(designs_under(p))
        elif os.path.exists(p):
            files.append(p)
        else:
            missing.append(p)
    return list(dict.fromkeys(files)), missing


def lint_file(path: str, config: LintConfig, overrides: dict | None = None, search_paths=(),
              verbose: bool = False, text: str | None = None) -> FileReport:
    """Lint one design; with ``text`` (standard input) that is its source and ``path`` its name."""
    from acl.design.resolve import check_design

    t0 = time.perf_counter()
    design, check_diags = check_design(path, overrides=overrides or {}, search_paths=search_paths, text=text)
    t_check = time.perf_counter() - t0
    return lint_design(path, design, check_diags, _read_source(path, text), config, verbose, t0, t_check)


def lint_design(path: str, design, check_diags: list[Diagnostic], source: SourceFile | None, config: LintConfig,
                verbose: bool = False, t0: float | None = None, t_check: float = 0.0) -> FileReport:
    """Rules over an already checked design (``design`` None when it did not resolve).

    ``source`` is :func:`acl.lint.source.scan` of the file's text (None when unreadable); the
    language server passes the editor's unsaved text here.
    """
    rules = load_rules()
    t0 = time.perf_counter() if t0 is None else t0
    notes: list[str] = []
    findings = list(check_diags)
    if design is None:
        notes.append("design does not resolve: rules not run")
    else:
        ctx = Context(design, config, source)
        with _one_blas_thread():
            _run_rules(path, rules, ctx, config, findings, notes, verbose)
        notes.extend(ctx.notes)
    findings = _apply(findings, source, config, path, design is not None)
    findings.sort(key=_order)
    return FileReport(path, findings, notes, design is not None, time.perf_counter() - t0, t_check)


def _one_blas_thread():
    """Limit BLAS to one thread while the rules run (threadpoolctl, the `scale` extra; else no limit).

    The rules solve many small dense systems (one per frequency, a few hundred unknowns): OpenBLAS's
    threads gain nothing there, and on a busy machine they spin (benchmarks/lint.py: 2,500 lines took
    15 s of CPU with two threads, 2.8 s with one)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def _run_rules(path: str, rules: dict, ctx: Context, config: LintConfig, findings: list, notes: list,
               verbose: bool) -> None:
    """Each enabled rule over ``ctx``: findings, the time each took (verbose), a failing rule as ACL999."""
    for code, r in rules.items():
        if r.check is None or not config.enabled(code):
            continue
        t = time.perf_counter()
        try:
            findings.extend(r.check(ctx) or ())
        except Unavailable as exc:
            ctx.note(code, f"not run: {exc}")
        except Exception as exc:  # a rule bug must not hide the other rules' findings
            findings.append(Diagnostic("ACL999", Severity.ERROR, f"rule {code} ({r.name}) failed: "
                                       f"{type(exc).__name__}: {exc}", Span(file=path, line=1, column=1)))
        if verbose:
            notes.append(f"{code} {r.name}: {(time.perf_counter() - t) * 1e3:.1f} ms")


def _read_source(path: str, text: str | None = None) -> SourceFile | None:
    from acl.design.modules import read_source
    from acl.diagnostics import DiagnosticError

    if text is not None:
        return scan(path, text)
    try:
        return scan(path, read_source(path))   # never blocks on a FIFO, never reads past the size limit
    except DiagnosticError:
        return None


def _apply(findings: list[Diagnostic], source: SourceFile | None, config: LintConfig, path: str,
           resolved: bool) -> list[Diagnostic]:
    """Per-file ignores, global ignores of check warnings, inline suppressions, severities, ACL900/901."""
    file_ignored = config.ignored_for(path)
    used: set[tuple[int, str]] = set()
    sups = source.suppressions if source else []
    same_file = _same_file_test(path)
    others: dict = {}
    out = []
    for d in findings:
        if d.code in file_ignored or (CHECK_CODE.match(d.code) and d.code.startswith("W") and d.code in config.ignore):
            continue
        if not d.code.startswith("E") and d.span is not None and same_file(d.span.file):
            hit = next((s for s in sups if d.code in s.codes and s.first <= d.span.line <= s.last), None)
            if hit is not None:
                used.add((hit.line, d.code))
                continue
        elif not d.code.startswith("E") and d.span is not None and d.span.file:
            # a finding inside a file this design extends or imports: that file's own suppressions
            # apply (its unused ones are reported when that file is linted itself)
            other = others.get(d.span.file)
            if other is None:
                other = others[d.span.file] = _read_source(d.span.file) if os.path.isfile(d.span.file) else None
            if other is not None and any(d.code in s.codes and s.first <= d.span.line <= s.last
                                         for s in other.suppressions):
                continue
        out.append(d)
    if resolved and source is not None:
        for s in sups:
            span = Span(file=path, line=s.line, column=s.column)
            for code in s.codes:
                if (s.line, code) in used:
                    continue
                if code not in RULES and not CHECK_CODE.match(code):
                    msg = f"suppression names unknown rule `{code}`"
                elif code in RULES and not config.enabled(code):
                    continue                    # the rule did not run: it may well be needed
                else:
                    msg = f"suppression of {code} suppresses nothing"
                if config.enabled("ACL900") and "ACL900" not in file_ignored:
                    out.append(Diagnostic("ACL900", RULES["ACL900"].severity, msg, span,
                                          "remove it (or the code) from the comment"))
            if not s.reason and config.enabled("ACL901") and "ACL901" not in file_ignored:
                out.append(Diagnostic("ACL901", RULES["ACL901"].severity,
                                      f"suppression of {', '.join(s.codes) or 'nothing'} gives no reason", span,
                                      "say why after the bracket: `# acl: ignore[ACL202] pair meant to reverse`"))
    return [replace(d, severity=config.severity[d.code]) if d.code in config.severity else d for d in out]


def _same_file_test(path: str):
    real = os.path.realpath(path)

    def same(other: str) -> bool:
        return other == path or os.path.realpath(other) == real
    return same


def _order(d: Diagnostic):
    s = d.span
    return (s.file if s else "", s.line if s else 0, s.column if s else 0, d.code)

"""Output formats of `acl lint`: full, concise, json, sarif (2.1.0), github annotations, junit XML.

Each writer takes the file reports and a text stream; none imports anything heavy (``full`` uses
rich through :func:`acl.diagnostics.render`).
"""
from __future__ import annotations

import json
import os
from collections import Counter
from typing import TextIO
from xml.sax.saxutils import escape, quoteattr

from acl.diagnostics import Diagnostic, Severity
from acl.lint.registry import RULES

FORMATS = ("full", "concise", "json", "sarif", "github", "junit")


def _all(reports) -> list[Diagnostic]:
    return [d for r in reports for d in r.findings]


def rule_name(code: str) -> str:
    r = RULES.get(code)
    return r.name if r else ("check-error" if code.startswith("E") else "check-warning")


def _loc(d: Diagnostic) -> str:
    return f"{d.span.file}:{d.span.line}:{d.span.column}" if d.span else "<unknown>"


def summary_line(reports) -> str:
    ds = _all(reports)
    n_err = sum(d.severity is Severity.ERROR for d in ds)
    n_files = len(reports)
    if not ds:
        return f"All checks passed ({n_files} file{'s' * (n_files != 1)})."
    return (f"Found {len(ds)} finding{'s' * (len(ds) != 1)} ({n_err} error{'s' * (n_err != 1)}) "
            f"in {n_files} file{'s' * (n_files != 1)}.")


def statistics(reports) -> str:
    counts = Counter(d.code for d in _all(reports))
    return "\n".join(f"{n:5d}  {code:<7} {rule_name(code)}" for code, n in counts.most_common())


# ----------------------------------------------------------------------------------------------

def write_full(reports, out: TextIO, summary: bool = True) -> None:
    from acl._console import make_console

    from acl.diagnostics import render

    console = make_console(file=out, highlight=False, soft_wrap=True)
    ds = _all(reports)
    named = [Diagnostic(d.code, d.severity, f"{d.message} ({rule_name(d.code)})", d.span, d.hint, d.notes) for d in ds]
    render(named, console)
    if summary:
        console.print(summary_line(reports))


def write_concise(reports, out: TextIO, summary: bool = True) -> None:
    for d in _all(reports):
        out.write(f"{_loc(d)}: {d.code} {d.message}\n")
    if summary:
        out.write(summary_line(reports) + "\n")


def write_json(reports, out: TextIO) -> None:
    findings = []
    for d in _all(reports):
        item = d.as_dict()
        item["name"] = rule_name(d.code)
        item["notes"] = list(d.notes)
        findings.append(item)
    doc = {"files": [r.path for r in reports], "findings": findings,
           "summary": {"findings": len(findings), "errors": sum(f["severity"] == "error" for f in findings)}}
    out.write(json.dumps(doc, indent=2) + "\n")


_SARIF_LEVEL = {Severity.ERROR: "error", Severity.WARNING: "warning", Severity.INFO: "note"}


def sarif_document(reports) -> dict:
    from acl import __version__

    ds = _all(reports)
    codes = sorted(RULES) + sorted({d.code for d in ds if d.code not in RULES})
    index = {c: i for i, c in enumerate(codes)}
    rules = []
    for c in codes:
        r = RULES.get(c)
        desc = r.summary if r else ("error found by `acl check`" if c.startswith("E") else "warning found by `acl check`")
        rules.append({
            "id": c, "name": rule_name(c),
            "shortDescription": {"text": desc},
            "help": {"text": f"{desc}. See `acl rule {c}` or docs/rules.md#{c.lower()}"},
            "helpUri": help_uri(c),
            "defaultConfiguration": {"level": _SARIF_LEVEL[r.severity] if r else
                                     ("error" if c.startswith("E") else "warning")},
        })
    results = []
    for d in ds:
        text = d.message + "".join(f"\nnote: {n}" for n in d.notes) + (f"\nhelp: {d.hint}" if d.hint else "")
        res = {"ruleId": d.code, "ruleIndex": index[d.code], "level": _SARIF_LEVEL[d.severity],
               "message": {"text": text}}
        if d.span is not None:
            region = {"startLine": max(1, d.span.line), "startColumn": max(1, d.span.column)}
            if d.span.end_line and d.span.end_line >= d.span.line:
                region["endLine"] = d.span.end_line
                if d.span.end_column and (d.span.end_line > d.span.line or d.span.end_column > d.span.column):
                    region["endColumn"] = d.span.end_column
            res["locations"] = [{"physicalLocation": {
                "artifactLocation": {"uri": _uri(d.span.file)}, "region": region}}]
        results.append(res)
    return {
        "$schema": "https://json.schemastore.org/sarif-2.1.0.json",
        "version": "2.1.0",
        "runs": [{
            "tool": {"driver": {"name": "acl lint", "version": __version__, "rules": rules}},
            "results": results,
            "columnKind": "unicodeCodePoints",
        }],
    }


def help_uri(code: str) -> str:
    """A URI of the documentation of ``code``: the page shipped with acl (``acl rule CODE`` prints it)."""
    from pathlib import Path

    from acl._resources import shipped_dir

    docs = Path(shipped_dir("docs"))
    if code.startswith("ACL"):
        return (docs / "rules.md").as_uri() + "#" + code.lower()
    if code.startswith("E8"):
        return (docs / "data.md").as_uri() + "#errors"
    return (docs / "diagnostics.md").as_uri()


def _uri(path: str) -> str:
    """A percent-encoded URI reference (RFC 3986) for a file: relative to the working directory
    when the file is under it, else an absolute ``file:`` URI."""
    from urllib.parse import quote

    p = path
    if os.path.isabs(p):
        try:
            rel = os.path.relpath(p)
            if not rel.startswith(".."):
                p = rel
        except ValueError:
            pass
    raw = os.fsencode(p.replace(os.sep, "/"))      # a name that is not UTF-8 keeps its bytes: `a%FFb.acl`
    if os.path.isabs(p):
        return "file://" + quote(raw, safe="/")
    return quote(raw, safe="/")


def write_sarif(reports, out: TextIO) -> None:
    out.write(json.dumps(sarif_document(reports), indent=2) + "\n")


def _gh_escape(text: str, prop: bool = False) -> str:
    text = text.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")
    if prop:
        text = text.replace(":", "%3A").replace(",", "%2C")
    return text


def write_github(reports, out: TextIO) -> None:
    kind = {Severity.ERROR: "error", Severity.WARNING: "warning", Severity.INFO: "notice"}
    for d in _all(reports):
        props = []
        if d.span is not None:
            props += [f"file={_gh_escape(d.span.file, True)}", f"line={d.span.line}", f"col={d.span.column}"]
            if d.span.end_line:
                props.append(f"endLine={d.span.end_line}")
        props.append(f"title={_gh_escape(d.code + ' ' + rule_name(d.code), True)}")
        msg = d.message + "".join(f"\n{n}" for n in d.notes) + (f"\nhelp: {d.hint}" if d.hint else "")
        out.write(f"::{kind[d.severity]} {','.join(props)}::{_gh_escape(msg)}\n")


def write_junit(reports, out: TextIO) -> None:
    ds = _all(reports)
    out.write('<?xml version="1.0" encoding="UTF-8"?>\n')
    total = sum(max(1, len(r.findings)) for r in reports)
    out.write(f'<testsuites name="acl lint" tests="{total}" failures="{len(ds)}" errors="0">\n')
    for r in reports:
        n = len(r.findings)
        out.write(f'  <testsuite name={quoteattr(r.path)} tests="{max(1, n)}" failures="{n}" errors="0" '
                  f'time="{r.seconds:.4f}">\n')
        if not r.findings:
            out.write(f'    <testcase name={quoteattr(r.path)} classname="acl.lint"/>\n')
        for d in r.findings:
            where = _loc(d)
            out.write(f'    <testcase name={quoteattr(f"{d.code} at {where}")} classname={quoteattr(r.path)}>\n')
            body = "\n".join([f"{where}: {d.message}", *d.notes] + ([f"help: {d.hint}"] if d.hint else []))
            out.write(f'      <failure message={quoteattr(d.message)} type={quoteattr(d.code)}>'
                      f'{escape(body)}</failure>\n')
            out.write("    </testcase>\n")
        out.write("  </testsuite>\n")
    out.write("</testsuites>\n")


WRITERS = {"full": write_full, "concise": write_concise, "json": write_json, "sarif": write_sarif,
           "github": write_github, "junit": write_junit}

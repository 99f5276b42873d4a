"""`acl rule CODE` explains every diagnostic code acl can print.

The newcomer review found E-DEPENDENCY, E-SYNTH-REPLAY and W-FIT-PAIR-MODEL reported as unknown codes, and
E-MECH-001..004, W-MECH-001 and the N-PAIR-* notes answered with a stray prose paragraph (no code table row).
This test collects every code literal in acl/ and asks the command's own lookup for a table row (docs/*.md) or a
rule page (docs/rules.md).
"""
from __future__ import annotations

import glob
import os
import re

import pytest

from acl.cli import main
from acl.commands import rule as R

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
# codes that never reach a user as such: E000 (a sweep's fallback label for a point that failed without an error
# code), E-SWEEP-Q01/Q02 (the sweep's internal QuantityError, printed as the column's note), E-INTERNAL (a bug
# report: "please report it", no page to read)
INTERNAL = {"E000", "E-SWEEP-Q01", "E-SWEEP-Q02", "E-INTERNAL"}
_LITERAL = re.compile(r"[\"'\[]((?:E|W|N)(?:\d{3}|-[A-Z][A-Z0-9]*(?:-[A-Z0-9]+)*))[\"'\]]")


def _codes():
    found = set()
    for path in glob.glob(os.path.join(ROOT, "acl", "**", "*.py"), recursive=True):
        with open(path, encoding="utf-8") as fh:
            found.update(m.group(1) for m in _LITERAL.finditer(fh.read()))
    return sorted(found - INTERNAL)


def test_the_scan_finds_the_codes_it_should():
    codes = _codes()
    assert len(codes) > 100 and {"E201", "W-SCHED-COVERAGE", "N-PAIR-SCALE", "E-MECH-001"} <= set(codes)


def test_every_code_has_a_table_row_or_a_rule_page():
    entries = {**R.code_entries(), **R.rule_pages()}
    missing = [c for c in _codes() if c not in entries]
    assert not missing, f"codes with no row in a docs/*.md code table: {missing}"


@pytest.mark.parametrize("code, words", [("E-DEPENDENCY", "pygls"), ("E-SYNTH-REPLAY", "stable equilibrium"),
                                         ("W-FIT-PAIR-MODEL", "RMS residual"), ("E-MECH-004", "rest position"),
                                         ("N-PAIR-SCALE", "first-principles"), ("E-CLUSTER", "scheduler")])
def test_acl_rule_prints_the_row(code, words, capsys):
    assert main(["rule", code]) == 0
    out = capsys.readouterr().out
    assert out.startswith(code) and words in out and "\n* `" not in out

"""`acl rule CODE` explains every code `acl compile` reports (issue 28, tried as a new user).

Each compile diagnostic points to `acl rule CODE`; for E-SCHED-TONES and 22 other compile codes it printed the
first paragraph of docs/schedule.md that named the code: a list of two dozen codes, or an unrelated paragraph
about options or the waveform's formula. Each now has its line in docs/schedule.md's table.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from acl.commands.rule import code_entries

ROOT = Path(__file__).resolve().parent.parent


def _compile_codes() -> set[str]:
    """Every E-/W- code of the compile pipeline (and its --calibration CSV) raised in acl/schedule, acl/emit and
    acl/commands/compile.py."""
    files = [*(ROOT / "acl" / "schedule").glob("*.py"), *(ROOT / "acl" / "emit").glob("*.py"),
             ROOT / "acl" / "commands" / "compile.py"]
    found = set()
    for f in files:
        found |= set(re.findall(r'"((?:E|W)-(?:SCHED|EMIT|COMPILE|CSV)-[A-Z-]+)"', f.read_text(encoding="utf-8")))
    return found


def test_the_scan_finds_the_compile_codes():
    codes = _compile_codes()
    assert {"E-SCHED-TONES", "E-SCHED-INFEASIBLE", "E-EMIT-OUTPUT", "E-COMPILE-PROGRAM", "W-SCHED-TRACKING",
            "E-CSV-HEADER"} <= codes


@pytest.mark.parametrize("code", sorted(_compile_codes()))
def test_each_compile_code_has_its_own_line(code):
    entry = code_entries().get(code)
    assert entry is not None, f"{code}: no row in a docs/*.md code table; `acl rule {code}` shows a stray paragraph"
    assert not re.search(r"`[EW]-[A-Z]+-[A-Z-]+`.*`[EW]-[A-Z]+-[A-Z-]+`.*`[EW]-[A-Z]+-[A-Z-]+`", entry["text"]), entry

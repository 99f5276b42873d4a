"""A newcomer's first run (the README's "Set up" command, `acl compile examples/fig3_three_orifice.acl
--program circle`) prints warnings before its table; the README explains each warning code that run
prints, so a first run's "warning" is not read as a failed install (found by a newcomer's review:
two W-ACOUSTIC-STREAMING warnings, one per circle, that the README did not mention)."""
from __future__ import annotations

import re
from pathlib import Path

from acl.schedule.compile import CompileOptions, compile_program

ROOT = Path(__file__).resolve().parents[1]


def _setup_section() -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    start = text.index("## Set up")
    return text[start:text.index("\n## ", start + 1)]


def test_the_readme_explains_every_warning_its_first_command_prints(fig3):
    section = _setup_section()
    assert "acl compile examples/fig3_three_orifice.acl --program circle" in section
    s = compile_program(fig3, "circle", CompileOptions(band_samples=6, resim_points=20))
    codes = {w.code for w in s.warnings if w.severity == "warning"}
    assert codes, "the first run prints no warning any more: the README's sentence about them can go"
    for code in codes:
        assert re.search(rf"\b{re.escape(code)}\b", section), f"README's Set up does not explain {code}"

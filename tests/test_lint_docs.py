"""docs/rules.md is a specification: every rule has a page whose examples fail and pass as stated."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from acl.lint import LintConfig, lint_file, load_rules

DOC = Path(__file__).resolve().parents[1] / "docs" / "rules.md"
BLOCK = re.compile(r"```acl (fails|passes|preamble)\n(.*?)```", re.S)


def sections() -> dict[str, str]:
    text = DOC.read_text()
    parts = re.split(r"^## (ACL\d{3})\s*$", text, flags=re.M)
    return {parts[i]: parts[i + 1] for i in range(1, len(parts), 2)}


def preamble() -> str:
    return next(m.group(2) for m in BLOCK.finditer(DOC.read_text()) if m.group(1) == "preamble")


def examples():
    for code, body in sections().items():
        for m in BLOCK.finditer(body):
            yield pytest.param(code, m.group(1), m.group(2), id=f"{code}-{m.group(1)}")


def test_every_rule_has_a_page_with_a_failing_and_a_passing_example():
    found = sections()
    for code in load_rules():
        assert code in found, f"{code} has no section in docs/rules.md"
        if code == "ACL999":
            continue
        kinds = [m.group(1) for m in BLOCK.finditer(found[code])]
        assert "fails" in kinds and "passes" in kinds, code
        assert f"[{code}](#{code.lower()})" in DOC.read_text(), f"{code} missing from the table"


@pytest.mark.parametrize("code, kind, body", list(examples()))
def test_documented_example(tmp_path, code, kind, body):
    head = preamble()
    path = tmp_path / "example.acl"
    path.write_text(head + body)
    report = lint_file(str(path), LintConfig())
    assert report.resolved, [d.message for d in report.findings]
    first = head.count("\n")
    hits = [d for d in report.findings if d.code == code and d.span and d.span.line > first]
    if kind == "fails":
        assert hits, f"{code} example should fire: {[(d.code, d.message) for d in report.findings]}"
    else:
        assert not hits, [d.message for d in hits]

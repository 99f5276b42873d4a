"""Every example in examples/ is lint-clean or carries a justified suppression.

`acl lint examples/` must exit 0 with no finding at error severity, no suppression that suppresses
nothing (ACL900) and no suppression without a reason (ACL901).
"""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
SUPPRESSION = re.compile(r"#.*acl\s*:\s*ignore\s*\[([^\]]*)\]\s*(.*)$", re.I)

pytestmark = pytest.mark.skipif(not EXAMPLES.is_dir(), reason="no examples folder")


@pytest.fixture(scope="module")
def lint():
    proc = subprocess.run([sys.executable, "-m", "acl", "lint", str(EXAMPLES), "--format", "json"],
                          capture_output=True, text=True, cwd=ROOT, timeout=600)
    report = json.loads(proc.stdout)
    return proc.returncode, report


def _where(findings):
    return "\n".join(f"{f['file']}:{f['line']}: {f['code']} {f['message']}" for f in findings)


def test_lint_examples_exits_zero(lint):
    code, report = lint
    assert code == 0, _where(report["findings"])


def test_no_error_findings(lint):
    _, report = lint
    errors = [f for f in report["findings"] if f["severity"] == "error"]
    assert not errors, _where(errors)
    assert report["summary"]["errors"] == 0


def test_no_unused_suppression(lint):
    _, report = lint
    unused = [f for f in report["findings"] if f["code"] == "ACL900"]
    assert not unused, _where(unused)


def test_every_suppression_has_a_reason(lint):
    _, report = lint
    bare = [f for f in report["findings"] if f["code"] == "ACL901"]
    assert not bare, _where(bare)


def test_every_example_is_linted(lint):
    _, report = lint
    linted = {Path(f).name for f in report["files"]}
    assert linted == {p.name for p in EXAMPLES.glob("*.acl")}


def test_suppression_reasons_are_specific():
    """Independent of ACL901: each suppression in examples names codes and gives a real reason."""
    for path in sorted(EXAMPLES.glob("*.acl")):
        for n, line in enumerate(path.read_text().splitlines(), 1):
            m = SUPPRESSION.search(line)
            if not m:
                continue
            codes = [c.strip() for c in m.group(1).split(",") if c.strip()]
            assert codes and all(re.fullmatch(r"ACL\d{3}", c) for c in codes), f"{path.name}:{n}"
            assert len(m.group(2).split()) >= 6, f"{path.name}:{n}: reason too short: {m.group(2)!r}"

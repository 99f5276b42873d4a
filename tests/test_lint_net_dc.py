"""ACL201 decides "closer than d_c" with the d_c acl analyze reports: where the net pair force (thrust, Bjerknes,
jet drag) changes sign (issue 24, item 5).  Before, the rule used paper Eq. 3's sqrt(alpha / 2 gamma) alone: on the
calibrated Fig. 4 pair at 61 um that is 57.8 um, while the net force still attracts out to 62.6 um, so the lint
passed a pair that `acl analyze` and `acl compile` see snap in (the unsafe direction)."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from example_designs import first_principles_text

ROOT = Path(__file__).resolve().parents[1]
EX = ROOT / "examples" / "fig4_facing_pair.acl"


def _unsuppressed(text: str) -> str:
    """The example with its ramp's ACL201 suppression removed (the ramp means to snap the pair)."""
    out = re.sub(r"(program ramp \{)\s*# acl: ignore\[ACL201\][^\n]*", r"\1", text)
    assert "ignore[ACL201]" not in out
    return out


def _acl(*args) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-m", "acl", *args], capture_output=True, text=True, env=env, timeout=300)


def _lint_dc(path: Path, gap: str) -> float | None:
    """The d_c (um) ACL201 prints for the pair, None when the rule does not fire."""
    proc = _acl("lint", str(path), "--set", f"gap={gap}")
    out = proc.stdout + proc.stderr
    m = re.search(r"error\[ACL201\]: .*closer than their critical distance ([0-9.]+) um", out)
    return float(m.group(1)) if m else None


def _analyze_dc(path: Path, gap: str) -> float:
    proc = _acl("analyze", str(path), "--set", f"gap={gap}", "--output-format", "json")
    (pair,) = json.loads(proc.stdout)["pairs"]
    return pair["critical_distance_m"] * 1e6


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "pair.acl"
    p.write_text(text)
    return p


def test_a_pair_between_eq3_and_the_net_d_c_is_flagged(tmp_path):
    path = _write(tmp_path, _unsuppressed(EX.read_text()))
    dc = _analyze_dc(path, "61um")
    assert 61.0 < dc < 64.0                                   # the net d_c of the calibrated pair: 62.6 um
    assert _lint_dc(path, "61um") == pytest.approx(dc, abs=0.05)    # printed to 0.1 um
    assert _lint_dc(path, "64um") is None                     # beyond the net d_c: the thrust wins


def test_the_first_principles_pair_gets_analyze_s_d_c(tmp_path):
    path = _write(tmp_path, _unsuppressed(first_principles_text("fig4_facing_pair")))
    dc = _analyze_dc(path, "40um")
    assert _lint_dc(path, "40um") == pytest.approx(dc, abs=0.05)
    assert _lint_dc(path, f"{dc + 3:.1f}um") is None


def test_the_sweep_s_acl201_column_follows_the_rule(tmp_path):
    """`acl sweep`'s lint_acl201_pass equals the rule at the two gaps around the net d_c (and at 61 um, where Eq. 3's
    criterion alone passed the pair)."""
    path = _write(tmp_path, _unsuppressed(EX.read_text()))
    out = tmp_path / "s.csv"
    proc = _acl("sweep", str(path), "--vary", "gap=61um,64um", "-o", str(out), "-q")
    assert proc.returncode == 0, proc.stderr
    import csv
    rows = list(csv.DictReader(out.open()))
    assert [r["lint_acl201_pass"] for r in rows] == ["False", "True"]

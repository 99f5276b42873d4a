"""Command-line output conventions (issue 11): whole lines off a terminal, one machine-output option,
-q/-v everywhere, folders accepted, `acl rule`, files that respect the umask."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FIG4 = "examples/fig4_facing_pair.acl"


def run(*args, cwd=ROOT, env=None):
    environ = {k: v for k, v in os.environ.items() if k != "COLUMNS"}
    environ.update(env or {})
    environ["PYTHONPATH"] = str(ROOT) + os.pathsep + environ.get("PYTHONPATH", "")
    return subprocess.run([sys.executable, "-m", "acl", *args], capture_output=True, text=True,
                          timeout=300, cwd=cwd, env=environ)


# -- piped output is never cut at 80 columns ------------------------------------------------------

def test_analyze_tables_are_not_truncated_when_piped():
    r = run("analyze", FIG4, "--no-snap")
    assert r.returncode == 0, r.stderr
    assert "…" not in r.stdout
    row = next(line for line in r.stdout.splitlines() if "left-right" in line)
    assert "attract" in row and "not computed" in row       # the last column of a 100+ column table
    assert f"{FIG4}:28" in r.stdout
    assert max(len(line) for line in r.stdout.splitlines()) > 80


def test_check_lines_are_not_wrapped_when_piped(tmp_path):
    deep = tmp_path / ("a_long_folder_name_" * 4) / "designs"
    deep.mkdir(parents=True)
    design = deep / "fig2.acl"
    shutil.copy(ROOT / "examples" / "fig2_vertical_cantilever.acl", design)
    text = design.read_text().replace("import stdlib.media", "import stdlib.media\nparam unused_but_long_name = 3 um")
    design.write_text(text)
    r = run("check", str(design))
    ok = [line for line in r.stderr.splitlines() if line.startswith("ok ")]
    assert len(ok) == 1 and str(design) in ok[0] and "capsule" in ok[0], r.stderr


def test_columns_still_wins_when_set():
    r = run("analyze", FIG4, "--no-snap", env={"COLUMNS": "60"})
    assert max(len(line) for line in r.stdout.splitlines()) <= 60

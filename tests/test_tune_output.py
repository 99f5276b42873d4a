"""Issue 28: `acl tune -o FOLDER/` and `-q`.

A tuned design `extends` the original by a path relative to its own folder; `acl check` reads an
`extends` only from the design's folder and below, or a --path folder (E210 otherwise).  So
`-o FOLDER/` writes FOLDER/<stem>.tuned.acl when FOLDER reaches the original (it holds it, or
--path names its folder) and is refused before the search (E-USAGE, exit 2, nothing written) when
it does not; and `-q` prints the summary line alone, no tables."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from acl.cli import main

ROOT = Path(__file__).resolve().parents[1]
FIG3 = ROOT / "examples" / "fig3_robust_radii.acl"
FAST = ["--samples", "150", "--max-evals", "8", "-q"]


@pytest.fixture
def lab(tmp_path, monkeypatch):
    (tmp_path / "designs").mkdir()
    (tmp_path / "other").mkdir()
    shutil.copy(FIG3, tmp_path / "designs" / FIG3.name)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_a_folder_that_cannot_reach_the_design_is_refused_before_the_search(lab, capsys):
    code = main(["tune", f"designs/{FIG3.name}", "-o", "other/", *FAST])
    err = capsys.readouterr().err
    assert code == 2
    assert "<--output>:1:1: error[E-USAGE]" in err and "E210" in err and "--path" in err
    assert list((lab / "other").iterdir()) == []


def test_a_folder_with_path_writes_the_tuned_design_that_checks_with_path(lab, capsys):
    assert main(["tune", f"designs/{FIG3.name}", "-o", "other/", "--path", "designs", *FAST]) == 0
    out = lab / "other" / "fig3_robust_radii.tuned.acl"
    assert out.is_file() and 'extends "../designs/fig3_robust_radii.acl"' in out.read_text()
    capsys.readouterr()
    assert main(["check", str(out), "--path", "designs"]) == 0
    assert main(["check", str(out)]) != 0                 # without --path the original is out of reach (E210)
    assert "E210" in capsys.readouterr().err


def test_a_folder_above_the_design_needs_no_path(lab, capsys):
    assert main(["tune", f"designs/{FIG3.name}", "-o", ".", *FAST]) == 0
    out = lab / "fig3_robust_radii.tuned.acl"
    assert 'extends "designs/fig3_robust_radii.acl"' in out.read_text()
    assert main(["check", str(out)]) == 0


def test_quiet_prints_the_summary_line_alone(lab, capsys):
    assert main(["tune", f"designs/{FIG3.name}", *FAST]) == 0
    out, err = capsys.readouterr()
    assert out.count("\n") == 1 and out.startswith("yield before ") and "after" in out
    assert "Free parameters" not in out and "┃" not in out and err == ""


"""`acl check` from the outside: exit codes, JSON output, and never a traceback."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from acl.cli import main

ROOT = Path(__file__).resolve().parents[1]
GOOD = ROOT / "examples" / "fig2_vertical_cantilever.acl"
FACING = ROOT / "examples" / "fig4_facing_pair.acl"
BAD = ROOT / "tests" / "bad" / "unit_missing.acl"
JSON_FIELDS = {"code", "severity", "message", "file", "line", "column", "end_line", "end_column", "hint"}


def _acl(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "acl", *args], capture_output=True, text=True, cwd=ROOT, timeout=60)


def _run(capsys, *args: str) -> tuple[int, str, str]:
    try:
        code = main(list(args))
    except SystemExit as exc:  # argparse usage errors
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("args, want", [
    ((str(GOOD),), 0),
    ((str(FACING), "--set", "gap=20um"), 0),
    ((str(BAD),), 1),
    ((str(GOOD), str(BAD)), 1),
    ((str(ROOT / "no_such_design.acl"),), 2),
    ((str(ROOT / "examples"),), 0),          # a folder: every design under it (issue 11)
    ((str(ROOT / "tests" / "bad" / "syntax_not_utf8.acl"),), 1),
    ((str(FACING), "--set", "gap"), 2),
    ((str(FACING), "--set", "=20um"), 2),
    ((str(GOOD), "--format", "yaml"), 2),
    ((), 2),
], ids=["clean", "set-override", "design-error", "worst-of-several", "missing-file", "directory", "not-utf8", "set-without-value",
        "set-without-name", "bad-format", "no-file"])
def test_check_exit_code(capsys, args, want):
    code, _, err = _run(capsys, "check", *args)
    assert code == want
    assert "Traceback" not in err


def test_warnings_alone_exit_zero(capsys):
    code, _, err = _run(capsys, "check", str(ROOT / "tests" / "bad" / "prog_empty.acl"))
    assert code == 0
    assert "W501" in err


def test_unknown_parameter_in_set_is_a_usage_error_with_a_suggestion(capsys):
    code, out, _ = _run(capsys, "check", str(FACING), "--set", "gapp=20um", "--format", "json")
    assert code == 2          # an error in an option's value: usage (docs/language.md, exit codes)
    d = json.loads(out)["diagnostics"][0]
    assert (d["code"], d["hint"]) == ("E211", "did you mean `gap`?")


def test_json_output_has_every_field(capsys):
    code, out, _ = _run(capsys, "check", str(BAD), "--format", "json")
    doc = json.loads(out)
    assert code == 1 and doc["ok"] is False and doc["files"] == [str(BAD)]
    (d,) = doc["diagnostics"]
    assert set(d) >= JSON_FIELDS
    assert (d["code"], d["severity"], d["line"], d["column"]) == ("E301", "error", 10, 45)
    assert d["file"].endswith("unit_missing.acl")


def test_json_output_of_a_clean_design_is_ok_and_empty(capsys):
    code, out, _ = _run(capsys, "check", str(GOOD), "--format", "json")
    assert code == 0
    assert json.loads(out) == {"files": [str(GOOD)], "ok": True, "diagnostics": []}


def test_json_output_of_a_missing_file_reports_the_io_error(capsys):
    code, out, _ = _run(capsys, "check", "nowhere.acl", "--format", "json")
    assert code == 2
    assert json.loads(out)["diagnostics"][0]["code"] == "E601"


def test_text_output_shows_location_code_and_caret(capsys):
    _, _, err = _run(capsys, "check", str(BAD))
    assert "unit_missing.acl:10:45: error[E301]" in err
    assert "^^" in err


@pytest.mark.parametrize("args, want", [
    ((str(GOOD),), 0),
    ((str(BAD),), 1),
    ((str(ROOT / "tests" / "bad" / "syntax_nul_byte.acl"),), 1),
    (("missing.acl",), 2),
    ((str(FACING), "--set", "gap"), 2),
], ids=["clean", "error", "binary", "missing", "bad-set"])
def test_subprocess_exit_code_and_no_traceback(args, want):
    r = _acl("check", *args)
    assert r.returncode == want, r.stderr
    assert "Traceback" not in r.stderr and "Traceback" not in r.stdout

"""`acl lint` as a command: exit codes, configuration, formats, no heavy imports."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from acl.cli import main

SCHEMA = Path("/work/shared/schemas/sarif-schema-2.1.0.json")

CLEAN = """\
import stdlib.media
import stdlib.capsules
import stdlib.beams
import stdlib.transducers

use medium media.pbs
use transducer transducers.immersion
beam arm like beams.cantilever50 { clamp = (0, 0, 0) }
capsule a like capsules.design1 { }
mount a on arm.tip
"""
# a capsule 20 um above the substrate (ACL502, a warning) and a failing requirement (ACL603, an error)
LOW = CLEAN.replace("beams.cantilever50 {", "beams.cantilever50 { length = 20 um,")
FAILING = CLEAN + "require resonance(a) in 50 kHz .. 60 kHz\n"


def write(tmp_path: Path, name: str, text: str) -> str:
    p = tmp_path / name
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(textwrap.dedent(text))
    return str(p)


def run(capsys, *argv) -> tuple[int, str, str]:
    rc = main(["lint", *argv])
    out, err = capsys.readouterr()
    return rc, out, err


# ---- exit codes ----------------------------------------------------------------------------------

def test_clean_design_exits_0(tmp_path, capsys):
    rc, out, _ = run(capsys, write(tmp_path, "a.acl", CLEAN))
    assert rc == 0 and "All checks passed" in out


def test_warnings_only_exit_0(tmp_path, capsys):
    rc, out, _ = run(capsys, "--format", "concise", write(tmp_path, "a.acl", LOW))
    assert rc == 0 and "ACL502" in out


def test_error_findings_exit_1(tmp_path, capsys):
    rc, out, _ = run(capsys, "--format", "concise", write(tmp_path, "a.acl", FAILING))
    assert rc == 1 and "ACL603" in out


def test_unresolved_design_exits_1_with_its_check_codes(tmp_path, capsys):
    rc, out, _ = run(capsys, "--format", "concise", write(tmp_path, "a.acl", CLEAN.replace("arm.tip", "arm.top")))
    assert rc == 1 and "E212" in out


def test_unknown_rule_code_exits_2_without_traceback(tmp_path, capsys):
    rc, _, err = run(capsys, "--select", "ACL1O1", write(tmp_path, "a.acl", CLEAN))
    assert rc == 2 and "unknown rule code" in err and "Traceback" not in err


def test_bad_format_exits_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["lint", "--format", "xml", write(tmp_path, "a.acl", CLEAN)])
    assert exc.value.code == 2


def test_missing_path_exits_2(tmp_path, capsys):
    rc, _, err = run(capsys, str(tmp_path / "nope.acl"))
    assert rc == 2 and "no such file" in err


def test_directories_are_searched_for_designs(tmp_path, capsys):
    write(tmp_path, "d/x/one.acl", LOW)
    write(tmp_path, "d/two.acl", FAILING)
    write(tmp_path, "d/notes.txt", "not a design")
    rc, out, _ = run(capsys, "--format", "concise", str(tmp_path / "d"))
    assert rc == 1 and "one.acl" in out and "two.acl" in out and "2 files" in out


def test_select_and_ignore_on_the_command_line(tmp_path, capsys):
    f = write(tmp_path, "a.acl", FAILING)
    rc, out, _ = run(capsys, "--format", "concise", "--ignore", "ACL603", f)
    assert rc == 0 and "ACL603" not in out
    rc, out, _ = run(capsys, "--format", "concise", "--select", "ACL5", write(tmp_path, "b.acl", LOW + FAILING[len(CLEAN):]))
    assert rc == 0 and "ACL502" in out and "ACL603" not in out


def test_statistics_counts_findings_per_rule(tmp_path, capsys):
    rc, out, _ = run(capsys, "--format", "concise", "--statistics", write(tmp_path, "a.acl", LOW))
    assert "1  ACL502  substrate-proximity" in out


# ---- configuration -------------------------------------------------------------------------------

def test_pyproject_configuration_is_found_by_walking_up(tmp_path, capsys):
    write(tmp_path, "pyproject.toml", '[tool.acl.lint]\nignore = ["ACL502"]\n')
    rc, out, _ = run(capsys, "--format", "concise", write(tmp_path, "sub/a.acl", LOW))
    assert rc == 0 and "ACL502" not in out


def test_acl_toml_thresholds_with_units(tmp_path, capsys):
    write(tmp_path, "acl.toml", '[lint.thresholds]\nsubstrate_clearance = "10 um"\n')
    rc, out, _ = run(capsys, "--format", "concise", write(tmp_path, "a.acl", LOW))
    assert "ACL502" not in out


def test_severity_override_turns_a_warning_into_an_error(tmp_path, capsys):
    write(tmp_path, "acl.toml", '[lint.severity]\nACL502 = "error"\n')
    rc, out, _ = run(capsys, "--format", "concise", write(tmp_path, "a.acl", LOW))
    assert rc == 1


def test_per_file_ignores_match_globs_relative_to_the_config(tmp_path, capsys):
    write(tmp_path, "acl.toml", '[lint.per-file-ignores]\n"legacy/*.acl" = ["ACL502"]\n')
    legacy = write(tmp_path, "legacy/a.acl", LOW)
    fresh = write(tmp_path, "new/a.acl", LOW)
    _, out, _ = run(capsys, "--format", "concise", legacy, fresh)
    assert "legacy/a.acl" not in out and "new/a.acl" in out


def test_explicit_config_wins(tmp_path, capsys):
    write(tmp_path, "acl.toml", '[lint]\nignore = ["ACL502"]\n')
    other = write(tmp_path, "elsewhere/strict.toml", '[lint]\nselect = ["ALL"]\n')
    _, out, _ = run(capsys, "--format", "concise", "--config", other, write(tmp_path, "a.acl", LOW))
    assert "ACL502" in out


def test_a_configuration_with_a_byte_order_mark_and_crlf_is_read(tmp_path, capsys):
    """A Windows editor's acl.toml (UTF-8 BOM, CRLF) was `invalid TOML: Invalid statement` at 1:1; .acl and .csv
    files with a BOM are read, so is the configuration now (found by walking up and given with --config)."""
    (tmp_path / "acl.toml").write_bytes('\ufeff[lint]\r\nignore = ["ACL502"]\r\n'.encode("utf-8"))
    rc, out, err = run(capsys, "--format", "concise", write(tmp_path, "a.acl", LOW))
    assert rc == 0 and "ACL502" not in out and "E-CONFIG" not in err
    rc, out, err = run(capsys, "--format", "concise", "--config", str(tmp_path / "acl.toml"), write(tmp_path, "b.acl", LOW))
    assert rc == 0 and "ACL502" not in out and "E-CONFIG" not in err
    # an error in it is still located at its line
    (tmp_path / "acl.toml").write_bytes('\ufeff[lint]\r\nignor = ["ACL502"]\r\n'.encode("utf-8"))
    rc, _, err = run(capsys, "--config", str(tmp_path / "acl.toml"), write(tmp_path, "c.acl", LOW))
    assert rc == 2 and "acl.toml:2:" in err and "unknown key `ignor`" in err


@pytest.mark.parametrize("toml, needle, line", [
    ('[tool.acl.lint]\nselect = ["ACL101"]\nignor = ["ACL102"]\n', "unknown key `ignor`", 3),
    ('[tool.acl.lint]\nselect = ["ACL101", "ACL123"]\n', "unknown rule code `ACL123`", 2),
    ('[tool.acl.lint]\n\n[tool.acl.lint.thresholds]\ncrosstalk = 0.1\n', "unknown threshold `crosstalk`", 4),
    ('[tool.acl.lint.thresholds]\nsubstrate_clearance = "10 kHz"\n', "wrong dimension", 2),
    ('[tool.acl.lint.severity]\nACL101 = "fatal"\n', "severity of `ACL101`", 2),
    ('[tool.acl.lint\n', "invalid TOML", 1),
])
def test_bad_configuration_exits_2_pointing_at_the_line(tmp_path, capsys, toml, needle, line):
    cfg = write(tmp_path, "pyproject.toml", toml)
    rc, _, err = run(capsys, "--config", cfg, write(tmp_path, "a.acl", CLEAN))
    assert rc == 2 and needle in err and f"pyproject.toml:{line}:" in err and "Traceback" not in err


@pytest.mark.parametrize("name, toml, needle", [
    ("acl.toml", "tool = 1\n", "`tool` must be a table"),
    ("acl.toml", "[tool]\nacl = 5\n", "`tool.acl` must be a table"),
    ("pyproject.toml", "[tool]\nacl = 5\n", "`tool.acl` must be a table"),
    ("pyproject.toml", "tool = []\n", "`tool` must be a table"),
    ("pyproject.toml", "[tool.acl]\nlint = 3\n", "`tool.acl.lint` must be a table"),
])
def test_a_configuration_whose_tool_tables_are_not_tables_is_a_located_error(tmp_path, capsys, name, toml, needle):
    """`tool = 1` in acl.toml was E-INTERNAL (AttributeError: 'int' object has no attribute 'get')."""
    cfg = write(tmp_path, name, toml)
    rc, _, err = run(capsys, "--config", cfg, write(tmp_path, "a.acl", CLEAN))
    assert rc == 2 and "E-INTERNAL" not in err and needle in err and f"{name}:" in err, err
    assert "error[E-CONFIG]" in err


@pytest.mark.parametrize("bom", [b"", b"\xef\xbb\xbf"], ids=["plain", "bom"])
def test_a_configuration_that_is_not_utf8_is_located_at_its_byte(tmp_path, capsys, bom):
    """Was `acl.toml:1:1 ... 'utf-8' codec can't decode byte 0xb5 in position 30` (Python's text, line 1)."""
    (tmp_path / "acl.toml").write_bytes(bom + b'[lint]\nselect = ["ACL101"] # \xb5m\n')
    rc, _, err = run(capsys, "--config", str(tmp_path / "acl.toml"), write(tmp_path, "a.acl", CLEAN))
    assert rc == 2 and "acl.toml:2:23: error[E-CONFIG]" in err and "not UTF-8 text (byte 0xb5)" in err, err


def test_an_infinite_threshold_is_refused_as_not_finite(tmp_path, capsys):
    cfg = write(tmp_path, "acl.toml", '[lint]\nthresholds = {snap_margin = "1e999"}\n')
    rc, _, err = run(capsys, "--config", cfg, write(tmp_path, "a.acl", CLEAN))
    assert rc == 2 and "acl.toml:2:" in err and "threshold `snap_margin`: must be positive and finite" in err, err


# ---- formats -------------------------------------------------------------------------------------

def test_full_format_shows_the_caret_and_the_physics(tmp_path, capsys):
    _, out, _ = run(capsys, write(tmp_path, "a.acl", LOW))
    assert "warning[ACL502]" in out and "^" in out and "note: threshold substrate_clearance" in out


def test_json_format(tmp_path, capsys):
    _, out, _ = run(capsys, "--format", "json", write(tmp_path, "a.acl", FAILING))
    doc = json.loads(out)
    f = doc["findings"][0]
    assert f["code"] == "ACL603" and f["name"] == "require-failed" and f["line"] == 11 and f["notes"]


def test_github_format_is_one_annotation_per_finding(tmp_path, capsys):
    path = write(tmp_path, "a.acl", FAILING)
    _, out, _ = run(capsys, "--format", "github", path)
    line = out.strip().splitlines()[0]
    assert line.startswith(f"::error file={path},line=11,col=1,") and "title=ACL603 require-failed::" in line


def test_junit_format_parses_and_counts_failures(tmp_path, capsys):
    _, out, _ = run(capsys, "--format", "junit", write(tmp_path, "a.acl", FAILING), write(tmp_path, "b.acl", CLEAN))
    root = ET.fromstring(out)
    assert root.tag == "testsuites" and root.get("failures") == "1"
    assert [s.get("failures") for s in root.findall("testsuite")] == ["1", "0"]
    assert root.find("testsuite/testcase/failure").get("type") == "ACL603"


def test_sarif_output_validates_against_the_2_1_0_schema(tmp_path, capsys):
    if not SCHEMA.exists():
        pytest.skip(f"SARIF schema not found at {SCHEMA}")
    jsonschema = pytest.importorskip("jsonschema")
    _, out, _ = run(capsys, "--format", "sarif", write(tmp_path, "a.acl", FAILING), write(tmp_path, "b.acl", LOW),
                    write(tmp_path, "c.acl", CLEAN.replace("arm.tip", "arm.top")))
    doc = json.loads(out)
    jsonschema.validate(doc, json.loads(SCHEMA.read_text()))
    results = doc["runs"][0]["results"]
    assert {"ACL603", "ACL502", "E212"} <= {r["ruleId"] for r in results}
    rules = doc["runs"][0]["tool"]["driver"]["rules"]
    assert all(rules[r["ruleIndex"]]["id"] == r["ruleId"] for r in results)


# ---- layering ------------------------------------------------------------------------------------

def test_lint_never_imports_cvxpy_or_matplotlib(tmp_path):
    path = write(tmp_path, "a.acl", FAILING)
    code = ("import sys\nfrom acl.cli import main\nrc = main(['lint', '--format', 'json', %r])\n"
            "heavy = sorted(m for m in sys.modules if m.split('.')[0] in ('cvxpy', 'matplotlib'))\n"
            "sys.stderr.write('HEAVY=' + ','.join(heavy) + ' RC=' + str(rc))\n") % path
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])})
    assert "HEAVY= RC=1" in proc.stderr, proc.stderr[-2000:]


def test_list_rules_names_every_rule(capsys):
    rc, out, _ = run(capsys, "--list-rules")
    assert rc == 0 and "ACL101  resonance-outside-band" in out and "ACL900" in out


def test_build_and_hidden_folders_are_not_searched(tmp_path, capsys):
    write(tmp_path, "d/build/lib/x.acl", FAILING)
    write(tmp_path, "d/.venv/y.acl", FAILING)
    write(tmp_path, "d/ok.acl", CLEAN)
    rc, out, _ = run(capsys, "--format", "concise", str(tmp_path / "d"))
    assert rc == 0 and "1 file" in out


def test_no_rule_crashes_on_the_bad_corpus_or_the_examples(capsys):
    root = Path(__file__).resolve().parents[1]
    dirs = [str(root / d) for d in ("tests/bad", "examples") if (root / d).is_dir()]
    if not dirs:
        pytest.skip("no tests/bad or examples folder")
    rc, out, err = run(capsys, "--format", "concise", *dirs)
    assert rc in (0, 1, 2) and "ACL999" not in out and "internal error" not in err


def test_lint_package_never_imports_the_parser_or_the_cli():
    import ast

    root = Path(__file__).resolve().parents[1] / "acl" / "lint"
    for path in root.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            for name in names:
                assert not name.startswith(("acl.syntax", "acl.cli", "acl.commands")), f"{path.name} imports {name}"


@pytest.mark.parametrize("value", ["", " , "])
def test_an_empty_select_option_is_a_usage_error_not_a_silent_pass(tmp_path, capsys, value):
    """`--select ""` (an empty CI variable) ran no rule: "All checks passed", exit 0, on a design with an error."""
    rc, out, err = run(capsys, "--select", value, write(tmp_path, "a.acl", FAILING))
    assert rc == 2 and "<--select>:1:1: error[E-USAGE]" in err and "no rule would run" in err, (out, err)


@pytest.mark.parametrize("toml", ['[lint]\nselect = []\n', '[lint]\nselect = ""\n'])
def test_an_empty_select_in_the_configuration_is_refused(tmp_path, capsys, toml):
    cfg = write(tmp_path, "acl.toml", toml)
    rc, out, err = run(capsys, "--config", cfg, write(tmp_path, "a.acl", FAILING))
    assert rc == 2 and "acl.toml:2:1: error[E-CONFIG]: `select` is empty" in err, (out, err)


def test_an_empty_config_path_is_a_usage_error(tmp_path, capsys):
    """`--config ""` silently used the configuration found by walking up instead."""
    rc, out, err = run(capsys, "--config", "", write(tmp_path, "a.acl", CLEAN))
    assert rc == 2 and "<--config>:1:1: error[E-USAGE]: --config '': an empty path" in err, (out, err)

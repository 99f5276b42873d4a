"""The bad-input corpus: every file in tests/bad/ names the diagnostics it must produce.

Each corpus file starts with ``# expect: CODE [FILE:]LINE:COL[, ...]`` (FILE relative to tests/bad,
for diagnostics located in an imported file or a CSV table, or ``<--set>``) and may carry a
``# set: NAME=VALUE`` line for command-line overrides.  The check asserts every expected
diagnostic at its exact position, and that no error of another code appears.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

import acl
from acl.design.resolve import check_design
from acl.diagnostics import DiagnosticError

BAD = Path(__file__).parent / "bad"
CORPUS = sorted(BAD.glob("*.acl"))
_EXPECT = re.compile(r"^(?P<code>[EW]\d{3})\s+(?:(?P<file>.+):)?(?P<line>\d+):(?P<col>\d+)$")


def _header(path: Path) -> tuple[list[tuple[str, str, int, int]], dict[str, str]]:
    lines = path.read_bytes().decode("utf-8", "replace").split("\n")
    assert lines[0].startswith("# expect: "), f"{path.name}: first line must be `# expect: ...`"
    expected = []
    for item in lines[0][len("# expect: "):].split(","):
        m = _EXPECT.match(item.strip())
        assert m, f"{path.name}: cannot read expectation {item!r}"
        where = m["file"] or path.name
        where = where if where.startswith("<") else os.path.realpath(BAD / where)
        expected.append((m["code"], where, int(m["line"]), int(m["col"])))
    sets = {}
    for line in lines[1:5]:
        if line.startswith("# set: "):
            name, value = line[len("# set: "):].split("=", 1)
            sets[name.strip()] = value.strip()
    return expected, sets


def _where(d) -> str:
    f = d.span.file
    return f if f.startswith("<") else os.path.realpath(f)


def test_corpus_is_large_and_covers_every_family():
    codes = {e[0] for p in CORPUS for e in _header(p)[0]}
    assert len(CORPUS) >= 40
    for family in ("E1", "E2", "E3", "E4", "E5", "W"):
        assert any(c.startswith(family) for c in codes), family


@pytest.mark.parametrize("path", CORPUS, ids=lambda p: p.stem)
def test_bad_file_reports_its_diagnostic_at_its_position(path):
    expected, sets = _header(path)
    design, diags = check_design(str(path), overrides=sets)
    got = {(d.code, _where(d), d.span.line, d.span.column) for d in diags if d.span is not None}
    for exp in expected:
        assert exp in got, f"{path.name}: missing {exp}; got {sorted(got)}"
    stray = {d.code for d in diags if d.is_error} - {e[0] for e in expected}
    assert not stray, f"{path.name}: unexpected errors {stray}: {[str(d.span) + ' ' + d.message for d in diags]}"
    if any(e[0].startswith("E") for e in expected):
        assert design is None


@pytest.mark.parametrize("path", [p for p in CORPUS if _header(p)[0][0][0].startswith("E")], ids=lambda p: p.stem)
def test_load_raises_diagnostic_error_for_bad_file(path):
    expected, sets = _header(path)
    with pytest.raises(DiagnosticError) as info:
        acl.load(str(path), overrides=sets)
    assert {e[0] for e in expected} <= {d.code for d in info.value.diagnostics}


def test_unknown_key_suggests_the_closest_key():
    _, diags = check_design(str(BAD / "name_unknown_key.acl"))
    assert diags[0].hint == "did you mean `length`?"


def test_unknown_stdlib_module_suggests_the_closest_module():
    _, diags = check_design(str(BAD / "import_missing_module.acl"))
    assert "media" in diags[0].hint


def test_text_larger_than_the_limit_is_refused_before_parsing():
    with pytest.raises(DiagnosticError) as info:
        acl.loads("#" * 2_100_000 + "\n", "big.acl")
    assert [d.code for d in info.value.diagnostics] == ["E102"]


def test_missing_file_is_an_io_error():
    with pytest.raises(DiagnosticError) as info:
        acl.load(str(BAD / "no_such_file.acl"))
    assert info.value.diagnostics[0].code == "E601"


def test_set_with_wrong_unit_hints_an_example_value():
    _, diags = check_design(str(BAD / "param_set_wrong_dimension.acl"), overrides={"gap": "5 V"})
    assert "--set gap=" in diags[0].hint


def test_failed_like_is_reported_once():
    _, diags = check_design(str(BAD / "name_like_other_kind.acl"))
    assert [d.code for d in diags].count("E207") == 1


def test_bad_set_is_reported_once_even_if_the_parameter_is_used_twice():
    _, diags = check_design(str(BAD / "param_set_wrong_dimension.acl"), overrides={"gap": "5 V"})
    assert [d.code for d in diags].count("E301") == 1


def test_transducer_without_gain_is_a_missing_key_diagnostic():
    text = "transducer t {\n  max_voltage = 20 V\n  band = 40 kHz .. 200 kHz\n}\n"
    with pytest.raises(DiagnosticError) as info:
        acl.loads(text, "no_gain.acl")
    assert [d.code for d in info.value.diagnostics] == ["E204"]


def test_parameter_cycle_is_reported_once_naming_the_whole_cycle():
    _, diags = check_design(str(BAD / "param_cycle.acl"))
    assert [d.code for d in diags] == ["E214"]
    assert "a -> b -> a" in diags[0].message


def test_overlong_drive_text_is_refused():
    from acl.syntax.parser import parse_drive

    with pytest.raises(DiagnosticError) as info:
        parse_drive("125 kHz @ 1 V + " * 1000 + "85 kHz @ 1 V", "data.csv", line=3, column=2)
    (d,) = info.value.diagnostics
    assert (d.code, d.span.file, d.span.line, d.span.column) == ("E101", "data.csv", 3, 2)


def test_drive_syntax_error_points_into_the_data_cell():
    from acl.design.drives import drive_from_text

    with pytest.raises(DiagnosticError) as info:
        drive_from_text("125 kHz 4 V", "data.csv", line=7, column=3)
    (d,) = info.value.diagnostics
    assert (d.code, d.span.file, d.span.line) == ("E111", "data.csv", 7)
    assert d.span.column > 3

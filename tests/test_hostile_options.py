"""Conflicting and repeated options, duplicated inputs (hostile pass over every subcommand).

Before: a single-valued option given twice kept the last value silently (`--program stroke --program
ramp` compiled ramp, `-o a.csv -o b.csv` wrote b.csv); `--program ""` compiled the design's first
program; `acl fit D data.csv data.csv` counted every row twice (every interval sqrt(2) too narrow, and
on the Fig. 2 cantilever data a spurious `bubble_shrinkage` was selected).
"""
from __future__ import annotations

import os
import shutil

import pytest

from acl.cli import main
from acl.diagnostics import DiagnosticError

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
EX = os.path.join(ROOT, "examples")
DATA = os.path.join(ROOT, "samples")
CSV = os.path.join(ROOT, "tests", "hostile", "inputs", "data_ok.csv")


@pytest.mark.parametrize("argv, option", [
    (["compile", "{EX}/fig2_stroke.acl", "--program", "stroke", "--program", "ramp", "-o", "{T}/o"], "--program"),
    (["compile", "{EX}/fig2_stroke.acl", "--program=stroke", "--program=ramp", "-o", "{T}/o"], "--program"),
    (["synth", "{D}/fit_cantilever.acl", "-o", "{T}/a.csv", "-o{T}/b.csv", "--voltages", "0V..1V:2"], "--output"),
    (["sweep", "{D}/sweep_cantilever.acl", "--vary", "radius=9um..11um:2", "--samples", "5", "--samples", "6",
      "-o", "{T}/a.csv"], "--samples"),
    (["analyze", "--no-snap", "--at", "125 kHz @ 2 V", "--at", "125 kHz @ 3 V", "{EX}/fig2_stroke.acl"], "--at"),
    (["fit", "{D}/fit_cantilever.acl", CSV, "--seed", "1", "--seed", "2"], "--seed"),
    (["check", "--output-format", "json", "--output-format", "text", "{EX}/fig2_stroke.acl"], "--output-format"),
])
def test_a_single_valued_option_given_twice_is_a_usage_error(tmp_path, capsys, argv, option):
    argv = [a.replace("{EX}", EX).replace("{D}", DATA).replace("{T}", str(tmp_path)) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"<{option}>:1:1: error[E-USAGE]: {option} given twice" in err, err
    assert not os.listdir(tmp_path)


@pytest.mark.parametrize("argv, full", [
    (["compile", "{EX}/fig2_stroke.acl", "--prog", "stroke", "-o", "{T}/o"], "--program"),
    (["compile", "{EX}/fig2_stroke.acl", "--prog=stroke", "-o", "{T}/o"], "--program"),
    # `check` has no --output: argparse took `--output json` for --output-format json
    (["check", "{EX}/fig2_stroke.acl", "--output", "json"], "--output-format"),
    (["fit", "{D}/fit_cantilever.acl", CSV, "--effect", "drift", "--calibrated", "{T}/cal.acl"], "--effects"),
    (["synth", "{D}/fit_cantilever.acl", "-o", "{T}/a.csv", "--voltages", "0V..1V:2", "--max-seg", "3"],
     "--max-segments"),
    (["sweep", "{D}/sweep_cantilever.acl", "--vary", "radius=9um..11um:2", "--sampl", "5", "-o", "{T}/a.csv"],
     "--samples"),
    (["--vers"], "--version"),
])
def test_an_abbreviated_option_is_an_unknown_option(tmp_path, capsys, argv, full):
    """argparse took a unique prefix for the option (`--prog` for `--program`): a script written so
    breaks, or changes meaning, the day a new option shares the prefix.  Now it is E-USAGE, exit 2,
    with the full name suggested, and nothing is written."""
    argv = [a.replace("{EX}", EX).replace("{D}", DATA).replace("{T}", str(tmp_path)) for a in argv]
    with pytest.raises(SystemExit) as exited:
        main(argv)
    assert exited.value.code == 2
    err = capsys.readouterr().err
    given = next(a for a in argv if a.split("=")[0] != full and full.startswith(a.split("=")[0])).split("=")[0]
    assert f"<{given}>:1:1: error[E-USAGE]: unrecognized arguments: {given}" in err, err
    assert f"did you mean `{full}`?" in err, err
    assert "Traceback" not in err
    assert not os.listdir(tmp_path)


def test_every_parser_refuses_abbreviations():
    """The root parser and every subcommand's (including placeholders) are built with allow_abbrev=False."""
    from acl.cli import COMMANDS, build_parser

    for name in COMMANDS:
        parser = build_parser([name])
        assert parser.allow_abbrev is False
        sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
        assert all(p.allow_abbrev is False for p in sub.choices.values()), name


def test_repeatable_options_and_flags_may_repeat(tmp_path, capsys):
    """--set and --path append, -q is a flag: repeating them is no conflict."""
    assert main(["check", "-q", "-q", "--set", "dwell=100ms", "--path", EX, "--path", EX,
                 os.path.join(EX, "fig4_facing_pair.acl"), "--set", "gap=30um"]) == 0, capsys.readouterr()
    from acl.cli import build_parser, repeated_option

    parser = build_parser(["compile"])
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction").choices["compile"]
    # a value that looks like an option is a value: `--set -o` is not a second -o; after `--` nothing counts
    assert repeated_option(sub, ["x.acl", "-o", "a", "--set", "-o", "--robust", "--band-samples", "3"]) is None
    assert repeated_option(sub, ["x.acl", "-o", "a", "--", "-o", "b"]) is None
    assert repeated_option(sub, ["x.acl", "--robust", "--robust", "worst"]) == ("--robust", ["", "worst"])


def test_an_empty_program_name_is_not_the_first_program(tmp_path, capsys):
    assert main(["compile", os.path.join(EX, "fig2_stroke.acl"), "--program", "", "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "<--program>:1:1: error[E-COMPILE-PROGRAM]: no program named ''" in err
    assert not os.listdir(tmp_path)


def test_the_same_data_file_twice_is_refused(tmp_path, capsys):
    shutil.copy(CSV, tmp_path / "d.csv")
    d = os.path.join(DATA, "fit_cantilever.acl")
    assert main(["fit", d, str(tmp_path / "d.csv"), str(tmp_path / "." / "d.csv"), "--free", "gamma",
                 "--report", str(tmp_path / "rep"), "--calibrated", str(tmp_path / "cal.acl")]) == 2
    err = capsys.readouterr().err
    assert "d.csv:1:1: error[E-USAGE]: data file" in err and "given twice" in err
    assert sorted(os.listdir(tmp_path)) == ["d.csv"]
    # the Python API (run_fit) refuses it too, at the second file
    from acl.fit import run_fit

    with pytest.raises(DiagnosticError) as exc:
        run_fit(d, [str(tmp_path / "d.csv"), str(tmp_path / "d.csv")], free=("gamma",))
    diag = exc.value.diagnostics[0]
    assert diag.code == "E801" and "given twice" in diag.message and diag.span.line == 1
    # two different files with the same rows are two measurements: allowed
    shutil.copy(CSV, tmp_path / "e.csv")
    assert run_fit(d, [str(tmp_path / "d.csv"), str(tmp_path / "e.csv")], free=("gamma",)).problem.y.size == 2 * \
        run_fit(d, [str(tmp_path / "d.csv")], free=("gamma",)).problem.y.size


@pytest.mark.parametrize("argv, option, text", [
    (["check", "--set", "dwell=1s", "--set", "dwell=2s", "{EX}/fig2_stroke.acl"], "--set",
     "--set dwell given twice ('1 s', then '2 s')"),
    (["synth", "{D}/fit_cantilever.acl", "-o", "{T}/s.csv", "--voltages", "0V..2V:3",
      "--effect", "drive_saturation=v_sat:8V", "--effect", "drive_saturation=v_sat:9V"], "--effect",
     "--effect drive_saturation given twice"),
    (["synth", "{D}/fit_cantilever.acl", "-o", "{T}/s.csv", "--voltages", "0V..2V:3",
      "--sweep", "length=40um,50um", "--sweep", "length=60um"], "--sweep", "--sweep length given twice"),
])
def test_a_name_given_twice_in_a_repeatable_option_is_a_usage_error(tmp_path, capsys, argv, option, text):
    """The second value of the same parameter or effect silently replaced the first (sweep --vary/--tolerance
    already refused it)."""
    argv = [a.replace("{EX}", EX).replace("{D}", DATA).replace("{T}", str(tmp_path)) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"<{option}>:1:1: error[E-USAGE]: {text}" in err, err
    assert not os.listdir(tmp_path)


@pytest.mark.parametrize("extra, option, text", [
    (["--interval", "1e308s"], "--interval", "beyond the 1e+09 s a data file may hold"),
    (["--observe", "deflection,deflection"], "--observe", "--observe deflection given twice"),
])
def test_synth_refuses_data_acl_fit_would_refuse_or_double_count(tmp_path, capsys, extra, option, text):
    """`--interval 1e308s` wrote times 1e+308 and inf, which acl fit refuses (E806); `--observe d,d` wrote every
    row twice, which acl fit counts as two measurements."""
    rc = main(["synth", os.path.join(DATA, "fit_cantilever.acl"), "-o", str(tmp_path / "s.csv"),
               "--voltages", "0V..2V:3", *extra])
    err = capsys.readouterr().err
    assert rc == 2 and f"<{option}>:1:1: error[E-USAGE]" in err and text in err, err
    assert not os.listdir(tmp_path)


# ------------------------------------------------------------------ one exit code for a bad option value
# docs/language.md (exit codes): 0 clean, 1 errors in a design, 2 usage or I/O error.  Before, an error in
# a --set value was exit 1 (it reached the loader, as a design's own errors do) while the same error in
# --vary, --at or --tolerance was exit 2; synth's --sweep was also reported at <--set>.
@pytest.mark.parametrize("argv, where, code", [
    (["check", "{EX}/fig4_facing_pair.acl", "--set", "gapp=20um"], "<--set>:1:1", "E211"),
    (["check", "{EX}/fig4_facing_pair.acl", "--set", "gap=3V"], "<--set>:1:1", "E301"),
    (["check", "{EX}/fig4_facing_pair.acl", "--set", "gap=(((("], "<--set>:1:1", "E212"),
    (["check", "{EX}/fig4_facing_pair.acl", "--set", "gap=abc"], "<--set gap>:1:20", "E201"),
    (["show", "{EX}/fig4_facing_pair.acl", "--set", "gap=3V"], "<--set>:1:1", "E301"),
    (["analyze", "{EX}/fig4_facing_pair.acl", "--set", "gap=3V"], "<--set>:1:1", "E301"),
    (["analyze", "{EX}/fig4_facing_pair.acl", "--at", "85 V @ 5 kHz"], "<--at>:1:1", "E301"),
    (["lint", "{EX}/fig4_facing_pair.acl", "--set", "gap=3V"], "<--set>:1:1", "E301"),
    (["compile", "{EX}/fig3_three_orifice.acl", "--program", "rectangle", "--set", "radiuss=3um", "-o", "{T}/o"],
     "<--set>:1:1", "E211"),
    (["compile", "{EX}/fig3_three_orifice.acl", "--program", "nope", "-o", "{T}/o"], "<--program>:1:1",
     "E-COMPILE-PROGRAM"),
    (["sweep", "{EX}/fig4_facing_pair.acl", "--set", "gap=3V", "--vary", "reach=20um..30um:2", "-o", "{T}/a.csv"],
     "<--set>:1:1", "E301"),
    (["sweep", "{EX}/fig4_facing_pair.acl", "--vary", "gap=20V..30V:2", "-o", "{T}/a.csv"], "<--vary>:1:5", "E301"),
    (["synth", "{EX}/fig4_facing_pair.acl", "-o", "{T}/a.csv", "--sweep", "gapp=20um,30um"], "<--sweep>:1:1", "E211"),
    (["synth", "{EX}/fig4_facing_pair.acl", "-o", "{T}/a.csv", "--sweep", "gap=20V,30V"], "<--sweep>:1:1", "E301"),
    (["synth", "{EX}/fig4_facing_pair.acl", "-o", "{T}/a.csv", "--noise", "3V"], "<--noise>:1:1", "E-USAGE"),
    (["fit", "{D}/fit_cantilever.acl", CSV, "--free", "nosuch"], "<--free>:1:1", "E-USAGE"),
])
def test_an_error_in_an_option_value_exits_2_on_every_command(tmp_path, capsys, argv, where, code):
    argv = [a.replace("{EX}", EX).replace("{D}", DATA).replace("{T}", str(tmp_path)) for a in argv]
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert f"{where}: error[{code}]" in (out if argv[0] == "lint" else err), (out, err)     # lint: findings on stdout
    assert not os.listdir(tmp_path)


def test_an_override_that_breaks_the_design_is_an_error_in_the_design(capsys):
    """The contrast: a valid --set value the design cannot take (orifices merge) is located in the design: exit 1."""
    assert main(["check", os.path.join(EX, "fig4_facing_pair.acl"), "--set", "gap=0um"]) == 1
    lines = open(os.path.join(EX, "fig4_facing_pair.acl")).read().splitlines()
    line = next(i for i, t in enumerate(lines, 1) if t.startswith("capsule right"))
    assert f"fig4_facing_pair.acl:{line}:1: error[E403]" in capsys.readouterr().err


def test_exit_code_of_an_option_located_error():
    from acl.commands._common import exit_code
    from acl.diagnostics import Span, error, warning

    at = lambda f: Span(file=f, line=1, column=1)          # noqa: E731
    assert exit_code([error("E301", "x", at("<--set>"))]) == 2
    assert exit_code([error("E201", "x", at("<--set gap>"))]) == 2
    assert exit_code([error("E301", "x", at("design.acl"))]) == 1
    assert exit_code([warning("W1", "x", at("<--set>"))]) == 0

"""Defects found by the third hardening pass (helper harden3), each pinned exactly; the hostile corpus
(tests/test_hostile_corpus.py, tests/hostile/) runs the new inputs through every command as well."""
from __future__ import annotations

import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
INPUTS = Path(__file__).parent / "hostile" / "inputs"
EXAMPLES = ROOT / "examples"


def _main(argv, capsys):
    from acl.cli import main

    capsys.readouterr()
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


# -- compile --band-samples with an absurd declared spread ------------------------------------------------------

def test_an_absurd_spread_refuses_the_error_band_before_planning(tmp_path, capsys):
    """`gamma +- 1e20 N/V^2` (finite) compiled with the default band took ~20 s per draw (every draw lost the
    equilibrium at all 100 waypoints), so up to --band-samples 10000 draws ran for days; --robust already refused it."""
    code, out, err = _main(["compile", INPUTS / "unc_sd_absurd.acl", "--band-samples", "2", "-o", tmp_path / "o"], capsys)
    assert code == 1
    assert "unc_sd_absurd.acl:16:3: error[E-SCHED-UNCERTAINTY]: step 1: follow act: --band-samples: at 1 sigma" in err
    assert "--band-samples 0" in err and "`gamma +- 1e+20 N/V^2`" in err
    assert not (tmp_path / "o").exists()


# -- a negative thrust coefficient -------------------------------------------------------------------------------

def test_a_negative_thrust_is_e401(capsys):
    """`thrust = gamma` with gamma < 0 reached the path solver (cvxpy 'Solution may be inaccurate' warnings,
    E-SCHED-SOLVER 'report this design'); gamma of paper Eq. (3) is a magnitude."""
    code, out, err = _main(["check", INPUTS / "unc_gain_huge_used.acl", "--set", "gamma=-1e-3N/V^2"], capsys)
    assert code == 1
    assert "unc_gain_huge_used.acl:11:46: error[E401]: act.thrust must not be negative" in err


def test_an_inaccurate_solve_warns_nobody_but_is_reported():
    """cvxpy's UserWarning 'Solution may be inaccurate' reached stderr (gamma = 1e10 N/V^2); the status says it."""
    from acl.schedule.solve import solve

    class Fake:
        status, value, solver_stats = None, 1.0, None

        def is_dcp(self):
            return True

        def is_qp(self):
            return True

        def solve(self, solver, **kw):
            warnings.warn("Solution may be inaccurate. Try another solver, adjusting the solver settings, "
                          "or solve with verbose=True for more information.", UserWarning)
            self.status = "optimal_inaccurate"

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = solve(Fake(), "test", solvers=("CLARABEL",))
    assert res.status == "optimal_inaccurate" and res.ok
    assert not caught


# -- declarations nothing uses are still checked ----------------------------------------------------------------

def test_an_unused_transducer_or_medium_is_checked_like_a_used_one(tmp_path, capsys):
    """A wrong value in a transducer or medium declared but not `use`d passed `acl check` (exit 0)."""
    f = tmp_path / "unused.acl"
    f.write_text("import stdlib.media\nimport stdlib.transducers\nuse medium media.pbs\n"
                 "use transducer transducers.contact_piezo\n"
                 "transducer spare like transducers.contact_piezo { max_voltage = -5 V }\n"
                 "transducer empty_band like transducers.contact_piezo { band = 200 kHz .. 100 kHz }\n"
                 "medium thick like media.pbs { density = -1000 kg/m^3 }\n")
    code, out, err = _main(["check", f], capsys)
    assert code == 1
    found = [line.split(": ", 1)[0].rsplit("/", 1)[-1] + " " + line.split("[", 1)[1].split("]")[0]
             for line in err.splitlines() if "error[" in line]
    assert found == ["unused.acl:5:65 E401", "unused.acl:6:63 E306", "unused.acl:7:41 E401"]


def test_a_good_unused_transducer_is_only_a_lint_warning(tmp_path, capsys):
    f = tmp_path / "spare.acl"
    f.write_text("import stdlib.transducers\nuse transducer transducers.contact_piezo\n"
                 "transducer spare like transducers.contact_piezo { max_voltage = 5 V }\n")
    assert _main(["check", f], capsys)[0] == 0
    code, out, err = _main(["lint", f], capsys)
    assert code == 0 and "ACL601" in out + err


# -- a relative spread of a zero value -----------------------------------------------------------------------------

@pytest.mark.parametrize("text, column", [("param x = 0 um +- 3 %", 19), ("param x = 0 um +- uniform(-3 %, 3 %)", 19),
                                          ("param x = -0.0 um +- normal(1 %, 2 %)", 22)])
def test_a_relative_spread_of_zero_is_e322(text, column, tmp_path, capsys):
    """`param x = 0 um +- 3 %` silently declared no uncertainty."""
    f = tmp_path / "z.acl"
    f.write_text(text + "\n")
    code, out, err = _main(["check", f], capsys)
    assert code == 1 and f"z.acl:1:{column}: error[E322]: spread of `x`: a relative spread (%) of a zero value" in err


def test_a_zero_relative_spread_of_zero_and_an_absolute_one_are_fine(tmp_path, capsys):
    f = tmp_path / "z.acl"
    f.write_text("param x = 0 um +- 0 %\nparam y = 0 um +- 1 um\nparam z = 5 um +- 3 %\n")
    assert _main(["check", f], capsys)[0] == 0


def test_a_set_to_zero_of_a_relative_spread_is_e322_at_the_spread(tmp_path, capsys):
    f = tmp_path / "z.acl"
    f.write_text("param x = 5 um +- 3 %\n")
    code, out, err = _main(["check", f, "--set", "x=0um"], capsys)
    assert code == 1 and "z.acl:1:19: error[E322]" in err


# -- command-line option errors are located like every option diagnostic ------------------------------------------

@pytest.mark.parametrize("argv, where", [(["check", "--bogus", "x.acl"], "<--bogus>:1:1"),
                                         (["tune", "d.acl", "--target", "inf"], "<--target>:1:1"),
                                         (["sweep", "d.acl", "--samples", "nan"], "<--samples>:1:1"),
                                         (["fit"], "<DESIGN>:1:1")])
def test_argparse_errors_have_line_and_column(argv, where, capsys):
    code, out, err = _main(argv, capsys)
    assert code == 2 and err.splitlines()[-1].startswith(f"{where}: error[E-USAGE]: ") and not out


# -- synth output ------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("target", ["folder", ""])
def test_synth_into_a_folder_or_nowhere_leaves_no_temporary_file(target, tmp_path, monkeypatch, capsys):
    """`acl synth D -o DIR` wrote DIR.tmpPID and left it (and `-o ""` left .tmpPID) after a `<command line>` error."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "folder").mkdir()
    code, out, err = _main(["synth", ROOT / "samples" / "fit_cantilever.acl", "-o", target], capsys)
    assert code == 2 and "<--output>:1:1: error[E-USAGE]: cannot write" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder"] and not any((tmp_path / "folder").iterdir())


# -- synth --schedule: a tampered schedule.json -------------------------------------------------------------------------

@pytest.mark.parametrize("name, message", [
    ("bool_amp", "amplitude_v is true, not a number"),
    ("chirp_end_nan", "frequency_end_hz is not finite"),
    ("end_before_start", "end_s 0.1 s is before start_s 0.5 s"),
    ("overlap", "before the previous segment ends"),
    ("nan_phase", "phase_rad is not finite"),
    ("step_neg", "step is -1, not a step index"),
    ("goal_target_huge", "goals[0].target_um: a target beyond"),
    ("goal_unknown_capsule", "follows capsule `nosuch`"),
])
def test_a_tampered_schedule_is_refused_where_it_is_wrong(name, message, tmp_path, capsys):
    """Each was replayed with exit 0 (a target of 1e308 um printed numpy overflow warnings and RMS inf)."""
    path = INPUTS / f"sched_t_{name}.json"
    code, out, err = _main(["synth", EXAMPLES / "fig2_stroke_truth.acl", "--schedule", path, "-o", tmp_path / "r.csv"],
                           capsys)
    assert code in (1, 2) and f"sched_t_{name}.json:" in err and "error[E-SYNTH-SCHEDULE]" in err and message in err
    assert not (tmp_path / "r.csv").exists()


def test_an_intact_short_schedule_still_replays(tmp_path, capsys):
    code, out, err = _main(["synth", EXAMPLES / "fig2_stroke_truth.acl", "--schedule", INPUTS / "sched_t_ok_goal.json",
                            "-o", tmp_path / "r.csv"], capsys)
    assert code == 0 and (tmp_path / "r.csv").read_text().count("\n") == 11


# -- messages and hints ---------------------------------------------------------------------------------------------

def test_compile_of_a_design_without_programs_says_so(tmp_path, capsys):
    """It said "the design has 0 programs; choose one with --program" (help: "programs: none")."""
    code, out, err = _main(["compile", ROOT / "samples" / "fit_cantilever.acl", "-o", tmp_path / "o"], capsys)
    assert code == 1 and "fit_cantilever.acl:1:1: error[E-COMPILE-PROGRAM]" in err and "declares no program" in err


def test_a_look_alike_letter_is_named(capsys):
    code, out, err = _main(["check", INPUTS / "h3_confusable.acl"], capsys)
    assert code == 1 and "U+0430 CYRILLIC SMALL LETTER A" in err


def test_a_huge_cell_is_quoted_clipped(tmp_path, capsys):
    """A 1 MB number cell was quoted whole in E806 (1 MB of stderr)."""
    f = tmp_path / "d.csv"
    f.write_text("observable,value,unit,drive,time\ndeflection," + "9" * 1_000_000 + ",um,125 kHz @ 1 V,1\n")
    code, out, err = _main(["fit", ROOT / "samples" / "fit_cantilever.acl", f], capsys)
    assert code == 1 and "d.csv:2:12: error[E806]" in err and "characters]..." in err and len(err) < 5_000


def test_an_empty_header_cell_is_named_as_such(capsys):
    code, out, err = _main(["fit", ROOT / "samples" / "fit_cantilever.acl",
                            INPUTS / "h3_data_trailing_commas.csv"], capsys)
    assert code == 1 and ":1:34: error[E801]: a column without a name" in err


# -- what acl writes passes `acl fmt --check` -------------------------------------------------------------------------

def test_a_written_calibrated_design_is_already_formatted(tmp_path):
    """The README tour's `acl fit ... --report fit/` wrote examples/*.calibrated.acl, which docs/editor.md's
    `acl fmt --check examples stdlib` then rejected (comment alignment)."""
    from acl.fmt import canonical, format_source

    text = ("extends \"d.acl\"\n"
            "param fit_gamma = 2.4e-11 N/V^2 +- 2.3e-13 N/V^2    # 95% interval\n"
            "param fit_alpha_long_name = 0.0155 V^-2 +- 0.00037 V^-2    # 95% interval\n")
    out = canonical(text, "x.acl")
    assert out != text and format_source(out, "x.acl") == out
    assert canonical("param = (", "x.acl") == "param = ("           # unparsable: kept as built, never lost

"""Data files and the fit/synth command line: every bad cell a diagnostic with file:row:column, exit codes."""
from __future__ import annotations

import os

import numpy as np
import pytest

from acl.cli import main

HERE = os.path.dirname(__file__)
CANTILEVER = os.path.join(HERE, "..", "samples", "fit_cantilever.acl")
HEADER = "observable,value,unit,drive,time,sigma,set:length\n"
GOOD = "deflection,1.2,um,125 kHz @ 3 V,0,0.2,50 um\n"


def _csv(tmp_path, body, header=HEADER, name="d.csv"):
    p = tmp_path / name
    p.write_text(header + body)
    return str(p)


@pytest.mark.parametrize("row,column,code,words", [
    ("deflection,abc,um,125 kHz @ 3 V,0,0.2,50 um", 12, "E806", "not a number"),
    ("deflektion,1.2,um,125 kHz @ 3 V,0,0.2,50 um", 1, "E803", "did you mean `deflection`"),
    ("deflection,1.2,V,125 kHz @ 3 V,0,0.2,50 um", 16, "E804", "length"),
    ("deflection,1.2,um,125 kHz @@ 3 V,0,0.2,50 um", 19, "E1", "drive"),
    ("deflection,1.2,um,125 V @ 3 kHz,0,0.2,50 um", 19, "E802", "frequency"),
    ("deflection,,um,125 kHz @ 3 V,0,0.2,50 um", 12, "E806", "missing value"),
    ("deflection,1.2,um,125 kHz @ 3 V,0,-1,50 um", 35, "E806", "positive"),
    ("deflection,1.2,um,125 kHz @ 3 V,0,0.2,fifty", 39, "E805", "number"),
])
def test_bad_cell_is_reported_at_file_row_column_and_nothing_is_written(tmp_path, capsys, row, column, code, words):
    path = _csv(tmp_path, GOOD + row + "\n")
    rep = tmp_path / "rep"
    assert main(["fit", CANTILEVER, path, "--free", "gamma", "--report", str(rep)]) == 1
    err = capsys.readouterr().err
    assert f"{path}:3:" in err and code in err and words in err
    assert f"{path}:3:{column}" in err or code == "E1"
    assert "Traceback" not in err
    assert not rep.exists()


def test_every_bad_row_is_reported_not_only_the_first(tmp_path, capsys):
    path = _csv(tmp_path, "deflection,x,um,,0,0.2,50 um\nfoo,1,um,,0,0.2,50 um\n")
    assert main(["fit", CANTILEVER, path]) == 1
    err = capsys.readouterr().err
    assert f"{path}:2:12" in err and f"{path}:3:1" in err


def test_unknown_column_and_unknown_set_parameter_are_reported(tmp_path, capsys):
    path = _csv(tmp_path, "deflection,1,um,,0,0.2,50 um,1\n", header="observable,value,unit,drive,time,sigma,set:lenght,colour\n")
    assert main(["fit", CANTILEVER, path]) == 1
    err = capsys.readouterr().err
    assert "set:lenght" in err and "did you mean `length`" in err and "unknown column `colour`" in err


def test_override_that_breaks_the_design_points_at_the_row(tmp_path, capsys):
    path = _csv(tmp_path, GOOD + "deflection,1.2,um,125 kHz @ 3 V,1,0.2,-5 um\n")
    assert main(["fit", CANTILEVER, path, "--free", "gamma"]) == 1
    err = capsys.readouterr().err
    assert f"{path}:3:1" in err and "E805" in err


@pytest.mark.parametrize("args,words", [
    (["--free", "gamm"], "did you mean `gamma`"),
    (["--free", "length"], "changes the geometry"),
    (["--effects", "saturation"], "unknown effect"),
])
def test_bad_options_are_usage_or_design_errors_without_traceback(tmp_path, capsys, args, words):
    path = _csv(tmp_path, GOOD)
    code = main(["fit", CANTILEVER, path, *args])
    err = capsys.readouterr().err
    assert code in (1, 2) and words in err and "Traceback" not in err
    if args[0] == "--free" and args[1] == "gamm" or args[0] == "--effects":
        assert code == 2


def test_missing_data_file_is_exit_2(tmp_path, capsys):
    assert main(["fit", CANTILEVER, str(tmp_path / "nope.csv")]) == 2


def test_units_and_multi_tone_drives_are_read_in_si(tmp_path):
    import acl
    from acl.fit.data import read_data

    path = _csv(tmp_path, "deflection,1200,nm,85 kHz @ 2 V + 125 kHz @ 3000 mV,0.1\n",
                header="observable,value,unit,drive,sigma\n")
    d = read_data([path], acl.load(CANTILEVER))
    assert d.value[0] == pytest.approx(1.2e-6) and d.sigma[0] == pytest.approx(1e-10)
    assert d.tones[0] == ((85e3, 2.0), (125e3, 3.0))
    assert not d.has_time and d.sets == {}


def test_several_files_are_one_data_set_and_keep_their_row_origins(tmp_path):
    import acl
    from acl.fit.data import read_data

    a = _csv(tmp_path, GOOD, name="a.csv")
    b = _csv(tmp_path, "deflection,2,um,125 kHz @ 4 V,0.3\n", header="observable,value,unit,drive,sigma\n",
             name="b.csv")
    d = read_data([a, b], acl.load(CANTILEVER))
    assert d.n == 2 and str(d.spans[0]) == f"{a}:2:1" and str(d.spans[1]) == f"{b}:2:1"
    assert list(d.sets["length"]) == ["50 um", ""] and np.isnan(d.time[1])
    assert not d.has_time          # time effects need every row timed


def test_files_that_mix_sigma_and_no_sigma_are_refused(tmp_path, capsys):
    a = _csv(tmp_path, GOOD, name="a.csv")
    b = _csv(tmp_path, "deflection,2,um,125 kHz @ 4 V\n", header="observable,value,unit,drive\n", name="b.csv")
    assert main(["fit", CANTILEVER, a, b, "--free", "gamma"]) == 1
    assert "some files give sigma" in capsys.readouterr().err


def test_an_optional_column_once_present_is_needed_on_every_row(tmp_path, capsys):
    path = _csv(tmp_path, GOOD + "deflection,1.3,um,125 kHz @ 3 V,,0.2,50 um\n")
    assert main(["fit", CANTILEVER, path, "--free", "gamma"]) == 1
    err = capsys.readouterr().err
    assert f"{path}:3:33" in err and "missing time" in err


def test_synth_command_writes_data_the_fit_reads_back(tmp_path, capsys):
    out = tmp_path / "s.csv"
    assert main(["synth", CANTILEVER, "-o", str(out), "--effect", "drive_saturation=v_sat:6V", "--noise", "0.2um",
                 "--frequencies", "110kHz,125kHz,140kHz", "--voltages", "0V..10V:11", "--repeats", "2",
                 "--seed", "1"]) == 0
    lines = out.read_text().splitlines()
    assert lines[0].startswith("observable,value,unit,drive,time,sigma") and len(lines) == 67
    capsys.readouterr()
    assert main(["fit", CANTILEVER, str(out), "--free", "gamma", "--json"]) == 0
    import json
    report = json.loads(capsys.readouterr().out)
    assert report["effects_selected"] == ["drive_saturation"]


def test_synth_rejects_unknown_effects_and_parameters(tmp_path, capsys):
    out = tmp_path / "s.csv"
    assert main(["synth", CANTILEVER, "-o", str(out), "--effect", "drive_saturaton=v_sat:6V"]) == 2
    assert main(["synth", CANTILEVER, "-o", str(out), "--effect", "drive_saturation=vs:6V"]) == 2
    assert "did you mean `drive_saturation`" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("example,obs", [("../samples/gripper_rigid_truss.acl", "left_delta")])
def test_mechanisms_outside_the_fit_model_are_a_diagnostic_not_a_guess(tmp_path, capsys, example, obs):
    """A rigid truss along the line of attraction holds the arm: nothing the data can tell (E810)."""
    design = os.path.join(HERE, example)
    path = _csv(tmp_path, f"{obs},1,um,125 kHz @ 3 V\n", header="observable,value,unit,drive\n")
    assert main(["fit", design, path]) == 1
    err = capsys.readouterr().err
    assert "E810" in err and "Traceback" not in err


def test_a_wrong_name_repeated_on_many_rows_is_reported_once_with_a_count(tmp_path, capsys):
    """Issue 11: 18 rows naming one wrong observable are one E803 (root cause once), not 18 blocks;
    an unknown unit repeated on rows is one E804 too, while different findings stay separate."""
    rows = "".join(f"deflektion,1.{i},um,125 kHz @ 3 V,{i},0.2,50 um\n" for i in range(18))
    rows += "deflection,1,furlongz,125 kHz @ 3 V,0,0.2,50 um\n" * 3
    rows += "deflection,abc,um,125 kHz @ 3 V,0,0.2,50 um\n"
    path = _csv(tmp_path, rows)
    assert main(["fit", CANTILEVER, path]) == 1
    err = capsys.readouterr().err
    assert err.count("[E803]") == 1 and f"{path}:2:1" in err and "and 17 more rows" in err
    assert err.count("[E804]") == 1 and f"{path}:20:14" in err and "and 2 more rows (lines 21, 22)" in err
    assert err.count("[E806]") == 1 and f"{path}:23:12" in err


@pytest.mark.parametrize("rows, free", [
    ("deflection,1.0,um,125 kHz @ 2 V,1,0.05\n", "gamma"),
    ("deflection,1.0,um,125 kHz @ 2 V,1,0.05\ndeflection,4.1,um,125 kHz @ 4 V,2,0.05\n", "gamma,E"),
])
def test_no_more_rows_than_free_coefficients_is_refused_not_a_zero_wide_interval(tmp_path, capsys, rows, free):
    """One row, gamma free: exit 0 with the 95 % interval [2.423e-11, 2.423e-11] (chi2 = 0 over dof clamped to 1)."""
    from acl.cli import main

    data = tmp_path / "d.csv"
    data.write_text("observable,value,unit,drive,time,sigma\n" + rows)
    cal = tmp_path / "cal.acl"
    assert main(["fit", CANTILEVER, str(data), "--free", free,
                 "--effects", "none", "--calibrated", str(cal)]) == 1
    err = capsys.readouterr().err
    n = rows.count("\n")
    assert f"{data}:{n + 1}:1: error[E801]: {n} row" in err and "free coefficient" in err, err
    assert not cal.exists()


@pytest.mark.parametrize("value, words", [
    ("3V", "`set:length` = `3V` is a voltage [V]; parameter `length` is a length [m]"),
    ("40", "`set:length` = `40` is a plain number; parameter `length` is a length [m]"),
])
def test_an_override_of_the_wrong_dimension_is_located_at_its_cell(tmp_path, capsys, value, words):
    """Was E805 at column 1 with the hint `see <--set>:1:1`, an option acl fit does not have."""
    path = _csv(tmp_path, GOOD + f"deflection,1.2,um,125 kHz @ 3 V,0,0.2,{value}\n")
    assert main(["fit", CANTILEVER, path, "--free", "gamma", "--effects", "none"]) == 1
    err = capsys.readouterr().err
    assert f"{path}:3:39: error[E805]: {words}" in err and "<--set>" not in err, err


def test_every_override_the_design_does_not_resolve_with_is_reported(tmp_path, capsys):
    """Only the first failing override set was reported (each later one needed another run)."""
    path = _csv(tmp_path, GOOD + "deflection,1.2,um,125 kHz @ 3 V,0,0.2,3 um\n"
                + "deflection,1.2,um,125 kHz @ 3 V,0,0.2,-3 um\n" + "deflection,1.2,um,125 kHz @ 3 V,0,0.2,3 um\n")
    assert main(["fit", CANTILEVER, path, "--free", "gamma", "--effects", "none"]) == 1
    err = capsys.readouterr().err
    assert f"{path}:3:1: error[E805]: the design does not resolve with length = 3 um" in err, err
    assert f"{path}:4:1: error[E805]: the design does not resolve with length = -3 um" in err, err
    assert err.count("error[E805]") == 2


@pytest.mark.parametrize("value", ["1_000", "\u0661\u0662", "0x10", "1e", "--1"])
def test_a_value_python_reads_but_a_csv_number_is_not_is_refused(tmp_path, capsys, value):
    """`1_000` was read as 1000 and `١٢` as 12 (Python's float() accepts both)."""
    path = _csv(tmp_path, GOOD + f"deflection,{value},um,125 kHz @ 3 V,0,0.2,50 um\n")
    assert main(["fit", CANTILEVER, path, "--free", "gamma", "--effects", "none"]) == 1
    err = capsys.readouterr().err
    assert f"{path}:3:12: error[E806]: value `{value}` is not a number" in err, err


def test_an_unclosed_quote_is_located_at_the_quote(tmp_path, capsys):
    """Was `row has 2 cells, the header has 7` at column 1, the quote unnamed."""
    path = _csv(tmp_path, GOOD + 'deflection,"1.2,um,125 kHz @ 3 V,0,0.2,50 um\n')
    assert main(["fit", CANTILEVER, path, "--free", "gamma", "--effects", "none"]) == 1
    err = capsys.readouterr().err
    assert f"{path}:3:12: error[E801]: a quote opened here is not closed" in err, err


def test_a_set_column_for_a_fitted_parameter_is_refused(tmp_path, capsys):
    """`set:gamma` with --free gamma ran (exit 0): rows' designs took the column's values, the fit one fitted value."""
    body = ("deflection,0.01,um,,0,0.05,\n" + "deflection,1.0,um,125 kHz @ 2 V,1,0.05,0.01 nN/V^2\n"
            + "deflection,4.0,um,125 kHz @ 4 V,2,0.05,\n")
    path = _csv(tmp_path, body, header="observable,value,unit,drive,time,sigma,set:gamma\n")
    assert main(["fit", CANTILEVER, path, "--free", "gamma", "--effects", "none"]) == 1
    err = capsys.readouterr().err
    assert f"{path}:3:1: error[E805]: `set:gamma` gives parameter `gamma` per row, but the fit determines it" in err, err
    assert main(["fit", CANTILEVER, path, "--free", "E", "--effects", "none"]) == 0     # gamma not fitted: a row setting
    capsys.readouterr()


@pytest.mark.parametrize("column", ["set: length", "SET:length", " set:length "])
def test_a_set_column_is_read_with_blanks_and_any_case_of_set(tmp_path, column):
    """`set: length` passed the header check, then every row failed: "the design has no parameter ` length`"."""
    import acl
    from acl.fit.data import read_data

    path = _csv(tmp_path, "deflection,1.2,um,125 kHz @ 3 V,0,0.2,60 um\n",
                header=f"observable,value,unit,drive,time,sigma,{column}\n")
    data = read_data([path], acl.load(CANTILEVER))
    assert list(data.sets) == ["length"] and data.sets["length"][0] == "60 um"
    assert data.set_si["length"][0] == pytest.approx(60e-6)


def test_a_drive_listing_one_frequency_twice_is_refused_as_in_a_design(tmp_path, capsys):
    """`125 kHz @ 2 V + 125 kHz @ 1 V` was read as two tones (a design's drive refuses it, E504)."""
    path = _csv(tmp_path, GOOD + "deflection,1.2,um,125 kHz @ 2 V + 125 kHz @ 1 V,0,0.2,50 um\n")
    assert main(["fit", CANTILEVER, path, "--free", "gamma", "--effects", "none"]) == 1
    err = capsys.readouterr().err
    assert f"{path}:3:" in err and "error[E802]" in err and "lists the frequency 125 kHz twice" in err, err


@pytest.mark.parametrize("sep, words", [(";", "separated by `;`"), ("\t", "separated by tabs")])
def test_a_semicolon_or_tab_separated_file_is_named_as_such(tmp_path, capsys, sep, words):
    """A European spreadsheet's `;` CSV (or a TSV) was "unknown column `observable;value;unit;drive`"."""
    path = _csv(tmp_path, sep.join(["deflection", "1,2", "um", "125 kHz @ 3 V"]) + "\n",
                header=sep.join(["observable", "value", "unit", "drive"]) + "\n")
    assert main(["fit", CANTILEVER, path, "--free", "gamma"]) == 1
    err = capsys.readouterr().err
    assert f"{path}:1:1: error[E801]: the header is {words}, not commas" in err, err

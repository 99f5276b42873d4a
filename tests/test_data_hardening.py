"""Data files and `acl synth`/`acl fit` options under hostile input (issue 11, "Data files"):
located diagnostics, never E-INTERNAL, no numpy warnings, no unbounded memory."""
from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from acl.cli import main

ROOT = Path(__file__).resolve().parents[1]
CANTILEVER = str(ROOT / "samples" / "fit_cantilever.acl")
HEADER = "observable,value,unit,drive,time,sigma,set:length\n"
GOOD = "deflection,1.2,um,125 kHz @ 3 V,0,0.2,50 um\n"


def _fit(capsys, tmp_path, body: bytes | str, *extra):
    path = tmp_path / "d.csv"
    path.write_bytes(body if isinstance(body, bytes) else body.encode())
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # a numpy RuntimeWarning fails the test
        # --calibrated in tmp_path: a fit that wrongly succeeds must not write next to the design in samples
        code = main(["fit", CANTILEVER, str(path), "--free", "gamma", "--report", str(tmp_path / "rep"),
                     "--calibrated", str(tmp_path / "cal.acl"), *extra])
    err = capsys.readouterr().err
    assert "E-INTERNAL" not in err and "Traceback" not in err
    assert not (tmp_path / "rep").exists() and not (tmp_path / "cal.acl").exists()
    return code, err, str(path)


def test_non_utf8_byte_is_located_at_row_and_column(tmp_path, capsys):
    body = (HEADER + GOOD).encode() + "deflection,1.2,\xb5m,125 kHz @ 3 V,0,0.2,50 um\n".encode("latin-1")
    code, err, path = _fit(capsys, tmp_path, body)
    assert code == 1 and f"{path}:3:16" in err and "E807" in err and "UTF-8" in err


def test_fifo_is_reported_as_not_a_regular_file_without_blocking(tmp_path):
    fifo = tmp_path / "data.csv"
    os.mkfifo(fifo)
    r = subprocess.run([sys.executable, "-m", "acl", "fit", CANTILEVER, str(fifo)], capture_output=True, text=True,
                       timeout=60, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert r.returncode == 2 and "E601" in r.stderr and "pipe" in r.stderr and "no such file" not in r.stderr


def test_reader_refuses_a_fifo_itself(tmp_path):
    import acl
    from acl.diagnostics import DiagnosticError
    from acl.fit.data import read_data

    fifo = tmp_path / "data.csv"
    os.mkfifo(fifo)
    with pytest.raises(DiagnosticError) as exc:
        read_data([str(fifo)], acl.load(CANTILEVER))
    assert exc.value.diagnostics[0].code == "E601" and "FIFO" in exc.value.diagnostics[0].message


@pytest.mark.parametrize("row, column, code, words", [
    ("deflection,1.2,um,300 kHz @ 3 V,0,0.2,50 um", 19, "E501", "outside the band"),
    ("deflection,1.2,um,125 kHz @ 300 V,0,0.2,50 um", 19, "E502", "above the maximum"),
    ("deflection,1e308,um,125 kHz @ 3 V,0,0.2,50 um", 12, "E806", "beyond 1 m"),
    ("deflection,1.2,um,125 kHz @ 3 V,0,1e308,50 um", 35, "E806", "beyond 1 m"),
    ("deflection,1.2,um,1e308 kHz @ 3 V,0,0.2,50 um", 19, "E501", "outside the band"),
    ("deflection,1.2,um,125 kHz @ 3 V,1e300,0.2,50 um", 33, "E806", "time"),
    ("deflection,1.2,um,125 kHz @ 3 V,0,0.2,1e308 um", 1, "E805", "does not resolve"),
], ids=["above-band", "above-max-voltage", "value-1e308-um", "sigma-1e308", "drive-1e308-kHz", "time-1e300",
        "set-1e308-um"])
def test_out_of_range_cells_are_located_diagnostics_without_numpy_warnings(tmp_path, capsys, row, column, code, words):
    code_, err, path = _fit(capsys, tmp_path, HEADER + GOOD + row + "\n")
    assert code_ == 1 and f"{path}:3:{column}" in err and code in err and words in err, err


# -- acl synth -----------------------------------------------------------------------------------------

def _synth(capsys, tmp_path, *args):
    out = tmp_path / "s.csv"
    code = main(["synth", CANTILEVER, "-o", str(out), *args])
    err = capsys.readouterr().err
    assert "E-INTERNAL" not in err and "Traceback" not in err
    return code, err, out


def test_huge_voltage_ramp_is_a_limit_diagnostic_not_out_of_memory(tmp_path, capsys):
    code, err, out = _synth(capsys, tmp_path, "--voltages", "0V..10V:100000000")
    assert code == 2 and "2,000,000" in err and not out.exists()


def test_experiment_larger_than_fit_reads_is_refused(tmp_path, capsys):
    code, err, out = _synth(capsys, tmp_path, "--voltages", "0V..10V:1000", "--repeats", "100000")
    assert code == 2 and "rows" in err and not out.exists()


@pytest.mark.parametrize("args, code", [
    (("--frequencies", "300kHz"), "E501"), (("--voltages", "0V..300V:3"), "E502"),
])
def test_synth_drive_outside_the_transducer_is_a_diagnostic(tmp_path, capsys, args, code):
    rc, err, out = _synth(capsys, tmp_path, *args)
    assert rc == 2 and code in err and not out.exists()


def test_effect_without_a_value_is_refused_not_silently_null(tmp_path, capsys):
    rc, err, out = _synth(capsys, tmp_path, "--effect", "drive_saturation")
    assert rc == 2 and "drive_saturation=v_sat:" in err and not out.exists()
    rc, err, out = _synth(capsys, tmp_path, "--effect", "offset_drift=offset:0um")
    assert rc == 2 and "plants nothing" in err and not out.exists()
    rc, err, out = _synth(capsys, tmp_path, "--effect", "drive_saturation=v_sat:0V")
    assert rc == 2 and "positive" in err and not out.exists()


@pytest.mark.parametrize("effect, column, got, declared", [
    ("drive_saturation=v_sat:8um", 24, "is a length", "voltage"),          # issue 11: was planted as 8e-6 V
    ("drive_saturation=v_sat:8", 24, "is a plain number", "voltage"),
    ("offset_drift=offset:0.5um, drift:3V", 34, "is a voltage", "speed"),
    ("neighbour_drag=plateau:5V", 24, "is a voltage", "length"),
    ("large_deflection=elastica_weight:0.5um", 34, "is a length", "a plain number"),
])
def test_effect_value_in_the_wrong_unit_is_a_located_usage_error(tmp_path, capsys, effect, column, got, declared):
    """Each --effect value's unit is checked against the unit acl.fit.effects declares for the
    parameter; the diagnostic points at the value's column in the option's text."""
    rc, err, out = _synth(capsys, tmp_path, "--effect", effect)
    assert rc == 2 and not out.exists()
    assert f"<--effect>:1:{column}: error[E-USAGE]" in err and got in err and declared in err


@pytest.mark.parametrize("args, option, got, need", [
    (["--noise", "0.05"], "--noise", "is a plain number", "give a length [m], e.g. 0.05um"),   # was "`0.05` is not in m"
    (["--noise", "5V"], "--noise", "is a voltage", "give a length"),
    (["--frequencies", "125,130kHz"], "--frequencies", "`125` is a plain number", "give a frequency"),
    (["--voltages", "0..2V:3"], "--voltages", "`0` is a plain number", "give a voltage"),
    (["--interval", "2"], "--interval", "is a plain number", "give a time"),
])
def test_quantity_option_without_its_unit_names_the_option_and_an_example(tmp_path, capsys, args, option, got, need):
    rc, err, out = _synth(capsys, tmp_path, *args)
    assert rc == 2 and not out.exists()
    assert f"<{option}>:1:1: error[E-USAGE]: {option} `" in err and got in err and need in err


def test_effect_values_in_their_declared_units_are_planted(tmp_path, capsys):
    rc, err, out = _synth(capsys, tmp_path, "--effect", "offset_drift=offset:0.5um,drift:10nm/s",
                          "--effect", "neighbour_drag=plateau:5um", "--effect", "stiffness_scale=e_scale:0.7")
    assert rc == 0 and out.exists(), err


def test_planted_effect_changes_the_data_and_is_announced(tmp_path, capsys):
    rc, err, plain = _synth(capsys, tmp_path, "--voltages", "0V..8V:5")
    base = plain.read_text()
    rc, err, out = _synth(capsys, tmp_path, "--voltages", "0V..8V:5", "--effect", "drive_saturation=v_sat:6V")
    assert rc == 0 and "planted drive_saturation: v_sat = 6" in err
    assert out.read_text() != base
    import json

    assert main(["synth", CANTILEVER, "-o", str(out), "--voltages", "0V..8V:5", "--effect", "drive_saturation=v_sat:6V",
                 "--output-format", "json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc == {"output": str(out), "rows": 5, "planted": {"drive_saturation": {"v_sat": 6.0}}}


def test_fit_warns_when_nothing_is_free(tmp_path, capsys):
    data = tmp_path / "s.csv"
    assert main(["synth", CANTILEVER, "-o", str(data), "--voltages", "0V..8V:5", "--noise", "0.05um"]) == 0
    capsys.readouterr()
    assert main(["fit", CANTILEVER, str(data), "--effects", "none"]) == 0
    err = capsys.readouterr().err
    assert "W810" in err and "nothing is free" in err
    assert main(["fit", CANTILEVER, str(data), "--effects", "none", "--free", "gamma"]) == 0
    out, err = capsys.readouterr()
    assert "W810" not in err
    assert "…" not in out and "gamma" in out             # the fit tables are whole when piped (not cut at 80)


@pytest.mark.parametrize("free, message", [
    ("q:", "--free q:: give a capsule after `q:`"),
    ("f0:", "--free f0:: give a capsule after `f0:`"),
    ("f0:nosuch", "--free f0:nosuch: no capsule `nosuch`"),
    ("GAMMA", "--free GAMMA: not a design parameter nor a model coefficient"),
])
def test_bad_free_names_are_usage_errors_at_the_option(free, message, capsys):
    data = ROOT / "tests" / "hostile" / "inputs" / "data_ok.csv"
    assert main(["fit", CANTILEVER, str(data), "--effects", "none", "--free", free]) == 2
    err = capsys.readouterr().err
    assert f"<--free>:1:1: error[E-USAGE]: {message}" in err, err
    hint = err.split("help:", 1)[-1]
    names = [n.strip() for n in hint.split("names:", 1)[-1].split(",")] if "names:" in hint else []
    assert len(names) == len(set(names)), f"a name listed twice in the hint: {hint}"


# -- a sigma no measurement has: weights of 1e306 overflowed the least-squares sums ---------------------

@pytest.mark.parametrize("sigma, unit", [("1e-300", "um"), ("1e-10", "nm"), ("0.0001", "pm")])
def test_a_sigma_below_a_femtometre_is_a_located_diagnostic_not_an_overflowing_fit(tmp_path, capsys, sigma, unit):
    """Was exit 0 with numpy overflow warnings, an interval of `[-, -]` and a calibrated design written."""
    row = f"deflection,1.2,{unit},125 kHz @ 3 V,0,{sigma},50 um\n".replace(",1.2,", ",1200," if unit == "nm" else ",1.2,")
    code, err, path = _fit(capsys, tmp_path, HEADER + GOOD + row)
    column = len(row.split(sigma)[0]) + 1
    assert code == 1 and f"{path}:3:{column}: error[E806]: sigma {sigma} {unit} is below 1e-15 m" in err, err


def test_a_sigma_of_a_femtometre_is_read(tmp_path):
    import acl
    from acl.fit.data import read_data

    path = tmp_path / "d.csv"
    path.write_text(HEADER + GOOD + "deflection,1.2,um,125 kHz @ 3 V,0,1e-9,50 um\n")
    assert read_data([str(path)], acl.load(CANTILEVER)).n == 2


@pytest.mark.parametrize("noise", ["1e-300um", "5m", "1e300um"])
def test_synth_noise_the_fit_would_refuse_is_a_usage_error_with_a_schedule_too(tmp_path, capsys, noise):
    """`--noise 5m` with --schedule wrote rows of 5e6 um (E806 in `acl fit`): the limit was checked only without it."""
    rc, err, out = _synth(capsys, tmp_path, "--noise", noise)
    assert rc == 2 and "<--noise>:1:1: error[E-USAGE]" in err and not out.exists(), err
    sched = tmp_path / "s.json"
    sched.write_text('{"version": "1.1", "segments": [{"start_s": 0, "tones": [{"frequency_hz": 125e3, "amplitude_v": 2}]}]}')
    rc, err, out = _synth(capsys, tmp_path, "--schedule", str(sched), "--noise", noise)
    assert rc == 2 and "<--noise>:1:1: error[E-USAGE]" in err and "1e-15 m" in err and not out.exists(), err


@pytest.mark.parametrize("args, option, words", [
    (["--interval", "0s"], "--interval", "--interval 0s: a positive, finite time"),       # was at <--noise>
    (["--interval", "1e999s"], "--interval", "a positive, finite time"),
    (["--frequencies", ""], "--frequencies", "give one frequency at least"),            # was at <command line>
    (["--repeats", "0"], "--repeats", "--repeats 0: at least 1"),                         # was at <command line>
    (["--noise=-1um"], "--noise", "the noise is 0 or from 1e-15 m to 1 m"),
])
def test_each_synth_option_is_refused_at_its_own_name(tmp_path, capsys, args, option, words):
    rc, err, out = _synth(capsys, tmp_path, *args)
    assert rc == 2 and f"<{option}>:1:1: error[E-USAGE]: " in err and words in err and not out.exists(), err


def test_an_effect_planting_values_the_fit_refuses_writes_nothing(tmp_path, capsys):
    """`offset_drift=drift:1e300 um/s` wrote values of 1e300 um, exit 0: rows `acl fit` refuses (E806).  Such a
    drift is now refused at its value, outside its physical range (acl.design.core.EFFECT_RANGES, as a declared
    effect); a drift inside it whose rows still pass 1 m over the run is refused as rows `acl fit` cannot read."""
    rc, err, out = _synth(capsys, tmp_path, "--voltages", "0V..8V:3", "--effect", "offset_drift=drift:1e300 um/s")
    assert rc == 2 and "<--effect>:1:20: error[E-USAGE]" in err and "outside its physical range" in err, err
    assert not out.exists()
    rc, err, out = _synth(capsys, tmp_path, "--voltages", "0V..8V:3", "--effect", "offset_drift=offset:1m,drift:1m/s")
    assert rc == 2 and "<--effect>:1:1: error[E-USAGE]" in err and "beyond the 1 m `acl fit` reads" in err, err
    assert not out.exists()


def test_an_effect_parameter_given_twice_is_refused(tmp_path, capsys):
    rc, err, out = _synth(capsys, tmp_path, "--effect", "drive_saturation=v_sat:8V,v_sat:9V")
    assert rc == 2 and "<--effect>:1:1: error[E-USAGE]" in err and "`v_sat` given twice" in err and not out.exists()


def test_an_effect_value_that_is_no_quantity_is_located_in_the_option(tmp_path, capsys):
    """`v_sat:inf V` was reported at `<command line>`."""
    rc, err, out = _synth(capsys, tmp_path, "--effect", "drive_saturation=v_sat:inf V")
    assert rc == 2 and "<--effect>:1:24: error[E-USAGE]: --effect 'drive_saturation=v_sat:inf V': `v_sat`" in err, err


def test_the_rows_acl_fit_refuses_are_found_before_writing():
    """The guard both synth paths (planted effects, a replayed schedule) apply before writing a CSV."""
    from types import SimpleNamespace

    import numpy as np

    from acl.commands.synth import _first_unreadable

    assert _first_unreadable(SimpleNamespace(value=np.array([0.0, 1e-6, 1.0]))) is None
    assert _first_unreadable(SimpleNamespace(value=np.array([0.0, -2.0, np.inf]))) == 1
    assert _first_unreadable(SimpleNamespace(value=np.array([1e-6, np.nan]))) == 1

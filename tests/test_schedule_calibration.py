"""Reading a measured frequency sweep CSV (acl.schedule.calibration)."""
import numpy as np
import pytest

from acl.diagnostics import DiagnosticError
from acl.schedule.calibration import read_sweep_csv


def write(tmp_path, text):
    p = tmp_path / "sweep.csv"
    p.write_text(text)
    return str(p)


def test_units_and_voltage_turn_displacements_into_metres_per_volt_squared(tmp_path):
    t = read_sweep_csv(write(tmp_path, "# voltage: 10 V\nfrequency [kHz], dx [um], dy [nm]\n"
                                       "40, 1.0, 500\n41, -2.0, 0\n"))
    assert np.allclose(t.frequencies, [40e3, 41e3])
    assert np.allclose(t.gains, [[1e-6 / 100, 0.5e-6 / 100], [-2e-6 / 100, 0.0]])


def test_voltage_column_replaces_the_comment(tmp_path):
    t = read_sweep_csv(write(tmp_path, "frequency_hz,dx_um,dy_um,voltage [V]\n1000,4,0,2\n"))
    assert np.allclose(t.gains, [[1e-6, 0.0]])


def diag(tmp_path, text):
    with pytest.raises(DiagnosticError) as exc:
        read_sweep_csv(write(tmp_path, text))
    return exc.value.diagnostics[0]


def test_non_numeric_cell_points_at_its_row_and_column(tmp_path):
    d = diag(tmp_path, "# voltage: 10 V\nfrequency [kHz], dx [um], dy [um]\n40, 1.0, 0\n41, oops, 0\n")
    assert d.code == "E-CSV-VALUE"
    assert (d.span.line, d.span.column) == (4, 5)
    assert d.span.file.endswith("sweep.csv")


def test_missing_unit_is_a_diagnostic_on_the_header(tmp_path):
    d = diag(tmp_path, "# voltage: 10 V\nfrequency, dx [um], dy [um]\n40, 1, 0\n")
    assert d.code == "E-CSV-UNIT" and d.span.line == 2 and d.hint


def test_missing_sweep_voltage_is_a_diagnostic(tmp_path):
    d = diag(tmp_path, "frequency [kHz], dx [um], dy [um]\n40, 1, 0\n")
    assert d.code == "E-CSV-VOLTAGE"


def test_missing_column_is_a_diagnostic(tmp_path):
    d = diag(tmp_path, "# voltage: 1 V\nfrequency [kHz], dx [um]\n40, 1\n")
    assert d.code == "E-CSV-HEADER" and "dy" in d.message


def test_unsorted_frequencies_are_a_diagnostic(tmp_path):
    d = diag(tmp_path, "# voltage: 1 V\nfrequency [kHz], dx [um], dy [um]\n41, 1, 0\n40, 1, 0\n")
    assert d.code == "E-CSV-ORDER" and d.span.line == 4


def test_short_row_is_a_diagnostic(tmp_path):
    d = diag(tmp_path, "# voltage: 1 V\nfrequency [kHz], dx [um], dy [um]\n40, 1\n")
    assert d.code == "E-CSV-ROW" and d.span.line == 3


def test_unreadable_file_is_a_diagnostic(tmp_path):
    with pytest.raises(DiagnosticError) as exc:
        read_sweep_csv(str(tmp_path / "missing.csv"))
    assert exc.value.diagnostics[0].code == "E-CSV-READ"


def test_file_without_data_rows_is_a_diagnostic(tmp_path):
    d = diag(tmp_path, "# voltage: 1 V\nfrequency [kHz], dx [um], dy [um]\n")
    assert d.code == "E-CSV-EMPTY"

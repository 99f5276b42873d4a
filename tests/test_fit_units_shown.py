"""A calibrated parameter is printed in a conventional unit (issue 28), not in SI base units: `acl fit`'s table and
the calibrated design file and the band cause compile prints (acl.units.conventional_unit)."""
from __future__ import annotations

import io

from acl.fit.report import render_table, shown
from acl.units import conventional_unit, parse_unit, si_unit


def test_si_base_strings_get_their_conventional_name():
    for u in ("1/V^2", "W", "Pa", "N/V^2", "N*m^2/V^2", "kg/s"):
        assert conventional_unit(si_unit(parse_unit(u)[1])) == u
    assert shown("m") == (1e6, "um") and shown("m/s") == (1e6, "um/s")
    assert conventional_unit("m^5") == "m^5"            # no conventional name: left as it is


def _report(unit, value):
    p = {"name": "q", "value": value, "unit": unit, "ci95": [value * 0.9, value * 1.1]}
    obs = {"n": 1, "rmse": 1e-7, "redchi": 1.0}
    return {"base": {"parameters": [p], "per_observable": {"d": obs}, "redchi": 1.0},
            "final": {"parameters": [p], "per_observable": {"d": obs}, "redchi": 1.0},
            "rows": 1, "rmse_before": 1e-7, "rmse_after": 1e-7, "effects": [], "selected": []}


def _table(report) -> str:
    from rich.console import Console

    buf = io.StringIO()
    try:
        render_table(report, Console(file=buf, width=200))
    except (KeyError, TypeError):
        pass                                             # only the parameter table is looked at
    return buf.getvalue()


def test_fit_table_prints_conventional_units():
    text = _table(_report(si_unit(parse_unit("1/V^2")[1]), 0.028))
    assert "1/V^2" in text and "kg" not in text and "0.028" in text
    text = _table(_report("m", 5e-5))
    assert " 50 " in text and "um" in text


def test_calibrated_literal_uses_the_conventional_unit(tmp_path):
    import acl
    from acl.fit import calibrated

    lit = calibrated._literal(0.028, si_unit(parse_unit("1/V^2")[1]))
    assert lit == "0.028 V^-2"
    (tmp_path / "d.acl").write_text(f"param k = {lit}\n")
    assert acl.load(str(tmp_path / "d.acl")).params[0].value == 0.028


def test_synth_prints_planted_effects_in_their_units(tmp_path):
    import os
    import subprocess
    import sys

    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    r = subprocess.run([sys.executable, "-m", "acl", "synth", "samples/fit_cantilever.acl", "-o",
                        str(tmp_path / "d.csv"), "--effect", "offset_drift=offset:0.5um,drift:0.01um/s",
                        "--effect", "drive_saturation=v_sat:6V", "--voltages", "0V..4V:3"],
                       capture_output=True, text=True, cwd=root, env={**os.environ, "PYTHONPATH": root})
    assert r.returncode == 0, r.stderr
    text = r.stdout + r.stderr
    assert "offset = 0.5 um, drift = 0.01 um/s" in text and "v_sat = 6 V" in text
    assert "SI" not in text and "e-07 m" not in text

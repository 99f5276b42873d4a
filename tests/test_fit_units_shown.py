"""A calibrated parameter is printed in a conventional unit (issue 28), not in SI base units: `acl fit`'s table and
the calibrated design file and the band cause compile prints (acl.units.conventional_unit)."""
from __future__ import annotations

import io

from acl.fit.report import render_table, shown
from acl.units import conventional_unit, parse_unit, si_unit


def test_si_base_strings_get_their_conventional_name():
    for u in ("1/V^2", "W", "Pa", "N/V^2", "N*m^2/V^2", "kg/s"):
        assert conventional_unit(si_unit(parse_unit(u)[1])) == u
    assert shown("m") == (1e6, "um")
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

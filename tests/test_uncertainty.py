"""Declared uncertainty: `param x = v +- s`, `uncertainty { correlation(..), covered(..) }`, transducer gain_uncertainty."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import acl
from acl.diagnostics import DiagnosticError

ROOT = Path(__file__).resolve().parents[1]

BASE = """import stdlib.media
import stdlib.transducers
use medium media.pbs
use transducer transducers.contact_piezo
"""


def _errors(text):
    with pytest.raises(DiagnosticError) as exc:
        acl.loads(BASE + text, "u.acl")
    return [(d.code, d.span.line, d.span.column) for d in exc.value.diagnostics if d.is_error]


def test_param_uncertainty_and_correlation_resolve_in_si():
    d = acl.loads(BASE + "param g = 27 pN/V^2 +- 2 pN/V^2\nparam a = 3 um ± 100 nm\nparam c = 5\n"
                  "uncertainty {\n  correlation(g, a) = -0.5\n  covered(voltage) = 0 V .. 4 V\n"
                  "  covered(frequency) = 125 kHz .. 125 kHz\n}\n", "u.acl")
    assert d.param("g").stddev == pytest.approx(2e-12)
    assert d.param("a").stddev == pytest.approx(1e-7)
    assert d.param("c").stddev is None
    assert [p.name for p in d.uncertain_params()] == ["g", "a"]
    cov = d.covariance()
    assert cov[0, 0] == pytest.approx(4e-24)
    assert cov[0, 1] == pytest.approx(-0.5 * 2e-12 * 1e-7)
    cover = {c.quantity: (c.lower, c.upper) for c in d.coverage}
    assert cover == {"voltage": (0.0, 4.0), "frequency": (125e3, 125e3)}


def test_stdlib_transducer_tables_carry_a_wide_declared_uncertainty():
    d = acl.loads(BASE, "u.acl")
    assert d.transducer.gain_uncertainty is not None and d.transducer.gain_uncertainty >= 0.2


def test_show_json_lists_uncertainty(tmp_path):
    f = tmp_path / "u.acl"
    f.write_text(BASE + "param g = 27 pN/V^2 +- 2 pN/V^2\nparam h = 1 um +- 0.1 um\n"
                 "uncertainty { correlation(g, h) = 0.25 }\n")
    out = subprocess.run([sys.executable, "-m", "acl", "show", str(f), "--json"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout)
    g = next(p for p in d["params"] if p["name"] == "g")
    assert g["stddev"] == pytest.approx(2e-12)
    assert d["correlations"][0]["value"] == 0.25
    assert d["transducer"]["gain_uncertainty"] == pytest.approx(0.3)


@pytest.mark.parametrize("text, code, line, col", [
    ("param g = 27 pN/V^2 +- -2 pN/V^2\n", "E320", 5, 24),              # negative
    ("param g = 27 pN/V^2 +- 2 um\n", "E321", 5, 24),                     # wrong unit
    ("param g = 3 um +- 1e200 um * 1e200\n", "E305", 5, 19),             # not finite
    ("param g = 3 um +- 1 um\nuncertainty { correlation(g, q) = 0.5 }\n", "E323", 6, 15),   # unknown name
    ("param g = 3 um +- 1 um\nparam q = 2 um\nuncertainty { correlation(g, q) = 0.5 }\n", "E323", 7, 15),
    ("param g = 3 um +- 1 um\nparam q = 2 um +- 1 um\nuncertainty { correlation(g, q) = 1.5 }\n", "E324", 7, 35),
    ("param a = 3 um +- 1 um\nparam b = 2 um +- 1 um\nparam c = 2 um +- 1 um\n"
     "uncertainty {\n correlation(a, b) = 0.9\n correlation(b, c) = 0.9\n correlation(a, c) = -0.9\n}\n", "E324", 9, 2),
    ("uncertainty { covered(voltage) = 0 um .. 4 um }\n", "E325", 5, 34),
    ("uncertainty { covered(pressure) = 0 V .. 4 V }\n", "E325", 5, 15),
    ("uncertainty { covered(voltage) = 4 V .. 1 V }\n", "E325", 5, 34),
    # issue 11 hostile corpus (tests/hostile/inputs/unc_*, ublock_*): accepted silently before
    ("param a = 3 um +- 1 um\nparam b = 2 um +- 1 um\n"
     "uncertainty {\n correlation(a, b) = 0.5\n correlation(b, a) = -0.5\n}\n", "E323", 9, 2),   # a pair twice
    ("uncertainty {\n covered(voltage) = 0 V .. 4 V\n covered(voltage) = 0 V .. 8 V\n}\n", "E325", 7, 2),
    ("uncertainty {\n discrepancy(position) = 50 nm\n discrepancy(position) = 60 nm\n}\n", "E325", 7, 2),
    ("uncertainty { discrepancy(position) = 1e300 m }\n", "E325", 5, 39),          # overflowed the error bands
    ("param g = 27 pN/V^2 +- 1e300 pN/V^2\n", "E305", 5, 24),                      # variance overflows
    ("param g = 3 um +- 1e170 um\n", "E305", 5, 19),
])
def test_bad_uncertainty_is_a_located_diagnostic(text, code, line, col):
    errs = _errors(text)
    assert (code, line, col) in errs, errs


def test_bad_transducer_gain_uncertainty():
    with pytest.raises(DiagnosticError) as exc:
        acl.loads("transducer t {\n max_voltage = 10 V\n band = 40 kHz .. 200 kHz\n gain = 200 Pa/V\n"
                  " gain_uncertainty = -10 %\n}\nuse transducer t\n", "u.acl")
    errs = [(d.code, d.span.line, d.span.column) for d in exc.value.diagnostics]
    assert ("E320", 5, 21) in errs, errs


@pytest.mark.parametrize("value", ["11", "1e300"])
def test_an_absurd_gain_uncertainty_is_e320(value):
    """Issue 11: gain_uncertainty = 1e300 passed check and `compile --robust` died with E-INTERNAL
    (LinAlgError: exp(1e300) gains)."""
    with pytest.raises(DiagnosticError) as exc:
        acl.loads("transducer t {\n max_voltage = 10 V\n band = 40 kHz .. 200 kHz\n gain = 200 Pa/V\n"
                  f" gain_uncertainty = {value}\n}}\nuse transducer t\n", "u.acl")
    errs = [(d.code, d.span.line, d.span.column) for d in exc.value.diagnostics]
    assert ("E320", 5, 21) in errs, errs
    assert acl.loads("transducer t {\n max_voltage = 10 V\n band = 40 kHz .. 200 kHz\n gain = 200 Pa/V\n"
                     " gain_uncertainty = 10\n}\nuse transducer t\n", "u.acl").transducer.gain_uncertainty == 10


@pytest.mark.parametrize("sd, mode", [("1e20 N/V^2", "mean"), ("1e140 N/V^2", "worst")])
def test_robust_compile_with_an_absurd_uncertainty_is_located(tmp_path, sd, mode):
    """Issue 11: a finite but absurd `+- s` made `compile --robust` fail inside the solver (E-INTERNAL
    ValueError from SCS, a TypeError formatting a missing slew limit, a bogus `<--set>` E212)."""
    f = tmp_path / "u.acl"
    f.write_text((ROOT / "tests" / "hostile" / "inputs" / "unc_huge.acl").read_text()
                 .replace("+- 1e300 nN/V^2", f"+- {sd}"))
    out = subprocess.run([sys.executable, "-m", "acl", "compile", str(f), "-o", str(tmp_path / "o"),
                          "--robust", mode, "--band-samples", "0"], capture_output=True, text=True,
                         env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert out.returncode == 1 and "Traceback" not in out.stderr and "E-INTERNAL" not in out.stderr, out.stderr
    assert f"{f}:16:3: error[E-SCHED-UNCERTAINTY]" in out.stderr and "gamma +- " in out.stderr
    assert "Warning" not in out.stderr and not (tmp_path / "o").exists()


def test_cli_bad_uncertainty_exit_code_no_traceback(tmp_path):
    f = tmp_path / "bad.acl"
    f.write_text(BASE + "param g = 27 pN/V^2 +- -2 pN/V^2\n")
    out = subprocess.run([sys.executable, "-m", "acl", "check", str(f)], capture_output=True, text=True)
    assert out.returncode == 1
    assert "E320" in out.stdout + out.stderr and "Traceback" not in out.stderr
    assert "bad.acl:5:24" in out.stdout + out.stderr


@pytest.mark.parametrize("spread, code, col, text", [
    ("-3 %", "E320", 24, "is negative (-3 %)"),                       # printed -0.03 % (the fraction)
    ("1e300 %", "E305", 24, "too large to compute with"),
    ("normal(1 pN/V^2, 1e300 N/V^2)", "E305", 24, "too large to compute with"),
    ("uniform(-1e300 N/V^2, 1e300 N/V^2)", "E305", 24, "too large to compute with"),
])
def test_spreads_too_large_or_negative_are_located(spread, code, col, text):
    with pytest.raises(DiagnosticError) as exc:
        acl.loads(BASE + f"param g = 27 pN/V^2 +- {spread}\n", "u.acl")
    d = exc.value.diagnostics[0]
    assert (d.code, d.span.line, d.span.column) == (code, 5, col) and text in d.message, (d.code, str(d.span), d.message)

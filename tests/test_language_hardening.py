"""Regression tests of issue 11, "The language": numbers, deep structures, non-finite values,
non-file inputs and diagnostics that name the root cause once."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

import acl
from acl.cli import main
from acl.commands._common import parse_sets, quantity_text
from acl.design.resolve import check_design
from acl.diagnostics import DiagnosticError

ROOT = Path(__file__).resolve().parents[1]
PAIR = ROOT / "examples" / "fig5a_gripper.acl"    # declares `param gap = ... um`


def _load(text: str, name: str = "t.acl", **kw):
    return acl.loads(text, name, **kw)


def _codes(text: str, name: str = "t.acl", **kw) -> list[tuple[str, int, int]]:
    with pytest.raises(DiagnosticError) as info:
        acl.loads(text, name, **kw)
    return [(d.code, d.span.line, d.span.column) for d in info.value.diagnostics]


def _param(design, name: str):
    return next(p for p in design.params if p.name == name)


# ------------------------------------------------------------------------------ scientific notation
@pytest.mark.parametrize("text, value, unit", [
    ("4.9e-1", 0.49, ""),
    ("5e-1 * 1 um", 5e-7, "m"),
    ("2.0e1 um", 2e-5, "m"),
    ("3e2um", 3e-4, "m"),
    ("4.9E+1 mm", 0.049, "m"),
    ("1.12e5 um^3", 1.12e-13, "m^3"),
    ("2 * 1e-3", 2e-3, ""),
])
def test_scientific_notation_is_one_number(text, value, unit):
    p = _param(_load(f"param d = {text}\n"), "d")
    assert p.value == pytest.approx(value, rel=1e-12)
    assert p.unit == unit


def test_the_unit_e_is_still_the_elementary_charge():
    assert _param(_load("param q = 1 e\n"), "q").unit == "s*A"


@pytest.mark.parametrize("given, want", [
    ("60um", "60 um"), ("2.0e1 um", "2.0e1 um"), ("2.0e1um", "2.0e1 um"), ("2e-5 m", "2e-5 m"),
    ("-3e2mV", "-3e2 mV"), ("0.5um/s", "0.5 um/s"), ("1.5", "1.5"),
])
def test_command_line_quantities_keep_the_exponent(given, want):
    assert quantity_text(given) == want


@pytest.mark.parametrize("value", ["2e-5 m", "2.0e1 um", "20um", "2e-05 m"])
def test_set_with_scientific_notation(value):
    sets, diags = parse_sets([f"gap={value}"])
    assert not diags
    design = acl.load(str(PAIR), overrides=sets)
    assert _param(design, "gap").value == pytest.approx(2e-5, rel=1e-12)


def test_set_scientific_notation_on_the_command_line(capsys):
    assert main(["check", str(PAIR), "--set", "gap=2.0e1 um"]) == 0
    assert main(["check", str(PAIR), "--set", "gap=2e-5 m"]) == 0


def test_python_float_override_is_an_si_value():
    design = acl.load(str(PAIR), overrides={"gap": 2e-05})
    p = _param(design, "gap")
    assert (p.value, p.unit) == (2e-05, "m")


def test_python_non_finite_override_is_e305():
    _, diags = check_design(str(PAIR), overrides={"gap": math.inf})
    assert [d.code for d in diags if d.is_error] == ["E305"]

"""acl sweep's inputs: grids, spreads (language and command line, one syntax), sampling."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import acl
from acl.diagnostics import DiagnosticError
from acl.sweep.sample import chunk_points
from acl.sweep.spec import build_spec, parse_vary

ROOT = Path(__file__).resolve().parents[1]
CANTILEVER = ROOT / "samples" / "sweep_cantilever.acl"


@pytest.fixture(scope="module")
def design():
    return acl.load(str(CANTILEVER))


def _errors(text: str):
    try:
        acl.loads(text, filename="t.acl")
    except DiagnosticError as exc:
        return [(d.code, d.span.line, d.span.column) for d in exc.diagnostics]
    return []


# -- the language ---------------------------------------------------------------------------------

@pytest.mark.parametrize("text, kind, a, b, relative, sd", [
    ("param r = 10 um +- 150 nm", None, None, None, None, 150e-9),
    ("param r = 10 um +- normal(0, 150 nm)", "normal", 0.0, 150e-9, False, 150e-9),
    ("param r = 10 um +- normal(-50 nm, 150 nm)", "normal", -50e-9, 150e-9, False, 150e-9),
    ("param r = 10 um +- normal(mean = 0, sd = 1 um)", "normal", 0.0, 1e-6, False, 1e-6),
    ("param r = 10 um +- uniform(-0.3 um, 0.3 um)", "uniform", -0.3e-6, 0.3e-6, False, 0.6e-6 / math.sqrt(12)),
    ("param r = 10 um +- 3 %", "normal", 0.0, 0.03, True, 0.3e-6),
    ("param r = 10 um ± normal(0, 3 %)", "normal", 0.0, 0.03, True, 0.3e-6),
    ("param r = 10 um +- uniform(-2 %, 1 %)", "uniform", -0.02, 0.01, True, 0.3e-6 / math.sqrt(12)),
])
def test_declared_spreads(text, kind, a, b, relative, sd):
    p = acl.loads(text + "\n").param("r")
    assert p.stddev == pytest.approx(sd, rel=1e-12)
    if kind is None:
        assert p.spread is None and p.distribution().kind == "normal"
    else:
        assert (p.spread.kind, p.spread.relative) == (kind, relative)
        assert p.spread.a == pytest.approx(a, rel=1e-12, abs=1e-30)
        assert p.spread.b == pytest.approx(b, rel=1e-12)


@pytest.mark.parametrize("text, code, col", [
    ("param r = 10 um +- gauss(0, 1 um)\n", "E322", 20),
    ("param r = 10 um +- normal(0)\n", "E322", 20),
    ("param r = 10 um +- normal\n", "E322", 20),
    ("param r = 10 um +- normal(0, 1 V)\n", "E321", 30),
    ("param r = 10 um +- normal(-50 nm, 3 %)\n", "E321", 27),
    ("param r = 10 um +- normal(0, -1 um)\n", "E320", 30),
    ("param r = 10 um +- uniform(1 um, -1 um)\n", "E322", 20),
    ("param r = 10 um +- normal(0, 1 um, sd = 2 um)\n", "E322", 20),
])
def test_bad_spread_is_located(text, code, col):
    assert (code, 1, col) in _errors(text)


def test_unclosed_spread_says_which_bracket_and_names_plus_minus():
    """`normal(0, 1 um` ending the file was hinted as a block missing its `}`, and listed `_pm`."""
    with pytest.raises(DiagnosticError) as exc:
        acl.loads("param r = 10 um +- normal(0, 1 um\n")
    d = exc.value.diagnostics[0]
    assert d.code == "E111" and d.hint == "a `(` is missing its closing `)`"
    assert "_pm" not in d.message


def test_correlation_accepts_new_spreads():
    d = acl.loads("param a = 1 um +- normal(0, 0.1 um)\nparam b = 2 um +- 5 %\nuncertainty { correlation(a, b) = 0.5 }\n")
    assert d.correlations[0].value == 0.5
    assert d.covariance(["a", "b"])[0, 1] == pytest.approx(0.5 * 0.1e-6 * 0.1e-6)


# -- --vary --------------------------------------------------------------------------------------

def test_vary_linear_log_list(design):
    a = parse_vary("radius=8um..12um:5", design)
    assert a.values.tolist() == pytest.approx([8e-6, 9e-6, 10e-6, 11e-6, 12e-6], rel=1e-12)
    assert a.values[0] == 8e-6 and a.values[-1] == 12e-6
    g = parse_vary("radius=1um..100um:3:log", design)
    assert g.log and g.values.tolist() == pytest.approx([1e-6, 1e-5, 1e-4], rel=1e-12)
    lst = parse_vary("radius=8um, 9 um,1.0e1um", design)
    assert lst.values.tolist() == pytest.approx([8e-6, 9e-6, 10e-6], rel=1e-12)
    one = parse_vary("radius=9.5um", design)
    assert one.values.tolist() == pytest.approx([9.5e-6])


@pytest.mark.parametrize("vary, tol, samples, seed, code, where, col", [
    (["radius=8um..12V:5"], None, None, 0, "E301", "<--vary>", 13),
    (["radius=8zz..12um:5"], None, None, 0, "E302", "<--vary>", 8),
    (["radus=8um..12um:5"], None, None, 0, "E211", "<--vary>", 1),
    (["radius=8um..12um:0"], None, None, 0, "E-USAGE", "<--vary>", 18),
    (["radius=8um..12um:x"], None, None, 0, "E-USAGE", "<--vary>", 18),
    (["radius=8um..12um"], None, None, 0, "E-USAGE", "<--vary>", 18),
    (["radius=8um..12um:5:lin"], None, None, 0, "E-USAGE", "<--vary>", 20),
    (["radius=-1um..12um:5:log"], None, None, 0, "E-USAGE", "<--vary>", 8),
    (["radius=8um..12um:1"], None, None, 0, "E-USAGE", "<--vary>", 18),
    (["radius=8um,,9um"], None, None, 0, "E-USAGE", "<--vary>", 12),
    (["radius="], None, None, 0, "E-USAGE", "<--vary>", 8),
    (["8um..9um:3"], None, None, 0, "E-USAGE", "<--vary>", 1),
    (["radius=1um", "radius=2um"], None, None, 0, "E-USAGE", "<--vary>", 1),
    (None, ["radius=normal(0, 150 V)"], None, 0, "E321", "<--tolerance>", 18),
    (None, ["radius=gauss(0, 1 um)"], None, 0, "E322", "<--tolerance>", 8),
    (None, ["radius=normal(0, 1 zz)"], None, 0, "E302", "<--tolerance>", 18),
    (None, ["radius=normal(0,"], None, 0, "E111", "<--tolerance>", 16),
    (None, ["radius=normal(0, height)"], None, 0, "E304", "<--tolerance>", 18),
    (None, ["radius="], None, 0, "E-USAGE", "<--tolerance>", 8),
    (None, ["nope=3%"], None, 0, "E211", "<--tolerance>", 1),
    (["radius=9um"], None, 0, 0, "E-USAGE", "<--samples>", 1),
    (["radius=9um"], None, None, -1, "E-USAGE", "<--seed>", 1),
    (None, None, None, 0, "E-USAGE", "<argv>", 1),
    (["radius=1um..20um:1000"], None, 10**6, 0, "E-USAGE", "<argv>", 1),      # 1e9 rows: beyond memory
])
def test_bad_sweep_inputs_are_located(design, vary, tol, samples, seed, code, where, col):
    with pytest.raises(DiagnosticError) as exc:
        build_spec(design, vary, tol, samples, seed)
    got = [(d.code, d.span.file, d.span.column) for d in exc.value.diagnostics]
    assert (code, where, col) in got, got


def test_samples_without_spreads_is_a_usage_error():
    d = acl.load(str(ROOT / "examples" / "fig4_facing_pair.acl"))
    with pytest.raises(DiagnosticError) as exc:
        build_spec(d, ["gap=30um..50um:3"], None, 10)
    assert exc.value.diagnostics[0].code == "E-USAGE" and "nothing to sample" in exc.value.diagnostics[0].message


def test_montecarlo_samples_declared_spreads_and_tolerance_replaces_them(design):
    s = build_spec(design, None, ["radius=3%"], 50)
    by = {t.name: t for t in s.tolerances}
    assert by["radius"].source == "--tolerance" and by["radius"].spread.relative
    assert by["height"].source == "design" and by["height"].spread.kind == "uniform"
    assert any("replaces" in n for n in s.notes)
    grid_only = build_spec(design, ["radius=9um..11um:3"])
    assert not grid_only.montecarlo and grid_only.tolerances == () and grid_only.n_points == 3


# -- sampling --------------------------------------------------------------------------------------

def test_chunks_are_deterministic_and_independent(design):
    s = build_spec(design, ["radius=9um..11um:3"], ["radius=normal(0, 150 nm)"], 1000, seed=7, chunk_size=500)
    a = chunk_points(s, 3, s.chunk_size)
    b = chunk_points(s, 3, s.chunk_size)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    other = build_spec(design, ["radius=9um..11um:3"], ["radius=normal(0, 150 nm)"], 1000, seed=8, chunk_size=500)
    assert not np.array_equal(chunk_points(other, 3, 500)["radius"], a["radius"])
    # point k = grid k // samples: chunk 3 covers points 1500..1999, grid point 1 (10 um)
    assert np.mean(a["radius"]) == pytest.approx(10e-6, rel=2e-3)


def test_grid_order_first_axis_slowest(design):
    s = build_spec(design, ["radius=9um..11um:3", "height=30um,31um"])
    p = chunk_points(s, 0, s.chunk_size)
    assert p["radius"].tolist() == pytest.approx([9e-6, 9e-6, 10e-6, 10e-6, 11e-6, 11e-6])
    assert p["height"].tolist() == pytest.approx([30e-6, 31e-6] * 3)


def test_sampled_statistics(design):
    """Sample moments within 5 standard errors of the spread's (n = 200,000)."""
    n = 200_000
    s = build_spec(design, None, ["radius=normal(-20 nm, 150 nm)", "height=uniform(-0.5um, 1.5um)"], n, seed=1, chunk_size=n)
    p = chunk_points(s, 0, n)
    dr = p["radius"] - 10e-6
    assert abs(dr.mean() - (-20e-9)) < 5 * 150e-9 / math.sqrt(n)
    assert abs(dr.std() / 150e-9 - 1) < 5 / math.sqrt(2 * n)
    dh = p["height"] - 33.15e-6
    assert dh.min() >= -0.5e-6 - 1e-18 and dh.max() <= 1.5e-6 + 1e-18
    assert abs(dh.mean() - 0.5e-6) < 5 * (2e-6 / math.sqrt(12)) / math.sqrt(n)
    rel = build_spec(design, ["radius=10um,20um"], ["radius=5%"], n // 2, seed=2, chunk_size=n)
    q = chunk_points(rel, 0, n)
    for half, v in ((q["radius"][: n // 2], 10e-6), (q["radius"][n // 2:], 20e-6)):   # grid point k // samples
        assert abs(half.std() / (0.05 * v) - 1) < 5 / math.sqrt(n)


def test_declared_correlation_is_honoured():
    """Correlated normals: sample correlation within 0.01 of the declared 0.8 (n = 100,000; standard error 0.0011)."""
    d = acl.loads("param a = 10 um +- 1 um\nparam b = 5 um +- normal(0, 0.5 um)\nuncertainty { correlation(a, b) = 0.8 }\n")
    s = build_spec(d, None, None, 100_000, seed=3, chunk_size=100_000)
    p = chunk_points(s, 0, 100_000)
    assert np.corrcoef(p["a"], p["b"])[0, 1] == pytest.approx(0.8, abs=0.01)


def test_show_prints_the_declared_spread():
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "acl", "show", str(CANTILEVER)], capture_output=True, text=True, cwd=ROOT)
    assert "radius = 10 um +- normal(0, 150 nm)" in r.stdout and "height = 33.15 um +- uniform(-500 nm, 500 nm)" in r.stdout

"""Issue 28: a design `acl tune` writes sweeps to the yield tune validated on it.

`free in lo .. hi` bounds the value chosen (the grid's, the nominal, the tuner's trial), never the
printed device about it; sweep and tune follow that one rule (acl.sweep.validity.without_free_ranges).
Before, a tuned design whose values sat on the bounds swept to yield 0.250 where tune had validated
1.000 (`acl sweep fig3_robust_radii.tuned.acl --samples 100000 --seed 3`: 74,959 points E306)."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import acl
from acl.sweep.tune import clopper_pearson, prepare, tune

ROOT = Path(__file__).resolve().parents[1]
TUNABLE = sorted(p for p in (ROOT / "examples").rglob("*.acl")
                 if re.search(r"\bfree\s+in\b", p.read_text(encoding="utf-8"))
                 and re.search(r"^\s*require\b", p.read_text(encoding="utf-8"), re.M))   # a design acl tune accepts


def _tuned(path: Path, folder: Path, samples: int, evals: int):
    problem = prepare(str(path), samples=samples, validate=samples, seed=1, search_paths=[str(path.parent)])
    result = tune(problem, max_evals=evals)
    out = result.write(str(folder / f"{path.stem}.tuned.acl"))
    return result, out


def test_every_tunable_example_is_found():
    assert TUNABLE, "no example declares `free in`: the test below would check nothing"


@pytest.mark.parametrize("path", TUNABLE, ids=lambda p: p.stem)
def test_a_tuned_design_sweeps_to_the_yield_tune_validated(tmp_path, path):
    result, out = _tuned(path, tmp_path, samples=200, evals=100)
    chosen = result.values
    d = acl.load(out, search_paths=[str(path.parent)])
    assert {p.name: p.value for p in d.params if p.name in chosen} == pytest.approx(chosen, rel=1e-12)
    on_bound = [f.name for f in result.problem.free if chosen[f.name] in (f.lower, f.upper)]
    table = acl.sweep(out, n=600, seed=3, search_paths=[str(path.parent)])
    codes = set(np.asarray(table["code"]).tolist())
    assert "E306" not in codes, f"prints about values on their bounds ({on_bound}) refused as E306"
    y = table.yields()["all"]
    lo_s, hi_s = clopper_pearson(y.passed, y.total)
    lo_t, hi_t = result.after.interval
    # two independent samples of the same devices: their 95 % intervals overlap
    assert lo_s <= hi_t and lo_t <= hi_s, (y.text(), result.after.text())


def test_a_grid_value_outside_the_free_range_is_still_E306(tmp_path):
    path = ROOT / "examples" / "fig3_robust_radii.acl"      # r1 `free in 8 um .. 16 um`, +- 150 nm
    table = acl.sweep(str(path), vary=["r1=7um,12um,17um"], n=50, seed=0)
    code = np.asarray(table["code"])
    r1_bad = np.isin(np.arange(len(code)) // 50, [0, 2])
    assert (code[r1_bad] == "E306").all()
    assert (code[~r1_bad] != "E306").all()


def test_prints_about_a_bound_are_devices(tmp_path):
    """At r1 = 16 um, its upper bound, about half the prints lie above 16 um: all evaluated."""
    path = ROOT / "examples" / "fig3_robust_radii.acl"
    table = acl.sweep(str(path), vary=["r1=16um"], n=400, seed=0)
    r1 = np.asarray(table["r1"])
    assert 0.3 < np.mean(r1 > 16e-6) < 0.7
    assert np.asarray(table["valid"])[r1 > 16e-6].all()


@pytest.mark.studies
def test_the_issue_run_sweeps_to_yield_one(tmp_path):
    """The issue's numbers: the default tune (2000 samples), then 100,000 swept samples, seed 3."""
    path = ROOT / "examples" / "fig3_robust_radii.acl"
    result, out = _tuned(path, tmp_path, samples=2000, evals=200)
    table = acl.sweep(out, n=100_000, seed=3, search_paths=[str(path.parent)])
    y = table.yields()["all"]
    lo_t, hi_t = result.after.interval
    assert y.lower <= hi_t and lo_t <= y.upper, (y.text(), result.after.text())
    assert y.passed / y.total > 0.99

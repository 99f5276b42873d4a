"""The Python API (acl.load/loads/analyze/compile/lint/fit): typed results equal to the commands'
JSON, HTML display, plots that leave the backend alone, lazy imports, and docs/python.md runs."""
from __future__ import annotations

import doctest
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
PAIR = "examples/fig4_facing_pair.acl"
SELECTIVE = "examples/fig1f_selective_beams.acl"


def _cli(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "acl", *args], capture_output=True, text=True, cwd=ROOT, env=ENV,
                          timeout=300)


def test_import_acl_loads_no_heavy_module():
    code = ("import sys, acl\n"
            "heavy = ['numpy', 'scipy', 'cvxpy', 'matplotlib', 'pint', 'pygls', 'lsprotocol', 'acl.notebook']\n"
            "print([m for m in heavy if m in sys.modules])\n"
            "print([callable(getattr(acl, f)) for f in acl.__all__ if f != '__version__'])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=ENV, timeout=60)
    lines = out.stdout.splitlines()
    assert lines[0] == "[]", out.stdout + out.stderr
    assert lines[1] == str([True] * 8)          # load, loads, analyze, compile, lint, fit, sweep, tune


def test_py_typed_is_shipped():
    assert (ROOT / "acl" / "py.typed").is_file()
    text = (ROOT / "setup.py").read_text() if (ROOT / "setup.py").exists() else (ROOT / "pyproject.toml").read_text()
    assert re.search(r'"acl"\s*[:=]\s*\[[^\]]*"py\.typed"', text)     # package data of acl


def test_lint_and_fit_stay_callable_after_their_subpackages_are_imported():
    import acl
    import acl.fit  # noqa: F401
    import acl.lint  # noqa: F401

    assert callable(acl.lint) and callable(acl.fit)
    assert acl.lint(SELECTIVE).path == SELECTIVE


def test_analyze_equals_acl_analyze_json(monkeypatch):
    import acl

    monkeypatch.chdir(ROOT)
    got = acl.analyze(PAIR, snap_in=False)
    proc = _cli("analyze", PAIR, "--output-format", "json", "--no-snap")
    want = json.loads(proc.stdout)
    assert json.loads(json.dumps(got.as_dict())) == want
    assert [c.name for c in got.capsules] == [c["name"] for c in want["capsules"]]
    assert got.capsules[0].modes[0].frequency_hz == want["capsules"][0]["modes"][0]["frequency_hz"]
    html = got._repr_html_()
    assert "<table>" in html and f"{want['capsules'][0]['modes'][0]['frequency_hz'] / 1e3:.1f}" in html


def test_analyze_at_a_drive_gives_the_equilibrium(monkeypatch):
    import acl

    monkeypatch.chdir(ROOT)
    got = acl.analyze(PAIR, at="125 kHz @ 5 V", snap_in=False)
    want = json.loads(_cli("analyze", PAIR, "--output-format", "json", "--no-snap", "--at", "125 kHz @ 5 V").stdout)
    assert got.equilibrium is not None     # (compared as JSON text: a NaN residual equals itself there)
    assert json.dumps(got.equilibrium, sort_keys=True) == json.dumps(want["equilibrium"], sort_keys=True)


def test_compile_equals_the_schedule_json_of_acl_compile(tmp_path, monkeypatch):
    import acl

    monkeypatch.chdir(ROOT)
    got = acl.compile(SELECTIVE, "sequential")
    proc = _cli("compile", SELECTIVE, "--program", "sequential", "-o", str(tmp_path))
    assert proc.returncode == 0, proc.stderr
    want = json.loads((tmp_path / "schedule.json").read_text())
    for k in ("waveform", "files"):
        want.pop(k, None)
    assert json.loads(json.dumps(got.as_dict())) == want
    assert [(s.start_s, s.end_s) for s in got.segments] == [(s["start_s"], s["end_s"]) for s in want["segments"]]
    assert "<table>" in got._repr_html_()


def test_compile_unknown_program_is_a_coded_diagnostic(monkeypatch):
    import acl
    from acl.diagnostics import DiagnosticError

    monkeypatch.chdir(ROOT)
    with pytest.raises(DiagnosticError) as exc:
        acl.compile(SELECTIVE, "sequentail")
    d = exc.value.diagnostics[0]
    assert d.code == "E-COMPILE-PROGRAM" and d.hint == "did you mean `sequential`?"


def test_lint_equals_acl_lint_json(monkeypatch):
    import acl

    monkeypatch.chdir(ROOT)
    path = "tests/bad/geom_double_mount.acl" if (ROOT / "tests/bad/geom_double_mount.acl").exists() else PAIR
    got = acl.lint(path)
    want = json.loads(_cli("lint", path, "--output-format", "json").stdout)
    assert got.as_dict() == want
    assert got.codes() == [f["code"] for f in want["findings"]]
    assert got.ok == (want["summary"]["errors"] == 0)
    assert "<table>" in got._repr_html_()


def test_plots_draw_on_given_axes_and_never_switch_backend(tmp_path):
    code = f"""
import sys, os
import matplotlib
import acl
from matplotlib.figure import Figure
d = acl.load({SELECTIVE!r})
results = [d, acl.analyze(d, snap_in=False), acl.compile(d, "sequential"), acl.lint({SELECTIVE!r})]
for r in results:
    ax = r.plot()
    assert ax.figure is not None and (ax.lines or ax.patches or ax.collections or ax.texts), type(r)
    ax.figure.savefig(os.path.join({str(tmp_path)!r}, type(r).__name__ + ".png"))
    fig = Figure()
    mine = fig.add_subplot()
    assert r.plot(mine) is mine
print("pyplot" if "matplotlib.pyplot" in sys.modules else "no pyplot", matplotlib.get_backend())
"""
    env = {**ENV, "MPLBACKEND": "pdf"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["no", "pyplot", "pdf"]
    assert len(list(tmp_path.glob("*.png"))) == 4


def test_fit_report_is_the_json_of_acl_fit(tmp_path, monkeypatch):
    import numpy as np

    import acl
    from acl.fit.synth import Experiment, generate, write_csv

    monkeypatch.chdir(ROOT)
    ex = Experiment(frequencies=(110e3, 125e3, 140e3), voltages=tuple(np.linspace(0, 10, 11)), repeats=1)
    data, _ = generate("samples/fit_cantilever.acl", ex, {}, noise=0.2e-6, seed=2)
    csv = tmp_path / "clean.csv"
    write_csv(data, str(csv))
    got = acl.fit("samples/fit_cantilever.acl", csv, free=["gamma"], effects=[])
    want = json.loads(_cli("fit", "samples/fit_cantilever.acl", str(csv), "--free", "gamma", "--effects", "none",
                           "--output-format", "json").stdout)
    a, b = got.as_dict(), want
    for k in ("timing_s",):
        a, b = {**a, k: None}, {**b, k: None}
    assert json.loads(json.dumps(a)) == b
    assert got.effects_selected == [] and [p.name for p in got.parameters] == ["gamma"]
    assert got.rmse_after == want["rmse_after"]
    assert "<table>" in got._repr_html_()
    ax = got.plot()
    assert len(ax.patches) == 2 * len(got.per_observable)


def _python_blocks(text: str) -> list[tuple[int, str]]:
    return [(text[:m.start()].count("\n") + 2, m.group(1)) for m in re.finditer(r"```python\n(.*?)```", text, re.S)]


def test_docs_python_md_examples_run(monkeypatch):
    monkeypatch.chdir(ROOT)
    monkeypatch.setenv("MPLBACKEND", "agg")
    text = (ROOT / "docs" / "python.md").read_text(encoding="utf-8")
    blocks = _python_blocks(text)
    assert len(blocks) >= 6
    parser = doctest.DocTestParser()
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    globs: dict = {}
    for line, block in blocks:
        test = parser.get_doctest(block, globs, f"docs/python.md:{line}", "docs/python.md", line)
        assert test.examples, f"docs/python.md:{line}: a python block without examples"
        runner.run(test, clear_globs=False)
        globs = test.globs
    failed, attempted = runner.summarize(verbose=False)
    assert failed == 0, f"{failed} of {attempted} docs/python.md examples failed (see the output above)"


def test_api_docstring_examples_run(monkeypatch):
    import acl

    monkeypatch.chdir(ROOT)
    import acl.notebook

    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    for module in (acl, acl.notebook):
        for t in finder.find(module, module.__name__):
            runner.run(t)
    failed, attempted = runner.summarize(verbose=False)
    assert attempted >= 20 and failed == 0


def test_every_public_function_has_a_docstring_with_an_example():
    import acl

    for name in acl.__all__:
        if name == "__version__":
            continue
        doc = getattr(acl, "_" + name, None).__doc__ if name in ("lint", "fit", "sweep") else getattr(acl, name).__doc__
        assert doc and ">>>" in doc, name


def test_load_is_the_design_acl_show_prints(monkeypatch):
    import acl

    monkeypatch.chdir(ROOT)
    d = acl.load(PAIR)
    want = json.loads(_cli("show", PAIR, "--output-format", "json").stdout)
    assert json.loads(d.model_dump_json()) == want
    html = d._repr_html_()
    assert "<table>" in html and all(c.name in html for c in d.capsules)

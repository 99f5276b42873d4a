"""Issue 28: every result type shows in a notebook: its table (`_repr_html_`) and, as a cell's last line,
its `.plot()` as a figure (not `<Axes: ...>`).  The test is a notebook run with `jupyter nbconvert
--execute` (tests/notebooks/results.ipynb); the executed notebook is checked for a table in each
result's cell and an image in each `.plot()` cell."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("nbconvert", reason="nbconvert is not installed (acl[docs], pulled in by the test extra, installs it)")
pytest.importorskip("nbformat")
pytest.importorskip("ipykernel")
pytest.importorskip("matplotlib")

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK = ROOT / "tests" / "notebooks" / "results.ipynb"
KINDS = ["design", "analysis", "compiled", "lint", "fit", "sweep-grid", "sweep-mc", "tuned"]


@pytest.fixture(scope="module")
def executed(tmp_path_factory):
    out = tmp_path_factory.mktemp("nb")
    shutil.copy(NOTEBOOK, out / NOTEBOOK.name)
    env = {**os.environ, "ACL_ROOT": str(ROOT), "MPLBACKEND": "Agg",
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}
    r = subprocess.run([sys.executable, "-m", "jupyter", "nbconvert", "--to", "notebook", "--execute",
                        "--ExecutePreprocessor.timeout=600", "--output", "executed.ipynb", str(out / NOTEBOOK.name)],
                       capture_output=True, text=True, env=env, cwd=out, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads((out / "executed.ipynb").read_text(encoding="utf-8"))


def _cell(nb, tag):
    (cell,) = [c for c in nb["cells"] if tag in c.get("metadata", {}).get("tags", [])]
    assert not [o for o in cell["outputs"] if o["output_type"] == "error"], cell["outputs"]
    # nbformat may store a text output as a list of lines
    return [{k: "".join(v) if isinstance(v, list) else v for k, v in o.get("data", {}).items()}
            for o in cell["outputs"] if o["output_type"] == "execute_result"]


@pytest.mark.parametrize("kind", KINDS)
def test_each_result_shows_a_table(executed, kind):
    (data,) = _cell(executed, f"{kind}-table")
    assert "<table" in data.get("text/html", ""), data.keys()


@pytest.mark.parametrize("kind", KINDS)
def test_each_plot_as_a_last_line_shows_the_figure(executed, kind):
    (data,) = _cell(executed, f"{kind}-figure")
    assert data.get("image/png"), f"{kind}.plot() showed only {data.get('text/plain')!r}"


def test_the_analysis_table_holds_equilibrium_pairs_and_selectivity(executed):
    (data,) = _cell(executed, "analysis-table")
    h = data["text/html"]
    for part in ("Equilibrium at 85 kHz @ 6 V", "tip deflection (um)", "Pairs (secondary Bjerknes force)", "low-high",
                 "Selectivity"):
        assert part in h, part


def test_the_sweep_and_tune_tables_hold_their_yields(executed):
    (grid,) = _cell(executed, "sweep-grid-table")
    assert "Yield per grid point" in grid["text/html"] and "First rows" in grid["text/html"]
    (tuned,) = _cell(executed, "tuned-table")
    assert "Free parameters" in tuned["text/html"] and "all together" in tuned["text/html"]

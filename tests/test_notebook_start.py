"""The results notebook runs from wherever Jupyter starts its kernel (issue 28, tried as a new user).

`jupyter nbconvert --execute tests/notebooks/results.ipynb` from the repository's root starts the
kernel in tests/notebooks; the notebook's first cell must still find `examples/` (it used to stop at
its first `acl.load` with E601 unless ACL_ROOT was set, which only the test harness does). Fast: only
the first code cell runs, in a plain subprocess, not the whole notebook.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK = ROOT / "tests" / "notebooks" / "results.ipynb"


def _first_code_cell() -> str:
    nb = json.loads(NOTEBOOK.read_text(encoding="utf-8"))
    return "".join(next(c for c in nb["cells"] if c["cell_type"] == "code")["source"])


def _run_from(cwd: Path) -> str:
    code = _first_code_cell() + "\nprint(os.getcwd())\n"
    env = {k: v for k, v in os.environ.items() if k != "ACL_ROOT"}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    r = subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    return r.stdout.strip().splitlines()[-1]


def test_started_in_the_notebooks_folder_it_moves_to_the_root_holding_examples():
    where = Path(_run_from(NOTEBOOK.parent))
    assert (where / "examples" / "fig1f_selective_beams.acl").is_file(), where


def test_started_at_the_root_it_stays_there():
    assert Path(_run_from(ROOT)).resolve() == ROOT

"""Shared CLI options: --path must exist; --set syntax; no tracebacks."""
from __future__ import annotations

import subprocess
import sys


def run(*args):
    return subprocess.run([sys.executable, "-m", "acl", *args], capture_output=True, text=True, timeout=120)


def test_missing_path_folder_is_a_usage_error():
    r = run("check", "--path", "/no/such/folder", "examples/fig2_vertical_cantilever.acl")
    assert r.returncode == 2 and "E-USAGE" in r.stderr and "Traceback" not in r.stderr


def test_missing_path_folder_is_rejected_by_show_too():
    r = run("show", "--path", "/no/such/folder", "examples/fig2_vertical_cantilever.acl")
    assert r.returncode == 2 and "--path" in r.stderr


def test_set_without_equals_is_a_usage_error():
    r = run("check", "--set", "gap", "examples/fig4_facing_pair.acl")
    assert r.returncode == 2 and "NAME=VALUE" in r.stderr


def test_unknown_command_is_a_usage_error():
    r = run("frobnicate")
    assert r.returncode == 2 and "Traceback" not in r.stderr


def test_check_imports_no_heavy_module():
    """`acl check` must start fast: no scipy, cvxpy or matplotlib (and, with the shipped unit
    table, not pint or numpy either for the examples' units)."""
    code = ("import sys\nfrom acl.cli import main\n"
            "rc = main(['check', 'examples/fig2_vertical_cantilever.acl'])\n"
            "heavy = sorted({m.split('.')[0] for m in sys.modules} & {'scipy', 'cvxpy', 'matplotlib', 'pint', 'numpy'})\n"
            "sys.stderr.write('HEAVY=' + ','.join(heavy) + ' RC=' + str(rc))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert "HEAVY= RC=0" in r.stderr, r.stderr[-2000:]

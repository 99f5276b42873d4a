"""The wheel: only `acl` at the top level, the stdlib and the docs shipped inside it, extras as documented."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
OFFLINE = re.compile(r"No matching distribution|Could not find a version|Failed to establish|"
                     r"Temporary failure in name resolution|Network is unreachable", re.I)


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> zipfile.ZipFile:
    """Build the wheel from a copy of the checkout (a build must not leave build/ in the repository)."""
    src = tmp_path_factory.mktemp("src")
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, src / name)
    for name in ("acl", "stdlib", "docs"):
        shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    out = tmp_path_factory.mktemp("wheel")
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet",
                           "--disable-pip-version-check", str(src), "-w", str(out)],
                          capture_output=True, text=True, timeout=300)
    if proc.returncode != 0 and OFFLINE.search(proc.stdout + proc.stderr):
        pytest.skip("building a wheel needs setuptools from the package index, which is unreachable")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    (path,) = out.glob("acl-*.whl")
    return zipfile.ZipFile(path)


def test_wheel_installs_only_the_acl_package(wheel):
    names = wheel.namelist()
    tops = {n.split("/", 1)[0] for n in names if not n.split("/", 1)[0].endswith((".dist-info", ".data"))}
    assert tops == {"acl"}, tops
    top_level = next(n for n in names if n.endswith(".dist-info/top_level.txt"))
    assert wheel.read(top_level).decode().split() == ["acl"]


def test_wheel_ships_every_module_the_stdlib_and_the_docs(wheel):
    names = set(wheel.namelist())
    for path in (ROOT / "acl").rglob("*"):
        if path.suffix in (".py", ".lark", ".json") and "__pycache__" not in path.parts:
            assert path.relative_to(ROOT).as_posix() in names, f"{path} is not in the wheel"
    for acl_file in (ROOT / "stdlib").glob("*.acl"):
        assert f"acl/stdlib/{acl_file.name}" in names
    for md in (ROOT / "docs").rglob("*.md"):     # the explanation, how-to and tutorial pages too
        assert f"acl/docs/{md.relative_to(ROOT / 'docs').as_posix()}" in names, md


def test_plotting_is_an_extra_and_test_pulls_in_every_extra(wheel):
    meta = next(n for n in wheel.namelist() if n.endswith(".dist-info/METADATA"))
    requires = [line.split(":", 1)[1].strip() for line in wheel.read(meta).decode().splitlines()
                if line.startswith("Requires-Dist:")]
    core = [r for r in requires if "extra ==" not in r]
    assert not any(r.startswith(("matplotlib", "osqp", "scs")) for r in core), core
    assert any(r.startswith("matplotlib") and 'extra == "plot"' in r for r in requires)
    assert any(r.startswith("pygls") and 'extra == "lsp"' in r for r in requires)
    test = [r for r in requires if 'extra == "test"' in r]
    assert any(r.startswith("acl[") and "plot" in r and "lsp" in r for r in test), test


def test_installed_layout_finds_the_stdlib_and_the_docs(tmp_path):
    """Unpacked as pip would install it (acl/stdlib inside the package), designs still import the stdlib."""
    site = tmp_path / "site"
    shutil.copytree(ROOT / "acl", site / "acl", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(ROOT / "stdlib", site / "acl" / "stdlib")
    shutil.copytree(ROOT / "docs", site / "acl" / "docs")
    code = ("import acl, acl._resources as r; print(r.shipped_dir('stdlib')); print(r.shipped_dir('docs')); "
            "d = acl.load(%r); print(d.medium.name)" % str(ROOT / "examples" / "fig2_vertical_cantilever.acl"))
    env = {**os.environ, "PYTHONPATH": str(site)}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    stdlib_dir, docs_dir, medium = proc.stdout.split()
    assert stdlib_dir == str(site / "acl" / "stdlib") and docs_dir == str(site / "acl" / "docs")
    assert medium


def test_shipped_ci_workflow_installs_acl_from_the_checkout():
    text = (ROOT / ".github" / "workflows" / "acl-lint.yml").read_text()
    installs = [line for line in text.splitlines() if "pip install" in line and not line.lstrip().startswith("#")]
    assert installs and all(re.search(r"pip install\s+(\.|'\.|\"\.|\S*git\+)", line) for line in installs), installs


@pytest.mark.parametrize("argv", [
    ["analyze", "examples/fig4_facing_pair.acl", "--plot", "FIGS"],
    ["compile", "examples/fig3_three_orifice.acl", "--program", "rectangle", "-o", "OUT", "--plot"],
    ["fit", "examples/fig2_vertical_cantilever.acl", "DATA", "--report", "REPORT"],
    ["sweep", "examples/fig4_facing_pair.acl", "--vary", "gap=30um..40um:2", "-o", "OUT.csv", "--plot", "FIGS"],
], ids=["analyze", "compile", "fit", "sweep"])
def test_plot_without_matplotlib_is_a_clear_diagnostic(tmp_path, monkeypatch, capsys, argv):
    """matplotlib is the `plot` extra: without it, --plot/--report stop with E-PLOT before any work."""
    import acl.analysis.report
    import acl.fit
    import acl.schedule.compile
    import acl.sweep.driver
    from acl.cli import main

    def work(*a, **k):
        raise AssertionError("the work started although the figures cannot be drawn")

    for module, name in ((acl.fit, "run_fit"), (acl.analysis.report, "analyze"),
                         (acl.schedule.compile, "compile_program"), (acl.sweep.driver, "run_sweep")):
        if hasattr(module, name):
            monkeypatch.setattr(module, name, work)
    monkeypatch.setitem(sys.modules, "matplotlib", None)      # as if not installed
    data = tmp_path / "d.csv"
    data.write_text("observable,value,unit,drive\ntip_x,1,um,125 kHz @ 2 V\n")
    names = {"FIGS": str(tmp_path / "figs"), "OUT": str(tmp_path / "out"), "DATA": str(data),
             "REPORT": str(tmp_path / "rep")}
    monkeypatch.chdir(ROOT)
    assert main([names.get(a, a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert "E-PLOT" in err and "acl[plot]" in err
    assert ("--calibrated PATH" in err) == (argv[0] == "fit")     # fit names the way without figures
    assert "E-INTERNAL" not in err and "AssertionError" not in err
    assert not any((tmp_path / n).exists() for n in ("figs", "out", "rep", "out.csv"))


def test_a_broken_matplotlib_stops_fit_report_before_the_fit(tmp_path):
    """matplotlib found but not importable (a missing shared library): E-PLOT before the (minutes-long) fit,
    nothing written.  Before, the fit ran to its end, then figure drawing failed: E-INTERNAL."""
    fake = tmp_path / "site" / "matplotlib"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text('raise ImportError("libfreetype.so.6: cannot open shared object file")\n')
    data = ROOT / "tests" / "hostile" / "inputs" / "data_ok.csv"
    code = ("import sys, acl.fit\n"
            "def run_fit(*a, **k):\n    print('FIT RAN'); raise SystemExit(99)\n"
            "acl.fit.run_fit = run_fit\n"
            "from acl.cli import main\n"
            f"sys.exit(main(['fit', {str(ROOT / 'samples' / 'fit_cantilever.acl')!r}, {str(data)!r}, "
            f"'--free', 'gamma', '--report', 'rep', '--calibrated', 'cal.acl']))\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path / "site"), str(ROOT)])}
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    assert "FIT RAN" not in proc.stdout
    assert ("<--report>:1:1: error[E-PLOT]: --report draws figures with matplotlib, which cannot be imported "
            "(ImportError: libfreetype.so.6") in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr and "E-INTERNAL" not in proc.stderr
    assert sorted(os.listdir(tmp_path)) == ["site"]


def test_pyproject_lists_every_package_of_acl():
    """pyproject.toml names the packages (a mapped folder cannot be found by `packages.find`): a new folder of
    acl/ with an __init__.py must be listed there, or the wheel silently leaves it out."""
    import tomllib

    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "acl").rglob("__init__.py")
             if "__pycache__" not in p.parts}
    assert set(config["packages"]) == found | {"acl.stdlib", "acl.docs"}
    assert config["package-dir"] == {"acl.stdlib": "stdlib", "acl.docs": "docs"}
    assert not (ROOT / "setup.py").exists()

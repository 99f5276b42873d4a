"""`acl sweep` on the command line: the summary line, JSON, figures, and every bad input (exit 2,
a located diagnostic, no traceback, no output file)."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from acl.cli import main

ROOT = Path(__file__).resolve().parents[1]
CANTILEVER = str(ROOT / "samples" / "sweep_cantilever.acl")


def test_sweep_writes_a_table_and_prints_the_yield(tmp_path):
    out = tmp_path / "t.csv"
    r = subprocess.run([sys.executable, "-m", "acl", "sweep", CANTILEVER, "--vary", "radius=9um..11um:3",
                        "--tolerance", "radius=normal(0, 150 nm)", "--samples", "50", "--seed", "3", "-o", str(out)],
                       capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert r.returncode == 0, r.stderr
    assert re.search(r"yield \d\.\d\d \[\d\.\d\d, \d\.\d\d\]", r.stdout), r.stdout
    lines = out.read_text().splitlines()
    assert len(lines) == 151 and lines[0].startswith("point,radius,height,valid,code,")


def test_json_summary_and_same_seed_same_rows(tmp_path, capsys):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    args = [CANTILEVER, "--samples", "30", "--seed", "9", "--output-format", "json"]
    assert main(["sweep", *args, "-o", str(a)]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["points"] == 30 and s["samples"] == 30 and {t["name"] for t in s["tolerances"]} == {"radius", "height"}
    y = s["yields"]["all"]
    assert y["lower"] <= y["yield"] <= y["upper"] and y["interval"] == "clopper-pearson"
    assert s["grid_yield"] is None
    assert main(["sweep", *args, "-o", str(b)]) == 0
    assert a.read_text() == b.read_text()


def test_figures(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    figs = tmp_path / "figs"
    assert main(["sweep", CANTILEVER, "--vary", "radius=9um..11um:3", "--vary", "height=30um,34um", "--samples", "20",
                 "--tolerance-scales", "0.5,1,2", "-o", str(tmp_path / "t.csv"), "--plot", str(figs)]) == 0
    names = sorted(p.name for p in figs.iterdir())
    assert "passmap_radius_height.png" in names and "yield_vs_tolerance.png" in names
    assert "hist_resonance_act_1_hz.png" in names
    assert all((figs / n).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for n in names)
    assert "tolerance x2" in capsys.readouterr().out


def test_figures_of_a_quantity_the_sweep_does_not_move(tmp_path):
    """A gap spread leaves the resonances constant up to round-off: the histogram once raised
    `ValueError: Too many bins for data range` (E-INTERNAL) after the table was written."""
    pytest.importorskip("matplotlib")
    figs = tmp_path / "figs"
    pair = str(ROOT / "examples" / "fig4_facing_pair.acl")
    assert main(["sweep", pair, "--tolerance", "gap=normal(0, 2 um)", "--samples", "200", "--at", "125 kHz @ 2 V",
                 "-o", str(tmp_path / "p.csv"), "--plot", str(figs)]) == 0
    assert "hist_resonance_left_1_hz.png" in {p.name for p in figs.iterdir()}


def _main(argv) -> int:
    try:
        return main(argv)
    except SystemExit as exc:         # argparse's own errors (bad integers) exit 2 with E-USAGE
        return exc.code


@pytest.mark.parametrize("extra, where", [
    (["--vary", "radius=8um..12um"], "<--vary>:1:18"),                        # no N
    (["--vary", "radius=8um..12um:0"], "<--vary>:1:18"),                      # N < 1
    (["--vary", "radus=8um..12um:5"], "<--vary>:1:1"),                        # unknown parameter
    (["--vary", "radius=8V..12V:5"], "<--vary>:1:8"),                         # wrong unit
    (["--vary", "radius"], "<--vary>:1:1"),                                   # no '='
    (["--tolerance", "radius=normal(0, 150 V)"], "<--tolerance>:1:18"),       # wrong unit
    (["--tolerance", "radius=gauss(0, 1 um)"], "<--tolerance>:1:8"),          # unknown distribution
    (["--tolerance", "radius=normal(0,"], "<--tolerance>:1:16"),              # syntax
    (["--samples", "0"], "<--samples>"),                                      # N < 1
    (["--samples", "ten"], "<--samples>"),
    (["--seed", "-1"], "<--seed>"),                                           # bad seed
    (["--seed", "x"], "<--seed>"),
    (["--scheduler", "ftp://host:1"], "<--scheduler>:1:1"),
    (["--at", "125 kHz @ 6 um"], "<--at>"),
    (["--quantity", "resonance_nope_hz"], "<--quantity>:1:1"),
    (["--tolerance-scales", "1,x"], "<--tolerance-scales>:1:3"),
])
def test_bad_input_is_a_located_diagnostic(tmp_path, capsys, extra, where):
    out = tmp_path / "t.csv"
    base = [] if extra[0] in ("--vary", "--tolerance") else ["--vary", "radius=9um..11um:3"]
    code = _main(["sweep", CANTILEVER, *base, *extra, "-o", str(out)])
    err = capsys.readouterr()
    assert code == 2
    assert where in err.err + err.out and "Traceback" not in err.err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("name, make, where", [
    ("t.txt", None, "<-o>"),                              # bad suffix
    ("t", None, "<-o>"),                                  # no suffix
    ("missing/t.csv", None, "<-o>"),                      # no such folder
    ("folder.csv", "dir", "<-o>"),                        # a folder
])
def test_bad_output_is_refused_before_any_work(tmp_path, capsys, name, make, where):
    target = tmp_path / name
    if make == "dir":
        target.mkdir()
    code = main(["sweep", CANTILEVER, "--vary", "radius=9um..11um:3", "-o", str(target)])
    err = capsys.readouterr().err
    assert code == 2 and where in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == (["folder.csv"] if make else [])


def test_unwritable_folder(tmp_path, capsys):
    import os

    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if os.access(ro, os.W_OK):
            pytest.skip("running as a user who can write anywhere (root)")
        code = main(["sweep", CANTILEVER, "--vary", "radius=9um..11um:3", "-o", str(ro / "t.csv")])
        assert code == 2 and "E601" in capsys.readouterr().err
        assert not list(ro.iterdir())
    finally:
        ro.chmod(0o700)


def test_parquet_without_pyarrow(tmp_path, capsys, monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "pyarrow" else real(name, *a))
    code = main(["sweep", CANTILEVER, "--vary", "radius=9um..11um:3", "-o", str(tmp_path / "t.parquet")])
    err = capsys.readouterr().err
    assert code == 2 and "pyarrow" in err and "acl[scale]" in err and "<-o>" in err
    assert not list(tmp_path.iterdir())


def test_design_errors_exit_1_without_output(tmp_path, capsys):
    bad = tmp_path / "bad.acl"
    bad.write_text("param r = 10 um +- gauss(0, 1 um)\n")
    code = main(["sweep", str(bad), "--vary", "r=1um..2um:2", "-o", str(tmp_path / "t.csv")])
    assert code == 1 and "E322" in capsys.readouterr().err
    assert not (tmp_path / "t.csv").exists()


def test_check_and_lint_do_not_import_the_sweep_stage():
    """`acl check` and `acl lint` start fast: neither numpy-heavy acl.sweep nor scipy/matplotlib/dask/pyarrow."""
    code = ("import sys\nfrom acl.cli import main\n"
            "rc = main(['check', 'samples/sweep_cantilever.acl']) + main(['lint', 'samples/sweep_cantilever.acl'])\n"
            "heavy = sorted({m for m in sys.modules if m.startswith('acl.sweep')} | ({m.split('.')[0] for m in sys.modules}"
            " & {'cvxpy', 'matplotlib', 'dask', 'distributed', 'pyarrow'}))\n"
            "sys.stderr.write('HEAVY=' + ','.join(heavy) + ' RC=' + str(rc))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert "HEAVY= RC=" in r.stderr, r.stderr[-2000:]


def test_json_grid_yield_per_grid_point(tmp_path, capsys):
    assert main(["sweep", CANTILEVER, "--vary", "radius=9um..11um:3", "--vary", "height=30um,34um", "--samples", "40",
                 "-o", str(tmp_path / "g.csv"), "--output-format", "json"]) == 0
    s = json.loads(capsys.readouterr().out)
    g = s["grid_yield"]
    assert len(g) == 3 and all(len(row) == 2 for row in g)
    assert sum(sum(row) for row in g) * 40 == pytest.approx(s["yields"]["all"]["passed"])


def test_a_spread_of_metres_gives_invalid_rows_not_a_usage_error(tmp_path, capsys):
    """A 1000 km spread on a 10 um radius: the map's first step (the whole range) resolved nowhere and
    the sweep stopped with E-USAGE at the design's line 1; now every point is a row with its code."""
    out = tmp_path / "h.csv"
    assert main(["sweep", CANTILEVER, "--tolerance", "radius=normal(0, 1e12 um)", "--samples", "100", "-o", str(out)]) == 0
    rows = out.read_text().splitlines()[1:]
    codes = {r.split(",")[4] for r in rows}
    assert len(rows) == 100 and codes <= {"E401", "E402"} and len(codes) == 2
    assert "100 invalid" in capsys.readouterr().out


def test_yield_vs_tolerance_lines_round_their_bounds_outwards(tmp_path, capsys):
    """`tolerance xS` lines printed bounds to the nearest 0.01 (a lower bound 0.998 of 2000 of 2000
    as 1.00); they now use the summary's text, rounded outwards."""
    from acl.sweep.table import Yield, clopper_pearson

    assert main(["sweep", CANTILEVER, "--samples", "300", "--tolerance-scales", "0,1", "-o", str(tmp_path / "t.csv")]) == 0
    lines = [ln.strip() for ln in capsys.readouterr().out.splitlines() if ln.strip().startswith("tolerance x0:")]
    assert lines == [f"tolerance x0: yield {Yield(300, 300, *clopper_pearson(300, 300)).text()}"]
    assert lines[0].endswith("[0.987, 1.000]")           # lower bound 0.9878, never shown as 1.00


def test_a_folder_without_suffix_is_named_a_folder(tmp_path, capsys):
    """`-o results/` (a folder) was "the table is written as .csv or .parquet, not 'a file without suffix'"."""
    (tmp_path / "results").mkdir()
    code = main(["sweep", CANTILEVER, "--vary", "radius=9um..11um:3", "-o", str(tmp_path / "results")])
    err = capsys.readouterr().err
    assert code == 2 and "<-o>:1:1: error[E601]: cannot write" in err and "it is a folder" in err, err


def test_grid_sweep_prints_the_yield_of_each_grid_point(tmp_path, capsys):
    """Issue 28: a grid with Monte Carlo printed only the pooled yield; each grid point's yield (with its
    interval) is printed too, and agrees with the table's rows counted by hand."""
    import csv

    out = tmp_path / "g.csv"
    assert main(["sweep", str(ROOT / "examples" / "fig3_robust_radii.acl"), "--vary", "r1=8um..14um:5",
                 "--samples", "40", "--seed", "1", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "yield per grid point (40 samples each):" in text
    shown = re.findall(r"^    r1=([\d.]+) um: (\d\.\d+) \[", text, re.M)
    assert [r for r, _ in shown] == ["8", "9.5", "11", "12.5", "14"]
    rows = list(csv.DictReader(out.open()))
    for g, (_, y) in enumerate(shown):
        mine = rows[40 * g: 40 * (g + 1)]
        ok = sum(r["valid"].lower() == "true" and all(r[f"require_{i}_pass"].lower() == "true" for i in range(1, 5)) for r in mine)
        assert abs(float(y) - ok / 40) <= 0.005 + 1e-12, (g, y, ok)
    ys = [float(y) for _, y in shown]
    assert min(ys) < 0.2 and max(ys) > 0.8          # the pooled yield alone hides this spread

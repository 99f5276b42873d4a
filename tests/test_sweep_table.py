"""Sweep tables: yields with exact intervals, CSV/Parquet round trips, atomic writes, the Python API."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

import acl
from acl.sweep import table as T

ROOT = Path(__file__).resolve().parents[1]
CANTILEVER = ROOT / "samples" / "sweep_cantilever.acl"


@pytest.mark.parametrize("k, n", [(0, 10), (10, 10), (93, 100), (1, 2), (930, 1000), (0, 1)])
def test_clopper_pearson_against_beta_quantiles(k, n):
    """Against scipy.stats.beta quantiles (an independent implementation) and the closed forms at k = 0, n."""
    from scipy.stats import beta

    lo, hi = T.clopper_pearson(k, n)
    want_lo = 0.0 if k == 0 else beta.ppf(0.025, k, n - k + 1)
    want_hi = 1.0 if k == n else beta.ppf(0.975, k + 1, n - k)
    assert lo == pytest.approx(want_lo, rel=1e-9, abs=1e-12) and hi == pytest.approx(want_hi, rel=1e-9, abs=1e-12)
    if k == 0:
        assert hi == pytest.approx(1 - 0.025 ** (1 / n), rel=1e-9)
    assert lo <= k / n <= hi


def test_yield_text_rounds_outwards():
    y = T.Yield(930, 1000, *T.clopper_pearson(930, 1000))
    lo, hi = y.lower, y.upper            # 0.9126.., 0.9455..
    assert y.text() == f"0.93 [{math.floor(lo * 100) / 100:.2f}, {math.ceil(hi * 100) / 100:.2f}]" == "0.93 [0.91, 0.95]"


@pytest.fixture(scope="module")
def table():
    return acl.sweep(str(CANTILEVER), vary={"radius": "8um..12um:5"}, tolerance={"radius": "normal(0, 300 nm)"}, n=40, seed=5)


def test_api_table_columns_and_yields(table):
    assert len(table) == 200
    assert table.columns[:5] == ("point", "radius", "height", "valid", "code")
    assert "resonance_act_1_hz" in table.columns and "require_1_pass" in table.columns
    assert table["point"].tolist() == list(range(200))
    ok = table["valid"] & table["require_1_pass"]
    y = table.yields()
    assert y["all"].passed == int(ok.sum()) and y["all"].total == 200
    assert table.grid_yield().shape == (5,)
    assert table.grid_yield()[2] > table.grid_yield()[0]            # 10 um sits in the required band, 8 um does not
    arrow = table.to_arrow()
    assert arrow.num_rows == 200 and arrow.column_names == list(table.columns)
    import acl.sweep.spec  # noqa: F401  (importing the package keeps acl.sweep callable)

    assert len(acl.sweep(str(CANTILEVER), vary={"radius": [9e-6, 10e-6]})) == 2


def test_csv_round_trip_is_bit_exact(table, tmp_path):
    out = tmp_path / "t.csv"
    T.write_table(table, str(out))
    with open(out, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == list(table.columns) and len(rows) == 201
    col = table.columns.index("resonance_act_1_hz")
    got = np.array([float(r[col]) for r in rows[1:]])
    assert np.array_equal(got, table["resonance_act_1_hz"], equal_nan=True)
    assert [r[table.columns.index("valid")] for r in rows[1:]] == [str(v) for v in table["valid"]]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".acl-")]


def test_parquet_round_trip(table, tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    out = tmp_path / "t.parquet"
    T.write_table(table, str(out))
    back = pq.read_table(str(out))
    assert back.column_names == list(table.columns)
    assert np.array_equal(back.column("radius").to_numpy(), table["radius"])


def test_failed_write_leaves_nothing(table, tmp_path, monkeypatch):
    out = tmp_path / "t.csv"
    out.write_text("old\n")

    def broken(tab, fh, rows_per_block=0):
        fh.write("point,radius\n0,")
        raise OSError(28, "No space left on device")

    def broken_arrow(tab, path, rows_per_batch=0):      # the writer used when pyarrow is installed
        with open(path, "w") as fh:
            broken(tab, fh)

    monkeypatch.setattr(T, "write_csv", broken)
    monkeypatch.setattr(T, "write_csv_arrow", broken_arrow)
    with pytest.raises(OSError):
        T.write_table(table, str(out))
    assert out.read_text() == "old\n"                                  # the old file is untouched
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.csv"]     # no temporary left


def test_yield_agrees_with_brute_force_analyze():
    """200 Monte Carlo points: every point's require verdict equals `acl analyze` of the same design
    resolved from scratch (acl.load with the point's values), so the yield is the brute-force yield."""
    t = acl.sweep(str(CANTILEVER), tolerance={"radius": "normal(0, 1 um)", "height": "normal(0, 3 um)"}, n=200, seed=11,
                  quantities=["resonance_act_1_hz"])
    passed = 0
    for i in range(len(t)):
        d = acl.load(str(CANTILEVER), overrides={"radius": float(t["radius"][i]), "height": float(t["height"][i])})
        a = acl.analyze(d, snap_in=False)
        ok = all(r["ok"] for r in a.as_dict()["requires"])
        assert ok == bool(t["require_1_pass"][i]), i
        assert a.resonance("act") == pytest.approx(t["resonance_act_1_hz"][i], rel=1e-9)
        passed += ok
    assert 0 < passed < 200                       # the spread straddles the band's edges
    assert t.yields()["all"].passed == passed


def test_narrow_interval_gets_more_decimals():
    """1,000,000 passes of 1,000,000: the lower bound 0.9999963 would print as 0.99 at two decimals."""
    y = T.Yield(10**6, 10**6, *T.clopper_pearson(10**6, 10**6))
    assert y.text() == "1.0000 [0.9999, 1.0000]"


def test_api_takes_a_loaded_design_but_not_one_from_text():
    from acl.diagnostics import DiagnosticError

    d = acl.load(str(CANTILEVER))
    assert len(acl.sweep(d, vary={"radius": "9um..10um:2"})) == 2
    text = acl.loads(CANTILEVER.read_text(), filename="<string>")
    with pytest.raises(DiagnosticError) as exc:
        acl.sweep(text, vary={"radius": "9um..10um:2"})
    assert exc.value.diagnostics[0].code == "E-USAGE" and "not a file" in exc.value.diagnostics[0].message


def test_two_worker_local_cluster_table_equals_one_process_bit_for_bit():
    """The whole sweep (sample, perturb, evaluate) as dask tasks on 2 worker processes: the same table."""
    distributed = pytest.importorskip("distributed")
    kw = dict(vary={"radius": "9um..11um:3"}, tolerance={"radius": "normal(0, 300 nm)"}, n=3000, seed=4)
    single = acl.sweep(str(CANTILEVER), **kw)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        from acl.sweep.driver import sweep

        on_cluster = sweep(str(CANTILEVER), scheduler=cluster.scheduler_address, chunk_size=1000, **kw)
        chunked_here = sweep(str(CANTILEVER), chunk_size=1000, **kw)
    assert on_cluster.data.dtype == chunked_here.data.dtype
    assert on_cluster.data.tobytes() == chunked_here.data.tobytes()
    assert len(single) == len(on_cluster) == 9000
    assert single.columns == on_cluster.columns


def test_require_bounds_follow_a_swept_parameter(tmp_path):
    """`require resonance(act) in f0 - 5 kHz .. f0 + 5 kHz` with f0 swept: the verdict uses each point's band."""
    path = tmp_path / "band.acl"
    path.write_text(CANTILEVER.read_text().replace("require resonance(act) in 110 kHz .. 135 kHz",
                                                   "param f0 = 122 kHz\nrequire resonance(act) in f0 - 5 kHz .. f0 + 5 kHz"))
    t = acl.sweep(str(path), vary={"f0": "100kHz..140kHz:5"}, quantities=["resonance_act_1_hz"])
    f = t["resonance_act_1_hz"][0]
    assert 117e3 < f < 127e3                                   # one point's band holds it
    assert t["require_1_pass"].tolist() == [abs(f - f0) <= 5e3 for f0 in t["f0"]]
    assert t["require_1_pass"].sum() == 1


def test_parameter_moving_a_drive_amplitude_keeps_the_program_columns_per_point():
    """A swept drive voltage (fig1f `volts`) no longer drops the forces: they are computed at each point's
    amplitude (tests/test_sweep_drives.py compares them with analyze); a moving tone frequency still
    drops them (same file)."""
    path = str(ROOT / "examples" / "fig1f_selective_beams.acl")
    t = acl.sweep(path, vary={"volts": "1V..3V:3"})
    assert "resonance_low_1_hz" in t.columns and "force_low_high_85khz_n" in t.columns
    # no program column left out (a deflection without `at` is, and says so: acl.sweep.driver.left_out)
    assert not any("left out" in n and "a swept parameter moves" in n for n in t.notes), t.notes
    assert [n for n in t.notes if "not computed" in n] == [
        "columns not computed: tip_deflection: deflections need a drive: give `at` (like `acl analyze --at`)"]
    f = t["force_low_high_85khz_n"]
    assert f[1] / f[0] == pytest.approx(4, rel=1e-12) and f[2] / f[0] == pytest.approx(9, rel=1e-12)   # F ~ V^2
    moved = acl.sweep(path, vary={"spacing": "80um..120um:3"})      # geometry only: forces are batched
    assert "force_low_high_85khz_n" in moved.columns


@pytest.mark.parametrize("k, n, want", [
    (2999995, 3000000, "0.9999 [0.9999, 1.0000]"),   # 5 failures: never printed as a perfect 1.0000
    (5, 3000000, "0.0000 [0.0000, 0.0001]"),         # rounding down is the safe side: kept
    (3000000, 3000000, "1.0000 [0.9999, 1.0000]"),
])
def test_point_estimate_is_not_rounded_up_to_all(k, n, want):
    assert T.Yield(k, n, *T.clopper_pearson(k, n)).text() == want


def test_to_pandas_without_pandas_says_what_to_install(table, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "pandas", None)       # `import pandas` raises ImportError
    with pytest.raises(ImportError, match="pip install pandas"):
        table.to_pandas()

"""Issue 28: tables written through pyarrow when it is installed.

The CSV through pyarrow has the Python writer's header, integers, booleans, codes, nan and inf; a
float is spelled as pyarrow spells its shortest round-trip digits (``3`` for ``3.0``, ``0.00001``
for ``1e-05``), so the bytes differ there: these tests prove that every reader reads the same values
from both files.  Parquet carries each column's unit (field and schema metadata) and is written in
row groups."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

import acl
from acl.sweep import table as T

pa = pytest.importorskip("pyarrow")
ROOT = Path(__file__).resolve().parents[1]
CANTILEVER = ROOT / "samples" / "sweep_cantilever.acl"
AWKWARD = np.array([0.0, -0.0, 3.0, 100.0, 1e-05, 2.5e-07, 1.2345678901234567e-06, 1e15, 1e16, 1e22, 0.1 + 0.2,
                    5e-324, 2.2250738585072014e-308, 1.7976931348623157e308, -1.5e-300, np.nan, np.inf, -np.inf,
                    123456789012345678.0, 9.999999999999999e-05])


@pytest.fixture(scope="module")
def table():
    t = acl.sweep(str(CANTILEVER), vary={"radius": "8um..12um:5"}, tolerance={"radius": "normal(0, 300 nm)"}, n=40, seed=5)
    rng = np.random.default_rng(0)
    data = t.data.copy()
    col = "resonance_act_1_hz"
    k = len(AWKWARD)
    data[col][:k] = AWKWARD                         # every awkward spelling in one column
    data[col][k:] = rng.standard_normal(len(data) - k) * 10.0 ** rng.integers(-300, 300, len(data) - k)
    return T.SweepTable(data, t.spec, units=t.units, notes=t.notes, unevaluated=t.unevaluated, n_requires=t.n_requires)


def _both(table, tmp_path):
    a, b = tmp_path / "arrow.csv", tmp_path / "python.csv"
    T.write_csv_arrow(table, str(a))
    with open(b, "w", encoding="utf-8", newline="") as fh:
        T.write_csv(table, fh)
    return a, b


def _bits(x: np.ndarray) -> np.ndarray:
    return np.asarray(x, np.float64).view(np.int64)


def test_python_csv_reader_reads_the_same_values_bit_for_bit(table, tmp_path):
    a, b = _both(table, tmp_path)
    ra, rb = (list(csv.reader(open(p, newline=""))) for p in (a, b))
    assert ra[0] == rb[0] == list(table.columns) and len(ra) == len(rb) == len(table) + 1
    for j, c in enumerate(table.columns):
        kind = table.data[c].dtype.kind
        ca, cb = [r[j] for r in ra[1:]], [r[j] for r in rb[1:]]
        if kind == "f":
            fa, fb = np.array([float(v) for v in ca]), np.array([float(v) for v in cb])
            same_nan = np.isnan(fa) == np.isnan(fb)
            assert same_nan.all() and np.array_equal(_bits(fa[~np.isnan(fa)]), _bits(table.data[c][~np.isnan(fa)]))
            assert np.array_equal(_bits(fa[~np.isnan(fa)]), _bits(fb[~np.isnan(fb)]))
        else:
            assert ca == cb, c                                  # ints, True/False, codes: the same text


def test_numpy_reads_the_same_table_from_both(table, tmp_path):
    a, b = _both(table, tmp_path)
    na, nb = (np.genfromtxt(p, delimiter=",", names=True, dtype=None, encoding="utf-8") for p in (a, b))
    # a float column whose every value is integral (model_form_rel = 0 below the validity limits) was spelled `0` by
    # pyarrow and `0.0` by Python, so numpy and pandas guessed int for one and float for the other: now `0.0` in both
    assert na.dtype.names == nb.dtype.names
    assert (table.data["model_form_rel"] == 0).all()        # the case stays in the table
    for c in na.dtype.names:
        assert na[c].dtype.kind == nb[c].dtype.kind, (c, na[c].dtype, nb[c].dtype)
        if na[c].dtype.kind == "f":
            assert np.array_equal(na[c], nb[c], equal_nan=True)
            assert np.array_equal(_bits(na[c][~np.isnan(na[c])]), _bits(nb[c][~np.isnan(nb[c])]))
        else:
            assert (na[c] == nb[c]).all()


def test_pandas_reads_the_same_frame_from_both(table, tmp_path):
    pd = pytest.importorskip("pandas")
    a, b = _both(table, tmp_path)
    fa, fb = pd.read_csv(a, keep_default_na=False, na_values=["nan"]), pd.read_csv(b, keep_default_na=False, na_values=["nan"])
    pd.testing.assert_frame_equal(fa, fb, check_exact=True)


def test_write_table_goes_through_pyarrow_and_stays_atomic(table, tmp_path):
    out = tmp_path / "t.csv"
    T.write_table(table, str(out))
    (tmp_path / "x").mkdir()
    a, _ = _both(table, tmp_path / "x")
    assert out.read_bytes() == a.read_bytes()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".acl-")]


def test_an_empty_table_is_the_header_alone(table, tmp_path):
    empty = T.SweepTable(table.data[:0], table.spec, units=table.units, n_requires=table.n_requires)
    a, b = _both(empty, tmp_path)
    assert a.read_bytes() == b.read_bytes() == (",".join(table.columns) + "\n").encode()


def test_parquet_carries_units_and_is_written_in_row_groups(table, tmp_path, monkeypatch):
    pq = pytest.importorskip("pyarrow.parquet")
    monkeypatch.setattr(T, "ROW_GROUP", 64)
    out = tmp_path / "t.parquet"
    T.write_table(table, str(out))
    f = pq.ParquetFile(str(out))
    assert f.metadata.num_row_groups == -(-len(table) // 64) and f.metadata.num_rows == len(table)
    schema = f.schema_arrow
    units = json.loads(schema.metadata[b"acl.units"])
    assert units["radius"] == "m" and units["resonance_act_1_hz"] == "Hz"
    assert schema.field("radius").metadata[b"unit"] == b"m" and schema.field("valid").metadata is None
    meta = json.loads(schema.metadata[b"acl.sweep"])
    assert meta["points"] == len(table) and meta["summary"] == table.summary_line()
    back = f.read()
    assert np.array_equal(back.column("resonance_act_1_hz").to_numpy(), table["resonance_act_1_hz"], equal_nan=True)

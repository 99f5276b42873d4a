"""acl.sweep.run.map_chunks: chunks as tasks, in order, identical on one process, threads and a cluster."""
from __future__ import annotations

import socket
import sys

import numpy as np
import pytest

from acl.diagnostics import DiagnosticError
from acl.sweep.run import map_chunks, scheduler_kind


def _chunk(k: int, seed: int = 7, size: int = 5000) -> np.ndarray:
    """A chunk's numbers from its own stream keyed on (seed, k), as acl.sweep.sample draws them."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(k,)))
    x = rng.normal(10e-6, 150e-9, size)
    return np.sqrt(x) * np.exp(-x * 1e4) + np.sin(x * 1e6)


def _fails_on_two(k: int) -> int:
    if k == 2:
        raise DiagnosticError([])
    return k


def test_one_chunk_runs_in_this_process():
    import threading

    seen = []
    out = map_chunks(lambda k: seen.append(threading.get_ident()) or k, 1)
    assert out == [0] and seen == [threading.get_ident()]


def test_local_results_come_back_in_chunk_order_with_progress():
    calls = []
    out = map_chunks(_chunk, 9, "local", progress=lambda d, t: calls.append((d, t)))
    assert len(out) == 9
    for k, arr in enumerate(out):
        assert np.array_equal(arr, _chunk(k))
    assert [d for d, _ in calls] == list(range(1, 10)) and {t for _, t in calls} == {9}


def test_zero_chunks_is_an_empty_list():
    assert map_chunks(_chunk, 0) == []


def test_a_task_error_propagates_unchanged():
    with pytest.raises(DiagnosticError):
        map_chunks(_fails_on_two, 5, "local")


@pytest.mark.parametrize("bad", ["cluster", "tcp://host", "tcp://host:0", "http://h:8786", "tcp://h:99999", ""])
def test_a_bad_scheduler_is_a_located_usage_error(bad):
    with pytest.raises(DiagnosticError) as exc:
        scheduler_kind(bad)
    d = exc.value.diagnostics[0]
    assert d.code == "E-USAGE" and d.span.file == "<--scheduler>"


def test_cluster_without_dask_installed_is_a_located_usage_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)       # import distributed -> ImportError
    with pytest.raises(DiagnosticError) as exc:
        map_chunks(_chunk, 2, "tcp://127.0.0.1:8786")
    d = exc.value.diagnostics[0]
    assert d.code == "E-USAGE" and "acl[scale]" in d.hint and d.span.file == "<--scheduler>"


def test_local_needs_no_dask(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    monkeypatch.setitem(sys.modules, "dask", None)
    out = map_chunks(_chunk, 3, "local")
    assert all(np.array_equal(a, _chunk(k)) for k, a in enumerate(out))


def test_unreachable_scheduler_is_E_CLUSTER_after_the_timeout(monkeypatch):
    pytest.importorskip("distributed")
    import acl.sweep.run as R

    monkeypatch.setattr(R, "CONNECT_TIMEOUT_S", 1.0)
    with socket.socket() as s:                 # a port nobody listens on: bind, then close
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(DiagnosticError) as exc:
        map_chunks(_chunk, 2, f"tcp://127.0.0.1:{port}")
    d = exc.value.diagnostics[0]
    assert d.code == "E-CLUSTER" and "cannot reach" in d.message and d.span.file == "<--scheduler>"


@pytest.fixture(scope="module")
def cluster():
    """One LocalCluster of 2 worker processes for the module (starting one takes seconds)."""
    distributed = pytest.importorskip("distributed")
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])   # workers need not import this test file
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as c:
        yield c


def test_two_worker_local_cluster_equals_one_process_bit_for_bit(cluster):
    single = map_chunks(_chunk, 6, None)
    calls = []
    on_cluster = map_chunks(_chunk, 6, cluster.scheduler_address, progress=lambda d, t: calls.append(d))
    assert len(on_cluster) == 6 and sorted(calls) == list(range(1, 7))
    for a, b in zip(single, on_cluster):
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes()


def test_a_sweep_on_the_cluster_equals_the_single_process_table_bit_for_bit(cluster):
    from pathlib import Path

    from acl.sweep.driver import sweep

    design = Path(__file__).resolve().parents[1] / "benchmarks" / "designs" / "sweep_cantilever.acl"
    kw = dict(n=3000, seed=11, chunk_size=1000, at="125 kHz @ 2 V",
              quantities=["resonance_act_1_hz", "q_act_1", "tip_deflection_arm_m", "requires_pass"])
    one = sweep(str(design), scheduler=None, **kw).data
    two = sweep(str(design), scheduler=cluster.scheduler_address, **kw).data
    assert one.dtype == two.dtype and len(one) == 3000
    for name in one.dtype.names:
        assert one[name].tobytes() == two[name].tobytes(), name
    assert 0 < one["requires_pass"].sum() < 3000             # the columns hold real, varied results


def test_dask_and_pyarrow_are_the_scale_extra_which_the_test_extra_pulls_in():
    import tomllib
    from pathlib import Path

    project = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())["project"]
    extras = project["optional-dependencies"]
    assert not any(r.startswith(("dask", "distributed", "pyarrow")) for r in project["dependencies"])
    assert any(r.startswith("dask[distributed]") for r in extras["scale"])
    assert any(r.startswith("pyarrow") for r in extras["scale"])
    assert any(r.startswith("acl[") and "scale" in r for r in extras["test"])

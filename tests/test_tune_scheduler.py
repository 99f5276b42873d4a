"""`acl.tune(...)` (the Python API) and `acl tune --scheduler`: the tuned result is the same bit for bit
in one process, on local threads and on a 2-worker dask LocalCluster; bad schedulers are located."""
from __future__ import annotations

import json
import socket
from pathlib import Path

import numpy as np
import pytest

import acl
from acl.cli import main
from acl.diagnostics import DiagnosticError
from acl.sweep.tune import Free, maximise, require_margins

ROOT = Path(__file__).resolve().parents[1]
FIG3 = ROOT / "examples" / "fig3_robust_radii.acl"


class _Req:
    def __init__(self, lower=None, upper=None):
        self.lower, self.upper = lower, upper


def _window(seed: int = 3):
    z = np.random.default_rng(seed).normal(0.0, 0.3, (500, 2))
    reqs = [_Req(2.0, 8.0), _Req(3.0, None)]
    calls = []

    def evaluate(x):
        calls.append(tuple(x))
        v1 = x[0] + z[:, 0]
        return require_margins(reqs, [v1, (x[1] + z[:, 1]) - v1])

    return evaluate, calls


FREE = (Free("x1", "", 0.0, 10.0, 2.2), Free("x2", "", 0.0, 10.0, 5.3))


@pytest.mark.parametrize("method", ["nelder-mead", "powell", "differential-evolution"])
def test_evaluating_trials_together_changes_no_trial_and_no_result(method):
    one, _ = _window()
    many_eval, calls = _window()
    batches = []

    def many(xs):
        batches.append(len(xs))
        return [many_eval(x) for x in xs]

    a = maximise(one, FREE, method=method, max_evals=60)
    b = maximise(many_eval, FREE, method=method, max_evals=60, evaluate_many=many)
    assert a.evaluations == b.evaluations and np.array_equal(a.x, b.x) and a.score == b.score
    assert [tuple(h[0]) for h in a.history] == [tuple(h[0]) for h in b.history]
    assert [h[1:] for h in a.history] == [h[1:] for h in b.history]
    assert max(batches) >= 3                               # the scan / a generation / the simplex went together
    # nothing evaluated beyond the budget or twice (the start's margins are the first call)
    assert len(calls) == len(set(calls)) <= 60


def _same(a, b) -> None:
    assert a.chosen.tobytes() == b.chosen.tobytes()
    assert (a.before, a.after, a.before_search, a.after_search) == (b.before, b.after, b.before_search, b.after_search)
    assert a.search.evaluations == b.search.evaluations
    for (xa, sa, ya), (xb, sb, yb) in zip(a.search.history, b.search.history):
        assert xa.tobytes() == xb.tobytes() and sa == sb and ya == yb
    assert [r["worst_after"] for r in a.per_require] == [r["worst_after"] for r in b.per_require]


KW = dict(n=300, validate=300, seed=4, max_evals=30)


@pytest.fixture(scope="module")
def in_process():
    return acl.tune(str(FIG3), **KW)


def test_the_api_tunes_the_fig3_module_and_writes_a_design_that_checks(in_process, tmp_path):
    r = in_process
    assert r.after.value > r.before.value and r.after.interval[0] > r.before.interval[1]
    assert set(r.values) == {"r1", "r2", "r3"} and all(6e-6 <= v <= 16e-6 for v in r.values.values())
    assert r.to_json()["after"]["passed"] == r.after.passed and "yield before" in repr(r)
    out = r.write(str(tmp_path / "tuned.acl"))           # extends the original by a relative path
    assert Path(out).read_text().startswith("# Tuned by `acl tune`")
    tuned = acl.load(out, search_paths=[str(FIG3.parent)])
    assert [tuned.param(n).value for n in ("r1", "r2", "r3")] == [r.values[n] for n in ("r1", "r2", "r3")]


def test_the_api_takes_tolerances_as_sweep_does_and_local_threads_give_the_same_result(in_process):
    spreads = {"r1": "normal(0, 150 nm)", "r2": "normal(0, 150 nm)", "r3": "normal(0, 150 nm)"}
    a = acl.tune(str(FIG3), tolerance=spreads, scheduler="local", **KW)
    _same(in_process, a)


def test_bad_api_arguments_are_located_diagnostics():
    with pytest.raises(DiagnosticError) as exc:
        acl.tune(str(FIG3), objective="fastest", **KW)
    assert exc.value.diagnostics[0].code == "E-USAGE" and exc.value.diagnostics[0].span.file == "<--objective>"
    with pytest.raises(DiagnosticError) as exc:
        acl.tune(str(FIG3), scheduler="udp://x:1", **KW)
    assert exc.value.diagnostics[0].span.file == "<--scheduler>"
    with pytest.raises(DiagnosticError) as exc:
        acl.tune(str(FIG3), tolerance={"nope": "normal(0, 1 um)"}, **KW)
    assert exc.value.diagnostics[0].code == "E211"


@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as c:
        yield c


@pytest.mark.parametrize("method", ["nelder-mead", "differential-evolution"])
def test_a_two_worker_local_cluster_tunes_bit_for_bit_as_one_process(cluster, in_process, method):
    one = in_process if method == "nelder-mead" else acl.tune(str(FIG3), method=method, **KW)
    two = acl.tune(str(FIG3), method=method, scheduler=cluster.scheduler_address, **KW)
    _same(one, two)


def test_the_command_takes_the_scheduler_and_prints_the_same_json(cluster, capsys):
    args = ["tune", str(FIG3), "--samples", "300", "--validate", "300", "--seed", "4", "--max-evals", "30",
            "--no-write", "--output-format", "json", "-q"]
    assert main(args) == 0
    local = json.loads(capsys.readouterr().out)
    assert main(args + ["--scheduler", cluster.scheduler_address]) == 0
    remote = json.loads(capsys.readouterr().out)
    assert local == remote and local["after"]["passed"] > local["before"]["passed"]


def test_the_command_refuses_a_bad_or_unreachable_scheduler_with_exit_2(capsys, monkeypatch, tmp_path):
    out = tmp_path / "t.acl"
    assert main(["tune", str(FIG3), "--scheduler", "somewhere", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "E-USAGE" in err and "<--scheduler>:1:1" in err and not out.exists()
    pytest.importorskip("distributed")
    import acl.sweep.run as R

    monkeypatch.setattr(R, "CONNECT_TIMEOUT_S", 1.0)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    # --path: a tuned design in tmp_path may extend FIG3 (else E-USAGE before the scheduler is tried)
    assert main(["tune", str(FIG3), "--samples", "50", "--scheduler", f"tcp://127.0.0.1:{port}", "-o", str(out),
                 "--path", str(FIG3.parent)]) == 2
    err = capsys.readouterr().err
    assert "E-CLUSTER" in err and "<--scheduler>" in err and not out.exists()

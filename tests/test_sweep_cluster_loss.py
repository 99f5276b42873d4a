"""Issue 28, measured on a real dask cluster (a `dask scheduler` and `dask worker` processes on 127.0.0.1):
losing the scheduler or every worker mid-run is a located E601 (exit 2) and no table, never
E-INTERNAL after dask's traceback nor a hang; the worker setting acl ships removes the
MALLOC_TRIM_THRESHOLD_ dask's nanny sets.  Each test is bounded (a few tens of seconds at most)."""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parents[1]
FIG3 = ROOT / "examples" / "fig3_robust_radii.acl"
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(args) -> subprocess.Popen:
    # a session of its own: killing it kills the nanny and its worker process together
    return subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=ENV, start_new_session=True)


def _kill(p: subprocess.Popen) -> None:
    try:
        os.killpg(p.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    p.wait(timeout=30)


@pytest.fixture
def scheduler():
    port = _port()
    p = _start([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", str(port),
                "--no-dashboard"])
    address = f"tcp://127.0.0.1:{port}"
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                break
        time.sleep(0.2)
    try:
        yield p, address
    finally:
        _kill(p)


def _worker(address: str, *extra: str) -> subprocess.Popen:
    return _start([sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1", "--no-dashboard", *extra])


def _client(address):
    from distributed import Client

    c = Client(address, timeout="20s", set_as_default=False)
    c.wait_for_workers(1, timeout=60)
    return c


def _sweep(address: str, out: Path, *extra: str) -> subprocess.Popen:
    # many chunks of a slow-enough sweep: it is still running when the cluster goes
    return subprocess.Popen([sys.executable, "-m", "acl", "sweep", str(FIG3), "--samples", "400000", "--seed", "1",
                             "-o", str(out), "--scheduler", address, *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)


def _when_running(client, run: subprocess.Popen) -> None:
    """Wait until the scheduler holds the sweep's chunks (then the run is mid-way)."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and run.poll() is None:
        if any(client.processing().values()):
            return
        time.sleep(0.1)
    raise AssertionError("the sweep never reached the cluster")


def test_losing_the_scheduler_is_a_located_E601(scheduler, tmp_path):
    sched, address = scheduler
    w = _worker(address)
    try:
        c = _client(address)
        out = tmp_path / "t.csv"
        run = _sweep(address, out)
        _when_running(c, run)
        c.close()
        _kill(sched)
        stdout, stderr = run.communicate(timeout=60)
    finally:
        _kill(w)
    assert run.returncode == 2, stderr
    assert "<--scheduler>:1:1: error[E601]" in stderr and "lost the connection to the dask scheduler" in stderr
    assert "E-INTERNAL" not in stderr and "Traceback" not in stderr and "distributed.client" not in stderr
    assert not out.exists() and not list(tmp_path.iterdir())


def test_losing_every_worker_says_so_and_times_out(scheduler, tmp_path):
    _, address = scheduler
    w = _worker(address)
    c = _client(address)
    out = tmp_path / "t.csv"
    run = _sweep(address, out, "--timeout", "3")
    try:
        _when_running(c, run)
        t0 = time.monotonic()
        _kill(w)
        stdout, stderr = run.communicate(timeout=60)
        waited = time.monotonic() - t0
    finally:
        c.close()
        if run.poll() is None:
            run.kill()
    assert run.returncode == 2, stderr
    assert "has no worker: waiting up to 3 s" in stderr
    assert "<--scheduler>:1:1: error[E601]" in stderr and "no worker left on the cluster for 3 s" in stderr
    assert "Traceback" not in stderr and 3 <= waited < 40
    assert not out.exists()


def test_a_worker_that_returns_within_the_timeout_finishes_the_sweep(scheduler, tmp_path):
    _, address = scheduler
    out = tmp_path / "t.csv"
    run = subprocess.Popen([sys.executable, "-m", "acl", "sweep", str(FIG3), "--samples", "2000", "--seed", "1",
                            "-o", str(out), "--scheduler", address, "--timeout", "60", "-q"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
    time.sleep(3)                          # the sweep waits with no worker ...
    w = _worker(address)                   # ... until one joins
    try:
        stdout, stderr = run.communicate(timeout=90)
    finally:
        _kill(w)
    assert run.returncode == 0, stderr
    assert "has no worker" in stderr and out.exists()


@pytest.mark.parametrize("preload, expected", [((), "65536"), (("--preload-nanny", "acl.sweep.worker"), None)])
def test_the_shipped_worker_setting_removes_the_nannys_malloc_trim_threshold(scheduler, preload, expected):
    _, address = scheduler
    w = _worker(address, *preload)
    try:
        c = _client(address)
        seen = c.run(lambda: os.environ.get("MALLOC_TRIM_THRESHOLD_"))
        c.close()
    finally:
        _kill(w)
    assert list(seen.values()) == [expected]


def test_tune_on_a_cluster_without_workers_times_out_too(scheduler, tmp_path):
    _, address = scheduler
    out = tmp_path / "t.acl"
    r = subprocess.run([sys.executable, "-m", "acl", "tune", str(FIG3), "--samples", "50", "--max-evals", "4",
                        "--scheduler", address, "--timeout", "2", "-o", str(out), "--path", str(FIG3.parent)],
                       capture_output=True, text=True, env=ENV, timeout=120)
    assert r.returncode == 2, r.stderr
    assert "has no worker: waiting up to 2 s" in r.stderr and "no worker left on the cluster for 2 s" in r.stderr
    assert "Traceback" not in r.stderr and not out.exists()

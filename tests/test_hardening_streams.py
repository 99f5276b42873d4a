"""Outputs into device nodes and FIFOs (issue 29, item 1: data loss).

Before, every file writer made a temporary file beside the output and renamed it over the output: a
device node or a FIFO named by ``-o`` (or reached through a symbolic link) was replaced by a regular
file (`mknod null c 1 3; acl synth ... -o null` left a 133-byte file named null; as root, `-o /dev/null`
would have replaced the system's /dev/null).  Now a character device or a FIFO receives the finished
output as a stream and stays what it was; a FIFO nobody reads is an error (never a hang); a block
device or a socket is refused (E601); nothing is created in the device's folder.

Device nodes can only be made as root: those tests skip otherwise.  /dev/null and FIFOs need no root.
"""
from __future__ import annotations

import os
import shutil
import socket
import stat
import threading

import pytest

from acl.cli import main

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
DATA = os.path.join(ROOT, "samples")
EX = os.path.join(ROOT, "examples")

needs_root = pytest.mark.skipif(os.geteuid() != 0, reason="making a device node (mknod) needs root")


@pytest.fixture
def work(tmp_path, monkeypatch):
    shutil.copy(os.path.join(DATA, "fit_cantilever.acl"), tmp_path)
    shutil.copy(os.path.join(EX, "fig3_robust_radii.acl"), tmp_path)
    monkeypatch.chdir(tmp_path)
    assert main(["synth", "fit_cantilever.acl", "-o", "data.csv", "--voltages", "0V..1V:5", "-q"]) == 0
    return tmp_path


def _writers(target):
    """One invocation per file writer, each writing its output to ``target``."""
    return {
        "synth": ["synth", "fit_cantilever.acl", "-o", target, "--voltages", "0V..1V:3", "-q"],
        "sweep": ["sweep", os.path.join(DATA, "sweep_cantilever.acl"), "--vary", "radius=9um..11um:2", "-o", target, "-q"],
        "fit": ["fit", "fit_cantilever.acl", "data.csv", "--free", "gamma", "--calibrated", target, "-q"],
        "tune": ["tune", "fig3_robust_radii.acl", "--samples", "8", "--validate", "8", "-o", target, "-q"],
    }


def _mknull(path):
    os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 3))


def _listing(folder):
    return sorted(os.listdir(folder))


@needs_root
@pytest.mark.parametrize("command", ["synth", "sweep", "fit", "tune"])
@pytest.mark.parametrize("via_link", [False, True], ids=["node", "link"])
def test_a_device_node_stays_a_device(work, capsys, command, via_link):
    name = "null.acl" if command == "tune" else "null.csv"
    _mknull(name)
    target = name
    if via_link:
        target = "link.acl" if command == "tune" else "link.csv"
        os.symlink(name, target)
    before = _listing(work)
    rc = main(_writers(target)[command])
    out = capsys.readouterr()
    assert rc == 0, out.err
    assert stat.S_ISCHR(os.lstat(name).st_mode), f"{command} replaced the device node"
    assert os.path.islink(target) or not via_link
    assert _listing(work) == before                  # no temporary file left beside it
    assert "Traceback" not in out.err


@pytest.mark.parametrize("command", ["synth", "fit"])
def test_dev_null_is_written_as_a_stream(work, capsys, command):
    """The system's /dev/null: written (discarded), never replaced; no temporary file lands in /dev."""
    dev_before = set(os.listdir("/dev"))
    rc = main(_writers("/dev/null")[command])
    assert rc == 0, capsys.readouterr().err
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    assert set(os.listdir("/dev")) - dev_before == set()


@pytest.mark.parametrize("command", ["synth", "sweep", "fit"])
def test_a_fifo_with_a_reader_receives_the_whole_output(work, capsys, command):
    os.mkfifo("pipe.csv")
    got = []

    def read():
        with open("pipe.csv", "rb") as fh:
            got.append(fh.read())

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        rc = main(_writers("pipe.csv")[command])
    finally:
        if reader.is_alive():                      # unblock the reader whatever happened
            fd = os.open("pipe.csv", os.O_WRONLY | os.O_NONBLOCK)
            os.close(fd)
        reader.join(5)
    assert rc == 0, capsys.readouterr().err
    assert stat.S_ISFIFO(os.lstat("pipe.csv").st_mode)
    text = got[0].decode()
    if command == "fit":
        assert text.startswith("#") or "extends" in text
    else:
        assert text.count("\n") >= 3
    assert _listing(work).count("pipe.csv") == 1 and not any(n.startswith(".acl-") for n in _listing(work))


@pytest.mark.parametrize("command", ["synth", "sweep", "fit"])
def test_a_fifo_nobody_reads_is_an_error_not_a_hang(work, capsys, command):
    os.mkfifo("pipe.csv")
    rc = main(_writers("pipe.csv")[command])
    out = capsys.readouterr()
    text = out.out + out.err
    assert rc == 2, text
    assert "error[E601]" in text and "FIFO" in text, text
    assert "Traceback" not in text and "E-INTERNAL" not in text
    assert stat.S_ISFIFO(os.lstat("pipe.csv").st_mode)
    assert not any(n.startswith(".acl-") for n in _listing(work))


@needs_root
@pytest.mark.parametrize("command", ["synth", "sweep", "fit"])
def test_a_block_device_is_refused(work, capsys, command):
    os.mknod("disk.csv", 0o600 | stat.S_IFBLK, os.makedev(7, 200))
    rc = main(_writers("disk.csv")[command])
    out = capsys.readouterr()
    text = out.out + out.err
    assert rc == 2, text
    assert "error[E601]" in text and "block device" in text, text
    assert stat.S_ISBLK(os.lstat("disk.csv").st_mode)


def test_a_socket_is_refused(work, capsys):
    path = os.path.join(str(work), "s.csv")
    srv = socket.socket(socket.AF_UNIX)
    try:
        srv.bind(path)
    except OSError as exc:          # a path too long for AF_UNIX on this machine
        pytest.skip(f"cannot bind a unix socket here: {exc}")
    try:
        rc = main(_writers("s.csv")["synth"])
        out = capsys.readouterr()
        assert rc == 2 and "error[E601]" in out.err and "socket" in out.err, out.err
        assert stat.S_ISSOCK(os.lstat(path).st_mode)
    finally:
        srv.close()

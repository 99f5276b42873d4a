"""Checks off the event loop (acl/lsp/checking.py, issue 27): a request during a long check answers
within the wait, from the last text checked or saying the server is still checking; checks of
texts that a newer edit superseded before they ran are skipped."""
from __future__ import annotations

import threading
import time

import pytest

pytest.importorskip("pygls", reason="acl lsp needs the optional extra acl[lsp] (pygls)")

from acl.lsp import checking  # noqa: E402
from acl.lsp.protocol import RequestFailed  # noqa: E402

TEXT = "param dwell = 300 ms\n"


@pytest.fixture
def slow(monkeypatch):
    """check_text that waits for ``gate`` on texts containing `slow` (the real check otherwise)."""
    gate = threading.Event()
    real = checking.check_text
    ran: list[str] = []

    def check(text, path, version=None, parser=None):
        ran.append(text)
        if "slow" in text:
            gate.wait(10)
        return real(text, path, version, parser=parser)

    monkeypatch.setattr(checking, "check_text", check)
    yield gate, ran
    gate.set()


def test_a_request_during_a_long_check_answers_within_the_wait(slow, tmp_path):
    gate, _ = slow
    c = checking.Checks(lambda u: str(tmp_path / "a.acl"), wait=0.15)
    try:
        first = c.snapshot("u", TEXT, 1)
        assert first.text == TEXT and first.design is not None
        newer = TEXT + "param slow = 1 um\n" + "# a large document\n" * (checking.SMALL_LINES + 1)
        t0 = time.perf_counter()
        got = c.snapshot("u", newer, 2)              # a reading request: the last text checked
        assert time.perf_counter() - t0 < 0.5 and got is first
        with pytest.raises(RequestFailed, match="E-LSP-BUSY"):   # an editing request: says it is still checking
            c.snapshot("u", newer, 2, fresh=True)
        gate.set()
        done = c.start("u", newer, 2).result(10)
        assert done.text == newer and c.snapshot("u", newer, 2, fresh=True) is done
    finally:
        c.stop()


def test_checks_of_superseded_texts_are_skipped(slow, tmp_path):
    gate, ran = slow
    c = checking.Checks(lambda u: str(tmp_path / "a.acl"))
    try:
        running = c.start("u", TEXT + "param slow = 1 um\n", 1)
        time.sleep(0.1)                               # it runs, and waits on the gate
        v2 = c.start("u", TEXT + "param b = 2 um\n", 2)
        v3 = c.start("u", TEXT + "param c = 3 um\n", 3)
        gate.set()
        assert running.result(10) is not None
        assert v2.result(10) is None                  # queued, superseded by v3 before it ran
        assert v3.result(10).text.endswith("param c = 3 um\n")
        assert c.skipped == 1 and not any("param b" in t for t in ran)
        assert c.snapshots["u"].version == 3
    finally:
        c.stop()


def test_the_documented_waits_are_the_code_s():
    from pathlib import Path

    from acl.lsp import formatting

    text = (Path(__file__).resolve().parents[1] / "docs" / "lsp.md").read_text(encoding="utf-8")
    assert f"at most {checking.WAIT_SECONDS * 1e3:.0f} ms on a design of more than {checking.SMALL_LINES:,} lines" in text
    assert f"for up to {formatting.PROCESS_LINES:,} lines" in text
    assert f"at most {formatting.WAIT_SECONDS * 1e3:.0f} ms, then fails" in text
    from acl.lsp import server

    assert f"({server.IDLE_COLLECT_SECONDS:g} s after the last check)" in text


def test_full_garbage_collections_wait_for_a_pause_in_the_edits():
    import asyncio

    from acl.lsp.server import AclLanguageServer

    ls = AclLanguageServer()

    async def edits():
        for _ in range(4):                    # a check ends every 20 ms: no collection meanwhile
            ls.collect_when_idle(0.08)
            await asyncio.sleep(0.02)
        assert ls.collections == 0
        await asyncio.sleep(0.2)              # then a pause: one
        assert ls.collections == 1

    asyncio.run(edits())

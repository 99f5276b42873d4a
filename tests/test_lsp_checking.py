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



# ------------------------------------------------------------------------------------------------
# The design's finiteness walk, made fast for the editor's checks (acl.design.assemble)
# ------------------------------------------------------------------------------------------------

def _float_slots(v, out, seen):
    """(model, field, index or None) of every float in the models reachable from ``v``."""
    from pydantic import BaseModel

    if id(v) in seen:
        return
    seen.add(id(v))
    if isinstance(v, (tuple, list)):
        for x in v:
            _float_slots(x, out, seen)
    elif isinstance(v, BaseModel):
        for k, x in v.__dict__.items():
            if k == "span":
                continue
            if type(x) is float:
                out.append((v, k, None))
            elif type(x) is tuple:
                out.extend((v, k, i) for i, y in enumerate(x) if type(y) is float)
                _float_slots(x, out, seen)
            else:
                _float_slots(x, out, seen)


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_the_fast_finiteness_walk_agrees_with_the_located_one_on_planted_values(bad):
    """`_all_finite` runs a fast walk without locations first, and the located one only when that
    finds a number that is not finite: both must visit the same numbers. Planted in 30 random
    floats of a real design's elements (and in none), both walks give the same answer, and a
    planted value is E305."""
    import random
    from pathlib import Path

    import acl
    from acl.design import finite as FIN
    from acl.diagnostics import DiagnosticBag

    path = Path(__file__).resolve().parents[1] / "examples" / "fig4h_unequal_pair.acl"
    design = acl.loads(path.read_text(encoding="utf-8"), str(path))

    def parts():
        return [x for x in (design.medium, design.transducer, design.materials, design.capsules, design.beams,
                            design.springs, design.latches, design.anchors, design.effects) if x is not None]

    def located() -> bool:
        real, FIN.finite_walk = FIN.finite_walk, lambda stack: False     # the located walk alone
        try:
            bag = DiagnosticBag()
            return FIN.all_finite(design, bag) and not bag.items
        finally:
            FIN.finite_walk = real

    assert FIN.finite_walk(parts()) is True and located() is True and FIN.all_finite(design, DiagnosticBag())
    slots = []
    _float_slots(parts(), slots, set())
    assert len(slots) > 30
    for model, k, i in random.Random(27).sample(slots, 30):
        old = model.__dict__[k]
        model.__dict__[k] = bad if i is None else old[:i] + (bad,) + old[i + 1:]
        try:
            bag = DiagnosticBag()
            assert FIN.finite_walk(parts()) is False and located() is False, (model, k, i)
            assert FIN.all_finite(design, bag) is False and [d.code for d in bag.items] == ["E305"]
        finally:
            model.__dict__[k] = old


def test_a_paused_collector_runs_again_after_the_check(monkeypatch, tmp_path):
    """`acl lsp` (serve) puts collections off during a check until its diagnostics are out: the check
    runs with the collector off, and resume_gc() turns it on; without pause_gc nothing changes."""
    import gc

    seen = []
    real = checking.check_text

    def check(text, path, version=None, parser=None):
        seen.append(gc.isenabled())
        return real(text, path, version, parser=parser)

    monkeypatch.setattr(checking, "check_text", check)
    assert gc.isenabled()
    try:
        c = checking.Checks(lambda u: str(tmp_path / "a.acl"), pause_gc=True)
        assert c.start("u", TEXT, 1).result(10).design is not None
        assert seen == [False] and not gc.isenabled()
        c.resume_gc()
        assert gc.isenabled()
        c2 = checking.Checks(lambda u: str(tmp_path / "a.acl"))
        c2.start("u", TEXT + "param x = 1 um\n", 1).result(10)
        assert seen == [False, True] and gc.isenabled()
        c.stop(), c2.stop()
    finally:
        gc.enable()

"""Long work off the language server's event loop (issue 27): the background worker runs it in a
process a newer edit can stop, and requests answer at once meanwhile."""
from __future__ import annotations

import time

import pytest

pytest.importorskip("pygls", reason="acl lsp needs the optional extra acl[lsp] (pygls)")

from lsp_client import LspClient  # noqa: E402


def test_a_newer_text_stops_the_worker_busy_with_an_older_one():
    from acl.lsp.background import Worker

    w = Worker()
    try:
        assert w.get(("doc", "old", "slow"), time.sleep, 60) is None
        fut = w.future(("doc", "old", "slow"))
        deadline = time.monotonic() + 30
        while not fut.running() and time.monotonic() < deadline:      # the process spawned and took it
            time.sleep(0.05)
        assert fut.running()
        procs = list(w._pool._processes.values())
        t0 = time.perf_counter()
        w.forget("doc", keep="new")
        for p in procs:
            p.join(10)
        assert all(not p.is_alive() for p in procs), "the worker still runs the old text's job"
        assert time.perf_counter() - t0 < 10 and w.cancelled == 1 and w.restarts == 1
        assert w.get(("doc", "new", "quick"), abs, -3) is None          # a fresh worker serves the new text
        deadline = time.monotonic() + 60
        while w.peek(("doc", "new", "quick")) is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert w.peek(("doc", "new", "quick")) == 3
    finally:
        w.stop()


def test_a_stopped_worker_forgets_what_warmed_it():
    """The warm-up results (imports, a document's first parse) belonged to the stopped process: a new one is warmed
    again (the server asks after its next publish); results keyed by a text stay."""
    from acl.lsp.background import Worker

    w = Worker()
    try:
        w.get(("warm",), abs, -1)
        w.get(("warm", "/doc.acl"), abs, -2)
        w.get(("doc", "text", "hover"), abs, -3)
        deadline = time.monotonic() + 60
        while w.peek(("doc", "text", "hover")) is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert [w.peek(k) for k in (("warm",), ("warm", "/doc.acl"), ("doc", "text", "hover"))] == [1, 2, 3]
        w.stop()
        assert w.peek(("warm",)) is None and w.peek(("warm", "/doc.acl")) is None
        assert w.peek(("doc", "text", "hover")) == 3
    finally:
        w.stop()


def test_queued_work_for_an_older_text_is_cancelled_and_other_documents_keep_theirs():
    from acl.lsp.background import Worker

    w = Worker()
    try:
        w.get(("doc", "a", "first"), time.sleep, 60)
        w.get(("doc", "a", "second"), time.sleep, 60)                   # queued behind the first
        w.get(("other", "x", "mine"), abs, -1)
        queued = w.future(("doc", "a", "second"))
        w.forget("other", keep="x")                                     # its own text: nothing to cancel
        assert w.cancelled == 0 and w.future(("doc", "a", "second")) is queued
        w.forget("doc", keep="b")
        assert w.cancelled == 2
        # the pool may already have moved the queued job into its call queue (it then counts as running and
        # cannot be cancelled): the worker is stopped instead, and the job ends without a result
        deadline = time.monotonic() + 30
        while not queued.done() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert queued.cancelled() or queued.exception() is not None
        assert w.future(("doc", "a", "first")) is None and w.future(("doc", "a", "second")) is None
    finally:
        w.stop()


def _design(n: int) -> str:
    head = ("import stdlib.media\nimport stdlib.capsules\nimport stdlib.beams\nimport stdlib.transducers\n"
            "use medium media.pbs\nuse transducer transducers.contact_piezo\n")
    body = "".join(f"beam arm{i} like beams.cantilever50 {{ clamp = ({i} mm, 0, 0) }}\n"
                   f"capsule cap{i} like capsules.design{1 + i % 3} {{ }}\nmount cap{i} on arm{i}.tip\n"
                   for i in range(n))
    return head + body + "program p {\n  drive 125 kHz @ 2 V for 10 ms\n}\n"


def test_a_capsule_hover_on_a_large_design_answers_at_once_and_completes_later(tmp_path):
    from acl.lsp.hover import INLINE_CAPSULES

    text = _design(INLINE_CAPSULES + 6)
    path = tmp_path / "large.acl"
    path.write_text(text, encoding="utf-8")
    c = LspClient({"lint": False, "debounce": 0.02})
    try:
        u = c.open(path, text)
        pub = c.wait_for("textDocument/publishDiagnostics", lambda p: p["uri"] == u)
        assert not [d for d in pub["diagnostics"] if d["severity"] == 1], pub["diagnostics"][:3]
        ln = text.split("\n").index("capsule cap0 like capsules.design1 { }")
        t0 = time.perf_counter()
        first = c.at("textDocument/hover", u, ln, 9)["contents"]["value"]
        took = time.perf_counter() - t0
        assert "predicted modes" in first and "computing in the background" in first
        assert took < 2.0, f"the first hover took {took:.2f} s"
        deadline = time.monotonic() + 120
        while True:
            value = c.at("textDocument/hover", u, ln, 9)["contents"]["value"]
            if "computing" not in value or time.monotonic() > deadline:
                break
            time.sleep(0.3)
        assert "computing" not in value and "phase of `jet` volume vs drive" in value
    finally:
        c.close()


def test_a_job_stopped_by_an_edit_leaves_no_result_behind():
    """Undoing the edit brings the old text back: its work must run again, not answer
    `(unavailable: BrokenProcessPool)` from the job the edit stopped."""
    from acl.lsp.background import Worker

    w = Worker()
    try:
        w.get(("doc", "old", "slow"), time.sleep, 60)
        fut = w.future(("doc", "old", "slow"))
        deadline = time.monotonic() + 30
        while not fut.running() and time.monotonic() < deadline:
            time.sleep(0.05)
        w.forget("doc", keep="new")
        deadline = time.monotonic() + 30
        while not fut.done() and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.2)
        assert w.peek(("doc", "old", "slow")) is None
    finally:
        w.stop()


def test_the_worker_checks_a_text_once_for_every_job_on_it(tmp_path):
    """One design object per text, so the analyses' per-design caches serve the next capsule's hover."""
    from acl.lsp.background import checked

    path = str(tmp_path / "a.acl")
    a = checked(path, "param a = 1 um\n")
    assert checked(path, "param a = 1 um\n") is a and a.design is not None
    b = checked(path, "param a = 2 um\n")
    assert b is not a and checked(path, "param a = 2 um\n") is b
    checked(path, "param a = 3 um\n")
    assert checked(path, "param a = 1 um\n") is not a          # only the last two texts are kept


def _progress(c: LspClient, kind: str, timeout: float = 60.0) -> dict:
    return c.wait_for("$/progress", lambda p: p["value"].get("kind") == kind, timeout=timeout)


def test_the_first_capsule_hover_says_computing_reports_progress_and_the_next_hover_is_full(tmp_path):
    """Issue 27: a hover never waits for the coupled modes. The first one answers with the single
    bubble's modes and says the coupled modes are being computed; the work shows as $/progress
    (begin, end) to a client that supports it; a later hover gives the full answer. Its time is
    compared with a documentSymbol on the same text (a ratio, not an absolute bound)."""
    from acl.lsp.hover import INLINE_CAPSULES

    text = _design(INLINE_CAPSULES + 6)
    path = tmp_path / "large.acl"
    path.write_text(text, encoding="utf-8")
    c = LspClient({"lint": False}, capabilities={"window": {"workDoneProgress": True}})
    try:
        u = c.open(path, text)
        c.wait_for("textDocument/publishDiagnostics", lambda p: p["uri"] == u)
        t0 = time.perf_counter()
        c.request("textDocument/documentSymbol", {"textDocument": {"uri": u}})
        symbols = time.perf_counter() - t0
        ln = text.split("\n").index("capsule cap3 like capsules.design1 { }")
        t0 = time.perf_counter()
        first = c.at("textDocument/hover", u, ln, 9)["contents"]["value"]
        took = time.perf_counter() - t0
        assert "predicted modes" in first and "coupled modes: *computing in the background" in first
        assert took < max(20 * symbols, 2.0), f"first hover {took:.2f} s, documentSymbol {symbols:.2f} s"
        begin = _progress(c, "begin")
        assert begin["value"]["title"] == "acl: coupled modes"
        end = _progress(c, "end", timeout=180)
        assert end["token"] == begin["token"] and end["value"]["message"] == "done"
        full = c.at("textDocument/hover", u, ln, 9)["contents"]["value"]
        assert "computing" not in full and "with its neighbours" in full
    finally:
        c.close()


def test_a_newer_edit_cancels_the_hover_work_and_ends_its_progress(tmp_path):
    from acl.lsp.hover import INLINE_CAPSULES

    text = _design(4 * INLINE_CAPSULES)
    path = tmp_path / "large.acl"
    path.write_text(text, encoding="utf-8")
    c = LspClient({"lint": False}, capabilities={"window": {"workDoneProgress": True}})
    try:
        u = c.open(path, text)
        c.wait_for("textDocument/publishDiagnostics", lambda p: p["uri"] == u)
        ln = text.split("\n").index("capsule cap5 like capsules.design3 { }")
        assert "computing" in c.at("textDocument/hover", u, ln, 9)["contents"]["value"]
        begin = _progress(c, "begin")
        c.change(u, 2, text + "param late = 1 um\n")                    # a newer text: the old work stops
        end = _progress(c, "end", timeout=30)
        assert end["token"] == begin["token"] and end["value"]["message"].startswith("cancelled")
        c.wait_for("textDocument/publishDiagnostics", lambda p: p["uri"] == u and p.get("version") == 2)
        again = c.at("textDocument/hover", u, ln, 9)["contents"]["value"]
        assert "computing" in again                                     # the new text's work starts afresh
        assert _progress(c, "begin")["token"] != begin["token"]
    finally:
        c.close()

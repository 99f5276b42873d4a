"""Edit storms on `acl lsp` (issue 28, "Hostile input": "broken LSP framing and edit storms ... with
hypothesis"): a design receives a burst of incremental `didChange` edits sent back to back, with
requests fired in between without waiting for their replies, as a fast typist, a paste-and-undo
macro or a refactoring tool does.  The edits are drawn by hypothesis from hostile text: the
example's own tokens, newlines and braces, zero-width and look-alike characters, extreme numbers,
units of the wrong dimension, astral characters (two UTF-16 units).  After the storm the server
must hold exactly the text the client holds: its pulled diagnostics and outline equal those of a
second server that opened the final text at once; no reply is an internal error or carries a
traceback, and nothing is printed as a traceback on stderr.  (Broken framing: tests/test_fuzz_hostile.py.)"""
from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

pytest.importorskip("pygls", reason="acl lsp needs the optional extra acl[lsp] (pygls)")

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

import fuzz_generators as G  # noqa: E402
from lsp_client import LspClient  # noqa: E402

BASES = ["fig2_vertical_cantilever.acl", "fig4_facing_pair.acl", "fig6_bistable_latch.acl"]
PIECES = (["\n", "", " ", "{", "}", "(", ")", ",", "=", "..", "+-", "±", "#", "\"", "😀", "µm", "\t",
           "param q = 1 um\n", "capsule z like capsules.design1 { }\n", "}\n}\n"]
          + G.INVISIBLE + list(G.LOOKALIKES.values()) + G.EXTREME_NUMBERS + G.WRONG_UNITS)
REQUESTS = ["textDocument/hover", "textDocument/completion", "textDocument/definition",
            "textDocument/documentHighlight", "textDocument/signatureHelp"]


def _units16(s: str) -> int:
    return len(s.encode("utf-16-le")) // 2


def _position(text: str, offset: int) -> dict:
    """The LSP position (UTF-16 units, the default encoding) of code point ``offset`` of ``text``."""
    line = text.count("\n", 0, offset)
    start = text.rfind("\n", 0, offset) + 1
    return {"line": line, "character": _units16(text[start:offset])}


class Servers:
    def __init__(self, tmp: Path):
        self.a, self.b = tmp / "a", tmp / "b"
        for root in (self.a, self.b):
            root.mkdir()
        self.storm = LspClient({"lint": False, "debounce": 0.02}, root=self.a)
        self.fresh = LspClient({"lint": False, "debounce": 0.02}, root=self.b)
        self.n = 0

    def close(self):
        self.storm.close()
        self.fresh.close()


@pytest.fixture(scope="module")
def servers(tmp_path_factory):
    s = Servers(tmp_path_factory.mktemp("storm"))
    yield s
    s.close()


def _comparable(diags: list[dict], folder: Path) -> list[tuple]:
    return sorted((d["range"]["start"]["line"], d["range"]["start"]["character"], d["range"]["end"]["line"],
                   d["range"]["end"]["character"], d.get("severity"), str(d.get("code")),
                   d["message"].replace(str(folder), "<folder>")) for d in diags)


def _outline(symbols) -> list[tuple]:
    return sorted((s["name"], s["kind"], s["range"]["start"]["line"]) for s in symbols or [])


def _storm(servers: Servers, data) -> None:
    servers.n += 1
    name = f"storm{servers.n}.acl"
    base = (G.ROOT / "examples" / data.draw(st.sampled_from(BASES), label="design")).read_text(encoding="utf-8")
    c = servers.storm
    u = c.open(servers.a / name, base)
    text, version, fired = base, 1, []
    for _ in range(data.draw(st.integers(5, 40), label="edits")):
        a = data.draw(st.integers(0, len(text)), label="start")
        b = data.draw(st.integers(a, min(len(text), a + 40)), label="end")
        new = data.draw(st.sampled_from(PIECES) | st.sampled_from(G._tokens(base)), label="text")
        version += 1
        c.notify("textDocument/didChange", {"textDocument": {"uri": u, "version": version}, "contentChanges": [
            {"range": {"start": _position(text, a), "end": _position(text, b)}, "text": new}]})
        text = text[:a] + new + text[b:]
        if data.draw(st.integers(0, 4), label="ask") == 0:       # a request in the storm, not waited for
            c._id += 1
            method = data.draw(st.sampled_from(REQUESTS), label="request")
            at = data.draw(st.integers(0, len(text)), label="at")
            c._send({"jsonrpc": "2.0", "id": c._id, "method": method,
                     "params": {"textDocument": {"uri": u}, "position": _position(text, at)}})
            fired.append((c._id, method))
    got = c.request("textDocument/diagnostic", {"textDocument": {"uri": u}}, timeout=120)
    outline = c.request("textDocument/documentSymbol", {"textDocument": {"uri": u}}, timeout=120)
    deadline = time.monotonic() + 120
    for rid, method in fired:                      # every request fired in the storm got its one reply
        with c._cond:
            while rid not in c.responses:
                assert time.monotonic() < deadline, f"no reply to {method} sent in the storm"
                c._cond.wait(1.0)
            reply = c.responses.pop(rid)
        err = reply.get("error")
        assert err is None or (err["code"] != -32603 and "Traceback" not in str(err)), (method, err)
    ref = servers.fresh
    ru = ref.open(servers.b / name, text)
    want = ref.request("textDocument/diagnostic", {"textDocument": {"uri": ru}}, timeout=120)
    want_outline = ref.request("textDocument/documentSymbol", {"textDocument": {"uri": ru}}, timeout=120)
    assert _comparable(got["items"], servers.a) == _comparable(want["items"], servers.b), repr(text[-400:])
    assert _outline(outline) == _outline(want_outline)
    for client, doc in ((c, u), (ref, ru)):
        client.notify("textDocument/didClose", {"textDocument": {"uri": doc}})
    for client in (c, ref):
        assert "Traceback" not in "".join(client.stderr_lines), "".join(client.stderr_lines)[-2000:]


FAST = settings(max_examples=4, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                       HealthCheck.data_too_large])
STUDY = settings(FAST, max_examples=int(os.environ.get("ACL_FUZZ_STORM", "40")))


@FAST
@given(data=st.data())
def test_after_an_edit_storm_the_server_holds_the_clients_text(servers, data):
    _storm(servers, data)


@pytest.mark.studies
@STUDY
@given(data=st.data())
def test_many_edit_storms(servers, data):
    _storm(servers, data)

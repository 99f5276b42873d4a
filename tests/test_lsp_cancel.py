"""Issue 27, "Long work reports $/progress and can be cancelled": a command run from the editor
(`acl.compile`) is cancelled by the client in either of the protocol's two ways, and the work
stops: `$/cancelRequest` gets RequestCancelled (-32800) and the progress ends "cancelled";
the progress's own cancel (`window/workDoneProgress/cancel`, the button an editor shows on a
`cancellable` progress) returns "cancelled in the editor". Before, pygls answered the cancel
request but the command ran on to its end and then showed its full summary."""
from __future__ import annotations

import time
from pathlib import Path

import pytest

pytest.importorskip("pygls", reason="acl lsp needs the optional extra acl[lsp] (pygls)")

from lsp_client import LspClient  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / "examples" / "fig3_three_orifice.acl"       # its `circle` compiles in seconds


@pytest.fixture
def client():
    c = LspClient({"lint": False, "debounce": 0.02}, root=DESIGN.parent,
                  capabilities={"window": {"workDoneProgress": True}})
    u = c.open(DESIGN)
    c.wait_for("textDocument/publishDiagnostics", lambda p: p["uri"] == u)
    yield c, u
    c.close()


def _start_compile(c: LspClient, u: str) -> tuple[int, dict]:
    c._id += 1
    rid = c._id
    c._send({"jsonrpc": "2.0", "id": rid, "method": "workspace/executeCommand",
             "params": {"command": "acl.compile", "arguments": [u, "circle"]}})
    begin = c.wait_for("$/progress", lambda p: p["value"].get("kind") == "begin", timeout=30)
    assert begin["value"]["title"] == "acl compile" and begin["value"].get("cancellable") is True
    return rid, begin


def _reply(c: LspClient, rid: int, timeout: float = 60) -> dict:
    deadline = time.monotonic() + timeout
    with c._cond:
        while rid not in c.responses:
            assert time.monotonic() < deadline, "no reply"
            c._cond.wait(deadline - time.monotonic())
        return c.responses.pop(rid)


def _end(c: LspClient, token: str) -> dict:
    return c.wait_for("$/progress", lambda p: p["token"] == token and p["value"].get("kind") == "end", timeout=60)


def test_cancel_request_stops_the_command_and_ends_its_progress(client):
    c, u = client
    rid, begin = _start_compile(c, u)
    c.notify("$/cancelRequest", {"id": rid})
    assert _reply(c, rid)["error"]["code"] == -32800
    end = _end(c, begin["token"])
    assert end["value"]["message"] == "acl compile: cancelled by the client", end
    # no summary of a finished compile is shown afterwards: the job was stopped, not left to run
    time.sleep(1.0)
    shown = [m for m in list(c.notifications.queue) if m.get("method") == "window/showMessage"]
    assert not [m for m in shown if "segment" in m["params"]["message"]], shown
    # the server goes on: the same command, run again to its end, gives the summary (a new token)
    got = c.request("workspace/executeCommand", {"command": "acl.compile", "arguments": [u, "circle"]}, timeout=120)
    assert got.startswith("acl compile circle: ") and "segment(s)" in got, got


def test_the_progress_cancel_button_stops_the_command(client):
    c, u = client
    rid, begin = _start_compile(c, u)
    c.notify("window/workDoneProgress/cancel", {"token": begin["token"]})
    reply = _reply(c, rid)
    assert reply.get("result") == "acl compile: cancelled in the editor", reply
    assert _end(c, begin["token"])["value"]["message"] == "acl compile: cancelled in the editor"

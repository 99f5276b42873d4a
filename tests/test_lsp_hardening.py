"""The language server under hostile and careless clients (issue 29, items 2 and 5).

Each test runs `python -m acl lsp` as a subprocess, writes a whole session of raw JSON-RPC to its
stdin and reads every reply: the server never reads a file the client did not open, every request
gets exactly one reply, no traceback reaches the client or stderr, and nothing hangs."""
from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

pytest.importorskip("pygls", reason="acl lsp needs the optional extra acl[lsp] (pygls)")

ROOT = Path(__file__).resolve().parents[1]
STDERR_LINE = re.compile(r"^acl lsp: <stdin>:\d+:\d+: (error|warning)\[[EW]-LSP-[A-Z]+\]: \S")

SECRET = """\
param secret_width = 123 um
beam hidden_beam { length = 500 um, width = 40 um, thickness = 10 um }
"""


def frame(body) -> bytes:
    if not isinstance(body, (bytes, str)):
        body = json.dumps(body)
    if isinstance(body, str):
        body = body.encode("utf-8")
    return b"Content-Length: %d\r\n\r\n" % len(body) + body


def rpc(method: str, params=None, id_=None) -> bytes:
    msg = {"jsonrpc": "2.0", "method": method}
    if params is not None:
        msg["params"] = params
    if id_ is not None:
        msg["id"] = id_
    return frame(msg)


def initialize(options=None) -> bytes:
    return rpc("initialize", {"processId": None, "rootUri": None, "capabilities": {},
                              "initializationOptions": options if options is not None else {"lint": False}},
               1) + rpc("initialized", {})


END = rpc("shutdown", None, 999) + rpc("exit")


def did_open(u: str, text: str) -> bytes:
    return rpc("textDocument/didOpen", {"textDocument": {"uri": u, "languageId": "acl", "version": 1, "text": text}})


def at(method: str, u: str, line: int, character: int, id_: int, **extra) -> bytes:
    return rpc(method, {"textDocument": {"uri": u}, "position": {"line": line, "character": character}, **extra}, id_)


from lsp_client import serve  # noqa: E402


def reply(msgs, id_) -> dict:
    got = [m for m in msgs if m.get("id") == id_ and "method" not in m]
    assert len(got) == 1, f"{len(got)} replies to request {id_}: {msgs}"
    return got[0]


def no_traceback(err: str, raw: bytes) -> None:
    assert "Traceback" not in err and "E-INTERNAL" not in err, err
    assert b"Traceback" not in raw and b"traceback" not in raw, raw[:2000]
    for line in err.strip().splitlines():
        assert STDERR_LINE.match(line), line


# ------------------------------------------------------------------------------------------------
# Item 2: only documents the client opened are served
# ------------------------------------------------------------------------------------------------

def test_a_file_never_opened_is_never_read(tmp_path):
    secret = tmp_path / "elsewhere" / "secret.acl"
    secret.parent.mkdir()
    secret.write_text(SECRET, encoding="utf-8")
    u = secret.as_uri()
    doc = {"textDocument": {"uri": u}}
    session = (initialize()
               + rpc("textDocument/documentSymbol", doc, 2)
               + at("textDocument/hover", u, 0, 8, 3)
               + at("textDocument/definition", u, 1, 6, 4)
               + at("textDocument/completion", u, 1, 0, 5)
               + rpc("textDocument/formatting", {**doc, "options": {"tabSize": 2, "insertSpaces": True}}, 6)
               + rpc("textDocument/codeAction", {**doc, "range": {"start": {"line": 0, "character": 0},
                                                                   "end": {"line": 1, "character": 0}},
                                                 "context": {"diagnostics": []}}, 7)
               + END)
    rc, msgs, err, raw = serve(session)
    assert rc == 0
    no_traceback(err, raw)
    assert b"secret_width" not in raw and b"hidden_beam" not in raw, "the server read a file it was not given"
    for id_ in range(2, 8):
        e = reply(msgs, id_)["error"]
        assert e["code"] == -32803 and "E-LSP-DOCUMENT" in e["message"] and "not open" in e["message"], e
        assert "data" not in e or not e["data"]
    assert "result" in reply(msgs, 999)


def test_device_and_fifo_uris_are_never_read_and_nothing_blocks(tmp_path):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs on this platform")
    fifo = tmp_path / "pipe.acl"
    os.mkfifo(fifo)
    session = initialize()
    for i, u in enumerate(["file:///dev/zero", "file:///dev/urandom", fifo.as_uri()]):
        session += at("textDocument/hover", u, 0, 0, 10 + i)
        session += rpc("textDocument/documentSymbol", {"textDocument": {"uri": u}}, 20 + i)
    rc, msgs, err, raw = serve(session + END, timeout=30)      # /dev/zero once grew to 10 GB; a FIFO hung
    assert rc == 0
    no_traceback(err, raw)
    for id_ in (10, 11, 12, 20, 21, 22):
        assert reply(msgs, id_)["error"]["code"] == -32803


def test_an_opened_document_is_served_from_the_client_s_text_not_the_disk(tmp_path):
    path = tmp_path / "d.acl"
    path.write_text(SECRET, encoding="utf-8")                   # on disk: the secret
    u = path.as_uri()
    session = initialize() + did_open(u, "param shown = 1 um\n") + rpc(
        "textDocument/documentSymbol", {"textDocument": {"uri": u}}, 2) + END
    rc, msgs, err, raw = serve(session)
    assert [s["name"] for s in reply(msgs, 2)["result"]] == ["shown"]
    assert b"secret_width" not in raw


# ------------------------------------------------------------------------------------------------
# Item 5: no tracebacks, one reply per request, no hangs
# ------------------------------------------------------------------------------------------------

def test_a_request_before_initialize_is_server_not_initialized():
    session = (at("textDocument/hover", "file:///x.acl", 0, 0, 5)
               + rpc("textDocument/didOpen", {"textDocument": {"uri": "file:///x.acl", "languageId": "acl",
                                                               "version": 1, "text": "param a = 1 um\n"}})
               + initialize() + at("textDocument/hover", "file:///x.acl", 0, 0, 6) + END)
    rc, msgs, err, raw = serve(session)
    no_traceback(err, raw)
    assert reply(msgs, 5)["error"]["code"] == -32002
    assert "capabilities" in reply(msgs, 1)["result"]
    assert reply(msgs, 6)["error"]["code"] == -32803       # the didOpen before initialize was dropped


def test_definition_on_a_missing_file_is_an_error_reply_without_traceback():
    rc, msgs, err, raw = serve(initialize() + at("textDocument/definition", "file:///nonexistent/x.acl", 0, 0, 2) + END)
    no_traceback(err, raw)
    e = reply(msgs, 2)["error"]
    assert e["code"] == -32803 and "FileNotFoundError" not in e["message"]


@pytest.mark.parametrize("options", [
    {"debounce": "abc", "lint_delay": [1], "lint": "yes"},
    {"debounce": 1e308, "lint_delay": -1},
    {"no_such_option": 1},
    [1, 2],
    "fast",
])
def test_bad_initialization_options_do_not_fail_initialize(options, tmp_path):
    u = (tmp_path / "a.acl").as_uri()
    session = initialize(options) + did_open(u, "param a = 1 um\n") + at("textDocument/hover", u, 0, 0, 2) + END
    rc, msgs, err, raw = serve(session)
    assert rc == 0
    no_traceback(err, raw)
    assert "capabilities" in reply(msgs, 1)["result"]
    logs = [m["params"]["message"] for m in msgs if m.get("method") == "window/logMessage"]
    assert logs and all("initializationOptions" in x for x in logs), logs
    assert "W-LSP-MESSAGE" in err
    assert "result" in reply(msgs, 2)
    assert any(m.get("method") == "textDocument/publishDiagnostics" for m in msgs)


@pytest.mark.parametrize("id_", [{"a": 1}, [1], 1.5, True])
def test_an_id_that_is_no_integer_or_string_is_invalid_request(id_):
    bad = frame({"jsonrpc": "2.0", "id": id_, "method": "textDocument/hover",
                 "params": {"textDocument": {"uri": "file:///x.acl"}, "position": {"line": 0, "character": 0}}})
    rc, msgs, err, raw = serve(initialize() + bad + END)
    no_traceback(err, raw)
    errors = [m for m in msgs if m.get("id") is None and "error" in m]
    assert len(errors) == 1 and errors[0]["error"]["code"] == -32600
    assert "result" in reply(msgs, 999)


def test_lone_surrogates_in_a_document_still_get_diagnostics_and_the_server_goes_on(tmp_path):
    a, b = (tmp_path / "s.acl").as_uri(), (tmp_path / "t.acl").as_uri()
    body = ('{"jsonrpc":"2.0","method":"textDocument/didOpen","params":{"textDocument":{"uri":"%s",'
            '"languageId":"acl","version":1,"text":"param a = 1 um \\ud800\\n# \\udfff\\nparam b = 2 um\\n"}}}' % a)
    session = (initialize() + frame(body) + at("textDocument/hover", a, 2, 7, 2)
               + at("textDocument/completion", a, 1, 3, 3) + did_open(b, "param c = 1 um + 1 V\n")
               # the diagnostics of b asked for (pull), so `exit` cannot overtake its check (a client
               # that sends exit without waiting for shutdown's answer gets no more notifications)
               + rpc("textDocument/diagnostic", {"textDocument": {"uri": b}}, 4) + END)
    rc, msgs, err, raw = serve(session)
    no_traceback(err, raw)
    pubs = {m["params"]["uri"]: m["params"]["diagnostics"] for m in msgs
            if m.get("method") == "textDocument/publishDiagnostics"}
    assert [d["code"] for d in pubs[a]][:1] == ["E110"]
    rng = pubs[a][0]["range"]
    assert rng["start"] == {"line": 0, "character": 15} and rng["end"] == {"line": 0, "character": 16}
    pulled = reply(msgs, 4)["result"]["items"]                    # later documents are still checked
    assert pulled and pulled[0]["code"].startswith("E")
    assert b not in pubs or (pubs[b] and pubs[b][0]["code"] == pulled[0]["code"])
    assert "result" in reply(msgs, 2) and "result" in reply(msgs, 3)


@pytest.mark.parametrize("line, character", [(2147483647, 2147483647), (2147483647, 0), (0, 2147483647),
                                             (3, 10**6)])
def test_a_position_far_past_the_end_is_answered_at_once(line, character, tmp_path):
    u = (tmp_path / "a.acl").as_uri()
    session = initialize() + did_open(u, "param a = 1 um\n")
    for i, method in enumerate(("textDocument/completion", "textDocument/hover", "textDocument/definition")):
        session += at(method, u, line, character, 10 + i)
    session += at("textDocument/hover", u, 0, 1, 20)
    rc, msgs, err, raw = serve(session + END, timeout=30)         # line 2147483647 once looped for good
    no_traceback(err, raw)
    for id_ in (10, 11, 12):
        assert "result" in reply(msgs, id_)
    assert "param" in reply(msgs, 20)["result"]["contents"]["value"]


def test_an_overlong_content_length_does_not_break_framing_for_good():
    hover = json.dumps({"jsonrpc": "2.0", "id": 2, "method": "textDocument/hover",
                        "params": {"textDocument": {"uri": "file:///x.acl"}, "position": {"line": 0, "character": 0}}})
    bad = b"Content-Length: %d\r\n\r\n" % (len(hover) + 200) + hover.encode()
    later = b"".join(rpc("textDocument/documentSymbol", {"textDocument": {"uri": "file:///y.acl"}}, 10 + i)
                     for i in range(20))
    rc, msgs, err, raw = serve(initialize() + bad + later + END)
    no_traceback(err, raw)
    assert reply(msgs, 2)["error"]["code"] == -32600                # the overlong message itself: refused
    answered = [i for i in range(10, 30) if any(m.get("id") == i for m in msgs)]
    assert len(answered) == 20, f"{len(answered)} of 20 later requests answered"
    assert "E-LSP-FRAME" in err and "Content-Length" in err


def test_a_short_content_length_loses_only_its_own_message():
    hover = json.dumps({"jsonrpc": "2.0", "id": 2, "method": "textDocument/hover",
                        "params": {"textDocument": {"uri": "file:///x.acl"}, "position": {"line": 0, "character": 0}}})
    bad = b"Content-Length: %d\r\n\r\n" % (len(hover) - 30) + hover.encode()
    later = b"".join(rpc("textDocument/documentSymbol", {"textDocument": {"uri": "file:///y.acl"}}, 10 + i)
                     for i in range(5))
    rc, msgs, err, raw = serve(initialize() + bad + later + END)
    no_traceback(err, raw)
    assert all(any(m.get("id") == i for m in msgs) for i in range(10, 15))


@pytest.mark.parametrize("params", [{"foo": 1}, {"textDocument": {"uri": 5}, "position": {"line": "x"}},
                                    {"textDocument": {"uri": "file:///x.acl"}, "position": {"line": -1, "character": 0}},
                                    5, "s"])
def test_invalid_params_get_an_invalid_params_reply(params):
    rc, msgs, err, raw = serve(initialize() + rpc("textDocument/hover", params, 2) + END)
    no_traceback(err, raw)
    assert reply(msgs, 2)["error"]["code"] == -32602
    assert "result" in reply(msgs, 999)


def test_a_request_after_shutdown_gets_invalid_request():
    session = initialize() + rpc("shutdown", None, 2) + at("textDocument/hover", "file:///x.acl", 0, 0, 3) + rpc("exit")
    rc, msgs, err, raw = serve(session)
    assert rc == 0
    no_traceback(err, raw)
    assert reply(msgs, 2)["result"] is None
    assert reply(msgs, 3)["error"]["code"] == -32600


@pytest.mark.parametrize("where", ["line", "id", "version"])
def test_an_integer_over_python_s_digit_limit_does_not_kill_the_server(where, tmp_path):
    huge = "9" * 5000
    u = (tmp_path / "a.acl").as_uri()
    if where == "line":
        body = ('{"jsonrpc":"2.0","id":2,"method":"textDocument/hover","params":{"textDocument":{"uri":"%s"},'
                '"position":{"line":%s,"character":0}}}' % (u, huge))
    elif where == "id":
        body = ('{"jsonrpc":"2.0","id":%s,"method":"textDocument/hover","params":{"textDocument":{"uri":"%s"},'
                '"position":{"line":0,"character":0}}}' % (huge, u))
    else:
        body = ('{"jsonrpc":"2.0","method":"textDocument/didOpen","params":{"textDocument":{"uri":"%s",'
                '"languageId":"acl","version":%s,"text":"x"}}}' % (u, huge))
    session = initialize() + did_open(u, "param a = 1 um\n") + frame(body) + at("textDocument/hover", u, 0, 1, 3) + END
    rc, msgs, err, raw = serve(session)
    assert rc == 0
    no_traceback(err, raw)
    assert "digits" in err
    if where == "line":
        assert reply(msgs, 2)["error"]["code"] == -32600
    assert "result" in reply(msgs, 3) and "result" in reply(msgs, 999)


def test_did_change_on_a_document_not_open_is_one_warning_line(tmp_path):
    u = (tmp_path / "never.acl").as_uri()
    session = initialize() + rpc("textDocument/didChange", {"textDocument": {"uri": u, "version": 2},
                                                            "contentChanges": [{"text": "x"}]}) + END
    rc, msgs, err, raw = serve(session)
    no_traceback(err, raw)
    assert "W-LSP-MESSAGE" in err and "not open" in err


def test_the_documented_limits_are_the_code_s():
    from acl.design import modules
    from acl.lsp import stream

    text = (ROOT / "docs" / "lsp.md").read_text(encoding="utf-8")
    assert f"more than {stream.MAX_INT_DIGITS:,} digits" in text
    assert f"at most {modules.MAX_BYTES // 1_000_000} MB each and {modules.MAX_FILES} per design" in text

"""Hostile input on the language server's stream (issue 11): absurd Content-Length, bodies that
are not JSON, broken headers. Each is one coded, located line on stderr, a JSON-RPC error to the
client, and the server keeps serving (or, when the input ends inside a message, exits cleanly)."""
from __future__ import annotations

import io
import json
import re
from pathlib import Path

import pytest

pytest.importorskip("pygls")

from acl.lsp.stream import FramedInput  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
LINE = re.compile(r"^acl lsp: <stdin>:\d+:\d+: (error|warning)\[[EW]-LSP-[A-Z]+\]: \S")


def frame(body: bytes | str) -> bytes:
    if isinstance(body, str):
        body = body.encode("utf-8")
    return b"Content-Length: %d\r\n\r\n" % len(body) + body


def rpc(method: str, params, id_=None) -> bytes:
    msg = {"jsonrpc": "2.0", "method": method, "params": params}
    if id_ is not None:
        msg["id"] = id_
    return frame(json.dumps(msg))


INITIALIZE = rpc("initialize", {"processId": None, "rootUri": None, "capabilities": {}}, id_=1)
SHUTDOWN_EXIT = rpc("shutdown", None, id_=2) + rpc("exit", None)


def serve(stdin: bytes, timeout: float = 60) -> tuple[int, list[dict], str]:
    from lsp_client import serve as serve_raw

    return serve_raw(stdin, timeout)[:3]


def replies(msgs, id_):
    return [m for m in msgs if m.get("id") == id_ and ("result" in m or "error" in m)]


def test_absurd_content_length_is_refused_without_allocating_and_the_stream_ends_cleanly():
    rc, msgs, err = serve(b"Content-Length: 99999999999\r\n\r\n{}")
    assert rc == 0
    assert "Traceback" not in err and "MemoryError" not in err and "E-INTERNAL" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and LINE.match(lines[0]), err
    assert "E-LSP-SIZE" in lines[0] and "<stdin>:1:1" in lines[0] and "99999999999" in lines[0]
    assert msgs and msgs[0]["id"] is None and msgs[0]["error"]["code"] == -32600


def test_an_oversized_message_is_skipped_and_the_next_one_is_served():
    big = b"Content-Length: %d\r\n\r\n" % (70 * 2**20) + b"x" * (70 * 2**20)
    rc, msgs, err = serve(big + INITIALIZE + SHUTDOWN_EXIT)
    assert rc == 0 and "Traceback" not in err
    assert "E-LSP-SIZE" in err and "<stdin>:1:1" in err
    assert replies(msgs, 1) and "capabilities" in replies(msgs, 1)[0]["result"]
    assert replies(msgs, 2), "the server stopped serving after the refused message"


@pytest.mark.parametrize("body, where, code, rpc_code", [
    (b"{abc}", "<stdin>:3:2", "E-LSP-JSON", -32700),
    (b'{\n  "jsonrpc": "2.0",\n  "id": 5,,\n}', "<stdin>:5:11", "E-LSP-JSON", -32700),
    (b"\xff\xfe{}", "<stdin>:3:1", "E-LSP-JSON", -32700),
    (b"[" * 100_000 + b"]" * 100_000, "<stdin>:3:1", "E-LSP-JSON", -32700),
    (b"5", "<stdin>:3:1", "E-LSP-JSON", -32600),
    (b"[]", "<stdin>:3:1", "E-LSP-JSON", -32600),
])
def test_a_body_that_is_not_a_json_object_is_one_located_line_and_serving_goes_on(body, where, code, rpc_code):
    rc, msgs, err = serve(frame(body) + INITIALIZE + SHUTDOWN_EXIT)
    assert rc == 0 and "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and LINE.match(lines[0]) and code in lines[0], err
    assert f"{where}:" in lines[0], lines[0]
    assert msgs[0]["id"] is None and msgs[0]["error"]["code"] == rpc_code
    assert replies(msgs, 1) and replies(msgs, 2)


@pytest.mark.parametrize("msg", [
    {"jsonrpc": "2.0", "method": "foo"},                                   # a notification without params
    {"jsonrpc": "2.0", "id": 9, "method": "textDocument/hover", "params": 5},
    {"jsonrpc": "2.0", "id": 9, "method": "textDocument/hover",
     "params": {"textDocument": {"uri": "file:///none.acl"}, "position": {"line": 0, "character": 0}}},
])
def test_pygls_errors_are_one_coded_line_not_a_traceback(msg):
    rc, msgs, err = serve(frame(json.dumps(msg)) + INITIALIZE + SHUTDOWN_EXIT)
    assert rc == 0 and "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert all(LINE.match(x) for x in lines), err
    if "id" in msg:       # a request gets one error reply (before initialize: ServerNotInitialized)
        got = replies(msgs, msg["id"])
        assert len(got) == 1 and "error" in got[0] and "traceback" not in json.dumps(got[0]), got
    else:
        assert lines, "nothing said about the message"
    assert replies(msgs, 1) and replies(msgs, 2)


@pytest.mark.parametrize("stream, code, where", [
    (b"Content-Length: x\r\n\r\n", "E-LSP-FRAME", "<stdin>:1:1"),
    (b"garbage\r\nContent-Length: 2\r\n\r\n{}", "E-LSP-FRAME", "<stdin>:1:1"),
    (b"Content-Type: text/plain\r\n\r\n", "E-LSP-FRAME", "<stdin>:1:1"),
    (b"X-Long: " + b"a" * 100_000 + b"\r\nContent-Length: 2\r\n\r\n{}", "E-LSP-FRAME", "<stdin>:1:1"),
    (b"\r\n\r\nContent-Length: 2\r\n\r\n[]", "E-LSP-JSON", "<stdin>:5:1"),
])
def test_broken_headers_are_located_and_the_next_message_is_read(stream, code, where):
    diags, replies_ = [], []
    raw = FramedInput(io.BytesIO(stream + INITIALIZE), log=diags.append, reply=replies_.append)
    headers = [raw.readline(), raw.readline()]
    assert headers == [b"Content-Length: %d\r\n" % (len(INITIALIZE) - INITIALIZE.index(b"{")), b"\r\n"]
    assert json.loads(raw.read(0))["method"] == "initialize"
    assert raw.readline() == b""
    assert [d.code for d in diags] == [code] and str(diags[0].span) == where
    assert replies_[0]["error"]["code"] in (-32600, -32700)


def test_input_ending_inside_a_message_ends_the_server_cleanly():
    rc, msgs, err = serve(INITIALIZE + b"Content-Length: 50\r\n\r\n{\"jsonrpc\"")
    assert rc == 0 and "Traceback" not in err
    assert replies(msgs, 1)
    assert "E-LSP-FRAME" in err and "ended after 10 of the 50 bytes of message 2" in err


def test_skipping_a_huge_body_reads_it_in_chunks():
    class Endless(io.RawIOBase):
        """A stream of 2 GiB of zero bytes, never held at once."""

        def __init__(self):
            self.left, self.biggest = 2**31, 0

        def readable(self):
            return True

        def readinto(self, b):
            n = min(len(b), self.left)
            self.biggest = max(self.biggest, n)
            b[:n] = bytes(n)
            self.left -= n
            return n

    src = Endless()
    stream = io.BufferedReader(src)

    class Source:
        def __init__(self):
            self.head = io.BytesIO(b"Content-Length: %d\r\n\r\n" % 2**31)

        def readline(self, n=-1):
            return self.head.readline(n)

        def read(self, n=-1):
            assert 0 <= n <= 2**20, f"read({n}) holds too much at once"
            return stream.read(n)

    diags = []
    raw = FramedInput(Source(), log=diags.append, max_bytes=2**20)
    assert raw.readline() == b""
    assert [d.code for d in diags] == ["E-LSP-SIZE"] and src.left == 0


def test_the_documented_limits_are_the_code_s():
    from acl.lsp import stream

    text = (ROOT / "docs" / "lsp.md").read_text()
    assert f"over {stream.MAX_MESSAGE_BYTES // 2**20} MiB ({stream.MAX_MESSAGE_BYTES:,} bytes)" in text
    assert f"over {stream.MAX_HEADER_LINE:,} bytes" in text and f"more than {stream.MAX_HEADER_LINES} lines" in text
    assert f"in {stream._CHUNK // 2**20} MiB chunks" in text


def test_a_content_length_longer_than_the_rest_of_the_input_still_serves_what_it_swallowed():
    """A length longer than everything after it ran the input out inside its body, and the server stopped there
    (found by tests/test_fuzz_hostile.py): the messages it swallowed are read again from their headers."""
    body = b'{"jsonrpc": "2.0", "id": 99, "method": "shutdown"}'
    rest = INITIALIZE + SHUTDOWN_EXIT
    lying = b"Content-Length: %d\r\n\r\n" % (len(body) + len(rest) + 1) + body
    rc, msgs, err = serve(lying + rest)
    assert rc == 0 and "Traceback" not in err
    assert "E-LSP-FRAME" in err
    assert replies(msgs, 1) and "capabilities" in replies(msgs, 1)[0]["result"]
    assert replies(msgs, 2), "the swallowed session was not served"

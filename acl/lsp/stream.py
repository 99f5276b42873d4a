"""The LSP input stream, checked before pygls sees it: one message at a time, bounded in size.

pygls reads ``Content-Length`` bytes as announced (``Content-Length: 99999999999`` allocated them
and died with MemoryError) and logs a traceback for a body that is not JSON.  :class:`FramedInput`
sits between stdin and pygls: it reads each message's header block and body itself, refuses a
header line over :data:`MAX_HEADER_LINE` bytes or a body over :data:`MAX_MESSAGE_BYTES` (the body is
skipped in chunks, never held), and checks that the body is UTF-8 JSON holding one object.  A
message that fails is reported as one line on stderr, with a code and its ``<stdin>:line:column``
(lines of the input stream), answered with a JSON-RPC error (id null, as JSON-RPC 2.0 asks), and
skipped: the server keeps serving.  Input that ends inside a message ends the server cleanly.

Only messages that pass reach pygls, re-framed with a canonical ``Content-Length`` header.
"""
from __future__ import annotations

import json
import sys
import threading
from collections import deque
from typing import BinaryIO, Callable

from acl.diagnostics import Diagnostic, Span, error

MAX_MESSAGE_BYTES = 64 * 2**20   # a document of acl's 2 MB source limit, JSON-escaped, with room to spare
MAX_HEADER_LINE = 8192           # bytes of one header line
MAX_HEADER_LINES = 32            # header lines of one message (LSP defines two)
_CHUNK = 1 << 20                 # bytes read at a time when skipping a refused body

PARSE_ERROR = -32700             # JSON-RPC 2.0 error codes
INVALID_REQUEST = -32600

STDIN = "<stdin>"


def log_line(d: Diagnostic) -> None:
    """One line on stderr: ``acl lsp: <stdin>:3:1: error[E-LSP-SIZE]: ...``."""
    try:
        print(f"acl lsp: {d.location()}: {d.severity.value}[{d.code}]: {d.message}", file=sys.stderr, flush=True)
    except (OSError, ValueError):   # stderr closed: the editor went away; nothing to tell
        pass


class LockedOutput:
    """stdout shared by pygls (the event loop) and :class:`FramedInput` (a reader thread)."""

    def __init__(self, raw: BinaryIO) -> None:
        self._raw = raw
        self._lock = threading.Lock()

    def write(self, data: bytes) -> None:
        with self._lock:
            self._raw.write(data)
            self._raw.flush()

    def flush(self) -> None:
        pass

    def close(self) -> None:
        with self._lock:
            self._raw.close()

    def send(self, payload: dict) -> None:
        body = json.dumps(payload).encode("utf-8")
        try:
            self.write(b"Content-Length: %d\r\n\r\n" % len(body) + body)
        except (OSError, ValueError):   # the client closed its end: the next read ends the server
            pass


class FramedInput:
    """A reader with the interface pygls uses on stdin (``readline``, ``read``) that passes on only
    well-formed messages within the limits; see the module docstring."""

    def __init__(self, raw: BinaryIO, log: Callable[[Diagnostic], None] = log_line,
                 reply: Callable[[dict], None] | None = None, max_bytes: int = MAX_MESSAGE_BYTES) -> None:
        self._raw = raw
        self._log = log
        self._reply = reply
        self._max = max_bytes
        self._line = 1            # line of the input stream the next byte is on
        self._queue: deque[bytes] = deque()
        self._body = b""
        self.messages = 0         # messages seen (refused ones included)
        self.refused = 0
        self.body_line = 1        # where the body of the latest message passed on starts

    def location(self) -> str:
        """``<stdin>:line:1`` of the body of the latest message passed on to pygls."""
        return f"{STDIN}:{self.body_line}:1"

    # ------------------------------------------------------------------ the interface pygls uses
    def readline(self, *_args) -> bytes:
        if not self._queue and not self._next():
            return b""
        return self._queue.popleft()

    def read(self, n: int = -1) -> bytes:
        body, self._body = self._body, b""
        return body

    # ------------------------------------------------------------------ framing
    def _refuse(self, code: str, message: str, line: int, column: int = 1, rpc: int = INVALID_REQUEST) -> None:
        self.refused += 1
        self._log(error(code, message, Span(file=STDIN, line=line, column=column)))
        if self._reply is not None and rpc:
            self._reply({"jsonrpc": "2.0", "id": None, "error": {"code": rpc, "message": f"{code}: {message}"}})

    def _readline(self) -> bytes:
        line = self._raw.readline(MAX_HEADER_LINE + 1)
        self._line += line.count(b"\n")
        return line

    def _skip(self, n: int | None) -> int:
        """Discard ``n`` bytes (None: the rest of the current line); returns how many were read."""
        got = 0
        while n is None or got < n:
            if n is None:
                chunk = self._raw.readline(_CHUNK)
            else:
                chunk = self._raw.read(min(_CHUNK, n - got))
            if not chunk:
                break
            got += len(chunk)
            self._line += chunk.count(b"\n")
            if n is None and chunk.endswith(b"\n"):
                break
        return got

    def _read_body(self, n: int) -> bytes:
        parts, got = [], 0
        while got < n:
            chunk = self._raw.read(n - got)
            if not chunk:
                break
            parts.append(chunk)
            got += len(chunk)
        body = b"".join(parts)
        self._line += body.count(b"\n")
        return body

    def _next(self) -> bool:
        """Read messages until one passes (queued for pygls: True) or the input ends (False)."""
        while True:
            start = self._line
            length: int | None = None
            bad: tuple[str, int] | None = None      # (what, line) of the first bad header line
            count = 0
            while True:
                here = self._line
                line = self._readline()
                if not line:
                    if count:
                        self._refuse("E-LSP-FRAME", f"the input ended inside the header of message {self.messages + 1}",
                                     here, rpc=0)
                    return False
                if not line.endswith(b"\n") and len(line) > MAX_HEADER_LINE:
                    self._skip(None)
                    bad = bad or (f"a header line is longer than {MAX_HEADER_LINE} bytes", here)
                    count += 1
                    continue
                if not line.strip():
                    if count:
                        break
                    start = self._line           # blank lines between messages are tolerated
                    continue
                count += 1
                if count > MAX_HEADER_LINES:
                    bad = bad or (f"it has more than {MAX_HEADER_LINES} header lines", here)
                    continue
                name, sep, value = line.partition(b":")
                if not sep:
                    bad = bad or (f"a header line is not `Name: value`: {_show(line)}", here)
                elif name.strip().lower() == b"content-length":
                    text = value.strip()
                    if text.isdigit() and text.isascii():
                        length = int(text)
                    else:
                        bad = bad or (f"Content-Length is not a whole number of bytes: {_show(text)}", here)
            self.messages += 1
            k = self.messages
            if bad is not None:
                self._refuse("E-LSP-FRAME", f"message {k}: {bad[0]}; the message is skipped", bad[1])
                if length is not None and length <= self._max:
                    self._skip(length)
                continue
            if length is None:
                self._refuse("E-LSP-FRAME", f"message {k} has no Content-Length header; its header is skipped", start)
                continue
            body_line = self._line
            if length > self._max:
                got = self._skip(length)
                self._refuse("E-LSP-SIZE", f"message {k} announces Content-Length {length} bytes, over the "
                             f"{self._max}-byte limit of one message; its {got} bytes were skipped unread", start)
                if got < length:
                    return False
                continue
            body = self._read_body(length)
            if len(body) < length:
                self._refuse("E-LSP-FRAME", f"the input ended after {len(body)} of the {length} bytes of message {k}",
                             body_line, rpc=0)
                return False
            problem = _check_body(body)
            if problem is not None:
                what, (dl, dc), rpc = problem
                self._refuse("E-LSP-JSON", f"message {k} {what}; the message is skipped",
                             body_line + dl - 1, dc, rpc=rpc)
                continue
            self._queue.extend((b"Content-Length: %d\r\n" % length, b"\r\n"))
            self._body = body
            self.body_line = body_line
            return True


def _show(raw: bytes, limit: int = 60) -> str:
    text = raw.strip().decode("utf-8", "replace")
    return repr(text if len(text) <= limit else text[:limit] + "…")


def _position(body: bytes, offset: int) -> tuple[int, int]:
    """(line, column), 1-based, of byte ``offset`` of ``body`` (columns in characters)."""
    head = body[:offset]
    line = head.count(b"\n") + 1
    last = head.rsplit(b"\n", 1)[-1]
    return line, len(last.decode("utf-8", "replace")) + 1


def _check_body(body: bytes) -> tuple[str, tuple[int, int], int] | None:
    """Why ``body`` is no JSON-RPC message (text, (line, column) in the body, JSON-RPC code), or None."""
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as exc:
        return "is not UTF-8", _position(body, exc.start), PARSE_ERROR
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        return f"is not JSON ({exc.msg})", (exc.lineno, exc.colno), PARSE_ERROR
    except RecursionError:
        return "is JSON nested too deeply to read", (1, 1), PARSE_ERROR
    if not isinstance(value, dict):
        kind = {list: "an array", str: "a string", bool: "a boolean", type(None): "null"}.get(type(value), "a number")
        return f"is {kind}, not a JSON-RPC message (an object)", (1, 1), INVALID_REQUEST
    return None

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
import re
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
INVALID_PARAMS = -32602

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
        self._back = b""          # bytes read too far (a Content-Length that overran its message), read again first
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
    def _refuse(self, code: str, message: str, line: int, column: int = 1, rpc: int = INVALID_REQUEST,
                id_=None) -> None:
        self.refused += 1
        self._log(error(code, message, Span(file=STDIN, line=line, column=column)))
        if self._reply is not None and rpc:
            self._reply({"jsonrpc": "2.0", "id": id_, "error": {"code": rpc, "message": f"{code}: {message}"}})

    def _raw_readline(self, limit: int) -> bytes:
        if self._back:
            cut = self._back.find(b"\n", 0, limit)
            n = limit if cut < 0 else cut + 1
            if cut < 0 and len(self._back) < limit:      # the rest of the line is still on the stream
                head, self._back = self._back, b""
                return head + self._raw.readline(limit - len(head))
            head, self._back = self._back[:n], self._back[n:]
            return head
        return self._raw.readline(limit)

    def _raw_read(self, n: int) -> bytes:
        if self._back:
            head, self._back = self._back[:n], self._back[n:]
            return head
        return self._raw.read(n)

    def _readline(self) -> bytes:
        line = self._raw_readline(MAX_HEADER_LINE + 1)
        self._line += line.count(b"\n")
        return line

    def _skip(self, n: int | None) -> int:
        """Discard ``n`` bytes (None: the rest of the current line); returns how many were read."""
        got = 0
        while n is None or got < n:
            if n is None:
                chunk = self._raw_readline(_CHUNK)
            else:
                chunk = self._raw_read(min(_CHUNK, n - got))
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
            chunk = self._raw_read(n - got)
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
                if not count:
                    at = _HEADER_START.search(line)
                    if at is not None and at.start() > 0:
                        # the rest of a message whose Content-Length fell short: resynchronise on the header
                        self._refuse("E-LSP-FRAME", f"{at.start()} bytes before the header of message "
                                     f"{self.messages + 1} are not part of any message; they are skipped", here)
                        line = line[at.start():]
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
            short = len(body) < length
            if short and _overrun(body) is None:
                self._refuse("E-LSP-FRAME", f"the input ended after {len(body)} of the {length} bytes of message {k}",
                             body_line, rpc=0)
                return False
            problem = _check_body(body)
            # a Content-Length too long swallowed the messages after it (up to the end of the input, when it was
            # longer than all that followed): they are read again from the header found inside the body
            cut = _overrun(body) if short or (problem is not None and problem[2] == PARSE_ERROR) else None
            if cut is not None:
                # the announced length ran into the next message: read that one again from its header
                self._back = body[cut:] + self._back
                self._line -= body.count(b"\n", cut)
                self.refused += 1
                self._log(error("E-LSP-FRAME", f"message {k} announces Content-Length {length} bytes but ends after "
                                f"{cut}: the next message begins inside it; the message is skipped and the next "
                                f"one read from its header", Span(file=STDIN, line=start, column=1)))
                if self._reply is not None:
                    self._reply({"jsonrpc": "2.0", "id": _request_id(body[:cut]), "error": {
                        "code": INVALID_REQUEST, "message": f"E-LSP-FRAME: Content-Length {length} is longer than "
                                                            f"the message ({cut} bytes)"}})
                continue
            if problem is not None:
                what, (dl, dc), rpc = problem
                self._refuse("E-LSP-JSON", f"message {k} {what}; the message is skipped",
                             body_line + dl - 1, dc, rpc=rpc, id_=_request_id(body) if rpc != PARSE_ERROR else None)
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


_HEADER_START = re.compile(rb"content-length[ \t]*:", re.IGNORECASE)
MAX_INT_DIGITS = 4000            # digits of one JSON integer (Python refuses to convert over 4,300)


class _HugeInt:
    """Stands for a JSON integer over :data:`MAX_INT_DIGITS` digits (never converted)."""


def _parse_int(text: str):
    return _HugeInt() if len(text) > MAX_INT_DIGITS else int(text)


def _loads(text: str):
    return json.loads(text, parse_int=_parse_int)


def _huge(value, depth: int = 0) -> bool:
    if isinstance(value, _HugeInt):
        return True
    if depth > 200:
        return False
    if isinstance(value, dict):
        return any(_huge(v, depth + 1) for v in value.values())
    if isinstance(value, list):
        return any(_huge(v, depth + 1) for v in value)
    return False


def _valid_id(value) -> bool:
    return isinstance(value, str) or (isinstance(value, int) and not isinstance(value, bool))


def _request_id(body: bytes):
    """The id of the request at the start of ``body`` when it can be read (else None)."""
    try:
        value, _ = json.JSONDecoder(parse_int=_parse_int).raw_decode(body.decode("utf-8", "replace").lstrip())
    except (ValueError, RecursionError):
        return None
    got = value.get("id") if isinstance(value, dict) else None
    return got if _valid_id(got) else None


def _overrun(body: bytes) -> int | None:
    """Where the next message's header starts inside ``body`` (a Content-Length that was too long), or None."""
    start = 0
    try:
        text = body.decode("utf-8", "replace")
        stripped = text.lstrip()
        _, end = json.JSONDecoder(parse_int=_parse_int).raw_decode(stripped)
        start = len(text[:len(text) - len(stripped) + end].encode("utf-8", "surrogatepass"))
    except (ValueError, RecursionError):
        pass
    at = _HEADER_START.search(body, start)
    return at.start() if at is not None and at.start() > 0 else None


def _check_body(body: bytes) -> tuple[str, tuple[int, int], int] | None:
    """Why ``body`` is no JSON-RPC message (text, (line, column) in the body, JSON-RPC code), or None."""
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as exc:
        return "is not UTF-8", _position(body, exc.start), PARSE_ERROR
    try:
        value = _loads(text)
    except json.JSONDecodeError as exc:
        return f"is not JSON ({exc.msg})", (exc.lineno, exc.colno), PARSE_ERROR
    except RecursionError:
        return "is JSON nested too deeply to read", (1, 1), PARSE_ERROR
    except ValueError as exc:       # a number Python will not convert
        return f"holds a number that cannot be read ({exc})", (1, 1), INVALID_REQUEST
    if not isinstance(value, dict):
        kind = {list: "an array", str: "a string", bool: "a boolean", type(None): "null"}.get(type(value), "a number")
        return f"is {kind}, not a JSON-RPC message (an object)", (1, 1), INVALID_REQUEST
    if _huge(value):
        return f"holds an integer of more than {MAX_INT_DIGITS:,} digits", (1, 1), INVALID_REQUEST
    if "method" in value:
        if not isinstance(value["method"], str):
            return "has a `method` that is not a string", (1, 1), INVALID_REQUEST
        if "id" in value and not _valid_id(value["id"]):
            return "has an `id` that is neither an integer nor a string", (1, 1), INVALID_REQUEST
        if "params" in value and not isinstance(value["params"], (dict, list, type(None))):
            return "has `params` that are neither an object nor an array", (1, 1), INVALID_PARAMS
    return None

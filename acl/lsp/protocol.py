"""JSON-RPC rules pygls leaves to the server: every request gets exactly one reply, and no reply
carries a Python traceback.

- A request before ``initialize`` is answered ``ServerNotInitialized`` (-32002); a notification
  before it is dropped (``exit`` excepted), as the protocol asks.
- A request after ``shutdown`` is answered ``InvalidRequest`` (-32600).
- A request whose params do not have the method's shape is answered ``InvalidParams`` (-32602)
  with the fields that are wrong (pygls logged a traceback and answered nothing).
- A handler that fails is answered with the exception's type and text; ``error.data`` never
  holds a traceback (`acl -v lsp` shows it on stderr).
"""
from __future__ import annotations

import logging
from functools import partial
from urllib.parse import unquote

from lsprotocol import types as T
from pygls.exceptions import JsonRpcException
from pygls.protocol import LanguageServerProtocol

log = logging.getLogger("pygls")

SERVER_NOT_INITIALIZED = -32002
INVALID_REQUEST = -32600
INVALID_PARAMS = -32602
REQUEST_FAILED = -32803


class RequestFailed(JsonRpcException):
    """A request that cannot be served (``RequestFailed``, -32803), e.g. on a document not open."""

    CODE = REQUEST_FAILED


class _Answered:
    """A message that was answered (or dropped) while it was read: nothing more to do."""


ANSWERED = _Answered()


def _shape_errors(exc: BaseException) -> str:
    """The fields of a message that do not fit its type, one phrase each (at most 3)."""
    cause = exc.__cause__ or exc
    try:
        from cattrs import transform_error

        found = transform_error(cause, path="$")
    except Exception:       # not a cattrs validation error
        found = [f"{type(cause).__name__}: {cause}"]
    text = "; ".join(found[:3]) + ("; …" if len(found) > 3 else "")
    return text if len(text) <= 400 else text[:400] + "…"


class AclProtocol(LanguageServerProtocol):
    def __init__(self, server, converter) -> None:
        super().__init__(server, converter)
        self.initialized = False

    # ------------------------------------------------------------------------------ reading
    def structure_message(self, data):
        try:
            return super().structure_message(data)
        except JsonRpcException as exc:
            if not isinstance(data, dict) or not isinstance(data.get("method"), str):
                raise
            why = _shape_errors(exc)
            if "id" in data:
                self._send_response(data["id"], error=T.ResponseError(
                    code=INVALID_PARAMS, message=f"invalid params for {data['method']}: {why}"))
            log.warning("invalid params for %s (id %s): %s", data["method"], data.get("id", "none"), why)
            return ANSWERED

    def handle_message(self, message) -> None:
        if message is ANSWERED:
            return
        method = getattr(message, "method", None)
        is_request = method is not None and hasattr(message, "id")
        if method is not None and not self.initialized and method not in (T.INITIALIZE, T.EXIT):
            if is_request:
                self._send_response(message.id, error=T.ResponseError(
                    code=SERVER_NOT_INITIALIZED, message=f"{method}: the server is not initialized yet "
                                                         "(send `initialize` first)"))
            return
        if self._shutdown and method is not None and method != T.EXIT:
            if is_request:
                self._send_response(message.id, error=T.ResponseError(
                    code=INVALID_REQUEST, message=f"{method}: the server is shutting down (only `exit` is accepted)"))
            return
        if method in (T.TEXT_DOCUMENT_DID_CHANGE, T.TEXT_DOCUMENT_DID_CLOSE) and not is_request:
            uri = getattr(getattr(getattr(message, "params", None), "text_document", None), "uri", None)
            if isinstance(uri, str) and self._workspace is not None and unquote(uri) not in self.workspace.text_documents:
                log.warning("%s for `%s`, which is not open: ignored", method, uri[:200])
                return
        if method == T.INITIALIZE and is_request:
            if self.initialized:
                self._send_response(message.id, error=T.ResponseError(
                    code=INVALID_REQUEST, message="initialize: the server is already initialized"))
                return
            self.initialized = True
        super().handle_message(message)

    # ------------------------------------------------------------------------------ cancelling
    def _execute_handler(self, msg_id, handler, callback, args=None, kwargs=None):
        """A handler that pygls runs on behalf of a request's generator (``workspace/executeCommand``
        runs the command this way) is cancelled with the request: ``$/cancelRequest`` then stops
        the command, not only its reply."""
        super()._execute_handler(msg_id, handler, callback, args, kwargs)
        outer = callback.keywords.get("result_future") if isinstance(callback, partial) else None
        inner = getattr(self, "_request_futures", {}).get(msg_id)      # pygls's own table (2.x): absent, no link
        if outer is not None and inner is not None:
            outer.add_done_callback(lambda f: inner.cancel() if f.cancelled() else None)

    # ------------------------------------------------------------------------------ replying
    def _send_response(self, msg_id, result=None, error=None) -> None:
        if error is not None:
            data = error.data
            if isinstance(data, dict) and "traceback" in data:
                data = {k: v for k, v in data.items() if k != "traceback"} or None
            error = T.ResponseError(code=error.code, message=error.message, data=data)
        super()._send_response(msg_id, result, error)

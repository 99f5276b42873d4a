"""`acl lsp`: start the language server on stdin/stdout (editors start it; see docs/lsp.md)."""
from __future__ import annotations

from acl.commands._common import report
from acl.diagnostics import Span, error


def add_parser(p) -> None:
    p.add_argument("--stdio", action="store_true", help="speak LSP over stdin/stdout (the default and only transport)")


def run(args) -> int:
    try:
        import lsprotocol  # noqa: F401
        import pygls  # noqa: F401
    except ImportError as exc:
        report([error("E-DEPENDENCY", f"`acl lsp` needs the optional packages pygls and lsprotocol ({exc.name} is missing)",
                      Span(file="<acl lsp>", line=1, column=1), "install them with: pip install 'acl[lsp]' (from a checkout: pip install '.[lsp]')")])
        return 2
    if getattr(args, "verbose", False):       # the protocol traffic and server events, on stderr
        import logging

        logging.basicConfig(level=logging.INFO, format="acl lsp: %(name)s: %(message)s")
    from acl.lsp.server import serve

    serve(verbose=bool(getattr(args, "verbose", False)))
    return 0

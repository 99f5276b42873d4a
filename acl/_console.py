"""The rich consoles of the command line: never truncated or wrapped when the output is not a terminal.

rich lays text out for 80 columns when it writes into a pipe or a file, cutting table cells to
``bef…`` and wrapping diagnostics in CI logs.  Off a terminal we give it a width no table reaches
and turn soft wrapping on; an explicit ``COLUMNS`` still wins.  On a terminal nothing changes.
"""
from __future__ import annotations

import os

WIDE = 10_000


def make_console(*, stderr: bool = False, file=None, **kwargs):
    """A rich Console for stdout (or stderr, or ``file``) that keeps whole lines when piped."""
    from rich.console import Console

    kwargs.setdefault("highlight", False)
    con = Console(stderr=stderr, file=file, **kwargs)
    if not con.is_terminal and "COLUMNS" not in os.environ and "width" not in kwargs:
        con.width = WIDE
        con.soft_wrap = True
    return con

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


def table(*args, **kwargs):
    """A rich Table whose columns fold a long cell onto more lines instead of cutting it: in an 80-column
    terminal the analyze pair table showed `lef…`, `125…`, `att…`, hiding the numbers (see also
    :func:`print_table`, which stacks a table too wide to read)."""
    from rich.table import Table

    class _FoldingTable(Table):
        def add_column(self, *a, **k):
            k.setdefault("overflow", "fold")
            return super().add_column(*a, **k)

    return _FoldingTable(*args, **kwargs)


def print_table(console, tbl) -> None:
    """Print ``tbl``; when its columns would not fit the console even at their widest word, print each row as a
    stacked block of ``header: value`` lines instead (every number whole, readable at 80 columns)."""
    from rich.console import Group
    from rich.text import Text

    cols = list(tbl.columns)
    n_rows = max((len(c._cells) for c in cols), default=0)
    headers = [Text.from_markup(str(c.header)).plain if isinstance(c.header, str) else str(c.header) for c in cols]
    # the narrowest each column can be without cutting a word, plus borders and padding
    need = sum(max([len(w) for h in [headers[i]] for w in h.split()] +
                   [len(w) for cell in cols[i]._cells for w in str(cell).split()] + [1]) + 3
               for i in range(len(cols))) + 1
    if need <= console.width or n_rows == 0:
        console.print(tbl)
        return
    lines = []
    if tbl.title:
        lines.append(Text(str(tbl.title), style="bold"))
    width = max(len(h) for h in headers)
    for r in range(n_rows):
        for i, c in enumerate(cols):
            cell = c._cells[r] if r < len(c._cells) else ""
            text = cell.plain if isinstance(cell, Text) else Text.from_markup(str(cell)).plain
            lines.append(Text(f"  {headers[i]:<{width}}  {text}"))
        lines.append(Text(""))
    console.print(Group(*lines))


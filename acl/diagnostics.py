"""Diagnostics: errors and warnings as values with a code, a span and a hint, rendered in one place.

Every stage reports problems as :class:`Diagnostic` objects.  A stage that cannot go on raises
:class:`DiagnosticError` carrying all diagnostics found so far; the CLI renders them (rich or JSON)
and picks the exit code.  Nothing here imports heavy modules.
"""
from __future__ import annotations

import enum
import json
from dataclasses import dataclass, field
from typing import Iterable, Sequence

from pydantic import BaseModel, ConfigDict


class Severity(str, enum.Enum):
    ERROR = "error"
    WARNING = "warning"
    INFO = "info"


class Span(BaseModel):
    """A region of a source file: 1-based line and column, end exclusive."""

    model_config = ConfigDict(frozen=True)

    file: str
    line: int
    column: int
    end_line: int | None = None
    end_column: int | None = None

    def __str__(self) -> str:   # an empty path (`acl check ""`) is still shown as a location
        return f"{self.file or '<empty-path>'}:{self.line}:{self.column}"


@dataclass(frozen=True)
class Diagnostic:
    code: str
    severity: Severity
    message: str
    span: Span | None = None
    hint: str | None = None
    notes: tuple[str, ...] = ()

    @property
    def is_error(self) -> bool:
        return self.severity is Severity.ERROR

    def location(self) -> str:
        return str(self.span) if self.span else "<unknown>"

    def as_dict(self) -> dict:
        d = {
            "code": self.code,
            "severity": self.severity.value,
            "message": self.message,
            "file": self.span.file if self.span else None,
            "line": self.span.line if self.span else None,
            "column": self.span.column if self.span else None,
            "end_line": self.span.end_line if self.span else None,
            "end_column": self.span.end_column if self.span else None,
            "hint": self.hint,
        }
        if self.notes:
            d["notes"] = list(self.notes)
        return d


MAX_MESSAGE = 600      # characters; a message quoting a 1 MB CSV cell printed all of it


def clip(text: str | None, limit: int = MAX_MESSAGE) -> str | None:
    """``text`` with its middle elided beyond ``limit`` characters (quoted input can be any size)."""
    if text is None or len(text) <= limit:
        return text
    keep = (limit - 40) // 2
    return f"{text[:keep]} ...[{len(text) - 2 * keep:,} characters]... {text[-keep:]}"


def error(code: str, message: str, span: Span | None = None, hint: str | None = None) -> Diagnostic:
    return Diagnostic(code, Severity.ERROR, clip(message), span, clip(hint))


def warning(code: str, message: str, span: Span | None = None, hint: str | None = None) -> Diagnostic:
    return Diagnostic(code, Severity.WARNING, clip(message), span, clip(hint))


class DiagnosticError(Exception):
    """Raised by a stage that cannot continue; carries every diagnostic found so far."""

    def __init__(self, diagnostics: Sequence[Diagnostic]):
        self.diagnostics = list(diagnostics)
        first = self.diagnostics[0] if self.diagnostics else None
        super().__init__(f"{first.location()}: {first.code}: {first.message}" if first else "error")


@dataclass
class DiagnosticBag:
    """Collects diagnostics during one stage so that every independent error is reported."""

    items: list[Diagnostic] = field(default_factory=list)
    _seen: set = field(default_factory=set, repr=False, compare=False)

    def add(self, d: Diagnostic) -> None:
        """Record a diagnostic once: the same finding at the same place reached twice is one."""
        key = (d.code, d.span, d.message)
        if key not in self._seen:
            self._seen.add(key)
            self.items.append(d)

    def error(self, code: str, message: str, span: Span | None = None, hint: str | None = None) -> None:
        self.add(error(code, message, span, hint))

    def warning(self, code: str, message: str, span: Span | None = None, hint: str | None = None) -> None:
        self.add(warning(code, message, span, hint))

    @property
    def has_errors(self) -> bool:
        return any(d.is_error for d in self.items)

    def raise_if_errors(self) -> None:
        if self.has_errors:
            raise DiagnosticError(self.items)


def suggest(name: str, candidates: Iterable[str]) -> str | None:
    """'did you mean' helper: the closest candidate, if it is close enough."""
    import difflib

    found = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.6)
    return f"did you mean `{found[0]}`?" if found else None


# ---------------------------------------------------------------------------------------------
# Rendering
# ---------------------------------------------------------------------------------------------

def diagnostics_to_json(diags: Sequence[Diagnostic]) -> str:
    return json.dumps({"diagnostics": [d.as_dict() for d in diags]}, indent=2)


MAX_EXCERPT = 240   # characters of a source line quoted under a diagnostic


def render(diags: Sequence[Diagnostic], console=None, sources: dict[str, str] | None = None) -> None:
    """Render diagnostics with a caret excerpt of the source line (rich)."""
    from acl._console import make_console
    from rich.text import Text

    console = console or make_console(stderr=True, highlight=False)
    cache: dict[str, list[str] | None] = {}
    colours = {Severity.ERROR: "bold red", Severity.WARNING: "bold yellow", Severity.INFO: "bold blue"}
    for d in diags:
        head = Text()
        head.append(f"{d.location()}: ", style="bold")
        head.append(f"{d.severity.value}[{d.code}]", style=colours[d.severity])
        head.append(f": {d.message}")
        console.print(head)
        if d.span is not None:
            lines = _source_lines(d.span.file, cache, sources)
            if lines and 1 <= d.span.line <= len(lines):
                src = lines[d.span.line - 1].rstrip("\n")
                gutter = f"{d.span.line:>5} | "
                width = 1
                if d.span.end_line == d.span.line and d.span.end_column:
                    width = max(1, d.span.end_column - d.span.column)
                column = d.span.column
                if len(src) > MAX_EXCERPT:   # a 200 kB line is shown around its column, not whole
                    start = max(0, column - 1 - MAX_EXCERPT // 4)
                    cut = src[start:start + MAX_EXCERPT]
                    src = ("…" if start else "") + cut + ("…" if start + MAX_EXCERPT < len(src) else "")
                    column = column - start + (1 if start else 0)
                    width = min(width, MAX_EXCERPT)
                console.print(Text(gutter, style="dim") + Text(src))
                caret = " " * (len(gutter) + max(0, column - 1)) + "^" * width
                console.print(Text(caret, style=colours[d.severity]))
        for note in d.notes:
            console.print(Text(f"      = note: {note}", style="dim"))
        if d.hint:
            console.print(Text(f"      = help: {d.hint}", style="cyan"))


def _source_lines(path: str, cache: dict, sources: dict[str, str] | None) -> list[str] | None:
    if path in cache:
        return cache[path]
    text = None
    if sources and path in sources:
        text = sources[path]
    else:
        import os

        try:
            if os.path.isfile(path):   # never a FIFO or a device: excerpts must not hang
                with open(path, encoding="utf-8", errors="replace") as fh:
                    text = fh.read(2_000_000)
        except OSError:
            text = None
    cache[path] = text.splitlines() if text is not None else None
    return cache[path]

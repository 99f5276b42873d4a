"""`acl fmt`: one canonical layout for acl files, built on acl's own parser.

    from acl.fmt import format_source
    text = format_source(open("design.acl").read(), "design.acl")

:func:`format_source` refuses text with syntax errors (it raises the parser's
:class:`~acl.diagnostics.DiagnosticError`, codes E1xx with file:line:column) and checks its own
output: the formatted text must parse to the same syntax tree, spans aside (else E190). The
layout rules are listed in :mod:`acl.fmt.layout`.
"""
from __future__ import annotations

__all__ = ["format_source", "format_file"]


def format_source(text: str, path: str = "<stdin>") -> str:
    """The canonical layout of ``text``; raises DiagnosticError on syntax errors.

    Idempotent: ``format_source(format_source(t)) == format_source(t)``.
    """
    from acl.syntax.parser import paused_gc

    with paused_gc():   # as in `acl check`: the collector would rescan the growing trees (superlinear)
        return _format(text, path)


def _format(text: str, path: str) -> str:
    from acl.diagnostics import DiagnosticError, Span, error
    from acl.fmt.layout import layout
    from acl.fmt.meaning import meaning
    from acl.fmt.tokens import tokenize
    from acl.syntax.parser import parse_module, parse_module_tree

    source = text.replace("\r\n", "\n").removeprefix("\ufeff")   # the canonical file has no byte-order mark
    # a file whose every line ends in CRLF (a Windows checkout, git autocrlf) keeps CRLF, so `acl fmt --check`
    # judges the layout, not the platform's line endings (as black does); mixed endings become LF
    crlf = "\r\n" in text and text.count("\r\n") == text.count("\n")
    # one parse gives the parser's diagnostics and limits (as `acl check`), the tree and its tokens
    before, tree = parse_module_tree(source, path)
    out = layout(tokenize(source, path, tree))
    del tree
    final = out.replace("\n", "\r\n") if crlf else out
    if final == text:   # already canonical: nothing to check
        return final
    try:
        after = parse_module(out, path)
    except DiagnosticError as exc:
        first = exc.diagnostics[0] if exc.diagnostics else None
        raise DiagnosticError([error("E190", "internal formatter error: the formatted text does not parse"
                                     + (f" ({first.code} {first.message})" if first else ""),
                                     Span(file=path, line=1, column=1), "please report it; the file is left as it is")]) from None
    if meaning(before) != meaning(after):
        raise DiagnosticError([error("E190", "internal formatter error: formatting would change the design",
                                     Span(file=path, line=1, column=1), "please report it; the file is left as it is")])
    return final


def format_file(path: str) -> tuple[str, str]:
    """(original text, formatted text) of a design file; raises DiagnosticError (E601/E103/E1xx)."""
    from acl.design.modules import read_source

    text = read_source(path)
    return text, format_source(text, path)


def canonical(text: str, path: str = "<generated>") -> str:
    """``text`` (a design acl writes: calibrated, tuned) in the canonical layout, so `acl fmt --check` passes on it; the text as built if it does not parse."""
    from acl.diagnostics import DiagnosticError

    try:
        return format_source(text, path)
    except DiagnosticError:      # never lose a result to the formatter
        return text

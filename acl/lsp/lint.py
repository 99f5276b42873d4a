"""Lint findings for the language server, computed in a worker process.

Rules can take seconds on large designs (they run analyses), so the server runs them in one
worker process after the check-stage diagnostics are published; a result for a document version
that has since changed is dropped.  The configuration is the one `acl lint` would use for the file
(the nearest acl.toml or pyproject.toml).
"""
from __future__ import annotations

from acl.diagnostics import Diagnostic


_PARSERS: dict[str, object] = {}      # path -> IncrementalParser, in the worker


def lint_text(path: str, text: str) -> list[Diagnostic]:
    """Every finding `acl lint PATH` would report if PATH held ``text`` (check-stage ones included).

    The texts of one path go through one incremental parser in the worker (the same tree as a
    whole-file parse; the statements an edit did not touch are not parsed again)."""
    from acl.lint.config import ConfigError, find_config, load_config
    from acl.lint.registry import load_rules
    from acl.lint.runner import lint_design
    from acl.lint.source import scan
    from acl.lsp.document import check_text
    from acl.lsp.incremental import IncrementalParser

    if path not in _PARSERS:
        _PARSERS.clear()                   # the document linted last only
        _PARSERS[path] = IncrementalParser()
    snap = check_text(text, path, parser=_PARSERS[path])
    rules = load_rules()
    try:
        cfg = load_config(find_config(path), rules)
    except ConfigError as exc:
        return list(snap.diagnostics) + list(exc.diagnostics)
    return lint_design(path, snap.design, snap.diagnostics, scan(path, text), cfg).findings


def lower_priority() -> None:
    """Worker initializer: run the rules (and the hover's analyses) at a lower CPU priority than
    the server answering keystrokes, with one BLAS thread (:func:`one_blas_thread`)."""
    import os

    try:
        os.nice(10)
    except (AttributeError, OSError):   # not on this platform, or not allowed
        pass
    one_blas_thread()


def one_blas_thread() -> None:
    """Limit this worker process's BLAS to one thread (unless the user set its thread count).

    Its dense solves are a few hundred to 1,600 unknowns; on a busy machine OpenBLAS's threads
    spin: a capsule's full hover on 5,000 lines (its coupled modes) took 12.5-19.7 s wall with two
    threads against 4.5-5.0 s with one, at load 8 on 2 CPUs. A spawned worker has not loaded numpy
    when this runs, so the variables suffice; if it has, threadpoolctl (the `scale` extra) sets it."""
    import os
    import sys

    if "numpy" not in sys.modules:
        for var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ.setdefault(var, "1")
        return
    if "OPENBLAS_NUM_THREADS" in os.environ:
        return
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return
    threadpool_limits(limits=1, user_api="blas")


def warm_up() -> bool:
    """Import the rules and analyses in the worker before the first real request."""
    from acl.lint.registry import load_rules

    load_rules()
    return True

"""acl: a language and compiler for acoustically programmable soft micro-mechanisms.

Public API (imports are lazy so that `import acl` stays cheap)::

    import acl
    design = acl.load("examples/fig2_vertical_cantilever.acl", overrides={"gap": "60 um"})
"""
from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["load", "loads", "__version__"]


def load(path, overrides=None, search_paths=()):
    """Parse, resolve and check a design file; return the resolved :class:`acl.design.model.Design`.

    Raises :class:`acl.diagnostics.DiagnosticError` with every diagnostic if the design has errors.
    """
    from acl.design.resolve import load_design

    return load_design(path, overrides=overrides or {}, search_paths=search_paths)


def loads(text, filename="<string>", overrides=None, search_paths=()):
    """Like :func:`load` but from source text."""
    from acl.design.resolve import load_text

    return load_text(text, filename=filename, overrides=overrides or {}, search_paths=search_paths)

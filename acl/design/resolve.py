"""Syntax tree -> resolved, checked Design: the stage's public entry points.

Loads the file and its imports (:mod:`~acl.design.modules`), evaluates parameters with command-line
overrides (:mod:`~acl.design.evaluate`), builds the immutable models (:mod:`~acl.design.builders`,
:mod:`~acl.design.programs`, :mod:`~acl.design.assemble`), then runs the geometry and program checks
of :mod:`acl.design.checks`.  Every independent error is reported.
"""
from __future__ import annotations

from acl.design import model as M
from acl.design.assemble import assemble
from acl.design.builders import Builder
from acl.design.core import DECL_KINDS, EFFECTS, SCHEMAS, Key  # noqa: F401  (re-exported: lint and tools read them here)
from acl.design.evaluate import Resolver
from acl.design.modules import Loader, ModuleEnv
from acl.diagnostics import Diagnostic, DiagnosticBag, DiagnosticError
from acl.syntax.parser import paused_gc as _no_gc

__all__ = ["load_design", "load_text", "check_design", "Resolver", "SCHEMAS", "DECL_KINDS", "EFFECTS", "Key"]


def load_design(path: str, overrides: dict[str, str] | None = None, search_paths=()) -> M.Design:
    with _no_gc():
        return _load_design(path, overrides, search_paths)


def _load_design(path: str, overrides: dict[str, str] | None = None, search_paths=()) -> M.Design:
    bag = DiagnosticBag()
    loader = Loader(bag, search_paths)
    env = loader.load_main(str(path))
    return _finish(env, loader, bag, overrides or {})


def load_text(text: str, filename: str = "<string>", overrides=None, search_paths=()) -> M.Design:
    with _no_gc():
        return _load_text(text, filename, overrides, search_paths)


def _load_text(text: str, filename: str = "<string>", overrides=None, search_paths=()) -> M.Design:
    bag = DiagnosticBag()
    loader = Loader(bag, search_paths)
    env = loader.load_text(text, filename)
    return _finish(env, loader, bag, overrides or {})


def check_design(path: str, overrides=None, search_paths=(), text: str | None = None) -> tuple[M.Design | None, list[Diagnostic]]:
    """Like load_design but returns (design or None, all diagnostics incl. warnings).

    With ``text``, that is the design's source and ``path`` only its name (standard input).
    """
    with _no_gc():
        return _check_design(path, overrides, search_paths, text)


def _check_design(path: str, overrides=None, search_paths=(), text=None) -> tuple[M.Design | None, list[Diagnostic]]:
    try:
        bag = DiagnosticBag()
        loader = Loader(bag, search_paths)
        env = loader.load_main(str(path)) if text is None else loader.load_text(text, str(path))
        design = _finish(env, loader, bag, overrides or {})
        return design, bag.items
    except DiagnosticError as exc:
        return None, exc.diagnostics


def finish_design(env: ModuleEnv, loader: Loader, bag: DiagnosticBag, overrides: dict[str, str]) -> M.Design:
    """Resolve and assemble a loaded module (the stages after parsing), the collector paused as in `load_design`."""
    with _no_gc():       # the collector's passes over the growing design doubled an LSP check every other edit
        return _finish(env, loader, bag, overrides)


def _finish(env: ModuleEnv, loader: Loader, bag: DiagnosticBag, overrides: dict[str, str]) -> M.Design:
    r = Resolver(env, loader, bag, overrides)
    design = assemble(Builder(r))
    if bag.has_errors:
        raise DiagnosticError(sorted(_root_causes(env, bag.items), key=_order))
    return design


_UNREADABLE = ("E208", "E209", "E210", "E211")    # an import or extends that could not be read


def _root_causes(env: ModuleEnv, diags: list) -> list:
    """The diagnostics without the unknown names (E201) that only follow from an import or
    `extends` of the main file that could not be read: `extends "x.acl"` failing makes every name
    of the base unknown, `import x as m` failing every `m.name` (issue 11: report the root cause once)."""
    from acl.syntax import ast as A

    failed_at = {(d.span.file, d.span.line) for d in diags if d.code in _UNREADABLE and d.span is not None}
    if not failed_at:
        return diags
    base_failed, aliases = False, set()
    for st in env.module.statements:
        if (st.span.file, st.span.line) not in failed_at:
            continue
        if isinstance(st, A.Extends):
            base_failed = True
        elif isinstance(st, A.Import):
            aliases.add(st.alias or (st.module[-1] if st.module else None))
    aliases.discard(None)
    if not base_failed and not aliases:
        return diags
    main = env.module.file

    def cascade(d) -> bool:
        if d.code != "E201" or d.span is None or d.span.file != main:
            return False
        return base_failed or any(f"`{a}." in d.message for a in aliases)

    kept = [d for d in diags if not cascade(d)]
    return kept if any(d.is_error for d in kept) else diags


def _order(d: Diagnostic):
    s = d.span
    return (0 if d.is_error else 1, s.file if s else "", s.line if s else 0, s.column if s else 0)

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


def _finish(env: ModuleEnv, loader: Loader, bag: DiagnosticBag, overrides: dict[str, str]) -> M.Design:
    r = Resolver(env, loader, bag, overrides)
    design = assemble(Builder(r))
    if bag.has_errors:
        raise DiagnosticError(sorted(bag.items, key=_order))
    return design


def _order(d: Diagnostic):
    s = d.span
    return (0 if d.is_error else 1, s.file if s else "", s.line if s else 0, s.column if s else 0)

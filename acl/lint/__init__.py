"""acl lint: design rules with stable codes for CI.

Public face::

    from acl.lint import lint_file, load_config, find_config
    report = lint_file("examples/fig2_vertical_cantilever.acl", load_config(None, load_rules()))
    for d in report.findings: print(d.code, d.message)

Modules: ``registry`` (rules, thresholds), ``config`` (TOML), ``source`` (comments, suppressions,
names), ``context`` (what a rule sees, cached analyses), ``rules/`` (one module per family),
``runner`` (one file -> findings), ``formats`` (output writers).  Lint consumes the resolved
design and the analysis layer; it never imports cvxpy or matplotlib.
"""
from __future__ import annotations

from acl.lint.config import ConfigError, LintConfig, find_config, load_config
from acl.lint.registry import RULES, THRESHOLDS, load_rules
from acl.lint.runner import FileReport, collect_files, lint_file

__all__ = ["ConfigError", "FileReport", "LintConfig", "RULES", "THRESHOLDS", "collect_files", "find_config",
           "lint_file", "load_config", "load_rules"]


# `acl.lint(...)` is also the Python API function (acl/__init__.py): keep it callable.
from acl._callable import make_callable as _make_callable  # noqa: E402

_make_callable(__name__)

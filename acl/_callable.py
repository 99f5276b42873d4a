"""`acl.lint` and `acl.fit` are both API functions and subpackages.

Importing a subpackage sets the parent's attribute to the module, which would replace the function;
so those subpackages turn themselves into callable modules whose call is the API function
(:func:`acl._lint`, :func:`acl._fit`).  ``acl.lint(path)`` works before and after ``import acl.lint``.
"""
from __future__ import annotations

import sys
import types


class CallableModule(types.ModuleType):
    def __call__(self, *args, **kwargs):
        import acl

        return getattr(acl, "_" + self.__name__.rsplit(".", 1)[1])(*args, **kwargs)


def make_callable(name: str) -> None:
    """Let module ``name`` (acl.lint or acl.fit) be called like the API function of that name."""
    sys.modules[name].__class__ = CallableModule

"""Files shipped with acl: the standard library (``stdlib/``) and the documentation (``docs/``).

In a source checkout they are the repository's top-level folders; an installed wheel carries them
inside the package (``acl/stdlib``, ``acl/docs``, mapped by pyproject.toml).  Each folder is recognised
by a file it must hold, so an unrelated folder of the same name is never picked up.
"""
from __future__ import annotations

import os
from functools import lru_cache

_MARKERS = {"stdlib": "media.acl", "docs": "rules.md"}


@lru_cache(maxsize=None)
def shipped_dir(name: str) -> str:
    """Absolute path of the shipped folder ``name`` ("stdlib" or "docs")."""
    here = os.path.dirname(os.path.abspath(__file__))
    for cand in (os.path.join(here, name), os.path.join(os.path.dirname(here), name)):
        if os.path.isfile(os.path.join(cand, _MARKERS[name])):
            return cand
    raise FileNotFoundError(f"acl installation is incomplete: no `{name}` folder beside {here}")

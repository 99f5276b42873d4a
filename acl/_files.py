"""Permissions of the files acl writes: what the user's umask gives a plain ``open``/``mkdir``.

Outputs are written atomically through :mod:`tempfile` names (``mkstemp`` creates 0600 files,
``mkdtemp`` 0700 folders, whatever the umask); :func:`as_umask` gives them the mode an ordinary
file or folder would have had before they are renamed into place.
"""
from __future__ import annotations

import os


def umask() -> int:
    """The process umask (read by setting and restoring it)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def as_umask(path: str, directory: bool | None = None) -> None:
    """chmod ``path`` to 0666 (files) or 0777 (folders) minus the umask."""
    if directory is None:
        directory = os.path.isdir(path)
    os.chmod(path, (0o777 if directory else 0o666) & ~umask())

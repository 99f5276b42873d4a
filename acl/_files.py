"""Files acl reads and writes: the designs under a folder, and the permissions of what it writes.

Permissions: what the user's umask gives a plain ``open``/``mkdir``.

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


#: folders a search for designs never enters (besides hidden ones)
SKIPPED_DIRS = frozenset({"build", "dist", "node_modules", "venv", "__pycache__", "site-packages"})


def designs_under(folder: str) -> list[str]:
    """The ``*.acl`` designs under ``folder`` (recursively, sorted).  The search stays in the folder:
    hidden and build folders are skipped, and so are links leading out of it and entries that are
    not regular files (a FIFO or a device named ``*.acl``)."""
    top = os.path.realpath(folder)
    inside = top.rstrip(os.sep) + os.sep
    files = []
    for dirpath, dirs, names in os.walk(folder):
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and d not in SKIPPED_DIRS)
        for n in sorted(names):
            f = os.path.join(dirpath, n)
            real = os.path.realpath(f)
            if n.endswith(".acl") and (real == top or real.startswith(inside)) and os.path.isfile(f):
                files.append(f)
    return files

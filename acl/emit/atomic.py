"""Atomic replacement of one text file: write a temporary file beside it, then rename.

A reader (or a crash) sees either the old file or the new one, never a half-written file; the
file keeps its permission bits.  A character device or a FIFO (``-o /dev/null``, a pipe) is written
as a stream once the text is complete, never renamed over (``acl._files.publish_file``).
Light on purpose (no numpy): `acl fmt` uses it.
"""
from __future__ import annotations

import os
import tempfile


def write_text_atomic(path: str, text: str) -> None:
    """Replace ``path`` with ``text`` (UTF-8, newlines as given) in one rename; a symbolic link is
    followed (its target is rewritten, the link stays)."""
    from acl._files import deferred_signals, publish_file, stream_kind, streamable_problem, temp_folder_for

    path = os.path.realpath(path)
    problem = streamable_problem(path)
    if problem:
        raise OSError(1, problem, path)
    try:
        mode = os.stat(path).st_mode & 0o7777
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        mode = 0o666 & ~umask
    if stream_kind(path):
        mode = 0o600
    tmp = None
    try:
        with deferred_signals():
            fd, tmp = tempfile.mkstemp(prefix=".acl-", suffix=".tmp", dir=temp_folder_for(path))
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, mode)
        publish_file(tmp, path)
    except BaseException:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
        raise

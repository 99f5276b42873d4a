"""Atomic replacement of one text file (the writers live in :mod:`acl._files`, below every stage that writes).

A reader (or a crash) sees either the old file or the new one, never a half-written file; the
file keeps its permission bits.  A character device or a FIFO (``-o /dev/null``, a pipe) is written
as a stream once the text is complete, never renamed over (``acl._files.publish_file``).
"""
from __future__ import annotations

from acl._files import write_chunks_atomic, write_text_atomic

__all__ = ["write_chunks_atomic", "write_text_atomic"]

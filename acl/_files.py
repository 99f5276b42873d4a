"""Files acl reads and writes: the designs under a folder, and the permissions of what it writes.

Permissions: what the user's umask gives a plain ``open``/``mkdir``.

Outputs are written atomically through :mod:`tempfile` names (``mkstemp`` creates 0600 files,
``mkdtemp`` 0700 folders, whatever the umask); :func:`as_umask` gives them the mode an ordinary
file or folder would have had before they are renamed into place.
"""
from __future__ import annotations

import os
import re
import tempfile


def undecodable(raw: bytes, exc: UnicodeDecodeError) -> tuple[int, int, int]:
    """(line, column, byte value) in ``raw`` of the first byte that ``exc`` (raised decoding ``raw``) could not
    decode; column counts characters.  With ``utf-8-sig`` the codec's offsets start after the byte-order
    mark: they are shifted back onto ``raw`` (reading them against ``raw`` named the wrong byte, 3 columns early)."""
    start = exc.start + (len(raw) - len(exc.object))
    line_start = raw.rfind(b"\n", 0, start) + 1
    column = len(raw[line_start:start].decode("utf-8-sig", errors="replace")) + 1
    return raw.count(b"\n", 0, start) + 1, column, raw[start]


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

MAX_DEPTH = 32           # folder levels below the folder searched
MAX_ENTRIES = 100_000    # directory entries examined by one search

#: kernel and pseudo filesystems: a search never enters them (`acl check /` must not read /proc)
VIRTUAL_FS = frozenset({"proc", "sysfs", "devtmpfs", "devpts", "cgroup", "cgroup2", "debugfs", "tracefs",
                        "securityfs", "pstore", "bpf", "mqueue", "hugetlbfs", "configfs", "fusectl", "autofs",
                        "binfmt_misc", "efivarfs", "rpc_pipefs", "nsfs", "selinuxfs", "devfs"})
_ALWAYS_VIRTUAL = ("/proc", "/sys", "/dev")


def virtual_mounts() -> frozenset[str]:
    """Mount points of kernel and pseudo filesystems (from /proc/self/mounts where there is one),
    and /proc, /sys and /dev always."""
    found = set(_ALWAYS_VIRTUAL)
    try:
        with open("/proc/self/mounts", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                parts = line.split()
                if len(parts) >= 3 and parts[2] in VIRTUAL_FS:
                    # the mount table escapes blanks as octal (\040)
                    found.add(re.sub(r"\\([0-7]{3})", lambda m: chr(int(m.group(1), 8)), parts[1]))
    except OSError:
        pass
    return frozenset(found)


def _limit(folder: str, where: str, message: str, hint: str):
    from acl.diagnostics import DiagnosticError, Span, error

    return DiagnosticError([error("E602", f"search of folder `{folder}` stopped: {message}",
                                  Span(file=where, line=1, column=1), hint)])


def designs_under(folder: str) -> list[str]:
    """The ``*.acl`` designs under ``folder`` (recursively; each folder's files sorted, then its
    sub-folders in order).  The search stays in the folder: hidden and build folders are skipped,
    and so are kernel and pseudo filesystems (/proc, /sys, /dev), links leading out of it (links to
    folders are not followed: no loops) and entries that are not regular files (a FIFO or a device
    named ``*.acl``).  It is bounded: more than :data:`MAX_DEPTH` folder levels or
    :data:`MAX_ENTRIES` entries raise DiagnosticError E602 (located at the folder where the limit
    was reached) rather than returning part of the designs."""
    top = os.path.realpath(folder)
    inside = top.rstrip(os.sep) + os.sep
    virtual = virtual_mounts()
    if any(top == v or top.startswith(v.rstrip(os.sep) + os.sep) for v in virtual):
        return []
    files: list[str] = []
    seen = 0
    stack = [(folder, 0)]
    while stack:
        path, depth = stack.pop()
        try:
            with os.scandir(path) as it:
                names, subdirs = [], []
                for entry in it:
                    seen += 1
                    if seen > MAX_ENTRIES:
                        raise _limit(folder, path, f"more than {MAX_ENTRIES:,} entries examined",
                                     "name the folders that hold your designs, not a whole disk")
                    n = entry.name
                    try:
                        is_dir = entry.is_dir(follow_symlinks=False)
                    except OSError:
                        continue
                    if is_dir:
                        if not n.startswith(".") and n not in SKIPPED_DIRS:
                            subdirs.append(entry.path)
                    elif n.endswith(".acl"):
                        names.append(n)
        except (PermissionError, FileNotFoundError, NotADirectoryError):
            continue          # unreadable or vanished meanwhile: nothing of ours in it
        except OSError:
            continue
        for n in sorted(names):
            f = os.path.join(path, n)
            real = os.path.realpath(f)
            if (real == top or real.startswith(inside)) and os.path.isfile(f):
                files.append(f)
        subdirs = [d for d in sorted(subdirs) if os.path.realpath(d) not in virtual]
        if subdirs and depth + 1 > MAX_DEPTH:
            raise _limit(folder, subdirs[0], f"folders nested more than {MAX_DEPTH} levels deep",
                         "name the folders that hold your designs (a bind mount or a generated tree can nest without end)")
        stack.extend((d, depth + 1) for d in reversed(subdirs))
    return files


def input_named(path: str, inputs) -> str | None:
    """The input among ``inputs`` that the output ``path`` names (the same file, through links too), else None.

    An output written over an input destroys it: `acl fit --calibrated DESIGN` wrote a design that
    extends itself over the design, `acl synth -o DESIGN` a CSV over it."""
    if not path:
        return None
    real = os.path.realpath(path)
    for p in inputs:
        if not p:
            continue
        try:
            if os.path.exists(path) and os.path.exists(p) and os.path.samefile(path, p):
                return p
        except OSError:
            pass
        if os.path.realpath(p) == real:
            return p
    return None


def inputs_inside(folder: str, inputs) -> list[str]:
    """The inputs that lie in ``folder`` or below it (a folder an output replaces as a whole must hold none)."""
    top = os.path.realpath(folder).rstrip(os.sep) + os.sep
    return [p for p in inputs if p and os.path.realpath(p).startswith(top)]


def write_figures_atomically(folder: str, draw) -> list[str]:
    """``draw(tmp)`` writes files into a temporary folder beside ``folder``; then every one is moved into
    ``folder`` (created), after checking that none would land on a folder.  Returns the paths in ``folder``.

    A failure (OSError) leaves ``folder`` as it was: before, `acl analyze --plot` wrote the first figures
    and then failed on a later one (exit 2 with part of the figures written)."""
    import shutil
    import tempfile

    if os.path.lexists(folder) and not os.path.isdir(folder):
        raise NotADirectoryError(20, "exists and is not a folder")
    tmp = tempfile.mkdtemp(prefix=".acl-figures-", dir=os.path.dirname(os.path.abspath(folder)))
    try:
        names = [os.path.basename(p) for p in draw(tmp)]
        for n in names:
            target = os.path.join(folder, n)
            if os.path.isdir(target) and not os.path.islink(target):
                raise IsADirectoryError(21, f"{target} is a folder")
        os.makedirs(folder, exist_ok=True)
        out = []
        for n in names:
            os.replace(os.path.join(tmp, n), os.path.join(folder, n))
            out.append(os.path.join(folder, n))
        return out
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


# --- Where a finished output goes: renamed into place, or streamed into a device or FIFO -------------------------

def stream_kind(path: str) -> str | None:
    """What ``path`` (links followed) is when it exists and is neither a regular file nor a folder: ``"device"``
    (a character device: /dev/null, a terminal), ``"fifo"``, ``"block device"`` or ``"socket"``; else None.

    An output must never be renamed over one of these: `acl synth -o null` (a device node named null)
    replaced the node with a 133-byte regular file, and as root `-o /dev/null` would replace the system's."""
    import stat

    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return None
    if stat.S_ISCHR(mode):
        return "device"
    if stat.S_ISFIFO(mode):
        return "fifo"
    if stat.S_ISBLK(mode):
        return "block device"
    if stat.S_ISSOCK(mode):
        return "socket"
    return None


def streamable_problem(path: str) -> str | None:
    """Why an output cannot go to ``path`` when it is a special file (a block device or a socket: refused, acl
    never writes a disk or a socket), else None.  Character devices and FIFOs are written as streams."""
    kind = stream_kind(path)
    if kind in ("block device", "socket"):
        return f"`{path}` is a {kind}: acl writes regular files, character devices and FIFOs only"
    return None


def temp_folder_for(path: str) -> str:
    """The folder for the temporary file of an output ``path``: beside it (so the final rename is atomic), or
    the system's temporary folder when ``path`` is a device or FIFO (acl must not create files in /dev)."""
    import tempfile

    if stream_kind(path):
        return tempfile.gettempdir()
    return os.path.dirname(os.path.abspath(path)) or "."


def publish_file(tmp: str, path: str) -> None:
    """Put the finished temporary file ``tmp`` at ``path``: one rename over a regular file (or a new name);
    into a character device or a FIFO, its bytes written as a stream, then ``tmp`` removed.  A block device
    or a socket is refused (OSError).  A FIFO with no reader is an error (ENXIO), never a hang."""
    import shutil

    kind = stream_kind(path)
    if kind is None:
        os.replace(tmp, path)
        return
    problem = streamable_problem(path)
    if problem:
        raise OSError(1, problem, path)
    flags = os.O_WRONLY | (os.O_NONBLOCK if kind == "fifo" else 0)
    try:
        fd = os.open(path, flags)    # no O_CREAT/O_TRUNC: the node stays what it is
    except OSError as exc:
        import errno

        if exc.errno == errno.ENXIO and kind == "fifo":
            raise OSError(exc.errno, "no process reads this FIFO (acl does not wait for one); start the reader first",
                          path) from None
        raise
    try:
        if kind == "fifo":
            os.set_blocking(fd, True)
        with open(tmp, "rb") as src, os.fdopen(fd, "wb", closefd=False) as dst:
            shutil.copyfileobj(src, dst, 1 << 20)
    finally:
        os.close(fd)
    os.unlink(tmp)



#: Python refuses to convert integers longer than this (sys.get_int_max_str_digits, CVE-2020-10735)
MAX_INT_DIGITS = 4300
_LONG_DIGITS = re.compile(r"[0-9_]{%d,}" % (MAX_INT_DIGITS + 1))


def overlong_integer(text: str) -> tuple[int, int] | None:
    """(line, column) of the first run of more than :data:`MAX_INT_DIGITS` digits in ``text``, else None.

    JSON and TOML parsers turn such a run into a Python int and fail with a bare ValueError (an internal
    error before): callers refuse it first, located."""
    m = _LONG_DIGITS.search(text)
    if m is None:
        return None
    start = m.start()
    line_start = text.rfind("\n", 0, start) + 1
    return text.count("\n", 0, start) + 1, start - line_start + 1


class deferred_signals:
    """``with deferred_signals(): tmp = mkstemp(...)``: SIGINT, SIGTERM and SIGHUP wait until the block ends, so an
    interrupt cannot land between the creation of a temporary file and the assignment that lets the cleanup find
    it (a SIGTERM there left `.acl-compile-*/` behind).  Outside the main thread, or where signals cannot be
    masked, it does nothing."""

    _SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")

    def __enter__(self):
        import signal
        import threading

        self.old = None
        if threading.current_thread() is threading.main_thread() and hasattr(signal, "pthread_sigmask"):
            wanted = {getattr(signal, n) for n in self._SIGNALS if hasattr(signal, n)}
            self.old = signal.pthread_sigmask(signal.SIG_BLOCK, wanted)
        return self

    def __exit__(self, *exc):
        import signal

        if self.old is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, self.old)
        return False


# --- Atomic replacement of one text file (a temporary file beside it, then one rename) ----------------------

def write_text_atomic(path: str, text: str) -> None:
    """Replace ``path`` with ``text`` (UTF-8, newlines as given) in one rename; a symbolic link is
    followed (its target is rewritten, the link stays)."""
    write_chunks_atomic(path, (text,))


def write_bytes_atomic(path: str, data: bytes, prefix: str = ".acl-") -> None:
    """:func:`write_text_atomic` of bytes (print files, figures)."""
    write_chunks_atomic(path, (data,), binary=True, prefix=prefix)


def write_chunks_atomic(path: str, chunks, binary: bool = False, prefix: str = ".acl-") -> None:
    """:func:`write_text_atomic` of the text (or, ``binary``, the bytes) that the iterable ``chunks`` yields piece
    by piece (memory bounded by one piece: `acl synth` writes millions of rows)."""
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
            fd, tmp = tempfile.mkstemp(prefix=prefix, suffix=".tmp", dir=temp_folder_for(path))
        with (os.fdopen(fd, "wb") if binary else os.fdopen(fd, "w", encoding="utf-8", newline="")) as fh:
            for text in chunks:
                fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, mode)
        publish_file(tmp, path)
    except BaseException:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
        raise

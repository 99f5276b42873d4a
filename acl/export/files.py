"""Print files: binary STL, 3MF and OBJ by suffix, written atomically, and the checks of an output path.

An output is refused before any work when it cannot be made (E-USAGE, E601; docs/export.md): an
unknown suffix, a folder, a missing or read-only folder, a path naming one of the design's inputs,
or an existing entry that is not a regular file (a FIFO or a device: acl never renames over one).
A file is written to a temporary name beside the target and renamed into place, so a failure
leaves no partial file and an earlier file intact.
"""
from __future__ import annotations

import os
import stat
import tempfile

import numpy as np

from acl.diagnostics import DiagnosticError, Span, error

FORMATS = {".stl": "stl", ".3mf": "3mf", ".obj": "obj"}
UNITS = {"um": 1.0, "mm": 1e-3, "m": 1e-6}      # per micrometre
THREEMF_UNITS = {"um": "micron", "mm": "millimeter", "m": "meter"}


def _span(option: str) -> Span:
    return Span(file=f"<{option}>", line=1, column=1)


def check_output(path: str, option: str, suffixes, inputs=()) -> None:
    """Raise DiagnosticError when ``path`` cannot be written as one of ``suffixes``."""
    where = _span(option)
    if not path or not path.strip():
        raise DiagnosticError([error("E-USAGE", f"{option} {path!r}: an empty path", where, "give a file name")])
    if os.path.isdir(path):
        raise DiagnosticError([error("E601", f"cannot write `{path}`: it is a folder", where,
                                     f"give a file, e.g. {option} device{sorted(suffixes)[0]}")])
    suffix = os.path.splitext(path)[1].lower()
    if suffix not in suffixes:
        raise DiagnosticError([error("E-USAGE", f"{option} {path}: the format is chosen by the suffix, "
                                     f"{', '.join(sorted(suffixes))}; not {suffix or 'a file without suffix'!r}",
                                     where, f"e.g. {option} device{sorted(suffixes)[0]}")])
    try:
        st = os.stat(path)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise DiagnosticError([error("E601", f"cannot write `{path}`: {exc.strerror or exc}", where)]) from None
    if st is not None and not stat.S_ISREG(st.st_mode):
        kind = "a FIFO" if stat.S_ISFIFO(st.st_mode) else "a device" if stat.S_ISCHR(st.st_mode) or \
            stat.S_ISBLK(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode) else "not a regular file"
        raise DiagnosticError([error("E601", f"cannot write `{path}`: it is {kind}; acl writes a print file "
                                     "as a regular file (a temporary file renamed into place) and never replaces "
                                     "another kind of entry", where, "give a regular file path")])
    from acl._files import input_named

    hit = input_named(path, inputs)
    if hit:
        raise DiagnosticError([error("E-USAGE", f"{option} {path}: names the input {hit}; writing would destroy it",
                                     where, "give another path")])
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise DiagnosticError([error("E601", f"cannot write `{path}`: no folder `{folder}`", where)])
    if not os.access(folder, os.W_OK | os.X_OK):
        raise DiagnosticError([error("E601", f"cannot write `{path}`: the folder is not writable", where)])


def meshes(parts, unit: str = "um") -> list:
    """trimesh meshes of the parts, scaled from micrometres to ``unit``."""
    import trimesh

    out = []
    k = UNITS[unit]
    for p in parts:
        m = p.solid.to_mesh()
        mesh = trimesh.Trimesh(np.asarray(m.vert_properties, float)[:, :3] * k, np.asarray(m.tri_verts), process=False)
        mesh.metadata["name"] = p.name
        out.append(mesh)
    return out


def encode(parts_meshes: list, names: list[str], fmt: str, unit: str = "um") -> bytes:
    """The file's bytes: STL (binary, all parts in one solid list), 3MF (one object per part, in
    ``unit``), OBJ (one object per part)."""
    import trimesh

    if fmt == "stl":
        return trimesh.util.concatenate(parts_meshes).export(file_type="stl")
    scene = trimesh.Scene()
    for m, n in zip(parts_meshes, names):
        scene.add_geometry(m, node_name=n, geom_name=n)
    if fmt == "3mf":
        return _threemf_unit(scene.export(file_type="3mf"), THREEMF_UNITS[unit])
    text = scene.export(file_type="obj")
    return text.encode("utf-8") if isinstance(text, str) else text


def _threemf_unit(data: bytes, unit: str) -> bytes:
    """The 3MF package with its model's ``unit`` set (trimesh writes millimetres whatever the numbers
    mean; a slicer reading micrometres as millimetres would print the device 1000x too large)."""
    import io
    import re
    import zipfile

    src, out = zipfile.ZipFile(io.BytesIO(data)), io.BytesIO()
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as dst:
        for info in src.infolist():
            body = src.read(info.filename)
            if info.filename.lower().endswith(".model"):
                body, n = re.subn(rb'(<model\b[^>]*?\bunit=")[^"]*(")', lambda m: m.group(1) + unit.encode() + m.group(2), body, count=1)
                if n != 1:
                    raise ValueError("3MF model without a unit attribute")
            dst.writestr(info, body)
    return out.getvalue()


def write_atomic(path: str, data: bytes) -> None:
    """``data`` into ``path`` through a temporary file beside it and one rename (acl._files.write_bytes_atomic)."""
    from acl._files import write_bytes_atomic

    write_bytes_atomic(path, data, prefix=".acl-export-")


def stage(path: str, data: bytes) -> str:
    """``data`` in a temporary file beside ``path`` (renamed into place later by :func:`publish`)."""
    from acl._files import as_umask

    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".acl-export-", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        as_umask(tmp, directory=False)
    except BaseException:
        os.unlink(tmp)
        raise
    return tmp


def publish(staged: list[tuple[str, str]]) -> None:
    """Rename every staged (temporary, target) pair into place; on a failure remove what is left."""
    try:
        for tmp, target in staged:
            os.replace(tmp, target)
    finally:
        for tmp, _ in staged:
            if os.path.exists(tmp):
                os.unlink(tmp)


def discard(staged: list[tuple[str, str]]) -> None:
    for tmp, _ in staged:
        if os.path.exists(tmp):
            os.unlink(tmp)


def load(path: str, unit: str = "um") -> list:
    """The parts of a print file read back (trimesh meshes, in micrometres)."""
    import trimesh

    fmt = FORMATS[os.path.splitext(path)[1].lower()]
    loaded = trimesh.load(path, file_type=fmt, force=None)
    k = 1.0 / UNITS[unit]
    if isinstance(loaded, trimesh.Scene):
        parts = [g.copy() for g in loaded.dump()] if hasattr(loaded, "dump") else list(loaded.geometry.values())
    else:
        parts = list(loaded.split(only_watertight=False))
    for m in parts:
        m.apply_scale(k)
    return parts

"""Examples of the paper's devices without their stdlib calibrations (first principles), for tests of the
model's own physics: the shipped examples declare the paper's fitted constants (stdlib/calibrations.acl)."""
from __future__ import annotations

import atexit
import re
import shutil
import tempfile
from pathlib import Path

import acl

EX = Path(__file__).resolve().parents[1] / "examples"
_CALIBRATED_PAIR = re.compile(r"(?ms)^effect bjerknes_scale \{.*?\}[^\n]*\n")
_DIR: list = []


def first_principles_text(name: str) -> str:
    """The example's source with its calibrated pair law (``effect bjerknes_scale``) removed."""
    text = _CALIBRATED_PAIR.sub("", (EX / f"{name}.acl").read_text())
    assert "effect bjerknes_scale" not in text, name
    return text


def first_principles_path(name: str) -> Path:
    """A file (in a private temporary folder, removed at exit) holding :func:`first_principles_text`: sweeps
    resolve a design again from its file."""
    if not _DIR:
        _DIR.append(Path(tempfile.mkdtemp(prefix="acl-fp-")))
        atexit.register(shutil.rmtree, _DIR[0], True)
    path = _DIR[0] / f"{name}.acl"
    if not path.exists():
        path.write_text(first_principles_text(name))
    return path


def load_first_principles(name: str, **kw):
    """:func:`acl.load` of the example without its calibrations."""
    return acl.load(str(first_principles_path(name)), **kw)

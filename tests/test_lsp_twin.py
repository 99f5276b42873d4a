"""The hover worker's reuse across texts (issue 27): a text whose design is the same physics as an
earlier one's (Enter, a comment, a moved line) takes its coupled modes from that design's caches,
and its hover is exactly the one a fresh check gives; any change of the physics computes anew."""
from __future__ import annotations

from pathlib import Path

import pytest

from acl.lsp import background as B
from acl.lsp.document import check_text
from acl.lsp.hover import hover

ROOT = Path(__file__).resolve().parents[1]

DESIGN = """\
import stdlib.media
import stdlib.capsules
import stdlib.beams
import stdlib.transducers
use medium media.pbs
use transducer transducers.contact_piezo

param dwell = 300 ms
param gap = 300 um
beam arm like beams.cantilever50 { clamp = (0, 0, 0) }
capsule c1 like capsules.design1 { }
capsule c2 like capsules.design2 { center = (gap, 0, 100 um) }
capsule c3 like capsules.design3 { center = (2 * gap, 0, 100 um) }
mount c1 on arm.tip
fix c2
fix c3

program ramp {
  drive 125 kHz @ 2 V for dwell
}
"""


@pytest.fixture(autouse=True)
def _fresh_worker_state():
    for store in (B._CHECKED, B._PARSERS, B._TWINS, B._TWIN_OF):
        store.clear()
    yield
    for store in (B._CHECKED, B._PARSERS, B._TWINS, B._TWIN_OF):
        store.clear()


def _line(text: str, needle: str) -> int:
    return next(i for i, ln in enumerate(text.split("\n")) if needle in ln)


def _fresh_hover(path: str, text: str, line: int) -> str:
    return hover(check_text(text, path), line, 9)[0]


def test_content_key_leaves_out_locations_only():
    path = "/tmp/twin.acl"
    a = check_text(DESIGN, path).design
    entered = DESIGN.replace("param gap", "\n\n# a comment\nparam gap")
    b = check_text(entered, path).design
    assert a != b                                       # the spans moved
    assert B.content_key(a) == B.content_key(b)
    moved = check_text(DESIGN.replace("= 300 um", "= 301 um"), path).design
    assert B.content_key(moved) != B.content_key(a)
    other_program = check_text(DESIGN.replace("@ 2 V", "@ 3 V"), path).design
    assert B.content_key(other_program) != B.content_key(a)     # conservative: any value counts
    with pytest.raises(TypeError):
        B.content_key({1: object()})


def test_a_hover_after_enter_reuses_the_earlier_design_and_equals_a_fresh_one(tmp_path, monkeypatch):
    path = str(tmp_path / "twin.acl")
    first = B.hover_text(path, DESIGN, _line(DESIGN, "capsule c2"), 9)
    assert "with its neighbours" in first                    # the coupled modes are part of it
    design0 = B.checked(path, DESIGN).design
    entered = DESIGN.replace("fix c2", "\n\nfix c2")         # Enter twice above c2's mount
    line = _line(entered, "capsule c3")
    got = B.hover_text(path, entered, line, 9)
    assert B.physics_twin(B.checked(path, entered).design) is design0    # served by the earlier design
    assert got == _fresh_hover(path, entered, line)
    assert f"twin.acl:{line + 1}" in got                     # its own location, not the earlier text's
    calls = []                                               # another hover on that text: no new key
    real = B.content_key
    monkeypatch.setattr(B, "content_key", lambda v: calls.append(1) or real(v))
    B.hover_text(path, entered, _line(entered, "capsule c1"), 9)
    assert calls == []
    monkeypatch.undo()
    # a physics edit (c3 moved): computed anew, and again what a fresh check gives
    moved = entered.replace("param gap = 300 um", "param gap = 250 um")
    got = B.hover_text(path, moved, line, 9)
    assert B.physics_twin(B.checked(path, moved).design) is not design0
    assert got == _fresh_hover(path, moved, line)
    assert got != _fresh_hover(path, entered, line)          # the coupled modes changed with the gap


def test_every_example_has_a_content_key_that_ignores_moved_lines():
    """No example's design holds a value content_key cannot key (it would lose the reuse), and two
    empty lines above its text leave the key as it was."""
    count = 0
    for f in sorted((ROOT / "examples").glob("*.acl")):
        text = f.read_text(encoding="utf-8")
        design = check_text(text, str(f)).design
        if design is None:
            continue
        assert B.content_key(check_text("\n\n" + text, str(f)).design) == B.content_key(design), f.name
        count += 1
    assert count >= 10


def _blas_threads():
    import os

    import numpy  # noqa: F401

    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        return os.environ.get("OPENBLAS_NUM_THREADS"), None
    return os.environ.get("OPENBLAS_NUM_THREADS"), \
        sorted({i["num_threads"] for i in threadpool_info() if i.get("user_api") == "blas"})


def test_the_background_worker_runs_one_blas_thread(monkeypatch):
    """The worker's dense solves run on one BLAS thread (two spin on a busy machine: 3-4x the
    wall time of a capsule's full hover at load 8), unless the user set the thread count."""
    import time

    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    w = B.Worker()
    try:
        assert w.get(("doc", "t", "blas"), _blas_threads) is None
        deadline = time.monotonic() + 120
        while w.peek(("doc", "t", "blas")) is None and time.monotonic() < deadline:
            time.sleep(0.05)
        env, threads = w.peek(("doc", "t", "blas"))
        assert env == "1"
        assert threads in (None, [1])
    finally:
        w.stop()


def test_the_warmed_document_serves_the_first_hover_and_parses_only_edits(monkeypatch):
    """warm_document (the worker's first job on a large document) leaves the coupled modes of the opened text
    computed and its statements parsed: the first hover on that text solves no eigenproblem, one on an edited text
    parses only the edited statement; both equal a fresh check's hover."""
    from acl.physics import coupling as CP

    path = "/tmp/warm.acl"
    assert B.warm_document(path, DESIGN) is True
    solved = []
    real = CP.mode_shapes
    monkeypatch.setattr(CP, "mode_shapes", lambda *a, **k: solved.append(1) or real(*a, **k))
    import acl.analysis.acoustics as AC

    monkeypatch.setattr(AC, "_physics_mode_shapes", CP.mode_shapes)
    line = _line(DESIGN, "capsule c2")
    got = B.hover_text(path, DESIGN, line, 9)
    assert not solved                              # the warm job's coupled modes served it
    assert "with its neighbours" in got and got == _fresh_hover(path, DESIGN, line)
    solved.clear()
    edited = DESIGN.replace("param gap = 300 um", "param gap = 310 um")
    got = B.hover_text(path, edited, line, 9)
    assert B._PARSERS[path].stats["parsed"] == 1   # the edited statement alone
    assert solved                                  # new physics: solved anew
    assert got == _fresh_hover(path, edited, line)

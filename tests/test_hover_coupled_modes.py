"""A capsule's hover lists its coupled modes (issue 23: a hover on any capsule of a 5,000-line design within 1 s)
from the same analysis as `acl analyze`, computed faster two ways, each checked here against the whole computation:

- only the hovered capsule's modes get their Q (:func:`acl.analysis.acoustics.coupled_modes_of`): the modes of
  :func:`acl.analysis.acoustics.coupled_modes` (what `acl analyze` reports) filtered by share, the same frequencies,
  shares and phases bit for bit and the same Q within 1e-12 relative (a sum over fewer modes may round differently);
- a system of at least :data:`acl.physics.coupling.SCALED_EIGH_MIN_MODES` bare modes solves the scaled standard
  eigenproblem instead of the Cholesky reduction: against the Cholesky solution within 1e-9 relative in frequency
  and Q, 1e-7 in the shares, and to every digit the hover and analyze print.

Designs: three capsules (the examples' size: the Cholesky reduction) and 88 capsules at seeded random
positions (264 bare modes; no repeated distance, so no shared Green-function table either).
"""
from __future__ import annotations

import re
from unittest import mock

import numpy as np
import pytest

from acl.analysis import acoustics as AC
from acl.lsp.document import check_text
from acl.lsp.hover import MIN_SHARE, hover
from acl.physics import constants as C, coupling as CP
from test_lsp_twin import DESIGN

SMALL = DESIGN          # three unlike capsules, one on a beam (the twin tests' design)


def mid_design(n: int = 88, seed: int = 23) -> str:
    """``n`` fixed capsules (the three stdlib designs in turn) at random positions in a 3 mm square, 80-400 um up,
    at least 150 um apart."""
    rng = np.random.default_rng(seed)
    pts: list = []
    while len(pts) < n:
        p = np.array([rng.uniform(0, 3000), rng.uniform(0, 3000), rng.uniform(80, 400)])
        if all(np.linalg.norm(p - q) >= 150 for q in pts):
            pts.append(p)
    out = SMALL.split("param gap")[0].splitlines()
    for i, (x, y, z) in enumerate(pts):
        out.append(f"capsule k{i} like capsules.design{1 + i % 3} {{ center = ({x:.1f} um, {y:.1f} um, {z:.1f} um) }}")
        out.append(f"fix k{i}")
    out += ["program scan {", "  drive 85 kHz @ 2 V for 100 ms", "  drive 170 kHz @ 2 V for 100 ms", "}"]
    return "\n".join(out) + "\n"


@pytest.fixture(scope="module")
def mid():
    snap = check_text(mid_design(), "/tmp/hover_mid.acl")
    assert snap.design is not None, [d.message for d in snap.diagnostics]
    return snap


def _filtered(design, cap) -> list:
    """The hover's selection as it was written before coupled_modes_of: every coupled mode of the design whose
    shares of the capsule's interfaces sum to MIN_SHARE or more."""
    return [m for m in AC.coupled_modes(design)
            if sum(v for k, v in m.shares.items() if k.split(".")[0] == cap.name) >= MIN_SHARE]


def _same(got: list, want: list) -> None:
    """The same modes: every field equal, Q within 1e-12 relative (mode_quality over a subset of the modes)."""
    assert len(got) == len(want)
    for a, b in zip(got, want):
        assert (a.frequency_hz, a.dominant_orifice, a.share, a.shares, a.phases, a.q_declared, a.notes) == \
            (b.frequency_hz, b.dominant_orifice, b.share, b.shares, b.phases, b.q_declared, b.notes)
        assert a.q == pytest.approx(b.q, rel=1e-12) and a.q_predicted == pytest.approx(b.q_predicted, rel=1e-12)
        assert _printed(a) == _printed(b)


def test_small_design_hover_modes_are_analyze_modes_exactly():
    from acl.analysis.report import analyze

    design = check_text(SMALL, "/tmp/hover_small.acl").design
    with mock.patch.object(CP, "_scaled_eigh", side_effect=AssertionError("a small system uses the Cholesky reduction")):
        rep = analyze(design)
        listed = 0
        for cap in design.capsules:
            mine = AC.coupled_modes_of(design, cap, MIN_SHARE)
            _same(mine, _filtered(design, cap))
            listed += len(mine)
            picked = [r for r in rep.coupled_modes
                      if sum(v for k, v in r["shares"].items() if k.split(".")[0] == cap.name) >= MIN_SHARE]
            assert [(m.frequency_hz, m.shares, f"{m.q:.1f}", f"{m.q_predicted:.1f}") for m in mine] == \
                [(r["frequency_hz"], r["shares"], f"{r['q']:.1f}", f"{r['q_predicted']:.1f}") for r in picked]
    assert listed >= 3          # each capsule takes part in a mode of its own at least


def test_scaled_eigensolver_equals_the_cholesky_reduction(mid, monkeypatch):
    design = mid.design
    system = AC._system(design)
    med = AC.medium_constants(design)
    phi, om, _ = CP._compact(system)
    assert om.size >= CP.SCALED_EIGH_MIN_MODES
    top = 2 * np.pi * 1.5 * AC._coupled_top(design)
    with mock.patch.object(CP, "_scaled_eigh", wraps=CP._scaled_eigh) as spy:
        fast = CP.coupled_modes(system, med.density, med.sound_speed, C.SUBSTRATE_REFLECTION, top)
    assert spy.call_count == 1
    monkeypatch.setattr(CP, "SCALED_EIGH_MIN_MODES", 10**9)
    whole = CP.coupled_modes(system, med.density, med.sound_speed, C.SUBSTRATE_REFLECTION, top)
    assert fast.omega.size == whole.omega.size == np.count_nonzero(whole.omega <= top) > 50
    np.testing.assert_allclose(fast.omega, whole.omega, rtol=1e-9)
    np.testing.assert_allclose(fast.quality, whole.quality, rtol=1e-9)
    np.testing.assert_allclose(fast.share, whole.share, rtol=0, atol=1e-7)
    sign = np.sign((fast.volume * whole.volume).sum(axis=0))
    np.testing.assert_allclose(fast.volume * sign, whole.volume, rtol=0, atol=1e-7 * np.abs(whole.volume).max())


def test_scaled_eigensolver_over_a_batch_axis():
    """Both solvers of diag(omega^2) q = w^2 M q on a batch of random mass matrices (I + a positive part)."""
    rng = np.random.default_rng(5)
    omega = rng.uniform(1.0, 30.0, (3, 40))
    a = rng.normal(size=(3, 40, 12))
    mass = np.eye(40) + 0.3 * a @ np.swapaxes(a, -1, -2)
    w1, q1 = CP._scaled_eigh(omega, mass)
    w0, q0 = CP._diagonal_eigh(omega, mass)
    np.testing.assert_allclose(w1, w0, rtol=1e-10)
    assert np.all(np.diff(w1, axis=-1) > 0)
    eye = np.swapaxes(q1, -1, -2) @ mass @ q1                      # mass-normalized
    np.testing.assert_allclose(eye, np.broadcast_to(np.eye(40), eye.shape), atol=1e-10)
    np.testing.assert_allclose((omega[:, :, None] ** 2) * q1, mass @ q1 * w1[:, None, :] ** 2, atol=1e-8 * 900)


def _printed(m) -> tuple:
    """A coupled mode's row as the hover prints it (f, Q, interfaces with their share and phase)."""
    parts = ", ".join(f"{k} {v:.0%} ({m.phases.get(k, 0.0):.0f} deg)" for k, v in m.shares.items() if v >= 0.05)
    return f"{m.frequency_hz / 1e3:.1f}", f"{m.q:.1f}", parts


def test_mid_design_hover_equals_analyze_to_its_digits(mid, monkeypatch):
    design = mid.design
    lines = mid.text.split("\n")
    caps = design.capsules
    with mock.patch.object(CP, "_scaled_eigh", wraps=CP._scaled_eigh) as spy:
        mine = {c.name: AC.coupled_modes_of(design, c, MIN_SHARE) for c in caps}
        shown = [c.name for c in caps if mine[c.name]][:6]
        texts = {name: hover(mid, next(i for i, ln in enumerate(lines) if ln.startswith(f"capsule {name} ")), 9)[0]
                 for name in shown}
    assert spy.call_count == 1                    # the fast path ran, once for all capsules
    assert sum(1 for v in mine.values() if v) >= 10
    for c in caps:                               # the modes of analyze's list, filtered
        _same(mine[c.name], _filtered(design, c))
    for name, text in texts.items():             # what the hover prints is analyze's numbers
        assert "with its neighbours" in text
        rows = re.findall(r"^\| \d+ \| ([\d.]+) \| ([\d.]+) \| (.*) \|$", text.split("with its neighbours")[-1], re.M)
        assert rows == [_printed(m) for m in mine[name][:6]], name
    # and analyze's numbers by the Cholesky reduction agree to the printed digits
    fast = {c.name: [_printed(m) for m in mine[c.name]] for c in caps}
    monkeypatch.setattr(CP, "SCALED_EIGH_MIN_MODES", 10**9)
    other = check_text(mid.text + "\n", "/tmp/hover_mid.acl").design      # a new design object: no cache
    assert {c.name: [_printed(m) for m in _filtered(other, c)] for c in caps} == fast


def test_phases_at_the_first_program_frequencies_equal_the_whole_programs_response():
    """The hover solves only the frequencies it shows (PHASE_FREQUENCIES): the same phases as the response at every
    program frequency (20 tones here, solved as one batch with the shared Green-function table)."""
    from acl.analysis.report import program_frequencies
    from acl.lsp.hover import PHASE_FREQUENCIES

    tones = "\n".join(f"  drive {60 + 7 * i} kHz @ 2 V for 10 ms" for i in range(20))
    text = SMALL.replace("  drive 125 kHz @ 2 V for dwell", tones)
    snap = check_text(text, "/tmp/hover_phases.acl")
    line = next(i for i, ln in enumerate(text.split("\n")) if ln.startswith("capsule c2"))
    got = re.search(r"volume vs drive: (.*)", hover(snap, line, 9)[0]).group(1)
    other = check_text(text, "/tmp/hover_phases.acl").design               # no cache shared with the hover's
    freqs = program_frequencies(other)
    assert len(freqs) == 20
    resp = AC.orifice_response(other, other.capsule("c2"), freqs)
    want = ", ".join(f"{f / 1e3:g} kHz: {np.degrees(np.angle(resp[j, 0])):.0f} deg"
                     for j, f in enumerate(freqs[:PHASE_FREQUENCIES]))
    assert got == want


@pytest.mark.studies
def test_every_capsule_of_the_5000_line_design_prints_the_cholesky_solutions_numbers(monkeypatch):
    """benchmarks/lsp.py's design (393 capsules on a lattice, 1,179 bare modes; near-degenerate modes 4.5e-6 apart):
    every capsule's listed coupled modes, as the hover prints them, from the scaled solver and the selection, equal
    analyze's list by the Cholesky reduction filtered by share."""
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location("acl_benchmark_check",
                                                  Path(__file__).resolve().parents[1] / "benchmarks" / "check.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    text = bench.generate(5000)
    fast = check_text(text, "/tmp/hover_big.acl").design
    with mock.patch.object(CP, "_scaled_eigh", wraps=CP._scaled_eigh) as spy:
        got = {c.name: [_printed(m) for m in AC.coupled_modes_of(fast, c, MIN_SHARE)] for c in fast.capsules}
    assert spy.call_count == 1 and len(fast.capsules) == 393
    monkeypatch.setattr(CP, "SCALED_EIGH_MIN_MODES", 10**9)
    slow = check_text(text + "\n", "/tmp/hover_big.acl").design
    assert got == {c.name: [_printed(m) for m in _filtered(slow, c)] for c in slow.capsules}
    assert sum(1 for v in got.values() if v) >= 10

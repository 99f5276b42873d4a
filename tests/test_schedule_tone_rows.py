"""Rows that each play one tone alone, solved as one batch (issue 23: the band cure's candidate readings):
acl.analysis.tones.force_rows_one_tone against the single-tone engine row by row, acl.schedule.gains
.model_forward_tones against model_forward_many tone by tone, and explain with the batch against explain without
it.  On the Fig. 3 module (examples/fig3_three_orifice.acl) with gain-table draws of its declared 30 %."""
from __future__ import annotations

import numpy as np
import pytest

from acl.analysis import tones as T
from acl.schedule import experiment
from acl.schedule import gains as G
from acl.schedule.bands import sample_designs

FREQS = [72.5e3, 128.5e3, 178.5e3, 100e3]


def test_rows_at_their_own_tones_are_the_single_tone_engine_bit_for_bit(fig3):
    rng = np.random.default_rng(3)
    c0 = np.array([np.asarray(c.center, float) for c in fig3.capsules])
    centres = c0[None] + rng.normal(0.0, 1e-6, (12,) + c0.shape)
    tone = rng.integers(0, len(FREQS), 12)
    amp = rng.uniform(0.5, 6.0, 12)
    g, s = T.drive_factors(fig3, FREQS)
    gain, scale = g[tone] * rng.uniform(0.7, 1.3, 12), np.broadcast_to(s, (12, s.size))
    got = T.force_rows_one_tone(fig3, centres, FREQS, tone, amp, gain, scale)
    for j in range(12):     # each row alone through the engine of its tone (acl.analysis.tones.force_batch_tones)
        one = T.force_batch_tones(fig3, centres[j:j + 1], [FREQS[tone[j]]], amp[j:j + 1, None], gain[j:j + 1, None],
                                  scale[j:j + 1])
        assert np.array_equal(got[j], one[0])
    assert np.abs(got).max() > 0


def test_model_forward_tones_is_model_forward_many_tone_by_tone(fig3, monkeypatch):
    """The same predictions as a loop over tones (1e-12 relative: BLAS sums a matrix product's row in an order that
    depends on the batch's row count, ~1e-16), from one batch (each waypoint's solve sees rows of every tone)."""
    designs = [fig3, *[d for _, d in sample_designs(fig3, 3, seed=2)]]
    volts = np.array([[0.8, 1.6, 3.2], [1.0, 2.0, 4.0], [0.5, 1.0, 2.0]])
    u = volts ** 2
    seen = []
    rows = T.force_rows_one_tone
    monkeypatch.setattr(T, "force_rows_one_tone",
                        lambda d, c, f, t, *a: seen.append(set(np.asarray(t).tolist())) or rows(d, c, f, t, *a))
    got = G.model_forward_tones(designs, "m", FREQS[:3], u)
    assert any(len(t) == 3 for t in seen)                       # rows of all three tones in one evaluation
    for k, f in enumerate(FREQS[:3]):
        loop = G.model_forward_many(designs, "m", [f], u[k][:, None])
        for a, b in zip(got[k], loop):
            assert np.all(np.isfinite(b)) and np.abs(b).max() > 1e-9
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-21)


def test_explain_with_the_tone_batch_proposes_the_same_readings(fig3):
    g = fig3
    from acl.schedule.compile import CompileOptions, compile_program

    sched = compile_program(g, "circle", CompileOptions(band_samples=4, resim_points=12))
    goal = sched.goals[0]
    idx = np.unique(np.linspace(0, len(goal.target_m) - 1, 12).astype(int))
    u, tg = (goal.amplitudes_v ** 2).T[:, idx], goal.target_m[idx]
    many = lambda ds, f, uu: G.model_forward_many(ds, "m", f, uu)          # noqa: E731
    loop = experiment.explain(g, many, "m", goal.frequencies_hz, u, tg)
    batch = experiment.explain(g, many, "m", goal.frequencies_hz, u, tg,
                               many_tones=lambda ds, f, uu: G.model_forward_tones(ds, "m", f, uu))
    a, b = loop["measurement"]["readings"], batch["measurement"]["readings"]
    assert [(r["frequency_hz"], r["voltage_v"]) for r in b] == [(r["frequency_hz"], r["voltage_v"]) for r in a]
    for x, y in zip(a, b):
        assert y["expected_displacement_m"] == pytest.approx(x["expected_displacement_m"], rel=1e-9)
    assert batch["measurement"]["expected_rms_p95_m"] == pytest.approx(loop["measurement"]["expected_rms_p95_m"],
                                                                       rel=1e-9)

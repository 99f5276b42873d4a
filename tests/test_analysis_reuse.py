"""Work the analysis and the compiler's forward batches share instead of repeating (issue 23): each reuse gives the
numbers of the computation it replaces, bit for bit."""
from __future__ import annotations

import os

import numpy as np
import pytest

import acl
from acl.design.model import Drive, Tone

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
FIG3 = os.path.join(ROOT, "examples", "fig3_three_orifice.acl")
PAIR = os.path.join(ROOT, "examples", "fig4_facing_pair.acl")


@pytest.fixture(scope="module")
def fig3():
    return acl.load(FIG3)


def test_a_pair_table_after_the_engine_moved_on_equals_a_fresh_one():
    """pair_table at rest, once from the engine's own rest forces and once after another drive replaced the engine
    (only the Bjerknes pair sum evaluated again): identical arrays."""
    from acl.analysis import acoustics

    d = acl.load(PAIR)
    a = Drive(tones=(Tone(frequency=125e3, amplitude=3.0),))
    b = Drive(tones=(Tone(frequency=90e3, amplitude=2.0),))
    first = acoustics.pair_table(d, a)
    acoustics.force_model(d, None, b)                       # the engine cache now holds drive b
    eng = acoustics._engine(d, a)
    assert not eng._rest                                    # a new engine: its rest forces are not computed ...
    again = acoustics.pair_table(d, a)
    assert not eng._rest                                    # ... and the pair table did not need them
    for name in ("force_on_a", "attraction", "phase_difference", "distance", "critical_distance"):
        np.testing.assert_array_equal(getattr(again, name), getattr(first, name))


def test_forward_rows_with_equal_drive_factors_are_solved_once_and_mapped_back(fig3):
    """model_forward_many: gain-table moves that no tone interpolates from give the nominal's prediction; the others
    their own, as when each design is solved alone."""
    from acl.analysis import tones
    from acl.schedule import experiment
    from acl.schedule.gains import model_forward_many

    f = [128.5e3]
    u = np.array([[4.0], [16.0], [36.0]])
    dirs, _ = experiment.directions(fig3)
    moved = [make(x) for *_, make in dirs for x in (0.5, -0.5)]
    g0 = tones.drive_factors(fig3, f)[0]
    same = [d for d in moved if np.array_equal(tones.drive_factors(d, f)[0], g0)]
    diff = [d for d in moved if not np.array_equal(tones.drive_factors(d, f)[0], g0)]
    assert same and diff
    got = model_forward_many([fig3, *same, *diff], "m", f, u)
    alone = model_forward_many([fig3], "m", f, u)[0]
    assert np.all(np.isfinite(alone))
    for g in got[:1 + len(same)]:
        np.testing.assert_array_equal(g, alone)
    for d, g in zip(diff, got[1 + len(same):]):
        np.testing.assert_array_equal(g, model_forward_many([d], "m", f, u)[0])
        assert not np.array_equal(g, alone)

"""Low-crest-factor phases (acl.schedule.phases)."""
import numpy as np
import pytest

from acl.schedule.phases import (analog_peaks, analog_period, choose_phases, common_period_samples,
                                 group_peaks, sampled_peak)

F = (85e3, 125e3, 170e3)
FS = 2e6


def test_tones_on_a_5_khz_grid_repeat_every_400_samples_at_2_msps():
    assert common_period_samples(F, FS) == 400


def test_incommensurate_tones_have_no_short_common_period():
    assert common_period_samples((85e3, 125e3 + np.pi), FS, max_samples=1 << 16) is None


def _dense_peak(freqs, amps, phi, period, n=400_001):
    t = np.linspace(0.0, period, n)
    return float(np.max(np.abs(np.asarray(amps) @ np.sin(2 * np.pi * np.outer(freqs, t) + np.asarray(phi)[:, None]))))


def test_chosen_phases_lower_the_analog_peak_below_zero_phases_and_the_amplitude_sum():
    f = (100e3, 105e3, 110e3, 115e3, 120e3)          # phases matter here (common period 200 us)
    amps = np.ones(5)
    phi, peak = choose_phases(f, amps, FS)
    assert peak < 0.6 * _dense_peak(f, amps, np.zeros(5), 2e-4)      # zero phases: ~5 V
    assert peak < 0.6 * amps.sum()
    dense = _dense_peak(f, amps, phi, 2e-4)
    assert dense <= peak <= dense + 1e-3 * amps.sum()                # the analog peak, bounded


def test_analog_peak_bounds_the_reconstructed_signal_where_the_samples_miss_the_crest():
    # issue 11: at 10 samples per cycle the sampled peak understates the analog peak by up to 4.9 %
    f = (89e3, 141.5e3, 184e3)
    rng = np.random.default_rng(3)
    for _ in range(5):
        amps, phi = rng.uniform(0.1, 1.0, 3), rng.uniform(0, 2 * np.pi, 3)
        (bound,) = analog_peaks(f, phi, amps[None])
        dense = _dense_peak(f, amps, phi, analog_period(f), n=2_000_001)
        assert dense <= bound <= dense + 2e-4 * amps.sum()
    crest_between_samples = np.pi / 2 + np.pi / 10
    sampled = sampled_peak((184e3,), [1.0], [crest_between_samples], 1.84e6, 10)
    assert sampled == pytest.approx(np.cos(np.pi / 10))             # 0.951: 4.9 % low
    assert analog_peaks((184e3,), [crest_between_samples], [[1.0]])[0] == 1.0


def test_explicit_phases_are_kept_and_only_free_ones_searched():
    f = (100e3, 105e3, 110e3)
    phi, _ = choose_phases(f, np.ones(3), FS, fixed=[True, True, True], start=[0.0, 0.0, 0.0])
    assert np.all(phi == 0.0)
    phi, _ = choose_phases(f, np.ones(3), FS, fixed=[True, False, False], start=[1.0, 0.0, 0.0])
    assert phi[0] == 1.0


def test_group_peaks_match_direct_evaluation():
    amps = np.array([[1.0, 0.5, 0.2], [0.1, 2.0, 0.3]])
    phi = np.array([0.0, 1.0, 2.0])
    got = group_peaks(F, phi, amps, FS)
    want = [_dense_peak(F, a, phi, analog_period(F)) for a in amps]
    assert np.all(got >= want) and np.allclose(got, want, rtol=2e-4)

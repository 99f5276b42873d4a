"""Low-crest-factor phases (acl.schedule.phases)."""
import numpy as np

from acl.schedule.phases import choose_phases, common_period_samples, group_peaks, sampled_peak

F = (85e3, 125e3, 170e3)
FS = 2e6


def test_tones_on_a_5_khz_grid_repeat_every_400_samples_at_2_msps():
    assert common_period_samples(F, FS) == 400


def test_incommensurate_tones_have_no_short_common_period():
    assert common_period_samples((85e3, 125e3 + np.pi), FS, max_samples=1 << 16) is None


def test_chosen_phases_lower_the_peak_below_zero_phases_and_the_amplitude_sum():
    amps = np.array([1.0, 1.0, 1.0])
    phi, peak = choose_phases(F, amps, FS)
    zero = sampled_peak(F, amps, np.zeros(3), FS, 400)
    assert peak < zero
    assert peak < 0.95 * amps.sum()
    assert np.isclose(peak, sampled_peak(F, amps, phi, FS, 400))


def test_group_peaks_match_direct_evaluation():
    amps = np.array([[1.0, 0.5, 0.2], [0.1, 2.0, 0.3]])
    phi = np.array([0.0, 1.0, 2.0])
    got = group_peaks(F, phi, amps, FS)
    want = [sampled_peak(F, a, phi, FS, 400) for a in amps]
    assert np.allclose(got, want)

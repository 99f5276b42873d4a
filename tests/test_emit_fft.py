"""The written waveform carries exactly the scheduled tones (FFT), within the limit, without clicks."""
import numpy as np
import pytest

from acl.emit.output import emit
from acl.emit.writers import read_wav_float32
from acl.schedule.model import Schedule, ScheduledTone, Segment
from acl.schedule.phases import common_period_samples


def steady_window(seg, ramp_s, fs, freqs):
    """Sample range inside the segment, clear of the crossfades, a whole number of common periods."""
    period = common_period_samples(freqs, fs) if freqs else 1
    a = int(np.ceil((seg.start_s + ramp_s) * fs))
    b = int(np.floor((seg.end_s - ramp_s) * fs))
    n = (b - a) // period * period
    assert n >= period, "segment too short for an exact FFT"
    return a, a + n


def tone_amplitudes(x, fs, freqs):
    spec = np.fft.rfft(x) / x.size * 2
    bins = np.fft.rfftfreq(x.size, 1 / fs)
    idx = [int(np.argmin(np.abs(bins - f))) for f in freqs]
    return np.abs(spec[idx]), spec, idx


def assert_segments_match(volts, schedule, fs, rel=0.01):
    floor = 1e-5 * schedule.full_scale_v
    for seg in schedule.segments:
        if any(t.sweep for t in seg.tones):
            continue
        freqs = [t.frequency_hz for t in seg.tones]
        a, b = steady_window(seg, schedule.ramp_s, fs, freqs)
        x = volts[a:b]
        if not freqs:
            assert np.max(np.abs(x)) < floor
            continue
        amps, spec, idx = tone_amplitudes(x, fs, freqs)
        want = np.array([t.amplitude_v for t in seg.tones])
        assert np.all(np.abs(amps - want) <= rel * want + floor), (seg, amps, want)
        rest = spec.copy()
        rest[idx] = 0
        assert np.sqrt(np.sum(np.abs(rest) ** 2)) <= rel * np.linalg.norm(want) + floor   # nothing else


def drive_schedule(ramp=1e-3):
    segs = [Segment(0.00, 0.02, (ScheduledTone(85e3, 2.0, 0.3), ScheduledTone(125e3, 1.0, 1.0)), 0),
            Segment(0.02, 0.04, (ScheduledTone(85e3, 3.0, 0.3), ScheduledTone(170e3, 0.5, 2.0)), 1),
            Segment(0.04, 0.05, (), 2),
            Segment(0.05, 0.07, (ScheduledTone(40e3, 1.0, 0.0, 160e3, "linear"),), 3),
            Segment(0.07, 0.09, (ScheduledTone(125e3, 5.0, 0.0),), 4)]
    return Schedule("t", segs, [], max_voltage_v=10.0, full_scale_v=10.0, ramp_s=ramp, sample_rate_hz=2e6)


def test_each_drive_segment_of_the_wav_has_exactly_its_tones_and_amplitudes(tmp_path):
    s = drive_schedule()
    emit(s, str(tmp_path / "out"), ("wav",), 2e6)
    x, fs = read_wav_float32(str(tmp_path / "out" / "waveform.wav"))
    assert fs == 2_000_000
    assert_segments_match(x.astype(float) * s.full_scale_v, s, fs)


def test_chirp_segment_sweeps_its_band(tmp_path):
    s = drive_schedule()
    emit(s, str(tmp_path / "out"), ("npy",), 2e6)
    x = np.load(tmp_path / "out" / "waveform.npy")
    seg = x[int(0.051 * 2e6):int(0.069 * 2e6)]
    spec = np.abs(np.fft.rfft(seg))
    bins = np.fft.rfftfreq(seg.size, 1 / 2e6)
    band = (bins > 45e3) & (bins < 155e3)
    assert spec[band].sum() > 0.95 * spec.sum()


def max_jump_bound(schedule, fs):
    """Largest possible sample step of smooth tones plus the crossfade term, per sample."""
    slope = max(sum(2 * np.pi * t.max_frequency_hz * t.amplitude_v for t in s.tones) for s in schedule.segments)
    peak = max(sum(t.amplitude_v for t in s.tones) for s in schedule.segments)
    h = schedule.ramp_s / 2
    return slope / fs + (np.pi / (4 * h * fs)) * 2 * peak if h > 0 else slope / fs


def phase_flip_schedule(ramp=1e-3):
    """40 kHz at 5 V whose phase flips by pi where the sine is at its crest: a 10 V step unless ramped."""
    b = 0.01 + 1 / (4 * 40e3)
    segs = [Segment(0.0, b, (ScheduledTone(40e3, 5.0, 0.0),), 0),
            Segment(b, 0.02, (ScheduledTone(40e3, 5.0, np.pi),), 1)]
    return Schedule("flip", segs, [], max_voltage_v=10.0, full_scale_v=10.0, ramp_s=ramp)


@pytest.mark.parametrize("make", [drive_schedule, phase_flip_schedule])
def test_segment_changes_are_click_free(tmp_path, make):
    s = make()
    r = emit(s, str(tmp_path / "out"), ("wav",), 2e6)
    assert r.stats.max_jump_v <= max_jump_bound(s, 2e6)


def test_without_ramps_a_phase_flip_clicks(tmp_path):
    r = emit(phase_flip_schedule(ramp=0.0), str(tmp_path / "out"), ("wav",), 2e6)
    assert r.stats.max_jump_v > 5 * max_jump_bound(phase_flip_schedule(), 2e6)


def test_compiled_path_program_segments_carry_their_tones_within_one_percent(tmp_path):
    from test_schedule_fig3 import FIG3, fake_calibration

    import acl
    from acl.schedule.compile import CompileOptions, compile_program

    design = acl.loads(FIG3, filename="fig3.acl")
    s = compile_program(design, "circle", CompileOptions(calibration=fake_calibration()))
    fs = s.sample_rate_hz
    r = emit(s, str(tmp_path / "out"), ("wav",))
    x, _ = read_wav_float32(str(tmp_path / "out" / "waveform.wav"))
    assert_segments_match(x.astype(float) * s.full_scale_v, s, fs)
    assert r.stats.peak_v <= s.max_voltage_v
    assert np.max(np.abs(x)) <= 1.0


def test_peak_of_the_file_equals_the_scheduled_segment_peaks(tmp_path):
    s = drive_schedule()
    from acl.schedule.compile import _choose_all_phases

    _choose_all_phases(s, 2e6)
    r = emit(s, str(tmp_path / "out"), ("npy",), 2e6)
    scheduled = max(seg.peak_v for seg in s.segments)
    assert r.stats.peak_v <= scheduled * (1 + 1e-6)
    assert r.stats.peak_v >= 0.98 * scheduled


def test_crossfades_form_a_partition_of_unity():
    """Many short segments of one unchanged tone render exactly as that tone (weights sum to 1)."""
    from hypothesis import given, settings
    from hypothesis import strategies as st

    from acl.emit.render import render_chunks

    @settings(max_examples=25, deadline=None)
    @given(st.lists(st.floats(min_value=2e-4, max_value=5e-3), min_size=2, max_size=12),
           st.floats(min_value=0.0, max_value=4e-3))
    def check(durations, ramp):
        edges = np.concatenate([[0.0], np.cumsum(durations)])
        tone = (ScheduledTone(40e3, 1.0, 0.7),)
        segs = [Segment(a, b, tone, i) for i, (a, b) in enumerate(zip(edges[:-1], edges[1:]))]
        s = Schedule("u", segs, [], 1.0, 1.0, ramp_s=ramp)
        fs = 1e6
        x = np.concatenate([c for _, c in render_chunks(s, fs, chunk=1000)])
        n = np.arange(x.size)
        pure = np.sin(2 * np.pi * 40e3 * n / fs + 0.7)
        h0 = min(ramp / 2, durations[0] / 2)
        h1 = min(ramp / 2, durations[-1] / 2)
        inner = (n / fs >= 2 * h0) & (n / fs <= edges[-1] - 2 * h1)
        assert np.allclose(x[inner], pure[inner], atol=1e-9)

    check()


def test_zero_ramp_boundary_sample_is_not_dropped():
    """Regression (found by hypothesis): with no ramp, a boundary sample that float rounding puts in
    the next segment must still carry the tone (it used to render as 0)."""
    from acl.emit.render import render_chunks

    durations = [0.001, 0.0002, 0.00390625]
    edges = np.concatenate([[0.0], np.cumsum(durations)])
    tone = (ScheduledTone(40e3, 1.0, 0.7),)
    segs = [Segment(a, b, tone, i) for i, (a, b) in enumerate(zip(edges[:-1], edges[1:]))]
    s = Schedule("u", segs, [], 1.0, 1.0, ramp_s=0.0)
    fs = 1e6
    x = np.concatenate([c for _, c in render_chunks(s, fs, chunk=1000)])
    n = np.arange(x.size)
    assert np.allclose(x, np.sin(2 * np.pi * 40e3 * n / fs + 0.7), atol=1e-9)

"""Output files: atomic directory, schema-valid schedule.json, formats that agree, segment table."""
import csv
import json
import os

import numpy as np
import pytest

from acl.diagnostics import DiagnosticError
from acl.emit import output as output_mod
from acl.emit.output import emit
from acl.emit.schedule_json import load_schema
from acl.emit.writers import read_wav_float32
from acl.schedule.model import GoalReport, Schedule, ScheduledTone, Segment


def schedule():
    segs = [Segment(0.0, 0.01, (ScheduledTone(85e3, 2.0, 0.3), ScheduledTone(125e3, 1.0, 1.0)), 0, "g"),
            Segment(0.01, 0.02, (ScheduledTone(85e3, 2.0, 0.3), ScheduledTone(125e3, 1.0, 1.0)), 0, "g"),
            Segment(0.02, 0.03, (), 1)]
    goal = GoalReport("g", "follow", 0, 0.0, 0.02, (85e3, 125e3), model="m", rms_error_m=1e-9,
                      max_error_m=2e-9)
    return Schedule("p", segs, [goal], max_voltage_v=10.0, full_scale_v=10.0, ramp_s=1e-3,
                    sample_rate_hz=1.25e6)


def test_schedule_json_is_valid_against_the_published_schema(tmp_path):
    import jsonschema

    emit(schedule(), str(tmp_path / "out"), ("wav",))
    data = json.loads((tmp_path / "out" / "schedule.json").read_text())
    jsonschema.validate(data, load_schema())
    assert data["version"] == "1.2"          # 1.2: steps counted from 1
    assert data["full_scale_v"] == 10.0 and data["sample_rate_hz"] == 1.25e6
    assert data["goals"][0]["rms_error_um"] == pytest.approx(1e-3)


def test_wav_npy_and_csv_hold_the_same_samples_in_their_documented_scales(tmp_path):
    emit(schedule(), str(tmp_path / "out"), ("wav", "npy", "csv"), 1.25e6)
    wav, fs = read_wav_float32(str(tmp_path / "out" / "waveform.wav"))
    npy = np.load(tmp_path / "out" / "waveform.npy")
    tv = np.loadtxt(tmp_path / "out" / "waveform-samples.csv", delimiter=",", skiprows=1)
    assert fs == 1_250_000 and wav.size == npy.size == tv.shape[0] == 37500
    assert np.allclose(wav * 10.0, npy, atol=1e-6)            # wav = volts / full scale
    assert np.allclose(tv[:, 1], npy, atol=1e-5)
    assert np.allclose(tv[:, 0], np.arange(npy.size) / 1.25e6)


def test_wav_header_is_ieee_float_readable_by_scipy(tmp_path):
    from scipy.io import wavfile

    emit(schedule(), str(tmp_path / "out"), ("wav",), 1.25e6)
    fs, data = wavfile.read(tmp_path / "out" / "waveform.wav")
    assert fs == 1_250_000 and data.dtype == np.float32


def test_segment_table_merges_identical_segments_and_lists_each_tone(tmp_path):
    emit(schedule(), str(tmp_path / "out"), ("npy",))
    rows = list(csv.DictReader(open(tmp_path / "out" / "segments.csv")))
    assert [(r["frequency_hz"], float(r["duration_s"])) for r in rows] == [
        ("85000", 0.02), ("125000", 0.02), ("", 0.01)]


def no_temp_dirs(parent):
    return not [n for n in os.listdir(parent) if n.startswith(".acl-compile-")]


def test_a_failure_while_writing_leaves_no_output_and_no_temp_dir(tmp_path, monkeypatch):
    class Broken(output_mod.WRITERS["wav"][0]):
        def write(self, n0, volts):
            raise OSError(28, "No space left on device")

    monkeypatch.setitem(output_mod.WRITERS, "wav", (Broken, "waveform.wav"))
    with pytest.raises(OSError):
        emit(schedule(), str(tmp_path / "out"), ("wav",))
    assert not (tmp_path / "out").exists()
    assert no_temp_dirs(tmp_path)


def test_keyboard_interrupt_during_render_cleans_up(tmp_path):
    def interrupt(done, total):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        emit(schedule(), str(tmp_path / "out"), ("wav",), progress=interrupt)
    assert not (tmp_path / "out").exists()
    assert no_temp_dirs(tmp_path)


def test_an_output_folder_holding_files_acl_did_not_write_is_refused_and_left_alone(tmp_path):
    # issue 11: an output folder holds one compile, nothing else; a user file is never deleted
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    with pytest.raises(DiagnosticError) as exc:
        emit(schedule(), str(out), ("wav",))
    d = exc.value.diagnostics[0]
    assert d.code == "E-EMIT-OUTPUT" and "notes.txt" in d.message and str(d.span) == "<--output>:1:1"
    assert os.listdir(out) == ["notes.txt"] and (out / "notes.txt").read_text() == "mine"
    assert no_temp_dirs(tmp_path)


def test_reusing_an_output_folder_replaces_the_previous_compile_without_stale_files(tmp_path):
    out = tmp_path / "out"
    emit(schedule(), str(out), ("wav", "npy", "csv"))
    assert {"waveform.npy", "waveform-samples.csv"} <= set(os.listdir(out))
    emit(schedule(), str(out), ("wav",))
    # before: waveform.npy and the csv of the first compile stayed beside the new schedule.json
    assert sorted(os.listdir(out)) == ["schedule.json", "segments.csv", "waveform.wav"]
    assert json.loads((out / "schedule.json").read_text())["files"]["wav"] == "waveform.wav"


def test_a_previous_compile_whose_manifest_was_tampered_with_cannot_delete_other_files(tmp_path):
    out = tmp_path / "out"
    emit(schedule(), str(out), ("wav",))
    data = json.loads((out / "schedule.json").read_text())
    data["files"]["evil"] = "../victim.txt"
    (out / "schedule.json").write_text(json.dumps(data))
    (tmp_path / "victim.txt").write_text("keep")
    emit(schedule(), str(out), ("npy",))
    assert (tmp_path / "victim.txt").read_text() == "keep"
    assert sorted(os.listdir(out)) == ["schedule.json", "segments.csv", "waveform.npy"]
    assert no_temp_dirs(tmp_path)


@pytest.mark.parametrize("formats,rate,code", [(("wav", "mp3"), 1.25e6, "E-EMIT-FORMAT"),
                                               (("wav",), 200e3, "E-EMIT-RATE"),
                                               (("wav",), 1.25e6 + 0.5, "E-EMIT-RATE")])
def test_bad_options_are_diagnostics_and_write_nothing(tmp_path, formats, rate, code):
    with pytest.raises(DiagnosticError) as exc:
        emit(schedule(), str(tmp_path / "out"), formats, rate)
    assert exc.value.diagnostics[0].code == code
    assert os.listdir(tmp_path) == []


def test_output_path_that_is_a_file_is_a_diagnostic(tmp_path):
    (tmp_path / "out").write_text("x")
    with pytest.raises(DiagnosticError) as exc:
        emit(schedule(), str(tmp_path / "out"), ("wav",))
    assert exc.value.diagnostics[0].code == "E-EMIT-OUTPUT"
    assert (tmp_path / "out").read_text() == "x"


def test_a_wav_beyond_4_gib_is_refused_before_writing(tmp_path):
    long = Schedule("p", [Segment(0.0, 600.0, (ScheduledTone(100e3, 1.0),), 0)], [], 10.0, 10.0)
    with pytest.raises(DiagnosticError) as exc:
        emit(long, str(tmp_path / "out"), ("wav",), 2e6)
    assert exc.value.diagnostics[0].code == "E-EMIT-SIZE"
    assert os.listdir(tmp_path) == []

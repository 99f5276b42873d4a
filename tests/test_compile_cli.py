"""`acl compile` end to end: files written on success, diagnostics and nothing written otherwise."""
import json
import os

import pytest

from acl.cli import main

DESIGN = """\
import stdlib.capsules
import stdlib.beams
import stdlib.media
import stdlib.transducers

use medium media.pbs
use transducer transducers.contact_piezo

param r = 1 um

beam arm like beams.cantilever50 { clamp = (0 um, 0 um, 0 um) }
capsule module like capsules.prism3 { }
mount module on arm.tip

program circle {
  follow module along circle(radius = r, center = (0.2 um, 0 um)) in 0.3 s
}
program tones {
  drive 85 kHz @ 3 V + 125 kHz @ 2 V for 20 ms
  pause 5 ms
}
"""

SWEEP = "# voltage: 10 V\\nfrequency [kHz], dx [um], dy [um]\\n"


@pytest.fixture
def design(tmp_path):
    p = tmp_path / "fig3.acl"
    p.write_text(DESIGN)
    return str(p)


def run(*args):
    return main(["compile", *args])


def test_compiles_a_path_program_into_schedule_waveform_and_table(design, tmp_path, capsys):
    out = tmp_path / "out"
    assert run(design, "--program", "circle", "-o", str(out)) == 0
    assert sorted(os.listdir(out)) == ["schedule.json", "segments.csv", "waveform.wav"]
    data = json.loads((out / "schedule.json").read_text())
    assert data["goals"][0]["rms_error_um"] is not None
    assert "acl compile: program" in capsys.readouterr().err      # the summary table


def test_formats_and_plot_are_written_when_asked(design, tmp_path):
    out = tmp_path / "out"
    assert run(design, "--program", "circle", "-o", str(out), "--format", "npy,csv", "--plot") == 0
    names = set(os.listdir(out))
    assert {"waveform.npy", "waveform-samples.csv", "goal-step1.png"} <= names and "waveform.wav" not in names


def test_sample_rate_option_reaches_the_wav_header(design, tmp_path):
    from acl.emit.writers import read_wav_float32

    assert run(design, "--program", "tones", "-o", str(tmp_path / "o"), "--sample-rate", "1.5MHz") == 0
    _, fs = read_wav_float32(str(tmp_path / "o" / "waveform.wav"))
    assert fs == 1_500_000


@pytest.mark.parametrize("extra,code", [
    (["--program", "nope"], "E-COMPILE-PROGRAM"),
    ([], "E-COMPILE-PROGRAM"),                                   # two programs, none chosen
    (["--program", "tones", "--format", "mp3"], "E-COMPILE-FORMAT"),
    (["--program", "tones", "--sample-rate", "200k"], "E-EMIT-RATE"),
    (["--program", "tones", "--sample-rate", "fast"], "E-COMPILE-RATE"),
])
def test_bad_options_exit_2_with_a_diagnostic_and_write_nothing(design, tmp_path, capsys, extra, code):
    out = tmp_path / "out"
    assert run(design, "-o", str(out), *extra) == 2
    assert code in capsys.readouterr().err
    assert not out.exists()


def test_infeasible_goal_exits_1_names_it_and_writes_nothing(design, tmp_path, capsys):
    out = tmp_path / "out"
    assert run(design, "--program", "circle", "--set", "r=60um", "-o", str(out)) == 1
    err = capsys.readouterr().err
    assert "E-SCHED-INFEASIBLE" in err and "waypoint" in err and "follow module" in err
    assert not out.exists()
    assert not [n for n in os.listdir(tmp_path) if n.startswith(".acl-")]


def test_malformed_calibration_csv_points_at_file_row_and_column(design, tmp_path, capsys):
    sweep = tmp_path / "sweep.csv"
    sweep.write_text("# voltage: 10 V\nfrequency [kHz], dx [um], dy [um]\n40, 1, 0\n41, 1, x\n")
    assert run(design, "--program", "circle", "--calibration", str(sweep), "-o", str(tmp_path / "o")) == 2
    assert f"{sweep}:4:8" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_diagnostics_can_be_json(design, tmp_path, capsys):
    assert run(design, "--program", "nope", "-o", str(tmp_path / "o"), "--diagnostics", "json") == 2
    data = json.loads(capsys.readouterr().out)
    assert data["diagnostics"][0]["code"] == "E-COMPILE-PROGRAM"


def test_compile_does_not_import_heavy_modules_for_a_bad_option(design, tmp_path):
    import subprocess
    import sys

    code = ("import sys; from acl.cli import main; "
            f"rc = main(['compile', {design!r}, '--format', 'mp3', '-o', {str(tmp_path / 'o')!r}]); "
            "print(rc, 'cvxpy' in sys.modules, 'matplotlib' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout.split()
    assert out == ["2", "False", "False"]


def test_matplotlib_is_imported_only_for_plots(design, tmp_path):
    import subprocess
    import sys

    code = ("import sys; from acl.cli import main; "
            f"rc = main(['compile', {design!r}, '--program', 'tones', '-o', {str(tmp_path / 'o')!r}]); "
            "print(rc, 'matplotlib' in sys.modules, 'cvxpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout.split()
    assert out == ["0", "False", "False"]         # a drive-only program needs no solver either


def test_non_positive_tolerance_is_an_option_diagnostic(design, tmp_path, capsys):
    assert run(design, "--program", "tones", "--tolerance", "0", "-o", str(tmp_path / "o")) == 2
    assert "E-COMPILE-OPTION" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_unwritable_output_is_an_io_diagnostic(design, tmp_path, capsys, monkeypatch):
    from acl.emit import output as output_mod

    def no_space(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(output_mod, "write_segments_csv", no_space)
    assert run(design, "--program", "tones", "-o", str(tmp_path / "o")) == 2
    assert "E-COMPILE-IO" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()

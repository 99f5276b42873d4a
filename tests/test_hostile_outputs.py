"""Outputs that would destroy inputs (found by a hostile pass over every subcommand's output options).

Before:

* `acl fit D.acl data.csv --report FOLDER` replaced FOLDER as a whole: it renamed any existing folder
  away and deleted it, with the user's files in it (the design and the data too: `--report .`);
* `acl fit --calibrated D.acl` wrote a design that extends itself over the design, `--calibrated
  data.csv` wrote it over the data;
* `acl synth D.acl -o D.acl` wrote the CSV over the design (and `--schedule S -o S` over the schedule);
* `acl tune -o base.acl` of a design that extends base.acl replaced base.acl (only DESIGN itself was
  refused); `acl sweep -o gain.csv` replaced a gain table the design reads;
* `acl fit --calibrated FOLDER --report NEW` wrote the report, then failed: a partial output.

Each is now refused before anything is written: a code, the option as location, exit 2, every input
byte for byte as it was.
"""
from __future__ import annotations

import hashlib
import os
import shutil

import pytest

from acl.cli import main

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
EX = os.path.join(ROOT, "examples")
DATA = os.path.join(ROOT, "samples")
HOSTILE = os.path.join(ROOT, "tests", "hostile", "inputs")


def _snapshot(folder):
    out = {}
    for base, _, files in os.walk(folder):
        for f in files:
            p = os.path.join(base, f)
            with open(p, "rb") as fh:
                out[os.path.relpath(p, folder)] = hashlib.sha256(fh.read()).hexdigest()
    return out


@pytest.fixture
def work(tmp_path):
    """A folder holding a design, its data and an unrelated file of the user's."""
    shutil.copy(os.path.join(DATA, "fit_cantilever.acl"), tmp_path)
    shutil.copy(os.path.join(HOSTILE, "data_ok.csv"), tmp_path)
    (tmp_path / "notes.txt").write_text("the user's own notes\n")
    return tmp_path


def _refused(capsys, argv, code, where, folder):
    before = _snapshot(folder)
    rc = main(argv)
    err = capsys.readouterr()
    text = err.out + err.err
    assert rc == 2, text
    assert f"{where}:1:1: error[{code}]" in text, text
    assert "Traceback" not in text and "E-INTERNAL" not in text
    assert _snapshot(folder) == before                # nothing written, nothing removed


def test_fit_report_into_a_folder_of_the_users_files_is_refused(work, capsys):
    d, csv = str(work / "fit_cantilever.acl"), str(work / "data_ok.csv")
    _refused(capsys, ["fit", d, csv, "--free", "gamma", "--report", str(work), "-q"], "E601", "<--report>", work)
    assert (work / "notes.txt").read_text() == "the user's own notes\n"


def test_fit_report_replaces_its_own_previous_report(work, capsys):
    d, csv = str(work / "fit_cantilever.acl"), str(work / "data_ok.csv")
    rep = work / "rep"
    assert main(["fit", d, csv, "--free", "gamma", "--report", str(rep), "-q"]) == 0
    assert sorted(os.listdir(rep)) == ["fit.png", "report.json", "residuals.png"]
    assert main(["fit", d, csv, "--free", "gamma", "--report", str(rep), "-q"]) == 0     # a report folder: replaced
    capsys.readouterr()


@pytest.mark.parametrize("target", ["fit_cantilever.acl", "data_ok.csv"])
def test_fit_calibrated_over_an_input_is_refused(work, capsys, target):
    d, csv = str(work / "fit_cantilever.acl"), str(work / "data_ok.csv")
    _refused(capsys, ["fit", d, csv, "--free", "gamma", "--calibrated", str(work / target), "-q"],
             "E-USAGE", "<--calibrated>", work)


def test_fit_calibrated_folder_fails_before_the_report_is_written(work, capsys):
    d, csv = str(work / "fit_cantilever.acl"), str(work / "data_ok.csv")
    (work / "cal").mkdir()
    _refused(capsys, ["fit", d, csv, "--free", "gamma", "--calibrated", str(work / "cal"), "--report",
                      str(work / "rep"), "-q"], "E601", "<--calibrated>", work)
    assert not (work / "rep").exists()


@pytest.mark.parametrize("option", ["--calibrated", "--report"])
def test_fit_empty_output_path_is_a_usage_error(work, capsys, option):
    """`--calibrated ""` wrote nothing and said nothing (an empty path read as no option)."""
    d, csv = str(work / "fit_cantilever.acl"), str(work / "data_ok.csv")
    _refused(capsys, ["fit", d, csv, "--free", "gamma", option, "", "-q"], "E-USAGE", f"<{option}>", work)


def test_synth_over_its_design_is_refused(work, capsys):
    d = str(work / "fit_cantilever.acl")
    _refused(capsys, ["synth", d, "-o", d, "--voltages", "0V..2V:3", "--frequencies", "125kHz"],
             "E-USAGE", "<--output>", work)


def test_synth_over_its_schedule_is_refused(tmp_path, capsys):
    for name in ("fig2_vertical_cantilever.acl", "fig2_stroke.acl"):
        shutil.copy(os.path.join(EX, name), tmp_path)
    out = tmp_path / "out"
    assert main(["compile", str(tmp_path / "fig2_stroke.acl"), "--program", "ramp", "-o", str(out), "-q",
                 "--allow-nonlinear"]) == 0
    capsys.readouterr()
    sched = str(out / "schedule.json")
    _refused(capsys, ["synth", str(tmp_path / "fig2_stroke.acl"), "--schedule", sched, "-o", sched],
             "E-USAGE", "<--output>", tmp_path)


def test_tune_over_a_file_the_design_extends_is_refused(tmp_path, capsys):
    shutil.copy(os.path.join(EX, "fig3_robust_radii.acl"), tmp_path)
    (tmp_path / "mine.acl").write_text('extends "fig3_robust_radii.acl"\n')
    _refused(capsys, ["tune", str(tmp_path / "mine.acl"), "--samples", "8", "--validate", "8",
                      "-o", str(tmp_path / "fig3_robust_radii.acl"), "-q"], "E-USAGE", "<--output>", tmp_path)


@pytest.mark.parametrize("extra", [["-o", ""], ["--no-write", "-o", "t.acl"]])
def test_tune_empty_or_contradicted_output_is_a_usage_error(tmp_path, capsys, extra, monkeypatch):
    """`-o ""` wrote the default path; `--no-write -o t.acl` silently wrote nothing."""
    shutil.copy(os.path.join(EX, "fig3_robust_radii.acl"), tmp_path)
    monkeypatch.chdir(tmp_path)
    _refused(capsys, ["tune", "fig3_robust_radii.acl", "--samples", "8", "--validate", "8", *extra],
             "E-USAGE", "<--output>", tmp_path)


def test_sweep_over_a_gain_table_the_design_reads_is_refused(tmp_path, capsys):
    with open(os.path.join(DATA, "sweep_cantilever.acl")) as fh:
        src = fh.read()
    (tmp_path / "gain.csv").write_text("frequency [kHz], gain [Pa/V]\n50, 1000\n125, 2000\n200, 1000\n")
    (tmp_path / "g.acl").write_text(src.replace(
        "use transducer transducers.contact_piezo",
        'transducer tg like transducers.contact_piezo { gain = csv("gain.csv") }\nuse transducer tg'))
    assert main(["check", str(tmp_path / "g.acl")]) == 0, capsys.readouterr()
    capsys.readouterr()
    _refused(capsys, ["sweep", str(tmp_path / "g.acl"), "--vary", "radius=9um..11um:2", "-o", str(tmp_path / "gain.csv")],
             "E-USAGE", "<--output>", tmp_path)


@pytest.mark.parametrize("argv, where", [
    (["sweep", "{D}/sweep_cantilever.acl", "--vary", "radius=9um..11um:99999999999999999999", "-o", "{T}/a.csv"], "<--vary>"),
    (["sweep", "{D}/sweep_cantilever.acl", "--vary", "radius=9um..11um:2", "--tolerance-scales", "", "-o", "{T}/a.csv"],
     "<--tolerance-scales>"),
    (["sweep", "{D}/sweep_cantilever.acl", "--vary", "radius=9um..11um:2", "--plot", "", "-o", "{T}/a.csv"], "<--plot>"),
    (["analyze", "--no-snap", "--plot", "", "{EX}/fig2_vertical_cantilever.acl"], "<--plot>"),
])
def test_option_values_that_were_ignored_or_overflowed(tmp_path, capsys, argv, where):
    """A grid of 1e20 points was E-INTERNAL (numpy: maximum allowed size exceeded); an empty
    --tolerance-scales or --plot was read as no option."""
    argv = [a.replace("{D}", DATA).replace("{EX}", EX).replace("{T}", str(tmp_path)) for a in argv]
    rc = main(argv)
    text = "".join(capsys.readouterr())
    assert rc == 2 and f"{where}:1:" in text and "error[E-USAGE]" in text, text
    assert "E-INTERNAL" not in text and not os.listdir(tmp_path)


@pytest.mark.parametrize("plot", ["blocker.txt/figs", "blocker.txt"])
def test_sweep_figures_that_cannot_be_written_leave_no_table(tmp_path, capsys, plot):
    """The table was written first, then the figures failed: exit 2 with the table left behind.  Now the
    figures are drawn into a temporary folder first; a failure writes neither."""
    (tmp_path / "blocker.txt").write_text("a file where a folder is asked for\n")
    before = _snapshot(tmp_path)
    rc = main(["sweep", os.path.join(DATA, "sweep_cantilever.acl"), "--vary", "radius=9um..11um:2",
               "-o", str(tmp_path / "a.csv"), "--plot", str(tmp_path / plot)])
    text = "".join(capsys.readouterr())
    assert rc == 2 and "<--plot>:1:1: error[E601]" in text, text
    assert _snapshot(tmp_path) == before and sorted(os.listdir(tmp_path)) == ["blocker.txt"]


def test_sweep_figures_and_table_are_written_together(tmp_path, capsys):
    rc = main(["sweep", os.path.join(DATA, "sweep_cantilever.acl"), "--vary", "radius=9um..11um:2",
               "-o", str(tmp_path / "a.csv"), "--plot", str(tmp_path / "figs"), "-q"])
    assert rc == 0, capsys.readouterr()
    assert (tmp_path / "a.csv").is_file() and any(n.endswith(".png") for n in os.listdir(tmp_path / "figs"))
    assert sorted(os.listdir(tmp_path)) == ["a.csv", "figs"]          # no temporary folder left


def test_analyze_figures_are_all_written_or_none(tmp_path, capsys):
    """A figure that could not be written (here a folder in its place) failed the command after the first
    figures were written; now they are drawn into a temporary folder and moved in together."""
    plots = tmp_path / "plots"
    (plots / "pair_left_right.png").mkdir(parents=True)
    rc = main(["analyze", "--no-snap", "-q", "--plot", str(plots), os.path.join(EX, "fig4_facing_pair.acl")])
    text = "".join(capsys.readouterr())
    assert rc == 2 and "<--plot>:1:1: error[E601]" in text, text
    assert sorted(os.listdir(plots)) == ["pair_left_right.png"] and sorted(os.listdir(tmp_path)) == ["plots"]
    (plots / "pair_left_right.png").rmdir()
    assert main(["analyze", "--no-snap", "-q", "--plot", str(plots), os.path.join(EX, "fig4_facing_pair.acl")]) == 0
    assert "modal_response.png" in os.listdir(plots) and sorted(os.listdir(tmp_path)) == ["plots"]

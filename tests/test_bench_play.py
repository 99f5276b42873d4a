"""acl play: the command stream of a compiled schedule, replayed on simulated instruments (pyvisa-sim).

Two SCPI dialects (samples/bench/*.yaml): a GW Instek AFG-2225 (the paper's generator; steps, one
channel per tone) and a Keysight 33522B (sequence of looped segments).  Every setting is read back.
"""
from __future__ import annotations

import json
import math
import os
import signal

import pytest

from acl.cli import main

HERE = os.path.dirname(__file__)
DATA = os.path.join(HERE, "..", "samples", "bench")
TWO = os.path.join(DATA, "two_drives.json")
AFG = ("afg2225.yaml", "USB0::0x2184::0x0049::SIM00001::INSTR", "afg2225")
KEY = ("keysight33522b.yaml", "USB0::0x2A8D::0x2C07::SIM00001::INSTR", "33522b")


def _sim(which):
    pyvisa = pytest.importorskip("pyvisa")
    pytest.importorskip("pyvisa_sim")
    yaml, address, _ = which
    rm = pyvisa.ResourceManager(os.path.join(DATA, yaml) + "@sim")
    inst = rm.open_resource(address)
    inst.write_termination = inst.read_termination = "\n"
    return inst


def _plan(path, key, amplifier="hva200", form=None):
    from acl.bench import chain, plan, schedule

    drives, meta = schedule.load(path)
    return plan.plan(drives, meta, chain.GENERATORS[key], chain.AMPLIFIERS[amplifier], form)


def _lines(stream):
    return [x for x in stream.splitlines() if not x.startswith("#")]


def _play(p, inst):
    from acl.bench.player import play

    now = [0.0]
    return play(p, inst, clock=lambda: now[0], sleep=lambda dt: now.__setitem__(0, now[0] + dt))


def _readbacks_equal(result):
    from acl.bench.player import agrees
    from acl.bench.plan import Setting

    for q, answer, expect in result.readbacks:
        tol = 0.5e-4 + 1e-9 if isinstance(expect, float) else 0.0
        assert agrees(answer, Setting("", q, expect, tol)), (q, answer, expect)
        if isinstance(expect, float):
            assert float(answer) == pytest.approx(expect, rel=1e-12, abs=1e-12), (q, answer, expect)


EXPECTED_AFG = """\
OUTP1 OFF|OUTP1?|OUTP2 OFF|OUTP2?|SOUR1:FUNC SIN|SOUR1:FUNC?|OUTP1:LOAD INF|OUTP1:LOAD?|SOUR1:DCO 0|SOUR1:DCO?|\
SOUR2:FUNC SIN|SOUR2:FUNC?|OUTP2:LOAD INF|OUTP2:LOAD?|SOUR2:DCO 0|SOUR2:DCO?|SYST:ERR?|\
SOUR1:FREQ 125000|SOUR1:FREQ?|SOUR1:AMP 0.4|SOUR1:AMP?|OUTP1 ON|OUTP1?|\
SOUR1:AMP 0.2|SOUR1:AMP?|SOUR2:FREQ 85000|SOUR2:FREQ?|SOUR2:AMP 0.3|SOUR2:AMP?|OUTP2 ON|OUTP2?|\
OUTP1 OFF|OUTP1?|OUTP2 OFF|OUTP2?|\
SOUR1:AMP 0.4|SOUR1:AMP?|OUTP1 ON|OUTP1?|SYST:ERR?|\
OUTP1 OFF|OUTP1?|OUTP2 OFF|OUTP2?""".split("|")


def test_afg_stream_is_exact_and_read_back():
    """Two drives and a pause on the AFG-2225 through the HVA200 (gain 20): Vpp = 2 x peak / 20 per
    tone; 125 kHz stays on channel 1 when 85 kHz joins; a pause switches the outputs off."""
    p = _plan(TWO, "afg2225")
    assert p.form == "steps"
    assert _lines(p.stream()) == EXPECTED_AFG
    inst = _sim(AFG)
    result = _play(p, inst)
    assert result.sent == EXPECTED_AFG
    assert len(result.readbacks) == sum(1 for x in EXPECTED_AFG if x.endswith("?") and x != "SYST:ERR?")
    _readbacks_equal(result)
    assert inst.query("OUTP1?") == "OFF" and inst.query("OUTP2?") == "OFF"


def test_keysight_sequence_stream():
    """The 33522B holds one looped segment per distinct drive: 125 kHz alone loops in 8 samples at
    1 MS/s (the lcm of the drives' common frequencies 125 kHz and 5 kHz, 8x the highest tone), the
    two-tone drive in 200; repeats = duration x rate / points; the silent segment ends it."""
    import numpy as np

    p = _plan(TWO, "33522b")
    assert p.form == "sequence"
    lines = _lines(p.stream())
    vmax = 0.2495                 # max |3 sin(2 pi 85k t) + 2 sin(2 pi 125k t + 1.5)| / 20 over the 200 samples, rounded up
    t = np.arange(200) / 1e6
    v = (3 * np.sin(2 * np.pi * 85e3 * t) + 2 * np.sin(2 * np.pi * 125e3 * t + 1.5)) / 20
    assert abs(v).max() <= vmax < abs(v).max() + 1e-4
    acl1 = [int(round(32767 * 0.2 * math.sin(2 * math.pi * k / 8) / vmax)) for k in range(8)]
    acl2 = [int(round(32767 * x / vmax)) for x in v]
    body = ('"ACLSEQ","ACL1",2500,repeat,maintain,4,"ACL2",150,repeat,maintain,4,"ACL0",1250,repeat,maintain,4,'
            '"ACL1",2500,repeat,maintain,4,"ACL0",0,repeatInf,maintain,4')
    assert lines == [
        "OUTP1 OFF", "OUTP1?", "SOUR1:DATA:VOL:CLE",
        "SOUR1:DATA:ARB:DAC ACL1," + ",".join(map(str, acl1)), "SOUR1:DATA:ATTR:POIN? ACL1",
        "SOUR1:DATA:ARB:DAC ACL2," + ",".join(map(str, acl2)), "SOUR1:DATA:ATTR:POIN? ACL2",
        "SOUR1:DATA:ARB:DAC ACL0," + ",".join(["0"] * 8), "SOUR1:DATA:ATTR:POIN? ACL0",
        f"SOUR1:DATA:SEQ #3{len(body)}{body}",
        "SOUR1:FUNC ARB", "SOUR1:FUNC?", "SOUR1:FUNC:ARB ACLSEQ", "SOUR1:FUNC:ARB?",
        "SOUR1:FUNC:ARB:SRAT 1000000", "SOUR1:FUNC:ARB:SRAT?", "OUTP1:LOAD INF", "OUTP1:LOAD?",
        "SOUR1:VOLT 0.499", "SOUR1:VOLT?", "SOUR1:VOLT:OFFS 0", "SOUR1:VOLT:OFFS?", "SYST:ERR?",
        "OUTP1 ON", "OUTP1?", "SYST:ERR?", "OUTP1 OFF", "OUTP1?"]
    inst = _sim(KEY)
    result = _play(p, inst)
    assert result.sent == lines
    _readbacks_equal(result)
    assert inst.query("SIM:SEQ?") == f"#3{len(body)}{body}"
    assert inst.query("OUTP1?") == "OFF"


@pytest.fixture(scope="module")
def fig3_schedule(tmp_path_factory):
    """The Fig. 3 circle program compiled (schedule.json only: no waveform is rendered)."""
    import acl
    from acl.emit.schedule_json import schedule_dict, write_schedule_json
    from acl.schedule.compile import CompileOptions, compile_program

    design = acl.load(os.path.join(HERE, "..", "examples", "fig3_three_orifice.acl"))
    s = compile_program(design, "circle", CompileOptions(band_samples=0))
    path = str(tmp_path_factory.mktemp("fig3") / "schedule.json")
    write_schedule_json(path, schedule_dict(s, s.sample_rate_hz))
    return path


@pytest.mark.parametrize("which", [AFG, KEY], ids=["afg2225", "33522b"])
def test_fig3_circle_under_64kB_and_replayed(fig3_schedule, which, capsys):
    """Issue 26: the Fig. 3 circle (800 segments of three tones) prints under 64 kB and pyvisa-sim
    replays it with every setting read back equal.  At most two of its three tones are above the
    generators' 2 mVpp at a time: each takes one of the two channels (re-tuned as the circle turns)."""
    assert main(["play", fig3_schedule, "--dry-run", "--instrument", which[2]]) == 0
    out = capsys.readouterr().out
    assert len(out.encode()) < 64 * 1024
    p = _plan(fig3_schedule, which[2])
    assert p.stream() == out and p.form == "steps"
    freqs = {x.split()[1] for x in out.splitlines() if ":FREQ " in x}
    assert freqs == {"72500", "128500", "178500"}   # the least-amplitude drive uses two of the three at a time
    result = _play(p, _sim(which))
    assert result.sent == _lines(out)
    assert len(result.readbacks) > 1000
    _readbacks_equal(result)


def test_seq_export_matches_drives(fig3_schedule, tmp_path):
    """compile --format seq's sequence.seq: one line per constant drive, loop period 1/gcd of its
    tones (2 ms for 72.5, 128.5 and 178.5 kHz), repeats = duration / period (10 ms: 5)."""
    from acl.bench.schedule import load
    from acl.emit.seq import write_seq

    drives, _ = load(fig3_schedule)
    path = tmp_path / "sequence.seq"
    assert write_seq(str(path), drives, {"program": "circle"}) == 800
    rows = [r for r in path.read_text().splitlines() if not r.startswith("#")]
    assert rows[0] == "drive,start_s,duration_s,period_s,repeats,tones"
    first = rows[1].split(",")
    assert first[:5] == ["1", "0", "0.01", "0.002", "5"]
    tones = [t.split(":") for t in first[5].split(";")]
    assert [float(t[0]) for t in tones] == [72500, 128500, 178500]
    assert float(tones[2][1]) == pytest.approx(drives[0].tones[2][1], rel=1e-8)
    assert len(path.read_bytes()) < 200 * 1024


def test_compile_format_seq(tmp_path):
    """`acl compile --format seq` writes sequence.seq beside schedule.json (and lists it there):
    85 kHz @ 3 V + 125 kHz @ 2 V for 20 ms loops every 1/5 kHz = 200 us, 100 times; the pause is a
    drive without tones."""
    from tests.test_compile_cli import DESIGN

    design = tmp_path / "d.acl"
    design.write_text(DESIGN)
    out = tmp_path / "out"
    assert main(["compile", str(design), "--program", "tones", "-o", str(out), "--format", "seq", "-q"]) == 0
    data = json.loads((out / "schedule.json").read_text())
    assert data["files"]["seq"] == "sequence.seq"
    assert sorted(os.listdir(out)) == ["schedule.json", "segments.csv", "sequence.seq"]
    rows = [r.split(",") for r in (out / "sequence.seq").read_text().splitlines() if not r.startswith("#")][1:]
    assert rows[0][:5] == ["1", "0", "0.02", "0.0002", "100"]
    assert [float(t.split(":")[1]) for t in rows[0][5].split(";")] == pytest.approx([3.0, 2.0])
    assert rows[-1][5] == ""


# -- safety: output off on a read-back that differs, on Ctrl-C and on SIGTERM ------------------------

def _quantizing_sim(tmp_path):
    """The AFG-2225 definition, its amplitude answered to 10 mV (as if the instrument rounded)."""
    text = open(os.path.join(DATA, "afg2225.yaml")).read().replace('r: "{:+.4E}"', 'r: "{:+.1E}"')
    path = tmp_path / "afg_round.yaml"
    path.write_text(text)
    return (str(path), AFG[1], AFG[2])


def test_readback_mismatch_stops_with_output_off(tmp_path):
    """An instrument that holds 0.41 Vpp when sent 0.4123 (it rounds): E-PLAY-READBACK, outputs off."""
    from acl.diagnostics import DiagnosticError

    inst = _sim(_quantizing_sim(tmp_path))
    p = _plan(_schedule(tmp_path, [[(125e3, 2.0)], [(125e3, 4.123)]]), "afg2225")
    with pytest.raises(DiagnosticError) as exc:
        _play(p, inst)
    d = exc.value.diagnostics[0]
    assert d.code == "E-PLAY-READBACK" and "'+4.1E-01' after `SOUR1:AMP 0.4123`" in d.message
    assert inst.query("OUTP1?") == "OFF" and inst.query("OUTP2?") == "OFF"


@pytest.mark.parametrize("how", ["ctrl-c", "sigterm"])
def test_interrupt_leaves_output_off(how):
    from acl.bench.player import play
    from acl.diagnostics import DiagnosticError

    inst = _sim(AFG)
    p = _plan(TWO, "afg2225")
    now = [0.0]

    def sleep(dt):
        now[0] += dt
        if now[0] > 0.03:             # during the two-tone drive: both outputs on
            assert inst.query("OUTP1?") == "ON" and inst.query("OUTP2?") == "ON"
            if how == "ctrl-c":
                raise KeyboardInterrupt
            os.kill(os.getpid(), signal.SIGTERM)

    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(DiagnosticError) as exc:
        play(p, inst, clock=lambda: now[0], sleep=sleep)
    assert exc.value.diagnostics[0].code == "E-PLAY-INTERRUPTED"
    assert inst.query("OUTP1?") == "OFF" and inst.query("OUTP2?") == "OFF"
    assert signal.getsignal(signal.SIGTERM) is before


# -- the chain refuses what it cannot play ------------------------------------------------------------

def _schedule(tmp_path, tones_per_segment):
    segs = [{"start_s": 0.01 * i, "end_s": 0.01 * (i + 1), "tones": [
        {"frequency_hz": f, "amplitude_v": a, "phase_rad": 0.0} for f, a in tones]}
        for i, tones in enumerate(tones_per_segment)]
    path = tmp_path / "s.json"
    path.write_text(json.dumps({"version": "1.1", "segments": segs, "goals": []}, indent=1))
    return str(path)


def test_chain_refuses_with_location(tmp_path, capsys):
    """A drive the generator cannot deliver without an amplifier (12 V > its 10 V), three tones at
    once on a two-channel AFG, and a drive beyond the HVA200's 200 V: E-PLAY-CHAIN at the segment."""
    path = _schedule(tmp_path, [[(125e3, 4.0)], [(125e3, 12.0)]])
    assert main(["play", path, "--dry-run", "--amplifier", "none"]) == 1
    err = capsys.readouterr()
    assert err.out == ""
    line = next(i for i, x in enumerate(open(path).read().splitlines(), 1) if '"start_s": 0.01' in x)
    assert f"s.json:{line}:" in err.err and "E-PLAY-CHAIN" in err.err and "12 V" in err.err
    path = _schedule(tmp_path, [[(85e3, 3.0), (125e3, 2.0), (170e3, 1.0)]])
    assert main(["play", path, "--dry-run"]) == 1
    assert "3 tones at once" in capsys.readouterr().err
    assert main(["play", path, "--dry-run", "--instrument", "33522b"]) == 0       # a sequence plays them
    capsys.readouterr()
    path = _schedule(tmp_path, [[(85e3, 150.0), (125e3, 60.0)]])
    assert main(["play", path, "--dry-run"]) == 1
    assert "beyond the Thorlabs HVA200's 200 V output" in capsys.readouterr().err


# -- bad input: located, coded, exit 2, no traceback -------------------------------------------------

@pytest.mark.parametrize("content,code,where", [
    (None, "E-PLAY-SCHEDULE", "missing.json:1:1"),
    ('{"version": "1.1", "segments": [\n  {"start_s": 0, oops}]}', "E-PLAY-SCHEDULE", "s.json:2:18"),
    ('[1, 2]', "E-PLAY-SCHEDULE", "s.json:1:1"),
    ('{"version": "1.1", "segments": [\n {"start_s": 0, "end_s": 0.1, "tones": [{"frequency_hz": -5, '
     '"amplitude_v": 1}]}]}', "E-PLAY-SCHEDULE", "s.json:2:3"),
    (b'\xff\xfe', "E-PLAY-SCHEDULE", "s.json:1:1"),
])
def test_bad_schedule(tmp_path, capsys, content, code, where):
    path = tmp_path / ("missing.json" if content is None else "s.json")
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif content is not None:
        path.write_text(content)
    assert main(["play", str(path), "--dry-run"]) == 2
    cap = capsys.readouterr()
    assert cap.out == "" and f"{where}: error[{code}]" in cap.err and "Traceback" not in cap.err


@pytest.mark.parametrize("args,code", [
    (["--resource", "not an address"], "E-PLAY-RESOURCE"),
    ([], "E-USAGE"),
    (["--resource", "USB0::0x1234::0x5678::NOPE::INSTR", "--visa-library", os.path.join(DATA, "afg2225.yaml") + "@sim"],
     "E-PLAY-CONNECT"),
    (["--resource", AFG[1], "--instrument", "33522b", "--visa-library", os.path.join(DATA, "afg2225.yaml") + "@sim"],
     "E-PLAY-INSTRUMENT"),
])
def test_bad_resource(capsys, args, code):
    pytest.importorskip("pyvisa_sim")
    assert main(["play", TWO, *args]) == 2
    cap = capsys.readouterr()
    assert f"<--resource>:1:1: error[{code}]" in cap.err and "Traceback" not in cap.err


@pytest.mark.parametrize("which", [AFG, KEY], ids=["afg2225", "33522b"])
def test_cli_plays_on_simulated_instrument(which, capsys):
    pytest.importorskip("pyvisa_sim")
    assert main(["play", TWO, "--resource", which[1], "--visa-library", os.path.join(DATA, which[0]) + "@sim"]) == 0
    assert "read back equal" in capsys.readouterr().err


def test_the_declared_chain_recorded_by_compile_is_played(tmp_path, capsys):
    """schedule.json records the design's `use generator`/`use amplifier`; acl play uses them unless
    --instrument/--amplifier say otherwise: a declared 8 V amplifier refuses a 12 V drive."""
    path = tmp_path / "s.json"
    segs = [{"start_s": 0.0, "end_s": 0.01, "tones": [{"frequency_hz": 125e3, "amplitude_v": 12.0}]}]
    chain = {"generator": {"name": "bench.keysight33522b", "max_voltage": 10.0},
             "amplifier": {"name": "weak", "gain": 2.0, "max_voltage": 8.0, "bandwidth": 1e6}}
    path.write_text(json.dumps({"version": "1.1", "segments": segs, "goals": [], "chain": chain}, indent=1))
    assert main(["play", str(path), "--dry-run"]) == 1
    err = capsys.readouterr().err
    assert "E-PLAY-CHAIN" in err and "weak (declared)'s 8 V output" in err
    assert main(["play", str(path), "--dry-run", "--amplifier", "hva200"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("# acl play: Keysight 33522B -> Thorlabs HVA200 (gain 20), form: sequence")


def test_compile_records_the_chain(tmp_path):
    import shutil

    shutil.copy(os.path.join(DATA, "loop.acl"), tmp_path / "loop.acl")
    assert main(["compile", str(tmp_path / "loop.acl"), "--program", "ramp", "-o", str(tmp_path / "out"), "-q"]) == 0
    data = json.loads((tmp_path / "out" / "schedule.json").read_text())
    assert data["chain"]["amplifier"] == {"name": "bench.hva200", "gain": 20.0, "max_voltage": 200.0, "bandwidth": 1e6}
    assert data["chain"]["generator"]["name"] == "bench.afg2225"
    jsonschema = pytest.importorskip("jsonschema")
    from acl.emit.schedule_json import load_schema

    jsonschema.validate(data, load_schema())

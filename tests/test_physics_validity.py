"""Issue 10 validity and defaults: linear-regime reports, lint/compile refusal, one polytropic default."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import acl
from acl.analysis import acoustics as A, interfaces
from acl.analysis.report import analyze
from acl.design.model import Drive, Tone
from acl.diagnostics import DiagnosticError
from acl.physics.constants import LINEAR_AMPLITUDE_LIMIT
from acl.schedule.compile import CompileOptions, compile_program

ROOT = Path(__file__).resolve().parents[1]

ONE = """import stdlib.capsules
import stdlib.beams
import stdlib.transducers
use transducer transducers.contact_piezo
beam arm like beams.cantilever50 { clamp = (0, 0, 0) }
capsule a like capsules.design1 { }
mount a on arm.tip
program p {
  drive 123 kHz @ VOLTS for 1 s
}
"""


def design(volts: str):
    return acl.loads(ONE.replace("VOLTS", volts), filename=str(ROOT / "examples" / "v.acl"))


def test_interface_amplitude_is_linear_in_voltage_and_reported_per_drive():
    # Linear model: eps/R doubles with the voltage (1e-12 rel.); analyze reports it per drive and orifice.
    d = design("2 V")
    a1 = interfaces.interface_amplitudes(d, Drive(tones=(Tone(frequency=123e3, amplitude=1.0),)))["a.jet"]
    a2 = interfaces.interface_amplitudes(d, Drive(tones=(Tone(frequency=123e3, amplitude=2.0),)))["a.jet"]
    assert a2 == pytest.approx(2 * a1, rel=1e-12)
    rep = analyze(d, snap_in=False).as_dict()
    (entry,) = [x for x in rep["drives"] if x["program"] == "p"]
    assert entry["interface_amplitude_over_radius"]["a.jet"] == pytest.approx(a2, rel=1e-12)
    assert entry["linear"] is (a2 <= LINEAR_AMPLITUDE_LIMIT)


HIGH = ONE.replace("use transducer transducers.contact_piezo",
                   "transducer amp like transducers.contact_piezo { max_voltage = 100 V }\nuse transducer amp")


def test_compile_warns_past_the_linear_limit_and_refuses_past_the_hemisphere_unless_allowed():
    # Issue 24: eps/R 0.25..1 is planned with W-ACOUSTIC-AMPLITUDE at the step (the paper's Fig. 2c/2f show its
    # bubbles linear at its drives); past the hemisphere (eps/R > 1) the model has no meaning: E-SCHED-NONLINEAR.
    d = design("10 V")            # ~0.46 eps/R at design 1's resonance
    s = compile_program(d, "p")
    (w,) = [w for w in s.warnings if w.code == "W-ACOUSTIC-AMPLITUDE"]
    assert w.span.line == 9 and "model-form uncertainty" in w.message and w.notes and "Fig. 2f" in w.notes[0]
    (goal,) = s.goals
    assert 0 < goal.details["model_form_force_rel"] < 1
    hot = acl.loads(HIGH.replace("VOLTS", "30 V"), filename=str(ROOT / "examples" / "v.acl"))
    assert max(interfaces.interface_amplitudes(hot, Drive(tones=(Tone(frequency=123e3, amplitude=30.0),))).values()) > 1.0
    with pytest.raises(DiagnosticError) as exc:
        compile_program(hot, "p")
    (diag,) = exc.value.diagnostics
    assert diag.code == "E-SCHED-NONLINEAR" and diag.span.line == 10 and "hemisphere" in diag.message
    s = compile_program(hot, "p", CompileOptions(allow_nonlinear=True))
    assert any("allowed by --allow-nonlinear" in n for n in s.notes)
    compile_program(design("2 V"), "p")          # inside the linear regime: planned, no warning
    assert not [w for w in compile_program(design("2 V"), "p").warnings if w.code == "W-ACOUSTIC-AMPLITUDE"]


def test_compile_cli_refuses_without_writing_and_accepts_allow_nonlinear(tmp_path):
    src = tmp_path / "v.acl"
    src.write_text(HIGH.replace("VOLTS", "30 V"))
    out = tmp_path / "out"
    run = [sys.executable, "-m", "acl", "compile", str(src), "-o", str(out)]
    r = subprocess.run(run, capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 1 and "E-SCHED-NONLINEAR" in (r.stdout + r.stderr) and "v.acl:10:" in (r.stdout + r.stderr)
    assert not out.exists()
    r = subprocess.run(run + ["--allow-nonlinear"], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr


def test_a_declared_medium_without_polytropic_uses_the_physics_default():
    # Issue 10: a declared medium without `polytropic` used 1.4 while the default medium used 1.0.
    props = ("density = 998.2 kg/m^3\n viscosity = 1.002 mPa*s\n sound_speed = 1482 m/s\n"
             " surface_tension = 0.0728 N/m")
    text = ONE.replace("VOLTS", "1 V").replace("use transducer", f"medium m {{\n {props}\n}}\nuse medium m\nuse transducer")
    d = acl.loads(text, filename=str(ROOT / "examples" / "m.acl"))
    assert d.medium.polytropic_index == 1.0
    f_declared = A.capsule_modes(d, "a")[0].frequency_hz
    f_default = A.capsule_modes(design("1 V"), "a")[0].frequency_hz
    assert f_declared == pytest.approx(f_default, rel=1e-9)


def test_each_orifice_reports_its_own_fundamental():
    # A capsule with a large and a very small orifice: the small one's fundamental (surface tension
    # dominated, far above) must be reported even when it is not among the lowest n modes.
    text = """import stdlib.beams
beam arm like beams.cantilever50 { clamp = (0, 0, 0) }
capsule c {
  cavity cylinder { radius = 25 um, height = 30 um, axis = +z }
  orifice big { radius = 14 um, normal = +x }
  orifice tiny { radius = 4 um, normal = -x }
}
mount c on arm.tip
"""
    d = acl.loads(text, filename=str(ROOT / "examples" / "two.acl"))
    modes = A.capsule_modes(d, "c")
    assert {m.dominant_orifice for m in modes} == {"big", "tiny"}
    assert modes[0].dominant_orifice == "big"


def test_analyze_json_keeps_old_fields_and_adds_issue_10_fields():
    rep = analyze(acl.load(str(ROOT / "examples" / "fig4h_unequal_pair.acl")), snap_in=False).as_dict()
    mode = rep["capsules"][0]["modes"][0]
    assert {"frequency_hz", "q", "q_declared", "dominant_orifice", "share", "q_predicted"} <= set(mode)
    assert len(rep["coupled_modes"]) == 2
    assert {"frequency_hz", "shares", "q_predicted"} <= set(rep["coupled_modes"][0])
    pair = rep["pairs"][0]
    assert {"critical_distance_m", "interface_amplitude_over_radius", "repel_from_q"} <= set(pair)
    json.dumps(rep)


def test_equilibrium_reports_beam_deflection_against_eq1_validity():
    # deflection / eq1_validity_limit(L, l) per beam (paper Eq. 1 vs the elastica, 5 %), 1e-12 rel.
    from acl.physics.beams import eq1_validity_limit

    d = acl.load(str(ROOT / "examples" / "fig4_facing_pair.acl"))
    rep = analyze(d, at=Drive(tones=(Tone(frequency=125e3, amplitude=2.0),)), snap_in=False).as_dict()
    eq = rep["equilibrium"]
    for name, ratio in eq["deflection_over_eq1_limit"].items():
        b = next(b for b in d.beams if b.name == name)
        assert ratio == pytest.approx(eq["deflections_m"][name] / eq1_validity_limit(b.length, b.rigid_length), rel=1e-12)
    assert set(eq["interface_amplitude_over_radius"]) == {"left.jet", "right.jet"}

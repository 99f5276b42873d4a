"""Declared `effect` coefficients are range-checked, not only sign-checked (acl.design.core.EFFECT_RANGES).

Before: `effect drive_saturation { v_sat = 1e-300 V }` or `effect transducer_resonance { ..., gain_q = 1e300 }`
made `acl analyze` die in a ZeroDivisionError / OverflowError, `effect transducer_gain { gain_slope = 1e300 }`
printed infinities, `offset_drift.drift = 1e300 um/s` was accepted.  Now a value outside a coefficient's physical
range is E401 at the value (file:line:column), the commands exit non-zero without a traceback and write nothing;
a finite but implausible value is the warning W402; a design at the edge of every accepted range analyses to
finite numbers (no inf or NaN in any output).
"""
from __future__ import annotations

import json
import math
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from acl.cli import main
from acl.design.core import EFFECT_RANGES, EFFECT_UNITS, PROPERTY_RANGES
from acl.design.resolve import check_design

ROOT = Path(__file__).resolve().parents[1]
CANTILEVER = ROOT / "samples" / "fit_cantilever.acl"
PAIR_CAL = ROOT / "samples" / "fit_pair_cal.acl"

# the unit each coefficient is written in (its SI unit in acl syntax)
_WRITE = {"": "", "Hz": "Hz", "V": "V", "1/V^2": "V^-2", "m": "m", "m/s": "m/s", "1/s": "Hz", "1/m": "m^-1"}


def _unit(effect, key):
    return _WRITE[EFFECT_UNITS[effect][key][0]]


def _decl(effect, key, value):
    u = _unit(effect, key)
    return f"effect {effect} {{ {key} = {value!r}{(' ' + u) if u else ''} }}"


def _outside(rng):
    """Values beyond the physical range: just past each finite end, and an absurd 1e300 of the sign that is out."""
    out = [rng.hi * 1.5 if rng.hi > 0 else rng.hi + 1.0, 1e300]
    if rng.lo > 0:
        out += [rng.lo / 1.5, 1e-300]
    elif rng.lo < 0:
        out += [rng.lo * 1.5, -1e300]
    return out


BAD = [(e, k, v) for (e, k), rng in EFFECT_RANGES.items() for v in _outside(rng)]


def _write(tmp_path, base: Path, text: str) -> Path:
    shutil.copy(base, tmp_path / base.name)
    path = tmp_path / "design.acl"
    path.write_text(f'extends "{base.name}"\n{text}\n')
    return path


@pytest.mark.parametrize("effect,key,value", BAD, ids=[f"{e}.{k}={v:g}" for e, k, v in BAD])
def test_value_outside_the_physical_range_is_e401_at_the_value(tmp_path, effect, key, value):
    decl = _decl(effect, key, value)
    path = _write(tmp_path, CANTILEVER, decl)
    _, diags = check_design(str(path))
    errors = [d for d in diags if d.is_error]
    column = decl.index(f"{key} = ") + len(f"{key} = ") + 1
    assert [(d.code, os.path.realpath(d.span.file), d.span.line, d.span.column) for d in errors] == \
        [("E401", os.path.realpath(path), 2, column)], [d.message for d in errors]
    # the sign check (EFFECT_DOMAIN, "must be positive") or the range check answers first; both give the reason
    assert ("outside its physical range" in errors[0].message or "must be" in errors[0].message) and errors[0].hint


def _run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


# one bad value per effect (class of coefficient), through the commands that write files
CLI_BAD = [
    ("transducer_gain", "effect transducer_gain { gain = 1e300 }"),
    ("transducer_gain", "effect transducer_gain { gain_slope = 1e300, f_ref = 125 kHz }"),
    ("transducer_resonance", "effect transducer_resonance { inv_f_ratio = 1, gain_q = 1e300, f_ref = 125 kHz }"),
    ("drive_saturation", "effect drive_saturation { v_sat = 1e-300 V }"),
    ("large_deflection", "effect large_deflection { elastica_weight = 1.01 }"),
    ("stiffness_scale", "effect stiffness_scale { e_scale = 1e-300 }"),
    ("stiffness_gradient", "effect stiffness_gradient { e_gradient = 1e300 }"),
    ("offset_drift", "effect offset_drift { drift = 1e300 um/s }"),
    ("bubble_shrinkage", "effect bubble_shrinkage { shrink_rate = 1e300 Hz }"),
    ("neighbour_drag", "effect neighbour_drag { plateau = 1e-300 m }"),
    ("substrate_proximity", "effect substrate_proximity { h_substrate = 1e300 m }"),
    ("bjerknes_scale", "effect bjerknes_scale { factor = 1e300 }"),
]


@pytest.mark.parametrize("effect,decl", CLI_BAD, ids=[f"{e}-{i}" for i, (e, _) in enumerate(CLI_BAD)])
def test_commands_refuse_a_bad_effect_value_without_traceback_or_output(tmp_path, capsys, effect, decl):
    src = (ROOT / "examples" / "fig2_stroke.acl").read_text()
    for name in ("fig2_stroke.acl", "fig2_vertical_cantilever.acl"):
        shutil.copy(ROOT / "examples" / name, tmp_path / name)
    assert "program stroke" in src
    path = tmp_path / "design.acl"
    path.write_text(f'extends "fig2_stroke.acl"\n{decl}\n')
    where = f"{path}:2:"
    runs = [("check", path), ("analyze", path, "--at", "125 kHz @ 6 V"), ("lint", path),
            ("compile", path, "--program", "stroke", "-o", tmp_path / "out"),
            ("synth", path, "-o", tmp_path / "data.csv"),
            ("fit", path, tmp_path / "measured.csv", "--effects", "none", "--report", tmp_path / "rep",
             "--calibrated", tmp_path / "cal.acl")]
    (tmp_path / "measured.csv").write_text("observable,value,unit,drive\ndelta,1,um,125 kHz @ 4 V\n"
                                           "delta,2,um,125 kHz @ 6 V\n")
    for args in runs:
        code, out, err = _run(capsys, *args)
        assert code != 0, args
        assert "E401" in out + err and where in out + err, (args, out + err)
        assert "Traceback" not in out + err and "E-INTERNAL" not in out + err, args
    assert not [p.name for p in tmp_path.iterdir() if p.name in ("out", "data.csv", "rep", "cal.acl")]


def test_bad_value_is_e401_in_json_with_its_location(tmp_path, capsys):
    path = _write(tmp_path, CANTILEVER, "effect offset_drift { offset = 0 um, drift = 1e300 um/s }")
    code, out, _ = _run(capsys, "check", path, "--output-format", "json")
    assert code == 1
    diags = [d for d in json.loads(out)["diagnostics"] if d["severity"] == "error"]
    assert [(d["code"], d["line"], d["column"]) for d in diags] == [("E401", 2, len("effect offset_drift { offset = 0 um, drift = ") + 1)]


@pytest.mark.parametrize("decl,code_count", [
    ("effect drive_saturation { v_sat = 0.05 V }", 1),            # below the fit's 0.1 V: plausible? no
    ("effect bubble_shrinkage { shrink_rate = 5 Hz }", 1),
    ("effect offset_drift { offset = 0 um, drift = 50 um/s }", 1),
    ("effect drive_saturation { v_sat = 8 V }", 0),               # the README's value: no warning
    ("effect transducer_gain { gain = 1.1, gain_slope = 0.93, f_ref = 125 kHz }", 0),
])
def test_implausible_but_finite_value_is_the_warning_w402(tmp_path, decl, code_count):
    path = _write(tmp_path, CANTILEVER, decl)
    design, diags = check_design(str(path))
    assert design is not None and not [d for d in diags if d.is_error]
    w = [d for d in diags if d.code == "W402"]
    assert len(w) == code_count, [d.message for d in diags]
    if w:
        assert w[0].span.line == 2 and "plausible range" in w[0].message


def test_gradient_is_checked_over_each_beams_length(tmp_path):
    """|g| = 10 is in the absolute range (27.6) and on the 50 um beam E(0)/E = e^5 (accepted, a warning), but on a
    150 um beam E(L)/E = e^25 (11 decades): E401 at the value."""
    path = _write(tmp_path, CANTILEVER, "effect stiffness_gradient { e_gradient = 10 }")
    _, diags = check_design(str(path))
    assert not [d for d in diags if d.is_error] and [d.code for d in diags if not d.is_error] == ["W402"]
    _, diags = check_design(str(path), overrides={"length": "150 um"})
    errors = [d for d in diags if d.is_error]
    assert [(d.code, d.span.line, d.span.column) for d in errors] == [("E401", 2, 42)], [d.message for d in diags]
    assert "beam `arm`" in errors[0].message


@pytest.mark.parametrize("decl,words", [
    ("effect stiffness_scale { e_scale = 0.001 }\neffect stiffness_gradient { e_gradient = -13.8 }", "13.1 Pa"),
    ("effect stiffness_scale { e_scale = 1000 }\neffect stiffness_gradient { e_gradient = 13.8 }", "1.29e+13 Pa"),
])
def test_scaled_and_graded_modulus_must_be_a_solids(tmp_path, decl, words):
    """Each factor is in its range, but TPETA's 13 MPa scaled and graded reaches 13 Pa (softer than any printable
    gel) or 13 TPa (stiffer than diamond) at an end of the beam: E401 at the gradient's value."""
    _, diags = check_design(str(_write(tmp_path, CANTILEVER, decl)))
    errors = [d for d in diags if d.is_error]
    assert [(d.code, d.span.line, d.span.column) for d in errors] == [("E401", 3, 42)], [d.message for d in diags]
    assert words in errors[0].message and "solid's modulus" in errors[0].message


def test_fit_library_bounds_lie_inside_the_accepted_ranges():
    """A calibrated design written by `acl fit` is never refused: every fitted coordinate's bounds are accepted."""
    from acl.fit.effects import ANALYSIS_NAME, EFFECTS

    pending = []
    for eid, eff in EFFECTS.items():
        for p in eff.params:
            key = ANALYSIS_NAME.get((eid, p.name), (eid, p.name))
            if key not in EFFECT_RANGES and key in ANALYSIS_NAME.values():
                pending.append(key)             # the analysis' coefficient another branch declares (gap_exponent)
                continue
            rng = EFFECT_RANGES[key]
            assert rng.lo <= p.lower and p.upper <= rng.hi, (eid, p.name)
            assert rng.plausible_lo >= rng.lo and rng.plausible_hi <= rng.hi
    if pending:
        pytest.skip(f"the analysis does not declare {pending} on this tree")


def test_synth_refuses_a_planted_effect_outside_its_range(tmp_path, capsys):
    code, out, err = _run(capsys, "synth", CANTILEVER, "-o", tmp_path / "d.csv",
                          "--effect", "offset_drift=offset:0um,drift:1e300um/s")
    assert code == 2 and "outside its physical range" in err and "<--effect>:1:" in err
    assert "Traceback" not in err and not (tmp_path / "d.csv").exists()


# ---- accepted edges: finite numbers everywhere

def _edges():
    out = []
    for (e, k), rng in EFFECT_RANGES.items():
        for v in {rng.lo, rng.hi}:
            if (e, k) in (("transducer_gain", "gain_slope"),):
                out.append((e, f"effect {e} {{ gain_slope = {v!r}, f_ref = 125 kHz }}"))
            elif (e, k) == ("transducer_resonance", "gain_q"):
                out.append((e, f"effect {e} {{ inv_f_ratio = 1, gain_q = {v!r}, f_ref = 125 kHz }}"))
            elif (e, k) == ("transducer_resonance", "inv_f_ratio"):
                out.append((e, f"effect {e} {{ inv_f_ratio = {v!r}, gain_q = 0.3, f_ref = 125 kHz }}"))
            elif (e, k) == ("stiffness_gradient", "e_gradient"):
                # on the cantilever's 50 um TPETA beam (13 MPa) the clamp or tip reaches a solid's 1 kPa first
                g = math.copysign(0.999 * 2 * math.log(13e6 / PROPERTY_RANGES[("material", "youngs")][0]), v)
                out.append((e, _decl(e, k, g)))
            elif (e, k) in (("transducer_gain", "f_ref"), ("transducer_resonance", "f_ref")):
                extra = "gain_slope = 6.9" if e == "transducer_gain" else "inv_f_ratio = 1, gain_q = 30"
                out.append((e, f"effect {e} {{ {extra}, f_ref = {v!r} Hz }}"))
            else:
                out.append((e, _decl(e, k, v)))
    # the softest and the stiffest beams the checker accepts, full elastica
    # (TPETA, 13 MPa: 1.8 kPa at the tip, 1.2 TPa at the clamp, both inside a solid's 1 kPa .. 1.2 TPa)
    out.append(("stiffness", "effect stiffness_scale { e_scale = 0.001 }\neffect stiffness_gradient { e_gradient = -4 }\n"
                              "effect large_deflection { elastica_weight = 1 }"))
    out.append(("stiffness", "effect stiffness_scale { e_scale = 1000 }\neffect stiffness_gradient { e_gradient = 9 }"))
    return out


EDGES = _edges()


def _finite(obj, where="report"):
    if isinstance(obj, float):
        assert math.isfinite(obj), where
    elif isinstance(obj, dict):
        for k, v in obj.items():
            _finite(v, f"{where}.{k}")
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            _finite(v, f"{where}[{i}]")
    elif isinstance(obj, np.ndarray):
        assert np.all(np.isfinite(obj)), where


@pytest.mark.parametrize("effect,decl", EDGES, ids=[f"{e}-{i}" for i, (e, _) in enumerate(EDGES)])
def test_design_at_the_edge_of_a_range_analyses_to_finite_numbers(tmp_path, effect, decl):
    import warnings

    from acl.analysis.report import analyze
    from acl.design.model import Drive, Tone

    base = PAIR_CAL if effect in ("neighbour_drag", "bjerknes_scale") else CANTILEVER
    design, diags = check_design(str(_write(tmp_path, base, decl)))
    assert design is not None and not [d for d in diags if d.is_error], [d.message for d in diags]
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)      # an overflow inside is a defect too
        rep = analyze(design, at=Drive(tones=(Tone(frequency=125e3, amplitude=8.0),)), snap_in=False)
    _finite(rep.as_dict())


def _strict_json(text):
    def refuse(c):
        raise AssertionError(f"non-finite {c} in JSON output")
    return json.loads(text, parse_constant=refuse)


def test_edge_design_runs_end_to_end(tmp_path, capsys):
    """Edges of several ranges at once, through check, analyze, lint, compile and synth --schedule: exit 0 (warnings
    only), strict JSON (no NaN/Infinity), finite schedule and data."""
    for name in ("fig2_stroke.acl", "fig2_vertical_cantilever.acl"):
        shutil.copy(ROOT / "examples" / name, tmp_path / name)
    path = tmp_path / "edge.acl"
    path.write_text('extends "fig2_stroke.acl"\n'
                    "effect transducer_gain { gain = 1000, gain_slope = 6.9, f_ref = 1 kHz }\n"
                    "effect transducer_resonance { inv_f_ratio = 1, gain_q = 10000, f_ref = 125 kHz }\n"
                    "effect drive_saturation { v_sat = 100 kV }\n"
                    "effect offset_drift { offset = 1 m, drift = -1 m/s }\n"
                    "effect bubble_shrinkage { shrink_rate = 100 Hz }\n")
    code, out, err = _run(capsys, "check", path)
    assert code == 0 and "W402" in err, err
    code, out, err = _run(capsys, "analyze", path, "--at", "125 kHz @ 8 V", "--output-format", "json")
    assert code == 0 and "Traceback" not in err, err
    _finite(_strict_json(out))
    code, out, err = _run(capsys, "lint", path, "--output-format", "json")
    assert "Traceback" not in err and "E-INTERNAL" not in out + err
    _strict_json(out)
    code, out, err = _run(capsys, "compile", path, "--program", "stroke", "-o", tmp_path / "out", "-q")
    assert code == 0, err
    _finite(_strict_json((tmp_path / "out" / "schedule.json").read_text()))
    code, out, err = _run(capsys, "synth", path, "--schedule", tmp_path / "out" / "schedule.json",
                          "-o", tmp_path / "run.csv", "-q")
    assert code == 0, err
    rows = (tmp_path / "run.csv").read_text().splitlines()[1:]
    assert rows and all(math.isfinite(float(r.split(",")[1])) for r in rows)


def test_docs_list_every_range(tmp_path):
    """docs/language.md's table of effect ranges is EFFECT_RANGES (hard and plausible bounds)."""
    text = (ROOT / "docs" / "language.md").read_text()
    for (e, k), rng in EFFECT_RANGES.items():
        row = re.search(rf"^\| `{e}` \| `{k}` \|(.*)$", text, re.M)
        assert row, (e, k)
        cells = [c.strip() for c in row.group(1).split("|")]      # unit, physical range, plausible range, why
        nums = [float(x) for x in re.findall(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?", cells[1] + " " + cells[2])]
        assert nums[:4] == pytest.approx([rng.lo, rng.hi, rng.plausible_lo, rng.plausible_hi], rel=1e-3), (e, k, nums)


# ---- other declared values that were only sign-checked: medium, material, capsule, transducer gain

_PROPS_TEXT = """import stdlib.capsules
param rho = 1005 kg/m^3
param mu = 1.02 mPa*s
param c = 1500 m/s
param sigma = 0.0725 N/m
param p0 = 101.325 kPa
param kappa = 2.1e-5 m^2/s
param E = 13 MPa
param rho_s = 1100 kg/m^3
param g = 230 Pa/V
param gamma = 0.027 nN/V^2
param qf = 6
medium m { density = rho, viscosity = mu, sound_speed = c, surface_tension = sigma, pressure = p0, thermal_diffusivity = kappa }
material mat { youngs = E, density = rho_s }
transducer t { max_voltage = 20 V, band = 40 kHz .. 200 kHz, gain = g }
use medium m
use transducer t
beam arm { length = 50 um, section = circle(2 um), material = mat, clamp = (0, 0, 0), axis = +z }
capsule act like capsules.design1 { thrust = gamma, q = qf }
mount act on arm.tip
observe delta = displacement(arm, -x)
"""
# parameter -> ((schema, key), unit written, the value's line:column in _PROPS_TEXT)
_PROP_PARAMS = {"rho": (("medium", "density"), "kg/m^3", "density = rho"),
                "mu": (("medium", "viscosity"), "Pa*s", "viscosity = mu"),
                "c": (("medium", "sound_speed"), "m/s", "sound_speed = c"),
                "sigma": (("medium", "surface_tension"), "N/m", "surface_tension = sigma"),
                "p0": (("medium", "pressure"), "Pa", "pressure = p0"),
                "kappa": (("medium", "thermal_diffusivity"), "m^2/s", "thermal_diffusivity = kappa"),
                "E": (("material", "youngs"), "Pa", "youngs = E"),
                "rho_s": (("material", "density"), "kg/m^3", "density = rho_s"),
                "g": (("transducer", "gain"), "Pa/V", "gain = g"),
                "qf": (("capsule", "q"), "", "q = qf")}
PROP_BAD = [(p, v) for p, ((sch, key), _, _) in _PROP_PARAMS.items()
            for v in ([PROPERTY_RANGES[(sch, key)][1] * 10, 1e300]
                      + ([PROPERTY_RANGES[(sch, key)][0] / 10, 1e-300]
                         if PROPERTY_RANGES[(sch, key)][0] > 0 else []))]


def _prop_loc(where):
    line = next(i for i, t in enumerate(_PROPS_TEXT.splitlines(), 1) if where in t)
    text = _PROPS_TEXT.splitlines()[line - 1]
    return line, text.index(where) + len(where.split(" = ")[0]) + len(" = ") + 1


@pytest.mark.parametrize("param,value", PROP_BAD, ids=[f"{p}={v:g}" for p, v in PROP_BAD])
def test_declared_property_outside_its_physical_range_is_an_error_at_the_value(tmp_path, param, value):
    (sch, key), unit, where = _PROP_PARAMS[param]
    path = tmp_path / "props.acl"
    path.write_text(_PROPS_TEXT)
    _, diags = check_design(str(path), overrides={param: f"{value!r} {unit}".strip()})
    errors = [d for d in diags if d.is_error]
    code = "E413" if sch == "transducer" else "E412"
    assert [(d.code, d.span.line, d.span.column) for d in errors] == [(code, *_prop_loc(where))], [d.message for d in diags]
    assert "physical range" in errors[0].message and errors[0].hint
    assert PROPERTY_RANGES[(sch, key)][0] <= PROPERTY_RANGES[(sch, key)][1]


PROP_EDGES = [(p, v) for p, ((sch, key), _, _) in _PROP_PARAMS.items()
              for v in {max(PROPERTY_RANGES[(sch, key)][0], 1e-12),
                        PROPERTY_RANGES[(sch, key)][1]}]


@pytest.mark.parametrize("param,value", PROP_EDGES, ids=[f"{p}={v:g}" for p, v in PROP_EDGES])
def test_declared_property_at_the_edge_of_its_range_analyses_to_finite_numbers(tmp_path, param, value):
    import warnings

    from acl.analysis.report import analyze
    from acl.design.model import Drive, Tone

    (_, _), unit, _ = _PROP_PARAMS[param]
    path = tmp_path / "props.acl"
    path.write_text(_PROPS_TEXT)
    design, diags = check_design(str(path), overrides={param: f"{value!r} {unit}".strip()})
    assert design is not None and not [d for d in diags if d.is_error], [d.message for d in diags]
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        rep = analyze(design, at=Drive(tones=(Tone(frequency=125e3, amplitude=8.0),)), snap_in=False)
    _finite(rep.as_dict())


def test_f_ref_outside_the_transducer_band_is_w402_at_the_value(tmp_path):
    """12.5 kHz (a unit slip for 125 kHz) is a drive frequency (accepted) but outside contact_piezo's 40 .. 200 kHz."""
    decl = "effect transducer_gain { gain_slope = 1, f_ref = 12.5 kHz }"
    design, diags = check_design(str(_write(tmp_path, CANTILEVER, decl)))
    assert design is not None and not [d for d in diags if d.is_error]
    w = [(d.code, d.span.line, d.span.column) for d in diags if d.code == "W402"]
    assert w == [("W402", 2, decl.index("12.5") + 1)], [d.message for d in diags]
    _, diags = check_design(str(_write(tmp_path, CANTILEVER, decl.replace("12.5 kHz", "125 kHz"))))
    assert not [d for d in diags if d.code == "W402"]

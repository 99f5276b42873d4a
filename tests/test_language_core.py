"""Core language behaviour: units, expressions, overrides, like, extends, effects, drive parsing."""
from __future__ import annotations

import math

import pytest

import acl
from acl.diagnostics import DiagnosticError
from acl.syntax.parser import parse_drive

HEAD = """import stdlib.media
import stdlib.capsules
import stdlib.beams
use medium media.pbs
"""


def codes(exc: DiagnosticError) -> list[str]:
    return [d.code for d in exc.diagnostics]


def test_units_are_converted_to_si():
    d = acl.loads(HEAD + "param a = 1.12e5 um^3\nparam b = 0.072 N/m\nparam c = 30 deg\nparam e = 1 mPa*s\n")
    p = {x.name: x for x in d.params}
    assert p["a"].value == pytest.approx(1.12e-13)
    assert p["a"].unit == "m^3"
    assert p["b"].value == pytest.approx(0.072)
    assert p["c"].value == pytest.approx(math.pi / 6)
    assert p["e"].value == pytest.approx(1e-3)


def test_arithmetic_between_parameters_keeps_dimensions():
    d = acl.loads("param gap = 40 um\nparam w = 2 * gap + 5 um\nparam f = 1 / (2 * 4 us)\n")
    p = {x.name: x for x in d.params}
    assert p["w"].value == pytest.approx(85e-6)
    assert p["f"].value == pytest.approx(125e3)
    assert p["f"].unit == "Hz"


def test_adding_length_to_frequency_is_a_dimension_error_at_its_column():
    with pytest.raises(DiagnosticError) as e:
        acl.loads("param x = 40 um + 3 kHz\n")
    d = e.value.diagnostics[0]
    assert d.code == "E303" and (d.span.line, d.span.column) == (1, 11)


def test_override_replaces_parameter_and_moves_geometry():
    src = HEAD + "param gap = 40 um\nbeam arm like beams.cantilever50 { clamp = (gap, 0, 50 um) }\n" \
                 "capsule c like capsules.design1 { }\nmount c on arm.tip\n"
    d = acl.loads(src, overrides={"gap": "60 um"})
    assert d.beam("arm").clamp[0] == pytest.approx(60e-6)
    assert d.capsule("c").center[2] == pytest.approx(100e-6 + 33.15e-6 / 2 + 2e-6)


def test_override_with_wrong_dimension_is_rejected():
    with pytest.raises(DiagnosticError) as e:
        acl.loads("param gap = 40 um\n", overrides={"gap": "60 V"})
    assert codes(e.value) == ["E301"]


def test_override_of_unknown_parameter_suggests_the_close_name():
    with pytest.raises(DiagnosticError) as e:
        acl.loads("param gap = 40 um\n", overrides={"gapp": "60 um"})
    assert codes(e.value) == ["E211"] and "gap" in e.value.diagnostics[0].hint


def test_like_inherits_and_overrides_entries():
    d = acl.loads(HEAD + "capsule c like capsules.design2 { center = (0, 0, 100 um) }\nfix c\n")
    c = d.capsule("c")
    assert c.orifice("jet").radius == pytest.approx(13e-6)
    assert c.cavity.volume == pytest.approx(1.12e-13, rel=2e-3)  # Table S1 design 2


def test_orifice_centre_sits_on_the_face_it_opens():
    d = acl.loads(HEAD + "capsule c like capsules.design1 { center = (0, 0, 100 um) }\nfix c\n")
    o = d.capsule("c").orifice("jet")
    assert o.center[0] == pytest.approx(27e-6)   # cylinder radius 25 um + 2 um wall along +x
    assert o.normal == (1.0, 0.0, 0.0)


def test_prism_faces_are_120_degrees_apart():
    d = acl.loads(HEAD + "capsule m like capsules.prism3 { center = (0, 0, 100 um) }\nfix m\n")
    ns = [o.normal for o in d.capsule("m").orifices]
    for i in range(3):
        a, b = ns[i], ns[(i + 1) % 3]
        assert sum(x * y for x, y in zip(a, b)) == pytest.approx(-0.5)


def test_every_independent_error_is_reported_in_one_run():
    src = "param a = 3 furlongz\nparam b = 40 um + 1 V\ncapsul c { }\n"
    with pytest.raises(DiagnosticError) as e:
        acl.loads(src)
    assert sorted(codes(e.value)) == ["E202", "E302", "E303"]


def test_syntax_errors_are_recovered_per_statement():
    src = "param a = 40 um\nparam b = = 3\nparam c = (\nparam d = 1 um\n"
    with pytest.raises(DiagnosticError) as e:
        acl.loads(src)
    lines = sorted(d.span.line for d in e.value.diagnostics)
    assert lines == [2, 3]


def test_drive_expression_parses_on_its_own():
    tones = parse_drive("85 kHz @ 8 V + 125 kHz @ 4 V")
    assert [(t.frequency.value, t.amplitude.value) for t in tones] == [(85.0, 8.0), (125.0, 4.0)]


def test_bad_drive_reports_the_cell_column():
    with pytest.raises(DiagnosticError) as e:
        parse_drive("85 kHz @", file="d.csv", line=7, column=4)
    d = e.value.diagnostics[0]
    assert d.span.file == "d.csv" and d.span.line == 7 and d.span.column >= 4


def test_extends_overrides_params_and_adds_effects(tmp_path):
    base = tmp_path / "base.acl"
    base.write_text(HEAD + "param h = 50 um\nbeam arm like beams.cantilever50 { clamp = (0, 0, h) }\n"
                           "capsule c like capsules.design1 { }\nmount c on arm.tip\n")
    cal = tmp_path / "cal.acl"
    cal.write_text('extends "base.acl"\nparam h = 70 um\neffect stiffness_scale { factor = 0.8 }\n')
    d = acl.load(cal)
    assert d.beam("arm").clamp[2] == pytest.approx(70e-6)
    assert d.effect("stiffness_scale").params == {"factor": 0.8}
    assert d.param("h").span.file.endswith("cal.acl")


def test_unknown_effect_gets_a_suggestion():
    with pytest.raises(DiagnosticError) as e:
        acl.loads("effect drive_saturaton { v_sat = 8 V }\n")
    assert codes(e.value) == ["E202"] and "drive_saturation" in e.value.diagnostics[0].hint


def test_import_outside_tree_is_refused(tmp_path):
    (tmp_path / "secret.acl").write_text("param s = 1 um\n")
    sub = tmp_path / "d"
    sub.mkdir()
    f = sub / "x.acl"
    f.write_text('import "../secret.acl" as s\n')
    with pytest.raises(DiagnosticError) as e:
        acl.load(f)
    assert codes(e.value) == ["E210"]


def test_deep_nesting_is_bounded():
    with pytest.raises(DiagnosticError) as e:
        acl.loads("param a = " + "(" * 100 + "1" + ")" * 100 + "\n")
    assert codes(e.value) == ["E104"]


PAIR = HEAD + """beam la like beams.cantilever50 { clamp = (0, 0, 50 um) }
beam ra like beams.cantilever50 { clamp = (94 um, 0, 50 um) }
capsule a like capsules.design1 { }
capsule b like capsules.design1 { orifice jet { radius = 10 um, normal = -x } }
mount a on la.tip
mount b on ra.tip
"""


def test_hold_takes_a_margin():
    d = acl.loads(PAIR + "program p {\n  hold gap(a.jet, b.jet) above 20 um for 1 s, margin 1.5\n}\n")
    assert d.program("p").steps[0].margin == 1.5


def test_hold_margin_below_one_is_rejected_at_its_column():
    with pytest.raises(DiagnosticError) as e:
        acl.loads(PAIR + "program p {\n  cross gap(a.jet, b.jet) for 1 s, margin 0.5\n}\n")
    d = e.value.diagnostics[0]
    assert d.code == "E505" and d.span.column == 43   # the `0.5`

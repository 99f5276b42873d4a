"""Every example resolves, cites its figure, and encodes the paper's numbers where it claims to."""
from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

import acl

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "examples").glob("*.acl"))
UM = 1e-6


def _load(name: str, **overrides):
    return acl.load(str(EXAMPLES[0].parent / name), overrides=overrides)


def _dist(p, q) -> float:
    return math.dist(p, q)


def _orifice(design, ref: str):
    cap, ori = ref.split(".")
    return design.capsule(cap).orifice(ori)


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_example_resolves_with_a_medium_and_a_transducer(path):
    design = acl.load(str(path))
    assert design.medium is not None and design.transducer is not None
    assert design.capsules and design.programs


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_example_header_cites_a_figure_and_lists_assumptions(path):
    header = path.read_text().split("\nimport", 1)[0]
    assert re.search(r"Fig\. S?\d", header.splitlines()[0]), "first line cites the figure"
    assert "Assumed" in header


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_example_file_name_names_its_figure(path):
    assert re.match(r"fig(S?\d+[a-z]?)_[a-z0-9_]+\.acl$", path.name)


def test_every_device_of_the_paper_has_an_example():
    names = {p.stem for p in EXAMPLES}
    for stem in ("fig1f_selective_beams", "fig2_vertical_cantilever", "fig3_three_orifice", "fig4_facing_pair",
                 "fig4h_unequal_pair", "figS6_flextensional", "fig5a_gripper", "fig5c_linear_spring",
                 "fig6_bistable_latch", "fig6e_reversible_latch", "fig6f_control_module"):
        assert stem in names


def test_fig1f_beams_carry_table_s1_designs_2_and_3():
    d = _load("fig1f_selective_beams.acl")
    radii = sorted(o.radius for c in d.capsules for o in c.orifices)
    assert radii == pytest.approx([7.75 * UM, 13 * UM])
    freqs = {t.frequency for p in d.programs for s in p.steps if s.kind == "drive" for t in s.drive.tones}
    assert freqs == {85e3, 170e3}


def test_fig2_capsule_is_at_least_50_um_above_the_substrate():
    d = _load("fig2_vertical_cantilever.acl")
    cap = d.capsule("act")
    bottom = cap.center[2] - cap.cavity.height / 2 - cap.cavity.wall
    assert bottom >= 50 * UM - 1e-12
    assert d.observe("delta").kind == "displacement"


def test_fig2_ramp_increases_the_voltage_at_125_khz():
    steps = [s for s in _load("fig2_vertical_cantilever.acl").program("ramp").steps if s.kind == "drive"]
    volts = [s.drive.tones[0].amplitude for s in steps]
    assert volts == sorted(volts) and len(set(volts)) == len(volts) > 3
    assert {s.drive.tones[0].frequency for s in steps} == {125e3}


def test_fig3_programs_follow_rectangle_circle_and_text():
    d = _load("fig3_three_orifice.acl")
    shapes = {p: {s.path.shape for s in d.program(p).steps} for p in ("rectangle", "circle", "epfl")}
    assert shapes == {"rectangle": {"rectangle"}, "circle": {"circle"}, "epfl": {"text"}}
    assert d.program("epfl").steps[0].path.text == "EPFL"
    assert sorted(o.radius for o in d.capsule("m").orifices) == pytest.approx([7.5 * UM, 9.5 * UM, 15 * UM])


@pytest.mark.parametrize("gap_um", [20, 40, 60, 80])
def test_fig4_set_gap_moves_the_orifices_apart_by_exactly_gap(gap_um):
    d = _load("fig4_facing_pair.acl", gap=f"{gap_um} um")
    assert _dist(_orifice(d, "left.jet").center, _orifice(d, "right.jet").center) == pytest.approx(gap_um * UM)
    assert d.observe("d").kind == "gap"


def test_fig4_orifices_face_each_other():
    d = _load("fig4_facing_pair.acl")
    assert _orifice(d, "left.jet").normal == (1.0, 0.0, 0.0)
    assert _orifice(d, "right.jet").normal == (-1.0, 0.0, 0.0)


def test_fig4h_cavity_radii_and_orifices_match_the_paper():
    d = _load("fig4h_unequal_pair.acl")
    assert sorted(c.cavity.radius for c in d.capsules) == pytest.approx([17.5 * UM, 25 * UM])
    assert [o.radius for c in d.capsules for o in c.orifices] == pytest.approx([10 * UM, 10 * UM])
    assert {p.name: p.steps[0].drive.tones[0].frequency for p in d.programs} == {"attract": 85e3, "repel": 125e3}


def test_fig5c_spring_has_the_fig_s8_stiffness_and_the_top_capsule_is_fixed():
    d = _load("fig5c_linear_spring.acl")
    assert d.spring("flexure").stiffness == pytest.approx(0.7563e-9 / 1e-6)
    assert d.mount_of("top").kind == "fix"
    assert d.mount_of("bottom").target_kind == "spring"


def test_fig5a_moving_capsules_are_tied_by_elastic_trusses():
    """Fig. 5a-b: each arm capsule is tied to its anchored partner by an elastic truss (an acl spring along the
    line of attraction), so the arm bends progressively (a rigid truss would hold it still)."""
    d = _load("fig5a_gripper.acl")
    links = {(j.a, j.b, j.element_kind) for j in d.joints if j.kind == "link"}
    assert links == {("left", "mid_left", "spring"), ("right", "mid_right", "spring")}


@pytest.mark.parametrize("theta", [30, 45, 60])
def test_fig6_set_theta_gives_each_prototype_of_table_s2(theta):
    d = _load("fig6_bistable_latch.acl", theta=f"{theta} deg")
    (latch,) = d.latches
    assert math.degrees(latch.angle) == pytest.approx(theta)
    assert d.mount_of("act").target == latch.name
    assert [s.kind for s in d.program("switch").steps][0] == "switch"


def test_fig6e_capsules_share_a_cavity_size_and_differ_in_orifice():
    d = _load("fig6e_reversible_latch.acl")
    f, b = d.capsule("forward"), d.capsule("backward")
    assert f.cavity.volume == pytest.approx(b.cavity.volume, rel=0.02)
    assert f.orifices[0].radius != b.orifices[0].radius
    assert f.orifices[0].normal == tuple(-x for x in b.orifices[0].normal)


def test_flextensional_has_two_pairs():
    d = _load("figS6_flextensional.acl")
    assert len(d.capsules) == 4 and len(d.beams) == 4


def _doc_blocks():
    doc = (EXAMPLES[0].parents[1] / "docs" / "language.md").read_text()
    return re.findall(r"```acl\n(.*?)```", doc, re.S)


def test_language_doc_has_checked_examples():
    assert _doc_blocks()


@pytest.mark.parametrize("i", range(len(_doc_blocks())))
def test_language_doc_acl_block_resolves(tmp_path, i):
    f = tmp_path / f"doc_{i}.acl"
    f.write_text(_doc_blocks()[i])
    acl.load(str(f))

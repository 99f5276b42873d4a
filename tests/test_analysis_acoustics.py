"""Design-level acoustics (acl.analysis.acoustics) on designs built from acl.design.model."""
from __future__ import annotations

import math

import numpy as np
import pytest

from acl.analysis import acoustics as A
from acl.analysis.selectivity import selectivity
from acl.design.model import (
    Capsule, Cavity, Design, Drive, Medium, Orifice, Tone, Transducer,
)
from acl.diagnostics import Span
from acl.physics.constants import DEFAULT_GAIN_PA_PER_V, WATER_20C

SP = Span(file="test.acl", line=1, column=1)
UM = 1e-6
# Capsules are built 10 mm above the substrate (z = 0): far from the wall, where its image sources
# change a single bubble's mass by ~2e-5 relative (acl.physics.coupling), i.e. the free-field bubble.
FAR = 10e-3


def _up(center):
    return (center[0], center[1], center[2] + FAR)


def cylinder(name, cavity_radius, height, orifice_radius, center=(0.0, 0.0, 0.0),
             normal=(1.0, 0.0, 0.0), q=None, gamma=None):
    """Cylindrical capsule with one orifice on its side wall facing ``normal``."""
    cav = Cavity(shape="cylinder", volume=math.pi * cavity_radius**2 * height,
                 radius=cavity_radius, height=height)
    center = _up(center)
    oc = tuple(np.add(center, np.multiply(normal, cavity_radius + cav.wall)))
    o = Orifice(name="jet", radius=orifice_radius, normal=normal, center=oc, span=SP)
    return Capsule(name=name, cavity=cav, orifices=(o,), center=center, quality_factor=q,
                   thrust_coefficient=gamma, span=SP)


def by_volume(name, volume, orifice_radius, center=(0.0, 0.0, 0.0), normal=(1.0, 0.0, 0.0)):
    cav = Cavity(shape="volume", volume=volume)
    center = _up(center)
    oc = tuple(np.add(center, np.multiply(normal, 30 * UM)))
    o = Orifice(name="jet", radius=orifice_radius, normal=normal, center=oc, span=SP)
    return Capsule(name=name, cavity=cav, orifices=(o,), center=center, span=SP)


def prism():
    """Fig. 3a: equilateral prism (side 60 um, height 60 um), orifices 15, 9.5, 7.5 um on its faces."""
    side, h = 60 * UM, 60 * UM
    cav = Cavity(shape="prism", volume=math.sqrt(3) / 4 * side**2 * h, side=side, height=h)
    inradius = side / (2 * math.sqrt(3))
    orifices = []
    for k, (nm, r) in enumerate([("o1", 15 * UM), ("o2", 9.5 * UM), ("o3", 7.5 * UM)]):
        ang = math.pi / 2 + 2 * math.pi * k / 3
        n = (math.cos(ang), math.sin(ang), 0.0)
        orifices.append(Orifice(name=nm, radius=r, normal=n,
                                center=_up(tuple(np.multiply(n, inradius))), span=SP))
    return Capsule(name="tri", cavity=cav, orifices=tuple(orifices), center=_up((0.0, 0.0, 0.0)), span=SP)


def tone(f_hz, volts=1.0):
    return Drive(tones=(Tone(frequency=f_hz, amplitude=volts),))


DESIGN_1 = Design(file="d1", capsules=(by_volume("d1", 6.51e4 * UM**3, 10 * UM),))


# --- modes -----------------------------------------------------------------------------------


def test_capsule_modes_reproduce_table_s1_design_1():
    # Paper Table S1, design 1: 122 kHz; tolerance 3 %.
    (mode,) = A.capsule_modes(DESIGN_1, "d1")
    assert abs(mode.frequency_hz / 122e3 - 1) < 0.03
    assert mode.dominant_orifice == "jet" and mode.share == 1.0


def test_missing_medium_and_transducer_fall_back_to_documented_defaults_and_say_so():
    (mode,) = A.capsule_modes(DESIGN_1, "d1")
    assert any("water" in n for n in mode.notes)
    assert any("transducer" in n for n in mode.notes)
    gain, outside = A.drive_gain(DESIGN_1, [1e5])
    assert gain[0] == DEFAULT_GAIN_PA_PER_V and not outside[0]


def test_declared_medium_changes_the_frequency():
    soapy = Medium(name="soapy", density=WATER_20C.density, viscosity=WATER_20C.viscosity,
                   sound_speed=WATER_20C.sound_speed, surface_tension=0.04,
                   ambient_pressure=WATER_20C.ambient_pressure, polytropic_index=1.0, span=SP)
    d = DESIGN_1.model_copy(update={"medium": soapy})
    assert A.capsule_modes(d, "d1")[0].frequency_hz < 0.9 * A.capsule_modes(DESIGN_1, "d1")[0].frequency_hz
    assert A.capsule_modes(d, "d1")[0].notes[0].startswith("no transducer")


def test_prism_modes_are_named_by_their_orifice_largest_first():
    d = Design(file="fig3", capsules=(prism(),))
    modes = A.capsule_modes(d, "tri")
    assert [m.dominant_orifice for m in modes] == ["o1", "o2", "o3"]
    assert all(m.share >= 0.70 for m in modes)


def test_declared_quality_factor_is_reported_as_declared():
    d = Design(file="q", capsules=(cylinder("c", 25 * UM, 35 * UM, 10 * UM, q=33.0),))
    (mode,) = A.capsule_modes(d, "c")
    assert mode.q == 33.0 and mode.q_declared


# --- responses and thrust ---------------------------------------------------------------------


def test_orifice_response_scales_with_transducer_table():
    tr = Transducer(name="t", max_voltage=20.0, band=(50e3, 200e3),
                    gain_frequencies=(50e3, 200e3), gain_pa_per_v=(200.0, 200.0), span=SP)
    d = DESIGN_1.model_copy(update={"transducer": tr})
    h_flat = A.orifice_response(DESIGN_1, "d1", [120e3])
    h_tab = A.orifice_response(d, "d1", [120e3])
    np.testing.assert_allclose(h_tab, h_flat * 200.0 / DEFAULT_GAIN_PA_PER_V)


def test_thrust_pushes_capsule_opposite_to_orifice_normal():
    f = A.thrust_vectors(DESIGN_1, tone(125e3, 5.0))["d1"]
    assert f[0] < 0 and abs(f[1]) == 0 and abs(f[2]) == 0


def test_thrust_is_quadratic_in_voltage():
    f1 = A.thrust_vectors(DESIGN_1, tone(125e3, 1.0))["d1"]
    f3 = A.thrust_vectors(DESIGN_1, tone(125e3, 3.0))["d1"]
    np.testing.assert_allclose(f3, 9 * f1, rtol=1e-12)


def test_tones_at_different_frequencies_add_in_power():
    both = Drive(tones=(Tone(frequency=100e3, amplitude=2.0), Tone(frequency=125e3, amplitude=3.0)))
    f = A.thrust_vectors(DESIGN_1, both)["d1"]
    f_sum = A.thrust_vectors(DESIGN_1, tone(100e3, 2.0))["d1"] + A.thrust_vectors(DESIGN_1, tone(125e3, 3.0))["d1"]
    np.testing.assert_allclose(f, f_sum, rtol=1e-12)


def test_declared_thrust_coefficient_sets_thrust_at_first_resonance():
    d = Design(file="g", capsules=(cylinder("c", 25 * UM, 33 * UM, 10 * UM, gamma=0.027e-9),))
    f1 = A.capsule_modes(d, "c")[0].frequency_hz
    f = np.linalg.norm(A.thrust_vectors(d, tone(f1, 4.0))["c"])
    assert f == pytest.approx(0.027e-9 * 16, rel=1e-9)


def test_predicted_gamma_of_design_1_is_within_an_order_of_magnitude_of_the_paper():
    # Paper Eq. (3) fit: gamma = 0.027 nN/V^2 at 125 kHz (design 1).  Predicted with the default
    # 100 Pa/V gain (not fitted): documented ratio ~0.19; bound: within a factor 10.
    gamma = np.linalg.norm(A.thrust_vectors(DESIGN_1, tone(125e3, 1.0))["d1"])
    assert 0.1 < gamma / 0.027e-9 < 10


def test_selectivity_follows_fig_1f_two_orifice_sizes():
    # Fig. 1f / Table S1 designs 2 and 3: 85 kHz drives design 2, 170 kHz drives design 3.
    d = Design(file="fig1f", capsules=(
        by_volume("d2", 1.12e5 * UM**3, 13 * UM, center=(0, 0, 0)),
        by_volume("d3", 1.13e5 * UM**3, 7.75 * UM, center=(0, 200 * UM, 0)),
    ))
    s = selectivity(d, [85e3, 170e3])
    assert s.capsules == ("d2", "d3")
    assert s.share[0, 0] > 0.8 and s.share[1, 1] > 0.8


# --- pairs --------------------------------------------------------------------------------------


def facing_pair(gap, big=(25 * UM, 35 * UM), small=(17.5 * UM, 24.5 * UM), q=None):
    """Fig. 4h: cavity radii 25 / 17.5 um (heights 35 / 24.5 um, chosen), orifices 10 um, facing."""
    a = cylinder("big", *big, 10 * UM, center=(0.0, 0.0, 0.0), normal=(1.0, 0.0, 0.0), q=q)
    xb = big[0] + small[0] + 2 * 2 * UM + gap
    b = cylinder("small", *small, 10 * UM, center=(xb, 0.0, 0.0), normal=(-1.0, 0.0, 0.0), q=q)
    return Design(file="fig4h", capsules=(a, b))


def test_fig4h_with_coupling_q_40_at_40_um_still_attracts_at_125_khz():
    # Issue 10's coupled-monopole estimate: at a 40 um gap the neighbour's field pulls the two
    # responses together, so even Q = 40 leaves the 125 kHz phase difference near -35 deg (attract).
    # Sign and a +-25 deg band around that estimate (the paper's Fig. 4h repulsion is NOT reproduced
    # here; docs/physics.md part A section 6).
    d = facing_pair(40 * UM, q=40.0)
    (p125,) = A.pair_forces(d, tone(125e3))
    assert p125.attract and -60 < math.degrees(p125.phase_difference) < -10


def test_fig4h_signs_reproduced_with_q_40_and_weak_coupling():
    # Paper Fig. 4h: attraction at 85 kHz, repulsion at 125 kHz.  Reproduced by the coupled model
    # with Q = 40 declared once the pair is far enough apart (160 um) for the coupling to be weak.
    d = facing_pair(160 * UM, q=40.0)
    (p85,) = A.pair_forces(d, tone(85e3))
    (p125,) = A.pair_forces(d, tone(125e3))
    assert p85.attract and abs(p85.phase_difference) < math.pi / 2
    assert not p125.attract and abs(p125.phase_difference) > math.pi / 2


def test_fig4h_predicted_damping_is_too_strong_to_give_repulsion():
    # Documented disagreement (docs/physics.md (part A)): predicted Q ~ 6.6 keeps the phase
    # difference at 125 kHz below 90 deg at any gap, so the model predicts attraction at both.
    for gap in (40 * UM, 160 * UM):
        d = facing_pair(gap)
        (p125,) = A.pair_forces(d, tone(125e3))
        assert p125.attract
    assert A.capsule_modes(d, "big")[0].q < 10


def test_pair_forces_are_equal_and_opposite():
    d = facing_pair(40 * UM, q=40.0)
    (p,) = A.pair_forces(d, tone(125e3, 3.0))
    np.testing.assert_allclose(p.force_on_a, -p.force_on_b)


def _identical_pair_dc(radius, f_hz, volume=6.51e4 * UM**3):
    a = by_volume("a", volume, radius, center=(0, 0, 0), normal=(1, 0, 0))
    b = by_volume("b", volume, radius, center=(100 * UM, 0, 0), normal=(-1, 0, 0))
    (p,) = A.pair_forces(Design(file="pair", capsules=(a, b)), tone(f_hz))
    assert p.attract and abs(p.phase_difference) < 1e-9
    return p.critical_distance


@pytest.mark.parametrize("radius, f_hz", [(7 * UM, 85e3), (14 * UM, 85e3), (7 * UM, 170e3), (14 * UM, 170e3)])
def test_identical_pair_critical_distance_follows_the_streaming_law(radius, f_hz):
    # The streaming law (acl.physics.forces.thrust_magnitude: Stuart 1966 / Riley 2001) gives, for
    # two identical coupled bubbles in phase, d_c = R^2 / (delta sqrt(192 C_s)) whatever the coupling
    # (both forces scale with |dV|^2).  Away from the calibration point (10 um, 125 kHz); 1e-9 rel.
    from acl.physics.constants import STREAMING_CONSTANT
    from acl.physics.forces import law_critical_distance

    law = law_critical_distance(radius, 2 * math.pi * f_hz, WATER_20C.density, WATER_20C.viscosity,
                                STREAMING_CONSTANT)
    assert _identical_pair_dc(radius, f_hz) == pytest.approx(law, rel=1e-9)


def test_critical_distance_scales_as_radius_squared_and_root_frequency():
    # d_c ~ R^2 / delta ~ R^2 sqrt(f) (the law's own scaling; not the calibration point); 1e-9 rel.
    assert _identical_pair_dc(14 * UM, 85e3) / _identical_pair_dc(7 * UM, 85e3) == pytest.approx(4.0, rel=1e-9)
    assert _identical_pair_dc(7 * UM, 170e3) / _identical_pair_dc(7 * UM, 85e3) == pytest.approx(math.sqrt(2), rel=1e-9)


def test_moving_a_capsule_closer_strengthens_bjerknes_attraction():
    d = facing_pair(60 * UM, q=40.0)
    rest = A.pair_forces(d, tone(85e3))[0]
    moved = A.pair_forces(d, tone(85e3), positions={"small": (d.capsule("small").center[0] - 30 * UM, 0, FAR)})[0]
    assert moved.distance == pytest.approx(rest.distance - 30 * UM)
    assert moved.attraction > rest.attraction > 0


def test_force_model_sums_thrust_bjerknes_and_drag_for_every_capsule():
    d = facing_pair(40 * UM, q=40.0)
    drive = tone(85e3, 2.0)
    total = A.force_model(d, None, drive)
    assert set(total) == {"big", "small"} and all(v.shape == (3,) for v in total.values())
    thrust = A.thrust_vectors(d, drive)
    (pair,) = A.pair_forces(d, drive)
    drag_on_small = total["small"] - thrust["small"] - pair.force_on_b
    assert drag_on_small[0] > 0           # big's jet (along +x) pushes small away along +x


def test_capsule_without_orifices_has_no_modes_and_no_thrust():
    blind = Capsule(name="blind", cavity=Cavity(shape="volume", volume=1e-13), orifices=(),
                    center=(0.0, 0.0, 0.0), span=SP)
    d = Design(file="blind", capsules=(blind, by_volume("d1", 6.51e4 * UM**3, 10 * UM, center=(100 * UM, 0, 0))))
    assert A.capsule_modes(d, "blind") == []
    total = A.force_model(d, None, tone(125e3, 3.0))
    np.testing.assert_array_equal(total["blind"], np.zeros(3))


def test_empty_drive_gives_zero_forces():
    d = facing_pair(40 * UM)
    total = A.force_model(d, None, Drive(tones=()))
    assert all(not v.any() for v in total.values())

"""Acoustic analysis of a design: capsule modes, orifice responses, thrust, pair forces, selectivity.

Turns :mod:`acl.design.model` objects into calls of :mod:`acl.physics.resonance`,
:mod:`acl.physics.transducer` and :mod:`acl.physics.forces`.  Per-capsule modal data are cached on
a hashable key (geometry + medium), so the equilibrium solver and the fitter can call
:func:`force_model` in inner loops.

Defaults: a design without ``medium`` uses :data:`acl.physics.constants.WATER_20C`; without
``transducer`` a flat :data:`acl.physics.constants.DEFAULT_GAIN_PA_PER_V`.  :func:`defaults_used`
lists what was assumed, and the result objects carry the same notes.

Geometry: a capsule translates rigidly (no rotation) when its centre is moved in ``positions``;
its orifice centres move with it.  Pair distances are between orifice centres (the vibrating
surfaces, paper Eq. 3).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Mapping, Sequence

import numpy as np

from acl.design.model import Capsule, Cavity, Design, Drive
from acl.analysis import effects as EF
from acl.physics import constants as C
from acl.physics import effects as PE
from acl.physics.forces import bjerknes_vectors, jet_drag, thrust_magnitude
from acl.physics.resonance import BubbleModes, capsule_modes as _physics_modes, volume_response
from acl.physics.transducer import pressure_per_volt


# ----------------------------------------------------------------------------------------------
# Results
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Mode:
    """One natural mode of a capsule: frequency, Q, which interface moves and how much."""

    frequency_hz: float
    q: float
    dominant_orifice: str
    share: float                               # |dV| of the dominant interface / sum of |dV|
    shares: dict = field(default_factory=dict)  # orifice name -> share
    q_declared: bool = False                   # Q from Capsule.quality_factor
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class PairForce:
    """Interaction of two capsules (sum over tones and orifice pairs).

    ``force_on_a``/``force_on_b`` are the Bjerknes vectors (N, equal and opposite); ``attraction``
    their attraction-positive magnitude along the line of centres; ``phase_difference`` (rad, in
    (-pi, pi]) between the dominant interfaces at the strongest tone; ``critical_distance`` (m)
    where Bjerknes attraction would balance the thrusts pushing the pair apart (paper Eq. 3), None
    where the pair does not attract or is not pushed apart.
    """

    a: str
    b: str
    force_on_a: np.ndarray
    force_on_b: np.ndarray
    attraction: float
    attract: bool
    phase_difference: float
    distance: float
    critical_distance: float | None
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Selectivity:
    """Thrust per V^2 of each capsule vs frequency and its share of the total at each frequency."""

    frequencies: np.ndarray
    capsules: tuple[str, ...]
    thrust_per_v2: np.ndarray      # (n_capsules, F) N/V^2
    share: np.ndarray              # (n_capsules, F)
    outside_table: np.ndarray      # (F,) bool: transducer gain extrapolated
    notes: tuple[str, ...] = ()


# ----------------------------------------------------------------------------------------------
# Environment (medium, transducer) with documented fallbacks
# ----------------------------------------------------------------------------------------------


def _medium(design: Design) -> C.MediumConstants:
    m = design.medium
    if m is None:
        return C.WATER_20C
    return C.MediumConstants(
        density=m.density, viscosity=m.viscosity, sound_speed=m.sound_speed,
        surface_tension=m.surface_tension, ambient_pressure=m.ambient_pressure,
        polytropic_index=m.polytropic_index, gas_thermal_diffusivity=m.gas_thermal_diffusivity,
    )


def defaults_used(design: Design) -> tuple[str, ...]:
    """Notes naming every documented default the acoustic analysis of ``design`` relies on."""
    notes = []
    if design.medium is None:
        notes.append("no medium declared: water at 20 C assumed (acl.physics.constants.WATER_20C)")
    if design.transducer is None:
        notes.append(f"no transducer declared: flat {C.DEFAULT_GAIN_PA_PER_V:g} Pa/V assumed")
    return tuple(notes)


def drive_gain(design: Design, frequencies) -> tuple[np.ndarray, np.ndarray]:
    """Transducer gain (Pa/V) at ``frequencies`` and the mask of frequencies outside its table."""
    f = np.asarray(frequencies, float)
    t = design.transducer
    if t is None:
        return np.full(f.shape, C.DEFAULT_GAIN_PA_PER_V), np.zeros(f.shape, bool)
    return pressure_per_volt(f, t.gain_frequencies, t.gain_pa_per_v)


def effect_pressure_factor(design: Design, f, vtot: float | None = None) -> np.ndarray:
    """Factor on the drive pressure from declared transducer_gain (gain, tilt) and drive_saturation (at total amplitude ``vtot``).

    Formulas of :mod:`acl.physics.effects` (the fit's forward model uses the same); 1 without effects.
    """
    f = np.asarray(f, float)
    out = np.ones(f.shape)
    tg = EF.coefficients(design, "transducer_gain")
    if tg:
        out = out * tg["gain"]
        if tg["gain_slope"] and math.isfinite(tg["f_ref"]):
            out = out * PE.gain_tilt(f, tg["f_ref"], tg["gain_slope"])
    sat = EF.coefficients(design, "drive_saturation")
    if sat and vtot is not None:
        out = out * PE.saturation(vtot, sat["inv_vsat2"])
    return out


def substrate_factor(design: Design, capsule) -> float:
    """Force factor of a declared substrate_proximity at the capsule's (first) orifice height at rest; 1 without it."""
    sp = EF.coefficients(design, "substrate_proximity")
    if not sp or sp["h_substrate"] <= 0:
        return 1.0
    cap = _capsule(design, capsule)
    z = cap.orifices[0].center[2] if cap.orifices else cap.center[2]
    return float(PE.substrate_factor(np.asarray(z, float), np.asarray(sp["h_substrate"], float)))


# ----------------------------------------------------------------------------------------------
# Capsule modal data (cached)
# ----------------------------------------------------------------------------------------------


def thermal_radius(cavity: Cavity) -> float:
    """Length for the thermal model: 3 V / S (sphere-equivalent) of the gas, or the equal-volume sphere radius."""
    v = cavity.volume
    if cavity.shape == "cylinder" and cavity.radius and cavity.height:
        s = 2 * math.pi * cavity.radius**2 + 2 * math.pi * cavity.radius * cavity.height
        return 3 * v / s
    if cavity.shape == "prism" and cavity.side and cavity.height:
        s = math.sqrt(3) / 2 * cavity.side**2 + 3 * cavity.side * cavity.height
        return 3 * v / s
    return (3 * v / (4 * math.pi)) ** (1 / 3)


def _outer_radius(capsule: Capsule) -> float:
    """Equal-volume sphere radius of the cavity plus its wall: the body the jets of others drag."""
    return (3 * capsule.cavity.volume / (4 * math.pi)) ** (1 / 3) + capsule.cavity.wall


@lru_cache(maxsize=4096)
def _modes_for(volume: float, radii: tuple[float, ...], r_th: float, medium: tuple,
               q_override: float | None, n_modes: int) -> BubbleModes:
    rho, mu, c, sigma, p0, kappa, diff, gamma = medium
    return _physics_modes(volume, np.asarray(radii), rho, sigma, p0, kappa, mu, c, r_th,
                          heat_capacity_ratio=gamma, thermal_diffusivity=diff,
                          quality_override=q_override, n_modes=n_modes)


def _capsule(design: Design, capsule) -> Capsule:
    return capsule if isinstance(capsule, Capsule) else design.capsule(capsule)


def modal_data(design: Design, capsule, n_modes: int = C.DEFAULT_MEMBRANE_MODES) -> BubbleModes:
    """The physics-level modes of ``capsule`` (all Rayleigh-Ritz modes), cached per geometry and medium."""
    cap = _capsule(design, capsule)
    radii = tuple(o.radius for o in cap.orifices)
    return _modes_for(cap.cavity.volume, radii, thermal_radius(cap.cavity),
                      _medium(design).as_tuple(), cap.quality_factor, n_modes)


def capsule_modes(design: Design, capsule, n_modes: int = C.DEFAULT_MEMBRANE_MODES) -> list[Mode]:
    """The fundamental modes of ``capsule``: one per orifice, ascending in frequency."""
    cap = _capsule(design, capsule)
    md = modal_data(design, cap, n_modes)
    names = [o.name for o in cap.orifices]
    share = md.share
    notes = defaults_used(design)
    out = []
    for n in range(len(names)):
        k = int(np.argmax(share[:, n]))
        out.append(Mode(frequency_hz=float(md.frequency[n]), q=float(md.quality[n]),
                        dominant_orifice=names[k], share=float(share[k, n]),
                        shares={nm: float(share[i, n]) for i, nm in enumerate(names)},
                        q_declared=cap.quality_factor is not None, notes=notes))
    return out


def orifice_response(design: Design, capsule, frequencies) -> np.ndarray:
    """Complex inward volume amplitude (m^3 per V peak) of each orifice, shape (F, n_orifices).

    Transducer gain included (flat-extrapolated outside its table: see :func:`drive_gain`).
    Phase convention of :func:`acl.physics.resonance.volume_response`.
    """
    f = np.atleast_1d(np.asarray(frequencies, float))
    gain, _ = drive_gain(design, f)
    return volume_response(modal_data(design, capsule), f) * gain[:, None]


# ----------------------------------------------------------------------------------------------
# Forces
# ----------------------------------------------------------------------------------------------


def _tones(drive: Drive) -> tuple[np.ndarray, np.ndarray]:
    f = np.array([t.frequency for t in drive.tones], float)
    v = np.array([t.amplitude for t in drive.tones], float)
    return f, v


def _normals(cap: Capsule) -> np.ndarray:
    n = np.array([o.normal for o in cap.orifices], float).reshape(-1, 3)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def _orifice_thrust(design: Design, cap: Capsule, f: np.ndarray, volts: np.ndarray) -> np.ndarray:
    """Thrust magnitude (N) of each orifice for each tone, shape (T, n_orifices), unscaled."""
    dv = orifice_response(design, cap, f) * volts[:, None]
    return _thrust_from_volumes(design, cap, f, dv)


def _thrust_from_volumes(design: Design, cap: Capsule, f: np.ndarray, dv: np.ndarray) -> np.ndarray:
    radii = np.array([o.radius for o in cap.orifices])
    return thrust_magnitude(dv, radii[None, :], 2 * np.pi * f[:, None], _medium(design).density,
                            C.STREAMING_CONSTANT)


def _thrust_scale(design: Design, cap: Capsule) -> float:
    """Factor that makes predicted thrust match a declared Capsule.thrust_coefficient at mode 1."""
    if cap.thrust_coefficient is None:
        return 1.0
    f1 = modal_data(design, cap).frequency[:1]
    per_v2 = _orifice_thrust(design, cap, f1, np.ones(1))       # (1, n_or), N at 1 V
    total = np.linalg.norm((per_v2[0][:, None] * -_normals(cap)).sum(axis=0))
    return cap.thrust_coefficient / total if total > 0 else 1.0


@dataclass(frozen=True)
class _DriveState:
    """One capsule under one drive: tone frequencies, orifice volume amplitudes, thrusts."""

    cap: Capsule
    f: np.ndarray               # (T,) Hz
    volumes: np.ndarray         # (T, n_or) complex m^3
    thrust: np.ndarray          # (n_or,) N, summed over tones (power), declared scale applied
    normals: np.ndarray         # (n_or, 3) outward unit normals
    offsets: np.ndarray         # (n_or, 3) orifice centre - capsule centre (rest)

    def orifices_at(self, centre: np.ndarray) -> np.ndarray:
        return self.offsets + centre

    @property
    def thrust_vector(self) -> np.ndarray:
        return (self.thrust[:, None] * -self.normals).sum(axis=0)


_LAST_STATES: list = []   # [(design, drive, states)]: identity cache for solver inner loops


def _drive_states(design: Design, drive: Drive) -> dict[str, _DriveState]:
    """Per-capsule drive state; the last (design, drive) pair is reused by identity (both frozen)."""
    if _LAST_STATES and _LAST_STATES[0][0] is design and _LAST_STATES[0][1] is drive:
        return _LAST_STATES[0][2]
    states = _compute_drive_states(design, drive)
    _LAST_STATES[:] = [(design, drive, states)]
    return states


def _compute_drive_states(design: Design, drive: Drive) -> dict[str, _DriveState]:
    f, v = _tones(drive)
    out = {}
    for cap in design.capsules:
        normals = _normals(cap)
        offsets = (np.array([o.center for o in cap.orifices], float).reshape(-1, 3)
                   - np.asarray(cap.center, float))
        if f.size == 0:
            vols = np.zeros((0, len(cap.orifices)), complex)
            thrust = np.zeros(len(cap.orifices))
        else:
            # declared effects scale the pressure after the thrust calibration (which is at the base model)
            gain = effect_pressure_factor(design, f, float(v.sum()))
            vols = orifice_response(design, cap, f) * (v * gain)[:, None]
            thrust = (_thrust_from_volumes(design, cap, f, vols).sum(axis=0) * _thrust_scale(design, cap)
                      * substrate_factor(design, cap))
        out[cap.name] = _DriveState(cap, f, vols, thrust, normals, offsets)
    return out


def thrust_vectors(design: Design, drive: Drive) -> dict[str, np.ndarray]:
    """Streaming thrust (N, 3-vector) on each capsule: sum over orifices of -|F| n_outward."""
    return {name: st.thrust_vector for name, st in _drive_states(design, drive).items()}


def _centres(design: Design, positions: Mapping[str, Sequence[float]] | None) -> dict[str, np.ndarray]:
    pos = {c.name: np.asarray(c.center, float) for c in design.capsules}
    if positions:
        for k, p in positions.items():
            pos[k] = np.asarray(p, float)
    return pos


def pair_forces(design: Design, drive: Drive,
                positions: Mapping[str, Sequence[float]] | None = None) -> list[PairForce]:
    """Secondary Bjerknes force of every capsule pair (sum over tones and orifice pairs)."""
    return _pair_forces(design, _drive_states(design, drive), _centres(design, positions))


def _pair_forces(design: Design, states: dict[str, _DriveState],
                 pos: dict[str, np.ndarray]) -> list[PairForce]:
    rho = _medium(design).density
    notes = defaults_used(design)
    names = [c.name for c in design.capsules]
    out = []
    for i, na in enumerate(names):
        for nb in names[i + 1:]:
            sa, sb = states[na], states[nb]
            va, vb, f = sa.volumes, sb.volumes, sa.f
            pa, pb = sa.orifices_at(pos[na]), sb.orifices_at(pos[nb])
            omega = 2 * np.pi * f
            on_a, _ = bjerknes_vectors(omega[:, None, None], va[:, :, None], pa[None, :, None, :],
                                       vb[:, None, :], pb[None, None, :, :], rho)
            fa = on_a.reshape(-1, 3).sum(axis=0)
            if design.effects:   # ~ product of the two volume amplitudes: geometric mean (as acl.fit.forward)
                fa = fa * math.sqrt(substrate_factor(design, sa.cap) * substrate_factor(design, sb.cap))
                bs = EF.coefficients(design, "bjerknes_scale")
                if bs is not None:       # a fitted Bjerknes coefficient (paper Eq. 3 alpha) relative to the physics
                    fa = fa * bs["factor"]
            line = pos[nb] - pos[na]
            dist = float(np.linalg.norm(line))
            unit = line / dist if dist > 0 else np.zeros(3)
            attraction = float(fa @ unit)
            if f.size and va.size and vb.size:   # phase of the dominant interfaces, strongest tone
                t = int(np.argmax(np.abs(va).max(axis=1) * np.abs(vb).max(axis=1)))
                ia, ib = int(np.argmax(np.abs(va[t]))), int(np.argmax(np.abs(vb[t])))
                dphi = float(np.angle(va[t, ia] * np.conj(vb[t, ib])))
                gap = float(np.linalg.norm(pb[ib] - pa[ia]))
            else:
                dphi, gap = 0.0, dist
            # reduced law (paper Eq. 3): alpha = attraction d^2, 2 gamma = thrusts pushing apart
            gamma2 = float(sa.thrust_vector @ -unit + sb.thrust_vector @ unit)
            alpha = attraction * gap**2
            dc = math.sqrt(alpha / gamma2) if alpha > 0 and gamma2 > 0 else None
            out.append(PairForce(a=na, b=nb, force_on_a=fa, force_on_b=-fa,
                                 attraction=attraction, attract=attraction > 0,
                                 phase_difference=dphi, distance=gap, critical_distance=dc,
                                 notes=notes))
    return out


def force_model(design: Design, positions: Mapping[str, Sequence[float]] | None,
                drive: Drive) -> dict[str, np.ndarray]:
    """Total acoustic force (N, 3-vector) on each capsule: thrust + Bjerknes + drag in others' jets.

    ``positions`` maps capsule names to displaced centres (missing names stay at rest).  Tones at
    different frequencies add in power (cross terms average to zero).
    """
    pos = _centres(design, positions)
    states = _drive_states(design, drive)
    total = {name: st.thrust_vector for name, st in states.items()}
    for pf in _pair_forces(design, states, pos):
        total[pf.a] = total[pf.a] + pf.force_on_a
        total[pf.b] = total[pf.b] + pf.force_on_b
    for src_name, src in states.items():           # drag of each capsule's jets on the others
        if not np.any(src.thrust):
            continue
        origins = src.orifices_at(pos[src_name])
        for tgt in design.capsules:
            if tgt.name == src_name:
                continue
            x = pos[tgt.name][None, :] - origins
            dist = np.linalg.norm(x, axis=1)
            cos = np.einsum("ij,ij->i", x, src.normals) / dist
            drag = jet_drag(src.thrust, dist, cos, _outer_radius(tgt))
            total[tgt.name] = total[tgt.name] + (drag[:, None] * src.normals).sum(axis=0)
    nd = EF.coefficients(design, "neighbour_drag") if design.effects else None
    if nd and nd["inv_plateau"] > 0:
        # P (1 - delta/delta_p) with delta the capsule's displacement from rest (acl.physics.effects.drag_load)
        for c in design.capsules:
            delta = float(np.linalg.norm(pos[c.name] - np.asarray(c.center, float)))
            total[c.name] = PE.drag_load(total[c.name], delta, nd["inv_plateau"])
    return total


# Every term (thrust, Bjerknes, jet drag) is quadratic in the tone amplitudes (linear acoustics):
# callers scaling a whole drive by V may evaluate once and multiply by V^2.
force_model.quadratic_in_amplitude = True


def _saturating_force_model(design: Design, positions, drive: Drive) -> dict[str, np.ndarray]:
    """:func:`force_model` of a design with drive_saturation: forces are not quadratic in the amplitude."""
    return force_model(design, positions, drive)


_saturating_force_model.quadratic_in_amplitude = False


def force_model_for(design: Design):
    """The force model to hand to :mod:`acl.analysis.mechanics` for ``design``.

    :func:`force_model` itself, flagged ``quadratic_in_amplitude`` (evaluate once, scale by V^2),
    unless the design declares drive_saturation, whose pressure factor depends on V.
    """
    return _saturating_force_model if design.effect("drive_saturation") is not None else force_model


def selectivity(design: Design, frequencies) -> Selectivity:
    """Thrust magnitude per V^2 of every capsule over ``frequencies`` and its share per frequency."""
    f = np.atleast_1d(np.asarray(frequencies, float))
    rows = []
    for cap in design.capsules:
        per = (_orifice_thrust(design, cap, f, np.ones_like(f)) * _thrust_scale(design, cap)
               * effect_pressure_factor(design, f)[:, None] ** 2 * substrate_factor(design, cap))
        rows.append(np.linalg.norm((per[:, :, None] * -_normals(cap)[None]).sum(axis=1), axis=-1))
    t = np.array(rows).reshape(len(design.capsules), f.size)
    tot = t.sum(axis=0, keepdims=True)
    share = np.divide(t, tot, out=np.zeros_like(t), where=tot > 0)
    _, outside = drive_gain(design, f)
    return Selectivity(frequencies=f, capsules=tuple(c.name for c in design.capsules),
                       thrust_per_v2=t, share=share, outside_table=outside,
                       notes=defaults_used(design))

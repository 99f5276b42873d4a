"""Acoustic analysis of a design: capsule modes, orifice responses, thrust, pair forces, selectivity.

Turns :mod:`acl.design.model` objects into calls of :mod:`acl.physics.coupling` and
:mod:`acl.physics.forces`.  The medium, the transducer and the declared factors on the drive are
:mod:`acl.analysis.environment`; each capsule's bare modes, cached on a hashable key (geometry +
medium), are :mod:`acl.analysis.modal` (both re-exported here), so the equilibrium solver and the
fitter can call :func:`force_model` in inner loops.

Defaults: a design without ``medium`` uses :data:`acl.physics.constants.WATER_20C`; without
``transducer`` a flat :data:`acl.physics.constants.DEFAULT_GAIN_PA_PER_V`.  :func:`defaults_used`
lists what was assumed, and the result objects carry the same notes.

Geometry: a capsule translates rigidly (no rotation) when its centre is moved in ``positions``;
its orifice centres move with it.  Pair distances are between orifice centres (the vibrating
surfaces, paper Eq. 3).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

import numpy as np

from acl.design.model import Capsule, Design, Drive
from acl.analysis import effects as EF
from acl.analysis.environment import (_capsule, defaults_used, drive_gain, effect_pressure_factor,  # noqa: F401
                                      medium_constants, substrate_factor)
from acl.analysis.modal import modal_data, thermal_radius  # noqa: F401  (public here since before)
from acl.physics import constants as C
from acl.physics.coupling import (BubbleSystem, CoupledModes, build_system, coupled_modes as _physics_coupled_modes,
                                  coupled_response as _physics_coupled, ModeShapes, mode_shapes as _physics_mode_shapes,
                                  prepared_response, uncoupled_blocks)
from acl.physics.forces import (bjerknes_pair_sum, capsule_forces, capsule_pair_forces, critical_distance,
                                dominant_pair_phase, force_constants, interface_distances, interface_pairs, jet_lines,
                                neighbour_drag, thrust_magnitude)
from acl.physics.forces import pressure_terms  # noqa: F401  (public here since before; acl.analysis.tones)
from acl.physics.ties import TIE_RTOL, first_max


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
    q_predicted: float | None = None           # the physics' own Q (declared quality_factor ignored)
    phases: dict = field(default_factory=dict)  # interface -> 0 (in phase with the dominant one) or 180 deg


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


def _outer_radius(capsule: Capsule) -> float:
    """Equal-volume sphere radius of the cavity plus its wall: the body the jets of others drag."""
    return (3 * capsule.cavity.volume / (4 * math.pi)) ** (1 / 3) + capsule.cavity.wall


# ----------------------------------------------------------------------------------------------
# The coupled bubble system of a design (acl.physics.coupling)
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Layout:
    """All interfaces of a design in one order: capsule by capsule, orifice by orifice."""

    caps: tuple
    labels: tuple[str, ...]       # "capsule.orifice"
    body: np.ndarray              # (n,) capsule index
    offsets: np.ndarray           # (n, 3) orifice centre - capsule centre (rest)
    normals: np.ndarray           # (n, 3) outward unit normals
    radii: np.ndarray             # (n,)
    rest: np.ndarray              # (C, 3) capsule centres at rest
    onehot: np.ndarray            # (n, C)

    def points(self, centres: np.ndarray) -> np.ndarray:
        """Orifice centres (..., n, 3) for capsule centres (..., C, 3)."""
        return centres[..., self.body, :] + self.offsets


_LAYOUTS: list = []


def _layout(design: Design) -> _Layout:
    for d, lay in _LAYOUTS:
        if d is design:
            return lay
    caps = tuple(design.capsules)
    body, offs, nrm, rad, labels = [], [], [], [], []
    for c, cap in enumerate(caps):
        for o in cap.orifices:
            body.append(c)
            offs.append(np.subtract(o.center, cap.center))
            n = np.asarray(o.normal, float)
            nrm.append(n / np.linalg.norm(n))
            rad.append(o.radius)
            labels.append(f"{cap.name}.{o.name}")
    n = len(body)
    body = np.asarray(body, int)
    onehot = np.zeros((n, len(caps)))
    onehot[np.arange(n), body] = 1.0
    lay = _Layout(caps, tuple(labels), body, np.asarray(offs, float).reshape(n, 3),
                  np.asarray(nrm, float).reshape(n, 3), np.asarray(rad, float),
                  np.array([c.center for c in caps], float).reshape(len(caps), 3), onehot)
    _LAYOUTS[:] = ([(design, lay)] + _LAYOUTS)[:4]
    return lay


def _system(design: Design, capsules=None, predicted: bool = False) -> BubbleSystem:
    """The coupled system of ``capsules`` (indices; default all) at rest (the whole design's: cached)."""
    if capsules is None:
        return _whole_system(design, predicted)
    return _build_system(design, capsules, predicted)


def _per_design(fn):
    """Cache ``fn(design, *args)`` by the design's identity (designs with effects are not hashable)."""
    store: dict = {}

    def wrapper(design, *args):
        key = (id(design), args)
        hit = store.get(key)
        if hit is not None and hit[0] is design:
            return hit[1]
        val = fn(design, *args)
        if len(store) >= 512:
            store.pop(next(iter(store)))
        store[key] = (design, val)
        return val

    wrapper.__doc__ = fn.__doc__
    return wrapper


@_per_design
def _whole_system(design: Design, predicted: bool) -> BubbleSystem:
    return _build_system(design, None, predicted)


def _build_system(design: Design, capsules, predicted: bool) -> BubbleSystem:
    lay = _layout(design)
    idx = range(len(lay.caps)) if capsules is None else capsules
    modes, pts, rad = [], [], []
    rest_pts = lay.points(lay.rest)
    for c in idx:
        modes.append(modal_data(design, lay.caps[c], predicted=predicted))
        sel = lay.body == c
        pts.append(rest_pts[sel])
        rad.append(lay.radii[sel])
    return build_system(modes, pts, rad)


def _centres_array(design: Design, positions) -> np.ndarray:
    lay = _layout(design)
    out = lay.rest.copy()
    if positions:
        for i, c in enumerate(lay.caps):
            if c.name in positions:
                out[i] = np.asarray(positions[c.name], float)
    return out


_REST: list = []          # [(design, {frequency: (n,) complex response per pascal at rest})]: the last few designs
_ENGINE_REST: list = []   # [(design, {tone frequencies: (1, T, n) the force engine's response at rest})]
_REST_THRUST: list = []   # [(design, {(tone frequencies, pressures): (1, n) thrust per interface at rest})]


def _per_design_store(stores: list, design: Design) -> dict:
    """The cache dict of ``design`` in ``stores`` (kept for the last four designs, by identity)."""
    store = next((s for d, s in stores if d is design), None)
    if store is None:
        store = {}
        stores[:] = ([(design, store)] + stores)[:4]
    return store


def rest_response(design: Design, frequencies) -> np.ndarray:
    """Inward volume displacement per pascal (F, n) of every interface at rest (:func:`acl.physics.coupling.coupled_response`).

    Each frequency is solved once per design: the missing ones of a call in one batched solve, the
    rest from the cache (kept for the last four designs, by identity), so that lint rules, hovers and
    analyses asking for the same tones share one coupled solve.
    """
    f = np.atleast_1d(np.asarray(frequencies, float))
    store = _per_design_store(_REST, design)
    missing = np.unique(f[[x not in store for x in f.tolist()]]) if f.size else f
    if missing.size:
        med = medium_constants(design)
        u = _physics_coupled(_system(design), missing, med.density, med.sound_speed, C.SUBSTRATE_REFLECTION)
        for x, row in zip(missing.tolist(), u):
            row.setflags(write=False)
            store[x] = row
    n = _layout(design).radii.size
    return np.array([store[x] for x in f.tolist()], complex).reshape(f.size, n)


def coupled_response(design: Design, frequencies, positions=None) -> np.ndarray:
    """Inward volume amplitude (m^3 per V peak) of every interface of the design, (F, n) in :func:`interface_labels` order.

    All bubbles coupled through the liquid and the substrate's images (acl.physics.coupling);
    transducer gain included.  ``positions`` maps capsule names to displaced centres.
    """
    f = np.atleast_1d(np.asarray(frequencies, float))
    lay = _layout(design)
    if positions:
        med = medium_constants(design)
        pts = lay.points(_centres_array(design, positions))
        u = _physics_coupled(_system(design), f, med.density, med.sound_speed, C.SUBSTRATE_REFLECTION,
                             points=pts[None])[0]
    else:
        u = rest_response(design, f)
    gain, _ = drive_gain(design, f)
    return u * gain[:, None]


def interface_labels(design: Design) -> tuple[str, ...]:
    """``capsule.orifice`` of every interface, in the order of :func:`coupled_response`."""
    return _layout(design).labels


def _capsule_index(design: Design, capsule) -> int:
    cap = _capsule(design, capsule)
    i = _capsule_indices(design).get(cap.name)
    if i is None:
        raise KeyError(cap.name)
    return i


@_per_design
def _capsule_indices(design: Design) -> dict:
    """{capsule name: index in the layout} (the first of a name)."""
    out: dict = {}
    for i, c in enumerate(_layout(design).caps):
        out.setdefault(c.name, i)
    return out


def _fundamentals(cm: CoupledModes | ModeShapes, n_interfaces: int) -> list[int]:
    """Each interface's own fundamental: the lowest mode a uniform pressure excites in which that interface moves most (ties count), else its largest-share driven mode."""
    if cm.omega.size == 0:
        return []
    share = cm.share
    net = np.abs(cm.volume.sum(axis=0)) / np.maximum(np.abs(cm.volume).sum(axis=0), 1e-300)
    driven = net > 1e-3
    picked = []
    for o in range(n_interfaces):
        top = share[o] >= share.max(axis=0) * (1 - TIE_RTOL)
        cand = np.flatnonzero(top & driven)
        if cand.size == 0:
            cand = np.flatnonzero(driven) if driven.any() else np.arange(share.shape[1])
            cand = cand[[first_max(share[o, cand])]]
        picked.append(int(cand[0]))
    return sorted(set(picked))


_SAME_CAPSULES: list = []     # [(design, {capsule geometry key: modes})]: capsules alike in all the modes depend on


def _modes_cached(design: Design, idx: tuple[int, ...], max_hz: float | None = None) -> tuple[Mode, ...]:
    """Modes of the capsules ``idx`` as one system (a single capsule: its fundamentals), up to ``max_hz`` if given.

    A capsule's own modes depend on its cavity, orifices and the distances between its orifices and their wall images:
    capsules alike in these (an array of one capsule at one height) share one computation, keyed on the exact numbers
    the distances are computed from (the same results, bit for bit)."""
    if len(idx) != 1:
        return _system_modes(design, idx, max_hz)
    lay = _layout(design)
    cap = lay.caps[idx[0]]
    pts = lay.points(lay.rest)[lay.body == idx[0]]
    key = (cap.cavity.volume, thermal_radius(cap.cavity), cap.quality_factor, max_hz,
           tuple((o.name, o.radius) for o in cap.orifices),
           (pts[:, None, :2] - pts[None, :, :2]).tobytes(), pts[:, 2].tobytes())
    store = _per_design_store(_SAME_CAPSULES, design)
    hit = store.get(key)
    if hit is None:
        hit = store[key] = _system_modes(design, idx, max_hz)
    return hit


@_per_design
def _system_shapes(design: Design, idx: tuple[int, ...], max_hz: float | None = None):
    """:func:`acl.physics.coupling.mode_shapes` of the capsules ``idx`` as one system, up to ``max_hz`` (a little above:
    the caller filters exactly)."""
    med = medium_constants(design)
    top = None if max_hz is None else 2 * math.pi * max_hz * (1 + 1e-9)
    return _physics_mode_shapes(_system(design, idx), med.density, C.SUBSTRATE_REFLECTION, top)


@_per_design
def _system_modes(design: Design, idx: tuple[int, ...], max_hz: float | None = None) -> tuple[Mode, ...]:
    """:func:`_modes_cached` computed."""
    return _modes_of_system(design, idx, max_hz)


def _modes_of_system(design: Design, idx: tuple[int, ...], max_hz: float | None, which=None) -> tuple[Mode, ...]:
    """The :class:`Mode` of the capsules ``idx`` as one system (a single capsule: its fundamentals); ``which``: only
    these indices of the system's modes (their Q alone computed), else all."""
    med = medium_constants(design)
    lay = _layout(design)
    sel = np.isin(lay.body, list(idx))
    labels = [lab for lab, s in zip(lay.labels, sel) if s]
    shapes = _system_shapes(design, idx, max_hz)
    short = len(idx) == 1
    picked = _fundamentals(shapes, len(labels)) if short else range(shapes.omega.size)
    if which is not None:
        wanted = set(which)
        picked = [n for n in picked if n in wanted]
    # one eigensolution for both dampings: a declared Q changes the modal damping only
    predicted = _system(design, idx, predicted=True)
    cm = _physics_coupled_modes(_system(design, idx), med.density, med.sound_speed, C.SUBSTRATE_REFLECTION,
                                also_damping=(predicted.damping,), shapes=shapes,
                                which=None if which is None else list(picked))
    column = {n: j for j, n in enumerate(picked)} if which is not None else None
    cp = replace(cm, quality=cm.also_quality[0]) if cm.also_quality else cm
    declared = any(lay.caps[c].quality_factor is not None for c in idx)
    notes = defaults_used(design)

    def name(s):
        return s.split(".", 1)[1] if short else s

    names = [name(lab) for lab in labels]
    shares = shapes.share
    out = []
    for n in picked:
        j = n if column is None else column[n]
        share = shares[:, n]
        k = first_max(share)                  # a symmetric pair's 50/50: the first declared (acl.physics.ties)
        q = cm.quality[j]
        if short and lay.caps[idx[0]].quality_factor is not None:   # a declared Q is the capsule's Q as measured
            q = lay.caps[idx[0]].quality_factor
        same = np.where(shapes.volume[:, n] * shapes.volume[k, n] >= 0, 0.0, 180.0)   # in phase with the dominant one
        out.append(Mode(frequency_hz=float(shapes.frequency[n]), q=float(q),
                        dominant_orifice=names[k], share=float(share[k]),
                        shares=dict(zip(names, share.tolist())),
                        q_declared=declared, notes=notes, q_predicted=float(cp.quality[j]),
                        phases=dict(zip(names, same.tolist()))))
    return tuple(out)


def capsule_modes(design: Design, capsule, n_modes: int = C.DEFAULT_MEMBRANE_MODES) -> list[Mode]:
    """The fundamental mode of each orifice of ``capsule`` (the capsule alone: its interfaces coupled through the gas, the liquid and the substrate's image), ascending."""
    cap = _capsule(design, capsule)
    if n_modes != C.DEFAULT_MEMBRANE_MODES:        # bare modes with another basis size (convergence studies)
        md = modal_data(design, cap, n_modes)
        names = [o.name for o in cap.orifices]
        out = []
        for n in range(min(len(names), md.omega.size)):
            k = first_max(md.share[:, n])
            out.append(Mode(frequency_hz=float(md.frequency[n]), q=float(md.quality[n]),
                            dominant_orifice=names[k], share=float(md.share[k, n]),
                            shares={nm: float(md.share[i, n]) for i, nm in enumerate(names)},
                            q_declared=cap.quality_factor is not None, notes=defaults_used(design)))
        return out
    return list(_modes_cached(design, (_capsule_index(design, cap),)))


def coupled_modes(design: Design) -> list[Mode]:
    """Undamped modes of all bubbles of the design as one coupled system, ascending (shares keyed ``capsule.orifice``).

    Listed: modes a uniform pressure excites (net volume >= 1e-3 of the moved volume) up to 1.5x the
    highest capsule fundamental (membrane overtones are left out).
    """
    lay = _layout(design)
    if not lay.caps:
        return []
    top = _coupled_top(design)
    ms = _modes_cached(design, tuple(range(len(lay.caps))), 1.5 * top if len(lay.caps) > 1 else None)
    return [m for m in ms if m.frequency_hz <= 1.5 * top]


def _coupled_top(design: Design) -> float:
    """The highest capsule fundamental (:func:`coupled_modes` lists up to 1.5x it)."""
    return max((m.frequency_hz for c in _layout(design).caps for m in capsule_modes(design, c)), default=0.0)


def coupled_modes_of(design: Design, capsule, min_share: float = 0.1) -> list[Mode]:
    """The modes of :func:`coupled_modes` in which the interfaces of ``capsule`` hold at least ``min_share`` of the
    moved volume (its shares summed in interface order), as :func:`coupled_modes` lists them.

    Only these modes' Q are computed (each mode's Q depends on that mode alone): on a design of hundreds of capsules
    a capsule takes part in a few of them.
    """
    lay = _layout(design)
    c = _capsule_index(design, capsule)
    if len(lay.caps) < 2:
        return [m for m in coupled_modes(design)
                if sum(v for k, v in m.shares.items() if k.split(".")[0] == lay.caps[c].name) >= min_share]
    top = _coupled_top(design)
    idx = tuple(range(len(lay.caps)))
    shapes = _system_shapes(design, idx, 1.5 * top)
    mine = [i for i, lab in enumerate(lay.labels) if lab.split(".")[0] == lay.caps[c].name]
    share = shapes.share
    rows = share[mine].T.tolist()                # (K, interfaces of the capsule), summed as Python floats
    which = [n for n, (f, r) in enumerate(zip(shapes.frequency.tolist(), rows))
             if f <= 1.5 * top and sum(r) >= min_share]
    return list(_modes_of_system(design, idx, 1.5 * top, which)) if which else []


def orifice_response(design: Design, capsule, frequencies) -> np.ndarray:
    """Complex inward volume amplitude (m^3 per V peak) of each orifice of ``capsule``, shape (F, n_orifices).

    In the coupled system of the whole design at rest (:func:`coupled_response`); transducer gain
    included (flat-extrapolated outside its table: see :func:`drive_gain`).  Phase convention of
    :func:`acl.physics.resonance.volume_response`.
    """
    c = _capsule_index(design, capsule)
    return coupled_response(design, frequencies)[:, _layout(design).body == c]


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


def _thrust_from_volumes(design: Design, radii: np.ndarray, f: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """Thrust magnitude (N) per tone and orifice from volume amplitudes (..., T, n) (acl.physics.forces.thrust_magnitude)."""
    return thrust_magnitude(dv, radii, 2 * np.pi * f[:, None], medium_constants(design).viscosity, C.STREAMING_CONSTANT)


@_per_design
def _isolated_thrust_per_v2(design: Design, c: int) -> float:
    lay = _layout(design)
    med = medium_constants(design)
    ms = capsule_modes(design, lay.caps[c])
    if not ms:
        return 0.0
    f1 = np.array([ms[0].frequency_hz])
    u = _physics_coupled(_system(design, [c]), f1, med.density, med.sound_speed, C.SUBSTRATE_REFLECTION)
    u = u * drive_gain(design, f1)[0][:, None]
    sel = lay.body == c
    per = _thrust_from_volumes(design, lay.radii[sel], f1, u)[0]
    return float(np.linalg.norm((per[:, None] * -lay.normals[sel]).sum(axis=0)))


def _thrust_scale(design: Design, cap: Capsule) -> float:
    """Factor that makes predicted thrust match a declared Capsule.thrust_coefficient at its first reported mode (:func:`capsule_modes`; the capsule alone)."""
    if cap.thrust_coefficient is None:
        return 1.0
    total = _isolated_thrust_per_v2(design, _capsule_index(design, cap))
    return cap.thrust_coefficient / total if total > 0 else 1.0


@dataclass(frozen=True)
class _Engine:
    """One design under one drive: everything the force model needs, vectorised over configurations."""

    design: Design
    lay: _Layout
    system: BubbleSystem
    f: np.ndarray               # (T,) Hz
    pressure: np.ndarray        # (T,) Pa: tone amplitude x gain x effects
    h0: np.ndarray | None       # (T, C, P, P) uncoupled blocks at the tones
    scale: np.ndarray           # (C,) declared thrust scale x substrate effect
    pair_scale: np.ndarray      # (C, C) effects factor on Bjerknes
    outer: np.ndarray           # (C,) equal-volume sphere + wall radius (jet drag target)
    rho: float
    c: float
    response: object = None     # acl.physics.coupling.prepared_response at the tones
    consts: dict = field(default_factory=dict)   # position-independent factors of forces()
    _rest: list = field(default_factory=list, compare=False, repr=False)

    def _rest_response(self):
        """The coupled response per pascal at rest (1, T, n), shared by the drives with the same tones; None without any."""
        if not (self.f.size and self.lay.radii.size):
            return None
        store = _per_design_store(_ENGINE_REST, self.design)
        key = tuple(self.f.tolist())
        r = store.get(key)
        if r is None:       # the same system at rest as rest_response's: its per-frequency cache (lint prefetches)
            r = store[key] = rest_response(self.design, self.f)[None]
        return r

    def _drive_key(self) -> tuple:
        return tuple(self.f.tolist()), self.pressure.tobytes()

    def rest_forces(self):
        """:meth:`forces` of the capsules at rest, with parts (total, u, thr, att), each (1, ...); computed once."""
        if not self._rest:
            self._rest.append(self.forces(self.lay.rest[None], parts=True, response=self._rest_response(), rest=True))
            # the thrust per interface (n floats) outlives the engine: :meth:`rest_pairs` of a later engine of the
            # same drive needs it (the last engine only is kept, and lint asks its drives in turn)
            _per_design_store(_REST_THRUST, self.design)[self._drive_key()] = self._rest[0][2]
        return self._rest[0]

    def rest_pairs(self):
        """(u, thr, att) of :meth:`rest_forces`, for the pair table: when an earlier engine of this drive computed the
        rest forces, only the Bjerknes pair sum is evaluated again (the same call, so the same numbers)."""
        thr = None if self._rest else _per_design_store(_REST_THRUST, self.design).get(self._drive_key())
        r = None if thr is None else self._rest_response()
        if r is None:
            _, u, thr, att = self.rest_forces()
            return u, thr, att
        k = self.consts
        pts, dist, _ = _rest_interfaces(self.design)
        _, att = bjerknes_pair_sum(pts, r, k["w2p2"], k["bjerknes"], k["other"], k.get("gap_exponent", 0.0),
                                   k.get("gap_ref", 1.0), dist)
        return r * self.pressure[None, :, None], thr, att

    def forces(self, centres: np.ndarray, parts: bool = False, consts: dict | None = None, response=None,
               rest: bool = False):
        """Total acoustic force (B, C, 3) on each capsule for centres (B, C, 3): thrust + Bjerknes + jet drag.

        ``consts``: per-configuration drive constants (:func:`drive_constants`: each row of the batch under its
        own tone amplitudes, gain table and thrust scale); default the engine's own drive for every row.
        ``response``: the coupled volume response (B, T, n) per pascal at these centres, when already known;
        ``rest``: the centres are the design's rest positions (B = 1; their distances are kept per design).
        """
        k = self.consts if consts is None else {**self.consts, **consts}
        lay = self.lay
        pts, dist, lines = _rest_interfaces(self.design) if rest else (centres[:, lay.body, :] + lay.offsets, None, None)
        if response is not None:
            r = response
        elif self.f.size == 0 or lay.radii.size == 0:
            r = np.zeros((centres.shape[0], self.f.size, lay.radii.size), complex)
        else:
            r = self.response(pts)                                         # (B, T, n) per pascal
        total, _, thr, att = capsule_forces(centres, lay.body, lay.offsets, lay.normals, lay.onehot, self.outer, r, k,
                                            points=pts, distance=dist, lines=lines)
        if parts:
            return total, r * self.pressure[None, :, None], thr, att
        return total


@_per_design
def _rest_interfaces(design: Design) -> tuple:
    """Interface centres at rest (1, n, 3), their :func:`acl.physics.forces.interface_distances` and
    :func:`acl.physics.forces.jet_lines` to the capsule centres, once per design (read-only)."""
    lay = _layout(design)
    pts = lay.rest[None][:, lay.body, :] + lay.offsets
    dist = interface_distances(pts, lay.body[:, None] != lay.body[None, :])
    lines = jet_lines(pts, lay.normals, lay.rest[None], lay.body[:, None] != np.arange(len(lay.caps))[None, :])
    for a in (pts, dist, *lines):
        a.setflags(write=False)
    return pts, dist, lines


def _engine_constants(design: Design, lay: _Layout, f: np.ndarray, pressure: np.ndarray, scale: np.ndarray,
                      pair: np.ndarray, shape: tuple = (0.0, 1.0)) -> dict:
    """Everything in :meth:`_Engine.forces` that does not depend on the capsule positions (acl.physics.forces.force_constants)."""
    med = medium_constants(design)
    return force_constants(2 * np.pi * f, lay.radii, lay.body, len(lay.caps), med.viscosity, med.density,
                           C.STREAMING_CONSTANT, pressure, scale, pair, gap_shape=shape)


@_per_design
def _capsule_factors(design: Design) -> tuple:
    """The drive-independent factors of :func:`_compute_engine`, once per design (read-only): thrust scale x substrate
    effect (C,), the Bjerknes factor (C, C) and its declared shape, each capsule's jet-drag radius (C,)."""
    lay = _layout(design)
    ncap = len(lay.caps)
    sub = np.array([substrate_factor(design, c) for c in lay.caps]) if design.effects else np.ones(ncap)
    scale = np.array([_thrust_scale(design, c) for c in lay.caps]) * sub
    pair = np.sqrt(np.outer(sub, sub)) if design.effects else np.ones((ncap, ncap))
    bs = EF.coefficients(design, "bjerknes_scale") if design.effects else None
    shape = (0.0, 1.0)
    if bs is not None:   # a fitted Bjerknes coefficient (paper Eq. 3 alpha) relative to the physics, and its shape
        pair = pair * bs["factor"]
        shape = EF.bjerknes_shape(bs)
    outer = np.array([_outer_radius(c) for c in lay.caps])
    for a in (scale, pair, outer):
        a.setflags(write=False)
    return scale, pair, shape, outer


def _compute_engine(design: Design, drive: Drive) -> _Engine:
    lay = _layout(design)
    med = medium_constants(design)
    f, v = _tones(drive)
    sysm = _system(design)
    if f.size:
        gain, _ = drive_gain(design, f)
        pressure = v * gain * effect_pressure_factor(design, f, float(v.sum()))
        h0 = uncoupled_blocks(sysm, 2 * np.pi * f)
    else:
        pressure, h0 = np.zeros(0), None
    scale, pair, shape, outer = _capsule_factors(design)
    response = (prepared_response(sysm, f, med.density, med.sound_speed, C.SUBSTRATE_REFLECTION, h0=h0)
                if f.size else None)
    return _Engine(design, lay, sysm, f, pressure, h0, scale, pair, outer, med.density, med.sound_speed, response,
                   _engine_constants(design, lay, f, pressure, scale, pair, shape))


_LAST_ENGINE: list = []   # [(design, drive, engine)]: identity cache for solver inner loops


def _engine(design: Design, drive: Drive) -> _Engine:
    if _LAST_ENGINE and _LAST_ENGINE[0][0] is design and _LAST_ENGINE[0][1] is drive:
        return _LAST_ENGINE[0][2]
    eng = _compute_engine(design, drive)
    _LAST_ENGINE[:] = [(design, drive, eng)]
    return eng


def thrust_vectors(design: Design, drive: Drive, positions=None) -> dict[str, np.ndarray]:
    """Streaming thrust (N, 3-vector) on each capsule: sum over orifices of -|F| n_outward (coupled volumes)."""
    eng = _engine(design, drive)
    at_rest = not positions
    _, _, thr, _ = eng.rest_forces() if at_rest else eng.forces(_centres_array(design, positions)[None], parts=True)
    vec = np.einsum("n,nk,nc->ck", thr[0], -eng.lay.normals, eng.lay.onehot)
    return {c.name: vec[i] for i, c in enumerate(eng.lay.caps)}


def _centres(design: Design, positions: Mapping[str, Sequence[float]] | None) -> dict[str, np.ndarray]:
    pos = {c.name: np.asarray(c.center, float) for c in design.capsules}
    if positions:
        for k, p in positions.items():
            pos[k] = np.asarray(p, float)
    return pos


@dataclass(frozen=True)
class PairTable:
    """:class:`PairForce` of every capsule pair as arrays (row k: capsules ``a[k] < b[k]``, in the
    order of ``design.capsules``); ``critical_distance`` is NaN where PairForce has None."""

    names: tuple[str, ...]
    a: np.ndarray                    # (P,) capsule index
    b: np.ndarray                    # (P,)
    force_on_a: np.ndarray           # (P, 3) N
    attraction: np.ndarray           # (P,) N, attraction positive
    phase_difference: np.ndarray     # (P,) rad
    distance: np.ndarray             # (P,) m
    critical_distance: np.ndarray    # (P,) m or NaN
    notes: tuple[str, ...] = ()

    def row(self, k: int) -> PairForce:
        dc = float(self.critical_distance[k])
        fa = self.force_on_a[k]
        return PairForce(a=self.names[self.a[k]], b=self.names[self.b[k]], force_on_a=fa, force_on_b=-fa,
                         attraction=float(self.attraction[k]), attract=bool(self.attraction[k] > 0),
                         phase_difference=float(self.phase_difference[k]), distance=float(self.distance[k]),
                         critical_distance=None if math.isnan(dc) else dc, notes=self.notes)


def _pair_lines(centres: np.ndarray) -> tuple:
    """(a, b, distance, unit vector a -> b) of every capsule pair a < b (the nested loops' order: a, then b > a)."""
    pa, pb = np.triu_indices(centres.shape[0], 1)
    line = centres[pb] - centres[pa]
    dist = np.linalg.norm(line, axis=-1)
    unit = np.divide(line, dist[:, None], out=np.zeros_like(line), where=dist[:, None] > 0)
    return pa, pb, dist, unit


@_per_design
def _rest_pair_lines(design: Design) -> tuple:
    """:func:`_pair_lines` at rest and the :func:`acl.physics.forces.interface_pairs` of the interfaces at rest, once
    per design (read-only)."""
    lay = _layout(design)
    out = _pair_lines(_centres_array(design, None))
    pairs = interface_pairs(lay.points(_centres_array(design, None)), lay.body, len(lay.caps))
    for a in out + pairs[:5]:
        a.setflags(write=False)
    return out + (pairs,)


def pair_attraction(design: Design, drive: Drive) -> np.ndarray:
    """:func:`pair_table`'s ``attraction`` column (P,) at rest alone (the same numbers; no phases, no critical distances)."""
    eng = _engine(design, drive)
    lay = eng.lay
    _, _, att = eng.rest_pairs()
    _, _, _, unit, pairs = _rest_pair_lines(design)
    fa = capsule_pair_forces(lay.points(_centres_array(design, None)), att[0], lay.body, len(lay.caps), pairs)
    return np.einsum("pk,pk->p", fa, unit)


def pair_table(design: Design, drive: Drive,
               positions: Mapping[str, Sequence[float]] | None = None) -> PairTable:
    """Secondary Bjerknes force of every capsule pair (coupled volumes; sum over tones and orifice
    pairs), vectorised over pairs; the reduced law of paper Eq. 3 gives each pair's critical distance."""
    eng = _engine(design, drive)
    lay = eng.lay
    centres = _centres_array(design, positions)
    u, thr, att = eng.rest_pairs() if not positions else eng.forces(centres[None], parts=True)[1:]
    u, thr, att = u[0], thr[0], att[0]
    pts = lay.points(centres)
    thrust_vec = np.einsum("n,nk,nc->ck", thr, -lay.normals, lay.onehot)
    ncap = len(lay.caps)
    pa, pb, dist, unit, pairs = _rest_pair_lines(design) if not positions else _pair_lines(centres) + (None,)
    fa = capsule_pair_forces(pts, att, lay.body, ncap, pairs)
    attraction = np.einsum("pk,pk->p", fa, unit)
    dphi, gap = dominant_pair_phase(u, pts, lay.body, ncap, dist, pairs)
    # reduced law (paper Eq. 3): alpha = attraction d^2, 2 gamma = thrusts pushing apart
    gamma2 = np.einsum("pk,pk->p", thrust_vec[pa], -unit) + np.einsum("pk,pk->p", thrust_vec[pb], unit)
    alpha = attraction * gap**2
    live = (alpha > 0) & (gamma2 > 0)
    dc = np.full(pa.size, np.nan)
    dc[live] = critical_distance(alpha[live], gamma2[live] / 2)
    return PairTable(names=tuple(c.name for c in lay.caps), a=pa, b=pb, force_on_a=fa, attraction=attraction,
                     phase_difference=dphi, distance=gap, critical_distance=dc, notes=defaults_used(design))


def pair_forces(design: Design, drive: Drive,
                positions: Mapping[str, Sequence[float]] | None = None) -> list[PairForce]:
    """Secondary Bjerknes force of every capsule pair (coupled volumes; sum over tones and orifice pairs)."""
    tab = pair_table(design, drive, positions)
    return [tab.row(k) for k in range(tab.a.size)]


def _apply_neighbour_drag(design: Design, lay: _Layout, centres: np.ndarray, total: np.ndarray) -> np.ndarray:
    """A declared neighbour_drag (acl.physics.forces.neighbour_drag) on capsules with a neighbour (acl.analysis.effects.neighbour_capsules; the fit's pairs)."""
    nd = EF.coefficients(design, "neighbour_drag") if design.effects else None
    if nd and nd["inv_plateau"] > 0:
        near = EF.neighbour_capsules(design)
        return neighbour_drag(total, centres, lay.rest, [c.name in near for c in lay.caps], nd["inv_plateau"])
    return total


def force_batch(design: Design, centres: np.ndarray, drive: Drive, consts: dict | None = None) -> np.ndarray:
    """:func:`force_model` for many configurations at once: capsule centres (B, C, 3) in ``design.capsules`` order -> forces (B, C, 3); ``consts`` overrides :meth:`_Engine.forces`' constants (e.g. ``jet_drag_fraction``)."""
    eng = _engine(design, drive)
    centres = np.asarray(centres, float)
    return _apply_neighbour_drag(design, eng.lay, centres, eng.forces(centres, consts=consts))


def force_model(design: Design, positions: Mapping[str, Sequence[float]] | None,
                drive: Drive) -> dict[str, np.ndarray]:
    """Total acoustic force (N, 3-vector) on each capsule: thrust + Bjerknes + drag in others' jets.

    ``positions`` maps capsule names to displaced centres (missing names stay at rest).  Tones at
    different frequencies add in power (cross terms average to zero).  Bubble volumes come from the
    coupled system at these positions (acl.physics.coupling).
    """
    if positions:
        total = force_batch(design, _centres_array(design, positions)[None], drive)[0]
    else:               # at rest: the engine's cached evaluation (pair_table and thrust_vectors share it)
        eng = _engine(design, drive)
        total = _apply_neighbour_drag(design, eng.lay, eng.lay.rest[None], eng.rest_forces()[0].copy())[0]
    return {c.name: total[i] for i, c in enumerate(design.capsules)}


# Every term (thrust, Bjerknes, jet drag) is quadratic in the tone amplitudes (linear acoustics):
# callers scaling a whole drive by V may evaluate once and multiply by V^2.
force_model.quadratic_in_amplitude = True
force_model.batch = force_batch


def _saturating_force_model(design: Design, positions, drive: Drive) -> dict[str, np.ndarray]:
    """:func:`force_model` of a design with drive_saturation: forces are not quadratic in the amplitude."""
    return force_model(design, positions, drive)


_saturating_force_model.quadratic_in_amplitude = False
_saturating_force_model.batch = force_batch


def force_model_for(design: Design):
    """The force model to hand to :mod:`acl.analysis.mechanics` for ``design``.

    :func:`force_model` itself, flagged ``quadratic_in_amplitude`` (evaluate once, scale by V^2),
    unless the design declares drive_saturation, whose pressure factor depends on V.
    """
    return _saturating_force_model if design.effect("drive_saturation") is not None else force_model

"""One analysis object per resolved design, shared by every lint rule and every editor hover.

:func:`analysis_for` returns the :class:`DesignAnalysis` of a design (kept for the last few designs,
by identity: a design is immutable).  It answers the questions the rules and hovers ask (capsule
modes, thrust per V^2 over frequency, the forces, pair table and interface amplitudes under a drive)
from the functions of :mod:`acl.analysis.acoustics`, each computed once: the coupled response of
the whole design at rest is solved once per frequency (:func:`acl.analysis.acoustics.rest_response`),
for all the frequencies a caller names in one batched solve (:meth:`DesignAnalysis.prefetch`).
Nothing here is a second copy of a law: every number comes from the analysis functions.
"""
from __future__ import annotations

import numpy as np

from acl.design.model import Design, Drive

_LIVE: list = []        # [(design, DesignAnalysis)], newest first
KEEP = 4                # designs kept (an editor alternates between a few open files)
PAIR_TABLES = 4         # pair tables kept per design


def analysis_for(design: Design) -> DesignAnalysis:
    """The shared :class:`DesignAnalysis` of ``design`` (created on first use)."""
    for d, a in _LIVE:
        if d is design:
            return a
    a = DesignAnalysis(design)
    _LIVE[:] = ([(design, a)] + _LIVE)[:KEEP]
    return a


def _drive_key(drive: Drive) -> tuple:
    return tuple((t.frequency, t.amplitude, t.phase) for t in drive.tones)


class DesignAnalysis:
    """Cached analyses of one design (:mod:`acl.analysis.acoustics`), batched over capsules, pairs and tones."""

    def __init__(self, design: Design):
        self.design = design
        self.names = tuple(c.name for c in design.capsules)
        self.index = {n: i for i, n in enumerate(self.names)}
        self._modes: dict = {}
        self._thrust: dict = {}        # frequency -> (C,) thrust per V^2 (selectivity column)
        self._drive: dict = {}         # (kind, drive key) -> value
        self._mode_table = None
        self._pairs: dict = {}         # drive key -> PairTable, the last few

    # -- modes ---------------------------------------------------------------------------------
    def modes(self, capsule) -> list:
        """:func:`acl.analysis.acoustics.capsule_modes` of ``capsule`` (a Capsule or its name)."""
        name = capsule if isinstance(capsule, str) else capsule.name
        hit = self._modes.get(name)
        if hit is None:
            from acl.analysis.acoustics import capsule_modes

            hit = self._modes[name] = capsule_modes(self.design, self.design.capsule(name))
        return hit

    def mode_table(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(frequency Hz, Q, capsule index) of every capsule's modes, in capsule order."""
        if self._mode_table is None:
            rows = [(m.frequency_hz, m.q, i) for i, c in enumerate(self.design.capsules) for m in self.modes(c)]
            arr = np.array(rows, float).reshape(-1, 3)
            self._mode_table = (arr[:, 0], arr[:, 1], arr[:, 2].astype(int))
        return self._mode_table

    def in_band(self, frequency: float) -> set[str]:
        """Capsules with a mode whose half-power band (f_m / 2Q) contains ``frequency``."""
        key = ("in_band", frequency)
        hit = self._drive.get(key)
        if hit is None:
            fm, q, ci = self.mode_table()
            hit = self._drive[key] = {self.names[i] for i in np.unique(ci[np.abs(frequency - fm) <= fm / (2 * q)])}
        return hit

    # -- the coupled response at rest -----------------------------------------------------------
    def prefetch(self, frequencies) -> None:
        """Solve the coupled system at rest at every one of ``frequencies`` not solved yet, in one batch."""
        from acl.analysis.acoustics import rest_response

        rest_response(self.design, np.atleast_1d(np.asarray(frequencies, float)))

    def thrust_per_v2(self, frequencies) -> np.ndarray:
        """Thrust magnitude per V^2 of every capsule (C, F) (:func:`acl.analysis.selectivity.selectivity`), each
        frequency computed once."""
        f = np.atleast_1d(np.asarray(frequencies, float))
        missing = [x for x in dict.fromkeys(f.tolist()) if x not in self._thrust]
        if missing:
            from acl.analysis.selectivity import selectivity

            t = selectivity(self.design, np.array(missing)).thrust_per_v2
            for j, x in enumerate(missing):
                self._thrust[x] = t[:, j]
        if not f.size:
            return np.zeros((len(self.names), 0))
        return np.stack([self._thrust[x] for x in f.tolist()], axis=1)

    def orifice_response(self, capsule, frequencies) -> np.ndarray:
        """:func:`acl.analysis.acoustics.orifice_response` (the coupled response at rest is cached per frequency)."""
        from acl.analysis.acoustics import orifice_response

        return orifice_response(self.design, capsule, frequencies)

    def sweep_interface_amplitudes(self, frequencies, amplitude: float) -> np.ndarray:
        """:func:`acl.analysis.interfaces.sweep_interface_amplitudes`: eps/R (F, interfaces)."""
        from acl.analysis.interfaces import sweep_interface_amplitudes

        f = np.atleast_1d(np.asarray(frequencies, float))
        return self._per(("sweep_eps", tuple(f.tolist()), amplitude),
                         lambda: sweep_interface_amplitudes(self.design, f, amplitude))

    # -- under one drive (the capsules at rest) -------------------------------------------------
    def _per(self, key, compute):
        hit = self._drive.get(key)
        if hit is None:
            hit = self._drive[key] = compute()
        return hit

    def _at_rest(self, drive: Drive) -> None:
        """:meth:`forces` and :meth:`thrust_array` under ``drive`` together: they share one force-engine
        evaluation at rest (the engine is kept for the drive last asked)."""
        from acl.analysis.acoustics import force_model, thrust_vectors

        key = _drive_key(drive)
        if ("forces", key) in self._drive:
            return
        self._drive[("forces", key)] = force_model(self.design, None, drive)
        tkey = ("thrust", tuple((t.frequency, t.amplitude) for t in drive.tones))
        if tkey not in self._drive:
            self._drive[tkey] = np.array(list(thrust_vectors(self.design, drive).values()), float).reshape(-1, 3)

    def forces(self, drive: Drive) -> dict:
        """:func:`acl.analysis.acoustics.force_model` at rest: total acoustic force on each capsule."""
        self._at_rest(drive)
        return self._drive[("forces", _drive_key(drive))]

    def force_array(self, drive: Drive) -> np.ndarray:
        """:meth:`forces` as an array (C, 3) in ``design.capsules`` order."""
        def compute():
            f = self.forces(drive)
            return np.array([f[n] for n in self.names], float).reshape(-1, 3)
        return self._per(("force_array", _drive_key(drive)), compute)

    def pair_table(self, drive: Drive):
        """:func:`acl.analysis.acoustics.pair_table` at rest: every capsule pair's Bjerknes interaction."""
        from acl.analysis.acoustics import pair_table

        key = _drive_key(drive)
        hit = self._pairs.get(key)
        if hit is None:
            hit = self._keep_pairs(key, pair_table(self.design, drive))
        return hit

    def pair_attraction(self, drive: Drive) -> np.ndarray:
        """The ``attraction`` column of :meth:`pair_table` (:func:`acl.analysis.acoustics.pair_attraction`: the same
        numbers, without the rest of the table)."""
        hit = self._pairs.get(_drive_key(drive))
        if hit is not None:
            return hit.attraction
        from acl.analysis.acoustics import pair_attraction

        return pair_attraction(self.design, drive)

    def _keep_pairs(self, key, tab):
        """Keep the pair tables of the last :data:`PAIR_TABLES` drives (a table of a design of hundreds of
        capsules holds every pair: megabytes each)."""
        self._pairs.pop(key, None)
        self._pairs[key] = tab
        while len(self._pairs) > PAIR_TABLES:
            self._pairs.pop(next(iter(self._pairs)))
        return tab

    def thrust_array(self, drive: Drive) -> np.ndarray:
        """Streaming thrust vector (N) of every capsule at rest, (C, 3) (:func:`acl.analysis.acoustics.thrust_vectors`)."""
        from acl.analysis.acoustics import thrust_vectors

        self._at_rest(drive)
        key = ("thrust", tuple((t.frequency, t.amplitude) for t in drive.tones))
        return self._per(key, lambda: np.array(
            [v for v in thrust_vectors(self.design, drive).values()], float).reshape(-1, 3))

    def net_force_array(self, drive: Drive) -> np.ndarray:
        """Total acoustic force (N) on every capsule at rest (thrust, Bjerknes, jet drag), (C, 3)
        (:func:`acl.analysis.acoustics.force_model`, the engine's cached evaluation at rest)."""
        from acl.analysis.acoustics import force_model

        self._at_rest(drive)
        key = ("net_force", _drive_key(drive))
        return self._per(key, lambda: np.array(
            [v for v in force_model(self.design, None, drive).values()], float).reshape(-1, 3))

    def interface_amplitudes(self, drive: Drive) -> dict[str, float]:
        """:func:`acl.analysis.interfaces.interface_amplitudes` at rest: eps/R of every interface."""
        from acl.analysis.interfaces import interface_amplitudes

        return self._per(("eps", _drive_key(drive)), lambda: interface_amplitudes(self.design, drive))

    def fixed(self) -> np.ndarray:
        """(C,) True for capsules held by a `fix` joint."""
        def compute():
            fixed = {j.capsule for j in self.design.joints if j.kind == "fix"}
            return np.array([n in fixed for n in self.names], bool)
        return self._per(("fixed",), compute)

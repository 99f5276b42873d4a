"""Design instances reduced to what the fit's forward model needs: beams, actuators, rest gap, observables.

One :class:`Instance` per override set (``set:NAME`` columns).  Supported mechanisms (paper Figs. 2
and 4): one single-orifice actuator on a cantilever (``single``), or two single-orifice actuators on
two cantilevers facing each other (``pair``).  Anything else is a diagnostic, not a guess.
Frequency responses come from :mod:`acl.analysis.acoustics` (thrust and Bjerknes coefficient per V^2
at each tone frequency, with the design's transducer table), relative to a reference frequency.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from acl.diagnostics import DiagnosticError, error


@dataclass
class Instance:
    design: object
    kind: str                              # "single" | "pair"
    capsules: tuple[str, ...]              # actuator on beam 0 (and beam 1)
    beams: tuple[str, ...]
    L: np.ndarray                          # (k,) flexible lengths
    l: np.ndarray                          # (k,) rigid half-actuator lengths
    EI: np.ndarray                         # (k,) declared bending stiffness
    E: np.ndarray                          # (k,) declared Young's modulus
    height: np.ndarray                     # (k,) actuator (orifice centre) height above the substrate
    u: np.ndarray                          # (k, 3) direction of positive deflection
    proj: np.ndarray                       # (k,) share of the thrust perpendicular to the beam
    rest: np.ndarray                       # (k, 3) actuator centres at rest
    d0: float                              # pair: rest distance between the orifices (m)
    modes: np.ndarray                      # (k, 2) natural frequency (Hz) and Q of each actuator
    _tau: dict = field(default_factory=dict)

    def output_map(self, obs) -> tuple[float, float, float]:
        """(base, scale on deflection 0, scale on deflection 1) of observable ``obs``."""
        if obs.kind == "gap":
            names = {obs.a.split(".")[0], obs.b.split(".")[0]}
            if self.kind == "pair" and names == set(self.capsules):
                return self.d0, -1.0, -1.0
            raise _unsupported(obs, "a gap is supported between the two actuators of a facing pair")
        k = self._index(obs.target)
        if k is None:
            raise _unsupported(obs, f"`{obs.target}` is neither an actuator nor the beam carrying one")
        s = [0.0, 0.0]
        if obs.kind == "displacement":
            axis = np.asarray(obs.axis, float)
            s[k] = float(self.u[k] @ (axis / np.linalg.norm(axis)))
            return 0.0, s[0], s[1]
        comp = "xyz".index(obs.component)
        s[k] = float(self.u[k][comp])
        return float(self.rest[k][comp]), s[0], s[1]

    def _index(self, target):
        for k, (c, b) in enumerate(zip(self.capsules, self.beams)):
            if target in (c, b):
                return k
        return None


def _unsupported(obs, why):
    return DiagnosticError([error("E810", f"observable `{obs.name}` cannot be predicted by the fit model: {why}",
                                  obs.span)])


def build_instance(design) -> Instance:
    """Reduce a resolved design to an :class:`Instance` (raises E810 for unsupported mechanisms)."""
    # the fit's base model is the design without declared effects (the fit adds them itself: a
    # calibrated design fitted again must not apply them twice)
    design = design.model_copy(update={"effects": ()}) if design.effects else design
    mounts = [j for j in design.joints if j.kind == "mount" and j.target_kind == "beam"]
    span = design.capsules[0].span if design.capsules else None
    if len(mounts) not in (1, 2):
        raise DiagnosticError([error(
            "E810", f"the fit model handles one actuator on a cantilever or two facing ones (paper Figs. 2, 4e); "
                    f"this design mounts {len(mounts)} capsule(s) on beams", span,
            "springs, latches, trusses and free capsules are not in the fit model yet (docs/fit.md)")])
    caps = [design.capsule(m.capsule) for m in mounts]
    beams = [design.beam(m.target) for m in mounts]
    for c in caps:
        if len(c.orifices) != 1:
            raise DiagnosticError([error("E810", f"capsule `{c.name}` has {len(c.orifices)} orifices; the fit model "
                                         "handles single-orifice actuators (1-D deflection)", c.span)])
    k = len(caps)
    axes = [np.asarray(b.axis, float) / np.linalg.norm(b.axis) for b in beams]
    if k == 1:
        t = -np.asarray(caps[0].orifices[0].normal, float)
        t = t / np.linalg.norm(t)
        perp = t - (t @ axes[0]) * axes[0]
        norm = float(np.linalg.norm(perp))
        if norm < 1e-9:
            raise DiagnosticError([error("E810", f"the thrust of `{caps[0].name}` is along its beam: no bending",
                                         caps[0].span)])
        u = [perp / norm]
        proj = [norm]
        d0 = float("nan")
    else:
        pa = np.asarray(caps[0].orifices[0].center, float)
        pb = np.asarray(caps[1].orifices[0].center, float)
        line = pb - pa
        d0 = float(np.linalg.norm(line))
        if d0 <= 0:
            raise DiagnosticError([error("E810", "the two actuators' orifices coincide", caps[1].span)])
        ua = line / d0
        u, proj = [], []
        for sgn, ax in ((1.0, axes[0]), (-1.0, axes[1])):
            perp = sgn * ua - (sgn * ua @ ax) * ax
            proj.append(float(np.linalg.norm(perp)))
            u.append(perp / max(proj[-1], 1e-300))
    from acl.analysis.acoustics import capsule_modes

    modes = []
    for c in caps:
        m = capsule_modes(design, c)[0]
        modes.append((m.frequency_hz, m.q))
    return Instance(
        design=design, kind="single" if k == 1 else "pair", capsules=tuple(c.name for c in caps),
        beams=tuple(b.name for b in beams), L=np.array([b.length for b in beams]),
        l=np.array([b.rigid_length for b in beams]), EI=np.array([b.bending_stiffness for b in beams]),
        E=np.array([b.youngs_modulus for b in beams]),
        height=np.array([c.orifices[0].center[2] for c in caps]), u=np.array(u), proj=np.array(proj),
        rest=np.array([c.center for c in caps], float), d0=d0, modes=np.array(modes))


def thrust_per_v2(inst: Instance, frequency: float) -> np.ndarray:
    """(k,) thrust magnitude (N/V^2) of each actuator at ``frequency`` (acl.analysis.acoustics, declared gamma applied)."""
    key = ("t", float(frequency))
    if key not in inst._tau:
        from acl.analysis.acoustics import thrust_vectors
        from acl.design.model import Drive, Tone

        tv = thrust_vectors(inst.design, Drive(tones=(Tone(frequency=float(frequency), amplitude=1.0),)))
        inst._tau[key] = np.array([np.linalg.norm(tv[c]) for c in inst.capsules])
    return inst._tau[key]


def alpha_per_v2(inst: Instance, frequency: float) -> float:
    """Bjerknes coefficient alpha(f) = attraction d^2 per V^2 (N m^2/V^2) of a pair (acl.analysis.acoustics)."""
    key = ("a", float(frequency))
    if key not in inst._tau:
        from acl.analysis.acoustics import pair_forces
        from acl.design.model import Drive, Tone

        pf = pair_forces(inst.design, Drive(tones=(Tone(frequency=float(frequency), amplitude=1.0),)))
        want = set(inst.capsules)
        val = next((p.attraction * p.distance**2 for p in pf if {p.a, p.b} == want), 0.0)
        inst._tau[key] = float(val)
    return inst._tau[key]

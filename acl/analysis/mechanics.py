"""Mechanics of a design: degrees of freedom, quasi-static equilibrium under a drive, snap-in, latch margins.

Turns :mod:`acl.design.model` objects into calls of :mod:`acl.physics.beams`, :mod:`acl.physics.latch`
and :mod:`acl.physics.equilibrium`.  Forces come from an injected ``force_model(design, positions,
drive) -> {capsule: force 3-vector (N)}`` (``acl.analysis.acoustics.force_model`` in production,
:func:`reduced_eq3_force_model` for tests and quick estimates); ``positions`` maps every capsule to
its centre (m, absolute).

Degrees of freedom (capsules translate rigidly, no rotation):

* Mount on a beam: the two in-plane directions perpendicular to the beam axis, restoring force
  from paper Eq. (1) (``mode="eq1"``) or the dead-load elastica (``mode="large"``), isotropic in
  that plane (smallest second moment of the section);
* Mount on a latch: one DOF along the latch axis (its direction a -> b), latch force law;
* Mount on a spring: one DOF along the spring axis, linear;
* Fix: none; a capsule that is neither mounted nor fixed moves along the axes of the springs
  linking it;
* Link by a truss: the linked capsules form a rigid group that moves together (its allowed
  displacements are the intersection of its members'); to an anchor or ``ground``: fixed.
* Link by a spring: linear spring along the spring axis between the two ends.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Callable, Mapping

import numpy as np

from acl.design.model import Design, Drive, Tone
from acl.diagnostics import Diagnostic, DiagnosticBag, warning
from acl.analysis import effects as EF
from acl.physics import beams as B
from acl.physics import effects as PE
from acl.physics import equilibrium as EQ
from acl.physics import latch as LT
from acl.physics.forces import pair_law_force
from acl.physics.springs import spring_force

ForceModel = Callable[[Design, Mapping[str, np.ndarray], Drive], Mapping[str, np.ndarray]]

CONTACT_GAP = 0.0     # m; orifice centres closer than this (along their rest direction) = contact
LENGTH_SCALE = 5e-6   # m; continuation scales displacements by this (steps of at most 0.5 of it)


# ----------------------------------------------------------------------------------------------
# Results
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class MechanismState:
    """One equilibrium of the whole mechanism (``status`` from :mod:`acl.physics.equilibrium`)."""

    positions: dict           # capsule -> centre (m)
    displacements: dict       # capsule -> displacement from rest (m)
    deflections: dict         # beam -> load-point deflection (m); latch -> shuttle travel; spring -> extension
    status: str
    stable: bool
    residual: float           # N
    diagnostics: tuple[Diagnostic, ...] = ()


@dataclass(frozen=True)
class VoltageSweep:
    """Stable branch in drive scale ``V`` (multiplier of the drive shape's amplitudes)."""

    voltage: np.ndarray
    positions: dict           # capsule -> (m, 3) centres
    status: str               # "ok" | "snap_in" | "no_convergence"
    snap_voltage: float | None
    snap_positions: dict | None
    message: str = ""
    checks: object = ()       # the validity diagnostics, or a function computing them on first use

    @cached_property
    def diagnostics(self) -> tuple[Diagnostic, ...]:
        """Validity warnings at the branch's last point (Eq. (1) range: W-MECH-001), computed on first use."""
        return tuple(self.checks() if callable(self.checks) else self.checks)

    def snap_gap(self, design: Design, a: str, b: str) -> float | None:
        """Distance between the closest orifice centres of a and b at the snap-in (m), None without snap."""
        if self.snap_positions is None:
            return None
        ca, cb = design.capsule(a), design.capsule(b)
        oa, ob = _closest_orifices(ca, cb)
        da = self.snap_positions[a] - np.asarray(ca.center)
        db = self.snap_positions[b] - np.asarray(cb.center)
        return float(np.linalg.norm((np.asarray(ob) + db) - (np.asarray(oa) + da)))

    def gap(self, design: Design, a: str, b: str) -> np.ndarray:
        """Distance between the closest orifice centres of capsules a and b along the branch (m)."""
        ca, cb = design.capsule(a), design.capsule(b)
        oa, ob = _closest_orifices(ca, cb)
        da = self.positions[a] - np.asarray(ca.center)
        db = self.positions[b] - np.asarray(cb.center)
        return np.linalg.norm((np.asarray(ob) + db) - (np.asarray(oa) + da), axis=-1)


@dataclass(frozen=True)
class LatchMargin:
    """Force available along a latch's switching direction vs the force its model requires."""

    latch: str
    state: str                # rest state of the latch ("a" or "b")
    bistable: bool
    required: float           # N, switching force (a -> b) or release force (b -> a)
    available: float          # N, drive force on the shuttle's capsules along the switching direction
    margin: float             # available / required (inf if required == 0)
    switching_force: float
    release_force: float | None
    barrier: float | None     # J


# ----------------------------------------------------------------------------------------------
# A reduced force law (paper Eq. 3) for tests and quick estimates
# ----------------------------------------------------------------------------------------------

def reduced_eq3_force_model(alpha: float, gamma: float) -> ForceModel:
    """Paper Eq. (3): every capsule pair attracts with (alpha/d^2 - 2 gamma) V^2 along the line of closest orifices.

    ``alpha`` in N m^2/V^2 (paper: 174.5 nN um^2 V^-2 = 1.745e-19), ``gamma`` in N/V^2 (0.027 nN V^-2);
    V is the root-sum-square of the drive's tone amplitudes; d the distance between orifice centres.
    """
    def model(design: Design, positions: Mapping[str, np.ndarray], drive: Drive) -> dict:
        V2 = sum(t.amplitude**2 for t in drive.tones)
        out = {c.name: np.zeros(3) for c in design.capsules}
        caps = design.capsules
        for i, ca in enumerate(caps):
            for cb in caps[i + 1:]:
                oa, ob = _closest_orifices(ca, cb)
                pa = np.asarray(oa) + np.asarray(positions[ca.name]) - np.asarray(ca.center)
                pb = np.asarray(ob) + np.asarray(positions[cb.name]) - np.asarray(cb.center)
                r = pb - pa
                d = float(np.linalg.norm(r))
                f = pair_law_force(alpha, gamma, d, 1.0) * V2 * r / d
                out[ca.name] = out[ca.name] + f
                out[cb.name] = out[cb.name] - f
        return out

    model.quadratic_in_amplitude = True   # (alpha/d^2 - 2 gamma) V^2
    return model


def _closest_orifices(ca, cb):
    best = None
    for oa in ca.orifices:
        for ob in cb.orifices:
            d = np.linalg.norm(np.subtract(ob.center, oa.center))
            if best is None or d < best[0]:
                best = (d, oa.center, ob.center)
    if best is None:
        return ca.center, cb.center
    return best[1], best[2]


# ----------------------------------------------------------------------------------------------
# Degrees of freedom
# ----------------------------------------------------------------------------------------------

def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _perp_basis(axis) -> np.ndarray:
    a = _unit(axis)
    trial = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = _unit(trial - a * (trial @ a))
    return np.column_stack([e1, np.cross(a, e1)])


def _intersect(A: np.ndarray, Bm: np.ndarray) -> np.ndarray:
    """Orthonormal basis of span(A) intersected with span(B) (3 x k)."""
    if A.shape[1] == 0 or Bm.shape[1] == 0:
        return np.zeros((3, 0))
    PA = A @ np.linalg.pinv(A)
    PB = Bm @ np.linalg.pinv(Bm)
    w, v = np.linalg.eigh(0.5 * (PA @ PB + PB @ PA))
    return v[:, w > 1 - 1e-9]


@dataclass
class _Element:
    """A restoring element acting on one capsule group's displacement x (3-vector)."""

    kind: str
    name: str
    group: int
    force: Callable[[np.ndarray], tuple]      # x -> (f (3,), K (3, 3))
    measure: Callable[[np.ndarray], float]    # x -> reported deflection
    span: object = None
    beam: object = None
    force_batch: Callable | None = None       # X (B, 3) -> (f (B, 3), K (B, 3, 3)); None: ``force`` row by row


@dataclass
class _Mechanism:
    groups: list                 # list of lists of capsule names
    bases: list                  # 3 x k_g per group
    offsets: list                # start index in q per group
    elements: list
    links: list                  # (spring k, axis n, group a or None, group b or None)
    n: int                       # number of group coordinates q (before truss-bar constraints)
    member_group: dict           # capsule -> group index
    Z: np.ndarray = None         # q = Z z: null space of the truss-bar constraints (n x m)

    @property
    def m(self) -> int:
        return self.Z.shape[1]


class _UnionFind:
    def __init__(self, items):
        self.parent = {i: i for i in items}

    def find(self, x):
        while self.parent[x] != x:
            self.parent[x] = self.parent[self.parent[x]]
            x = self.parent[x]
        return x

    def union(self, a, b):
        self.parent[self.find(a)] = self.find(b)


def _beam_effects(design: Design | None) -> tuple[float, float, float] | None:
    """(E scale, E gradient, elastica weight) of declared stiffness_scale / stiffness_gradient / large_deflection, None if none."""
    if design is None or not any(PE.EFFECT_TABLE[e.name].beam_law for e in design.effects):   # the one table
        return None
    es = (EF.coefficients(design, "stiffness_scale") or {"e_scale": 1.0})["e_scale"]
    g = (EF.coefficients(design, "stiffness_gradient") or {"e_gradient": 0.0})["e_gradient"]
    w = (EF.coefficients(design, "large_deflection") or {"elastica_weight": 0.0})["elastica_weight"]
    return es, g, w


def _e_scale(design: Design | None) -> float:
    sc = EF.coefficients(design, "stiffness_scale") if design is not None else None
    return sc["e_scale"] if sc else 1.0


def _beam_law(beam, mode: str, design: Design | None = None):
    L, l, EI = beam.length, beam.rigid_length, beam.bending_stiffness
    basis = _perp_basis(beam.axis)
    P_perp = basis @ basis.T
    eff = _beam_effects(design)
    if eff is not None:
        # declared effects: the fit's deflection law (acl.physics.effects), inverted; mode "large" = full elastica
        es, g, w = eff
        w = 1.0 if mode == "large" else w
        k0 = 1e-30 / float(PE.effective_beam_deflection(1e-30, L, l, EI, es, g, w))
    else:
        k0 = B.eq1_small_force_stiffness(L, l, EI)

    def law_batch(X):
        """Paper Eq. (1) for displacements X (B, 3) at once: restoring force (B, 3) and tangent stiffness (B, 3, 3)."""
        u = X @ P_perp.T
        delta = np.linalg.norm(u, axis=1)
        small = delta < 1e-15 * L
        d = np.where(small, 1e-3 * L, delta)             # a placeholder in the linear range where delta ~ 0
        P = np.asarray(B.eq1_force(d, L, l, EI), float)
        kt = 1.0 / np.asarray(B.eq1_compliance(P, L, l, EI), float)       # = eq1_tangent_stiffness, one inversion
        n = u / d[:, None]
        nn = n[:, :, None] * n[:, None, :]
        K = kt[:, None, None] * nn + (P / d)[:, None, None] * (P_perp[None] - nn)
        f = P[:, None] * n
        if small.any():
            f[small], K[small] = k0 * u[small], k0 * P_perp
        return f, K

    def law(x):
        if eff is None and mode != "large":
            f, K = law_batch(np.asarray(x, float)[None])
            return f[0], K[0]
        u = P_perp @ x
        delta = float(np.linalg.norm(u))
        if delta < 1e-15 * L:
            return k0 * u, k0 * P_perp
        if eff is not None:
            P, kt = PE.effective_beam_force(delta, L, l, EI, es, g, w)
        elif mode == "large":
            P = float(B.elastica_force(delta, L, l, EI))
            kt = float(B.elastica_tangent_stiffness(delta, L, l, EI))
        else:
            P = float(B.eq1_force(delta, L, l, EI))
            kt = float(1.0 / B.eq1_compliance(P, L, l, EI))       # = eq1_tangent_stiffness, one inversion
        n = u / delta
        K = kt * np.outer(n, n) + (P / delta) * (P_perp - np.outer(n, n))
        return P * n, K

    law.batch = law_batch if eff is None and mode != "large" else None
    return law, basis, (lambda x: float(np.linalg.norm(P_perp @ x)))


def latch_geometry(latch, design: Design | None = None) -> tuple:
    """(angle, length, width, thickness, E) of a latch; E scaled by a declared stiffness_scale."""
    return (latch.angle, latch.length, latch.width, latch.thickness, latch.youngs_modulus * _e_scale(design))


def _latch_law(latch, design: Design | None = None):
    a = _unit(latch.axis)
    aa = np.outer(a, a)
    geo = latch_geometry(latch, design)
    u0 = 0.0
    if latch.state == "b":
        land = LT.latch_landscape(*geo)
        u0 = land.state_b if land.bistable else 0.0

    h = 1e-7 * geo[1]

    def law_batch(X):
        """The latch law for displacements X (B, 3): LT.latch_force_and_stiffness row by row, one evaluation."""
        u = u0 + np.asarray(X, float) @ a
        f = LT.latch_force(np.concatenate([u, u + h, u - h]), *geo).reshape(3, -1)
        k = (f[1] - f[2]) / (2 * h)
        return f[0][:, None] * a, k[:, None, None] * aa

    def law(x):
        f, K = law_batch(np.asarray(x, float)[None])
        return f[0], K[0]

    law.batch = law_batch
    return law, a[:, None], (lambda x: u0 + float(a @ x))


def build_mechanism(design: Design, mode: str = "eq1") -> _Mechanism:
    """Degrees of freedom and restoring elements of ``design`` (module docstring); raises DiagnosticError on bad joints."""
    bag = DiagnosticBag()
    names = [c.name for c in design.capsules]
    uf = _UnionFind(names)
    grounded: set = set()
    bars: list = []                   # (capsule, capsule or anchor position) distance constraints
    anchors = {a.name: a for a in design.anchors}
    trusses = {t.name for t in design.trusses}
    springs = {s.name: s for s in design.springs}
    supported = {n for n in names if design.mount_of(n) is not None}
    for j in design.joints:
        if j.kind != "link":
            continue
        for end in (j.a, j.b):
            if end not in names and end not in anchors and end != "ground":
                bag.error("E-MECH-001", f"link end `{end}` is not a capsule, an anchor or ground", j.span,
                          "link capsules, anchors or `ground`")
        if j.element_kind == "truss":
            if j.element not in trusses:
                bag.error("E-MECH-002", f"no truss named `{j.element}`", j.span)
                continue
            ends = [e for e in (j.a, j.b) if e in names]
            other = j.b if j.a in names else j.a
            if len(ends) == 2 and ends[0] in supported and ends[1] in supported:
                bars.append((ends[0], ends[1], j.span))            # two-force member between supports
            elif len(ends) == 2:
                uf.union(ends[0], ends[1])                         # carries the unsupported capsule
            elif len(ends) == 1 and ends[0] in supported and other in anchors:
                bars.append((ends[0], np.asarray(anchors[other].position, float), j.span))
            else:
                grounded.update(ends)
        elif j.element not in springs:
            bag.error("E-MECH-002", f"no spring named `{j.element}`", j.span)
    bag.raise_if_errors()

    roots = sorted({uf.find(n) for n in names}, key=names.index)
    groups = [[n for n in names if uf.find(n) == r] for r in roots]
    member_group = {n: gi for gi, g in enumerate(groups) for n in g}

    elements: list[_Element] = []
    allowed = [np.eye(3) for _ in groups]
    mounted = [False] * len(groups)
    for gi, g in enumerate(groups):
        for cname in g:
            joint = design.mount_of(cname)
            if cname in grounded or (joint is not None and joint.kind == "fix"):
                allowed[gi] = np.zeros((3, 0))
                mounted[gi] = True
                continue
            if joint is None:
                continue
            mounted[gi] = True
            try:
                if joint.target_kind == "beam":
                    beam = design.beam(joint.target)
                    law, basis, measure = _beam_law(beam, mode, design)
                    elements.append(_Element("beam", beam.name, gi, law, measure, beam.span, beam, law.batch))
                elif joint.target_kind == "latch":
                    lt = design.latch(joint.target)
                    law, basis, measure = _latch_law(lt, design)
                    elements.append(_Element("latch", lt.name, gi, law, measure, lt.span, None, law.batch))
                else:
                    sp = design.spring(joint.target)
                    n_ax = _unit(sp.axis)
                    basis = n_ax[:, None]
                    elements.append(_Element(      # restoring force k x along the axis (= -spring_force)
                        "spring", sp.name, gi,
                        (lambda x, k=sp.stiffness, n_=n_ax: (-spring_force(k, n_ @ x) * n_, k * np.outer(n_, n_))),
                        (lambda x, n_=n_ax: float(n_ @ x)), sp.span, None,
                        (lambda X, k=sp.stiffness, n_=n_ax: (-spring_force(k, X @ n_)[:, None] * n_,
                                                             np.broadcast_to(k * np.outer(n_, n_), (X.shape[0], 3, 3))))))
            except KeyError as exc:
                bag.error("E-MECH-003", f"capsule `{cname}` is mounted on a missing element: {exc}",
                          joint.span)
                continue
            allowed[gi] = _intersect(allowed[gi], basis)

    links = []
    for j in design.joints:
        if j.kind == "link" and j.element_kind == "spring":
            sp = springs[j.element]
            ga = member_group.get(j.a)
            gb = member_group.get(j.b)
            links.append((sp.stiffness, _unit(sp.axis), ga, gb, sp.name))
    # floating groups move along the axes of their springs
    for gi in range(len(groups)):
        if not mounted[gi]:
            axes = [n for (_, n, ga, gb, _) in links if gi in (ga, gb)]
            if not axes:
                bag.error("E-MECH-004", f"capsule group {groups[gi]} is neither mounted, fixed nor linked by a spring",
                          design.capsule(groups[gi][0]).span, "add `mount`, `fix` or a spring link")
                continue
            allowed[gi] = np.linalg.svd(np.column_stack(axes), full_matrices=False)[0][:, :np.linalg.matrix_rank(np.column_stack(axes))]
    bag.raise_if_errors()
    offsets, n = [], 0
    for A in allowed:
        offsets.append(n)
        n += A.shape[1]
    # truss bars between supported capsules keep their length (linearized): n . (x_a - x_b) = 0
    rows = []
    for a, b, _span in bars:
        pa = np.asarray(design.capsule(a).center, float)
        pb = np.asarray(design.capsule(b).center, float) if isinstance(b, str) else b
        nb = _unit(pb - pa)
        row = np.zeros(n)
        for end, sgn in ((a, 1.0), (b, -1.0)):
            if isinstance(end, str):
                g = member_group[end]
                A, o = allowed[g], offsets[g]
                row[o:o + A.shape[1]] += sgn * (A.T @ nb)
        rows.append(row)
    Z = np.eye(n)
    if rows and n:
        C = np.array(rows)
        _, s, vt = np.linalg.svd(C)
        rank = int(np.sum(s > 1e-9 * max(s.max(), 1e-300)))
        Z = vt[rank:].T
    return _Mechanism(groups, allowed, offsets, elements, links, n, member_group, Z)


def _group_x(mech: _Mechanism, q: np.ndarray, gi) -> np.ndarray:
    if gi is None:
        return np.zeros(3)
    A = mech.bases[gi]
    o = mech.offsets[gi]
    return A @ q[o:o + A.shape[1]]


def _restoring(mech: _Mechanism):
    """Generalized restoring force and stiffness at one configuration z: :func:`_restoring_rows` at batch size 1."""
    rows = _restoring_rows(mech)

    def restoring(z):
        f, K = rows(np.asarray(z, float)[None])
        return f[0], K[0]

    return restoring


def _positions(design: Design, mech: _Mechanism, q: np.ndarray) -> dict:
    return {c.name: np.asarray(c.center, float) + _group_x(mech, q, mech.member_group[c.name])
            for c in design.capsules}


def _scaled_drive(drive: Drive, V: float) -> Drive:
    return Drive(tones=tuple(Tone(frequency=t.frequency, amplitude=t.amplitude * V, phase=t.phase)
                             for t in drive.tones))


def _external(design: Design, mech: _Mechanism, drive: Drive, force_model: ForceModel):
    # Linear acoustics: every force of a drive whose amplitudes all scale by V scales by V^2.  A force
    # model that declares it (``quadratic_in_amplitude``) is evaluated once per configuration at
    # unit scale instead of rebuilding its drive state for every V of the continuation.
    quadratic = bool(getattr(force_model, "quadratic_in_amplitude", False))

    batch = getattr(force_model, "batch", None)
    caps = design.capsules
    # capsule displacements are linear in the coordinates: centres = rest + z P, and the generalized
    # force is the transpose map, g = f P^T (P: m x 3C, each group's basis placed at its capsules)
    rest, place = _placement(design, mech)

    def centres_of(zs: np.ndarray) -> np.ndarray:          # (B, m) -> (B, C, 3)
        return rest[None] + (zs @ place).reshape(zs.shape[0], len(caps), 3)

    def generalized(forces: np.ndarray) -> np.ndarray:     # (B, C, 3) -> (B, m)
        return forces.reshape(forces.shape[0], -1) @ place.T

    # Continuation asks for the force at one configuration several times (the point, its voltage
    # derivative at V +- dV, the tangent, the fold test): a quadratic model's unit-drive force of the
    # last configurations is kept (keyed on the exact coordinates; the design is immutable).
    memo: dict = {}

    def external_batch(zs, V):
        """external() for many configurations (B, m) at once (one vectorised force evaluation)."""
        zs = np.atleast_2d(np.asarray(zs, float))
        if not quadratic:
            return generalized(batch(design, centres_of(zs), _scaled_drive(drive, V)))
        keys = [z.tobytes() for z in zs]
        missing = [i for i, k in enumerate(keys) if k not in memo]
        if missing:
            rows = generalized(batch(design, centres_of(zs[missing]), drive))
            for i, row in zip(missing, rows):
                memo[keys[i]] = row
        out = np.array([memo[k] for k in keys]).reshape(zs.shape[0], -1) * (V * V)
        while len(memo) > 64:
            memo.pop(next(iter(memo)))
        return out

    def external(z, V):
        if batch is not None:
            return external_batch(np.asarray(z, float)[None], V)[0]
        q = mech.Z @ z
        if quadratic:
            unit = force_model(design, _positions(design, mech, q), drive)
            forces = {k: np.asarray(v, float) * V * V for k, v in unit.items()}
        else:
            forces = force_model(design, _positions(design, mech, q), _scaled_drive(drive, V))
        g = np.zeros(mech.n)
        for gi, members in enumerate(mech.groups):
            A, o = mech.bases[gi], mech.offsets[gi]
            if A.shape[1] == 0:
                continue
            total = sum((np.asarray(forces.get(c, np.zeros(3)), float) for c in members), np.zeros(3))
            g[o:o + A.shape[1]] += A.T @ total
        return mech.Z.T @ g

    if batch is not None:
        external.batch = external_batch
    return external


def _admissible(design: Design, mech: _Mechanism):
    caps = design.capsules
    pairs = []
    for i, ca in enumerate(caps):
        for cb in caps[i + 1:]:
            if mech.member_group[ca.name] == mech.member_group[cb.name]:
                continue
            oa, ob = _closest_orifices(ca, cb)
            rest = np.subtract(ob, oa)
            pairs.append((ca.name, cb.name, np.asarray(oa), np.asarray(ob), rest / np.linalg.norm(rest)))

    # each pair's gap along its rest direction is affine in the coordinates: gap = gap0 + z . slope
    gap0 = np.array([n @ (ob - oa) for _, _, oa, ob, n in pairs], float)
    slope = np.zeros((mech.m, len(pairs)))
    for k, (a, b, _, _, n) in enumerate(pairs):
        for name, sign in ((b, 1.0), (a, -1.0)):
            gi = mech.member_group[name]
            A, o = mech.bases[gi], mech.offsets[gi]
            row = np.zeros(mech.n)
            row[o:o + A.shape[1]] = A.T @ n
            slope[:, k] += sign * (mech.Z.T @ row)

    def admissible(z):
        return bool(np.all(gap0 + np.asarray(z, float) @ slope > CONTACT_GAP))

    admissible.rows = lambda zs: np.all(gap0 + np.asarray(zs, float) @ slope > CONTACT_GAP, axis=-1)
    return admissible


def _deflections(mech: _Mechanism, q: np.ndarray) -> dict:
    out = {el.name: el.measure(_group_x(mech, q, el.group)) for el in mech.elements}
    for (_, nax, ga, gb, name) in mech.links:
        out[name] = float(nax @ (_group_x(mech, q, ga) - _group_x(mech, q, gb)))
    return out


def _validity(mech: _Mechanism, q: np.ndarray, mode: str) -> tuple[Diagnostic, ...]:
    if mode != "eq1":
        return ()
    found = []
    for el in mech.elements:
        if el.kind != "beam":
            continue
        beam = el.beam
        delta = el.measure(_group_x(mech, q, el.group))
        if delta <= B.EQ1_LIMIT_FLOOR * beam.length:       # below the limit of any rigid length
            continue
        limit = B.eq1_validity_limit(beam.length, beam.rigid_length)
        if delta > limit:
            found.append(warning(
                "W-MECH-001",
                f"beam `{beam.name}` deflects {delta * 1e6:.3g} um, beyond the {limit * 1e6:.3g} um where "
                f"paper Eq. (1) departs from the elastica by more than {B.EQ1_TOLERANCE:.0%}",
                beam.span, "analyse with mode='large' (elastica)"))
    return tuple(found)


_PREPARED: list = []     # [(design, mode, (mechanism, restoring, admissible))], most recent first


def _prepared(design: Design, mode: str):
    """(mechanism, restoring, admissible) of ``design``: built once per design (immutable) and mode.

    Schedulers solve thousands of equilibria of one design under different drives.
    """
    for d, m, hit in _PREPARED:
        if d is design and m == mode:
            return hit
    mech = build_mechanism(design, mode)
    hit = (mech, _restoring(mech), _admissible(design, mech))
    _PREPARED[:] = ([(design, mode, hit)] + _PREPARED)[:8]
    return hit


def _restoring_rows(mech: _Mechanism):
    """The restoring force of :func:`_restoring` for B configurations at once: z (B, m) -> (f (B, m), K (B, m, m))."""
    def restoring(z):
        q = np.atleast_2d(np.asarray(z, float)) @ mech.Z.T
        nb = q.shape[0]
        f = np.zeros((nb, mech.n))
        K = np.zeros((nb, mech.n, mech.n))

        def x_of(g):
            if g is None or mech.bases[g].shape[1] == 0:
                return np.zeros((nb, 3))
            A, o = mech.bases[g], mech.offsets[g]
            return q[:, o:o + A.shape[1]] @ A.T

        for el in mech.elements:
            A, o = mech.bases[el.group], mech.offsets[el.group]
            k = A.shape[1]
            if k == 0:
                continue
            X = x_of(el.group)
            if el.force_batch is not None:
                fe, Ke = el.force_batch(X)
            else:
                each = [el.force(x) for x in X]
                fe, Ke = np.array([e[0] for e in each]), np.array([e[1] for e in each])
            f[:, o:o + k] += fe @ A
            K[:, o:o + k, o:o + k] += A.T[None] @ Ke @ A[None]
        for (ks, nax, ga, gb, _) in mech.links:
            pull = -spring_force(ks, (x_of(ga) - x_of(gb)) @ nax)        # restoring k x of the link's extension
            blocks = [(g, s) for g, s in ((ga, 1.0), (gb, -1.0)) if g is not None and mech.bases[g].shape[1]]
            for g, sgn in blocks:
                A, o = mech.bases[g], mech.offsets[g]
                f[:, o:o + A.shape[1]] += sgn * pull[:, None] * (A.T @ nax)[None]
            for g1, s1 in blocks:
                for g2, s2 in blocks:
                    A1, o1, A2, o2 = mech.bases[g1], mech.offsets[g1], mech.bases[g2], mech.offsets[g2]
                    K[:, o1:o1 + A1.shape[1], o2:o2 + A2.shape[1]] += s1 * s2 * ks * np.outer(A1.T @ nax, A2.T @ nax)
        return f @ mech.Z, mech.Z.T[None] @ K @ mech.Z[None]

    return restoring


def _placement(design: Design, mech: _Mechanism) -> tuple[np.ndarray, np.ndarray]:
    """(rest centres (C, 3), P (m, 3C)): capsule centres = rest + z P; a generalized force is f P^T."""
    caps = design.capsules
    rest = np.array([c.center for c in caps], float).reshape(len(caps), 3)
    place = np.zeros((mech.n, 3 * len(caps)))
    for i, c in enumerate(caps):
        gi = mech.member_group[c.name]
        if gi is not None:
            A, o = mech.bases[gi], mech.offsets[gi]
            place[o:o + A.shape[1], 3 * i:3 * i + 3] = A.T
    return rest, mech.Z.T @ place


# ----------------------------------------------------------------------------------------------
# Public entry points
# ----------------------------------------------------------------------------------------------

def equilibrium(design: Design, drive: Drive, force_model: ForceModel, *, mode: str = "eq1",
                start: Mapping[str, np.ndarray] | None = None) -> MechanismState:
    """Stable equilibrium of the whole mechanism under ``drive``, reached by continuation from rest.

    Continuation in the drive scale from 0 to 1 avoids jumping to a far root; if the branch snaps
    before full drive, the status is ``snap_in`` and the positions are those at the snap.
    ``start`` (capsule -> centre) instead solves directly from that configuration (a warm start,
    which keeps hysteresis such as a switched latch); if that fails or is unstable, it continues from rest.
    """
    mech, rest, adm = _prepared(design, mode)
    ext = _external(design, mech, drive, force_model)
    if mech.m == 0:
        q = np.zeros(mech.n)
        return MechanismState(_positions(design, mech, q), _displacements(design, mech, q),
                              _deflections(mech, q), "ok", True, 0.0)
    if start is not None:
        q0 = np.zeros(mech.n)
        for gi, g in enumerate(mech.groups):
            A, o = mech.bases[gi], mech.offsets[gi]
            d = np.asarray(start[g[0]], float) - np.asarray(design.capsule(g[0]).center)
            q0[o:o + A.shape[1]] = A.T @ d
        eq = EQ.solve_equilibrium(rest, ext, mech.Z.T @ q0, 1.0, admissible=adm)
        z, status, stable, res = eq.q, eq.status, eq.stable, eq.residual
    if start is None or status != "ok" or not stable:     # only stable equilibria: continue from rest
        start = None
    if start is None:
        br = EQ.continuation(rest, ext, np.zeros(mech.m), 1.0, admissible=adm, length_scale=LENGTH_SCALE)
        if br.status == "snap_in":
            z, status, stable, res = br.snap.q, "snap_in", False, float("nan")
        elif br.voltage.size and br.status == "ok":
            z, status, stable, res = br.q[-1], "ok", True, float(br.residual[-1])
        else:
            z = br.q[-1] if br.voltage.size else np.zeros(mech.m)
            status, stable, res = "no_convergence", False, float("nan")
    q = mech.Z @ z
    return MechanismState(_positions(design, mech, q), _displacements(design, mech, q),
                          _deflections(mech, q), status, stable, res, _validity(mech, q, mode))


def _displacements(design: Design, mech: _Mechanism, q: np.ndarray) -> dict:
    return {c.name: _group_x(mech, q, mech.member_group[c.name]) for c in design.capsules}


def sweep_voltage(design: Design, drive_shape: Drive, v_max: float, force_model: ForceModel, *,
                  mode: str = "eq1") -> VoltageSweep:
    """Stable equilibria as the drive shape's amplitudes are scaled by V from 0 to ``v_max``; reports snap-in."""
    mech, rest, adm = _prepared(design, mode)
    ext = _external(design, mech, drive_shape, force_model)
    if mech.m == 0:
        return VoltageSweep(np.array([0.0, v_max]), {c.name: np.tile(c.center, (2, 1)) for c in design.capsules},
                            "ok", None, None)
    br = EQ.continuation(rest, ext, np.zeros(mech.m), v_max, admissible=adm, length_scale=LENGTH_SCALE)
    per_point = [_positions(design, mech, mech.Z @ z) for z in br.q]
    positions = {c.name: np.array([p[c.name] for p in per_point]).reshape(len(per_point), 3)
                 for c in design.capsules}
    snap_v, snap_pos = None, None
    if br.status == "snap_in":
        snap_v, snap_pos = br.snap.voltage, _positions(design, mech, mech.Z @ br.snap.q)
    last = mech.Z @ br.q[-1] if br.q.size else None
    # the Eq. (1) validity check solves elastica BVPs: only when someone reads the diagnostics
    checks = (lambda: _validity(mech, last, mode)) if last is not None else ()
    return VoltageSweep(br.voltage, positions, br.status, snap_v, snap_pos, br.message, checks)


def latch_carried(design: Design, latch) -> list[str]:
    """Capsules whose force moves ``latch``'s shuttle: those mounted on it and every capsule trussed to them (one rigid group)."""
    names = {c.name for c in design.capsules}
    group = {j.capsule for j in design.joints if j.kind == "mount" and j.target_kind == "latch" and j.target == latch.name}
    frontier = list(group)
    while frontier:
        c = frontier.pop()
        for j in design.joints:
            if j.kind == "link" and j.element_kind == "truss" and c in (j.a, j.b):
                other = j.b if j.a == c else j.a
                if other not in group and other in names:
                    group.add(other)
                    frontier.append(other)
    return sorted(group)


def latch_margins(design: Design, drive: Drive, force_model: ForceModel,
                  states: dict | None = None) -> dict[str, LatchMargin]:
    """For every latch: drive force on its shuttle's capsules along the switching direction / force required to switch.

    A latch in state a must be pushed along +axis by more than its switching force; one in state b along
    -axis by more than its release force.  The shuttle's capsules are those mounted on it and those trussed
    to them (:func:`latch_carried`).  ``states`` ({latch: "a" | "b"}, e.g. what earlier program steps left)
    overrides the declared rest state; a latch in its other state has its capsules moved by the travel between
    the states (acl.physics.latch.latch_landscape ``state_b``).  Forces are evaluated at those positions.
    """
    states = states or {}
    positions = {c.name: np.asarray(c.center, float) for c in design.capsules}
    lands = {lt.name: LT.latch_landscape(*latch_geometry(lt, design)) for lt in design.latches}
    for lt in design.latches:
        now = states.get(lt.name, lt.state)
        travel = lands[lt.name].state_b
        if now != lt.state and travel is not None:
            shift = float(travel) * (1.0 if now == "b" else -1.0) * _unit(lt.axis)
            for c in latch_carried(design, lt):
                positions[c] = positions[c] + shift
    forces = force_model(design, positions, drive)
    out = {}
    for lt in design.latches:
        land = lands[lt.name]
        a = _unit(lt.axis)
        push = float(sum((np.asarray(forces.get(c, np.zeros(3)), float) @ a for c in latch_carried(design, lt)), 0.0))
        now = states.get(lt.name, lt.state)
        if now == "a":
            required, available = land.switching_force, push
        else:
            required, available = (land.release_force if land.bistable else 0.0), -push
        margin = available / required if required > 0 else float("inf")
        out[lt.name] = LatchMargin(lt.name, now, land.bistable, float(required), available, margin,
                                   land.switching_force, land.release_force, land.barrier)
    return out

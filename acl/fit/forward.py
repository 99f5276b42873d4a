"""Forward model: predict every observable of every row from design + overrides + drive + coefficients + effects.

Rows are grouped by override set (one :class:`acl.fit.mechanism.Instance` each); the frequency
responses are looked up once per (instance, frequency); then every row is evaluated at once with
numpy (no per-row Python).  Base model, per row:

* thrust of actuator i: gamma tau_i(f) V^2 summed over tones (tones add in power), tau_i the thrust
  per V^2 of :mod:`acl.analysis.acoustics` relative to the reference actuator at ``f_ref``;
* single actuator: load P = thrust x (share perpendicular to the beam); deflection by paper Eq. (1);
* facing pair: paper Eq. (3) with attraction positive, P(d) = alpha a(f) V^2/d^2 - (thrust_a + thrust_b)
  (own thrust plus the drag of the partner's jet, F_AS = F_d as the paper assumes), each beam
  deflecting by Eq. (1); the stable equilibrium d = d0 - delta_a - delta_b reached from the rest gap,
  or contact (d = 0) past snap-in.  Solved by a vectorized bracket search and bisection.

Effects (acl.fit.effects) modify these steps; each modifier below cites its source.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from acl.fit import beam as B

N_GRID = 32
N_REFINE = 12
_GRID = np.linspace(0.0, 1.0, N_GRID + 1)     # the bracket grid from the rest gap (0) to the far end (1)


@dataclass
class Prepared:
    """Row-aligned arrays for the forward model (built once per data set).  Side 0 / 1 of a row are
    the actuators of its observable's unit (acl.fit.mechanism); a single unit leaves side 1 empty."""

    n: int
    f: np.ndarray            # (n, T) Hz (0 where no tone)
    v: np.ndarray            # (n, T) V peak
    tau: np.ndarray          # (2, n, T) relative thrust of sides 0, 1
    arel: np.ndarray         # (n, T) relative Bjerknes coefficient
    pair: np.ndarray         # (n,) bool
    L: np.ndarray            # (2, n)
    l: np.ndarray            # (2, n)
    EI: np.ndarray           # (2, n)
    cd: np.ndarray           # (2, n) Eq. (1) integrals at declared uniform stiffness (spring: c_D = 1/k)
    ct: np.ndarray           # (2, n)
    height: np.ndarray       # (2, n)
    proj: np.ndarray         # (n,) thrust share along the motion (single)
    d0: np.ndarray           # (n,) rest gap (pair)
    base: np.ndarray         # (n,) observable = base + s0 delta_0 + s1 delta_1
    s0: np.ndarray
    s1: np.ndarray
    fn: np.ndarray           # (2, n) natural frequency of each side's capsule
    q: np.ndarray            # (2, n) its quality factor
    t: np.ndarray            # (n,) time (s), 0 where not given
    f_ref: float
    gamma0: float            # thrust per V^2 of the reference actuator at f_ref (design value)
    alpha0: float            # Bjerknes coefficient at f_ref (design or physics)
    E0: float                # declared Young's modulus of the first beam
    vmax: float
    instances: dict          # override key -> Instance
    law: np.ndarray = None   # (2, n) int: 0 beam, 1 spring, 2 fixed, 3 latch (acl.fit.mechanism.LAW_CODES)
    caps: np.ndarray = None  # (2, n) object: capsule name of each side ('' none)
    volume: np.ndarray = None    # (2, n) gas volume (m^3)
    radius: np.ndarray = None    # (2, n) orifice radius (m)
    medium: np.ndarray = None    # (4, n) density, surface tension, ambient pressure, polytropic index
    latch_id: np.ndarray = None  # (n,) index into latch_tables (-1: none)
    latch_tables: list = None
    ref_side: np.ndarray = None  # (2, n) bool: the side is the reference capsule (for f_ref normalisation)
    ref_capsule: str = ""
    units: np.ndarray = None     # (n,) object: unit label ("pair a-b", "single c")
    experiment: np.ndarray = None  # (n,) object: experiment label of the row ('' none)
    modes0: dict = None          # capsule -> (natural frequency Hz, Q) in the reference instance
    cavity: dict = field(default_factory=dict)   # free cavity parameter -> {"value", "dlnv": {capsule: dlnV/dp}}
    side_table: np.ndarray = None    # (2, n) index into ftables (-1: no capsule)
    ftables: list = None             # (ln V/V0, ln f/f0) of each capsule kind (acl.physics.effects.volume_frequency_table)
    groups: list = None              # acl.fit.group.GroupBlock of every group of 3+ capsules (their rows)
    group_row: np.ndarray = None     # (n,) bool: the row belongs to one of them
    state: np.ndarray = None         # (n,) bool: the row observes a latch state (0 a, 1 b), acl.fit.forward.switch_probability
    pearson: tuple = None            # (measured values, row weights) when fitting: state rows predict y + r_P / w
    ref_orifice: str = ""            # "capsule.orifice" of the reference capsule's first orifice
    gamma_caps: frozenset = None     # capsules whose thrust gamma scales (a design parameter declared as their
                                     # `thrust`); None: every capsule (gamma then stands for the drive pressure)
    gamma_side: np.ndarray = None    # (2, n) bool: side c's capsule is one of them
    latch_geometries: list = None    # the geometry (acl.analysis.mechanics.latch_geometry) of each of latch_tables

    def volume_shift(self, c, fn, lnx):
        """Natural frequency of side ``c`` after its gas volume changed by a factor exp(lnx) (rows), from the tables."""
        out = fn.copy()
        for j, (lx, lf) in enumerate(self.ftables):
            m = self.side_table[c] == j
            if np.any(m):
                x = np.broadcast_to(lnx, fn.shape)[m]
                out[m] = fn[m] * np.exp(np.interp(x, lx, lf))
        return out

    @property
    def beam(self):
        return self.law == 0


def prepare(data, load_instance, f_ref: float | None = None, gamma_caps=None) -> Prepared:
    """Build the row arrays; ``load_instance(key)`` returns the Instance of an override set.  ``gamma_caps``: the
    capsules whose thrust the coefficient gamma scales (those declaring a design parameter as their ``thrust``,
    acl.fit.problem.thrust_capsules; the reference capsule is the first of them); None: every capsule."""
    from acl.fit.mechanism import (LAW_CODES, alpha_per_v2, pair_alpha_per_v2, reference_pair, reference_unit,
                                   thrust_per_v2)

    n = data.n
    T = max(1, max((len(t) for t in data.tones), default=1))
    f = np.zeros((n, T))
    v = np.zeros((n, T))
    for i, tones in enumerate(data.tones):
        for k, (fk, vk) in enumerate(tones):
            f[i, k], v[i, k] = fk, vk
    if f_ref is None:
        used = f[v > 0]
        vals, counts = np.unique(used, return_counts=True) if used.size else (np.array([1e5]), np.array([1]))
        top = vals[counts == counts.max()]
        f_ref = float(top[np.argmin(np.abs(top - np.median(used)))]) if used.size else 1e5
    keys = [data.override_key(i) for i in range(n)]
    instances = {}
    for key in dict.fromkeys(keys):
        instances[key] = load_instance(key)
    ref = instances[keys[0]]
    ref_unit = ref.unit(data.observable[0]) if n else reference_unit(ref)
    gamma_caps = frozenset(gamma_caps) if gamma_caps else None

    def in_units(name):
        return any(name in (u.net.caps if u.net is not None else u.capsules) for u in ref.units.values())

    ref_cap = next((c.name for c in ref.design.capsules
                    if in_units(c.name) and (gamma_caps is None or c.name in gamma_caps)), None) or \
        next((c.name for c in ref.design.capsules if any(c.name in u.capsules for u in ref.units.values())),
             ref_unit.capsules[0])
    gamma0 = float(thrust_per_v2(ref, f_ref)[ref_cap])
    pair_ref = None
    for key in dict.fromkeys(keys):
        pu = next((u for name, u in instances[key].units.items() if u.kind in ("pair", "group")
                   and np.any(data.observable[np.array([k == key for k in keys])] == name)), None)
        if pu is not None:
            pair_ref = (instances[key], pu)
            break
    ref_pair = reference_pair(*pair_ref) if pair_ref else ()
    # alpha scales the reference pair's Bjerknes coefficient: its magnitude (two bubbles driven above and below their
    # resonances repel, a negative coefficient; every pair keeps its sign in arel)
    alpha_ref = abs(pair_alpha_per_v2(pair_ref[0], *ref_pair, f_ref)) if len(ref_pair) == 2 else 0.0
    arr = {k: np.zeros((2, n)) for k in ("L", "l", "EI", "height", "fn", "q", "cd", "ct", "volume", "radius")}
    arr["L"][:] = 1.0
    arr["EI"][:] = 1.0
    arr["fn"][:] = 1e5
    arr["q"][:] = 10.0
    law = np.full((2, n), LAW_CODES["fixed"], int)
    caps = np.full((2, n), "", dtype=object)
    medium = np.ones((4, n))
    tau = np.zeros((2, n, T))
    arel = np.zeros((n, T))
    pair = np.zeros(n, bool)
    proj = np.ones(n)
    d0 = np.full(n, np.nan)
    base, s0, s1 = np.zeros(n), np.zeros(n), np.zeros(n)
    latch_id = np.full(n, -1)
    latch_tables: list = []
    latch_index: dict = {}
    units = np.full(n, "", dtype=object)
    groups: list = []
    group_row = np.zeros(n, bool)
    state = np.zeros(n, bool)
    gtables: dict = {}

    def gtable(volume, radii, target_hz, med):
        """First-mode table of a single-orifice capsule; a multi-orifice capsule's mode nearest ``target_hz``."""
        key = (volume, radii, target_hz if len(radii) > 1 else 0.0, *med)
        if key not in gtables:
            gtables[key] = (volume_frequency_table(volume, radii[0], *med) if len(radii) == 1 else
                            capsule_volume_frequency_table(volume, radii, target_hz, *med))
        return gtables[key]

    by_group: dict = {}
    for i, key in enumerate(keys):
        by_group.setdefault((key, data.observable[i]), []).append(i)
    from acl.fit.beam import stiffness_integrals

    for (key, name), rows in by_group.items():
        inst = instances[key]
        unit = inst.unit(name)
        rows = np.asarray(rows)
        units[rows] = f"{unit.kind} {'-'.join(unit.capsules)}"
        state[rows] = inst.design.observe(name).kind == "state"
        medium[:, rows] = np.asarray(inst.medium, float)[:, None]
        if unit.kind == "group":
            from acl.fit.group import block

            blk = block(inst, unit, name, rows, f, v, gamma0, alpha_ref, gtable)
            if gamma_caps is not None:
                blk.gmask = np.array([blk.caps[c] in gamma_caps for c in blk.orif_cap], bool)
            groups.append(blk)
            group_row[rows] = True
            oc = blk.orif_cap[blk.oi[0]] if blk.kind[0] == 0 else blk.oi[0]
            s0_ = unit.sides[blk.cap_node[oc]]
            law[0, rows], caps[0, rows] = LAW_CODES[s0_.law], blk.caps[oc]
            o0 = int(np.flatnonzero(blk.orif_cap == oc)[0]) if np.any(blk.orif_cap == oc) else 0
            arr["height"][0, rows] = blk.cap_height[oc]
            arr["fn"][0, rows], arr["q"][0, rows] = blk.fn[o0], blk.q[o0]
            arr["L"][0, rows], arr["l"][0, rows], arr["EI"][0, rows] = s0_.L, s0_.l, s0_.EI
            if s0_.law == "latch":
                if s0_.latch not in latch_index:
                    latch_index[s0_.latch] = len(latch_tables)
                    latch_tables.append(latch_table(s0_.latch))
                latch_id[rows] = latch_index[s0_.latch]
            rest_gap = np.linalg.norm(blk.points[blk.oj[0]] - blk.points[blk.oi[0]])
            base[rows] = np.where(blk.kind == 0, rest_gap, blk.obase)
            d0[rows] = rest_gap if blk.kind[0] == 0 else np.nan
            continue
        for c, side in enumerate(unit.sides):
            law[c, rows] = LAW_CODES[side.law]
            caps[c, rows] = side.capsule
            arr["height"][c, rows] = side.height
            arr["fn"][c, rows], arr["q"][c, rows] = side.mode
            arr["volume"][c, rows], arr["radius"][c, rows] = side.bubble
            if side.law == "beam":
                arr["L"][c, rows], arr["l"][c, rows], arr["EI"][c, rows] = side.L, side.l, side.EI
                cd, ct = stiffness_integrals(np.array([side.L]), np.array([side.l]), np.array([side.EI]))
                arr["cd"][c, rows], arr["ct"][c, rows] = cd[0], ct[0]
            elif side.law == "spring":
                arr["cd"][c, rows] = side.compliance
            elif side.law == "latch":
                if side.latch not in latch_index:
                    latch_index[side.latch] = len(latch_tables)
                    latch_tables.append(latch_table(side.latch))
                latch_id[rows] = latch_index[side.latch]
        pair[rows] = unit.kind == "pair"
        proj[rows] = unit.sides[0].proj
        d0[rows] = unit.d0
        for fk in np.unique(f[rows][v[rows] > 0]):
            m = (f[rows] == fk) & (v[rows] > 0)
            tp = thrust_per_v2(inst, fk)
            for c, side in enumerate(unit.sides):
                tau[c, rows] += m * (tp[side.capsule] / gamma0)
            if unit.kind == "pair" and alpha_ref:
                arel[rows] += m * (alpha_per_v2(inst, unit, fk) / alpha_ref)
        b, a0, a1 = inst.output_map(inst.design.observe(name))
        base[rows], s0[rows], s1[rows] = b, a0, a1
    alpha0 = _alpha0(ref, alpha_ref)
    t = np.where(np.isfinite(data.time), data.time, 0.0)
    E0 = next((s.E for u in ref.units.values() for s in u.sides if s.law == "beam"), 0.0)
    exp = getattr(data, "experiment", None)
    # first natural frequency vs gas volume of every side's capsule, tabulated (bubble shrinkage, cavity)
    ftab_index: dict = {}
    ftables: list = []
    side_table = np.full((2, n), -1)
    for c in range(2):
        combo = np.column_stack([arr["volume"][c], arr["radius"][c], medium.T])
        uniq, inv = np.unique(combo, axis=0, return_inverse=True)
        for j, row in enumerate(uniq):
            if row[0] <= 0:
                continue
            key = tuple(row)
            if key not in ftab_index:
                ftab_index[key] = len(ftables)
                ftables.append(volume_frequency_table(*row))
            side_table[c, inv.ravel() == j] = ftab_index[key]
    modes0 = {}
    for inst in instances.values():
        for u in inst.units.values():
            if u.net is not None:       # a group: every capsule (its first orifice's mode) and every orifice
                for lab, (fn, q) in zip(u.net.labels, u.net.modes):
                    modes0.setdefault(lab.split(".")[0], (float(fn), float(q)))
                    modes0.setdefault(lab, (float(fn), float(q)))
                continue
            for s in u.sides:
                modes0.setdefault(s.capsule, s.mode)
                c = inst.design.capsule(s.capsule)
                if len(c.orifices) == 1:
                    modes0.setdefault(f"{s.capsule}.{c.orifices[0].name}", s.mode)
    rc = ref.design.capsule(ref_cap)
    ref_orifice = f"{ref_cap}.{rc.orifices[0].name}" if rc.orifices else ""
    gamma_side = (np.ones((2, n), bool) if gamma_caps is None else
                  np.array([[c in gamma_caps for c in caps[k]] for k in range(2)], bool).reshape(2, n))
    return Prepared(n, f, v, tau, arel, pair, arr["L"], arr["l"], arr["EI"], arr["cd"], arr["ct"], arr["height"],
                    proj, d0, base, s0, s1, arr["fn"], arr["q"], t, f_ref, gamma0, alpha0, float(E0),
                    float(max(v.sum(axis=1).max(), 1e-9)), instances, law, caps, arr["volume"], arr["radius"],
                    medium, latch_id, latch_tables, caps == ref_cap, ref_cap, units,
                    exp if exp is not None else np.full(n, "", dtype=object), modes0, {}, side_table, ftables,
                    groups, group_row, state, ref_orifice=ref_orifice, gamma_caps=gamma_caps, gamma_side=gamma_side,
                    latch_geometries=list(latch_index))


def latch_table(geometry) -> tuple:
    """(F_a, u_a, F_switch, F_b, u_b): rising branches of the latch holding force (acl.physics.latch), from state a
    up to the switching force and beyond state b, for a vectorized inverse (load -> shuttle travel)."""
    from acl.physics.latch import latch_landscape

    land = latch_landscape(*geometry)
    u, F = np.asarray(land.u), np.asarray(land.force)
    i_peak = int(np.argmax(F[: np.searchsorted(u, land.unstable)] if land.bistable else F))
    Fa, ua = np.maximum.accumulate(F[: i_peak + 1]), u[: i_peak + 1]
    if land.bistable:
        ib = int(np.searchsorted(u, land.state_b))
        Fb, ub = np.maximum.accumulate(F[ib:]), u[ib:]
    else:
        Fb, ub = Fa[-1:], ua[-1:]
    return Fa, ua, float(Fa[-1]), Fb, ub


def latch_travel(load, table, e_scale=1.0, blend=0.0):
    """Shuttle travel under ``load`` from state a: the first branch below the switching force, the far branch above it
    (a fresh ramp from state a on every row; latch_force scales with E, acl.physics.latch).

    ``blend`` > 0 (a search device, never the model: acl.fit.select._cross_switch): the expected travel when the
    switching force scatters log-normally by ``blend`` (the probit of :func:`switch_probability`), (1 - p) u_a + p u_b,
    which is smooth in the load where the step is not."""
    Fa, ua, fsw, Fb, ub = table
    x = np.asarray(load, float) / e_scale
    if blend > 0:
        p = switch_probability(x / fsw, blend)
        return (1.0 - p) * np.interp(x, Fa, ua) + p * np.interp(x, Fb, ub)
    return np.where(x <= fsw, np.interp(x, Fa, ua), np.interp(x, Fb, ub))


def lone_latch_rows(P) -> np.ndarray:
    """(n,) bool: displacement rows of a latch on its own (not in a pair or a group; not a state row)."""
    if P.latch_id is None:
        return np.zeros(P.n, bool)
    grp = P.group_row if P.group_row is not None else np.zeros(P.n, bool)
    state = P.state if P.state is not None else np.zeros(P.n, bool)
    return (P.latch_id >= 0) & ~P.pair & ~grp & ~state & (P.s0 != 0)


def latch_branch_mismatch(P, y, prediction) -> np.ndarray:
    """(n,) bool: lone-latch displacement rows whose ``prediction`` lies on the other side of the switch than the
    measured value ``y`` (each side of the midpoint between the travel at the switching force and state b)."""
    out = np.zeros(P.n, bool)
    rows = lone_latch_rows(P)
    for tid in np.unique(P.latch_id[rows]):
        m = rows & (P.latch_id == tid)
        _, ua, _, _, ub = P.latch_tables[tid]
        mid = 0.5 * (ua[-1] + ub[0])
        meas = (np.asarray(y, float)[m] - P.base[m]) / P.s0[m] > mid
        pred = (np.asarray(prediction, float)[m] - P.base[m]) / P.s0[m] > mid
        out[np.flatnonzero(m)] = meas != pred
    return out


def latch_travel_exact(load, geometry, table, e_scale=1.0, steps=4):
    """Shuttle travel under ``load`` of either sign from state a, as the analysis solves the latch law: the branch of
    :func:`latch_travel` (a pull towards state a stretches the beams, u < 0, from the stiffness at rest) polished by
    Newton on acl.physics.latch.latch_force (von Mises truss), each step kept inside its branch."""
    from acl.physics.latch import latch_force

    th, L, w, t, E = geometry
    Fa, ua, fsw, Fb, ub = table
    x = np.asarray(load, float) / e_scale
    h = 1e-7 * L
    k0 = float((latch_force(h, th, L, w, t, E) - latch_force(-h, th, L, w, t, E)) / (2 * h))
    far = x > fsw
    lo = np.where(x < 0, -np.inf, np.where(far, ub[0], ua[0]))
    hi = np.where(x < 0, 0.0, np.where(far, ub[-1], ua[-1]))
    u = np.where(x < 0, x / k0, latch_travel(np.maximum(x, 0.0), table))
    for _ in range(steps):
        F = latch_force(np.stack([u, u + h, u - h]), th, L, w, t, E)
        slope = (F[1] - F[2]) / (2 * h)
        step = np.where(slope > 0, (F[0] - x) / np.where(slope > 0, slope, 1.0), 0.0)
        u = np.clip(u - step, lo, hi)
    return u


def eq3_alpha_param(design):
    """The design's parameter that gives paper Eq. (3)'s alpha: one named `alpha` whose unit is a force times an
    area per volt squared (N m^2/V^2), else None.  A parameter that is only named alpha (`param alpha = 1`, an
    angle, a design's own coefficient) is not the fit's alpha: read by name alone, `param alpha = 1` (1 N m^2/V^2 in
    SI) made `acl synth` snap every pair in at 1 V."""
    from acl.units import UnitError, parse_unit

    for p in design.params:
        if p.name == "alpha":
            try:
                dims = parse_unit(p.unit)[1] if p.unit else (0,) * 7
            except UnitError:
                return None
            return p if dims == parse_unit("N*m^2/V^2")[1] else None
    return None


def _alpha0(inst, alpha_ref: float) -> float:
    """Design value of alpha: a parameter `alpha` in N m^2/V^2 (:func:`eq3_alpha_param`), else the physics
    prediction at f_ref."""
    p = eq3_alpha_param(inst.design)
    if p is not None:
        return float(p.value)
    return float(alpha_ref) if alpha_ref > 0 else 1.745e-19   # paper Eq. (3): 174.5 nN um^2/V^2


# ----------------------------------------------------------------------------------------------
# Effect modifiers (each one formula, its source in the docstring)
# ----------------------------------------------------------------------------------------------

# The formulas live in acl.physics.effects (the analysis applies the same ones to declared effects).
from acl.physics.effects import (capsule_volume_frequency_table, drag_load, elastica_blend,  # noqa: E402,F401
                                 gain_tilt, mode_response_ratio, saturation, shrunk_frequency, substrate_factor, transducer_resonance,
                                 volume_frequency_table)


# ----------------------------------------------------------------------------------------------
# Prediction
# ----------------------------------------------------------------------------------------------

def predict(P: Prepared, coeffs: dict, effects: dict, latch_blend: float = 0.0) -> np.ndarray:
    """Predicted value (SI) of every row.  ``coeffs``: gamma, alpha, e_scale, gain, f0 / q (scales of every
    capsule's natural frequency and Q), ``f0@CAP`` / ``q@CAP`` (one capsule's), absent = design value;
    ``effects``: effect id -> {param: value} (internal coordinates, acl.fit.effects).  ``latch_blend`` > 0: a lone
    latch's shuttle travel smoothed across its switch (:func:`latch_travel`; a search device, not the model)."""
    key = _memo_key(P, coeffs, effects, latch_blend) if MEMO > 0 else None
    if key is not None:
        memo = P.__dict__.setdefault("_memo", {})
        if key in memo:
            return memo[key].copy()
    with np.errstate(all="ignore"):
        red = _distinct(P, effects, coeffs) if DEDUP else None
        if red is None:
            out = _predict(P, coeffs, effects, latch_blend)
        else:       # each distinct row once (repeats, a calibration beam's rows at every gap): the same numbers
            Pu, inv = red
            out = _predict(Pu, coeffs, {k: e for k, e in effects.items() if k != "offset_drift"}, latch_blend)[inv]
            out = _offset_drift(P, out, effects)
    if key is not None:
        if len(memo) >= MEMO:
            del memo[next(iter(memo))]                 # the oldest
        memo[key] = out.copy()
    return out


def predict_many(P: Prepared, items) -> list:
    """[:func:`predict` (P, coeffs, effects) for (coeffs, effects) in ``items``], the same numbers bit for bit, the pair
    solves of the predictions made at once (:func:`_pair_solve_many`: fewer, larger array operations; a Jacobian's
    columns, acl.fit.solve.fd_least_squares, or independent probes).  The last full pair solve kept for reuse
    (:func:`_pair_solve`) is read, not replaced: it changes which work a solve skips, never its numbers.  With groups
    or latch states (whose solves keep state from one prediction to the next), or the warm start inside FD_COLUMNS,
    one after the other."""
    items = list(items)
    if len(items) < 2 or (WARM and FD_COLUMNS.active) or P.groups or _layout(P)["any_state"] or not np.any(P.pair):
        return [predict(P, c, e) for c, e in items]
    out: list = [None] * len(items)
    keys = [_memo_key(P, c, e, 0.0) if MEMO > 0 else None for c, e in items]
    memo = P.__dict__.setdefault("_memo", {})
    todo = []
    for i, key in enumerate(keys):
        if key is not None and key in memo:
            out[i] = memo[key].copy()
        else:
            todo.append(i)
    reds = [_distinct(P, items[i][1], items[i][0]) if DEDUP else None for i in todo]
    if any(r is not reds[0] for r in reds):          # different row reductions (an effect reads the time)
        for i in todo:
            out[i] = predict(P, *items[i])
        return out
    red = reds[0] if reds else None
    Pu = P if red is None else red[0]
    with np.errstate(all="ignore"):
        steps = [_predict_steps(Pu, items[i][0], items[i][1] if red is None else
                                {k: e for k, e in items[i][1].items() if k != "offset_drift"}) for i in todo]
        reqs, done = [], {}
        for t, st in enumerate(steps):
            try:
                reqs.append((t, next(st)))
            except StopIteration as stop:
                done[t] = stop.value
        for (t, _), ab in zip(reqs, _pair_solve_many(Pu, [q for _, q in reqs])):
            try:
                steps[t].send(ab)
                raise RuntimeError("a prediction makes one pair solve")
            except StopIteration as stop:
                done[t] = stop.value
    for t, i in enumerate(todo):
        res = done[t] if red is None else _offset_drift(P, done[t][red[1]], items[i][1])
        if keys[i] is not None:
            if len(memo) >= MEMO:
                del memo[next(iter(memo))]
            memo[keys[i]] = res.copy()
        out[i] = res
    return out


class Model:
    """The forward model of a prepared data set as the fit calls it: ``model(coeffs, effects)`` is :func:`predict`,
    ``model.many([(coeffs, effects), ...])`` :func:`predict_many` (a Jacobian's columns at once)."""

    def __init__(self, P: Prepared):
        self.P = P

    def __call__(self, coeffs: dict, effects: dict) -> np.ndarray:
        return predict(self.P, coeffs, effects)

    def many(self, items) -> list:
        return predict_many(self.P, items)


MEMO = 64      # predictions kept per data set (an optimizer revisits points: starts, polishes, the final evaluation)
DEDUP = True   # predict each distinct row once (:func:`_distinct`)

# the row-aligned fields of Prepared that _predict reads, with their row axis
_ROW_FIELDS = {"f": 0, "v": 0, "tau": 1, "arel": 0, "pair": 0, "L": 1, "l": 1, "EI": 1, "cd": 1, "ct": 1, "height": 1,
               "proj": 0, "d0": 0, "base": 0, "s0": 0, "s1": 0, "fn": 1, "q": 1, "t": 0, "law": 1, "volume": 1,
               "radius": 1, "medium": 1, "latch_id": 0, "ref_side": 1, "side_table": 1, "gamma_side": 1,
               "group_row": 0, "state": 0, "caps": 1, "units": 0, "experiment": 0}
_TIMED = ("bubble_shrinkage",)    # effects whose prediction of a row depends on its time other than by offset_drift


def _distinct(P: Prepared, effects: dict, coeffs: dict = None):
    """(Prepared of the distinct rows, index of each row's) when the prediction can be made on the distinct rows only,
    else None.  Rows are alike when every input of :func:`_predict` is bitwise the same (time left out unless an
    effect other than offset_drift reads it: offset_drift is added after, :func:`_offset_drift`); _predict is
    elementwise in the rows, and its few reductions over rows (the pair solve's tolerance from the largest gap, its
    stop when every row converged, the reference row of a free resonance) see the same set of values, so each row's
    number is the one the full prediction gives, bit for bit (tests/test_fit_pair_warm.py).  Not with groups (their
    blocks index rows) nor latch states (their Pearson weights are per row), nor with a coefficient given per row
    (acl.fit.report's ``tone_weight``)."""
    lay = _layout(P)
    if P.groups or lay["any_state"] or P.pearson is not None or lay["any_grp"]:
        return None
    if coeffs and any(np.ndim(v) for v in coeffs.values()):
        return None
    timed = any(e in effects for e in _TIMED)
    cache = P.__dict__.setdefault("_distinct", {})
    if timed not in cache:
        cache[timed] = _reduce_rows(P, with_time=timed)
    return cache[timed]


def _reduce_rows(P: Prepared, with_time: bool):
    """(Prepared of P's distinct rows in order of first occurrence, inverse index), or None when every row differs."""
    import dataclasses

    cols = []
    for name, ax in _ROW_FIELDS.items():
        a = getattr(P, name)
        if a is None or (name == "t" and not with_time) or name in ("units", "experiment"):
            continue
        a = np.moveaxis(np.asarray(a), ax, 0).reshape(P.n, -1)
        if a.dtype == object:
            _, codes = np.unique(a.astype(str), return_inverse=True)
            a = codes.reshape(P.n, -1)
        cols.append(np.ascontiguousarray(a).astype(np.float64).view(np.uint64) if a.dtype.kind == "f"
                    else a.astype(np.int64).view(np.uint64))
    rows = np.ascontiguousarray(np.hstack(cols))
    key = rows.view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))).ravel()
    _, first, inv = np.unique(key, return_index=True, return_inverse=True)
    if first.size == P.n:
        return None
    order = np.argsort(first)                     # distinct rows in order of first occurrence
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    keep = first[order]
    sub = {}
    for name, ax in _ROW_FIELDS.items():
        a = getattr(P, name)
        if a is not None:
            sub[name] = np.take(a, keep, axis=ax)
    Pu = dataclasses.replace(P, n=int(keep.size), **sub)
    return Pu, rank[inv.ravel()]


def _offset_drift(P: Prepared, out, effects):
    """An offset and a linear drift in time added to every row (effect offset_drift)."""
    if "offset_drift" in effects:
        e = effects["offset_drift"]
        out = out + e["offset"] + e["drift"] * P.t
    return out


def _memo_key(P, coeffs, effects, latch_blend):
    """Key of a prediction that depends on its arguments alone (floats only; not with latch states, whose rows depend
    on the fit's reweighting state), else None."""
    if _layout(P)["any_state"]:
        return None
    try:
        return (tuple(sorted((k, float(v).hex()) for k, v in coeffs.items())),
                tuple(sorted((e, tuple(sorted((k, float(v).hex()) for k, v in ps.items()))) for e, ps in effects.items())),
                float(latch_blend).hex())
    except (TypeError, ValueError):
        return None


def _resonance_factors(P: Prepared, coeffs: dict, effects: dict):
    """(2, n, T) factor on each side's squared volume amplitude from a shifted resonance: free f0 / Q
    (normalised so that the reference capsule's thrust at f_ref keeps its value gamma) and bubble
    shrinkage (the volume V0 exp(-r t) through the resonance model, acl.physics.effects.shrunk_frequency)."""
    keys = [k for k in coeffs if k.split("@")[0] in ("f0", "q")]
    cav = [k for k in coeffs if k.startswith("cavity@")]
    rate = effects.get("bubble_shrinkage", {}).get("shrink_rate", 0.0)
    if not keys and not rate and not cav:
        return None
    fn = P.fn.copy()
    q = P.q.copy()
    for k in keys:
        what, _, cap = k.partition("@")
        arr, j = (fn, 0) if what == "f0" else (q, 1)
        cap = cap or P.ref_capsule
        scale = coeffs[k] / P.modes0[cap][j]
        if k.partition("@")[2]:
            arr[P.caps == cap] *= scale
        else:
            arr *= scale
    for k in cav:      # a free cavity parameter: gas volumes linear in it, the resonance follows (resonance model)
        spec = P.cavity[k.partition("@")[2]]
        for cap, dlnv in spec["dlnv"].items():
            m = P.caps == cap
            ratio = max(1.0 + dlnv * (coeffs[k] - spec["value"]), 1e-6)
            for c in range(2):
                fn[c] = np.where(m[c], P.volume_shift(c, fn[c], np.log(ratio)), fn[c])
    keys = keys + cav
    norm = 1.0
    for c in range(2 if keys else 0):   # the reference capsule's thrust at f_ref stays gamma
        r = np.flatnonzero(P.ref_side[c])
        if r.size:
            i = int(r[0])
            norm = float(mode_response_ratio(P.f_ref, P.fn[c, i], P.q[c, i], fn[c, i], q[c, i]))
            break
    out = np.ones((2,) + P.f.shape)
    for c in range(2):
        fc = fn[c]
        if rate:
            fc = P.volume_shift(c, fc, -rate * P.t)
        out[c] = mode_response_ratio(P.f, P.fn[c][:, None], P.q[c][:, None], fc[:, None], q[c][:, None]) / norm
    return np.where(np.isfinite(out), out, 0.0)


def _predict(P: Prepared, coeffs: dict, effects: dict, latch_blend: float = 0.0) -> np.ndarray:
    steps = _predict_steps(P, coeffs, effects, latch_blend)
    try:
        req = next(steps)
        while True:
            req = steps.send(_pair_solve(*req[:9]))
    except StopIteration as stop:
        return stop.value


def _predict_steps(P: Prepared, coeffs: dict, effects: dict, latch_blend: float = 0.0):
    """The prediction as a generator: it yields its pair equilibrium request (the arguments of :func:`_pair_solve`,
    then the pair rows' law spec, lam and c_p) once, receives (delta_a, delta_b), and returns the prediction: so that
    the pair solves of several predictions can be made at once (:func:`predict_many`)."""
    lay = _layout(P)
    gamma = coeffs.get("gamma", P.gamma0)
    alpha = coeffs.get("alpha", P.alpha0) * (effects["bjerknes_scale"]["factor"] if "bjerknes_scale" in effects else 1.0)
    e_scale = coeffs.get("e_scale", 1.0)
    gain = coeffs.get("gain", 1.0)
    v2 = lay["v2"]
    g2 = gain * gain            # (a scalar factor: the same products as the full array of it)
    if "transducer_gain" in effects:
        g2 = g2 * gain_tilt(P.f, P.f_ref, effects["transducer_gain"]["gain_slope"]) ** 2
    if "transducer_resonance" in effects:
        e = effects["transducer_resonance"]
        g2 = g2 * transducer_resonance(P.f, P.f_ref, e["inv_f_ratio"], e["gain_q"]) ** 2
    if "drive_saturation" in effects:
        g2 = g2 * saturation(lay["vtot"], effects["drive_saturation"]["inv_vsat2"]) ** 2
    w = v2 * g2
    if "tone_weight" in coeffs:     # (n, T) factor on each tone's squared pressure (acl.fit.report.tone_gain_stderr)
        w = w * coeffs["tone_weight"]
    if np.ndim(w) < 2:
        w = np.broadcast_to(w, P.v.shape)
    thrust = np.empty((2, P.n))
    sub = None                  # no substrate factor (a factor 1: the same numbers)
    if "substrate_proximity" in effects:
        sub = substrate_factor(P.height, effects["substrate_proximity"]["h_substrate"])
    res = _resonance_factors(P, coeffs, effects)
    for c in range(2):
        wc = w if res is None else w * res[c]
        # gamma scales the capsules declaring it (P.gamma_caps); the others keep the design's thrust
        g = gamma if lay["gamma_all"][c] else np.where(P.gamma_side[c], gamma, P.gamma0)
        thrust[c] = g * (P.tau[c] * wc).sum(axis=1)
        if sub is not None:
            thrust[c] = thrust[c] * sub[c]
    es = e_scale * (effects["stiffness_scale"]["e_scale"] if "stiffness_scale" in effects else 1.0)
    beam = lay["beam"]
    cav = [k for k in coeffs if k.startswith("cavity@")]
    grad = effects["stiffness_gradient"]["e_gradient"] if "stiffness_gradient" in effects else None
    lam = effects["large_deflection"]["elastica_weight"] if "large_deflection" in effects else 0.0
    c_p = effects["neighbour_drag"]["inv_plateau"] if "neighbour_drag" in effects else 0.0
    # the per-row law arrays (stiffness integrals, rigid lengths) depend on these alone: kept per data set
    law_key = (float(es).hex(), None if grad is None else float(grad).hex(),
               tuple((k, float(coeffs[k]).hex()) for k in cav))
    arrays = _law_arrays(P, coeffs, es, cav, grad, law_key)
    rigid, cd, ct = arrays["rigid"], arrays["cd"], arrays["ct"]

    def spec(idx, kind=None, parent=None):
        """The deflection law arrays of rows ``idx`` (``kind``: a fixed row set, its arrays kept with the law's;
        ``parent``: the flags of a spec of rows including these, :func:`_spec`)."""
        if kind is not None and kind in arrays:
            return arrays[kind]
        out = _spec(tuple((rigid[c, idx], cd[c, idx], ct[c, idx], P.L[c, idx], P.EI[c, idx] * es, beam[c, idx])
                          for c in range(2)), tuple(P.law[c, idx] for c in range(2)), parent)
        if kind is not None:
            arrays[kind] = out
        return out

    def rows(idx, kind=None, parent=None):
        """Deflection laws of sides 0 and 1 restricted to rows ``idx`` (one law when both sides are alike)."""
        return _make_laws(spec(idx, kind, parent), lam)

    d_0 = np.zeros(P.n)
    d_1 = np.zeros(P.n)
    grp = lay["grp"]
    ratio = np.zeros(P.n)                    # latch rows: push / switching force
    if lay["any_single"]:
        idx = lay["single"]
        latch = lay["latch"]
        load = thrust[0, idx] * lay["proj_single"]
        # a lone actuator has no neighbour (units do not interact): neighbour_drag acts on pairs only
        if lay["any_free"]:
            j = lay["free"]
            law0, _, _ = rows(j, "single")
            d_0[j] = law0(load[~latch])
        for tid, m in lay["latches"]:
            table = P.latch_tables[tid]
            ratio[idx[m]] = load[m] / (table[2] * es)
            d_0[idx[m]] = latch_travel(load[m], table, es, latch_blend)
    if lay["any_pair"]:
        idx = lay["pair"]
        law0, law1, same = rows(idx, "pair")
        if c_p > 0:
            law0 = _with_drag(law0, c_p)
            law1 = law0 if same else _with_drag(law1, c_p)
        # Bjerknes force ~ product of the two volume amplitudes: geometric mean of the per-bubble factors
        wab = w[idx] if res is None else w[idx] * np.sqrt(res[0][idx] * res[1][idx])
        a_rad = alpha * (lay["arel_pair"] * wab).sum(axis=1)
        if sub is not None:
            a_rad = a_rad * np.sqrt(sub[0, idx] * sub[1, idx])
        push = thrust[0, idx] + thrust[1, idx]

        def laws(sub):
            """(law0, law1, same) of the pair rows ``idx[sub]`` (the fallback of the warm start)."""
            l0, l1, sm = rows(idx[sub], parent=spec(idx, "pair")[2])
            if c_p > 0:
                l0 = _with_drag(l0, c_p)
                l1 = l0 if sm else _with_drag(l1, c_p)
            return l0, l1, sm

        # what fixes the deflection laws of the pair rows besides (a_rad, push): equal -> the same equilibrium
        sp = spec(idx, "pair")
        law_sig = (lam, c_p, *sp[0][0], *sp[0][1])
        da, db = yield (P, law0, law1, a_rad, push, lay["d0_pair"], same, law_sig, laws, sp, lam, c_p)
        d_0[idx], d_1[idx] = da, db
    out = P.base + P.s0 * d_0 + P.s1 * d_1
    if lay["any_grp"]:
        from acl.fit import group as G

        grad = effects["stiffness_gradient"]["e_gradient"] if "stiffness_gradient" in effects else 0.0
        for blk in P.groups:
            change, _, rat = G.predict(P, blk, coeffs, effects, w[blk.rows], gamma, alpha, es, lam, grad, c_p)
            out[blk.rows] = P.base[blk.rows] + change
            ratio[blk.rows] = np.where(blk.kind == 3, rat, ratio[blk.rows])
    out = _offset_drift(P, out, effects)
    if lay["any_state"]:
        p = switch_probability(ratio, coeffs.get("spread", SPREAD))
        if P.pearson is not None:
            # fitting a 0/1 outcome y of probability p: while the optimizer searches, the row enters the weighted
            # least squares as its deviance residual sign(p - y) sqrt(-2 ln L) (the sum of squares is -2 ln L: the
            # optimum is the maximum-likelihood probit fit); at that optimum the binomial variance p (1 - p) is held
            # (acl.fit.solve._reweighted) and the row becomes its Pearson residual (p - y)/sqrt(p (1 - p)), whose
            # J^T J is the Fisher information (the intervals) and whose score vanishes at the same optimum.
            # The row "predicts" y + r / w.
            y, wt, held = P.pearson
            REWEIGHT.seen = True
            REWEIGHT.rows = P.state
            if REWEIGHT.active:
                held["var"], held["gen"] = np.maximum(p * (1.0 - p), 1e-10), REWEIGHT.generation
            if held.get("gen") == REWEIGHT.generation:
                r = (p - y) / np.sqrt(held["var"])
            else:
                like = np.maximum(1.0 - np.abs(y - p), 1e-300)
                r = np.sign(p - y) * np.sqrt(-2.0 * np.log(like))
            p = y + r / wt
        out = np.where(P.state, p, out)
    return out


def _layout(P: Prepared) -> dict:
    """What :func:`_predict_steps` reads of the data set alone (row sets, squared drives), made once per data set."""
    lay = P.__dict__.get("_layout")
    if lay is not None:
        return lay
    grp = P.group_row if P.group_row is not None else np.zeros(P.n, bool)
    single = np.flatnonzero(~P.pair & ~grp)
    latch = P.latch_id[single] >= 0
    pair = np.flatnonzero(P.pair)
    lay = {"v2": P.v * P.v, "vtot": P.v.sum(axis=1, keepdims=True), "beam": P.law == 0, "grp": grp,
           "any_grp": bool(grp.any()), "any_state": bool(P.state is not None and np.any(P.state)),
           "gamma_all": [P.gamma_side is None or bool(np.all(P.gamma_side[c])) for c in range(2)],
           "any_single": single.size > 0, "single": single, "latch": latch, "proj_single": P.proj[single],
           "any_free": bool(np.any(~latch)), "free": single[~latch],
           "latches": [(tid, P.latch_id[single] == tid) for tid in np.unique(P.latch_id[single][latch])],
           "any_pair": pair.size > 0, "pair": pair, "arel_pair": P.arel[pair], "d0_pair": P.d0[pair]}
    P.__dict__["_layout"] = lay
    return lay


def _law_arrays(P: Prepared, coeffs: dict, es, cav, grad, key) -> dict:
    """{"rigid", "cd", "ct"} (2, n) of the deflection laws at E scale ``es``, gradient ``grad`` and the free cavity
    sizes ``cav`` (their values in ``coeffs``), kept per data set by ``key``; the row sets' law arrays are added to it
    (:func:`_predict_steps` ``spec``)."""
    store = P.__dict__.setdefault("_law_arrays", {})
    if key in store:
        return store[key]
    beam = P.beam
    rigid = P.l
    for k in cav:       # a free cavity size also lengthens the actuator (its rigid half-length on the beam)
        spec = P.cavity[k.partition("@")[2]]
        for cap, dl in spec.get("dl", {}).items():
            rigid = np.where(P.caps == cap, rigid + dl * (coeffs[k] - spec["value"]), rigid)
    if grad is not None or cav:
        cd, ct = B.stiffness_integrals(P.L, rigid, P.EI * es, 0.0 if grad is None else grad)
        cd, ct = np.where(beam, cd, P.cd), np.where(beam, ct, P.ct)
    else:
        cd, ct = np.where(beam, P.cd / es, P.cd), np.where(beam, P.ct / es, P.ct)
    if len(store) >= LAW_ARRAYS:
        del store[next(iter(store))]
    store[key] = {"rigid": rigid, "cd": cd, "ct": ct}
    return store[key]


LAW_ARRAYS = 16     # law array sets kept per data set (a fit moves E or a gradient only when they are free)


def _spec(arrs, law, parent=None) -> tuple:
    """A law spec: per side the arrays (rigid length, c_D, c_T, L, EI, is a beam) and law codes of some rows, with
    (side 0 fixed, side 1 fixed, both sides alike).  ``parent``: the flags of a spec whose rows include these (a
    side fixed, or sides alike, on all of them is so on any of them: not checked again)."""
    pf = parent or (False, False, False)
    fixed = tuple(pf[c] or bool(np.all(law[c] == 2)) for c in range(2))
    return arrs, law, (*fixed, pf[2] or all(np.array_equal(a, b) for a, b in zip(arrs[0], arrs[1])))


def _make_laws(spec, lam):
    """(law of side 0, law of side 1, same) from a law spec (:func:`_spec`): paper Eq. (1), blended with the elastica
    by ``lam`` (large_deflection), zero for a side fixed to the substrate; one law when both sides are alike.  ``lam``
    a scalar or per row (rows of several predictions stacked, :func:`predict_many`)."""
    arrs, law, (fixed0, fixed1, same) = spec

    def make(l_, cd_, ct_, L_, EI_, beam_):
        if _on(lam) and np.any(beam_):
            wgt = np.where(beam_, lam, 0.0)
            return lambda load: elastica_blend(B.eq1_deflection(load, l_, cd_, ct_),
                                               np.where(beam_, B.elastica_deflection(load, L_, l_, EI_), 0.0), wgt)
        return lambda load: B.eq1_deflection(load, l_, cd_, ct_)

    def still(load):                                     # a side fixed to the substrate does not move
        return np.zeros(np.shape(load))

    first = still if fixed0 else make(*arrs[0])
    if fixed1 and not same:
        return first, still, False
    return first, (first if same else make(*arrs[1])), same


def _on(x) -> bool:
    """A scalar coefficient is non-zero (per-row coefficients: stacked only when all are, :func:`predict_many`)."""
    return bool(np.all(x != 0)) if np.ndim(x) else bool(x)


SPREAD = 0.05     # default relative scatter of a latch's switching force from one ramp to the next


class _Flag:
    """A switch that ``with FLAG: ...`` turns on for the block (``active``)."""

    def __init__(self):
        self.active = False

    def __enter__(self):
        self.active = True
        return self

    def __exit__(self, *exc):
        self.active = False
        return False


class _Reweight(_Flag):
    """Latch states (acl.fit.solve.fit): each fit starts a new ``generation`` (deviance residuals, the likelihood);
    ``with REWEIGHT: predict(...)`` at its optimum holds the binomial variances for the Pearson polish."""

    def __init__(self):
        super().__init__()
        self.generation = 0
        self.seen = False              # set by a prediction that had state rows to weigh
        self.rows = None               # (n,) bool: the state rows of that prediction


REWEIGHT = _Reweight()


def switch_probability(ratio, spread):
    """Probability that a ramp from state a ends in state b: Phi(ln(push / F_switch) / s), the switching force
    log-normally scattered by s from ramp to ramp (a probit threshold model; F_switch of acl.physics.latch)."""
    from scipy.special import ndtr

    with np.errstate(divide="ignore"):
        z = np.log(np.maximum(ratio, 1e-300)) / max(spread, 1e-9)
    return ndtr(z)


def _with_drag(law, c_p, steps=3):
    """Deflection law under a neighbour's jet drag, delta = law(P (1 - c_p |delta|)) (acl.physics.effects.drag_load),
    solved by Newton from the linear-law solution delta_lin / (1 + c_p |delta_lin|)."""
    def dragged(load):
        lin = law(load)
        lo, hi = np.minimum(lin, 0.0), np.maximum(lin, 0.0)
        d = lin / (1.0 + c_p * np.abs(lin))
        for _ in range(steps):
            ad = np.abs(d)
            x = drag_load(load, ad, c_p)
            h = 1e-6 * np.maximum(np.abs(x), 1e-30)
            lx, lxh = law(np.stack([x, x + h]))                     # (one call: the law is elementwise)
            r = lx - d
            slope = (lxh - lx) / h                                  # d law / d load
            dr = -slope * load * c_p * np.sign(d) * (1.0 - c_p * ad > 0) - 1.0   # d r / d delta
            d = np.clip(d - r / np.where(dr != 0, dr, -1.0), lo, hi)
        return d
    return dragged


def _pair_equilibrium(law0, law1, a_rad, push, d0, same=False, tol=None, info=None, guess=None, gather=None):
    """Stable gap of a facing pair under P(d) = a/d^2 - b, first root of d0 - d - delta_a - delta_b from d0.

    Bracketed on a grid from d0 (towards contact when the pair attracts at rest, outwards up to the
    largest repulsive opening otherwise; the whole grid in one vectorized evaluation), then refined by
    the Illinois variant of regula falsi (superlinear, always inside the bracket).
    Returns (delta_a, delta_b); past snap-in (no root before contact) the pair is in contact, d = 0.
    ``tol``: on |gap residual| (default 1e-12 of the largest d0); ``info``: a dict, filled with what
    :func:`_pair_warm` needs to reuse this solve (the bracket cell, its sign margin, the root).
    ``guess`` (with ``gather(rows) -> (law0, law1, same)`` of those rows, repeats allowed): each row's bracketing cell
    in an earlier solve; the grid is then read from d0 only up to the end of that cell (and on to the end where it has
    no crossing there), which gives the same first crossing, the same bracket and the same values bit for bit: the
    grid is elementwise.
    """
    both, g = _gap_residual(law0, law1, a_rad, push, d0, same)
    attract = a_rad / (d0 * d0) - push >= 0
    ra, rb = both(-push)
    far = np.where(attract, 0.02 * d0, d0 - ra - rb + 1e-12)
    m = d0.size
    cols = np.arange(m)
    if guess is None or gather is None or np.shape(guess) != (m,):
        guess, G = None, None
    else:
        G = np.full((N_GRID + 1, m), np.nan) if info is not None and WARM else None
    found, k, a, fa, b, fb, G0, G = _bracket(g, a_rad, push, d0, far, guess, gather, G)
    exact = G0 == 0
    tol = 1e-12 * np.max(d0) if tol is None else tol
    for _ in range(N_REFINE):
        c, fc, flip = _illinois(g, a, fa, b, fb)
        a, fa = np.where(flip, b, a), np.where(flip, fb, 0.5 * fa)
        b, fb = c, fc
        if np.all(np.abs(fc[found]) <= tol):
            break
    d = np.where(exact, d0, b)
    if info is not None and not WARM:       # what a later solve's guess needs (the warm start's extras only with WARM)
        info.update(k=k, found=found)
        info = None
    if info is not None:
        # sign margin: the smallest |G| on the grid points before the bracketing cell (all of them when there is no
        # crossing), where a perturbation would have to flip a sign to make the search stop at another root
        j = np.arange(N_GRID + 1)[:, None]
        before = np.where(found, j < k, True)
        absg = np.where(before & np.isfinite(G), np.abs(G), np.inf)
        jmin = np.argmin(absg, axis=0)
        info.update(attract=attract, far=far, k=k, found=found, exact=exact, d=d, fb=fb,
                    conv=~found | exact | (np.abs(fb) <= tol), jmin=jmin, margin=absg[jmin, cols], Gj=G[jmin, cols],
                    tol=tol)
    found = found | exact
    if info is not None:       # the deflections at d and, 1e-8 d0 further, the slope of the gap residual there
        e = 1e-8 * d0
        dd = np.stack([d, d + e])
        da2, db2 = both(a_rad / (dd * dd) - push)
        da, db = da2[0], db2[0]
        info["slope"] = ((d0 - dd[1] - da2[1] - db2[1]) - (d0 - d - da - db)) / e
    else:
        load = a_rad / (d * d) - push
        da, db = both(load)
    return np.where(found, da, 0.5 * d0), np.where(found, db, 0.5 * d0)


def _gap_residual(law0, law1, a_rad, push, d0, same):
    """(both, g): the two deflections under a load, and the gap residual g(d) = d0 - d - delta_a - delta_b of a pair
    at gap d (paper Eq. 3: Bjerknes a_rad / d^2 against the push)."""
    def both(load):
        da = law0(load)
        return da, (da if same else law1(load))

    def g(d):
        da, db = both(a_rad / (d * d) - push)
        return d0 - d - da - db

    return both, g


def _bracket(g, a_rad, push, d0, far, guess, gather, G=None):
    """(found, k, a, fa, b, fb, g at d0, G) of the first sign change of ``g`` per row on the grid from d0 to ``far``:
    the whole grid at once (``guess`` None; G the grid's values), or read with :func:`_scan` from d0 up to each
    row's guessed cell and on to the end where it has no crossing there (``G``, if given, receives the values)."""
    m = d0.size
    cols = np.arange(m)
    if guess is None:
        D = d0 + _GRID[:, None] * (far - d0)                       # (N_GRID + 1, n)
        G = g(D)
        sg = np.sign(G)
        cross = sg[1:] != sg[:-1]
        k = np.argmax(cross, axis=0)
        return cross.any(axis=0), k, D[k, cols], G[k, cols], D[k + 1, cols], G[k + 1, cols], G[0], G
    npts = np.minimum(np.asarray(guess, int) + 2, N_GRID + 1)
    found, k, a, fa, b, fb, G0 = _scan(cols, npts, a_rad, push, d0, far, gather, G)
    more = ~found & (npts < N_GRID + 1)
    if np.any(more):                               # no crossing up to the guessed cell: read the rest of the grid
        r = np.flatnonzero(more)
        f2, k2, a2, fa2, b2, fb2, _ = _scan(r, np.full(r.size, N_GRID + 1), a_rad, push, d0, far, gather, G)
        found[r], k[r], a[r], fa[r], b[r], fb[r] = f2, k2, a2, fa2, b2, fb2
    return found, k, a, fa, b, fb, G0, G


def _illinois(g, a, fa, b, fb):
    """One step of the Illinois variant of regula falsi inside the bracket [a, b] (Dowell & Jarratt 1971, BIT 11,
    168): (c, g(c), whether the sign flipped against b); the caller keeps or halves fa."""
    den = fb - fa
    nz = den != 0
    mid = 0.5 * (a + b)
    c = np.where(nz, b - fb * (b - a) / np.where(nz, den, 1.0), mid)
    c = np.where((c >= np.minimum(a, b)) & (c <= np.maximum(a, b)), c, mid)
    fc = g(c)
    return c, fc, np.sign(fc) != np.sign(fb)


def _scan(rows, npts, a_rad, push, d0, far, gather, G=None):
    """The grid of :func:`_pair_equilibrium` read on rows ``rows`` from d0 up to ``npts`` points each (one flat
    evaluation): (found, k, a, fa, b, fb, G at d0) of the first crossing per row; ``G`` (N_GRID + 1, n) receives
    the values read."""
    total = int(npts.sum())
    start = np.cumsum(npts) - npts
    r = np.repeat(rows, npts)
    j = np.arange(total) - np.repeat(start, npts)
    d0r, farr = d0[r], far[r]
    D = d0r + _GRID[j] * (farr - d0r)
    l0, l1, sm = gather(r)
    load = a_rad[r] / (D * D) - push[r]
    da = l0(load)
    Gv = d0r - D - da - (da if sm else l1(load))
    if G is not None:
        G[j, r] = Gv
    sg = np.sign(Gv)
    cross = np.zeros(total, bool)
    cross[1:] = (sg[1:] != sg[:-1]) & (j[1:] > 0)
    hits = np.flatnonzero(cross)
    first_row, first = np.unique(r[hits], return_index=True)      # r is sorted by row: the first crossing of each
    t = hits[first]
    pos = np.searchsorted(rows, first_row)
    n = rows.size
    found = np.zeros(n, bool)
    k = np.zeros(n, int)
    a, fa, b, fb = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    found[pos] = True
    k[pos] = j[t] - 1
    a[pos], fa[pos], b[pos], fb[pos] = D[t - 1], Gv[t - 1], D[t], Gv[t]
    # rows without a crossing: the full grid's argmax of no crossing is cell 0
    none = ~found
    if np.any(none):
        t0 = start[none]
        a[none], fa[none] = D[t0], Gv[t0]
        t1 = np.minimum(t0 + 1, start[none] + npts[none] - 1)
        b[none], fb[none] = D[t1], Gv[t1]
    return found, k, a, fa, b, fb, Gv[start]


WARM = False           # True: finite-difference columns start from the last full pair solve (_pair_warm; off: see docs/fit.md)
WARM_SAFETY = 100.0     # a grid sign may move by at most this fraction of its margin (1/100) for the warm start
WARM_CHANGE = 1e-3      # largest relative change of a_rad, push and the rest opening for which a warm start is tried


class _FDColumns(_Flag):
    """``with FD_COLUMNS: predict(...)``: the predictions are finite-difference neighbours of the last one made outside
    (acl.fit.solve.fit's Jacobian), so a pair's equilibrium may start from that solve (:func:`_pair_solve`)."""


FD_COLUMNS = _FDColumns()


def _pair_solve(P, law0, law1, a_rad, push, d0, same, law_sig, laws):
    """:func:`_pair_equilibrium` of the pair rows, using the last full solve (kept on ``P``) where it can.

    Inputs (a_rad, push, deflection laws) bitwise those of the last full solve: its result (the solve is
    deterministic).  Otherwise the full solve reads the grid only up to each row's last bracketing cell (the same
    result bit for bit, :func:`_pair_equilibrium` ``guess``), except inside ``FD_COLUMNS`` (a Jacobian's
    finite-difference columns) with a_rad and push within WARM_CHANGE of the last full solve: :func:`_pair_warm`, a
    Newton step from the last root, kept for a row only if no grid sign before its cell can have flipped and it
    converges to the full solve's tolerance (else that row is solved in full), so a column agrees with the full
    solve's to the solver tolerance (tests/test_fit_pair_warm.py).  Full solves outside FD_COLUMNS refresh the cache."""
    cache = getattr(P, "_eq_cache", None)
    guess = None
    if cache is not None and (cache["d0"] is d0 or (cache["d0"].shape == d0.shape and np.array_equal(cache["d0"], d0))) \
            and cache["same"] == same:
        same_law = _same_law(law_sig, cache["law_sig"])
        if same_law and np.array_equal(a_rad, cache["a_rad"]) and np.array_equal(push, cache["push"]):
            return cache["da"], cache["db"]
        if law_sig[0] or law_sig[1]:     # an iterated law (elastica blend, drag): read the grid only up to the cell
            guess = np.where(cache["found"], cache["k"], N_GRID)
        if WARM and FD_COLUMNS.active and "slope" in cache:
            with np.errstate(all="ignore"):
                ok = np.all(np.abs(a_rad - cache["a_rad"]) <= WARM_CHANGE * np.abs(cache["a_rad"])) and \
                    np.all(np.abs(push - cache["push"]) <= WARM_CHANGE * np.abs(cache["push"]))
            if ok:
                return _pair_warm(cache, law0, law1, a_rad, push, d0, same, laws)
            return _pair_equilibrium(law0, law1, a_rad, push, d0, same, guess=guess, gather=laws)
    if FD_COLUMNS.active:
        return _pair_equilibrium(law0, law1, a_rad, push, d0, same, guess=guess, gather=laws)
    info: dict = {}
    da, db = _pair_equilibrium(law0, law1, a_rad, push, d0, same, info=info, guess=guess, gather=laws)
    info.update(d0=d0, same=same, law_sig=law_sig, a_rad=a_rad, push=push, da=da, db=db)
    P._eq_cache = info
    return da, db


def _same_law(sig, ref) -> bool:
    """Two law signatures (lam, c_p, law arrays) are equal (the same deflection laws)."""
    return (sig[0] == ref[0] and sig[1] == ref[1] and len(sig) == len(ref)
            and all(a is b or np.array_equal(a, b) for a, b in zip(sig[2:], ref[2:])))


def _pair_solve_many(P, reqs) -> list:
    """[:func:`_pair_solve` of each request] (the warm start off): the same numbers, with the solves of
    requests whose deflection laws have the same form (fixed sides, alike sides, elastica blend and drag on or off)
    made at once on their stacked rows (:func:`_pair_equilibrium_many`)."""
    cache = getattr(P, "_eq_cache", None)
    out: list = [None] * len(reqs)
    todo: dict = {}
    for j, q in enumerate(reqs):
        _, law0, law1, a_rad, push, d0, same, law_sig, laws, sp, lam, c_p = q
        guess = None
        if cache is not None and (cache["d0"] is d0 or (cache["d0"].shape == d0.shape
                                                        and np.array_equal(cache["d0"], d0))) and cache["same"] == same:
            if _same_law(law_sig, cache["law_sig"]) and np.array_equal(a_rad, cache["a_rad"]) \
                    and np.array_equal(push, cache["push"]):
                out[j] = (cache["da"], cache["db"])
                continue
            if law_sig[0] or law_sig[1]:
                guess = np.where(cache["found"], cache["k"], N_GRID)
        form = (sp[2], same, _on(lam), bool(c_p > 0))
        todo.setdefault(form, []).append((j, guess))
    for form, items in todo.items():
        if len(items) == 1:
            (j, guess), = items
            q = reqs[j]
            out[j] = _pair_equilibrium(q[1], q[2], q[3], q[4], q[5], q[6], guess=guess, gather=q[8])
            continue
        qs = [reqs[j] for j, _ in items]
        m = qs[0][5].size
        d0 = np.concatenate([q[5] for q in qs])
        arrs = tuple(tuple(np.concatenate([q[9][0][c][k] for q in qs]) for k in range(6)) for c in range(2))
        law = tuple(np.concatenate([q[9][1][c] for q in qs]) for c in range(2))

        def per_row(vals):
            """One coefficient of the stacked predictions: a scalar when they agree bitwise, else per row."""
            vals = [float(v) for v in vals]
            if all(v.hex() == vals[0].hex() for v in vals):
                return vals[0]
            return np.repeat(np.array(vals), m)

        lam = per_row([q[10] for q in qs])
        c_p = per_row([q[11] for q in qs])

        def gather(sub, arrs=arrs, law=law, lam=lam, c_p=c_p, parent=_spec(arrs, law)[2]):
            """(law0, law1, same) of the stacked rows ``sub``."""
            sl = lambda x: x[sub] if np.ndim(x) else x      # noqa: E731
            l0, l1, sm = _make_laws(_spec(tuple(tuple(a[sub] for a in side) for side in arrs),
                                          tuple(x[sub] for x in law), parent), sl(lam))
            if _on(c_p > 0):
                l0 = _with_drag(l0, sl(c_p))
                l1 = l0 if sm else _with_drag(l1, sl(c_p))
            return l0, l1, sm

        law0, law1, same = gather(np.arange(d0.size))
        guess = None if all(g is None for _, g in items) else \
            np.concatenate([np.full(m, N_GRID) if g is None else g for _, g in items])
        da, db = _pair_equilibrium_many(law0, law1, np.concatenate([q[3] for q in qs]),
                                        np.concatenate([q[4] for q in qs]), d0, same, len(qs), guess, gather)
        for b, (j, _) in enumerate(items):
            out[j] = (da[b * m:(b + 1) * m], db[b * m:(b + 1) * m])
    return out


def _pair_equilibrium_many(law0, law1, a_rad, push, d0, same, nblk, guess, gather):
    """:func:`_pair_equilibrium` of ``nblk`` pair solves at once, their rows stacked (blocks of equal size, equal rest
    gaps): the bracket grid read as with ``guess`` (None: the whole grid for every row; a row of a solve without one
    reads the whole grid, which gives the same bracket), and each block's refinement stopped where its own solve stops (all its rows converged), so that
    every block's numbers are its own solve's, bit for bit."""
    both, g = _gap_residual(law0, law1, a_rad, push, d0, same)
    attract = a_rad / (d0 * d0) - push >= 0
    ra, rb = both(-push)
    far = np.where(attract, 0.02 * d0, d0 - ra - rb + 1e-12)
    per = d0.size // nblk
    found, _, a, fa, b, fb, G0, _ = _bracket(g, a_rad, push, d0, far, guess, gather)
    exact = G0 == 0
    tol = 1e-12 * np.max(d0)
    live = np.ones(nblk, bool)
    for _ in range(N_REFINE):
        on = None if live.all() else np.repeat(live, per)
        c, fc, flip = _illinois(g, a, fa, b, fb)
        if live.all():
            a, fa = np.where(flip, b, a), np.where(flip, fb, 0.5 * fa)
            b, fb = c, fc
        else:
            a, fa = np.where(on & flip, b, a), np.where(on, np.where(flip, fb, 0.5 * fa), fa)
            b, fb = np.where(on, c, b), np.where(on, fc, fb)
        live &= ~np.all(((np.abs(fc) <= tol) | ~found).reshape(nblk, per), axis=1)     # as each solve stops
        if not np.any(live):
            break
    d = np.where(exact, d0, b)
    found = found | exact
    load = a_rad / (d * d) - push
    da, db = both(load)
    return np.where(found, da, 0.5 * d0), np.where(found, db, 0.5 * d0)


def _pair_warm(c, law0, law1, a_rad, push, d0, same, laws):
    """Pair equilibrium from the cached full solve ``c`` (:func:`_pair_solve`): one Newton step from its root with its
    slope.  A row keeps it if the gap residual changed, at the root and at the grid point of smallest margin before
    the bracketing cell, by less than 1/WARM_SAFETY of that margin (no grid sign before the root can have flipped:
    the full solve would stop at the same root) and the step lands within the full solve's tolerance; any other row
    is solved by :func:`_pair_equilibrium` with that tolerance."""
    def g(d):
        load = a_rad / (d * d) - push
        da = law0(load)
        db = da if same else law1(load)
        return d0 - d - da - db, da, db

    root, tol = c["d"], c["tol"]
    dj = d0 + np.linspace(0.0, 1.0, N_GRID + 1)[c["jmin"]] * (c["far"] - d0)
    with np.errstate(all="ignore"):
        attract = a_rad / (d0 * d0) - push >= 0
        (g0, gj), DA, DB = g(np.stack([root, dj]))
        change = np.maximum(np.abs(g0 - c["fb"]), np.abs(gj - c["Gj"]))
        found = c["found"] & ~c["exact"]
        # a row at rest (G = 0 at d0: no load) stays there while it has no load
        good = (attract == c["attract"]) & np.where(
            c["exact"], g0 == 0, c["conv"] & (c["margin"] > WARM_SAFETY * change))
        da, db = DA[0], DB[0]
        step = found & good & ~(np.abs(g0) <= tol)
        if np.any(step):
            d1 = root - g0 / c["slope"]
            f1, da1, db1 = g(d1)
            good &= ~step | (np.abs(f1) <= tol)
            da, db = np.where(step, da1, da), np.where(step, db1, db)
    live = c["found"] | c["exact"]
    da, db = np.where(live, da, 0.5 * d0), np.where(live, db, 0.5 * d0)
    bad = ~good
    if np.any(bad):
        l0, l1, sm = laws(bad)
        ra, rb = _pair_equilibrium(l0, l1, a_rad[bad], push[bad], d0[bad], sm, tol=tol)
        da[bad], db[bad] = ra, rb
    return da, db

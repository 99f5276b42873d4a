"""Forward model: predict every observable of every row from design + overrides + drive + coefficients + effects.

Rows are grouped by override set (one :class:`acl.fit.mechanism.Instance` each); the frequency
responses are looked up once per (instance, frequency); then every row is evaluated at once with
numpy (no per-row Python).  Base model, per row:

* thrust of actuator i: gamma tau_i(f) V^2 summed over tones (tones add in power), tau_i the thrust
  per V^2 of :mod:`acl.analysis.acoustics` relative to the reference actuator at ``f_ref``;
* single actuator: load P = thrust x (share perpendicular to the beam); deflection by paper Eq. (1);
* interacting capsules (pairs by default, groups, bodies): the analysis' force model (acl.fit.group: per-orifice
  thrust, Bjerknes force, jet drag, coupled volumes where the capsules are), the one `acl analyze` and `acl compile`
  use;
* facing pair under the declared reduced model (``--model eq3`` only): paper Eq. (3), acl.fit.eq3.

Effects (acl.fit.effects) modify these steps; each modifier below cites its source.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from acl.fit import beam as B
from acl.fit.latch import latch_table, latch_travel, switch_probability
from acl.fit.eq3 import FD_COLUMNS, _Flag, _make_laws, _pair_solve, _pair_solve_many, _spec, _with_drag
from acl.fit.group import Request as GroupRequest


@dataclass(frozen=True)
class ForwardOptions:
    """How the forward model of one data set evaluates (never what it predicts; explicit per data set, not
    process-wide): ``memo`` predictions kept (an optimizer revisits points: starts, polishes, the final evaluation);
    ``dedup`` each distinct row predicted once (:func:`_distinct`); ``warm`` (paper Eq. 3 pairs only, opt-in) a
    Jacobian's finite-difference columns start from the last full pair solve (acl.fit.eq3._pair_warm)."""

    memo: int = 64
    dedup: bool = True
    warm: bool = False


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
    state: np.ndarray = None         # (n,) bool: the row observes a latch state (0 a, 1 b), acl.fit.latch.switch_probability
    pearson: tuple = None            # (measured values, row weights) when fitting: state rows predict y + r_P / w
    ref_orifice: str = ""            # "capsule.orifice" of the reference capsule's first orifice
    gamma_caps: frozenset = None     # capsules whose thrust gamma scales (a design parameter declared as their
                                     # `thrust`); None: every capsule (gamma then stands for the drive pressure)
    gamma_side: np.ndarray = None    # (2, n) bool: side c's capsule is one of them
    latch_geometries: list = None    # the geometry (acl.analysis.mechanics.latch_geometry) of each of latch_tables
    options: ForwardOptions = field(default_factory=ForwardOptions)
    declared: dict = field(default_factory=dict)     # the design's declared effects (fixed in the base model)

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
    if len(groups) > 1:                 # one topology at several rest geometries: one batched solve (acl.fit.group.stack)
        from acl.fit.group import stack

        groups = stack(groups)
    gamma_side = (np.ones((2, n), bool) if gamma_caps is None else
                  np.array([[c in gamma_caps for c in caps[k]] for k in range(2)], bool).reshape(2, n))
    return Prepared(n, f, v, tau, arel, pair, arr["L"], arr["l"], arr["EI"], arr["cd"], arr["ct"], arr["height"],
                    proj, d0, base, s0, s1, arr["fn"], arr["q"], t, f_ref, gamma0, alpha0, float(E0),
                    float(max(v.sum(axis=1).max(), 1e-9)), instances, law, caps, arr["volume"], arr["radius"],
                    medium, latch_id, latch_tables, caps == ref_cap, ref_cap, units,
                    exp if exp is not None else np.full(n, "", dtype=object), modes0, {}, side_table, ftables,
                    groups, group_row, state, ref_orifice=ref_orifice, gamma_caps=gamma_caps, gamma_side=gamma_side,
                    latch_geometries=list(latch_index), declared=dict(ref.declared))


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
    effects = _with_declared(P, effects)
    key = _memo_key(P, coeffs, effects, latch_blend) if P.options.memo > 0 else None
    if key is not None:
        memo = P.__dict__.setdefault("_memo", {})
        if key in memo:
            return memo[key].copy()
    with np.errstate(all="ignore"):
        red = _distinct(P, effects, coeffs) if P.options.dedup else None
        if red is None:
            out = _predict(P, coeffs, effects, latch_blend)
        else:       # each distinct row once (repeats, a calibration beam's rows at every gap): the same numbers
            Pu, inv = red
            out = _predict(Pu, coeffs, {k: e for k, e in effects.items() if k != "offset_drift"}, latch_blend)[inv]
            out = _offset_drift(P, out, effects)
    if key is not None:
        if len(memo) >= P.options.memo:
            del memo[next(iter(memo))]                 # the oldest
        memo[key] = out.copy()
    return out


def predict_many(P: Prepared, items) -> list:
    """[:func:`predict` (P, coeffs, effects) for (coeffs, effects) in ``items``], the same numbers bit for bit, the pair
    solves of the predictions made at once (:func:`_pair_solve_many`: fewer, larger array operations; a Jacobian's
    columns, acl.fit.solve.fd_least_squares, or independent probes).  The last full pair solve kept for reuse
    (:func:`_pair_solve`) is read, not replaced: it changes which work a solve skips, never its numbers.  Groups:
    each block's rows of every prediction in one batched solve from the block's last state, read, not replaced
    (acl.fit.group.predict_many: the same numbers to the solver's tolerance).  With latch states (whose rows keep
    state from one prediction to the next), or the warm start inside FD_COLUMNS, one after the other."""
    items = [(c, _with_declared(P, e)) for c, e in items]
    if len(items) < 2 or (P.options.warm and FD_COLUMNS.active) or _layout(P)["any_state"] or \
            not (np.any(P.pair) or P.groups):
        return [predict(P, c, e) for c, e in items]
    out: list = [None] * len(items)
    keys = [_memo_key(P, c, e, 0.0) if P.options.memo > 0 else None for c, e in items]
    memo = P.__dict__.setdefault("_memo", {})
    todo = []
    for i, key in enumerate(keys):
        if key is not None and key in memo:
            out[i] = memo[key].copy()
        else:
            todo.append(i)
    reds = [_distinct(P, items[i][1], items[i][0]) if P.options.dedup else None for i in todo]
    if any(r is not reds[0] for r in reds):          # different row reductions (an effect reads the time)
        for i in todo:
            out[i] = predict(P, *items[i])
        return out
    red = reds[0] if reds else None
    Pu = P if red is None else red[0]
    with np.errstate(all="ignore"):
        steps = [_predict_steps(Pu, items[i][0], items[i][1] if red is None else
                                {k: e for k, e in items[i][1].items() if k != "offset_drift"}) for i in todo]
        done: dict = {}
        pending = {t: None for t in range(len(steps))}
        while pending:           # every prediction asks for its pair solve, then its groups: each asked at once
            reqs = {}
            for t, ans in pending.items():
                try:
                    reqs[t] = next(steps[t]) if ans is None else steps[t].send(ans)
                except StopIteration as stop:
                    done[t] = stop.value
            pending = _answer_many(Pu, reqs)
    for t, i in enumerate(todo):
        res = done[t] if red is None else _offset_drift(P, done[t][red[1]], items[i][1])
        if keys[i] is not None:
            if len(memo) >= P.options.memo:
                del memo[next(iter(memo))]
            memo[keys[i]] = res.copy()
        out[i] = res
    return out


def _answer_many(P: Prepared, reqs: dict) -> dict:
    """{t: answer} of the requests {t: request} of several predictions (:func:`_predict_steps`): their pair solves in
    one :func:`_pair_solve_many`, each group's rows of every prediction in one acl.fit.group.predict_many."""
    out: dict = {}
    pair = [t for t, q in reqs.items() if not isinstance(q, GroupRequest)]
    for t, ab in zip(pair, _pair_solve_many(P, [reqs[t] for t in pair])):
        out[t] = ab
    grp = [t for t, q in reqs.items() if isinstance(q, GroupRequest)]
    out.update(zip(grp, GroupRequest.answer_many([reqs[t] for t in grp])))
    return out


def _with_declared(P: Prepared, effects: dict) -> dict:
    """``effects`` over the design's declared ones (P.declared, acl.fit.effects.declared_effects): a fitted effect
    replaces the declared effect of the same id."""
    return {**P.declared, **effects} if P.declared else effects


class Model:
    """The forward model of a prepared data set as the fit calls it: ``model(coeffs, effects)`` is :func:`predict`,
    ``model.many([(coeffs, effects), ...])`` :func:`predict_many` (a Jacobian's columns at once)."""

    def __init__(self, P: Prepared):
        self.P = P

    def __call__(self, coeffs: dict, effects: dict) -> np.ndarray:
        return predict(self.P, coeffs, effects)

    def many(self, items) -> list:
        return predict_many(self.P, items)



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
    if cache[timed] is not None:
        cache[timed][0].options = P.options          # the data set's options, as they are now
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
            req = steps.send(req.answer() if isinstance(req, GroupRequest) else _pair_solve(*req[:9]))
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
        grad = effects["stiffness_gradient"]["e_gradient"] if "stiffness_gradient" in effects else 0.0
        got = yield GroupRequest(P, [(coeffs, effects, w[blk.rows], gamma, alpha, es, lam, grad, c_p)
                                     for blk in P.groups])
        for blk, (change, _, rat) in zip(P.groups, got):
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


SPREAD = 0.05     # default relative scatter of a latch's switching force from one ramp to the next


class _Reweight(_Flag):
    """Latch states (acl.fit.solve.fit): each fit starts a new ``generation`` (deviance residuals, the likelihood);
    ``with REWEIGHT: predict(...)`` at its optimum holds the binomial variances for the Pearson polish."""

    def __init__(self):
        super().__init__()
        self.generation = 0
        self.seen = False              # set by a prediction that had state rows to weigh
        self.rows = None               # (n,) bool: the state rows of that prediction


REWEIGHT = _Reweight()


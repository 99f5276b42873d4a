"""Assemble a fit problem: design + data -> prepared rows + the free coefficients (names in docs/data.md).

Names accepted by ``--free`` and by ``free`` design parameters:

* ``gamma`` -- thrust coefficient (N/V^2) of the (first) actuator at the reference frequency; a design
  parameter used as a capsule's ``thrust`` stands for it;
* ``alpha`` -- Bjerknes coefficient of paper Eq. (3) (N m^2/V^2); a design parameter named ``alpha``
  gives its value and bounds;
* ``E`` -- Young's modulus of the beams (fitted as a scale of the declared value); a design
  parameter used as a material's ``youngs`` stands for it;
* ``gain`` -- transducer gain scale (degenerate with gamma and alpha: free only with both fixed);
* ``f0``, ``q`` -- natural frequency (Hz) and quality factor of the reference capsule's first mode,
  every capsule's scaled alike; ``f0:CAP``, ``q:CAP`` -- one capsule's own (paper Fig. 1e / Table S1);
* ``spread`` -- relative scatter of a latch's switching force from ramp to ramp (0/1 ``state`` rows);
* a design parameter that changes only capsule cavities (e.g. a cavity height) -- its value, acting
  through the gas volume on the resonance (acl.physics.resonance), like ``f0`` but physical.

Other free design parameters (geometry that moves bodies) are refused with a diagnostic (E812): the
fit model does not re-resolve geometry per iteration.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acl.diagnostics import DiagnosticError, Span, error, suggest
from acl.fit.solve import Coef

COEFFICIENTS = ("gamma", "alpha", "E", "gain", "f0", "q", "spread")


@dataclass
class Problem:
    path: str
    design: object
    data: object
    prepared: object
    coefs: list
    y: np.ndarray
    sigma: np.ndarray
    param_roles: dict          # design param name -> role
    model: str = "coupled"     # force model of simple pairs: coupled (the analysis', acl.fit.group) or eq3


def load_problem(design_path, data_paths, free=(), search_paths=(), model: str = "coupled", coupled: bool = False):
    """Load design and data, build the rows and the free coefficients; DiagnosticError on any problem.

    ``model``: the force model of simple pairs (acl.fit.mechanism.build_instance: ``eq3`` or ``coupled``);
    ``coupled``: every design through the group model, lone actuators included."""
    import acl
    from acl.fit.data import read_data
    from acl.fit.forward import prepare
    from acl.fit.mechanism import build_instance

    design = acl.load(design_path, search_paths=search_paths)
    data = read_data(data_paths, design)
    cache: dict = {}
    # every override set the rows name is resolved first, so that each one the design does not resolve with is
    # reported (at its first row), not only the first
    designs: dict = {(): design}
    bad = []
    for i in range(data.n):
        key = data.override_key(i)
        if key in designs:
            continue
        try:
            designs[key] = acl.load(design_path, overrides=dict(key), search_paths=search_paths)
        except DiagnosticError as exc:
            designs[key] = None
            first = exc.diagnostics[0]
            where = first.location()
            sp = data.spans[i]
            bad.append(error("E805", f"the design does not resolve with "
                             f"{', '.join(f'{k} = {v}' for k, v in key)}: {first.message}",
                             Span(file=sp.file, line=sp.line, column=1),
                             None if where.startswith("<") else f"see {where}"))
    if bad:
        raise DiagnosticError(bad)

    def load_instance(key):
        if key not in cache:
            d = designs[key] if key in designs else acl.load(design_path, overrides=dict(key), search_paths=search_paths)
            cache[key] = build_instance(d, model, coupled=coupled)
        return cache[key]

    roles = classify_params(design_path, design, search_paths)
    names = [p.name for p in design.params if p.free] + [n for n in free if n]
    # a parameter the fit determines (one value) cannot also be given per row by a `set:` column: the rows' designs
    # used the column's values while the fit reported and wrote back one fitted value (no diagnostic)
    fitted = {n for n in names if any(p.name == n for p in design.params)}
    fitted |= {p for p, r in roles.items() if r in COEFFICIENTS and r in {n if n in COEFFICIENTS else roles.get(n)
                                                                         for n in names}}
    clash = []
    for k in sorted(fitted & set(data.sets)):
        if roles.get(k) in ("geometry", "unused"):        # refused below as not fittable at all (E812)
            continue
        rows = [i for i in range(data.n) if data.sets[k][i]]
        if rows:
            sp = data.spans[rows[0]]
            clash.append(error("E805", f"`set:{k}` gives parameter `{k}` per row, but the fit determines it "
                               f"({'declared `free`' if design.param(k).free else 'the --free names'})", sp,
                               f"drop the set:{k} column, or fix `{k}` (leave it out of --free)"))
    if clash:
        raise DiagnosticError(clash)
    gamma_param = next((n for n in names if (n if n in COEFFICIENTS else roles.get(n)) == "gamma"
                        and (n not in COEFFICIENTS or _has_param(design, n)) and roles.get(n) == "gamma"), None)
    # a design parameter declared as some capsules' `thrust`: gamma scales exactly those (as the analysis applies it)
    P = prepare(data, load_instance, gamma_caps=thrust_capsules(design_path, design, gamma_param, search_paths)
                if gamma_param else None)
    coefs = []
    seen = set()
    caps = {c.name for c in design.capsules}
    for name in names:
        role = name if name in COEFFICIENTS else roles.get(name)
        what, sep, cap = name.partition(":")
        if sep and what in ("f0", "q"):
            if not cap:
                raise DiagnosticError([error("E-USAGE", f"--free {name}: give a capsule after `{what}:`",
                                             Span(file="<--free>", line=1, column=1),
                                             f"e.g. {what}:{sorted(caps)[0]}" if caps else "the design has no capsule")])
            orifices = sorted(f"{c.name}.{o.name}" for c in design.capsules for o in c.orifices)
            if cap not in caps and cap not in orifices:
                raise DiagnosticError([error("E-USAGE", f"--free {name}: no capsule `{cap}`" if "." not in cap else
                                             f"--free {name}: no orifice `{cap}`",
                                             Span(file="<--free>", line=1, column=1),
                                             suggest(cap, sorted(caps) + orifices)
                                             or f"capsules: {', '.join(sorted(caps))}")])
            if cap not in P.modes0:
                raise DiagnosticError([error("E-USAGE", f"--free {name}: `{cap}` is in no unit the data observe",
                                             Span(file="<--free>", line=1, column=1),
                                             f"observed: {', '.join(sorted(k for k in P.modes0 if '.' not in k))}")])
            role = f"{what}@{cap}"
        if role is None:
            cands = list(dict.fromkeys([*COEFFICIENTS, *[p.name for p in design.params]]))
            raise DiagnosticError([error("E-USAGE", f"--free {name}: not a design parameter nor a model coefficient",
                                         Span(file="<--free>", line=1, column=1),
                                         suggest(name, cands) or f"names: {', '.join(cands)}")])
        if role == "cavity":
            coefs.append(_cavity_coef(name, design, P, design_path, search_paths))
            continue
        if role == "geometry":
            p = design.param(name)
            raise DiagnosticError([error("E812", f"parameter `{name}` changes the geometry; the fit model cannot "
                                         "fit geometry yet", p.span, "fix it, or give it per row with set:" + name)])
        if role == "unused":
            p = design.param(name)
            raise DiagnosticError([error("E812", f"parameter `{name}` is not used by the design: the data cannot "
                                         "determine it", p.span)])
        if role in seen:
            continue
        seen.add(role)
        coefs.append(_coef(role, name, design, P))
    if coefs and not np.any(P.state) and data.n <= len(coefs):
        # as many rows as coefficients fit exactly: the residual scale (chi2 / dof) is 0 / 0, and the intervals came
        # out zero-wide ([2.42e-11, 2.42e-11] from one row): an optimistic answer where the data say nothing
        sp = data.spans[-1] if data.n else Span(file=str(data_paths[0]), line=1, column=1)
        raise DiagnosticError([error("E801", f"{data.n} row{'s' if data.n != 1 else ''} for {len(coefs)} free "
                                     f"coefficient{'s' if len(coefs) != 1 else ''} "
                                     f"({', '.join(c.name for c in coefs)}): a fit needs more rows than free "
                                     "coefficients to estimate its errors", sp,
                                     "measure more rows (other voltages, frequencies or gaps), or free fewer "
                                     "coefficients")])
    y = data.value
    if P.group_row is not None and np.any(P.group_row):
        _group_start(P, coefs, y, data.sigma)
    if np.any(P.state):
        from acl.fit.solve import NOMINAL_SIGMA

        if not data.has_sigma:
            sp = data.spans[int(np.flatnonzero(P.state)[0])]
            raise DiagnosticError([error("E801", "latch states (0/1) need a `sigma` column: the fit weighs every other "
                                         "row by it against the states' binomial scatter", sp,
                                         "add a sigma column (for the state rows any positive number, e.g. 0.5)")])
        P.pearson = (np.asarray(y, float), 1.0 / np.where(np.isfinite(data.sigma), data.sigma, NOMINAL_SIGMA), {})
        # a state row's weight is its own: the Pearson residual is already in units of its standard deviation
        P.pearson[1][P.state] = 1.0
        data.sigma = np.where(P.state, 1.0, data.sigma)
    return Problem(design_path, design, data, P, coefs, y, data.sigma, roles, "coupled" if coupled else model)


def _group_start(P, coefs, y, sigma) -> None:
    """Start gamma and alpha where the data are: a group snaps in at a voltage set by alpha/gamma (paper Eq. (3)),
    and a start on the wrong side of that jump traps the least squares (rows predicted in contact while measured
    apart).  A coarse grid of scale factors, each scored by its residuals clipped at 10 sigma, picks the start."""
    from acl.fit.forward import predict
    from acl.fit.solve import JUMP, NOMINAL_SIGMA

    free = [c for c in coefs if c.kind in ("gamma", "alpha")]
    if not free:
        return
    w = 1.0 / np.where(np.isfinite(sigma), sigma, NOMINAL_SIGMA)
    r0 = np.abs(predict(P, {c.kind: c.value for c in free}, {}) - y) * w
    if not np.any(~np.isfinite(r0) | (r0 > JUMP)):
        return                                   # no row on the wrong side of a jump: the design is a fine start
    grid = (0.4, 0.6, 0.8, 1.0, 1.25, 1.6, 2.5)
    best, best_cost = None, np.inf
    import itertools

    for factors in itertools.product(grid, repeat=len(free)):
        coeffs = {c.kind: c.value * f for c, f in zip(free, factors)}
        if any(not (c.lower <= coeffs[c.kind] <= c.upper) for c in free):
            continue
        r = np.clip(np.abs(predict(P, coeffs, {}) - y) * w, 0.0, JUMP)
        cost = float(np.sum(np.where(np.isfinite(r), r, JUMP) ** 2))
        if cost < best_cost:
            best, best_cost = coeffs, cost
    # then a short robust (soft-l1) descent from there: the rows on the wrong side of a snap-in cannot pull it away
    from scipy.optimize import least_squares

    def resid(u):
        r = (predict(P, {c.kind: best[c.kind] * np.exp(x) for c, x in zip(free, u)}, {}) - y) * w
        return np.where(np.isfinite(r), r, 1e6)

    try:
        sol = least_squares(resid, np.zeros(len(free)), loss="soft_l1", f_scale=3.0, max_nfev=25, x_scale=0.1,
                            diff_step=1e-6, bounds=([np.log(c.lower / best[c.kind]) for c in free],
                                                    [np.log(c.upper / best[c.kind]) for c in free]))
        best = {c.kind: best[c.kind] * np.exp(x) for c, x in zip(free, sol.x)}
    except ValueError:
        pass
    for c in free:
        c.value = float(best[c.kind])


def _coef(role, name, design, P) -> Coef:
    dp = name if name not in COEFFICIENTS or _has_param(design, name) else None
    if role == "gamma":
        v = P.gamma0
        lo, hi = v / 1e3, v * 1e3
        if dp and _has_param(design, dp):
            p = design.param(dp)
            ratio = v / p.value if p.value else 1.0
            lo = p.lower * ratio if p.lower is not None else lo
            hi = p.upper * ratio if p.upper is not None else hi
        return Coef("gamma", "gamma", v, lo, hi, v, "N/V^2", design_param=dp)
    if role == "alpha":
        v = P.alpha0
        lo, hi = v / 1e3, v * 1e3
        from acl.fit.forward import eq3_alpha_param

        p = eq3_alpha_param(design)
        if p is not None:
            lo = p.lower if p.lower is not None else lo
            hi = p.upper if p.upper is not None else hi
        return Coef("alpha", "alpha", v, lo, hi, v, "N*m^2/V^2", design_param="alpha" if p is not None else None)
    if role.split("@")[0] in ("f0", "q"):
        what, _, cap = role.partition("@")
        cap = cap or P.ref_capsule
        fn, q = P.modes0[cap]
        if what == "f0":
            return Coef(name, role, fn, 0.5 * fn, 2.0 * fn, fn, "Hz")
        return Coef(name, role, q, 0.2, 200.0, q, "")
    if role == "E":
        return Coef("E", "e_scale", 1.0, 0.01, 100.0, 1.0, "", design_param=dp)
    if role == "spread":
        from acl.fit.forward import SPREAD

        if not np.any(P.state):
            raise DiagnosticError([error("E-USAGE", "--free spread: the data observe no latch state (`state(latch)`)",
                                         Span(file="<--free>", line=1, column=1),
                                         "spread is the scatter of a latch's switching force, seen in 0/1 state rows")])
        return Coef("spread", "spread", SPREAD, 1e-3, 2.0, SPREAD, "")
    return Coef("gain", "gain", 1.0, 0.01, 100.0, 1.0, "")


def _cavity_coef(name, design, P, path, search_paths) -> Coef:
    """A design parameter that changes capsule cavities only: the gas volumes are linear in it (checked by
    perturbation), and the resonance follows them (acl.fit.forward._resonance_factors)."""
    import acl

    p = design.param(name)
    d = acl.load(path, overrides={name: f"{p.value * 1.01!r} {p.unit}".strip()}, search_paths=search_paths)
    slopes, dl = {}, {}
    dp = 0.01 * p.value
    for c0, c1 in zip(design.capsules, d.capsules):
        if c0.cavity.volume != c1.cavity.volume:
            slopes[c0.name] = (c1.cavity.volume / c0.cavity.volume - 1.0) / dp
            m = design.mount_of(c0.name)
            if m is not None and getattr(m, "target_kind", "") == "beam":
                dl[c0.name] = (d.beam(m.target).rigid_length - design.beam(m.target).rigid_length) / dp
    P.cavity[name] = {"value": float(p.value), "dlnv": slopes, "dl": dl}
    lo = p.lower if p.lower is not None else 0.3 * p.value
    hi = p.upper if p.upper is not None else 3.0 * p.value
    return Coef(name, f"cavity@{name}", float(p.value), lo, hi, abs(float(p.value)), p.unit, design_param=name)


def thrust_capsules(path, design, name, search_paths=()) -> tuple:
    """The capsules whose declared ``thrust`` changes with design parameter ``name`` (found by perturbing it, as
    :func:`classify_params`); () when none does."""
    import acl

    p = design.param(name)
    if not p.value:
        return ()
    try:
        d = acl.load(path, overrides={name: f"{p.value * 1.01!r} {p.unit}".strip()}, search_paths=search_paths)
    except DiagnosticError:
        return ()
    return tuple(c0.name for c0, c1 in zip(design.capsules, d.capsules)
                 if c0.thrust_coefficient is not None and c0.thrust_coefficient != c1.thrust_coefficient)


def _has_param(design, name):
    return any(p.name == name for p in design.params)


def classify_params(path, design, search_paths=()) -> dict:
    """Role of each design parameter, found by perturbing it: gamma | E | alpha | geometry | unused."""
    import acl

    roles = {}
    base = design.model_dump(exclude={"params", "sources", "file"})
    from acl.fit.forward import eq3_alpha_param

    alpha = eq3_alpha_param(design)
    for p in design.params:
        if p is alpha:
            roles[p.name] = "alpha"
            continue
        if not p.value:
            roles[p.name] = "geometry"
            continue
        try:
            d = acl.load(path, overrides={p.name: f"{p.value * 1.01!r} {p.unit}".strip()}, search_paths=search_paths)
        except DiagnosticError:
            roles[p.name] = "geometry"
            continue
        new = d.model_dump(exclude={"params", "sources", "file"})
        changed = set(_diff(base, new))
        if not changed:
            roles[p.name] = "alpha" if p is alpha else ("gamma" if p.name == "gamma" else "unused")
        elif all(c.endswith("thrust_coefficient") for c in changed):
            roles[p.name] = "gamma"
        elif all(c.endswith("youngs_modulus") for c in changed):
            roles[p.name] = "E"
        elif any(c.endswith(".cavity.volume") for c in changed) and all(
                (c.startswith(".capsules[") and (".cavity." in c or c.endswith("center[2]")))
                or c.endswith(".rigid_length") for c in changed):
            # a cavity size: the gas volume (resonance) and the actuator's size on its beam; the orifice's
            # small shift in height is neglected (docs/fit.md)
            roles[p.name] = "cavity"
        else:
            roles[p.name] = "geometry"
    return roles


def _diff(a, b, path=""):
    if isinstance(a, dict) and isinstance(b, dict):
        for k in a:
            if k == "span":
                continue
            yield from _diff(a[k], b.get(k), f"{path}.{k}")
    elif isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            yield from _diff(x, y, f"{path}[{i}]")
    elif a != b:
        yield path

"""Assemble the Design: parameters, environment, elements, joints, observations, requirements, programs."""
from __future__ import annotations

import math


from acl.design import geometry as G
from acl.design import model as M
from acl.design.builders import Builder
from acl.design.checks import check_design_geometry, check_programs
from acl.design.core import (D, DECL_KINDS, EFFECT_DOMAIN, EFFECT_RANGES, EFFECT_UNITS, EFFECTS,
                             GRADIENT_REFERENCE, MODULUS_DECADES, PROPERTY_RANGES, Fail, what_is)
from acl.design.finite import all_finite
from acl.design.programs import build_program
from acl.design.values import DeclVal
from acl.diagnostics import Span, suggest
from acl.syntax import ast as A
from acl.units import Quantity, describe, si_unit

TARGET_POINTS = {"beam": "tip", "latch": "shuttle", "spring": "end"}


def assemble(b: Builder) -> M.Design:
    r, env, bag = b.r, b.env, b.bag
    params = _params(b)
    correlations, coverage, discrepancy, measured, lognormal = _uncertainty(b, params)
    medium, transducer = _uses(b)
    if transducer is None and any(m.gain is not None for m in measured):
        bag.error("E325", "measured(gain) gives a gain but the design uses no transducer",
                  next(m.span for m in measured if m.gain is not None), "add `use transducer NAME`")
    transducer = M.with_measured_gain(transducer, measured)

    # ---- elements
    beams_raw: dict[str, dict] = {}
    effects: list[M.Effect] = []
    for name, blk in env.decls.items():
        kind = blk.kind
        if kind not in DECL_KINDS:
            bag.error("E202", f"unknown declaration `{kind}`", blk.kind_span,
                      suggest(kind, DECL_KINDS) or "declarations: " + ", ".join(DECL_KINDS))
            continue
        b.kinds[name] = kind
        try:
            _element(b, name, blk, beams_raw, effects)
        except OverflowError:
            bag.error("E305", f"{kind} `{name}`: a value derived from its entries overflows", blk.span,
                      "check the magnitudes and units of its entries")
            b.failed.add(name)

    # ---- joints
    joints, mounted_on = _joints(b, beams_raw)

    # ---- positions: capsule centres from mounts, beam rigid lengths from their capsules
    capsules: list[M.Capsule] = []
    for name, spec in b.capsules.items():
        if name in b.failed:    # its mount was wrong (reported there)
            continue
        j = mounted_on.get(name)
        if spec.center is None:
            if j is not None and j[0] == "beam":
                beam = beams_raw[j[1]]
                spec.center = G.add(beam["tip"], G.scale(beam["axis"], spec.extent(beam["axis"])))
            elif j is not None and j[0] == "latch":
                spec.center = b.latches[j[1]].anchor
            else:
                bag.error("E204", f"capsule `{name}` needs a `center`" + ("" if j is None else " (a spring end has no position of its own)"),
                          spec.span, "give `center = (x, y, z)` or mount it on a beam tip")
                continue
        orifices = tuple(
            M.Orifice(name=o[0], radius=o[1], normal=o[2], center=G.add(spec.center, G.scale(o[2], o[3])), span=o[4])
            for o in spec.orifices)
        capsules.append(M.Capsule(
            name=name, cavity=M.Cavity(shape=spec.shape, volume=spec.volume, radius=spec.radius, side=spec.side,
                                       height=spec.height, axis=spec.axis, wall=spec.wall),
            orifices=orifices, center=spec.center, thrust_coefficient=spec.thrust, quality_factor=spec.q, span=spec.span))
    beams = []
    carried = {t: c for c, t in mounted_on.items()}
    for name, raw in beams_raw.items():
        if raw["rigid_length"] is None:
            cap = carried.get(("beam", name))
            raw["rigid_length"] = b.capsules[cap].extent(raw["axis"]) if cap in b.capsules else 0.0
        beams.append(M.Beam(**raw))

    design_kw = dict(
        file=env.file, params=params, medium=medium, transducer=transducer,
        generator=b.chain[0], amplifier=b.chain[1], materials=tuple(b.materials.values()), capsules=tuple(capsules), beams=tuple(beams),
        springs=tuple(b.springs.values()), trusses=tuple(b.trusses.values()), latches=tuple(b.latches.values()),
        anchors=tuple(b.anchors.values()), joints=tuple(joints),
    )
    partial = M.Design(**design_kw)
    observes = _observes(b, partial)
    requires = _requires(b, partial)
    programs = _programs(b, partial)
    design = M.Design(**design_kw, observes=tuple(observes), requires=tuple(requires), programs=tuple(programs),
                      effects=tuple(effects), correlations=correlations, coverage=coverage, discrepancy=discrepancy,
                      lognormal=lognormal,
                      measured_gain=measured,
                      sources=tuple(dict.fromkeys(r.loader.sources)))
    if not all_finite(design, bag):
        return design
    _effect_beam_ranges(b, design)
    _effect_band(b, design)
    check_design_geometry(design, bag, b.capsules)
    check_programs(design, bag)
    return design


def _element(b: Builder, name: str, blk: A.Block, beams_raw: dict, effects: list) -> None:
    kind = blk.kind
    if kind == "capsule":
        _put(b, b.capsules, name, b.capsule(blk))
    elif kind == "beam":
        _put(b, beams_raw, name, b.beam(blk))
    elif kind == "spring":
        _put(b, b.springs, name, b.spring(blk))
    elif kind == "truss":
        _put(b, b.trusses, name, b.truss(blk))
    elif kind == "latch":
        _put(b, b.latches, name, b.latch(blk))
    elif kind == "anchor":
        _put(b, b.anchors, name, b.anchor(blk))
    elif kind == "material":
        b.material(DeclVal(kind, name, blk, b.env))
    elif kind == "effect":
        eff = _effect(b, blk)
        if eff is not None:
            effects.append(eff)
    # a medium or transducer is built when used (`use`); one declared but not used is lint's concern


def _effect(b: Builder, blk: A.Block) -> M.Effect | None:
    """`effect drive_saturation { v_sat = 8.2 V }`: the name is the effect identifier; keys are its coefficients."""
    if blk.name not in EFFECTS:
        b.bag.error("E202", f"unknown effect `{blk.name}`", blk.span, suggest(blk.name, EFFECTS) or "effects: " + ", ".join(EFFECTS))
        return None
    params, units = {}, {}
    for ent, env in b.r.entries(blk, b.env):
        if not isinstance(ent, A.Assign):
            b.bag.error("E203", "an effect holds only `coefficient = value` entries", ent.kind_span)
            return None
        try:
            v = b.r.eval(ent.value, env)
        except Fail:
            return None
        if not isinstance(v, Quantity):
            b.bag.error("E304", f"effect coefficient `{ent.key}` must be a quantity, found {what_is(v)}", ent.value.span)
            return None
        want = EFFECT_UNITS.get(blk.name, {}).get(ent.key)
        if want is not None and v.dims != want[1]:
            b.bag.error("E301", f"effect {blk.name}.{ent.key}: expected "
                        f"{describe(want[1]) if want[0] else 'a plain number'}, found {describe(v.dims)}",
                        ent.value.span, f"`{ent.key}` is in {want[0]}" if want[0] else f"`{ent.key}` has no unit")
            return None
        dom = EFFECT_DOMAIN.get((blk.name, ent.key))
        bad = {"positive": not v.value > 0, "nonneg": not v.value >= 0, "unit": not 0 <= v.value <= 1}.get(dom, False)
        if bad:
            need = {"positive": "positive", "nonneg": "not negative", "unit": "in 0 .. 1"}[dom]
            b.bag.error("E401", f"effect {blk.name}.{ent.key} must be {need}, got {v.value:g}"
                        + (f" {si_unit(v.dims)}" if si_unit(v.dims) else ""), ent.value.span,
                        "its physical range (docs/explanation/fit-effects.md)")
            return None
        if not _effect_in_range(b, blk.name, ent.key, v, ent.value.span):
            return None
        params[ent.key] = v.value
        units[ent.key] = si_unit(v.dims)
        b.effect_spans[(blk.name, ent.key)] = ent.value.span
    return M.Effect(name=blk.name, params=params, units=units, span=blk.span)


def _effect_in_range(b: Builder, effect: str, key: str, v: Quantity, span: Span) -> bool:
    """Whether ``effect.key = v`` lies in its admissible range (acl.design.core.EFFECT_RANGES): E401 outside it
    (no physical value; an absurd one made the analyses overflow or divide by zero), W402 outside its plausible range."""
    rng = EFFECT_RANGES.get((effect, key))
    if rng is None:
        return True
    unit = si_unit(v.dims)
    show = (lambda x: f"{x:g}" + (f" {unit}" if unit else ""))
    if not rng.lo <= v.value <= rng.hi:
        b.bag.error("E401", f"effect {effect}.{key} = {show(v.value)} is outside its physical range "
                    f"{show(rng.lo)} .. {show(rng.hi)}", span, rng.why)
        return False
    if not rng.plausible_lo <= v.value <= rng.plausible_hi:
        b.bag.warning("W402", f"effect {effect}.{key} = {show(v.value)} is outside its plausible range "
                      f"{show(rng.plausible_lo)} .. {show(rng.plausible_hi)} (accepted; check the value and its unit)",
                      span, rng.why)
    return True


def _effect_band(b: Builder, design: M.Design) -> None:
    """W402: an effect's f_ref outside the declared transducer's band (the tilt or resonance is referenced to a
    frequency the transducer never plays: likely a unit slip, `125 Hz` for `125 kHz`)."""
    tr = design.transducer
    if tr is None:
        return
    lo, hi = tr.band
    for name in ("transducer_gain", "transducer_resonance"):
        eff = design.effect(name)
        f = eff.params.get("f_ref") if eff is not None else None
        if f is not None and not lo * (1 - 1e-9) <= f <= hi * (1 + 1e-9):
            b.bag.warning("W402", f"effect {name}.f_ref = {f:g} Hz is outside the band of transducer `{tr.name}` "
                          f"({lo:g} .. {hi:g} Hz): accepted, but the effect is referenced to a frequency it never plays",
                          b.effect_spans.get((name, "f_ref"), eff.span), "f_ref is a frequency of the data's sweep, "
                          "inside the band (check its unit)")


def _effect_beam_ranges(b: Builder, design: M.Design) -> None:
    """stiffness_scale and stiffness_gradient over each beam's own length: E(s) = E e_scale exp(g (s/50um - 1/2)),
    s in 0 .. L.  At both ends of every beam (and on every latch, scaled only) the modulus must be a solid's
    (PROPERTY_RANGES' material youngs, 1 kPa .. 1.2 TPa) and within MODULUS_DECADES of the declared one (E401; a beam
    longer than the 50 um reference amplifies g); beyond three decades it is implausible (W402)."""
    eff = design.effect("stiffness_gradient")
    g = eff.params.get("e_gradient", 0.0) if eff is not None else 0.0
    sc = design.effect("stiffness_scale")
    es = (sc.params.get("e_scale", sc.params.get("factor", 1.0)) if sc is not None else 1.0)
    if not g and es == 1.0:
        return
    if g:
        key, span = ("stiffness_gradient", "e_gradient"), b.effect_spans.get(("stiffness_gradient", "e_gradient"), eff.span)
    else:
        name = "e_scale" if "e_scale" in sc.params else "factor"
        key, span = ("stiffness_scale", name), b.effect_spans.get(("stiffness_scale", name), sc.span)
    rng = EFFECT_RANGES[key]
    e_lo, e_hi, e_why = PROPERTY_RANGES[("material", "youngs")]
    what = (f"effect stiffness_gradient.e_gradient = {g:g}" + (f" with stiffness_scale {es:g}" if es != 1.0 else "")
            if g else f"effect stiffness_scale.{key[1]} = {es:g}")
    members = [(f"beam `{x.name}` (L = {x.length * 1e6:.4g} um)", x.youngs_modulus, x.length) for x in design.beams]
    members += [(f"latch `{x.name}`", x.youngs_modulus, None) for x in design.latches]
    for label, modulus, length in members:
        ends = [math.log10(es)]
        if length is not None and g:
            ends = [math.log10(es) + g * (s / GRADIENT_REFERENCE - 0.5) / math.log(10) for s in (0.0, length)]
        decades = max(abs(x) for x in ends)
        e_min, e_max = modulus * 10 ** min(ends), modulus * 10 ** max(ends)
        if decades > MODULUS_DECADES:
            b.bag.error("E401", f"{what} makes the modulus of {label} {10 ** decades:.3g}x off the declared one at an "
                        f"end: outside its physical range ({10 ** MODULUS_DECADES:g}x)", span, rng.why)
            return
        if not e_lo <= e_min <= e_max <= e_hi:
            b.bag.error("E401", f"{what} makes the modulus of {label} {e_min if e_min < e_lo else e_max:.3g} Pa: outside "
                        f"the physical range of a solid's modulus, {e_lo:g} .. {e_hi:g} Pa", span, e_why)
            return
        if decades > 3.0 and rng.plausible_lo <= (g if g else es) <= rng.plausible_hi:
            b.bag.warning("W402", f"{what} makes the modulus of {label} {10 ** decades:.3g}x off the declared one at "
                          f"an end: outside its plausible range (1000x; accepted)", span, rng.why)
            return


def _put(b: Builder, store: dict, name: str, value) -> None:
    if value is None:
        b.failed.add(name)
    else:
        store[name] = value


# ------------------------------------------------------------------------------------------------
def _params(b: Builder) -> tuple[M.Param, ...]:
    out = []
    for name, decl in b.env.params.items():
        try:
            v = b.r.param(b.env, name)
        except Fail:
            continue
        lo = hi = None
        if decl.free and decl.lower is not None:
            try:
                if decl.upper is None:
                    b.bag.error("E306", f"bounds of `{name}` are written `free in lo .. hi`", decl.lower.span)
                    continue
                lo_q, hi_q = b.r.eval(decl.lower, b.env), b.r.eval(decl.upper, b.env)
            except Fail:
                continue
            for q, e in ((lo_q, decl.lower), (hi_q, decl.upper)):
                if not isinstance(q, Quantity) or q.dims != v.dims:
                    b.bag.error("E306", f"bound of `{name}` must be {describe(v.dims)} like its value, found "
                                f"{describe(q.dims) if isinstance(q, Quantity) else what_is(q)}", e.span)
                    break
            else:
                lo, hi = lo_q.value, hi_q.value
                if not lo < hi:
                    b.bag.error("E306", f"bounds of `{name}` are empty ({lo:g} >= {hi:g})", decl.lower.span)
                    continue
                if not lo <= v.value <= hi:
                    b.bag.error("E306", f"value of `{name}` lies outside its bounds", decl.value.span,
                                "a free parameter's starting value must lie within its bounds")
                    continue
        sd, spread = _stddev(b, name, decl, v) or (False, None) if decl.stddev is not None else (None, None)
        if sd is False:
            continue
        out.append(M.Param(name=name, value=v.value, unit=si_unit(v.dims), free=decl.free, lower=lo, upper=hi,
                           stddev=sd, spread=spread, span=decl.span))
    return tuple(out)


def _stddev(b: Builder, name: str, decl, v: Quantity):
    """(standard deviation in SI, Spread or None) of ``param NAME = v +- SPREAD`` (acl.design.spread);
    False (reported) when it is bad."""
    from acl.design.spread import SpreadError, spread_of

    def evaluate(e):
        return b.r.eval(e, b.env)

    try:
        return spread_of(decl.stddev, v, name, evaluate, lambda code, msg, span, hint: b.bag.error(code, msg, span, hint))
    except (Fail, SpreadError):
        return False


COVERED = {"voltage": "V", "frequency": "Hz", "deflection": "m"}
MAX_DISCREPANCY = 1.0   # m: as data files (acl.fit.data.MAX_LENGTH), nothing of a micro-device is a metre off


def _uncertainty(b: Builder, params: tuple[M.Param, ...]):
    """``uncertainty { correlation(a, b) = r, covered(q) = lo .. hi, discrepancy(position) = d,
    measured(gain) = [(f, s), ...] }`` -> (correlations, coverage, discrepancy, measured gains)."""
    sds = {p.name: p.stddev for p in params}
    corr: dict[tuple[str, str], M.Correlation] = {}
    cover: dict[str, M.Coverage] = {}
    discrepancy = discrepancy_line = None
    measured: list[M.MeasuredGain] | None = None
    logn: dict[str, Span] = {}
    for st in b.env.statements:
        if not isinstance(st, A.UncertaintyDecl):
            continue
        for ent in st.entries:
            key = ent.key
            if key.name == "lognormal":
                _lognormal(b, ent, params, logn)
                continue
            if ent.value is None:
                b.bag.error("E325", f"`{key.name}(...)` needs a value: write `{key.name}(...) = ...`", key.span,
                            "only `lognormal(a, b, ...)` stands without one")
                continue
            if key.name == "correlation":
                names = [a.dotted if isinstance(a, A.Ref) else None for a in key.args]
                if len(names) != 2 or None in names or key.kwargs:
                    b.bag.error("E323", "write a correlation as `correlation(a, b) = r` with two parameter names",
                                key.span)
                    continue
                bad = [n for n in names if n not in sds]
                if bad:
                    b.bag.error("E323", f"correlation: no parameter named `{bad[0]}`", key.span,
                                suggest(bad[0], list(sds)))
                    continue
                exact = [n for n in names if not sds[n]]
                if exact:
                    b.bag.error("E323", f"correlation: `{exact[0]}` declares no uncertainty (`+- s`)", key.span,
                                f"write `param {exact[0]} = value +- s`")
                    continue
                if names[0] == names[1]:
                    b.bag.error("E323", "a parameter's correlation with itself is 1", key.span)
                    continue
                try:
                    r = b.r.eval(ent.value, b.env)
                except Fail:
                    continue
                if not isinstance(r, Quantity) or r.dims != D("") or not math.isfinite(r.value) or abs(r.value) > 1:
                    b.bag.error("E324", "a correlation is a number in -1 .. 1", ent.value.span)
                    continue
                pair = tuple(sorted(names))
                if pair in corr:
                    b.bag.error("E323", f"correlation({pair[0]}, {pair[1]}) is given twice (first at line "
                                f"{corr[pair].span.line})", key.span, "keep one of them")
                    continue
                corr[pair] = M.Correlation(a=names[0], b=names[1], value=float(r.value), span=ent.span)
            elif key.name == "covered":
                q = key.args[0].dotted if len(key.args) == 1 and isinstance(key.args[0], A.Ref) else None
                if q not in COVERED:
                    b.bag.error("E325", "write `covered(voltage|frequency|deflection) = lo .. hi`", key.span,
                                suggest(q, COVERED) if q else None)
                    continue
                from acl.design.values import RangeVal

                try:
                    rv = b.r.eval(ent.value, b.env)
                except Fail:
                    continue
                want = D(COVERED[q])
                if not (isinstance(rv, RangeVal) and all(isinstance(x, Quantity) and x.dims == want
                                                         for x in (rv.lower, rv.upper))):
                    b.bag.error("E325", f"covered({q}): expected a range `lo .. hi` of {describe(want)}",
                                ent.value.span)
                    continue
                lo, hi = rv.lower.value, rv.upper.value
                if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
                    b.bag.error("E325", f"covered({q}): the range must be finite and lo <= hi", ent.value.span)
                    continue
                if q in cover:
                    b.bag.error("E325", f"covered({q}) is given twice (first at line {cover[q].span.line})", key.span,
                                "keep one range")
                    continue
                cover[q] = M.Coverage(quantity=q, lower=lo, upper=hi, span=ent.span)
            elif key.name == "discrepancy":
                if not (len(key.args) == 1 and isinstance(key.args[0], A.Ref) and key.args[0].dotted == "position"):
                    b.bag.error("E325", "write `discrepancy(position) = LENGTH`", key.span)
                    continue
                try:
                    v = b.r.eval(ent.value, b.env)
                except Fail:
                    continue
                if not (isinstance(v, Quantity) and v.dims == D("m") and math.isfinite(v.value) and v.value >= 0):
                    b.bag.error("E325", "discrepancy(position): expected a finite length >= 0", ent.value.span)
                    continue
                if v.value > MAX_DISCREPANCY:
                    b.bag.error("E325", f"discrepancy(position) = {v.value:g} m: a residual beyond "
                                f"{MAX_DISCREPANCY:g} m is no measurement of a micro-device", ent.value.span,
                                "give the fit's RMS residual, e.g. `50 nm`")
                    continue
                if discrepancy is not None:
                    b.bag.error("E325", f"discrepancy(position) is given twice (first at line {discrepancy_line})",
                                key.span, "keep one of them")
                    continue
                discrepancy, discrepancy_line = float(v.value), ent.span.line
            elif key.name == "measured":
                if not (len(key.args) == 1 and isinstance(key.args[0], A.Ref) and key.args[0].dotted == "gain"):
                    b.bag.error("E325", "write `measured(gain) = [(frequency, relative sd), ...]` (or `(frequency, "
                                "gain, relative sd)` entries)", key.span)
                    continue
                if measured is not None:
                    b.bag.error("E325", "measured(gain) is given twice", key.span, "keep one list")
                    continue
                got = _measured_gain(b, ent)
                if got is not None:
                    measured = got
            else:
                b.bag.error("E325", f"unknown uncertainty entry `{key.name}`", key.span,
                            suggest(key.name, ["correlation", "covered", "discrepancy", "measured", "lognormal"])
                            or "entries: correlation(a, b), covered(q), discrepancy(position), measured(gain), "
                               "lognormal(a, ...)")
    correlations = tuple(corr.values())
    if correlations:
        import numpy as np

        names = [p.name for p in params if p.stddev]
        pos = {n: i for i, n in enumerate(names)}
        C = np.eye(len(names))
        for c in correlations:
            C[pos[c.a], pos[c.b]] = C[pos[c.b], pos[c.a]] = c.value
        if np.linalg.eigvalsh(C).min() < -1e-9:
            b.bag.error("E324", "the correlations are not consistent (the correlation matrix is not positive "
                        "semidefinite)", correlations[0].span, "check the signs and sizes of the correlations")
            correlations = ()
    return correlations, tuple(cover.values()), discrepancy, tuple(measured or ()), tuple(logn)


def _lognormal(b: Builder, ent, params: tuple[M.Param, ...], seen: dict) -> None:
    """``lognormal(a, b, ...)``: positive uncertain parameters whose draws are log-normal (acl.schedule.bands)."""
    key = ent.key
    if ent.value is not None:
        b.bag.error("E325", "`lognormal(a, ...)` takes no value", ent.value.span,
                    "write `lognormal(a, b)`: it names the positive parameters drawn log-normal")
        return
    names = [a.dotted if isinstance(a, A.Ref) else None for a in key.args]
    if not names or None in names or key.kwargs:
        b.bag.error("E325", "write `lognormal(a, b, ...)` with parameter names", key.span)
        return
    by = {p.name: p for p in params}
    for n, arg in zip(names, key.args):
        p = by.get(n)
        if p is None:
            b.bag.error("E323", f"lognormal: no parameter named `{n}`", arg.span, suggest(n, list(by)))
        elif not p.stddev:
            b.bag.error("E323", f"lognormal: `{n}` declares no uncertainty (`+- s`)", arg.span,
                        f"write `param {n} = value +- s`")
        elif p.spread is not None:
            b.bag.error("E325", f"lognormal: `{n}` declares its own distribution (`+- {p.spread.kind}(...)` or "
                        "`+- %`)", arg.span, "give it `+- s` (the standard deviation) to draw it log-normal")
        elif not p.value > 0:
            b.bag.error("E325", f"lognormal: `{n}` = {p.value:g} is not positive; a log-normal value is",
                        arg.span, "a signed parameter keeps the normal `+- s`")
        elif n in seen:
            b.bag.error("E325", f"lognormal: `{n}` is given twice (first at line {seen[n].line})", arg.span,
                        "name each parameter once")
        else:
            seen[n] = arg.span


def _measured_gain(b: Builder, ent) -> list | None:
    """``measured(gain) = [(f, s), ...]`` or ``[(f, g, s), ...]``: positive, distinct frequencies; the gain ``g``
    (pressure per volt, positive, finite) measured there, optional; relative sd finite in 0 .. 1."""
    from acl.design.values import ListVal, VecVal

    try:
        v = b.r.eval(ent.value, b.env)
    except Fail:
        return None
    subs = getattr(ent.value, "items", None)
    if not (isinstance(v, ListVal) and v.items and subs is not None):
        b.bag.error("E325", "measured(gain): expected a list `[(frequency, relative sd), ...]` or "
                    "`[(frequency, gain, relative sd), ...]`", ent.value.span,
                    "e.g. `measured(gain) = [(72.5 kHz, 0.4 %), (178.5 kHz, 212 Pa/V, 0.6 %)]`")
        return None
    out: list[M.MeasuredGain] = []
    for item, sub in zip(v.items, subs):
        n = len(item.items) if isinstance(item, VecVal) else 0
        ok = (n in (2, 3) and all(isinstance(x, Quantity) for x in item.items) and item.items[0].dims == D("Hz")
              and item.items[-1].dims == D("") and (n == 2 or item.items[1].dims == D("Pa/V")))
        f, s = (item.items[0].value, item.items[-1].value) if ok else (float("nan"), float("nan"))
        g = item.items[1].value if ok and n == 3 else None
        if not (ok and math.isfinite(f) and f > 0 and math.isfinite(s) and 0 <= s <= 1
                and (g is None or (math.isfinite(g) and g > 0))):
            b.bag.error("E325", "measured(gain): each entry is `(frequency, relative sd)` or `(frequency, gain, "
                        "relative sd)` with a positive frequency, a positive finite gain (pressure per volt) and a "
                        "relative standard deviation in 0 .. 100 %", sub.span,
                        "e.g. `(72.5 kHz, 0.4 %)` or `(72.5 kHz, 212 Pa/V, 0.4 %)`")
            return None
        if any(abs(m.frequency - f) <= 1e-9 * f for m in out):
            b.bag.error("E325", f"measured(gain): {f:g} Hz is given twice", sub.span, "keep one entry per tone")
            return None
        out.append(M.MeasuredGain(frequency=float(f), gain=None if g is None else float(g), stddev=float(s),
                                  span=sub.span))
    return sorted(out, key=lambda m: m.frequency)


_USED = ("medium", "transducer", "generator", "amplifier")


def _uses(b: Builder):
    """The used medium and transducer (returned) and drive chain (stored in ``b.chain``)."""
    used: dict[str, object] = {k: None for k in _USED}
    build = {"medium": b.medium, "transducer": b.transducer, "generator": b.generator, "amplifier": b.amplifier}
    built: set[int] = set()                 # declarations built above (by identity)
    seen: dict[str, Span] = {}
    for st in b.env.statements:
        if not isinstance(st, A.Use):
            continue
        if st.what not in _USED:
            b.bag.error("E213", f"`use {st.what}`: only a medium, a transducer, a generator or an amplifier is used",
                        st.span, suggest(st.what, list(_USED)))
            continue
        if st.what in seen:
            b.bag.error("E206", f"`use {st.what}` given twice (first at line {seen[st.what].line})", st.span)
            continue
        seen[st.what] = st.span
        try:
            v = b.r.eval(st.target, b.env)
        except Fail:
            continue
        if not isinstance(v, DeclVal) or v.kind != st.what:
            b.bag.error("E207", f"`use {st.what}` needs a {st.what}, found {what_is(v)}", st.target.span, b.r.kind_hint(st.what, b.env))
            continue
        built.add(id(v.node))
        used[st.what] = build[st.what](v)
    # a single local medium/transducer/generator/amplifier is used without saying so
    for kind in _USED:
        if kind in seen:
            continue
        local = [blk for blk in b.env.decls.values() if blk.kind == kind]
        if len(local) == 1:
            dv = DeclVal(kind, local[0].name, local[0], b.env)
            built.add(id(local[0]))
            used[kind] = build[kind](dv)
    # the others declared here are checked the same way (an unused one is ACL601 in lint, but a wrong
    # value in it is an error now, not when someone first uses it)
    for blk in list(b.env.decls.values()):
        if blk.kind in _USED and id(blk) not in built:
            build[blk.kind](DeclVal(blk.kind, blk.name, blk, b.env))
    b.chain = (used["generator"], used["amplifier"])
    return used["medium"], used["transducer"]


# ------------------------------------------------------------------------------------------------
def _joints(b: Builder, beams_raw):
    joints = []
    mounted_on: dict[str, tuple[str, str]] = {}
    target_used: dict[tuple[str, str], Span] = {}
    capsule_joined: dict[str, Span] = {}

    def claim_capsule(name, span):
        if name in capsule_joined:
            b.bag.error("E406", f"capsule `{name}` is attached twice (first at line {capsule_joined[name].line})", span,
                        "a capsule sits on one beam tip, latch shuttle or spring end, or is fixed")
            return False
        capsule_joined[name] = span
        return True

    def unplaced(cap):
        # the mount is wrong: its capsule has no position, which every later use would report again
        if cap is not None:
            b.failed.add(cap[1])

    for st in b.env.statements:
        if isinstance(st, A.MountStmt):
            cap = b.local(st.capsule, ("capsule",), "mount")
            tgt_name = st.target.parts[0]
            tkind = b.kinds.get(tgt_name)
            if tkind not in TARGET_POINTS:
                if tkind is None:
                    cands = [n for n, k in b.kinds.items() if k in TARGET_POINTS]
                    b.bag.error("E201", f"mount: unknown beam, latch or spring `{tgt_name}`", st.target.span,
                                suggest(tgt_name, cands))
                else:
                    b.bag.error("E207", f"mount: `{tgt_name}` is a {tkind}; capsules mount on a beam tip, latch shuttle or spring end",
                                st.target.span)
                unplaced(cap)
                continue
            point = TARGET_POINTS[tkind]
            if len(st.target.parts) != 2 or st.target.parts[1] != point:
                got = st.target.parts[1] if len(st.target.parts) > 1 else None
                b.bag.error("E212", f"mount: a {tkind} is mounted at `{tgt_name}.{point}`" + (f", not `.{got}`" if got else ""),
                            st.target.span, f"write `mount ... on {tgt_name}.{point}`")
                unplaced(cap)
                continue
            if cap is None or tgt_name in b.failed:
                unplaced(cap)
                continue
            key = (tkind, tgt_name)
            if key in target_used:
                b.bag.error("E405", f"`{tgt_name}.{point}` already carries a capsule (line {target_used[key].line})", st.span,
                            f"to carry a second capsule on `{tgt_name}`, link it to the first: "
                            "`link SECOND to FIRST with TRUSS` (a truss declared with `truss NAME { }`)")
                continue
            if not claim_capsule(cap[1], st.span):
                continue
            target_used[key] = st.span
            mounted_on[cap[1]] = key
            joints.append(M.Mount(capsule=cap[1], target=tgt_name, target_kind=tkind, span=st.span))
        elif isinstance(st, A.FixStmt):
            cap = b.local(st.capsule, ("capsule",), "fix")
            if cap and claim_capsule(cap[1], st.span):
                joints.append(M.Fix(capsule=cap[1], span=st.span))
        elif isinstance(st, A.LinkStmt):
            a = b.local(st.a, ("capsule", "anchor", "ground"), "link")
            c = b.local(st.b, ("capsule", "anchor", "ground"), "link")
            el = b.local(st.element, ("truss", "spring"), "link ... with")
            # a failed end or element (reported where it failed) leaves the capsule it carries unplaced: no W401
            # "not attached" and no later report of it
            if any(r.parts[0] in b.failed for r in (st.a, st.b, st.element)):
                unplaced(a if a and a[0] == "capsule" else None)
                unplaced(c if c and c[0] == "capsule" else None)
                continue
            if a and c and a == c:
                b.bag.error("E207", "link: both ends are the same point", st.span)
                continue
            if a and c and el:
                joints.append(M.Link(a=a[1], b=c[1], element=el[1], element_kind=el[0], span=st.span))
    return joints, mounted_on


# ------------------------------------------------------------------------------------------------
def _observes(b: Builder, design: M.Design) -> list[M.Observe]:
    out = []
    for st in b.env.statements:
        if not isinstance(st, A.ObserveDecl):
            continue
        c = st.call
        if c.name == "gap":
            if not b.arity(c, (2,), "gap(a.orifice, b.orifice)"):
                continue
            x, y = (b.orifice_ref(a, "gap") for a in c.args)
            if x and y:
                out.append(M.Observe(name=st.name, kind="gap", a=x, b=y, span=st.span))
        elif c.name == "displacement":
            if not b.arity(c, (2,), "displacement(element, direction)"):
                continue
            tgt = c.args[0]
            if not isinstance(tgt, A.Ref) or len(tgt.parts) != 1:
                b.bag.error("E304", "displacement: first argument is a beam, capsule or latch name", tgt.span)
                continue
            k = b.local(tgt, ("beam", "capsule", "latch", "spring"), "displacement")
            try:
                axis = b.r.direction(c.args[1], b.env, "displacement direction")
            except Fail:
                continue
            if k:
                out.append(M.Observe(name=st.name, kind="displacement", target=k[1], axis=axis, span=st.span))
        elif c.name == "position":
            if not b.arity(c, (2,), "position(capsule, x|y|z)"):
                continue
            tgt, comp = c.args
            k = b.local(tgt, ("capsule",), "position") if isinstance(tgt, A.Ref) else None
            if not (isinstance(comp, A.Ref) and comp.dotted in ("x", "y", "z")):
                b.bag.error("E304", "position: second argument is x, y or z", comp.span)
                continue
            if k:
                out.append(M.Observe(name=st.name, kind="position", target=k[1], component=comp.dotted, span=st.span))
        elif c.name == "state":
            if not b.arity(c, (1,), "state(latch)"):
                continue
            tgt = c.args[0]
            if not isinstance(tgt, A.Ref) or len(tgt.parts) != 1:
                b.bag.error("E304", "state: the argument is a latch name", tgt.span)
                continue
            k = b.local(tgt, ("latch",), "state")
            if k:
                out.append(M.Observe(name=st.name, kind="state", target=k[1], span=st.span))
        else:
            b.bag.error("E201", f"unknown observable `{c.name}`", c.span,
                        suggest(c.name, ["gap", "displacement", "position", "state"])
                        or "observables: gap, displacement, position, state")
    return out


def _requires(b: Builder, design: M.Design) -> list[M.Require]:
    out = []
    units = {"resonance": "Hz", "separation": "Hz", "margin": "", "gap": "m"}
    for st in b.env.statements:
        if not isinstance(st, A.RequireDecl):
            continue
        c = st.call
        if c.name not in units:
            b.bag.error("E201", f"unknown requirement `{c.name}`", c.span,
                        suggest(c.name, units) or "requirements: " + ", ".join(units))
            continue
        try:
            lo = hi = None
            if st.op == "in":
                if st.upper is None:
                    b.bag.error("E304", "`require ... in lo .. hi` needs a range", st.value.span)
                    continue
                lo = b.r.q(st.value, b.env, units[c.name], f"require {c.name}")
                hi = b.r.q(st.upper, b.env, units[c.name], f"require {c.name}")
            elif st.op in (">=", ">"):
                lo = b.r.q(st.value, b.env, units[c.name], f"require {c.name}")
            else:
                hi = b.r.q(st.value, b.env, units[c.name], f"require {c.name}")
        except Fail:
            continue
        args: tuple[str, ...] = ()
        mode = 0
        if c.name in ("resonance", "margin"):
            kind = "capsule" if c.name == "resonance" else "latch"
            if not b.arity(c, (1,), f"{c.name}({kind})") or not isinstance(c.args[0], A.Ref):
                continue
            k = b.local(c.args[0], (kind,), f"require {c.name}")
            if not k:
                continue
            args = (k[1],)
            m = c.kw("mode")
            if m is not None:
                try:
                    mode = int(b.r.q(m, b.env, "", "mode")) - 1
                except Fail:
                    continue
                if mode < 0:
                    b.bag.error("E304", "modes are numbered from 1", m.span)
                    continue
        elif c.name == "separation":
            # separation(a, b): first modes of two capsules; separation(m): adjacent modes of one capsule
            if not b.arity(c, (1, 2), "separation(capsule, capsule) or separation(capsule)"):
                continue
            ks = [b.local(a, ("capsule",), "require separation") if isinstance(a, A.Ref) else None for a in c.args]
            if not all(ks):
                continue
            args = tuple(k[1] for k in ks)
        else:
            if not b.arity(c, (2,), "gap(a.orifice, b.orifice)"):
                continue
            x, y = (b.orifice_ref(a, "require gap") for a in c.args)
            if not (x and y):
                continue
            args = (x, y)
        out.append(M.Require(kind=c.name, args=args, mode=mode, lower=lo, upper=hi, text=st.text, span=st.span))
    return out


# ------------------------------------------------------------------------------------------------
def _programs(b: Builder, design: M.Design) -> list[M.Program]:
    out = []
    for name, decl in b.env.programs.items():
        p = build_program(b, design, decl)
        if p is not None:
            out.append(p)
    return out

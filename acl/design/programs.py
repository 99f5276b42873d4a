"""Program blocks -> Program models (timed drive steps and goals for the compiler)."""
from __future__ import annotations

from acl.design import model as M
from acl.design.builders import Builder
from acl.design.core import D, Fail, what_is
from acl.design.values import ListVal, StrVal, VecVal
from acl.diagnostics import suggest
from acl.syntax import ast as A
from acl.units import Quantity

PATH_SHAPES = ("line", "polyline", "rectangle", "circle", "text", "csv")
MAX_STEPS = 10_000

MAX_MARGIN = 100.0   # switch/hold/cross margins are ratios (default 1.2); beyond this they only break the solver


def build_program(b: Builder, design: M.Design, decl: A.ProgramDecl) -> M.Program | None:
    steps = []
    ok = True
    if len(decl.steps) > MAX_STEPS:
        b.bag.error("E503", f"program `{decl.name}` has more than {MAX_STEPS} steps", decl.span)
        return None
    for st in decl.steps:
        try:
            steps.append(_step(b, design, st))
        except Fail:
            ok = False
    if not steps and ok:
        b.bag.warning("W501", f"program `{decl.name}` is empty", decl.span)
    return M.Program(name=decl.name, steps=tuple(steps), span=decl.span) if ok else None


def _dur(b, e: A.Expr, what: str) -> float:
    t = b.r.q(e, b.env, "s", what)
    if not t > 0:
        b.bag.error("E503", f"{what} must be positive", e.span)
        raise Fail()
    return t


def _tones(b, tones: tuple[A.ToneExpr, ...]) -> M.Drive:
    out = []
    for t in tones:
        f = b.r.q(t.frequency, b.env, "Hz", "tone frequency")
        v = b.r.q(t.amplitude, b.env, "V", "tone amplitude")
        ph = b.r.q(t.phase, b.env, "", "tone phase") if t.phase is not None else 0.0
        if f <= 0:
            b.bag.error("E401", "tone frequency must be positive", t.frequency.span)
            raise Fail()
        if v < 0:
            b.bag.error("E401", "tone amplitude must not be negative", t.amplitude.span)
            raise Fail()
        out.append(M.Tone(frequency=f, amplitude=v, phase=ph, phase_given=t.phase is not None))
    freqs = [t.frequency for t in out]
    if len(set(freqs)) != len(freqs):
        b.bag.error("E504", "a drive lists the same frequency twice", tones[0].span, "merge the tones into one")
        raise Fail()
    return M.Drive(tones=tuple(out))


def _limits(b, opts: A.Options) -> M.Limits:
    vmax = b.r.q(opts.limit, b.env, "V", "limit") if opts.limit is not None else None
    slew = b.r.q(opts.slew, b.env, "V/s", "slew") if opts.slew is not None else None
    if vmax is not None and vmax <= 0:
        b.bag.error("E401", "limit must be positive", opts.limit.span)
        raise Fail()
    if slew is not None and slew <= 0:
        b.bag.error("E401", "slew must be positive", opts.slew.span)
        raise Fail()
    return M.Limits(max_voltage=vmax, slew_rate=slew)


def _using(b, opts: A.Options) -> tuple[float, ...]:
    if opts.using is None:
        return ()
    v = b.r.eval(opts.using, b.env)
    items = v.items if isinstance(v, (ListVal, VecVal)) else (v,)
    out = []
    for it in items:
        if not isinstance(it, Quantity) or it.dims != D("Hz"):
            b.bag.error("E301", f"using: expected frequencies, found {what_is(it)}", opts.using.span, "e.g. `using [85 kHz, 125 kHz]`")
            raise Fail()
        out.append(it.value)
    if not out:   # `using []` would otherwise mean "no `using`": every candidate tone
        b.bag.error("E505", "using: an empty list allows no tone", opts.using.span,
                    "name the tones, e.g. `using [85 kHz]`, or leave `using` out to let the compiler choose")
        raise Fail()
    return tuple(out)


def _no(b, opts: A.Options, names: tuple[str, ...], step: str) -> None:
    for n in names:
        e = getattr(opts, n)
        if e is not None:
            b.bag.error("E505", f"`{n}` does not apply to a {step} step", e.span)
            raise Fail()


def _step(b, design: M.Design, st):
    if isinstance(st, A.DriveS):
        _no(b, st.options, ("margin", "using", "slew"), "drive")
        drive = _tones(b, st.tones)
        lim = _limits(b, st.options)
        if lim.max_voltage is not None and sum(t.amplitude for t in drive.tones) > lim.max_voltage * (1 + 1e-9):
            b.bag.error("E502", f"drive amplitudes add up to {sum(t.amplitude for t in drive.tones):.3g} V, above its limit {lim.max_voltage:.3g} V",
                        st.span, "lower the amplitudes or raise the limit")
            raise Fail()
        return M.DriveStep(drive=drive, duration=_dur(b, st.duration, "drive duration"), limits=lim, span=st.span)
    if isinstance(st, A.SweepS):
        _no(b, st.options, ("margin", "using", "slew", "limit"), "sweep")
        f0 = b.r.q(st.f_start, b.env, "Hz", "sweep start")
        f1 = b.r.q(st.f_stop, b.env, "Hz", "sweep stop")
        v = b.r.q(st.amplitude, b.env, "V", "sweep amplitude")
        if f0 <= 0 or f1 <= 0 or f0 == f1:
            b.bag.error("E505", "a sweep needs two different positive frequencies", st.span)
            raise Fail()
        if v < 0:
            b.bag.error("E401", "sweep amplitude must not be negative", st.amplitude.span)
            raise Fail()
        return M.SweepStep(f_start=f0, f_stop=f1, amplitude=v, duration=_dur(b, st.duration, "sweep duration"),
                           log=st.log, span=st.span)
    if isinstance(st, A.PauseS):
        return M.PauseStep(duration=_dur(b, st.duration, "pause duration"), span=st.span)
    if isinstance(st, A.FollowS):
        _no(b, st.options, ("margin",), "follow")
        k = b.local(st.capsule, ("capsule",), "follow")
        if not k:
            raise Fail()
        mount = design.mount_of(k[1])
        if mount is None or mount.kind != "mount" or mount.target_kind != "beam":
            carriers = [j.b if j.a == k[1] else j.a for j in design.joints
                        if j.kind == "link" and j.element_kind == "truss" and k[1] in (j.a, j.b)]
            carried = [n for n in carriers if (design.mount_of(n) is not None and design.mount_of(n).kind == "mount"
                                               and design.mount_of(n).target_kind == "beam")]
            hint = (f"`{k[1]}` moves with `{carried[0]}`, which its truss links it to: follow `{carried[0]}` instead"
                    if carried and mount is None else f"mount it: `mount {k[1]} on BEAM.tip`")
            b.bag.error("E509", f"follow: capsule `{k[1]}` is not on a beam tip, so it has no planar motion to program",
                        st.capsule.span, hint)
            raise Fail()
        path = _path(b, st.path)
        dur = _dur(b, st.duration, "follow duration") if st.duration is not None else None
        speed = None
        if st.speed is not None:
            speed = b.r.q(st.speed, b.env, "m/s", "follow speed")
            if speed <= 0:
                b.bag.error("E503", "follow speed must be positive", st.speed.span)
                raise Fail()
        return M.FollowStep(capsule=k[1], path=path, duration=dur, speed=speed, tones=_using(b, st.options),
                            limits=_limits(b, st.options), span=st.span)
    if isinstance(st, A.SwitchS):
        _no(b, st.options, ("slew",), "switch")
        k = b.local(st.latch, ("latch",), "switch")
        if not k:
            raise Fail()
        if st.state not in ("a", "b"):
            b.bag.error("E506", f"unknown latch state `{st.state}`", st.state_span, "latch states are `a` (as printed) and `b` (snapped through)")
            raise Fail()
        margin = b.r.q(st.options.margin, b.env, "", "margin") if st.options.margin is not None else 1.2
        if margin < 1:
            b.bag.error("E505", f"switch margin {margin:g} is below 1: the latch would not switch", st.options.margin.span)
            raise Fail()
        if margin > MAX_MARGIN:
            b.bag.error("E505", f"switch margin {margin:g} is above {MAX_MARGIN:g}: no drive within a transducer's range "
                        "gives it, and the switching program becomes numerically meaningless", st.options.margin.span,
                        "margins are ratios like 1.2 or 2")
            raise Fail()
        return M.SwitchStep(latch=k[1], state=st.state, margin=margin, tones=_using(b, st.options),
                            limits=_limits(b, st.options), span=st.span)
    if isinstance(st, A.HoldS):
        c = st.gap
        if c.name != "gap":
            b.bag.error("E201", f"`{'hold' if st.mode == 'above' else 'cross'}` takes gap(a.orifice, b.orifice), not `{c.name}`", c.span)
            raise Fail()
        if not b.arity(c, (2,), "gap(a.orifice, b.orifice)"):
            raise Fail()
        x, y = (b.orifice_ref(a, "gap") for a in c.args)
        if not (x and y):
            raise Fail()
        if x == y:
            b.bag.error("E505", f"`{'hold' if st.mode == 'above' else 'cross'}`: the gap between an orifice and itself is "
                        "always 0", c.span, "name two orifices of different capsules")
            raise Fail()
        bound = b.r.q(st.bound, b.env, "m", "hold bound") if st.bound is not None else None
        if bound is not None and bound <= 0:
            b.bag.error("E401", "hold bound must be positive", st.bound.span)
            raise Fail()
        margin = b.r.q(st.options.margin, b.env, "", "margin") if st.options.margin is not None else 1.2
        if margin < 1:
            b.bag.error("E505", f"hold margin {margin:g} is below 1: it would not keep clear of snap-in", st.options.margin.span)
            raise Fail()
        if margin > MAX_MARGIN:
            b.bag.error("E505", f"{'hold' if st.mode == 'above' else 'cross'} margin {margin:g} is above {MAX_MARGIN:g}: "
                        "the voltage bound it sets is meaningless", st.options.margin.span, "margins are ratios like 1.2 or 2")
            raise Fail()
        return M.HoldStep(a=x, b=y, mode=st.mode, bound=bound, margin=margin, duration=_dur(b, st.duration, "hold duration"),
                          tones=_using(b, st.options), limits=_limits(b, st.options), span=st.span)
    raise Fail()  # pragma: no cover


def _pt(b, v, e, what) -> tuple[float, float]:
    if not isinstance(v, VecVal) or len(v.items) != 2 or not all(
            i.dims == D("m") or (i.value == 0 and i.dimensionless) for i in v.items):
        b.bag.error("E505", f"{what}: expected a planar point `(x, y)` in lengths", e.span)
        raise Fail()
    return (v.items[0].value, v.items[1].value)


def _path(b, call: A.Call) -> M.PathSpec:
    if call.name not in PATH_SHAPES:
        b.bag.error("E504", f"unknown path `{call.name}`", call.span, suggest(call.name, PATH_SHAPES) or "paths: " + ", ".join(PATH_SHAPES))
        raise Fail()
    v = b.r.eval(call, b.env)
    allowed = {"line": set(), "polyline": set(), "rectangle": {"width", "height", "center"},
               "circle": {"radius", "center"}, "text": {"height", "center"}, "csv": set()}[call.name]
    for k, _ in call.kwargs:
        if k not in allowed:
            b.bag.error("E505", f"{call.name}(): unknown argument `{k}`", call.span,
                        suggest(k, allowed) or (f"{call.name} takes " + ", ".join(sorted(allowed)) if allowed else None))
            raise Fail()
    kwe = dict(call.kwargs)

    def length(key, required=True):
        if key not in kwe:
            if required:
                b.bag.error("E505", f"{call.name}() needs `{key} = ...`", call.span)
                raise Fail()
            return None
        x = b.r.q(kwe[key], b.env, "m", f"{call.name} {key}")
        if x <= 0:
            b.bag.error("E401", f"{call.name} {key} must be positive", kwe[key].span)
            raise Fail()
        return x

    center = _pt(b, v.kw("center"), kwe["center"], "center") if "center" in kwe else (0.0, 0.0)
    if call.name in ("line", "polyline"):
        items = v.args
        exprs = call.args
        if len(items) == 1 and isinstance(items[0], ListVal):
            items, exprs = items[0].items, call.args[0].items
        pts = tuple(_pt(b, it, e, call.name) for it, e in zip(items, exprs))
        need = 2
        if len(pts) < need or (call.name == "line" and len(pts) != 2):
            b.bag.error("E505", f"{call.name}() needs {'two points' if call.name == 'line' else 'at least two points'}", call.span)
            raise Fail()
        return M.PathSpec(shape=call.name, points=pts)
    if call.name == "rectangle":
        return M.PathSpec(shape="rectangle", width=length("width"), height=length("height"), center=center)
    if call.name == "circle":
        return M.PathSpec(shape="circle", radius=length("radius"), center=center)
    if call.name == "text":
        if len(v.args) != 1 or not isinstance(v.args[0], StrVal) or not v.args[0].value.strip():
            b.bag.error("E505", 'text() takes the text to write: text("EPFL", height = 10 um)', call.span)
            raise Fail()
        txt = v.args[0].value
        bad = [ch for ch in txt if not (ch.isascii() and (ch.isalnum() or ch in " -."))]
        if bad:
            b.bag.error("E505", f"text(): no glyph for {bad[0]!r}", call.span, "letters A-Z, digits, space, '-' and '.'")
            raise Fail()
        return M.PathSpec(shape="text", text=txt.upper(), height=length("height"), center=center)
    # csv
    from acl.design.tables import read_table

    path = b.user_file(v, call.span, b.env)
    rows = read_table(path, b.bag, [("x", D("m")), ("y", D("m"))], call.span)
    if rows is None:
        raise Fail()
    if len(rows) < 2:
        b.bag.error("E505", f"`{path}` needs at least two waypoints", call.span)
        raise Fail()
    b.r.loader.sources.append(path)
    return M.PathSpec(shape="csv", points=tuple((r[0], r[1]) for r in rows), source=path)

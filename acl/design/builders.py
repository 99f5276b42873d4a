"""Build the resolved Design models from resolved syntax (one builder per declaration kind)."""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

from acl.design import geometry as G
from acl.design import model as M
from acl.design.core import D, PROPERTY_RANGES, SCHEMAS, Fail, what_is
from acl.design.evaluate import Resolver
from acl.design.values import CallVal, DeclVal, IdentVal, ListVal, StrVal, VecVal
from acl.diagnostics import Span, suggest
from acl.syntax import ast as A
from acl.units import Quantity, describe

MAX_GAIN_UNCERTAINTY = 10.0     # log-normal sd of a gain-table value: exp(10) = 22,026x at 1 sigma (beyond: overflow)
MAX_TRANSDUCER_VOLTAGE = 1e4   # V: the top of compile's accepted `limit` range (acl.schedule.compile.VOLTAGE_RANGE)


@dataclass
class CapsuleSpec:
    name: str
    span: Span
    shape: str
    volume: float
    axis: tuple
    radius: float | None = None
    side: float | None = None
    height: float | None = None
    wall: float = 2e-6
    facing: tuple | None = None
    orifices: list = field(default_factory=list)   # (name, radius, normal, face_distance, span)
    center: tuple | None = None
    thrust: float | None = None
    q: float | None = None

    def extent(self, u) -> float:
        return G.half_extent(self.shape, u, self.axis, self.radius, self.side, self.height, self.volume, self.wall)

    def bounding_radius(self) -> float:
        return G.bounding_radius(self.shape, self.radius, self.side, self.height, self.volume, self.wall)


class Builder:
    def __init__(self, r: Resolver):
        self.r = r
        self.bag = r.bag
        self.env = r.main
        self.materials: dict[str, M.Material] = {}
        self.capsules: dict[str, CapsuleSpec] = {}
        self.beams: dict[str, dict] = {}
        self.springs: dict[str, M.Spring] = {}
        self.trusses: dict[str, M.Truss] = {}
        self.latches: dict[str, M.Latch] = {}
        self.anchors: dict[str, M.Anchor] = {}
        self.media: dict[str, M.Medium] = {}
        self.transducers: dict[str, M.Transducer] = {}
        self.kinds: dict[str, str] = {}      # local element name -> kind
        self.chain: tuple = (None, None)     # the used generator and amplifier (assemble._uses)
        self.failed: set[str] = set()        # local elements whose declaration had errors
        self.failed_materials: set[str] = set()
        self.effect_spans: dict = {}          # (effect, coefficient) -> span of its value (range checks)

    # ------------------------------------------------------------------------------ materials
    def material(self, dv: DeclVal) -> M.Material | None:
        if dv.name in self.materials:
            return self.materials[dv.name]
        if dv.name in self.failed_materials:   # reported once, where it is declared
            return None
        self.failed_materials.add(dv.name)
        try:
            keys = self.r.assigns(dv.node, dv.env, "material")
            E = self._pos(keys, "youngs", "material", dv.name)
            nu = self.r.get(keys, "poisson", "material", dv.name)
            rho = self._pos(keys, "density", "material", dv.name)
            if not -1.0 < nu <= 0.5:
                self._err_key(keys, "poisson", "E412", f"Poisson ratio {nu:g} outside (-1, 0.5]")
                return None
            m = M.Material(name=dv.name, youngs_modulus=E, poisson_ratio=nu, density=rho, span=dv.node.span)
        except Fail:
            return None
        self.failed_materials.discard(dv.name)
        self.materials[dv.name] = m
        return m

    def medium(self, dv: DeclVal) -> M.Medium | None:
        try:
            keys = self.r.assigns(dv.node, dv.env, "medium")
            vals = {k: self._pos(keys, k, "medium", dv.name) for k in SCHEMAS["medium"]}
            if vals["polytropic"] < 1.0 or vals["polytropic"] > 5 / 3:
                self._err_key(keys, "polytropic", "E412", f"polytropic index {vals['polytropic']:g} outside [1, 5/3]")
                return None
            return M.Medium(name=dv.name, density=vals["density"], viscosity=vals["viscosity"],
                            sound_speed=vals["sound_speed"], surface_tension=vals["surface_tension"],
                            ambient_pressure=vals["pressure"], polytropic_index=vals["polytropic"],
                            gas_thermal_diffusivity=vals["thermal_diffusivity"], span=dv.node.span)
        except Fail:
            return None

    def transducer(self, dv: DeclVal) -> M.Transducer | None:
        try:
            keys = self.r.assigns(dv.node, dv.env, "transducer")
            vmax = self._pos(keys, "max_voltage", "transducer", dv.name)
            if vmax is not None and vmax > MAX_TRANSDUCER_VOLTAGE:   # as compile's limit range (E-SCHED-LIMIT)
                self._err_key(keys, "max_voltage", "E502", f"transducer `{dv.name}`: max_voltage {vmax:.3g} V is above "
                              f"{MAX_TRANSDUCER_VOLTAGE:g} V, beyond any amplifier driving a piezo transducer",
                              "give the amplifier's real peak voltage")
                return None
            band = self.r.get(keys, "band", "transducer", dv.name)
            if band[0] <= 0:
                self._err_key(keys, "band", "E401", "band must be at positive frequencies")
                return None
            fs, gs = self._gain_table(keys, dv)
            unc = self.r.get(keys, "gain_uncertainty", "transducer", dv.name)
            if unc is not None and not (math.isfinite(unc) and 0 <= unc <= MAX_GAIN_UNCERTAINTY):
                self._err_key(keys, "gain_uncertainty", "E320" if math.isfinite(unc) else "E305",
                              f"{dv.name}.gain_uncertainty must be a finite relative standard deviation in 0 .. "
                              f"{MAX_GAIN_UNCERTAINTY:g} ({MAX_GAIN_UNCERTAINTY:.0%}), got {unc:g}",
                              "e.g. `gain_uncertainty = 40 %`")
                return None
            return M.Transducer(name=dv.name, max_voltage=vmax, band=band, gain_frequencies=fs,
                                gain_pa_per_v=gs, gain_uncertainty=unc, span=dv.node.span)
        except Fail:
            return None

    def generator(self, dv: DeclVal) -> M.Generator | None:
        try:
            keys = self.r.assigns(dv.node, dv.env, "generator")
            vmax = self._pos(keys, "max_voltage", "generator", dv.name)
            opt = {k: self._pos(keys, k, "generator", dv.name) if k in keys else None
                   for k in ("sample_rate", "memory", "channels", "max_frequency")}
            channels = opt["channels"] or 1.0
            if channels != int(channels):
                self._err_key(keys, "channels", "E401", f"{dv.name}.channels must be a whole number, got {channels:g}")
                return None
            return M.Generator(name=dv.name, max_voltage=vmax, sample_rate=opt["sample_rate"], memory=opt["memory"],
                               channels=int(channels), max_frequency=opt["max_frequency"], span=dv.node.span)
        except Fail:
            return None

    def amplifier(self, dv: DeclVal) -> M.Amplifier | None:
        try:
            keys = self.r.assigns(dv.node, dv.env, "amplifier")
            gain = self._pos(keys, "gain", "amplifier", dv.name)
            vmax = self._pos(keys, "max_voltage", "amplifier", dv.name)
            bw = self._pos(keys, "bandwidth", "amplifier", dv.name) if "bandwidth" in keys else None
            return M.Amplifier(name=dv.name, gain=gain, max_voltage=vmax, bandwidth=bw, span=dv.node.span)
        except Fail:
            return None

    def _gain_table(self, keys, dv: DeclVal):
        if "gain" not in keys:      # missing key already reported by assigns()
            raise Fail()
        ent, env = keys["gain"]
        v = self.r.eval(ent.value, env)
        if isinstance(v, Quantity):  # a flat gain
            if v.dims != D("Pa/V"):
                self.bag.error("E301", f"{dv.name}.gain: expected {describe(D('Pa/V'))}, found {describe(v.dims)}", ent.value.span)
                raise Fail()
            return self._check_table([1.0], [v.value], ent.value.span)
        if isinstance(v, CallVal) and v.name == "csv":
            return self._gain_csv(v, ent, env)
        if isinstance(v, ListVal) and v.items:
            fs, gs = [], []
            for item, sub in zip(v.items, ent.value.items):
                if not (isinstance(item, VecVal) and len(item.items) == 2 and item.items[0].dims == D("Hz")
                        and item.items[1].dims == D("Pa/V")):
                    self.bag.error("E304", "gain table rows are `(frequency, pressure per volt)`, e.g. `(85 kHz, 2 kPa/V)`", sub.span)
                    raise Fail()
                fs.append(item.items[0].value)
                gs.append(item.items[1].value)
            return self._check_table(fs, gs, ent.value.span)
        self.bag.error("E304", f"{dv.name}.gain: expected a table `[(f, Pa/V), ...]`, `csv(\"file.csv\")` or a constant, found {what_is(v)}", ent.value.span)
        raise Fail()

    def _check_table(self, fs, gs, span):
        if any(b <= a for a, b in zip(fs, fs[1:])):
            self.bag.error("E413", "gain table frequencies must be strictly increasing", span)
            raise Fail()
        if any(g < 0 or not math.isfinite(g) for g in gs) or any(f <= 0 for f in fs):
            self.bag.error("E413", "gain table needs positive frequencies and non-negative gains", span)
            raise Fail()
        lo, hi, why = PROPERTY_RANGES[("transducer", "gain")]
        if any(g > hi for g in gs):
            self.bag.error("E413", f"gain table: {max(gs):g} Pa/V is outside its physical range {lo:g} .. {hi:g} Pa/V",
                           span, why)
            raise Fail()
        return tuple(fs), tuple(gs)

    def _gain_csv(self, call: CallVal, ent, env):
        from acl.design.tables import read_table

        path = self.user_file(call, ent.value.span, env)
        rows = read_table(path, self.bag, [("frequency", D("Hz")), ("gain", D("Pa/V"))], ent.value.span)
        if rows is None:
            raise Fail()
        self.r.loader.sources.append(path)
        return self._check_table([r[0] for r in rows], [r[1] for r in rows], ent.value.span)

    def user_file(self, call: CallVal, span: Span, env) -> str:
        if not call.args or not isinstance(call.args[0], StrVal):
            self.bag.error("E304", "csv(...) takes a quoted file path: csv(\"table.csv\")", span)
            raise Fail()
        rel = call.args[0].value
        base = os.path.dirname(os.path.realpath(env.file)) if os.path.exists(env.file) else os.getcwd()
        path = os.path.realpath(os.path.join(base, rel))
        if not self.r.loader.allowed(path, os.path.dirname(os.path.realpath(self.env.file)) if os.path.exists(self.env.file) else os.getcwd()):
            self.bag.error("E210", f"`{rel}` is outside the design's directory tree", span,
                           "a design reads only files in its folder and below, the stdlib, and --path folders")
            raise Fail()
        if not os.path.isfile(path):
            self.bag.error("E507", f"cannot find `{rel}`", span)
            raise Fail()
        from acl.design.modules import shown_path

        # named in diagnostics (`lib/gain.csv:3:2`) from the design's name as the user gave it, as imports are
        return shown_path(path, path, os.path.join(os.path.dirname(env.file), rel))

    # ------------------------------------------------------------------------------ references to local elements
    def local(self, ref: A.Ref, kinds: tuple[str, ...], what: str):
        """Resolve a reference to a local element of one of `kinds`; returns (kind, name) or None."""
        name = ref.parts[0]
        if len(ref.parts) > 1 and ref.parts[0] in self.env.imports:
            self.bag.error("E207", f"{what}: `{ref.dotted}` is imported; declare the element in this file (e.g. `capsule c like {ref.dotted} {{ ... }}`)", ref.span)
            return None
        if name == "ground" and "ground" in kinds:
            return ("ground", "ground")
        kind = self.kinds.get(name)
        if kind is None:
            cands = [n for n, k in self.kinds.items() if k in kinds]
            self.bag.error("E201", f"{what}: unknown {' or '.join(k for k in kinds if k != 'ground')} `{name}`", ref.span,
                        suggest(name, cands) or (("available: " + ", ".join(cands)) if cands else None))
            return None
        if kind not in kinds:
            self.bag.error("E207", f"{what}: `{name}` is a {kind}, expected a {' or '.join(k for k in kinds if k != 'ground')}", ref.span)
            return None
        if name in self.failed:
            return None
        return (kind, name)

    def orifice_ref(self, ref: A.Expr, what: str) -> str | None:
        """`capsule.orifice` naming a built capsule's orifice, or None (reported unless the capsule failed)."""
        if not isinstance(ref, A.Ref) or len(ref.parts) != 2:
            self.bag.error("E304", f"{what}: expected `capsule.orifice`", ref.span)
            return None
        cap, ori = ref.parts
        kind = self.kinds.get(cap)
        if kind != "capsule":
            cands = [n for n, k in self.kinds.items() if k == "capsule"]
            self.bag.error("E201", f"{what}: unknown capsule `{cap}`", ref.span, suggest(cap, cands))
            return None
        if cap in self.failed or cap not in self.capsules:
            return None
        names = [o[0] for o in self.capsules[cap].orifices]
        if ori not in names:
            self.bag.error("E212", f"{what}: capsule `{cap}` has no orifice `{ori}`", ref.span, suggest(ori, names) or "orifices: " + ", ".join(names))
            return None
        return f"{cap}.{ori}"

    def arity(self, call: A.Call, n: tuple[int, ...], what: str) -> bool:
        """Whether a call has one of the argument counts `n` (reported if not)."""
        if len(call.args) not in n:
            self.bag.error("E304", f"{what} takes {' or '.join(map(str, n))} argument(s), got {len(call.args)}", call.span)
            return False
        return True

    # ------------------------------------------------------------------------------ helpers
    def _pos(self, keys, key, schema, what) -> float:
        v = self.r.get(keys, key, schema, what)
        if v is None:
            return v
        if not (v > 0 and math.isfinite(v)):
            self._err_key(keys, key, "E401", f"{what}.{key} must be positive, got {Quantity(v, D(SCHEMAS[schema][key].unit)) if SCHEMAS[schema][key].unit is not None else v}")
            raise Fail()
        if not self._in_range(keys, key, schema, what, v):
            raise Fail()
        return v

    def _in_range(self, keys, key, schema, what, v) -> bool:
        """Whether ``v`` lies in the physical range of ``schema.key`` (acl.design.core.PROPERTY_RANGES); E412 if not."""
        rng = PROPERTY_RANGES.get((schema, key))
        if rng is None or v is None or rng[0] <= v <= rng[1]:
            return True
        unit = SCHEMAS[schema][key].unit if key in SCHEMAS.get(schema, {}) else None
        shown = (lambda x: str(Quantity(x, D(unit))) if unit else f"{x:g}")
        self._err_key(keys, key, "E412", f"{what}.{key} = {shown(v)} is outside its physical range "
                      f"{shown(rng[0])} .. {shown(rng[1])}", rng[2])
        return False

    def _err_key(self, keys, key, code, msg, hint=None):
        ent, _ = keys[key]
        self.bag.error(code, msg, ent.value.span, hint)

    def _section(self, keys, schema, what) -> M.Section:
        (v, ent) = self.r.get(keys, "section", schema, what)
        span = ent.value.span
        if not isinstance(v, CallVal) or v.name not in ("circle", "rect"):
            self.bag.error("E304", f"{what}.section: expected `circle(diameter)` or `rect(width, thickness)`, found {what_is(v)}", span,
                           suggest(v.name, ["circle", "rect"]) if isinstance(v, CallVal) else None)
            raise Fail()
        want = 1 if v.name == "circle" else 2
        vals = list(v.args) + [x for _, x in v.kwargs]
        if len(vals) != want or not all(isinstance(x, Quantity) and x.dims == D("m") for x in vals):
            self.bag.error("E304", f"{what}.section: `{v.name}` takes {want} length(s)", span)
            raise Fail()
        if any(x.value <= 0 for x in vals):
            self.bag.error("E401", f"{what}.section sizes must be positive", span)
            raise Fail()
        if v.name == "circle":
            return M.Section(shape="circle", diameter=vals[0].value)
        return M.Section(shape="rect", width=vals[0].value, thickness=vals[1].value)

    # ------------------------------------------------------------------------------ elements
    def capsule(self, blk: A.Block) -> CapsuleSpec | None:
        name = blk.name
        try:
            keys = self.r.assigns(blk, self.env, "capsule", allowed_blocks=("cavity", "orifice"))
        except Fail:
            return None
        cavities = [(e, en) for e, en in self.r.entries(blk, self.env) if isinstance(e, A.Block) and e.kind == "cavity"]
        orifices = [(e, en) for e, en in self.r.entries(blk, self.env) if isinstance(e, A.Block) and e.kind == "orifice"]
        if (not cavities or not orifices) and self.r.incomplete(blk):
            return None
        if not cavities:
            self.bag.error("E204", f"capsule `{name}` has no cavity", blk.span, "add `cavity cylinder { radius = 25 um, height = 33 um }`")
            return None
        if len(cavities) > 1:
            self.bag.error("E206", f"capsule `{name}` has more than one cavity", cavities[1][0].kind_span)
            return None
        if not orifices:
            self.bag.error("E204", f"capsule `{name}` has no orifice", blk.span, "add `orifice jet { radius = 10 um, normal = +x }`")
            return None
        cav, cenv = cavities[0]
        spec = self._cavity(name, cav, cenv)
        if spec is None:
            return None
        spec.span = blk.span
        ok = True
        try:
            spec.center = self.r.get(keys, "center", "capsule", name)
        except Fail:
            ok = False
        try:
            spec.thrust = self.r.get(keys, "thrust", "capsule", name)
            if spec.thrust is not None and spec.thrust < 0:      # gamma of paper Eq. (3): a jet pushes, never pulls
                self._err_key(keys, "thrust", "E401", f"{name}.thrust must not be negative, got {spec.thrust:g} N/V^2",
                              "the thrust coefficient (gamma of paper Eq. 3) is a magnitude; the orifice's `normal` gives its direction")
                ok = False
            spec.q = self.r.get(keys, "q", "capsule", name)
            if spec.q is not None and spec.q <= 0:
                self._err_key(keys, "q", "E401", f"{name}.q must be positive")
                ok = False
            for key in ("thrust", "q"):
                if ok and not self._in_range(keys, key, "capsule", name, getattr(spec, key)):
                    ok = False
        except Fail:
            ok = False
        seen = set()
        side_normals = []
        for ob, oenv in orifices:
            if not ob.name:
                self.bag.error("E204", "an orifice needs a name: `orifice jet { ... }`", ob.kind_span)
                ok = False
                continue
            if ob.name in seen:
                self.bag.error("E205", f"orifice `{ob.name}` declared twice in capsule `{name}`", ob.span)
                ok = False
                continue
            seen.add(ob.name)
            o = self._orifice(spec, ob, oenv, side_normals)
            if o is None:
                ok = False
            else:
                spec.orifices.append(o)
        return spec if ok else None

    def _cavity(self, name: str, cav: A.Block, env) -> CapsuleSpec | None:
        shape = cav.name or ""
        if shape not in ("cylinder", "prism", "volume"):
            self.bag.error("E202", f"unknown cavity shape `{shape}`", cav.kind_span,
                           suggest(shape, ["cylinder", "prism", "volume"]) or "cavity shapes: cylinder, prism, volume")
            return None
        try:
            keys = self.r.assigns(cav, env, "cavity")
            allowed = {"cylinder": {"radius", "height", "axis", "wall"}, "prism": {"side", "height", "axis", "facing", "wall"},
                       "volume": {"volume", "wall", "axis"}}[shape]
            for k, (ent, _) in keys.items():
                if k not in allowed:
                    self.bag.error("E203", f"`{k}` does not apply to a {shape} cavity", ent.key_span,
                                   f"a {shape} cavity takes: " + ", ".join(sorted(allowed)))
                    raise Fail()
            need = {"cylinder": ("radius", "height"), "prism": ("side", "height"), "volume": ("volume",)}[shape]
            missing = [k for k in need if k not in keys]
            if missing:
                self.bag.error("E204", f"{shape} cavity of `{name}` is missing " + ", ".join(f"`{k}`" for k in missing), cav.span)
                raise Fail()
            vals = {k: self._pos(keys, k, "cavity", f"{name}.cavity") for k in need}
            wall = self._pos(keys, "wall", "cavity", f"{name}.cavity")
            axis = self.r.get(keys, "axis", "cavity", f"{name}.cavity") or (0.0, 0.0, 1.0)
            facing = self.r.get(keys, "facing", "cavity", f"{name}.cavity")
        except Fail:
            return None
        if shape == "cylinder":
            vol = G.cylinder_volume(vals["radius"], vals["height"])
        elif shape == "prism":
            vol = G.prism_volume(vals["side"], vals["height"])
        else:
            vol = vals["volume"]
        if facing is not None:
            if abs(G.dot(facing, axis)) > 1e-6:
                self.bag.error("E410", "prism `facing` must be perpendicular to its axis", keys["facing"][0].value.span)
                return None
        return CapsuleSpec(name=name, span=cav.span, shape=shape, volume=vol, axis=axis,
                           radius=vals.get("radius"), side=vals.get("side"), height=vals.get("height"),
                           wall=wall, facing=facing)

    def _orifice(self, spec: CapsuleSpec, ob: A.Block, env, side_normals):
        where = f"{spec.name}.{ob.name}"
        try:
            keys = self.r.assigns(ob, env, "orifice")
            R = self._pos(keys, "radius", "orifice", where)
            normal = self.r.get(keys, "normal", "orifice", where)
            face = None
            if "face" in keys:
                face_v, face_ent = self.r.get(keys, "face", "orifice", where)
                face = _face_name(face_v)
                if face is None:
                    self.bag.error("E304", f"{where}.face: expected 1, 2, 3, top, bottom or side", face_ent.value.span)
                    raise Fail()
        except Fail:
            return None
        span = ob.span
        ax = spec.axis
        if normal is None and face is None:
            if spec.shape == "prism" or spec.shape == "cylinder":
                self.bag.error("E204", f"orifice `{where}` needs a `normal` or a `face`", span, "e.g. `normal = +x`")
            else:
                self.bag.error("E204", f"orifice `{where}` needs a `normal`", span, "e.g. `normal = +x`")
            return None
        if spec.shape == "prism":
            if face in ("1", "2", "3"):
                ref = spec.facing or perp_default(ax, side_normals)
                normal = G.rotate(ref, ax, (int(face) - 1) * 2 * math.pi / 3)
            elif face in ("top", "bottom"):
                normal = ax if face == "top" else G.scale(ax, -1)
            c = G.dot(normal, ax)
            if abs(abs(c) - 1) < 1e-6:
                dist = spec.height / 2 + spec.wall
                fits = R < G.prism_inradius(spec.side)
                limit = f"the end face's inradius {G.prism_inradius(spec.side) * 1e6:.3g} um"
            elif abs(c) < 1e-6:
                ref = spec.facing or (side_normals[0] if side_normals else normal)
                ok = any(abs(G.dot(normal, G.rotate(ref, ax, k * 2 * math.pi / 3)) - 1) < 1e-4 for k in range(3))
                if not ok:
                    self.bag.error("E410", f"orifice `{where}`: normal is not on a face of the prism", span,
                                   "prism side faces are 120 degrees apart; use `face = 1|2|3` or set the cavity's `facing`")
                    return None
                side_normals.append(normal)
                dist = G.prism_inradius(spec.side) + spec.wall
                fits = 2 * R <= min(spec.side, spec.height)
                limit = f"the side face ({spec.side * 1e6:.3g} um x {spec.height * 1e6:.3g} um)"
            else:
                self.bag.error("E410", f"orifice `{where}`: normal must be along the prism axis or perpendicular to it", span)
                return None
        elif spec.shape == "cylinder":
            if face in ("top", "bottom"):
                normal = ax if face == "top" else G.scale(ax, -1)
            elif face is not None and normal is None:
                self.bag.error("E204", f"orifice `{where}` on the cylinder side needs a `normal`", span)
                return None
            c = G.dot(normal, ax)
            if abs(abs(c) - 1) < 1e-6:
                dist = spec.height / 2 + spec.wall
                fits = R < spec.radius
                limit = f"the end face (radius {spec.radius * 1e6:.3g} um)"
            elif abs(c) < 1e-6:
                dist = spec.radius + spec.wall
                fits = 2 * R <= spec.height and R <= spec.radius
                limit = f"the side wall (height {spec.height * 1e6:.3g} um)"
            else:
                self.bag.error("E410", f"orifice `{where}`: normal must be along the cylinder axis or perpendicular to it", span)
                return None
        else:
            if normal is None:
                self.bag.error("E204", f"orifice `{where}` needs a `normal` (a volume cavity has no faces)", span)
                return None
            dist = spec.extent(normal)
            req = (3 * spec.volume / (4 * math.pi)) ** (1 / 3)
            fits = R < req
            limit = f"the equivalent sphere (radius {req * 1e6:.3g} um)"
        if not fits:
            self.bag.error("E402", f"orifice `{where}` (radius {R * 1e6:.3g} um) does not fit {limit}", span,
                           "reduce the orifice radius or enlarge the cavity")
            return None
        return (ob.name, R, tuple(normal), dist, span)

    def beam(self, blk: A.Block) -> dict | None:
        name = blk.name
        try:
            keys = self.r.assigns(blk, self.env, "beam")
            L = self._pos(keys, "length", "beam", name)
            section = self._section(keys, "beam", name)
            mat_dv = self.r.get(keys, "material", "beam", name)
            clamp = self.r.get(keys, "clamp", "beam", name)
            axis = self.r.get(keys, "axis", "beam", name)
            rigid = self.r.get(keys, "rigid", "beam", name)
            if rigid is not None and rigid < 0:
                self._err_key(keys, "rigid", "E401", f"{name}.rigid must not be negative")
                raise Fail()
        except Fail:
            return None
        mat = self.material(mat_dv)
        if mat is None:
            return None
        return dict(name=name, length=L, section=section, material=mat.name, youngs_modulus=mat.youngs_modulus,
                    clamp=clamp, axis=axis, tip=G.add(clamp, G.scale(axis, L)), rigid_length=rigid, span=blk.span)

    def spring(self, blk: A.Block) -> M.Spring | None:
        name = blk.name
        try:
            keys = self.r.assigns(blk, self.env, "spring")
            axis = self.r.get(keys, "axis", "spring", name)
            if "stiffness" in keys:
                k = self._pos(keys, "stiffness", "spring", name)
                extra = [key for key in ("length", "section", "material") if key in keys]
                if extra:
                    self._err_key(keys, extra[0], "E203", "give a spring either `stiffness` or its geometry, not both")
                    raise Fail()
            else:
                missing = [key for key in ("length", "section", "material") if key not in keys]
                if missing:
                    self.bag.error("E204", f"spring `{name}` needs `stiffness`, or `length`, `section` and `material`", blk.span,
                                   "e.g. `stiffness = 0.7563 nN/um` (paper Fig. 5c)")
                    raise Fail()
                L = self._pos(keys, "length", "spring", name)
                section = self._section(keys, "spring", name)
                mat = self.material(self.r.get(keys, "material", "spring", name))
                if mat is None:
                    raise Fail()
                count = self._pos(keys, "count", "spring", name)
                k = count * 12 * mat.youngs_modulus * section.second_moment / L**3  # guided beams (Roark)
        except Fail:
            return None
        return M.Spring(name=name, stiffness=k, axis=axis, span=blk.span)

    def latch(self, blk: A.Block) -> M.Latch | None:
        name = blk.name
        try:
            keys = self.r.assigns(blk, self.env, "latch")
            angle = self.r.get(keys, "angle", "latch", name)
            if not 0 < angle < math.pi / 2:
                self._err_key(keys, "angle", "E411", f"latch angle {math.degrees(angle):.3g} deg outside (0, 90) deg",
                              "write the angle with a unit: `30 deg`")
                raise Fail()
            L = self._pos(keys, "length", "latch", name)
            w = self._pos(keys, "width", "latch", name)
            t = self._pos(keys, "thickness", "latch", name)
            mat = self.material(self.r.get(keys, "material", "latch", name))
            at = self.r.get(keys, "at", "latch", name)
            axis = self.r.get(keys, "axis", "latch", name)
            state = "a"
            if "state" in keys:
                v, ent = self.r.get(keys, "state", "latch", name)
                state = v.name if isinstance(v, IdentVal) else None
                if state not in ("a", "b"):
                    self.bag.error("E506", f"latch state must be `a` or `b`, found {what_is(v)}", ent.value.span)
                    raise Fail()
            if mat is None:
                raise Fail()
        except Fail:
            return None
        return M.Latch(name=name, angle=angle, length=L, width=w, thickness=t, material=mat.name,
                       youngs_modulus=mat.youngs_modulus, anchor=at, axis=axis, state=state, span=blk.span)

    def anchor(self, blk: A.Block) -> M.Anchor | None:
        try:
            keys = self.r.assigns(blk, self.env, "anchor")
            at = self.r.get(keys, "at", "anchor", blk.name)
        except Fail:
            return None
        return M.Anchor(name=blk.name, position=at, span=blk.span)

    def truss(self, blk: A.Block) -> M.Truss | None:
        try:
            self.r.assigns(blk, self.env, "truss")
        except Fail:
            return None
        return M.Truss(name=blk.name, span=blk.span)


def perp_default(axis, side_normals):
    return side_normals[0] if side_normals else G.perpendicular(axis)


def _face_name(v) -> str | None:
    if isinstance(v, Quantity) and v.dimensionless and v.value in (1.0, 2.0, 3.0):
        return str(int(v.value))
    if isinstance(v, IdentVal) and v.name in ("top", "bottom", "side"):
        return v.name
    return None


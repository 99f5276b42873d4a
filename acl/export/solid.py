"""The resolved design as printable solids (manifold3d's exact booleans), in micrometres.

Every element becomes a closed body in the design frame (substrate plane z = 0, z up); the printed
parts are the connected pieces of their union, less the cavities and the orifice holes:

* a capsule: the outer body (its cavity grown by the wall thickness on every face) less the cavity
  (the declared cylinder, triangular prism or, for a cavity given by its volume only, the sphere of
  that volume) less one hole per orifice (a cylinder of the orifice radius along its outward normal
  from the cavity's inside through the wall, centred on the orifice centre);
* a beam: its section extruded from the clamp along its axis for its length, into the pad below a
  clamp on the substrate and half a wall into the capsule it carries;
* a latch: two inclined beams (length, width in the plane of motion, thickness out of it) from the
  shuttle to clamps on posts, inclined by the latch angle towards the actuation axis (state a as
  printed: the clamps lie ahead of the shuttle along the axis, acl.physics.latch);
* a fixed capsule, an anchor, a latch clamp, a spring's ground end: a post down to the substrate;
* trusses and springs linking two capsules: a straight bar under the capsules' floors.

Where a part touches the substrate a pad reaches ``print_pad_depth`` into it.  Circles are
polygons scaled to the circle's area and spheres polyhedra scaled to the sphere's volume, so
cavity volumes, orifice areas and beam sections equal the declared ones.  What the language does
not declare is taken from stdlib/printing.acl (:func:`print_defaults`), never guessed here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from acl.design import geometry as G
from acl.diagnostics import Diagnostic, DiagnosticError, Span, error, warning

UM = 1e6          # the solids are built in micrometres (SI m x UM)
_Z = (0.0, 0.0, 1.0)
ON_SUBSTRATE = 1e-9   # m: a clamp or a body this close to z = 0 stands on the substrate


# ------------------------------------------------------------------------------------------------
# Defaults (stdlib/printing.acl)
# ------------------------------------------------------------------------------------------------

DEFAULT_NAMES = ("print_pad_depth", "print_pad_margin", "print_post_diameter", "print_bar_width",
                 "print_shuttle_side", "print_spring_length", "print_segments")


def print_defaults(design=None) -> dict[str, tuple[float, Span]]:
    """name -> (SI value, where it is declared): stdlib/printing.acl, each overridden by a parameter
    of the same name in ``design``."""
    import os

    from acl._resources import shipped_dir
    from acl.design.resolve import load_design

    lib = load_design(os.path.join(shipped_dir("stdlib"), "printing.acl"))
    out = {p.name: (p.value, p.span) for p in lib.params if p.name in DEFAULT_NAMES}
    if design is not None:
        for p in design.params:
            if p.name in DEFAULT_NAMES:
                out[p.name] = (p.value, p.span)
    missing = [n for n in DEFAULT_NAMES if n not in out]
    if missing:
        raise RuntimeError(f"stdlib/printing.acl lacks {', '.join(missing)}")
    bad = []
    for name, (value, span) in out.items():
        if name == "print_segments":
            ok = value == int(value) and 16 <= value <= 1024
            want = "a whole number of segments from 16 to 1024"
        else:
            ok = 0 < value <= 1e-3 or (name == "print_pad_depth" and value == 0)
            want = "a length above 0 and at most 1 mm" + (" (0: no pads)" if name == "print_pad_depth" else "")
        if not ok:
            bad.append(error("E-EXPORT-PARAM", f"`{name}` = {value:g} (SI): the export needs {want}", span))
    if bad:
        raise DiagnosticError(bad)
    return out


# ------------------------------------------------------------------------------------------------
# Primitives
# ------------------------------------------------------------------------------------------------

def _mf():
    import manifold3d

    return manifold3d


def unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def frame(axis, ref=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, v, w): w the axis, u the reference direction made perpendicular to it (default
    acl.design.geometry.perpendicular: +x projected, else +y), v = w x u."""
    w = unit(axis)
    if ref is not None:
        r = np.asarray(ref, float) - w * float(np.dot(ref, w))
        if np.linalg.norm(r) < 1e-9:
            ref = None
    u = unit(r) if ref is not None else np.asarray(G.perpendicular(tuple(w)), float)
    return u, np.cross(w, u), w


def circle(radius: float, segments: int) -> np.ndarray:
    """A regular polygon with the area of the circle of ``radius`` (counter-clockwise)."""
    n = int(segments)
    scale = math.sqrt(2 * math.pi / (n * math.sin(2 * math.pi / n)))
    t = 2 * math.pi * np.arange(n) / n
    return np.column_stack([np.cos(t), np.sin(t)]) * radius * scale


def rectangle(width: float, thickness: float) -> np.ndarray:
    a, b = width / 2, thickness / 2
    return np.array([[-a, -b], [a, -b], [a, b], [-a, b]], float)


def triangle(inradius: float) -> np.ndarray:
    """Equilateral triangle of ``inradius``, face 1's outward normal along +u (faces 120 deg apart)."""
    t = math.radians(60) + 2 * math.pi * np.arange(3) / 3
    return np.column_stack([np.cos(t), np.sin(t)]) * 2 * inradius


def extrude(poly: np.ndarray, z0: float, z1: float, origin, axis, ref=None):
    """The 2-D polygon (in the (u, v) plane) swept from ``z0`` to ``z1`` along ``axis`` from ``origin``."""
    mf = _mf()
    u, v, w = frame(axis, ref)
    body = mf.Manifold.extrude(mf.CrossSection([np.ascontiguousarray(poly, float)]), float(z1 - z0))
    body = body.translate((0.0, 0.0, float(z0)))
    m = np.column_stack([u, v, w, np.asarray(origin, float)])
    return body.transform(m)


def sphere(radius: float, segments: int, origin):
    """A polyhedron with the volume of the sphere of ``radius``."""
    mf = _mf()
    s = mf.Manifold.sphere(1.0, max(int(segments), 16))
    k = (4 / 3 * math.pi / s.volume()) ** (1 / 3)
    return s.scale((radius * k,) * 3).translate(tuple(float(x) for x in origin))


def prism_ref(c):
    """A prism cavity's face-1 direction: the first orifice normal across the axis (the builder's
    `facing`), else None (the default perpendicular)."""
    ax = np.asarray(c.cavity.axis, float)
    for o in c.orifices:
        if abs(float(np.dot(o.normal, ax))) < 1e-6:
            return np.asarray(o.normal, float)
    return None


# ------------------------------------------------------------------------------------------------
# The build
# ------------------------------------------------------------------------------------------------

@dataclass
class Part:
    """One printed part: a connected solid (um) and the names of the elements in it."""

    name: str
    solid: object                 # manifold3d.Manifold
    elements: tuple[str, ...]


@dataclass
class Build:
    parts: list[Part]
    diagnostics: list[Diagnostic] = field(default_factory=list)
    defaults: dict = field(default_factory=dict)
    latch_beams: dict = field(default_factory=dict)  # latch -> [(start, direction, width direction)] of its beams (um)


class _Builder:
    def __init__(self, design, defaults):
        self.d = design
        self.k = {n: v for n, (v, _) in defaults.items()}
        self.spans = {n: s for n, (_, s) in defaults.items()}
        self.n = int(round(self.k["print_segments"]))
        self.add: list = []          # (element name, manifold)
        self.cut: list = []
        self.diags: list[Diagnostic] = []
        self.latch_beams: dict = {}
        self.pad_depth = self.k["print_pad_depth"] * UM

    # -- capsules ---------------------------------------------------------------------------------
    def capsule(self, c):
        cv, ctr = c.cavity, np.asarray(c.center, float) * UM
        w = cv.wall * UM
        if cv.shape == "cylinder":
            r, h = cv.radius * UM, cv.height * UM
            outer = extrude(circle(r + w, self.n), -h / 2 - w, h / 2 + w, ctr, cv.axis)
            inner = extrude(circle(r, self.n), -h / 2, h / 2, ctr, cv.axis)
        elif cv.shape == "prism":
            ri, h = G.prism_inradius(cv.side) * UM, cv.height * UM
            ref = prism_ref(c)
            outer = extrude(triangle(ri + w), -h / 2 - w, h / 2 + w, ctr, cv.axis, ref)
            inner = extrude(triangle(ri), -h / 2, h / 2, ctr, cv.axis, ref)
        else:
            rs = (3 * cv.volume / (4 * math.pi)) ** (1 / 3) * UM
            outer = sphere(rs + w, self.n, ctr)
            inner = sphere(rs, self.n, ctr)
        self.add.append((c.name, outer))
        self.cut.append(inner)
        for o in c.orifices:
            n = np.asarray(o.normal, float)
            oc = np.asarray(o.center, float) * UM
            depth = max(float(np.dot(oc - ctr, n)), w)      # from the cavity's centre plane
            self.cut.append(extrude(circle(o.radius * UM, self.n), -depth, w / 2, oc, n))

    def outer_extent(self, c, direction) -> float:
        """Support function (um) of a capsule's outer body along a unit direction from its centre."""
        cv = c.cavity
        return G.half_extent(cv.shape, tuple(direction), cv.axis, cv.radius, cv.side, cv.height, cv.volume, cv.wall) * UM

    # -- substrate contact -----------------------------------------------------------------------
    def pad(self, name, xy, half: float, ref=None):
        """A square pad below z = 0 under ``xy`` (um), ``half`` the half-side of what stands on it."""
        s = 2 * (half + self.k["print_pad_margin"] * UM)
        self.add.append((name, extrude(rectangle(s, s), -self.pad_depth, 0.0, (xy[0], xy[1], 0.0), _Z, ref)))

    def post(self, name, top, ref=None):
        """A square post from ``top`` (um) down into the substrate, with its pad."""
        side = self.k["print_post_diameter"] * UM
        top = np.asarray(top, float)
        if top[2] > 0:
            self.add.append((name, extrude(rectangle(side, side), -self.pad_depth / 2, top[2], (top[0], top[1], 0.0), _Z, ref)))
        self.pad(name, top, side / 2, ref)

    # -- beams ------------------------------------------------------------------------------------
    def beam(self, b, carried):
        s = b.section
        poly = circle(s.diameter / 2 * UM, max(self.n // 3, 16)) if s.shape == "circle" else \
            rectangle(s.width * UM, s.thickness * UM)
        clamp, ax, L = np.asarray(b.clamp, float) * UM, unit(b.axis), b.length * UM
        z0 = 0.0
        if abs(b.clamp[2]) <= ON_SUBSTRATE and ax[2] > 0.5:        # standing on the substrate
            z0 = -self.pad_depth / 2
            self.pad(b.name, clamp, float(np.max(np.abs(poly))))
        else:                                                    # clamped on a post behind the clamp
            side = self.k["print_post_diameter"] * UM
            back = ax.copy()
            back[2] = 0.0
            half = float(np.max(np.abs(poly)))
            if np.linalg.norm(back) < 1e-6:                      # vertical: the post stands under the clamp
                self.post(b.name, clamp)
            else:
                back = unit(back)
                self.post(b.name, clamp - back * side / 2 + np.array([0.0, 0.0, half]), back)
            z0 = -side / 4
        embed = (carried.cavity.wall * UM / 2) if carried is not None else 0.0
        self.add.append((b.name, extrude(poly, z0, L + embed, clamp, ax)))

    # -- latches ----------------------------------------------------------------------------------
    def latch(self, l, carried):
        a = unit(l.axis)
        p = np.cross(_Z, a)
        p = unit(p) if np.linalg.norm(p) > 1e-6 else np.asarray(G.perpendicular(tuple(a)), float)
        s = np.asarray(l.anchor, float) * UM
        L, wd, th = l.length * UM, l.width * UM, l.thickness * UM
        if carried is not None:
            group = self.rigid_group(carried)
            embed = carried.cavity.wall * UM / 2
        else:
            side = self.k["print_shuttle_side"] * UM
            self.add.append((l.name, extrude(rectangle(side, side), -side / 2, side / 2, s, _Z, a)))
            group, embed = [], side / 4
        sign_a = 1.0 if l.state == "a" else -1.0       # state b printed stress-free in its own shape
        post = self.k["print_post_diameter"] * UM
        for side_sign in (1.0, -1.0):
            e = unit(side_sign * p * math.cos(l.angle) + sign_a * a * math.sin(l.angle))
            start = s + side_sign * p * (self.k["print_shuttle_side"] * UM / 2)
            best = None
            for c in group:          # the beam holds the outermost capsule the shuttle carries on its side
                ctr = np.asarray(c.center, float) * UM
                reach = float(np.dot(ctr - s, side_sign * p)) + self.outer_extent(c, tuple(side_sign * p))
                if best is None or reach > best[0]:
                    best = (reach, ctr)
            if best is not None:
                start = best[1] + side_sign * p * (best[0] - float(np.dot(best[1] - s, side_sign * p)))
                start[2] = s[2]
            normal_out = np.cross(e, _Z) if abs(e[2]) < 0.99 else p
            self.add.append((l.name, extrude(rectangle(wd, th), -embed, L + post / 2, start, e, normal_out)))
            self.latch_beams.setdefault(l.name, []).append((start.copy(), e, unit(normal_out)))
            clamp = start + e * L
            eh = e.copy()
            eh[2] = 0.0
            self.post(l.name, clamp + unit(eh) * post / 2 + np.array([0, 0, th]), unit(eh))   # above the beam: no shared face

    def rigid_group(self, capsule) -> list:
        """The capsule and every capsule tied to it by trusses (they move as one body)."""
        group, todo = {capsule.name}, [capsule.name]
        while todo:
            n = todo.pop()
            for j in self.d.joints:
                if j.kind == "link" and j.element_kind == "truss" and n in (j.a, j.b):
                    other = j.b if j.a == n else j.a
                    if other not in group and other in {c.name for c in self.d.capsules}:
                        group.add(other)
                        todo.append(other)
        return [c for c in self.d.capsules if c.name in group]

    # -- links and supports ----------------------------------------------------------------------
    def floor_point(self, c, lift: float | None = None):
        """A point (um) under a capsule's centre, ``lift`` above the bottom of its outer body (default
        half a wall)."""
        ctr = np.asarray(c.center, float) * UM
        lift = c.cavity.wall * UM / 2 if lift is None else lift
        return ctr - np.array([0, 0, self.outer_extent(c, (0.0, 0.0, -1.0)) - lift])

    def bar(self, name, p0, p1, width):
        d = np.asarray(p1, float) - np.asarray(p0, float)
        length = float(np.linalg.norm(d))
        if length < 1e-9:
            return
        self.add.append((name, extrude(rectangle(width, width), 0.0, length, p0, d, _Z if abs(unit(d)[2]) < 0.99 else None)))

    def build(self) -> Build:
        d = self.d
        carried = {}
        for j in d.joints:
            if j.kind == "mount":
                carried.setdefault(j.target, d.capsule(j.capsule))
        for c in d.capsules:
            self.capsule(c)
        for b in d.beams:
            self.beam(b, carried.get(b.name))
        for l in d.latches:
            self.latch(l, carried.get(l.name))
        for a in d.anchors:
            self.post(a.name, np.asarray(a.position, float) * UM)
        bar_w = self.k["print_bar_width"] * UM
        positions = {c.name: c for c in d.capsules}
        anchors = {a.name: np.asarray(a.position, float) * UM for a in d.anchors}
        for j in d.joints:
            if j.kind == "fix":
                c = d.capsule(j.capsule)
                self.post(c.name, self.floor_point(c))
            elif j.kind == "mount" and j.target_kind == "spring":
                self.spring_mount(d.capsule(j.capsule), d.spring(j.target), bar_w)
            elif j.kind == "link":
                ends = []
                for n in (j.a, j.b):
                    if n in positions:      # the bar's underside flush with the capsule's floor
                        ends.append(self.floor_point(positions[n], bar_w / 2))
                    elif n in anchors:
                        ends.append(anchors[n])
                    else:
                        ends.append(None)          # ground
                if j.element_kind == "spring":
                    self.spring_warning(d.spring(j.element))
                if ends[0] is not None and ends[1] is not None:
                    self.bar(j.element, ends[0], ends[1], bar_w)
                else:
                    live = ends[0] if ends[0] is not None else ends[1]
                    if live is not None:
                        self.post(j.element, live)
        return self.finish()

    def spring_warning(self, s):
        self.diags.append(warning(
            "W-EXPORT-SPRING", f"spring `{s.name}` declares its stiffness ({s.stiffness:.4g} N/m) but no printable "
            "shape: it is printed as a straight bar (stdlib/printing.acl print_bar_width), whose stiffness is not the declared one",
            s.span, "design the flexure (e.g. as a beam) and print that; the bar only holds the parts in place"))

    def spring_mount(self, c, s, bar_w):
        """A capsule on a spring's end: a bar along the spring axis, away from the other capsules, to a post."""
        self.spring_warning(s)
        ctr = np.asarray(c.center, float) * UM
        ax = unit(s.axis)
        others = [np.asarray(o.center, float) * UM for o in self.d.capsules if o.name != c.name]

        def clearance(sign):
            return min((float(np.dot(o - ctr, sign * ax)) for o in others), default=0.0)
        sign = 1.0 if clearance(1.0) < clearance(-1.0) else -1.0     # the side facing away from the neighbours
        start = self.floor_point(c, bar_w / 2)
        reach = self.outer_extent(c, tuple(sign * ax)) + self.k["print_spring_length"] * UM
        end = start + sign * ax * reach
        self.bar(s.name, start, end, bar_w)
        self.post(s.name, end, ax)

    def finish(self) -> Build:
        mf = _mf()
        if not self.add:
            raise DiagnosticError([error("E-EXPORT-EMPTY", "the design declares nothing to print (no capsule, beam, "
                                         "latch or anchor)", Span(file=self.d.file, line=1, column=1))])
        solid = mf.Manifold.batch_boolean([m for _, m in self.add], mf.OpType.Add)
        if self.cut:
            solid = mf.Manifold.batch_boolean([solid, *self.cut], mf.OpType.Subtract)
        pieces = sorted(solid.decompose(), key=lambda m: tuple(np.round(m.bounding_box()[:3], 6)))
        parts = []
        for i, piece in enumerate(pieces):
            names = tuple(n for n, m in self.add if _overlaps(piece, m))
            parts.append(Part(name=f"part{i + 1}" + (f"-{names[0]}" if names else ""), solid=piece, elements=names))
        return Build(parts=parts, diagnostics=self.diags, latch_beams=self.latch_beams)


def _overlaps(piece, m) -> bool:
    """Whether body ``m`` is part of ``piece``: its box inside the piece's box, and a common volume."""
    a, b = piece.bounding_box(), m.bounding_box()
    eps = 1e-6 * max(1.0, max(abs(x) for x in a))
    if any(b[i] < a[i] - eps or b[i + 3] > a[i + 3] + eps for i in range(3)):
        return False
    return (piece ^ m).volume() > 0.0


def build(design, defaults=None) -> Build:
    """The printed parts of ``design`` (um), with warnings about what the print cannot carry."""
    defaults = defaults if defaults is not None else print_defaults(design)
    out = _Builder(design, defaults).build()
    out.defaults = defaults
    return out

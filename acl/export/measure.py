"""Measure an exported mesh against the design the physics used (docs/export.md, "Geometry checks").

Every measurement is taken on the triangle mesh as written (any mesh: the one just built or one
read back from the file), in micrometres, and compared with the resolved design:

* cavity volume: the convex hull of the mesh vertices lying on the declared cavity surface (within a
  quarter wall), i.e. the cavity as printed with each orifice opening closed flush with the cavity
  surface; for a cavity given by its volume only (a sphere) the spherical caps of the openings are
  added back. Tolerance 0.5 %.
* orifice radius: rays parallel to the orifice normal, cast inwards from just outside the wall at 64
  angles; along each angle a bisection finds the largest offset at which a ray still passes through
  the hole into the cavity; the radius is the root mean square of those offsets (the radius of the
  circle of the hole's area). Tolerance 0.5 %.
* beam section: the mesh sliced across the beam at mid-length: the piece around the beam's axis,
  its area as a circle's diameter, or a rectangle's width and thickness. Tolerance 0.1 um.
* beam free length: rays parallel to the beam just beside it, from mid-length to the surfaces that
  end it (the substrate pad, the capsule it carries, or its own tip). Tolerance 0.1 um.
* wall thickness: the thinnest wall along the cavity surface's normals from the centre, away from
  the orifices (what is joined to a wall only thickens it). Tolerance 0.1 um.

A mismatch is an error diagnostic E-EXPORT-GEOMETRY at the element's declaration.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from acl.design import geometry as G
from acl.diagnostics import Diagnostic, error

UM = 1e6
VOLUME_TOL = 0.005        # relative
RADIUS_TOL = 0.005        # relative
LENGTH_TOL = 0.1          # um
ANGLES = 64


@dataclass
class Measurement:
    element: str
    quantity: str
    declared: float
    measured: float | None
    unit: str
    tolerance: str
    ok: bool

    def as_dict(self) -> dict:
        return {"element": self.element, "quantity": self.quantity, "declared": float(self.declared),
                "measured": None if self.measured is None else float(self.measured), "unit": self.unit,
                "tolerance": self.tolerance, "ok": bool(self.ok)}


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _frame(axis, ref=None):
    from acl.export.solid import frame

    return frame(axis, ref)


class Probe:
    """Rays and slices on one mesh (um)."""

    def __init__(self, mesh):
        import trimesh

        self.mesh = mesh
        self.rays = trimesh.ray.ray_triangle.RayMeshIntersector(mesh)
        self._manifold = None
        self._boxes = None

    def first_hit(self, origins, direction) -> np.ndarray:
        """Distance to the first surface along ``direction`` from each origin (inf when none)."""
        origins = np.atleast_2d(np.asarray(origins, float))
        dirs = np.tile(_unit(direction), (len(origins), 1))
        out = np.full(len(origins), np.inf)
        loc, idx, _ = self.rays.intersects_location(origins, dirs, multiple_hits=True)
        if len(idx):
            dist = np.einsum("ij,ij->i", loc - origins[idx], dirs[idx])
            keep = dist > 1e-9
            np.minimum.at(out, idx[keep], dist[keep])
        return out

    def near(self, lo, hi) -> "Probe":
        """A probe on the triangles whose bounding boxes meet the box [lo, hi] (um): rays cast inside
        the box find the same surfaces, a hundred capsules away cost nothing."""
        if getattr(self, "_boxes", None) is None:
            tri = self.mesh.triangles
            self._boxes = (tri.min(axis=1), tri.max(axis=1))
        tmin, tmax = self._boxes
        keep = np.all(tmax >= np.asarray(lo) - 1e-9, axis=1) & np.all(tmin <= np.asarray(hi) + 1e-9, axis=1)
        if keep.all():
            return self
        sub = Probe.__new__(Probe)
        import trimesh

        sub.mesh = trimesh.Trimesh(self.mesh.vertices, self.mesh.faces[keep], process=False)
        sub.rays = trimesh.ray.ray_triangle.RayMeshIntersector(sub.mesh)
        sub._manifold = self.manifold()
        sub._boxes = None
        return sub

    def manifold(self):
        if self._manifold is None:
            import manifold3d as mf

            mesh = mf.Mesh(vert_properties=np.ascontiguousarray(self.mesh.vertices, np.float32),
                           tri_verts=np.ascontiguousarray(self.mesh.faces, np.uint32))
            self._manifold = mf.Manifold(mesh)
        return self._manifold


# ------------------------------------------------------------------------------------------------
# Capsules
# ------------------------------------------------------------------------------------------------

def cavity_distance(points, capsule) -> np.ndarray:
    """Distance (um) of points (um) from the declared cavity surface (exact for cylinder and sphere,
    the largest face distance outside a prism)."""
    cv = capsule.cavity
    c = np.asarray(capsule.center, float) * UM
    p = np.asarray(points, float) - c
    if cv.shape == "volume":
        rs = (3 * cv.volume / (4 * math.pi)) ** (1 / 3) * UM
        return np.abs(np.linalg.norm(p, axis=1) - rs)
    ax = _unit(cv.axis)
    t = p @ ax
    hh = cv.height * UM / 2
    if cv.shape == "cylinder":
        r = cv.radius * UM
        rho = np.linalg.norm(p - np.outer(t, ax), axis=1)
        inside = (rho <= r) & (np.abs(t) <= hh)
        d_in = np.minimum(r - rho, hh - np.abs(t))
        d_out = np.hypot(np.maximum(rho - r, 0), np.maximum(np.abs(t) - hh, 0))
        return np.where(inside, d_in, d_out)
    from acl.export.solid import prism_ref

    ref = prism_ref(capsule)
    u, v, _ = _frame(ax, ref)
    ri = G.prism_inradius(cv.side) * UM
    planes = [np.abs(t) - hh]
    for k in range(3):
        n = math.cos(2 * math.pi * k / 3) * u + math.sin(2 * math.pi * k / 3) * v
        planes.append(p @ n - ri)
    s = np.max(np.stack(planes), axis=0)
    return np.abs(s)


def cavity_volume(probe: Probe, capsule, orifice_radii: dict[str, float] | None = None) -> float | None:
    """The printed cavity's volume (um^3): hull of the vertices on the declared cavity surface."""
    from scipy.spatial import ConvexHull, QhullError

    verts = np.asarray(probe.mesh.vertices, float)
    near = verts[cavity_distance(verts, capsule) < capsule.cavity.wall * UM / 4]
    if len(near) < 4:
        return None
    try:
        vol = float(ConvexHull(near).volume)
    except (QhullError, ValueError):
        return None
    if capsule.cavity.shape == "volume":      # the openings' spherical caps, cut off by the hull's flat faces
        rs = (3 * capsule.cavity.volume / (4 * math.pi)) ** (1 / 3) * UM
        for o in capsule.orifices:
            r = (orifice_radii or {}).get(o.name, o.radius * UM)
            if r < rs:
                h = rs - math.sqrt(rs * rs - r * r)
                vol += math.pi * h * h * (3 * rs - h) / 3
    return vol


def orifice_radius(probe: Probe, capsule, orifice) -> float | None:
    """Radius (um) of the circle of the hole's area, by rays through the hole (None: closed or unbounded)."""
    n = _unit(orifice.normal)
    o = np.asarray(orifice.center, float) * UM
    c = np.asarray(capsule.center, float) * UM
    w = capsule.cavity.wall * UM
    u, v, _ = _frame(n)
    start = o + n * w
    through_at = w + float(np.dot(o - c, n))          # deeper than the cavity's centre plane: through the hole
    th = 2 * math.pi * np.arange(ANGLES) / ANGLES
    dirs = np.outer(np.cos(th), u) + np.outer(np.sin(th), v)

    def through(rho):
        return probe.first_hit(start + dirs * rho[:, None], -n) > through_at

    r0 = orifice.radius * UM
    lo, hi = np.zeros(ANGLES), np.full(ANGLES, 1.3 * r0)
    if not through(lo).all() or through(hi).any():
        return None
    for _ in range(18):
        mid = (lo + hi) / 2
        ok = through(mid)
        lo = np.where(ok, mid, lo)
        hi = np.where(ok, hi, mid)
    r = (lo + hi) / 2
    return float(np.sqrt(np.mean(r * r)))


def wall_thickness(probe: Probe, capsule) -> float | None:
    """The thinnest wall (um) along the cavity surface's normals from the centre (radial for a cylinder
    and a sphere, the face normals of a prism, both ends along the axis), away from the orifices: the
    distance from the cavity surface to the next surface out.  What is joined to the wall (a beam, a
    latch) only thickens it."""
    cv = capsule.cavity
    c = np.asarray(capsule.center, float) * UM
    ax = _unit(cv.axis)
    if cv.shape == "volume":
        dirs = [np.array(d, float) for d in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))]
        dirs += [_unit(d) for d in ((1, 1, 1), (1, -1, 1), (-1, 1, 1), (-1, -1, 1), (1, 1, -1), (1, -1, -1), (-1, 1, -1), (-1, -1, -1))]
    else:
        from acl.export.solid import prism_ref

        u, v, _ = _frame(ax, prism_ref(capsule) if cv.shape == "prism" else None)
        k = 3 if cv.shape == "prism" else 8
        dirs = [math.cos(2 * math.pi * i / k) * u + math.sin(2 * math.pi * i / k) * v for i in range(k)] + [ax, -ax]
    best = None
    for d in dirs:
        if any(_cone(d, c, o) for o in capsule.orifices):
            continue
        loc, idx, _ = probe.rays.intersects_location(c[None, :], d[None, :], multiple_hits=True)
        dist = np.sort(np.einsum("ij,j->i", loc - c, d)) if len(loc) else np.array([])
        dist = dist[dist > 1e-9]
        if len(dist) >= 2:
            t = float(dist[1] - dist[0])
            best = t if best is None else min(best, t)
    return best


def _cone(d, c, o) -> bool:
    """Whether direction ``d`` from the centre ``c`` (um) passes near orifice ``o``'s opening."""
    to = np.asarray(o.center, float) * UM - c
    dist = float(np.linalg.norm(to))
    return float(np.dot(d, to)) > 0 and math.acos(min(1.0, float(np.dot(d, to)) / dist)) < math.atan2(1.5 * o.radius * UM, dist) + 0.05


# ------------------------------------------------------------------------------------------------
# Beams
# ------------------------------------------------------------------------------------------------

def beam_section(probe: Probe, beam) -> tuple[float, ...] | None:
    """(diameter,) or (width, thickness) in um of the slice across the beam at mid-length."""
    u, v, w = _frame(beam.axis)
    clamp = np.asarray(beam.clamp, float) * UM
    rot = np.vstack([u, v, w])
    m = np.column_stack([rot, -rot @ clamp])
    section = probe.manifold().transform(m).slice(beam.length * UM / 2)
    for piece in section.decompose():
        x0, y0, x1, y1 = piece.bounds()
        if x0 <= 0 <= x1 and y0 <= 0 <= y1:
            if beam.section.shape == "circle":
                return (2 * math.sqrt(piece.area() / math.pi),)
            return (x1 - x0, y1 - y0)
    return None


def beam_length(probe: Probe, beam) -> float | None:
    """Free length (um): from the surface that holds the beam's foot to the one at its tip."""
    u, v, w = _frame(beam.axis)
    s = beam.section
    half = (s.diameter / 2 if s.shape == "circle" else math.hypot(s.width, s.thickness) / 2) * UM
    mid = (np.asarray(beam.clamp, float) + np.asarray(beam.axis, float) * beam.length / 2) * UM
    beside = np.array([mid + d * (half + 0.3) for d in (u, -u, v, -v)])
    up, down = probe.first_hit(beside, w), probe.first_hit(beside, -w)
    if not np.isfinite(down).any():
        return None
    lower = float(np.nanmin(np.where(np.isfinite(down), down, np.nan)))
    if np.isfinite(up).any():
        upper = float(np.nanmin(np.where(np.isfinite(up), up, np.nan)))
    else:                                          # a free tip: its end face, from beyond it
        tip = np.asarray(beam.tip, float) * UM + w * 1.0
        back = probe.first_hit(tip[None, :], -w)[0]
        if not np.isfinite(back):
            return None
        upper = beam.length * UM / 2 + 1.0 - back
    return lower + upper


def latch_beam(probe: Probe, start, e, across, length_um: float, width_um: float, thickness_um: float):
    """(width, thickness, free length) in um of one inclined latch beam laid out from ``start`` (um)
    along ``e``, its width along ``across``: the slice at mid-length, and rays along it just above and
    below it (the surfaces that end it: the shuttle's side and the clamp's post)."""
    w = _unit(e)
    u = _unit(across)
    v = np.cross(w, u)
    start = np.asarray(start, float)
    rot = np.vstack([u, v, w])
    section = probe.manifold().transform(np.column_stack([rot, -rot @ start])).slice(length_um / 2)
    size = None
    for piece in section.decompose():
        x0, y0, x1, y1 = piece.bounds()
        if x0 <= 0 <= x1 and y0 <= 0 <= y1:
            size = (x1 - x0, y1 - y0)
    mid = start + w * length_um / 2
    beside = np.array([mid + v * (thickness_um / 2 + 0.3), mid - v * (thickness_um / 2 + 0.3)])
    up, down = probe.first_hit(beside, w), probe.first_hit(beside, -w)
    total = up + down
    free = float(np.mean(total)) if np.isfinite(total).all() else None
    return (None, None, free) if size is None else (size[0], size[1], free)


# ------------------------------------------------------------------------------------------------
# All of them
# ------------------------------------------------------------------------------------------------

def check(design, mesh, latch_beams=None) -> tuple[list[Measurement], list[Diagnostic]]:
    """Measure ``mesh`` (um) against ``design``: the measurements and an error for each mismatch.

    ``latch_beams`` (acl.export.solid.Build.latch_beams): where the export laid each latch's inclined
    beams out (the language places the shuttle, not the beams); their sections and free lengths are
    measured too."""
    probe = Probe(mesh)
    out: list[Measurement] = []
    diags: list[Diagnostic] = []

    def record(name, quantity, declared, measured, unit_, tol_text, ok, span, hint=None):
        ok = bool(ok)
        out.append(Measurement(name, quantity, declared, measured, unit_, tol_text, ok))
        if not ok:
            got = "could not be measured" if measured is None else f"measures {measured:.6g} {unit_}"
            diags.append(error("E-EXPORT-GEOMETRY", f"{quantity} of `{name}` {got} on the exported mesh, "
                               f"declared {declared:.6g} {unit_} (tolerance {tol_text})", span,
                               hint or "the print file would not be the device the physics describes"))

    for c in design.capsules:
        radii = {}
        cv = c.cavity
        reach = G.bounding_radius(cv.shape, cv.radius, cv.side, cv.height, cv.volume, 3 * cv.wall) * UM
        ctr = np.asarray(c.center, float) * UM
        local = probe.near(ctr - reach, ctr + reach)
        for o in c.orifices:
            r = orifice_radius(local, c, o)
            want = o.radius * UM
            radii[o.name] = r if r is not None else want
            record(f"{c.name}.{o.name}", "orifice radius", want, r, "um", "0.5 %",
                   r is not None and abs(r - want) <= RADIUS_TOL * want, o.span,
                   "a closed hole or a neighbour within a wall of it" if r is None else None)
        wall = wall_thickness(local, c)
        want_w = c.cavity.wall * UM
        record(c.name, "wall thickness", want_w, wall, "um", "0.1 um",
               wall is not None and abs(wall - want_w) <= LENGTH_TOL, c.span)
        vol = cavity_volume(probe, c, radii)
        want = c.cavity.volume * UM ** 3
        record(c.name, "cavity volume", want, vol, "um^3", "0.5 %",
               vol is not None and abs(vol - want) <= VOLUME_TOL * want, c.span)
    for b in design.beams:
        sec = beam_section(probe, b)
        s = b.section
        want = (s.diameter * UM,) if s.shape == "circle" else (s.width * UM, s.thickness * UM)
        names = ("diameter",) if s.shape == "circle" else ("width", "thickness")
        for k, nm in enumerate(names):
            got = None if sec is None else sec[k]
            record(b.name, f"beam {nm}", want[k], got, "um", "0.1 um",
                   got is not None and abs(got - want[k]) <= LENGTH_TOL, b.span)
        ends = np.array([b.clamp, b.tip]) * UM
        margin = b.length * UM / 2 + 10.0
        length = beam_length(probe.near(ends.min(axis=0) - margin, ends.max(axis=0) + margin), b)
        record(b.name, "beam free length", b.length * UM, length, "um", "0.1 um",
               length is not None and abs(length - b.length * UM) <= LENGTH_TOL, b.span)
    for l in design.latches:
        for k, (start, e, across) in enumerate((latch_beams or {}).get(l.name, [])):
            got = latch_beam(probe, start, e, across, l.length * UM, l.width * UM, l.thickness * UM)
            for nm, want, val in (("latch beam width", l.width * UM, got[0]), ("latch beam thickness", l.thickness * UM, got[1]),
                                  ("latch beam free length", l.length * UM, got[2])):
                record(f"{l.name} beam {k + 1}", nm, want, val, "um", "0.1 um",
                       val is not None and abs(val - want) <= LENGTH_TOL, l.span)
    return out, diags


# ------------------------------------------------------------------------------------------------
# Printability of the parts themselves
# ------------------------------------------------------------------------------------------------

def part_checks(design, parts) -> list[Diagnostic]:
    """Warnings on the exported parts (manifolds, um): a part that does not reach the substrate
    floats away when the resist is developed (W-EXPORT-FLOATING); two parts closer than the printer's
    lateral resolution print fused (W-EXPORT-TOUCH, acl.design.checks.PRINT_LATERAL)."""
    from acl.design.checks import PRINT_LATERAL
    from acl.diagnostics import warning

    spans = {}
    for kind in ("capsules", "beams", "latches", "anchors", "springs", "trusses"):
        for el in getattr(design, kind):
            spans.setdefault(el.name, el.span)

    def where(part):
        return next((spans[n] for n in part.elements if n in spans), None)

    out = []
    for p in parts:
        if p.solid.bounding_box()[2] > 1e-6:
            names = ", ".join(f"`{n}`" for n in dict.fromkeys(p.elements))
            out.append(warning("W-EXPORT-FLOATING", f"printed part {p.name} ({names}) does not reach the substrate: "
                               "developed, it floats away", where(p),
                               "hold it: mount its capsule on a beam or a latch, `fix` it, or link it to an anchor"))
    gap = PRINT_LATERAL * UM
    for i, a in enumerate(parts):
        for b in parts[i + 1:]:
            if a.solid.min_gap(b.solid, gap) < gap:
                out.append(warning("W-EXPORT-TOUCH", f"printed parts {a.name} and {b.name} come within the printer's lateral "
                                   f"resolution ({gap:g} um): they print fused", where(b),
                                   "move them apart, or join them on purpose"))
    return out

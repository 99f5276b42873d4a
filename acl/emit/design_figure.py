"""PNG of a design (`acl show DESIGN --plot FILE.png`): an isometric view and the three orthographic views.

Drawn from the resolved design alone (no solid modelling): capsules as the outlines of their outer
bodies (cavity dashed) with their names, beams, latches (inclined beams, with their state),
springs and trusses (dashed, named), anchors; at each orifice its outward normal as a black arrow,
the jet it streams along that normal as a dashed blue arrow and the capsule's thrust (against the
jet) as a red arrow at its centre; each observed gap as a dotted line between its two orifices with
its rest value.  matplotlib is imported here only, with the Agg backend.
"""
from __future__ import annotations

import math

import numpy as np

from acl.design import geometry as G

UM = 1e6
VIEWS2D = (("top (xy)", 0, 1), ("front (xz)", 0, 2), ("side (yz)", 1, 2))


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _frame(axis, ref=None):
    w = _unit(axis)
    if ref is not None:
        r = np.asarray(ref, float) - w * float(np.dot(ref, w))
        u = _unit(r) if np.linalg.norm(r) > 1e-9 else np.asarray(G.perpendicular(tuple(w)), float)
    else:
        u = np.asarray(G.perpendicular(tuple(w)), float)
    return u, np.cross(w, u), w


def _prism_ref(c):
    for o in c.orifices:
        if abs(float(np.dot(o.normal, c.cavity.axis))) < 1e-6:
            return np.asarray(o.normal, float)
    return None


def capsule_rings(c, grow: float = 0.0) -> list[np.ndarray]:
    """Closed outlines (um, (n, 3)) of a capsule's body (``grow`` = wall: the outer body, 0: the cavity)."""
    cv, ctr = c.cavity, np.asarray(c.center, float) * UM
    g = grow * UM
    if cv.shape == "volume":
        r = (3 * cv.volume / (4 * math.pi)) ** (1 / 3) * UM + g
        t = np.linspace(0, 2 * math.pi, 49)
        e = np.eye(3)
        return [ctr + r * (np.outer(np.cos(t), e[i]) + np.outer(np.sin(t), e[j])) for i, j in ((0, 1), (0, 2), (1, 2))]
    if cv.shape == "cylinder":
        u, v, w = _frame(cv.axis)
        t = np.linspace(0, 2 * math.pi, 49)
        ring = (cv.radius * UM + g) * (np.outer(np.cos(t), u) + np.outer(np.sin(t), v))
    else:
        u, v, w = _frame(cv.axis, _prism_ref(c))
        t = math.radians(60) + 2 * math.pi * np.arange(4) / 3
        ring = 2 * (G.prism_inradius(cv.side) * UM + g) * (np.outer(np.cos(t), u) + np.outer(np.sin(t), v))
    hh = cv.height * UM / 2 + g
    rings = [ctr + ring + w * hh, ctr + ring - w * hh]
    step = max(1, (len(ring) - 1) // 8)
    for k in range(0, len(ring) - 1, step):
        rings.append(np.array([ctr + ring[k] + w * hh, ctr + ring[k] - w * hh]))
    return rings


def latch_lines(l) -> list[np.ndarray]:
    """The latch's two inclined beams (um) from the shuttle to their clamps, in its rest state."""
    a = _unit(l.axis)
    p = np.cross((0, 0, 1.0), a)
    p = _unit(p) if np.linalg.norm(p) > 1e-6 else np.asarray(G.perpendicular(tuple(a)), float)
    s = np.asarray(l.anchor, float) * UM
    sign = 1.0 if l.state == "a" else -1.0
    L = l.length * UM
    return [np.array([s, s + side * p * L * math.cos(l.angle) + sign * a * L * math.sin(l.angle)]) for side in (1.0, -1.0)]


def _hull2d(pts: np.ndarray) -> np.ndarray:
    from scipy.spatial import ConvexHull, QhullError

    try:
        h = ConvexHull(pts)
        return pts[np.r_[h.vertices, h.vertices[0]]]
    except (QhullError, ValueError):
        return pts


def plot_design(design, path: str) -> None:
    """Write ``path`` (PNG): the design in four views."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colours = plt.get_cmap("tab10").colors
    fig = plt.figure(figsize=(12, 10))
    ax3 = fig.add_subplot(2, 2, 1, projection="3d", proj_type="ortho")
    axes2 = [fig.add_subplot(2, 2, k + 2) for k in range(3)]
    pts = [np.zeros(3)]
    caps = {c.name: c for c in design.capsules}

    def line3(seg, **kw):
        seg = np.asarray(seg)
        pts.extend(seg)
        ax3.plot(seg[:, 0], seg[:, 1], seg[:, 2], **kw)
        for ax, (_, i, j) in zip(axes2, VIEWS2D):
            ax.plot(seg[:, i], seg[:, j], **kw)

    def arrow(p0, d, **kw):
        p0, d = np.asarray(p0, float), np.asarray(d, float)
        pts.extend([p0, p0 + d])
        ax3.quiver(*p0, *d, arrow_length_ratio=0.25, **{k: v for k, v in kw.items() if k != "ls"},
                   linestyle=kw.get("ls", "-"))
        for ax, (_, i, j) in zip(axes2, VIEWS2D):
            if math.hypot(d[i], d[j]) > 1e-3 * np.linalg.norm(d):
                ax.annotate("", xy=(p0[i] + d[i], p0[j] + d[j]), xytext=(p0[i], p0[j]),
                            arrowprops=dict(arrowstyle="->", color=kw.get("color", "k"), ls=kw.get("ls", "-"), lw=1.2))

    def label(p, text, **kw):
        ax3.text(p[0], p[1], p[2], text, fontsize=7, **kw)
        for ax, (_, i, j) in zip(axes2, VIEWS2D):
            ax.text(p[i], p[j], text, fontsize=7, ha="center", va="center", **kw)

    for k, c in enumerate(design.capsules):
        col = colours[k % 10]
        outer = capsule_rings(c, c.cavity.wall)
        for ring in outer:
            ax3.plot(ring[:, 0], ring[:, 1], ring[:, 2], color=col, lw=0.8)
        allp = np.vstack(outer)
        pts.extend(allp)
        inner = np.vstack(capsule_rings(c))
        for ax, (_, i, j) in zip(axes2, VIEWS2D):
            h = _hull2d(allp[:, [i, j]])
            ax.fill(h[:, 0], h[:, 1], color=col, alpha=0.25, lw=1, ec=col)
            hi = _hull2d(inner[:, [i, j]])
            ax.plot(hi[:, 0], hi[:, 1], color=col, lw=0.6, ls="--")
        ctr = np.asarray(c.center, float) * UM
        label(ctr, c.name, weight="bold")
        size = max(G.bounding_radius(c.cavity.shape, c.cavity.radius, c.cavity.side, c.cavity.height, c.cavity.volume) * UM, 5.0)
        thrust = np.zeros(3)
        for o in c.orifices:
            oc, n = np.asarray(o.center, float) * UM, np.asarray(o.normal, float)
            arrow(oc, n * max(o.radius * UM, 0.3 * size), color="k")
            arrow(oc + n * max(o.radius * UM, 0.3 * size), n * 0.6 * size, color="tab:blue", ls="--")
            label(oc + n * (max(o.radius * UM, 0.3 * size) + 0.7 * size), "jet" if o.name == "jet" else f"{o.name} jet", color="tab:blue")
            thrust -= n * o.radius ** 2
        if np.linalg.norm(thrust) > 0:
            arrow(ctr, _unit(thrust) * 0.5 * size, color="tab:red")
    for b in design.beams:
        seg = np.array([b.clamp, b.tip]) * UM
        line3(seg, color="0.3", lw=2.5)
        label(seg.mean(axis=0), b.name, color="0.3")
    for l in design.latches:
        for seg in latch_lines(l):
            line3(seg, color="tab:purple", lw=2)
        below = np.asarray(l.anchor) * UM - np.array([0.0, 0.0, 0.6 * l.length * UM])
        label(below, f"latch {l.name}: state {l.state}", color="tab:purple")
    for a in design.anchors:
        p = np.asarray(a.position) * UM
        line3(np.array([p, p]), color="k", marker="^", ms=6)
        label(p, a.name)
    for j in design.joints:
        if j.kind == "link" and j.a in caps and j.b in caps:
            seg = np.array([caps[j.a].center, caps[j.b].center]) * UM
            line3(seg, color="tab:green", ls="--", lw=1)
            label(seg.mean(axis=0), f"{j.element_kind} {j.element}", color="tab:green")
        elif j.kind == "fix":
            c = caps[j.capsule]
            p = np.asarray(c.center) * UM
            line3(np.array([p, [p[0], p[1], 0.0]]), color="k", ls=":", lw=1)
    for ob in design.observes:
        if ob.kind == "gap" and ob.a and ob.b:
            try:
                oa = caps[ob.a.split(".")[0]].orifice(ob.a.split(".")[1])
                obb = caps[ob.b.split(".")[0]].orifice(ob.b.split(".")[1])
            except (KeyError, IndexError):
                continue
            seg = np.array([oa.center, obb.center]) * UM
            line3(seg, color="tab:orange", ls=":", lw=1.5)
            label(seg.mean(axis=0) + np.array([0, 0, 4.0]), f"{ob.name} = {np.linalg.norm(seg[1] - seg[0]):.4g} um", color="tab:orange")
    allp = np.array(pts)
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    lo[2] = min(lo[2], 0.0)
    centre, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2 * 1.08, 1.0)
    for setter, c in zip((ax3.set_xlim, ax3.set_ylim, ax3.set_zlim), centre):
        setter(c - half, c + half)
    ax3.set_box_aspect((1, 1, 1))
    ax3.view_init(elev=25, azim=-60)
    ax3.set_title("isometric", fontsize=9)
    names = "xyz"
    for ax, (title, i, j) in zip(axes2, VIEWS2D):
        ax.set_xlim(centre[i] - half, centre[i] + half)
        ax.set_ylim(centre[j] - half, centre[j] + half)
        ax.set_aspect("equal")
        if j == 2:
            ax.axhline(0.0, color="k", lw=1.5)       # the substrate
        ax.set_xlabel(f"{names[i]} (um)", fontsize=8)
        ax.set_ylabel(f"{names[j]} (um)", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.set_title(title, fontsize=9)
    for k, (lbl, c) in enumerate((("orifice normal", "k"), ("jet", "tab:blue"), ("thrust", "tab:red"),
                                  ("observed gap", "tab:orange"))):
        axes2[0].plot([], [], color=c, ls="--" if lbl == "jet" else ":" if lbl == "observed gap" else "-", label=lbl)
    axes2[0].legend(fontsize=7, loc="upper right")
    fig.suptitle(f"{design.file}: {design.summary()}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100, format="png")
    plt.close(fig)

"""PNG of the exported solid: an isometric view and the three orthographic views of the meshes.

Each view projects the triangles orthographically, drops those facing away (the parts are closed),
shades the rest by a fixed light and paints them far to near (matplotlib's 2-D PolyCollection: a
few thousand triangles draw in a fraction of a second, where mplot3d takes seconds).  matplotlib
is imported here only, with the Agg backend.
"""
from __future__ import annotations

import math

import numpy as np

VIEWS = (("isometric", 30.0, -60.0), ("top (xy)", 90.0, -90.0), ("front (xz)", 0.0, -90.0), ("side (yz)", 0.0, 0.0))
_LIGHT = np.array([0.35, -0.55, 0.76]) / np.linalg.norm([0.35, -0.55, 0.76])


def view_axes(elev: float, azim: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(right, up, towards the viewer) of a view at elevation and azimuth in degrees (matplotlib's convention)."""
    e, a = math.radians(elev), math.radians(azim)
    eye = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    right = np.array([-math.sin(a), math.cos(a), 0.0])
    return right, np.cross(eye, right), eye


def _draw(ax, meshes, elev, azim, colours, names: bool):
    from matplotlib.collections import PolyCollection

    right, up, eye = view_axes(elev, azim)
    polys, faces, depth = [], [], []
    for i, m in enumerate(meshes):
        tri = np.asarray(m.vertices, float)[np.asarray(m.faces)]
        n = np.asarray(m.face_normals, float)
        front = n @ eye > 1e-9
        tri, n = tri[front], n[front]
        polys.append(np.stack([tri @ right, tri @ up], axis=-1))
        k = 0.35 + 0.65 * np.abs(n @ _LIGHT)
        faces.append(np.clip(np.outer(k, colours[i % len(colours)][:3]), 0, 1))
        depth.append(tri.mean(axis=1) @ eye)
    if polys:
        p, c, d = np.concatenate(polys), np.concatenate(faces), np.concatenate(depth)
        order = np.argsort(d, kind="stable")
        ax.add_collection(PolyCollection(p[order], facecolors=c[order], edgecolors=c[order], linewidths=0.2))
    if names:
        for i, m in enumerate(meshes):
            top = np.asarray(m.vertices)[np.argmax(np.asarray(m.vertices) @ up)]
            ax.annotate(m.metadata.get("name", f"part{i + 1}"), (top @ right, top @ up), fontsize=7,
                        xytext=(0, 4), textcoords="offset points", ha="center")
    return right, up


def render(meshes, path: str, title: str = "", unit: str = "um", dpi: int = 100) -> None:
    """Write ``path`` (PNG): each part in its own colour, named in the isometric view."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colours = plt.get_cmap("tab10").colors
    allv = np.vstack([m.vertices for m in meshes]) if meshes else np.zeros((1, 3))
    fig, axes = plt.subplots(2, 2, figsize=(10, 9))
    for ax, (name, elev, azim) in zip(axes.flat, VIEWS):
        right, up = _draw(ax, meshes, elev, azim, colours, names=name == "isometric")
        x, y = allv @ right, allv @ up
        half = max(float(np.ptp(x)), float(np.ptp(y)), 1e-12) / 2 * 1.1
        cx, cy = (x.max() + x.min()) / 2, (y.max() + y.min()) / 2
        ax.set_xlim(cx - half, cx + half)
        ax.set_ylim(cy - half, cy + half)
        ax.set_aspect("equal")
        ax.set_title(name, fontsize=9)
        ax.tick_params(labelsize=7)
        if name == "isometric":
            ax.set_xticks([])
            ax.set_yticks([])
        else:
            axis_names = "xyz"
            ax.set_xlabel(f"{axis_names[int(np.argmax(np.abs(right)))]} ({unit})", fontsize=8)
            ax.set_ylabel(f"{axis_names[int(np.argmax(np.abs(up)))]} ({unit})", fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=dpi, format="png", metadata={"Software": None})
    plt.close(fig)

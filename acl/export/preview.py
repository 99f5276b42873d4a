"""PNG of the exported solid: an isometric view and the three orthographic views of the meshes.

matplotlib is imported here only, with the Agg backend.
"""
from __future__ import annotations

import numpy as np

VIEWS = (("isometric", 30.0, -60.0), ("top (xy)", 90.0, -90.0), ("front (xz)", 0.0, -90.0), ("side (yz)", 0.0, 0.0))


def _shade(normals: np.ndarray, base) -> np.ndarray:
    light = np.array([0.4, -0.5, 0.77])
    light = light / np.linalg.norm(light)
    k = 0.35 + 0.65 * np.clip(np.abs(normals @ light), 0, 1)
    return np.clip(np.outer(k, base), 0, 1)


def render(meshes, path: str, title: str = "", unit: str = "um") -> None:
    """Write ``path`` (PNG): each part in its own colour, names at the parts in the isometric view."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    colours = plt.get_cmap("tab10").colors
    allv = np.vstack([m.vertices for m in meshes]) if meshes else np.zeros((1, 3))
    lo, hi = allv.min(axis=0), allv.max(axis=0)
    centre, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-12)
    fig = plt.figure(figsize=(10, 9))
    for k, (name, elev, azim) in enumerate(VIEWS):
        ax = fig.add_subplot(2, 2, k + 1, projection="3d", proj_type="ortho")
        for i, m in enumerate(meshes):
            tris = m.vertices[m.faces]
            pc = Poly3DCollection(tris, facecolors=_shade(m.face_normals, colours[i % 10]), edgecolors="none", linewidths=0)
            ax.add_collection3d(pc)
            if k == 0:
                top = m.vertices[np.argmax(m.vertices[:, 2])]
                ax.text(top[0], top[1], top[2] + 0.05 * half, m.metadata.get("name", f"part{i + 1}"), fontsize=7)
        for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
            setter(c - half, c + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=elev, azim=azim)
        labels = [f"x ({unit})", f"y ({unit})", f"z ({unit})"]
        hidden = {1: 2, 2: 1, 3: 0}.get(k)          # the axis a view looks along: no ticks, no label
        for i, (set_label, set_ticks) in enumerate(((ax.set_xlabel, ax.set_xticks), (ax.set_ylabel, ax.set_yticks),
                                                     (ax.set_zlabel, ax.set_zticks))):
            if i == hidden:
                set_label("")
                set_ticks([])
            else:
                set_label(labels[i], fontsize=7)
        ax.tick_params(labelsize=6)
        ax.set_title(name, fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100, format="png")
    plt.close(fig)

"""PNG of a path goal (as paper Fig. 3e-g): target and predicted path with its 95 % band (and the band the proposed
readings would leave: acl.schedule.experiment), tone amplitudes over time.

matplotlib is imported here only, with the Agg backend.
"""
from __future__ import annotations

import numpy as np

from acl.schedule.model import GoalReport


# 95 % of a 2-D normal lies inside the ellipse of Mahalanobis radius sqrt(chi2_2(0.95)) = sqrt(-2 ln 0.05)
ELLIPSE_95 = float(np.sqrt(-2.0 * np.log(0.05)))


# the band reads as one shaded region whatever the number of waypoints: each ellipse's opacity is set so that the
# ellipses overlapping at a point add up to about this (a fixed 4 / n made a narrow band vanish: 0.02 per ellipse)
BAND_ALPHA = 0.35
# a path along one line has a band of zero width across it: its ellipses are drawn at least this fraction of the
# widest band's half-axis across (and never wider than long), so the band shows (the label says so)
MIN_WIDTH_FRACTION = 0.04


def _band_axes(covs) -> np.ndarray:
    """Half-axes (major, minor) in um and orientation (deg) of each waypoint's 95 % ellipse."""
    out = []
    for xx, xy, yy in covs:
        w, V = np.linalg.eigh(np.array([[xx, xy], [xy, yy]]) * 1e12)
        w = np.sqrt(np.maximum(w, 0.0)) * ELLIPSE_95
        out.append((w[1], w[0], float(np.degrees(np.arctan2(V[1, 1], V[0, 1])))))
    return np.array(out, dtype=float).reshape(-1, 3)


def _band(ax, centres, covs, colour, label, floor_um: float = 0.0) -> bool:
    """The band around the path: a 95 % ellipse of each re-simulated waypoint's covariance (um); True when an
    ellipse was widened across (to ``floor_um``, at most its length) to be seen."""
    if not centres or not covs:
        return False
    from matplotlib.patches import Ellipse

    axes = _band_axes(covs)
    c = np.asarray(centres, dtype=float) * 1e6
    step = float(np.median(np.linalg.norm(np.diff(c, axis=0), axis=1))) if len(c) > 1 else 0.0
    overlap = max(1.0, 2.0 * float(np.mean(axes[:, 0])) / step) if step > 0 else float(len(c))
    alpha = float(np.clip(1.0 - (1.0 - BAND_ALPHA) ** (1.0 / overlap), 0.01, BAND_ALPHA))
    across = np.minimum(floor_um, axes[:, 0])      # never wider across than the ellipse is long
    widened = bool(np.any(axes[:, 1] < across * (1 - 1e-9)))
    for k, ((x, y), (major, minor, angle), least) in enumerate(zip(c, axes, across)):
        ax.add_patch(Ellipse((x, y), 2 * major, 2 * max(minor, least), angle=angle,
                             facecolor=colour, alpha=alpha, edgecolor="none", zorder=1,
                             label=label if k == 0 else None))
    return widened


def plot_goal(goal: GoalReport, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 5.2))
    tgt = goal.target_m * 1e6
    ax1.plot(tgt[:, 0], tgt[:, 1], "r--", lw=1.2, label="target", zorder=3)
    if goal.predicted_m is not None:
        pred = goal.predicted_m * 1e6
        ok = np.all(np.isfinite(pred), axis=1)
        ax1.plot(pred[ok, 0], pred[ok, 1], "b.", ms=2.5, label=f"predicted ({goal.model})", zorder=3)
    cause = ((goal.details or {}).get("band") or {}).get("cause") or {}
    bp = goal.band_plot or {}
    bands = {}              # label -> (colour, label shown): legend swatches as opaque as the band reads
    if bp.get("waypoints_m") and bp.get("cov_m2"):
        floor = MIN_WIDTH_FRACTION * float(np.max(_band_axes(bp["cov_m2"])[:, 0], initial=0.0))
        label = (f"95 % band (declared uncertainty; RMS p95 {goal.rms_error_p95_m * 1e6:.3g} um)"
                 if goal.rms_error_p95_m is not None else "95 % band (declared uncertainty)")
        after = cause.get("measurement") or {}
        after_label = (f"95 % band after the proposed readings ({after['expected_rms_p95_m'] * 1e6:.3g} um)"
                       if after and bp.get("cov_after_m2") else None)
        suffix = f"; where thinner, drawn {2 * floor:.2g} um across"
        widened = _band(ax1, bp["waypoints_m"], bp["cov_m2"], "tab:orange", label, floor)
        bands = {label: ("tab:orange", label + (suffix if widened else ""))}
        if after_label:
            widened = _band(ax1, bp["waypoints_m"], bp["cov_after_m2"], "tab:green", after_label, floor)
            bands[after_label] = ("tab:green", after_label + (suffix if widened else ""))
    ax1.plot([0], [0], "k+", ms=8, label="rest")
    ax1.set_aspect("equal", adjustable="datalim")
    ax1.set_xlabel("x (um)")
    ax1.set_ylabel("y (um)")
    err = "" if goal.rms_error_m is None else f"  RMS {goal.rms_error_m * 1e6:.3g} um"
    ax1.set_title(goal.name + err, fontsize=9)
    handles, labels = ax1.get_legend_handles_labels()
    if bands:
        from matplotlib.patches import Patch

        for i, lb in enumerate(labels):
            if lb in bands:
                colour, labels[i] = bands[lb]
                handles[i] = Patch(facecolor=colour, alpha=BAND_ALPHA, edgecolor="none")
    ax1.legend(handles, labels, fontsize=6, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=1, frameon=False)
    for k, f in enumerate(goal.frequencies_hz):
        ax2.plot(goal.times_s, goal.amplitudes_v[:, k], lw=1, label=f"{f / 1e3:g} kHz")
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("amplitude (V peak)")
    ax2.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)

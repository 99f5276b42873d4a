"""PNG of a path goal (as paper Fig. 3e-g): target and predicted path with its 95 % band (and the band the proposed
readings would leave: acl.schedule.experiment), tone amplitudes over time.

matplotlib is imported here only, with the Agg backend.
"""
from __future__ import annotations

import numpy as np

from acl.schedule.model import GoalReport


# 95 % of a 2-D normal lies inside the ellipse of Mahalanobis radius sqrt(chi2_2(0.95)) = sqrt(-2 ln 0.05)
ELLIPSE_95 = float(np.sqrt(-2.0 * np.log(0.05)))


def _band(ax, centres, covs, colour, label) -> None:
    """The band around the path: a 95 % ellipse of each re-simulated waypoint's covariance (um)."""
    if not centres or not covs:
        return
    from matplotlib.patches import Ellipse

    alpha = min(0.3, 4.0 / len(covs))          # the ellipses overlap along the path: the envelope reads as one band
    for k, ((x, y), (xx, xy, yy)) in enumerate(zip(centres, covs)):
        w, V = np.linalg.eigh(np.array([[xx, xy], [xy, yy]]) * 1e12)
        w = np.sqrt(np.maximum(w, 0.0)) * ELLIPSE_95
        angle = float(np.degrees(np.arctan2(V[1, 1], V[0, 1])))
        ax.add_patch(Ellipse((x * 1e6, y * 1e6), 2 * w[1], 2 * w[0], angle=angle, facecolor=colour, alpha=alpha,
                             edgecolor="none", zorder=1, label=label if k == 0 else None))


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
    _band(ax1, bp.get("waypoints_m"), bp.get("cov_m2"), "tab:orange",
          f"95 % band (declared uncertainty; RMS p95 {goal.rms_error_p95_m * 1e6:.3g} um)"
          if goal.rms_error_p95_m is not None else "95 % band (declared uncertainty)")
    after = cause.get("measurement") or {}
    if after and bp.get("cov_after_m2"):
        _band(ax1, bp["waypoints_m"], bp["cov_after_m2"], "tab:green",
              f"95 % band after the proposed readings ({after['expected_rms_p95_m'] * 1e6:.3g} um)")
    ax1.plot([0], [0], "k+", ms=8, label="rest")
    ax1.set_aspect("equal", adjustable="datalim")
    ax1.set_xlabel("x (um)")
    ax1.set_ylabel("y (um)")
    err = "" if goal.rms_error_m is None else f"  RMS {goal.rms_error_m * 1e6:.3g} um"
    ax1.set_title(goal.name + err, fontsize=9)
    ax1.legend(fontsize=6, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2, frameon=False)
    for k, f in enumerate(goal.frequencies_hz):
        ax2.plot(goal.times_s, goal.amplitudes_v[:, k], lw=1, label=f"{f / 1e3:g} kHz")
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("amplitude (V peak)")
    ax2.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)

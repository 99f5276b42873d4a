"""PNG of a path goal (as paper Fig. 3e-g): target and predicted path, tone amplitudes over time.

matplotlib is imported here only, with the Agg backend.
"""
from __future__ import annotations

import numpy as np

from acl.schedule.model import GoalReport


def plot_goal(goal: GoalReport, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4.2))
    tgt = goal.target_m * 1e6
    ax1.plot(tgt[:, 0], tgt[:, 1], "r--", lw=1.2, label="target")
    if goal.predicted_m is not None:
        pred = goal.predicted_m * 1e6
        ok = np.all(np.isfinite(pred), axis=1)
        ax1.plot(pred[ok, 0], pred[ok, 1], "b.", ms=2.5, label=f"predicted ({goal.model})")
    ax1.plot([0], [0], "k+", ms=8, label="rest")
    ax1.set_aspect("equal", adjustable="datalim")
    ax1.set_xlabel("x (um)")
    ax1.set_ylabel("y (um)")
    err = "" if goal.rms_error_m is None else f"  RMS {goal.rms_error_m * 1e6:.3g} um"
    ax1.set_title(goal.name + err, fontsize=9)
    ax1.legend(fontsize=7, loc="best")
    for k, f in enumerate(goal.frequencies_hz):
        ax2.plot(goal.times_s, goal.amplitudes_v[:, k], lw=1, label=f"{f / 1e3:g} kHz")
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("amplitude (V peak)")
    ax2.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)

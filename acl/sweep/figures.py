"""Figures of a sweep as PNG (matplotlib, the `acl[plot]` extra, imported here only; backend untouched).

* ``hist_<column>.png``: histogram of each float quantity over the valid points;
* ``yield_<param>.png``: yield (with its Clopper-Pearson interval) along a one-parameter grid with
  Monte Carlo samples at each point, or pass/fail along a grid;
* ``passmap_<a>_<b>.png``: pass/fail (or yield) map over the first two varied parameters;
* ``yield_vs_tolerance.png``: :func:`yield_vs_tolerance` results.
"""
from __future__ import annotations

import os

import numpy as np

from acl.sweep.table import SweepTable, clopper_pearson

_SCALE = {"m": (1e6, "um"), "Hz": (1e-3, "kHz"), "N": (1e9, "nN"), "Pa": (1e-6, "MPa"), "m^3": (1e18, "um^3")}


def _figure():
    from matplotlib.figure import Figure

    return Figure(figsize=(5.0, 3.6), dpi=120, layout="constrained")


def _axis_label(name: str, unit: str) -> tuple[float, str]:
    f, u = _SCALE.get(unit, (1.0, unit))
    return f, f"{name} ({u})" if u else name


def write_figures(table: SweepTable, folder: str) -> list[str]:
    """Every figure the table supports into ``folder`` (created); returns the paths written."""
    os.makedirs(folder, exist_ok=True)
    written = []
    data, spec = table.data, table.spec
    valid = data["valid"]
    skip = {"point", "valid", "code", *spec.names}
    for c in table.columns:
        if c in skip or data[c].dtype.kind != "f" or c.endswith("_value"):
            continue
        vals = data[c][valid & np.isfinite(data[c])]
        if vals.size == 0:
            continue
        unit = "Hz" if c.endswith("_hz") else ("m" if c.endswith("_m") else ("N" if c.endswith("_n") else ""))
        f, label = _axis_label(c, unit)
        fig = _figure()
        ax = fig.add_subplot()
        ax.hist(vals * f, bins=min(60, max(10, int(np.sqrt(vals.size)))), color="#4477aa")
        ax.set_xlabel(label)
        ax.set_ylabel("points")
        ax.set_title(f"{c}: {vals.size} valid points", fontsize=9)
        written.append(_save(fig, folder, f"hist_{c}.png"))
    passed = table.passed
    if passed is not None and len(spec.axes) >= 1:
        a = spec.axes[0]
        f, label = _axis_label(a.name, a.unit)
        if len(spec.axes) == 1:
            k = passed.reshape(spec.n_grid, spec.samples).sum(axis=1)
            y = k / spec.samples
            fig = _figure()
            ax = fig.add_subplot()
            if spec.samples > 1:
                lo, hi = np.array([clopper_pearson(int(x), spec.samples) for x in k]).T
                ax.fill_between(a.values * f, lo, hi, color="#88ccee", alpha=0.6, label="95 % interval")
            ax.plot(a.values * f, y, "o-", color="#332288", ms=3, label="yield" if spec.samples > 1 else "pass")
            ax.set_xlabel(label)
            ax.set_ylabel("yield" if spec.samples > 1 else "pass (1) / fail (0)")
            ax.set_ylim(-0.02, 1.02)
            if a.log:
                ax.set_xscale("log")
            ax.legend(fontsize=8)
            written.append(_save(fig, folder, f"yield_{a.name}.png"))
        else:
            b = spec.axes[1]
            fb, label_b = _axis_label(b.name, b.unit)
            g = table.grid_yield()
            z = g.reshape(len(a.values), len(b.values), -1).mean(axis=2)
            fig = _figure()
            ax = fig.add_subplot()
            mesh = ax.pcolormesh(b.values * fb, a.values * f, z, vmin=0, vmax=1, cmap="RdYlGn", shading="nearest")
            fig.colorbar(mesh, ax=ax, label="yield" if spec.samples > 1 else "pass")
            ax.set_xlabel(label_b)
            ax.set_ylabel(label)
            if a.log:
                ax.set_yscale("log")
            if b.log:
                ax.set_xscale("log")
            written.append(_save(fig, folder, f"passmap_{a.name}_{b.name}.png"))
    return written


def plot_yield_vs_tolerance(rows: list[dict], folder: str) -> str:
    """``rows`` from :func:`yield_vs_tolerance`: yield with its interval against the scale."""
    os.makedirs(folder, exist_ok=True)
    fig = _figure()
    ax = fig.add_subplot()
    s = np.array([r["scale"] for r in rows])
    ax.fill_between(s, [r["lower"] for r in rows], [r["upper"] for r in rows], color="#88ccee", alpha=0.6, label="95 % interval")
    ax.plot(s, [r["yield"] for r in rows], "o-", color="#332288", ms=3, label="yield")
    ax.set_xlabel("tolerance scale (1 = as given)")
    ax.set_ylabel("yield")
    ax.set_ylim(-0.02, 1.02)
    ax.legend(fontsize=8)
    return _save(fig, folder, "yield_vs_tolerance.png")


def _save(fig, folder: str, name: str) -> str:
    path = os.path.join(folder, name.replace("/", "_"))
    fig.savefig(path)
    return path

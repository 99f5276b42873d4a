"""`acl compile --plot` shows the 95 % band around the path (issue 28), also where it is a line.

Tried as a new user on the first tutorial's stroke (docs/tutorials/first-device.md): the Fig. 2 cantilever
moves along x only, so each waypoint's band ellipse has zero width across the path, and at an opacity of
4 / n per ellipse the band and its legend swatches were invisible (no pixel of the panel in the band's shade; 1.4 % now). The band is
now drawn at least a fixed fraction of its widest half-axis across (the legend says so), with opacities
that add up to one visible shade, and legend swatches as opaque as the band reads.
"""
from __future__ import annotations

import os

import numpy as np
import pytest

import acl
from acl.schedule.compile import CompileOptions, compile_program

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")


def _draw(goal, path, saved):
    from acl.emit import plot

    plot.plot_goal(goal, str(path))
    return saved[path.name]


def _share(png, fig, rgb, tol=0.12):
    """Share of the path panel's pixels within `tol` of a blended band colour."""
    import matplotlib.image

    img = matplotlib.image.imread(str(png))[..., :3]
    h = img.shape[0]
    x0, y0, x1, y1 = fig.axes[0].get_window_extent().extents
    panel = img[int(h - y1):int(h - y0), int(x0):int(x1)]
    return float(np.mean(np.all(np.abs(panel - np.asarray(rgb)) < tol, axis=-1)))


@pytest.fixture(scope="module")
def stroke():
    pytest.importorskip("matplotlib")
    d = acl.load(os.path.join(ROOT, "examples", "fig2_stroke.acl"))
    return compile_program(d, "stroke", CompileOptions(band_samples=6, resim_points=20)).goals[0]


def test_a_band_along_one_line_is_drawn_where_it_can_be_seen(stroke, tmp_path, saved_figures):
    from matplotlib.colors import to_rgb

    assert stroke.band_plot and stroke.band_plot["cov_m2"]
    fig = _draw(stroke, tmp_path / "g.png", saved_figures)
    # tab:orange at the band's opacity over white; its ellipses span about 18 um by 0.7 um of a 23 x 18 um panel
    orange = 1 - 0.35 * (1 - np.asarray(to_rgb("tab:orange")))
    assert _share(tmp_path / "g.png", fig, orange) > 0.005
    labels = fig.axes[0].get_legend().get_texts()
    assert any("drawn" in t.get_text() and "um across" in t.get_text() for t in labels)


def test_legend_swatches_are_as_opaque_as_the_band(stroke, tmp_path, saved_figures):
    fig = _draw(stroke, tmp_path / "g.png", saved_figures)
    leg = fig.axes[0].get_legend()
    swatches = [(h, t.get_text()) for h, t in zip(leg.legend_handles, leg.get_texts()) if "95 % band" in t.get_text()]
    assert len(swatches) == 2 and all(h.get_alpha() >= 0.3 for h, _ in swatches), swatches

"""`acl analyze --plot`'s pair figure (Fig. 4f) is drawn as the modal response is (issue 28, figures).

Seen in the README's tour (`acl analyze examples/fig4_facing_pair.acl --at "125 kHz @ 2 V" --plot figs/`):
pair_left_right.png drew |dV| per volt from 20 to 250 kHz, past the transducer's 40 .. 200 kHz band, with a kink
at each point of the gain table (its linear interpolation), the defect the modal response had. It now runs over
the band, per pascal, and the phases (which the gain does not change) are those of the same response.
"""
from __future__ import annotations

import os

import numpy as np
import pytest

import acl

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
FIG4 = os.path.join(ROOT, "examples", "fig4_facing_pair.acl")


def test_pair_figure_is_limited_to_the_band_per_pascal_and_smooth(tmp_path, saved_figures):
    from acl.analysis.report import analyze
    from acl.emit import analysis_figures

    design = acl.load(FIG4)
    analysis_figures.write_figures(design, analyze(design, None, snap_in=False), str(tmp_path))
    fig = next(f for f in saved_figures.values() if f._suptitle is not None and "phase difference" in f._suptitle.get_text())
    amp, phase = fig.axes[:2]
    lo, hi = (b / 1e3 for b in design.transducer.band)
    assert amp.get_xlim() == pytest.approx((lo, hi)) and "per pascal" in amp.get_ylabel()
    t = design.transducer
    for line in amp.get_lines() + phase.get_lines():
        x, _ = line.get_data()
        assert np.min(x) >= lo - 1e-9 and np.max(x) <= hi + 1e-9
    for line in amp.get_lines():
        x, y = (np.asarray(v, float) for v in line.get_data())
        d2 = np.abs(np.diff(np.log(y), 2))
        for ft in t.gain_frequencies:
            k = int(np.argmin(np.abs(x - ft / 1e3)))
            if 5 <= k < len(d2) - 5:      # a kink: a spike of the second difference at one sample
                assert d2[k - 2:k + 1].max() <= 3 * max(d2[k - 5], d2[k + 4]) + 1e-9, (ft, line.get_label())

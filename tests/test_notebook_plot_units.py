"""Notebook figures read as a user expects (issue 28, the executed results notebook looked at as a new user).

- `FitReport.plot()` drew the RMSE in metres under "RMSE (SI)" (7.4e-07 on a 1e-7 offset axis) while `acl fit`
  prints um; it now draws um for lengths (a latch state's Pearson residual as it is, labelled).
- `LintResult.plot()` of a clean design was an empty panel with -0.04 .. 0.04 ticks on both axes.
Fast: the results are built directly, no fit or lint runs.
"""
from __future__ import annotations

import pytest

from acl.notebook import FitReport, LintResult

pytest.importorskip("matplotlib")


@pytest.fixture(autouse=True)
def _agg():
    import matplotlib

    matplotlib.use("Agg")
    yield
    import matplotlib.pyplot as plt

    plt.close("all")


def _report(per):
    return FitReport("d.acl", 18, 7.4e-7, 1.1e-7, ["drive_saturation"], [], per)


def test_fit_plot_draws_lengths_in_um():
    ax = _report({"deflection": {"n": 18, "rmse_before": 7.4e-7, "rmse_after": 1.1e-7, "unit": "m"}}).plot()
    heights = sorted(round(p.get_height(), 6) for p in ax.patches)
    assert heights == [0.11, 0.74] and ax.get_ylabel() == "RMSE (um)"


def test_fit_plot_keeps_a_latch_state_pearson_residual_and_says_so():
    ax = _report({"deflection": {"n": 9, "rmse_before": 2e-6, "rmse_after": 1e-6, "unit": "m"},
                  "latched": {"n": 9, "rmse_before": 0.8, "rmse_after": 0.5, "unit": "Pearson"}}).plot()
    assert sorted(round(p.get_height(), 6) for p in ax.patches) == [0.5, 0.8, 1.0, 2.0]
    assert "Pearson" in ax.get_ylabel() and [t.get_text() for t in ax.get_xticklabels()] == ["deflection",
                                                                                            "latched (Pearson)"]


def test_fit_html_gives_the_rmse_in_um():
    html = _report({})._repr_html_()
    assert "RMSE 0.74 -&gt; 0.11 um" in html and "(SI)" not in html


def test_a_clean_lint_plot_has_no_meaningless_ticks():
    ax = LintResult("examples/fig4_facing_pair.acl", [], []).plot()
    assert list(ax.get_yticks()) == [] and ax.get_xlim() == (0.0, 1.0)
    assert any(t.get_text() == "no findings" for t in ax.texts)

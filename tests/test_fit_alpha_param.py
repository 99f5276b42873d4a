"""A design parameter that is only *named* alpha is not paper Eq. (3)'s alpha (issue 23).

The fit's pair law read any `param alpha` as the Bjerknes coefficient in N m^2/V^2: adding an unused
`param alpha = 1` to the Fig. 4 pair (now examples/first_principles/fig4_facing_pair.acl) made `acl synth` put the 60 um pair in contact at 1 V
(1 N m^2/V^2 in SI), where the design without it (and `acl analyze`) keeps it apart (63.0 um at 3 V under Eq. (3); 61.7 um on the
analysis' force model, which synth now uses).
"""
from __future__ import annotations

import csv
import os

import pytest

from acl.cli import main

# the first-principles pair (the shipped examples/fig4_facing_pair.acl declares the paper's calibration)
EX = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples", "first_principles")


def _synth(tmp_path, design, sweep):
    out = tmp_path / f"{os.path.basename(design)}-{sweep}.csv"
    assert main(["synth", str(design), "-o", str(out), "--observe", "d", "--sweep", sweep,
                 "--voltages", "0V..3V:4", "-q"]) == 0
    with open(out) as fh:
        return {(r["set:gap"], r["drive"]): float(r["value"]) for r in csv.DictReader(fh)}


@pytest.mark.parametrize("alpha", ["1", "30 deg"])
def test_an_unrelated_param_named_alpha_changes_nothing(tmp_path, alpha):
    src = open(os.path.join(EX, "fig4_facing_pair.acl")).read()
    plain = tmp_path / "plain.acl"
    plain.write_text(src)
    named = tmp_path / "named.acl"
    i = src.index("param gap")
    named.write_text(src[:i] + f"param alpha = {alpha}\n" + src[i:])
    want = _synth(tmp_path, plain, "gap=20um,60um")
    import acl
    from acl.analysis import acoustics, mechanics
    from acl.design.model import Drive, Tone
    from acl.fit.synth import observe_value

    d = acl.load(str(plain), overrides={"gap": "60um"})
    st = mechanics.equilibrium(d, Drive(tones=(Tone(frequency=125e3, amplitude=3.0),)), acoustics.force_model_for(d))
    apart = observe_value(d, d.observe("d"), st) * 1e6          # 61.7 um: apart, as acl analyze says
    assert st.status == "ok" and want[("60 um", "125 kHz @ 3 V")] == pytest.approx(apart, abs=0.05)
    for order in ("gap=20um,60um", "gap=60um,20um"):
        assert _synth(tmp_path, named, order) == want


def test_an_alpha_in_eq3_units_is_still_the_pairs_coefficient(tmp_path):
    """docs/data.md: a parameter `alpha` in N m^2/V^2 gives the Eq. (3) coefficient's start value."""
    from acl import load
    from acl.fit.forward import eq3_alpha_param

    src = open(os.path.join(EX, "fig4_facing_pair.acl")).read()
    i = src.index("param gap")
    (tmp_path / "a.acl").write_text(src[:i] + "param alpha = 174.5 nN*um^2/V^2\n" + src[i:])
    p = eq3_alpha_param(load(str(tmp_path / "a.acl")))
    assert p is not None and p.value == pytest.approx(174.5e-21)
    (tmp_path / "b.acl").write_text(src[:i] + "param alpha = 1\n" + src[i:])
    assert eq3_alpha_param(load(str(tmp_path / "b.acl"))) is None

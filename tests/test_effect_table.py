"""The one table of effects (acl.physics.effect_table.EFFECT_TABLE) and the Bjerknes pair law's shape."""
from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

import acl
from acl.physics.effect_table import EFFECT_TABLE
from acl.physics.effects import bjerknes_gap_factor

ROOT = Path(__file__).resolve().parents[1]


def test_every_stage_reads_the_one_table():
    from acl.analysis import effects as AE
    from acl.design import core
    from acl.fit.effects import EFFECTS as FIT
    from acl.sweep import evaluate as SE

    assert core.EFFECTS == tuple(EFFECT_TABLE)
    assert set(AE.NULLS) == set(EFFECT_TABLE) and set(AE.WHERE) | set(AE.STATIC_NOTES) == set(EFFECT_TABLE)
    assert SE.STATIC_EFFECTS == set(AE.STATIC_NOTES) == {"offset_drift", "bubble_shrinkage"}
    from acl.fit.effects import ANALYSIS_NAME

    for eid, eff in FIT.items():          # the fit's search library: effects and units of the table
        for p in eff.params:              # (a fitted coordinate the table holds under another effect: ANALYSIS_NAME)
            e, k = ANALYSIS_NAME.get((eid, p.name), (eid, p.name))
            units = {c.name: c.unit for c in EFFECT_TABLE[e].coefficients}
            assert units[k] == p.unit, (eid, p.name)
    for (e, k), rng in core.EFFECT_RANGES.items():   # a coefficient at its null value lies inside its range
        null = next(c.null for c in EFFECT_TABLE[e].coefficients if c.name == k)
        assert math.isnan(null) or rng.lo <= null <= rng.hi, (e, k)


def test_no_other_list_of_effects_in_the_package():
    """A literal naming three or more effects anywhere in acl/ outside the table is a second table."""
    names = "|".join(EFFECT_TABLE)
    pat = re.compile(rf"[\"']({names})[\"']")
    for path in (ROOT / "acl").rglob("*.py"):
        if path.as_posix().endswith("acl/physics/effect_table.py"):
            continue
        for i, line in enumerate(path.read_text().splitlines(), 1):
            assert len(set(pat.findall(line))) < 3, f"{path.relative_to(ROOT)}:{i}: {line.strip()}"


def test_gap_factor_closed_form():
    assert bjerknes_gap_factor(20e-6, 40e-6, 0.5) == pytest.approx(math.sqrt(2.0), rel=1e-12)
    assert bjerknes_gap_factor(40e-6, 40e-6, 3.0) == pytest.approx(1.0, rel=1e-12)


SRC = (ROOT / "examples" / "fig4_facing_pair.acl").read_text()


def _attraction(gap_um, effect=""):
    text = re.sub(r"(?ms)^effect bjerknes_scale \{.*?^\}\n", "", SRC).replace("import stdlib.transducers",
                                                                      "import stdlib.transducers\n" + effect)
    d = acl.loads(text, filename=str(ROOT / "examples" / "x.acl"), overrides={"gap": f"{gap_um} um"})
    return [p for p in acl.analyze(d, snap_in=False).as_dict()["pairs"] if p["frequency_hz"] == 125e3][0]["force_n"]


def test_shape_applies_in_the_force_engine():
    """At rest, factor (gap_ref/d)^n scales the Bjerknes attraction of the pair exactly (distance = the gap)."""
    for gap in (20, 60):
        base = _attraction(gap)
        got = _attraction(gap, "effect bjerknes_scale { factor = 1.5, gap_exponent = 0.8, gap_ref = 40 um }")
        assert got / base == pytest.approx(1.5 * (40 / gap) ** 0.8, rel=1e-9)

"""`acl sweep` names every column it leaves out, and why (issue 23).

A calibrated design (`acl fit --calibrated`, with a declared `stiffness_scale` effect) lost its deflection
and lint columns from the sweep table without a word; the uncalibrated design had them.
"""
from __future__ import annotations

import os

from acl import load
from acl.sweep.driver import left_out

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "samples")


def test_a_design_with_effects_names_the_columns_it_lacks():
    """Every effect is batched now: the calibrated cantilever lacks only what the design without its effect lacks
    (deflections without a drive, said so), and nothing once a drive is named."""
    notes = left_out(load(os.path.join(DATA, "fit_cantilever.calibrated.acl")))
    text = "\n".join(notes)
    assert "stiffness_scale" not in text and "effects" not in text
    assert "tip_deflection: deflections need a drive" in text
    with_at = "\n".join(left_out(load(os.path.join(DATA, "fit_cantilever.calibrated.acl")), "125 kHz @ 2 V"))
    assert with_at == ""
    assert "switching_force" not in text          # no latch: nothing of a latch to leave out
    assert "snap_in" not in text                  # one capsule: no pair


def test_an_effect_the_batch_would_not_model_is_named(monkeypatch):
    """The naming path stays for an effect added to the table later (stood for by stiffness_scale taken out of
    BATCHED_EFFECTS): the model-form columns and the program lint rules are named with the effect."""
    from acl.sweep import columns

    monkeypatch.setattr(columns, "BATCHED_EFFECTS", columns.BATCHED_EFFECTS - {"stiffness_scale"})
    text = "\n".join(left_out(load(os.path.join(DATA, "fit_cantilever.calibrated.acl")), "125 kHz @ 2 V"))
    assert "model_form" in text and "stiffness_scale" in text


def test_the_same_design_without_effects_lacks_nothing_for_that_reason():
    notes = left_out(load(os.path.join(DATA, "fit_cantilever.acl")))
    assert not any("effects" in n for n in notes), notes


def test_the_note_reaches_the_table(tmp_path, capsys):
    from acl.cli import main

    rc = main(["sweep", os.path.join(DATA, "fit_cantilever.calibrated.acl"), "--samples", "4",
               "-o", str(tmp_path / "t.csv")])
    out = capsys.readouterr()
    assert rc == 0, out.err
    assert "columns not computed: tip_deflection" in " ".join((out.out + out.err).split())


EXAMPLES = os.path.join(os.path.dirname(os.path.abspath(DATA)), "examples")


def _designs():
    import glob

    ex = EXAMPLES    # the examples and their first-principles versions; of the sample designs, those that stand alone
    return sorted(glob.glob(os.path.join(ex, "*.acl")) + glob.glob(os.path.join(ex, "first_principles", "*.acl"))
                  + glob.glob(os.path.join(DATA, "sweep_*.acl")) + glob.glob(os.path.join(DATA, "fit_*.acl"))
                  + [os.path.join(DATA, n) for n in ("gripper_rigid_truss.acl", "latch_deflect.acl", "latch_path.acl")])


def _could_have(d) -> list[str]:
    """Every column the sweep's families name for design ``d`` at a drive (acl.sweep.columns.QUANTITIES), built
    from the design alone: modes, pairs at the program tones, latches, each mechanism element's deflection,
    requires, model form, lint rules."""
    from acl.analysis.report import program_frequencies, step_drives
    from acl.design import model as M
    from acl.sweep.columns import LINT_RULES, _elements, _fkey, _ident, _pairs

    out = [f"{k}_{_ident(c.name)}_{i}" + ("_hz" if k == "resonance" else "") for c in d.capsules
           for i in range(1, len(c.orifices) + 1) for k in ("resonance", "q")]
    for f in program_frequencies(d) or []:
        for a, b in _pairs(d):
            t = f"{_ident(a)}_{_ident(b)}_{_fkey(f)}"
            out += [f"force_{t}_n", f"attract_{t}", f"phase_{t}_deg", f"critical_distance_{t}_m", f"snap_in_{t}_v"]
    for lt in d.latches:
        k = _ident(lt.name)
        out += [f"switching_force_{k}_n", f"release_force_{k}_n", f"bistable_{k}"]
        out += [f"margin_{k}_{_ident(p.name)}_{i + 1}" for p, i, _s, _d in step_drives(d)]
    if any((d.mount_of(c.name) or M.Fix(capsule="", span=c.span)).kind == "mount" for c in d.capsules):
        out += [f"{'tip_deflection' if kind == 'beam' else 'deflection'}_{_ident(n)}_m" for n, kind in _elements(d)]
        out.append("equilibrium_ok")
    out += [f"require_{i}_{k}" for i in range(1, len(d.requires) + 1) for k in ("value", "pass")]
    out += ["requires_pass"] * bool(d.requires) + ["model_form_rel", "model_form_uncertain"]
    if len(d.capsules) >= 2 and d.effect("bjerknes_scale") is None:     # a first-principles pair force's spread
        out += ["model_form_pair_uncertain"] + ["model_form_pair_median_pass"] * any(
            r.kind in ("margin", "gap") for r in d.requires)
    return out + [f"lint_{c}_pass" for c in LINT_RULES]


def test_every_column_is_given_or_named_with_its_reason():
    """Issue 23 item 2 on every example and test design (springs, trusses, latches, groups, effects): each column
    the design could have is in the table or left out under a named reason."""
    from acl.design.resolve import load_design
    from acl.sweep.columns import supported

    designs = _designs()
    assert len(designs) >= 30
    kinds = set()
    for path in designs:
        d = load_design(path)
        kinds |= {k for k, v in (("spring", d.springs), ("truss", d.trusses), ("latch", d.latches),
                                 ("effects", d.effects), ("group", len(d.capsules) >= 3)) if v}
        names, missing = supported(d, "125 kHz @ 2 V")
        unnamed = [q for q in _could_have(d) if q not in names and not any(
            q.startswith(k) and (k.endswith("_") or q[len(k):len(k) + 1] in ("", "_")) for k in missing)]
        assert not unnamed, f"{os.path.basename(path)}: columns absent without a reason: {unnamed}"
        assert all(len(why) > 20 for why in missing.values())
    assert kinds == {"spring", "truss", "latch", "effects", "group"}


def test_every_physical_effect_of_the_table_has_its_place_in_the_batched_sweep():
    """The one table of effects (acl.physics.effect_table) names where the batched sweep applies each effect; every
    effect that changes a static prediction has one (the two static ones, offset_drift and bubble_shrinkage, do not
    need one)."""
    from acl.physics.effect_table import EFFECT_TABLE
    from acl.sweep import acoustic_state
    from acl.sweep.columns import BATCHED_EFFECTS

    physical = {e.name for e in EFFECT_TABLE.values() if not e.static_note}
    assert BATCHED_EFFECTS == physical and len(physical) == 9
    for e in EFFECT_TABLE.values():
        if e.sweep:
            method = e.sweep.split()[0].rstrip(";").split(".")[1]
            assert hasattr(acoustic_state.PointAcoustics, method), (e.name, e.sweep)

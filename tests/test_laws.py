"""Every physical law once (issue 23): the list of laws is read from acl/physics (tests/laws.py); the page
docs/explanation/laws.md must show exactly that list, and no source may be implemented by two functions
(one that calls the other only uses it) outside the exceptions below, each with its reason.  The golden-section
search is written once (acl.physics.roots); its other copies are listed and may only go away.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
import laws as L  # noqa: E402

# source -> (the functions allowed to implement it side by side, why).  The list only shrinks: an entry whose
# functions no longer all implement the source fails test_no_stale_exception.
EXCEPTIONS: dict[str, tuple[frozenset, str]] = {
    "Kinsler et al.": (frozenset({"acl.physics.coupling.coupled_volumes", "acl.physics.coupling.mutual_resistance",
                                  "acl.physics.coupling.coupled_mode_shapes",
                                  "acl.physics.resonance.radiation_resistance",
                                  "acl.physics.effects.transducer_resonance"}),
                       "five laws of one textbook: the mutual radiation impedance (coupled response), the mutual "
                       "radiation mass of interface pairs (the coupled modes), their mutual radiation resistance (the "
                       "coupled modes' Q), a monopole's radiation resistance (the capsule's Q) and the transducer's "
                       "driven oscillator"),
    "paper Eq. 1": (frozenset({"acl.physics.beams.eq1_profile_deflection", "acl.physics.beams.eq1_compliance",
                               "acl.physics.beams.eq1_small_force_stiffness", "acl.physics.effects.elastica_blend"}),
                    "beams.eq1_compliance / eq1_small_force_stiffness are the closed-form derivative of "
                    "eq1_profile_deflection's uniform case and its P -> 0 limit (tests/test_physics_beams.py checks "
                    "them against eq1_deflection; as 1/eq1_compliance(0) the limit rounds differently and moves the "
                    "README compile's plan by 3e-12); effects.elastica_blend blends deflections it is given"),
    "Suppl. Eq. 2.5": (frozenset({"acl.physics.beams.eq1_slope", "acl.physics.beams.flexible_part_stiffness"}),
                       "two quantities of one equation: the rigid segment's rotation and the flexible part's stiffness"),
    "paper Fig. 2e": (frozenset({"acl.physics.effects.saturation", "acl.physics.transducer.drive_pressure"}),
                      "the drive's linear part (transducer) and its declared saturation (effects)"),
    "paper Eq. 3": (frozenset({"acl.physics.forces.pair_law_force", "acl.physics.forces.critical_distance"}),
                    "the reduced pair law and its zero in closed form"),
    "Hooke's law": (frozenset({"acl.physics.springs.in_series", "acl.physics.springs.in_parallel",
                               "acl.physics.springs.spring_force"}),
                    "a linear spring's force and the two rules that combine springs"),
}

# Golden-section loops outside acl.physics.roots (the constant (sqrt 5 - 1)/2 written out), by file: none left (the
# sweep's and physics/batch.py's call acl.physics.roots.golden_max); a new one fails the test below.
GOLDEN_COPIES: set[str] = set()
_GOLDEN = re.compile(r"sqrt\(5(\.0?)?\)\s*-\s*1")


def test_primary_source_reads_the_citation_styles_of_the_docstrings():
    assert L.primary_source("Thrust (Stuart, J. Fluid Mech. 24, 673 (1966); Riley 2001)") == "Stuart 1966"
    assert L.primary_source("Load-point deflection, paper Eq. (1) (= Suppl. Eq. 2.7).") == "paper Eq. 1"
    assert L.primary_source("Drag (laminar round jet, Schlichting, Boundary-Layer Theory)") == "Schlichting"
    assert L.primary_source("Exact M (Lamb, Hydrodynamics §102/§329)") == "Lamb"
    assert L.primary_source("Coupled modes (Kinsler et al. ch. 7/8)") == "Kinsler et al."
    assert L.primary_source("Index of the first value within a tolerance of the maximum") is None


def test_the_page_lists_every_law_of_the_code():
    expected = L.render(L.collect())
    page = L.PAGE.read_text() if L.PAGE.exists() else ""
    assert page == expected, "docs/explanation/laws.md is out of date: run `python tests/laws.py --update`"


def test_the_page_is_in_the_docs_navigation():
    assert "explanation/laws.md" in (L.ROOT / "mkdocs.yml").read_text()


def test_the_force_engine_laws_are_found_and_implemented_once():
    laws = {x.qualname: x for x in L.collect()}
    for fn, src in (("acl.physics.forces.thrust_magnitude", "Stuart 1966"),
                    ("acl.physics.forces.bjerknes_from_rates", "Crum 1975"),
                    ("acl.physics.forces.jet_drag", "Schlichting")):
        assert laws[fn].source == src and laws[fn].uses is None
    implementers = {s: [q for q, x in laws.items() if x.source == s and x.uses is None]
                    for s in ("Stuart 1966", "Crum 1975", "Schlichting")}
    assert implementers == {"Stuart 1966": ["acl.physics.forces.thrust_magnitude"],
                            "Crum 1975": ["acl.physics.forces.bjerknes_from_rates"],
                            "Schlichting": ["acl.physics.forces.jet_drag"]}


def test_the_elastica_and_eq1_are_implemented_once():
    # issue 23 item 1: one elastica solver and one Eq. (1); every other cantilever function uses them (an import
    # alias, ``from acl.physics.beams import eq1_force as _eq1_force``, counts as a use).
    laws = {x.qualname: x for x in L.collect()}
    assert [q for q, x in laws.items() if x.source == "Bisshopp & Drucker 1945" and x.uses is None] == \
        ["acl.physics.beams.elastica_tip"]
    for fn in ("elastica", "elastica_force", "elastica_table", "elastica_deflection", "eq1_validity_limit"):
        assert laws[f"acl.physics.beams.{fn}"].uses is not None, fn
    assert laws["acl.physics.beams.eq1_deflection"].uses == "acl.physics.beams.eq1_profile_deflection"
    assert laws["acl.physics.batch.eq1_force"].uses == "acl.physics.beams.eq1_force"


def test_no_law_is_implemented_twice():
    bad = {}
    for src, fns in L.duplicates(L.collect()).items():
        allowed = EXCEPTIONS.get(src, (frozenset(), ""))[0]
        extra = sorted(set(fns) - allowed)
        if extra:
            bad[src] = extra
    assert not bad, f"a second implementation of a law (call the one function instead, or list it with a reason): {bad}"


def test_no_stale_exception():
    dup = L.duplicates(L.collect())
    stale = {src: sorted(fns - set(dup.get(src, ()))) for src, (fns, _) in EXCEPTIONS.items()
             if fns - set(dup.get(src, ()))}
    assert not stale, f"exceptions that no longer occur (remove them from EXCEPTIONS): {stale}"


def test_golden_section_is_written_once():
    found = {str(p.relative_to(L.ROOT)) for p in (L.ROOT / "acl").rglob("*.py")
             if p.name != "roots.py" and _GOLDEN.search(p.read_text())}
    assert found <= GOLDEN_COPIES, f"a new golden-section loop: call acl.physics.roots.golden_max: {found - GOLDEN_COPIES}"
    assert found == GOLDEN_COPIES, f"copies gone (remove them from GOLDEN_COPIES): {GOLDEN_COPIES - found}"


@pytest.mark.parametrize("src", sorted(EXCEPTIONS))
def test_every_exception_has_a_reason(src):
    assert len(EXCEPTIONS[src][1]) > 20

"""The stdlib: every module imports by name from any directory, and its numbers match the paper."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

import acl
from acl.design.modules import stdlib_root

MODULES = sorted(p.stem for p in Path(stdlib_root()).glob("*.acl"))
UM3 = 1e-18


def _design(tmp_path, text: str):
    f = tmp_path / "probe.acl"
    f.write_text(text)
    return acl.load(str(f))


def test_the_stdlib_ships_its_five_modules():
    assert {"media", "materials", "capsules", "beams", "transducers"} <= set(MODULES)


@pytest.mark.parametrize("module", MODULES)
def test_module_imports_by_name_from_an_unrelated_directory(tmp_path, monkeypatch, module):
    monkeypatch.chdir(tmp_path)
    design = _design(tmp_path, f"import stdlib.{module}\nparam x = 1\n")
    assert design.params[0].name == "x"


@pytest.mark.parametrize("ref, kind", [
    ("media.water", "medium"), ("media.pbs", "medium"), ("media.air", "medium"),
    ("materials.tpeta", "material"), ("capsules.design1", "capsule"), ("capsules.design2", "capsule"),
    ("capsules.design3", "capsule"), ("capsules.prism3", "capsule"), ("capsules.large25", "capsule"),
    ("capsules.small17", "capsule"), ("beams.cantilever50", "beam"),
    ("transducers.contact_piezo", "transducer"), ("transducers.immersion", "transducer"),
])
def test_named_declaration_exists_with_its_kind(tmp_path, ref, kind):
    module, _ = ref.split(".")
    body = "{ center = (0, 0, 100 um) }\nfix probe" if kind == "capsule" else "{ }"
    _design(tmp_path, f"import stdlib.{module}\n{kind} probe like {ref} {body}\n")


def _capsule(tmp_path, name: str):
    d = _design(tmp_path, f"import stdlib.capsules\ncapsule c like capsules.{name} {{ center = (0, 0, 100 um) }}\nfix c\n")
    return d.capsule("c")


@pytest.mark.parametrize("name, volume_um3, radius_um", [
    ("design1", 6.51e4, 10), ("design2", 1.12e5, 13), ("design3", 1.13e5, 7.75),
])
def test_capsule_designs_match_table_s1(tmp_path, name, volume_um3, radius_um):
    c = _capsule(tmp_path, name)
    assert c.cavity.volume / UM3 == pytest.approx(volume_um3, rel=0.005)
    assert c.orifices[0].radius == pytest.approx(radius_um * 1e-6)


def test_prism3_has_three_orifices_on_three_faces(tmp_path):
    c = _capsule(tmp_path, "prism3")
    assert [o.radius * 1e6 for o in c.orifices] == pytest.approx([15, 9.5, 7.5])
    normals = [o.normal for o in c.orifices]
    for i in range(3):
        for j in range(i + 1, 3):
            cos = sum(a * b for a, b in zip(normals[i], normals[j]))
            assert math.degrees(math.acos(cos)) == pytest.approx(120)


def test_cantilever50_is_50_um_by_2_um_tpeta(tmp_path):
    d = _design(tmp_path, "import stdlib.beams\nbeam b like beams.cantilever50 { }\n")
    b = d.beam("b")
    assert (b.length, b.section.diameter, b.youngs_modulus) == pytest.approx((50e-6, 2e-6, 13e6))


def test_importing_one_declaration_binds_its_name(tmp_path):
    d = _design(tmp_path, "import stdlib.media.pbs\nuse medium pbs\n")
    assert d.medium.density == pytest.approx(1005)


def test_alias_namespaces_a_module(tmp_path):
    d = _design(tmp_path, "import stdlib.media as m\nuse medium m.water\n")
    assert d.medium.density == pytest.approx(998)


def test_transducer_bands_cover_every_excitation_frequency_of_the_paper(tmp_path):
    for name in ("contact_piezo", "immersion"):
        d = _design(tmp_path, f"import stdlib.transducers\nuse transducer transducers.{name}\n")
        lo, hi = d.transducer.band
        assert lo <= 40e3 and hi >= 170e3   # 40..160 kHz sweep (Fig. S4a), 85/125/170 kHz (Table S1)

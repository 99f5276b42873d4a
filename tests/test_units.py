"""Units: the shipped table agrees with pint; unknown units are diagnosed; the cache is used."""
from __future__ import annotations

import pytest

from acl._unit_table import TABLE
from acl.units import UnitError, parse_unit, parse_unit_with_pint


@pytest.mark.parametrize("unit", sorted(TABLE))
def test_shipped_unit_table_agrees_with_pint(unit):
    factor, dims = parse_unit_with_pint(unit)
    assert TABLE[unit][1] == dims
    assert TABLE[unit][0] == pytest.approx(factor, rel=1e-12)


def test_rare_unit_goes_through_pint_and_is_cached(tmp_path, monkeypatch):
    import acl.units as U

    monkeypatch.setenv("ACL_CACHE_DIR", str(tmp_path))
    U._disk_cache.cache_clear()
    U.parse_unit.cache_clear()
    assert "furlong/fortnight" not in TABLE
    f, d = parse_unit("furlong/fortnight")
    assert d == (1, 0, -1, 0, 0, 0, 0) and f == pytest.approx(201.168 / 1209600, rel=1e-5)
    assert not (tmp_path / "units-v2.json").exists()        # saved once, when the process ends
    U.flush_unit_cache()
    assert (tmp_path / "units-v2.json").exists()
    U._disk_cache.cache_clear()
    assert "furlong/fortnight" in U._disk_cache()
    U._disk_cache.cache_clear()
    U.parse_unit.cache_clear()


def test_unknown_unit_raises_with_hint():
    with pytest.raises(UnitError) as e:
        parse_unit("blorp")
    assert "blorp" in str(e.value) and e.value.hint


def test_corrupt_cache_is_ignored(tmp_path, monkeypatch):
    import acl.units as U

    monkeypatch.setenv("ACL_CACHE_DIR", str(tmp_path))
    (tmp_path / "units-v2.json").write_text("{not json")
    U._disk_cache.cache_clear()
    assert U._disk_cache() == {}
    U._disk_cache.cache_clear()

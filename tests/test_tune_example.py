"""The Fig. 3 robust-radii example and `require separation(m)`: the language form, the scalar
analysis, the batched evaluation and acl tune's pass/fail agree point by point."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import acl
from acl.diagnostics import DiagnosticError

ROOT = Path(__file__).resolve().parents[1]
FIG3 = ROOT / "examples" / "fig3_robust_radii.acl"


def test_separation_of_one_capsule_is_its_closest_adjacent_modes():
    from acl.analysis.acoustics import capsule_modes

    d = acl.load(str(FIG3))
    fs = sorted(m.frequency_hz for m in capsule_modes(d, d.capsule("m")))
    rep = acl.analyze(str(FIG3)) if hasattr(acl, "analyze") else None
    value = min(b - a for a, b in zip(fs, fs[1:]))
    assert len(fs) == 3 and value == pytest.approx(30.37e3, abs=0.05e3)     # drawn radii: 0.4 kHz to spare
    if rep is not None:
        req = next(r for r in rep.requires if r["text"] == "require separation(m) >= 30 kHz")
        assert req["value"] == pytest.approx(value) and req["ok"]


@pytest.mark.parametrize("call", ["separation()", "separation(m, m, m)"])
def test_separation_takes_one_or_two_capsules(tmp_path, call):
    text = FIG3.read_text().replace("require separation(m) >= 30 kHz", f"require {call} >= 30 kHz")
    p = tmp_path / "d.acl"
    p.write_text(text)
    with pytest.raises(DiagnosticError) as exc:
        acl.load(str(p), search_paths=[str(ROOT / "examples")])
    assert any(d.code == "E304" and "separation(capsule)" in d.message for d in exc.value.diagnostics)


def test_tune_pass_fail_equals_the_scalar_analysis_point_by_point():
    from acl.analysis.acoustics import capsule_modes
    from acl.sweep.tune import passing, prepare

    p = prepare(str(FIG3), samples=40, validate=40, seed=5)
    x = np.array([f.start for f in p.free])
    pts = p.points(x, 1)
    batched = passing(p.margins(x, 1))
    scalar = []
    for i in range(len(batched)):
        d = acl.load(str(FIG3), overrides={n: f"{float(pts[n][i])!r} m" for n in ("r1", "r2", "r3")})
        fs = sorted(m.frequency_hz for m in capsule_modes(d, d.capsule("m")))
        ok = len(fs) == 3 and min(np.diff(fs)) >= 30e3 and all(40e3 <= f <= 200e3 for f in fs)
        scalar.append(ok)
    assert 0 < sum(scalar) < len(scalar)                  # the sample straddles the requirement
    assert batched.tolist() == scalar


def test_prints_beyond_a_free_range_are_devices_not_invalid_points():
    """`free in lo .. hi` bounds the search; a device printed at the upper bound deviates above it."""
    from acl.sweep.tune import prepare

    p = prepare(str(FIG3), samples=400, validate=400, seed=2)
    at_bounds = np.array([16e-6, 8e-6, 10.4e-6])                  # r1 at its upper, r2 at its lower bound
    pts = p.points(at_bounds, 1)
    assert (pts["r1"] > 16e-6).sum() > 100 and (pts["r2"] < 8e-6).sum() > 100
    assert not np.isnan(p.margins(at_bounds, 1)).any()


def test_a_require_bound_that_follows_a_free_parameter_is_moved_with_it(tmp_path):
    """`in f0 - 4 kHz .. f0 + 4 kHz` with f0 free: the bounds move per trial (never the nominal ones)."""
    from acl.sweep.tune import prepare, tune

    text = FIG3.read_text()
    text = text.replace("free in 8 um .. 16 um", "").replace("free in 6 um .. 12 um", "")
    text = text.replace("require separation(m) >= 30 kHz",
                        "param f0 = 100 kHz free in 60 kHz .. 140 kHz\n"
                        "require resonance(m, mode = 1) in f0 - 4 kHz .. f0 + 4 kHz")
    d = tmp_path / "fig3_f0.acl"
    d.write_text(text)
    p = prepare(str(d), samples=300, seed=1)
    assert [f.name for f in p.free] == ["f0"]
    out = tune(p, max_evals=40)
    assert out.before.value == 0.0 and out.after.value > 0.95
    assert abs(out.chosen[0] - 90.5e3) < 2e3                       # centred on the mode (about 90.5 kHz)

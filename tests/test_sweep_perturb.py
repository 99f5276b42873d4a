"""Resolve once, perturb the SI arrays: every field of every point equals a full re-resolution."""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import acl
from acl.diagnostics import DiagnosticError
from acl.sweep.perturb import SweepWarning, field_batch, field_map, flatten, materialize
from acl.sweep.sample import chunk_points
from acl.sweep.spec import build_spec

ROOT = Path(__file__).resolve().parents[1]
CANTILEVER = ROOT / "samples" / "sweep_cantilever.acl"
PAIR = ROOT / "examples" / "fig4_facing_pair.acl"


def _same_fields(a, b, rtol=1e-12):
    fa, fb = flatten(a), flatten(b)
    assert fa.keys() == fb.keys()
    for k in fa:
        assert fa[k] == pytest.approx(fb[k], rel=rtol, abs=1e-300), k


def _compare_with_load(path, design, params, batch, idx, overrides=None):
    """Point by point: a valid point's materialised design equals acl.load with the point's values
    (every float field, to 1e-12), and an invalid point is one acl.load rejects with the same code."""
    for i in idx:
        ov = {**(overrides or {}), **{n: float(v[i]) for n, v in params.items()}}
        try:
            exact = acl.load(str(path), overrides=ov)
        except DiagnosticError as exc:
            assert not batch.valid[i], (i, ov, [d.code for d in exc.diagnostics])
            assert batch.code[i] in {d.code for d in exc.diagnostics}, (i, batch.code[i], [d.code for d in exc.diagnostics])
            continue
        assert batch.valid[i] and batch.code[i] == "", (i, ov, batch.code[i])
        _same_fields(materialize(batch, i), exact)


def test_cantilever_points_equal_full_resolution():
    d = acl.load(str(CANTILEVER))
    s = build_spec(d, ["radius=0.05um..30um:12", "height=5um..60um:5"], ["radius=normal(0, 150 nm)"], 4, seed=2)
    fm = field_map(d, s.names, s.box())
    assert not fm.exact and "capsules.act.cavity.volume" in fm.derived
    assert "capsules.act.center.2" in fm.linear          # the capsule sits on the tip: it moves with its height
    pts = chunk_points(s, 0, s.chunk_size)
    b = field_batch(d, pts, fm)
    assert 0 < b.valid.sum() < b.n                      # the grid crosses invalid sizes
    assert set(np.unique(b.code)) >= {"", "E402"}
    _compare_with_load(CANTILEVER, d, pts, b, range(b.n))


def test_pair_gap_moves_the_capsules_and_overlaps_are_invalid():
    d = acl.load(str(PAIR))
    s = build_spec(d, ["gap=-80um..80um:9", "reach=20um..30um:3"])
    pts = chunk_points(s, 0, s.chunk_size)
    b = field_batch(d, pts)
    assert "E403" in set(b.code) or "E404" in set(b.code) or not b.valid.all()
    _compare_with_load(PAIR, d, pts, b, range(b.n))


def test_materialize_gives_fresh_lookups():
    d = acl.load(str(CANTILEVER))
    b = field_batch(d, {"radius": np.array([9e-6, 11e-6])})
    m = materialize(b, 1)
    assert m.capsule("act").orifices[0].radius == 11e-6
    assert d.capsule("act").orifices[0].radius == acl.load(str(CANTILEVER)).capsule("act").orifices[0].radius   # untouched
    assert b.get("beams.arm.length").tolist() == [d.beam("arm").length] * 2


def test_nonlinear_field_is_resolved_exactly_with_a_warning(tmp_path):
    src = CANTILEVER.read_text().replace("orifice jet { radius = radius,", "orifice jet { radius = radius * radius / 10 um,")
    path = tmp_path / "nonlinear.acl"
    path.write_text(src)
    d = acl.load(str(path))
    vals = np.array([8e-6, 9e-6, 9e-6, 10e-6, 12e-6, 40e-6])
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        b = field_batch(d, {"radius": vals})
    assert any(issubclass(x.category, SweepWarning) and "nonlinear" in str(x.message) for x in w)
    want = vals**2 / 10e-6
    ok = b.valid
    assert np.allclose(b.fields["capsules.act.orifices.jet.radius"][ok], want[ok], rtol=1e-14)
    assert not b.valid[-1] and b.code[-1] == "E402"        # 160 um: does not fit (the resolver's own verdict)
    _compare_with_load(path, d, {"radius": vals}, b, range(len(vals)))


def test_printability_and_positive_sizes_are_codes_not_exceptions():
    d = acl.load(str(CANTILEVER))
    vals = np.array([-1e-6, 0.0, 0.05e-6, 10e-6])
    b = field_batch(d, {"radius": vals})
    assert b.code.tolist() == ["E401", "E401", "E407", ""]
    _compare_with_load(CANTILEVER, d, {"radius": vals}, b, range(4))


def test_free_parameter_outside_its_bounds_is_invalid():
    path = ROOT / "examples" / "fig3_robust_radii.acl"
    d = acl.load(str(path))
    vals = np.array([7e-6, 8e-6, 12e-6, 16.5e-6])        # r1 is `free in 8 um .. 16 um`
    b = field_batch(d, {"r1": vals})
    assert b.code.tolist() == ["E306", "", "", "E306"]
    _compare_with_load(path, d, {"r1": vals}, b, range(4))


def test_affine_expressions_of_two_parameters_match_resolution(tmp_path):
    """Property: for random affine expressions `a * radius + b * height + c`, every point's fields equal acl.load."""
    from hypothesis import given, settings
    from hypothesis import strategies as st

    @settings(max_examples=15, deadline=None, derandomize=True)
    @given(a=st.sampled_from(["0.5", "1", "0.25", "-0.1"]), b=st.sampled_from(["0", "0.1", "-0.05"]),
           c=st.sampled_from(["0 um", "2 um", "3.3 um"]), seed=st.integers(0, 100))
    def check(a, b, c, seed):
        src = CANTILEVER.read_text().replace("orifice jet { radius = radius,",
                                             f"orifice jet {{ radius = {a} * radius + {b} * height + {c},")
        path = tmp_path / f"affine_{abs(hash((a, b, c)))}.acl"
        path.write_text(src)
        try:
            d = acl.load(str(path))
        except DiagnosticError:
            return                                   # the nominal design itself is invalid: nothing to sweep
        s = build_spec(d, None, ["radius=normal(0, 2 um)", "height=normal(0, 4 um)"], 12, seed=seed)
        pts = chunk_points(s, 0, s.chunk_size)
        with warnings.catch_warnings():
            warnings.simplefilter("error", SweepWarning)      # affine: no exact fallback
            b_ = field_batch(d, pts, field_map(d, s.names, s.box()))
        _compare_with_load(path, d, pts, b_, range(b_.n))

    check()


def test_touching_orifices_are_E403_as_acl_check_says():
    """Orifices of the Fig. 4 pair closer than the printable gap (0.2 um) are one bubble: `acl check`
    says E403; the sweep said valid (it checked only the capsule bodies' overlap)."""
    d = acl.load(str(PAIR))
    s = build_spec(d, ["gap=0um,0.1um,0.19um,0.5um,40um"])
    b = field_batch(d, chunk_points(s, 0, s.chunk_size))
    for gap, code in zip(s.axes[0].values, b.code):
        try:
            acl.load(str(PAIR), overrides={"gap": float(gap)})
            want = ""
        except DiagnosticError as exc:
            want = exc.diagnostics[0].code
        assert code == want, gap
    assert list(b.valid) == [False, False, False, True, True]


@pytest.mark.parametrize("example, vary, codes", [
    ("fig3_three_orifice.acl", "vmax=-20V,0V,20V,30V", ["E401", "E401", "", "E502"]),   # limit above the transducer's
    ("fig4h_unequal_pair.acl", "volts=-1.2V,1.2V", ["E401", ""]),                       # negative drive amplitude
    ("fig4h_unequal_pair.acl", "q_declared=-40,0,40", ["E401", "E401", ""]),            # declared Q not positive
    ("fig6_bistable_latch.acl", "vmax=100V,150V", ["", "E502"]),
])
def test_drive_transducer_and_q_points_get_the_code_acl_check_gives(example, vary, codes):
    """These were valid rows (the vectorised checks cover geometry only), though `acl check` refuses them."""
    path = ROOT / "examples" / example
    name, values = vary.split("=")
    t = acl.sweep(str(path), vary={name: values})
    assert list(t["code"]) == codes
    for x, code in zip(t[vary.split("=")[0]], codes):
        try:
            acl.load(str(path), overrides={vary.split("=")[0]: float(x)})
            assert code == ""
        except DiagnosticError as exc:
            assert code in {d.code for d in exc.diagnostics if d.is_error}


def test_a_map_no_check_point_verifies_is_not_trusted_as_affine(tmp_path):
    """A range so wide that no check point resolves (even halved six times towards the nominal) leaves
    the one-step map unverified: a nonlinear field must then be resolved exactly, not linearised."""
    src = CANTILEVER.read_text().replace("orifice jet { radius = radius,", "orifice jet { radius = radius * radius / 10 um,")
    path = tmp_path / "nonlinear.acl"
    path.write_text(src)
    d = acl.load(str(path))
    fmap = field_map(d, ["radius"], box={"radius": (-1e3, 1e3)})
    assert "capsules.act.orifices.jet.radius" in fmap.exact
    assert "capsules.act.orifices.jet.radius" not in fmap.linear
    assert any("no point of the sweep's range resolved" in n for n in fmap.notes)
    vals = np.array([9.5e-6, 10e-6, 10.5e-6])
    b = field_batch(d, {"radius": vals}, fmap=fmap)
    assert np.allclose(b.fields["capsules.act.orifices.jet.radius"], vals**2 / 10e-6, rtol=1e-14)

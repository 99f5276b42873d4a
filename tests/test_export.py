"""`acl export`: every example becomes closed solids that agree with the design the physics used.

For each example the STL and the 3MF are written by the command and read back with trimesh: each part
is a volume (closed, consistently oriented); on the STL, measured independently of acl.export.measure
where it can be (the cavity: its cross-section sliced with manifold3d times its height found by rays),
the cavity volumes and orifice radii agree with `acl show --output-format json` within 0.5 %; a ray
from each orifice centre along its outward normal meets no material within the first wall thickness;
each capsule's centre (in its cavity) is outside the solid and a point in the middle of its wall inside.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
mf = pytest.importorskip("manifold3d")

from acl.cli import main  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("*.acl"))
UM = 1e6


def _load(path, fmt):
    loaded = trimesh.load(str(path), file_type=fmt, force=None)
    if isinstance(loaded, trimesh.Scene):
        return list(loaded.geometry.values())
    return list(loaded.split(only_watertight=False))


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """example name -> (design JSON, STL parts, 3MF parts), each written by `acl export` once."""
    import contextlib
    import io

    out = {}
    folder = tmp_path_factory.mktemp("export")
    for ex in EXAMPLES:
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            assert main(["show", str(ex), "--output-format", "json"]) == 0
        design = json.loads(buf.getvalue())
        parts = {}
        for fmt in ("stl", "3mf"):
            target = folder / f"{ex.stem}.{fmt}"
            with contextlib.redirect_stdout(io.StringIO()):
                assert main(["export", str(ex), "-o", str(target), "-q"]) == 0, ex
            parts[fmt] = _load(target, fmt)
        out[ex.stem] = (design, parts["stl"], parts["3mf"])
    return out


@pytest.mark.parametrize("example", [e.stem for e in EXAMPLES])
def test_every_part_of_every_example_reads_back_as_a_volume(exported, example):
    _, stl, threemf = exported[example]
    assert stl and len(stl) == len(threemf)
    for part in [*stl, *threemf]:
        assert part.is_volume, example
        assert part.volume > 0


def _cavity_volume_by_slice(mesh, capsule) -> float:
    """Cross-section of the cavity (the hole of the wall's ring, sliced between the orifices and the end
    cap) times its height (rays from the centre to both end caps), um^3."""
    cav = capsule["cavity"]
    c = np.array(capsule["center"]) * UM
    ax = np.array(cav["axis"], float)
    u = np.cross(ax, [0.0, 1.0, 0.3])
    u /= np.linalg.norm(u)
    v = np.cross(ax, u)
    rmax = max(o["radius"] for o in capsule["orifices"]) * UM
    hh = cav["height"] * UM / 2
    assert rmax < hh, "an orifice reaching an end cap: no clear slice"
    z = (rmax + hh) / 2
    rot = np.vstack([u, v, ax])
    m = mf.Manifold(mf.Mesh(vert_properties=np.ascontiguousarray(mesh.vertices, np.float32),
                            tri_verts=np.ascontiguousarray(mesh.faces, np.uint32)))
    section = m.transform(np.column_stack([rot, -rot @ c])).slice(z)
    holes = []
    for contour in section.to_polygons():
        p = np.asarray(contour)
        signed = 0.5 * float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))
        inside = _winds_around_origin(p)
        if signed < 0 and inside:       # a hole contour around the axis: the cavity
            holes.append(-signed)
    assert len(holes) == 1, holes
    rays = trimesh.ray.ray_triangle.RayMeshIntersector(mesh)
    height = 0.0
    for d in (ax, -ax):
        loc, idx, _ = rays.intersects_location([c], [d], multiple_hits=False)
        height += float(np.linalg.norm(loc[0] - c))
    return holes[0] * height


def _winds_around_origin(p) -> bool:
    ang = np.arctan2(p[:, 1], p[:, 0])
    turn = np.diff(np.r_[ang, ang[0]])
    turn = (turn + np.pi) % (2 * np.pi) - np.pi
    return abs(turn.sum()) > np.pi


@pytest.mark.parametrize("example", [e.stem for e in EXAMPLES])
def test_cavity_volumes_and_orifice_radii_on_the_mesh_match_the_design(exported, example):
    from acl.design.model import Capsule
    from acl.export.measure import Probe, orifice_radius

    design, stl, _ = exported[example]
    mesh = trimesh.util.concatenate(stl)
    probe = Probe(mesh)
    for cap in design["capsules"]:
        assert cap["cavity"]["shape"] in ("cylinder", "prism")
        vol = _cavity_volume_by_slice(mesh, cap)
        want = cap["cavity"]["volume"] * UM ** 3
        assert abs(vol - want) <= 0.005 * want, (cap["name"], vol, want)
        model = Capsule.model_validate(cap)
        for o in model.orifices:
            r = orifice_radius(probe, model, o)
            assert r is not None and abs(r - o.radius * UM) <= 0.005 * o.radius * UM, (cap["name"], o.name, r)


@pytest.mark.parametrize("example", [e.stem for e in EXAMPLES])
def test_orifices_open_cavities_void_walls_solid(exported, example):
    design, stl, _ = exported[example]
    mesh = trimesh.util.concatenate(stl)
    rays = trimesh.ray.ray_triangle.RayMeshIntersector(mesh)
    for cap in design["capsules"]:
        w = cap["cavity"]["wall"] * UM
        c = np.array(cap["center"]) * UM
        ax = np.array(cap["cavity"]["axis"], float)
        for o in cap["orifices"]:
            n = np.array(o["normal"], float)
            start = np.array(o["center"]) * UM - n * 1e-3
            loc, idx, _ = rays.intersects_location([start], [n], multiple_hits=True)
            near = [float(np.dot(p - start, n)) for p in loc]
            assert all(d > w for d in near), (cap["name"], o["name"], near)
        assert not mesh.contains([c])[0], cap["name"]
        up = not any(np.dot(o["normal"], ax) > 0.5 for o in cap["orifices"])
        side = 1.0 if up else -1.0
        wall = c + side * ax * (cap["cavity"]["height"] * UM / 2 + w / 2)
        assert mesh.contains([wall])[0], cap["name"]


def test_units_scale_the_file_and_3mf_declares_its_unit(tmp_path, capsys):
    import zipfile

    ex = str(ROOT / "examples" / "fig2_vertical_cantilever.acl")
    assert main(["export", ex, "-o", str(tmp_path / "a.3mf"), "-q"]) == 0
    assert main(["export", ex, "-o", str(tmp_path / "b.3mf"), "--unit", "mm", "-q"]) == 0
    a, b = _load(tmp_path / "a.3mf", "3mf"), _load(tmp_path / "b.3mf", "3mf")
    assert np.allclose(a[0].bounds * 1e-3, b[0].bounds, rtol=1e-5)
    model = zipfile.ZipFile(tmp_path / "b.3mf").read("3D/3dmodel.model")
    assert b'unit="millimeter"' in model
    assert b'unit="micron"' in zipfile.ZipFile(tmp_path / "a.3mf").read("3D/3dmodel.model")
    # the beam stands on the substrate: z from the pad (1 um into the glass) to the capsule's top
    assert a[0].bounds[0][2] == pytest.approx(-1.0, abs=1e-4)


def test_obj_and_a_json_report_of_the_measurements(tmp_path, capsys):
    ex = str(ROOT / "examples" / "fig3_three_orifice.acl")
    assert main(["export", ex, "-o", str(tmp_path / "m.obj"), "--output-format", "json"]) == 0
    out = json.loads(capsys.readouterr().out)
    ms = out["files"][0]["measurements"]
    assert {m["quantity"] for m in ms} == {"orifice radius", "cavity volume", "wall thickness", "beam diameter",
                                                "beam free length"}
    assert all(m["ok"] for m in ms)
    assert all(p.is_volume for p in _load(tmp_path / "m.obj", "obj"))


def test_variants_are_named_by_their_values_and_spaced_beyond_coupling(tmp_path, capsys):
    ex = str(ROOT / "examples" / "fig4_facing_pair.acl")
    assert main(["export", ex, "-o", str(tmp_path / "pair.stl"), "--vary", "gap=30um..50um:3", "-q"]) == 0
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["pair-arrangement.json", "pair-array.stl", "pair-gap=30um.stl", "pair-gap=40um.stl", "pair-gap=50um.stl"]
    lay = json.loads((tmp_path / "pair-arrangement.json").read_text())
    a = (3 * 6.509e4 / (4 * math.pi)) ** (1 / 3)          # design1's bubble, um
    assert lay["largest_bubble_radius"] == pytest.approx(a, rel=1e-3)
    offsets = np.array([v["offset"] for v in lay["variants"]])
    # nearest capsules of two variants: at least 50 a apart (the bodies' footprints are disjoint by that much)
    for i in range(3):
        for j in range(i + 1, 3):
            assert np.abs(offsets[i] - offsets[j]).max() >= 50 * a
    gaps = []
    for v in lay["variants"]:
        parts = _load(tmp_path / v["file"], "stl")
        xs = sorted(p.bounds[:, 0].mean() for p in parts)
        gaps.append(xs[1] - xs[0])
    assert gaps == pytest.approx([84.0, 94.0, 104.0], abs=1e-3)    # 54 um + gap between the arm axes
    array = _load(tmp_path / "pair-array.stl", "stl")
    assert len(array) == 6 and all(p.is_volume for p in array)


def test_a_blocked_orifice_is_an_error_and_writes_nothing(tmp_path, capsys):
    design = tmp_path / "blocked.acl"
    design.write_text(
        "import stdlib.beams\nimport stdlib.capsules\n"
        "beam arm like beams.cantilever50 { clamp = (0, 0, 0) }\n"
        "capsule act like capsules.design1 { }\n"
        "mount act on arm.tip\n"
        "beam post like beams.cantilever50 { clamp = (28.2 um, 0, 0), length = 90 um }\n")
    out = tmp_path / "blocked.stl"
    code = main(["export", str(design), "-o", str(out)])
    err = capsys.readouterr()
    assert code == 1, err
    assert "E-EXPORT-GEOMETRY" in err.out + err.err and "act.jet" in err.out + err.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["blocked.acl"]


def test_the_largest_example_exports_in_under_two_seconds():
    import time

    from acl.design.resolve import load_design
    from acl.export import files
    from acl.export.measure import check
    from acl.export.solid import build

    design = load_design(str(ROOT / "examples" / "figS6_flextensional.acl"))
    start = time.perf_counter()
    b = build(design)
    meshes = files.meshes(b.parts)
    data = files.encode(meshes, [p.name for p in b.parts], "stl")
    _, diags = check(design, trimesh.util.concatenate(meshes))
    elapsed = time.perf_counter() - start
    assert data and not diags
    assert elapsed < 2.0, elapsed


def test_a_floating_part_and_parts_that_touch_are_warned(tmp_path, capsys):
    floating = tmp_path / "floating.acl"
    floating.write_text("import stdlib.capsules\ncapsule free like capsules.design1 { center = (0, 0, 60 um) }\n")
    assert main(["export", str(floating), "-o", str(tmp_path / "f.stl")]) == 0
    err = capsys.readouterr().err
    assert "floating.acl:2:1" in err and "W-EXPORT-FLOATING" in err
    touching = tmp_path / "touching.acl"
    touching.write_text(
        "import stdlib.capsules\n"
        "capsule a like capsules.design1 { center = (0, 0, 30 um), orifice jet { radius = 10 um, normal = -x } }\n"
        "capsule b like capsules.design1 { center = (54.1 um, 0, 30 um), orifice jet { radius = 10 um, normal = +y } }\n"
        "fix a\nfix b\n")
    assert main(["export", str(touching), "-o", str(tmp_path / "t.stl")]) == 0
    err = capsys.readouterr().err
    assert "touching.acl:3:1" in err and "W-EXPORT-TOUCH" in err
    apart = tmp_path / "apart.acl"
    apart.write_text(touching.read_text().replace("54.1 um", "54.5 um"))
    assert main(["export", str(apart), "-o", str(tmp_path / "a.stl")]) == 0
    assert "W-EXPORT" not in capsys.readouterr().err


def test_latch_beams_are_measured_on_the_mesh(tmp_path, capsys):
    ex = str(ROOT / "examples" / "fig6_bistable_latch.acl")
    assert main(["export", ex, "-o", str(tmp_path / "l.stl"), "--output-format", "json"]) == 0
    ms = [m for m in json.loads(capsys.readouterr().out)["files"][0]["measurements"] if m["quantity"].startswith("latch")]
    assert len(ms) == 6 and all(m["ok"] for m in ms)
    for m in ms:
        assert abs(m["measured"] - m["declared"]) <= 0.1


SHAPES = """import stdlib.beams
capsule s {
  cavity volume { volume = 6.5e4 um^3, wall = 3 um }
  orifice jet { radius = 8 um, normal = +x }
  orifice up { radius = 5 um, normal = (0, 0.6, 0.8) }
}
capsule c {
  center = (150 um, 0, 60 um)
  cavity cylinder { radius = 20 um, height = 40 um }
  orifice top { radius = 6 um, face = top }
  orifice side { radius = 8 um, normal = -y }
}
capsule p {
  center = (0, 150 um, 60 um)
  cavity prism { side = 50 um, height = 40 um, facing = +y }
  orifice t { radius = 6 um, face = top }
  orifice f2 { radius = 8 um, face = 2 }
}
beam b like beams.cantilever50 { clamp = (0, 0, 0) }
beam h like beams.cantilever50 { clamp = (150 um, -80 um, 60 um), axis = +y, length = 50 um, section = rect(3 um, 2 um) }
mount s on b.tip
fix c
fix p
"""


def test_every_cavity_shape_end_orifices_and_rect_beams(tmp_path, capsys):
    """A cavity given by its volume (a sphere) with an oblique orifice, a cylinder and a prism with
    orifices on their end faces, a horizontal rectangular beam on a post: all measured within tolerance."""
    design = tmp_path / "shapes.acl"
    design.write_text(SHAPES)
    assert main(["export", str(design), "-o", str(tmp_path / "s.3mf"), "--output-format", "json"]) == 0
    out = json.loads(capsys.readouterr().out)
    ms = out["files"][0]["measurements"]
    assert len(ms) == 17 and all(m["ok"] for m in ms), [m for m in ms if not m["ok"]]
    assert not out["diagnostics"]
    parts = _load(tmp_path / "s.3mf", "3mf")
    assert len(parts) == 4 and all(p.is_volume for p in parts)

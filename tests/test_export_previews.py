"""The preview of every example committed in docs/previews/ is what `acl export --preview` renders now.

Each example is exported and rendered again (acl.export.preview, 60 dpi) and compared pixel by pixel
with the committed PNG: the same size, a mean absolute difference below 0.2 % of full scale and at
most 0.1 % of the pixels off by more than 10 % (antialiasing may move a few edge pixels with a
matplotlib release; Fig. 3's module with the robust radii instead of the paper's, orifices of 12.4
instead of 15 um, moves 0.44 % of them, and a changed title 0.14 %).  Regenerate after a change that moves the pictures:

    python tests/test_export_previews.py --update
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("*.acl"))
PREVIEWS = ROOT / "docs" / "previews"
DPI = 60


def render_example(example: Path, png: Path) -> None:
    """The preview `acl export EXAMPLE --preview` draws, titled by the example's name, at :data:`DPI`."""
    sys.path.insert(0, str(ROOT))
    from acl.design.resolve import load_design
    from acl.export import files
    from acl.export.preview import render
    from acl.export.solid import build

    design = load_design(str(example))
    render(files.meshes(build(design).parts), str(png), title=example.name, dpi=DPI)


@pytest.mark.parametrize("example", EXAMPLES, ids=[e.stem for e in EXAMPLES])
def test_committed_preview_is_the_rendered_one(example, tmp_path):
    pytest.importorskip("trimesh")
    pytest.importorskip("manifold3d")
    pytest.importorskip("matplotlib")
    committed = PREVIEWS / f"{example.stem}.png"
    assert committed.is_file(), f"no {committed.relative_to(ROOT)}: run `python tests/test_export_previews.py --update`"
    fresh = tmp_path / "fresh.png"
    render_example(example, fresh)
    assert same_picture(committed, fresh), \
        f"{committed.relative_to(ROOT)} differs from a fresh render: run `python tests/test_export_previews.py --update`"


def same_picture(a_path, b_path) -> bool:
    import matplotlib.image as mpimg
    import numpy as np

    a, b = mpimg.imread(str(a_path)), mpimg.imread(str(b_path))
    if a.shape != b.shape:
        return False
    diff = np.abs(a[..., :3] - b[..., :3])
    return bool(diff.mean() < 0.002 and (diff.max(axis=-1) > 0.1).mean() < 0.001)


def test_the_comparison_tells_close_designs_apart():
    pytest.importorskip("matplotlib")
    assert not same_picture(PREVIEWS / "fig3_three_orifice.png", PREVIEWS / "fig3_robust_radii.png")
    assert not same_picture(PREVIEWS / "fig2_stroke.png", PREVIEWS / "fig2_vertical_cantilever.png")   # the title
    assert same_picture(PREVIEWS / "fig3_three_orifice.png", PREVIEWS / "fig3_three_orifice.png")


if __name__ == "__main__":
    if "--update" not in sys.argv[1:]:
        sys.exit("usage: python tests/test_export_previews.py --update")
    PREVIEWS.mkdir(exist_ok=True)
    for ex in EXAMPLES:
        render_example(ex, PREVIEWS / f"{ex.stem}.png")
        print(f"wrote {(PREVIEWS / f'{ex.stem}.png').relative_to(ROOT)}")

"""Path sampling (acl.design.paths): shapes, even spacing, the stroke font."""
import numpy as np
import pytest

from acl.design.model import PathSpec
from acl.design.paths import GLYPHS, PathError, path_length, sample_path, text_strokes

UM = 1e-6


def test_rectangle_samples_lie_on_its_edges_and_close_the_loop():
    spec = PathSpec(shape="rectangle", width=2 * UM, height=1 * UM, center=(0.5 * UM, 0.0))
    p = sample_path(spec, 101).points
    x, y = p[:, 0] - 0.5 * UM, p[:, 1]
    on_edge = np.isclose(np.abs(x), 1 * UM) | np.isclose(np.abs(y), 0.5 * UM)
    assert on_edge.all()
    assert np.allclose(p[0], p[-1])


def test_samples_are_evenly_spaced_by_arc_length():
    spec = PathSpec(shape="polyline", points=((0, 0), (3 * UM, 0), (3 * UM, 1 * UM)))
    p = sample_path(spec, 41).points
    steps = np.linalg.norm(np.diff(p, axis=0), axis=1)
    arc = 4 * UM / 40
    # every chord equals the arc step except the one that cuts the corner (shorter)
    assert np.sum(~np.isclose(steps, arc, rtol=1e-9)) <= 1
    assert np.all(steps <= arc * (1 + 1e-9))
    assert np.isclose(path_length(spec), 4 * UM)


def test_circle_samples_have_the_radius():
    spec = PathSpec(shape="circle", radius=2 * UM, center=(1 * UM, -1 * UM))
    p = sample_path(spec, 200).points - [1 * UM, -1 * UM]
    r = np.linalg.norm(p, axis=1)
    assert np.allclose(r, 2 * UM, rtol=1e-3)


@pytest.mark.parametrize("ch", list("ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789"))
def test_font_has_every_letter_and_digit_within_the_cell(ch):
    strokes = GLYPHS[ch]
    assert strokes
    pts = np.concatenate(strokes)
    assert pts[:, 0].min() >= 0 and pts[:, 0].max() <= 4
    assert pts[:, 1].min() >= 0 and pts[:, 1].max() <= 6


def test_text_is_centred_and_has_the_cap_height():
    pts = np.concatenate(text_strokes("EPFL", 3 * UM, center=(1 * UM, 2 * UM)))
    assert np.isclose(pts[:, 1].max() - pts[:, 1].min(), 3 * UM)
    assert np.isclose((pts[:, 0].max() + pts[:, 0].min()) / 2, 1 * UM)


def test_text_path_marks_travel_moves_between_strokes_as_not_drawn():
    s = sample_path(PathSpec(shape="text", text="EPFL", height=2 * UM), 2000)
    assert s.drawn.any() and not s.drawn.all()


def test_unknown_glyph_is_a_path_error_naming_the_character():
    with pytest.raises(PathError, match="'#'"):
        sample_path(PathSpec(shape="text", text="A#", height=1 * UM), 10)


def test_lower_case_text_uses_the_upper_case_glyphs():
    a = np.concatenate(text_strokes("epfl", 1 * UM))
    b = np.concatenate(text_strokes("EPFL", 1 * UM))
    assert np.array_equal(a, b)

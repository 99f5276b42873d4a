"""E-SCHED-TONES says why, for a capsule that moves along one line (issue 28).

The Fig. 2 cantilever's capsule has one orifice: every tone pushes it along -x. Told to follow a circle, compile
said "the gain table has 1 usable frequencies; 3 tones are needed" and suggested pinning tones, which cannot help.
It now says the capsule moves along one line and by how much the path leaves it; a path on the line without
`using` keeps the tone count, in the singular, with the direction.
"""
from __future__ import annotations

import numpy as np

from acl.cli import main

STROKE = """extends "{base}"

program circ {{
  follow act along circle(radius = 2 um, center = (-3 um, 0)) in 2 s
}}
program line {{
  follow act along polyline([(0, 0), (-4 um, 0), (0, 0)]) in 2 s
}}
"""


def _design(tmp_path):
    import os
    import shutil

    base = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples", "fig2_vertical_cantilever.acl")
    shutil.copy(base, tmp_path / "fig2_vertical_cantilever.acl")
    f = tmp_path / "one_line.acl"
    f.write_text(STROKE.format(base="fig2_vertical_cantilever.acl"), encoding="utf-8")
    return f


def test_a_circle_for_a_capsule_on_one_line_says_so(tmp_path, capsys):
    f = _design(tmp_path)
    assert main(["compile", str(f), "--program", "circ", "-o", str(tmp_path / "c"), "-q"]) == 1
    err = capsys.readouterr().err
    assert "error[E-SCHED-TONES]" in err and "moves along one line only" in err and "(-1, 0)" in err, err
    assert "leaves that line by up to 2 um" in err and "orifices facing different ways" in err
    assert "usable frequencies" not in err and "Traceback" not in err
    assert f"{f}:4:3" in err                                  # located at the follow step
    assert not (tmp_path / "c" / "schedule.json").exists()


def test_a_path_on_the_line_without_tones_names_one_frequency_in_the_singular(tmp_path, capsys):
    f = _design(tmp_path)
    assert main(["compile", str(f), "--program", "line", "-o", str(tmp_path / "l"), "-q"]) == 1
    err = capsys.readouterr().err
    assert "1 usable frequency (" in err and "moves along (-1, 0) only" in err and "using [" in err, err


def test_one_line_finds_the_direction_and_only_then():
    from acl.schedule.tones import GainTable, one_line

    f = np.linspace(100e3, 150e3, 5)
    g = np.outer([1, 3, 2, 0.5, 0.1], [-0.6, -0.8])
    assert np.allclose(one_line(GainTable(f, g)), [-0.6, -0.8])
    g2 = g.copy()
    g2[2] = [0.3, -0.9]
    assert one_line(GainTable(f, g2)) is None

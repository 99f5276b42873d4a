"""`acl show --plot DIR/` draws into the folder, as `acl analyze --plot DIR` and `acl compile --plot` do
(issue 28, tried as a new user: `acl show examples/fig5a_gripper.acl --plot show/` stopped with "the format is
chosen by the suffix, .png; not 'a file without suffix'" after the README's `--plot figs/`)."""
from __future__ import annotations

import os
import shutil

import pytest

from acl.cli import main

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")


@pytest.fixture
def design(tmp_path):
    pytest.importorskip("matplotlib")
    src = os.path.join(ROOT, "examples", "fig2_vertical_cantilever.acl")
    shutil.copy(src, tmp_path / "fig2_vertical_cantilever.acl")
    return tmp_path / "fig2_vertical_cantilever.acl"


def test_a_new_folder_gets_the_design_named_png(design, tmp_path):
    out = tmp_path / "figs"
    assert main(["show", str(design), "--plot", str(out) + "/", "-q"]) == 0
    png = out / "fig2_vertical_cantilever.png"
    assert png.is_file() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in out.iterdir()] == ["fig2_vertical_cantilever.png"]     # no temporary file left


def test_an_existing_folder_without_slash_and_a_png_path_still_work(design, tmp_path):
    (tmp_path / "there").mkdir()
    assert main(["show", str(design), "--plot", str(tmp_path / "there"), "-q"]) == 0
    assert (tmp_path / "there" / "fig2_vertical_cantilever.png").is_file()
    assert main(["show", str(design), "--plot", str(tmp_path / "x.png"), "-q"]) == 0
    assert (tmp_path / "x.png").is_file()


def test_a_file_where_the_folder_should_be_is_a_located_error(design, tmp_path, capsys):
    (tmp_path / "afile").write_text("keep", encoding="utf-8")
    assert main(["show", str(design), "--plot", str(tmp_path / "afile") + "/", "-q"]) == 2
    err = capsys.readouterr().err
    assert "error[E601]" in err and "<--plot>:1:1" in err and "a file of that name exists" in err, err
    assert (tmp_path / "afile").read_text(encoding="utf-8") == "keep"

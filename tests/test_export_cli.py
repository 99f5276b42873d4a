"""`acl export` and `acl show --plot` refuse every output they cannot make: a located diagnostic,
a non-zero exit, no traceback and no file (nor a temporary one) left behind; a FIFO or a device
named as the output stays what it was."""
from __future__ import annotations

import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("trimesh")
pytest.importorskip("manifold3d")

from acl.cli import main  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
EX = str(ROOT / "examples" / "fig2_vertical_cantilever.acl")


def _run(args, capsys):
    code = main(args)
    out = capsys.readouterr()
    text = out.out + out.err
    assert "Traceback" not in text and "E-INTERNAL" not in text, text
    return code, text


def _only(folder, *names):
    assert sorted(p.name for p in Path(folder).iterdir()) == sorted(names)


def test_unknown_suffix(tmp_path, capsys):
    code, text = _run(["export", EX, "-o", str(tmp_path / "dev.step")], capsys)
    assert code == 2 and "<--output>:1:1" in text and "E-USAGE" in text and ".stl" in text
    _only(tmp_path)


def test_missing_folder_and_a_folder_as_output(tmp_path, capsys):
    code, text = _run(["export", EX, "-o", str(tmp_path / "nowhere" / "dev.stl")], capsys)
    assert code == 2 and "E601" in text and "<--output>:1:1" in text
    code, text = _run(["export", EX, "-o", str(tmp_path)], capsys)
    assert code == 2 and "E601" in text and "folder" in text
    _only(tmp_path)


def test_unwritable_output(tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        if os.access(ro, os.W_OK):                     # root writes anywhere: a kernel file system refuses it
            target = "/proc/acl-export-test.stl"
        else:
            target = str(ro / "dev.stl")
        code, text = _run(["export", EX, "-o", target], capsys)
        assert code == 2 and "E601" in text and "cannot write" in text
        assert not os.path.exists(target)
        assert list(ro.iterdir()) == []
    finally:
        ro.chmod(0o755)


def test_output_naming_the_input(tmp_path, capsys):
    design = tmp_path / "dev.stl"                       # a design under a print file's name
    design.write_text(Path(EX).read_text())
    code, text = _run(["export", str(design), "-o", str(design)], capsys)
    assert code == 2 and "names the input" in text and "<--output>:1:1" in text
    assert design.read_text() == Path(EX).read_text()
    link = tmp_path / "link.stl"                        # through a link too
    real = tmp_path / "d.acl"
    real.write_text(Path(EX).read_text())
    link.symlink_to(real)
    code, text = _run(["export", str(real), "-o", str(link)], capsys)
    assert code == 2 and "names the input" in text
    assert link.is_symlink() and real.read_text() == Path(EX).read_text()


def test_a_fifo_as_output_is_refused_and_stays_a_fifo(tmp_path, capsys):
    fifo = tmp_path / "dev.stl"
    os.mkfifo(fifo)
    code, text = _run(["export", EX, "-o", str(fifo)], capsys)
    assert code == 2 and "E601" in text and "FIFO" in text
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    _only(tmp_path, "dev.stl")


def test_a_device_as_output_is_refused(tmp_path, capsys):
    if not os.path.exists("/dev/null"):
        pytest.skip("no /dev/null")
    link = tmp_path / "null.stl"
    link.symlink_to("/dev/null")
    code, text = _run(["export", EX, "-o", str(link)], capsys)
    assert code == 2 and "E601" in text and "device" in text
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    _only(tmp_path, "null.stl")


def test_bad_preview_and_bad_vary(tmp_path, capsys):
    code, text = _run(["export", EX, "-o", str(tmp_path / "a.stl"), "--preview", str(tmp_path / "a.jpg")], capsys)
    assert code == 2 and "<--preview>:1:1" in text and ".png" in text
    code, text = _run(["export", EX, "-o", str(tmp_path / "a.stl"), "--preview", str(tmp_path / "a.stl")], capsys)
    assert code == 2
    code, text = _run(["export", EX, "-o", str(tmp_path / "a.stl"), "--vary", "nope=1um..2um:3"], capsys)
    assert code == 2 and "E211" in text and "<--vary>" in text
    _only(tmp_path)


def test_bad_unit_is_a_usage_error(tmp_path):
    r = subprocess.run([sys.executable, "-m", "acl", "export", EX, "-o", str(tmp_path / "a.stl"), "--unit", "inch"],
                       capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 2 and "<--unit>:1:1" in r.stderr and "Traceback" not in r.stderr
    _only(tmp_path)


def test_a_design_error_writes_nothing(tmp_path, capsys):
    bad = tmp_path / "bad.acl"
    bad.write_text("capsule c { cavity cylinder { radius = 3 V, height = 2 um } }\n")
    code, text = _run(["export", str(bad), "-o", str(tmp_path / "bad.stl")], capsys)
    assert code == 1 and "bad.acl:1:" in text
    _only(tmp_path, "bad.acl")


def test_without_the_cad_extra_export_stops_before_any_work(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "manifold3d", None)
    code, text = _run(["export", EX, "-o", str(tmp_path / "a.stl")], capsys)
    assert code == 2 and "E-EXPORT-CAD" in text and "acl[cad]" in text
    _only(tmp_path)


def test_export_preview_and_show_plot_write_pngs(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    code, text = _run(["export", EX, "-o", str(tmp_path / "a.stl"), "--preview", str(tmp_path / "a.png")], capsys)
    assert code == 0 and "wrote" in text
    assert (tmp_path / "a.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    code, text = _run(["show", EX, "--plot", str(tmp_path / "d.png")], capsys)
    assert code == 0 and "capsule act" in text          # the tree as before
    assert (tmp_path / "d.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    _only(tmp_path, "a.stl", "a.png", "d.png")


def test_show_plot_bad_outputs(tmp_path, capsys):
    code, text = _run(["show", EX, "--plot", str(tmp_path / "d.svg")], capsys)
    assert code == 2 and "<--plot>:1:1" in text
    fifo = tmp_path / "d.png"
    os.mkfifo(fifo)
    code, text = _run(["show", EX, "--plot", str(fifo)], capsys)
    assert code == 2 and "FIFO" in text and stat.S_ISFIFO(os.stat(fifo).st_mode)
    code, text = _run(["show", EX, "--plot", str(tmp_path / "no" / "d.png")], capsys)
    assert code == 2 and "E601" in text
    _only(tmp_path, "d.png")


def test_an_empty_design_and_a_bad_print_default_are_errors_in_the_design(tmp_path, capsys):
    empty = tmp_path / "empty.acl"
    empty.write_text("import stdlib.media\nuse medium media.pbs\n")
    code, text = _run(["export", str(empty), "-o", str(tmp_path / "e.stl")], capsys)
    assert code == 1 and "E-EXPORT-EMPTY" in text and "empty.acl:1:1" in text
    seg = tmp_path / "seg.acl"
    seg.write_text("import stdlib.capsules\nparam print_segments = 5\n"
                   "capsule c like capsules.design1 { center = (0, 0, 30 um) }\nfix c\n")
    code, text = _run(["export", str(seg), "-o", str(tmp_path / "s.stl")], capsys)
    assert code == 1 and "E-EXPORT-PARAM" in text and "seg.acl:2:1" in text
    _only(tmp_path, "empty.acl", "seg.acl")
    # the design's own value overrides stdlib/printing.acl's
    seg.write_text(seg.read_text().replace("= 5", "= 24"))
    code, text = _run(["export", str(seg), "-o", str(tmp_path / "s.stl"), "--output-format", "json"], capsys)
    assert code == 0
    import json

    assert json.loads(text)["files"][0]["parts"][0]["triangles"] < 600


def test_variants_write_all_or_nothing(tmp_path, capsys):
    pair = str(ROOT / "examples" / "fig4_facing_pair.acl")
    fifo = tmp_path / "pair-gap=40um.stl"               # a name a variant makes
    os.mkfifo(fifo)
    code, text = _run(["export", pair, "-o", str(tmp_path / "pair.stl"), "--vary", "gap=30um..50um:3"], capsys)
    assert code == 2 and "FIFO" in text and stat.S_ISFIFO(os.stat(fifo).st_mode)
    _only(tmp_path, "pair-gap=40um.stl")
    os.unlink(fifo)
    code, text = _run(["export", pair, "-o", str(tmp_path / "pair.stl"), "--vary", "gap=40um,-20um"], capsys)
    assert code == 1 and "E403" in text                 # the second variant's capsules overlap
    _only(tmp_path)


def test_files_respect_the_umask(tmp_path, capsys):
    old = os.umask(0o027)
    try:
        code, _ = _run(["export", EX, "-o", str(tmp_path / "a.3mf"), "--preview", str(tmp_path / "a.png"), "-q"], capsys)
    finally:
        os.umask(old)
    assert code == 0
    for name in ("a.3mf", "a.png"):
        assert stat.S_IMODE(os.stat(tmp_path / name).st_mode) == 0o640, name

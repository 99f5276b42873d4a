"""Folder searches for designs are bounded (issue 11: `acl check /` walked the whole filesystem):
depth, entries examined, kernel filesystems skipped, links to folders not followed (no loops).
A limit reached is E602, located at the folder where the search stopped, exit code 2, no partial
list of designs."""
from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

import acl._files as F
from acl.cli import main
from acl.diagnostics import DiagnosticError

ROOT = Path(__file__).resolve().parents[1]
GOOD = (ROOT / "examples" / "fig2_vertical_cantilever.acl").read_text()
needs_posix = pytest.mark.skipif(sys.platform == "win32", reason="symlinks, /proc")


def test_more_entries_than_the_limit_is_e602_not_a_partial_list(tmp_path, monkeypatch):
    for i in range(30):
        (tmp_path / f"d{i:02d}.acl").write_text(GOOD)
    monkeypatch.setattr(F, "MAX_ENTRIES", 29)
    with pytest.raises(DiagnosticError) as exc:
        F.designs_under(str(tmp_path))
    (d,) = exc.value.diagnostics
    assert d.code == "E602" and "more than 29 entries" in d.message and d.span.file == str(tmp_path)
    monkeypatch.setattr(F, "MAX_ENTRIES", 30)
    assert len(F.designs_under(str(tmp_path))) == 30


def test_folders_nested_deeper_than_the_limit_is_e602_at_the_deepest(tmp_path, monkeypatch):
    monkeypatch.setattr(F, "MAX_DEPTH", 5)
    deep = tmp_path
    for i in range(7):
        deep = deep / f"l{i}"
    deep.mkdir(parents=True)
    (deep / "x.acl").write_text(GOOD)
    with pytest.raises(DiagnosticError) as exc:
        F.designs_under(str(tmp_path))
    (d,) = exc.value.diagnostics
    assert d.code == "E602" and "more than 5 levels" in d.message
    assert d.span.file == str(tmp_path / "l0" / "l1" / "l2" / "l3" / "l4" / "l5")
    monkeypatch.setattr(F, "MAX_DEPTH", 7)
    assert F.designs_under(str(tmp_path)) == [str(deep / "x.acl")]


@needs_posix
def test_link_loops_end_and_stay_inside(tmp_path):
    (tmp_path / "good.acl").write_text(GOOD)
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "more.acl").write_text(GOOD)
    (tmp_path / "sub" / "loop").symlink_to(tmp_path, target_is_directory=True)     # a folder link: not followed
    (tmp_path / "self").symlink_to(tmp_path / "self")                            # a link to itself
    (tmp_path / "a.acl").symlink_to(tmp_path / "b.acl")                          # a.acl -> b.acl -> a.acl
    (tmp_path / "b.acl").symlink_to(tmp_path / "a.acl")
    assert F.designs_under(str(tmp_path)) == [str(tmp_path / "good.acl"), str(tmp_path / "sub" / "more.acl")]


def test_kernel_filesystems_are_never_entered(tmp_path, monkeypatch):
    (tmp_path / "real").mkdir()
    (tmp_path / "real" / "a.acl").write_text(GOOD)
    (tmp_path / "procfs").mkdir()
    (tmp_path / "procfs" / "b.acl").write_text(GOOD)
    monkeypatch.setattr(F, "virtual_mounts", lambda: frozenset({str(tmp_path / "procfs"), "/proc"}))
    assert F.designs_under(str(tmp_path)) == [str(tmp_path / "real" / "a.acl")]
    assert F.designs_under(str(tmp_path / "procfs")) == []


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux /proc")
def test_proc_sys_and_dev_are_known_virtual():
    v = F.virtual_mounts()
    assert {"/proc", "/sys", "/dev"} <= v
    assert F.designs_under("/proc") == [] and F.designs_under("/proc/self") == []


@needs_posix
@pytest.mark.parametrize("command", ["check", "lint", "fmt", "analyze"])
def test_a_command_on_the_root_folder_stops_with_e602_and_never_reads_proc(command, monkeypatch, capsys):
    visited = []
    real_scandir = os.scandir

    def scandir(path):
        visited.append(str(path))
        return real_scandir(path)

    monkeypatch.setattr(F, "MAX_ENTRIES", 3000)
    monkeypatch.setattr(F.os, "scandir", scandir)
    code = main([command, "/"])
    out = capsys.readouterr()
    assert code == 2, out
    assert "E602" in out.err and "search of folder `/` stopped" in out.err and "Traceback" not in out.err
    assert "E-INTERNAL" not in out.err
    assert visited and not [p for p in visited if p.split("/")[1] in ("proc", "sys", "dev")]


def test_e602_in_json_output(tmp_path, monkeypatch, capsys):
    import json

    for i in range(5):
        (tmp_path / f"d{i}.acl").write_text(GOOD)
    monkeypatch.setattr(F, "MAX_ENTRIES", 3)
    assert main(["check", str(tmp_path), "--output-format", "json"]) == 2
    got = json.loads(capsys.readouterr().out)
    (d,) = got["diagnostics"]
    assert d["code"] == "E602" and d["file"] == str(tmp_path) and d["line"] == 1 and d["column"] == 1


def test_the_documented_limits_are_the_code_s():
    for page in ("diagnostics.md", "editor.md"):
        text = (ROOT / "docs" / page).read_text()
        assert f"{F.MAX_ENTRIES:,} entries" in text and f"{F.MAX_DEPTH} levels" in text, page

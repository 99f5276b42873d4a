"""The examples `acl --help` prints run as shown (a newcomer copies them first)."""
from __future__ import annotations

import shlex
from pathlib import Path


from acl.cli import EPILOG, main

ROOT = Path(__file__).resolve().parents[1]


def _examples(command: str) -> list[list[str]]:
    lines = [ln.strip() for ln in EPILOG.split("examples:", 1)[1].split("\n\n", 1)[0].splitlines()]
    return [shlex.split(ln)[1:] for ln in lines if ln.startswith(f"acl {command} ")]


def test_the_help_names_designs_that_exist():
    for command in ("check", "show", "analyze", "compile", "lint", "fmt"):
        for argv in _examples(command):
            for arg in argv:
                if arg.startswith("examples/"):
                    assert (ROOT / arg).exists(), f"`acl {' '.join(argv)}`: no {arg}"


def test_the_help_s_compile_example_compiles(tmp_path, monkeypatch, capsys):
    """It compiled --program rectangle, which `acl compile` refuses without --allow-nonlinear (README, exit 1)."""
    (argv,) = _examples("compile")
    monkeypatch.chdir(ROOT)
    argv = [a if a != "out/" else str(tmp_path / "out") for a in argv]
    code = main([*argv, "-q", "--band-samples", "0"])
    assert code == 0, capsys.readouterr().err

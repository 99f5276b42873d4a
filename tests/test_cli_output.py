"""Command-line output conventions (issue 11): whole lines off a terminal, one machine-output option,
-q/-v everywhere, folders accepted, `acl rule`, files that respect the umask."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FIG4 = "examples/fig4_facing_pair.acl"
FIG4_LEFT = next(i for i, t in enumerate((ROOT / FIG4).read_text().splitlines(), 1) if t.startswith("capsule left"))


def run(*args, cwd=ROOT, env=None):
    environ = {k: v for k, v in os.environ.items() if k != "COLUMNS"}
    environ.update(env or {})
    environ["PYTHONPATH"] = str(ROOT) + os.pathsep + environ.get("PYTHONPATH", "")
    return subprocess.run([sys.executable, "-m", "acl", *args], capture_output=True, text=True,
                          timeout=300, cwd=cwd, env=environ)


# -- piped output is never cut at 80 columns ------------------------------------------------------

def test_analyze_tables_are_not_truncated_when_piped():
    r = run("analyze", FIG4, "--no-snap")
    assert r.returncode == 0, r.stderr
    assert "…" not in r.stdout
    row = next(line for line in r.stdout.splitlines() if "left-right" in line)
    assert "attract" in row and "not computed" in row       # the last column of a 100+ column table
    assert f"{FIG4}:{FIG4_LEFT}" in r.stdout
    assert max(len(line) for line in r.stdout.splitlines()) > 80


def test_check_lines_are_not_wrapped_when_piped(tmp_path):
    deep = tmp_path / ("a_long_folder_name_" * 4) / "designs"
    deep.mkdir(parents=True)
    design = deep / "fig2.acl"
    shutil.copy(ROOT / "examples" / "fig2_vertical_cantilever.acl", design)
    text = design.read_text().replace("import stdlib.media", "import stdlib.media\nparam unused_but_long_name = 3 um")
    design.write_text(text)
    r = run("check", str(design))
    ok = [line for line in r.stderr.splitlines() if line.startswith("ok ")]
    assert len(ok) == 1 and str(design) in ok[0] and "capsule" in ok[0], r.stderr


def test_columns_still_wins_when_set():
    r = run("analyze", FIG4, "--no-snap", env={"COLUMNS": "60"})
    assert max(len(line) for line in r.stdout.splitlines()) <= 60


# -- one machine-output option; the old spellings still work, with a warning ------------------------

def _json(r):
    import json

    assert r.returncode in (0, 1), r.stderr
    return json.loads(r.stdout)


@pytest.mark.parametrize("args", [
    ("check", FIG4), ("show", FIG4), ("analyze", FIG4, "--no-snap"), ("lint", FIG4), ("rule", "ACL201"),
], ids=["check", "show", "analyze", "lint", "rule"])
def test_output_format_json_on_every_command(args):
    doc = _json(run(*args, "--output-format", "json"))
    assert isinstance(doc, (dict, list)) and doc


@pytest.mark.parametrize("args, old", [
    (("check", FIG4), ("--format", "json")),
    (("show", FIG4), ("--json",)),
    (("analyze", FIG4, "--no-snap"), ("--json",)),
    (("lint", FIG4), ("--format", "json")),
], ids=["check --format", "show --json", "analyze --json", "lint --format"])
def test_old_output_spellings_still_work_and_say_they_are_deprecated(args, old):
    new = run(*args, "--output-format", "json")
    r = run(*args, *old)
    assert _json(r) == _json(new)
    assert "deprecated" in r.stderr and "--output-format" in r.stderr
    assert "deprecated" not in run(*args, *old, "-q").stderr


def test_compile_keeps_format_for_waveforms_and_diagnostics_becomes_output_format(tmp_path):
    import json

    r = run("compile", "examples/fig3_three_orifice.acl", "--program", "nope", "-o", str(tmp_path / "o"),
            "--output-format", "json")
    assert r.returncode == 2 and json.loads(r.stdout)["diagnostics"][0]["code"] == "E-COMPILE-PROGRAM"
    r = run("compile", "examples/fig3_three_orifice.acl", "--program", "nope", "-o", str(tmp_path / "o"),
            "--diagnostics", "json")
    assert r.returncode == 2 and json.loads(r.stdout)["diagnostics"] and "deprecated" in r.stderr
    r = run("compile", "examples/fig3_three_orifice.acl", "--program", "rectangle", "--allow-nonlinear", "-o", str(tmp_path / "o"),
            "--format", "mp3")
    assert r.returncode == 2 and "E-COMPILE-FORMAT" in r.stderr


def test_lint_output_formats_include_text_as_full():
    full = run("lint", FIG4, "--output-format", "full")
    text = run("lint", FIG4, "--output-format", "text")
    assert full.stdout == text.stdout and "All checks passed" in full.stdout


# -- -q / -v on every command -----------------------------------------------------------------------

def _commands():
    from acl.cli import COMMANDS

    return list(COMMANDS)


@pytest.mark.parametrize("command", _commands())
def test_every_command_takes_quiet_and_verbose(command):
    from acl.cli import build_parser

    parser = build_parser([command])          # builds the named command in full
    sub = next(a for a in parser._actions if a.dest == "command").choices[command]
    for flag in ("-q", "--quiet", "-v", "--verbose"):
        assert flag in sub._option_string_actions, (command, flag)


def test_quiet_check_prints_only_diagnostics_and_verbose_prints_timing():
    assert run("check", "-q", FIG4).stderr == ""
    assert "ok " in run("check", FIG4).stderr
    assert "after" in run("check", "-v", FIG4).stderr
    r = run("lint", "-q", "--output-format", "concise", FIG4)
    assert r.returncode == 0 and r.stdout == ""


# -- folders are accepted wherever designs are --------------------------------------------------------

def test_check_accepts_folders():
    r = run("check", "examples", "--output-format", "json")
    doc = _json(r)
    assert len(doc["files"]) >= 10 and all(f.endswith(".acl") for f in doc["files"])


@pytest.mark.parametrize("command", ["show", "analyze", "compile", "fit", "synth"])
def test_single_design_commands_accept_a_folder_with_one_design(tmp_path, command):
    one = tmp_path / "one"
    one.mkdir()
    shutil.copy(ROOT / "examples" / "fig2_vertical_cantilever.acl", one / "d.acl")
    if command == "show":
        r = run("show", str(one), "--output-format", "json")
        assert r.returncode == 0 and '"capsules"' in r.stdout, r.stderr
    # several designs: a usage error naming them, whatever the command
    shutil.copy(ROOT / "examples" / "fig4_facing_pair.acl", one / "e.acl")
    extra = {"compile": ["-o", str(tmp_path / "o")], "fit": [str(tmp_path / "data.csv")],
             "synth": ["-o", str(tmp_path / "x.csv")]}.get(command, [])
    r = run(command, str(one), *extra)
    assert r.returncode == 2 and "E-USAGE" in r.stderr and "d.acl" in r.stderr and "e.acl" in r.stderr, r.stderr
    assert not (tmp_path / "o").exists() and not (tmp_path / "x.csv").exists()


# -- acl rule ------------------------------------------------------------------------------------------

def test_rule_prints_the_documented_page():
    r = run("rule", "ACL201")
    assert r.returncode == 0 and "snap-in" in r.stdout and "```acl fails" in r.stdout
    r = run("rule", "e303")
    assert r.returncode == 0 and "incompatible dimensions" in r.stdout


def test_every_lint_rule_has_a_page():
    import json

    from acl.lint import load_rules

    pages = {e["code"]: e for e in json.loads(run("rule", "--all", "--output-format", "json").stdout)}
    for code, rule in load_rules().items():
        assert code in pages and pages[code]["name"] == rule.name and pages[code]["severity"] == rule.severity.value


def test_codes_documented_in_prose_are_found_too():
    r = run("rule", "E-EMIT-RATE")
    assert r.returncode == 0 and "E-EMIT-RATE" in r.stdout and "docs/schedule.md" in r.stdout
    r = run("rule", "E-PLOT")
    assert r.returncode == 0 and "acl[plot]" in r.stdout


def test_unknown_rule_is_a_usage_error_with_a_suggestion():
    r = run("rule", "ACL2011")
    assert r.returncode == 2 and "E-USAGE" in r.stderr and "ACL201" in r.stderr


@pytest.mark.parametrize("args, usage, hint", [
    (["compile", "examples/fig2_stroke.acl", "--programm", "stroke", "-o", "OUT"], "usage: acl compile", "`--program`"),
    (["synth", "examples/fig2_stroke_truth.acl", "--schedulle", "s.json", "-o", "OUT"], "usage: acl synth", "`--schedule`"),
    (["fit", "examples/fig2_stroke.acl", "d.csv", "--xyz"], "usage: acl fit", None),
])
def test_a_mistyped_option_shows_the_command_s_usage_and_the_closest_option(tmp_path, args, usage, hint):
    """argparse reported `unrecognized arguments` with acl's own usage line (`acl [-h] ... COMMAND`);
    now the command's usage, the located E-USAGE, and a did-you-mean for a near miss."""
    out = tmp_path / "out"
    args = [str(out) if a == "OUT" else a for a in args]
    r = run(*args)
    assert r.returncode == 2 and "Traceback" not in r.stderr and not out.exists()
    first = next(a for a in args if a.startswith("--") and a not in ("-o",))
    assert r.stderr.startswith(usage) and f"<{first}>:1:1: error[E-USAGE]: unrecognized arguments: {first}" in r.stderr
    assert (f"did you mean {hint}?" in r.stderr) if hint else "did you mean" not in r.stderr


# -- SARIF: helpUri on every rule, percent-encoded locations, schema-valid ----------------------------

def test_sarif_has_help_uris_and_percent_encoded_locations(tmp_path):
    import json
    from urllib.parse import unquote, urlparse

    folder = tmp_path / "my designs ü#1"
    folder.mkdir()
    design = folder / "pair 100%.acl"
    design.write_text((ROOT / FIG4).read_text().replace("require resonance(left) in 110 kHz .. 135 kHz",
                                                        "require resonance(left) in 10 kHz .. 13 kHz"))
    r = run("lint", str(design), "--output-format", "sarif", cwd=tmp_path)
    assert r.returncode == 1, r.stderr
    doc = json.loads(r.stdout)
    run0 = doc["runs"][0]
    rules = run0["tool"]["driver"]["rules"]
    assert all(urlparse(rule["helpUri"]).scheme == "file" for rule in rules)
    page = next(rule for rule in rules if rule["id"] == "ACL603")["helpUri"]
    assert Path(unquote(urlparse(page).path)).is_file() and page.endswith("#acl603")
    uris = [loc["physicalLocation"]["artifactLocation"]["uri"] for res in run0["results"] for loc in res["locations"]]
    assert uris and all(" " not in u and "#" not in u and u.isascii() for u in uris), uris
    assert {unquote(u) for u in uris} == {"my designs ü#1/pair 100%.acl"}
    schema = next((p for p in (ROOT.parent / "shared" / "schemas" / "sarif-schema-2.1.0.json",
                               Path("/work/shared/schemas/sarif-schema-2.1.0.json")) if p.exists()), None)
    if schema is None:
        pytest.skip("SARIF schema not found in ../shared/schemas")
    jsonschema = pytest.importorskip("jsonschema")
    jsonschema.validate(doc, json.loads(schema.read_text()))


# -- outputs respect the umask -------------------------------------------------------------------------

def _modes(root: Path) -> dict[str, int]:
    out = {str(root): root.stat().st_mode & 0o777} if root.is_dir() else {}
    for p in ([root] if root.is_file() else root.rglob("*")):
        out[str(p)] = p.stat().st_mode & 0o777
    return out


@pytest.mark.parametrize("mask", [0o022, pytest.param(0o027, marks=pytest.mark.studies)])
def test_outputs_respect_the_umask(tmp_path, mask):
    env = {k: v for k, v in os.environ.items() if k != "COLUMNS"}
    env["PYTHONPATH"] = str(ROOT)

    def acl(*args):
        r = subprocess.run([sys.executable, "-m", "acl", *args], capture_output=True, text=True, cwd=ROOT,
                           env=env, timeout=600, preexec_fn=lambda: os.umask(mask))
        assert r.returncode == 0, r.stderr
    fig2 = "examples/fig2_vertical_cantilever.acl"
    acl("compile", "examples/fig3_three_orifice.acl", "--program", "rectangle", "--allow-nonlinear", "-o", str(tmp_path / "out"))
    acl("analyze", FIG4, "--no-snap", "--plot", str(tmp_path / "figs"))
    acl("synth", fig2, "--voltages", "0V..6V:4", "--noise", "0.05um", "-o", str(tmp_path / "data.csv"))
    acl("fit", fig2, str(tmp_path / "data.csv"), "--effects", "none", "--free", "gamma",
        "--report", str(tmp_path / "fit"), "--calibrated", str(tmp_path / "cal.acl"))
    modes = {}
    for name in ("out", "figs", "data.csv", "fit", "cal.acl"):
        modes.update(_modes(tmp_path / name))
    assert len(modes) > 8
    for path, mode in modes.items():
        want = (0o777 if os.path.isdir(path) else 0o666) & ~mask
        assert mode == want, f"{path}: {oct(mode)}, umask {oct(mask)} gives {oct(want)}"


@pytest.mark.parametrize("command", ["check", "show", "analyze", "compile", "lint", "fit", "synth", "rule"])
def test_every_command_with_machine_output_spells_it_output_format(command):
    from acl.cli import build_parser

    parser = build_parser([command])
    sub = next(a for a in parser._actions if a.dest == "command").choices[command]
    action = sub._option_string_actions["--output-format"]
    assert {"text", "json"} <= set(action.choices) or command == "lint" and {"full", "json"} <= set(action.choices)


# -- paths are shown as the user wrote them ------------------------------------------------------
# Diagnostics name the main design as given; a file it extends or imports, the calibrated design's header
# and `acl fit`'s "written to" lines printed absolute paths (/home/.../lib/base.acl), carrying the
# machine's folders into messages, docs and shared files.

def test_a_file_the_design_extends_is_named_relative_to_how_the_design_was_named(tmp_path):
    (tmp_path / "lib").mkdir()
    base = (ROOT / FIG4).read_text().replace("param reach = ", "param reach = 3 * nosuch + ", 1)
    (tmp_path / "lib" / "base.acl").write_text(base)
    line = next(i for i, t in enumerate(base.splitlines(), 1) if "nosuch" in t)
    (tmp_path / "d.acl").write_text('extends "lib/base.acl"\n')
    r = run("check", "d.acl", cwd=tmp_path)
    assert r.returncode == 1
    assert r.stderr.startswith(f"lib/base.acl:{line}:"), r.stderr
    r = run("check", "../d.acl", cwd=tmp_path / "lib")
    assert r.stderr.startswith(f"../lib/base.acl:{line}:"), r.stderr
    r = run("check", str(tmp_path / "d.acl"), cwd=ROOT)          # given absolute: absolute
    assert r.stderr.startswith(f"{tmp_path / 'lib' / 'base.acl'}:{line}:"), r.stderr
    (tmp_path / "lib" / "base.acl").write_text((ROOT / FIG4).read_text())
    r = run("analyze", "d.acl", "--no-snap", cwd=tmp_path)         # the source column of the tables
    assert r.returncode == 0, r.stderr
    assert f"lib/base.acl:{FIG4_LEFT}" in r.stdout and str(tmp_path) not in r.stdout + r.stderr
    r = run("check", "tests/bad/csv_non_numeric_cell.acl")       # a CSV file the design reads, at row:column
    assert r.stderr.startswith("tests/bad/lib/path_bad_cell.csv:3:2: error[E507]"), r.stderr


def test_fit_names_the_files_it_read_and_wrote_as_given(tmp_path):
    shutil.copy(ROOT / "samples" / "fit_cantilever.acl", tmp_path / "d.acl")
    shutil.copy(ROOT / "tests" / "hostile" / "inputs" / "data_ok.csv", tmp_path / "m.csv")
    (tmp_path / "out").mkdir()
    r = run("fit", "d.acl", "./m.csv", "--free", "gamma", "--calibrated", "out/c.acl", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "calibrated design written to out/c.acl (load it with --path .)" in r.stderr, r.stderr
    text = (tmp_path / "out" / "c.acl").read_text()
    head = [t for t in text.splitlines() if t.startswith("# ")]
    assert "# design: d.acl" in head and "# data: m.csv" in head, head
    assert "# load with `--path .` (the original is outside this file's folder tree)" in head, head
    assert str(tmp_path) not in text and str(tmp_path) not in r.stderr
    r = run("check", "--path", ".", "out/c.acl", cwd=tmp_path)       # the note's advice works
    assert r.returncode == 0, r.stderr


def test_fit_report_names_the_default_calibrated_design_as_given(tmp_path):
    pytest.importorskip("matplotlib")
    (tmp_path / "designs").mkdir()
    shutil.copy(ROOT / "samples" / "fit_cantilever.acl", tmp_path / "designs" / "d.acl")
    shutil.copy(ROOT / "tests" / "hostile" / "inputs" / "data_ok.csv", tmp_path / "m.csv")
    r = run("fit", "designs", "m.csv", "--free", "gamma", "--report", "rep", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "report written to rep/" in r.stderr
    assert "calibrated design written to designs/d.calibrated.acl\n" in r.stderr, r.stderr
    text = (tmp_path / "designs" / "d.calibrated.acl").read_text()
    assert "# design: designs/d.acl\n# data: m.csv\n# report: rep/report.json\n" in text, text[:400]
    assert str(tmp_path) not in text and str(tmp_path) not in r.stderr

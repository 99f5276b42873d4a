"""`acl fmt`: one canonical layout, idempotent, comment-preserving, never changing the design.

Every example, every stdlib file and every parseable file of the bad-input corpus is formatted
twice (the second pass must change nothing) and resolved before and after (the resolved design,
spans aside, or the diagnostic codes of a bad design, must be identical). Hypothesis mutants of
the examples (the generator of tests/test_fuzz_parser.py) go through the same checks.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import acl
from acl.diagnostics import DiagnosticError
from acl.fmt import format_source
from acl.syntax.parser import parse_module

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("*.acl"))
STDLIB = sorted((ROOT / "stdlib").glob("*.acl"))
BAD = sorted((ROOT / "tests" / "bad").rglob("*.acl"))
CORPUS = EXAMPLES + STDLIB + BAD


def _read(path: Path) -> str | None:
    try:
        return path.read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        return None


def _parses(text: str, name: str) -> bool:
    try:
        parse_module(text, name)
        return True
    except DiagnosticError:
        return False


def _strip_spans(x):
    if isinstance(x, dict):
        return {k: (re.sub(r"\s+", "", v) if k == "text" and isinstance(v, str) else _strip_spans(v))
                for k, v in x.items() if k != "span" and not k.endswith("_span")}
    if isinstance(x, list):
        return [_strip_spans(v) for v in x]
    return x


def resolved(text: str, name: str):
    """What a source means once resolved: the design (spans aside) or its diagnostic codes.

    `sources` lists the files read in the order the imports load them: sorted imports load
    them in another order, so it is compared as a set.
    """
    try:
        design = _strip_spans(acl.loads(text, name).model_dump(mode="json"))
        design["sources"] = sorted(design.get("sources", []))
        return "design", design
    except DiagnosticError as exc:
        return "diagnostics", sorted(d.code for d in exc.diagnostics)


def _comments(text: str) -> list[str]:
    """Every comment's words (the formatter may put a space after the `#`)."""
    from acl.fmt.tokens import tokenize

    return sorted(t.text[1:].strip() for t in tokenize(text) if t.type == "COMMENT")


# ---- the corpus --------------------------------------------------------------------------------

@pytest.mark.parametrize("path", CORPUS, ids=lambda p: str(p.relative_to(ROOT)))
def test_formatting_twice_changes_nothing_and_keeps_the_design(path):
    text = _read(path)
    if text is None or not _parses(text, str(path)):
        pytest.skip("not a parseable file (refusal is tested below)")
    once = format_source(text, str(path))
    assert format_source(once, str(path)) == once
    assert resolved(once, str(path)) == resolved(text, str(path))
    assert _comments(once) == _comments(text)


def test_the_corpus_is_mostly_parseable():
    """The check above must not silently skip everything."""
    ok = [p for p in CORPUS if (t := _read(p)) is not None and _parses(t, str(p))]
    assert len(ok) >= len(EXAMPLES) + len(STDLIB) + 40


@pytest.mark.parametrize("path", [p for p in BAD if p.stem.startswith("syntax_")], ids=lambda p: p.stem)
def test_files_with_syntax_errors_are_refused_with_the_parser_diagnostic(path):
    text = _read(path)
    if text is None:
        pytest.skip("not UTF-8: refused when read (see the CLI test)")
    with pytest.raises(DiagnosticError) as fmt_err:
        format_source(text, str(path))
    with pytest.raises(DiagnosticError) as parse_err:
        parse_module(text, str(path))
    got = [(d.code, d.span.line, d.span.column) for d in fmt_err.value.diagnostics]
    assert got == [(d.code, d.span.line, d.span.column) for d in parse_err.value.diagnostics]


def test_examples_and_stdlib_are_formatted():
    r = subprocess.run([sys.executable, "-m", "acl", "fmt", "--check", "examples", "stdlib"], cwd=ROOT,
                       capture_output=True, text=True, timeout=300, env=_env())
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]


def test_acl_blocks_in_the_docs_are_formatted():
    blocks = [(doc.name, b) for doc in sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]
              for b in re.findall(r"```acl\n(.*?)```", doc.read_text(encoding="utf-8"), re.S)]
    assert blocks
    for name, block in blocks:
        assert format_source(block, name) == block, name


# ---- hypothesis: mutants of the examples -----------------------------------------------------

SOURCES = [(str(p), p.read_text(encoding="utf-8")) for p in EXAMPLES]
TOKEN = re.compile(r"\s+|[A-Za-z_][A-Za-z0-9_]*|\d+(?:\.\d+)?(?:[eE][+-]?\d+)?|\.\.|.", re.S)
SPACING = st.sampled_from(["", " ", "  ", "\t", "\n", " \\\n", "  # note\n"])


def _mutate(text: str, data) -> str:
    units = TOKEN.findall(text)
    for _ in range(data.draw(st.integers(1, 4), label="mutations")):
        i = data.draw(st.integers(0, len(units) - 1), label="at")
        op = data.draw(st.sampled_from(["delete", "duplicate", "swap", "respace"]), label="op")
        if op == "delete":
            del units[i]
        elif op == "duplicate":
            units.insert(i, units[i])
        elif op == "swap":
            j = data.draw(st.integers(0, len(units) - 1), label="with")
            units[i], units[j] = units[j], units[i]
        else:   # change the layout only: spaces, newlines, continuations, comments
            units.insert(i, data.draw(SPACING, label="spacing"))
    return "".join(units)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(SOURCES), st.data())
def test_mutants_format_stably_and_keep_their_meaning(source, data):
    path, text = source
    mutant = _mutate(text, data)
    if not _parses(mutant, path):
        with pytest.raises(DiagnosticError):
            format_source(mutant, path)
        return
    once = format_source(mutant, path)
    assert format_source(once, path) == once
    assert resolved(once, path) == resolved(mutant, path)
    assert _comments(once) == _comments(mutant)


def _offsets(text: str):
    from acl.fmt.tokens import tokenize

    starts = [0] + [m.end() for m in re.finditer("\n", text)]
    return [(starts[t.line - 1] + t.column - 1, t) for t in tokenize(text) if t.type not in ("NL", "CONT")]


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(SOURCES), st.data())
def test_the_layout_does_not_depend_on_spaces_indentation_or_extra_blank_lines(source, data):
    """One canonical layout: extra spaces and tabs between tokens, any indentation, trailing
    whitespace and extra blank lines where there is one already all format to the same text."""
    path, text = source
    out, pos = [], 0
    pad = st.text(st.sampled_from(" \t"), max_size=3)
    for start, t in _offsets(text):
        gap = text[pos:start]
        if "\n" in gap:
            lines = gap.split("\n")
            lines = [ln + data.draw(pad, label="trailing") if not ln.lstrip().startswith("#") else ln
                     for ln in lines[:-1]] + [data.draw(pad, label="indent")]
            gap = "\n".join(lines)
            if gap.count("\n") >= 2:
                gap = "\n" * data.draw(st.integers(0, 2), label="blank lines") + gap
        elif pos > 0:
            gap += data.draw(pad, label="spaces")
        out.append(gap)
        out.append(text[start:start + len(t.text)])
        pos = start + len(t.text)
    out.append(text[pos:])
    perturbed = "".join(out)
    assert format_source(perturbed, path) == format_source(text, path)


# ---- the layout rules ------------------------------------------------------------------------

@pytest.mark.parametrize("before, after", [
    ("param x=2*pitch+5um\n", "param x = 2 * pitch + 5 um\n"),
    ("param a=(3 um)^2\n", "param a = (3 um)^2\n"),
    ("param a = 3 um ^ 2\n", "param a = 3 um ^ 2\n"),                 # `3 um^2` is one quantity
    ("param y = - x\n", "param y = - x\n"),                            # `-x` is a direction
    ("param y = -( x )\n", "param y = -(x)\n"),
    ("param w = a -x\n", "param w = a - x\n"),
    ("param d = 2.1e-5   m^2/s\n", "param d = 2.1e-5 m^2/s\n"),
    ("param e=2e-5*4.9E-1/2.0e1um\n", "param e = 2e-5 * 4.9E-1 / 2.0e1 um\n"),
    ("beam b like beams.cantilever50{clamp=(0,0,0)}\n", "beam b like beams.cantilever50 { clamp = (0, 0, 0) }\n"),
    ("capsule c {}\n", "capsule c { }\n"),
    ("require resonance( c ,mode=1 ) in 75kHz..95kHz\n", "require resonance(c, mode = 1) in 75 kHz .. 95 kHz\n"),
    ("program p {\n      drive 85kHz@4V+170 kHz @ 4 V for 1 s,limit 5 V\n}\n",
     "program p {\n  drive 85 kHz @ 4 V + 170 kHz @ 4 V for 1 s, limit 5 V\n}\n"),
])
def test_spacing_and_indentation(before, after):
    assert format_source(before) == after


def test_imports_are_sorted_with_their_comments():
    src = 'import stdlib.media  # liquid\nimport "lib/x.acl" as x\nimport stdlib.beams\n\nparam a = 1\n'
    assert format_source(src) == ('import stdlib.beams\nimport stdlib.media  # liquid\nimport "lib/x.acl" as x\n'
                                  '\nparam a = 1\n')


def test_trailing_comments_of_consecutive_lines_line_up():
    src = "param gap = 40 um     # a\nparam reach = 27 um # b\n\nparam c = 1 # c\n"
    assert format_source(src) == "param gap = 40 um    # a\nparam reach = 27 um  # b\n\nparam c = 1  # c\n"


def test_multi_line_blocks_get_a_blank_line_around_them_and_keep_their_comments():
    src = ("param a = 1\n# about c\ncapsule c {\n\n    q = 40   # declared\n  # last\n\n}\n"
           "capsule d { }\n\n\n\nparam b = 2\n")
    assert format_source(src) == ("param a = 1\n\n# about c\ncapsule c {\n  q = 40  # declared\n  # last\n}\n"
                                  "\ncapsule d { }\n\nparam b = 2\n")


def test_wrapped_brackets_line_up_or_hang():
    src = "transducer t {\n gain = [(40 kHz, 9 Pa/V),\n (60 kHz, 15 Pa/V)]\n band = [\n40 kHz,\n 200 kHz\n   ]\n}\n"
    assert format_source(src) == ("transducer t {\n  gain = [(40 kHz, 9 Pa/V),\n          (60 kHz, 15 Pa/V)]\n"
                                  "  band = [\n    40 kHz,\n    200 kHz\n  ]\n}\n")


def test_comments_get_a_space_after_the_hash():
    src = "#note\n##  banner\n#!keep\nparam a = 1 #acl: ignore[ACL601] unused\n"
    assert format_source(src) == "# note\n##  banner\n#!keep\nparam a = 1  # acl: ignore[ACL601] unused\n"


def test_backslash_continuations_are_kept():
    assert format_source("param a = 1 +   \\\n 2\n") == "param a = 1 + \\\n    2\n"


def test_a_backslash_before_an_empty_line_is_dropped():
    """`\\` joins its line to an empty one, whose newline ends the statement: the `}` stays on its line."""
    assert format_source("program p {\n  pause 1 s \\\n\n}\n") == "program p {\n  pause 1 s\n}\n"


def test_crlf_and_missing_final_newline_are_normalised():
    assert format_source("param a = 1\r\nparam b = 2") == "param a = 1\r\nparam b = 2\r\n"   # all CRLF: kept
    assert format_source("param a = 1\r\nparam b = 2\nparam c = 3") == "param a = 1\nparam b = 2\nparam c = 3\n"  # mixed: LF


def test_a_crlf_file_keeps_crlf_and_passes_check_when_canonical(tmp_path):
    """Every line in CRLF (a Windows checkout): the layout is canonicalised, the line endings kept, so
    `acl fmt --check` passes on a canonical CRLF file and is idempotent."""
    import subprocess
    import sys

    lf = format_source("param   a = 1\nparam b=2\n")
    crlf = format_source("param   a = 1\r\nparam b=2\r\n")
    assert crlf == lf.replace("\n", "\r\n") and format_source(crlf) == crlf
    f = tmp_path / "w.acl"
    f.write_bytes(crlf.encode())
    r = subprocess.run([sys.executable, "-m", "acl", "fmt", "--check", "-q", str(f)], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    f.write_bytes(b"param   a = 1\r\nparam b=2\r\n")
    r = subprocess.run([sys.executable, "-m", "acl", "fmt", "-q", str(f)], capture_output=True, text=True)
    assert r.returncode == 0 and f.read_bytes() == crlf.encode()


def test_an_empty_file_stays_empty():
    assert format_source("") == "" and format_source("\n\n") == ""


# ---- the command line ------------------------------------------------------------------------

def _env():
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def acl_fmt(*args, cwd, stdin=None):
    return subprocess.run([sys.executable, "-m", "acl", "fmt", *args], cwd=cwd, input=stdin,
                          capture_output=True, text=True, timeout=120, env=_env())


UGLY = "param gap=40um\nparam v = 2*gap # x\n"
PRETTY = "param gap = 40 um\nparam v = 2 * gap  # x\n"


def test_fmt_rewrites_files_and_folders_in_place(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "a.acl").write_text(UGLY)
    (tmp_path / "sub" / "b.acl").write_text(UGLY)
    (tmp_path / "sub" / "notes.txt").write_text(UGLY)
    r = acl_fmt(".", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "a.acl").read_text() == PRETTY
    assert (tmp_path / "sub" / "b.acl").read_text() == PRETTY
    assert (tmp_path / "sub" / "notes.txt").read_text() == UGLY
    assert "2 file(s) reformatted" in r.stderr
    assert not [p for p in tmp_path.rglob("*") if p.name.startswith(".acl-")]   # no temporary left


def test_fmt_check_prints_a_diff_exits_1_and_writes_nothing(tmp_path):
    (tmp_path / "a.acl").write_text(UGLY)
    (tmp_path / "ok.acl").write_text(PRETTY)
    r = acl_fmt("--check", "a.acl", "ok.acl", cwd=tmp_path)
    assert r.returncode == 1
    assert "-param gap=40um" in r.stdout and "+param gap = 40 um" in r.stdout and "ok.acl" not in r.stdout
    assert (tmp_path / "a.acl").read_text() == UGLY
    assert acl_fmt("--check", "ok.acl", cwd=tmp_path).returncode == 0


def test_fmt_diff_prints_a_diff_and_writes_nothing(tmp_path):
    (tmp_path / "a.acl").write_text(UGLY)
    r = acl_fmt("--diff", "a.acl", cwd=tmp_path)
    assert r.returncode == 0 and "+param v = 2 * gap  # x" in r.stdout
    assert (tmp_path / "a.acl").read_text() == UGLY


def test_fmt_check_and_diff_are_exclusive(tmp_path):
    r = acl_fmt("--check", "--diff", "x.acl", cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr


def test_fmt_reads_stdin_and_writes_stdout(tmp_path):
    r = acl_fmt("-", cwd=tmp_path, stdin=UGLY)
    assert r.returncode == 0 and r.stdout == PRETTY
    r = acl_fmt("--check", "-", cwd=tmp_path, stdin=UGLY)
    assert r.returncode == 1 and "+param gap = 40 um" in r.stdout


def test_fmt_refuses_a_syntax_error_and_leaves_the_file_untouched(tmp_path):
    bad = tmp_path / "bad.acl"
    bad.write_text("param gap=40um\nparam v = 'x'\n")
    before = bad.stat().st_mtime_ns
    r = acl_fmt("bad.acl", cwd=tmp_path)
    assert r.returncode == 1
    assert "bad.acl:2:11" in r.stderr and "E110" in r.stderr and "Traceback" not in r.stderr
    assert bad.read_text() == "param gap=40um\nparam v = 'x'\n" and bad.stat().st_mtime_ns == before


def test_fmt_stdin_syntax_error_writes_nothing_to_stdout(tmp_path):
    r = acl_fmt("-", cwd=tmp_path, stdin="param = 1\n")
    assert r.returncode == 1 and r.stdout == "" and "<stdin>:1:7" in r.stderr and "E111" in r.stderr


def test_fmt_reports_unreadable_inputs(tmp_path):
    (tmp_path / "latin1.acl").write_bytes(b"# caf\xe9\nparam a = 1\n")
    r = acl_fmt("latin1.acl", "missing.acl", cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "E103" in r.stderr and "latin1.acl:1:6" in r.stderr
    assert "E601" in r.stderr and "missing.acl:1:1" in r.stderr


def test_fmt_keeps_the_file_mode(tmp_path):
    f = tmp_path / "a.acl"
    f.write_text(UGLY)
    f.chmod(0o640)
    assert acl_fmt("a.acl", cwd=tmp_path).returncode == 0
    assert f.stat().st_mode & 0o777 == 0o640


def test_fmt_rewrites_the_target_of_a_symbolic_link(tmp_path):
    (tmp_path / "real.acl").write_text(UGLY)
    (tmp_path / "link.acl").symlink_to("real.acl")
    assert acl_fmt("link.acl", cwd=tmp_path).returncode == 0
    assert (tmp_path / "link.acl").is_symlink() and (tmp_path / "real.acl").read_text() == PRETTY


def test_fmt_imports_no_heavy_module():
    code = ("import sys\nfrom acl.cli import main\n"
            "rc = main(['fmt', '--check', 'examples'])\n"
            "heavy = sorted({m.split('.')[0] for m in sys.modules} & {'scipy', 'cvxpy', 'matplotlib', 'pint', 'numpy'})\n"
            "sys.stderr.write('HEAVY=' + ','.join(heavy) + ' RC=' + str(rc))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT, env=_env())
    assert "HEAVY= RC=" in r.stderr, r.stderr[-2000:]


def test_pre_commit_hook_runs_acl_fmt():
    text = (ROOT / ".pre-commit-hooks.yaml").read_text()
    block = text[text.index("- id: acl-fmt"):]
    assert "entry: acl fmt" in block and r"files: \.acl$" in block

"""Highlighting: the Pygments lexer and the TextMate grammar agree with acl's own parser.

The reference is the parser's token stream (acl.fmt.tokens, the grammar's terminals as the LALR
parser reads them): on every example and stdlib file, each keyword, unit, number, string,
comment, direction and name must get its class in both highlighters, and nothing may be an
error token. The TextMate grammar runs in tests/textmate.py on Python's `re` and, when
`onigurumacffi` is installed, on Oniguruma (the engine of VS Code).
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

pygments = pytest.importorskip("pygments")
from pygments.token import Comment, Error, Keyword, Name, Number, String   # noqa: E402

from acl.editor.pygments_lexer import KINDS, AclLexer   # noqa: E402
from acl.fmt.tokens import tokenize   # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
from textmate import Grammar, OnigurumaEngine, PythonEngine   # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
VSCODE = ROOT / "editors" / "vscode"
GRAMMAR = json.loads((VSCODE / "syntaxes" / "acl.tmLanguage.json").read_text(encoding="utf-8"))
SOURCES = sorted((ROOT / "examples").glob("*.acl")) + sorted((ROOT / "stdlib").glob("*.acl"))

# Every lexical class and every statement and step of the grammar (it parses; it need not resolve).
SAMPLE = '''# a sample: every class once
import stdlib.media
import "lib/parts.acl" as parts
param d = 2.1e-5 m^2/s free in 1e-6 m^2/s .. 1.5e-4 m^2/s
param e = 2e-5 * 4.9E-1 / 2.0e1 um
param k = 0.7563 nN/um  # acl: ignore[ACL601] unused on purpose
param x = 5 inch
capsule c like parts.c1 { orifice jet { radius = 10 um, normal = -x }, q = 40 }
latch l { at = (0, 0, 25 um), axis = +x, angle = 45 deg }
observe g = gap(c.jet, c.jet)
require margin(l) >= 1
program switch {
  follow c along text("EPFL", height = 6 um) in 12 s, limit 20 V
  switch l to b, margin 1.2
  sweep 40 kHz to 160 kHz @ 5 V in 4 s log
}
extends "base.acl"
anchor post { at = (0, 0, 0) }
effect drag { kind = "added_mass", factor = 1.5 }
mount c on l.shuttle
fix c
link c to c with t
require gap(c.jet, c.jet) > 10 um
require resonance(c) < 200 kHz
program more {
  drive 85 kHz @ 2 V phase 90 deg + 170 kHz @ 1 V for 1 s, limit 5 V
  follow c along circle(radius = 3 um) at 10 um/s, slew 100 V/s, using [85 kHz, 125 kHz]
  hold gap(c.jet, c.jet) above 10 um for 1 s, margin 1.5
  cross gap(c.jet, c.jet) for 500 ms
  pause 500 ms
}
'''
_NUMBER = re.compile(r"(\d+\.\d+|\d+\.(?!\.)|\.\d+|\d+)([eE][+-]?\d+)?")
_NOT_WORDS = {"NAME", "QUANTITY", "NUMBER", "STRING", "DIRECTION", "COMMENT", "NL", "CONT"}


def expectations(text: str):
    """(start, end, class, token text) for every token the parser reads, offsets into ``text``."""
    starts = [0] + [m.end() for m in re.finditer("\n", text)]
    out = []
    for t in tokenize(text):
        if t.type in ("NL", "CONT"):
            continue
        a = starts[t.line - 1] + t.column - 1
        b = a + len(t.text.rstrip())
        if t.type == "QUANTITY":   # the number as the parser's builder reads it, then the unit
            n = _NUMBER.match(t.text).end()
            unit = t.text[n:].strip()
            out.append((a, a + n, "number", t.text))
            if unit:
                out.append((b - len(unit), b, "unit", t.text))
        elif t.type == "NUMBER":
            out.append((a, b, "number", t.text))
        elif t.type == "STRING":
            out.append((a, b, "string", t.text))
        elif t.type == "COMMENT":
            out.append((a, b, "comment", t.text))
        elif t.type == "DIRECTION":
            out.append((a, b, "direction", t.text))
        elif t.type == "NAME":
            out.append((a, b, "kind-or-name" if t.text in KINDS else "name", t.text))
        elif t.type not in _NOT_WORDS and t.text.isalpha():
            out.append((a, b, "keyword", t.text))
    return out


# ---- Pygments --------------------------------------------------------------------------------

PYGMENTS = {
    "number": lambda tt: tt in Number,
    "unit": lambda tt: tt in Keyword.Type,
    "string": lambda tt: tt in String,
    "comment": lambda tt: tt in Comment,
    "direction": lambda tt: tt in Name.Constant,
    "keyword": lambda tt: tt in Keyword and tt not in Keyword.Type,
    "name": lambda tt: tt in Name,
    "kind-or-name": lambda tt: tt in Name or tt in Keyword.Declaration,
}


def pygments_classes(text: str) -> list:
    per_char = [None] * len(text)
    for index, tt, value in AclLexer().get_tokens_unprocessed(text):
        for i in range(index, index + len(value)):
            per_char[i] = tt
    return per_char


def check_pygments(text: str) -> None:
    per_char = pygments_classes(text)
    errors = [(i, text[i]) for i, tt in enumerate(per_char) if tt is None or tt in Error]
    assert not errors, f"error tokens at {errors[:5]}"
    for a, b, cls, tok in expectations(text):
        bad = {str(per_char[i]) for i in range(a, b) if not PYGMENTS[cls](per_char[i])}
        assert not bad, f"{tok!r} (line {text.count(chr(10), 0, a) + 1}) should be {cls}, got {bad}"


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.name)
def test_pygments_lexer_classes_every_token_of_the_file_as_the_parser_reads_it(path):
    check_pygments(path.read_text(encoding="utf-8"))


def test_the_sample_parses():
    from acl.syntax.parser import parse_module

    parse_module(SAMPLE)


def test_pygments_sample_covers_every_class():
    check_pygments(SAMPLE)
    per_char = pygments_classes(SAMPLE)

    def cls_of(word, nth=0):
        i = [m.start() for m in re.finditer(rf"(?<![\w.]){re.escape(word)}(?![\w])", SAMPLE)][nth]
        return {per_char[j] for j in range(i, i + len(word))}
    assert cls_of("2e-5") == cls_of("4.9E-1") == {Number.Float}   # one number each, as the parser reads them
    assert cls_of("2.1e-5") == {Number.Float} and cls_of("m^2/s") == {Keyword.Type}
    assert cls_of("inch") == {Keyword.Type} and cls_of("in", 0) == {Keyword}   # `free in`
    assert cls_of("# acl: ignore[ACL601] unused on purpose") == {Comment.Special}
    assert cls_of('"EPFL"') == {String.Double}
    assert cls_of("switch", 0) == {Name.Function} and cls_of("switch", 1) == {Keyword}


def test_pygments_finds_the_lexer_by_name_through_the_entry_point(tmp_path):
    """`get_lexer_by_name("acl")` through the `pygments.lexers` entry point that pyproject.toml
    declares (as an installed acl would register it)."""
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    eps = project["entry-points"]["pygments.lexers"]
    dist = tmp_path / "acl_probe-0.0.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: acl-probe\nVersion: 0.0.0\n")
    (dist / "entry_points.txt").write_text("[pygments.lexers]\n" + "".join(f"{k} = {v}\n" for k, v in eps.items()))
    code = ("from pygments.lexers import get_lexer_by_name, get_lexer_for_filename\n"
            "print(type(get_lexer_by_name('acl')).__module__, get_lexer_for_filename('x.acl').name)\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(ROOT), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert r.stdout.split() == ["acl.editor.pygments_lexer", "acl"], r.stderr


def test_pygments_is_an_optional_dependency():
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert not any(d.lower().startswith("pygments") for d in project["dependencies"])
    extras = project["optional-dependencies"]
    assert any(d.startswith("pygments") for d in extras["highlight"])
    # the test extra pulls pygments in, directly or through acl[...,highlight,...]
    assert any(d.startswith("pygments") or (d.startswith("acl[") and "highlight" in d) for d in extras["test"])


SCIENTIFIC = "param e = 2e-5\nparam f = 4.9e-1 * 1 um\nparam g = 2.0E1 um\nparam h = 2 e5\n"


def test_pygments_scientific_notation_is_one_number():
    got = [(str(tt), v) for _, tt, v in AclLexer().get_tokens_unprocessed(SCIENTIFIC) if v.strip()]
    assert ("Token.Literal.Number.Float", "2e-5") in got and ("Token.Literal.Number.Float", "4.9e-1") in got
    assert ("Token.Literal.Number.Float", "2.0E1") in got and ("Token.Keyword.Type", "um") in got
    assert ("Token.Literal.Number.Integer", "2") in got and ("Token.Name", "e5") in got   # `2 e5`: no unit
    assert not [v for t, v in got if "Error" in t]


# ---- TextMate --------------------------------------------------------------------------------

def _engines():
    yield pytest.param(PythonEngine(), id="python-re")
    try:
        yield pytest.param(OnigurumaEngine(), id="oniguruma")
    except ImportError:
        yield pytest.param(None, id="oniguruma", marks=pytest.mark.skip(reason="onigurumacffi not installed"))


ENGINES = list(_engines())

TEXTMATE = {
    "number": lambda s: s.startswith("constant.numeric."),
    "unit": lambda s: s == "keyword.other.unit.acl",
    "string": lambda s: s.startswith("string.quoted.double"),
    "comment": lambda s: s.startswith("comment.line"),
    "direction": lambda s: s == "constant.language.direction.acl",
    "keyword": lambda s: (s.startswith(("keyword.", "storage.type."))
                          and not s.startswith(("keyword.other.unit", "keyword.operator"))),
    "name": lambda s: s.startswith(("variable.", "entity.name.", "support.function.")),
    "kind-or-name": lambda s: s.startswith(("variable.", "entity.name.", "support.function.", "storage.type.")),
}


def check_textmate(text: str, engine) -> list:
    chars = Grammar(GRAMMAR, engine).tokenize(text)
    assert "".join(ch for ch, _ in chars) == text
    for i, (ch, scopes) in enumerate(chars):
        assert scopes[0] == "source.acl"
        assert not any("invalid" in s for s in scopes), (i, ch, scopes)
        if not ch.isspace():
            assert len(scopes) > 1, f"{ch!r} at offset {i} has no scope"
    for a, b, cls, tok in expectations(text):
        for i in range(a, b):
            scopes = chars[i][1]
            # a comment or string scope covers its punctuation; elsewhere the innermost scope counts
            ok = any(TEXTMATE[cls](s) for s in scopes) if cls in ("comment", "string") else TEXTMATE[cls](scopes[-1])
            assert ok, f"{tok!r} (line {text.count(chr(10), 0, a) + 1}) should be {cls}, got {scopes}"
    return chars


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.name)
def test_textmate_grammar_scopes_every_token_of_the_file_as_the_parser_reads_it(path, engine):
    check_textmate(path.read_text(encoding="utf-8"), engine)


@pytest.mark.parametrize("engine", ENGINES)
def test_textmate_sample_covers_every_class(engine):
    chars = check_textmate(SAMPLE, engine)

    def scopes_of(word, nth=0):
        i = [m.start() for m in re.finditer(rf"(?<![\w.]){re.escape(word)}(?![\w])", SAMPLE)][nth]
        return {chars[j][1][-1] for j in range(i, i + len(word))}
    assert scopes_of("m^2/s") == {"keyword.other.unit.acl"}
    assert scopes_of("2e-5") == scopes_of("4.9E-1") == {"constant.numeric.float.acl"}
    assert scopes_of("inch") == {"keyword.other.unit.acl"} and scopes_of("in", 0) == {"keyword.other.acl"}
    assert scopes_of("ACL601") == {"constant.other.rule-code.acl"}
    assert scopes_of("switch", 0) == {"entity.name.function.program.acl"}
    assert scopes_of("switch", 1) == {"keyword.control.step.acl"}
    assert scopes_of("capsule") == {"storage.type.acl"} and scopes_of("c like", 0) >= {"entity.name.type.acl"}


@pytest.mark.parametrize("engine", ENGINES)
def test_textmate_scientific_notation_is_one_number(engine):
    chars = Grammar(GRAMMAR, engine).tokenize(SCIENTIFIC)
    text = "".join(ch for ch, _ in chars)

    def scopes_of(word):
        i = text.index(word)
        return {chars[j][1][-1] for j in range(i, i + len(word))}
    assert scopes_of("2e-5") == scopes_of("4.9e-1") == scopes_of("2.0E1") == {"constant.numeric.float.acl"}
    i = text.index("2.0E1 um") + len("2.0E1 ")
    assert {chars[j][1][-1] for j in (i, i + 1)} == {"keyword.other.unit.acl"}
    assert scopes_of("e5") == {"variable.other.acl"}


@pytest.mark.parametrize("engine", ENGINES)
def test_every_textmate_regex_compiles_on_the_engine(engine):
    assert Grammar(GRAMMAR, engine).compile_all() >= 20


def test_both_engines_give_the_same_scopes_on_every_example():
    pytest.importorskip("onigurumacffi")
    for path in SOURCES:
        text = path.read_text(encoding="utf-8")
        assert Grammar(GRAMMAR, PythonEngine()).tokenize(text) == Grammar(GRAMMAR, OnigurumaEngine()).tokenize(text), path.name


def test_textmate_interpreter_follows_leftmost_match_and_begin_end():
    """The interpreter itself, on a toy grammar: leftmost match wins, ties go to the first
    pattern, begin/end pushes a scope across lines."""
    toy = {"scopeName": "source.toy", "patterns": [
        {"match": "ab", "name": "first"}, {"match": "a", "name": "second"}, {"match": "b+", "name": "bees"},
        {"begin": "<", "end": ">", "name": "angle", "patterns": [{"match": "x", "name": "ex"}]}]}
    chars = Grammar(toy).tokenize("cab bb <x\nx> x")
    assert [s[-1] for _, s in chars] == ["source.toy", "first", "first", "source.toy", "bees", "bees", "source.toy",
                                         "angle", "ex", "source.toy", "ex", "angle", "source.toy", "source.toy"]


# ---- the VS Code extension -------------------------------------------------------------------

def test_vscode_manifest_contributes_the_language_grammar_and_server():
    manifest = json.loads((VSCODE / "package.json").read_text(encoding="utf-8"))
    lang = manifest["contributes"]["languages"][0]
    assert lang["id"] == "acl" and ".acl" in lang["extensions"]
    assert (VSCODE / lang["configuration"]).is_file()
    grammar = manifest["contributes"]["grammars"][0]
    assert grammar["scopeName"] == "source.acl" == GRAMMAR["scopeName"] and grammar["language"] == "acl"
    assert (VSCODE / grammar["path"]).resolve() == (VSCODE / "syntaxes" / "acl.tmLanguage.json").resolve()
    assert "onLanguage:acl" in manifest["activationEvents"]
    # the client is bundled into manifest["main"] (dist/, built before packaging) from extension.js
    assert "vscode-languageclient" in manifest["devDependencies"]
    assert manifest["main"] == "./dist/extension.js" and "./extension.js" in manifest["scripts"]["bundle"]
    command = manifest["contributes"]["configuration"]["properties"]["acl.server.command"]["default"]
    assert command == ["acl", "lsp"]
    main = (VSCODE / "extension.js").read_text(encoding="utf-8")
    assert "acl.server.command" in main and "LanguageClient" in main


def test_vscode_language_configuration_matches_the_language():
    conf = json.loads((VSCODE / "language-configuration.json").read_text(encoding="utf-8"))
    assert conf["comments"]["lineComment"] == "#"
    assert ["{", "}"] in conf["brackets"] and ["(", ")"] in conf["brackets"] and ["[", "]"] in conf["brackets"]
    increase = re.compile(conf["indentationRules"]["increaseIndentPattern"])
    decrease = re.compile(conf["indentationRules"]["decreaseIndentPattern"])
    assert increase.search("capsule c {") and increase.search("program p {   # note")
    assert not increase.search("capsule c { }") and decrease.search("  }")


def test_vscode_extension_script_is_valid_javascript():
    import shutil

    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed")
    r = subprocess.run([node, "--check", str(VSCODE / "extension.js")], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr


# ---- acl show ----------------------------------------------------------------------------------

def test_acl_show_colours_source_lines_on_a_terminal_only():
    import io

    from rich.console import Console

    import acl
    from acl.commands.show import design_tree

    tree = design_tree(acl.load(str(ROOT / "examples" / "fig1f_selective_beams.acl")))
    term = io.StringIO()
    Console(file=term, force_terminal=True, color_system="256", width=200).print(tree)
    line = next(x for x in term.getvalue().splitlines() if "separation" in x)
    assert re.search(r"\x1b\[[0-9;]*mrequire\x1b\[0m", line) and re.search(r"\x1b\[[0-9;]*mkHz\x1b\[0m", line)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-m", "acl", "show", "examples/fig1f_selective_beams.acl"], cwd=ROOT,
                       capture_output=True, text=True, env=env, timeout=120)
    assert "require separation(low, high) >= 50 kHz" in r.stdout and "\x1b[" not in r.stdout

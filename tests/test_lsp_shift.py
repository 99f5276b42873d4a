"""The editor's incremental parse when lines are inserted or deleted (Enter, Backspace, pastes,
moved statements): the statements after the edit are shifted (acl.syntax.ast.shift_lines), not
parsed again, and everything the editor shows must be what a whole-file parse gives: the syntax
tree span for span, the diagnostics with their locations, hover, definition, references, semantic
tokens, folding and selection ranges."""
from __future__ import annotations

import random
import sys
from pathlib import Path

import pytest

from acl.diagnostics import DiagnosticError, Span
from acl.lsp.document import check_text
from acl.lsp.incremental import IncrementalParser
from acl.syntax import ast as A
from acl.syntax.parser import parse_module

ROOT = Path(__file__).resolve().parents[1]

# a located design error (a length plus a time) at the end, so that an edit above moves it
BAD_TAIL = "param wrong_sum = 3 um + 2 s\n"


def _generated(n: int) -> str:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        from check import generate
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    return generate(n)


def _texts():
    return {"fig6f": (ROOT / "examples" / "fig6f_control_module.acl").read_text(encoding="utf-8") + BAD_TAIL,
            "fig4h": (ROOT / "examples" / "fig4h_unequal_pair.acl").read_text(encoding="utf-8"),
            "generated": _generated(200)}


def _edit(rng: random.Random, lines: list[str], step: int) -> str:
    """One line-count-changing edit of ``lines`` (in place); returns its name."""
    n = len(lines)
    i = rng.choice([0, 1, n // 2, n - 2, n - 1, rng.randrange(n)])
    op = rng.choice(["enter", "enter2", "backspace", "paste", "cut", "move", "newparam", "comment_block"])
    if op == "enter":                      # Enter at the start of a line
        lines.insert(i, "")
    elif op == "enter2":                   # Enter inside a block: an indented empty line
        lines.insert(i, "  ")
    elif op == "backspace" and n > 5 and i > 0:    # a line joined to an empty one above or below
        if not lines[i].strip():
            del lines[i]
        elif not lines[i - 1].strip():
            del lines[i - 1]
    elif op == "paste":                    # a copy of a few lines pasted elsewhere
        a = rng.randrange(n)
        lines[i:i] = lines[a:a + rng.randint(1, 6)]
    elif op == "cut" and n > 10:
        del lines[i:i + rng.randint(1, 4)]
    elif op == "move":                     # a run of lines cut and pasted elsewhere
        a = rng.randrange(n)
        block = lines[a:a + rng.randint(1, 8)]
        del lines[a:a + len(block)]
        j = rng.randrange(len(lines) + 1)
        lines[j:j] = block
    elif op == "newparam":
        lines[i:i] = [f"param pasted{step} = {step + 1} um", f"param pasted{step}b = pasted{step} * 2", ""]
    else:
        lines[i:i] = ["# a comment", "#"]
    return op


def _spans(node, out: list) -> list:
    if type(node) is Span:
        out.append(node)
    elif type(node) is tuple:
        for v in node:
            _spans(v, out)
    elif hasattr(node, "__dataclass_fields__"):
        for k in node.__dataclass_fields__:
            _spans(getattr(node, k), out)
    return out


@pytest.mark.parametrize("name", ["fig6f", "fig4h", "generated"])
def test_incremental_parse_after_line_inserts_deletes_and_pastes_equals_whole_file(name):
    """One parser through random edits that add or remove lines (80 on an example, 40 on the
    generated design): after each, parse() gives the whole-file tree (every span equal), or None
    where the whole-file parse fails; the shift path (chunks moved, not parsed) is taken in most."""
    text = _texts()[name]
    rng = random.Random(sum(map(ord, name)))
    lines = text.split("\n")
    p = IncrementalParser()
    assert p.parse(text, "s.acl") == parse_module(text, "s.acl")
    shifted_steps = moved_spans = 0
    steps = 40 if name == "generated" else 80
    for step in range(steps):
        before = list(lines)
        op = _edit(rng, lines, step)
        t = "\n".join(lines)
        got = p.parse(t, "s.acl")
        try:
            want = parse_module(t, "s.acl")
        except DiagnosticError:
            assert got is None, (step, op)
            lines = before                 # undone, as a user would; the parser goes back too
            assert p.parse("\n".join(lines), "s.acl") is not None
            continue
        assert got is not None, (step, op)
        assert got == want, (step, op)
        assert _spans(got.statements, []) == _spans(want.statements, []), (step, op)
        if p.stats["shifted"]:
            shifted_steps += 1
            moved_spans += p.stats["shifted"]
    assert shifted_steps >= steps * 0.4, shifted_steps


def test_enter_in_the_middle_parses_nothing_after_it():
    """Enter in the middle of a 300-line design: every later statement is shifted, none parsed;
    the blank line removed again: the same. (This is what makes Enter cost about what an edit in
    place costs: benchmarks/lsp.py.)"""
    text = _generated(300)
    lines = text.split("\n")
    mid = next(i for i in range(len(lines) // 2, len(lines)) if lines[i].startswith("param"))
    p = IncrementalParser()
    p.parse(text, "g.acl")
    entered = "\n".join(lines[:mid] + [""] + lines[mid:])
    got = p.parse(entered, "g.acl")
    assert got == parse_module(entered, "g.acl")
    assert p.stats["parsed"] == 0 and p.stats["shifted"] > 20 and p.stats["kept"] > 20, p.stats
    assert p.parse(text, "g.acl") == parse_module(text, "g.acl")
    assert p.stats["parsed"] == 0 and p.stats["shifted"] > 20, p.stats
    # a new statement pasted in the middle: that one is parsed, the rest shifted
    pasted = "\n".join(lines[:mid] + ["param pasted = 2 um", "param pasted2 = pasted * 3"] + lines[mid:])
    assert p.parse(pasted, "g.acl") == parse_module(pasted, "g.acl")
    assert p.stats["parsed"] == 2 and p.stats["shifted"] > 20, p.stats


def test_a_moved_statement_is_shifted_from_the_cache():
    """A statement cut from one place and pasted at another is not parsed again (its text is the
    cache key) and lands with the spans a whole-file parse gives it."""
    lines = _generated(300).split("\n")
    p = IncrementalParser()
    p.parse("\n".join(lines), "g.acl")
    i = next(k for k, x in enumerate(lines) if x.startswith("param x") and k > 40)
    moved = lines[:i] + lines[i + 1:]
    moved.insert(10, lines[i])
    t = "\n".join(moved)
    assert p.parse(t, "g.acl") == parse_module(t, "g.acl")
    assert p.stats["parsed"] == 0, p.stats


def test_shift_lines_moves_every_span_and_only_lines():
    m = parse_module((ROOT / "examples" / "fig6f_control_module.acl").read_text(encoding="utf-8"), "f.acl")
    moved = A.shift_lines(m.statements, 7)
    before, after = _spans(m.statements, []), _spans(moved, [])
    assert len(before) == len(after) > 100
    for a, b in zip(before, after):
        assert (b.line, b.end_line, b.column, b.end_column, b.file) == \
            (a.line + 7, a.end_line + 7, a.column, a.end_column, a.file)
        assert b == Span(file=a.file, line=a.line + 7, column=a.column, end_line=a.end_line + 7,
                         end_column=a.end_column)
        assert hash(b) == hash(Span(**b.model_dump()))
    assert A.shift_lines(moved, -7) == m.statements
    assert A.shift_lines(m.statements, 0) is m.statements
    # a span without an end (lark's empty position: line 1 in any parse) stays where it is
    empty = A.Num(Span(file="f.acl", line=1, column=1), 2.0)
    assert A.shift_lines(empty, 5) == empty
    with pytest.raises(TypeError):
        A.shift_lines((object(),), 1)


def test_span_moves_fall_back_to_pydantic_when_the_fast_construction_differs(monkeypatch):
    """shift_lines builds spans without pydantic's constructor only after checking, on its first
    move, that the result is pydantic's own; a construction that differs (another pydantic) is
    never used."""
    import acl.syntax.ast as ast_mod

    def wrong(s, d):                       # a construction that loses the end line's move
        return Span.model_construct(file=s.file, line=s.line + d, column=s.column, end_line=s.end_line,
                                    end_column=s.end_column)

    monkeypatch.setattr(ast_mod, "_moved_fast", wrong)
    monkeypatch.setattr(ast_mod, "_moved", ast_mod._moved_checked)
    text = (ROOT / "examples" / "fig4h_unequal_pair.acl").read_text(encoding="utf-8")
    assert A.shift_lines(parse_module(text, "f.acl").statements, 3) == \
        parse_module("\n\n\n" + text, "f.acl").statements
    assert ast_mod._moved is ast_mod._moved_constructed


def _features(snap) -> dict:
    """What the editor shows of a snapshot, at every name and number of every line."""
    from acl.lsp import references as R
    from acl.lsp.definition import definition
    from acl.lsp.hover import hover
    from acl.lsp.structure import folding, selection, semantic_tokens

    out = {"diagnostics": [(d.code, d.message, d.span) for d in snap.diagnostics],
           "tokens": semantic_tokens(snap), "folding": folding(snap)}
    for ln, text in enumerate(snap.lines):
        for col in sorted({m.start() + 1 for m in R.IDENT.finditer(text)} | {len(text) // 2}):
            h = hover(snap, ln, col, quick=True)
            d = definition(snap, ln, col)
            t = R.target_at(snap.env, snap.lines, ln, col)
            refs = sorted(R.occurrences(snap.env, snap.lines, R.key(t[0]))) if t else None
            out[(ln, col)] = (h, d[:2] if d else None, refs, R.declaration(t[0]) if t else None,
                              selection(snap, ln, col))
    return out


@pytest.mark.parametrize("name", ["fig6f", "generated"])
def test_editor_features_after_shifted_edits_equal_a_fresh_check(name, tmp_path):
    """After Enter, a pasted block and a deletion (each shifting what follows), the document
    checked through one incremental parser shows exactly what a fresh whole-file check shows:
    diagnostics (codes, messages, locations), hover, definition, references, the declaration
    reached, semantic tokens, folding and selection ranges."""
    path = str(tmp_path / f"{name}.acl")
    text = _texts()[name]
    lines = text.split("\n")
    p = IncrementalParser()
    check_text(text, path, 1, parser=p)
    mid = len(lines) // 2
    edits = [lines[:mid] + [""] + lines[mid:],                                   # Enter
             lines[:3] + lines[mid:mid + 4] + lines[3:],                          # a paste near the top
             lines[:2] + lines[4:]]                                               # two lines deleted
    checked = 0
    for v, new in enumerate(edits, start=2):
        t = "\n".join(new)
        try:
            parse_module(t, path)
        except DiagnosticError:
            continue                        # a paste that breaks a block: not this test's case
        inc = check_text(t, path, v, parser=p)
        assert p.stats["shifted"] > 0, (v, p.stats)
        fresh = check_text(t, path, v)
        assert inc.parsed and fresh.parsed
        assert _features(inc) == _features(fresh), v
        checked += 1
    assert checked >= 2
    if name == "fig6f":                      # the located design error moved with its line
        assert any(d.code.startswith("E") and d.span.line == t.split("\n").index(BAD_TAIL.strip()) + 1
                   for d in inc.diagnostics)


def test_lint_findings_after_shifted_edits_equal_a_fresh_lint(tmp_path):
    """The lint worker parses through one incremental parser too: its findings after lines are
    inserted above them are those of a fresh lint, at their new lines."""
    from acl.lsp import lint as L

    path = str(tmp_path / "fig5a.acl")
    text = (ROOT / "examples" / "fig5a_gripper.acl").read_text(encoding="utf-8")
    # a finding to follow: an implausible pair factor (the example's own 14.985, Fig. 5b, is plausible: W402 from 38x)
    assert "factor = calibrations.gripper_pair_factor" in text
    text = text.replace("factor = calibrations.gripper_pair_factor", "factor = 50")
    L._PARSERS.clear()
    first = L.lint_text(path, text)
    assert any(d.code == "W402" and d.span.line > 5 for d in first)     # the effect's implausible factor
    lines = text.split("\n")
    moved = "\n".join(lines[:5] + ["", "# pasted", "param pasted = 2 um"] + lines[5:])
    got = L.lint_text(path, moved)
    L._PARSERS.clear()
    fresh = L.lint_text(path, moved)
    assert got == fresh
    assert sorted(d.span.line for d in got if d.span.line > 8) == \
        sorted(d.span.line + 3 for d in first if d.span.line > 5)          # past the 3 pasted lines
    L._PARSERS.clear()

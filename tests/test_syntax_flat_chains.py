"""Issue 28: a flat sum or product is parsed as one list of terms (acl/syntax/grammar.lark `sum`, `product`),
not one tree level per term, so 1,000 terms are not "nested deeper than 200 levels" (E104).  The syntax
tree is exactly the one the left-recursive grammar gave, spans included: checked against that grammar,
rebuilt here, on every design file in the repository and on generated expressions."""
from __future__ import annotations

import functools
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from lark import Lark

from acl.cli import main
from acl.syntax import parser as P

ROOT = Path(__file__).resolve().parents[1]
OLD_RULES = '''?sum: product
    | sum "+" product   -> add
    | sum "-" product   -> sub
?product: unary
    | product "*" unary -> mul
    | product "/" unary -> div'''


@functools.lru_cache(maxsize=1)
def _reference() -> Lark:
    text = (ROOT / "acl" / "syntax" / "grammar.lark").read_text(encoding="utf-8")
    start, end = text.index("?sum:"), text.index("?unary:")
    old = text[:start] + OLD_RULES + "\n" + text[end:]
    return Lark(old, parser="lalr", start=["start", "drive_only"], propagate_positions=True,
                maybe_placeholders=True, postlex=P._ParenNewlines())


class _OldBuilder(P._Builder):
    add = P._Builder._bin("+")
    sub = P._Builder._bin("-")
    mul = P._Builder._bin("*")
    div = P._Builder._bin("/")


def _old(source: str, file: str = "x.acl"):
    tree = _reference().parse(source, start="start")
    return tuple(_OldBuilder(file, source).transform(tree))


def _new(source: str, file: str = "x.acl"):
    return tuple(P.parse_module(source, file).statements)


def _files():
    for folder in ("examples", "stdlib", "tests"):
        for p in sorted((ROOT / folder).rglob("*.acl")):
            try:
                text = p.read_text(encoding="utf-8").removeprefix("\ufeff")
                _new(text, str(p))
                _old(text, str(p))
            except Exception:
                continue                   # the bad-input corpus: refused before any tree
            yield p, text


def test_every_design_file_parses_to_the_left_recursive_tree_spans_included():
    n = 0
    for p, text in _files():
        assert repr(_new(text, str(p))) == repr(_old(text, str(p))), p
        n += 1
    assert n > 100


_atoms = st.sampled_from(["1", "2.5", "3 um", "(4)", "((4))", "(5 kHz)", "a", "b.c", "f(1, a)", "(a)", "((a))", "-a",
                          "-(a)", "2 ^ a", "(2 ^ (a))", "(1, 2, 3)", "[1, 2]", "\"s\"", "\"(\"", "f((1), (a))"])


@st.composite
def _expr(draw, depth=0):
    n = draw(st.integers(1, 6))
    parts = []
    for i in range(n):
        if depth < 3 and draw(st.booleans()) and draw(st.booleans()):
            inner = draw(_expr(depth + 1))
            gap = draw(st.sampled_from(["", " ", "\n  ", " # note\n "]))
            term = f"({gap}{inner}{gap})"
        else:
            term = draw(_atoms)
        if i:
            parts.append(draw(st.sampled_from([" + ", " - ", " * ", " / "])))
        parts.append(term)
    return "".join(parts)


@settings(max_examples=300, deadline=None)
@given(_expr())
def test_generated_chains_give_the_left_recursive_tree(expr):
    source = f"param q = {expr}\n"
    assert repr(_new(source)) == repr(_old(source))


@pytest.mark.parametrize("op", ["+", "-", "*", "/"])
def test_a_thousand_term_chain_checks_and_formats(tmp_path, capsys, op):
    p = tmp_path / "flat.acl"
    unit = " um" if op in "+-" else ""
    p.write_text(f"param a = 1000{unit}\nparam s = a {op} " + f" {op} ".join([f"1.001{unit}"] * 999) + "\n")
    assert main(["check", str(p)]) == 0
    assert main(["fmt", "--check", str(p)]) == 0
    err = capsys.readouterr().err
    assert "E104" not in err and "E-INTERNAL" not in err


def test_deep_nesting_is_still_E104():
    from acl.diagnostics import DiagnosticError

    with pytest.raises(DiagnosticError) as exc:
        _new("param n = " + "-" * 1000 + "1 um\n")
    assert [d.code for d in exc.value.diagnostics] == ["E104"]

"""Property tests: no input text makes the front-end fail with anything but a DiagnosticError.

Random text and mutated valid examples (characters and tokens deleted, duplicated, swapped) go
through `acl.loads` and through `acl check`; the only acceptable failure is a diagnostic.
"""
from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import acl
from acl.cli import main
from acl.diagnostics import DiagnosticError

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "examples").glob("*.acl"))
SOURCES = [(str(p), p.read_text()) for p in EXAMPLES]
TOKEN = re.compile(r"\s+|[A-Za-z_][A-Za-z0-9_]*|\d+(?:\.\d+)?(?:[eE][+-]?\d+)?|\.\.|.", re.S)
FAST = settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])

# Characters the grammar cares about, plus a few it must reject gracefully.
ALPHABET = st.sampled_from(list("abcdeflmnopstuxyzEHkVz0123456789 _.,:;=+-*/^@#()[]{}<>\"'\n\t\\") +
                           ["\x00", "\u00b5", "\u00b0", "\ufeff", "\r"])
WORDS = st.sampled_from(["import ", "stdlib.", "media", "param ", "capsule ", "beam ", "like ", "mount ", " on ",
                         "program ", "drive ", "follow ", "switch ", "hold ", "cross ", "sweep ", "pause ",
                         " free in ", "..", "kHz", " um", " V", " @ ", " for ", "{", "}", "(", ")", "[", "]",
                         "=", ",", "\n", "fix ", "link ", " with ", "observe ", "require ", "gap(", "use "])


def _loads_or_diagnose(text: str, filename: str = "<fuzz>") -> None:
    try:
        acl.loads(text, filename)
    except DiagnosticError as exc:
        assert exc.diagnostics, "a DiagnosticError carries at least one diagnostic"
        for d in exc.diagnostics:
            assert re.fullmatch(r"[EW]\d{3}", d.code), d.code
            assert d.span is None or (d.span.line >= 1 and d.span.column >= 1)


def _mutate(text: str, data, tokens: bool) -> str:
    units = TOKEN.findall(text) if tokens else list(text)
    for _ in range(data.draw(st.integers(1, 4), label="mutations")):
        if not units:
            break
        i = data.draw(st.integers(0, len(units) - 1), label="at")
        op = data.draw(st.sampled_from(["delete", "duplicate", "swap"]), label="op")
        if op == "delete":
            del units[i]
        elif op == "duplicate":
            units.insert(i, units[i])
        else:
            j = data.draw(st.integers(0, len(units) - 1), label="with")
            units[i], units[j] = units[j], units[i]
    return "".join(units)


@FAST
@given(st.text(ALPHABET, max_size=300))
def test_random_characters_only_raise_diagnostics(text):
    _loads_or_diagnose(text)


@FAST
@given(st.lists(WORDS | st.text(ALPHABET, max_size=5), max_size=60).map("".join))
def test_random_keyword_soup_only_raises_diagnostics(text):
    _loads_or_diagnose(text)


@FAST
@given(st.sampled_from(SOURCES), st.data())
def test_examples_with_characters_mutated_only_raise_diagnostics(source, data):
    path, text = source
    _loads_or_diagnose(_mutate(text, data, tokens=False), path)


@FAST
@given(st.sampled_from(SOURCES), st.data())
def test_examples_with_tokens_mutated_only_raise_diagnostics(source, data):
    path, text = source
    _loads_or_diagnose(_mutate(text, data, tokens=True), path)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(st.sampled_from(SOURCES), st.data())
def test_check_command_never_prints_a_traceback(tmp_path_factory, source, data):
    _, text = source
    f = tmp_path_factory.mktemp("fuzz") / "mutant.acl"
    f.write_text(_mutate(text, data, tokens=True), encoding="utf-8")
    fmt = data.draw(st.sampled_from(["text", "json"]), label="format")
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(["check", str(f), "--format", fmt])
        except SystemExit as exc:
            code = exc.code
    assert code in (0, 1), err.getvalue()
    assert "Traceback" not in err.getvalue() and "E-INTERNAL" not in err.getvalue()

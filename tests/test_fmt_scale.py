"""`acl fmt` on large files (issue 11: 12-15 s on a 10,001-line file): the formatter parses its
input once (and its output once, to check the meaning), and the diff of `--check`/`--diff` is not
quadratic. Times are printed by benchmarks/fmt.py, never asserted here; these tests pin the work
done (parses counted, diffs applied back)."""
from __future__ import annotations

import os
import random
import re
import subprocess
import sys
from pathlib import Path

import pytest

import acl.syntax.parser as P
from acl.fmt import format_source
from acl.fmt.diff import _AnchoredMatcher, unified_diff

ROOT = Path(__file__).resolve().parents[1]


def _benchmark():
    import importlib.util

    spec = importlib.util.spec_from_file_location("acl_benchmark_fmt", ROOT / "benchmarks" / "fmt.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


design = _benchmark().design     # the benchmark's messy generated design

_HUNK = re.compile(r"^@@ -(\d+)(?:,(\d+))? \+(\d+)(?:,(\d+))? @@$")


def apply(a: list[str], diff: list[str]) -> list[str]:
    """Apply a unified diff to ``a`` (checking every context and removed line)."""
    out, pos, k = [], 0, 2 if diff else 0
    while k < len(diff):
        m = _HUNK.match(diff[k].rstrip("\n"))
        assert m, diff[k]
        start = int(m.group(1)) - (0 if m.group(2) == "0" else 1)
        out.extend(a[pos:start])
        pos = start
        k += 1
        while k < len(diff) and not diff[k].startswith("@@"):
            tag, line = diff[k][0], diff[k][1:]
            if tag in " -":
                assert a[pos] == line, (pos, a[pos], line)
                pos += 1
            if tag in " +":
                out.append(line)
            k += 1
    return out + a[pos:]


class CountingLark:
    def __init__(self, real):
        self.real, self.parses = real, 0

    def parse(self, *args, **kw):
        self.parses += 1
        return self.real.parse(*args, **kw)


@pytest.fixture
def counting(monkeypatch):
    real = P.lark_parser()
    counter = CountingLark(real)
    monkeypatch.setattr(P, "lark_parser", lambda: counter)
    return counter


def test_formatting_parses_the_input_once_and_the_output_once(counting):
    messy = design(300)
    tidy = format_source(messy)
    assert counting.parses == 2 and tidy != messy
    counting.parses = 0
    assert format_source(tidy) == tidy
    assert counting.parses == 1          # already formatted: nothing to check


@pytest.mark.parametrize("seed", range(200))
def test_the_diff_applied_to_the_original_gives_the_new_text(seed):
    r = random.Random(seed)
    a = [f"{r.randint(0, 9)}\n" for _ in range(r.randint(0, 80))]
    b = [x if r.random() < 0.6 else f"{r.randint(0, 14)}\n" for x in a] + [f"{r.randint(0, 5)}\n" for _ in range(r.randint(0, 6))]
    if seed % 5 == 0:
        r.shuffle(b)
    d = list(unified_diff(a, b, "a", "b"))
    assert apply(a, d) == b
    if a == b:
        assert d == []
    for blk in _AnchoredMatcher(None, a, b, autojunk=False).get_matching_blocks():
        assert a[blk.a:blk.a + blk.size] == b[blk.b:blk.b + blk.size]


def test_the_diff_of_a_reformat_is_no_longer_than_difflibs():
    """On the benchmark's design (1,000 lines, where difflib is still quick) the diff applies back
    and is no longer than difflib's."""
    import difflib

    messy = design(1000)
    tidy = format_source(messy)
    a, b = messy.splitlines(keepends=True), tidy.splitlines(keepends=True)
    ours = list(unified_diff(a, b, "x", "y"))
    assert apply(a, ours) == b
    assert len(ours) <= len(list(difflib.unified_diff(a, b, "x", "y")))


def test_fmt_check_on_a_10000_line_design_prints_a_diff_that_applies(tmp_path):
    messy = design(10_000)
    (tmp_path / "big.acl").write_text(messy)
    r = subprocess.run([sys.executable, "-m", "acl", "fmt", "--check", "big.acl"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=600,
                       env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert r.returncode == 1 and "Traceback" not in r.stderr
    diff = r.stdout.splitlines(keepends=True)
    assert diff[0].startswith("--- big.acl") and apply(messy.splitlines(keepends=True), diff) == \
        format_source(messy).splitlines(keepends=True)
    assert (tmp_path / "big.acl").read_text() == messy

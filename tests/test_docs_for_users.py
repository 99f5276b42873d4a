"""The docs are for users (issue 28, "Docs that teach"): what a page says is about acl, not about its test suite.

A user page is every page under docs/ except docs/contributing.md, the developers' page. Its text as the site
renders it (the ``<!-- doc: ... -->`` markers are HTML comments, invisible there, and are left out) must not send
the reader into the repository's internals: no test module or test data path (`tests/...`), no source file path
(`acl/<module>.py`: a user calls the Python API, `acl.fit(...)`), and benchmark scripts only on the explanation
pages, where a figure's evidence may be rerun. A page holds one idea a user can read in one sitting: at most
6,000 words; a longer one is split into its reference and its explanation.

Before the editorial pass this test failed on 18 pages: 131 `tests/` paths, 55 `acl/*.py` paths and 28 benchmark
mentions in the rendered text, and four pages over 6,000 words (fit.md 19,765).
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
USER_PAGES = sorted(p for p in DOCS.rglob("*.md") if p.name != "contributing.md" and "hooks" not in p.parts)
MAX_WORDS = 6000

COMMENT = re.compile(r"<!--.*?-->", re.S)
INTERNALS = [
    (re.compile(r"(?<![\w./-])tests/"), "a path into the test suite (tests/...)"),
    (re.compile(r"(?<![\w./-])acl/[\w/]+\.py\b"), "a source file path (acl/....py)"),
]
BENCHMARKS = (re.compile(r"(?<![\w./-])benchmarks/"), "a benchmark script outside the explanation pages")
# the generated map from each law to the one function that implements it names the functions' files
SOURCE_PATHS_ALLOWED = {DOCS / "explanation" / "laws.md"}


def rendered(page: Path) -> str:
    """The page's text as the site shows it, with each line kept in place (markers blanked, newlines kept)."""
    text = page.read_text(encoding="utf-8")
    return COMMENT.sub(lambda m: "\n" * m.group(0).count("\n"), text)


def internals(page: Path) -> list[str]:
    text = rendered(page)
    checks = [c for c in INTERNALS if not (page in SOURCE_PATHS_ALLOWED and "acl/" in c[0].pattern)]
    if "explanation" not in page.relative_to(DOCS).parts:
        checks.append(BENCHMARKS)
    found = []
    for number, line in enumerate(text.splitlines(), 1):
        for pattern, what in checks:
            for m in pattern.finditer(line):
                found.append(f"{page.relative_to(ROOT)}:{number}:{m.start() + 1}: {what}: "
                             f"{line[m.start():m.start() + 60]!r}")
    return found


def test_the_user_pages_are_found():
    names = {str(p.relative_to(DOCS)) for p in USER_PAGES}
    assert {"index.md", "fit.md", "tutorials/first-device.md", "explanation/validity.md"} <= names
    assert "contributing.md" not in names


@pytest.mark.parametrize("page", USER_PAGES, ids=lambda p: str(p.relative_to(DOCS)))
def test_a_user_page_does_not_send_the_reader_into_the_repository(page):
    found = internals(page)
    assert not found, "\n".join(found[:40]) + (f"\n... {len(found) - 40} more" if len(found) > 40 else "")


@pytest.mark.parametrize("page", USER_PAGES, ids=lambda p: str(p.relative_to(DOCS)))
def test_a_user_page_can_be_read_in_one_sitting(page):
    words = len(rendered(page).split())
    assert words <= MAX_WORDS, (f"{page.relative_to(ROOT)}: {words} words (at most {MAX_WORDS}): split it into a "
                                "reference page and an explanation page")


def test_the_check_finds_what_it_looks_for(tmp_path):
    """The patterns catch a test path, a source path and a benchmark, and skip markers and look-alikes."""
    page = DOCS / "fit.md"     # a reference page: no benchmarks, no source paths
    sample = tmp_path / "p.md"
    sample.write_text("see tests/test_fit.py and acl/fit/forward.py\nrun benchmarks/fit.py\n"
                      "<!-- doc: = json_of('fit tests/data/x.acl') -->1<!-- /doc --> and examples/tests/ no\n"
                      "mytests/x.py\n", encoding="utf-8")
    text = rendered(sample)
    hits = [(n, m.group(0)) for n, line in enumerate(text.splitlines(), 1)
            for pattern, _ in INTERNALS + [BENCHMARKS] for m in pattern.finditer(line)]
    assert hits == [(1, "tests/"), (1, "acl/fit/forward.py"), (2, "benchmarks/")]
    assert page in USER_PAGES

"""README.md and docs/*.md quote only what a fresh run prints: every `<!-- doc: ... -->` part of a page
is regenerated (tests/docs_sync.py) and must match.  Regenerate with `python tests/docs_sync.py --update`."""
from __future__ import annotations

import pytest

import docs_sync


@pytest.mark.parametrize("page", [pytest.param(p, marks=pytest.mark.studies) if p in ("docs/fit.md", "docs/schedule.md") else p
                                  for p in docs_sync.PAGES if "<!-- doc" in (docs_sync.ROOT / p).read_text()])
def test_page_matches_a_fresh_run(page):
    diffs = docs_sync.stale([page])
    assert not diffs, (f"{page} quotes output that a fresh run no longer prints; regenerate with "
                       f"`python tests/docs_sync.py --update {page}` and review the diff:\n" + diffs[page][0])


def test_harness_regenerates_commands_values_and_sessions(tmp_path):
    page = ("<!-- doc-run: acl synth samples/fit_cantilever.acl -o s.csv --voltages 0V..2V:3 -->\n"
            "<!-- doc: $ acl check examples/fig2_vertical_cantilever.acl -->stale<!-- /doc -->\n"
            "<!-- doc: $ acl check nowhere.acl -> exit 2 --><!-- /doc -->\n"
            "rows: <!-- doc: = len(open('s.csv').read().splitlines()) - 1 -->0<!-- /doc -->\n"
            "<!-- doc: doctest -->\n```python\n>>> 6 * 7\n41\n>>> x = 1\n```\n<!-- /doc -->\n")
    out = docs_sync.render("example.md", page)
    assert "ok examples/fig2_vertical_cantilever.acl: 1 capsules" in out and "stale" not in out
    assert "E601" in out
    assert "rows: <!-- doc: = len(open('s.csv').read().splitlines()) - 1 -->3<!-- /doc -->" in out
    assert ">>> 6 * 7\n42\n>>> x = 1\n```" in out
    assert docs_sync.render("example.md", out) == out          # a fresh page is a fixed point


def test_a_command_that_fails_unexpectedly_is_an_error():
    with pytest.raises(docs_sync.DocError):
        docs_sync.render("example.md", "<!-- doc: $ acl check nowhere.acl --><!-- /doc -->")


def test_numbers_compare_to_a_relative_tolerance_and_text_exactly():
    assert docs_sync.same("d_c = 48.6 um, r = 5.0e-26", "d_c = 48.6 um, r = 3.1e-25")
    assert docs_sync.same("f = 123139.0 Hz", "f = 123139.2 Hz")
    assert not docs_sync.same("d_c = 56.5 um", "d_c = 48.6 um")
    assert not docs_sync.same("3 programs", "1 programs")
    assert not docs_sync.same("attract", "repel")

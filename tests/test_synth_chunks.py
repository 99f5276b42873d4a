"""`acl synth` predicts its rows in chunks and writes them as a stream (issue 29, item 6).

`acl synth --voltages 0V..10V:2000000` (the documented row limit) peaked at 6.4 GB for a 103 MB CSV: every
row's Span object, the model's intermediates for all rows at once, and the whole CSV text in memory.  Rows
are now predicted :data:`acl.fit.synth.CHUNK_ROWS` at a time and written block by block; here the chunked
output is compared byte for byte with the one-chunk output (the memory figure is in benchmarks/, not timed).
"""
from __future__ import annotations

import os

import pytest

import acl.fit.synth as S
from acl.cli import main

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "samples")

CASES = {
    "cantilever": ["fit_cantilever.acl", "--voltages", "0V..2V:37", "--noise", "0.02um"],
    "pair, swept gap": ["fit_pair.acl", "--voltages", "0V..2V:7", "--sweep", "gap=30um,40um,50um", "--noise", "0.02um"],
    "latch state": ["fit_latch_state.acl", "--voltages", "0V..100V:9", "--noise", "0.02um"],
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_chunked_rows_are_the_rows(tmp_path, monkeypatch, case):
    design, *rest = CASES[case]
    argv = ["synth", os.path.join(DATA, design), *rest, "-q"]
    assert main([*argv, "-o", str(tmp_path / "whole.csv")]) == 0
    monkeypatch.setattr(S, "CHUNK_ROWS", 5)
    assert main([*argv, "-o", str(tmp_path / "chunks.csv")]) == 0
    whole = (tmp_path / "whole.csv").read_bytes()
    assert whole.count(b"\n") > 10
    assert (tmp_path / "chunks.csv").read_bytes() == whole


def test_row_spans_are_made_on_demand():
    spans = S.RowSpans(3)
    assert len(spans) == 3 and spans[0].line == 2 and spans[-1].line == 4
    assert [s.line for s in spans[1:]] == [3, 4]
    with pytest.raises(IndexError):
        spans[3]

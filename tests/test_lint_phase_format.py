"""ACL201's note prints the pair's phase difference in whole degrees and never as "-0 deg" (a symmetric pair's
phase is 0 up to rounding, of either sign)."""
from __future__ import annotations

from pathlib import Path

from acl.lint import LintConfig, lint_file

DATA = Path(__file__).parent.parent / "samples"


def test_snap_in_note_of_a_symmetric_pair_says_0_deg():
    res = lint_file(str(DATA / "sweep_drives.acl"), LintConfig())
    notes = [n for d in res.findings if d.code == "ACL201" for n in d.notes if "phase difference" in n]
    assert notes, "sweep_drives.acl's facing pair snaps in under its 6 V drive"
    assert all("phase difference 0 deg" in n for n in notes), notes

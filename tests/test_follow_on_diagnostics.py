"""One mistake, one diagnostic: a capsule linked to one that failed is not reported again (issue 28).

Tried as a new user on Fig. 6e's latch with a value out of range (E305 on `latch_youngs = 1e308 MPa`, E412 on
a 1e308 um flexure): the latch fails, so the capsule mounted on its shuttle is unplaced, and the capsule
`link`ed to that one by a truss was reported as well, W401 "not attached to anything", although the file
attaches it and the one error is elsewhere.
"""
from __future__ import annotations

import os
import shutil

import pytest

from acl.cli import main

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")


@pytest.mark.parametrize("old,new,code", [
    ("param latch_youngs = 2.8315 MPa", "param latch_youngs = 1e308 MPa", "E305"),
    ("length = 50 um", "length = 1e308 um", "E412"),
])
def test_a_trussed_capsule_of_a_failed_latch_is_not_called_unattached(tmp_path, capsys, old, new, code):
    shutil.copytree(os.path.join(ROOT, "examples"), tmp_path / "examples")
    f = tmp_path / "examples" / "fig6e_reversible_latch.acl"
    text = f.read_text(encoding="utf-8")
    assert text.count(old) == 1
    f.write_text(text.replace(old, new), encoding="utf-8")
    assert main(["check", str(f)]) == 1
    err = capsys.readouterr().err
    assert f"error[{code}]" in err and "W401" not in err, err
    assert "Traceback" not in err


def test_the_example_itself_still_checks_clean(capsys):
    assert main(["check", os.path.join(ROOT, "examples", "fig6e_reversible_latch.acl")]) == 0
    assert "W401" not in capsys.readouterr().err

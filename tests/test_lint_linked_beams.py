"""ACL401/402 on beams whose capsule is linked by a truss: the free-cantilever load does not apply."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

GRIPPER = Path(__file__).resolve().parents[1] / "examples" / "fig5a_gripper.acl"


def lint(*args):
    return subprocess.run([sys.executable, "-m", "acl", "lint", "--format", "concise", *args],
                          capture_output=True, text=True, timeout=300)


def test_linked_beam_is_not_judged_as_a_free_cantilever():
    r = lint("--select", "ACL401,ACL402", "--verbose", str(GRIPPER))
    assert "ACL401 " not in r.stdout and "ACL402 " not in r.stdout
    assert "linked by a truss" in r.stdout + r.stderr     # says why it was not checked


def test_with_mechanics_the_linked_beam_is_checked_through_the_equilibrium():
    r = lint("--select", "ACL401,ACL402", "--mechanics", str(GRIPPER))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "ACL401 " not in r.stdout     # the trusses carry the load: zero arm deflection

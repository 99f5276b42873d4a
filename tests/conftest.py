"""Test configuration: hypothesis explores freely on developer machines; in CI (CI=true) its
examples are derandomized so a submission's result does not depend on a lucky draw.

The suite runs on pytest-xdist workers (``-n auto`` in pyproject.toml).  A worker inherits
``COLUMNS=80``/``LINES=24`` from xdist, and an explicit ``COLUMNS`` makes acl's consoles lay out
for that width (acl/_console.py), wrapping a long ``file:line:column`` the tests look for; the
commands under test must see what a user's pipe gives them, so a worker drops both."""
from __future__ import annotations

import os

from hypothesis import settings

if os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ.pop("COLUMNS", None)
    os.environ.pop("LINES", None)

settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


# The files that take longest (pytest --durations on two workers, 2026-11-27: docs/fit.md's regeneration 240 s,
# the committed fit-diagnosis runs, the closed-loop studies, ...) run first: a worker that draws one of them last
# keeps the run going alone for minutes while the other has finished.  Whole files move (their order inside is
# kept), so module fixtures are still set up once.
SLOW_FIRST = ("test_docs_sync.py", "test_fit_diagnosis.py", "test_fit_bodies.py", "test_closed_loop.py",
              "test_fit_coupled.py", "test_fit_one_physics.py", "test_cli_output.py", "test_fit_mechanisms.py",
              "test_fit_fig4e.py", "test_sweep_mechanism.py")


def pytest_collection_modifyitems(session, config, items):
    rank = {name: i for i, name in enumerate(SLOW_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(SLOW_FIRST)))

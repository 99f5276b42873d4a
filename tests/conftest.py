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

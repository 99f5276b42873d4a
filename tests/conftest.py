"""Test configuration: hypothesis explores freely on developer machines; in CI (CI=true) its
examples are derandomized so a submission's result does not depend on a lucky draw."""
from __future__ import annotations

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

"""In CI (`CI=true`, set by .ci/run) the headless clients that the editor and browser tests drive are
installed: without one, its tests skip, and a CI run would pass without ever driving it.  .ci/run
installs the missing ones (Debian packages); this test says which are still missing.  On a
developer's machine it skips (the tests that need a client say so themselves)."""
from __future__ import annotations

import os
import shutil
import subprocess

import pytest

CLIENTS = {    # what runs it -> (the tests that need it, the Debian package)
    "chromium": ("tests/test_docs_site.py", "chromium"),
    "nvim": ("tests/test_lsp_neovim.py, tests/test_lsp_neovim_requests.py", "neovim"),
    "emacs": ("tests/test_lsp_eglot.py", "emacs-nox elpa-eglot"),
    "npm": ("tests/test_lsp_editors.py (vsce package)", "npm"),
    "script": ("tests/test_lsp_editors.py (vsce package on a terminal)", "util-linux"),
}


def _missing() -> list[str]:
    out = [f"{exe} ({why}; apt-get install {pkg})" for exe, (why, pkg) in CLIENTS.items() if shutil.which(exe) is None]
    emacs = shutil.which("emacs")
    if emacs is not None:
        probe = subprocess.run([emacs, "--batch", "--eval", "(require 'eglot)"], capture_output=True,
                               stdin=subprocess.DEVNULL, timeout=60)
        if probe.returncode != 0:
            out.append("eglot in Emacs (tests/test_lsp_eglot.py; apt-get install elpa-eglot)")
    return out


def test_ci_has_every_headless_client_the_tests_drive():
    if not os.environ.get("CI"):
        pytest.skip("not CI (CI=true): a missing client only skips its own tests")
    assert not _missing(), "missing in CI: " + "; ".join(_missing())


def test_the_missing_list_names_an_absent_client(monkeypatch):
    real = shutil.which
    monkeypatch.setattr(shutil, "which", lambda name: None if name == "nvim" else real(name))
    assert any(m.startswith("nvim (") and "apt-get install neovim" in m for m in _missing())

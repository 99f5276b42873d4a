"""Test configuration: hypothesis explores freely on developer machines; in CI (CI=true) its
examples are derandomized so a submission's result does not depend on a lucky draw.

The suite runs on pytest-xdist workers (``-n auto`` in pyproject.toml).  A worker inherits
``COLUMNS=80``/``LINES=24`` from xdist, and an explicit ``COLUMNS`` makes acl's consoles lay out
for that width (acl/_console.py), wrapping a long ``file:line:column`` the tests look for; the
commands under test must see what a user's pipe gives them, so a worker drops both."""
from __future__ import annotations

import os

import pytest
from hypothesis import settings

if os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ.pop("COLUMNS", None)
    os.environ.pop("LINES", None)

settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


# The files that take longest run first: a worker that draws one of them last keeps the run going alone while the
# other has finished.  Whole files move (their order inside is kept), so module fixtures are still set up once.
# pytest --durations on two workers, 2026-11-27: the studies (`-m studies`: docs/fit.md's regeneration 137 s, a
# body-pair fit-diagnosis run 95 s, the group recovery through snap-in 103 s, the coupled pair fits 130 s, the Fig. 3
# closed loop 55 s, ...) and, in the default run, the edge-of-range end-to-end run 27 s, the body-pair thrust fit
# 17 s, the stroke closed loop 14 s, the umask run 14 s, the two-worker fit search 12 s.
SLOW_FIRST = ("test_docs_sync.py", "test_fit_bodies.py", "test_fit_diagnosis.py", "test_fit_coupled.py",
              "test_closed_loop.py", "test_fit_one_physics.py", "test_effect_ranges.py", "test_cli_output.py",
              "test_fit_jobs.py", "test_fit_fig4e.py", "test_sweep_mechanism.py", "test_hostile_corpus.py",
              "test_lsp.py", "test_fmt.py")


def pytest_collection_modifyitems(session, config, items):
    rank = {name: i for i, name in enumerate(SLOW_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(SLOW_FIRST)))


@pytest.fixture
def saved_figures(monkeypatch):
    """The figures acl saves during a test, by file name in the order saved: matplotlib's ``savefig`` is
    recorded (and still writes the file).  Skips without matplotlib (the plot extra)."""
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.figure

    saved = {}
    orig = matplotlib.figure.Figure.savefig

    def grab(fig, path, *a, **k):
        out = orig(fig, path, *a, **k)
        saved[os.path.basename(str(path))] = fig
        return out

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", grab)
    return saved


@pytest.fixture(scope="session")
def fig3():
    """The paper's three-orifice module (examples/fig3_three_orifice.acl, Fig. 3), resolved once per worker."""
    import acl

    return acl.load(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples", "fig3_three_orifice.acl"))

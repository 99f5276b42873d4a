"""`uncertainty { lognormal(a, ...) }`: positive uncertain parameters drawn log-normal (acl.schedule.bands, acl sweep).

A calibration's poorly identified positive coefficients (a pair's gamma and alpha tied in ratio by the data:
relative standard errors above 1, correlation 0.999) drawn from their normal go negative in a large share of draws,
which then count as failing (error and margin bands: conservative, but uninformative).  The log-normal of the same
mean and covariance stays positive and keeps the ratio the data tie.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import acl
from acl.diagnostics import DiagnosticError
from acl.schedule.bands import Uncertainty, _chol, declared, draw_params, log_moments, sample_designs

ROOT = Path(__file__).resolve().parents[1]
EX = ROOT / "examples"


def _errors(text):
    with pytest.raises(DiagnosticError) as exc:
        acl.loads(text, "u.acl")
    return [(d.code, d.span.line, d.span.column) for d in exc.value.diagnostics if d.is_error]


def test_lognormal_entry_resolves_and_shows(tmp_path):
    text = ("param g = 27 pN/V^2 +- 2 pN/V^2\nparam a = 3 um +- 1 um\nparam s = -1 +- 1\n"
            "uncertainty {\n  correlation(g, a) = 0.5\n  lognormal(g, a)\n}\n")
    d = acl.loads(text, "u.acl")
    assert d.lognormal == ("g", "a")
    assert declared(d).log == (True, True, False)
    f = tmp_path / "u.acl"
    f.write_text(text)
    out = subprocess.run([sys.executable, "-m", "acl", "show", str(f), "--json"], capture_output=True, text=True,
                         env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["lognormal"] == ["g", "a"]


@pytest.mark.parametrize("text, code, line, col", [
    ("param s = -1 +- 1\nuncertainty { lognormal(s) }\n", "E325", 2, 25),              # not positive
    ("param e = 2\nuncertainty { lognormal(e) }\n", "E323", 2, 25),                    # no +- s
    ("param g = 2 +- 1\nuncertainty { lognormal(zz) }\n", "E323", 2, 25),               # unknown name
    ("param u = 2 +- 10 %\nuncertainty { lognormal(u) }\n", "E325", 2, 25),             # its own distribution
    ("param g = 2 +- 1\nuncertainty {\n lognormal(g)\n lognormal(g)\n}\n", "E325", 4, 12),   # twice
    ("param g = 2 +- 1\nuncertainty { lognormal(3) }\n", "E325", 2, 15),                # not a name
    ("param g = 2 +- 1\nuncertainty { lognormal() }\n", "E325", 2, 15),                 # nothing named
    ("param g = 2 +- 1\nuncertainty { lognormal(g) = 2 }\n", "E325", 2, 30),            # takes no value
    ("uncertainty { covered(voltage) }\n", "E325", 1, 15),                               # others need one
])
def test_bad_lognormal_is_a_located_diagnostic(text, code, line, col):
    errs = _errors(text)
    assert (code, line, col) in errs, errs


def test_cli_bad_lognormal_exits_1_without_traceback(tmp_path):
    f = tmp_path / "bad.acl"
    f.write_text("param s = -1 +- 1\nuncertainty { lognormal(s) }\n")
    out = subprocess.run([sys.executable, "-m", "acl", "check", str(f)], capture_output=True, text=True,
                         env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert out.returncode == 1 and "Traceback" not in out.stderr
    assert "bad.acl:2:25: error[E325]" in out.stdout + out.stderr


def _draws(m, sd, R, log, n=200_000, seed=1):
    C = np.asarray(R) * np.outer(sd, sd)
    unc = Uncertainty(0.0, 0.0, 0, tuple("abc"[:len(m)]), np.asarray(m, float), C, ("",) * len(m), (), tuple(log))
    mu, S = log_moments(unc.mean, unc.cov, unc.log)
    rng = np.random.default_rng(seed)
    L = _chol(S)
    return np.array([draw_params(unc, rng, L, mu) for _ in range(n)]), C


def test_lognormal_draws_keep_mean_and_covariance_and_stay_positive():
    """Moment matching (Johnson, Kotz & Balakrishnan, ch. 45; Stein's lemma for the mixed pair): sample mean,
    standard deviation and correlation within a few standard errors of the declared ones; never <= 0."""
    m, sd = [2.0, 3.0, -1.0], [0.6, 0.9, 0.5]
    X, C = _draws(m, sd, [[1, 0.6, 0.3], [0.6, 1, -0.2], [0.3, -0.2, 1]], (True, True, False))
    assert X[:, :2].min() > 0
    n = len(X)
    assert np.allclose(X.mean(axis=0), m, atol=4 * np.array(sd) / np.sqrt(n))
    assert np.allclose(X.std(axis=0), sd, rtol=0.02)
    assert np.allclose(np.corrcoef(X.T), C / np.outer(sd, sd), atol=0.02)


def test_a_ratio_the_data_tie_stays_tied():
    """The pair-hold case (docs/fit.md): gamma and alpha with relative standard errors 3.46, correlation 0.999.
    A normal draw goes negative in about 39 % of draws; the log-normal never, and gamma/alpha varies by a few
    percent (log sd) where each alone varies by a factor of 5 (log sd 1.6)."""
    m, sd, R = [1.0, 1.0], [3.46, 3.46], [[1, 0.999], [0.999, 1]]
    Xn, _ = _draws(m, sd, R, (False, False), n=20_000)
    Xl, _ = _draws(m, sd, R, (True, True), n=20_000)
    assert 0.37 < np.mean(np.any(Xn <= 0, axis=1)) < 0.41      # Phi(-1 / 3.46) = 0.386
    assert Xl.min() > 0
    assert np.std(np.log(Xl[:, 0])) > 1.4
    assert np.std(np.log(Xl[:, 0] / Xl[:, 1])) < 0.05


def test_impossible_log_correlation_keeps_the_variances():
    """Two log-normals of very different spreads cannot have correlation 0.999 in value: the nearest valid
    correlation is drawn and the variances still match (acl.schedule.bands._valid_cov)."""
    m, sd = [2.0, 3.0], [0.2, 9.0]
    mu, S = log_moments(np.array(m), np.array([[1, 0.999], [0.999, 1]]) * np.outer(sd, sd), (True, True))
    assert np.linalg.eigvalsh(S).min() >= -1e-12
    assert np.allclose(np.diag(S), np.log1p((np.array(sd) / m) ** 2))


def test_sample_designs_resolve_every_lognormal_draw(tmp_path):
    """A thrust coefficient 27 +- 40 pN/V^2: from its normal, about a quarter of the draws are negative and the
    design does not resolve (E401: a thrust coefficient is a magnitude); declared lognormal, every draw resolves."""
    import shutil

    for name in ("fig2_vertical_cantilever.acl", "fig2_stroke.acl"):
        shutil.copy(EX / name, tmp_path)
    base = ('extends "fig2_stroke.acl"\nparam g = 27 pN/V^2 +- 40 pN/V^2\n'
            "capsule act like capsules.design1 { thrust = g }\n")
    out = {}
    for tag, extra in (("normal", ""), ("lognormal", "uncertainty { lognormal(g) }\n")):
        f = tmp_path / f"{tag}.acl"
        f.write_text(base + extra)
        d = acl.load(str(f))
        draws = list(sample_designs(d, 40, seed=2, reload=lambda ov, f=f: acl.load(str(f), overrides=ov)))
        out[tag] = [x for _, x in draws]
    assert sum(x is None for x in out["normal"]) >= 4
    assert all(x is not None for x in out["lognormal"])
    thrust = [x.capsule("act").thrust_coefficient for x in out["lognormal"]]
    assert min(thrust) > 0 and max(thrust) > 2 * 27e-12


def test_sweep_samples_a_lognormal_parameter_positive():
    from acl.design.model import Spread
    from acl.sweep.sample import apply_spread

    z = np.random.default_rng(0).standard_normal(400_000)
    x = apply_spread(Spread(kind="lognormal", a=0.0, b=2.0, relative=True), np.full(z.size, 3.0), z)
    assert x.min() > 0
    assert x.mean() == pytest.approx(3.0, rel=0.03) and np.median(x) == pytest.approx(3.0 / np.sqrt(5.0), rel=0.01)
    assert Spread(kind="lognormal", a=0.0, b=2.0, relative=True).stddev(3.0) == pytest.approx(6.0)

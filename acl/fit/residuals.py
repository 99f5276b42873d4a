"""Structure in a residual: trend, runs and heteroscedasticity against every covariate the data have.

For each covariate with at least 3 distinct values: Spearman rank correlation of residual vs
covariate (trend), the Wald-Wolfowitz runs test on the residual signs ordered by the covariate
(curvature, plateaus, any non-monotone structure), Spearman correlation of |residual| vs
covariate (heteroscedasticity, a Breusch-Pagan-like check robust to outliers) and, for covariates
with few distinct values (frequencies, set: values), the Kruskal-Wallis test of the residual grouped
by value (a level that stands out, e.g. one frequency).  A finding is
reported when its Bonferroni-adjusted p-value (over all tests run) is below ``alpha``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

ALPHA = 0.01
MAX_LEVELS = 20      # covariates with at most this many distinct values also get a groups test


@dataclass
class Test:
    covariate: str
    test: str              # "trend" | "runs" | "heteroscedasticity" | "groups"
    statistic: float
    p_value: float
    p_adjusted: float = 1.0

    def as_dict(self):
        return {"covariate": self.covariate, "test": self.test, "statistic": _num(self.statistic),
                "p_value": _num(self.p_value), "p_adjusted": _num(self.p_adjusted)}


def covariates(data, P, prediction, predicted_name: str = "prediction") -> dict[str, np.ndarray]:
    """Covariates of each row: voltage (sum of tone amplitudes), frequency (strongest tone),
    time, every numeric set: column, the predicted value (named ``predicted deflection``, ``predicted
    gap`` or ``predicted position`` after the observables, ``prediction`` if mixed) and the
    actuator height above the substrate."""
    out = {}
    out["voltage"] = P.v.sum(axis=1)
    strongest = np.argmax(P.v, axis=1)
    out["frequency"] = P.f[np.arange(P.n), strongest]
    if data.has_time:
        out["time"] = np.where(np.isfinite(data.time), data.time, np.nan)
    for k, v in data.set_si.items():
        out[f"set:{k}"] = v
    out[predicted_name] = prediction
    out["height"] = P.height[0]
    return out


def runs_test(signs_in_order) -> tuple[float, float]:
    """Wald-Wolfowitz runs test (normal approximation): (z, two-sided p)."""
    s = np.asarray(signs_in_order)
    s = s[s != 0]
    n1, n2 = int(np.sum(s > 0)), int(np.sum(s < 0))
    n = n1 + n2
    if n1 == 0 or n2 == 0 or n < 3:
        return float("nan"), 1.0
    runs = 1 + int(np.sum(s[1:] != s[:-1]))
    mu = 2.0 * n1 * n2 / n + 1
    var = 2.0 * n1 * n2 * (2.0 * n1 * n2 - n) / (n * n * (n - 1))
    if var <= 0:
        return float("nan"), 1.0
    z = (runs - mu) / math.sqrt(var)
    return float(z), float(math.erfc(abs(z) / math.sqrt(2)))


def examine(residual, cov: dict[str, np.ndarray], weights=None, seed: int = 0) -> list[Test]:
    """Every test on every usable covariate, p-values Bonferroni-adjusted over the whole list."""
    from scipy.stats import kruskal, spearmanr

    r = np.asarray(residual, float) * (1.0 if weights is None else np.asarray(weights, float))
    rng = np.random.default_rng(seed)
    tests: list[Test] = []
    for name, x in cov.items():
        x = np.asarray(x, float)
        ok = np.isfinite(x) & np.isfinite(r)
        if np.unique(x[ok]).size < 3 or ok.sum() < 8:
            continue
        xs, rs = x[ok], r[ok]
        rho, p = spearmanr(xs, rs)
        tests.append(Test(name, "trend", float(rho), float(p) if np.isfinite(p) else 1.0))
        order = np.lexsort((rng.random(xs.size), xs))     # ties broken at random, fixed seed
        z, p = runs_test(np.sign(rs[order]))
        tests.append(Test(name, "runs", z, p))
        rho, p = spearmanr(xs, np.abs(rs))
        tests.append(Test(name, "heteroscedasticity", float(rho), float(p) if np.isfinite(p) else 1.0))
        levels = np.unique(xs)
        if 3 <= levels.size <= MAX_LEVELS:
            groups = [rs[xs == v] for v in levels]
            if min(g.size for g in groups) >= 2:
                h, p = kruskal(*groups)
                tests.append(Test(name, "groups", float(h), float(p) if np.isfinite(p) else 1.0))
    m = max(len(tests), 1)
    for t in tests:
        t.p_adjusted = min(1.0, t.p_value * m)
    return tests


def structured(tests: list[Test], alpha: float = ALPHA) -> list[Test]:
    return sorted([t for t in tests if t.p_adjusted < alpha], key=lambda t: t.p_value)


def _num(x):
    x = float(x)
    return x if math.isfinite(x) else None


def scatter_test(weighted_residual, dof) -> tuple[float, float]:
    """Chi-square test of excess scatter of one group: sum (r/sigma)^2 against chi2(dof), one-sided (p of that much or more)."""
    from scipy.stats import chi2

    s = float(np.sum(np.asarray(weighted_residual, float) ** 2))
    return s / max(dof, 1e-9), float(chi2.sf(s, max(dof, 1e-9)))


def examine_groups(residual, cov: dict[str, np.ndarray], weights, labels: dict[str, np.ndarray], n_params: int,
                   sigma_given: bool, seed: int = 0) -> list[Test]:
    """Residual tests per observable and per experiment (each label family with 2+ groups), besides the pooled ones.

    For each group: its own covariate tests (as :func:`examine`, covariate named ``[observable d] voltage``)
    and a **scatter** test: with sigma given, the chi-square of its weighted residual against its share of
    the degrees of freedom (an observable left at 1.2 sigma shows as chi2/dof = 1.44); without sigma, an
    F-test of its variance against the other rows'.  Across groups, a **groups** test (Kruskal-Wallis)
    of the weighted residual by label.  p-values are Bonferroni-adjusted within two families: the
    scatter and groups tests, and the covariate tests inside the groups.
    """
    from scipy.stats import f as fdist
    from scipy.stats import kruskal

    r = np.asarray(residual, float) * np.asarray(weights, float)
    n = r.size
    tests: list[Test] = []
    for family, lab in labels.items():
        lab = np.asarray(lab, dtype=object)
        levels = [x for x in dict.fromkeys(lab.tolist())]
        if len(levels) < 2:
            continue
        groups = []
        for level in levels:
            m = lab == level
            groups.append(r[m])
            name = f"[{family} {level}]"
            sub = {f"{name} {k}": np.asarray(v)[m] for k, v in cov.items()}
            for t in examine(residual[m], sub, np.asarray(weights)[m], seed):
                tests.append(t)
            dof = m.sum() * (1.0 - n_params / max(n, 1))
            if sigma_given:
                stat, p = scatter_test(r[m], dof)
            else:
                rest = r[~m]
                v_in = float(np.sum(r[m] ** 2)) / max(dof, 1)
                v_out = float(np.sum(rest ** 2)) / max(rest.size * (1.0 - n_params / max(n, 1)), 1)
                stat = v_in / max(v_out, 1e-300)
                p = float(fdist.sf(stat, max(dof, 1), max(rest.size - n_params, 1)))
            tests.append(Test(f"{name}", "scatter", stat, p))
        if min(g.size for g in groups) >= 2:
            h, p = kruskal(*groups)
            tests.append(Test(family, "groups", float(h), float(p) if np.isfinite(p) else 1.0))
    # Bonferroni within two families: the scatter and groups tests (one per group / label family), and the
    # covariate tests inside the groups (many, correlated with the pooled ones)
    level = [t for t in tests if t.test in ("scatter", "groups") and not t.covariate.startswith("[") or t.test == "scatter"]
    inner = [t for t in tests if t not in level]
    for fam in (level, inner):
        m = max(len(fam), 1)
        for t in fam:
            t.p_adjusted = min(1.0, t.p_value * m)
    return tests

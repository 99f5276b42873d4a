"""Robust design (``acl tune``): choose a design's ``free`` parameters to maximise the yield of its
``require``s under the declared print tolerances.

The problem, stage by stage:

* the design's ``free`` parameters (``param x = v free in lo .. hi``) are the unknowns, searched in
  their box (scaled to the unit cube);
* the tolerances (declared ``+- ...`` spreads and ``--tolerance``) are sampled once: common random
  numbers (one seed, the same chunks of :mod:`acl.sweep.sample` at every trial point), so the
  sample-average objective is a deterministic function of the free values;
* at a trial point the design is re-resolved with the free values (about a millisecond), the
  sample drawn about it, and every ``require`` evaluated for all samples at once, vectorised
  (:mod:`acl.sweep.perturb`, :mod:`acl.sweep.evaluate`): a margin per sample and requirement, in
  the requirement's unit (value minus bound; nan where a point is invalid, counted as failing);
* the objective: ``yield`` maximises the sample-average fraction passing every requirement,
  searched on a smoothed indicator (a logistic of the margin in units of its spread, so the
  derivative-free search sees a slope where the exact yield is flat) and judged on the exact
  count; ``margin`` maximises the worst case over the sample of the smallest margin (each
  requirement's margin in units of its spread at the start);
* the search is derivative-free in the box: a Latin hypercube scan, then Nelder-Mead (or Powell,
  or differential evolution) from the best point;
* the written values (rounded to :data:`DIGITS` significant digits) are validated on a fresh
  sample drawn from chunks the search never saw, before and after, each yield with a
  Clopper-Pearson 95 % interval (exact, conservative: a lab builds on it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

OBJECTIVES = ("yield", "margin")
METHODS = ("nelder-mead", "powell", "differential-evolution")
DIGITS = 6                       # significant digits of a written value (and of the validated one)
SMOOTHING = 0.5                  # logistic width of the smoothed yield, in units of a margin's spread
CONFIDENCE = 0.95


# ------------------------------------------------------------------------------------------------
# Results
# ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Estimate:
    """A yield: ``passed`` of ``n`` samples, with a Clopper-Pearson interval at :data:`CONFIDENCE`."""

    passed: int
    n: int

    @property
    def value(self) -> float:
        return self.passed / self.n if self.n else float("nan")

    @property
    def interval(self) -> tuple[float, float]:
        return clopper_pearson(self.passed, self.n)

    def text(self, digits: int = 3) -> str:
        lo, hi = self.interval
        return f"{self.value:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


def clopper_pearson(k: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Exact binomial interval of a proportion k/n (Clopper & Pearson, Biometrika 26, 404 (1934))."""
    from scipy.stats import beta

    if n <= 0:
        return float("nan"), float("nan")
    a = (1 - confidence) / 2
    lo = 0.0 if k == 0 else float(beta.ppf(a, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a, k + 1, n - k))
    return lo, hi


@dataclass(frozen=True)
class Free:
    """A free parameter: its name, SI unit, box and starting value (SI)."""

    name: str
    unit: str
    lower: float
    upper: float
    start: float


@dataclass
class Search:
    """What the optimiser found, in SI; ``history`` holds (x, score, exact yield) of every trial."""

    x: np.ndarray
    score: float
    evaluations: int
    history: list = field(default_factory=list)


# ------------------------------------------------------------------------------------------------
# Objectives on a matrix of margins (samples x requirements)
# ------------------------------------------------------------------------------------------------

def passing(margins: np.ndarray) -> np.ndarray:
    """Samples passing every requirement (a nan margin, an invalid point, fails)."""
    m = np.asarray(margins, float)
    return np.all(np.nan_to_num(m, nan=-np.inf) >= 0, axis=1)


def spreads(margins: np.ndarray) -> np.ndarray:
    """Per requirement, the standard deviation of its margin over the sample (the scale the search uses).

    A requirement the tolerances do not move (spread 0) gets a scale of 1e-3 of its typical
    margin magnitude, or 1 when that is 0 too, so it still counts but cannot dominate.
    """
    m = np.asarray(margins, float)
    with np.errstate(all="ignore"):
        sd = np.nanstd(m, axis=0)
        typical = np.nanmedian(np.abs(m), axis=0)
    fallback = np.where(np.isfinite(typical) & (typical > 0), typical * 1e-3, 1.0)
    return np.where(np.isfinite(sd) & (sd > 0), sd, fallback)


def normalised_worst(margins: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Per sample, the smallest margin over the requirements in units of each one's spread (-inf if invalid)."""
    z = np.asarray(margins, float) / scale
    return np.min(np.nan_to_num(z, nan=-np.inf), axis=1)


def score(margins: np.ndarray, scale: np.ndarray, objective: str) -> float:
    """What the search maximises: the smoothed yield, or the worst-case normalised margin."""
    g = normalised_worst(margins, scale)
    if objective == "margin":
        return float(np.min(g)) if g.size else -math.inf
    with np.errstate(over="ignore"):
        return float(np.mean(1.0 / (1.0 + np.exp(-g / SMOOTHING))))


# ------------------------------------------------------------------------------------------------
# The search
# ------------------------------------------------------------------------------------------------

def rounded(x: np.ndarray, digits: int = DIGITS) -> np.ndarray:
    """Values as they are written (``digits`` significant digits)."""
    return np.array([float(f"{v:.{digits}g}") for v in np.asarray(x, float)])


def maximise(evaluate: Callable[[np.ndarray], np.ndarray], free: Sequence[Free], objective: str = "yield",
             method: str = "nelder-mead", max_evals: int = 200, seed: int = 0,
             progress: Callable[[int, int, float], None] | None = None,
             evaluate_many: Callable[[list], list] | None = None) -> Search:
    """Maximise the objective over the box of ``free``; ``evaluate(x_SI) -> margins (n, R)``.

    The margin scales are fixed at the start (so the objective does not move during the search);
    the best trial by exact yield (then by score) is returned, never worse than the start.
    ``evaluate_many([x, ...]) -> [margins, ...]`` (optional, e.g. on a cluster) evaluates the trials
    the search knows in advance (the scan, each differential-evolution generation, the first
    simplex) together; the trials, their order and the result are the same as without it, as
    long as it returns what ``evaluate`` would.
    """
    from scipy.optimize import differential_evolution, minimize
    from scipy.stats import qmc

    if objective not in OBJECTIVES:
        raise ValueError(f"objective must be one of {OBJECTIVES}")
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}")
    lo = np.array([f.lower for f in free], float)
    hi = np.array([f.upper for f in free], float)
    width = np.where(hi > lo, hi - lo, 1.0)
    start = np.array([f.start for f in free], float)
    to_x = lambda u: rounded(lo + np.clip(u, 0.0, 1.0) * width)         # noqa: E731 (SI, as written)
    start_written = rounded(start)
    m0 = evaluate(start_written)
    scale = spreads(m0)
    history: list = []
    cache: dict[tuple, float] = {}
    budget = max(1, int(max_evals))
    ahead: dict[tuple, np.ndarray] = {}          # margins evaluated in advance by evaluate_many

    def prefetch(us) -> None:
        """Evaluate together the trials ``us`` that ``trial`` would evaluate next (within the budget)."""
        if evaluate_many is None:
            return
        xs, seen = [], set()
        for u in us:
            x = to_x(np.asarray(u, float))
            key = tuple(x)
            if key in cache or key in ahead or key in seen or np.array_equal(x, start_written):
                continue
            if len(history) + len(xs) >= budget:
                break
            seen.add(key)
            xs.append(x)
        for x, m in zip(xs, evaluate_many(xs) if xs else []):
            ahead[tuple(x)] = m

    def trial(u) -> float:
        x = to_x(np.asarray(u, float))
        key = tuple(x)
        if key in cache:
            return cache[key]
        if len(history) >= budget:
            return -cache_best()
        m = m0 if np.array_equal(x, start_written) else ahead.pop(key, None)
        if m is None:
            m = evaluate(x)
        s = score(m, scale, objective)
        y = int(passing(m).sum())
        history.append((x, s, y))
        cache[key] = -s
        if progress is not None:
            progress(len(history), budget, max(h[2] for h in history) / max(len(m), 1))
        return -s

    def cache_best() -> float:
        return max(h[1] for h in history)

    d = len(free)
    u0 = (start - lo) / width
    trial(u0)
    if method == "differential-evolution":
        pop = max(5, min(15, budget // (4 * d) or 1))
        def generation(func, population):
            # a whole generation at once (deferred updating: the same with or without evaluate_many)
            population = [np.asarray(u, float) for u in population]
            prefetch(population)
            return [func(u) for u in population]

        differential_evolution(trial, [(0.0, 1.0)] * d, seed=seed, popsize=pop, maxiter=max(1, budget // (pop * d)),
                               polish=False, init="latinhypercube", x0=u0, tol=0.0, atol=0.0,
                               updating="deferred", workers=generation)
    else:
        scan = qmc.LatinHypercube(d=d, seed=seed).random(max(8, 4 * d)) if budget > 8 * d else np.empty((0, d))
        prefetch(scan)
        for u in scan:
            trial(u)
        best_u = (to_x_inverse(min(history, key=lambda h: (-h[2], -h[1]))[0], lo, width))
        opts = {"maxfev": max(1, budget - len(history)), "xatol": 1e-4, "fatol": 1e-6} if method == "nelder-mead" else \
               {"maxfev": max(1, budget - len(history)), "xtol": 1e-4, "ftol": 1e-6}
        if method == "nelder-mead":
            simplex = np.vstack([best_u] + [np.clip(best_u + 0.1 * np.eye(d)[i] * np.where(best_u[i] > 0.9, -1, 1),
                                                     0, 1) for i in range(d)])
            opts["initial_simplex"] = simplex
            prefetch(simplex)
        minimize(trial, best_u, method="Nelder-Mead" if method == "nelder-mead" else "Powell",
                 bounds=[(0.0, 1.0)] * d, options=opts)
    x, s, _y = max(history, key=lambda h: (h[2], h[1]) if objective == "yield" else (h[1], h[2]))
    return Search(x=np.asarray(x, float), score=float(s), evaluations=len(history), history=history)


def to_x_inverse(x: np.ndarray, lo: np.ndarray, width: np.ndarray) -> np.ndarray:
    """The unit-cube coordinates of SI values ``x`` in the box (lo, lo + width)."""
    return np.clip((np.asarray(x, float) - lo) / width, 0.0, 1.0)


# ------------------------------------------------------------------------------------------------
# A design as the function the search maximises
# ------------------------------------------------------------------------------------------------

@dataclass
class Problem:
    """A design read for tuning: its free parameters, requirements and how to evaluate them.

    ``margins(x, block)``: per sample (rows) and requirement (columns), value minus the nearer
    bound in the requirement's unit, at free values ``x`` (SI); ``block`` 0 is the search's sample,
    1 the validation sample (chunks the search never sees, same seed: independent streams).
    """

    path: str
    design: object
    free: tuple[Free, ...]
    requires: tuple
    tolerances: tuple                 # acl.sweep.spec.Tolerance of the spec at the start
    samples: int
    validate: int
    seed: int
    search_paths: tuple = ()
    tolerance_args: tuple = ()

    spec: object = None               # acl.sweep.spec.SweepSpec of the start (search and validation chunks)
    fmap: object = None               # acl.sweep.perturb.FieldMap over the free box widened by the spreads
    batch_design: object = None       # the design without the free ranges (they bound the search, not the prints)

    def setup(self) -> None:
        """The sampling spec and the parameter-to-field map, found once (the design is resolved a few
        times here and never again: every trial perturbs arrays)."""
        import dataclasses

        from acl.sweep.perturb import field_map
        from acl.sweep.spec import build_spec

        self.spec = build_spec(self.design, tolerance=list(self.tolerance_args), samples=self.samples + self.validate,
                               seed=self.seed, chunk_size=self.samples)
        names = tuple(dict.fromkeys([*self.spec.names, *(f.name for f in self.free)]))
        box = {n: (v, v) for n, v in ((n, self.design.param(n).value) for n in names)}
        for n, (lo, hi) in self.spec.box().items():
            box[n] = (lo, hi)
        for f in self.free:                     # the free range, widened as the spec widens a nominal
            at_lo = dataclasses.replace(self.spec, nominal={**self.spec.nominal, f.name: f.lower}).box()
            at_hi = dataclasses.replace(self.spec, nominal={**self.spec.nominal, f.name: f.upper}).box()
            box[f.name] = (min(at_lo.get(f.name, (f.lower,))[0], f.lower), max(at_hi.get(f.name, (0, f.upper))[1], f.upper))
        self.fmap = field_map(self.design, names, box, search_paths=self.search_paths)
        # `free in lo .. hi` bounds where the search may put the drawn value; a printed device deviates
        # from it by its spread, beyond the range too: such samples are devices, not E306 points
        from acl.sweep.validity import without_free_ranges

        self.batch_design = without_free_ranges(self.design)

    def points(self, x: np.ndarray, block: int = 0) -> dict[str, np.ndarray]:
        """{parameter: SI values} of the search (block 0) or validation (block 1) sample about free values ``x``."""
        import dataclasses

        from acl.sweep.sample import chunk_points

        if self.spec is None:
            self.setup()
        at = {f.name: float(v) for f, v in zip(self.free, np.asarray(x, float))}
        spec = dataclasses.replace(self.spec, nominal={**self.spec.nominal, **at})
        chunks = [0] if block == 0 else range(1, spec.n_chunks)
        parts = [chunk_points(spec, k, spec.chunk_size) for k in chunks]
        pts = {name: np.concatenate([p[name] for p in parts]) for name in parts[0]}
        n = len(next(iter(pts.values())))
        for name, v in at.items():
            pts.setdefault(name, np.full(n, v))
        return {name: pts[name] for name in self.fmap.names}

    def margins(self, x: np.ndarray, block: int = 0) -> np.ndarray:
        """Margins (samples x requirements) at free values ``x`` (SI) on sample ``block``."""
        from acl.sweep.evaluate import evaluate
        from acl.sweep.perturb import field_batch

        pts = self.points(x, block)
        batch = field_batch(self.batch_design, pts, self.fmap)
        wanted = [f"require_{i + 1}_value" for i in range(len(self.requires))]
        cols = evaluate(batch, quantities=wanted)
        # a bound may follow a parameter (`in f0 - 5 kHz .. f0 + 5 kHz` with f0 free or spread): per point
        bounds = [(None if r.lower is None else batch.get(f"requires.{j}.lower"),
                   None if r.upper is None else batch.get(f"requires.{j}.upper")) for j, r in enumerate(self.requires)]
        return require_margins(self.requires, [cols[q] for q in wanted], bounds)


@dataclass(frozen=True)
class MarginJobs:
    """``jobs(k)``: :meth:`Problem.margins` of job k, (free values, block); picklable, so a dask worker
    can run it (acl.sweep.run.Executor).  Every job is the whole sample of its block, as in one
    process: a trial's numbers do not depend on where it runs."""

    problem: Problem
    jobs: tuple

    def __call__(self, k: int) -> np.ndarray:
        x, block = self.jobs[k]
        return self.problem.margins(np.asarray(x, float), block)


def require_margins(requires, values, bounds=None) -> np.ndarray:
    """(n, R): each requirement's value minus its nearer bound (positive: passes), nan where unknown.

    ``bounds``: per requirement (lower, upper) arrays over the points when they vary (None: the
    requirement's own bounds)."""
    out = []
    for j, (r, v) in enumerate(zip(requires, values)):
        v = np.asarray(v, float)
        lo, hi = bounds[j] if bounds is not None else (None, None)
        lo = r.lower if lo is None else np.asarray(lo, float)
        hi = r.upper if hi is None else np.asarray(hi, float)
        m = np.full(v.shape, np.inf)
        if r.lower is not None:
            m = np.minimum(m, v - lo)
        if r.upper is not None:
            m = np.minimum(m, hi - v)
        out.append(np.where(np.isfinite(v), m, np.nan))
    return np.stack(out, axis=1) if out else np.empty((0, 0))


# ------------------------------------------------------------------------------------------------
# Reading the problem, with a located diagnostic for everything that makes it ill-posed
# ------------------------------------------------------------------------------------------------

def _at_file(design, path: str):
    from acl.diagnostics import Span

    return Span(file=getattr(design, "path", None) or path, line=1, column=1)


def prepare(path: str, tolerance: Sequence[str] = (), samples: int = 2000, validate: int | None = None,
            seed: int = 0, search_paths: Sequence[str] = ()) -> Problem:
    """Load the design and check it can be tuned; raises DiagnosticError (every problem found).

    E870 no free parameter; E871 a free parameter without a finite range (``free in lo .. hi``);
    E872 no requirement; E873 a requirement the batched evaluation cannot give; E874 nothing
    spread (no ``+- ...`` on a parameter and no ``--tolerance``); E-USAGE bad numbers of samples.
    """
    from acl.design.resolve import load_design
    from acl.diagnostics import DiagnosticError, Span, error
    from acl.sweep.evaluate import per_point_names, supported

    diags = []
    validate = samples if validate is None else validate
    for opt, v in (("--samples", samples), ("--validate", validate)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            diags.append(error("E-USAGE", f"{opt} {v!r}: a number of samples is an integer >= 1",
                               Span(file=f"<{opt}>", line=1, column=1)))
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        diags.append(error("E-USAGE", f"--seed {seed!r}: a seed is a non-negative integer", Span(file="<--seed>", line=1, column=1)))
    if diags:
        raise DiagnosticError(diags)
    design = load_design(path, search_paths=list(search_paths))
    where = _at_file(design, path)
    free = []
    for p in design.params:
        if not p.free:
            continue
        lo, hi = p.lower, p.upper
        if lo is None or hi is None or not (math.isfinite(lo) and math.isfinite(hi)) or not hi > lo:
            diags.append(error("E871", f"free parameter `{p.name}` needs a finite range to search in", p.span,
                               f"write `param {p.name} = ... free in LO .. HI` (LO < HI)"))
            continue
        free.append(Free(p.name, p.unit, float(lo), float(hi), float(p.value)))
    if not any(p.free for p in design.params):
        diags.append(error("E870", "nothing to tune: the design has no `free` parameter", where,
                           "declare the dimensions acl tune may choose, e.g. `param r1 = 12 um +- 150 nm free in 8 um .. 16 um`"))
    if not design.requires:
        diags.append(error("E872", "nothing to tune for: the design has no `require`", where,
                           "state what must hold, e.g. `require separation(m) >= 30 kHz` (docs/language.md)"))
    else:
        names, missing = supported(design)
        slow = per_point_names(design)
        for i, r in enumerate(design.requires, start=1):
            if f"require_{i}_value" in slow:
                # acl sweep gives it point by point (acl.sweep.points, ~0.1 s a point): too slow for a search
                # that evaluates --samples points at each of --max-evals candidates
                diags.append(error("E873", f"`{r.text}` cannot be evaluated batched, so acl tune cannot use it: the "
                                   "design declares effects that change it, which only `acl analyze`'s engine point by "
                                   "point gives (acl sweep does)", r.span,
                                   "remove it or state it another way; docs/tune.md lists what acl tune evaluates"))
            elif f"require_{i}_value" not in names:
                why = next((v for k, v in missing.items() if k.split("_")[:2] == ["require", str(i)]), None)
                diags.append(error("E873", f"`{r.text}` cannot be evaluated batched, so acl tune cannot use it"
                                   + (f": {why}" if why else ""), r.span,
                                   "remove it or state it another way; docs/tune.md lists what acl tune evaluates"))
    spread_declared = any(p.distribution() is not None for p in design.params)
    if not spread_declared and not list(tolerance):
        diags.append(error("E874", "no tolerance: nothing in the design is spread, so every printed device is the "
                           "drawn one and the yield is 0 or 1", where,
                           "declare the print tolerance, `param r1 = 12 um +- 150 nm`, or give --tolerance "
                           "'r1=normal(0, 150 nm)'"))
    if diags:
        raise DiagnosticError(diags)
    problem = Problem(path=path, design=design, free=tuple(free), requires=tuple(design.requires), tolerances=(),
                      samples=int(samples), validate=int(validate), seed=int(seed), search_paths=tuple(search_paths),
                      tolerance_args=tuple(tolerance))
    problem.setup()
    problem.tolerances = problem.spec.tolerances
    if not any(hi > lo for lo, hi in problem.spec.box().values()):
        raise DiagnosticError([error("E874", "no tolerance: every spread is zero, so every printed device is the "
                                     "drawn one and the yield is 0 or 1", where,
                                     "give a spread wider than zero, e.g. --tolerance 'r1=normal(0, 150 nm)'")])
    return problem


# ------------------------------------------------------------------------------------------------
# The whole run: search, validate, report
# ------------------------------------------------------------------------------------------------

@dataclass
class Tuned:
    """The outcome of ``acl tune``: chosen values and the yield before and after."""

    problem: Problem
    objective: str
    method: str
    start: np.ndarray                 # SI, as declared
    chosen: np.ndarray                # SI, rounded as written
    search: Search
    before: Estimate                  # validation sample, at the start
    after: Estimate                   # validation sample, at the chosen values
    before_search: Estimate           # the sample the search used
    after_search: Estimate
    per_require: list                 # [{text, line, before, after (Estimate), worst_before, worst_after}]
    timing_s: dict = field(default_factory=dict)   # stage -> seconds (search, validate)

    @property
    def values(self) -> dict[str, float]:
        """{free parameter: chosen SI value, as written}."""
        return {f.name: float(c) for f, c in zip(self.problem.free, self.chosen)}

    def write(self, path: str | None = None, command: str = "") -> str:
        """Write the tuned design (it ``extends`` the original; default ``<stem>.tuned.acl`` beside it)
        atomically; returns the path written.  Written outside the original's folder tree, it loads
        only with that folder among the search paths (:func:`reaches`; `acl tune -o` refuses such a folder)."""
        import os

        from acl._files import write_text_atomic

        out = os.path.abspath(path) if path else default_path(self.problem.path)
        write_text_atomic(out, tuned_text(self, out, command=command))
        return out

    def __repr__(self) -> str:
        chosen = ", ".join(f"{f.name}={literal(c, f.unit)}" for f, c in zip(self.problem.free, self.chosen))
        return f"<Tuned {chosen}: yield before {self.before.text()}, after {self.after.text()}>"

    def _repr_html_(self) -> str:
        """The free parameters (start, chosen, range) and the yield before and after, per require."""
        from acl._display import html_table

        p = self.problem
        out = html_table("Free parameters", ["parameter", "start", "chosen", "range"],
                         [[f.name, literal(s, f.unit), literal(c, f.unit), f"{literal(f.lower, f.unit)} .. {literal(f.upper, f.unit)}"]
                          for f, s, c in zip(p.free, self.start, self.chosen)])
        rows = [[q["text"], q["before"].text(), q["after"].text()] for q in self.per_require]
        rows.append(["all together", self.before.text(), self.after.text()])
        return out + html_table(f"Yield on {p.validate} fresh samples (95% Clopper-Pearson interval)",
                                ["requirement", "before", "after"], rows,
                                f"{self.objective}, {self.search.evaluations} trials on {p.samples} samples, seed {p.seed}")

    def plot(self, ax=None):
        """The search: each trial's exact yield on the search sample, and the best so far; returns the Axes."""
        from acl._display import new_axes

        ax = new_axes(ax)
        n = max(self.problem.samples, 1)
        y = np.array([h[2] for h in self.search.history], float) / n
        k = np.arange(1, len(y) + 1)
        ax.plot(k, y, ".", alpha=0.6, label="trial")
        if len(y):
            ax.plot(k, np.maximum.accumulate(y), "-", label="best so far")
        ax.axhline(self.after.value, ls="--", color="0.4", lw=1, label=f"validated after: {self.after.value:.3f}")
        ax.set_xlabel("trial")
        ax.set_ylabel("yield (search sample)")
        ax.set_ylim(-0.02, 1.02)
        ax.set_title("acl tune: search")
        ax.legend(fontsize="small")
        return ax

    def to_json(self) -> dict:
        def est(e: Estimate) -> dict:
            lo, hi = e.interval
            return {"yield": e.value, "interval": [lo, hi], "passed": e.passed, "n": e.n}

        return {
            "design": self.problem.path, "objective": self.objective, "method": self.method,
            "samples": self.problem.samples, "validation_samples": self.problem.validate, "seed": self.problem.seed,
            "evaluations": self.search.evaluations, "confidence": CONFIDENCE,
            "free": [{"name": f.name, "unit": f.unit, "lower": f.lower, "upper": f.upper, "start": float(s),
                      "chosen": float(c)} for f, s, c in zip(self.problem.free, self.start, self.chosen)],
            "tolerances": [{"name": t.name, "kind": t.spread.kind, "a": t.spread.a, "b": t.spread.b,
                            "relative": t.spread.relative, "source": t.source} for t in self.problem.tolerances],
            "before": est(self.before), "after": est(self.after),
            "search_sample": {"before": est(self.before_search), "after": est(self.after_search)},
            "requires": [{"text": r["text"], "line": r["line"], "before": est(r["before"]), "after": est(r["after"]),
                          "worst_margin_before": _finite(r["worst_before"]), "worst_margin_after": _finite(r["worst_after"]),
                          "unit": r["unit"]} for r in self.per_require],
        }


def _finite(x: float) -> float | None:
    """JSON has no infinities: an invalid point's margin (-inf) is null."""
    return float(x) if math.isfinite(x) else None


def tune(problem: Problem, objective: str = "yield", method: str = "nelder-mead", max_evals: int = 200,
         progress: Callable[[int, int, float], None] | None = None, scheduler: str | None = None,
         timeout: float | None = None, notify: Callable[[str], None] | None = None) -> Tuned:
    """Search, then validate the start and the written values on the fresh sample.

    ``scheduler``: where trials run, as ``acl sweep --scheduler``: None/"local" (this machine, a
    thread per core) or "tcp://HOST:PORT" (a dask.distributed cluster, ``acl[scale]``).  Trials the
    search knows in advance (its scan, a differential-evolution generation, the first simplex, the
    validation) run together; each trial evaluates its whole sample in one task, so the result is
    the same bit for bit on any scheduler.  ``timeout``/``notify``: a cluster left without workers
    (acl.sweep.run.map_chunks).

    Raises DiagnosticError E875 when no validation sample passes at the chosen values (infeasible
    within the free ranges, as far as the search looked).
    """
    from acl.diagnostics import DiagnosticError, Span, error
    from acl.sweep.run import Executor

    import time

    for what, v, allowed in (("objective", objective, OBJECTIVES), ("method", method, METHODS)):
        if v not in allowed:
            raise DiagnosticError([error("E-USAGE", f"--{what} {v!r}: expected one of " + ", ".join(allowed),
                                         Span(file=f"<--{what}>", line=1, column=1))])
    if problem.spec is None:
        problem.setup()
    t0 = time.perf_counter()
    start = np.array([f.start for f in problem.free], float)
    with Executor(scheduler, connect=False, timeout=timeout, notify=notify) as ex:
        def run(jobs: list) -> list:
            return ex.map(MarginJobs(problem, tuple((tuple(float(v) for v in x), b) for x, b in jobs)), len(jobs))

        found = maximise(lambda x: run([(x, 0)])[0], problem.free, objective=objective, method=method, max_evals=max_evals,
                         seed=problem.seed, progress=progress, evaluate_many=lambda xs: run([(x, 0) for x in xs]))
        chosen = rounded(found.x)
        t1 = time.perf_counter()
        m_before, m_after, s_before, s_after = run([(start, 1), (chosen, 1), (start, 0), (chosen, 0)])
    n = m_before.shape[0]
    before, after = Estimate(int(passing(m_before).sum()), n), Estimate(int(passing(m_after).sum()), n)
    if after.passed == 0 and before.passed == 0:
        raise DiagnosticError([error(
            "E875", f"infeasible: no validation sample meets every requirement, at the start or at the best point "
            f"found in {found.evaluations} trials", _at_file(problem.design, problem.path),
            "widen the free ranges, relax a requirement, or tighten the tolerances; `acl sweep` maps where "
            "requirements fail")])
    per = []
    units = {"resonance": "Hz", "separation": "Hz", "margin": "", "gap": "m"}
    for j, r in enumerate(problem.requires):
        ok_b = np.nan_to_num(m_before[:, j], nan=-np.inf) >= 0
        ok_a = np.nan_to_num(m_after[:, j], nan=-np.inf) >= 0
        per.append({"text": r.text, "line": r.span.line, "unit": units.get(r.kind, ""),
                    "before": Estimate(int(ok_b.sum()), n), "after": Estimate(int(ok_a.sum()), n),
                    "worst_before": float(np.nan_to_num(m_before[:, j], nan=-np.inf).min()),
                    "worst_after": float(np.nan_to_num(m_after[:, j], nan=-np.inf).min())})
    ns = s_before.shape[0]
    return Tuned(problem=problem, objective=objective, method=method, start=start, chosen=chosen, search=found,
                 before=before, after=after, before_search=Estimate(int(passing(s_before).sum()), ns),
                 after_search=Estimate(int(passing(s_after).sum()), ns), per_require=per,
                 timing_s={"search": t1 - t0, "validate": time.perf_counter() - t1})


# ------------------------------------------------------------------------------------------------
# The tuned design: `extends` the original, the free parameters redeclared with the chosen values
# ------------------------------------------------------------------------------------------------

def reaches(folder: str, design_path: str, search_paths=()) -> bool:
    """Whether a design in ``folder`` may extend ``design_path`` (`acl check` reads an `extends` only from the
    design's folder and below, or a --path folder: E210): it lies in ``folder`` or below, or in a search path."""
    import os

    real = os.path.realpath(design_path)
    roots = [os.path.realpath(folder), *(os.path.realpath(p) for p in search_paths or ())]
    return any(real.startswith(r.rstrip(os.sep) + os.sep) for r in roots)


def default_path(design_path: str) -> str:
    """``<folder>/<stem>.tuned.acl`` next to the original (its ``extends`` then needs no --path)."""
    import os

    folder, name = os.path.split(os.path.abspath(design_path))
    stem = name[:-4] if name.endswith(".acl") else name
    return os.path.join(folder, f"{stem}.tuned.acl")


def literal(value: float, unit: str, digits: int = DIGITS) -> str:
    """An acl literal of an SI value, in a readable unit where one is obvious (um, nm, kHz)."""
    unit = (unit or "").replace(" ", "")
    if unit == "m" and value != 0 and 1e-7 <= abs(value) < 1e-3:
        return f"{value * 1e6:.{digits}g} um"
    if unit == "m" and value != 0 and 1e-10 <= abs(value) < 1e-7:
        return f"{value * 1e9:.{digits}g} nm"
    if unit == "Hz" and 1e3 <= abs(value) < 1e6:
        return f"{value / 1e3:.{digits}g} kHz"
    return f"{value:.{digits}g} {unit}".strip()


def _spread_text(p) -> str:
    sp = p.distribution()
    if sp is None:
        return ""
    if sp.relative:
        a, b = (f"{v * 100:.{DIGITS}g} %" for v in (sp.a, sp.b))
    else:
        a, b = literal(sp.a, p.unit), literal(sp.b, p.unit)
    if sp.kind == "normal" and sp.a == 0:
        return f" +- {b}"
    return f" +- {sp.kind}({a}, {b})"


def tuned_text(result: Tuned, out_path: str, command: str = "") -> str:
    """The tuned design's source: ``extends`` the original, each free parameter redeclared at its chosen
    value with the same spread and range (so the file can be swept or tuned again)."""
    import datetime
    import os

    p = result.problem
    rel = os.path.relpath(os.path.abspath(p.path), os.path.dirname(os.path.abspath(out_path))).replace(os.sep, "/")
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    lo_b, hi_b = result.before.interval
    lo_a, hi_a = result.after.interval
    lines = [f"# Tuned by `acl tune`{': ' + command if command else ''}",
             f"# date: {now}",
             f"# objective: {result.objective} of every require; {p.samples} samples searched (seed {p.seed}, "
             f"{result.method}, {result.search.evaluations} trials)",
             f"# yield on {p.validate} fresh samples, {CONFIDENCE:.0%} Clopper-Pearson interval: before "
             f"{result.before.value:.4g} [{lo_b:.4g}, {hi_b:.4g}], after {result.after.value:.4g} [{lo_a:.4g}, {hi_a:.4g}]",
             "", f'extends "{rel}"', ""]
    for f, s, c in zip(p.free, result.start, result.chosen):
        decl = p.design.param(f.name)
        lines.append(f"param {f.name} = {literal(c, f.unit)}{_spread_text(decl)} free in "
                     f"{literal(f.lower, f.unit)} .. {literal(f.upper, f.unit)}    # was {literal(s, f.unit)}")
    from acl.fmt import canonical

    return canonical("\n".join(lines) + "\n", out_path)

"""Solving a cvxpy problem the house way: DCP checked, Clarabel first, OSQP/SCS as fallbacks, status checked.

cvxpy is imported inside the functions (it is heavy); nothing here runs at import time.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

SOLVERS = ("CLARABEL", "OSQP", "SCS")
OPTIMAL = ("optimal", "optimal_inaccurate")
INFEASIBLE = ("infeasible", "infeasible_inaccurate")
UNBOUNDED = ("unbounded", "unbounded_inaccurate")


class SolverFailure(RuntimeError):
    """No solver returned a usable status; ``status`` is the last one seen."""

    def __init__(self, what: str, status: str, tried: tuple[str, ...]):
        self.what, self.status, self.tried = what, status, tried
        super().__init__(f"{what}: no solver succeeded (last status {status!r}, tried {', '.join(tried)})")


@dataclass(frozen=True)
class SolveResult:
    status: str             # "optimal" | "optimal_inaccurate" | "infeasible" | "unbounded"
    solver: str
    value: float | None
    solve_time_s: float | None = None

    @property
    def ok(self) -> bool:
        return self.status in OPTIMAL

    @property
    def infeasible(self) -> bool:
        return self.status in INFEASIBLE

    @property
    def unbounded(self) -> bool:
        return self.status in UNBOUNDED


def solve(problem, what: str, solvers: tuple[str, ...] = SOLVERS, **kwargs) -> SolveResult:
    """Solve ``problem`` with the first solver that gives a definite answer.

    An infeasible or unbounded verdict from a solver is believed (the next solvers would only
    confirm it); an error or an ``inaccurate``/``None`` status moves on to the next solver.
    OSQP is skipped for problems with cone constraints (it solves QPs only).
    """
    import cvxpy as cp

    if not problem.is_dcp():
        raise ValueError(f"{what}: problem is not DCP (a compiler bug)")
    installed = set(cp.installed_solvers())
    status, tried, fallback = "not solved", [], None
    is_qp = problem.is_qp()
    for name in solvers:
        if name not in installed or (name == "OSQP" and not is_qp):
            continue
        tried.append(name)
        try:
            with warnings.catch_warnings():      # cvxpy warns "Solution may be inaccurate": the status says so
                warnings.filterwarnings("ignore", message="Solution may be inaccurate", category=UserWarning)
                problem.solve(solver=name, **kwargs)
        except (cp.error.SolverError, ValueError, ArithmeticError):   # SCS raises ValueError on a badly scaled problem
            status = "solver error"
            continue
        status = problem.status or "none"
        stats = problem.solver_stats
        result = SolveResult(status=status, solver=name, value=problem.value,
                             solve_time_s=getattr(stats, "solve_time", None))
        if status == "optimal" or status in ("infeasible", "unbounded"):
            return result
        if status in OPTIMAL and fallback is None:   # inaccurate: keep unless a later one does better
            fallback = result
    if fallback is not None:
        return fallback
    raise SolverFailure(what, status, tuple(tried))

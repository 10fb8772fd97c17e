"""``lsq``: nonlinear least squares on the scalar residual ``|M (raw - o)| - F`` (seed 000, eq. 3)
with the analytic Jacobian of ``ScalarObjective.jacobian``; Levenberg-Marquardt (MINPACK, through
``scipy.optimize.least_squares``).  Under Gaussian noise this is the maximum-likelihood estimator and
reaches the Cramér-Rao bound (tests/test_lsq.py)."""
from __future__ import annotations

import numpy as np
from scipy.optimize import OptimizeResult, least_squares

from magbench.errors import InputError

from .base import Calibrator, Problem, SolveOutput
from .objective import lm_normal
from .registry import register


LARGE_RECORD = 100_000
"""From this many readings on, least squares runs on the normal equations accumulated block by block
(bounded memory, one pass per iteration) instead of on the full (n, p) Jacobian."""


def levenberg_marquardt(problem: Problem, x_start: np.ndarray, tol: float = 1e-12, max_nfev: int = 200,
                        bounded: bool = True):
    """Least squares on the problem's counted residuals and analytic Jacobian from ``x_start``: the
    trust-region reflective method inside the problem's search box (``bounded``), or plain
    Levenberg-Marquardt (MINPACK); on a long record, Levenberg-Marquardt on the normal equations."""
    left = problem.evaluations_left
    if left is not None:
        max_nfev = max(1, min(max_nfev, left))
    if problem.n_points >= LARGE_RECORD:
        lo, hi = (problem.lower, problem.upper) if bounded else (None, None)
        x, cost, calls = lm_normal(problem.normal_equations, x_start, lo, hi, tol=tol, max_iter=max_nfev - 1)
        return OptimizeResult(x=x, status=2, nfev=calls, message="normal-equation Levenberg-Marquardt converged")
    if bounded:
        lo, hi = problem.lower, problem.upper
        x_start = np.clip(x_start, lo + 1e-12, hi - 1e-12)
        return least_squares(problem.residuals, x_start, jac=problem.jacobian, method="trf", bounds=(lo, hi),
                             x_scale="jac", ftol=tol, xtol=tol, gtol=tol, max_nfev=max_nfev)
    return least_squares(problem.residuals, x_start, jac=problem.jacobian, method="lm", x_scale="jac",
                         ftol=tol, xtol=tol, gtol=tol, max_nfev=max_nfev)


@register
class LeastSquares(Calibrator):
    """Least squares on the scalar residuals, analytic Jacobian: trust-region reflective inside the
    physical box (``bounded``, default) or plain Levenberg-Marquardt.

    ``init``: ``identity`` starts from no correction; ``ellipsoid`` from the algebraic fit (the ellipsoid
    for ``nine``, the axis-aligned ellipsoid for ``diag``, the sphere for ``offset``; none for ``angles``);
    ``auto`` uses the algebraic start when it fits and is better than the identity.
    """

    name = "lsq"
    summary = "Levenberg-Marquardt on the scalar residual, analytic Jacobian (maximum likelihood)"

    def __init__(self, model: str = "nine", seed: int | None = 0, budget=None, init: str = "auto",
                 tol: float = 1e-12, max_nfev: int = 200, bounded: bool = True):
        super().__init__(model=model, seed=seed, budget=budget)
        self.init = init
        self.tol = tol
        self.max_nfev = max_nfev
        self.bounded = bounded

    def _start(self, problem: Problem) -> np.ndarray:
        if self.init not in ("auto", "identity", "ellipsoid"):
            raise InputError(f"lsq: init must be auto, identity or ellipsoid, not {self.init!r}")
        if self.init == "identity" or problem.model == "angles":
            return problem.x0
        start = problem.algebraic_start()  # the framework's ellipsoid fit, counted
        if start is None:
            if self.init == "ellipsoid":
                raise InputError("lsq: init='ellipsoid', but the readings do not fit an ellipsoid")
            return problem.x0
        x_e, f_e = start
        if self.init == "ellipsoid":
            return x_e
        return x_e if f_e < problem.value(problem.x0) else problem.x0

    def _solve(self, problem: Problem) -> SolveOutput:
        sol = levenberg_marquardt(problem, self._start(problem), self.tol, self.max_nfev, bounded=self.bounded)
        status = {0: "max_nfev", 1: "gtol", 2: "ftol", 3: "xtol", 4: "ftol_xtol"}.get(sol.status, str(sol.status))
        return SolveOutput(sol.x, status=status, message=sol.message, nit=int(sol.nfev),
                           success=bool(sol.status > 0))

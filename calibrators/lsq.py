"""``lsq``: nonlinear least squares on the scalar residual ``|M (raw - o)| - F`` (seed 000, eq. 3)
with the analytic Jacobian of ``ScalarObjective.jacobian``; Levenberg-Marquardt (MINPACK, through
``scipy.optimize.least_squares``).  Under Gaussian noise this is the maximum-likelihood estimator and
reaches the Cramér-Rao bound (tests/test_lsq.py)."""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from magbench.errors import InputError
from magbench.simulate.sensor import PARAM_NAMES

from .base import Calibrator, Problem, SolveOutput
from .ellipsoid import ellipsoid_params
from .registry import register


def physical_bounds(model: str, f_ref_nT) -> tuple[np.ndarray, np.ndarray]:
    """Where a sensor can physically be: angles within 0.5 rad, scales 0.5..2, offsets within twice the
    field.  Scalar data admit degenerate 'far-centre' solutions (huge scale and offset that shrink the
    residual below the noise) when the attitudes cover few directions; the box excludes them."""
    lo, hi = [-0.5] * 3, [0.5] * 3
    if model == "nine":
        f = float(np.median(f_ref_nT))
        lo += [0.5] * 3 + [-2.0 * f] * 3
        hi += [2.0] * 3 + [2.0 * f] * 3
    return np.array(lo), np.array(hi)


def levenberg_marquardt(problem: Problem, x_start: np.ndarray, tol: float = 1e-12, max_nfev: int = 200,
                        bounded: bool = False):
    """Least squares on the problem's counted residuals and analytic Jacobian from ``x_start``:
    Levenberg-Marquardt (MINPACK), or the trust-region reflective method inside ``physical_bounds``."""
    obj = problem.objective
    if obj.budget.max_evaluations is not None:
        max_nfev = max(1, min(max_nfev, obj.budget.max_evaluations - obj.n_evaluations))
    if bounded:
        lo, hi = physical_bounds(problem.model, problem.f_ref_nT)
        x_start = np.clip(x_start, lo + 1e-12, hi - 1e-12)
        return least_squares(obj.residuals, x_start, jac=obj.jacobian, method="trf", bounds=(lo, hi),
                             x_scale="jac", ftol=tol, xtol=tol, gtol=tol, max_nfev=max_nfev)
    return least_squares(obj.residuals, x_start, jac=obj.jacobian, method="lm", x_scale="jac",
                         ftol=tol, xtol=tol, gtol=tol, max_nfev=max_nfev)


@register
class LeastSquares(Calibrator):
    """Least squares on the scalar residuals, analytic Jacobian: trust-region reflective inside the
    physical box (``bounded``, default) or plain Levenberg-Marquardt.

    ``init``: ``identity`` starts from no correction; ``ellipsoid`` from the algebraic ellipsoid fit
    (``nine`` only); ``auto`` uses the ellipsoid start when it fits and is better than the identity.
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
        if self.init == "identity" or problem.model != "nine":
            return problem.x0
        try:
            x_e = ellipsoid_params(problem.raw_nT, problem.f_ref_nT).to_vector("nine")
        except InputError:
            if self.init == "ellipsoid":
                raise
            return problem.x0
        if self.init == "ellipsoid":
            return x_e
        f0, fe = problem.objective.objective.values(np.vstack([problem.x0, x_e]))
        return x_e if fe < f0 else problem.x0

    def _solve(self, problem: Problem) -> SolveOutput:
        sol = levenberg_marquardt(problem, self._start(problem), self.tol, self.max_nfev, bounded=self.bounded)
        status = {0: "max_nfev", 1: "gtol", 2: "ftol", 3: "xtol", 4: "ftol_xtol"}.get(sol.status, str(sol.status))
        extra = {}
        if self.bounded:
            lo, hi = physical_bounds(problem.model, problem.f_ref_nT)
            at = [PARAM_NAMES[problem.model][i] for i in np.flatnonzero((sol.x <= lo + 1e-9 * np.abs(lo) + 1e-12)
                                                                         | (sol.x >= hi - 1e-9 * np.abs(hi) - 1e-12))]
            if at:
                extra["at_bounds"] = at
        return SolveOutput(sol.x, status=status, message=sol.message, nit=int(sol.nfev),
                           success=bool(sol.status > 0), extra=extra)

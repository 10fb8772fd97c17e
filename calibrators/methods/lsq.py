"""``lsq``: nonlinear least squares on the scalar residual ``|M (raw - o)| - F`` (seed 000, eq. 3)
with the analytic Jacobian of ``ScalarObjective``: Levenberg-Marquardt (Marquardt's scaling) on the
normal equations (a strategy asking the framework for them, ``core/loop.py``), accumulated block by block
so that memory stays bounded on long records, the search box enforced by projection.  Under Gaussian
noise this is the maximum-likelihood estimator and reaches the Cramér-Rao bound (tests/test_lsq.py).
It gives the same optimum as MINPACK's Levenberg-Marquardt and SciPy's trust-region reflective method
(checked to 1e-8 relative on every scenario) without importing SciPy's optimizer, which costs a third
of a second at start-up."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from magbench.errors import InputError
from magbench.numerics import lm_iterations

from ..base import Calibrator
from ..core import loop
from ..core.problem import Problem, SolveOutput
from ..params import AT_LEAST_ONE, NON_NEGATIVE, Options


def levenberg_marquardt(problem: Problem, x_start: np.ndarray, tol: float = 1e-12, max_nfev: int = 200,
                        bounded: bool = True):
    """Least squares from ``x_start`` as a strategy: each step asks for the counted normal equations (one
    evaluation and one Jacobian), inside the problem's search box when ``bounded``.  Returns ``x``,
    ``nfev``, ``status`` (2: converged, 0: ``max_nfev`` spent), ``message`` and ``cost`` (the sum of squares at
    ``x``)."""
    left = problem.evaluations_left
    if left is not None:
        max_nfev = max(1, min(max_nfev, left))
    lo, hi = (problem.lower, problem.upper) if bounded else (None, None)
    if lo is not None and hi is not None:
        x_start = np.clip(x_start, lo + 1e-12, hi - 1e-12)
    x, cost, calls = yield from loop.asks("normal_equations", lm_iterations(x_start, lo, hi, tol=tol,
                                                                              max_iter=max(max_nfev - 1, 0)))
    done = calls < max_nfev
    return SimpleNamespace(x=x, nfev=calls, status=2 if done else 0, cost=cost,
                           message="converged (the sum of squares or the step stopped changing)" if done else
                           f"stopped after {calls} evaluations (max_nfev)")


class LeastSquares(Calibrator):
    """Least squares on the scalar residuals, analytic Jacobian: Levenberg-Marquardt on the normal
    equations, inside the physical box (``bounded``, default) or unbounded.

    ``init``: ``identity`` starts from no correction; ``ellipsoid`` from the algebraic fit (the ellipsoid
    for ``nine``, the axis-aligned ellipsoid for ``diag``, the sphere for ``offset``; none for ``angles``);
    ``auto`` uses the algebraic start when it fits and is better than the identity, and searches again from the
    identity when the search from the algebraic start spends ``max_nfev`` without converging (on attitudes that leave
    a valley of the model nearly free, the ellipsoid can start far along it), keeping it when it converges to a lower
    sum of squares.
    """

    name = "lsq"
    summary = "Levenberg-Marquardt on the scalar residual, analytic Jacobian (maximum likelihood)"

    _parameter_constraints = {**Calibrator._parameter_constraints, "init": [Options(("auto", "identity", "ellipsoid"))],
                              "tol": NON_NEGATIVE, "max_nfev": AT_LEAST_ONE, "bounded": [bool]}

    def __init__(self, model: str = "nine", seed: int | None = 0, budget=None, init: str = "auto",
                 tol: float = 1e-12, max_nfev: int = 200, bounded: bool = True):
        super().__init__(model=model, seed=seed, budget=budget)
        self.init = init
        self.tol = tol
        self.max_nfev = max_nfev
        self.bounded = bounded

    def _start(self, problem: Problem):
        if self.init == "identity" or problem.model == "angles":
            return problem.x0
        start = yield loop.START  # the framework's ellipsoid fit, counted
        if start is None:
            if self.init == "ellipsoid":
                raise InputError("lsq: init='ellipsoid', but the readings do not fit an ellipsoid")
            return problem.x0
        x_e, f_e = start
        if self.init == "ellipsoid":
            return x_e
        return x_e if f_e < (yield loop.value(problem.x0)) else problem.x0

    def _solve(self, problem: Problem):
        x_start = yield from self._start(problem)
        sol = yield from levenberg_marquardt(problem, x_start, self.tol, self.max_nfev, bounded=self.bounded)
        nfev = sol.nfev
        left = problem.evaluations_left
        if (sol.status == 0 and self.init == "auto" and not np.array_equal(x_start, problem.x0)
                and (left is None or left > RESTART_MIN_CALLS * (1 + problem.n_params))):
            # The algebraic start can sit far along a valley that the attitudes leave nearly free (a towed body
            # that stays level: the ellipsoid's scales of 0.75 and offsets of 10^4 nT, from which the search had
            # not reached the least squares after 200 steps, while from no correction it does in 60): the search
            # again from no correction, kept when it converges to a lower sum of squares (two searches that both
            # stop short are both somewhere along the valley: the first is kept, as before).
            again = yield from levenberg_marquardt(problem, problem.x0, self.tol, self.max_nfev, bounded=self.bounded)
            nfev += again.nfev
            if again.status == 2 and again.cost < sol.cost:  # a converged search replaces one that was not
                first = sol.message
                sol = again
                sol.message = f"{again.message} from no correction, after the search from the algebraic start {first}"
        status = "converged" if sol.status == 2 else "max_nfev"
        return SolveOutput(sol.x, status=status, message=sol.message, nit=int(nfev),
                           success=bool(sol.status > 0))


RESTART_MIN_CALLS = 10
"""``lsq`` searches again from no correction when its search from the algebraic start spent ``max_nfev`` without
converging, if the budget leaves at least this many normal-equation calls."""

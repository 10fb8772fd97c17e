"""``nlopt``: the NLopt library's algorithms behind one calibrator.

Local derivative-free (default ``LN_BOBYQA``; also LN_NELDERMEAD, LN_SBPLX, LN_COBYLA, ...), global
(``GN_CRS2_LM``, ``GN_ISRES``, ``GN_ESCH``, ``GN_DIRECT_L``, ...) and gradient-based (``LD_LBFGS``,
``LD_MMA``, ``LD_SLSQP``, ...; they get the analytic gradient of eq. 3).  The variables are normalized
to [0, 1] over the search box so that one tolerance fits angles, scales and offsets.  Stochastic
algorithms are seeded with ``nlopt.srand(seed)``.
"""
from __future__ import annotations

from numbers import Integral

import nlopt
import numpy as np

from ..base import Calibrator
from ..core import loop
from ..core.evaluator import BudgetExhausted
from ..core.problem import Problem, SolveOutput, population_box
from ..params import AT_LEAST_ONE, BOX, MAX_POPULATION, NON_NEGATIVE, Interval

RESULT_NAMES = {1: "success", 2: "stopval_reached", 3: "ftol_reached", 4: "xtol_reached", 5: "maxeval_reached",
                6: "maxtime_reached"}


STOCHASTIC_NLOPT = ("CRS2", "ISRES", "ESCH", "MLSL", "STOGO_RAND")
"""NLopt algorithms that draw random numbers (seeded with ``nlopt.srand``); the others ignore the seed."""


class NLoptCalibrator(Calibrator):
    """Any NLopt algorithm on the shared objective (``algorithm`` is NLopt's name, e.g. LN_BOBYQA)."""

    name = "nlopt"
    summary = "NLopt algorithms (--algorithm; default LN_BOBYQA; GN_* global, LD_* analytic gradient)"
    stochastic = True
    check_tolerance = {"angle_rad": 5e-5, "scale": 5e-5, "offset_nT": 1.0}

    _parameter_constraints = {**Calibrator._parameter_constraints, **BOX, "max_evaluations": AT_LEAST_ONE,
                              "ftol_rel": NON_NEGATIVE, "xtol_rel": NON_NEGATIVE,
                              "population": [Interval(Integral, 0, MAX_POPULATION)]}

    @classmethod
    def _params_together(cls, params: dict) -> str | None:
        algorithm = params["algorithm"]
        if not isinstance(getattr(nlopt, str(algorithm), None), int) or str(algorithm)[:3] not in ("LN_", "LD_", "GN_", "GD_"):
            return f"unknown algorithm {algorithm!r} (e.g. LN_BOBYQA, LD_LBFGS, GN_CRS2_LM, GN_ISRES, GN_ESCH)"
        return None

    def __init__(self, model: str = "nine", seed: int | None = 0, budget=None, algorithm: str = "LN_BOBYQA",
                 max_evaluations: int = 20000, ftol_rel: float = 1e-14, xtol_rel: float = 1e-10,
                 angle_range_rad: float = 0.1, scale_range: float = 0.1, offset_range_nT: float | None = None,
                 population: int = 0):
        super().__init__(model=model, seed=seed, budget=budget)
        self.algorithm = algorithm
        self.max_evaluations = max_evaluations
        self.ftol_rel = ftol_rel
        self.xtol_rel = xtol_rel
        self.angle_range_rad = angle_range_rad
        self.scale_range = scale_range
        self.offset_range_nT = offset_range_nT
        self.population = population

    def search_box(self) -> dict:
        return population_box(self)

    def is_stochastic(self) -> bool:
        """Only NLopt's randomized algorithms use the seed (``nlopt.srand``)."""
        return any(tag in str(self.algorithm) for tag in STOCHASTIC_NLOPT)

    termination_params = {"max_evaluations": "max_evaluations"}

    def termination_settings(self) -> dict:
        return {"max_evaluations": int(self.max_evaluations), "tol": None,
                "tol_meaning": f"NLopt's own: ftol_rel {self.ftol_rel:g}, xtol_rel {self.xtol_rel:g}, maxeval counted "
                               "in NLopt's calls"}

    def _solve(self, problem: Problem):
        lo, hi = problem.lower, problem.upper
        span = hi - lo
        uses_gradient = str(self.algorithm)[1] == "D"
        gradient, Ask = loop.gradient, loop.Ask

        spent: list[bool] = []  # the framework said the budget is spent

        def run(ask):  # NLopt's loop, asking the framework for every value (recast: core/loop.py)
            nlopt.srand(int(self.seed) if self.seed is not None else 0)
            opt = nlopt.opt(getattr(nlopt, str(self.algorithm)), len(lo))

            def f(u, grad):  # NLopt's callback: a request to the framework and nothing else
                x = lo + u * span
                try:
                    if grad.size:
                        grad[:] = ask(gradient(x)) * span
                    return ask(Ask("value", x))
                except BudgetExhausted:  # NLopt's gradient methods report it as a runtime_error
                    spent.append(True)
                    raise

            opt.set_min_objective(f)
            opt.set_lower_bounds(np.zeros(len(lo)))
            opt.set_upper_bounds(np.ones(len(lo)))
            opt.set_maxeval(int(problem.termination.max_evaluations or self.max_evaluations))
            if problem.max_time_s is not None:
                opt.set_maxtime(problem.max_time_s)
            opt.set_ftol_rel(self.ftol_rel)
            opt.set_xtol_rel(self.xtol_rel)
            if self.population:
                opt.set_population(int(self.population))
            if str(self.algorithm).startswith("LN_"):
                opt.set_initial_step(np.full(len(lo), 0.05))
            u0 = np.clip((problem.x0 - lo) / span, 0.0, 1.0)
            try:
                opt.optimize(u0)
                return opt.last_optimize_result(), ""
            except nlopt.RoundoffLimited:
                return -4, ""
            except BudgetExhausted:
                raise
            except Exception as exc:  # NLopt's generic failures (nlopt.runtime_error, a broken line search, ...)
                if spent:
                    raise BudgetExhausted("the evaluation budget was spent") from None
                if problem.best_x is None:
                    raise
                return -1, f" ({type(exc).__name__}: {exc})"

        result, message = yield from loop.recast(run)
        status = RESULT_NAMES.get(result, {-1: "failure", -4: "roundoff_limited"}.get(result, f"nlopt_{result}"))
        return SolveOutput(problem.best_x, status=status, message=f"NLopt {self.algorithm}: {status}{message}",
                           nit=problem.n_evaluations, success=result > 0 or result == -4,
                           extra={"algorithm": self.algorithm, "uses_gradient": uses_gradient})

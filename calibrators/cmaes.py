"""``cmaes``: CMA-ES (Hansen's covariance matrix adaptation evolution strategy), the reference method of
continuous black-box optimization, through the well-kept ``cma`` package (pycma).

The search runs in the search box normalized to [0, 1]^p (pycma's bound handling), starting from the
identity with step ``sigma0`` (a fraction of the box).  Each generation is asked for as one population
and evaluated in one call of the shared counted objective.  The normal samples come from the problem's
``numpy.random.Generator`` (pycma's ``randn`` option), so the global numpy random state is neither used
nor changed and the same seed gives the same numbers.
"""
from __future__ import annotations

import numpy as np

from magbench.errors import InputError

from .base import Calibrator, Problem, SolveOutput, population_box
from .registry import register


@register
class CMAES(Calibrator):
    """CMA-ES (Hansen & Ostermeier 2001; pycma) on the shared objective, population per generation.  Stops
    on pycma's criteria: ``tolfun`` in nT² of the objective, ``tolx`` in the normalized box (1e-8 of the
    angle box is 2e-9 rad, far below any Cramér-Rao bound), or ``max_evaluations``."""

    name = "cmaes"
    summary = "CMA-ES (pycma), the reference black-box evolution strategy; one objective call per generation"
    stochastic = True
    check_tolerance = {"angle_rad": 2e-4, "scale": 2e-4, "offset_nT": 5.0}

    def __init__(self, model: str = "nine", seed: int | None = 0, budget=None, population: int = 0,
                 sigma0: float = 0.3, max_evaluations: int = 20000, tolfun: float = 1e-9, tolx: float = 1e-8,
                 angle_range_rad: float = 0.1, scale_range: float = 0.1, offset_range_nT: float | None = None):
        super().__init__(model=model, seed=seed, budget=budget)
        self.population = population
        self.sigma0 = sigma0
        self.max_evaluations = max_evaluations
        self.tolfun = tolfun
        self.tolx = tolx
        self.angle_range_rad = angle_range_rad
        self.scale_range = scale_range
        self.offset_range_nT = offset_range_nT

    @classmethod
    def checking_params(cls) -> dict:
        return {"max_evaluations": 8000}

    def search_box(self) -> dict:
        return population_box(self)

    def _solve(self, problem: Problem) -> SolveOutput:
        import cma

        if not (0 < self.sigma0 <= 1 and self.max_evaluations >= 1 and self.population >= 0):
            raise InputError("cmaes: 0 < sigma0 <= 1, max_evaluations >= 1 and population >= 0 are required")
        lo, hi = problem.lower, problem.upper
        span = hi - lo
        rng = problem.rng
        options = {"bounds": [0.0, 1.0], "maxfevals": int(self.max_evaluations), "tolfun": self.tolfun,
                   "tolx": self.tolx, "verbose": -9, "seed": np.nan,
                   "randn": lambda lam, n: rng.standard_normal((lam, n))}
        if self.population:
            options["popsize"] = int(self.population)
        es = cma.CMAEvolutionStrategy(np.clip((problem.x0 - lo) / span, 0.0, 1.0), self.sigma0, options)
        generations = 0
        while not es.stop():
            u = np.asarray(es.ask())
            f = problem.values(lo + u * span)
            es.tell(list(u), f.tolist())
            generations += 1
        stop = ", ".join(f"{k}" for k in es.stop())
        return SolveOutput(problem.best_x, status="converged" if "maxfevals" not in es.stop() else "max_evaluations",
                           message=f"{generations} generations of {es.popsize}; stop: {stop}", nit=generations,
                           extra={"generations": generations, "population": es.popsize})

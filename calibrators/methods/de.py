"""``de``: differential evolution (Storn & Price 1997) through SciPy's ``differential_evolution`` with
``vectorized=True``: each generation is one request to the framework (SciPy's loop runs under
``core.loop.recast``, its objective callback asking the framework).  Pang et al. (2013,
JMMM) found differential evolution the best of the evolutionary methods for fluxgate calibration.

The population is seeded from the problem's generator (SciPy's ``rng``); SciPy's final L-BFGS-B polish
is off by default (``polish=True`` turns it on; its evaluations are counted like every other).
"""
from __future__ import annotations

from numbers import Integral, Real

import numpy as np

from magbench.errors import InputError

from ..base import Calibrator
from ..core import loop
from ..core.problem import Problem, SolveOutput, population_box
from ..params import AT_LEAST_ONE, BOX, MAX_POPULATION, NON_NEGATIVE, PROBABILITY, Interval, Options

STRATEGIES = ("best1bin", "best1exp", "rand1bin", "rand1exp", "rand2bin", "rand2exp", "randtobest1bin",
              "randtobest1exp", "currenttobest1bin", "currenttobest1exp", "best2exp", "best2bin")
"""SciPy's differential_evolution strategies by name (a callable strategy is not taken here)."""


class DifferentialEvolution(Calibrator):
    """SciPy's differential evolution (best1bin by default), vectorized over the population.  It stops when
    the population's objective values agree to ``tol`` relative (SciPy's criterion; 1e-6 puts the answer
    within about 1e-6 of the optimum's residual), or after ``generations``."""

    name = "de"
    summary = "differential evolution (SciPy, vectorized: one objective call per generation)"
    stochastic = True
    check_tolerance = {"angle_rad": 2e-4, "scale": 2e-4, "offset_nT": 5.0}
    imports = ("scipy.optimize",)

    _parameter_constraints = {**Calibrator._parameter_constraints, **BOX,
                              "popsize": [Interval(Integral, 1, MAX_POPULATION // 10)],
                              "generations": AT_LEAST_ONE, "recombination": PROBABILITY, "tol": NON_NEGATIVE,
                              "strategy": [Options(STRATEGIES)], "mutation": [Interval(Real, 0, 2, "left"), tuple]}

    def __init__(self, model: str = "nine", seed: int | None = 0, budget=None, strategy: str = "best1bin",
                 popsize: int = 15, generations: int = 1000, mutation: float = 0.7, recombination: float = 0.9,
                 tol: float = 1e-6, polish: bool = False, angle_range_rad: float = 0.1, scale_range: float = 0.1,
                 offset_range_nT: float | None = None):
        super().__init__(model=model, seed=seed, budget=budget)
        self.strategy = strategy
        self.popsize = popsize
        self.generations = generations
        self.mutation = mutation
        self.recombination = recombination
        self.tol = tol
        self.polish = polish
        self.angle_range_rad = angle_range_rad
        self.scale_range = scale_range
        self.offset_range_nT = offset_range_nT

    @classmethod
    def checking_params(cls) -> dict:
        return {"generations": 600}

    def search_box(self) -> dict:
        return population_box(self)

    termination_params = {"max_iterations": "generations"}

    def termination_settings(self) -> dict:
        return {"max_iterations": int(self.generations), "tol": None,
                "tol_meaning": f"SciPy's own: std of the population's values <= {self.tol:g} x |their mean|"}

    def _solve(self, problem: Problem):
        from scipy.optimize import differential_evolution  # imported on use: the registry stays light

        lo, hi = problem.lower, problem.upper

        def run(ask):  # SciPy's loop, asking the framework for every population (recast: core/loop.py)
            def population_values(x_t: np.ndarray) -> np.ndarray:  # SciPy passes (p, S) when vectorized
                x = np.ascontiguousarray(np.atleast_2d(x_t.T) if x_t.ndim > 1 else x_t[None, :])
                return ask(loop.values(x))

            def generation_done(intermediate_result) -> bool:  # the framework counts the generation
                return ask(loop.iteration()) not in ("", "max_iterations")  # maxiter: SciPy's own stop, same place

            return differential_evolution(population_values, list(zip(lo, hi)), strategy=self.strategy,
                                          maxiter=int(self.generations), popsize=int(self.popsize), tol=self.tol,
                                          atol=0.0, mutation=self.mutation, recombination=self.recombination,
                                          rng=problem.rng, polish=self.polish, init="latinhypercube",
                                          updating="deferred", vectorized=True, x0=problem.x0,
                                          callback=generation_done)

        try:
            sol = yield from loop.recast(run)
        except ValueError as exc:  # SciPy's checks of strategy and the like
            raise InputError(f"de: {exc}") from None
        return SolveOutput(problem.best_x, status="converged" if sol.success else "max_generations",
                           message=f"{sol.nit} generations: {sol.message}", nit=int(sol.nit),
                           extra={"generations": int(sol.nit)})

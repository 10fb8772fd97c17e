"""``cmaes``: CMA-ES (Hansen's covariance matrix adaptation evolution strategy), the reference method of
continuous black-box optimization, through the well-kept ``cma`` package (pycma).

The search runs in the search box normalized to [0, 1]^p with pycma's bound handling (its
``BoxConstraintsLinQuadTransformation``: genotypes outside [0.05, 0.95] folded into the box by a periodic
linear-quadratic map), starting from the identity with step ``sigma0`` (a fraction of the box).  The map is
applied here to the whole population at once (``into_box``: the same element-wise arithmetic, so the same
numbers to the last bit) and pycma is told the genotypes; given ``bounds``, pycma would map and look up
each solution in Python, which was 40 % of a fit's time on 300 readings (the objective 5 %).  Each
generation is asked for as one population and evaluated in one call of the shared counted objective.  The
normal samples come from the problem's ``numpy.random.Generator`` (pycma's ``randn`` option), so the global
numpy random state is neither used nor changed and the same seed gives the same numbers.

Besides pycma's own stops, the search ends when the objective has flattened relative to its value
(``tolfun_rel``): the spread of the current population's values and of the best values of the last
``10 + 30 p / lambda`` generations (pycma's ``tolfun`` window) are both below ``tolfun_rel`` times the
best value.  ``F`` is a mean square in nT², so ``tolfun`` (absolute) depends on the data's noise and
units; the relative form does not.  The default 1e-6 is the precision of the population objective itself
(its fast quadric form agrees with the exact residuals to about 1e-6 of F), so generations after that
only sort rounding noise; an excess ``dF`` over the optimum moves the estimate by about
``sqrt(2 N dF / F)`` Cramér-Rao standard deviations (N readings): 0.02 at 1e-6 for N = 300.
``tolfun_rel = 0`` leaves only pycma's stops.
"""
from __future__ import annotations

import functools
from numbers import Integral, Real

import numpy as np

from ..base import Calibrator
from ..core import loop
from ..core.problem import Problem, SolveOutput, population_box
from ..params import AT_LEAST_ONE, BOX, MAX_POPULATION, NON_NEGATIVE, Interval

TOLFUN_REL = 1e-6
MARGIN = 0.05
"""The width of the linear-quadratic margins of pycma's map into [0, 1] (``linquad_margin_width``: 0.05 times
max(|bound|, 1), at most half the range) at both bounds."""
MAXSTD = 1.0 / 3.0
"""pycma's largest standard deviation in a box of range 1 (its ``maxstd_boundrange``, 1/3)."""


@functools.cache
def _box_map():
    """pycma's own map into [0, 1] (for its ``inverse`` at the start point, once per fit)."""
    from cma.transformations import BoxConstraintsLinQuadTransformation

    return BoxConstraintsLinQuadTransformation([[0.0, 1.0]])


def into_box(y: np.ndarray) -> np.ndarray:
    """pycma's ``BoxConstraintsLinQuadTransformation([[0, 1]])`` applied to every row of ``y`` (m, p): the same
    element-wise steps in the same order (a shift by whole periods into [lb - 2 al - r/2, ub + 2 au + r/2),
    reflections at ub + au and lb - al, then the quadratic pieces within al of each bound), so the same
    numbers to the last bit (tests/test_cmaes_box.py) at one vector operation per step for the population."""
    lb, ub, al, au = 0.0, 1.0, MARGIN, MARGIN
    y = np.array(y, dtype=float)
    out = (y < lb - 2 * al - (ub - lb) / 2.0) | (y > ub + 2 * au + (ub - lb) / 2.0)
    if out.any():
        r = 2 * (ub - lb + al + au)  # period
        s = lb - 2 * al - (ub - lb) / 2.0  # start
        y[out] -= r * ((y[out] - s) // r)
    idx = y > ub + au
    y[idx] -= 2 * (y[idx] - ub - au)
    idx = y < lb - al
    y[idx] += 2 * (lb - al - y[idx])
    idx = y < lb + al
    y[idx] = lb + (y[idx] - (lb - al))**2 / 4 / al
    idx = y > ub - au
    y[idx] = ub - (y[idx] - (ub + au))**2 / 4 / au
    return y


class CMAES(Calibrator):
    """CMA-ES (Hansen & Ostermeier 2001; pycma) on the shared objective, population per generation.  Stops
    on pycma's criteria: ``tolfun`` in nT² of the objective, ``tolx`` in the normalized box (1e-8 of the
    angle box is 2e-9 rad, far below any Cramér-Rao bound), ``tolfun_rel`` (relative to the best value),
    or ``max_evaluations``."""

    name = "cmaes"
    summary = "CMA-ES (pycma), the reference black-box evolution strategy; one objective call per generation"
    stochastic = True
    check_tolerance = {"angle_rad": 2e-4, "scale": 2e-4, "offset_nT": 5.0}
    imports = ("cma",)

    _parameter_constraints = {**Calibrator._parameter_constraints, **BOX, "population": [Interval(Integral, 0, MAX_POPULATION)],
                              "sigma0": [Interval(Real, 0, 1, "right")], "max_evaluations": AT_LEAST_ONE,
                              "tolfun": NON_NEGATIVE, "tolx": NON_NEGATIVE, "tolfun_rel": NON_NEGATIVE}

    @classmethod
    def _params_together(cls, params: dict) -> str | None:
        population = params["population"]
        if population == 1:  # pycma's own ValueError ('number of weights must be >=2') came from inside it
            return "population must be 0 (automatic) or at least 2 (CMA-ES recombines the best half)"
        if population > params["max_evaluations"]:
            return (f"population {population} is more than max_evaluations {params['max_evaluations']}: not even one "
                    "generation fits")
        return None

    def __init__(self, model: str = "nine", seed: int | None = 0, budget=None, population: int = 0,
                 sigma0: float = 0.3, max_evaluations: int = 20000, tolfun: float = 1e-9, tolx: float = 1e-8,
                 tolfun_rel: float = TOLFUN_REL,
                 angle_range_rad: float = 0.1, scale_range: float = 0.1, offset_range_nT: float | None = None):
        super().__init__(model=model, seed=seed, budget=budget)
        self.population = population
        self.sigma0 = sigma0
        self.max_evaluations = max_evaluations
        self.tolfun = tolfun
        self.tolx = tolx
        self.tolfun_rel = tolfun_rel
        self.angle_range_rad = angle_range_rad
        self.scale_range = scale_range
        self.offset_range_nT = offset_range_nT

    @classmethod
    def checking_params(cls) -> dict:
        return {"max_evaluations": 8000}

    def search_box(self) -> dict:
        return population_box(self)

    termination_params = {"max_evaluations": "max_evaluations", "tol": "tolfun_rel"}

    def termination_settings(self) -> dict:
        return {"max_evaluations": int(self.max_evaluations), "tol": float(self.tolfun_rel),
                "tol_meaning": "spread of the population's values and of the best values over pycma's tolfun window, "
                               "relative to the best value"}

    def _solve(self, problem: Problem):
        import cma

        lo, hi = problem.lower, problem.upper
        span = hi - lo
        rng = problem.rng
        # pycma's own bounds [0, 1] replaced by ``into_box`` on the population; what else pycma derives from
        # them is given explicitly: maxstd (the box's range times its maxstd_boundrange, 1/3) and the mean's
        # genotype (the map's inverse at x0)
        options = {"maxstd": MAXSTD, "maxfevals": int(problem.termination.max_evaluations or self.max_evaluations),
                   "tolfun": self.tolfun, "tolx": self.tolx, "verbose": -9, "seed": np.nan, "signals_filename": "",
                   "randn": lambda lam, n: rng.standard_normal((lam, n))}
        if self.population:
            options["popsize"] = int(self.population)
        x0 = np.clip((problem.x0 - lo) / span, 0.0, 1.0)
        es = cma.CMAEvolutionStrategy(_box_map().inverse(x0), self.sigma0, options)
        generations, bests, stop = 0, [], ""
        window = 10 + int(np.ceil(30 * len(lo) / es.popsize))  # pycma's tolfun history
        while not es.stop():
            genotypes = es.ask()
            u = into_box(np.asarray(genotypes))
            f = yield loop.values(lo + u * span)
            es.tell(genotypes, f.tolist())
            generations += 1
            bests.append(f.min())
            flat = np.inf
            if generations > window:  # the relative flatness; the framework compares it with tolfun_rel
                recent = bests[-window:]
                spread, best = max(f.max() - f.min(), max(recent) - min(recent)), abs(min(bests))
                flat = spread / best if best else (0.0 if spread == 0 else np.inf)
            stop = yield loop.iteration(flat)
            if stop:
                break
        stops = ["tolfun_rel"] if stop == "converged" else ["maxfevals"] if stop else list(es.stop())
        return SolveOutput(problem.best_x, status="max_evaluations" if "maxfevals" in stops else "converged",
                           message=f"{generations} generations of {es.popsize}; stop: {', '.join(stops)}",
                           nit=generations, extra={"generations": generations, "population": es.popsize})

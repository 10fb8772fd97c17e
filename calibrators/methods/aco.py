"""``aco``: ant colony optimization for continuous domains, ACO_R (Socha and Dorigo, "Ant colony
optimization for continuous domains", EJOR 185, 2008).

A solution archive of ``archive_size`` points, sorted by objective, is a mixture of Gaussian kernels.
Kernel l (rank l, from 1) has weight ``w_l = exp(-(l-1)² / (2 q² k²)) / (q k sqrt(2 pi))`` (their
eq. 7); each ant picks a kernel with probability ``w_l / sum w`` (eq. 8) and samples every coordinate
i from N(s_l^i, sigma_l^i) with ``sigma_l^i = xi sum_e |s_e^i - s_l^i| / (k - 1)`` (eq. 9).  The
``ants`` new solutions join the archive and the worst are dropped.  All ants of an iteration are
sampled and evaluated in one call; genes are normalized to [0, 1] over the search box.

The search ends after ``iterations``, or earlier when the archive has converged: the values of all its
``archive_size`` solutions agree within ``tol`` relative to the best, ``f_k - f_1 <= tol |f_1|`` (``tol = 0``
runs every iteration).  The default 1e-6 is the numerical precision of the population objective itself
(its fast quadric form agrees with the exact residuals to about 1e-6 of F), so iterations after that
point only sort rounding noise; an excess of 1e-6 F over the optimum moves the estimate by about
``sqrt(2e-6 N)`` Cramér-Rao standard deviations (0.02 for N = 300 readings).  An archive still spread
over the box (a search that has not found the basin) never stops early.
"""
from __future__ import annotations

from numbers import Integral

import numpy as np

from ..base import Calibrator
from ..core import loop
from ..core.problem import Problem, SolveOutput, population_box
from ..params import AT_LEAST_ONE, BOX, MAX_POPULATION, NON_NEGATIVE, POPULATION, POSITIVE, Interval

TOL = 1e-6


class AntColony(Calibrator):
    """ACO_R (Socha & Dorigo 2008) with archive size, q and xi as hyper-parameters; stops after
    ``iterations`` or when the whole archive's values agree within ``tol`` relative (converged)."""

    name = "aco"
    summary = "ant colony optimization for continuous domains (ACO_R, Socha & Dorigo 2008)"
    stochastic = True
    check_tolerance = {"angle_rad": 2e-4, "scale": 2e-4, "offset_nT": 5.0}

    _parameter_constraints = {**Calibrator._parameter_constraints, **BOX, "archive_size": [Interval(Integral, 2, MAX_POPULATION)],
                              "ants": POPULATION, "q": POSITIVE, "xi": POSITIVE, "iterations": AT_LEAST_ONE,
                              "tol": NON_NEGATIVE}

    def __init__(self, model: str = "nine", seed: int | None = 0, budget=None, archive_size: int = 50,
                 ants: int = 20, q: float = 0.1, xi: float = 0.85, iterations: int = 4000,
                 tol: float = TOL,
                 angle_range_rad: float = 0.1, scale_range: float = 0.1, offset_range_nT: float | None = None):
        super().__init__(model=model, seed=seed, budget=budget)
        self.archive_size = archive_size
        self.ants = ants
        self.q = q
        self.xi = xi
        self.iterations = iterations
        self.tol = tol
        self.angle_range_rad = angle_range_rad
        self.scale_range = scale_range
        self.offset_range_nT = offset_range_nT

    @classmethod
    def checking_params(cls) -> dict:
        return {"iterations": 1500}

    def search_box(self) -> dict:
        return population_box(self)

    termination_params = {"max_iterations": "iterations", "tol": "tol"}

    def termination_settings(self) -> dict:
        return {"max_iterations": int(self.iterations), "tol": float(self.tol),
                "tol_meaning": "(f_k - f_1) / |f_1| over the archive's values (converged when they agree)"}

    def _solve(self, problem: Problem):
        k, m = self.archive_size, self.ants
        rng = problem.rng
        lo, hi = problem.lower, problem.upper
        span, p = hi - lo, len(lo)
        rank = np.arange(k)
        with np.errstate(all="ignore"):
            w = np.exp(-rank**2 / (2.0 * (self.q * k) ** 2)) / (self.q * k * np.sqrt(2 * np.pi))  # eq. 7
            cum = np.cumsum(w / w.sum())  # eq. 8
        if not np.all(np.isfinite(cum)):  # a q so small that eq. 7's factor overflows: the best solution alone
            cum = np.ones(k)

        archive = rng.random((k, p))
        f = yield loop.values(lo + archive * span)
        order = np.argsort(f)
        archive, f = archive[order], f[order]
        best = [float(f[0])]
        pool = np.empty((k + m, p))  # the archive and this iteration's ants, rows k.. overwritten each time
        f_pool = np.empty(k + m)
        tol = float(self.tol)
        done, status = 0, "max_iterations"
        while True:
            chosen = np.searchsorted(cum, rng.random(m) * cum[-1], side="right")
            centres = archive[chosen]  # (m, p)
            sigma = self.xi * np.abs(archive[None, :, :] - centres[:, None, :]).sum(axis=1) / (k - 1)  # eq. 9
            ants = centres + sigma * rng.standard_normal((m, p))
            np.clip(ants, 0.0, 1.0, out=ants)
            f_ants = yield loop.values(lo + ants * span)
            pool[:k], pool[k:] = archive, ants
            f_pool[:k], f_pool[k:] = f, f_ants
            keep = np.argsort(f_pool, kind="stable")[:k]
            archive, f = pool[keep], f_pool[keep]
            best.append(float(f[0]))
            done += 1
            spread = (f[-1] - f[0]) / abs(f[0]) if f[0] != 0 else (0.0 if f[-1] == f[0] else np.inf)
            stop = yield loop.iteration(spread)  # the framework compares it with tol, counts iterations
            if stop:
                status = "converged" if stop == "converged" else "max_iterations"
                break
        message = f"{done} iterations" + (f" (the archive's values agree within {tol:g})" if status == "converged"
                                          else "")
        return SolveOutput(problem.best_x, status=status, message=message, nit=done, extra={"best_F": best})

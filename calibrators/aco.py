"""``aco``: ant colony optimization for continuous domains, ACO_R (Socha and Dorigo, "Ant colony
optimization for continuous domains", EJOR 185, 2008).

A solution archive of ``archive_size`` points, sorted by objective, is a mixture of Gaussian kernels.
Kernel l (rank l, from 1) has weight ``w_l = exp(-(l-1)² / (2 q² k²)) / (q k sqrt(2 pi))`` (their
eq. 7); each ant picks a kernel with probability ``w_l / sum w`` (eq. 8) and samples every coordinate
i from N(s_l^i, sigma_l^i) with ``sigma_l^i = xi sum_e |s_e^i - s_l^i| / (k - 1)`` (eq. 9).  The
``ants`` new solutions join the archive and the worst are dropped.  All ants of an iteration are
sampled and evaluated in one call; genes are normalized to [0, 1] over the search box.
"""
from __future__ import annotations

import numpy as np

from magbench.errors import InputError

from .base import Calibrator, Problem, SolveOutput, population_box
from .registry import register


@register
class AntColony(Calibrator):
    """ACO_R (Socha & Dorigo 2008) with archive size, q and xi as hyper-parameters."""

    name = "aco"
    summary = "ant colony optimization for continuous domains (ACO_R, Socha & Dorigo 2008)"
    stochastic = True
    check_tolerance = {"angle_rad": 2e-4, "scale": 2e-4, "offset_nT": 5.0}

    def __init__(self, model: str = "nine", seed: int | None = 0, budget=None, archive_size: int = 50,
                 ants: int = 20, q: float = 0.1, xi: float = 0.85, iterations: int = 4000,
                 angle_range_rad: float = 0.1, scale_range: float = 0.1, offset_range_nT: float | None = None):
        super().__init__(model=model, seed=seed, budget=budget)
        self.archive_size = archive_size
        self.ants = ants
        self.q = q
        self.xi = xi
        self.iterations = iterations
        self.angle_range_rad = angle_range_rad
        self.scale_range = scale_range
        self.offset_range_nT = offset_range_nT

    @classmethod
    def checking_params(cls) -> dict:
        return {"iterations": 1500}

    def search_box(self) -> dict:
        return population_box(self)

    def _solve(self, problem: Problem) -> SolveOutput:
        k, m = self.archive_size, self.ants
        if k < 2 or m < 1 or self.q <= 0 or self.xi <= 0:
            raise InputError("aco: archive_size >= 2, ants >= 1, q > 0 and xi > 0 are required")
        rng, obj = problem.rng, problem
        lo, hi = problem.lower, problem.upper
        span, p = hi - lo, len(lo)
        rank = np.arange(k)
        w = np.exp(-rank**2 / (2.0 * (self.q * k) ** 2)) / (self.q * k * np.sqrt(2 * np.pi))  # eq. 7
        cum = np.cumsum(w / w.sum())  # eq. 8

        archive = rng.random((k, p))
        f = obj.values(lo + archive * span)
        order = np.argsort(f)
        archive, f = archive[order], f[order]
        best = [f[0]]
        for _ in range(self.iterations):
            chosen = np.searchsorted(cum, rng.random(m) * cum[-1], side="right")
            centres = archive[chosen]  # (m, p)
            sigma = self.xi * np.abs(archive[None, :, :] - centres[:, None, :]).sum(axis=1) / (k - 1)  # eq. 9
            ants = np.clip(centres + sigma * rng.standard_normal((m, p)), 0.0, 1.0)
            f_ants = obj.values(lo + ants * span)
            pool = np.vstack([archive, ants])
            f_pool = np.concatenate([f, f_ants])
            keep = np.argsort(f_pool, kind="stable")[:k]
            archive, f = pool[keep], f_pool[keep]
            best.append(f[0])
        return SolveOutput(problem.best_x, status="max_iterations", message=f"{self.iterations} iterations",
                           nit=self.iterations, extra={"best_F": best})

"""``ellipsoid``: the linear algebraic ellipsoid fit with the ellipsoid-specific constraint.

Li and Griffiths (2004), "Least squares ellipsoid specific fitting", GMP 2004: the quadric
``a x² + b y² + c z² + 2f yz + 2g xz + 2h xy + 2p x + 2q y + 2r z + d = 0`` is fitted under
``k J - I² = 1`` (k = 4, I = a + b + c, J = ab + bc + ca - f² - g² - h²), which makes the
solution an ellipsoid whenever the data are roughly ellipsoidal; the generalized eigenproblem
``C1^-1 (S11 - S12 S22^-1 S21) v1 = λ v1`` gives it in closed form (their eq. 13-15).  The fitted
shape ``(x - c)^T A (x - c) = 1`` is scaled to the reference magnitude, ``W = F² A = M^T M``, and
reported through the canonical decomposition of CONTRACT section 1.  Seed 003 builds RANSAC on it.
"""
from __future__ import annotations

from ..base import Calibrator
from ..core.algebra import ellipsoid_params
from ..core.problem import ReadingsProblem, SolveOutput


class EllipsoidFit(Calibrator):
    """Algebraic ellipsoid-specific fit (Li and Griffiths 2004), closed form, no iterations."""

    name = "ellipsoid"
    summary = "linear ellipsoid-specific fit (Li & Griffiths 2004), canonical decomposition"
    supported_models = ("nine",)
    check_tolerance = {"angle_rad": 1e-4, "scale": 1e-4, "offset_nT": 2.0}
    closed_form = True

    def __init__(self, model: str = "nine", seed: int | None = 0, budget=None):
        super().__init__(model=model, seed=seed, budget=budget)

    def min_points(self, model: str) -> int:
        return 10

    def _solve(self, problem: ReadingsProblem) -> SolveOutput:
        params = ellipsoid_params(problem.raw_nT, problem.f_ref_nT)
        return SolveOutput(params.to_vector("nine"), status="closed_form", message="algebraic fit")

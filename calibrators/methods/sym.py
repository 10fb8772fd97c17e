"""``sym``: the general least-squares ellipsoid with a symmetric soft-iron matrix, as MATLAB magcal's
``sym`` option returns it (``corrected = (D - b) * A``, A symmetric positive definite).

The quadric's ten coefficients minimize the algebraic distance under a unit norm (the smallest right
singular vector of the design; Fitzgibbon-style direct fit without the ellipsoid-specific constraint, so
elongated ellipsoids such as magcal's documentation example, radii 30/20/50, are fitted), the ellipsoid
``(x - b)^T Q (x - b) = 1`` is scaled to the reference magnitude ``F``: ``W = F² Q = A² = M^T M`` with
``A = sqrtm(W)``, and reported through the canonical decomposition of CONTRACT section 1.  ``expmfs`` (the
radius of the sphere of the ellipsoid's volume) is given in ``extra``; with ``--field auto`` it is the
reference."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..acceptance import DEFAULT_LIMITS
from ..base import Calibrator
from ..core.algebra import fit_quadric, shape_to_params, volume_radius
from ..core.problem import ReadingsProblem, SolveOutput


class SymmetricEllipsoid(Calibrator):
    """magcal-style symmetric ellipsoid fit: closed form, no iterations."""

    name = "sym"
    summary = "general least-squares ellipsoid, symmetric soft-iron matrix (MATLAB magcal 'sym'), closed form"
    supported_models = ("nine",)
    check_tolerance = {"angle_rad": 1e-4, "scale": 1e-4, "offset_nT": 2.0}
    closed_form = True
    # a general ellipsoid (a hard-iron offset larger than the field, strongly elongated soft iron) is not held
    # to a fluxgate's physical range; every other acceptance check applies
    acceptance = replace(DEFAULT_LIMITS, physical_range=False)

    def __init__(self, model: str = "nine", seed: int | None = 0, budget=None):
        super().__init__(model=model, seed=seed, budget=budget)

    def min_points(self, model: str) -> int:
        return 10

    def _solve(self, problem: ReadingsProblem) -> SolveOutput:
        shape, centre = fit_quadric(problem.raw_nT)
        params = shape_to_params(shape, centre, problem.f_ref_nT)
        f = float(np.median(problem.f_ref_nT))
        w = f * f * shape
        evals, evecs = np.linalg.eigh(w)
        soft_iron = (evecs * np.sqrt(evals)) @ evecs.T  # A = sqrtm(W), symmetric positive definite
        return SolveOutput(params.to_vector("nine"), status="closed_form", message="algebraic general ellipsoid",
                           extra={"expmfs_nT": volume_radius(shape), "soft_iron_A": soft_iron.tolist(),
                                  "hard_iron_b_nT": centre.tolist()})

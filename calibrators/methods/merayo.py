"""``merayo``: the non-iterative scalar calibration of Merayo, Brauer, Primdahl, Petersen and Nielsen
(2000), "Scalar calibration of vector magnetometers", Meas. Sci. Technol. 11, 120-132.

The scalar model ``|T (r_k - o)|² = F_k²`` is, with ``W = T^T T``, the quadric
``r^T W r - 2 (W o)^T r + o^T W o = F_k²``.  Written with free coefficients ``Q = W / mu``, ``l``, ``d``
and the reference's weight ``mu``, ``r^T Q r + 2 l^T r + d - mu F_k² = 0`` is linear and homogeneous; the
trace normalization ``trace Q = 1`` makes it one linear least-squares solve, without iteration (their
section 3: the problem linearized in the quadric's coefficients and solved directly).  The offset is
``o = -Q^-1 l``; the gain follows from the reference: ``W = Q / mu`` when the reference varies along the
record, else (a constant ``F``, where ``mu F²`` and ``d`` cannot be told apart) from the ellipsoid
``(r - o)^T Q (r - o) = gamma`` scaled to ``F²``.  T is reduced to the canonical lower-triangular form of
CONTRACT section 1 (the orthogonal part that scalar data cannot see is dropped)."""
from __future__ import annotations

import numpy as np

from magbench.errors import FitError
from magbench.simulate.sensor import ErrorParams

from ..base import Calibrator
from ..core.algebra import normalize, quadric_to_ellipsoid, shape_to_params
from ..core.problem import ReadingsProblem, SolveOutput

REFERENCE_VARIES = 1e-6
"""Relative spread of F below which the reference is treated as constant (its weight is then not fitted)."""


def merayo_params(raw_nT: np.ndarray, f_ref_nT: np.ndarray) -> ErrorParams:
    """The closed-form scalar calibration, in the canonical parameters."""
    raw = np.asarray(raw_nT, dtype=float)
    f = np.broadcast_to(np.asarray(f_ref_nT, dtype=float), (len(raw),))
    norm, mu, s = normalize(raw)  # conditioning: readings centred and scaled
    x, y, z = norm.T
    f2 = (f / s) ** 2
    varies = np.ptp(f) > REFERENCE_VARIES * np.median(f)
    # trace Q = 1: q_xx = a, q_yy = b, q_zz = 1 - a - b
    cols = [x * x - z * z, y * y - z * z, 2 * x * y, 2 * x * z, 2 * y * z, 2 * x, 2 * y, 2 * z, np.ones_like(x)]
    if varies:
        cols.append(-f2)
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), -z * z, rcond=None)
    a, b, h, g, fz = coef[:5]
    quad = np.array([[a, h, g], [h, b, fz], [g, fz, 1.0 - a - b]])
    lin, const = coef[5:8], coef[8]
    if not np.all(np.isfinite(coef)):
        raise FitError("the readings do not determine a scalar calibration")
    if varies:
        weight = coef[9]
        if not weight > 0:
            raise FitError("the scalar calibration found no positive gain for the reference")
        w_n = quad / weight  # W in normalized units: (r - o)^T W (r - o) = F² / s²
        centre_n = -np.linalg.solve(quad, lin)
        shape_n = w_n / float(np.median(f2))  # the form shape_to_params scales back by the median F²
        if np.any(np.linalg.eigvalsh(shape_n) <= 0):
            raise FitError("the fitted quadric is not an ellipsoid")
    else:
        shape_n, centre_n = quadric_to_ellipsoid(quad, lin, const)
    return shape_to_params(shape_n / (s * s), mu + s * centre_n, f)


class Merayo(Calibrator):
    """Merayo et al. (2000) non-iterative scalar calibration: closed form."""

    name = "merayo"
    summary = "non-iterative scalar calibration (Merayo et al. 2000), closed form"
    supported_models = ("nine",)
    check_tolerance = {"angle_rad": 1e-4, "scale": 1e-4, "offset_nT": 2.0}
    closed_form = True

    def __init__(self, model: str = "nine", seed: int | None = 0, budget=None):
        super().__init__(model=model, seed=seed, budget=budget)

    def min_points(self, model: str) -> int:
        return 11

    def _solve(self, problem: ReadingsProblem) -> SolveOutput:
        params = merayo_params(problem.raw_nT, problem.f_ref_nT)
        return SolveOutput(params.to_vector("nine"), status="closed_form", message="linear scalar calibration")

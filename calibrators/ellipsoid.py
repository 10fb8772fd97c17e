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

import numpy as np

from magbench.errors import InputError
from magbench.simulate.sensor import ErrorParams

from .base import Calibrator, ReadingsProblem, SolveOutput
from .registry import register


def fit_ellipsoid(raw_nT: np.ndarray, k: float = 4.0) -> tuple[np.ndarray, np.ndarray]:
    """Li-Griffiths fit: returns (A, center) with ``(x - center)^T A (x - center) = 1``.

    Raises ``InputError`` when the data do not determine an ellipsoid (too few or coplanar points,
    or a solution that is not positive definite).
    """
    raw = np.asarray(raw_nT, dtype=float)
    if raw.shape[0] < 9:
        raise InputError(f"an ellipsoid fit needs at least 9 points, got {raw.shape[0]}")
    norm, mu, s = normalize(raw)
    x, y, z = norm.T  # normalized for numerical conditioning
    d = np.array([x * x, y * y, z * z, 2 * y * z, 2 * x * z, 2 * x * y, 2 * x, 2 * y, 2 * z, np.ones_like(x)])
    s_mat = d @ d.T
    s11, s12, s22 = s_mat[:6, :6], s_mat[:6, 6:], s_mat[6:, 6:]
    c1 = np.zeros((6, 6))
    c1[:3, :3] = k / 2.0 - 1.0
    np.fill_diagonal(c1[:3, :3], -1.0)
    c1[3:, 3:] = -k * np.eye(3)
    try:
        s22_inv_s21 = np.linalg.solve(s22, s12.T)
        eigval, eigvec = np.linalg.eig(np.linalg.solve(c1, s11 - s12 @ s22_inv_s21))
    except np.linalg.LinAlgError:
        raise InputError("the readings do not determine an ellipsoid (singular design: coplanar "
                         "or too few distinct points)") from None
    eigval, eigvec = np.real(eigval), np.real(eigvec)
    positive = np.flatnonzero(eigval > 0)
    if positive.size == 0:
        raise InputError("the ellipsoid fit has no admissible solution (no positive eigenvalue)")
    v1 = eigvec[:, positive[np.argmax(eigval[positive])]]
    v2 = -s22_inv_s21 @ v1
    a, b, c, f, g, h = v1
    shape, center_n = quadric_to_ellipsoid(np.array([[a, h, g], [h, b, f], [g, f, c]]), v2[:3], v2[3])
    return shape / (s * s), mu + s * center_n


def normalize(raw_nT: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Readings centred on their mean and divided by their mean distance from it (for conditioning)."""
    raw = np.asarray(raw_nT, dtype=float)
    mu = raw.mean(axis=0)
    s = float(np.mean(np.linalg.norm(raw - mu, axis=1)))
    if not s > 0:
        raise InputError("all readings are identical: no ellipsoid or sphere can be fitted to them")
    return (raw - mu) / s, mu, s


def quadric_to_ellipsoid(quad: np.ndarray, lin: np.ndarray, const: float) -> tuple[np.ndarray, np.ndarray]:
    """``x^T Q x + 2 l^T x + d = 0`` -> (A, c) with ``(x - c)^T A (x - c) = 1``; refuses a non-ellipsoid."""
    if np.trace(quad) < 0:
        quad, lin, const = -quad, -lin, -const
    if np.any(np.linalg.eigvalsh(quad) <= 0):
        raise InputError("the fitted quadric is not an ellipsoid (the readings do not cover enough "
                         "directions)")
    center = -np.linalg.solve(quad, lin)
    rhs = center @ quad @ center - const
    if not rhs > 0:
        raise InputError("the fitted quadric is not an ellipsoid (imaginary or degenerate)")
    return quad / rhs, center


def shape_to_params(shape: np.ndarray, center: np.ndarray, f_ref_nT) -> ErrorParams:
    """Canonical 9 parameters of the ellipsoid ``(x - c)^T A (x - c) = 1`` scaled to the reference:
    W = F² A = M^T M (CONTRACT section 1)."""
    f = float(np.median(f_ref_nT))
    w = f * f * shape
    m = np.linalg.cholesky(w).T  # any C with C^T C = W; the canonical form fixes the rotation
    return ErrorParams.from_correction(m, center)


def ellipsoid_params(raw_nT: np.ndarray, f_ref_nT) -> ErrorParams:
    """Canonical 9 parameters from the ellipsoid fit, scaled to the median reference magnitude."""
    return shape_to_params(*fit_ellipsoid(raw_nT), f_ref_nT)


@register
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

"""Closed-form quadric fits shared by the framework (start points, ``--field auto``) and the algebraic
methods: the Li-Griffiths ellipsoid-specific fit (Li and Griffiths 2004, eq. 13-15), the least-squares
sphere and the axis-aligned ellipsoid, and the ellipsoid's canonical parameters (CONTRACT section 1)."""
from __future__ import annotations

import numpy as np

from magbench.errors import FitError, InputError
from magbench.simulate.sensor import ErrorParams

ELLIPSOID_K_MAX = 256.0
"""The largest k of the constraint ``k J - I² = 1`` tried: k = 4 guarantees an ellipsoid when its shortest
semi-axis is at least half the longest; where it finds none, k is doubled (Li & Griffiths 2004, section 4,
search k upwards), up to this bound."""


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
        raise FitError("the readings do not determine an ellipsoid (singular design: coplanar "
                         "or too few distinct points)") from None
    eigval, eigvec = np.real(eigval), np.real(eigvec)
    positive = np.flatnonzero(eigval > 0)
    if positive.size == 0:
        if k < ELLIPSOID_K_MAX:  # Li & Griffiths, section 4: a larger k admits more elongated ellipsoids
            return fit_ellipsoid(raw, 2.0 * k)
        raise FitError("the ellipsoid fit has no admissible solution (no positive eigenvalue)")
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
        raise FitError("the fitted quadric is not an ellipsoid (the readings do not cover enough "
                         "directions)")
    center = -np.linalg.solve(quad, lin)
    rhs = center @ quad @ center - const
    if not rhs > 0:
        raise FitError("the fitted quadric is not an ellipsoid (imaginary or degenerate)")
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


def sphere_fit(raw_nT: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre and radius of the least-squares sphere ``|r - c|² = R²`` (linear in c and R² - |c|²)."""
    raw = np.asarray(raw_nT, dtype=float)
    if raw.shape[0] < 4:
        raise InputError(f"a sphere fit needs at least 4 points, got {raw.shape[0]}")
    x, mu, s = normalize(raw)
    design = np.column_stack([2 * x, np.ones(len(x))])
    sol, *_ = np.linalg.lstsq(design, np.sum(x * x, axis=1), rcond=None)
    c, k = sol[:3], sol[3]
    r2 = k + c @ c
    if not r2 > 0:
        raise FitError("the readings fit no sphere")
    return mu + s * c, float(s * np.sqrt(r2))


def axis_ellipsoid_fit(raw_nT: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centre and semi-axes of the least-squares axis-aligned ellipsoid
    ``a x² + b y² + c z² + d x + e y + f z = 1`` (linear), for the ``diag`` model."""
    raw = np.asarray(raw_nT, dtype=float)
    if raw.shape[0] < 7:
        raise InputError(f"an axis-aligned ellipsoid fit needs at least 7 points, got {raw.shape[0]}")
    x, mu, s = normalize(raw)
    design = np.column_stack([x * x, x])
    sol, *_ = np.linalg.lstsq(design, np.ones(len(x)), rcond=None)
    quad, lin = sol[:3], sol[3:]
    if np.any(quad <= 0):
        raise FitError("the readings fit no axis-aligned ellipsoid (they cover too few directions)")
    centre = -lin / (2 * quad)
    g = 1.0 + np.sum(quad * centre * centre)
    if not g > 0:
        raise FitError("the readings fit no axis-aligned ellipsoid")
    return mu + s * centre, s * np.sqrt(g / quad)


def fit_quadric(raw_nT: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The general least-squares ellipsoid (algebraic distance, unit-norm coefficients): the right singular
    vector of the smallest singular value of the quadric design ``[x², y², z², 2xy, 2xz, 2yz, 2x, 2y, 2z, 1]``
    on normalized readings (the fit behind MATLAB magcal's ``sym`` option).  Unlike the Li-Griffiths fit it
    has no ellipsoid-specific constraint, so elongated ellipsoids (radii in ratio beyond 2) are fitted too;
    returns (A, centre) with ``(x - centre)^T A (x - centre) = 1``, or raises ``InputError`` when the quadric
    is not an ellipsoid."""
    raw = np.asarray(raw_nT, dtype=float)
    if raw.shape[0] < 10:
        raise InputError(f"a general ellipsoid fit needs at least 10 points, got {raw.shape[0]}")
    norm, mu, s = normalize(raw)
    x, y, z = norm.T
    design = np.column_stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z, 2 * x, 2 * y, 2 * z,
                              np.ones_like(x)])
    try:
        v = np.linalg.svd(design, full_matrices=False)[2][-1]
    except np.linalg.LinAlgError:
        raise FitError("the readings do not determine an ellipsoid (singular design)") from None
    a, b, c, h, g, f = v[:6]
    shape, centre_n = quadric_to_ellipsoid(np.array([[a, h, g], [h, b, f], [g, f, c]]), v[6:9], v[9])
    return shape / (s * s), mu + s * centre_n


def volume_radius(shape: np.ndarray) -> float:
    """The radius of the sphere of the ellipsoid ``x^T A x = 1``'s volume: the geometric mean of its semi-axes
    (MATLAB magcal's ``expmfs``)."""
    det = float(np.linalg.det(shape))
    if not det > 0:
        raise FitError("the fitted quadric is not an ellipsoid")
    return det ** (-1.0 / 6.0)

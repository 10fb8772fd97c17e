"""A base correction (``angles`` or ``nine``, CONTRACT section 1) extended by one effect's fitted form
(``simulate.effects``), fitted by least squares on the scalar residual:

    u = raw - effect.fit_offset(o)
    u = effect.fit_readings(u)
    r = |P(alpha, beta, gamma) K^-1 u| - F          (seed 000, eq. 2)
    r = effect.fit_residual(r)
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from magbench.simulate.effects import Columns, Effect, Normalization
from magbench.simulate.sensor import PARAM_NAMES, paper_matrix

ANGLE_BOX_RAD = 0.1
"""The base correction may move by this much in each angle from its start ..."""
SCALE_BOX = 0.1
"""... by this share of each scale factor ..."""
OFFSET_BOX_OF_FIELD = 0.2
"""... and by this share of the field in offset."""
NFEV_PER_PARAMETER = 100
TOLERANCE = 1e-10


def base_correction(base_x: np.ndarray, base: str) -> tuple[np.ndarray, np.ndarray]:
    """M = P(alpha, beta, gamma) K^-1 and the offset o of a base parameter vector (CONTRACT section 1)."""
    mat = paper_matrix(base_x[0], base_x[1], base_x[2])
    if base == "nine":
        return mat * (1.0 / base_x[3:6])[None, :], np.asarray(base_x[6:9], dtype=float)
    return mat, np.zeros(3)


class EffectModel:
    """Base model plus one effect (``None``: the base model alone); ``norm`` fixes the normalizations
    (time span, mean temperature, F0) from the full record so that every fold uses the same parameter
    meaning."""

    def __init__(self, base: str, effect: type[Effect] | None, norm: Normalization):
        self.base, self.effect, self.norm = base, effect or Effect, norm
        self.names = PARAM_NAMES[base] + self.effect.fit_params
        self.nb = len(PARAM_NAMES[base])

    @property
    def n_params(self) -> int:
        return len(self.names)

    def x0(self, base_x: np.ndarray) -> np.ndarray:
        """The base parameters followed by the effect's start values."""
        return np.concatenate([base_x, self.effect.fit_start()])

    def residuals(self, x: np.ndarray, d: Columns) -> np.ndarray:
        """The scalar residual |B| - F of the extended correction (module docstring)."""
        base_x, e = x[:self.nb], x[self.nb:]
        mat, o = base_correction(base_x, self.base)
        u = d.raw_nT - self.effect.fit_offset(o, e)
        u = self.effect.fit_readings(u, e, d, self.norm)
        r = np.linalg.norm(u @ mat.T, axis=1) - d.f_ref_nT
        return self.effect.fit_residual(r, e, d, self.norm)

    def bounds(self, x_start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A trust box about the start: the base correction may move by ANGLE_BOX_RAD, SCALE_BOX of scale and
        OFFSET_BOX_OF_FIELD of the field in offset (far enough for any real sensor; it keeps the fit off the
        degenerate far-centre ellipsoids that scalar data otherwise allow); the effect's own bounds."""
        half = np.full(self.nb, ANGLE_BOX_RAD)
        if self.base == "nine":
            half[3:6] = SCALE_BOX * np.abs(x_start[3:6])
            half[6:9] = OFFSET_BOX_OF_FIELD * self.norm.f0_nT
        lo_e, hi_e = self.effect.fit_bounds(self.norm)
        base_x = x_start[:self.nb]
        return np.concatenate([base_x - half, lo_e]), np.concatenate([base_x + half, hi_e])

    def fit(self, d: Columns, x_start: np.ndarray) -> np.ndarray:
        """Bounded least squares (trust-region reflective) from ``x_start``."""
        lo, hi = self.bounds(x_start)
        sol = least_squares(self.residuals, x_start, args=(d,), method="trf", bounds=(lo, hi), x_scale="jac",
                            max_nfev=NFEV_PER_PARAMETER * self.n_params, ftol=TOLERANCE, xtol=TOLERANCE)
        return sol.x

"""Model extensions for the effects of ``simulate.effects``: the base correction (angles or nine) plus
one effect's parameters, fitted by least squares on the scalar residual.

    u = raw - o                                   offset (base nine, or the ``offset`` effect)
    u = (u - o_T dT) / (1 + k_T dT)               ``temperature``: dT = T - mean(T), k_T in ppm/°C
    u = u - q u² / F0                             ``nonlinearity`` (first-order inverse of the quadratic)
    B = P(alpha, beta, gamma) K^-1 u              ``scale`` (K free) on the angles base
    r = |B| - F - sum_j c_j L_j(t)                ``field_drift``: Legendre polynomials of the time
    ``outliers``: a robust (soft-L1) fit; held-out samples beyond 5 robust sigma are explained as spikes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.polynomial import legendre
from scipy.optimize import least_squares

from magbench.simulate.sensor import PARAM_NAMES

from .objective import correction_matrices

DRIFT_DEGREE = 8
EFFECT_PARAMS = {
    "none": (), "scale": ("kx", "ky", "kz"), "offset": ("ox_nT", "oy_nT", "oz_nT"),
    "temperature": ("oTx_nT_per_C", "oTy_nT_per_C", "oTz_nT_per_C", "kTx_ppm_per_C", "kTy_ppm_per_C", "kTz_ppm_per_C"),
    "nonlinearity": ("qx", "qy", "qz"), "field_drift": tuple(f"drift_L{j}_nT" for j in range(1, DRIFT_DEGREE + 1)),
    "outliers": (),
}
NEEDS = {"temperature": "temp_C", "field_drift": "t_s"}


@dataclass
class Data:
    """The columns the extended models use (a subset of a Dataset, e.g. one cross-validation fold)."""

    raw: np.ndarray
    f_ref: np.ndarray
    t_s: np.ndarray | None = None
    temp_C: np.ndarray | None = None

    def take(self, idx) -> "Data":
        return Data(self.raw[idx], self.f_ref[idx], None if self.t_s is None else self.t_s[idx],
                    None if self.temp_C is None else self.temp_C[idx])


class ExtendedModel:
    """Base model (``angles`` or ``nine``) plus one effect; ``context`` fixes the normalizations (time span,
    mean temperature, F0) from the full record so that every fold uses the same parameter meaning."""

    def __init__(self, base: str, effect: str, context: Data):
        if effect not in EFFECT_PARAMS:
            raise ValueError(f"unknown effect {effect!r}")
        self.base, self.effect = base, effect
        self.names = PARAM_NAMES[base] + EFFECT_PARAMS[effect]
        self.nb = len(PARAM_NAMES[base])
        self.f0 = float(np.median(context.f_ref))
        if context.t_s is not None:
            self.t0, self.t_span = float(context.t_s.min()), max(float(np.ptp(context.t_s)), 1e-9)
        if context.temp_C is not None:
            self.temp0 = float(np.mean(context.temp_C))

    @property
    def n_params(self) -> int:
        return len(self.names)

    def x0(self, base_x: np.ndarray) -> np.ndarray:
        extra = np.zeros(len(EFFECT_PARAMS[self.effect]))
        if self.effect == "scale":
            extra[:] = 1.0
        return np.concatenate([base_x, extra])

    def residuals(self, x: np.ndarray, d: Data) -> np.ndarray:
        base_x, e = x[:self.nb], x[self.nb:]
        mat, o = correction_matrices(base_x[None, :], self.base)
        mat, o = mat[0], o[0]
        if self.effect == "offset":
            o = o + e
        u = d.raw - o
        if self.effect == "temperature":
            dt = (d.temp_C - self.temp0)[:, None]
            u = (u - e[:3] * dt) / (1.0 + 1e-6 * e[3:6] * dt)
        elif self.effect == "nonlinearity":
            u = u - e * u * u / self.f0
        elif self.effect == "scale":
            u = u / e
        r = np.linalg.norm(u @ mat.T, axis=1) - d.f_ref
        if self.effect == "field_drift":
            tau = 2.0 * (d.t_s - self.t0) / self.t_span - 1.0
            r = r - legendre.legvander(tau, DRIFT_DEGREE)[:, 1:] @ e
        return r

    def bounds(self, x_start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A trust box about the start: the base correction may move by 0.1 rad, 10 % of scale and 20 % of
        the field in offset (far enough for any real sensor; it keeps the fit off the degenerate
        far-centre ellipsoids that scalar data otherwise allow), the effect parameters are free
        (a ``scale`` effect within 0.5..2)."""
        half = np.full(self.n_params, np.inf)
        half[:3] = 0.1
        if self.base == "nine":
            half[3:6] = 0.1 * np.abs(x_start[3:6])
            half[6:9] = 0.2 * self.f0
        lo, hi = x_start - half, x_start + half
        if self.effect == "scale":
            lo[self.nb:], hi[self.nb:] = 0.5, 2.0
        if self.effect == "offset":
            lo[self.nb:], hi[self.nb:] = -0.2 * self.f0, 0.2 * self.f0
        return lo, hi

    def fit(self, d: Data, x_start: np.ndarray) -> np.ndarray:
        lo, hi = self.bounds(x_start)
        sol = least_squares(self.residuals, x_start, args=(d,), method="trf", bounds=(lo, hi),
                            x_scale="jac", max_nfev=100 * self.n_params, ftol=1e-10, xtol=1e-10)
        return sol.x


def applicable_effects(base: str, data: Data) -> list[str]:
    """Library effects that can be fitted on these data with this base model."""
    out = []
    for effect in ("scale", "offset", "temperature", "field_drift", "nonlinearity", "outliers"):
        if effect in ("scale", "offset") and base == "nine":
            continue  # already in the base model
        need = NEEDS.get(effect)
        if need and getattr(data, need) is None:
            continue
        if need == "t_s" and np.ptp(data.t_s) <= 0:
            continue
        if need == "temp_C" and np.ptp(data.temp_C) < 1.0:
            continue
        out.append(effect)
    return out

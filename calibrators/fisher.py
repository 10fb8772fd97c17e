"""Fisher information and the Cramér-Rao bound of the scalar calibration problem.

With white noise of standard deviation sigma on each raw axis, the scalar residual
``r_i = |M (raw_i - o)| - F_i`` has, to first order, variance ``sigma² |M^T u_i|²`` (u_i the unit
corrected field).  The Fisher information of the parameters is ``I = J^T W J`` with
``W = diag(1 / (sigma² |M^T u_i|²))`` and the Cramér-Rao lower bound on the covariance of any
unbiased estimator is ``I^-1``.  The rotation that scalar data cannot see is fixed by the canonical
lower-triangular form of CONTRACT section 1, so ``I`` is regular on a well-covered sphere.
"""
from __future__ import annotations

import numpy as np

from magbench.simulate.sensor import PARAM_NAMES

from .objective import ScalarObjective, correction_matrices

# Per-nT-of-noise standard deviations above which the coverage is called ill-conditioned (warning)
# or degenerate (refusal): (angle rad, scale, offset as a fraction of the field).
WARN_PER_NT = {"angle": 1e-4, "scale": 1e-4, "offset": 2e-5}
REFUSE_PER_NT = {"angle": 0.1, "scale": 0.1, "offset": 0.1}
COND_REFUSE = 1e10


def noise_weights(objective: ScalarObjective, x: np.ndarray) -> np.ndarray:
    """|M^T u_i|² for each sample: the residual variance per unit raw-axis noise variance."""
    mat, o = correction_matrices(np.asarray(x, dtype=float)[None, :], objective.model)
    c = (objective.raw_nT - o[0]) @ mat[0].T
    u = c / np.linalg.norm(c, axis=1, keepdims=True)
    return np.sum((u @ mat[0]) ** 2, axis=1)


def fisher_information(objective: ScalarObjective, x: np.ndarray, noise_nT: float) -> np.ndarray:
    jac = objective.jacobian(x)
    w = 1.0 / (noise_nT ** 2 * noise_weights(objective, x))
    return jac.T @ (jac * w[:, None])


def crb_covariance(objective: ScalarObjective, x: np.ndarray, noise_nT: float) -> np.ndarray:
    """Cramér-Rao bound on the covariance of the parameters at ``x`` (pseudo-inverse if singular)."""
    return np.linalg.pinv(fisher_information(objective, x, noise_nT))


def crb_std(objective: ScalarObjective, x: np.ndarray, noise_nT: float) -> np.ndarray:
    return np.sqrt(np.diag(crb_covariance(objective, x, noise_nT)))


def _kind(name: str) -> str:
    return "angle" if name.endswith("_rad") else ("offset" if name.endswith("_nT") else "scale")


def coverage(objective: ScalarObjective, x: np.ndarray) -> dict:
    """How well the attitudes determine each parameter: the condition number of the column-normalized
    Jacobian, the CRB standard deviation per nT of noise, the worst parameter relative to the
    thresholds, and ``warning``/``refusal`` messages (``None`` when fine)."""
    names = PARAM_NAMES[objective.model]
    jac = objective.jacobian(x)
    norms = np.linalg.norm(jac, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        sv = np.linalg.svd(jac / np.where(norms > 0, norms, 1.0), compute_uv=False)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 and np.all(norms > 0) else np.inf
    f = float(np.median(objective.f_ref_nT))
    sigma = crb_std(objective, x, 1.0) if np.isfinite(cond) else np.full(len(names), np.inf)
    limit_w = np.array([WARN_PER_NT[_kind(n)] * (f if _kind(n) == "offset" else 1.0) for n in names])
    limit_r = np.array([REFUSE_PER_NT[_kind(n)] * (f if _kind(n) == "offset" else 1.0) for n in names])
    worst = int(np.argmax(sigma / limit_w))
    unit = {"angle": " rad", "offset": " nT", "scale": ""}[_kind(names[worst])]
    bound = f"{names[worst]} +-{sigma[worst]:.2g}{unit} per nT of noise (Cramér-Rao)"
    refusal = warning = None
    if cond > COND_REFUSE or np.any(sigma > limit_r):
        bad = [names[i] for i in np.flatnonzero(sigma > limit_r)] or [names[worst]]
        refusal = (f"degenerate attitude coverage: the data cannot determine {', '.join(bad)} "
                   f"(condition number {cond:.2g}; {bound}); rotate the sensor through more "
                   f"directions or use a model with fewer parameters")
    elif np.any(sigma > limit_w):
        warning = f"ill-conditioned attitude coverage: condition number {cond:.2g}; worst-determined {bound}"
    return {"condition_number": cond, "sigma_per_nT": dict(zip(names, sigma.tolist())),
            "worst": names[worst], "warning": warning, "refusal": refusal}

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

from magbench.numerics import systematic_rows
from magbench.simulate.sensor import PARAM_NAMES

from .core.objective import ScalarObjective

# Standard deviations per nT of noise *for one point's worth of information* (the Cramér-Rao standard
# deviation times sqrt(n)) above which the attitudes are called ill-conditioned (warning) or degenerate
# (refusal): (angle rad, scale, offset as a fraction of the field).  Normalizing by sqrt(n) measures the
# geometry alone: a plane sampled 36 or 3,600 times has the same information per point, so it is
# refused alike (repeating a plane adds no direction).
WARN_PER_POINT = {"angle": 1e-3, "scale": 1e-3, "offset": 1e-3}
REFUSE_PER_POINT = {"angle": 0.05, "scale": 0.05, "offset": 0.05}
COND_REFUSE = 1e10
COVERAGE_ROWS = 20_000
"""The coverage check reads at most this many rows (every k-th): it judges the geometry per point, which a
sample stratified along the record gives to well under 1 %."""


def fisher_information(objective: ScalarObjective, x: np.ndarray, noise_nT: float) -> np.ndarray:
    """``J^T W J / sigma²`` with ``W = 1/|M^T u|²``, accumulated block by block (bounded memory)."""
    return objective.normal_equations(x, weighted=True)[0] / noise_nT ** 2


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
    rows = systematic_rows(objective.raw_nT.shape[0], COVERAGE_ROWS)
    if rows.step != 1:  # the geometry per point, from a sample stratified along the record
        objective = ScalarObjective(objective.raw_nT[rows], objective.f_ref_nT[rows], objective.model)
    gram, info = objective.grams(x)  # J^T J (the singular values of J are its eigenvalues' roots) and J^T W J
    norms = np.sqrt(np.maximum(np.diag(gram), 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        scaled = gram / np.outer(np.where(norms > 0, norms, 1.0), np.where(norms > 0, norms, 1.0))
        ev = np.linalg.eigvalsh(scaled)
    cond = float(np.sqrt(ev[-1] / ev[0])) if ev[0] > 0 and np.all(norms > 0) else np.inf
    f = float(np.median(objective.f_ref_nT))
    n = objective.raw_nT.shape[0]
    sigma = np.sqrt(np.diag(np.linalg.pinv(info))) if np.isfinite(cond) else np.full(len(names), np.inf)
    per_point = sigma * np.sqrt(n)
    scale = np.array([f if _kind(nm) == "offset" else 1.0 for nm in names])
    limit_w = np.array([WARN_PER_POINT[_kind(nm)] for nm in names]) * scale
    limit_r = np.array([REFUSE_PER_POINT[_kind(nm)] for nm in names]) * scale
    worst = int(np.argmax(per_point / limit_w))
    unit = {"angle": " rad", "offset": " nT", "scale": ""}[_kind(names[worst])]
    bound = f"{names[worst]} +-{sigma[worst]:.2g}{unit} per nT of noise (Cramér-Rao)"
    refusal = warning = None
    if cond > COND_REFUSE or np.any(per_point > limit_r):
        bad = [names[i] for i in np.flatnonzero(per_point > limit_r)] or [names[worst]]
        refusal = (f"degenerate attitude coverage: the data cannot determine {', '.join(bad)} "
                   f"(condition number {cond:.2g}; {bound}); rotate the sensor through more "
                   f"directions or use a model with fewer parameters")
    elif np.any(per_point > limit_w):
        warning = f"ill-conditioned attitude coverage: condition number {cond:.2g}; worst-determined {bound}"
    return {"condition_number": cond, "sigma_per_nT": dict(zip(names, sigma.tolist())),
            "worst": names[worst], "warning": warning, "refusal": refusal}

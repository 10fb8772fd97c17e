"""Fisher information and the Cramér-Rao bound of the scalar calibration problem.

With white noise of standard deviation sigma on each raw axis, the scalar residual
``r_i = |M (raw_i - o)| - F_i`` has, to first order, variance ``sigma² |M^T u_i|²`` (u_i the unit
corrected field).  The Fisher information of the parameters is ``I = J^T W J`` with
``W = diag(1 / (sigma² |M^T u_i|²))`` and the Cramér-Rao lower bound on the covariance of any
unbiased estimator is ``I^-1``.  The rotation that scalar data cannot see is fixed by the canonical
lower-triangular form of CONTRACT section 1, so ``I`` is regular on a well-covered sphere.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

try:  # the gufunc behind np.linalg.eigh: a private module of numpy, so np.linalg.eigh stands in where it is missing
    from numpy.linalg import _umath_linalg
    _eigh_lo = getattr(_umath_linalg, "eigh_lo", None)
except ImportError:  # pragma: no cover - depends on the numpy build
    _eigh_lo = None

from magbench.numerics import median, systematic_rows
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


@dataclass(frozen=True)
class PassAt:
    """What the acceptance checks read at one point ``x``, from one pass over the data (``one_pass``): the
    residuals ``r``, the normal equations ``gram`` (J^T J), ``grad`` (J^T r) and ``ss`` (r^T r), the Fisher
    information per unit noise variance ``fisher`` (J^T W J), and the Jacobian J (n, p) when the record is
    short enough to keep it (``None`` otherwise)."""

    x: np.ndarray
    r: np.ndarray
    gram: np.ndarray
    grad: np.ndarray
    ss: float
    fisher: np.ndarray
    jacobian: np.ndarray | None

    def normal_equations(self, normal_equations):
        """``normal_equations`` (a function of x) answering at ``self.x`` from this pass, elsewhere by itself."""
        def at(x):
            if np.array_equal(x, self.x):
                return self.gram, self.grad, self.ss
            return normal_equations(x)
        return at


KEEP_JACOBIAN_ROWS = 200_000
"""``one_pass`` keeps the Jacobian of a record of at most this many rows (16 MB at 10 parameters)."""


def one_pass(objective: ScalarObjective, x: np.ndarray, keep_jacobian_rows: int = KEEP_JACOBIAN_ROWS) -> PassAt:
    """Every quantity of ``PassAt`` at ``x`` from one pass over the data (``ScalarObjective.one_pass``)."""
    x = np.array(x, dtype=float)
    r, gram, grad, ss, fisher, jacobian = objective.one_pass(x, objective.raw_nT.shape[0] <= keep_jacobian_rows)
    return PassAt(x, r, gram, grad, ss, fisher, jacobian)


def std_from_information(information: np.ndarray, noise_nT: float) -> np.ndarray:
    """Cramér-Rao standard deviations from the Fisher information per unit noise variance and the noise (as
    ``crb_std`` computes them: the same pseudo-inverse, ``pinv_eigen``, its diagonal only)."""
    return np.sqrt(_pinv_diagonal(information / noise_nT ** 2))


def unit_scale(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``a`` with unit diagonal (``s a s``, ``s = 1 / sqrt(diag a)``; a parameter of no information keeps 0) and
    ``s``.  The parameters' units differ by ten orders of magnitude (a scale moves a reading by the field, an
    offset by one nT), so the raw information matrix of a near-planar record has a condition number near
    1e16, and a pseudo-inverse cut relative to its largest singular value would drop a direction the data
    do determine (an offset and a scale along the least-covered axis), stating a deviation hundreds of times
    too small.  The cut is made on the scaled matrix, where it drops only what no data determine."""
    d = a.diagonal()
    if d.min(initial=1.0) > 0:  # the usual case, in few operations (twice in every fit's checks)
        s = 1.0 / np.sqrt(d)
    else:
        d = np.sqrt(np.clip(d, 0.0, None))
        s = np.divide(1.0, d, out=np.zeros_like(d), where=d > 0)
    return a * np.multiply.outer(s, s), s


def _did_not_converge(err, flag):
    raise np.linalg.LinAlgError("Eigenvalues did not converge")


def eigh(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.linalg.eigh(a)`` (eigenvalues ascending, eigenvectors as columns) of a square float64 matrix: the
    same gufunc under the same floating-point settings (the same numbers; ``LinAlgError`` where it does not
    converge), without the wrapper's conversions and checks, which take a third of its time on the 9 x 9
    matrices of every fit's checks.  Other input goes to ``np.linalg.eigh``, and all input does where numpy's
    private module does not have the gufunc (``tests/test_acceptance_lean.py`` checks the two agree bit for bit)."""
    if _eigh_lo is None or not (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.ndim == 2
                                and a.shape[0] == a.shape[1]):
        return tuple(np.linalg.eigh(a))  # type: ignore[return-value]
    with np.errstate(call=_did_not_converge, invalid="call", over="ignore", divide="ignore", under="ignore"):
        return _eigh_lo(a, signature="d->dd")


def pinv_eigen(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pseudo-inverse of a symmetric ``a`` (an information matrix, or normal equations) as the Cramér-Rao
    bound takes it, in parts: ``pinv(a) = (s V) diag(inv) (s V)^T`` with ``V`` the eigenvectors of ``a`` scaled to
    unit diagonal (``unit_scale``), ``inv`` the inverse eigenvalues (0 for those below 1e-15 of the largest in
    magnitude: pinv's cut) and ``s`` the scale.  Returns (V, inv, s)."""
    scaled, s = unit_scale(a)
    values, vectors = eigh(scaled)
    size = np.abs(values)
    keep = size > 1e-15 * size.max(initial=0.0)
    return vectors, np.divide(1.0, values, out=np.zeros_like(values), where=keep), s


def _pinv_diagonal(a: np.ndarray) -> np.ndarray:
    """The diagonal of ``pinv_eigen``'s pseudo-inverse of ``a`` without forming the whole inverse
    (``sum_j v_ij² / lambda_j`` over the kept eigenvalues, scaled back; a third of the SVD's time)."""
    vectors, inv, s = pinv_eigen(a)
    return ((vectors * vectors) @ inv) * s * s


def fisher_information(objective: ScalarObjective, x: np.ndarray, noise_nT: float) -> np.ndarray:
    """``J^T W J / sigma²`` with ``W = 1/|M^T u|²``, accumulated block by block (bounded memory)."""
    return objective.normal_equations(x, weighted=True)[0] / noise_nT ** 2


def crb_covariance(objective: ScalarObjective, x: np.ndarray, noise_nT: float) -> np.ndarray:
    """Cramér-Rao bound on the covariance of the parameters at ``x`` (pseudo-inverse if singular, cut on the
    information scaled to unit diagonal, ``unit_scale``: the cut of ``pinv_eigen``)."""
    scaled, s = unit_scale(fisher_information(objective, x, noise_nT))
    return np.linalg.pinv(scaled, hermitian=True) * s[:, None] * s[None, :]


def crb_std(objective: ScalarObjective, x: np.ndarray, noise_nT: float) -> np.ndarray:
    return np.sqrt(np.diag(crb_covariance(objective, x, noise_nT)))


def _kind(name: str) -> str:
    return "angle" if name.endswith("_rad") else ("offset" if name.endswith("_nT") else "scale")


@functools.cache
def _coverage_limits(model: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per parameter of ``model``: whether it is an offset (its limits scale with the field), and its warning
    and refusal limits per point (``WARN_PER_POINT``, ``REFUSE_PER_POINT``)."""
    kinds = [_kind(nm) for nm in PARAM_NAMES[model]]
    return (np.array([k == "offset" for k in kinds]), np.array([WARN_PER_POINT[k] for k in kinds]),
            np.array([REFUSE_PER_POINT[k] for k in kinds]))


def coverage(objective: ScalarObjective, x: np.ndarray, field_nT: float | None = None) -> dict:
    """How well the attitudes determine each parameter: the condition number of the column-normalized
    Jacobian, the CRB standard deviation per nT of noise, the worst parameter relative to the
    thresholds, and ``warning``/``refusal`` messages (``None`` when fine).  ``field_nT``: the median
    reference, when the caller has it.

    Bounded and stratified: a record of more than ``COVERAGE_ROWS`` rows is judged on every k-th row (a
    systematic sample in time order, ``systematic_rows``), ``rows`` in the report.  Its power: the per-point
    information of m sampled rows estimates all rows' to a relative standard error of at most CV / sqrt(m)
    (CV the coefficient of variation of one row's contribution along the worst direction, below 2 for any
    attitude distribution whose rows are not concentrated on a few points), so 1.4 % at 20,000 rows: a record
    5 % or more beyond (or within) a limit gets all rows' verdict with probability above 99.9 % (3.5 standard
    errors); records nearer the limit may go either way, as they would under fresh noise.  The messages of a
    sampled record say so."""
    names = PARAM_NAMES[objective.model]
    n_all = objective.raw_nT.shape[0]
    rows = systematic_rows(n_all, COVERAGE_ROWS)
    if rows.step != 1:  # the geometry per point, from a sample stratified along the record
        objective = ScalarObjective(objective.raw_nT[rows], objective.f_ref_nT[rows], objective.model)
    gram, info = objective.grams(x)  # J^T J (the singular values of J are its eigenvalues' roots) and J^T W J
    norms = np.sqrt(np.maximum(np.diag(gram), 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        safe = np.where(norms > 0, norms, 1.0)
        ev = np.linalg.eigvalsh(gram / np.outer(safe, safe))
    cond = float(np.sqrt(ev[-1] / ev[0])) if ev[0] > 0 and np.all(norms > 0) else np.inf
    f = median(objective.f_ref_nT) if field_nT is None else float(field_nT)
    n = objective.raw_nT.shape[0]
    # the per-point deviations of the limits below are those of the unscaled pseudo-inverse (its cut drops a
    # direction of a near-planar record that the data determine weakly): the limits were set on them, and
    # paper 004's vehicle regime (vehicle9) is calibrated and judged, not refused; the stated uncertainty of a
    # fit is ``crb_std``'s, cut on the scaled information (``unit_scale``)
    sigma = np.sqrt(np.diag(np.linalg.pinv(info))) if np.isfinite(cond) else np.full(len(names), np.inf)
    per_point = sigma * np.sqrt(n)
    offset, warn, refuse = _coverage_limits(objective.model)
    scale = np.where(offset, f, 1.0)
    limit_w, limit_r = warn * scale, refuse * scale
    worst = int(np.argmax(per_point / limit_w))
    refusal = warning = None
    over_r, over_w = per_point > limit_r, per_point > limit_w
    if cond > COND_REFUSE or over_r.any() or over_w.any():
        unit = {"angle": " rad", "offset": " nT", "scale": ""}[_kind(names[worst])]
        bound = f"{names[worst]} +-{sigma[worst]:.2g}{unit} per nT of noise (Cramér-Rao)"
        sampled = (f"; judged on a systematic sample of {n:,} of {n_all:,} rows (per-point information to about "
                   f"{100 * 2 / np.sqrt(n):.2g} %)") if rows.step != 1 else ""
        if cond > COND_REFUSE or over_r.any():
            bad = [names[i] for i in np.flatnonzero(over_r)] or [names[worst]]
            refusal = (f"degenerate attitude coverage: the data cannot determine {', '.join(bad)} "
                       f"(condition number {cond:.2g}; {bound}{sampled}); rotate the sensor through more "
                       f"directions or use a model with fewer parameters")
        else:
            warning = f"ill-conditioned attitude coverage: condition number {cond:.2g}; worst-determined {bound}{sampled}"
    return {"condition_number": cond, "sigma_per_nT": dict(zip(names, sigma.tolist())),
            "worst": names[worst], "warning": warning, "refusal": refusal, "rows": n, "of_rows": n_all}

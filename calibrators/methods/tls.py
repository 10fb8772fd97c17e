"""``tls`` and ``ttls``: the linearized calibration equations solved by total least squares and by
truncated total least squares with the truncation level from the L-curve (seed 004, eq. 6-10).

The ellipsoid ``x² + X0 y² + X1 z² + X2 xy + X3 xz + X4 yz + X5 x + X6 y + X7 z + X8 = 0`` of the
readings is linear in the nine intermediate unknowns X: ``A X = b`` with rows
``[y², z², xy, xz, yz, x, y, z, 1]`` and ``b = -x²`` (the Foster-Elkaim linearization that seed 004
cites; its own A and b did not survive in our copy).  TLS (eq. 8-10) takes the right singular vector of
``[A b]`` of the smallest singular value; TTLS (Fierro, Golub, Hansen and O'Leary 1997) keeps the k
largest, ``X_k = -V12 V22^T / |V22|²``, and k is the corner of the L-curve of ``log |X_k|`` against
``log |[A b] - [A b]_k|_F`` (the point of largest curvature; seed 004 names the corner, not the rule).
By default the readings enter in nT as they are, as in the paper (whose A has a condition number of
1.36e10); ``normalize=True`` centres and scales them first, as the ellipsoid fit does.  The condition
number of A is reported in the message.  The ellipsoid is then reported through the canonical decomposition.
"""
from __future__ import annotations

from numbers import Integral

import numpy as np

from magbench.errors import FitError, InputError

from ..base import Calibrator
from ..core.algebra import normalize, quadric_to_ellipsoid, shape_to_params
from ..core.problem import ReadingsProblem, SolveOutput
from ..params import Interval

N_UNKNOWNS = 9
CORNER_MIN_DISTANCE = 0.05


def linear_system(norm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x, y, z = norm.T
    a = np.column_stack([y * y, z * z, x * y, x * z, y * z, x, y, z, np.ones_like(x)])
    return a, -x * x


def ttls_solution(vt: np.ndarray, k: int) -> np.ndarray:
    """Fierro et al. (1997): X_k = -V12 V22^T / |V22|², V partitioned after the k-th column."""
    v = vt.T
    v12, v22 = v[:N_UNKNOWNS, k:], v[N_UNKNOWNS, k:]
    denom = float(v22 @ v22)
    if denom <= 1e-300:
        raise FitError("the TLS problem has no solution (the last row of V vanishes)")
    return -v12 @ v22 / denom


def l_curve_corner(sv: np.ndarray, vt: np.ndarray) -> tuple[int, list[dict]]:
    """Truncation level at the corner of the L-curve: the points (log residual norm, log solution norm)
    for k = 1..n, scaled to the unit square; the corner is the point farthest from the chord joining
    the first and last points on the side of the origin (the triangle method of the L-curve corner).
    Where no point lies clearly on that side (by more than ``CORNER_MIN_DISTANCE`` of the unit square)
    the curve has no corner and k = n (plain TLS) is kept."""
    pts: list[dict] = []
    for k in range(1, N_UNKNOWNS + 1):
        try:
            xk = ttls_solution(vt, k)
        except InputError:
            continue
        resid = float(np.sqrt(np.sum(sv[k:] ** 2)))
        pts.append({"k": k, "residual_norm": resid, "solution_norm": float(np.linalg.norm(xk))})
    if len(pts) < 3:
        return int(pts[-1]["k"]), pts
    xy = np.log([[max(p["residual_norm"], 1e-300), max(p["solution_norm"], 1e-300)] for p in pts])
    span = np.ptp(xy, axis=0)
    xy = (xy - xy.min(axis=0)) / np.where(span > 0, span, 1.0)
    p0, p1 = xy[0], xy[-1]
    chord = (p1 - p0) / np.linalg.norm(p1 - p0)
    # signed distance; positive on the origin's side of the chord
    dist = (xy[:, 0] - p0[0]) * chord[1] - (xy[:, 1] - p0[1]) * chord[0]
    origin_side = -((0 - p0[0]) * chord[1] - (0 - p0[1]) * chord[0])
    dist = dist * np.sign(-origin_side) if origin_side != 0 else dist
    for p, d in zip(pts, dist):
        p["corner_distance"] = float(d)
    i = int(np.argmax(dist))
    return int(pts[i]["k"] if dist[i] > CORNER_MIN_DISTANCE else pts[-1]["k"]), pts


class _LinearizedFit(Calibrator):
    supported_models = ("nine",)
    check_tolerance = {"angle_rad": 1e-4, "scale": 1e-4, "offset_nT": 2.0}
    closed_form = True
    truncate = False
    normalize: bool  # hyper-parameters of the subclasses
    truncation: int

    def min_points(self, model: str) -> int:
        return 10

    def _solve(self, problem: ReadingsProblem) -> SolveOutput:
        if self.normalize:
            norm, mu, s = normalize(problem.raw_nT)
        else:  # the paper's formulation: readings in nT as they are (cond(A) ~ 1e10 on a vehicle)
            norm, mu, s = np.asarray(problem.raw_nT, dtype=float), np.zeros(3), 1.0
        a, b = linear_system(norm)
        sv_a = np.linalg.svd(a, compute_uv=False)
        cond = float(sv_a[0] / sv_a[-1]) if sv_a[-1] > 0 else np.inf
        _, sv, vt = np.linalg.svd(np.column_stack([a, b]), full_matrices=False)
        curve: list[dict] = []
        if self.truncate:
            k, curve = (l_curve_corner(sv, vt) if self.truncation == 0 else (int(self.truncation), []))
            if not 1 <= k <= N_UNKNOWNS:
                raise InputError(f"ttls: truncation must be 1..{N_UNKNOWNS} (0 = L-curve), got {k}")
        else:
            k = N_UNKNOWNS
        x = ttls_solution(vt, k)
        quad = np.array([[1.0, x[2] / 2, x[3] / 2], [x[2] / 2, x[0], x[4] / 2], [x[3] / 2, x[4] / 2, x[1]]])
        try:
            shape, center = quadric_to_ellipsoid(quad, x[5:8] / 2, x[8])
        except InputError as exc:
            raise InputError(f"{self.name}: {exc} (cond(A) = {cond:.2g}, truncation k = {k})") from None
        params = shape_to_params(shape / (s * s), mu + s * center, problem.f_ref_nT)
        xp = params.to_vector("nine")
        return SolveOutput(xp, status="closed_form", message=f"cond(A) = {cond:.3g}, truncation k = {k} of {N_UNKNOWNS}",
                           extra={"condition_number_A": cond, "truncation": k, "l_curve": curve})


class TotalLeastSquares(_LinearizedFit):
    """Total least squares of the linearized calibration equations (seed 004, eq. 8-10)."""

    name = "tls"
    summary = "total least squares of the linearized ellipsoid equations (Zhang et al.)"

    _parameter_constraints = {**Calibrator._parameter_constraints, "normalize": [bool]}

    def __init__(self, model: str = "nine", seed: int | None = 0, budget=None, normalize: bool = False):
        super().__init__(model=model, seed=seed, budget=budget)
        self.normalize = normalize


class TruncatedTLS(_LinearizedFit):
    """Truncated TLS, the truncation level from the L-curve corner (seed 004); ``truncation`` > 0 fixes it."""

    name = "ttls"
    summary = "truncated TLS with the L-curve truncation level (Zhang et al.)"
    truncate = True

    _parameter_constraints = {**Calibrator._parameter_constraints, "truncation": [Interval(Integral, 0, N_UNKNOWNS)],
                              "normalize": [bool]}

    def __init__(self, model: str = "nine", seed: int | None = 0, budget=None, truncation: int = 0,
                 normalize: bool = False):
        super().__init__(model=model, seed=seed, budget=budget)
        self.truncation = truncation
        self.normalize = normalize

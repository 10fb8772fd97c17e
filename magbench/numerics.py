"""Shared numerics used by the simulator, the calibrators and the diagnosis: robust scale and the
Levenberg-Marquardt iteration on accumulated normal equations.  Imports nothing of magbench's."""
from __future__ import annotations

import math
import sys
from collections.abc import Generator
from typing import NamedTuple

import numpy as np

MAD_TO_SIGMA = 1.4826
"""Median absolute deviation to the standard deviation of a normal distribution."""


def robust_sigma(x: np.ndarray) -> float:
    """The scale estimate MAD_TO_SIGMA * median absolute deviation (Hampel 1974); 0 for no values."""
    return median_and_sigma(x)[1]


def lm_normal(normal_equations, x: np.ndarray, lower: np.ndarray | None = None, upper: np.ndarray | None = None,
              tol: float = 1e-12, max_iter: int = 100, atol: float = 0.0) -> tuple[np.ndarray, float, int]:
    """Levenberg-Marquardt on the normal equations (``lm_iterations``) with ``normal_equations(x)`` returning
    ``(J^T J, J^T r, r^T r)``, which a long record accumulates block by block in bounded memory.  Returns
    the point, its sum of squares and the number of calls."""
    steps = lm_iterations(x, lower, upper, tol=tol, max_iter=max_iter, atol=atol)
    try:
        point = next(steps)
        while True:
            point = steps.send(normal_equations(point))
    except StopIteration as done:
        return done.value


def lm_iterations(x: np.ndarray, lower: np.ndarray | None = None, upper: np.ndarray | None = None,
                  tol: float = 1e-12, max_iter: int = 100, atol: float = 0.0
                  ) -> Generator[np.ndarray, tuple, tuple[np.ndarray, float, int]]:
    """Levenberg-Marquardt on the normal equations (Marquardt's diagonal scaling; a step leaving the box
    is projected back onto it), as a generator: it yields each point whose ``(J^T J, J^T r, r^T r)`` it
    needs and is sent them (the framework's ask/tell, ``calibrators/core/loop.py``).  Stops when the sum of
    squares or the step no longer changes relative to ``tol``, or the sum of squares by less than ``atol``.
    Returns the point, its sum of squares and the number of points asked for."""
    x = np.asarray(x, dtype=float).copy()
    a, g, cost = yield x
    calls, damping = 1, 1e-3
    if at_optimum(a, g, cost, tol, atol):
        return x, float(cost), calls
    for _ in range(max_iter):
        diag = np.maximum(np.diag(a), 1e-300)
        try:
            step = np.linalg.solve(a + damping * np.diag(diag), -g)
        except np.linalg.LinAlgError:
            damping *= 10.0
            continue
        trial = x + step
        if lower is not None:
            trial = np.clip(trial, lower, upper)
        a_t, g_t, cost_t = yield trial
        calls += 1
        if np.isfinite(cost_t) and cost_t < cost:
            done = (cost - cost_t <= max(tol * cost, atol)
                    or np.linalg.norm(trial - x) <= tol * (np.linalg.norm(x) + tol))
            x, a, g, cost = trial, a_t, g_t, cost_t
            damping = max(damping / 3.0, 1e-15)
            if done or at_optimum(a, g, cost, tol, atol):
                break
        else:
            damping *= 4.0
            if damping > 1e15:
                break
    return x, float(cost), calls


def at_optimum(a: np.ndarray, g: np.ndarray, cost: float, tol: float, atol: float) -> bool:
    """Whether the Gauss-Newton step from here would lower the sum of squares by at most ``tol`` of it (or
    ``atol``): the decrement ``g^T A^-1 g`` (the predicted decrease, half of it for a full step), so that
    no further point need be asked for.  Near the optimum of a long record the sum of squares changes by
    less than its own rounding from step to step; without this test the search asked for a handful more
    points whose differences were only rounding before one happened to be accepted."""
    try:
        decrement = float(g @ np.linalg.solve(a, g))
    except np.linalg.LinAlgError:
        return False
    # a numerically singular A can give a negative decrement: that is no sign of an optimum
    return 0.0 <= decrement <= max(tol * cost, atol)


def repeated_rows(x: np.ndarray, order: np.ndarray | None = None) -> np.ndarray:
    """Mask (in the rows of ``x``) of the rows identical to the row before them in ``order`` (the file's order when
    None): a logger writing its last reading again.  Compared one column at a time (no copy of a long record)."""
    n = len(x)
    if n == 0:
        return np.zeros(0, dtype=bool)
    same = np.ones(n - 1, dtype=bool)
    for axis in range(x.shape[1]):
        column = x[:, axis] if order is None else x[order, axis]
        same &= column[1:] == column[:-1]
    out = np.zeros(n, dtype=bool)
    if order is None:
        out[1:] = same
    else:
        out[order[1:]] = same
    return out


def _row_keys(x: np.ndarray) -> np.ndarray:
    """One 64-bit key per row of a float array (n, k), k <= 3: the rows' bits multiplied by odd constants and mixed.
    Equal rows have equal keys; unequal rows rarely do (callers compare the rows of equal keys)."""
    bits = np.ascontiguousarray(x, dtype=float).view(np.uint64)
    key = bits[:, 0] * np.uint64(0x9E3779B97F4A7C15)
    for axis, mix in zip(range(1, bits.shape[1]), (0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9)):
        key ^= bits[:, axis] * np.uint64(mix) + np.uint64(axis)
    return key


def copied_runs(x: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Mask, in ``order`` (time order), of the rows that copy an earlier stretch: row i equals an earlier row j exactly,
    and its neighbour in order equals j's neighbour on the same side, the two readings of the pair being different
    (rows written twice under new times: a file appended to itself, its t renumbered).  A logger holding its last
    value repeats one reading in consecutive rows (``repeated_rows``), and a coarse converter at one attitude repeats
    a reading anywhere, neither a run of different readings."""
    n = len(order)
    out = np.zeros(n, dtype=bool)
    if n < 4:
        return out
    key = _row_keys(x)[order]  # each row hashed to one integer (sorting rows as rows is 50 times slower)
    sorted_key = np.sort(key)
    if not np.any(sorted_key[1:] == sorted_key[:-1]):  # no reading repeats (a fifth of the time of the rest)
        return out
    xo = np.asarray(x, dtype=float)[order]
    by_key = np.argsort(key, kind="stable")  # equal keys in their order: each group's first is its earliest row
    sorted_key = key[by_key]
    start = np.ones(n, dtype=bool)
    start[1:] = sorted_key[1:] != sorted_key[:-1]
    first = np.empty(n, dtype=np.int64)
    first[by_key] = by_key[start][np.cumsum(start) - 1]  # each row's first occurrence (of its key), in order
    earlier = first < np.arange(n)
    earlier[earlier] = np.all(xo[earlier] == xo[first[earlier]], axis=1)  # the same readings, not a collision
    differs = np.any(xo[1:] != xo[:-1], axis=1)
    pair = earlier[1:] & earlier[:-1] & (first[1:] == first[:-1] + 1) & differs  # rows k, k+1 copy j, j+1
    # runs of at least COPY_RUN_MIN rows (COPY_RUN_MIN - 1 pairs in a row): a coarse converter at one attitude, whose
    # rows take a few values, repeats a pair of them by chance, eight in a row practically never
    edges = np.diff(np.concatenate([[0], pair.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # pairs starts..ends-1
    long = ends - starts >= COPY_RUN_MIN - 1
    if long.any():
        mark = np.zeros(n + 1, dtype=np.int64)
        np.add.at(mark, starts[long], 1)
        np.add.at(mark, ends[long] + 1, -1)  # rows starts..ends (the last pair's second row)
        out = np.cumsum(mark[:n]) > 0
    return out


COPY_RUN_MIN = 8
"""``copied_runs``: the fewest consecutive rows that copy an earlier stretch before they count as copies."""


BRUTE_NEAREST_ROWS = 2048
"""Up to this many points ``nearest_other`` compares every pair itself; above, SciPy's k-d tree (whose import,
with scipy.sparse behind it, costs about 0.1 s: half of a one-off ``calibrate`` of a few hundred readings)."""
BRUTE_NEAREST_ROWS_UNLOADED = 6000
"""... and up to this many while SciPy's spatial module is not imported yet (a one-off command): 5000 points take
0.07 s compared pair by pair against 0.21-0.23 s for the tree with its import; 10,000 take 0.27 s against 0.23 s."""
NEAREST_BLOCK_ELEMENTS = 1 << 20
"""Pairs handled at once by ``nearest_other`` (their squared distances and one axis's differences, 8 MiB each): its
memory bounded whatever the count."""


def nearest_other(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each point's nearest other point of ``points`` (n, d), n >= 2, by Euclidean distance: (distances, indices).
    Up to BRUTE_NEAREST_ROWS points (BRUTE_NEAREST_ROWS_UNLOADED before SciPy's spatial module is imported) every
    pair is compared (a tie goes to the lower index; the distances are the tree's to the last bit), above that a k-d
    tree answers (``cKDTree.query`` with k = 2, its second column)."""
    points = np.asarray(points, dtype=float)
    n = points.shape[0]
    if n > (BRUTE_NEAREST_ROWS if "scipy.spatial" in sys.modules else BRUTE_NEAREST_ROWS_UNLOADED):
        from scipy.spatial import cKDTree

        dist, idx = cKDTree(points).query(points, k=2)
        return dist[:, 1], idx[:, 1]
    dist, idx = np.empty(n), np.empty(n, dtype=np.int64)
    step = max(1, NEAREST_BLOCK_ELEMENTS // n)
    for start in range(0, n, step):
        block = points[start:start + step]
        d2 = squared_distances(block, points)
        rows = np.arange(len(block))
        d2[rows, rows + start] = np.inf  # each point's own pair left out
        near = d2.argmin(axis=1)
        idx[start:start + step] = near
        dist[start:start + step] = np.sqrt(d2[rows, near])
    return dist, idx


def squared_distances(block: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Squared distances (rows of ``block``, rows of ``points``), summed axis by axis as SciPy's k-d tree sums them:
    the tree's distances to the last bit."""
    d2 = np.zeros((len(block), len(points)))
    for axis in range(points.shape[1]):
        diff = block[:, axis, None] - points[None, :, axis]
        d2 += diff * diff
    return d2


def systematic_rows(n: int, limit: int) -> slice:
    """Every k-th row, k the smallest step that keeps at most ``limit`` of ``n`` rows (all when n <= limit):
    a sample stratified in file order (time, and so attitude along the record)."""
    return slice(None, None, max(1, -(-n // limit)))


def representatives(points: np.ndarray, radius: float, enough: int) -> np.ndarray:
    """Rows of ``points`` (n, d) farther than ``radius`` from each other, chosen greedily (a row in file order farther
    than ``radius`` from every row chosen before it is chosen) until ``enough`` are: their indices, in the order
    chosen.  A systematic sample of 4 ``enough`` rows first, then one of 20,000, then every row, each only when the
    one before gave fewer than ``enough``: a record at many attitudes is settled on a few rows, and fewer than
    ``enough`` is answered only after every row was looked at (then every row lies within ``radius`` of one chosen).
    ``enough`` found in a sample are ``enough`` separated rows, not the greedy pass's count over every row."""
    points = np.asarray(points, dtype=float)
    n = points.shape[0]
    limit = radius * radius
    chosen: list[int] = []
    for rows in (systematic_rows(n, 4 * enough), systematic_rows(n, 20_000), slice(None)):
        sample = points[rows]
        place = np.arange(n)[rows]
        chosen = []
        nearest = np.full(sample.shape[0], np.inf)  # squared distance to the nearest row chosen
        while len(chosen) < enough:
            far = np.flatnonzero(nearest > limit)
            if not far.size:
                break
            chosen.append(int(place[far[0]]))
            diff = sample - sample[far[0]]
            np.minimum(nearest, np.einsum("ij,ij->i", diff, diff), out=nearest)
        if len(chosen) >= enough or sample.shape[0] == n:
            break
    return np.asarray(chosen, dtype=np.int64)


DRIFT_MAX_DEGREE = 12
DRIFT_ROWS_PER_COLUMN = 5
"""``drift_degree``: a drift's Legendre polynomials of time go up to this degree, with at least this many rows per
column (four columns per degree)."""


def drift_degree(m: int, reserved: int = 0) -> int:
    """The degree of ``drift_columns`` for ``m`` rows, ``reserved`` of the rows' columns' worth kept for other
    parameters fitted beside it (0 or less: too short for a drift)."""
    return min(DRIFT_MAX_DEGREE, (m // DRIFT_ROWS_PER_COLUMN - reserved) // 4)


def drift_columns(t_s: np.ndarray, unit: np.ndarray, degree: int, constant: bool = True) -> np.ndarray:
    """Columns of a drift in time, each scaled to unit length: Legendre polynomials of the time mapped onto [-1, 1]
    of degree 0 (``constant``) or 1 to ``degree``, alone (a drift of the field's magnitude) and times each axis's
    direction cosine ``unit`` (n, 3) (a drift of the body's offsets, seen in the magnitude along the field);
    without the constant, every column centred (the constant outside their span, whatever the times).
    The acceptance checks' and the diagnosis's floor's fit of a drift at random attitudes."""
    t = np.asarray(t_s, dtype=float)
    tau = 2.0 * (t - t.min()) / max(float(np.ptp(t)), 1e-300) - 1.0
    legendre = np.polynomial.legendre.legvander(tau, degree)[:, (0 if constant else 1):]
    design = np.hstack([legendre] + [legendre * unit[:, [a]] for a in range(3)])
    if not constant:
        # every column centred: a nine-parameter model's Jacobian holds |M (raw - o)| = r + F (its scales are
        # homogeneous), so columns that can make the constant make the residual itself.  On few distinct times (stamps
        # rounded to the minute, all equal but one) or clustered ones they could, and a clean record's drift left
        # 1e-10 nT of it and was rejected.  A column that was the constant there is dropped (set to zero).
        before = np.linalg.norm(design, axis=0)
        design -= design.mean(axis=0)
        norms = np.linalg.norm(design, axis=0)
        design[:, norms <= 1e-9 * before] = 0.0  # zero, and still zero once divided by its old length below
    else:
        norms = np.linalg.norm(design, axis=0)
    design /= np.maximum(norms, 1e-300)
    return design


LSTSQ_FULL_RANK = 1e-6
"""``residual_sum_of_squares``: the triangular factor's smallest diagonal entry, relative to its largest, above which
the design is taken as of full rank (the QR's residual); at or below it, ``np.linalg.lstsq``'s rank cut decides."""


def triangular_factor(a: np.ndarray, scratch: bool = False) -> np.ndarray:
    """``np.linalg.qr(a, mode="r")`` of a float64 matrix (m, n): the upper triangular (min(m, n), n) factor, from the
    gufunc numpy's ``qr`` calls (LAPACK's Householder QR, under the same floating-point settings: the same numbers,
    ``tests/test_acceptance_lean.py``), without the wrapper's conversions and checks, a fifth to a quarter of the
    call on the (300, 10-22) designs of every fit's checks.  (SciPy's ``dgeqrf`` is faster still, but importing
    ``scipy.linalg`` costs a one-off ``calibrate`` 0.27 s.)  Input that is not a non-empty float64 matrix, or a numpy
    without the gufunc, goes to numpy's ``qr``.  ``scratch``: ``a`` may be overwritten (a design built for this call
    is then factored where it lies, not copied)."""
    if (_qr_r_raw is None or not (isinstance(a, np.ndarray) and a.ndim == 2 and a.dtype == np.float64 and a.size)):
        return np.asarray(np.linalg.qr(a, mode="r"))
    work = a if scratch and a.flags.writeable else a.copy()
    with np.errstate(call=_qr_did_not_converge, invalid="call", over="ignore", divide="ignore", under="ignore"):
        _qr_r_raw(work, signature="d->d")
    return np.triu(work[:min(work.shape)])


def _qr_did_not_converge(err, flag):
    raise np.linalg.LinAlgError("Incorrect argument found while performing QR factorization")


try:  # numpy's private gufunc behind np.linalg.qr (``triangular_factor``)
    from numpy.linalg import _umath_linalg

    _qr_r_raw = getattr(_umath_linalg, "qr_r_raw", None)
except ImportError:  # pragma: no cover - a numpy without it: np.linalg.qr itself
    _qr_r_raw = None


def residual_sum_of_squares(design: np.ndarray, y: np.ndarray, rcond: float) -> float:
    """``|y - design coef|²`` of the least-squares ``coef``, as ``np.linalg.lstsq(design, y, rcond)`` leaves it,
    from the triangular factor of one QR of ``[design | y]``: its last diagonal entry is the length of what the
    columns leave of ``y``.  A third to a quarter of lstsq's singular value decomposition (the diagnosis floor's
    drift, and ``residual_sum_of_squares_beside``'s rank-deficient case).  A design whose factor's diagonal spans more
    than 1 / LSTSQ_FULL_RANK, nearly rank deficient, goes to lstsq itself, whose cut at ``rcond`` then decides what is
    fitted."""
    m, q = design.shape
    if m > q:
        r = triangular_factor(np.column_stack([design, y]))  # R alone
        diag = np.abs(np.diagonal(r)[:q])
        if q == 0 or diag.min() > LSTSQ_FULL_RANK * diag.max():
            return float(r[q, q] ** 2)
    coef, *_ = np.linalg.lstsq(design, y, rcond=rcond)
    left = y - design @ coef
    return float(left @ left)


class Basis(NamedTuple):
    """An orthonormal basis ``q`` (m, k) of some columns (m, k) and the triangular factor ``r`` (k, k) of their thin
    QR, ``columns = q r`` (``orthonormal_basis``): the part of a least-squares design that a record's checks share
    between fits (``residual_sum_of_squares_beside``).  The columns themselves are not kept (a record's cache would
    hold them twice): ``q @ r`` gives them again to rounding where the rare rank-deficient case needs them."""

    q: np.ndarray
    r: np.ndarray

    @property
    def diag(self) -> np.ndarray:
        """The triangular factor's absolute diagonal."""
        return np.abs(np.diagonal(self.r))


def orthonormal_basis(columns: np.ndarray) -> Basis:
    """``Basis`` of ``columns`` (m, k), m > k: one thin QR, its arrays read-only (kept with a record's data)."""
    q, r = np.linalg.qr(columns)
    basis = Basis(np.ascontiguousarray(q), np.ascontiguousarray(r))
    for part in basis:
        part.setflags(write=False)
    return basis


def residual_sum_of_squares_beside(basis: Basis, extra: np.ndarray, y: np.ndarray, rcond: float) -> float:
    """``residual_sum_of_squares`` of the design ``[extra | columns]``, with the columns' QR made once (``basis``): ``extra``
    and ``y`` are projected off ``basis.q`` (twice, so that they are orthogonal to it to rounding: classical
    Gram-Schmidt with one reorthogonalization) and the rest is one QR of (m, p + 1).  The same number as the whole
    design's QR to rounding (the residual of a least-squares fit does not depend on the order of the columns); the
    full-rank test asks the same of the two triangular factors' diagonals together, and a design that fails it goes
    to ``residual_sum_of_squares`` of the whole design (lstsq's cut).  The acceptance check of a drift at random
    attitudes, on every fit: its drift columns are the record's, the model's Jacobian the answer's (0.3 of a
    300-point lsq fit's 1.2 ms had gone to the whole design's QR and columns)."""
    m, p = extra.shape
    k = basis.q.shape[1]
    if m > p + k:
        both = np.column_stack([extra, y])
        q = basis.q
        both -= q @ (q.T @ both)
        both -= q @ (q.T @ both)
        r = triangular_factor(both)
        diag = np.concatenate([basis.diag, np.abs(np.diagonal(r)[:p])])
        if diag.size == 0 or diag.min() > LSTSQ_FULL_RANK * diag.max():
            return float(r[p, p] ** 2)
    return residual_sum_of_squares(np.column_stack([extra, basis.q @ basis.r]), y, rcond)


def median(x: np.ndarray) -> float:
    """``np.median`` of a 1-D array, the same number, faster: one partition about the upper middle element (the
    lower one of an even count is then the largest before it), where np.median partitions about both, which
    takes several times longer on long arrays (2e6 values: 3 against 21 ms)."""
    x = np.asarray(x, dtype=float).ravel()
    n = x.size
    if n == 0 or np.isnan(x).any():
        return float(np.median(x))
    return _middle(np.partition(x, n // 2))


def _middle(part: np.ndarray) -> float:
    """The median of values (1-D, none NaN) partitioned about their upper middle element (``n // 2``)."""
    n = part.size
    k = n // 2
    if n % 2:
        return float(part[k])
    return float((part[:k].max() + part[k]) / 2.0)


def median_and_sigma(x: np.ndarray) -> tuple[float, float]:
    """The median of ``x`` and ``robust_sigma(x)``, sharing the median."""
    x = np.asarray(x, dtype=float)
    if x.size == 0:
        return float("nan"), 0.0
    m = median(x)
    if not math.isfinite(m):  # NaN among the values, or infinite ones in the middle
        with np.errstate(invalid="ignore"):  # inf - inf: NaN, as the answer is
            return m, MAD_TO_SIGMA * median(np.abs(x - m))
    # about a finite median the deviations are NaN only where a value is, and there is none (the median would
    # be NaN): they are partitioned in place, a new array of their own
    deviation = np.abs(x - m).ravel()
    deviation.partition(deviation.size // 2)
    return m, MAD_TO_SIGMA * _middle(deviation)


def roughness(t_s: np.ndarray | None, raw_nT: np.ndarray, order: np.ndarray | None = None,
              max_rows: int | None = None) -> float | None:
    """How unrelated consecutive readings are: the RMS of the second differences of the reading's direction over
    that of its central differences, in time order (``order``, when the caller has it): sqrt(3) for unrelated
    samples (random attitudes), at most about 1 for a continuous path or noise about held attitudes.  None without
    time or with fewer than 5 samples.  ``max_rows``: on a longer record, 40 evenly spaced windows of consecutive
    samples holding that many rows in all (a ratio of sums: the windows estimate it as the whole does)."""
    if t_s is None or len(t_s) < 5:
        return None
    order = np.argsort(t_s, kind="stable") if order is None else order
    n = len(order)
    if max_rows is not None and n > max_rows:
        width = max(5, max_rows // 40)
        starts = np.linspace(0, n - width, 40).astype(np.int64)
        windows = [order[s:s + width] for s in starts]
    else:
        windows = [order]
    num = den = 0.0
    for idx in windows:
        x = raw_nT[idx]
        u = x / np.maximum(np.linalg.norm(x, axis=1), 1e-12)[:, None]
        d1 = u[2:] - u[:-2]
        d2 = u[2:] - 2 * u[1:-1] + u[:-2]
        num += float(np.sum(d2 ** 2))
        den += float(np.sum(d1 ** 2))
    return float(np.sqrt(num / den)) if den > 0 else None


TIME_REPEAT_SHARE = 0.01
"""``time_column_note`` speaks of repeated times when at least this share of the rows repeat the previous row's."""


TIME_GLITCH_STEPS = 1000.0
"""``timestamp_glitches``: a row's time lies this many median steps (or more) from both its neighbours' while theirs
are within it of each other."""


def lone_values(x: np.ndarray, far: float) -> np.ndarray:
    """Positions (1 .. n-2) of the values of a sequence more than ``far`` from both neighbours while the neighbours lie
    within ``far`` of each other: one glitched entry (a timestamp, a heading), not a jump that stays."""
    return np.flatnonzero((np.abs(x[1:-1] - x[:-2]) > far) & (np.abs(x[1:-1] - x[2:]) > far)
                          & (np.abs(x[2:] - x[:-2]) <= far)) + 1


def timestamp_glitches(t_s: np.ndarray | None) -> str | None:
    """Why the t column cannot be used as it is, or None: rows (in file order) whose time lies far from both
    neighbours' (TIME_GLITCH_STEPS median steps) while the neighbours agree with each other: a glitched timestamp
    (one row's clock read as 0, or 1e9 among seconds).  Every time-based test takes such a row far from its
    readings (a fixed sensor's 20 nT/h drift had come back 'not significant', the time span 277,778 h; the lag's
    derivatives had failed with a singular matrix).  A gap in a record (its time jumps and stays) is no glitch,
    nor rows in no time order (their steps are all large)."""
    try:
        t = np.asarray(t_s, dtype=float)
    except (TypeError, ValueError):  # not numbers: the columns' own checks say so
        return None
    if t.ndim != 1 or len(t) < 5 or not np.all(np.isfinite(t)):
        return None
    steps = np.abs(np.diff(t))
    moving = steps[steps > 0]
    if not len(moving):
        return None
    rows = lone_values(t, TIME_GLITCH_STEPS * float(np.median(moving)))
    if not len(rows):
        return None
    i = int(rows[0])
    return (f"the t column has {len(rows)} glitched time{'s' if len(rows) > 1 else ''}: row {i} reads {t[i]:.6g} s "
            f"between {t[i - 1]:.6g} and {t[i + 1]:.6g} s (more than {TIME_GLITCH_STEPS:g} sampling steps from both); "
            "correct or remove such rows")


def time_column_note(t_s: np.ndarray | None) -> str | None:
    """What a user should know of a time column that is not a clock read once per sample in file order (None when
    it is): times that step back between rows (a logger restarted, files joined out of order: every time-based
    check then takes the rows in time order, where stretches that overlap in time interleave), and times that
    repeat the previous row's in at least ``TIME_REPEAT_SHARE`` of the rows (a clock coarser than the sampling:
    rows of one time are taken in file order).  A column in reverse time order throughout is only reversed."""
    if t_s is None or len(t_s) < 3:
        return None
    d = np.diff(np.asarray(t_s, dtype=float))
    notes = []
    back = np.flatnonzero(d < 0)
    if len(back) and not np.all(d <= 0):
        i = int(back[0])
        notes.append(f"the t column steps back {len(back):,} time{'s' if len(back) > 1 else ''} in file order (first "
                     f"between rows {i:,} and {i + 1:,}: {t_s[i]:.6g} -> {t_s[i + 1]:.6g} s; a logger restarted "
                     "or files joined?): the time-based checks take the rows in time order, where stretches that "
                     "overlap in time interleave")
    repeats = int(np.count_nonzero(d == 0))
    if repeats and repeats >= TIME_REPEAT_SHARE * len(d) and np.ptp(t_s) > 0:
        notes.append(f"{repeats:,} rows ({100 * repeats / len(d):.0f} %) repeat the previous row's t (a clock coarser "
                     "than the sampling?): rows of one time are taken in file order")
    return "; ".join(notes) or None

"""Where the residual lies, in two dimensions and per axis: an attitude x time map, the body-axis
projections, change points in time, and the temperature share beyond time.

One variable at a time cannot place a residual whose structure depends on attitude *and* time (a body field
that switches on; temperature that follows the attitude), and it cannot say which axis carries it.  This
module adds:

* ``attitude_time_map``: the residual's mean in each cell of direction clusters (k-means on the unit
  reading) x time blocks, and the shares of its variance explained by attitude alone, time alone, both
  additively, and the interaction (cross-validated on random folds like the one-variable fractions);
* ``axis_projections``: for scalar references, the share of the residual explained by each body axis's
  component of the unit reading (linear), i.e. which sensor axis the structure is seen along;
* ``change_points``: steps in the residual's time series, found by binary segmentation of the cumulative
  sum (CUSUM) with a z threshold against the floor, located to a sample;
* ``temperature_beyond_time_pct``: the explained share of a temperature polynomial after a smooth function
  of time has been taken out.
"""
from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre

from magbench.numerics import robust_sigma

MAP_DIRECTIONS = 6
MAP_TIME_BLOCKS = 6
CHANGE_Z = 8.0
"""A step is a change point when its CUSUM statistic exceeds this many standard errors (a scan over n
candidate times needs a high threshold: about 4 to 5 for Gaussian noise over thousands of points, and the
residual is rarely white)."""
MAX_CHANGE_POINTS = 4
MIN_SEGMENT = 10


def _clusters(unit: np.ndarray, k: int, seed: int = 0, iterations: int = 10) -> np.ndarray:
    rng = np.random.default_rng(seed)
    centres = unit[rng.choice(len(unit), size=min(k, len(unit)), replace=False)]
    label = np.zeros(len(unit), dtype=int)
    for _ in range(iterations):
        label = np.argmax(unit @ centres.T, axis=1)
        for j in range(len(centres)):
            m = unit[label == j]
            if len(m):
                c = m.sum(axis=0)
                centres[j] = c / max(np.linalg.norm(c), 1e-12)
    return label


def _explained(design: np.ndarray, r: np.ndarray, fold: np.ndarray, k: int) -> float:
    """Held-out explained share (%) of r by a linear model in ``design`` (with a constant)."""
    x = np.column_stack([np.ones(len(r)), design])
    pred = np.empty(len(r))
    for f in range(k):
        tr, te = fold != f, fold == f
        coef, *_ = np.linalg.lstsq(x[tr], r[tr], rcond=None)
        pred[te] = x[te] @ coef
    return float(100.0 * (1.0 - np.mean((r - pred) ** 2) / max(np.var(r), 1e-300)))


def _onehot(label: np.ndarray, k: int) -> np.ndarray:
    return (label[:, None] == np.arange(1, k)[None, :]).astype(float)  # drop level 0 (the constant)


def attitude_time_map(r: np.ndarray, unit: np.ndarray, t_s: np.ndarray, seed: int = 0, folds: int = 5) -> dict:
    """Means of r in direction-cluster x time-block cells and the explained shares of each factor."""
    n = len(r)
    a = _clusters(unit, MAP_DIRECTIONS, seed)
    order = np.argsort(t_s, kind="stable")
    tb = np.empty(n, dtype=int)
    tb[order] = np.minimum(np.arange(n) * MAP_TIME_BLOCKS // n, MAP_TIME_BLOCKS - 1)
    fold = np.random.default_rng(seed + 7).permutation(n) % folds
    da, dt = _onehot(a, MAP_DIRECTIONS), _onehot(tb, MAP_TIME_BLOCKS)
    cell = a * MAP_TIME_BLOCKS + tb
    filled = np.unique(cell)
    di = (cell[:, None] == filled[None, 1:]).astype(float)
    means = np.full((MAP_DIRECTIONS, MAP_TIME_BLOCKS), np.nan)
    counts = np.zeros((MAP_DIRECTIONS, MAP_TIME_BLOCKS), dtype=int)
    for i in range(MAP_DIRECTIONS):
        for j in range(MAP_TIME_BLOCKS):
            m = (a == i) & (tb == j)
            counts[i, j] = int(m.sum())
            if m.any():
                means[i, j] = float(r[m].mean())
    both = _explained(np.column_stack([da, dt]), r, fold, folds)
    full = _explained(di, r, fold, folds) if len(filled) < n // 3 else both
    return {"directions": MAP_DIRECTIONS, "time_blocks": MAP_TIME_BLOCKS,
            "cell_mean_nT": [[None if np.isnan(v) else v for v in row] for row in means.tolist()],
            "cell_count": counts.tolist(),
            "attitude_explained_pct": _explained(da, r, fold, folds), "time_explained_pct": _explained(dt, r, fold, folds),
            "additive_explained_pct": both, "with_interaction_explained_pct": full,
            "interaction_pct": full - both}


def axis_projections(r: np.ndarray, unit: np.ndarray, seed: int = 0, folds: int = 5) -> dict:
    """Held-out explained share (%) of the residual by each body axis's component of the unit reading."""
    fold = np.random.default_rng(seed + 11).permutation(len(r)) % folds
    return {f"{ax}_explained_pct": _explained(unit[:, [i]], r, fold, folds) for i, ax in enumerate("xyz")}


def change_points(r: np.ndarray, t_s: np.ndarray, floor_nT: float) -> list[dict]:
    """Steps in the residual in time order (binary segmentation, CUSUM): time, size and z of each."""
    order = np.argsort(t_s, kind="stable")
    x, t = r[order], t_s[order]
    sigma = max(floor_nT, robust_sigma(np.diff(x)) / np.sqrt(2.0), 1e-12)
    found: list[dict] = []
    segments = [(0, len(x))]
    while segments and len(found) < MAX_CHANGE_POINTS:
        best = None
        for lo, hi in segments:
            m = hi - lo
            if m < 2 * MIN_SEGMENT:
                continue
            seg = x[lo:hi]
            c = np.cumsum(seg - seg.mean())[MIN_SEGMENT - 1:m - MIN_SEGMENT]
            i = np.arange(MIN_SEGMENT, m - MIN_SEGMENT + 1)
            z = np.abs(c) / (sigma * np.sqrt(i * (m - i) / m))
            j = int(np.argmax(z))
            if best is None or z[j] > best[0]:
                best = (float(z[j]), lo, hi, lo + int(i[j]))
        if best is None or best[0] < CHANGE_Z:
            break
        z, lo, hi, cut = best
        size = float(x[cut:hi].mean() - x[lo:cut].mean())
        found.append({"time_s": float(0.5 * (t[cut - 1] + t[cut])), "row_in_time_order": cut, "size_nT": size,
                      "z": z, "fraction_of_record": float((t[cut] - t[0]) / max(np.ptp(t), 1e-12))})
        segments = [s for s in segments if s != (lo, hi)] + [(lo, cut), (cut, hi)]
    return sorted(found, key=lambda c: c["time_s"])


def temperature_beyond_time(r: np.ndarray, t_s: np.ndarray, temp_C: np.ndarray, seed: int = 0,
                            folds: int = 5) -> float:
    """Held-out explained share (%) of the residual by a cubic in temperature, beyond a degree-6 function of
    time (the time model fitted first; the temperature model on what it leaves)."""
    s = 2 * (t_s - t_s.min()) / max(np.ptp(t_s), 1e-12) - 1
    tpoly = legendre.legvander(s, 6)[:, 1:]
    fold = np.random.default_rng(seed + 13).permutation(len(r)) % folds
    base = _explained(tpoly, r, fold, folds)
    u = 2 * (temp_C - temp_C.min()) / max(np.ptp(temp_C), 1e-12) - 1
    both = _explained(np.column_stack([tpoly, legendre.legvander(u, 3)[:, 1:]]), r, fold, folds)
    return both - base


STEP_GRID = 200
STEP_CHI2_Z = 8.0
"""A body-fixed step is reported when the sum of squares it removes, in units of the floor's variance, is
this many standard deviations above what three free parameters remove from noise (chi-squared, 3 degrees
of freedom, scanned over STEP_GRID candidate times)."""


def body_field_step(r: np.ndarray, unit: np.ndarray, t_s: np.ndarray, floor_nT: float) -> dict | None:
    """A field fixed in the body that switches on at one time (a current loop, a load) is seen in the scalar
    residual as ``u . d`` after the switch (u the unit reading): scan the switch time, fit ``[u H, u, 1]``
    and keep the best; None when it is not significant against the floor.  Each candidate's least squares
    comes from the normal equations, built from sums over the rows after it (one pass over the record, then
    a 7 x 7 system per candidate), so the scan costs little more than one fit."""
    order = np.argsort(t_s, kind="stable")
    ts, rs, us = t_s[order], r[order], unit[order]
    n = len(rs)
    base = np.column_stack([us, np.ones(n)])
    g_base, b_base, rr = base.T @ base, base.T @ rs, float(rs @ rs)
    sse0 = rr - float(b_base @ np.linalg.lstsq(g_base, b_base, rcond=None)[0])
    cuts = np.searchsorted(ts, np.quantile(ts, np.linspace(0.02, 0.98, STEP_GRID)), side="left")
    cuts = np.unique(cuts[(cuts >= MIN_SEGMENT) & (n - cuts >= MIN_SEGMENT)])
    best = None
    if len(cuts):
        rows = np.column_stack([(us[:, :, None] * us[:, None, :]).reshape(n, 9), us * rs[:, None]])
        seg = np.add.reduceat(rows, cuts, axis=0)  # sums from each cut to the next (the last to the end)
        after = np.cumsum(seg[::-1], axis=0)[::-1]  # sums over the rows at and after each cut
        m_after = np.add.reduceat(us, cuts, axis=0)[::-1].cumsum(axis=0)[::-1]
        for cut, sums, m in zip(cuts, after, m_after):
            p_mat, c = sums[:9].reshape(3, 3), sums[9:]
            a = np.zeros((7, 7))
            a[:3, :3], a[:3, 3:6], a[3:6, :3], a[:3, 6], a[6, :3] = p_mat, p_mat, p_mat, m, m
            a[3:, 3:] = g_base
            b = np.concatenate([c, b_base])
            coef = np.linalg.lstsq(a, b, rcond=None)[0]
            sse = rr - float(b @ coef)
            if best is None or sse < best[0]:
                best = (sse, float(0.5 * (ts[cut - 1] + ts[cut])), coef[:3])
    if best is None or not floor_nT > 0:
        return None
    drop = (sse0 - best[0]) / floor_nT ** 2
    z = (drop - 3.0) / np.sqrt(6.0)
    if z < STEP_CHI2_Z:
        return None
    return {"time_s": best[1], "size_nT": float(np.linalg.norm(best[2])), "vector_nT": [float(v) for v in best[2]],
            "z": float(z), "fraction_of_record": float((best[1] - ts[0]) / max(np.ptp(ts), 1e-12))}

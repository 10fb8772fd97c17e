"""The noise floor, estimated independently of the structured residual: from differences of samples
close in time (a smooth structured residual cancels in them), with its own interval.

* vector data with a time column (or rows in acquisition order): the robust scatter of the second
  differences r_i - 2 r_(i+1) + r_(i+2) in time order, / sqrt(6) (white noise); the third differences
  (/ sqrt(20)) check that structure does not leak into them;
* without any order the samples can be trusted in: the k-NN scatter in attitude, an upper bound (flagged).

The interval is +-1.96 standard errors of the MAD-based scale (1.166 sigma / sqrt(m), m the number of
independent differences, about n / 3 for overlapping second differences)."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from magbench.simulate.effects import SPIKE_SIGMA, Columns, robust_sigma

KNN_NEIGHBOURS = 6
MAD_SE = 1.166  # standard error of the MAD scale: 1.166 sigma / sqrt(m) for Gaussian data
D2_VAR, D3_VAR = 6.0, 20.0
INDEPENDENT_SHARE = 1.0 / 3.0  # overlapping second differences: about a third of them independent
LEAK_Z = 3.0

__all__ = ["KNN_NEIGHBOURS", "knn_floor", "robust_sigma", "second_difference_floor", "unit_span", "vector_floor",
           "time_difference_floor"]


def knn_floor(features: np.ndarray, r: np.ndarray, k: int = KNN_NEIGHBOURS) -> float:
    """Robust scatter of r_i about the mean of its k nearest neighbours in feature space, scaled by
    sqrt(k / (k + 1)) (the neighbours' mean carries noise too)."""
    k = min(k, len(r) - 1)
    _, idx = cKDTree(features).query(features, k=k + 1)
    local = r[idx[:, 1:]].mean(axis=1)
    return robust_sigma(r - local) * np.sqrt(k / (k + 1.0))


def unit_span(v: np.ndarray | None) -> np.ndarray | None:
    """``v`` mapped onto [0, 1] (None when absent or constant)."""
    if v is None or np.ptp(v) <= 0:
        return None
    return (v - v.min()) / np.ptp(v)


def _interval(sigma: float, m: int) -> tuple[float, float, float]:
    se = MAD_SE * sigma / np.sqrt(max(m, 1))
    return se, max(sigma - 1.96 * se, 0.0), sigma + 1.96 * se


def time_difference_floor(r_in_order: np.ndarray) -> dict:
    """Floor from second differences in time order, checked against third differences; differences that
    touch a spike (a sample beyond SPIKE_SIGMA robust sigma) are left out, since each spike would otherwise
    inflate three (four) of them."""
    n = len(r_in_order)
    spk = np.abs(r_in_order - np.median(r_in_order)) > SPIKE_SIGMA * robust_sigma(r_in_order)
    d2 = np.diff(r_in_order, 2)
    d3 = np.diff(r_in_order, 3)
    if spk.any() and (~spk).sum() > 10:
        touch2 = np.convolve(spk, np.ones(3), mode="valid") > 0
        touch3 = np.convolve(spk, np.ones(4), mode="valid") > 0
        d2, d3 = d2[~touch2], d3[~touch3]
        n = int((~spk).sum())
    s2 = robust_sigma(d2) / np.sqrt(D2_VAR)
    s3 = robust_sigma(d3) / np.sqrt(D3_VAR) if len(d3) else s2
    se, lo, hi = _interval(s2, int(INDEPENDENT_SHARE * n))
    leak = bool(s2 - s3 > LEAK_Z * se)  # structure left in the second differences inflates them
    sigma = min(s2, s3) if leak else s2
    se, lo, hi = _interval(sigma, int(INDEPENDENT_SHARE * n))
    return {"noise_floor_nT": float(sigma), "floor_se_nT": float(se), "floor_interval_nT": [float(lo), float(hi)],
            "floor_method": "third differences in time order (second ones carry structure)" if leak
            else "second differences in time order", "floor_is_upper_bound": False,
            "floor_second_diff_nT": float(s2), "floor_third_diff_nT": float(s3)}


def vector_floor(unit: np.ndarray, d: Columns, r: np.ndarray, rows_in_time_order: bool = False) -> dict:
    """The floor of a vector record (module docstring)."""
    n = len(r)
    if d.t_s is not None and np.ptp(d.t_s) > 0:
        return time_difference_floor(r[np.argsort(d.t_s, kind="stable")])
    if rows_in_time_order:
        out = time_difference_floor(r)
        out["floor_method"] += " (row order taken as time order)"
        return out
    sigma = knn_floor(unit, r)
    se, lo, hi = _interval(sigma, n)
    return {"noise_floor_nT": float(sigma), "floor_se_nT": float(se), "floor_interval_nT": [float(lo), float(hi)],
            "floor_method": "nearest neighbours in attitude (no time order: an upper bound, structure included)",
            "floor_is_upper_bound": True}


def second_difference_floor(r_in_order: np.ndarray) -> float:
    """The floor of a series from its second differences r_i - (r_{i-1} + r_{i+1}) / 2, robustly."""
    d2 = r_in_order[1:-1] - 0.5 * (r_in_order[:-2] + r_in_order[2:])
    return robust_sigma(d2) / np.sqrt(1.5)

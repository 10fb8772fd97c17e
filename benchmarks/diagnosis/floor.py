"""The noise floor, estimated without any calibration model: the scatter of each residual about its
neighbours (in attitude, time and temperature for vector data; along the turn for a scalar series)."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from magbench.simulate.effects import Columns, robust_sigma

KNN_NEIGHBOURS = 6
SECOND_DIFFERENCE_VARIANCE = 1.5  # var(r_i - (r_{i-1} + r_{i+1}) / 2) = 1.5 sigma² for white noise

__all__ = ["KNN_NEIGHBOURS", "knn_floor", "robust_sigma", "second_difference_floor", "unit_span", "vector_floor"]


def knn_floor(features: np.ndarray, r: np.ndarray, k: int = KNN_NEIGHBOURS) -> float:
    """Noise floor: robust scatter of r_i about the mean of its k nearest neighbours in feature space,
    scaled by sqrt(k / (k + 1)) (the neighbours' mean carries noise too)."""
    k = min(k, len(r) - 1)
    _, idx = cKDTree(features).query(features, k=k + 1)
    local = r[idx[:, 1:]].mean(axis=1)
    return robust_sigma(r - local) * np.sqrt(k / (k + 1.0))


def unit_span(v: np.ndarray | None) -> np.ndarray | None:
    """``v`` mapped onto [0, 1] (None when absent or constant)."""
    if v is None or np.ptp(v) <= 0:
        return None
    return (v - v.min()) / np.ptp(v)


def vector_floor(unit: np.ndarray, d: Columns, r: np.ndarray) -> float:
    """The k-NN floor with neighbours in field direction (sensor frame), time and temperature, each
    scaled to a unit range."""
    features = [unit] + [u[:, None] for u in (unit_span(d.t_s), unit_span(d.temp_C)) if u is not None]
    return knn_floor(np.hstack(features), r)


def second_difference_floor(r_in_order: np.ndarray) -> float:
    """The floor of a series from its second differences r_i - (r_{i-1} + r_{i+1}) / 2, robustly."""
    d2 = r_in_order[1:-1] - 0.5 * (r_in_order[:-2] + r_in_order[2:])
    return robust_sigma(d2) / np.sqrt(SECOND_DIFFERENCE_VARIANCE)

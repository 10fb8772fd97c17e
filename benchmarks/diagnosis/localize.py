"""Where the residual of the base calibration lies: over attitude (the field direction in the sensor
frame: variance explained on held-out folds by degree-1 and degree-2 spherical harmonics; Fourier
harmonics of heading on turntable data), over time, against temperature, and in its distribution
(excess kurtosis, share beyond SPIKE_SIGMA robust sigma)."""
from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre

from magbench.simulate.effects import SPIKE_SIGMA, Columns, robust_sigma

from .floor import unit_span

HEADING_HARMONICS = 4
TIME_LEGENDRE_DEGREE = 8
TIME_BANDS = 4
LOCALIZE_SEED_OFFSET = 1  # folds of the localization differ from those of the effect scoring


def folds(n: int, k: int, seed: int) -> np.ndarray:
    """Fold label of each of n samples: a seeded permutation modulo k."""
    return np.random.default_rng(seed).permutation(n) % k


def cv_r2(design: np.ndarray, r: np.ndarray, fold: np.ndarray) -> float:
    """Share (%) of the residual variance a linear model in ``design`` explains on held-out folds."""
    pred = np.empty_like(r)
    for f in np.unique(fold):
        tr, te = fold != f, fold == f
        coef, *_ = np.linalg.lstsq(design[tr], r[tr], rcond=None)
        pred[te] = design[te] @ coef
    return float(100.0 * (1.0 - np.sum((r - pred) ** 2) / np.sum((r - r.mean()) ** 2)))


def harmonics(heading_deg: np.ndarray, r: np.ndarray, k_max: int = HEADING_HARMONICS) -> dict:
    """Amplitude (nT) of the residual at k cycles per revolution of the heading (least squares)."""
    h = np.radians(heading_deg)
    cols = [np.ones_like(h)] + [f(k * h) for k in range(1, k_max + 1) for f in (np.cos, np.sin)]
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), r, rcond=None)
    amps = {f"{k}_per_rev_nT": float(np.hypot(coef[2 * k - 1], coef[2 * k])) for k in range(1, k_max + 1)}
    fit = np.column_stack(cols) @ coef
    amps["mean_nT"] = float(coef[0])
    amps["rms_beyond_nT"] = float(np.sqrt(np.mean((r - fit) ** 2)))
    return amps


def spherical_design(u: np.ndarray, degree: int) -> np.ndarray:
    """Real spherical harmonics up to degree 1 or 2 of unit vectors ``u`` (n, 3), as design columns."""
    x, y, z = u.T
    cols = [np.ones_like(x), x, y, z]
    if degree >= 2:
        cols += [x * y, x * z, y * z, x * x - y * y, 3 * z * z - 1]
    return np.column_stack(cols)


def localize(r: np.ndarray, unit: np.ndarray, d: Columns, heading_deg, k: int, seed: int) -> dict:
    """The localization block of the diagnosis (module docstring)."""
    fold = folds(len(r), k, seed + LOCALIZE_SEED_OFFSET)
    loc = {"attitude_deg1_explained_pct": cv_r2(spherical_design(unit, 1), r, fold),
           "attitude_deg2_explained_pct": cv_r2(spherical_design(unit, 2), r, fold)}
    if unit_span(d.t_s) is not None:
        order = np.argsort(d.t_s)
        tau = 2 * (d.t_s - d.t_s.min()) / np.ptp(d.t_s) - 1
        loc["time_explained_pct"] = cv_r2(legendre.legvander(tau, TIME_LEGENDRE_DEGREE), r, fold)
        rs = r[order] - r.mean()
        loc["time_lag1_autocorrelation"] = float(np.sum(rs[1:] * rs[:-1]) / np.sum(rs * rs))
    if unit_span(d.temp_C) is not None:
        loc["temperature_correlation"] = float(np.corrcoef(d.temp_C, r)[0, 1])
    if heading_deg is not None:
        loc["heading_harmonics"] = harmonics(heading_deg, r)
    s = robust_sigma(r)
    loc["excess_kurtosis"] = float(np.mean((r - r.mean()) ** 4) / np.var(r) ** 2 - 3.0)
    loc[f"beyond_{SPIKE_SIGMA:g}_robust_sigma_pct"] = float(100.0 * np.mean(np.abs(r - np.median(r)) > SPIKE_SIGMA * s))
    return loc


def residual_spectrum(r: np.ndarray, heading_deg, t_s) -> dict:
    """Amplitudes per heading harmonic (turntable data), else RMS in TIME_BANDS bands of the time
    spectrum, else nothing."""
    if heading_deg is not None:
        h = harmonics(heading_deg, r)
        return {k: v for k, v in h.items() if k.endswith("per_rev_nT")}
    if unit_span(t_s) is not None:
        rs = r[np.argsort(t_s)]
        p = np.abs(np.fft.rfft(rs - rs.mean())) ** 2 / len(rs)
        bands = np.array_split(np.arange(1, len(p)), TIME_BANDS)
        return {f"time_band{i + 1}_rms_nT": float(np.sqrt(2 * p[b].sum() / len(rs))) for i, b in enumerate(bands)}
    return {}

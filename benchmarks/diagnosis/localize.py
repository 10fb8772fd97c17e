"""Where the residual of the base calibration lies.  Every figure is a held-out explained fraction (%),
comparable with the effects' shrink: a linear model in the named variable is fitted on K-1 folds and
the share of the residual's variance it explains on the fold left out is reported.

* attitude: real spherical harmonics of the unit corrected field (sensor frame), degrees 1 to 6
  (cumulative; degrees 1-2 are mostly removed by the 9-parameter fit itself);
* time (Legendre polynomials to degree 8), temperature (cubic), the reference's rate of change and the
  rotation rate (quadratics), and the gravity direction (degree-2 harmonics of the accelerometer
  direction) when the file has ax, ay, az;
* the distribution (excess kurtosis, share beyond SPIKE_SIGMA robust sigma) and, on turntable data,
  Fourier harmonics of heading."""
from __future__ import annotations

from itertools import combinations_with_replacement

import numpy as np
from numpy.polynomial import legendre

from magbench.simulate.effects import SPIKE_SIGMA, Columns, robust_sigma, time_derivative

from .floor import unit_span
from .wheremap import (
    MAP_DIRECTIONS,
    MAP_TIME_BLOCKS,
    attitude_time_map,
    axis_projections,
    body_field_step,
    change_points,
    temperature_beyond_time,
)

HEADING_HARMONICS = 4
MAX_DEGREE = 6
TIME_LEGENDRE_DEGREE = 8
TIME_BANDS = 4
LOCALIZE_SEED_OFFSET = 1  # folds of the localization differ from those of the effect scoring
BLOCK_ROWS = 65536
MIN_POINTS_PER_COLUMN = 3


def folds(n: int, k: int, seed: int) -> np.ndarray:
    """Fold label of each of n samples: a seeded permutation modulo k."""
    return np.random.default_rng(seed).permutation(n) % k


def cv_explained(design, r: np.ndarray, fold: np.ndarray, k: int) -> float | None:
    """Share (%) of the residual variance that a linear model (with a constant) in ``design(sl)`` explains
    on held-out folds, from per-fold Gram matrices (blocks of rows); None with too few points."""
    n = len(r)
    grams: np.ndarray | None = None
    for s in range(0, n, BLOCK_ROWS):
        sl = slice(s, min(n, s + BLOCK_ROWS))
        x = design(sl)
        z = np.column_stack([np.ones(len(x)), x, r[sl]])
        if grams is None:
            if n < MIN_POINTS_PER_COLUMN * z.shape[1]:
                return None
            grams = np.zeros((k, z.shape[1], z.shape[1]))
        fl = fold[sl]
        for f in range(k):
            zf = z[fl == f]
            grams[f] += zf.T @ zf
    if grams is None:
        return None
    p = grams.shape[1] - 1
    tot = grams.sum(axis=0)
    sse = 0.0
    for f in range(k):
        g = tot - grams[f]
        a, b = g[:p, :p], g[:p, p]
        dg = np.sqrt(np.clip(np.diag(a), 1e-300, None))
        coef = np.linalg.lstsq(a / dg[:, None] / dg[None, :], b / dg, rcond=1e-10)[0] / dg
        t = grams[f]
        sse += t[p, p] - 2 * coef @ t[:p, p] + coef @ t[:p, :p] @ coef
    mean = tot[0, p] / tot[0, 0]
    sst = tot[p, p] - tot[0, 0] * mean**2
    return float(100.0 * (1.0 - sse / sst)) if sst > 0 else 0.0


def spherical_design(u: np.ndarray, degree: int) -> np.ndarray:
    """Columns spanning the real spherical harmonics of degrees 1..``degree`` of unit vectors ``u``: the
    monomials of degree ``degree`` and ``degree - 1`` (on the sphere they span every lower degree), without
    the constant."""
    cols = []
    for deg in (degree - 1, degree):
        for combo in combinations_with_replacement(range(3), deg):
            if deg == 0:
                continue
            c = np.ones(len(u))
            for i in combo:
                c = c * u[:, i]
            cols.append(c)
    return np.column_stack(cols)


def heading_design(heading_deg: np.ndarray, k_max: int = HEADING_HARMONICS) -> np.ndarray:
    """The columns 1, cos h, sin h, ..., cos k_max h, sin k_max h of ``harmonics``' least squares."""
    h = np.radians(heading_deg)
    return np.column_stack([np.ones_like(h)] + [f(k * h) for k in range(1, k_max + 1) for f in (np.cos, np.sin)])


def harmonics(heading_deg: np.ndarray, r: np.ndarray, k_max: int = HEADING_HARMONICS) -> dict:
    """Amplitude (nT) of the residual at k cycles per revolution of the heading (least squares)."""
    design = heading_design(heading_deg, k_max)
    coef, *_ = np.linalg.lstsq(design, r, rcond=None)
    amps = {f"{k}_per_rev_nT": float(np.hypot(coef[2 * k - 1], coef[2 * k])) for k in range(1, k_max + 1)}
    fit = design @ coef
    amps["mean_nT"] = float(coef[0])
    amps["rms_beyond_nT"] = float(np.sqrt(np.mean((r - fit) ** 2)))
    return amps


def _poly(v: np.ndarray, degree: int) -> np.ndarray:
    s = unit_span(v) * 2 - 1  # type: ignore[operator]
    return legendre.legvander(s, degree)[:, 1:]


def localize(r: np.ndarray, unit: np.ndarray, d: Columns, heading_deg, k: int, seed: int,
             gravity: np.ndarray | None = None, floor_nT: float | None = None) -> dict:
    """The localization block of the diagnosis (module docstring)."""
    fold = folds(len(r), k, seed + LOCALIZE_SEED_OFFSET)
    loc: dict = {}
    for deg in range(1, MAX_DEGREE + 1):
        loc[f"attitude_deg{deg}_explained_pct"] = cv_explained(lambda sl, g=deg: spherical_design(unit[sl], g), r,
                                                               fold, k)
    if unit_span(d.t_s) is not None:
        tpoly = _poly(d.t_s, TIME_LEGENDRE_DEGREE)
        loc["time_explained_pct"] = cv_explained(lambda sl: tpoly[sl], r, fold, k)
        order = np.argsort(d.t_s, kind="stable")
        rs = r[order] - r.mean()
        loc["time_lag1_autocorrelation"] = float(np.sum(rs[1:] * rs[:-1]) / np.sum(rs * rs))
        rate = np.linalg.norm(time_derivative(d.t_s, unit), axis=1)
        if unit_span(rate) is not None:
            rpoly = _poly(rate, 2)
            loc["rotation_rate_explained_pct"] = cv_explained(lambda sl: rpoly[sl], r, fold, k)
        fdot = time_derivative(d.t_s, d.f_ref_nT)
        if unit_span(fdot) is not None:
            fpoly = _poly(fdot, 2)
            loc["reference_rate_explained_pct"] = cv_explained(lambda sl: fpoly[sl], r, fold, k)
    if unit_span(d.temp_C) is not None:
        tp = _poly(d.temp_C, 3)
        loc["temperature_explained_pct"] = cv_explained(lambda sl: tp[sl], r, fold, k)
        loc["temperature_correlation"] = float(np.corrcoef(d.temp_C, r)[0, 1])
    if gravity is not None:
        g = gravity / np.linalg.norm(gravity, axis=1, keepdims=True)
        loc["gravity_direction_explained_pct"] = cv_explained(lambda sl: spherical_design(g[sl], 2), r, fold, k)
    if heading_deg is not None:
        loc["heading_harmonics"] = harmonics(heading_deg, r)
    if len(r) >= 4 * MAP_DIRECTIONS * MAP_TIME_BLOCKS:
        loc["axis_projections"] = axis_projections(r, unit, seed)
        if unit_span(d.t_s) is not None:
            loc["attitude_time_map"] = attitude_time_map(r, unit, d.t_s, seed)
            fl = float(robust_sigma(np.diff(r[np.argsort(d.t_s, kind="stable")])) / np.sqrt(2.0)) \
                if floor_nT is None else floor_nT
            loc["change_points"] = change_points(r, d.t_s, fl)
            step = body_field_step(r, unit, d.t_s, fl)
            if step is not None:
                loc["body_field_step"] = step
            if unit_span(d.temp_C) is not None:
                loc["temperature_beyond_time_pct"] = temperature_beyond_time(r, d.t_s, d.temp_C, seed)
    loc.update(tails(r))
    return {k_: v for k_, v in loc.items() if v is not None}


def tails(r: np.ndarray) -> dict:
    """The residual's tails: excess kurtosis and the share beyond SPIKE_SIGMA robust sigma."""
    s = robust_sigma(r)
    return {"excess_kurtosis": float(np.mean((r - r.mean()) ** 4) / max(np.var(r), 1e-300) ** 2 - 3.0),
            f"beyond_{SPIKE_SIGMA:g}_robust_sigma_pct": float(100.0 * np.mean(np.abs(r - np.median(r)) > SPIKE_SIGMA * s))}


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

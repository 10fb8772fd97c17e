"""The time-only diagnosis of a fixed sensor (or any record whose attitudes cannot determine the model).

A fixed instrument (an observatory variometer beside its scalar magnetometer) cannot be rotated, so no
calibration model can be fitted; its time question still has an answer.  With the readings' magnitude
``|B|`` and the reference ``F``: the constant ``|B| - F`` (its median), its drift (a straight line in time,
in nT per hour, with its standard error, and a smooth trend), its temperature dependence beyond what time
predicts (when ``temp`` is logged), the noise floor from time neighbours, and a verdict on the time part;
the attitude part is stated as ``insufficient_data``.

Spikes and a temperature effect are what a fixed sensor can name.  Spikes: glitches in ``|B| - F`` beyond
the smooth trend, judged by the vector diagnosis's own tests (their count, isolation and spread in time, not clipped
readings, a noise-like rest).  A temperature effect: ``|B| - F`` follows the logged temperature beyond a smooth function
of time (the temperature's own changes, not only the time they share).  A drift alone cannot be named: with
one direction seen and a scalar reference, a drift of the offsets, of the scale and of the field's magnitude
move ``|B| - F`` alike, so it is reported in ``time_only`` and ``time_verdict``, and the verdict stays
``insufficient_data``.
"""
from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre

from magbench.simulate.dataset import Dataset
from magbench.simulate.effects import OutlierEffect

from .floor import time_difference_floor
from .naming import spike_signature
from .scoring import rms

SECONDS_PER_HOUR = 3600.0
DRIFT_Z = 3.0
"""A drift or temperature coefficient is reported as significant beyond this many standard errors (its
standard error inflated for the residual's autocorrelation: effective samples from the lag-1 correlation)."""
TREND_DEGREE = 6
TEMPERATURE_NAME_Z = 4.0
"""A fixed sensor's temperature effect is named when |B| - F follows the logged temperature beyond a smooth
function of time by this many standard errors."""


def _effective_n(resid: np.ndarray) -> float:
    """Samples worth of independent information in an autocorrelated residual (AR(1) approximation)."""
    n = len(resid)
    if n < 3 or np.var(resid) == 0:
        return float(n)
    rho = float(np.corrcoef(resid[:-1], resid[1:])[0, 1])
    rho = min(max(rho, 0.0), 0.99)
    return max(n * (1 - rho) / (1 + rho), 2.0)


def _linear(design: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least squares with standard errors inflated for autocorrelation: (coef, se, residual)."""
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    resid = y - design @ coef
    n_eff = _effective_n(resid)
    dof = max(n_eff - design.shape[1], 1.0)
    sigma2 = float(resid @ resid) / len(y) * len(y) / dof
    cov = sigma2 * np.linalg.pinv(design.T @ design) * (len(y) / n_eff)
    return coef, np.sqrt(np.clip(np.diag(cov), 0, None)), resid


def time_only(data: Dataset, reason: str) -> dict:
    """The JSON-ready answer to the time question of a record whose attitudes do not determine the model."""
    raw = np.asarray(data.raw_nT, dtype=float)
    f = np.asarray(data.f_ref_nT, dtype=float)
    r = np.linalg.norm(raw, axis=1) - f
    n = len(r)
    t = np.arange(n, dtype=float) if data.t_s is None else np.asarray(data.t_s, dtype=float)
    order = np.argsort(t, kind="stable")
    t, r = t[order], r[order]
    hours = (t - t[0]) / SECONDS_PER_HOUR
    out: dict = {"kind": "time_only", "n_points": n, "attitude": "insufficient_data", "attitude_reason": reason}
    span = np.ptp(t)
    trend_design = legendre.legvander(2 * (t - t[0]) / span - 1, TREND_DEGREE) if span > 0 else None
    spikes, spike_info = _spikes(r, trend_design, t, raw[order])
    keep = ~spikes
    floor = time_difference_floor(r[keep], t[keep] if data.t_s is not None else None)
    design = np.column_stack([np.ones(n), hours - hours.mean()])
    coef, se, resid = _linear(design[keep], r[keep])
    drift = {"drift_nT_per_h": float(coef[1]), "drift_se_nT_per_h": float(se[1]),
             "significant": bool(abs(coef[1]) > DRIFT_Z * se[1]) if np.ptp(hours) > 0 else False}
    if trend_design is not None and n > 3 * TREND_DEGREE:
        trend = trend_design @ np.linalg.lstsq(trend_design[keep], r[keep], rcond=None)[0]
        drift["trend_range_nT"] = float(np.ptp(trend))
        drift["rms_after_trend_nT"] = rms((r - trend)[keep])
    out["time_only"] = {
        "constant_nT": float(np.median(r)), "mean_nT": float(np.mean(r[keep])), "rms_nT": rms(r[keep]),
        "spikes": spike_info,
        "span_h": float(np.ptp(hours)), "drift": drift, "noise_floor_nT": floor["noise_floor_nT"],
        "floor_method": floor["floor_method"],
        "statement": "|B| - F of the uncalibrated readings: a constant is a scale or offset error along the one "
                     "direction the fixed sensor sees; its drift is a drift of either or of the field's magnitude"}
    if data.temp_C is not None and np.ptp(data.temp_C) > 0:
        temp = np.asarray(data.temp_C, dtype=float)[order]
        tdesign = np.column_stack([design, temp - temp.mean()])
        tcoef, tse, _ = _linear(tdesign[keep], r[keep])
        out["time_only"]["temperature"] = {
            "temperature_nT_per_C": float(tcoef[2]), "temperature_se_nT_per_C": float(tse[2]),
            "beyond_time": "the coefficient with a linear drift in time fitted beside it",
            "significant": bool(abs(tcoef[2]) > DRIFT_Z * tse[2])}
        if trend_design is not None and n > 3 * TREND_DEGREE:  # beyond any smooth function of time: its own signature
            sdesign = np.column_stack([trend_design, temp - temp.mean()])
            scoef, sse, _ = _linear(sdesign[keep], r[keep])
            z = float(abs(scoef[-1]) / sse[-1]) if sse[-1] > 0 else 0.0
            out["time_only"]["temperature"].update({
                "beyond_smooth_time_nT_per_C": float(scoef[-1]), "beyond_smooth_time_z": z,
                "named": bool(z > TEMPERATURE_NAME_Z),
                "named_rule": f"the coefficient with a degree-{TREND_DEGREE} polynomial of time fitted beside it, beyond "
                              f"{TEMPERATURE_NAME_Z:g} standard errors (inflated for autocorrelation): |B| - F follows the "
                              "logged temperature's own changes, not only the time they share"})
    named = [name for name, part in (("drift", drift), ("temperature", out["time_only"].get("temperature", {})))
             if part.get("significant")]
    outliers = ["outliers"] if spike_info["named"] else []
    named = outliers + named
    verdict = outliers + (["temperature"] if out["time_only"].get("temperature", {}).get("named") else [])
    out["verdict"] = "+".join(verdict) if verdict else "insufficient_data"
    out["time_verdict"] = "+".join(named) if named else "constant"
    return out


def _spikes(r: np.ndarray, design: np.ndarray | None, t: np.ndarray, raw_nT: np.ndarray) -> tuple[np.ndarray, dict]:
    """Glitches in the time series ``r`` (in time order): samples beyond SPIKE_SIGMA robust sigma of what a
    smooth trend (the columns ``design``) leaves, named only when their count and the naming rule's spike
    signature (``spike_signature``) say they are outliers; (mask, the evidence)."""
    n = len(r)
    if n < 3 * TREND_DEGREE or design is None:
        return np.zeros(n, dtype=bool), {"n": 0, "named": False}
    resid = r - design @ np.linalg.lstsq(design, r, rcond=None)[0]
    mask = OutlierEffect.spike_mask(resid)
    if mask.any():  # the trend again without them, so that large spikes do not bend it
        resid = r - design @ np.linalg.lstsq(design[~mask], r[~mask], rcond=None)[0]
        mask = OutlierEffect.spike_mask(resid)
    glitches, share, ratio, clip = spike_signature(mask, resid, t, raw_nT)
    named = bool(OutlierEffect.enough(int(mask.sum()), n) and glitches)
    return (mask if named else np.zeros(n, dtype=bool)), {
        "n": int(mask.sum()), "named": named, "neighbour_share": share, "bulk_tail_ratio": ratio,
        "clipped_share": clip,
        "rule": "beyond 5 robust sigma of a smooth trend; named when more than noise gives, isolated and spread in "
                "time, not readings at a repeated extreme (clipping), on a noise-like rest"}

"""The time-only diagnosis of a fixed sensor (or any record whose attitudes cannot determine the model).

A fixed instrument (an observatory variometer beside its scalar magnetometer) cannot be rotated, so no
calibration model can be fitted; its time question still has an answer.  With the readings' magnitude
``|B|`` and the reference ``F``: the constant ``|B| - F`` (its median), its drift (a straight line in time,
in nT per hour, with its standard error, and a smooth trend; per row where the t column is no clock: absent, one or
a few different times, or a sample index), its temperature dependence beyond what time
predicts (when ``temp`` is logged), the noise floor from time neighbours (on the distinct samples when a logger
held its value: exact repeats of the previous reading), and a verdict on the time part; the attitude part is stated
as ``insufficient_data``.  A record of almost nothing but repeats (a stuck sensor) is refused.

Spikes and a temperature effect are what a fixed sensor can name.  Spikes: glitches in ``|B| - F`` beyond
the smooth trend, judged by the vector diagnosis's own tests (their count, isolation and spread in time, not clipped
readings, a noise-like rest); a long record's few glitches, below the selection's share of the samples, count when
Gaussian noise does not give their number and the residual's shoulder below them is Gaussian (SHOULDER_SIGMA).
A temperature effect: ``|B| - F`` follows the logged temperature beyond a smooth function of time (the
temperature's own changes, not only the time they share).

A drift is named from the direction in which the *vector* readings move, which ``|B| - F`` alone cannot tell:
a change of the field's magnitude that the reference does not follow moves the readings along the direction
they point (radially: an offset error of up to a few thousand nT tilts that direction by at most a few
hundredths of a radian), while a drift of the offsets moves them along a direction of its own, in general
across.  So does a change of the field's *direction* (an observatory's daily variation is mostly in declination
and horizontal intensity): a scalar reference follows no direction, so to these data it is a field drift that
cannot be told from a drift of the offsets.  The smooth trend of the readings (a degree-TREND_DEGREE polynomial
of time on each axis, spikes left out) is split into its radial part and its part across; both are tested
against the readings' own scatter about the trend (an F test, its samples deflated for autocorrelation, at
DRIFT_DIRECTION_ALPHA):

* a significant part across at least ACROSS_MIN_RATIO of the radial part, beyond the turning the field's own
  variation gives where the reference varies (TURN_FACTOR times its RMS: a field that changes also turns, and
  a scalar reference follows its magnitude only): ``offset_drift|field_drift`` (the offsets drift, or the field
  turns beyond its followed variation), with ``temperature`` among the alternatives when the logged temperature
  follows time and, through its best first-order lag, takes at least THERMAL_SHARE_OF_TREND of what the trend takes
  (a temperature coefficient is a drift of the temperature's own smooth shape, not any drift), or when the logged
  temperature through a first-order lag fits the trend across as well as the smooth trend does (the same F test
  as for a radial trend, below: a temperature effect whose temperature wanders on its own, too weakly beyond
  time to be named on its own signature, still fits the drift it makes); ``confounded``
  says what would separate them (a vector reference, or turning the sensor);
* a significant radial part with the part across below RADIAL_MAX_RATIO of it: ``field_drift``, said with
  ``temperature`` when the logged temperature (through a first-order lag, as the library's temperature effect)
  fits the radial trend as well (the scale coefficients of the three axes changing together move the readings
  radially too); the gains of the three axes drifting together in time (outside the library) would look the
  same;
* where the reference varies and the trend across is no more than the field's own turning (TURN_FACTOR), a
  significant radial trend beyond the reference's variation (the part a fitted gain of it leaves, at least
  REFERENCE_FOLLOW_SHARE of that variation): ``offset_drift|field_drift`` (the offsets drift along the field, or
  the field's magnitude here changes otherwise than the reference's), with ``temperature`` among the alternatives
  as above; the radial trend alone is then tested for a step and against the temperature;
* in between, or when a single step (a field switched on near the sensor) explains the trend as well as the
  smooth drift does (STEP_SHARE): no name; the drift stays in ``time_only``.

A temperature effect named on its own signature takes precedence (the drift is then its shape).
"""
from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre

from magbench.errors import InputError
from magbench.simulate.dataset import Dataset
from magbench.simulate.effects import SPIKE_SIGMA, OutlierEffect, f_test_p, first_order_lag

from .floor import consecutive_repeats, noise_spectrum, time_difference_floor
from .naming import STEP_SHARE, TEMPERATURE_FOLLOWS_TIME_R2, spike_signature, temperature_follows_time
from .scoring import rms, shoulder_p, spike_z, spikes_enough

SECONDS_PER_HOUR = 3600.0
DRIFT_Z = 3.0
"""A drift or temperature coefficient is reported as significant beyond this many standard errors (its
standard error inflated for the residual's autocorrelation: effective samples from the lag-1 correlation)."""
TREND_DEGREE = 6
TREND_DEGREES = (TREND_DEGREE, 12, 24, 48)
TREND_RHO_MAX = 0.5
TREND_SAMPLES_PER_TERM = 8
"""``_trend_fit``: the degrees of a fixed sensor's drift trend tried in turn, the lag-1 correlation of what it leaves
below which the degree suffices, and the samples each term of the next degree needs."""
DRIFT_DIRECTION_ALPHA = 1e-6
"""Level of the F tests of the radial trend and of the trend across (a drift of tens of noise sigmas is far
beyond it; a record without drift is far from it)."""
ACROSS_MIN_RATIO = 0.1
RADIAL_MAX_RATIO = 0.05
"""The RMS of the trend across over that of the radial trend: at least ACROSS_MIN_RATIO for a drift of the offsets,
at most RADIAL_MAX_RATIO for a change of the field's magnitude (an offset error of 2500 nT in a 50,000 nT field tilts
the radial direction by 0.05 rad).  Where neither holds, the drift stays ``offset_drift|temperature|field_drift``
(or ``offset_drift|field_drift``): the ratio does not tell the three apart in between.  Measured on the 752 fixed
records of the four independent generators whose drift came back as one of these ambiguities (round 27), the true
cause was a field drift at every ratio (6 of the 12 records below 0.22, 78 of the 313 above 2.2) and so was an
offset drift (1 of the 12 below 0.22, 145 of the 313 above 2.2), so no narrower verdict there would avoid wrong
names."""
TURN_FACTOR = 3.0
"""Where the reference varies, the field is changing, and a changing field turns: a geomagnetic variation moves
the field's direction by about as much as its magnitude (the daily variation and a storm's ring current change
the horizontal intensity, the declination and the vertical intensity together, by amounts of the same order).
An across trend of the readings up to TURN_FACTOR times the RMS of the reference's own variation is therefore
the field's own turning, which a scalar reference follows in magnitude but not in direction: it is reported,
not named (a drift of the offsets beneath it cannot be told without a vector reference)."""
REFERENCE_FOLLOW_SHARE = 0.02
"""Where the reference varies and the readings turn with the field, the radial trend left once the reference's
variation is taken out (with a fitted gain) is named only beyond this share of that variation's RMS: a scalar
reference follows the field's variation in shape to within a few per mille to a few per cent (its site, its own
response), and below that the shape left is the reference's, not a drift.  Set from the independent generators'
fixed records: the one record below it (0.5 %) had outliers only, no drift; the named ones are at 3.3 % and
more."""
THERMAL_LAG_OF_SPAN = (0.0, 0.01, 0.03, 0.1, 0.3, 1.0)
"""First-order thermal time constants tried (shares of the record's span) when asking whether the logged
temperature fits a drift (radial or across) as well as the smooth trend does."""
THERMAL_SHARE_OF_TREND = 0.5
"""The logged temperature is an alternative for a fixed sensor's drift only when, through its best first-order lag,
it takes at least this share of what the drift's trend (``_trend_fit``) takes from the readings' scatter; also when
it follows time (``TEMPERATURE_FOLLOWS_TIME_R2``), since a smooth temperature takes only a drift of its own shape (the
development fixed records of the four independent generators: true temperatures take 0.80-1.0 of the trend, the
field and offset drifts beside a temperature that follows time 0.004-0.42)."""
MIN_DISTINCT = 10
"""A fixed record needs at least this many readings that differ from the one before them (the floor's least
number of distinct samples); fewer is a stuck sensor or logger, refused."""
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


def _autocorrelation(x: np.ndarray, lags: int) -> np.ndarray:
    """The sample autocorrelation of ``x`` at lags 1..``lags`` (in sample order), by FFT."""
    x = x - x.mean()
    n = len(x)
    spec = np.fft.rfft(x, 2 * n)
    acov = np.fft.irfft(spec * np.conj(spec), 2 * n)[:lags + 1]
    return acov[1:] / acov[0] if acov[0] > 0 else np.zeros(lags)


def _bartlett_n(resid: np.ndarray, regressor: np.ndarray) -> float:
    """Samples worth of independent information in the regression of an autocorrelated residual on an
    autocorrelated regressor (Bartlett 1935): ``n / (1 + 2 sum_k rho_r(k) rho_x(k))`` over the lags up to a
    quarter of the record.  Two slowly wandering series (a weather temperature and 1/f sensor noise) correlate
    by chance far beyond an AR(1) residual's allowance; this counts their common memory."""
    n = len(resid)
    if n < 8 or np.var(resid) == 0 or np.var(regressor) == 0:
        return float(n)
    lags = n // 4
    total = float(np.sum(_autocorrelation(resid, lags) * _autocorrelation(regressor, lags)))
    return float(min(max(n / max(1.0 + 2.0 * total, 1e-9), 2.0), n))


def _linear(design: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least squares with standard errors inflated for autocorrelation: (coef, se, residual).  The columns are
    scaled to unit size first (and the coefficients back): a column of hours spanning 1e-9 h had fallen below the
    pseudo-inverse's cutoff beside the column of ones, and a drift came with a standard error of 0."""
    size = np.max(np.abs(design), axis=0)
    size[size == 0] = 1.0
    scaled = design / size
    coef, *_ = np.linalg.lstsq(scaled, y, rcond=None)
    resid = y - scaled @ coef
    n_eff = _effective_n(resid)
    dof = max(n_eff - design.shape[1], 1.0)
    sigma2 = float(resid @ resid) / len(y) * len(y) / dof
    cov = sigma2 * np.linalg.pinv(scaled.T @ scaled) * (len(y) / n_eff)
    return coef / size, np.sqrt(np.clip(np.diag(cov), 0, None)) / size, resid


def _distinct_times(t_s) -> int:
    return 0 if t_s is None else len(np.unique(np.asarray(t_s, dtype=float)))


def has_clock(t_s) -> bool:
    """Whether a t column can serve as a clock for the time question: present, with at least MIN_DISTINCT
    different times (one time on every row, or two, says nothing of how the readings move in time: a 'drift' from
    two time points had been called significant).  Without one the rows' order is the time axis."""
    return _distinct_times(t_s) >= MIN_DISTINCT


def t_is_sample_index(data) -> bool:
    """Whether the file says (a ``# t_note:`` line naming an index) that its t column counts samples, not seconds:
    a drift per hour would then be a drift per 3600 rows, said as such."""
    return "index" in " ".join(str(v) for k, v in (getattr(data, "meta", None) or {}).items()
                               if k.startswith("t_note")).lower()


def _time_axis(t_s, indexed: bool = False) -> str:
    if indexed and t_s is not None:
        return "the rows' order (the file's t_note says its t counts samples: a drift is per row, not per hour)"
    if t_s is None:
        return "the rows' order (no t column: a drift is per row, not per hour)"
    k = _distinct_times(t_s)  # has_clock's count, taken once
    if k >= MIN_DISTINCT:
        return "the t column"
    held = "one time for every row" if k == 1 else f"only {k} different times"
    return f"the rows' order (the t column holds {held}: no clock; a drift is per row, not per hour)"


def time_only(data: Dataset, reason: str) -> dict:
    """The JSON-ready answer to the time question of a record whose attitudes do not determine the model."""
    raw = np.asarray(data.raw_nT, dtype=float)
    f = np.asarray(data.f_ref_nT, dtype=float)
    r = np.linalg.norm(raw, axis=1) - f
    n = len(r)
    # a clock: a t column that changes (one time on every row is no clock, as on the vector path's 'no informative t
    # column'); without one the rows' order is the time axis, and a drift is per row, not per hour (it had been
    # reported in nT/h as if the rows were one second apart)
    indexed = t_is_sample_index(data)
    clock = has_clock(data.t_s) and not indexed
    t = np.asarray(data.t_s, dtype=float) if clock else np.arange(n, dtype=float)
    order = np.argsort(t, kind="stable")
    t, r = t[order], r[order]
    hours = (t - t[0]) / SECONDS_PER_HOUR if clock else t  # rows, without a clock
    out: dict = {"kind": "time_only", "n_points": n, "attitude": "insufficient_data", "attitude_reason": reason}
    span = np.ptp(t)
    trend_design = legendre.legvander(2 * (t - t[0]) / span - 1, TREND_DEGREE) if span > 0 else None
    # a logger that holds its last value repeats readings exactly: a held sample interpolates perfectly from its twin
    # and pulls the floor down, so the floor comes from the distinct samples (as the vector floor's); a record of
    # almost nothing but repeats is a stuck sensor or logger, with no time question to answer.  A fixed sensor below
    # its resolution repeats values too, each axis on its own: those are its readings, not holds (``repeats``)
    held_rows, grid, logger = consecutive_repeats(raw, order)
    held = held_rows[order]  # in time order
    distinct = int((~held).sum())
    if distinct < MIN_DISTINCT:
        raise InputError(f"{n - distinct} of {n} readings repeat the one before them exactly ({distinct} distinct): a "
                         "stuck sensor, a logger that holds its value, or a resolution far coarser than the changes; "
                         "nothing to diagnose")
    unique = len(np.unique(raw, axis=0))
    if unique < MIN_DISTINCT:  # a few readings written again in turn: no more samples than they are (CONTRACT: distinct)
        raise InputError(f"the {n} readings hold only {unique} different values, written again in turn: a logger "
                         "replaying a few samples, or a resolution far coarser than the changes; nothing to diagnose")
    spikes, spike_info = _spikes(r, trend_design, t, raw[order])
    keep = ~spikes
    held_share = float(held.mean())
    on = keep & ~held if logger and (keep & ~held).sum() >= MIN_DISTINCT else keep
    floor = time_difference_floor(r[on], t[on] if clock else None, grid=grid)
    if on is not keep:
        floor["floor_method"] += f" (on the {int(on.sum())} distinct samples: {100 * held_share:.1f} % held)"
    design = np.column_stack([np.ones(n), hours - hours.mean()])
    coef, se, resid = _linear(design[keep], r[keep])
    unit = "h" if clock else "row"
    drift: dict = {f"drift_nT_per_{unit}": float(coef[1]), f"drift_se_nT_per_{unit}": float(se[1]),
                   "significant": bool(abs(coef[1]) > DRIFT_Z * se[1]) if np.ptp(hours) > 0 else False}
    if not clock:  # the keys of the other time axis, said empty rather than left out (either way)
        drift.update(drift_nT_per_h=None, drift_se_nT_per_h=None)
    else:
        drift.update(drift_nT_per_row=None, drift_se_nT_per_row=None)
    left = None  # what the smooth trend of |B| - F leaves on the kept samples
    if trend_design is not None and n > 3 * TREND_DEGREE:
        trend = trend_design @ np.linalg.lstsq(trend_design[keep], r[keep], rcond=None)[0]
        left = (r - trend)[keep]
        drift["trend_range_nT"] = float(np.ptp(trend))
        drift["rms_after_trend_nT"] = rms(left)
        drift["noise_spectrum"] = noise_spectrum(left)  # over time scales
    out["time_only"] = {
        "constant_nT": float(np.median(r)), "mean_nT": float(np.mean(r[keep])), "rms_nT": rms(r[keep]),
        "spikes": spike_info,
        "span_h": float(np.ptp(hours)) if clock else None, "span_rows": None if clock else n - 1,
        "time_axis": _time_axis(data.t_s, indexed),
        "drift": drift, "noise_floor_nT": floor["noise_floor_nT"],
        "floor_method": floor["floor_method"], "held_sample_fraction": held_share,
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
        if left is not None and trend_design is not None:  # beyond any smooth function of time: its own signature
            sdesign = np.column_stack([trend_design, temp - temp.mean()])
            scoef, sse, sres = _linear(sdesign[keep], r[keep])
            # the temperature's own changes (what the smooth trend leaves of it) against the residual: their common
            # memory, not the residual's alone, sets how far they can correlate by chance
            # (under the null: the residual of the smooth trend alone, not the one the temperature was fitted into)
            td, tk = trend_design[keep], temp[keep] - temp[keep].mean()
            t_own = tk - td @ np.linalg.lstsq(td, tk, rcond=None)[0]
            bartlett = _bartlett_n(left, t_own)
            se_t = float(sse[-1]) * np.sqrt(max(_effective_n(sres) / bartlett, 1.0))
            z = float(abs(scoef[-1]) / se_t) if se_t > 0 else 0.0
            out["time_only"]["temperature"].update({
                "beyond_smooth_time_nT_per_C": float(scoef[-1]), "beyond_smooth_time_z": z,
                "beyond_smooth_time_effective_n": bartlett,
                "named": bool(z > TEMPERATURE_NAME_Z),
                "named_rule": f"the coefficient with a degree-{TREND_DEGREE} polynomial of time fitted beside it, beyond "
                              f"{TEMPERATURE_NAME_Z:g} standard errors (inflated for the residual's and the temperature's "
                              "common autocorrelation, Bartlett's effective samples): |B| - F follows the "
                              "logged temperature's own changes, not only the time they share"})
    named = [name for name, part in (("drift", drift), ("temperature", out["time_only"].get("temperature", {})))
             if part.get("significant")]
    outliers = ["outliers"] if spike_info["named"] else []
    named = outliers + named
    temperature_named = bool(out["time_only"].get("temperature", {}).get("named"))
    direction = _drift_direction(raw[order], t, keep, None if data.temp_C is None else np.asarray(data.temp_C, float)[order],
                                 clock, f[order])
    out["time_only"]["drift_direction"] = direction
    drifts = [] if temperature_named or direction.get("named") is None else [direction["named"]]
    out["confounded"] = [_alternatives(name, direction) for name in drifts if "|" in name]
    verdict = outliers + (["temperature"] if temperature_named else []) + drifts
    out["verdict"] = "+".join(verdict) if verdict else "insufficient_data"
    if drifts and "drift" not in named:  # a drift the straight line misses (a bay, a pulsation): the vector trend's
        named.append("drift")
    out["time_verdict"] = "+".join(named) if named else "constant"
    return out


def _alternatives(name: str, direction: dict) -> dict:
    """The ``confounded`` entry of a fixed sensor's drift named ``a|b[|c]`` (the vector path's form: the
    alternatives, the evidence and the measurement that would separate them)."""
    parts = name.split("|")
    separate = []
    if "field_drift" in parts:
        separate.append("a vector reference beside the sensor (an observatory's vector data), or turning the sensor, "
                        "tells a field that turns or changes from offsets that drift")
    if "temperature" in parts:
        separate.append("a record in which the temperature changes independently of time tells a temperature "
                        "coefficient from a drift in time" if direction.get("temperature_follows_time_r2", 0.0)
                        >= TEMPERATURE_FOLLOWS_TIME_R2 else
                        "a longer record, or a larger change of the temperature on its own, tells a temperature "
                        "coefficient (the readings follow the logged temperature's own changes) from a drift that "
                        "happens to have its shape")
    return {"alternatives": parts,
            "evidence": {key: direction[key] for key in ("radial_trend_rms_nT", "across_trend_rms_nT",
                                                          "temperature_follows_time_r2", "trend_beats_temperature_p")
                         if key in direction}
            | {"statement": direction.get("why", "")},
            "separate_by": "; ".join(separate)}


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
    glitches, share, ratio, clip, _ = spike_signature(mask, resid, t, raw_nT)
    # their number: at least the selection's share of the samples; or, fewer (a fixed record is long and its glitches
    # few), a count Gaussian noise does not give beyond SPIKE_SIGMA with a Gaussian shoulder below it (heavy-tailed
    # noise crowds the shoulder, glitches far beyond it do not)
    n_spikes = int(mask.sum())
    count_z = spike_z(n_spikes, n, SPIKE_SIGMA)
    shoulder = shoulder_p(resid, mask)
    named = bool(spikes_enough(n_spikes, n, count_z, shoulder) and glitches)
    return (mask if named else np.zeros(n, dtype=bool)), {
        "n": n_spikes, "count_z": count_z, "shoulder_p": shoulder, "named": named, "neighbour_share": share,
        "bulk_tail_ratio": ratio, "clipped_share": clip,
        "rule": "beyond 5 robust sigma of a smooth trend; named when more than noise gives, isolated and spread in "
                "time, not readings at a repeated extreme (clipping), on a noise-like rest"}


def _f_p(sse0: float, sse1: float, extra: int, n_eff: float, n_params: int) -> float:
    """p-value of the F test of ``extra`` columns lowering the sum of squares from sse0 to sse1
    (``effects.f_test_p``), the samples deflated to ``n_eff`` for autocorrelation; 0 for an exact fit."""
    if sse1 <= 0:
        return 0.0
    return f_test_p(sse0, sse1, extra, max(n_eff - n_params, 1.0))


def _step_sse(y: np.ndarray) -> float:
    """The smallest sum of squares of the rows of ``y`` (n, m) about a constant before and another after one
    time (a step; any time between the first and last 5 % of the samples)."""
    n = len(y)
    c = np.cumsum(y, axis=0)
    i = np.arange(max(1, n // 20), n - max(1, n // 20))
    before = c[i - 1]
    after = c[-1] - before
    sse = float(np.sum(y ** 2)) - np.sum(before ** 2, axis=1) / i - np.sum(after ** 2, axis=1) / (n - i)
    return float(sse.min()) if len(sse) else np.inf


def _trend_fit(u: np.ndarray, y: np.ndarray) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    """The smooth trend of the columns of ``y`` on ``u`` in [-1, 1]: (degree, Legendre design, coefficients, what
    the trend of degree TREND_DEGREE leaves, which the temperature's comparison reads).  Degree TREND_DEGREE,
    raised (TREND_DEGREES) while what it leaves on some column still follows its time neighbours (lag-1
    correlation, ``_autocorrelation``, above TREND_RHO_MAX) and the samples allow (TREND_SAMPLES_PER_TERM each): a
    drift faster than the degree leaves a residual so correlated that the F test, its samples deflated for that
    correlation, sees almost nothing (a pulsation of 30 noise sigmas in one hour was "no significant drift")."""
    smooth = y
    for degree in TREND_DEGREES:
        design = legendre.legvander(u, degree)
        coef = np.linalg.lstsq(design, y, rcond=None)[0]
        resid = y - design @ coef
        if degree == TREND_DEGREE:
            smooth = resid
        rho = max(float(_autocorrelation(resid[:, j], 1)[0]) for j in range(y.shape[1]))
        if rho <= TREND_RHO_MAX or len(y) < TREND_SAMPLES_PER_TERM * (2 * degree + 1):
            break
    return degree, design, coef, smooth


def _drift_direction(raw: np.ndarray, t: np.ndarray, keep: np.ndarray, temp: np.ndarray | None, timed: bool,
                     f_ref: np.ndarray | None = None) -> dict:
    """The direction in which the vector readings drift (module docstring): the RMS of the radial trend and of
    the trend across, their F tests, and the name they give (None for none).  ``f_ref``: the reference in the
    same order; where it varies (an observatory's scalar magnetometer), the readings' radial change that it
    follows (a fitted multiple of its change: the sensor's gain along its direction) is the field's own, not a
    drift, and is taken out first."""
    n = int(keep.sum())
    span = float(np.ptp(t))
    if not timed or span <= 0 or n <= 3 * TREND_DEGREE:
        return {"named": None, "why": "no clock (no t column, too few different times, or a sample index), or too few "
                                      "samples"}
    x, tk = raw[keep], t[keep]
    m = x.mean(axis=0)
    m = m / np.linalg.norm(m)
    e1 = np.cross(m, [1.0, 0.0, 0.0] if abs(m[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(m, e1)
    y = x @ np.column_stack([m, e1, e2])  # radial, across, across
    turning = 0.0  # the across trend the field's own turning can give (TURN_FACTOR)
    if f_ref is not None and np.ptp(f_ref[keep]) > 0:  # the field's magnitude as the reference follows it
        fk = f_ref[keep] - f_ref[keep].mean()
        turning = TURN_FACTOR * float(np.sqrt(np.mean(fk ** 2)))
        gain = float(fk @ (y[:, 0] - y[:, 0].mean()) / (fk @ fk))
        y[:, 0] -= gain * fk
    u = 2 * (tk - t[0]) / span - 1
    sse0 = np.sum((y - y.mean(axis=0)) ** 2, axis=0)
    # a trend flexible enough for the drift (``_trend_fit``)
    degree, design, coef, left = _trend_fit(u, y)
    resid = y - design @ coef
    n_eff = [_effective_n(resid[:, j]) for j in range(3)]
    sse1 = np.sum(resid ** 2, axis=0)
    p_radial = _f_p(float(sse0[0]), float(sse1[0]), degree, n_eff[0], degree + 1)
    p_across = _f_p(float(sse0[1:].sum()), float(sse1[1:].sum()), 2 * degree, float(np.mean(n_eff[1:])) * 2,
                    2 * (degree + 1))
    trend = design @ coef
    trend -= trend.mean(axis=0)
    # the temperature is asked whether it fits the drift as well as a smooth trend (degree TREND_DEGREE) does
    smooth_n_eff, smooth_sse = n_eff, sse1
    if degree != TREND_DEGREE:
        smooth_n_eff, smooth_sse = [_effective_n(left[:, j]) for j in range(3)], np.sum(left ** 2, axis=0)
    radial = float(np.sqrt(np.mean(trend[:, 0] ** 2)))
    across = float(np.sqrt(np.mean(np.sum(trend[:, 1:] ** 2, axis=1))))
    ratio = across / radial if radial > 0 else np.inf
    out: dict = {"radial_trend_rms_nT": radial, "across_trend_rms_nT": across, "across_over_radial": float(ratio),
                 "radial_p": p_radial, "across_p": p_across, "trend_degree": degree, "named": None}
    follows = temperature_follows_time(tk, None if temp is None else temp[keep])
    if follows is not None:
        out["temperature_follows_time_r2"] = follows
    across_drift = p_across < DRIFT_DIRECTION_ALPHA and ratio >= ACROSS_MIN_RATIO
    radial_drift = p_radial < DRIFT_DIRECTION_ALPHA and ratio <= RADIAL_MAX_RATIO
    if turning > 0:
        out["field_turning_nT"] = turning
    turned = across_drift and across <= turning  # the trend across is the field's own turning
    if turned:
        out["why"] = (f"the readings turn across their own direction (RMS {across:.3g} nT) no more than the field's own "
                      f"turning gives: the reference varies (RMS {turning / TURN_FACTOR:.3g} nT), so the field changes, "
                      "and a changing field turns by about as much; a scalar reference follows no direction, so a "
                      "drift of the offsets beneath it cannot be told without a vector reference")
        if p_radial >= DRIFT_DIRECTION_ALPHA or radial < REFERENCE_FOLLOW_SHARE * turning / TURN_FACTOR:
            return out
    if not (across_drift or radial_drift):
        out["why"] = ("no significant drift" if min(p_radial, p_across) >= DRIFT_DIRECTION_ALPHA else
                      "the drift is neither along the readings' direction nor clearly across it")
        return out
    # the magnitude beyond the reference's: with the trend across the field's own turning, only the radial trend
    # (what the reference's variation does not follow) is the sensor's or the field's own drift
    cols = [0] if radial_drift or turned else [0, 1, 2]
    sse_trend = float(sse1[cols].sum())
    sse_const = float(sse0[cols].sum())
    sse_step = _step_sse(y[:, cols])
    out["step_share"] = float((sse_const - sse_step) / max(sse_const - sse_trend, 1e-300))
    if sse_const - sse_step >= STEP_SHARE * (sse_const - sse_trend):
        out["why"] = ("a single step explains the drift as well as a smooth change: a field switched on near the "
                      "sensor (outside the library), not a drift")
        return out
    p_beats = None  # whether the smooth trend beats the logged temperature (through a first-order lag) on ``cols``
    if temp is not None and np.ptp(temp) > 0:
        best = np.inf
        for share in THERMAL_LAG_OF_SPAN:
            lagged = first_order_lag(tk, temp[keep], share * span) if share > 0 else temp[keep]
            d2 = np.column_stack([np.ones(n), lagged])
            best = min(best, float(np.sum((y[:, cols] - d2 @ np.linalg.lstsq(d2, y[:, cols], rcond=None)[0]) ** 2)))
        p_beats = _f_p(best, float(smooth_sse[cols].sum()), len(cols) * (TREND_DEGREE - 1),
                       float(np.mean([smooth_n_eff[j] for j in cols])) * len(cols), len(cols) * (TREND_DEGREE + 1))
        out["trend_beats_temperature_p"] = p_beats
        out["temperature_share_of_trend"] = float((sse_const - best) / max(sse_const - sse_trend, 1e-300))
    # the temperature fits the smooth trend as well, and takes most of what the drift's own trend takes (a drift
    # faster than the smooth trend is not its shape)
    fits = (p_beats is not None and p_beats >= DRIFT_DIRECTION_ALPHA
            and out["temperature_share_of_trend"] >= THERMAL_SHARE_OF_TREND)
    if across_drift:
        # a temperature that follows time is an alternative only for the part of the drift it can take: a drift whose
        # shape the temperature does not have (a pulsation beside a warming) is not a temperature coefficient's
        follows_time = (follows is not None and follows >= TEMPERATURE_FOLLOWS_TIME_R2
                        and out.get("temperature_share_of_trend", 0.0) >= THERMAL_SHARE_OF_TREND)
        thermal = follows_time or fits
        out["named"] = "offset_drift|temperature|field_drift" if thermal else "offset_drift|field_drift"
        out["why"] = ((f"the readings' magnitude drifts beyond the reference's (RMS {radial:.3g} nT along their "
                       f"direction, beyond what follows the reference), while they turn across it (RMS {across:.3g} nT) "
                       "no more than the field's own turning gives: the offsets drift (along the field), or the field's "
                       "magnitude here changes otherwise than the reference's" if turned else
                       f"the readings drift across their own direction (RMS {across:.3g} nT against {radial:.3g} nT "
                       "along it): the offsets drift") + (", or a temperature coefficient (the logged temperature "
                                                         "follows time)" if follows_time else
                                                         ", or a temperature coefficient (the logged temperature, through "
                                                         "a first-order lag, fits the drift as well)" if fits else "") +
                      ("" if turned else ", or the field's direction changes (a scalar reference follows no direction)"))
        return out
    out["named"] = "field_drift"
    out["why"] = (f"the readings drift along their own direction only (RMS {radial:.3g} nT, {across:.3g} nT across): "
                  "the field's magnitude changes")
    if fits:
        out["named"] = "field_drift|temperature"
        out["why"] += ("; the logged temperature fits it as well (the scale coefficients of the axes changing "
                       "together)")
    return out

"""The noise floor, estimated independently of the structured residual: from differences of samples
close in time (a smooth structured residual cancels in them), with its own interval.

* vector data with a time column (or rows in acquisition order): the robust scatter of the errors of
  linear interpolation between the time neighbours, r_i - (w r_(i-1) + (1 - w) r_(i+1)), scaled to white
  noise (the second differences / sqrt(6) on even sampling, exact for a line at any spacing); the errors
  of cubic interpolation from four neighbours check that structure does not leak into them;
* with the attitude changing fast between samples, the same from the residual of the fit with every effect
  free (``model_floor``): time neighbours are then not attitude neighbours and the base residual's
  interpolation errors carry the effects themselves;
* without any order the samples can be trusted in: the k-NN scatter in attitude, an upper bound (flagged).

The interval is +-1.96 standard errors of the MAD-based scale (1.166 sigma / sqrt(m), m the number of
independent differences, about n / 3 for overlapping second differences)."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from magbench.lightstats import normal_isf, one_pole_lowpass, spearman_rho
from magbench.numerics import MAD_TO_SIGMA, drift_columns, drift_degree, repeated_rows, residual_sum_of_squares, systematic_rows
from magbench.simulate.effects import SPIKE_SIGMA, Columns, f_test_p, robust_sigma

KNN_NEIGHBOURS = 6
MAD_SE = 1.166  # standard error of the MAD scale: 1.166 sigma / sqrt(m) for Gaussian data
INDEPENDENT_SHARE = 1.0 / 3.0  # overlapping second differences: about a third of them independent
LEAK_Z = 3.0

__all__ = ["KNN_NEIGHBOURS", "MOTION_Z", "attitude_floor", "knn_floor", "model_floor", "neighbour_z", "rail_rows",
           "robust_sigma",
           "second_difference_floor", "unit_span", "vector_floor",
           "time_difference_floor"]


def knn_floor(features: np.ndarray, r: np.ndarray, k: int = KNN_NEIGHBOURS) -> float:
    """Robust scatter of r_i about the mean of its k nearest neighbours in feature space, scaled by
    sqrt(k / (k + 1)) (the neighbours' mean carries noise too)."""
    k = min(k, len(r) - 1)
    return robust_sigma(_knn_errors(features, r, k)) * np.sqrt(k / (k + 1.0))


def _knn_errors(features: np.ndarray, r: np.ndarray, k: int) -> np.ndarray:
    """r_i minus the mean of its k nearest neighbours in feature space."""
    _, idx = cKDTree(features).query(features, k=k + 1)
    return r - r[idx[:, 1:]].mean(axis=1)


TIME_BLOCKS = (2, 3)
"""``attitude_floor`` also takes the attitude neighbours within each of these many consecutive blocks of time
(halves, thirds: a change over the middle third of a record mixes both sides in either half)."""


def drift_floor(r: np.ndarray, unit: np.ndarray, t_s: np.ndarray, n_free: int) -> float | None:
    """At random attitudes, the RMS of ``r`` left by a regression on Legendre polynomials of time of degree 0..D
    (``numerics.drift_degree``), alone and times each axis's
    direction cosine ``unit`` (the field's magnitude and the body's offsets drifting), scaled for the ``n_free``
    parameters of the fit that left ``r`` and the regression's columns.  A third upper bound of the noise: there a
    drift in time moves both the time neighbours' scatter and the attitude neighbours' with it (an offset
    oscillating 3 times over sphere9, 150 nT, left a floor of 50 nT and a verdict of ``none``), while random
    attitudes make it easy to fit.  None when too short."""
    m = len(r)
    degree = drift_degree(m)
    if degree < 1 or not np.ptp(t_s) > 0:
        return None
    design = drift_columns(t_s, unit, degree)  # degree 0 too: r need not have a zero mean
    dof = m - n_free - design.shape[1]
    if dof < 10:
        return None
    return float(np.sqrt(residual_sum_of_squares(design, r, rcond=1e-10) / dof))


def lowest_blocked_knn_floor(features: np.ndarray, r: np.ndarray, t_s: np.ndarray) -> tuple[float, int] | None:
    """The lowest ``blocked_knn_floor`` over the block counts of TIME_BLOCKS, with its count (None when no count
    leaves its blocks long enough)."""
    found = [(f, b) for b in TIME_BLOCKS if (f := blocked_knn_floor(features, r, t_s, b)) is not None]
    return min(found, key=lambda fb: fb[0]) if found else None


def blocked_knn_floor(features: np.ndarray, r: np.ndarray, t_s: np.ndarray, blocks: int = 2,
                      k: int = KNN_NEIGHBOURS) -> float | None:
    """``knn_floor`` with each sample's neighbours taken within its own block of time (``blocks`` consecutive
    blocks of equal counts): structure that is a smooth function of the attitude within each block but differs
    between them (an axis swapped or a sensor remounted mid-record, a body field switched on) cancels here and not
    in ``knn_floor``, whose neighbours come from either block.  None when a block has too few samples."""
    n = len(r)
    if n < blocks * 10 * k:
        return None
    order = np.argsort(t_s, kind="stable")
    errors = [_knn_errors(features[part], r[part], k) for part in np.array_split(order, blocks)]
    return float(robust_sigma(np.concatenate(errors)) * np.sqrt(k / (k + 1.0)))


def unit_span(v: np.ndarray | None) -> np.ndarray | None:
    """``v`` mapped onto [0, 1] (None when absent, constant or not finite everywhere)."""
    if v is None or not np.all(np.isfinite(v)) or np.ptp(v) <= 0:  # a rate over repeated times is infinite: no span
        return None
    return (v - v.min()) / np.ptp(v)


def _interval(sigma: float, m: int) -> tuple[float, float, float]:
    se = MAD_SE * sigma / np.sqrt(max(m, 1))
    return se, max(sigma - 1.96 * se, 0.0), sigma + 1.96 * se


def _interpolation_errors(r: np.ndarray, t: np.ndarray | None, order: int) -> np.ndarray:
    """r_i minus its Lagrange interpolation at t_i from its neighbours in time order (order 1: i-1 and i+1,
    exact for a line; order 3: i-2, i-1, i+1, i+2, exact for a cubic), divided by sqrt(1 + sum of squared
    weights) so that white noise of sigma gives sigma.  On even sampling order 1 is the classical second
    difference / 2; on irregular sampling it still cancels a smooth structure, which the plain second
    difference (built for even spacing) leaks into the floor in proportion to the spacing's unevenness."""
    n = len(r)
    t = np.arange(n, dtype=float) if t is None else t + np.arange(n) * 1e-9 * max(float(np.ptp(t)), 1.0)
    offs = (-1, 1) if order == 1 else (-2, -1, 1, 2)
    lo, hi = -min(offs), n - max(offs)
    if hi - lo < 1:
        return np.zeros(0)
    i = np.arange(lo, hi)
    nodes = [t[i + o] for o in offs]
    weights = []
    with np.errstate(divide="ignore", invalid="ignore"):  # times tied at the float resolution (1e9 s + 1e-7 s steps)
        for a, ta in enumerate(nodes):
            w = np.ones(len(i))
            for b, tb in enumerate(nodes):
                if a != b:
                    w = w * (t[i] - tb) / (ta - tb)
            weights.append(w)
        pred = sum(w * r[i + o] for w, o in zip(weights, offs))
        return (r[i] - pred) / np.sqrt(1.0 + sum(w * w for w in weights))


def time_difference_floor(r_in_order: np.ndarray, t_in_order: np.ndarray | None = None, grid: bool = False) -> dict:
    """Floor from the errors of linear interpolation between time neighbours (``_interpolation_errors``;
    the second differences on even sampling), checked against cubic interpolation from four neighbours;
    errors that touch a spike (a sample beyond SPIKE_SIGMA robust sigma) are left out, since each spike
    would otherwise inflate three (five) of them.  Their scale is the median absolute deviation, or with
    ``grid`` (readings on a grid coarser than their noise: a fixed sensor below its resolution) their trimmed RMS
    (``grid_sigma``): the errors then take a few lattice values, whose median absolute deviation falls to a
    fraction of the spread."""
    n = len(r_in_order)
    spread = float(np.std(r_in_order)) if grid else robust_sigma(r_in_order)  # a grid's MAD can be 0
    spk = np.abs(r_in_order - np.median(r_in_order)) > SPIKE_SIGMA * spread
    e1 = _interpolation_errors(r_in_order, t_in_order, 1)
    e3 = _interpolation_errors(r_in_order, t_in_order, 3)
    if spk.any() and (~spk).sum() > 10:
        touch1 = np.convolve(spk, np.ones(3), mode="valid") > 0
        touch3 = np.convolve(spk, np.ones(5), mode="valid") > 0
        e1, e3 = e1[~touch1], e3[~touch3]
        n = int((~spk).sum())
    scale = grid_sigma if grid else robust_sigma
    s1 = scale(e1)
    s3 = scale(e3) if len(e3) else s1
    leak = bool(s1 - s3 > LEAK_Z * _interval(s1, int(INDEPENDENT_SHARE * n))[0])  # structure inflates s1
    sigma = min(s1, s3) if leak else s1
    se, lo, hi = _interval(sigma, int(INDEPENDENT_SHARE * n))
    method = ("cubic interpolation from four time neighbours (the two-neighbour one carries structure)" if leak else
              "linear interpolation between time neighbours (second differences on even sampling)")
    return {"noise_floor_nT": float(sigma), "floor_se_nT": float(se), "floor_interval_nT": [float(lo), float(hi)],
            "floor_method": method + (", their trimmed RMS (readings on a grid coarser than their noise)" if grid else ""),
            "floor_is_upper_bound": False,
            "floor_second_diff_nT": float(s1), "floor_third_diff_nT": float(s3)}


HELD_MIN_FRACTION = 0.02
"""A record in which more than this share of consecutive rows repeat the previous reading exactly (a logger
that holds its last value) has its floor computed on the distinct samples only: a held sample interpolates
perfectly from its twin and would pull the floor down."""


def held_samples(raw_nT: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Mask (in the record's rows) of readings identical to the previous one in time order."""
    return repeated_rows(raw_nT, order)


def consecutive_repeats(raw_nT: np.ndarray, order: np.ndarray) -> tuple[np.ndarray, bool, bool]:
    """``held_samples`` (the mask, in the record's rows) and ``repeats`` (grid, logger) of the readings in time
    order ``order``, from one comparison of each reading with the one before it."""
    held, same, whole = _repeat_masks(raw_nT, order)
    return (held, *_repeats_of(same, whole))


def _repeat_masks(raw_nT: np.ndarray, order: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(held: the mask in the record's rows; same: (n - 1, 3), each axis equal to its previous reading in time
    order; whole: all three)."""
    x = raw_nT[order]
    same = x[1:] == x[:-1]
    whole = np.all(same, axis=1)
    held = np.zeros(len(x), dtype=bool)
    held[order[1:]] = whole
    return held, same, whole


STALE_MIN_DISTINCT = 30
"""``stale_copies`` finds them only when at least this many distinct rows remain."""
AXIS_REPEAT_MAX = 0.01
"""... and only when no axis repeats its previous value on its own (in the rows that do not repeat whole) more
than this share of the time: continuous readings, in which an exact repeat of all three axes is the logger's.  On
the independent generators' records, a logger's holds on continuous readings give at most 0.9 %; readings rounded
to a grid step near the noise at a turntable's pauses, 14 to 40 %."""


def stale_copies(raw_nT: np.ndarray, order: np.ndarray) -> np.ndarray | None:
    """The rows a logger held (``consecutive_repeats``) in continuous readings (AXIS_REPEAT_MAX), with at least
    STALE_MIN_DISTINCT distinct rows left: a mask in the record's rows, else None.  On a grid coarser than the noise,
    at held attitudes, three axes can repeat together and such a row is a reading."""
    held, same, whole = _repeat_masks(raw_nT, order)
    if not _repeats_of(same, whole)[1] or int((~held).sum()) < STALE_MIN_DISTINCT:
        return None
    return None if _own_rates(same, whole).max() > AXIS_REPEAT_MAX else held


RAIL_MIN_ROWS = 3
"""``rail_rows`` finds an axis clipped at a converter's rail when at least this many readings sit exactly at its
largest or smallest value ..."""
RAIL_OVER_ANY_VALUE = 3
"""... at least this many times as many as share any other single value of that axis (on a grid coarser than the
noise every value repeats; a rail piles the readings up at one) ..."""
RAIL_SPREAD_OF_FIELD = 0.005
"""... and with the other two axes spread over more than this share of the field among those rows: readings at
many attitudes stopped at one value, not one attitude held at an extreme."""


def rail_rows(raw_nT: np.ndarray) -> tuple[np.ndarray, list[dict]] | None:
    """The readings clipped at a converter's rail: for each axis and side, the rows whose reading equals exactly
    that axis's largest (smallest) value, when RAIL_MIN_ROWS or more do, RAIL_OVER_ANY_VALUE times as many as share
    any other value of the axis, at attitudes whose other axes spread over RAIL_SPREAD_OF_FIELD of the field; and
    then the readings of any axis at exactly such a level or its negative (the same converter range: two rows of x
    at the level of z's rail had been left in, and named ``outliers``).  A
    continuous reading takes its extreme value once; a converter that saturates returns it for every attitude
    beyond its range, and those readings say only that the field there was beyond it.  Stricter than
    ``simulate.effects.clipped`` (three repeats of an extreme, which refuses spikes that are clipped readings as
    outliers): a grid's or a held attitude's repeats are no rail here, since these rows leave the whole diagnosis.
    Returns (a mask of the rows with any axis at a rail, one dict per rail: axis, side, level_nT, rows), or None."""
    raw = np.asarray(raw_nT, dtype=float)
    n = raw.shape[0]
    if n < 2 * RAIL_MIN_ROWS:
        return None
    field = float(np.median(np.linalg.norm(raw, axis=1))) or 1.0
    mask = np.zeros(n, dtype=bool)
    rails: list[dict] = []
    for a in range(3):
        col = raw[:, a]
        values, counts = np.unique(col, return_counts=True)
        if len(values) < 3:
            continue
        for side, idx in (("high", len(values) - 1), ("low", 0)):
            k = int(counts[idx])
            others = counts[1:-1]  # the values between the two extremes (either may be a rail)
            if k < RAIL_MIN_ROWS or k < RAIL_OVER_ANY_VALUE * int(others.max()):
                continue
            rows = col == values[idx]
            rest = np.delete(raw[rows], a, axis=1)
            if float(np.ptp(rest, axis=0).max()) <= RAIL_SPREAD_OF_FIELD * field:
                continue
            mask |= rows
            rails.append({"axis": "xyz"[a], "side": side, "level_nT": float(values[idx]), "rows": k})
    for level in sorted({abs(r["level_nT"]) for r in rails}):  # one converter's range: another axis at that rail is clipped too
        for a in range(3):
            for value in (level, -level):
                rows = raw[:, a] == value
                k = int(rows.sum())
                if k and not any(r["axis"] == "xyz"[a] and r["level_nT"] == value for r in rails):
                    mask |= rows
                    rails.append({"axis": "xyz"[a], "side": "high" if value > 0 else "low", "level_nT": value,
                                  "rows": k})
    return (mask, rails) if rails else None


GRID_TRIM = 0.9
GRID_TRIM_FACTOR = 0.7893
"""On a grid the floor is the RMS of the central GRID_TRIM of the interpolation errors (by size), divided by
GRID_TRIM_FACTOR, that RMS for unit Gaussian errors (sqrt(1 - 2 z phi(z) / 0.9), z = 1.645): unlike the median
absolute deviation it does not collapse on lattice values, and unlike the plain RMS it leaves out the few large
errors where held attitudes change (a turntable stepping between pauses)."""


def grid_sigma(e: np.ndarray) -> float:
    """The Gaussian sigma of errors ``e`` on a grid (GRID_TRIM): the RMS of the smallest GRID_TRIM of them by size,
    ties at the cut included as a share, over GRID_TRIM_FACTOR; 0 for no errors."""
    if not len(e):
        return 0.0
    sq = np.sort(e * e)
    k = GRID_TRIM * len(sq)
    whole = int(k)
    total = float(np.sum(sq[:whole])) + (k - whole) * (float(sq[whole]) if whole < len(sq) else 0.0)
    return float(np.sqrt(total / k)) / GRID_TRIM_FACTOR


GRID_REPEAT_SHARE = 0.25
"""An axis whose reading equals the previous one this often is read on a grid coarser than its noise (a fixed
sensor, or held attitudes, below the resolution; continuous readings of a turning sensor never repeat exactly)."""


def repeats(x: np.ndarray) -> tuple[bool, bool]:
    """(grid, logger) for readings ``x`` (n, 3) in time order: whether whole rows repeat (more than
    HELD_MIN_FRACTION of them) more than twice as often as the axes' own repeats together give (a logger holding
    its last reading, rather than three axes rounding to their previous values at once), and whether an axis
    repeats its previous value on its own more than GRID_REPEAT_SHARE of the time (a resolution coarser than the
    noise).  The axes' own rates come from the rows that do not repeat whole, so that a logger's holds on a coarse
    grid are told from the grid alone."""
    return consecutive_repeats(x, np.arange(len(x)))[1:]


def _own_rates(same: np.ndarray, whole: np.ndarray) -> np.ndarray:
    """Each axis's rate of repeating its previous value in the rows that do not repeat whole (some must not)."""
    return same[~whole].mean(axis=0)


def _repeats_of(same: np.ndarray, whole: np.ndarray) -> tuple[bool, bool]:
    """``repeats`` from ``same`` (n - 1, 3), each axis equal to its previous reading, and ``whole`` (all three)."""
    if not len(whole):
        return False, False
    rows = float(whole.mean())
    if not (~whole).any():
        return True, rows > HELD_MIN_FRACTION
    # the axes' own repeat rates q_i, from the rows that do not repeat whole (a logger's holds are all among those
    # that do): there an axis repeats with (q_i - P) / (1 - P), P = prod(q_i) the whole-row rate the axes give alone
    part = _own_rates(same, whole)
    alone = 0.0
    for _ in range(200):  # the smallest fixed point of P = prod(part (1 - P) + P), approached from below
        step = float(np.prod(part * (1.0 - alone) + alone))
        settled = step - alone <= 1e-12
        alone = step
        if settled:
            break
    logger = bool(rows > HELD_MIN_FRACTION and rows > 2 * alone)
    own = part * (1.0 - alone) + alone
    return bool(own.max() > GRID_REPEAT_SHARE), logger


def vector_floor(unit: np.ndarray, d: Columns, r: np.ndarray, rows_in_time_order: bool = False) -> dict:
    """The floor of a vector record (module docstring); held samples (exact repeats of the previous reading)
    are left out when a logger held them (``repeats``), and their share is reported; readings on a grid coarser
    than their noise take the interpolation errors' trimmed RMS (``time_difference_floor``, ``grid_sigma``)."""
    n = len(r)
    if d.t_s is not None and np.ptp(d.t_s) > 0:
        order = np.argsort(d.t_s, kind="stable")
        held, grid, logger = consecutive_repeats(d.raw_nT, order)  # held attitudes below the resolution: no logger
        share = float(held.mean())
        if logger and (~held).sum() >= 10:
            keep = order[~held[order]]
            out = time_difference_floor(r[keep], d.t_s[keep], grid=grid)
            out["floor_method"] += f" (on the {int((~held).sum())} distinct samples: {100 * share:.1f} % held)"
        else:
            out = time_difference_floor(r[order], d.t_s[order], grid=grid)
        out["held_sample_fraction"] = share
        return out
    if rows_in_time_order:
        out = time_difference_floor(r)
        out["floor_method"] += " (row order taken as time order)"
        return out
    sigma = knn_floor(unit, r)
    method = "nearest neighbours in attitude (no time order: an upper bound, structure included)"
    # the rows in file order stand in for time (the acceptance checks do the same): a sensor changed between parts of
    # the file, or drifting along it, cancels within its halves or thirds, or in a drift's fit (sphere9 with z's sign
    # flipped halfway and no t column was 'none' with 200 nT of residual against a 182 nT floor)
    rows = np.arange(n, dtype=float)
    blocked = lowest_blocked_knn_floor(unit, r, rows)
    if blocked is not None and blocked[0] < sigma:
        sigma, method = blocked[0], (f"nearest neighbours in attitude within each of {blocked[1]} blocks of the rows in "
                                     "file order (no time column: an upper bound, structure included)")
    drift = drift_floor(r, unit, rows, 9)  # r: the base fit's residual, at most nine parameters
    if drift is not None and drift < sigma:
        sigma, method = drift, ("RMS left by drifts along the rows in file order (no time column: an upper bound, "
                                "structure included)")
    se, lo, hi = _interval(sigma, n)
    return {"noise_floor_nT": float(sigma), "floor_se_nT": float(se), "floor_interval_nT": [float(lo), float(hi)],
            "floor_method": method, "floor_is_upper_bound": True}


def _second_differences(r_in_order: np.ndarray) -> np.ndarray:
    """r_i - (r_{i-1} + r_{i+1}) / 2 along the last axis."""
    return r_in_order[..., 1:-1] - 0.5 * (r_in_order[..., :-2] + r_in_order[..., 2:])


def second_difference_floor(r_in_order: np.ndarray) -> float:
    """The floor of a series from its second differences r_i - (r_{i-1} + r_{i+1}) / 2, robustly."""
    return robust_sigma(_second_differences(r_in_order)) / np.sqrt(1.5)


def second_difference_floors(rows_in_order: np.ndarray) -> np.ndarray:
    """``second_difference_floor`` of each row of a (k, n) array in one pass (the same MAD, by numpy's median along
    the rows: the scalar diagnosis's null draws)."""
    d2 = _second_differences(rows_in_order)
    return MAD_TO_SIGMA * np.median(np.abs(d2 - np.median(d2, axis=1, keepdims=True)), axis=1) / np.sqrt(1.5)


MOTION_Z = LEAK_Z
"""The residual of the fit with every effect free is taken as noise only when the size of its samples does not
follow how far the readings moved from their time neighbours (Spearman, |z| at most this) and it does not depend
on the neighbouring readings (``neighbour_z``): a reading mixed with a
neighbouring sample (a lag at random attitudes) leaves a residual that does, and no fit of the library removes it."""


MEMORY_SAMPLES = (4.0, 16.0)
"""Time constants (in samples) of the running means of the past readings ``neighbour_z`` also tests."""


NEIGHBOUR_ROWS = 50_000
"""``neighbour_z`` fits on a systematic sample of at most this many rows (in time order)."""


def neighbour_z(r: np.ndarray, raw_nT: np.ndarray) -> float:
    """How far the residual ``r`` (in time order) depends on the neighbouring readings: the F test of ``r`` on the
    products of the reading's direction with the previous and the next reading and of each neighbour with itself
    (the second-order terms of a mix of a reading with its neighbours) and of the reading's direction with running
    means of the past readings (MEMORY_SAMPLES: a field induced with a lag; 48 columns), as a one-sided z.  A
    reading mixed with its neighbours (a lag, an induced field that lags, at random attitudes) leaves such a
    dependence; noise does not.  The current reading enters by its direction only: its own noise along the field is
    the residual's noise, and products of the reading itself with a neighbour carry that noise linearly, so that
    where consecutive readings are related but not equal (a walker's gait) they reproduced a clean record's noise
    (z 19-37 on the fourth independent generator's clean pedestrians); the direction carries only the noise across
    the field, which is independent of the residual's."""
    n = len(r)
    if n < 60:
        return 0.0
    scale = float(np.median(np.linalg.norm(raw_nT, axis=1))) or 1.0
    idx = np.arange(1, n - 1)[systematic_rows(n - 2, NEIGHBOUR_ROWS)]
    here, prev, nxt = raw_nT[idx] / scale, raw_nT[idx - 1] / scale, raw_nT[idx + 1] / scale
    cur = here / np.maximum(np.linalg.norm(here, axis=1), 1e-12)[:, None]
    cols = [np.ones(len(idx))] + [cur[:, a] * nb[:, b] for nb in (prev, nxt) for a in range(3) for b in range(3)]
    cols += [nb[:, a] * nb[:, b] for nb in (prev, nxt) for a in range(3) for b in range(a, 3)]
    for tau in MEMORY_SAMPLES:  # where the sensor pointed over the last samples (a field induced with a lag)
        w = np.exp(-1.0 / tau)
        past = one_pole_lowpass(raw_nT, w)[idx] / scale  # w past[i-1] + (1 - w) x[i-1]
        cols += [cur[:, a] * past[:, b] for a in range(3) for b in range(3)]
    design = np.column_stack(cols)
    y = r[idx]
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    rss1 = float(np.sum((y - design @ coef) ** 2))
    rss0 = float(np.sum((y - y.mean()) ** 2))
    q, dof = design.shape[1] - 1, len(y) - design.shape[1]
    if rss1 <= 0 or dof <= 0:
        return 0.0
    return normal_isf(max(f_test_p(rss0, rss1, q, dof), 1e-300))


ALLAN_MIN_WINDOWS = 8
"""The longest averaging window of ``noise_spectrum`` leaves at least this many windows (its Allan deviation then
has a relative standard error of about 0.27)."""
FLICKER_SLOPES = (-0.25, 0.15)
"""The log-log slope of the Allan deviation over the three longest windows that counts as level (1/f noise's is 0,
white noise's -1/2, a linear drift's +1)."""
NON_WHITE_EXCESS = 2.0
"""The residual averaged over the longest window is called non-white when its Allan deviation is more than this
many times what white noise of the one-sample deviation gives there."""


def noise_spectrum(r: np.ndarray) -> dict:
    """How the residual ``r`` (in time order) averages down: its Allan deviation over windows of 1, 2, 4, ...
    samples (non-overlapping means; at least ALLAN_MIN_WINDOWS windows), against white noise's 1/sqrt(m) from the
    one-sample value.  White noise keeps the ratio at 1 (slope -1/2 in log-log); 1/f noise flattens (slope 0) and a
    drift or other slow structure rises.  The floor is the white part: this says whether slow wander of the size
    seen over long windows is what the noise itself does."""
    r = np.asarray(r, dtype=float)
    n = len(r)
    sizes, adev = [], []
    m = 1
    while n // m >= ALLAN_MIN_WINDOWS:
        k = n // m
        means = r[:k * m].reshape(k, m).mean(axis=1)
        sizes.append(m)
        adev.append(float(np.sqrt(0.5 * np.mean(np.diff(means) ** 2))))
        m *= 2
    if len(sizes) < 3 or adev[0] <= 0:
        return {"kind": "too short", "averaging_samples": sizes, "allan_deviation_nT": adev}
    white = adev[0] / np.sqrt(np.asarray(sizes, dtype=float))
    # the slope over the three longest windows, where the slow part shows (at short ones the white part rules)
    slope = float(np.polyfit(np.log(sizes[-3:]), np.log(np.maximum(adev[-3:], 1e-300)), 1)[0])
    excess = float(adev[-1] / white[-1])
    if excess <= NON_WHITE_EXCESS:
        kind, statement = "white", "it averages down like white noise: the floor describes it at every time scale"
    else:
        if slope > FLICKER_SLOPES[1]:
            kind, meaning = "wander (a drift or slow structure)", "it grows over the longest windows"
        elif slope >= FLICKER_SLOPES[0]:
            kind, meaning = "flicker (1/f)", ("it stays level over the longest windows: slow wander of this size is "
                                              "what 1/f noise does, not a drift")
        else:
            kind, meaning = "correlated at shorter time scales", ("it averages down over the longest windows but from "
                                                                 "above white noise: a periodic or coloured component")
        statement = (f"over {sizes[-1]} samples it averages to {adev[-1]:.3g} nT, {excess:.3g} times white noise's "
                     f"{white[-1]:.3g} nT (log-log slope over the longest windows {slope:.2f}; white -0.5, 1/f 0): "
                     f"{meaning}; the floor is its white part")
    return {"kind": kind, "averaging_samples": sizes, "allan_deviation_nT": adev,
            "white_allan_deviation_nT": [float(w) for w in white], "log_slope": slope,
            "excess_at_longest": excess, "statement": statement}


def model_floor(fl: dict, r_model: np.ndarray, t_s: np.ndarray, raw_nT: np.ndarray, n_free: int,
                spikes: np.ndarray) -> dict:
    """The floor ``fl`` (``vector_floor``, from the base residual) again from the residual ``r_model`` of the fit
    with every testable effect free (``n_free`` parameters), spikes and held samples left out, scaled by
    sqrt(n / (n - n_free)) for the parameters fitted.  When the attitude changes between samples as much as it
    does over the record (random attitudes), the time neighbours of a sample are not its neighbours in attitude and
    every effect tied to the attitude (temperature through the offsets, a nonlinearity) stays in the base
    residual's interpolation errors: the floor is then many times the noise and hides every effect.  The model's
    floor replaces it when it is lower by more than LEAK_Z standard errors and its samples' size does not follow
    the motion between samples nor depends on the neighbouring readings (``neighbour_z``, both at most MOTION_Z):
    a reading mixed with its neighbours leaves structure no library fit removes and no time difference cancels at
    random attitudes; outside-library structure the model cannot fit otherwise stays in both floors."""
    order = np.argsort(t_s, kind="stable")
    held, grid, logger = consecutive_repeats(raw_nT, order)
    drop = spikes | held if logger else spikes
    keep = order[~drop[order]]
    n = len(keep)
    if n - n_free < 10:
        return fl
    rk = r_model[keep]
    step = np.linalg.norm(np.diff(raw_nT[keep], axis=0), axis=1)
    jump = np.zeros(n)
    jump[1:] += step
    jump[:-1] += step
    rho = spearman_rho(np.abs(rk - np.median(rk)), jump)
    out = dict(fl)
    out["floor_motion_z"] = float(rho * np.sqrt(n - 1)) if np.isfinite(rho) else 0.0
    out["floor_neighbour_z"] = neighbour_z(rk, raw_nT[keep])
    alt = time_difference_floor(rk, t_s[keep], grid=grid)
    scale = float(np.sqrt(n / (n - n_free)))
    sigma, se = alt["noise_floor_nT"] * scale, alt["floor_se_nT"] * scale
    out["floor_model_nT"] = float(sigma)
    out["noise_spectrum"] = noise_spectrum(rk)  # what the fit with every effect free leaves, over time scales
    follows = abs(out["floor_motion_z"]) > MOTION_Z or out["floor_neighbour_z"] > MOTION_Z
    if follows or fl["noise_floor_nT"] - sigma <= LEAK_Z * np.hypot(fl["floor_se_nT"], se):
        return out
    out.update({"noise_floor_nT": float(sigma), "floor_se_nT": float(se),
                "floor_interval_nT": [float(max(sigma - 1.96 * se, 0.0)), float(sigma + 1.96 * se)],
                "floor_method": "interpolation between time neighbours of the residual of the fit with every effect free "
                                f"(the base residual's, {fl['noise_floor_nT']:.3g} nT, carries attitude structure)"})
    return out


ATTITUDE_FLOOR_ROWS = 50_000
"""``attitude_floor`` reads a systematic sample of at most this many rows (its neighbours then a little farther
apart, so the estimate stays an upper bound; the k-d tree of a million rows in six dimensions is not needed)."""


def attitude_floor(fl: dict, r_model: np.ndarray, unit: np.ndarray, gravity: np.ndarray | None, n_free: int,
                   spikes: np.ndarray, t_s: np.ndarray | None = None) -> dict:
    """The floor ``fl`` again from neighbours in attitude, for records whose consecutive attitudes are unrelated
    (random attitudes), where time neighbours cancel nothing that depends on the attitude: the scatter of the
    residual ``r_model`` of the fit with every effect free (spikes left out) about the mean of its KNN_NEIGHBOURS
    nearest neighbours in attitude (the unit field direction, and the unit gravity direction when an accelerometer
    gives it: the two fix the attitude), scaled by sqrt(n / (n - n_free)).  Structure that is a smooth function
    of the attitude (a body field that follows gravity or heading, a gradient seen through a lever arm) cancels
    between attitude neighbours; at random attitudes it does not cancel between time neighbours and the time
    floor holds it, so that no remainder is ever seen.  With times, the neighbours are also taken within each of
    TIME_BLOCKS blocks of time (``blocked_knn_floor``) and the lower scatter kept: structure that depends on the
    attitude differently before and after a change of the sensor (axes swapped halfway: 578 nT of scatter over the
    whole record, 183 nT within the halves, 537 nT of residual) cancels only there; and the RMS a drift in time leaves
    (``drift_floor``), which moves both neighbours' scatter at random attitudes.  It replaces the floor when
    lower by more than LEAK_Z standard errors (both estimates are upper bounds of the noise: structure on scales
    below the neighbour spacing stays in either); its standard error counts a third of the samples as independent, as for the
    overlapping time differences.  Not when the residual follows the motion or the neighbouring readings
    (``model_floor``'s tests): a reading mixed with its neighbours is no function of the attitude, and its square
    would pass for a nonlinearity against a floor that no longer holds it."""
    keep = ~spikes
    n = int(keep.sum())
    follows = abs(fl.get("floor_motion_z", 0.0)) > MOTION_Z or fl.get("floor_neighbour_z", 0.0) > MOTION_Z
    if follows or n - n_free < 10 * KNN_NEIGHBOURS:  # a reading mixed with its neighbours: no attitude fits it
        return fl
    rows = np.flatnonzero(keep)[systematic_rows(n, ATTITUDE_FLOOR_ROWS)]
    feats = [unit[rows]]
    if gravity is not None:
        g = np.asarray(gravity, dtype=float)[rows]
        norm_g = np.linalg.norm(g, axis=1, keepdims=True)
        if np.all(np.isfinite(g)) and np.all(norm_g > 0):
            feats.append(g / norm_g)
    features = np.column_stack(feats)
    inflate = float(np.sqrt(n / (n - n_free)))
    sigma = knn_floor(features, r_model[rows]) * inflate
    where = ""
    se_count = int(INDEPENDENT_SHARE * len(rows))
    drift = None
    if t_s is not None:
        t_rows = np.asarray(t_s, dtype=float)[rows]
        blocked = lowest_blocked_knn_floor(features, r_model[rows], t_rows)
        if blocked is not None and blocked[0] * inflate < sigma:
            sigma, where = blocked[0] * inflate, f" within each of {blocked[1]} blocks of time"
        drift = drift_floor(r_model[rows], unit[rows], t_rows, n_free)
    out = dict(fl)
    out["floor_attitude_nT"] = float(sigma)
    method = (f"scatter about the {KNN_NEIGHBOURS} nearest neighbours in attitude{where}"
              f"{' (field and gravity directions)' if len(feats) > 1 else ' (field direction)'} of the residual of the "
              f"fit with every effect free (random attitudes: the time floor, {fl['noise_floor_nT']:.3g} nT, holds "
              "structure that depends on the attitude)")
    if drift is not None:
        out["floor_drift_nT"] = drift
        if drift < sigma:  # a regression's residual: every sample counts
            sigma, se_count = drift, len(rows)
            method = ("RMS left by drifts in time (Legendre polynomials of time, alone and times each axis's direction "
                      "cosine) of the residual of the fit with every effect free (random attitudes: the time floor, "
                      f"{fl['noise_floor_nT']:.3g} nT, and the scatter about the nearest attitudes hold a drift in time)")
    se = _interval(sigma, se_count)[0]
    if fl["noise_floor_nT"] - sigma <= LEAK_Z * np.hypot(fl["floor_se_nT"], se):
        return out
    out.update({"noise_floor_nT": float(sigma), "floor_se_nT": float(se),
                "floor_interval_nT": [float(max(sigma - 1.96 * se, 0.0)), float(sigma + 1.96 * se)],
                "floor_method": method})
    return out

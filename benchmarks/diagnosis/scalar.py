"""The diagnosis of a scalar turntable series (seed 000's Table 2 style: total field per heading, after
the paper's calibration).  The residual is ``f_meas_after - f_ref`` (else ``f_meas - f_ref``).  Each
library effect with a first-order signature on a level turntable (``Effect.scalar_columns``: offset 1
cycle/rev, scale 2, nonlinearity 3 and 4, field_drift a cubic in time, i.e. heading order; outliers:
spikes beyond SPIKE_SIGMA robust sigma) is scored by leave-one-out cross-validation against a constant."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from magbench import paper
from magbench.calibrators.acceptance import GLITCH_FACTOR, MIN_REFERENCE_NT, reference_jumps, units_apart
from magbench.errors import InputError
from magbench.numerics import lone_values
from magbench.simulate.dataset import MAX_ABS_OTHER, ScalarSeries, temperature_problem
from magbench.simulate.effects import EFFECTS, OutlierEffect, library_effects
from magbench.simulate.sensor import paper_matrix

from .floor import second_difference_floor, second_difference_floors
from .localize import harmonics, heading_design
from .naming import FAMILY_ALPHA
from .scoring import MIN_SIGNIFICANT_SHRINK_PCT, Z_SIGNIFICANT, paired_z, rms, shrink_pct
from .timeonly import has_clock

MIN_HEADINGS = 12
HEADING_APART_DEG = 1.0
"""Headings are counted as different in steps of this width (0-1, 1-2, ... degrees): four headings taken three times each
at 0.001 degree apart had counted as 12 and been diagnosed, their floor 48 nT from the jumps between them, and a 40 nT
twice-per-turn error came back ``none``; the fourth harmonic changes by 4 degrees of phase within one step."""
MAX_HEADING_GAP_DEG = 90.0
"""The widest gap between neighbouring headings (around the circle) a scalar turntable series may leave: the 1..4
cycles-per-revolution harmonics the diagnosis separates are confounded over a wider one."""
TOGETHER = ("offset", "scale")  # the two first-order heading effects, also scored together
MIN_GAP_NT = 1e-9


@dataclass
class ScalarFit:
    """The residual of a scalar series with what the effects' scalar signatures are built from."""

    r: np.ndarray
    heading_rad: np.ndarray
    order: np.ndarray  # the samples in time order (row order without a time column)
    tau: np.ndarray  # the time order mapped onto [-1, 1]
    base_cv: np.ndarray | None = None  # leave-one-out residuals of a constant

    def loo(self, cols: list[np.ndarray]) -> np.ndarray:
        """Leave-one-out residuals of the linear model ``constant + cols``: e_i / (1 - h_ii)."""
        x = np.column_stack([np.ones(len(self.r))] + list(cols))
        pinv = np.linalg.pinv(x)  # (p, n): no n x n hat matrix
        h = np.einsum("ij,ji->i", x, pinv)  # leverages
        return (self.r - x @ (pinv @ self.r)) / (1.0 - h)


def scalar_residual(series: ScalarSeries) -> np.ndarray:
    """``f_meas_after - f_ref`` (the file's calibration), else ``f_meas - f_ref``."""
    after = series.extra.get("f_meas_after")
    f = np.asarray(after if after is not None else series.f_meas_nT, dtype=float)
    return f - np.asarray(series.f_ref_nT, dtype=float)


def together_columns(heading_rad: np.ndarray, tau=None) -> list[np.ndarray]:
    """The scalar signatures of the TOGETHER effects, side by side."""
    return [c for name in TOGETHER for c in EFFECTS[name].scalar_columns(heading_rad, tau)]


def series_problem(series: ScalarSeries) -> str | None:
    """Why a scalar series cannot be diagnosed as it is, or None: its columns one finite number per row (a reference
    given as one number is taken for every row), a positive reference, and measured magnitudes that fit it (a
    reference of 1 nT against 5e4 measured, or magnitudes in uT, had come back as an ``offset``, NaN as
    ``unexplained``)."""
    n = None
    for name in ("f_meas_nT", "heading_deg", "f_ref_nT", "t_s", "temp_C"):
        value = getattr(series, name)
        if value is None:
            continue
        if np.iscomplexobj(value):
            return f"{name} must be real numbers, got complex ones"
        try:
            a = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            return f"{name} must be numbers, got {type(value).__name__}"
        if name == "f_ref_nT" and a.ndim == 0:
            continue
        if a.ndim != 1:
            return f"{name} must be one value per row (a 1-D array), got shape {a.shape}"
        n = len(a) if n is None else n
        if len(a) != n:
            return f"{name} has {len(a)} values for {n} rows"
        bad = np.flatnonzero(~np.isfinite(a))
        if len(bad):
            return f"{name} is NaN or infinite in row(s) {', '.join(map(str, bad[:5]))}"
        if name in ("t_s", "temp_C", "heading_deg") and len(a) and float(np.max(np.abs(a))) > MAX_ABS_OTHER:
            return f"{name} has values beyond {MAX_ABS_OTHER:g} in magnitude: a broken column, not {name}"
        hot = temperature_problem(a) if name == "temp_C" else None
        if hot is not None:
            return f"temp_C in row {hot[0]} is {hot[1]}"
    extra = series.extra if isinstance(series.extra, dict) else {}
    measured = {"f_meas_nT": np.asarray(series.f_meas_nT, dtype=float)}
    for name in ("f_meas_before", "f_meas_after"):
        value = extra.get(name)
        if value is None:
            continue
        try:
            a = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            return f"{name} must be numbers, got {type(value).__name__}"
        if a.shape != (n,) or not np.all(np.isfinite(a)):
            return f"{name} must be one finite value per row"
        if name == "f_meas_before" and np.array_equal(a, measured["f_meas_nT"]):
            del measured["f_meas_nT"]  # the file's one column, read as both: checked once, under the file's name
        measured[name] = a
    for name, meas in measured.items():  # the contract's row checks, as on the readings of a vector record
        problem = _magnitude_rows(name, meas)
        if problem:
            return problem
    if series.f_ref_nT is None:
        return None
    ref = np.asarray(series.f_ref_nT, dtype=float)
    if np.any(ref <= 0):
        return "the reference magnitude must be positive on every row"
    if not float(np.median(ref)) >= MIN_REFERENCE_NT:
        return (f"the reference magnitude is {float(np.median(ref)):.4g} nT: no calibration field is below "
                f"{MIN_REFERENCE_NT:g} nT; f_meas_nT and f_ref_nT in another unit (uT?), or a wrong reference")
    # the reference's rows as a vector record's (a row 2000 times the others, a jump between rows: had been diagnosed,
    # a residual of 1.8e7 nT reported)
    rows = np.atleast_1d(ref)  # one value for every row, or one per row
    problem = _magnitude_rows("f_ref_nT", rows) or reference_jumps(rows, series.t_s if len(rows) > 1 else None)
    if problem:
        return problem
    for name, meas in measured.items():  # every measured column, the file's calibrated one too (the residual's)
        ratio = float(np.median(meas) / np.median(ref))
        if not SCALAR_RATIO_RANGE[0] <= ratio <= SCALAR_RATIO_RANGE[1]:
            return (f"the measured magnitude {name} (median {np.median(meas):.4g}) is {ratio:.3g} times the reference "
                    f"(median {np.median(ref):.6g} nT): " + (units_apart(ratio) or "wrong units (every magnitude "
                                                              "column is read in one unit, units=), or a wrong reference"))
        # row by row too: a row at 1/520 of the field (a dropout) had passed the 1/1000 glitch check and been diagnosed
        row_ref = np.broadcast_to(ref, meas.shape)
        row_ratio = meas / row_ref
        off = np.flatnonzero((row_ratio < SCALAR_RATIO_RANGE[0]) | (row_ratio > SCALAR_RATIO_RANGE[1]))
        if len(off):
            i = int(off[0])
            return (f"{name} in row(s) {', '.join(map(str, off[:5]))}{', ...' if len(off) > 5 else ''} is outside "
                    f"{SCALAR_RATIO_RANGE[0]:g}-{SCALAR_RATIO_RANGE[1]:g} times its reference (row {i}: {meas[i]:.4g} "
                    f"against {float(row_ref[i]):.6g} nT): no reading of this field (a dropout, a corrupt row); remove "
                    "those rows")
    return None


def _magnitude_rows(name: str, meas: np.ndarray) -> str | None:
    """Why a column of measured magnitudes has impossible rows, or None: a magnitude is positive, and a row more than
    GLITCH_FACTOR times the median one is no sensor's reading (docs/CONTRACT.md section 7: a corrupt row, named)."""
    if not len(meas):
        return None
    bad = np.flatnonzero(meas <= 0)
    if len(bad):
        return (f"{name} is {meas[bad[0]]:g} in row(s) {', '.join(map(str, bad[:5]))}{', ...' if len(bad) > 5 else ''}: "
                "a measured magnitude is positive (a missing value written as 0, or a signed component?)")
    middle = float(np.median(meas))
    tiny = np.flatnonzero(meas * GLITCH_FACTOR < middle)
    if len(tiny):
        return (f"{name} in row(s) {', '.join(map(str, tiny[:5]))}{', ...' if len(tiny) > 5 else ''} is less than "
                f"1/{GLITCH_FACTOR:g} of the median (row {int(tiny[0])}: {meas[tiny[0]]:.4g} against {middle:.4g} nT): "
                "no reading of this field (a dropout, a corrupt row); remove those rows")
    absurd = np.flatnonzero(meas > GLITCH_FACTOR * middle)
    if len(absurd):
        worst = int(absurd[np.argmax(meas[absurd])])
        return (f"{name} in row(s) {', '.join(map(str, absurd[:5]))}{', ...' if len(absurd) > 5 else ''} is more than "
                f"{GLITCH_FACTOR:g} times the median (row {worst}: {meas[worst]:.4g} against {middle:.4g} nT): beyond any "
                "magnetometer's range in this field, not a reading (a glitch, a corrupt row); remove those rows")
    return None


SCALAR_RATIO_RANGE = (0.5, 2.0)
"""The median measured magnitude over the reference's that a scalar series of one instrument in one field can have
(its own calibration applied, or not: scales and offsets of a few per cent); outside it the units or the reference
are wrong.  Each row's ratio too: outside it a row is a dropout or a corrupt row (a spike of 20,000 nT is inside)."""


def _as_numbers(series: ScalarSeries) -> ScalarSeries:
    """``series`` with its columns as float arrays (a reference of one number repeated on every row), once
    ``series_problem`` finds nothing wrong with them (headings given as numeric strings had reached numpy's ufuncs)."""
    problem = series_problem(series)
    if problem:
        raise InputError(problem)
    n = len(np.asarray(series.f_meas_nT))
    columns = {name: np.asarray(getattr(series, name), dtype=float) for name in
               ("f_meas_nT", "heading_deg", "f_ref_nT", "t_s", "temp_C") if getattr(series, name) is not None}
    if "f_ref_nT" in columns and columns["f_ref_nT"].ndim == 0:
        columns["f_ref_nT"] = np.full(n, float(columns["f_ref_nT"]))
    return replace(series, **columns)


def heading_glitch(heading_deg: np.ndarray, t_s: np.ndarray | None = None) -> str | None:
    """Why a heading cannot be read, or None: a row whose heading differs by more than a full turn from the rows
    before and after it (in time order, else file order) while those two lie within a turn of each other.  Headings are
    read modulo 360 (a column counted on through several turns, or offset by -720, is read right), so one such row would
    be taken at another heading without a word (1e6 as 280 degrees had moved the held-out residual from 1 to 105 nT)."""
    n = len(heading_deg)
    if n < 3:
        return None
    order = np.argsort(t_s, kind="stable") if t_s is not None and len(t_s) == n else np.arange(n)
    rows = order[lone_values(heading_deg[order], 360.0)]
    if not len(rows):
        return None
    i = int(rows[0])
    return (f"heading_deg has {len(rows)} glitched value{'s' if len(rows) > 1 else ''}: row {i} reads {heading_deg[i]:.6g} "
            "degrees, more than a full turn from the rows before and after it; correct or remove such rows")


def _checked(series: ScalarSeries) -> ScalarFit:
    """The series' fit after ``_as_numbers`` (its columns checked and float): the headings and reference present,
    enough distinct headings, no gap wider than MAX_HEADING_GAP_DEG."""
    if series.heading_deg is None:
        raise InputError("a scalar-only series needs heading_deg to be diagnosed")
    if series.f_ref_nT is None:
        raise InputError("no reference magnitude: give an f_ref column, --field NT, or a '# field_nT:' line")
    r = scalar_residual(series)
    n = len(r)
    if n < MIN_HEADINGS:
        raise InputError(f"{n} headings are too few to diagnose (need at least {MIN_HEADINGS})")
    glitch = heading_glitch(np.asarray(series.heading_deg, dtype=float), series.t_s)
    if glitch:
        raise InputError(glitch)
    heading = np.mod(np.asarray(series.heading_deg, dtype=float), 360.0)
    distinct = len(np.unique(np.floor(heading / HEADING_APART_DEG)))
    if distinct < MIN_HEADINGS:  # the harmonics of the heading need that many different headings, not rows
        raise InputError(f"the {n} readings have only {distinct} different heading(s) (in {HEADING_APART_DEG:g}-degree "
                         f"steps; need at least {MIN_HEADINGS} around the turntable)")
    gap = float(np.max(np.diff(np.concatenate([np.sort(heading), [np.min(heading) + 360.0]]))))
    if gap > MAX_HEADING_GAP_DEG:
        raise InputError(f"the headings leave a gap of {gap:.0f} degrees (at most {MAX_HEADING_GAP_DEG:g} for the "
                         "harmonics of one turn): turn the table all the way round")
    order = np.argsort(series.t_s if series.t_s is not None else np.arange(n))
    tau = np.empty(n)
    tau[order] = np.linspace(-1, 1, n)
    s = ScalarFit(r, np.radians(series.heading_deg), order, tau)
    s.base_cv = s.loo([])
    return s


def scalar_heldout(cls, s: ScalarFit) -> np.ndarray | None:
    """Leave-one-out residuals with the effect's signature fitted (spikes: explained away); None without one."""
    if cls.robust:
        return np.where(OutlierEffect.spike_mask(s.r), 0.0, s.base_cv)  # type: ignore[arg-type]
    cols = cls.scalar_columns(s.heading_rad, s.tau)
    return None if cols is None else s.loo(cols)


def score_scalar_effects(s: ScalarFit, rms_base: float, floor: float) -> list[dict]:
    """One entry per library effect with a scalar signature, best (lowest held-out RMS) first."""
    effects = []
    for cls in library_effects():
        cv = scalar_heldout(cls, s)
        if cv is None:
            continue
        z = paired_z(s.base_cv, cv)  # type: ignore[arg-type]
        shrink = shrink_pct(rms_base, rms(cv), floor)
        effects.append({"name": cls.name, "rms_heldout_nT": rms(cv), "shrink_pct": shrink,
                        "significant": bool(z > Z_SIGNIFICANT and shrink > MIN_SIGNIFICANT_SHRINK_PCT), "z": z})
    return sorted(effects, key=lambda e: e["rms_heldout_nT"])


ARITHMETIC_FLOOR = 1e-9
"""The least noise floor of a scalar series, as a share of the field (5e-5 nT at 50,000 nT: far below any
magnetometer's resolution): a residual that is exactly constant (f_meas 3 nT above f_ref on every row) had a floor of 0,
and the rounding of its leave-one-out residuals (1e-16 nT) had named an ``offset``, z 3e16."""
UNEXPLAINED_SIZE = 1.5
"""``_verdict``: a series with no significant effect is ``unexplained`` when its residual exceeds the floor by at least
this factor and by the ratio that white noise exceeds with probability SCALAR_FALSE_ALARM (``null_limit``)."""
LEFT_SIZE = 2.0
"""... and ``+unexplained`` beside an effect when what the effect leaves exceeds the floor by this factor and by that
ratio for the effect's own columns."""
SCALAR_FALSE_ALARM = FAMILY_ALPHA
"""The level at which a clean series (white noise about the file's calibration) is called ``unexplained``: the floor
of a short series is itself uncertain (second differences of 24 rows: the ratio of the residual to it exceeded 1.5
in 7.5 % of clean series, 12.5 % of 2 x 12-row ones), so the fixed factors alone had said ``unexplained`` of 25
clean series in 200."""
NULL_DRAWS = 10_000
"""White-noise series drawn (a fixed seed: the same series, the same verdict) for ``null_limit``, in blocks of
NULL_BLOCK: the 99 % point of 2000 draws had varied by +-4 % with the seed (1.98-2.16 at 24 rows)."""
NULL_BLOCK = 2000
NULL_MAX_ROWS = 72
"""Above this many rows the null ratio's 1 - SCALAR_FALSE_ALARM quantile is below both size factors (at 72 rows 1.46
for the constant and 1.49 beside the widest effect's columns, against 1.5 and 2; 1.42 and 1.46 at 80), and is not
drawn.  At 24 rows it is 2.02 (2.20 without a clock, the floor then the lower of two orders'), at 12 rows 3.2."""


def _floors(r: np.ndarray, s: ScalarFit, clock: bool) -> np.ndarray:
    """``_floor`` of each row of ``r`` (draws, n) in the series' orders, in one pass (for ``null_limit``)."""
    if clock:
        return second_difference_floors(r[:, s.order])
    by_row = second_difference_floors(r)
    by_heading = second_difference_floors(r[:, _heading_order(s)])
    return np.where(by_heading < HEADING_ORDER_SHARE * by_row, by_heading, by_row)


def null_limit(s: ScalarFit, cols: list[np.ndarray], clock: bool, size: float) -> float:
    """The larger of ``size`` and the 1 - SCALAR_FALSE_ALARM quantile of rms(leave-one-out residuals of constant +
    ``cols``) / floor over NULL_DRAWS series of white Gaussian noise with the series' rows, headings and times, the
    floor taken as ``_floor`` takes it (``clock``: in time order).  Its ratio to the floor is what a clean series
    of this length reaches by chance."""
    n = len(s.r)
    if n > NULL_MAX_ROWS:
        return size
    x = np.column_stack([np.ones(n)] + list(cols))
    pinv = np.linalg.pinv(x)
    h = np.einsum("ij,ji->i", x, pinv)
    rng = np.random.default_rng(n)
    ratios = []
    for _ in range(NULL_DRAWS // NULL_BLOCK):
        noise = rng.standard_normal((NULL_BLOCK, n))
        loo = (noise - (noise @ pinv.T) @ x.T) / (1.0 - h)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratios.append(np.sqrt(np.mean(loo * loo, axis=1)) / _floors(noise, s, clock))
    limit = float(np.quantile(np.concatenate(ratios), 1.0 - SCALAR_FALSE_ALARM))
    return max(size, limit) if np.isfinite(limit) else size


def _verdict(effects: list[dict], rms_base: float, floor: float, s: ScalarFit, clock: bool) -> tuple[str, dict]:
    """Significant effects, best first; ``+unexplained`` when the best of them leaves more than ``null_limit`` times
    the floor (at least LEFT_SIZE); without one, ``unexplained`` when the residual does (at least UNEXPLAINED_SIZE).
    Returns the verdict and its limits."""
    sig = [e for e in effects if e["significant"]]
    if not sig:
        limit = null_limit(s, [], clock, UNEXPLAINED_SIZE)
        return ("none" if rms_base <= limit * floor else "unexplained"), {"base_over_floor": limit}
    best, left = sig[0], sig[0]["rms_heldout_nT"]
    cls = EFFECTS[best["name"]]
    # outliers: a constant's null (what the spikes' removal leaves of white noise is at most that: conservative)
    cols = [] if cls.robust else cls.scalar_columns(s.heading_rad, s.tau)
    limit = null_limit(s, list(cols or []), clock, LEFT_SIZE)
    return best["name"] + ("+unexplained" if left > limit * floor else ""), {"left_over_floor": limit}


def _harm(series, col):
    v = series.extra.get(col)
    if v is None or series.heading_deg is None:
        return None
    return harmonics(series.heading_deg, np.asarray(v, float) - np.asarray(series.f_ref_nT))


HEADING_ORDER_SHARE = 0.5
"""``_floor``: without a clock, heading order's floor is taken only below this share of file order's.  Rows out of
heading order (shuffled) put it 8 times higher; where both orders are nearly one (two turns written one after the
other) the lower of two noisy estimates had biased the floor low (0.86 of the noise on 2 x 12 rows, 59 clean records
in 300 called unexplained against 35)."""


def _heading_order(s: ScalarFit) -> np.ndarray:
    """The rows in heading order around the circle (the floor's second order without a clock)."""
    return np.argsort(s.heading_rad % (2 * np.pi), kind="stable")


def _floor(s: ScalarFit, clock: bool) -> tuple[float, str]:
    """The noise floor from second differences of neighbouring samples: in time order with a ``t`` column; without
    one, the lower of file order and heading order (rows written in another order than they were taken, sorted or
    shuffled, had made neighbours of unrelated headings: a floor of 4.3 nT for noise of 0.5 nT, and an offset of 5 nT
    came back ``none``; heading order alone interleaves the turns of a record of several, which a drift between them
    separates).  Structure raises second differences, so the lower is the nearer bound of the noise, when it is
    clearly lower (``HEADING_ORDER_SHARE``): two noisy estimates differ by chance.  ``clock``: ``has_clock`` of the t
    column (fewer than ``timeonly.MIN_DISTINCT`` different times is no clock), taken once by the caller."""
    if clock:
        return second_difference_floor(s.r[s.order]), "second differences in time order"
    by_row = second_difference_floor(s.r)
    by_heading = second_difference_floor(s.r[_heading_order(s)])
    if by_heading < HEADING_ORDER_SHARE * by_row:
        return by_heading, ("second differences in heading order (no clock in a t column; less than "
                            f"{HEADING_ORDER_SHARE:g} of file order's)")
    return by_row, "second differences in file order (no clock in a t column)"


def diagnose_scalar(series: ScalarSeries, folds: int = 0, seed: int = 0) -> dict:
    """The scalar-series diagnosis (module docstring); ``folds`` and ``seed`` are unused (leave-one-out)."""
    series = _as_numbers(series)
    s = _checked(series)
    n = len(s.r)
    rms_base = rms(s.base_cv)  # type: ignore[arg-type]
    clock = has_clock(series.t_s)
    floor, floor_method = _floor(s, clock)
    least = ARITHMETIC_FLOOR * float(np.median(np.abs(np.asarray(series.f_ref_nT, dtype=float))))
    if not floor >= least:  # exact (or rounding-level) residuals: no effect is seen in the arithmetic's rounding
        floor, floor_method = least, floor_method + f" (raised to {ARITHMETIC_FLOOR:g} of the field: the arithmetic's rounding)"
    effects = score_scalar_effects(s, rms_base, floor)
    verdict, limits = _verdict(effects, rms_base, floor, s, clock)
    rms_both = rms(s.loo(together_columns(s.heading_rad, s.tau)))
    used = "f_meas_after" if series.extra.get("f_meas_after") is not None else series.meta.get("f_meas_column", "f_meas")
    return {"kind": "scalar_series", "base_model": "as given (the file's calibration)", "n_points": n,
            "residual_of": f"{used} - f_ref",
            "rms_fit_nT": rms(s.r), "rms_base_nT": rms_base, "noise_floor_nT": float(floor), "floor_method": floor_method,
            "verdict": verdict, "unexplained_limits": {**limits, "false_alarm": SCALAR_FALSE_ALARM}, "effects": effects,
            "localization": {"heading_harmonics": harmonics(series.heading_deg, s.r)},
            "geometry": fit_geometry(series),
            "series": {"before": _harm(series, "f_meas_before"), "after": _harm(series, "f_meas_after")},
            "offset_and_scale_together": {"rms_heldout_nT": rms_both,
                                          "shrink_pct": 100.0 * (rms_base - rms_both) / max(rms_base - floor, MIN_GAP_NT)}}


# ------------------------------------------------------------------------------------ the experiment's geometry
GEOMETRY_PRIOR = {"angle_rad": 0.05, "scale": 0.05, "offset_nT": 500.0, "tilt_rad": 0.05, "cubic": 2e-3}
TABLE1_RANDOM_MOUNTINGS = 3000
CONFUSABLE_CORRELATION = 0.95


def _paper_angles():

    a = paper.TABLE1_ANGLES_RAD
    return a["alpha_rad"], a["beta_rad"], a["gamma_rad"]


def _rot(ax: float, ay: float) -> np.ndarray:
    cx, sx, cy, sy = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay)
    return np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]]) @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])


GEOMETRY_NAMES = ("alpha_rad", "beta_rad", "gamma_rad", "kx", "ky", "kz", "ox_nT", "oy_nT", "oz_nT",
                  "mount_tilt_x_rad", "mount_tilt_y_rad", "axis_to_field_elevation_rad", "heading_zero_rad",
                  "soft_iron_xy", "cubic_x", "cubic_y")


def _raw(theta: np.ndarray, h: np.ndarray, f: float) -> np.ndarray:
    """Readings of the sensor on the turntable (module section: the experiment's geometry)."""
    a, b, g, kx, ky, kz, ox, oy, oz, mx, my, el, h0, sxy, cx, cy = theta
    c = f * np.column_stack([np.cos(el) * np.cos(h0 - h), np.cos(el) * np.sin(h0 - h), np.full(len(h), np.sin(el))])
    soft = np.array([[1.0, sxy, 0], [sxy, 1.0, 0], [0, 0, 1.0]])
    lin = c @ (np.diag([kx, ky, kz]) @ np.linalg.inv(paper_matrix(a, b, g)) @ soft @ _rot(mx, my)).T
    x = lin / f
    lin[:, 0] += f * cx * (x[:, 0] ** 3 - 0.6 * x[:, 0])
    lin[:, 1] += f * cy * (x[:, 1] ** 3 - 0.6 * x[:, 1])
    return lin + np.array([ox, oy, oz])


def _series(theta, h, f, p_after):
    raw = _raw(theta, h, f)
    return np.linalg.norm(raw, axis=1), np.linalg.norm(raw @ p_after.T, axis=1)


def _raw_jacobian(theta: np.ndarray, h: np.ndarray, f: float) -> tuple[np.ndarray, np.ndarray]:
    """``_raw`` and its derivatives by the 16 numbers of ``GEOMETRY_NAMES``, analytic: (raw (n, 3), d raw / d theta
    (n, 3, 16)).  raw = lin0 + cubic terms + o, lin0 = c T^T with T = K P^-1 S R and c the field seen on the
    turntable; d P^-1 = -P^-1 dP P^-1 (P of seed 000, eq. 2), R = Rx(mx) Ry(my)."""
    a, b, g, kx, ky, kz, ox, oy, oz, mx, my, el, h0, sxy, cx, cy = theta
    d = h0 - h
    ce, se, cd, sd = np.cos(el), np.sin(el), np.cos(d), np.sin(d)
    c = f * np.column_stack([ce * cd, ce * sd, np.full(len(h), se)])
    k = np.diag([kx, ky, kz])
    p_inv = np.linalg.inv(paper_matrix(a, b, g))
    soft = np.array([[1.0, sxy, 0.0], [sxy, 1.0, 0.0], [0.0, 0.0, 1.0]])
    c1, s1, c2, s2 = np.cos(mx), np.sin(mx), np.cos(my), np.sin(my)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, c1, -s1], [0.0, s1, c1]])
    ry = np.array([[c2, 0.0, s2], [0.0, 1.0, 0.0], [-s2, 0.0, c2]])
    rot = rx @ ry
    tail = soft @ rot
    t = k @ p_inv @ tail
    ca, sa, cb, sb, cg, sg = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(g), np.sin(g)
    d_p = {0: [[-sa * cg, 0, 0], [0, 0, 0], [ca * cg, 0, 0]],
           1: [[0, 0, 0], [0, -sb, 0], [0, cb, 0]],
           2: [[-ca * sg, 0, 0], [cg, 0, 0], [-sa * sg, 0, 0]]}
    d_t = {i: k @ (-p_inv @ np.array(dp, dtype=float) @ p_inv) @ tail for i, dp in d_p.items()}
    for i in range(3):  # kx, ky, kz
        unit = np.zeros((3, 3))
        unit[i, i] = 1.0
        d_t[3 + i] = unit @ p_inv @ tail
    d_rx = np.array([[0.0, 0.0, 0.0], [0.0, -s1, -c1], [0.0, c1, -s1]])
    d_ry = np.array([[-s2, 0.0, c2], [0.0, 0.0, 0.0], [-c2, 0.0, -s2]])
    d_t[9] = k @ p_inv @ soft @ (d_rx @ ry)
    d_t[10] = k @ p_inv @ soft @ (rx @ d_ry)
    d_t[13] = k @ p_inv @ np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]) @ rot
    lin0 = c @ t.T
    jac = np.zeros((len(h), 3, len(GEOMETRY_NAMES)))
    for i, dt in d_t.items():
        jac[:, :, i] = c @ dt.T
    jac[:, :, 11] = f * np.column_stack([-se * cd, -se * sd, np.full(len(h), ce)]) @ t.T
    jac[:, :, 12] = f * np.column_stack([-ce * sd, ce * cd, np.zeros(len(h))]) @ t.T
    x = lin0 / f
    jac[:, 0, :] *= (1.0 + cx * (3.0 * x[:, 0] ** 2 - 0.6))[:, None]  # the cubic response's slope
    jac[:, 1, :] *= (1.0 + cy * (3.0 * x[:, 1] ** 2 - 0.6))[:, None]
    jac[:, 0, 14] = f * (x[:, 0] ** 3 - 0.6 * x[:, 0])
    jac[:, 1, 15] = f * (x[:, 1] ** 3 - 0.6 * x[:, 1])
    for j in range(3):
        jac[:, j, 6 + j] = 1.0
    lin = lin0.copy()
    lin[:, 0] += f * cx * (x[:, 0] ** 3 - 0.6 * x[:, 0])
    lin[:, 1] += f * cy * (x[:, 1] ** 3 - 0.6 * x[:, 1])
    return lin + np.array([ox, oy, oz]), jac


def _mounting_harmonics(thetas: np.ndarray, h: np.ndarray, f: float, p_after: np.ndarray) -> np.ndarray:
    """For each row of ``thetas`` (m, 16) that differs from the others only in the mounting (tilts, the field's
    elevation, the heading's zero): the amplitudes at 1 and 2 cycles per revolution of |raw| - |P_after raw| (the
    least squares of ``localize.harmonics``), all mountings in one pass: (m, 2)."""
    a, b, g, kx, ky, kz = thetas[0, :6]
    ox, oy, oz, sxy, cx, cy = thetas[0, [6, 7, 8, 13, 14, 15]]
    assert sxy == 0.0 and cx == 0.0 and cy == 0.0 and np.all(thetas[:, :9] == thetas[0, :9])
    mx, my, el, h0 = thetas[:, 9], thetas[:, 10], thetas[:, 11], thetas[:, 12]
    d = h0[:, None] - h[None, :]
    c = f * np.stack([np.cos(el)[:, None] * np.cos(d), np.cos(el)[:, None] * np.sin(d),
                      np.broadcast_to(np.sin(el)[:, None], d.shape)], axis=-1)  # (m, n, 3)
    c1, s1, c2, s2 = np.cos(mx), np.sin(mx), np.cos(my), np.sin(my)
    zero, one = np.zeros_like(mx), np.ones_like(mx)
    rx = np.stack([np.stack([one, zero, zero], -1), np.stack([zero, c1, -s1], -1), np.stack([zero, s1, c1], -1)], -2)
    ry = np.stack([np.stack([c2, zero, s2], -1), np.stack([zero, one, zero], -1), np.stack([-s2, zero, c2], -1)], -2)
    t = np.diag([kx, ky, kz]) @ np.linalg.inv(paper_matrix(a, b, g)) @ (rx @ ry)  # (m, 3, 3); soft iron: none
    raw = np.einsum("mnj,mkj->mnk", c, t) + np.array([ox, oy, oz])
    diff = np.linalg.norm(raw, axis=-1) - np.linalg.norm(raw @ p_after.T, axis=-1)  # (m, n)
    coef, *_ = np.linalg.lstsq(heading_design(np.degrees(h)), diff.T, rcond=None)  # as ``harmonics`` is given them
    return np.column_stack([np.hypot(coef[1], coef[2]), np.hypot(coef[3], coef[4])])


def _series_jacobian(theta, h, f, p_after) -> np.ndarray:
    """d (|raw|, |P_after raw|) / d theta, stacked as the residuals of ``fit_geometry`` stack them: (2 n, 16)."""
    raw, jac = _raw_jacobian(theta, h, f)
    after = raw @ p_after.T
    d_after = np.einsum("kj,nji->nki", p_after, jac)
    d_before = np.einsum("nj,nji->ni", raw, jac) / np.linalg.norm(raw, axis=1)[:, None]
    return np.vstack([d_before, np.einsum("nk,nki->ni", after, d_after) / np.linalg.norm(after, axis=1)[:, None]])


GEOMETRY_SCREEN_NFEV = 20
"""Objective evaluations of each start's screening run in ``fit_geometry`` (MINPACK's lmder: the analytic Jacobian's
evaluations are not counted)."""
GEOMETRY_FINALISTS = 3
"""Screened starts run to convergence."""


def fit_geometry(series: ScalarSeries) -> dict | None:
    """Fit sensor model and geometry to both series (before: |raw|; after: |P(Table 1) raw|), with weak
    priors (the series alone cannot fix all 16 numbers); report the misfit of each series, what the Table-1
    angles alone could give, and which causes share a harmonic."""
    from scipy.optimize import least_squares

    before, after = series.extra.get("f_meas_before"), series.extra.get("f_meas_after")
    if before is None or after is None or series.heading_deg is None:
        return None
    h = np.radians(np.asarray(series.heading_deg, dtype=float))
    f = float(np.median(series.f_ref_nT))
    before, after = np.asarray(before, float), np.asarray(after, float)
    p_after = paper_matrix(*_paper_angles())
    prior_sd = np.array([GEOMETRY_PRIOR["angle_rad"]] * 3 + [GEOMETRY_PRIOR["scale"]] * 3 + [GEOMETRY_PRIOR["offset_nT"]] * 3
                        + [GEOMETRY_PRIOR["tilt_rad"]] * 2 + [np.inf, np.inf, GEOMETRY_PRIOR["scale"]]
                        + [GEOMETRY_PRIOR["cubic"]] * 2)
    nominal = np.array([*_paper_angles(), 1, 1, 1, 0, 0, 0, 0, 0, np.radians(55.0), 0, 0, 0, 0])

    def resid(th):
        fb, fa = _series(th, h, f, p_after)
        prior = np.where(np.isfinite(prior_sd), (th - nominal) / np.where(np.isfinite(prior_sd), prior_sd, 1), 0.0)
        return np.concatenate([fb - before, fa - after, prior])

    prior_jac = np.diag(np.where(np.isfinite(prior_sd), 1.0 / np.where(np.isfinite(prior_sd), prior_sd, 1), 0.0))

    def jacobian(th):
        return np.vstack([_series_jacobian(th, h, f, p_after), prior_jac])

    # 16 starts screened with a short run each; only the GEOMETRY_FINALISTS best are run to convergence (run to
    # convergence with the analytic Jacobian, 11 of the 16 reach the same optimum, and the screen's two best are
    # among them; the numerical Jacobian's 14,000 evaluations had been 0.6 s of Table 2's diagnosis)
    screened = []
    for el0 in np.radians([30.0, 45.0, 55.0, 65.0]):
        for h00 in np.radians([0.0, 90.0, 180.0, 270.0]):
            th0 = nominal.copy()
            th0[11], th0[12] = el0, h00
            screened.append(least_squares(resid, th0, jac=jacobian, method="lm", max_nfev=GEOMETRY_SCREEN_NFEV))
    best = None
    for start in sorted(screened, key=lambda sol: sol.cost)[:GEOMETRY_FINALISTS]:
        sol = least_squares(resid, start.x, jac=jacobian, method="lm", max_nfev=4000)
        if best is None or sol.cost < best.cost:
            best = sol
    th = best.x  # type: ignore[union-attr]
    fb, fa = _series(th, h, f, p_after)
    jac = best.jac[:2 * len(h)]  # type: ignore[union-attr]
    sv = np.linalg.svd(jac / np.maximum(np.linalg.norm(jac, axis=0), 1e-300), compute_uv=False)
    rank = int(np.sum(sv > 1e-3 * sv[0]))
    # causes sharing a harmonic: their signatures in the 'after' series (Jacobian columns at the fit)
    causes = {"scale mismatch (kx - ky)": (3, 4, -1), "x-y non-orthogonality (gamma)": (2, None, 1),
              "in-plane soft iron": (13, None, 1), "cubic response (x and y)": (14, 15, 1)}
    ja = best.jac[len(h):2 * len(h)]  # type: ignore[union-attr]
    sig = {}
    for name, (i, j, sgn) in causes.items():
        col = ja[:, i] + (sgn * ja[:, j] if j is not None else 0)
        sig[name] = col - col.mean()
    names = list(sig)
    corr = {}
    for a_ in range(len(names)):
        for b_ in range(a_ + 1, len(names)):
            u, v = sig[names[a_]], sig[names[b_]]
            # best alignment over the unknown heading zero: the 2/rev phase is set by the mounting azimuth
            cu = [np.column_stack([np.cos(k * h), np.sin(k * h)]) for k in (1, 2, 3, 4)]
            pu = np.concatenate([np.linalg.lstsq(c, u, rcond=None)[0] for c in cu])
            pv = np.concatenate([np.linalg.lstsq(c, v, rcond=None)[0] for c in cu])
            amp_u = np.hypot(pu[0::2], pu[1::2])
            amp_v = np.hypot(pv[0::2], pv[1::2])
            corr[f"{names[a_]} / {names[b_]}"] = float(amp_u @ amp_v / max(np.linalg.norm(amp_u) * np.linalg.norm(amp_v), 1e-300))
    # the Table-1 angles alone (no scale, offset or soft iron), level turntable and random mountings
    rng = np.random.default_rng(0)
    change_obs = harmonics(np.degrees(h), before - after)
    mountings = np.tile(nominal, (TABLE1_RANDOM_MOUNTINGS, 1))
    for i in range(TABLE1_RANDOM_MOUNTINGS):  # the draws in the order they were always taken
        th1 = mountings[i]
        th1[9:11] = (0.0, 0.0) if i == 0 else rng.normal(0, 0.05, 2)
        th1[11] = np.radians(rng.uniform(20, 70)) if i else np.radians(55.0)
        th1[12] = rng.uniform(0, 2 * np.pi)
    b1, a1 = _series(mountings[0], h, f, p_after)
    level = harmonics(np.degrees(h), b1 - a1)
    per_rev = _mounting_harmonics(mountings, h, f, p_after)  # (mountings, 2): 1 and 2 per revolution
    return {
        "fitted": dict(zip(GEOMETRY_NAMES, map(float, th))),
        "rms_misfit_before_nT": rms(fb - before), "rms_misfit_after_nT": rms(fa - after),
        "rms_before_nT": rms(before - series.f_ref_nT), "rms_after_nT": rms(after - series.f_ref_nT),
        "identifiable_combinations": rank, "n_geometry_parameters": len(th),
        "note": (f"the two series fix {rank} of the {len(th)} numbers; the others follow the weak priors "
                 "(angles and tilts ~0.05 rad, scales ~5 %, offsets ~500 nT, cubic ~2e-3)"),
        "change_before_minus_after": {k: v for k, v in change_obs.items() if k.endswith("per_rev_nT")},
        "table1_angles_only": {
            "level_turntable": {k: v for k, v in level.items() if k.endswith("per_rev_nT")},
            "random_mountings": TABLE1_RANDOM_MOUNTINGS,
            "max_1_per_rev_nT": float(per_rev[:, 0].max()),
            "max_2_per_rev_nT": float(per_rev[:, 1].max())},
        "harmonic_causes": {
            "1_per_rev": ["offset / hard iron", "z-coupling non-orthogonality (alpha, beta) with the vertical field",
                          "mounting or axis tilt together with non-orthogonality", "quadratic response"],
            "2_per_rev": names, "3_per_rev": ["quadratic response"], "4_per_rev": ["cubic response"],
            "time order": ["field drift (one revolution: confounded with heading)"]},
        "two_per_rev_signature_similarity": corr,
        "cannot_tell_apart": [k for k, v in corr.items() if v >= CONFUSABLE_CORRELATION],
        "can_tell_apart": [k for k, v in corr.items() if v < CONFUSABLE_CORRELATION],
    }

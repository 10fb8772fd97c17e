"""Held-out scoring: residuals on folds not used to fit, paired z-tests, shrink with a bootstrap
interval, the significance of what is left, and which effects the data can test at all."""
from __future__ import annotations

import numpy as np

from magbench.lightstats import normal_isf, normal_sf, poisson_sf
from magbench.simulate.effects import SPIKE_SIGMA, Columns, Effect, OutlierEffect, library_effects, robust_sigma

from .floor import MAD_SE

Z_SIGNIFICANT = 3.0
MIN_SIGNIFICANT_SHRINK_PCT = 10.0  # a selected effect removes at least this share of the gap on held-out data
POINTS_PER_PARAMETER = 2  # a fold's training set must have at least this many points per parameter
MIN_COVERAGE_PCT = 10.0  # attitude coverage (share of equal-area cells hit) for the attitude-shaped effects
ATTITUDE_SHAPED = ("nonlinearity",)
MIN_SPREAD_FOR_ATTITUDE_SHAPED = 0.25
"""An attitude-shaped effect needs readings that span three dimensions: along their least-covered direction
at least this share of the largest spread (a vehicle's band, a level turntable fall short; there the base
model's poorly determined directions and the effect's columns trade places).  Measured on the four independent
generators by re-running every record whose spread lies in the band (no other record can change):
- 0.35 to 0.25 (round 28, adopted; 1177 records with spreads in [0.25, 0.35)): mean score -0.01, +0.60, +0.31 and
  +0.01 points on generators 1-4, wrong names +1 net (one on generator 1, none net elsewhere), no clean record
  changed; 56 single nonlinearities that had been ``unexplained`` named;
- 0.25 to 0.20 (round 28, refused; 613 more records in [0.20, 0.25)): a further +0.00, +0.17, +0.17, -0.02 points,
  wrong names +3, and a clean buoy (generator 3, case 1248, spread 0.21) went from ``none`` to ``unexplained``;
- below 0.25 (round 30, adopted with a screen, ``Diagnosis._planar_screen`` and ``_planar_whole``): tested only where
  its own fit on base + it agrees with its linearisation, and named only where it leaves no remainder beside it;
- 0.15 (round 22, refused): +0.00, +0.96, +0.64 and +0.02 points, wrong names +1, +3, +1 and +2, the same buoy
  ``unexplained``: there the nonlinearity's columns and the base model's loosely held direction took 59 % of a clean
  residual on random folds (z 29.7), the naming rule refused it on the attitude-blocked folds, but the model floor it
  lowered made the base residual significant.
The held-out tests do not replace this guard."""
DISTINCT_PER_PARAMETER = 3
"""... and at least this many distinct directions per parameter of base + effect (a record of a dozen held
attitudes fits any smooth function of direction through them)."""
DIRECTION_GRID = 0.05
"""Unit readings closer than this on every component are one direction when counting distinct ones."""


def distinct_directions(unit: np.ndarray) -> int:
    return int(len(np.unique(np.round(unit / DIRECTION_GRID).astype(np.int64), axis=0)))


def spread_ratio(unit: np.ndarray) -> float:
    """Spread of the directions along the least-covered axis over the largest (1 on a sphere, ~0 on a plane)."""
    centred = unit - unit.mean(axis=0)
    values = np.linalg.eigvalsh(centred.T @ centred / max(len(unit), 1))
    return float(np.sqrt(max(values[0], 0.0) / values[-1])) if values[-1] > 0 else 0.0
BOOTSTRAP = 400
BOOTSTRAP_GROUPS = 200
INTERVAL = (5.0, 95.0)
REMAINDER_Z = 3.0
REMAINDER_Z_BESIDE_NAMED = 5.0
"""Beside named effects, a remainder is ``+unexplained`` only above this z (five sigma; REMAINDER_Z alone otherwise).
The library's forms of the named effects are approximations of the physics (a lag's first-order terms, a drift's
polynomials, a temperature's linear coefficient), and a remainder a little above the floor beside them is more likely
their form's imperfection than another cause; the JSON still gives it (``remainder_beside_named``).  Measured in round
28 on the four independent generators (the 327 records whose verdict ended in ``+unexplained`` beside names with a
remainder z of at most 5, re-run; no other record can change): mean score +0.32, +0.31, +0.36 and +0.34 points, wrong
names unchanged; 139 verdicts to a full score (97 of them a single effect, 55 of those a lag), 21 outside effects beside or
instead of a named one no longer said (a full score to a partial one)."""
REMAINDER_MIN_OF_FLOOR = 0.3  # a remainder counts when its RMS is at least this share of the floor
POWER_Z = Z_SIGNIFICANT + 1.28  # 90 % power of the one-sided paired test
POWER_MAX_OF_FLOOR = 1.0  # "none" needs the power to see an effect of RMS at most this share of the floor


def rms(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(r)))) if len(r) else 0.0


def paired_z(base_resid: np.ndarray, resid: np.ndarray) -> float:
    """z of the mean decrease of the squared residual, sample by sample (0 when nothing changes)."""
    diff = base_resid**2 - resid**2
    sd = np.std(diff, ddof=1) if len(diff) > 1 else 0.0
    if not sd > 0:
        return 0.0
    return float(np.mean(diff) / (sd / np.sqrt(len(diff))))


def spike_z(n_spikes: int, n: int, sigma: float = 5.0) -> float:
    """z of a count of samples beyond ``sigma`` robust sigma against Gaussian noise (Poisson tail of
    n P(|z| > sigma)).  The test for spikes: their evidence is their number, while the paired z of squared
    residuals cannot exceed about sqrt(number of spikes) however large they are."""
    if n_spikes <= 0:
        return 0.0
    p = poisson_sf(n_spikes - 1, n * 2.0 * normal_sf(sigma))
    return normal_isf(max(p, 1e-300))


def shrink_pct(rms_base: float, rms_effect: float, floor: float) -> float:
    """The share (%) of the gap between the base RMS and the noise floor that the effect removes."""
    gap = rms_base - floor
    return 100.0 * (rms_base - rms_effect) / gap if gap > 0 else 0.0


def shrink_interval(base: np.ndarray, without: np.ndarray, with_: np.ndarray, floor: float, floor_se: float,
                    seed: int) -> list[float]:
    """5-95 % bootstrap interval of (rms(without) - rms(with)) / (rms(base) - floor), resampling groups of
    samples and the floor within its standard error."""
    n = len(base)
    rng = np.random.default_rng(seed)
    g = min(n, BOOTSTRAP_GROUPS)
    lab = rng.permutation(n) % g
    sums = np.stack([np.bincount(lab, weights=x**2, minlength=g) for x in (base, without, with_)])
    cnt = np.bincount(lab, minlength=g)
    pick = rng.integers(0, g, size=(BOOTSTRAP, g))
    tot = sums[:, pick].sum(axis=2)
    m = cnt[pick].sum(axis=1)
    rb, rw, rs = np.sqrt(tot / m)
    fl = np.clip(floor + floor_se * rng.standard_normal(BOOTSTRAP), 0, None)
    gap = rb - fl
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(gap > 0, 100.0 * (rw - rs) / gap, 0.0)
    lo, hi = np.percentile(s, INTERVAL)
    return [float(lo), float(hi)]


def remainder(resid: np.ndarray, floor: float, floor_se: float, n_params: int, n_train: int,
              robust: bool = False) -> dict:
    """What is left above the noise: RMS in nT (held-out mean square minus the floor's square, the latter
    inflated by the fit's own held-out variance 1 + p / n_train) and whether it is significant.

    ``robust`` (the outliers effect selected, its spikes set to 0 in ``resid``): the mean square is
    replaced by the square of the MAD scale of the other samples.  Once the record is found to carry
    heavy-tailed errors, the ones below the spike threshold (a Student-t burst has them at every size) are
    part of that effect, not a remainder; a structured remainder still widens the bulk and is still seen."""
    if robust:
        kept = resid[resid != 0.0]
        scale = robust_sigma(kept) if len(kept) > 2 else 0.0
        n, mse = len(kept), scale * scale
        se_mse = 2.0 * MAD_SE * mse / np.sqrt(max(n, 1))
    else:
        n = len(resid)
        mse = float(np.mean(resid**2))
        se_mse = np.sqrt(np.var(resid**2) / n)
    expected = floor**2 * (1.0 + n_params / max(n_train, 1))
    excess = mse - expected
    se = np.sqrt(se_mse**2 + (2 * floor * floor_se) ** 2)
    z = excess / se if se > 0 else 0.0
    rem = float(np.sqrt(max(excess, 0.0)))
    return {"remainder_nT": rem, "remainder_z": float(z),
            "remainder_significant": bool(z > REMAINDER_Z and rem > REMAINDER_MIN_OF_FLOOR * floor),
            "remainder_measure": "MAD scale (heavy-tailed errors found)" if robust else "mean square"}


def min_detectable_nT(floor: float, n: int) -> float:
    """RMS of an effect the paired held-out test sees with 90 % power: mean decrease s^2 against a
    standard deviation 2 sigma s of the per-sample difference, so s = 2 POWER_Z sigma / sqrt(n)."""
    return float(2.0 * POWER_Z * floor / np.sqrt(max(n, 1)))


SHOULDER_SIGMA = 3.5
SHOULDER_ALPHA = 0.01
"""Fewer spikes than the selection's share of the samples (``OutlierEffect.enough``) are glitches only when their
count is more than Gaussian noise gives (``spike_z`` above Z_SIGNIFICANT) and the residual's shoulder (between
SHOULDER_SIGMA and SPIKE_SIGMA robust sigma) holds no more samples than Gaussian noise gives (Poisson, at this level):
heavy-tailed noise (Student's t) puts many there, glitches of tens of sigma few."""


def shoulder_p(resid: np.ndarray, spikes: np.ndarray) -> float:
    """p-value (Poisson, upper tail) of the count of samples between SHOULDER_SIGMA and SPIKE_SIGMA robust sigma of
    the residual (spikes left out of the scale) against Gaussian noise's."""
    sigma = robust_sigma(resid[~spikes])
    if not sigma > 0:
        return 0.0
    a = np.abs(resid - np.median(resid[~spikes])) / sigma
    count = int(np.sum((a > SHOULDER_SIGMA) & (a <= SPIKE_SIGMA)))
    expected = len(resid) * 2.0 * float(normal_sf(SHOULDER_SIGMA) - normal_sf(SPIKE_SIGMA))
    return poisson_sf(count - 1, expected)


def spikes_enough(n_spikes: int, n: int, count_z: float, shoulder: float) -> bool:
    """The count test of spikes, one rule for the vector and the fixed-sensor paths: at least the selection's share
    of the samples (``OutlierEffect.enough``); or, fewer (a long record's few glitches, or glitches the scalar
    residual shows only in part: a spike across the field barely changes the magnitude), at least
    ``OutlierEffect.MIN_SPIKES`` of them, a count Gaussian noise does not give (``count_z``, ``spike_z``) and a
    Gaussian shoulder below them (``shoulder``, ``shoulder_p``, above SHOULDER_ALPHA)."""
    return OutlierEffect.enough(n_spikes, n) or (
        n_spikes >= OutlierEffect.MIN_SPIKES and count_z > Z_SIGNIFICANT and shoulder > SHOULDER_ALPHA)


def coverage_pct(unit: np.ndarray, cells_az: int = 12, cells_z: int = 6) -> float:
    """Share (%) of equal-area cells of the sphere (cells_az azimuths x cells_z bands of z) the field
    directions hit."""
    az = ((np.arctan2(unit[:, 1], unit[:, 0]) + np.pi) / (2 * np.pi) * cells_az).astype(int) % cells_az
    zc = np.clip(((unit[:, 2] + 1) / 2 * cells_z).astype(int), 0, cells_z - 1)
    return float(100.0 * len(np.unique(zc * cells_az + az)) / (cells_az * cells_z))


def candidate_effects(base: str, d: Columns) -> list[type[Effect]]:
    """The library effects that can be fitted on these data with this base model, in registry order."""
    return [cls for cls in library_effects() if cls.applicable(base, d)]


def planar_reason(spread: float) -> str:
    return (f"the directions span {100 * spread:.0f} % out of their main plane (at least "
            f"{100 * MIN_SPREAD_FOR_ATTITUDE_SHAPED:.0f} % needed to tell it from the base model)")


def testable(base: str, d: Columns, unit: np.ndarray, n_base: int, k: int) -> tuple[list, dict, dict]:
    """(effects the data can test, {name: why not tested}, {name: why not applicable}).  An attitude-shaped effect on
    directions spanning less than MIN_SPREAD_FOR_ATTITUDE_SHAPED out of their main plane is left to the caller's
    screen (``Diagnosis._planar_screen``, ``planar_reason``)."""
    n = len(d)
    n_train = n * (k - 1) // k
    cover = coverage_pct(unit)
    distinct = distinct_directions(unit)
    ok, untested, not_applicable = [], {}, {}
    for cls in library_effects():
        if base in cls.included_in:
            continue
        miss = cls.missing(d)
        if miss:
            not_applicable[cls.name] = "no informative " + ", ".join(miss) + " column"
            continue
        need = POINTS_PER_PARAMETER * (n_base + len(cls.fit_params))
        if n_train < need:
            untested[cls.name] = f"{n_train} training points per fold, {need} needed for its {len(cls.fit_params)} parameters"
            continue
        if cls.name in ATTITUDE_SHAPED and cover < MIN_COVERAGE_PCT:
            untested[cls.name] = f"attitude coverage {cover:.0f} % of the sphere (at least {MIN_COVERAGE_PCT:.0f} % needed)"
            continue
        need_dirs = DISTINCT_PER_PARAMETER * (n_base + len(cls.fit_params))
        if cls.name in ATTITUDE_SHAPED and distinct < need_dirs:
            untested[cls.name] = f"{distinct} distinct directions, {need_dirs} needed for base + {cls.name}"
            continue
        ok.append(cls)
    return ok, untested, not_applicable

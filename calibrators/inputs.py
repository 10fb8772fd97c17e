"""What ``Calibrator.fit`` accepts, and the field magnitude when no reference is given.

``fit`` takes a ``Dataset``, an (N, 3) array of readings in nT, or a pandas ``DataFrame`` with columns
``bx, by, bz`` (any letter case; optional ``f_ref``, ``t``, ``temp``, ``heading_deg``), with the reference
as the keyword ``f_ref_nT=`` (a scalar or one value per row) or ``field="auto"``.

``field="auto"`` (``magbench calibrate --field auto``) is MATLAB ``magcal``'s ``expmfs``: with no
reference, the field magnitude is estimated from the readings themselves as the radius of the fitted
sphere (``offset`` model) or the geometric mean of the fitted ellipsoid's semi-axes (``diag``: an
axis-aligned ellipsoid; ``nine``: the Li-Griffiths ellipsoid; the radius of the sphere of equal volume,
so that the correction preserves volume, ``det M = 1``), and the calibration is made relative to it.
What then stays relative: the overall gain (the absolute scale of the corrected field, in nT) is only as
good as that estimate, not traceable to a magnetometer or a field model; the shape (angles, the ratios of
the scales, the offsets) is determined as with a reference.  For the ``angles`` model (no scale, no
offset) the magnitude is the mean corrected magnitude, refined together with the angles.
"""
from __future__ import annotations

import numpy as np

from magbench.errors import InputError
from magbench.numerics import lm_normal, median_and_sigma
from magbench.simulate.dataset import UNIT_FACTORS_NT, Dataset, real_array

from .acceptance import least_covered_direction
from .core.algebra import axis_ellipsoid_fit, ellipsoid_params, fit_ellipsoid, sphere_fit
from .core.objective import ScalarObjective

FIELD_AUTO_NOTE = ("field magnitude estimated from the readings (--field auto, as magcal's expmfs): the overall "
                   "gain (absolute scale of the corrected field) is relative to this estimate, not to a reference; "
                   "angles, scale ratios and offsets are determined as with a reference")


def as_dataset(data, f_ref_nT=None, field=None, units: str = "nT", model: str = "nine") -> Dataset:
    """``data`` (a Dataset, an (N, 3) array or a DataFrame) as a Dataset, with the reference given by
    ``f_ref_nT`` (scalar or per row), ``field`` (a number of nT, or ``"auto"``), else the data's own."""
    if not isinstance(units, str) or units not in UNIT_FACTORS_NT:
        raise InputError(f"unknown unit {units!r}: use one of nT, uT, mG, G")
    factor = UNIT_FACTORS_NT[units]
    if isinstance(data, Dataset):
        dataset = data
        if units != "nT":
            raise InputError("units= applies to arrays and DataFrames; a Dataset is in nT already")
    elif _is_dataframe(data):
        dataset = _from_frame(data, factor)
    elif isinstance(data, (np.ndarray, list, tuple)):
        raw = real_array(data, "readings", "readings must be numbers: an (N, 3) array of bx, by, bz")
        if raw.ndim != 2 or raw.shape[1] != 3:
            raise InputError(f"readings must be an (N, 3) array of bx, by, bz, not of shape {raw.shape}")
        dataset = Dataset(raw * factor, meta={"source": "array"})
    else:
        raise InputError(f"fit takes a Dataset, an (N, 3) array or a DataFrame with bx, by, bz columns, "
                         f"not {type(data).__name__}")
    given = [name for name, v in (("f_ref_nT", f_ref_nT), ("field", field)) if v is not None]
    if len(given) > 1:
        raise InputError("give the reference once: f_ref_nT= or field=, not both")
    if isinstance(field, str):
        if field != "auto":
            raise InputError(f"field must be a number of nT or 'auto', not {field!r}")
        return with_estimated_field(dataset, model)
    ref = f_ref_nT if f_ref_nT is not None else field
    if ref is not None and dataset.f_ref_nT is not None:
        # one order of reference sources for Python and the command line (CONTRACT section 2): the data's own
        # f_ref comes first, so an explicit value is not used; the result says so
        given_as = "f_ref_nT=" if f_ref_nT is not None else "field="
        return Dataset(dataset.raw_nT, dataset.f_ref_nT, dataset.t_s, dataset.temp_C, dataset.heading_deg,
                       dataset.truth, {**dataset.meta,
                                       "reference_source": f"the data's own f_ref (it takes precedence over {given_as})",
                                       "reference_ignored": f"{given_as} was not used: the data's own f_ref comes "
                                                            "first (CONTRACT section 2)"})
    if ref is not None:
        arr = real_array(ref, "the reference", "the reference must be a number of nT or one number per row")
        if arr.ndim > 1 or (arr.ndim == 1 and arr.shape[0] != len(dataset)):
            raise InputError(f"the reference has shape {arr.shape}; give a scalar or {len(dataset)} values")
        source = "f_ref_nT= (keyword)" if f_ref_nT is not None else f"field={float(np.median(arr)):g} (keyword)"
        dataset = dataset.with_reference(np.broadcast_to(arr, (len(dataset),)).copy())
        dataset = Dataset(dataset.raw_nT, dataset.f_ref_nT, dataset.t_s, dataset.temp_C, dataset.heading_deg,
                          dataset.truth, {**dataset.meta, "reference_source": source})
    return dataset


def _is_dataframe(data) -> bool:
    return type(data).__name__ == "DataFrame" and hasattr(data, "columns")


def _from_frame(frame, factor: float) -> Dataset:
    cols = {str(c).strip().lower(): c for c in frame.columns}
    missing = [c for c in ("bx", "by", "bz") if c not in cols]
    if missing:
        raise InputError(f"the DataFrame lacks column(s) {', '.join(missing)} (it has {', '.join(map(str, frame.columns))})")

    def col(name):
        if name not in cols:
            return None
        return real_array(frame[cols[name]].to_numpy(), f"DataFrame column {name}", f"DataFrame column {name} is not numeric")

    raw = np.column_stack([col(c) for c in ("bx", "by", "bz")]) * factor
    f_ref = col("f_ref")
    meta = {"source": "DataFrame"}
    if f_ref is not None:
        meta["reference_source"] = "the DataFrame's f_ref column"
    return Dataset(raw, f_ref_nT=None if f_ref is None else f_ref * factor, t_s=col("t"), temp_C=col("temp"),
                   heading_deg=col("heading_deg"), meta=meta)


# ------------------------------------------------------------------------------- algebraic fits
def algebraic_vector(raw_nT: np.ndarray, f_ref_nT, model: str) -> np.ndarray | None:
    """A closed-form start for ``model`` scaled to the median reference, or None where the readings fit
    no such shape: the ellipsoid fit (``nine``), the axis-aligned ellipsoid (``diag``: k_i = r_i / F),
    the sphere (``offset``: its centre); ``angles`` has none."""
    f = float(np.median(f_ref_nT))
    try:
        if model == "nine":
            return ellipsoid_params(raw_nT, f_ref_nT).to_vector("nine")
        if model == "diag":
            centre, radii = axis_ellipsoid_fit(raw_nT)
            return np.concatenate([radii / f, centre])
        if model == "offset":
            return sphere_fit(raw_nT)[0]
    except (InputError, np.linalg.LinAlgError):
        return None
    return None


SPIKE_SHARE = 0.05
"""Fewer readings than this share far from the others' magnitude are spikes (CONTRACT section 5: left to the outlier
screening); more are a record of another shape (mixed units, a second field), which the reference checks name."""
SPIKE_SPREADS = 10.0
"""A reading is far from the others when its magnitude is more than this many robust spreads (1.4826 MAD) from their
median, and more than ``SPIKE_FIELD_SHARE`` of it."""
SPIKE_FIELD_SHARE = 0.1


def magnitude_spikes(raw_nT: np.ndarray) -> str | None:
    """What to add to a closed-form method's ``FitError`` when a few readings (fewer than ``SPIKE_SHARE``) have
    magnitudes far from the others: spikes, perhaps, which a closed-form fit takes as they are (one row in a hundred
    at 50 times the field had turned TWOSTEP's and Merayo's quadrics indefinite, refused as too little attitude
    coverage on a full sphere).  A vehicle's brief turn with a large hard iron can look the same: hence 'if'."""
    raw = np.asarray(raw_nT, dtype=float)
    mag = np.sqrt(np.einsum("ij,ij->i", raw, raw))
    middle, spread = median_and_sigma(mag)
    far = np.abs(mag - middle) > max(SPIKE_SPREADS * spread, SPIKE_FIELD_SHARE * middle)
    k = int(far.sum())
    if k == 0 or k >= SPIKE_SHARE * len(mag):
        return None
    rows = np.flatnonzero(far)
    listed = ", ".join(map(str, rows[:5])) + (", ..." if k > 5 else "")
    return (f"{k} of {len(mag)} readings (row{'s' if k > 1 else ''} {listed}) have magnitudes far from the others' "
            f"(median {middle:.6g} nT): if they are spikes, this method fits them as they are; a robust method "
            "(ransac) fits around them, and lsq names them")


MIN_SPREAD_FOR_SHAPE_FIT = 0.2
"""Readings whose spread along their least-covered direction is below this fraction of the largest spread
(a level turntable, a vehicle pitching a few degrees) fit no sphere or ellipsoid reliably: the magnitude is
then the angles model's (the mean corrected magnitude)."""


def estimate_field(raw_nT: np.ndarray, model: str) -> tuple[float, str]:
    """The field magnitude of readings without a reference (magcal's ``expmfs``) and how it was found."""
    raw = np.asarray(raw_nT, dtype=float)
    if raw.ndim != 2 or raw.shape[1] != 3 or raw.shape[0] < 4 or not np.all(np.isfinite(raw)):
        raise InputError("field='auto' needs at least 4 finite readings bx, by, bz")
    angles_how = "mean corrected magnitude, refined with the angles (angles model)"
    if model == "angles":
        return _angles_field(raw), angles_how
    _, spread = least_covered_direction(raw)
    if spread < MIN_SPREAD_FOR_SHAPE_FIT:
        # near-planar readings determine no sphere or ellipsoid (their centre along the normal is free)
        return _angles_field(raw), (f"{angles_how}: the readings lie close to a plane (out-of-plane spread "
                                    f"{100 * spread:.2g} % of the in-plane spread), so no sphere or ellipsoid fits")
    typical = float(np.median(np.linalg.norm(raw, axis=1)))
    tries = {"nine": ("ellipsoid", "axis", "sphere"), "auto": ("ellipsoid", "axis", "sphere"),
             "diag": ("axis", "sphere")}.get(model, ("sphere",))
    for kind in tries:
        try:
            if kind == "ellipsoid":
                shape, _ = fit_ellipsoid(raw)
                det = float(np.linalg.det(shape))
                f, how = (det ** (-1.0 / 6.0) if det > 0 else float("nan"),
                          "radius of the sphere of the fitted ellipsoid's volume")
            elif kind == "axis":
                _, radii = axis_ellipsoid_fit(raw)
                f, how = float(np.prod(radii) ** (1.0 / 3.0)), ("radius of the sphere of the fitted axis-aligned "
                                                                 "ellipsoid's volume")
            else:
                f, how = sphere_fit(raw)[1], "radius of the fitted sphere"
        except (InputError, np.linalg.LinAlgError):
            continue
        if np.isfinite(f) and 0.2 * typical <= f <= 5.0 * typical:
            return float(f), how
    raise InputError("field='auto': the readings fit no sphere or ellipsoid (they cover too few directions); "
                     "give a reference (f_ref_nT= or field=NT)")


def _angles_field(raw: np.ndarray) -> float:
    """Least squares over (angles, F): F is the mean corrected magnitude for given angles, the angles the
    least-squares fit for given F; alternated until F settles."""
    f = float(np.mean(np.linalg.norm(raw, axis=1)))
    x = np.zeros(3)
    for _ in range(10):
        obj = ScalarObjective(raw, np.full(len(raw), f), "angles")
        with np.errstate(all="ignore"):
            x, _, _ = lm_normal(obj.normal_equations, x, -0.5 * np.ones(3), 0.5 * np.ones(3), tol=1e-12, max_iter=50)
        new = float(np.mean(obj.residuals(x) + f))
        done = abs(new - f) <= 1e-9 * f
        f = new
        if done:
            break
    return f


def with_estimated_field(dataset: Dataset, model: str) -> Dataset:
    """The dataset with its reference replaced by the magnitude estimated from its readings."""
    f, how = estimate_field(dataset.raw_nT, model)
    if not (np.isfinite(f) and f > 0):
        raise InputError("field='auto': the estimated field magnitude is not a positive number")
    had = dataset.meta.get("reference_source") if dataset.f_ref_nT is not None else None
    meta = {**dataset.meta, "reference_source": f"estimated from the readings: {how} (--field auto)",
            "reference_estimated": FIELD_AUTO_NOTE}
    if had:
        meta["reference_ignored"] = had
    return Dataset(dataset.raw_nT, np.full(len(dataset), f), dataset.t_s, dataset.temp_C, dataset.heading_deg,
                   dataset.truth, meta)

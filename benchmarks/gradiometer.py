"""Seed 001's simulation experiment (section 4): the gradiometer calibrations compared, their metrics, the
report and the ``magbench gradiometer`` command.

Seed 001: Jin, Zhuang, Wang, "基于磁梯度测量的磁校准方法", Aero Weaponry 2024 (1): 117-121.  The sensor
pair and its simulator are in ``magbench.simulate.gradiometer``, the calibrations in
``magbench.calibrators.methods.gradiometer``.  ``run_gradiometer`` simulates the paper's gradiometer in a field
fluctuating in time, calibrates it by single-sensor ellipsoid fits and by the paper's three 6-gene GAs
(plus our references) and measures each by the per-axis gradient residual (RMS of eq. 8's left side over
the record), per-sensor vector errors and parameter errors against the truth.  ``magbench reproduce``
writes its result for seed 0 to results/gradiometer.json (``benchmarks/claims.py``).

What we measured (``run_gradiometer`` defaults, 50 seeds): gradient residual per axis after the GA
[1.78, 1.84, 1.78] +- 0.2 nT (paper [1.848, 1.845, 1.915]), noise floor 1.55 nT, single-sensor ellipsoid
fits [302, 203, 362] nT, uncalibrated [523, 318, 359] nT.  The ellipsoid fits' gradient residual is the
same without the fluctuation: it comes from the alignment errors (Rg, R1a, R2a of eq. 6) that a single
sensor cannot observe.  The fluctuation does corrupt each single-sensor fit (~110 nT vector error per
sensor instead of 2 nT, offsets off by ~120 nT), but almost identically for both sensors, so it cancels in
the gradient (ellipsoid fits + the best relative rotation: 1.6 nT).  The gradient calibration does not
repair the sensors' absolute calibration either: the GA's M1, M2 drift along the gauge (~1 %, ~400 nT on
each sensor) while their gradient stays right.
"""
from __future__ import annotations

import time

import numpy as np

from magbench.calibrators.methods.gradiometer import (
    GradientCalibration,
    best_rotation,
    check_ga_options,
    ellipsoid_calibration,
    ga_gradient_calibration,
    gauge_fixed,
    lsq_reference,
    rotated_ellipsoid,
    true_calibration,
    uncalibrated,
)
from magbench.errors import InputError
from magbench.simulate.gradiometer import (
    DEFAULT_DURATION_S,
    DEFAULT_FIELD,
    DEFAULT_FLUCTUATION_NT,
    DEFAULT_NOISE_NT,
    DEFAULT_POINTS,
    MIN_POINTS,
    GradiometerDataset,
    GradiometerParams,
    check_int,
    check_nonneg,
    simulate_gradiometer,
)

PAPER_GA_RMS_NT = (1.8482, 1.8453, 1.9150)
"""Seed 001, abstract and section 4: gradient (difference) error per axis after the GA calibration."""

PAPER = ("Jin, Zhuang & Wang 2024, magnetic calibration based on magnetic gradient measurement, "
         "Aero Weaponry 2024(1):117-121")

GA_STREAM = 1
"""The GA's random numbers come from ``default_rng([seed, GA_STREAM])``, a stream apart from the
simulator's ``default_rng(seed)``."""

JUDGED = ("ellipsoid", "ga", "ga_gauge_fixed_ours", "lsq_ours")
"""The calibrations whose parameters are compared with the truth and written out."""


# --------------------------------------------------------------------------------------------------
# Metrics
# --------------------------------------------------------------------------------------------------

def gradient_rms(cal: GradientCalibration, ds: GradiometerDataset) -> np.ndarray:
    """Per-axis RMS of the calibrated gradient (eq. 8's left side) over the record, nT."""
    g = cal.gradient(ds.raw1_nT, ds.raw2_nT)
    return np.sqrt(np.mean(g * g, axis=0))


def parameter_errors(cal: GradientCalibration, params: GradiometerParams, f_ref_nT: float) -> dict:
    """Errors against the truth.

    Gauge-invariant (ours): the calibrated gradient of a noise-free uniform field B is
    ``coupling · B + bias`` with ``coupling = M1 F1 - M2 F2`` (F_i the true body-field -> reading maps,
    eq. 4, 6) and ``bias = M1 (B1h_true - B1h) - M2 (B2h_true - B2h)``; both are zero for every exact
    solution of eq. 7.  ``coupling_nT`` is its largest element times the reference magnitude.  Absolute:
    M1 and M2 after the best common rotation (the body frame is not observable from field data), largest
    element error; hard-iron errors per sensor."""
    coupling = cal.m1 @ params.forward(1) - cal.m2 @ params.forward(2)
    bias = cal.m1 @ (params.h1_nT - cal.h1_nT) - cal.m2 @ (params.h2_nT - cal.h2_nT)
    t1, t2 = params.m1, params.m2
    q = best_rotation(np.hstack([cal.m1, cal.m2]), np.hstack([t1, t2]))
    return {
        "coupling_max": float(np.max(np.abs(coupling))),
        "coupling_nT": float(np.max(np.abs(coupling)) * f_ref_nT),
        "bias_nT": bias.tolist(),
        "m1_max_error": float(np.max(np.abs(q @ cal.m1 - t1))),
        "m2_max_error": float(np.max(np.abs(q @ cal.m2 - t2))),
        "b1h_error_nT": (cal.h1_nT - params.h1_nT).tolist(),
        "b2h_error_nT": (cal.h2_nT - params.h2_nT).tolist(),
    }


def sensor_rms(cal: GradientCalibration, ds: GradiometerDataset) -> list[float]:
    """Per sensor: RMS vector error (nT, all axes) of the corrected field (eq. 10) against the true field,
    after the best rotation (what a single-sensor calibration can be judged on)."""
    out = []
    for b in cal.corrected(ds.raw1_nT, ds.raw2_nT):
        q = best_rotation(b.T, ds.field_body_nT.T)
        e = b @ q.T - ds.field_body_nT
        out.append(float(np.sqrt(np.mean(np.sum(e * e, axis=1)))))
    return out


def _floats(a) -> list:
    return [float(v) for v in np.ravel(a)]


# --------------------------------------------------------------------------------------------------
# The experiment
# --------------------------------------------------------------------------------------------------

def calibrate_all(ds: GradiometerDataset, ga: dict, seed: int) -> tuple[dict, dict]:
    """Every calibration of the comparison on ``ds`` (``ga``: the checked GA options), and the seconds
    each step took."""
    t0 = time.perf_counter()
    ell = ellipsoid_calibration(ds.raw1_nT, ds.raw2_nT, ds.f_ref_nT)
    t1 = time.perf_counter()
    ga_cal = ga_gradient_calibration(ds.raw1_nT, ds.raw2_nT, ell, np.random.default_rng([seed, GA_STREAM]), **ga)
    t2 = time.perf_counter()
    lsq = lsq_reference(ds.raw1_nT, ds.raw2_nT, ell)
    t3 = time.perf_counter()
    cals = {"raw": uncalibrated(), "ellipsoid": ell, "ga": ga_cal,
            "ga_gauge_fixed_ours": gauge_fixed(ga_cal, ell),
            "ellipsoid_rotated_ours": rotated_ellipsoid(ell, ds.raw1_nT, ds.raw2_nT),
            "lsq_ours": lsq, "truth": true_calibration(ds.params)}
    return cals, {"ellipsoid": t1 - t0, "ga": t2 - t1, "lsq_ours": t3 - t2}


def _measurements(ds: GradiometerDataset, cals: dict) -> dict:
    """The metrics of every calibration (the middle of ``run_gradiometer``'s result)."""
    ga_cal, ell = cals["ga"], cals["ellipsoid"]
    drift = ga_cal.m1 @ np.linalg.inv(ell.m1) - np.eye(3)
    return {
        "gradient_rms_nT": {k: _floats(gradient_rms(c, ds)) for k, c in cals.items()},
        "paper_ga_rms_nT": list(PAPER_GA_RMS_NT),
        "sensor_rms_nT": {k: sensor_rms(c, ds) for k, c in cals.items() if k != "raw"},
        "parameter_errors": {k: parameter_errors(cals[k], ds.params, ds.f_ref_nT) for k in JUDGED},
        "ga_best_fitness_nT": _floats(ga_cal.info["best_fitness_nT"]),
        "ga_rotations": ga_cal.info["rotations"],
        "ga_gauge_drift": float(np.max(np.abs(drift))),
        "n_evaluations": int(ga_cal.info["n_evaluations"]),
    }


def run_gradiometer(seed: int = 0, n_points: int = DEFAULT_POINTS, fluctuation_nT: float = DEFAULT_FLUCTUATION_NT,
                    noise_nT: float = DEFAULT_NOISE_NT, *, duration_s: float = DEFAULT_DURATION_S,
                    attitude: str = "tumble", **ga_options) -> dict:
    """Seed 001's simulation experiment (section 4) end to end; returns a JSON-serializable dict.

    Simulates the paper's gradiometer (``GradiometerParams.paper``) rotated through ``n_points``
    attitudes over ``duration_s`` in a field fluctuating by up to ``fluctuation_nT``, calibrates it by
    (a) single-sensor ellipsoid fits and (b) the paper's three 6-gene GAs on eq. 11 (``ga_options``:
    any of ``GA_DEFAULTS``), plus our references, and reports the per-axis gradient residual (RMS of
    eq. 8's left side over the record) of each, per-sensor vector errors, parameter errors against the
    truth, the number of fitness evaluations (the GAs' counter) and the runtime.
    """
    t_start = time.perf_counter()
    seed = check_int(seed, "seed", 0)
    n_points = check_int(n_points, "n_points (--points)", MIN_POINTS)
    fluctuation_nT = check_nonneg(fluctuation_nT, "fluctuation_nT")
    noise_nT = check_nonneg(noise_nT, "noise_nT")
    limit = MAX_SHARE_OF_FIELD * DEFAULT_FIELD.total_nT
    for name, value in (("fluctuation_nT (--fluctuation-nT)", fluctuation_nT), ("noise_nT (--noise-nT)", noise_nT)):
        if value > limit:
            raise InputError(f"{name} must be at most {limit:g} nT (a tenth of the {DEFAULT_FIELD.total_nT:g} nT "
                             f"field: beyond it the paper's model of a small fluctuation and noise does not hold), "
                             f"got {value:g}")
    ga = check_ga_options(ga_options, n_points)
    ds = simulate_gradiometer(None, n_points, fluctuation_nT, noise_nT, DEFAULT_FIELD, duration_s, attitude, seed)
    t_sim = time.perf_counter()
    cals, timings = calibrate_all(ds, ga, seed)
    out = {
        "paper": PAPER,
        "seed": seed,
        "n_points": n_points,
        "duration_s": float(duration_s),
        "attitude": attitude,
        "fluctuation_nT": fluctuation_nT,
        "noise_nT": noise_nT,
        "field_nT": ds.f_ref_nT,
        "inclination_deg": round(DEFAULT_FIELD.inclination_deg, 9),
        "declination_deg": round(DEFAULT_FIELD.declination_deg, 9),
        "ga_options": ga,
        **_measurements(ds, cals),
        "runtime_s": 0.0,
        "runtime_breakdown_s": {"simulate": t_sim - t_start, **timings},
        "truth": ds.params.as_dict(),
        "calibration": {k: cals[k].as_dict() for k in JUDGED},
    }
    out["runtime_s"] = time.perf_counter() - t_start
    return out


# --------------------------------------------------------------------------------------------------
# The report
# --------------------------------------------------------------------------------------------------

_GRADIENT_ROWS = (("raw", "uncalibrated (B1m - B2m)"),
                  ("ellipsoid", "single-sensor ellipsoid fits"),
                  ("ga", "GA gradient calibration (paper)"),
                  ("paper", "paper's reported (GA)"),
                  ("ga_gauge_fixed_ours", "GA + gauge fix (ours)"),
                  ("ellipsoid_rotated_ours", "ellipsoid + best rotation (ours)"),
                  ("lsq_ours", "least-squares reference (ours)"),
                  ("truth", "true parameters (noise floor)"))

_SENSOR_ROWS = (("ellipsoid", "single-sensor ellipsoid fits"), ("ga", "GA gradient calibration"),
                ("ga_gauge_fixed_ours", "GA + gauge fix (ours)"), ("lsq_ours", "least-squares reference (ours)"),
                ("truth", "true parameters"))


def _header(r: dict) -> list[str]:
    return [f"gradiometer of Jin, Zhuang & Wang (2024): two fluxgates on one body, seed {r['seed']}, "
            f"{r['n_points']} attitudes "
            f"({r['attitude']}) over {r['duration_s']:g} s",
            f"field {r['field_nT']:.0f} nT (I {r['inclination_deg']:.0f} deg, D {r['declination_deg']:.0f} deg), "
            f"fluctuation up to {r['fluctuation_nT']:g} nT, noise {r['noise_nT']:g} nT per axis per sensor"]


MAX_SHARE_OF_FIELD = 0.1
"""The largest fluctuation and noise ``run_gradiometer`` simulates, as a share of the ambient field."""


def _num(x: float, width: int, decimals: int, exp: bool = False) -> str:
    """``x`` right-aligned in ``width`` characters with ``decimals`` (``e`` notation with ``exp``), in ``e``
    notation when that would not leave a space before it (a column never runs into the next)."""
    text = f"{x:.{decimals}{'e' if exp else 'f'}}"
    if len(text) >= width:
        text = f"{x:.3g}"
    return text.rjust(width)


def _gradient_table(r: dict) -> list[str]:
    lines = [f"{'gradient residual per axis (RMS, nT)':40s}{'x':>10s}{'y':>10s}{'z':>10s}"]
    for key, label in _GRADIENT_ROWS:
        v = r["paper_ga_rms_nT"] if key == "paper" else r["gradient_rms_nT"][key]
        lines.append(f"  {label:38s}" + "".join(_num(x, 10, 3) for x in v))
    return lines


def _sensor_table(r: dict) -> list[str]:
    lines = [f"{'per-sensor vector error, best rotation (nT)':46s}{'sensor 1':>12s}{'sensor 2':>12s}"]
    for key, label in _SENSOR_ROWS:
        s = r["sensor_rms_nT"][key]
        lines.append(f"  {label:44s}{_num(s[0], 12, 2)}{_num(s[1], 12, 2)}")
    return lines


def _parameter_table(r: dict) -> list[str]:
    lines = [f"{'parameter errors':34s}{'coupling nT':>12s}{'bias nT (max)':>15s}{'M1 max':>10s}"
             f"{'M2 max':>10s}{'|dB1h| nT':>11s}{'|dB2h| nT':>11s}"]
    for key in JUDGED:
        e = r["parameter_errors"][key]
        lines.append(f"  {key:32s}{_num(e['coupling_nT'], 12, 3)}{_num(max(map(abs, e['bias_nT'])), 15, 3)}"
                     f"{_num(e['m1_max_error'], 10, 2, exp=True)}{_num(e['m2_max_error'], 10, 2, exp=True)}"
                     f"{_num(float(np.linalg.norm(e['b1h_error_nT'])), 11, 2)}"
                     f"{_num(float(np.linalg.norm(e['b2h_error_nT'])), 11, 2)}")
    lines.append("  (coupling, bias: the gradient error c.B + b, zero for every exact solution; M errors after the "
                 "best common rotation)")
    return lines


def _ga_summary(r: dict) -> list[str]:
    g = r["ga_options"]
    return [f"GA: 3 GAs x {g['population']} x {g['generations']} generations = {r['n_evaluations']} fitness "
            f"evaluations on {g['n_rotations']} attitudes; best fitness "
            + ", ".join(f"{v:.2f}" for v in r["ga_best_fitness_nT"]) + " nT; gauge drift "
            f"{r['ga_gauge_drift']:.2e}",
            f"runtime {r['runtime_s']:.3f} s"]


def format_report(r: dict) -> str:
    """The human table of ``run_gradiometer``'s result."""
    parts = (_header(r), _gradient_table(r), _sensor_table(r), _parameter_table(r), _ga_summary(r))
    return "\n\n".join("\n".join(p) for p in parts)

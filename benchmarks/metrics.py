"""Metrics of one calibration run against the truth (issue: benchmark harness, point 2).

Angle, scale and offset recovery errors; total-field RMS before and after on the fitting data and on a
held-out validation set from the same sensor (seeds 002 and 003 validate on a second data set); RMS
reduction; heading error (seed 004's figure of merit) where the scenario has a horizontal heading;
the Cramér-Rao bound of the trial (calibrators/fisher.py) for the efficiency of the estimator.
"""
from __future__ import annotations

import numpy as np

from magbench.calibrators.base import CalibrationResult
from magbench.calibrators.core.objective import ScalarObjective
from magbench.calibrators.fisher import crb_std
from magbench.calibrators.params import as_budget
from magbench.simulate.dataset import Dataset
from magbench.simulate.sensor import PARAM_NAMES, ErrorParams


def total_field_rms(params: ErrorParams, data: Dataset) -> float:
    f = np.linalg.norm(params.correct(data.raw_nT), axis=1)
    return float(np.sqrt(np.mean((f - data.f_ref_nT) ** 2)))


def heading_error_deg(params: ErrorParams, data: Dataset) -> float | None:
    """RMS compass-heading error: the corrected field is taken to the North-East-Down frame with the true
    attitude (the pitch and roll a compass would know); its azimuth is compared with the true field's."""
    truth = data.truth
    if truth is None or truth.attitude_quat is None or data.heading_deg is None:
        return None
    from scipy.spatial.transform import Rotation  # SciPy's spatial package when needed: a campaign process
    # that only writes tables does not load it (its workers do, in their untimed warm-up)

    b_ned = Rotation.from_quat(truth.attitude_quat).apply(params.correct(data.raw_nT))
    true_azimuth = np.arctan2(truth.field_ned_nT[1], truth.field_ned_nT[0])
    err = np.angle(np.exp(1j * (np.arctan2(b_ned[:, 1], b_ned[:, 0]) - true_azimuth)))
    return float(np.degrees(np.sqrt(np.mean(err**2))))


def noise_sigma_nT(data: Dataset) -> float | None:
    """The simulated per-axis noise standard deviation, with quantization as q²/12 added to the variance."""
    if data.truth is None:
        return None
    s = data.truth.sensor
    var = s.noise_nT**2 + s.quantization_nT**2 / 12.0
    return float(np.sqrt(var)) if var > 0 else None


def crb_row(data: Dataset, model: str) -> dict:
    """Cramér-Rao standard deviation of each parameter at the true parameters on this trial's data."""
    sigma = noise_sigma_nT(data)
    if sigma is None:
        return {}
    x_true = data.truth.params.to_vector(model)
    std = crb_std(ScalarObjective(data.raw_nT, data.f_ref_nT, model), x_true, sigma)
    return {f"crb_{name.replace('_rad', '')}_rad" if name.endswith("_rad") else f"crb_{name}": float(v)
            for name, v in zip(PARAM_NAMES[model], std)}


def budget_violation(result: CalibrationResult, budget) -> str:
    """The harness's own re-check of a run against its budget (nevergrad's ``xpbase`` re-checks the
    optimizer's call count after the run): '' when the run kept to it, else why it did not."""
    if result.n_overrun_calls:
        return (f"budget overrun: the solver asked {result.n_overrun_calls} more time(s) after the counter "
                "said the budget was spent")
    limit = as_budget(budget).max_evaluations
    if limit is not None and result.n_evaluations > limit:
        return f"budget overrun: {result.n_evaluations} evaluation-equivalents with a budget of {limit}"
    return ""


def evaluations_label(mode: str, n: float) -> str:
    """What a table shows for a run's evaluations: the count, or 'closed-form' for a method whose cost
    a count of objective evaluations does not describe."""
    if mode == "closed-form":
        return "closed-form"
    return "-" if n != n else f"{n:.0f}"


def run_metrics(result: CalibrationResult, data: Dataset, validation: Dataset | None = None) -> dict:
    """Flat metrics of a fitted result (no truth needed for the RMS ones)."""
    p = result.params
    row = {"success": result.success, "status": result.status, "n_evaluations": result.n_evaluations,
           "n_function_evaluations": result.n_function_evaluations, "n_jacobians": result.n_jacobians,
           "evaluation_mode": result.evaluation_mode,
           "accepted": result.accepted, "rejections": "; ".join(result.rejections),
           "runtime_s": result.runtime_s, "rms_before_nT": result.rms_before_nT,
           "rms_after_nT": result.rms_after_nT,
           "rms_reduction_pct": 100.0 * (1.0 - result.rms_after_nT / result.rms_before_nT),
           "alpha_rad": p.alpha_rad, "beta_rad": p.beta_rad, "gamma_rad": p.gamma_rad,
           "warnings": "; ".join(result.warnings)}
    if result.model == "nine":
        row.update({f"k{a}": v for a, v in zip("xyz", p.scale)})
        row.update({f"o{a}_nT": v for a, v in zip("xyz", p.offset_nT)})
    if validation is not None:
        before = total_field_rms(ErrorParams(), validation)
        after = total_field_rms(p, validation)
        row.update(val_rms_before_nT=before, val_rms_after_nT=after,
                   val_rms_reduction_pct=100.0 * (1.0 - after / before))
    truth = data.truth
    if truth is not None:
        t = truth.params
        for name, est, true in zip(("alpha", "beta", "gamma"), (p.alpha_rad, p.beta_rad, p.gamma_rad),
                                   (t.alpha_rad, t.beta_rad, t.gamma_rad)):
            row[f"{name}_err_rad"] = est - true
        if result.model == "nine":
            row["scale_err_max"] = float(np.max(np.abs(np.subtract(p.scale, t.scale))))
            row["offset_err_max_nT"] = float(np.max(np.abs(np.subtract(p.offset_nT, t.offset_nT))))
        h_before = heading_error_deg(ErrorParams(), data)
        if h_before is not None:
            row["heading_err_before_deg"] = h_before
            row["heading_err_after_deg"] = heading_error_deg(p, data)
    return row

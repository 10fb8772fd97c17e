"""One calibration run as one flat row (nevergrad's benchmark rows): descriptors, settings, metrics,
runtime, seed, and an ``error`` column instead of an exception, so a sweep never dies of one run."""
from __future__ import annotations

import numpy as np

from calibrators import make
from simulate.dataset import Dataset, InputError

ARCSEC_PER_RAD = 180.0 / np.pi * 3600.0


def run_one(dataset: Dataset, method: str, model: str, seed: int = 0, scenario: str = "", **params) -> dict:
    """Fit ``method`` on ``dataset`` and return one flat row; a refusal lands in ``error``."""
    row = {"scenario": scenario or dataset.meta.get("scenario", ""), "method": method, "model": model,
           "seed": seed, "error": ""}
    try:
        result = make(method, model=model, seed=seed, **params).fit(dataset)
    except InputError as exc:
        row["error"] = str(exc)
        return row
    except Exception as exc:  # a failing run is a row, not the end of the campaign
        row["error"] = f"{type(exc).__name__}: {exc}"
        return row
    row.update(success=result.success, status=result.status, rms_before_nT=result.rms_before_nT,
               rms_after_nT=result.rms_after_nT, n_evaluations=result.n_evaluations,
               runtime_s=result.runtime_s, warnings="; ".join(result.warnings))
    for name, value in zip(("alpha_rad", "beta_rad", "gamma_rad"), result.x[:3]):
        row[name] = float(value)
    truth = dataset.truth
    if truth is not None:
        t = truth.params
        for name, est, true in zip(("alpha", "beta", "gamma"), result.x[:3],
                                   (t.alpha_rad, t.beta_rad, t.gamma_rad)):
            row[f"{name}_err_rad"] = float(est - true)
        if model == "nine":
            row["scale_err_max"] = float(np.max(np.abs(np.subtract(result.params.scale, t.scale))))
            row["offset_err_max_nT"] = float(np.max(np.abs(np.subtract(result.params.offset_nT, t.offset_nT))))
    return row

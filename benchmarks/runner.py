"""One calibration run as one flat row (nevergrad's benchmark rows): descriptors, settings, metrics,
runtime, seed, and an ``error`` column instead of an exception, so a sweep never dies of one run."""
from __future__ import annotations

from magbench.calibrators import make
from magbench.errors import InputError
from magbench.simulate.dataset import Dataset

from .metrics import budget_violation, run_metrics


def run_one(dataset: Dataset, method: str, model: str, seed: int = 0, scenario: str = "", **params) -> dict:
    """Fit ``method`` on ``dataset`` and return one flat row; a refusal or a failure lands in ``error``."""
    row = {"scenario": scenario or dataset.meta.get("scenario", ""), "method": method, "model": model,
           "seed": seed, "error": ""}
    try:
        calibrator = make(method, model=model, seed=seed, **params)
        result = calibrator.fit(dataset)
    except InputError as exc:
        row["error"] = str(exc)
        return row
    except Exception as exc:  # a failing run is a row, not the end of the campaign
        row["error"] = f"{type(exc).__name__}: {exc}"
        return row
    row.update(run_metrics(result, dataset))
    row["error"] = budget_violation(result, calibrator.budget)
    return row

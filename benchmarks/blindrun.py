"""The project's own blind check of the diagnosis, run: each case of ``diagnosis.blind`` (datasets written
independently of the fitted effect classes) diagnosed, classified against its label, on worker processes.
Kept outside the diagnosis package, which it uses (the package does not import it)."""
from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor

import numpy as np

from .diagnosis import diagnose
from .diagnosis.blind import blind_dataset, category, classify


def blind_case(i: int) -> dict:
    """Diagnose case i: its label, the verdict and outcome, and what the true noise (known only here) says
    about the case ('beyond base': the RMS the base fit leaves above the generator's noise)."""
    label, base, data = blind_dataset(i)
    result = diagnose(data, base=base)
    return {"case": i, "label": label, "category": category(label), "points": len(data),
            "noise_nT": float(data.meta["noise_nT"]), "coverage": data.meta["coverage"],
            "beyond_base_nT": float(np.sqrt(max(result["rms_base_nT"] ** 2 - data.meta["noise_nT"] ** 2, 0.0))),
            "min_detectable_nT": float(result["power"]["min_detectable_effect_rms_nT"]),
            "floor_nT": float(result["noise_floor_nT"]), "verdict": result["verdict"],
            "outcome": classify(label, result["verdict"])}


def run_blind(n: int, jobs: int = 1, progress=None) -> list[dict]:
    """``blind_case`` for cases 0 .. n-1, on ``jobs`` worker processes (in case order; ``progress``: a
    callable wrapping the iterator, e.g. a tqdm bar)."""
    wrap = progress or (lambda it, **kw: it)
    if jobs <= 1:
        return [blind_case(i) for i in wrap(range(n), total=n)]
    with ProcessPoolExecutor(jobs) as pool:
        return list(wrap(pool.map(blind_case, range(n), chunksize=4), total=n))

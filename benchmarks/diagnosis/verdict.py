"""The verdict of a diagnosis (CONTRACT section 3): the best significant effect when it removes at least
MIN_SHRINK_PCT of the gap; else ``none`` when the base residual is within NONE_TOLERANCE / sqrt(n) of the
noise floor; else ``unexplained``."""
from __future__ import annotations

import numpy as np

MIN_SHRINK_PCT = 50.0
NONE_TOLERANCE = 4.0


def verdict(effects: list[dict], rms_base: float, floor: float, n: int) -> str:
    """``effects`` best first, as ``scoring.score_vector_effects`` or ``scalar.score_scalar_effects`` give them."""
    best = next((e for e in effects if e["significant"]), None)
    if best is not None and best["shrink_pct"] >= MIN_SHRINK_PCT:
        return best["name"]
    return "none" if rms_base <= floor * (1.0 + NONE_TOLERANCE / np.sqrt(n)) else "unexplained"

"""Cross-validated scoring of each candidate effect: the base model and the base model plus one library
effect (``simulate.effects``) are fitted on K-1 folds and their residuals measured on the fold left out,
so that added parameters cannot win by over-fitting.  ``shrink_pct`` is the share of the gap (held-out
base RMS minus noise floor) the effect removes; ``significant`` needs the effect's held-out evidence (a
paired z-test on the squared residuals beyond Z_SIGNIFICANT, or, for spikes, enough of them) and a
shrink beyond MIN_SIGNIFICANT_SHRINK_PCT."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magbench.simulate.effects import Columns, Effect, Normalization, library_effects, robust_sigma

from .localize import folds
from .model import EffectModel

Z_SIGNIFICANT = 3.0
MIN_SIGNIFICANT_SHRINK_PCT = 10.0
POINTS_PER_PARAMETER = 2  # a fold's training set must have at least this many points per parameter


@dataclass
class HeldOut:
    """Residuals on held-out folds (spikes the effect explains set to zero) and their RMS."""

    rms_nT: float
    resid_nT: np.ndarray
    n_flagged: int = 0


def rms(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(r**2)))


def paired_z(base_resid: np.ndarray, resid: np.ndarray) -> float:
    """z of the mean decrease of the squared residual, sample by sample (0 when nothing changes)."""
    diff = base_resid**2 - resid**2
    if not np.std(diff) > 0:
        return 0.0
    return float(np.mean(diff) / (np.std(diff, ddof=1) / np.sqrt(len(diff))))


def shrink_pct(rms_base: float, rms_effect: float, floor: float) -> float:
    """The share (%) of the gap between the base RMS and the noise floor that the effect removes."""
    gap = rms_base - floor
    return 100.0 * (rms_base - rms_effect) / gap if gap > 0 else 0.0


def candidate_effects(base: str, d: Columns) -> list[type[Effect]]:
    """The library effects that can be fitted on these data with this base model, in registry order."""
    return [cls for cls in library_effects() if cls.applicable(base, d)]


def cross_validate(base: str, effect: type[Effect] | None, d: Columns, norm: Normalization, base_x: np.ndarray,
                   k: int, seed: int, spike_scale: float = 0.0) -> HeldOut:
    """K-fold held-out residuals of the base model plus ``effect`` (None: the base model alone)."""
    model = EffectModel(base, effect, norm)
    fold = folds(len(d.raw_nT), k, seed)
    resid = np.empty(len(d.raw_nT))
    flagged = 0
    for f in range(k):
        tr, te = fold != f, fold == f
        resid[te], n = model.effect.heldout_residuals(model, d.take(tr), d.take(te), model.x0(base_x), spike_scale)
        flagged += n
    return HeldOut(rms(resid), resid, flagged)


def score_vector_effects(base: str, d: Columns, base_x: np.ndarray, base_cv: HeldOut, floor: float,
                         k: int, seed: int) -> list[dict]:
    """One entry per candidate effect with enough points for its parameters, best (lowest held-out RMS) first."""
    n = len(d.raw_nT)
    n_train = n * (k - 1) // k
    norm = Normalization.of(d)
    spike_scale = robust_sigma(base_cv.resid_nT)
    effects = []
    for cls in candidate_effects(base, d):
        if n_train < POINTS_PER_PARAMETER * (len(base_x) + len(cls.fit_params)):
            continue  # too many parameters for the points available
        cv = cross_validate(base, cls, d, norm, base_x, k, seed, spike_scale)
        z = paired_z(base_cv.resid_nT, cv.resid_nT)
        shrink = shrink_pct(base_cv.rms_nT, cv.rms_nT, floor)
        significant = cls.evidence(z, cv.n_flagged, n, Z_SIGNIFICANT) and shrink > MIN_SIGNIFICANT_SHRINK_PCT
        effects.append({"name": cls.name, "rms_heldout_nT": cv.rms_nT, "shrink_pct": shrink,
                        "significant": bool(significant), "z": z,
                        "n_parameters": len(cls.fit_params) + cv.n_flagged})  # a flagged spike is one parameter
    return sorted(effects, key=lambda e: e["rms_heldout_nT"])

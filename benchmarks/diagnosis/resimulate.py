"""The re-simulation, scored on data not used to fit: the selected effects are fitted (with the base
model) on one part of the folds; the sensor is then simulated at the attitudes of the other part (the
corrected field directions, scaled to the reference) with those fitted errors and effects and white
noise at the floor, calibrated with the base model, and its residual RMS and spectrum compared with the
observed base residual of that part.  The same without the effects shows what they account for."""
from __future__ import annotations

import numpy as np

from magbench.calibrators import make
from magbench.simulate.dataset import Dataset
from magbench.simulate.effects import EFFECTS, OutlierEffect

from .localize import residual_spectrum
from .model import base_correction
from .scoring import rms

RESIM_SEED_OFFSET = 7
MIN_RESIM_POINTS = 30


def _base_residual(raw, ref, base, t, temp, heading):
    sim = Dataset(raw, f_ref_nT=ref, t_s=t, temp_C=temp, heading_deg=heading)
    fit = make("lsq", model=base).fit(sim)
    return np.linalg.norm(fit.correct(raw), axis=1) - ref


def resimulate(diag, names: list[str], robust: bool, floor: float, seed: int) -> dict | None:
    tan, model, d = diag.tangent, diag.model, diag.columns
    held = np.isin(tan.fold, np.arange(tan.k // 2 + 1, tan.k))  # fit on the first folds, score on the rest
    if held.sum() < MIN_RESIM_POINTS:
        return None
    x = tan.fit_on(names, robust, np.flatnonzero(~np.isin(np.arange(tan.k), np.arange(tan.k // 2 + 1, tan.k))))
    rng = np.random.default_rng(seed + RESIM_SEED_OFFSET)
    idx = np.flatnonzero(held)
    dh = d.take(idx)
    t = dh.t_s
    temp = dh.temp_C
    heading = None if diag.dataset.heading_deg is None else np.asarray(diag.dataset.heading_deg)[idx]
    r_obs = _base_residual(dh.raw_nT, dh.f_ref_nT, diag.base, t, temp, heading)
    m_mat, o = base_correction(x[:9])
    b_true = diag.unit[idx] * dh.f_ref_nT[:, None]
    lin = b_true @ np.linalg.inv(m_mat).T + o
    ctx = {"t_s": t, "temp_C": temp, "offset_nT": tuple(o), "f_nT": model.norm.f0_nT}
    stats = {}
    for label, with_effect in (("without_effect", False), ("with_effect", True)):
        raw, ref = lin.copy(), dh.f_ref_nT.copy()
        if with_effect:
            for nm in names:
                cls = EFFECTS[nm]
                if cls.base_part or cls.robust:
                    continue
                e = x[model.groups[nm]]
                fwd = cls.from_fit(e, model.norm, diag.effect_info.get(nm))
                if fwd is not None:
                    raw = fwd.readings(raw, ctx, rng)
                ref = cls.resim_reference(ref, e, dh, model.norm)
        raw = raw + rng.normal(0.0, floor, raw.shape)
        if with_effect and robust:
            flagged = tan.spikes[idx]
            r_full = diag.r_star[idx]
            raw[flagged] += (r_full[flagged] - np.median(r_full))[:, None] * diag.unit[idx][flagged]
        r_sim = _base_residual(raw, ref, diag.base, t, temp, heading)
        stats[label] = {"rms_nT": rms(r_sim), **residual_spectrum(r_sim, heading, t)}
    observed = {"rms_nT": rms(r_obs), **residual_spectrum(r_obs, heading, t)}
    obs = max(observed["rms_nT"], 1e-12)
    return {"scored_on": f"{len(idx)} samples of folds not used to fit the effects", "observed": observed, **stats,
            "remaining_gap_pct": 100.0 * abs(stats["with_effect"]["rms_nT"] - obs) / obs,
            "gap_without_effect_pct": 100.0 * abs(stats["without_effect"]["rms_nT"] - obs) / obs}


__all__ = ["resimulate", "OutlierEffect"]

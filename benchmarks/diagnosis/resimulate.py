"""How far the residual shrinks, checked by re-simulation: the sensor is simulated at the observed
attitudes (the corrected field directions, scaled to the reference) with the fitted base errors, white
noise at the floor, and the fitted effect or none; it is calibrated again with the base model and its
residual RMS and spectrum compared with the observed ones."""
from __future__ import annotations

import numpy as np

from magbench.calibrators import make
from magbench.simulate.dataset import Dataset
from magbench.simulate.effects import Columns

from .localize import residual_spectrum
from .model import EffectModel, base_correction
from .scoring import rms

RESIM_SEED_OFFSET = 7


def _simulated_residual(raw: np.ndarray, ref: np.ndarray, base: str, d: Columns, heading_deg) -> np.ndarray:
    """Residual of the base ``lsq`` calibration of simulated readings."""
    sim = Dataset(raw, f_ref_nT=ref, t_s=d.t_s, temp_C=d.temp_C, heading_deg=heading_deg)
    fit = make("lsq", model=base).fit(sim)
    return np.linalg.norm(fit.correct(raw), axis=1) - ref


def resimulate(model: EffectModel, x: np.ndarray, d: Columns, unit: np.ndarray, heading_deg, floor: float,
               r_obs: np.ndarray, seed: int) -> dict:
    """Residual statistics of the re-simulation without and with the fitted effect (module docstring)."""
    effect, norm = model.effect, model.norm
    rng = np.random.default_rng(seed + RESIM_SEED_OFFSET)
    base_x, e = x[:model.nb], x[model.nb:]
    mat, o = base_correction(base_x, model.base)
    lin = (unit * d.f_ref_nT[:, None]) @ np.linalg.inv(mat).T + o
    ctx = {"t_s": d.t_s, "temp_C": d.temp_C, "offset_nT": tuple(o), "f_nT": norm.f0_nT}
    forward = effect.from_fit(e, norm)
    stats = {}
    for label, with_effect in (("without_effect", False), ("with_effect", True)):
        raw, ref = lin.copy(), d.f_ref_nT
        if with_effect:
            raw = raw if forward is None else forward.readings(raw, ctx, rng)
            ref = effect.resim_reference(ref, e, d, norm)
        raw = raw + rng.normal(0.0, floor, raw.shape)
        if with_effect:
            raw = effect.resim_spikes(raw, r_obs, unit)
        r_sim = _simulated_residual(raw, ref, model.base, d, heading_deg)
        stats[label] = {"rms_nT": rms(r_sim), **residual_spectrum(r_sim, heading_deg, d.t_s)}
    observed = {"rms_nT": rms(r_obs), **residual_spectrum(r_obs, heading_deg, d.t_s)}
    obs = observed["rms_nT"]
    return {"observed": observed, **stats, "remaining_gap_pct": 100.0 * (abs(stats["with_effect"]["rms_nT"] - obs) / obs),
            "gap_without_effect_pct": 100.0 * abs(stats["without_effect"]["rms_nT"] - obs) / obs}

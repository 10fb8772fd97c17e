"""The diagnosis of a scalar turntable series (seed 000's Table 2 style: total field per heading, after
the paper's calibration).  The residual is ``f_meas_after - f_ref`` (else ``f_meas - f_ref``).  Each
library effect with a first-order signature on a level turntable (``Effect.scalar_columns``: offset 1
cycle/rev, scale 2, nonlinearity 3 and 4, field_drift a cubic in time, i.e. heading order; outliers:
spikes beyond SPIKE_SIGMA robust sigma) is scored by leave-one-out cross-validation against a constant."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from magbench.errors import InputError
from magbench.simulate.dataset import ScalarSeries
from magbench.simulate.effects import EFFECTS, library_effects

from .floor import second_difference_floor
from .localize import harmonics
from .scoring import MIN_SIGNIFICANT_SHRINK_PCT, Z_SIGNIFICANT, paired_z, rms, shrink_pct
from .verdict import verdict

MIN_HEADINGS = 12
TOGETHER = ("offset", "scale")  # the two first-order heading effects, also scored together
MIN_GAP_NT = 1e-9


@dataclass
class ScalarFit:
    """The residual of a scalar series with what the effects' scalar signatures are built from."""

    r: np.ndarray
    heading_rad: np.ndarray
    order: np.ndarray  # the samples in time order (row order without a time column)
    tau: np.ndarray  # the time order mapped onto [-1, 1]
    base_cv: np.ndarray | None = None  # leave-one-out residuals of a constant

    def loo(self, cols: list[np.ndarray]) -> np.ndarray:
        """Leave-one-out residuals of the linear model ``constant + cols``: e_i / (1 - h_ii)."""
        x = np.column_stack([np.ones(len(self.r))] + list(cols))
        hat = x @ np.linalg.pinv(x)
        return (self.r - hat @ self.r) / (1.0 - np.diag(hat))


def scalar_residual(series: ScalarSeries) -> np.ndarray:
    """``f_meas_after - f_ref`` (the file's calibration), else ``f_meas - f_ref``."""
    after = series.extra.get("f_meas_after")
    f = np.asarray(after if after is not None else series.f_meas_nT, dtype=float)
    return f - np.asarray(series.f_ref_nT)


def together_columns(heading_rad: np.ndarray, tau=None) -> list[np.ndarray]:
    """The scalar signatures of the TOGETHER effects, side by side."""
    return [c for name in TOGETHER for c in EFFECTS[name].scalar_columns(heading_rad, tau)]


def _checked(series: ScalarSeries) -> ScalarFit:
    if series.heading_deg is None:
        raise InputError("a scalar-only series needs heading_deg to be diagnosed")
    if series.f_ref_nT is None:
        raise InputError("no reference magnitude: give an f_ref column, --field NT, or a '# field_nT:' line")
    r = scalar_residual(series)
    n = len(r)
    if n < MIN_HEADINGS:
        raise InputError(f"{n} headings are too few to diagnose (need at least {MIN_HEADINGS})")
    order = np.argsort(series.t_s if series.t_s is not None else np.arange(n))
    tau = np.empty(n)
    tau[order] = np.linspace(-1, 1, n)
    s = ScalarFit(r, np.radians(series.heading_deg), order, tau)
    s.base_cv = s.loo([])
    return s


def score_scalar_effects(s: ScalarFit, rms_base: float, floor: float) -> list[dict]:
    """One entry per library effect with a scalar signature, best (lowest held-out RMS) first."""
    effects = []
    for cls in library_effects():
        cv = cls.scalar_heldout(s)
        if cv is None:
            continue
        z = paired_z(s.base_cv, cv)
        shrink = shrink_pct(rms_base, rms(cv), floor)
        effects.append({"name": cls.name, "rms_heldout_nT": rms(cv), "shrink_pct": shrink,
                        "significant": bool(z > Z_SIGNIFICANT and shrink > MIN_SIGNIFICANT_SHRINK_PCT), "z": z})
    return sorted(effects, key=lambda e: e["rms_heldout_nT"])


def diagnose_scalar(series: ScalarSeries, folds: int = 0, seed: int = 0) -> dict:
    """The scalar-series diagnosis (module docstring); ``folds`` and ``seed`` are unused (leave-one-out)."""
    s = _checked(series)
    n = len(s.r)
    rms_base = rms(s.base_cv)
    floor = second_difference_floor(s.r[s.order])
    effects = score_scalar_effects(s, rms_base, floor)
    rms_both = rms(s.loo(together_columns(s.heading_rad, s.tau)))
    return {"kind": "scalar_series", "base_model": "as given (the file's calibration)", "n_points": n,
            "rms_fit_nT": rms(s.r), "rms_base_nT": rms_base, "noise_floor_nT": float(floor),
            "verdict": verdict(effects, rms_base, floor, n), "effects": effects,
            "localization": {"heading_harmonics": harmonics(series.heading_deg, s.r)},
            "offset_and_scale_together": {"rms_heldout_nT": rms_both,
                                          "shrink_pct": 100.0 * (rms_base - rms_both) / max(rms_base - floor, MIN_GAP_NT)}}

"""The sim-to-real diagnosis: where the residual of a calibration lies, which unmodelled effect causes it,
and how far it shrinks once that effect is modelled (``magbench diagnose``, CONTRACT section 3).

1. Calibrate with the base model (``angles`` or ``nine``) and localize the residual: over attitude
   (the field direction in the sensor frame: variance explained by degree-1 and degree-2 spherical
   harmonics; Fourier harmonics of heading on turntable data), over time, against temperature, and in
   its distribution (excess kurtosis, share beyond 5 robust sigma).
2. Estimate the noise floor without any model: the scatter of each residual about the mean of its
   nearest neighbours in direction (and time, temperature), robustly (MAD).
3. Add each applicable library effect in turn (calibrators.extended) and measure the residual on data
   not used for the fit (K-fold cross-validation), so that added parameters cannot win by
   over-fitting; ``shrink_pct`` is the share of the gap (base minus floor) that the effect removes,
   ``significant`` a paired test on the held-out squared residuals (z > 3).
4. Verdict: ``none`` when the base residual is consistent with the floor and no effect helps; the best
   significant effect when it removes at least half of the gap; otherwise ``unexplained``.
5. Re-simulate the sensor with the fitted effect (and without it) at the observed attitudes and noise
   floor, calibrate again, and compare residual RMS and spectra with the observed ones.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.polynomial import legendre
from scipy.spatial import cKDTree

from magbench.calibrators import make
from magbench.calibrators.extended import EFFECT_PARAMS, Data, ExtendedModel, applicable_effects
from magbench.errors import InputError
from magbench.simulate.dataset import Dataset, ScalarSeries

Z_SIGNIFICANT = 3.0
MIN_SHRINK_PCT = 50.0
OUTLIER_SIGMA = 5.0


def robust_sigma(x: np.ndarray) -> float:
    x = np.asarray(x, dtype=float)
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def _folds(n: int, k: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).permutation(n) % k


def knn_floor(features: np.ndarray, r: np.ndarray, k: int = 6) -> float:
    """Noise floor: robust scatter of r_i about the mean of its k nearest neighbours in feature space,
    scaled by sqrt(k / (k + 1)) (the neighbours' mean carries noise too)."""
    k = min(k, len(r) - 1)
    _, idx = cKDTree(features).query(features, k=k + 1)
    local = r[idx[:, 1:]].mean(axis=1)
    return robust_sigma(r - local) * np.sqrt(k / (k + 1.0))


def _cv_r2(design: np.ndarray, r: np.ndarray, folds: np.ndarray) -> float:
    """Share (%) of the residual variance a linear model in ``design`` explains on held-out folds."""
    pred = np.empty_like(r)
    for f in np.unique(folds):
        tr, te = folds != f, folds == f
        coef, *_ = np.linalg.lstsq(design[tr], r[tr], rcond=None)
        pred[te] = design[te] @ coef
    return float(100.0 * (1.0 - np.sum((r - pred) ** 2) / np.sum((r - r.mean()) ** 2)))


def harmonics(heading_deg: np.ndarray, r: np.ndarray, k_max: int = 4) -> dict:
    """Amplitude (nT) of the residual at k cycles per revolution of the heading (least squares)."""
    h = np.radians(heading_deg)
    cols = [np.ones_like(h)] + [f(k * h) for k in range(1, k_max + 1) for f in (np.cos, np.sin)]
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), r, rcond=None)
    amps = {f"{k}_per_rev_nT": float(np.hypot(coef[2 * k - 1], coef[2 * k])) for k in range(1, k_max + 1)}
    fit = np.column_stack(cols) @ coef
    amps["mean_nT"] = float(coef[0])
    amps["rms_beyond_nT"] = float(np.sqrt(np.mean((r - fit) ** 2)))
    return amps


def _spherical_design(u: np.ndarray, degree: int) -> np.ndarray:
    x, y, z = u.T
    cols = [np.ones_like(x), x, y, z]
    if degree >= 2:
        cols += [x * y, x * z, y * z, x * x - y * y, 3 * z * z - 1]
    return np.column_stack(cols)


@dataclass
class _Cv:
    rms: float
    resid: np.ndarray  # held-out residuals, with spikes explained (zero) for the outlier model
    n_flagged: int = 0


class Diagnosis:
    """Runs the diagnosis of a vector dataset; ``result`` is the JSON-ready dict."""

    def __init__(self, data: Dataset, base: str = "nine", folds: int = 5, seed: int = 0):
        if base not in ("angles", "nine"):
            raise InputError(f"unknown base model {base!r}: use angles or nine")
        if not data.has_reference:
            raise InputError("no reference magnitude: give an f_ref column, --field NT, --igrf ..., or '# field_nT:'")
        self.dataset, self.base, self.k, self.seed = data, base, folds, seed
        self.d = Data(np.asarray(data.raw_nT), np.asarray(data.f_ref_nT),
                      None if data.t_s is None else np.asarray(data.t_s),
                      None if data.temp_C is None else np.asarray(data.temp_C))
        n = len(data)
        need = (9 if base == "nine" else 3) + 10
        if n < need:
            raise InputError(f"{n} points are too few to diagnose with the {base} model (need at least {need})")

    # -- fitting --------------------------------------------------------------------------------
    def _cv(self, effect: str, base_x: np.ndarray, spike_scale: float = 0.0) -> _Cv:
        model = ExtendedModel(self.base, "none" if effect == "outliers" else effect, self.d)
        folds = _folds(len(self.d.raw), self.k, self.seed)
        resid = np.empty(len(self.d.raw))
        flagged = 0
        for f in range(self.k):
            tr, te = folds != f, folds == f
            train = self.d.take(tr)
            x = model.fit(train, model.x0(base_x))
            r = model.residuals(x, self.d.take(te))
            if effect == "outliers":
                x, scale, centre = trimmed_fit(model, train, x)
                r = model.residuals(x, self.d.take(te))
                # held-out residuals of a small training set are inflated by leverage: a spike must also
                # stand out from the base model's own held-out scatter
                spike = np.abs(r - centre) > OUTLIER_SIGMA * max(scale, spike_scale)
                flagged += int(spike.sum())
                r = np.where(spike, 0.0, r)
            resid[te] = r
        return _Cv(float(np.sqrt(np.mean(resid**2))), resid, flagged)

    def run(self) -> dict:
        base_fit = make("lsq", model=self.base).fit(self.dataset)
        base_x = base_fit.x
        corrected = base_fit.correct(self.d.raw)
        r_all = np.linalg.norm(corrected, axis=1) - self.d.f_ref
        unit = corrected / np.linalg.norm(corrected, axis=1, keepdims=True)
        features = [unit]
        if self.d.t_s is not None and np.ptp(self.d.t_s) > 0:
            features.append(((self.d.t_s - self.d.t_s.min()) / np.ptp(self.d.t_s))[:, None])
        if self.d.temp_C is not None and np.ptp(self.d.temp_C) > 0:
            features.append(((self.d.temp_C - self.d.temp_C.min()) / np.ptp(self.d.temp_C))[:, None])
        floor = knn_floor(np.hstack(features), r_all)

        base_cv = self._cv("none", base_x)
        n = len(r_all)
        effects = []
        n_train = n * (self.k - 1) // self.k
        nb = len(base_x)
        for effect in applicable_effects(self.base, self.d):
            if n_train < 2 * (nb + len(EFFECT_PARAMS[effect])):
                continue  # too many parameters for the points available
            cv = self._cv(effect, base_x, spike_scale=robust_sigma(base_cv.resid))
            diff = base_cv.resid**2 - cv.resid**2
            z = float(np.mean(diff) / (np.std(diff, ddof=1) / np.sqrt(n))) if np.std(diff) > 0 else 0.0
            gap = base_cv.rms - floor
            shrink = 100.0 * (base_cv.rms - cv.rms) / gap if gap > 0 else 0.0
            if effect == "outliers":  # spikes: more beyond 5 robust sigma than Gaussian noise would give
                significant = cv.n_flagged >= max(3, 0.005 * n) and shrink > 10.0
            else:
                significant = z > Z_SIGNIFICANT and shrink > 10.0
            item = {"name": effect, "rms_heldout_nT": cv.rms, "shrink_pct": shrink,
                    "significant": bool(significant), "z": z,
                    "n_parameters": len(EFFECT_PARAMS[effect]) if effect != "outliers" else cv.n_flagged}
            effects.append(item)
        effects.sort(key=lambda e: e["rms_heldout_nT"])
        verdict = _verdict(effects, base_cv.rms, floor, n)
        self._winner = next((e for e in effects if e["name"] == verdict), None)
        self._unit = unit  # the observed attitudes, for the re-simulation
        out = {"kind": "vector", "base_model": self.base, "n_points": n, "rms_fit_nT": float(np.sqrt(np.mean(r_all**2))),
               "rms_base_nT": base_cv.rms, "noise_floor_nT": floor, "verdict": verdict, "effects": effects,
               "folds": self.k, "seed": self.seed, "localization": self.localize(r_all, unit),
               "base_params": dict(zip(ExtendedModel(self.base, "none", self.d).names, map(float, base_x)))}
        if self._winner is not None:
            model = ExtendedModel(self.base, verdict if verdict != "outliers" else "none", self.d)
            x = model.fit(self.d, model.x0(base_x))
            if verdict == "outliers":
                x = trimmed_fit(model, self.d, x)[0]
            out["winner_params"] = dict(zip(model.names, map(float, x)))
            out["resimulation"] = self.resimulate(verdict, model, x, floor, r_all)
        return out

    # -- where the residual lies ------------------------------------------------------------------
    def localize(self, r: np.ndarray, unit: np.ndarray) -> dict:
        folds = _folds(len(r), self.k, self.seed + 1)
        loc = {"attitude_deg1_explained_pct": _cv_r2(_spherical_design(unit, 1), r, folds),
               "attitude_deg2_explained_pct": _cv_r2(_spherical_design(unit, 2), r, folds)}
        if self.d.t_s is not None and np.ptp(self.d.t_s) > 0:
            order = np.argsort(self.d.t_s)
            tau = 2 * (self.d.t_s - self.d.t_s.min()) / np.ptp(self.d.t_s) - 1
            loc["time_explained_pct"] = _cv_r2(legendre.legvander(tau, 8), r, folds)
            rs = r[order] - r.mean()
            loc["time_lag1_autocorrelation"] = float(np.sum(rs[1:] * rs[:-1]) / np.sum(rs * rs))
        if self.d.temp_C is not None and np.ptp(self.d.temp_C) > 0:
            loc["temperature_correlation"] = float(np.corrcoef(self.d.temp_C, r)[0, 1])
        if self.dataset.heading_deg is not None:
            loc["heading_harmonics"] = harmonics(self.dataset.heading_deg, r)
        s = robust_sigma(r)
        loc["excess_kurtosis"] = float(np.mean((r - r.mean()) ** 4) / np.var(r) ** 2 - 3.0)
        loc["beyond_5_robust_sigma_pct"] = float(100.0 * np.mean(np.abs(r - np.median(r)) > OUTLIER_SIGMA * s))
        return loc

    # -- how far it shrinks: re-simulation ------------------------------------------------------
    def resimulate(self, effect: str, model: ExtendedModel, x: np.ndarray, floor: float, r_obs: np.ndarray) -> dict:
        """Simulate the sensor at the observed attitudes (the corrected field directions, scaled to the
        reference) with the fitted base errors, white noise at the floor, and the fitted effect or none;
        calibrate with the base model and compare residual statistics with the observation."""
        from magbench.simulate import effects as fx

        rng = np.random.default_rng(self.seed + 7)
        base_x = x[:model.nb]
        e = x[model.nb:]
        b_true = self._unit * self.d.f_ref[:, None]
        from magbench.calibrators.objective import correction_matrices

        mat, o = correction_matrices(base_x[None, :], self.base)
        lin = b_true @ np.linalg.inv(mat[0]).T + o[0]
        ctx = {"t_s": self.d.t_s, "temp_C": self.d.temp_C, "offset_nT": tuple(o[0]), "f_nT": model.f0}
        f_ref = self.d.f_ref
        eff = None
        if effect == "offset":
            eff = fx.OffsetEffect(tuple(e))
        elif effect == "scale":
            eff = fx.ScaleEffect(tuple(e))
        elif effect == "temperature":
            eff = fx.TemperatureEffect(tuple(e[:3]), tuple(e[3:]), ref_C=model.temp0)
        elif effect == "nonlinearity":
            eff = fx.NonlinearityEffect(tuple(e))
        stats = {}
        for label, with_effect in (("without_effect", False), ("with_effect", True)):
            raw = lin.copy()
            ref = f_ref
            if with_effect and eff is not None:
                raw = eff.readings(raw, ctx, rng)
            if with_effect and effect == "field_drift":
                tau = 2.0 * (self.d.t_s - model.t0) / model.t_span - 1.0
                ref = f_ref - legendre.legvander(tau, len(e))[:, 1:] @ e
            raw = raw + rng.normal(0.0, floor, raw.shape)
            if with_effect and effect == "outliers":
                flagged = np.abs(r_obs - np.median(r_obs)) > OUTLIER_SIGMA * robust_sigma(r_obs)
                raw[flagged] += (r_obs[flagged] - np.median(r_obs))[:, None] * self._unit[flagged]
            sim = Dataset(raw, f_ref_nT=ref, t_s=self.d.t_s, temp_C=self.d.temp_C,
                          heading_deg=self.dataset.heading_deg)
            fit = make("lsq", model=self.base).fit(sim)
            r_sim = np.linalg.norm(fit.correct(raw), axis=1) - ref
            stats[label] = {"rms_nT": float(np.sqrt(np.mean(r_sim**2))), **self._spectrum(r_sim)}
        observed = {"rms_nT": float(np.sqrt(np.mean(r_obs**2))), **self._spectrum(r_obs)}
        gap = abs(stats["with_effect"]["rms_nT"] - observed["rms_nT"]) / observed["rms_nT"]
        return {"observed": observed, **stats, "remaining_gap_pct": 100.0 * gap,
                "gap_without_effect_pct": 100.0 * abs(stats["without_effect"]["rms_nT"] - observed["rms_nT"])
                / observed["rms_nT"]}

    def _spectrum(self, r: np.ndarray) -> dict:
        if self.dataset.heading_deg is not None:
            h = harmonics(self.dataset.heading_deg, r)
            return {k: v for k, v in h.items() if k.endswith("per_rev_nT")}
        if self.d.t_s is not None and np.ptp(self.d.t_s) > 0:
            rs = r[np.argsort(self.d.t_s)]
            p = np.abs(np.fft.rfft(rs - rs.mean())) ** 2 / len(rs)
            bands = np.array_split(np.arange(1, len(p)), 4)
            return {f"time_band{i + 1}_rms_nT": float(np.sqrt(2 * p[b].sum() / len(rs))) for i, b in enumerate(bands)}
        return {}


def trimmed_fit(model: ExtendedModel, d: Data, x: np.ndarray, rounds: int = 2):
    """The outlier model: least squares refitted without the samples beyond 5 robust sigma (twice).
    Returns the parameters, the robust residual scale and centre of the inliers."""
    for _ in range(rounds):
        r = model.residuals(x, d)
        centre, scale = np.median(r), robust_sigma(r)
        keep = np.abs(r - centre) <= OUTLIER_SIGMA * scale
        if keep.all() or keep.sum() < model.n_params + 2:
            break
        x = model.fit(d.take(keep), x)
    r = model.residuals(x, d)
    return x, robust_sigma(r), float(np.median(r))


def _verdict(effects: list[dict], rms_base: float, floor: float, n: int) -> str:
    """The best significant effect that removes at least half of the gap; else ``none`` when the base
    residual is within 4/sqrt(n) of the noise floor, else ``unexplained``."""
    best = next((e for e in effects if e["significant"]), None)
    if best is not None and best["shrink_pct"] >= MIN_SHRINK_PCT:
        return best["name"]
    return "none" if rms_base <= floor * (1.0 + 4.0 / np.sqrt(n)) else "unexplained"


def diagnose(data, base: str = "nine", folds: int = 5, seed: int = 0) -> dict:
    """Diagnose a vector ``Dataset`` or a scalar turntable ``ScalarSeries``."""
    if isinstance(data, ScalarSeries):
        return diagnose_scalar(data, folds=folds, seed=seed)
    return Diagnosis(data, base, folds, seed).run()


# ---------------------------------------------------------------------------------------------- scalar series
SCALAR_EFFECTS = {  # first-order signatures on a level turntable
    "offset": (1,),  # hard iron / zero offsets: one cycle per revolution
    "scale": (2,),  # scale mismatch (and gamma): two cycles per revolution
    "nonlinearity": (3, 4),  # a quadratic/cubic response adds higher harmonics
}


def diagnose_scalar(series: ScalarSeries, folds: int = 0, seed: int = 0) -> dict:
    """Seed 000's Table 2 style: total field per turntable heading, after the paper's calibration.

    The residual is ``f_meas_after - f_ref`` (else ``f_meas - f_ref``).  Effects are their first-order
    signatures in heading (offset: 1 cycle/rev, scale: 2, nonlinearity: 3 and 4), ``field_drift`` a
    cubic in time (heading order), ``outliers`` spikes beyond 5 robust sigma; each is scored by
    leave-one-out cross-validation against a constant.
    """
    if series.heading_deg is None:
        raise InputError("a scalar-only series needs heading_deg to be diagnosed")
    if series.f_ref_nT is None:
        raise InputError("no reference magnitude: give an f_ref column, --field NT, or a '# field_nT:' line")
    after = series.extra.get("f_meas_after")
    f = np.asarray(after if after is not None else series.f_meas_nT, dtype=float)
    r = f - np.asarray(series.f_ref_nT)
    n = len(r)
    if n < 12:
        raise InputError(f"{n} headings are too few to diagnose (need at least 12)")
    h = np.radians(series.heading_deg)
    order = np.argsort(series.t_s if series.t_s is not None else np.arange(n))
    tau = np.empty(n)
    tau[order] = np.linspace(-1, 1, n)

    def design(effect):
        cols = [np.ones(n)]
        if effect in SCALAR_EFFECTS:
            cols += [f(k * h) for k in SCALAR_EFFECTS[effect] for f in (np.cos, np.sin)]
        elif effect == "field_drift":
            cols += list(legendre.legvander(tau, 3)[:, 1:].T)
        return np.column_stack(cols)

    def loo(effect):
        x = design(effect)
        hat = x @ np.linalg.pinv(x)
        res = r - hat @ r
        cv = res / (1.0 - np.diag(hat))  # leave-one-out residuals of a linear model
        return cv

    base_cv = loo("none")
    rms_base = float(np.sqrt(np.mean(base_cv**2)))
    d2 = r[order][1:-1] - 0.5 * (r[order][:-2] + r[order][2:])  # second differences along the turn
    floor = robust_sigma(d2) / np.sqrt(1.5)
    effects = []
    for effect in ("offset", "scale", "nonlinearity", "field_drift", "outliers"):
        if effect == "outliers":
            s = robust_sigma(r)
            spikes = np.abs(r - np.median(r)) > OUTLIER_SIGMA * s
            cv = np.where(spikes, 0.0, base_cv)
        else:
            cv = loo(effect)
        diff = base_cv**2 - cv**2
        z = float(np.mean(diff) / (np.std(diff, ddof=1) / np.sqrt(n))) if np.std(diff) > 0 else 0.0
        rms = float(np.sqrt(np.mean(cv**2)))
        gap = rms_base - floor
        shrink = 100.0 * (rms_base - rms) / gap if gap > 0 else 0.0
        effects.append({"name": effect, "rms_heldout_nT": rms, "shrink_pct": shrink,
                        "significant": bool(z > Z_SIGNIFICANT and shrink > 10.0), "z": z})
    effects.sort(key=lambda e: e["rms_heldout_nT"])
    verdict = _verdict(effects, rms_base, floor, n)
    # the combination of the harmonic effects, for "how far the residual would shrink"
    both = np.column_stack([design("offset"), design("scale")[:, 1:]])
    hat = both @ np.linalg.pinv(both)
    cv_both = (r - hat @ r) / (1.0 - np.diag(hat))
    return {"kind": "scalar_series", "base_model": "as given (the file's calibration)", "n_points": n,
            "rms_fit_nT": float(np.sqrt(np.mean(r**2))), "rms_base_nT": rms_base, "noise_floor_nT": float(floor),
            "verdict": verdict, "effects": effects,
            "localization": {"heading_harmonics": harmonics(series.heading_deg, r)},
            "offset_and_scale_together": {"rms_heldout_nT": float(np.sqrt(np.mean(cv_both**2))),
                                          "shrink_pct": 100.0 * (rms_base - float(np.sqrt(np.mean(cv_both**2))))
                                          / max(rms_base - floor, 1e-9)}}


# ---------------------------------------------------------------------------------------------- output
def diagnosis_text(result: dict, source: str = "") -> str:
    """The human table of a diagnosis."""
    lines = [f"diagnosis of {source} ({result['n_points']} points, base model: {result['base_model']})",
             f"  residual RMS {result['rms_fit_nT']:.3f} nT on the fit, {result['rms_base_nT']:.3f} nT held out; "
             f"noise floor {result['noise_floor_nT']:.3f} nT",
             "", f"  {'effect':<14}{'held-out RMS nT':>16}{'shrink %':>10}{'z':>8}  significant"]
    for e in result["effects"]:
        lines.append(f"  {e['name']:<14}{e['rms_heldout_nT']:>16.3f}{e['shrink_pct']:>10.1f}{e['z']:>8.1f}  "
                     f"{'yes' if e['significant'] else 'no'}")
    loc = result.get("localization", {})
    if loc:
        lines.append("")
        lines.append("  where the residual lies:")
        for k, v in loc.items():
            if isinstance(v, dict):
                lines.append(f"    {k}: " + ", ".join(f"{kk} {vv:.2f}" for kk, vv in v.items()))
            else:
                lines.append(f"    {k}: {v:.3f}")
    if "resimulation" in result:
        rs = result["resimulation"]
        lines.append("")
        lines.append(f"  re-simulated: residual RMS {rs['without_effect']['rms_nT']:.3f} nT without the effect, "
                     f"{rs['with_effect']['rms_nT']:.3f} nT with it, observed {rs['observed']['rms_nT']:.3f} nT "
                     f"(remaining gap {rs['remaining_gap_pct']:.1f} %)")
    if "offset_and_scale_together" in result:
        both = result["offset_and_scale_together"]
        lines.append(f"  offset (1/rev) and scale (2/rev) together: held-out RMS {both['rms_heldout_nT']:.2f} nT "
                     f"(shrink {both['shrink_pct']:.0f} %)")
    lines.append("")
    lines.append(f"  verdict: {result['verdict']}")
    if result.get("figure"):
        lines.append(f"  figure: {result['figure']}")
    return "\n".join(lines)


def diagnosis_figure(data, result: dict, path) -> None:
    """Residual before and after the winning effect, against heading (turntable) or time or sample."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 4.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(111)
    if isinstance(data, ScalarSeries):
        after = data.extra.get("f_meas_after")
        f = np.asarray(after if after is not None else data.f_meas_nT)
        r = f - np.asarray(data.f_ref_nT)
        x, label = np.asarray(data.heading_deg), "turntable heading (deg)"
        ax.plot(x, r, "o-", label="residual of the file's calibration")
        h = np.radians(x)
        cols = np.column_stack([np.ones_like(h), np.cos(h), np.sin(h), np.cos(2 * h), np.sin(2 * h)])
        coef, *_ = np.linalg.lstsq(cols, r, rcond=None)
        ax.plot(x, r - cols @ coef, "s-", label="after removing 1 and 2 cycles/rev (offset + scale)")
    else:
        d = Diagnosis(data, result["base_model"] if result["base_model"] in ("angles", "nine") else "nine")
        fit = make("lsq", model=d.base).fit(data)
        r = np.linalg.norm(fit.correct(np.asarray(data.raw_nT)), axis=1) - np.asarray(data.f_ref_nT)
        if data.heading_deg is not None:
            x, label = np.asarray(data.heading_deg), "heading (deg)"
        elif data.t_s is not None:
            x, label = np.asarray(data.t_s), "time (s)"
        else:
            x, label = np.arange(len(r)), "sample"
        ax.plot(x, r, ".", ms=3, label=f"base model ({result['base_model']})")
        if result["verdict"] in EFFECT_PARAMS and "winner_params" in result:
            model = ExtendedModel(d.base, result["verdict"] if result["verdict"] != "outliers" else "none", d.d)
            xw = np.array(list(result["winner_params"].values()))
            ax.plot(x, model.residuals(xw, d.d), ".", ms=3, label=f"with {result['verdict']}")
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel(label)
    ax.set_ylabel("total-field residual (nT)")
    ax.set_title(f"verdict: {result['verdict']}  (noise floor {result['noise_floor_nT']:.2f} nT)")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110, metadata={"Software": None})


# ---------------------------------------------------------------------------------------------- blind check
BLIND_KINDS = ("none", "scale", "offset", "temperature", "field_drift", "nonlinearity", "outliers")
BLIND_STRENGTH = {"nonlinearity": 2.0, "field_drift": 2.0}


def blind_dataset(i: int):
    """Dataset i of the blind check: (true effect, base model, data).  The effect cycles through
    ``none`` and the library; its parameters and the data seed are drawn from seed 1000 + i; scale and
    offset (and every other ``none``) use the angles-only tumble, the rest the 9-parameter one."""
    from magbench.simulate.effects import random_effect
    from magbench.simulate.scenarios import get_scenario

    rng = np.random.default_rng(1000 + i)
    kind = BLIND_KINDS[i % len(BLIND_KINDS)]
    base = "angles" if kind in ("scale", "offset") or (kind == "none" and i % 2) else "nine"
    scenario = get_scenario("tumble3" if base == "angles" else "tumble9q")
    if kind != "none":
        scenario = scenario.with_effects(random_effect(kind, rng, BLIND_STRENGTH.get(kind, 1.0)))
    return kind, base, scenario.build(int(rng.integers(2**31)))

"""Effects that simple calibration models leave out: one class per effect, one registry (``EFFECTS``).

Names follow CONTRACT section 3: ``scale``, ``offset`` (relative to the ``angles`` model),
``temperature`` (offset and scale drifting with temperature), ``field_drift`` (the ambient field
changing in time, unseen by the reference), ``nonlinearity`` (per-axis response beyond linear),
``outliers`` (sparse spikes, seed 003).  ``attitude_ripple`` is deliberately *outside* the library
(``in_library = False``: a high-order attitude-dependent error no library model can represent); the
diagnosis must not claim it.

Each class carries both sides of its effect:

* the **forward model** the simulator applies (``simulate.scenarios``), one hook per stage of

      field (NED, time) -> attitude -> linear sensor (K P^-1 B + o) -> effect on readings -> noise -> spikes

  (``field``, ``temperature``, ``readings``, ``spikes``; each returns its input unchanged by default);

* the **fitted form** the sim-to-real diagnosis adds to a base correction (``angles`` or ``nine``,
  CONTRACT section 1; ``benchmarks.diagnosis``): extra parameters ``fit_params``, their start values
  (``fit_start``) and bounds (``fit_bounds``), and where they enter the scalar residual

      u = raw - fit_offset(o)                 ``offset``
      u = fit_readings(u)                     ``temperature``, ``nonlinearity``, ``scale``
      r = |P(alpha, beta, gamma) K^-1 u| - F
      r = fit_residual(r)                     ``field_drift``

  with its held-out scoring (``heldout_residuals``; ``outliers`` is a trimmed robust fit), how a fitted
  effect is re-simulated (``from_fit``, ``resim_reference``, ``resim_spikes``) and its first-order
  signature on a level turntable's scalar series (``heading_harmonics``, ``scalar_columns``).

Adding an effect is one new class decorated with ``@register_effect`` in this file (or in a plug-in):
the simulator (``Scenario.with_effects``), ``magbench list`` and the diagnosis's candidate effects all
read the registry.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import ClassVar

import numpy as np
from numpy.polynomial import legendre

from magbench.errors import InputError

from .field import ConstantField, VaryingField

PPM = 1e-6
SPIKE_SIGMA = 5.0
"""A sample further than this many robust sigmas (MAD) from the median residual is a spike (seed 003)."""
MIN_TEMPERATURE_SPAN_C = 1.0
"""Least temperature range (max - min) that makes a temperature effect identifiable."""
MIN_SPAN_S = 1e-9
"""Least time span used as a divisor (a record at one instant)."""
MAD_TO_SIGMA = 1.4826
"""Robust sigma = 1.4826 median |x - median x| (consistent with the standard deviation for Gaussian x)."""


def robust_sigma(x: np.ndarray) -> float:
    """The scale estimate MAD_TO_SIGMA * median absolute deviation (Hampel 1974)."""
    x = np.asarray(x, dtype=float)
    return float(MAD_TO_SIGMA * np.median(np.abs(x - np.median(x))))


# ---------------------------------------------------------------------------------------------- data
@dataclass(frozen=True)
class Column:
    """A data column an effect needs (CONTRACT section 2 name), the ``Columns`` field that holds it, and
    the least spread (max - min) that makes it informative (any spread at all when ``min_span`` is 0)."""

    csv: str
    field: str
    min_span: float = 0.0

    def informative(self, d: "Columns") -> bool:
        values = getattr(d, self.field)
        if values is None:
            return False
        span = float(np.ptp(values))
        return span > 0 and span >= self.min_span


COLUMNS = {c.csv: c for c in (Column("t", "t_s"), Column("temp", "temp_C", MIN_TEMPERATURE_SPAN_C))}


@dataclass
class Columns:
    """The columns the fitted forms use (a subset of a Dataset, e.g. one cross-validation fold)."""

    raw_nT: np.ndarray
    f_ref_nT: np.ndarray
    t_s: np.ndarray | None = None
    temp_C: np.ndarray | None = None

    @classmethod
    def of(cls, data) -> "Columns":
        """The columns of a ``Dataset`` as plain arrays."""
        opt = lambda v: None if v is None else np.asarray(v)  # noqa: E731
        return cls(np.asarray(data.raw_nT), np.asarray(data.f_ref_nT), opt(data.t_s), opt(data.temp_C))

    def take(self, idx) -> "Columns":
        return Columns(self.raw_nT[idx], self.f_ref_nT[idx], None if self.t_s is None else self.t_s[idx],
                       None if self.temp_C is None else self.temp_C[idx])


@dataclass(frozen=True)
class Normalization:
    """Fixed from the full record, so that every fold gives the effect parameters the same meaning: the
    median reference F0, the time origin and span, the mean temperature."""

    f0_nT: float
    t0_s: float | None = None
    t_span_s: float | None = None
    temp0_C: float | None = None

    @classmethod
    def of(cls, d: Columns) -> "Normalization":
        t0 = span = temp0 = None
        if d.t_s is not None:
            t0, span = float(d.t_s.min()), max(float(np.ptp(d.t_s)), MIN_SPAN_S)
        if d.temp_C is not None:
            temp0 = float(np.mean(d.temp_C))
        return cls(float(np.median(d.f_ref_nT)), t0, span, temp0)

    def tau(self, t_s: np.ndarray) -> np.ndarray:
        """Time mapped onto [-1, 1] (the Legendre domain)."""
        return 2.0 * (t_s - self.t0_s) / self.t_span_s - 1.0


# ---------------------------------------------------------------------------------------------- registry
EFFECTS: dict[str, type["Effect"]] = {}
"""The one effect registry: name -> class, in registration order."""


def register_effect(cls: type["Effect"]) -> type["Effect"]:
    """Class decorator: add an effect under ``cls.name``; a second class with the same name is refused."""
    if not cls.name:
        raise ValueError(f"{cls.__name__} has no 'name'")
    if EFFECTS.get(cls.name, cls) is not cls:
        raise ValueError(f"an effect named {cls.name!r} is already registered ({EFFECTS[cls.name].__qualname__})")
    EFFECTS[cls.name] = cls
    return cls


def unregister_effect(name: str) -> None:
    EFFECTS.pop(name, None)


def get_effect(name: str) -> type["Effect"]:
    try:
        return EFFECTS[name]
    except KeyError:
        raise InputError(f"unknown effect {name!r}; known: {', '.join(EFFECTS)}") from None


def effect_names(in_library: bool | None = None) -> tuple[str, ...]:
    """Registered effect names; only those in (or outside) the fitted library when ``in_library`` is given."""
    return tuple(n for n, cls in EFFECTS.items() if in_library is None or cls.in_library == in_library)


def library_effects() -> tuple[type["Effect"], ...]:
    """The effects the diagnosis may fit and claim."""
    return tuple(cls for cls in EFFECTS.values() if cls.in_library)


def make_effect(name: str, **params) -> "Effect":
    """An effect by name with its default parameters, or those given."""
    return get_effect(name)(**params)


def random_effect(name: str, rng: np.random.Generator, strength: float = 1.0) -> "Effect":
    """An effect of the named kind with random parameters (signs and axes drawn), scaled by ``strength``."""
    return get_effect(name).random(rng, strength)


def _signed(rng: np.random.Generator, k: int) -> np.ndarray:
    """k random signs times magnitudes uniform in [0.5, 1)."""
    return rng.choice([-1.0, 1.0], size=k) * rng.uniform(0.5, 1.0, size=k)


# ---------------------------------------------------------------------------------------------- base class
@dataclass(frozen=True)
class Effect:
    """An unmodelled effect: its forward model (instance hooks) and its fitted form (class hooks)."""

    name: ClassVar[str] = ""
    in_library: ClassVar[bool] = True  # False: forward only, never fitted nor claimed by the diagnosis
    needs: ClassVar[tuple[str, ...]] = ()  # dataset columns (CONTRACT section 2 names) the fitted form needs
    included_in: ClassVar[tuple[str, ...]] = ()  # base models that already contain the effect
    unseen_by_reference: ClassVar[bool] = False  # the simulated reference stays at its initial value
    blind_strength: ClassVar[float] = 1.0  # strength of the effect in the diagnosis's blind check
    fit_params: ClassVar[tuple[str, ...]] = ()  # extra parameters of the fitted form
    heading_harmonics: ClassVar[tuple[int, ...]] = ()  # cycles per revolution on a level turntable

    def as_dict(self) -> dict:
        return {"name": self.name, **{k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}}

    @classmethod
    def random(cls, rng: np.random.Generator, strength: float = 1.0) -> "Effect":
        """An instance with random parameters scaled by ``strength`` (default: the default parameters)."""
        return cls()

    # -- forward model (simulator) ---------------------------------------------------------------
    def field(self, b_ned: np.ndarray, t_s: np.ndarray, rng) -> np.ndarray:
        return b_ned

    def readings(self, lin: np.ndarray, ctx: dict, rng) -> np.ndarray:
        """Noise-free readings (n, 3) -> readings with the effect; ``ctx`` has t_s, temp_C, offset_nT, f_nT."""
        return lin

    def spikes(self, raw: np.ndarray, rng) -> np.ndarray:
        return raw

    def temperature(self, t_s: np.ndarray, rng) -> np.ndarray | None:
        return None

    # -- fitted form (diagnosis) -----------------------------------------------------------------
    @classmethod
    def applicable(cls, base: str, d: Columns) -> bool:
        """Fittable on these data with this base model: in the library, not already in the base model, and
        every needed column present with some spread."""
        return cls.in_library and base not in cls.included_in and all(COLUMNS[c].informative(d) for c in cls.needs)

    @classmethod
    def fit_start(cls) -> np.ndarray:
        """Start values of ``fit_params`` (the effect absent)."""
        return np.zeros(len(cls.fit_params))

    @classmethod
    def fit_bounds(cls, norm: Normalization) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of ``fit_params`` (free by default)."""
        k = len(cls.fit_params)
        return np.full(k, -np.inf), np.full(k, np.inf)

    @classmethod
    def fit_offset(cls, o: np.ndarray, e: np.ndarray) -> np.ndarray:
        """The offset subtracted from the readings, given the base offset ``o`` and effect parameters ``e``."""
        return o

    @classmethod
    def fit_readings(cls, u: np.ndarray, e: np.ndarray, d: Columns, norm: Normalization) -> np.ndarray:
        """Offset-free readings (n, 3) -> readings with the effect removed, before the base matrix."""
        return u

    @classmethod
    def fit_residual(cls, r: np.ndarray, e: np.ndarray, d: Columns, norm: Normalization) -> np.ndarray:
        """The scalar residual |B| - F -> the residual with the effect's contribution removed."""
        return r

    @classmethod
    def fit_model(cls, model, d: Columns, x_start: np.ndarray) -> np.ndarray:
        """Parameters of ``model`` (base + this effect, ``benchmarks.diagnosis.model``) fitted to ``d``."""
        return model.fit(d, x_start)

    @classmethod
    def heldout_residuals(cls, model, train: Columns, test: Columns, x_start: np.ndarray,
                          spike_scale: float) -> tuple[np.ndarray, int]:
        """Residuals on ``test`` of the model fitted on ``train``, and the number of test samples the
        effect explains away (spikes; none by default)."""
        return model.residuals(cls.fit_model(model, train, x_start), test), 0

    @classmethod
    def evidence(cls, z: float, n_flagged: int, n: int, z_threshold: float) -> bool:
        """The held-out evidence for the effect: a paired test on the squared residuals beyond ``z_threshold``."""
        return z > z_threshold

    @classmethod
    def from_fit(cls, e: np.ndarray, norm: Normalization) -> "Effect | None":
        """The forward effect with the fitted parameters, when the readings carry it (else None)."""
        return None

    @classmethod
    def resim_reference(cls, f_ref_nT: np.ndarray, e: np.ndarray, d: Columns, norm: Normalization) -> np.ndarray:
        """The reference a re-simulation of the fitted effect uses."""
        return f_ref_nT

    @classmethod
    def resim_spikes(cls, raw: np.ndarray, r_obs: np.ndarray, unit: np.ndarray) -> np.ndarray:
        """Noisy re-simulated readings -> with the fitted effect's spikes (none by default)."""
        return raw

    @classmethod
    def scalar_columns(cls, heading_rad: np.ndarray, tau: np.ndarray) -> list[np.ndarray] | None:
        """Design columns of the effect's first-order signature in a turntable's scalar series (``tau``: the
        time order mapped onto [-1, 1]); None when a scalar series cannot show it."""
        if not cls.heading_harmonics:
            return None
        return [f(k * heading_rad) for k in cls.heading_harmonics for f in (np.cos, np.sin)]

    @classmethod
    def scalar_heldout(cls, s) -> np.ndarray | None:
        """Leave-one-out residuals of the scalar series ``s`` (``benchmarks.diagnosis.scalar``) with the
        effect's signature fitted; None when the effect has none."""
        cols = cls.scalar_columns(s.heading_rad, s.tau)
        return None if cols is None else s.loo(cols)


# ---------------------------------------------------------------------------------------------- the library
@register_effect
@dataclass(frozen=True)
class ScaleEffect(Effect):
    """Per-axis scale factors on top of an ``angles``-model sensor: raw_j = k_j lin_j (about the offset)."""

    name: ClassVar[str] = "scale"
    included_in: ClassVar[tuple[str, ...]] = ("nine",)
    fit_params: ClassVar[tuple[str, ...]] = ("kx", "ky", "kz")
    heading_harmonics: ClassVar[tuple[int, ...]] = (2,)  # scale mismatch (and gamma): two cycles per revolution
    FIT_RANGE: ClassVar[tuple[float, float]] = (0.5, 2.0)
    RANDOM_SIZE: ClassVar[float] = 0.01
    scale: tuple[float, float, float] = (1.01, 0.99, 1.005)

    @classmethod
    def random(cls, rng, strength=1.0):
        return cls(tuple(1.0 + strength * cls.RANDOM_SIZE * _signed(rng, 3)))

    def readings(self, lin, ctx, rng):
        o = np.asarray(ctx["offset_nT"])
        return (lin - o) * np.asarray(self.scale) + o

    @classmethod
    def fit_start(cls):
        return np.ones(3)

    @classmethod
    def fit_bounds(cls, norm):
        lo, hi = cls.FIT_RANGE
        return np.full(3, lo), np.full(3, hi)

    @classmethod
    def fit_readings(cls, u, e, d, norm):
        """u / k (CONTRACT section 1: B = P K^-1 (raw - o))."""
        return u / e

    @classmethod
    def from_fit(cls, e, norm):
        return cls(tuple(e))


@register_effect
@dataclass(frozen=True)
class OffsetEffect(Effect):
    """Per-axis offsets (hard iron, zero-point bias) on top of an ``angles``-model sensor."""

    name: ClassVar[str] = "offset"
    included_in: ClassVar[tuple[str, ...]] = ("nine",)
    fit_params: ClassVar[tuple[str, ...]] = ("ox_nT", "oy_nT", "oz_nT")
    heading_harmonics: ClassVar[tuple[int, ...]] = (1,)  # hard iron / zero offsets: one cycle per revolution
    FIT_BOX_OF_FIELD: ClassVar[float] = 0.2  # |o| within 20 % of the field
    RANDOM_SIZE_NT: ClassVar[float] = 150.0
    offset_nT: tuple[float, float, float] = (150.0, -100.0, 80.0)

    @classmethod
    def random(cls, rng, strength=1.0):
        return cls(tuple(strength * cls.RANDOM_SIZE_NT * _signed(rng, 3)))

    def readings(self, lin, ctx, rng):
        return lin + np.asarray(self.offset_nT)

    @classmethod
    def fit_bounds(cls, norm):
        half = cls.FIT_BOX_OF_FIELD * norm.f0_nT
        return np.full(3, -half), np.full(3, half)

    @classmethod
    def fit_offset(cls, o, e):
        return o + e

    @classmethod
    def from_fit(cls, e, norm):
        return cls(tuple(e))


@register_effect
@dataclass(frozen=True)
class TemperatureEffect(Effect):
    """Offset and scale drifting linearly with temperature about ``ref_C``:
    raw_j = o_j + o_T,j (T - T0) + (1 + k_T,j (T - T0)) (lin_j - o_j).  The temperature follows a warm-up
    ramp from ``start_C`` to ``end_C`` with a slow oscillation, written to the ``temp`` column."""

    name: ClassVar[str] = "temperature"
    needs: ClassVar[tuple[str, ...]] = ("temp",)
    fit_params: ClassVar[tuple[str, ...]] = ("oTx_nT_per_C", "oTy_nT_per_C", "oTz_nT_per_C",
                                             "kTx_ppm_per_C", "kTy_ppm_per_C", "kTz_ppm_per_C")
    RAMP_RATE: ClassVar[float] = 3.0  # warm-up time constant: a third of the record
    RIPPLE_C: ClassVar[float] = 1.5
    RIPPLE_CYCLES: ClassVar[float] = 2.3
    RANDOM_OFFSET_NT_PER_C: ClassVar[float] = 3.0
    RANDOM_SCALE_PPM_PER_C: ClassVar[float] = 60.0
    offset_nT_per_C: tuple[float, float, float] = (3.0, -2.0, 2.5)
    scale_ppm_per_C: tuple[float, float, float] = (60.0, -40.0, 30.0)
    start_C: float = 10.0
    end_C: float = 35.0
    ref_C: float = 20.0

    @classmethod
    def random(cls, rng, strength=1.0):
        offset = tuple(strength * cls.RANDOM_OFFSET_NT_PER_C * _signed(rng, 3))
        return cls(offset, tuple(strength * cls.RANDOM_SCALE_PPM_PER_C * _signed(rng, 3)))

    def temperature(self, t_s, rng):
        u = (t_s - t_s.min()) / max(np.ptp(t_s), MIN_SPAN_S)
        a = self.RAMP_RATE
        ramp = self.start_C + (self.end_C - self.start_C) * (1 - np.exp(-a * u)) / (1 - np.exp(-a))
        return ramp + self.RIPPLE_C * np.sin(2 * np.pi * self.RIPPLE_CYCLES * u + rng.uniform(0, 2 * np.pi))

    def readings(self, lin, ctx, rng):
        dt = (ctx["temp_C"] - self.ref_C)[:, None]
        o = np.asarray(ctx["offset_nT"])
        return o + np.asarray(self.offset_nT_per_C) * dt + (1 + PPM * np.asarray(self.scale_ppm_per_C) * dt) * (lin - o)

    @classmethod
    def fit_readings(cls, u, e, d, norm):
        """The inverse of ``readings`` about the mean temperature: u = (u - o_T dT) / (1 + k_T dT)."""
        dt = (d.temp_C - norm.temp0_C)[:, None]
        return (u - e[:3] * dt) / (1.0 + PPM * e[3:6] * dt)

    @classmethod
    def from_fit(cls, e, norm):
        return cls(tuple(e[:3]), tuple(e[3:]), ref_C=norm.temp0_C)


@register_effect
@dataclass(frozen=True)
class FieldDriftEffect(Effect):
    """The ambient field varies in time (seed 001: up to 200 nT) while the reference magnitude stays at its
    initial value (an absolute magnetometer measured before or elsewhere)."""

    name: ClassVar[str] = "field_drift"
    needs: ClassVar[tuple[str, ...]] = ("t",)
    unseen_by_reference: ClassVar[bool] = True
    blind_strength: ClassVar[float] = 2.0
    DEGREE: ClassVar[int] = 8  # Legendre polynomials of the time in the fitted form
    SCALAR_DEGREE: ClassVar[int] = 3  # a cubic in time on a short turntable series
    fit_params: ClassVar[tuple[str, ...]] = tuple(f"drift_L{j}_nT" for j in range(1, DEGREE + 1))
    RANDOM_AMPLITUDE_NT: ClassVar[tuple[float, float]] = (40.0, 80.0)
    N_COMPONENTS: ClassVar[int] = 3
    amplitude_nT: float = 60.0
    min_period_s: float = 300.0
    max_period_s: float = 3000.0

    @classmethod
    def random(cls, rng, strength=1.0):
        return cls(amplitude_nT=strength * rng.uniform(*cls.RANDOM_AMPLITUDE_NT))

    def field(self, b_ned, t_s, rng):
        var = VaryingField(ConstantField(tuple(b_ned[0])), self.amplitude_nT, self.min_period_s, self.max_period_s,
                           self.N_COMPONENTS)
        return b_ned + var.variation(t_s, rng)

    @classmethod
    def drift_nT(cls, e, t_s, norm):
        """sum_j c_j L_j(tau): the field change seen in the magnitude, without the constant L_0."""
        return legendre.legvander(norm.tau(t_s), len(e))[:, 1:] @ e

    @classmethod
    def fit_residual(cls, r, e, d, norm):
        return r - cls.drift_nT(e, d.t_s, norm)

    @classmethod
    def resim_reference(cls, f_ref_nT, e, d, norm):
        return f_ref_nT - cls.drift_nT(e, d.t_s, norm)

    @classmethod
    def scalar_columns(cls, heading_rad, tau):
        return list(legendre.legvander(tau, cls.SCALAR_DEGREE)[:, 1:].T)


@register_effect
@dataclass(frozen=True)
class NonlinearityEffect(Effect):
    """A per-axis quadratic response: raw_j = o_j + u_j + q_j u_j² / F, u_j = lin_j - o_j (q relative to the
    field magnitude F, so q = 1e-3 gives up to ~50 nT in a 50,000 nT field)."""

    name: ClassVar[str] = "nonlinearity"
    blind_strength: ClassVar[float] = 2.0
    fit_params: ClassVar[tuple[str, ...]] = ("qx", "qy", "qz")
    heading_harmonics: ClassVar[tuple[int, ...]] = (3, 4)  # a quadratic/cubic response adds higher harmonics
    RANDOM_SIZE: ClassVar[float] = 1e-3
    quadratic: tuple[float, float, float] = (8e-4, -6e-4, 5e-4)

    @classmethod
    def random(cls, rng, strength=1.0):
        return cls(tuple(strength * cls.RANDOM_SIZE * _signed(rng, 3)))

    def readings(self, lin, ctx, rng):
        o = np.asarray(ctx["offset_nT"])
        u = lin - o
        return o + u + np.asarray(self.quadratic) * u * u / ctx["f_nT"]

    @classmethod
    def fit_readings(cls, u, e, d, norm):
        """u - q u² / F0: the first-order inverse of the quadratic response."""
        return u - e * u * u / norm.f0_nT

    @classmethod
    def from_fit(cls, e, norm):
        return cls(tuple(e))


@register_effect
@dataclass(frozen=True)
class OutlierEffect(Effect):
    """Sparse spikes (seed 003: 10 % of the points with 500 nT noise): a ``fraction`` of the samples get
    Gaussian errors of ``amplitude_nT`` on every axis."""

    name: ClassVar[str] = "outliers"
    TRIM_ROUNDS: ClassVar[int] = 2
    MIN_SPIKES: ClassVar[int] = 3  # spikes found on held-out data before the effect counts ...
    MIN_SPIKE_SHARE: ClassVar[float] = 0.005  # ... and at least this share of the samples
    RANDOM_FRACTION: ClassVar[tuple[float, float]] = (0.03, 0.08)
    RANDOM_AMPLITUDE_NT: ClassVar[tuple[float, float]] = (200.0, 500.0)
    fraction: float = 0.05
    amplitude_nT: float = 300.0

    @classmethod
    def random(cls, rng, strength=1.0):
        fraction = rng.uniform(*cls.RANDOM_FRACTION)
        return cls(fraction=fraction, amplitude_nT=strength * rng.uniform(*cls.RANDOM_AMPLITUDE_NT))

    def spikes(self, raw, rng):
        n = raw.shape[0]
        k = max(1, int(round(self.fraction * n)))
        idx = rng.choice(n, size=k, replace=False)
        out = raw.copy()
        out[idx] += rng.normal(0.0, self.amplitude_nT, size=(k, 3))
        return out

    @classmethod
    def trimmed_fit(cls, model, d: Columns, x: np.ndarray) -> tuple[np.ndarray, float, float]:
        """Least squares refitted without the samples beyond SPIKE_SIGMA robust sigma (TRIM_ROUNDS times).
        Returns the parameters and the robust scale and centre of the residuals."""
        for _ in range(cls.TRIM_ROUNDS):
            r = model.residuals(x, d)
            centre, scale = np.median(r), robust_sigma(r)
            keep = np.abs(r - centre) <= SPIKE_SIGMA * scale
            if keep.all() or keep.sum() < model.n_params + 2:
                break
            x = model.fit(d.take(keep), x)
        r = model.residuals(x, d)
        return x, robust_sigma(r), float(np.median(r))

    @classmethod
    def fit_model(cls, model, d, x_start):
        return cls.trimmed_fit(model, d, model.fit(d, x_start))[0]

    @classmethod
    def heldout_residuals(cls, model, train, test, x_start, spike_scale):
        """Held-out samples beyond SPIKE_SIGMA robust sigma of the trimmed fit are explained (zero).  The
        held-out residuals of a small training set are inflated by leverage, so a spike must also stand out
        from the base model's own held-out scatter ``spike_scale``."""
        x, scale, centre = cls.trimmed_fit(model, train, model.fit(train, x_start))
        r = model.residuals(x, test)
        spike = np.abs(r - centre) > SPIKE_SIGMA * max(scale, spike_scale)
        return np.where(spike, 0.0, r), int(spike.sum())

    @classmethod
    def evidence(cls, z, n_flagged, n, z_threshold):
        """More spikes beyond SPIKE_SIGMA than Gaussian noise would give."""
        return n_flagged >= max(cls.MIN_SPIKES, cls.MIN_SPIKE_SHARE * n)

    @classmethod
    def spike_mask(cls, r: np.ndarray) -> np.ndarray:
        return np.abs(r - np.median(r)) > SPIKE_SIGMA * robust_sigma(r)

    @classmethod
    def resim_spikes(cls, raw, r_obs, unit):
        """The observed spikes, added along the field direction."""
        flagged = cls.spike_mask(r_obs)
        out = raw.copy()
        out[flagged] += (r_obs[flagged] - np.median(r_obs))[:, None] * unit[flagged]
        return out

    @classmethod
    def scalar_heldout(cls, s):
        return np.where(cls.spike_mask(s.r), 0.0, s.base_cv)


# ---------------------------------------------------------------------------------------------- outside the library
@register_effect
@dataclass(frozen=True)
class AttitudeRipple(Effect):
    """Outside the library: an error of high angular order in the sensor frame,
    amplitude * cos(order * azimuth) * sin(order * elevation) along the field direction."""

    name: ClassVar[str] = "attitude_ripple"
    in_library: ClassVar[bool] = False
    RANDOM_AMPLITUDE_NT: ClassVar[tuple[float, float]] = (20.0, 35.0)
    RANDOM_ORDER: ClassVar[tuple[int, int]] = (4, 7)  # integers from 4 to 6
    amplitude_nT: float = 25.0
    order: int = 5

    @classmethod
    def random(cls, rng, strength=1.0):
        amplitude = strength * rng.uniform(*cls.RANDOM_AMPLITUDE_NT)
        return cls(amplitude_nT=amplitude, order=int(rng.integers(*cls.RANDOM_ORDER)))

    def readings(self, lin, ctx, rng):
        o = np.asarray(ctx["offset_nT"])
        u = lin - o
        unit = u / np.linalg.norm(u, axis=1, keepdims=True)
        az, el = np.arctan2(unit[:, 1], unit[:, 0]), np.arcsin(np.clip(unit[:, 2], -1, 1))
        ripple = self.amplitude_nT * np.cos(self.order * az) * np.sin(self.order * el)
        return lin + ripple[:, None] * unit

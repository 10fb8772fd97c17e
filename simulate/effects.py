"""Effects that simple calibration models leave out, each a small component the simulator switches on.

Names follow CONTRACT section 3: ``scale``, ``offset`` (relative to the ``angles`` model),
``temperature`` (offset and scale drifting with temperature), ``field_drift`` (the ambient field
changing in time, unseen by the reference), ``nonlinearity`` (per-axis response beyond linear),
``outliers`` (sparse spikes, seed 003).  ``attitude_ripple`` is deliberately *outside* the library
(a high-order attitude-dependent error no library model can represent): the diagnosis must not claim
it.  Each effect acts at one stage of the forward model:

    field (NED, time) -> attitude -> linear sensor (K P^-1 B + o) -> effect on readings -> noise -> spikes
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import ClassVar

import numpy as np

from .field import VaryingField

EFFECT_NAMES = ("scale", "offset", "temperature", "field_drift", "nonlinearity", "outliers")


@dataclass(frozen=True)
class Effect:
    name: ClassVar[str] = ""
    in_library: ClassVar[bool] = True
    needs: ClassVar[tuple[str, ...]] = ()  # dataset columns the matching model needs

    def as_dict(self) -> dict:
        return {"name": self.name, **{k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}}

    # hooks, each returning its input unchanged by default
    def field(self, b_ned: np.ndarray, t_s: np.ndarray, rng) -> np.ndarray:
        return b_ned

    def readings(self, lin: np.ndarray, ctx: dict, rng) -> np.ndarray:
        """Noise-free readings (n, 3) -> readings with the effect; ``ctx`` has t_s, temp_C, offset_nT, f_nT."""
        return lin

    def spikes(self, raw: np.ndarray, rng) -> np.ndarray:
        return raw

    def temperature(self, t_s: np.ndarray, rng) -> np.ndarray | None:
        return None


@dataclass(frozen=True)
class ScaleEffect(Effect):
    """Per-axis scale factors on top of an ``angles``-model sensor: raw_j = k_j lin_j (about the offset)."""

    name: ClassVar[str] = "scale"
    scale: tuple[float, float, float] = (1.01, 0.99, 1.005)

    def readings(self, lin, ctx, rng):
        o = np.asarray(ctx["offset_nT"])
        return (lin - o) * np.asarray(self.scale) + o


@dataclass(frozen=True)
class OffsetEffect(Effect):
    """Per-axis offsets (hard iron, zero-point bias) on top of an ``angles``-model sensor."""

    name: ClassVar[str] = "offset"
    offset_nT: tuple[float, float, float] = (150.0, -100.0, 80.0)

    def readings(self, lin, ctx, rng):
        return lin + np.asarray(self.offset_nT)


@dataclass(frozen=True)
class TemperatureEffect(Effect):
    """Offset and scale drifting linearly with temperature about ``ref_C``:
    raw_j = o_j + o_T,j (T - T0) + (1 + k_T,j (T - T0)) (lin_j - o_j).  The temperature follows a warm-up
    ramp from ``start_C`` to ``end_C`` with a slow oscillation, written to the ``temp`` column."""

    name: ClassVar[str] = "temperature"
    needs: ClassVar[tuple[str, ...]] = ("temp",)
    offset_nT_per_C: tuple[float, float, float] = (3.0, -2.0, 2.5)
    scale_ppm_per_C: tuple[float, float, float] = (60.0, -40.0, 30.0)
    start_C: float = 10.0
    end_C: float = 35.0
    ref_C: float = 20.0

    def temperature(self, t_s, rng):
        u = (t_s - t_s.min()) / max(np.ptp(t_s), 1e-9)
        ramp = self.start_C + (self.end_C - self.start_C) * (1 - np.exp(-3 * u)) / (1 - np.exp(-3))
        return ramp + 1.5 * np.sin(2 * np.pi * 2.3 * u + rng.uniform(0, 2 * np.pi))

    def readings(self, lin, ctx, rng):
        dt = (ctx["temp_C"] - self.ref_C)[:, None]
        o = np.asarray(ctx["offset_nT"])
        return o + np.asarray(self.offset_nT_per_C) * dt + (1 + 1e-6 * np.asarray(self.scale_ppm_per_C) * dt) * (lin - o)


@dataclass(frozen=True)
class FieldDriftEffect(Effect):
    """The ambient field varies in time (seed 001: up to 200 nT) while the reference magnitude stays at its
    initial value (an absolute magnetometer measured before or elsewhere)."""

    name: ClassVar[str] = "field_drift"
    needs: ClassVar[tuple[str, ...]] = ("t",)
    amplitude_nT: float = 60.0
    min_period_s: float = 300.0
    max_period_s: float = 3000.0

    def field(self, b_ned, t_s, rng):
        base = b_ned[0]
        from .field import ConstantField

        var = VaryingField(ConstantField(tuple(base)), self.amplitude_nT, self.min_period_s, self.max_period_s, 3)
        return b_ned + var.variation(t_s, rng)


@dataclass(frozen=True)
class NonlinearityEffect(Effect):
    """A per-axis quadratic response: raw_j = o_j + u_j + q_j u_j² / F, u_j = lin_j - o_j (q relative to the
    field magnitude F, so q = 1e-3 gives up to ~50 nT in a 50,000 nT field)."""

    name: ClassVar[str] = "nonlinearity"
    quadratic: tuple[float, float, float] = (8e-4, -6e-4, 5e-4)

    def readings(self, lin, ctx, rng):
        o = np.asarray(ctx["offset_nT"])
        u = lin - o
        return o + u + np.asarray(self.quadratic) * u * u / ctx["f_nT"]


@dataclass(frozen=True)
class OutlierEffect(Effect):
    """Sparse spikes (seed 003: 10 % of the points with 500 nT noise): a ``fraction`` of the samples get
    Gaussian errors of ``amplitude_nT`` on every axis."""

    name: ClassVar[str] = "outliers"
    fraction: float = 0.05
    amplitude_nT: float = 300.0

    def spikes(self, raw, rng):
        n = raw.shape[0]
        k = max(1, int(round(self.fraction * n)))
        idx = rng.choice(n, size=k, replace=False)
        out = raw.copy()
        out[idx] += rng.normal(0.0, self.amplitude_nT, size=(k, 3))
        return out


@dataclass(frozen=True)
class AttitudeRipple(Effect):
    """Outside the library: an error of high angular order in the sensor frame,
    amplitude * cos(order * azimuth) * sin(order * elevation) along the field direction."""

    name: ClassVar[str] = "attitude_ripple"
    in_library: ClassVar[bool] = False
    amplitude_nT: float = 25.0
    order: int = 5

    def readings(self, lin, ctx, rng):
        o = np.asarray(ctx["offset_nT"])
        u = lin - o
        unit = u / np.linalg.norm(u, axis=1, keepdims=True)
        az, el = np.arctan2(unit[:, 1], unit[:, 0]), np.arcsin(np.clip(unit[:, 2], -1, 1))
        ripple = self.amplitude_nT * np.cos(self.order * az) * np.sin(self.order * el)
        return lin + ripple[:, None] * unit


EFFECTS: dict[str, type[Effect]] = {cls.name: cls for cls in (
    ScaleEffect, OffsetEffect, TemperatureEffect, FieldDriftEffect, NonlinearityEffect, OutlierEffect, AttitudeRipple)}


def random_effect(name: str, rng: np.random.Generator, strength: float = 1.0) -> Effect:
    """An effect of the named kind with random parameters (signs and axes drawn), scaled by ``strength``."""
    s = strength
    sign = lambda k: rng.choice([-1.0, 1.0], size=k) * rng.uniform(0.5, 1.0, size=k)  # noqa: E731
    if name == "scale":
        return ScaleEffect(tuple(1.0 + s * 0.01 * sign(3)))
    if name == "offset":
        return OffsetEffect(tuple(s * 150.0 * sign(3)))
    if name == "temperature":
        return TemperatureEffect(tuple(s * 3.0 * sign(3)), tuple(s * 60.0 * sign(3)))
    if name == "field_drift":
        return FieldDriftEffect(amplitude_nT=s * rng.uniform(40.0, 80.0))
    if name == "nonlinearity":
        return NonlinearityEffect(tuple(s * 1e-3 * sign(3)))
    if name == "outliers":
        return OutlierEffect(fraction=rng.uniform(0.03, 0.08), amplitude_nT=s * rng.uniform(200.0, 500.0))
    if name == "attitude_ripple":
        return AttitudeRipple(amplitude_nT=s * rng.uniform(20.0, 35.0), order=int(rng.integers(4, 7)))
    raise KeyError(f"unknown effect {name!r}; known: {', '.join(EFFECTS)}")

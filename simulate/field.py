"""The ambient geomagnetic field, in the local North-East-Down frame (nT).

* ``ConstantField`` from a vector, or from magnitude, inclination and declination;
* ``igrf_field`` at a place and date through the IGRF-14 model of the ``ppigrf`` package;
* ``VaryingField``: a constant field plus a smooth random fluctuation in time (seed 001 reports
  short-term fluctuations of up to 200 nT during its gradiometer calibration).
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import io
import math
import warnings
from dataclasses import dataclass

import numpy as np

IGRF_VALID = (_dt.datetime(1900, 1, 1), _dt.datetime(2030, 1, 1))
"""IGRF-14's coefficients: definitive and predictive, 1900 to 2030 (exclusive)."""
IGRF_ALTITUDE_KM = (-12.0, 6000.0)
"""Altitudes accepted for a reference from IGRF: from the deepest ocean to beyond low Earth orbit."""


@dataclass(frozen=True)
class ConstantField:
    """A field vector fixed in the North-East-Down frame."""

    vector_nT: tuple[float, float, float]

    def __post_init__(self):
        object.__setattr__(self, "vector_nT", tuple(float(v) for v in self.vector_nT))

    @classmethod
    def from_angles(cls, total_nT: float, inclination_deg: float, declination_deg: float = 0.0) -> ConstantField:
        """B = F [cos I cos D, cos I sin D, sin I] (inclination positive downwards)."""
        i, d = np.radians(inclination_deg), np.radians(declination_deg)
        return cls((total_nT * np.cos(i) * np.cos(d), total_nT * np.cos(i) * np.sin(d), total_nT * np.sin(i)))

    @property
    def total_nT(self) -> float:
        return float(np.linalg.norm(self.vector_nT))

    @property
    def inclination_deg(self) -> float:
        n, e, d = self.vector_nT
        return float(np.degrees(np.arctan2(d, np.hypot(n, e))))

    @property
    def declination_deg(self) -> float:
        n, e, _ = self.vector_nT
        return float(np.degrees(np.arctan2(e, n)))

    def at(self, t_s: np.ndarray, rng: np.random.Generator | None = None) -> np.ndarray:
        """The field at each time, shape (n, 3)."""
        return np.tile(np.asarray(self.vector_nT), (np.size(t_s), 1))


def igrf_field(lat_deg: float, lon_deg: float, alt_km: float, date) -> ConstantField:
    """The IGRF-14 main field at a geodetic place and date (via ``ppigrf``).

    ``date`` is a ``datetime.date``/``datetime`` or an ISO string ``YYYY-MM-DD``.
    """
    import ppigrf

    if isinstance(date, str):
        date = _dt.datetime.fromisoformat(date)
    elif isinstance(date, _dt.date) and not isinstance(date, _dt.datetime):
        date = _dt.datetime(date.year, date.month, date.day)
    if not all(math.isfinite(v) for v in (lat_deg, lon_deg, alt_km)):
        raise ValueError("latitude, longitude and altitude must be finite numbers")
    if not -90.0 <= lat_deg <= 90.0:
        raise ValueError(f"latitude {lat_deg} is outside [-90, 90] degrees")
    if not -180.0 <= lon_deg <= 360.0:
        raise ValueError(f"longitude {lon_deg} is outside [-180, 360] degrees")
    if not IGRF_ALTITUDE_KM[0] <= alt_km <= IGRF_ALTITUDE_KM[1]:
        raise ValueError(f"altitude {alt_km} km is implausible for a magnetometer (IGRF is used here from "
                         f"{IGRF_ALTITUDE_KM[0]:g} to {IGRF_ALTITUDE_KM[1]:g} km)")
    if not IGRF_VALID[0] <= date < IGRF_VALID[1]:
        raise ValueError(f"date {date.date()} is outside IGRF-14's validity ({IGRF_VALID[0].date()} to "
                         f"{IGRF_VALID[1].date()}, exclusive)")
    with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():  # ppigrf prints its warnings
        warnings.simplefilter("ignore")
        be, bn, bu = ppigrf.igrf(lon_deg, lat_deg, alt_km, date)
    vector = (float(np.ravel(bn)[0]), float(np.ravel(be)[0]), -float(np.ravel(bu)[0]))
    if not all(math.isfinite(v) for v in vector):
        raise ValueError(f"IGRF-14 gives no field at {lat_deg}, {lon_deg}, {alt_km} km on {date.date()}")
    return ConstantField(vector)


@dataclass(frozen=True)
class VaryingField:
    """A base field plus a smooth random variation: a sum of ``n_components`` sinusoids with random
    directions, periods (log-uniform in [min_period_s, max_period_s]) and phases, scaled so that the
    largest deviation over the requested times equals ``amplitude_nT``.
    """

    base: ConstantField
    amplitude_nT: float = 200.0
    min_period_s: float = 30.0
    max_period_s: float = 1800.0
    n_components: int = 6

    def variation(self, t_s: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)
        k = self.n_components
        periods = np.exp(rng.uniform(np.log(self.min_period_s), np.log(self.max_period_s), k))
        phases = rng.uniform(0, 2 * np.pi, k)
        dirs = rng.normal(size=(k, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        amps = rng.uniform(0.5, 1.0, k)
        waves = np.sin(2 * np.pi * t[:, None] / periods[None, :] + phases[None, :]) * amps  # (n, k)
        dv = waves @ dirs
        peak = np.max(np.linalg.norm(dv, axis=1)) if len(t) else 1.0
        return dv * (self.amplitude_nT / peak if peak > 0 else 0.0)

    def at(self, t_s: np.ndarray, rng: np.random.Generator | None = None) -> np.ndarray:
        if rng is None:
            raise ValueError("a varying field needs an rng (np.random.default_rng(seed))")
        return self.base.at(t_s) + self.variation(t_s, rng)

    @property
    def total_nT(self) -> float:
        return self.base.total_nT

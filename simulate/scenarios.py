"""Named scenarios: a field, an attitude schedule and a sensor, simulated with one seed.

``lu2014`` is seed 000's turntable experiment (section 3; angles of its Table 1); ``sphere9`` is the
9-parameter full-sphere case of seeds 002 and 003.  Every scenario returns a ``Dataset`` with its
``Truth``; the same name and seed give the same numbers.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import cache

import numpy as np

from magbench import paper
from magbench.errors import InputError, check_seed

from . import attitude as att
from .dataset import Dataset, Truth
from .effects import make_effect
from .field import ConstantField, VaryingField, igrf_field
from .sensor import ErrorParams, SensorModel

# Seed 000: Xi'an (34.26 N, 108.94 E, about 0.4 km), 2013; reference magnitude 51978.74 nT (Table 2).
XIAN_LAT_DEG, XIAN_LON_DEG, XIAN_ALT_KM, XIAN_DATE = 34.26, 108.94, 0.4, "2013-06-27"
LU2014_F_NT = paper.F_XIAN_NT
LU2014_ANGLES = ErrorParams(alpha_rad=paper.TABLE1_ANGLES_RAD["alpha_rad"], beta_rad=paper.TABLE1_ANGLES_RAD["beta_rad"],
                            gamma_rad=paper.TABLE1_ANGLES_RAD["gamma_rad"])  # seed 000, Table 1

# A typical small fluxgate with 9-parameter errors (seeds 002, 003 use errors of this order).
SPHERE9_ERRORS = ErrorParams(alpha_rad=0.012, beta_rad=-0.008, gamma_rad=0.015,
                             scale=(1.021, 0.984, 1.008), offset_nT=(152.0, -218.0, 85.0))


@cache
def xian_2013() -> ConstantField:
    """IGRF at Xi'an on the paper's submission date, scaled to the paper's reference magnitude."""
    igrf = igrf_field(XIAN_LAT_DEG, XIAN_LON_DEG, XIAN_ALT_KM, XIAN_DATE)
    return ConstantField.from_angles(LU2014_F_NT, igrf.inclination_deg, igrf.declination_deg)


@dataclass(frozen=True)
class Scenario:
    """A recipe for a simulated dataset; ``build(seed)`` makes it."""

    name: str
    description: str
    model: str  # the calibration model the scenario is meant for
    schedule: str
    n_points: int
    sensor: SensorModel
    field_fn: Callable[[], ConstantField] = field(repr=False, default=lambda: ConstantField.from_angles(50000.0, 60.0, 5.0))
    schedule_kw: dict = field(default_factory=dict)
    drift_nT: float = 0.0  # peak ambient-field variation (unseen by the reference unless reference_tracks)
    reference_tracks_drift: bool = True
    effects: tuple = ()  # simulate.effects.Effect instances switched on

    def with_effects(self, *effects, name: str | None = None) -> Scenario:
        """The same scenario with effects switched on: ``simulate.effects.Effect`` instances, or names of
        registered effects (``simulate.effects.EFFECTS``) with their default parameters."""
        effects = tuple(make_effect(e) if isinstance(e, str) else e for e in effects)
        label = name or "+".join([self.name] + [e.name for e in effects])
        return replace(self, name=label, effects=tuple(self.effects) + effects)

    def attitudes(self, rng: np.random.Generator) -> att.Attitudes:
        kw = dict(self.schedule_kw)
        if self.schedule == "turntable":
            return att.turntable(n_steps=self.n_points, **kw)
        schedules: dict[str, Callable[..., att.Attitudes]] = {
            "sphere": att.full_sphere, "cap": att.cap, "vehicle": att.vehicle, "tumble": att.tumble}
        return schedules[self.schedule](self.n_points, rng, **kw)

    def build(self, seed: int | None = 0) -> Dataset:
        rng = np.random.default_rng(check_seed(seed))
        base = self.field_fn()
        attitudes = self.attitudes(rng)
        t = attitudes.t_s
        field_ned = VaryingField(base, amplitude_nT=self.drift_nT).at(t, rng) if self.drift_nT > 0 else base.at(t)
        clean_field = field_ned
        for e in self.effects:
            field_ned = e.field(field_ned, t, rng)
        temp = None
        for e in self.effects:
            profile = e.temperature(t, rng)
            temp = profile if profile is not None else temp
        lin = self.sensor.linear(attitudes.rotation.apply(field_ned, inverse=True))
        clean = self.sensor.linear(attitudes.rotation.apply(clean_field, inverse=True))
        ctx = {"t_s": t, "temp_C": temp, "offset_nT": self.sensor.errors.offset_nT, "f_nT": base.total_nT}
        for e in self.effects:
            lin = e.readings(lin, ctx, rng)
        noise_state = rng.bit_generator.state
        raw = self.sensor.add_noise(lin, rng)
        rng_clean = np.random.default_rng()
        rng_clean.bit_generator.state = noise_state  # the very same noise on the effect-free readings
        clean = self.sensor.add_noise(clean, rng_clean)
        for e in self.effects:
            raw = e.spikes(raw, rng)
        drift_unseen = any(e.unseen_by_reference for e in self.effects)
        if self.reference_tracks_drift and not drift_unseen:
            f_ref = np.linalg.norm(field_ned, axis=1)
        else:
            f_ref = np.full(len(attitudes), base.total_nT)
        vx, vy, vz = (float(v) for v in base.vector_nT)
        field_ned_tuple = (vx, vy, vz)
        truth = Truth(params=self.sensor.true_correction(), sensor=self.sensor,
                      field_ned_nT=field_ned_tuple, scenario=self.name, seed=seed,
                      effects=tuple(e.as_dict() for e in self.effects),
                      attitude_quat=attitudes.rotation.as_quat(),
                      raw_without_effects_nT=clean if self.effects else None)
        meta = {"scenario": self.name, "seed": seed, "field_nT": f"{base.total_nT:.2f}",
                "model": self.model, "generator": "magbench simulate"}
        return Dataset(raw, f_ref_nT=f_ref, t_s=t, temp_C=temp, heading_deg=attitudes.heading_deg,
                       truth=truth, meta=meta)


_SCENARIOS: dict[str, Scenario] = {}


def register_scenario(s: Scenario) -> Scenario:
    if s.name in _SCENARIOS:
        raise ValueError(f"a scenario named {s.name!r} is already registered")
    _SCENARIOS[s.name] = s
    return s


def get_scenario(name: str) -> Scenario:
    try:
        return _SCENARIOS[name]
    except KeyError:
        raise InputError(f"unknown scenario {name!r}; known: {', '.join(sorted(_SCENARIOS))}") from None


def scenario_names() -> list[str]:
    return list(_SCENARIOS)


def simulate(name: str, seed: int = 0) -> Dataset:
    """Build the named scenario with a seed."""
    return get_scenario(name).build(seed)


register_scenario(Scenario(
    "lu2014",
    "Lu et al. 2014's experiment: FGM-2000 on a level turntable, 36 steps of 10 deg, Xi'an 2013 (IGRF "
    "inclination), F = 51978.74 nT, Table 1 angles, 1 nT noise, 0.1 nT resolution",
    model="angles", schedule="turntable", n_points=36,
    sensor=SensorModel(LU2014_ANGLES, noise_nT=1.0, quantization_nT=0.1),
    field_fn=xian_2013, schedule_kw=dict(step_deg=10.0, dwell_s=30.0)))
register_scenario(Scenario(
    "sphere9",
    "full sphere, 9-parameter sensor, 300 points, 2 nT noise, F = 50000 nT",
    model="nine", schedule="sphere", n_points=300,
    sensor=SensorModel(SPHERE9_ERRORS, noise_nT=2.0)))
register_scenario(Scenario(
    "cap9",
    "upper hemisphere only (body Z within 90 deg of down), 9-parameter sensor, 200 points, 2 nT noise",
    model="nine", schedule="cap", n_points=200,
    sensor=SensorModel(SPHERE9_ERRORS, noise_nT=2.0), schedule_kw=dict(max_tilt_deg=90.0)))
register_scenario(Scenario(
    "vehicle9",
    "Zhang et al.'s regime (TTLS with the L-curve): land vehicle, one full turn of yaw with pitch and roll within 5 deg, "
    "9-parameter sensor, 360 points, 2 nT noise",
    model="nine", schedule="vehicle", n_points=360,
    sensor=SensorModel(SPHERE9_ERRORS, noise_nT=2.0), schedule_kw=dict(pitch_roll_deg=5.0)))
register_scenario(Scenario(
    "tumble9",
    "smooth 10-minute tumble, ambient field varying by up to 200 nT (tracked by the reference), "
    "9-parameter sensor, 600 points, 2 nT noise",
    model="nine", schedule="tumble", n_points=600,
    sensor=SensorModel(SPHERE9_ERRORS, noise_nT=2.0), drift_nT=200.0, schedule_kw=dict(duration_s=600.0)))
register_scenario(Scenario(
    "vehicle9n",
    "Zhang et al.'s regime (TTLS, L-curve) with vehicle-level noise: one turn of yaw, pitch and roll within 3 deg, 9-parameter "
    "sensor, 200 points, 20 nT noise",
    model="nine", schedule="vehicle", n_points=200,
    sensor=SensorModel(SPHERE9_ERRORS, noise_nT=20.0), schedule_kw=dict(pitch_roll_deg=3.0)))
register_scenario(Scenario(
    "tumble9q",
    "smooth 10-minute tumble in a quiet field (no ambient variation), 9-parameter sensor, 600 points, 2 nT noise",
    model="nine", schedule="tumble", n_points=600,
    sensor=SensorModel(SPHERE9_ERRORS, noise_nT=2.0), schedule_kw=dict(duration_s=600.0)))
register_scenario(Scenario(
    "tumble3",
    "smooth 10-minute tumble in a quiet field, sensor with the three angles only (Lu et al. 2014's model), "
    "600 points, 2 nT noise",
    model="angles", schedule="tumble", n_points=600,
    sensor=SensorModel(LU2014_ANGLES, noise_nT=2.0), schedule_kw=dict(duration_s=600.0)))
register_scenario(Scenario(
    "sphere9_axes",
    "as sphere9 but simulated with the axis-projection model (raw = K A B + o, A = P^T)",
    model="nine", schedule="sphere", n_points=300,
    sensor=SensorModel(SPHERE9_ERRORS, noise_nT=2.0, convention="axis_projection")))

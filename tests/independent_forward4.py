"""A fourth forward model of a tri-axial fluxgate in the geomagnetic field: a blind source of cases for the
diagnosis, written from the physics with numpy and scipy only.  It shares no code with magbench (its simulator,
diagnosis or calibrators) nor with the first three generators; from tests/independent_forward.py it reuses only
the ``Case`` record, so that tests/independent_scoring.py scores its cases unchanged.

Sensor.  Three fluxgate axes with their own unit vectors ``u_i`` in the body frame (each tilted by up to ~1 deg
from the body axes, so the triad is non-orthogonal), a gain ``g_i`` and an offset ``o_i`` each, behind a constant
platform soft iron ``S`` (a general matrix within 2 % of the identity) and hard iron ``h``:
``raw_i = g_i u_i . (S B_body + h) + o_i + noise``.  The true calibration is therefore ``B = C (raw - c)`` with
``C = (diag(g) U S)^-1`` and ``c = diag(g) U h + o`` (``notes["true_C"]``, ``notes["true_offset_nT"]``).  White
noise of 0.1-5 nT per axis (log-uniform), sometimes an ADC grid of 0.5-2 times the noise;
``notes["noise_nT"]`` is the resulting white level of the scalar residual (noise, grid and reference noise
together).  The field is 20,000-65,000 nT at an inclination of up to 80 deg (either hemisphere) in a north-east-
down world frame; the satellite's is a tilted dipole along its orbit.  The scalar reference ``F`` is either a
model value (a constant; along the orbit the model's magnitude), or a measured co-located scalar magnetometer
(an Overhauser or caesium sensor, 0.01-0.05 nT noise, 0.01 nT resolution) that follows the natural variation of
the field; that variation is then modelled along the field only (a pure change of magnitude), so it is no effect.
When the record holds a ``field_drift`` or a ``path_anomaly`` the reference is a model value.  The logged
temperature is a thermometer that lags the environment with its own time constant (the sensor core lags it with
another), with its own noise and resolution (0.01, 0.0625 or 0.1 degC).  Gravity (a unit vector, down, in the
body frame, from an accelerometer or the platform's AHRS, with 0.001-0.04 noise) is given on the borehole probe,
the pedestrian, the UAV, the robot arm, and on some towed fish and observatory piers; never on the satellite.

Attitude schedules (``SCHEDULES``, all new), each a physical model evaluated at any time (so that delays and
integration windows are exact):
- towed_fish: a marine fish on survey lines with lawnmower turns (alternating sides), hunting in yaw about the
  tow line, banking in turns, pitching with its depth changes; the water temperature follows depth through a
  thermocline.  0.5-5 Hz, regular, jittered or with gaps.
- borehole: a wireline probe logging up a deviated hole at 0.05-0.3 m/s with stations, spinning about its long
  axis (cable torsion, slower at stations) while the hole's inclination and azimuth change slowly with depth; the
  temperature follows the geothermal gradient.
- pedestrian: a helmet or hand-held sensor on a walker: straight stretches, corners of 45-180 deg, pauses, gait
  oscillation at the step frequency (pitch) and half of it (roll, yaw), glances to the side; warming by the body
  and by the sun according to heading.  3-20 Hz, jittered.
- uav_survey: a fixed-wing UAV flying lawnmower lines: long legs with a wind crab angle, coordinated banked
  turns (bank 20-35 deg), turbulence, drape climbs; the throttle load follows the load factor and climb.
- robot_arm: a wrist carrying the sensor between random programmed poses (joint-space moves with trapezoidal
  velocity profiles, dwells); the wrist motors heat while moving.  Regular, jittered or in bursts.
- satellite: a spin-stabilised (small nutation cone) or slowly tumbling (torque-free precession) spacecraft on a
  circular orbit of 400-800 km in a tilted-dipole field, so F varies by up to a factor of two; sun and eclipse
  drive the temperature.  The reference is the model's magnitude along the orbit.
- observatory (the ``fixed`` category): a sensor on a pier, not rotating, 2-20 h at one sample per 4-240 s,
  in a hut whose temperature follows the day and the heating's cycles.

Library effects (the names the diagnosis may use), in this generator's own parametrisations:
- temperature: any of offsets (up to 20 nT/degC), scale factors (up to 300 ppm/degC, a common part and per
  axis) and axis directions (each axis turning about its own random axis, up to 50 urad/degC), linear in the
  sensor core's true temperature, which lags the environment differently from the logged thermometer.
- field_drift: a world-frame natural variation the reference does not follow: a substorm bay, a storm sudden
  commencement, a Pc5 wave packet (1-3 periods in the record), the daily (Sq) variation on a fixed sensor; on the
  satellite field-aligned-current crossings (transverse to the field) or a ring current changing along the orbit.
  Peak up to min(1 % of F, 500 nT).
- offset_drift: sensor-frame offsets settling after power-on (per-axis exponentials), wandering (a smoothed random
  walk), or shifting gradually (per-axis tanh transitions).  Peak up to min(1 % of F, 300 nT).
- lag: axes sampled at staggered instants (skew), per-axis integrating windows of an integrating converter (the
  reading is the mean over its window), or a first-order digital smoothing of one or more axes in the firmware;
  every equivalent delay within half a (median) sample period.
- nonlinearity: per-axis quadratic-and-cubic transfer, a knee (the gain changes above a level), or soft
  compression (F tanh(b/F) - b); the largest deviation within 1 % of F.
- outliers: 5-12 isolated spikes at random rows (one axis, a random direction, or one axis's power-of-two jump),
  each moving the scalar residual (a fixed sensor's vector) by at least 10 times the noise.

Effects outside the library (``OUTSIDE``), each chosen to resemble a library effect; ``ACCEPTABLE_FOR`` says what
is not wrong to name, decided from the physics and erring towards strictness:
- cross_field: the fluxgate's perpendicular-field effect: a ring core's sensitivity falls with the field across
  it in its plane, ``b_i -> b_i (1 - k_i b_j^2 / F^2)`` for one perpendicular axis j.  Resembles nonlinearity; it
  is the sensor's response beyond linear (cubic), so ``nonlinearity`` is acceptable; the cross-axis part is
  outside a per-axis transfer and stays unexplained.
- reference_heading: the platform's caesium reference has a heading error (a third-order Legendre term in the
  angle between the field and its optical axis) and a loss of signal near its dead-zone plane; the reference is
  wrong, not the sensor.  Resembles nonlinearity (an attitude-dependent residual).  Nothing acceptable.
- adc_dnl: the converter's differential nonlinearity: a sawtooth in the transfer at major code transitions
  (period 300-3000 nT, at most 30 nT).  Resembles nonlinearity (and noise).  It is the sensor chain's per-axis
  transfer beyond linear, so ``nonlinearity`` is acceptable; the sawtooth is not quadratic or cubic and stays
  unexplained.
- throttle_current: the UAV's motor supply cable runs past the sensor; its current follows the throttle (load
  factor in banked turns, climbs), a body-fixed field.  Resembles offset_drift and temperature.  Nothing.
- core_gradient: one side of the sensor head is heated (sun on one side, an amplifier cycling beside it) so one
  or two cores sit at a temperature the single logged thermometer does not see; their offsets follow it (up to
  20 nT/degC over 0.5-3 degC).  Physically the sensor's temperature dependence: ``temperature`` is acceptable;
  the part not following the logged temperature stays unexplained.
- excitation_crosstalk: a second fluxgate nearby excited at a slightly different frequency; the beat appears as
  a sensor-frame offset oscillating at a slowly drifting frequency (6-40 cycles in the record).  Resembles
  offset_drift, but it is neither slow nor a drift of the sensor.  Nothing.
- vibration_noise: magnetostrictive noise of the cores while the platform vibrates (winch, motor, tool knocks):
  long bursts (at least 40 rows, 30-60 % of the record) of raised, band-limited noise.  Resembles outliers and
  coloured noise; not isolated spikes.  Nothing.
- path_anomaly: ferrous objects along the path (casing collars every 9-12 m in a borehole, a pipeline or a wreck
  under the fish, rebar and parked cars beside a walker): dipole fields in the world frame seen as the platform
  passes.  The ambient field at the sensor changes and the (model) reference does not follow: physically a field
  drift, so ``field_drift`` is acceptable; the short passes are beyond a slow drift and stay unexplained.
- tx_supply_dip: a radio transmitting in bursts loads the supply; the sensor's ratiometric scale factors dip
  during each burst, differently per axis (some up, some down).  Resembles field_drift or offset switching; it is
  none of them.  Nothing.
- solar_array: the satellite's solar-array string currents follow each panel's sun incidence (spin phase,
  eclipse) and make body-fixed fields.  Resembles offset_drift (eclipse steps) and attitude structure.  Nothing.
- pressure_stress: hydrostatic pressure stresses the cores (magnetoelastic), the per-axis scale factors follow
  depth.  Resembles temperature (which also follows depth) and offset_drift.  Nothing.
(A moving ferrous object in the world frame would physically be a field drift: here it is ``path_anomaly``.  A
clock offset between the reference and the sensor was not used: its residual is a scalar series in time,
indistinguishable from a field drift or a lag.)

Visibility (``present`` holds only effects a perfect analyst could see).  Every effect is built with a unit
amplitude in physical units; its contribution to the scalar residual is computed exactly (the forward model with
and without it, both corrected with the true calibration, minus the reference); what a perfect calibration can
absorb (a least-squares fit of the nine linearised calibration directions ``|B| u_i u_j`` and ``u_i``) is taken
out, and the amplitude is scaled (iterated for effects not linear in it) so that the RMS of the rest is 5-18
times the noise (``VISIBLE_RANGE`` 4-20 is checked).  A fixed sensor uses the corrected vector readings about
their mean instead.  Each amplitude must stay physically plausible (``_Eff.amax`` and no reading moved by more
than 1 % of the field; a lag is bounded by its delay alone, half a sample, since a delay of a turning sensor
moves its readings along the turn); otherwise the record is drawn again (new platform, sampling, sensor and
shapes; ``_FAILURES`` keeps the reasons).  Effects that stay small at a plausible size are given a quieter
sensor (``NOISE_CAP``: a caesium heading error needs noise of at most 0.5 nT, a DNL 2 nT).  An
outside effect is scaled on what remains after the calibration AND every library effect's linearised model
together (independent bases: the logged temperature times the nine calibration directions; Legendre polynomials
of degree 5 in time along the field's world direction for field_drift and along each sensor axis for
offset_drift; each axis's exact time derivative for lag; each axis's square and cube for nonlinearity): that is
5-13 times the noise (``BEYOND_RANGE`` 4-15; vibration_noise 4-6), so ``expect_unexplained`` is honest.  Two
library effects are ``confoundable`` when what remains of a present one after the calibration and the other's
model is below max(3 noise, 30 % of its visible size) (for every other library effect, present or not); on a
fixed sensor offset_drift and field_drift always are, and temperature with both when its effect is a smooth
function of time (degree-5 polynomial per axis), and a drift with temperature when the logged temperature fits
it.  ``too_short`` records (8-14 rows) carry no effect or one library effect at a plausible size; nothing is
present (nothing is visible), the effect is acceptable.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from independent_forward import Case
from scipy.signal import lfilter

LIBRARY = ("temperature", "field_drift", "offset_drift", "lag", "nonlinearity", "outliers")
OUTSIDE = ("cross_field", "reference_heading", "adc_dnl", "throttle_current", "core_gradient",
           "excitation_crosstalk", "vibration_noise", "path_anomaly", "tx_supply_dip", "solar_array",
           "pressure_stress")
ACCEPTABLE_FOR = {"cross_field": ("nonlinearity",), "adc_dnl": ("nonlinearity",),
                  "core_gradient": ("temperature",), "path_anomaly": ("field_drift",)}
SCHEDULES = ("towed_fish", "borehole", "pedestrian", "uav_survey", "robot_arm", "satellite")
FIXED_SCHEDULE = "observatory"
FIXED_EFFECTS = ("temperature", "field_drift", "offset_drift", "outliers")
OUTSIDE_SCHEDULES = {"reference_heading": ("towed_fish", "uav_survey"), "throttle_current": ("uav_survey",),
                     "path_anomaly": ("towed_fish", "borehole", "pedestrian"), "solar_array": ("satellite",),
                     "pressure_stress": ("towed_fish", "borehole")}
REFERENCE_NEEDED = {"field_drift": "model", "path_anomaly": "model", "reference_heading": "measured"}
# nT: effects small at a plausible size need a quiet sensor
NOISE_CAP = {"reference_heading": 0.5, "adc_dnl": 2.0, "excitation_crosstalk": 3.0, "cross_field": 2.0}
# one block of 24: 2 clean, 6 single, 2 pair, 2 triple, 6 outside, 2 outside_plus, 2 too_short, 2 fixed
PATTERN = ("single", "outside", "clean", "pair", "outside", "single", "fixed", "too_short", "outside_plus",
           "single", "outside", "triple", "single", "outside", "clean", "fixed", "pair", "single", "outside",
           "too_short", "outside_plus", "single", "triple", "outside")
VISIBLE_RANGE = (4.0, 20.0)
BEYOND_RANGE = (4.0, 15.0)
OUTLIER_MIN_SIGMA = 10.0
DEG = np.pi / 180.0
POLY_DEGREE = 5
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(3)


# ------------------------------------------------------------------------------------------------ helpers
def _rx(a: np.ndarray) -> np.ndarray:
    c, s, o, z = np.cos(a), np.sin(a), np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def _ry(a: np.ndarray) -> np.ndarray:
    c, s, o, z = np.cos(a), np.sin(a), np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def _rz(a: np.ndarray) -> np.ndarray:
    c, s, o, z = np.cos(a), np.sin(a), np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _ypr(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """Body-to-world (north-east-down) rotations: heading, then pitch, then roll."""
    return _rz(yaw) @ _ry(pitch) @ _rx(roll)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _to_z(v: np.ndarray) -> np.ndarray:
    """A rotation taking the z axis to the unit vector v."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, v)
    s, c = np.linalg.norm(axis), float(z @ v)
    if s < 1e-9:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = axis / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * kx @ kx


def _loguniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def _lowpass(x: np.ndarray, step: float, tau: float) -> np.ndarray:
    """First-order lag of a series on a uniform grid, starting settled."""
    if tau <= 0:
        return x.copy()
    a = np.exp(-step / tau)
    return lfilter([1 - a], [1, -a], x, zi=[a * x[0]])[0]


def _wander(rng: np.random.Generator, tt: np.ndarray, shortest: float, longest: float | None = None,
            k: int = 8) -> np.ndarray:
    """A smooth random signal of unit peak: k sinusoids of periods shortest..longest, amplitudes ~ sqrt(period)."""
    span = max(float(tt[-1] - tt[0]), shortest)
    longest = longest or 2.0 * span
    if longest <= shortest:
        longest = 1.5 * shortest
    f = np.exp(rng.uniform(np.log(1 / longest), np.log(1 / shortest), k))
    amp = rng.uniform(0.5, 1.0, k) / np.sqrt(f)
    ph = rng.uniform(0, 2 * np.pi, k)
    x = (amp[:, None] * np.sin(2 * np.pi * f[:, None] * (tt - tt[0])[None, :] + ph[:, None])).sum(0)
    x -= x.mean()
    return x / max(np.abs(x).max(), 1e-12)


def _times(rng: np.random.Generator, n: int, dt: float, modes: tuple[str, ...]) -> tuple[np.ndarray, str]:
    mode = str(rng.choice(modes))
    inc = np.full(n - 1, dt)
    if mode == "jitter":
        inc *= rng.uniform(0.7, 1.3, n - 1)
    elif mode == "gaps" and n > 20:
        k = int(rng.integers(1, 5))
        inc[rng.choice(n - 1, k, replace=False)] *= rng.uniform(5, 40, k)
    elif mode == "bursts" and n > 20:
        length = int(rng.integers(25, 120))
        inc[length - 1::length] *= rng.uniform(3, 15, len(inc[length - 1::length]))
    t = rng.uniform(0, 60) + np.concatenate([[0.0], np.cumsum(inc)])
    return t, mode


def _legendre(t: np.ndarray, degree: int) -> np.ndarray:
    x = 2 * (t - t[0]) / max(t[-1] - t[0], 1e-9) - 1
    return np.polynomial.legendre.legvander(x, degree)


def _orth(x: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the columns of x (each scaled to unit RMS first; directions below 1e-5 of the
    strongest singular value dropped), from the eigen-decomposition of the Gram matrix (fast for tall x)."""
    x = x / np.maximum(np.sqrt(np.mean(x ** 2, axis=0)), 1e-300)
    lam, vec = np.linalg.eigh(x.T @ x)
    keep = lam > 1e-10 * lam[-1]
    return x @ (vec[:, keep] / np.sqrt(lam[keep]))


def _remove(q: np.ndarray, y: np.ndarray) -> np.ndarray:
    return y - q @ (q.T @ y)


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


# ------------------------------------------------------------------------------------------------ platforms
@dataclass
class _Platform:
    name: str
    t: np.ndarray
    sampling: str
    grid: np.ndarray
    series: dict[str, np.ndarray]
    rot: Callable[[np.ndarray], np.ndarray]
    ref_options: tuple[str, ...]
    gravity_p: float
    gravity_noise: float
    path_axis: str = "heading"  # how a path anomaly's geometry is oriented
    orbit: dict | None = None

    def at(self, name: str, times: np.ndarray) -> np.ndarray:
        return np.interp(times, self.grid, self.series[name])


def _grid(t: np.ndarray, step: float, pad: float) -> np.ndarray:
    return np.arange(t[0] - pad, t[-1] + pad + step, step)


def _ypr_rot(grid: np.ndarray, yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray):
    def rot(times: np.ndarray) -> np.ndarray:
        return _ypr(np.interp(times, grid, yaw), np.interp(times, grid, pitch), np.interp(times, grid, roll))
    return rot


def _lines(tt: np.ndarray, line: float, turn: float, offset: float, ramp: float = 0.0) -> tuple[np.ndarray, ...]:
    """Turn-rate profile (integrating to pi per turn, alternate sides) of a lawnmower pattern: (rate, in_turn)."""
    period = line + turn
    phase = (tt + offset) % period
    k = np.floor((tt + offset) / period)
    x = np.clip((phase - line) / turn, 0.0, 1.0)
    if ramp > 0:
        shape = np.clip(np.minimum(x, 1 - x) / ramp, 0.0, 1.0)
        shape = shape * shape * (3 - 2 * shape) / (1 - ramp)  # smoothstep ramps; integral over the turn ~ 1
    else:
        shape = 2 * np.sin(np.pi * x) ** 2
    rate = np.where(phase > line, np.pi / turn * shape, 0.0) * np.where(k % 2 == 0, 1.0, -1.0)
    return rate, (phase > line).astype(float)


def _towed_fish(rng: np.random.Generator, n: int) -> _Platform:
    dt = _loguniform(rng, 0.2, 2.0)
    t, mode = _times(rng, n, dt, ("regular", "jitter", "gaps"))
    step = min(0.1, dt / 4)
    g = _grid(t, step, 2 * dt)
    tt = g - g[0]
    speed = rng.uniform(1.8, 3.0)
    rate, _ = _lines(tt, rng.uniform(120, 500), rng.uniform(40, 100), rng.uniform(0, 600))
    heading = rng.uniform(-np.pi, np.pi) + np.cumsum(rate) * step
    bank = -rate / max(np.abs(rate).max(), 1e-9) * rng.uniform(4, 14) * DEG
    yaw = heading + rng.uniform(2, 10) * DEG * np.sin(2 * np.pi * tt / rng.uniform(8, 30) + rng.uniform(0, 6.3)) \
        + rng.uniform(0.5, 3) * DEG * _wander(rng, tt, 20)
    depth = rng.uniform(10, 60) + rng.uniform(2, 12) * _wander(rng, tt, 200)
    pitch = rng.uniform(-3, 3) * DEG - np.arctan(np.gradient(depth, step) / speed) \
        + rng.uniform(0.5, 3) * DEG * np.sin(2 * np.pi * tt / rng.uniform(15, 60) + rng.uniform(0, 6.3))
    roll = bank + rng.uniform(1, 4) * DEG * np.sin(2 * np.pi * tt / rng.uniform(3, 8) + rng.uniform(0, 6.3)) \
        + DEG * _wander(rng, tt, 10)
    env = rng.uniform(5, 25) - rng.uniform(0.05, 0.3) * (depth - depth.mean()) \
        + rng.uniform(1, 6) * (1 - np.exp(-tt / rng.uniform(200, 900)))
    series = {"yaw": yaw, "pitch": pitch, "roll": roll, "env": env, "depth": depth, "pos": speed * tt}
    return _Platform("towed_fish", t, mode, g, series, _ypr_rot(g, yaw, pitch, roll), ("measured", "model"),
                     0.6, 0.01)


def _borehole(rng: np.random.Generator, n: int) -> _Platform:
    dt = rng.uniform(0.2, 1.5)
    t, mode = _times(rng, n, dt, ("regular", "jitter", "gaps"))
    step = min(0.05, dt / 5)
    g = _grid(t, step, 2 * dt)
    tt = g - g[0]
    moving = np.clip(0.5 + 0.8 * np.sin(2 * np.pi * tt / rng.uniform(60, 400) + rng.uniform(0, 6.3)), 0, 1)
    depth = rng.uniform(200, 1500) - rng.uniform(0.05, 0.3) * np.cumsum(moving) * step
    span = max(np.ptp(depth), 1.0)
    x = (depth[0] - depth) / span
    incl = rng.uniform(0, 60) * DEG + rng.uniform(-15, 15) * DEG * np.sin(np.pi / 2 * x)
    azim = rng.uniform(-np.pi, np.pi) + rng.uniform(-40, 40) * DEG * x
    spin_rate = 2 * np.pi * rng.uniform(0.02, min(0.3, 0.15 / dt))
    spin = np.cumsum(spin_rate * (0.25 + 0.75 * moving) * (1 + 0.3 * _wander(rng, tt, 30))) * step
    spin += rng.uniform(0, 2 * np.pi)

    def rot(times: np.ndarray) -> np.ndarray:
        hole = _ypr(np.interp(times, g, azim), np.interp(times, g, incl), np.zeros(len(times)))
        return hole @ _rz(np.interp(times, g, spin))

    env = rng.uniform(10, 20) + rng.uniform(0.02, 0.04) * depth + 0.3 * _wander(rng, tt, 120)
    series = {"env": env, "depth": depth, "pos": depth[0] - depth, "yaw": azim, "pitch": incl}
    return _Platform("borehole", t, mode, g, series, rot, ("model", "measured"), 0.9, 0.005, path_axis="down")


def _pedestrian(rng: np.random.Generator, n: int) -> _Platform:
    dt = rng.uniform(0.05, 0.3)
    t, mode = _times(rng, n, dt, ("jitter", "regular", "gaps"))
    step = 0.02
    g = _grid(t, step, 2 * dt)
    tt = g - g[0]
    rate = np.zeros_like(tt)
    walking = np.ones_like(tt)
    c = rng.uniform(0, 20)
    while c < tt[-1]:
        length = rng.uniform(1.5, 4.0)
        turn = rng.choice([90, -90, 45, -45, 135, -135, 180]) * DEG
        sel = (tt >= c) & (tt < c + length)
        rate[sel] += turn / length * 2 * np.sin(np.pi * (tt[sel] - c) / length) ** 2
        c += length
        if rng.random() < 0.3:
            pause = rng.uniform(3, 15)
            walking[(tt >= c) & (tt < c + pause)] = 0.0
            c += pause
        c += rng.uniform(8, 40)
    walking = _lowpass(walking, step, 0.3)
    heading = rng.uniform(-np.pi, np.pi) + np.cumsum(rate) * step
    glances = np.zeros_like(tt)
    for _ in range(int(tt[-1] / 30) + 1):
        glances += rng.uniform(20, 60) * DEG * rng.choice([-1, 1]) * np.exp(
            -(((tt - rng.uniform(0, tt[-1])) / rng.uniform(1, 3)) ** 2))
    phone = rng.random() < 0.4
    f = rng.uniform(1.6, 2.2)
    pitch = (rng.uniform(20, 50) if phone else rng.uniform(-10, 10)) * DEG \
        + walking * rng.uniform(1, 6 if phone else 3) * DEG * np.sin(2 * np.pi * f * tt + rng.uniform(0, 6.3)) \
        + 3 * DEG * _wander(rng, tt, 5)
    roll = walking * rng.uniform(1, 3) * DEG * np.sin(np.pi * f * tt + rng.uniform(0, 6.3)) \
        + (6 if phone else 2) * DEG * _wander(rng, tt, 5)
    yaw = heading + glances + walking * rng.uniform(1, 3) * DEG * np.sin(np.pi * f * tt + rng.uniform(0, 6.3))
    sun = _lowpass(np.maximum(0, np.cos(heading - rng.uniform(-np.pi, np.pi))), step, rng.uniform(20, 60))
    env = rng.uniform(-5, 30) + rng.uniform(2, 10) * (1 - np.exp(-tt / rng.uniform(60, 400))) \
        + rng.uniform(1, 4) * sun
    series = {"yaw": yaw, "pitch": pitch, "roll": roll, "env": env,
              "pos": rng.uniform(1.1, 1.6) * np.cumsum(walking) * step, "sun": sun}
    return _Platform("pedestrian", t, mode, g, series, _ypr_rot(g, yaw, pitch, roll), ("model", "measured"),
                     1.0, rng.uniform(0.02, 0.04))


def _uav_survey(rng: np.random.Generator, n: int) -> _Platform:
    dt = rng.uniform(0.1, 1.0)
    t, mode = _times(rng, n, dt, ("regular", "jitter", "gaps"))
    step = min(0.05, dt / 4)
    g = _grid(t, step, 2 * dt)
    tt = g - g[0]
    speed, bank = rng.uniform(18, 30), rng.uniform(20, 35) * DEG
    omega = 9.81 * np.tan(bank) / speed
    ramp = 0.15
    rate, _ = _lines(tt, rng.uniform(40, 180), np.pi / (omega * (1 - ramp)), rng.uniform(0, 300), ramp)
    heading = rng.uniform(-np.pi, np.pi) + np.cumsum(rate) * step
    wind, wind_dir = rng.uniform(0, 8), rng.uniform(-np.pi, np.pi)
    turb = rng.uniform(0.5, 3) * DEG
    alt = rng.uniform(0, 40) * _wander(rng, tt, 60)
    climb = np.gradient(alt, step)
    roll = np.arctan(speed * rate / 9.81) + turb * _wander(rng, tt, 1, 10)
    pitch = rng.uniform(1, 4) * DEG + np.arctan(climb / speed) + turb * _wander(rng, tt, 1, 10)
    yaw = heading + np.arcsin(wind / speed * np.sin(wind_dir - heading)) + turb * _wander(rng, tt, 1, 10)
    load = 1 / np.cos(roll) + 0.15 * climb + 0.05 * _wander(rng, tt, 2, 20)
    sun = _lowpass(np.maximum(0, np.cos(heading - rng.uniform(-np.pi, np.pi))), step, rng.uniform(30, 120))
    env = rng.uniform(-5, 30) + rng.uniform(2, 8) * (1 - np.exp(-tt / rng.uniform(100, 600))) - 0.0065 * alt \
        + rng.uniform(1, 4) * sun
    series = {"yaw": yaw, "pitch": pitch, "roll": roll, "env": env, "load": load, "sun": sun}
    return _Platform("uav_survey", t, mode, g, series, _ypr_rot(g, yaw, pitch, roll), ("measured", "model"),
                     1.0, 0.01)


def _trapezoid(x: np.ndarray, accel: float) -> np.ndarray:
    """Normalised position 0..1 of a trapezoidal velocity profile over x in [0, 1] (accel: ramp fraction)."""
    a = min(max(accel, 1e-3), 0.5)
    v = 1 / (1 - a)
    return np.where(x < a, 0.5 * v / a * x ** 2,
                    np.where(x > 1 - a, 1 - 0.5 * v / a * (1 - x) ** 2, 0.5 * v * a + v * (x - a)))


def _robot_arm(rng: np.random.Generator, n: int) -> _Platform:
    dt = rng.uniform(0.05, 0.4)
    t, mode = _times(rng, n, dt, ("regular", "jitter", "bursts"))
    step = min(0.02, dt / 4)
    g = _grid(t, step, 2 * dt)
    tt = g - g[0]
    vmax, accel_t = rng.uniform(20, 90) * DEG, rng.uniform(0.2, 0.8)
    pose = np.array([rng.uniform(-np.pi, np.pi), rng.uniform(-1.3, 1.3), rng.uniform(-np.pi, np.pi)])
    knots_t, knots_a, moving_t = [0.0], [pose], []
    c = rng.uniform(0.5, 3)
    knots_t.append(c)
    knots_a.append(pose)
    while c < tt[-1]:
        new = np.array([rng.uniform(-np.pi, np.pi), rng.uniform(-1.3, 1.3), rng.uniform(-np.pi, np.pi)])
        delta = new - pose
        delta[[0, 2]] = (delta[[0, 2]] + np.pi) % (2 * np.pi) - np.pi
        duration = np.abs(delta).max() / vmax + accel_t
        moving_t.append((c, c + duration))
        pose = pose + delta
        c += duration
        knots_t.append(c)
        knots_a.append(pose)
        c += rng.uniform(1, 6)
        knots_t.append(c)
        knots_a.append(pose)
    kt, ka = np.array(knots_t), np.array(knots_a)
    angles = np.empty((len(tt), 3))
    moving = np.zeros_like(tt)
    idx = np.clip(np.searchsorted(kt, tt, side="right") - 1, 0, len(kt) - 2)
    x = np.clip((tt - kt[idx]) / np.maximum(kt[idx + 1] - kt[idx], 1e-9), 0, 1)
    for m0, m1 in moving_t:
        moving[(tt >= m0) & (tt < m1)] = 1.0
    frac = np.where(moving > 0, _trapezoid(x, accel_t / max(np.median(np.diff(kt)), 1e-3)), x)
    angles = ka[idx] + (ka[idx + 1] - ka[idx]) * frac[:, None]
    yaw, pitch, roll = angles[:, 0], angles[:, 1], angles[:, 2]
    env = rng.uniform(18, 28) + rng.uniform(2, 10) * _lowpass(moving, step, rng.uniform(20, 200)) \
        + rng.uniform(0, 4) * (1 - np.exp(-tt / rng.uniform(100, 600)))
    series = {"yaw": yaw, "pitch": pitch, "roll": roll, "env": env, "moving": moving}
    return _Platform("robot_arm", t, mode, g, series, _ypr_rot(g, yaw, pitch, roll), ("model", "measured"),
                     1.0, 0.002)


def _satellite(rng: np.random.Generator, n: int) -> _Platform:
    dt = rng.uniform(0.5, 4.0)
    t, mode = _times(rng, n, dt, ("regular", "gaps"))
    step = 2.0
    g = _grid(t, step, 4 * dt)
    t0 = g[0]
    r_km = 6371.0 + rng.uniform(400, 800)
    n_orb = np.sqrt(398600.0 / r_km ** 3)
    incl, raan, u0 = rng.uniform(50, 98) * DEG, rng.uniform(0, 2 * np.pi), rng.uniform(0, 2 * np.pi)
    tilt, lon = 10 * DEG, rng.uniform(0, 2 * np.pi)
    mdir = -np.array([np.sin(tilt) * np.cos(lon), np.sin(tilt) * np.sin(lon), np.cos(tilt)])
    b0 = rng.uniform(29000, 31500) * (6371.0 / r_km) ** 3

    def position(times: np.ndarray) -> np.ndarray:
        u = u0 + n_orb * (times - t0)
        cu, su = np.cos(u), np.sin(u)
        return np.stack([np.cos(raan) * cu - np.sin(raan) * su * np.cos(incl),
                         np.sin(raan) * cu + np.cos(raan) * su * np.cos(incl), su * np.sin(incl)], -1)

    def dipole(times: np.ndarray) -> np.ndarray:
        p = position(times)
        return b0 * (3 * (p @ mdir)[:, None] * p - mdir)

    spinner = rng.random() < 0.6
    if spinner:
        w_s = 2 * np.pi * rng.uniform(0.02, min(0.2, 0.12 / dt))
        cone = rng.uniform(0.5, 5) * DEG
        w_p = w_s * rng.uniform(0.2, 0.9) * rng.choice([-1, 1])
    else:
        w_s = rng.uniform(0.2, 2.0) * DEG
        cone = rng.uniform(20, 70) * DEG
        w_p = w_s * rng.uniform(0.3, 1.5) * rng.choice([-1, 1])
    base = _to_z(_unit(rng.normal(size=3)))
    ph_s, ph_p = rng.uniform(0, 2 * np.pi, 2)

    def rot(times: np.ndarray) -> np.ndarray:
        tau = times - t0
        return base @ _rz(w_p * tau + ph_p) @ _rx(np.full(len(tau), cone)) @ _rz(w_s * tau + ph_s)

    sun_dir = _unit(rng.normal(size=3))
    p = position(g) * r_km
    behind = (p @ sun_dir < 0) & (np.linalg.norm(np.cross(p, sun_dir), axis=1) < 6371.0)
    sunlit = _lowpass((~behind).astype(float), step, 20)
    env = rng.uniform(-10, 10) + rng.uniform(10, 40) * _lowpass(sunlit, step, rng.uniform(600, 2000)) \
        + 0.5 * _wander(rng, g - t0, 300)
    series = {"env": env, "sunlit": sunlit}
    orbit = {"dipole": dipole, "mdir": mdir, "sun": sun_dir, "altitude_km": r_km - 6371.0, "spinner": spinner,
             "spin_rate_rad_s": w_s, "cone_deg": cone / DEG}
    return _Platform("satellite", t, mode, g, series, rot, ("model",), 0.0, 0.0, path_axis="none", orbit=orbit)


def _observatory(rng: np.random.Generator, n: int) -> _Platform:
    dt = rng.uniform(2, 20) * 3600 / n
    t, mode = _times(rng, n, dt, ("regular", "gaps"))
    step = min(60.0, dt / 2)
    g = _grid(t, step, 2 * dt)
    tt = g - g[0]
    angles = np.array([rng.choice([0, 0.5, 1, -0.5]) * np.pi + rng.normal(0, 2) * DEG, rng.normal(0, 1) * DEG,
                       rng.normal(0, 1) * DEG])
    fixed = _ypr(*(np.array([a]) for a in angles))[0]

    def rot(times: np.ndarray) -> np.ndarray:
        return np.broadcast_to(fixed, (len(times), 3, 3))

    day = rng.uniform(0, 2 * np.pi)
    env = rng.uniform(5, 25) + rng.uniform(1, 6) * np.cos(2 * np.pi * tt / 86400 + day) \
        + rng.uniform(0, 0.5) * ((tt / rng.uniform(1200, 3600)) % 1.0) + 0.3 * _wander(rng, tt, 1800)
    series = {"env": env}
    return _Platform("observatory", t, mode, g, series, rot, ("measured", "model"), 0.5, 0.001, path_axis="none")


_BUILDERS = {"towed_fish": _towed_fish, "borehole": _borehole, "pedestrian": _pedestrian, "uav_survey": _uav_survey,
             "robot_arm": _robot_arm, "satellite": _satellite, "observatory": _observatory}


# ------------------------------------------------------------------------------------------------ sensor
@dataclass
class _Sensor:
    axes: np.ndarray  # rows: unit vectors of the axes in the body frame
    gain: np.ndarray
    offset: np.ndarray
    soft: np.ndarray
    hard: np.ndarray
    sigma: float
    lsb: float


def _sensor(rng: np.random.Generator, noise_cap: float) -> _Sensor:
    axes = _unit(np.eye(3) + rng.uniform(0, 1.0, (3, 1)) * DEG * _unit(rng.normal(size=(3, 3))) * (1 - np.eye(3)))
    soft = np.eye(3) + rng.uniform(-0.02, 0.02, (3, 3)) * np.where(np.eye(3) > 0, 1.0, 0.5)
    sigma = _loguniform(rng, 0.1, min(5.0, noise_cap))
    lsb = sigma * rng.uniform(0.5, 2.0) if rng.random() < 0.3 else 0.0
    return _Sensor(axes, 1 + rng.normal(0, 0.01, 3), rng.uniform(-500, 500, 3), soft,
                   rng.uniform(-800, 800, 3), sigma, lsb)


# ------------------------------------------------------------------------------------------------ effects
@dataclass
class _Eff:
    name: str
    form: str
    stage: str  # world, body, axis, raw, analog, adc, digital, ref
    fn: Callable
    amax: float
    unit: float
    info: dict = field(default_factory=dict)


@dataclass
class _Ctx:
    P: _Platform
    S: _Sensor
    t: np.ndarray
    f0: float
    bdir: np.ndarray
    world: Callable[[np.ndarray], np.ndarray]
    fref0: np.ndarray
    core: np.ndarray  # the core's temperature on the platform grid
    temp_log: np.ndarray | None
    heat2: np.ndarray  # an unlogged side temperature on the grid (unit peak)
    noise: float
    dt: float
    ainv: np.ndarray = field(default_factory=lambda: np.eye(3))
    c: np.ndarray = field(default_factory=lambda: np.zeros(3))
    raw0: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    b0: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    m0: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    ref_kind: str = "model"
    sigma_ref: float = 0.0

    def core_at(self, times: np.ndarray) -> np.ndarray:
        return np.interp(times, self.P.grid, self.core)

    def tau(self, times: np.ndarray) -> np.ndarray:
        return times - self.t[0]

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])


def _peak_norm(v: np.ndarray) -> float:
    return float(max(np.abs(v).max() if v.ndim == 1 else np.linalg.norm(v, axis=1).max(), 1e-300))


def _temperature(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    if ctx.temp_log is None:
        return None
    comps = [str(rng.choice(["offset", "scale"]))]
    comps += [c for c in ("offset", "scale", "align") if c not in comps and rng.random() < 0.5]
    v_off = rng.normal(size=3) if "offset" in comps else np.zeros(3)
    v_sc = (rng.normal(size=3) * 0.5 + rng.normal()) if "scale" in comps else np.zeros(3)
    v_al = rng.normal(size=(3, 3)) if "align" in comps else np.zeros((3, 3))
    norm = np.sqrt(np.sum(v_off ** 2) + np.sum(v_sc ** 2) + np.sum(v_al ** 2))
    v_off, v_sc, v_al = v_off / norm, v_sc / norm, v_al / norm
    f0, s = ctx.f0, ctx.S
    k, w, off = v_sc / f0, np.cross(v_al, s.axes) / f0, v_off / s.gain
    tref = float(ctx.core_at(ctx.t).mean())

    def fn(c: _Ctx, times: np.ndarray, m: np.ndarray, bp: np.ndarray, a: float) -> np.ndarray:
        d = (c.core_at(times) - tref)[:, None]
        return m + a * d * (m * k + bp @ w.T + off)

    lim = [20.0 / np.abs(v_off).max() if "offset" in comps else np.inf,
           300e-6 * f0 / np.abs(v_sc).max() if "scale" in comps else np.inf,
           50e-6 * f0 / np.linalg.norm(v_al, axis=1).max() if "align" in comps else np.inf]
    amax = float(min(lim))
    info = {"components": comps, "offset_nT_per_C": v_off, "scale_per_C": v_sc / f0,
            "align_rad_per_C": v_al / f0}
    return _Eff("temperature", "+".join(comps), "axis", fn, amax, amax / 10, info)


def _field_drift(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    name = ctx.P.name
    forms = {"observatory": ("sq", "bay", "storm"), "satellite": ("fac", "ring")}.get(name, ("pulsation", "bay",
                                                                                            "ssc"))
    form = str(rng.choice(forms))
    dur = max(ctx.duration, 1.0)
    direction = _unit(rng.normal(size=3) + np.array([-1.0, 0.0, 0.5]))
    if form == "sq":
        amps, ph1 = rng.uniform(0.3, 1, 3), rng.uniform(0, 2 * np.pi, 3)
        amps2, ph2 = rng.uniform(0, 0.4, 3), rng.uniform(0, 2 * np.pi, 3)

        def shape(tau):
            x = 2 * np.pi * tau[:, None] / 86400
            return amps * np.cos(x + ph1) + amps2 * np.cos(2 * x + ph2)
    elif form == "bay":
        c, w = rng.uniform(0.2, 0.8) * dur, rng.uniform(0.1, 0.3) * dur

        def shape(tau):
            return np.exp(-(((tau - c) / w) ** 2))[:, None] * direction
    elif form in ("storm", "ssc"):
        c, w, rec = rng.uniform(0.15, 0.7) * dur, rng.uniform(0.02, 0.1) * dur, rng.uniform(0.5, 3) * dur

        def shape(tau):
            up = 0.5 * (1 + np.tanh((tau - c) / w))
            return (up * np.exp(-np.maximum(tau - c, 0) / rec))[:, None] * direction
    elif form == "pulsation":
        period = rng.uniform(dur / 3, dur)
        e1, e2 = _unit(rng.normal(size=3)), _unit(rng.normal(size=3))
        ell, ph = rng.uniform(0, 1), rng.uniform(0, 2 * np.pi)
        c, w = float(rng.uniform(0.3, 0.7) * dur), float(rng.uniform(0.4, 1) * dur)

        def shape(tau):
            x = 2 * np.pi * tau / period + ph
            env = np.exp(-(((tau - c) / w) ** 2))
            return (env * np.cos(x))[:, None] * e1 + (ell * env * np.sin(x))[:, None] * e2
    elif form == "fac":
        k = int(rng.integers(1, 4))
        cs, ws, amps = rng.uniform(0.1, 0.9, k) * dur, rng.uniform(0.03, 0.15, k) * dur, rng.uniform(0.4, 1, k)
        dip = ctx.world

        def shape(tau):
            b = _unit(dip(tau + ctx.t[0]))
            east = _unit(np.cross(b, np.array([0.0, 0.0, 1.0])) + 1e-9)
            prof = (amps[:, None] * np.exp(-(((tau[None, :] - cs[:, None]) / ws[:, None]) ** 2))).sum(0)
            return prof[:, None] * east
    else:  # ring current along the dipole axis, building up
        mdir = ctx.P.orbit["mdir"] if ctx.P.orbit else np.array([0, 0, -1.0])
        c, w = rng.uniform(0.2, 0.8) * dur, rng.uniform(0.1, 0.4) * dur

        def shape(tau):
            return (0.5 * (1 + np.tanh((tau - c) / w)))[:, None] * (-mdir)
    scale = 1 / _peak_norm(shape(ctx.tau(ctx.t)))

    def fn(c: _Ctx, times: np.ndarray, a: float) -> np.ndarray:
        return a * scale * shape(c.tau(times))

    amax = min(0.01 * ctx.f0, 500.0)
    return _Eff("field_drift", form, "world", fn, amax, amax / 10)


def _offset_drift(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    form = str(rng.choice(["settle", "walk", "sigmoid"]))
    dur = max(ctx.duration, 1.0)
    coef = rng.normal(size=3)
    if form == "settle":
        taus = rng.uniform(0.1, 0.6, 3) * dur

        def shape(tau):
            return coef * (1 - np.exp(-tau[:, None] / taus))
    elif form == "walk":
        nodes = np.linspace(0, dur, 40)
        walk = np.cumsum(rng.normal(size=(40, 3)), axis=0)
        kernel = np.hanning(9)
        walk = np.stack([np.convolve(np.pad(walk[:, i], 4, mode="edge"), kernel / kernel.sum(), "valid")
                         for i in range(3)], -1)

        def shape(tau):
            return np.stack([np.interp(tau, nodes, walk[:, i]) for i in range(3)], -1)
    else:
        cs, ws = rng.uniform(0.25, 0.75, 3) * dur, rng.uniform(0.08, 0.3, 3) * dur

        def shape(tau):
            return coef * np.tanh((tau[:, None] - cs) / ws)
    base = shape(ctx.tau(ctx.t))
    scale = 1 / _peak_norm(base - base.mean(0))

    def fn(c: _Ctx, times: np.ndarray, a: float) -> np.ndarray:
        return a * scale * shape(c.tau(times))

    amax = min(0.01 * ctx.f0, 300.0)
    return _Eff("offset_drift", form, "raw", fn, amax, amax / 10)


def _lag(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    form = str(rng.choice(["skew", "window", "iir"]))
    if form == "skew":
        k = rng.permutation(rng.choice([[0.0, 0.5, 1.0], [0.0, 0.0, 1.0], [0.0, 1.0, 1.0]]))
    else:
        k = np.zeros(3)
        chosen = rng.choice(3, int(rng.integers(1, 4)), replace=False)
        k[chosen] = rng.uniform(0.3, 1.0, len(chosen))
        k /= k.max()
    dt = ctx.dt

    if form == "skew":
        def fn(c: _Ctx, chain: Callable, a: float) -> np.ndarray:
            out = np.empty((len(c.t), 3))
            for d in np.unique(k):
                cols = k == d
                out[:, cols] = chain(c.t - a * d * dt)[:, cols]
            return out
        stage = "analog"
    elif form == "window":
        def fn(c: _Ctx, chain: Callable, a: float) -> np.ndarray:
            out = chain(c.t) if np.any(k == 0) else np.empty((len(c.t), 3))
            for i in np.flatnonzero(k > 0):
                width = 2 * a * k[i] * dt
                acc = np.zeros(len(c.t))
                for x, wgt in zip(_GL_NODES, _GL_WEIGHTS):
                    acc += 0.5 * wgt * chain(c.t - 0.5 * width * (1 - x))[:, i]
                out[:, i] = acc
            return out
        stage = "analog"
    else:
        def fn(c: _Ctx, raw: np.ndarray, a: float) -> np.ndarray:  # type: ignore[misc]
            out = raw.copy()
            for i in np.flatnonzero(k > 0):
                alpha = 1 / (1 + a * k[i])
                out[:, i] = lfilter([alpha], [1, alpha - 1], raw[:, i], zi=[(1 - alpha) * raw[0, i]])[0]
            return out
        stage = "digital"
    return _Eff("lag", form, stage, fn, 0.5, 0.1, {"axis_weights": k, "unit": "delay in sample periods"})


def _nonlinearity(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    form = str(rng.choice(["poly", "knee", "soft"]))
    f0 = ctx.f0
    if form == "poly":
        a2, a3 = rng.normal(size=3), rng.normal(size=3)

        def shape(m):
            x = m / f0
            return f0 * (a2 * x ** 2 + a3 * x ** 3)
    elif form == "knee":
        knee = rng.uniform(0.3, 0.8, 3) * np.abs(ctx.m0).max(0)
        kap = rng.normal(size=3)

        def shape(m):
            return kap * np.sign(m) * np.maximum(np.abs(m) - knee, 0)
    else:
        cc = rng.uniform(0.2, 1.0, 3)

        def shape(m):
            return cc * (f0 * np.tanh(m / f0) - m)
    scale = 1 / float(np.abs(shape(ctx.m0)).max() + 1e-300)

    def fn(c: _Ctx, times: np.ndarray, m: np.ndarray, bp: np.ndarray, a: float) -> np.ndarray:
        return m + a * scale * shape(m)

    amax = 0.01 * f0
    return _Eff("nonlinearity", form, "axis", fn, amax, amax / 20)


def _cross_field(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    perp = np.array([rng.choice([j for j in range(3) if j != i]) for i in range(3)])
    kc = rng.uniform(0.3, 1.0, 3) * (rng.random(3) < 0.8)
    if not kc.any():
        kc[int(rng.integers(3))] = 1.0
    f0 = ctx.f0

    def shape(m):
        return -kc * m * m[:, perp] ** 2 / f0 ** 2
    scale = 1 / float(np.abs(shape(ctx.m0)).max() + 1e-300)

    def fn(c: _Ctx, times: np.ndarray, m: np.ndarray, bp: np.ndarray, a: float) -> np.ndarray:
        return m + a * scale * shape(m)

    return _Eff("cross_field", "ring_core", "axis", fn, 0.01 * f0, 0.001 * f0, {"perpendicular_axis": perp})


def _reference_heading(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    axis = _unit(rng.normal(size=3))
    alpha, width = rng.uniform(0.0, 0.7), rng.uniform(0.1, 0.25)

    def shape(b):
        c = _unit(b) @ axis
        return alpha * 0.5 * (5 * c ** 3 - 3 * c) + (1 - alpha) * np.exp(-((c / width) ** 2))
    base = shape(ctx.b0)
    mean = base.mean()
    scale = 1 / float(np.abs(base - mean).max() + 1e-300)

    def fn(c: _Ctx, a: float) -> np.ndarray:
        return a * scale * (shape(c.b0) - mean)

    return _Eff("reference_heading", "caesium", "ref", fn, 20.0, 2.0, {"optical_axis": axis})


def _adc_dnl(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    period = rng.uniform(300, 3000, 3)
    phase = rng.uniform(0, 3000, 3)
    mask = (rng.random(3) < 0.7).astype(float)
    if not mask.any():
        mask[int(rng.integers(3))] = 1.0

    def fn(c: _Ctx, raw: np.ndarray, a: float) -> np.ndarray:
        x = (raw - phase) / period
        return raw + a * mask * (2 * (x - np.floor(x)) - 1)

    amax = float(min(30.0, 0.1 * period[mask > 0].min()))
    return _Eff("adc_dnl", "sawtooth", "adc", fn, amax, amax / 5, {"period_nT": period, "axes": mask})


def _throttle_current(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    if "load" not in ctx.P.series:
        return None
    direction = _unit(rng.normal(size=3))
    base = ctx.P.at("load", ctx.t)
    mean = base.mean()
    scale = 1 / float(np.abs(base - mean).max() + 1e-300)

    def fn(c: _Ctx, times: np.ndarray, r: np.ndarray, a: float) -> np.ndarray:
        return a * scale * (c.P.at("load", times) - mean)[:, None] * direction

    return _Eff("throttle_current", "cable", "body", fn, 300.0, 30.0)


def _core_gradient(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    j = int(rng.integers(3))
    coef = _unit(np.eye(3)[j] + 0.4 * rng.normal(size=3))
    dtemp = rng.uniform(0.5, 3.0)
    base = np.interp(ctx.t, ctx.P.grid, ctx.heat2)
    mean = base.mean()
    scale = 1 / float(np.abs(base - mean).max() + 1e-300)

    def fn(c: _Ctx, times: np.ndarray, a: float) -> np.ndarray:
        return a * scale * (np.interp(times, c.P.grid, c.heat2) - mean)[:, None] * coef

    return _Eff("core_gradient", "one_side", "raw", fn, 20.0 * dtemp, 2.0 * dtemp, {"side_dT_C": dtemp})


def _excitation_crosstalk(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    dur = max(ctx.duration, 1.0)
    f0 = min(rng.uniform(8, 40) / dur, 0.15 / ctx.dt)
    if f0 * dur < 6:
        return None
    drift, ph = rng.uniform(-0.5, 0.5), rng.uniform(0, 2 * np.pi)
    coef = _unit(rng.normal(size=3))

    def fn(c: _Ctx, times: np.ndarray, a: float) -> np.ndarray:
        tau = c.tau(times)
        phase = 2 * np.pi * f0 * (tau + drift * (tau ** 2 / (2 * dur) - tau / 2)) + ph
        return a * np.cos(phase)[:, None] * coef

    return _Eff("excitation_crosstalk", "beat", "raw", fn, 50.0, 5.0, {"beat_Hz": f0, "cycles": f0 * dur})


def _vibration_noise(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    n = len(ctx.t)
    k = int(rng.integers(2, 6))
    total = int(rng.uniform(0.3, 0.6) * n)
    if total < 40 * k:
        k = max(1, total // 40)
    if k < 1 or total < 40:
        return None
    lengths = np.full(k, total // k)
    gaps = rng.dirichlet(np.ones(k + 1)) * (n - total)
    mask = np.zeros(n, bool)
    pos = 0.0
    for i in range(k):
        pos += gaps[i]
        mask[int(pos):int(pos) + lengths[i]] = True
        pos += lengths[i]
    x = rng.normal(size=(n + 2, 3))
    x = (0.5 * x[:-2] + x[1:-1] + 0.5 * x[2:]) / np.sqrt(1.5)
    x[~mask] = 0.0
    x /= np.sqrt(np.mean(x[mask] ** 2))

    def fn(c: _Ctx, raw: np.ndarray, a: float) -> np.ndarray:
        return raw + a * x

    amax = 10 * ctx.noise
    return _Eff("vibration_noise", "bursts", "digital", fn, amax, 2 * ctx.noise, {"fraction": float(mask.mean())})


def _path_anomaly(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    P = ctx.P
    if "pos" not in P.series:
        return None
    pos_t = P.at("pos", ctx.t)
    s0, s1 = float(pos_t[0]), float(pos_t[-1])
    speed = np.gradient(P.series["pos"], P.grid)
    vmax = float(speed.max())
    if s1 - s0 < 5.0 or vmax <= 0:
        return None
    if P.name == "borehole":
        spacing = rng.uniform(9, 12)
        centres = np.arange(s0 + rng.uniform(0, spacing), s1, spacing)
        dist = np.full(len(centres), rng.uniform(0.15, 0.4))
    else:
        k = int(rng.integers(2, 8))
        centres = rng.uniform(s0 + 0.05 * (s1 - s0), s1 - 0.05 * (s1 - s0), k)
        dist = rng.uniform(5, 30, k) if P.name == "towed_fish" else rng.uniform(1, 4, k)
    dist = np.maximum(dist, 3 * ctx.dt * vmax)
    if len(centres) < 2:
        return None
    moments = _unit(rng.normal(size=(len(centres), 3)))
    strength = rng.uniform(0.3, 1.0, len(centres))
    along, across = [], []
    for sc in centres:
        tc = np.interp(sc, P.series["pos"], P.grid)
        if P.path_axis == "down":
            e = np.array([0.0, 0.0, 1.0])
        else:
            yaw = np.interp(tc, P.grid, P.series["yaw"])
            e = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        along.append(e)
        across.append(_unit(np.cross(e, rng.normal(size=3))))
    along_a, across_a = np.array(along), np.array(across)

    def raw_field(times):
        s = P.at("pos", times)
        out = np.zeros((len(times), 3))
        for i in range(len(centres)):
            r = (s - centres[i])[:, None] * along_a[i] + dist[i] * across_a[i]
            rn = np.linalg.norm(r, axis=1)
            rh = r / rn[:, None]
            out += strength[i] * dist[i] ** 3 * (3 * (rh @ moments[i])[:, None] * rh - moments[i]) / rn[:, None] ** 3
        return out
    scale = 1 / _peak_norm(raw_field(ctx.t))

    def fn(c: _Ctx, times: np.ndarray, a: float) -> np.ndarray:
        return a * scale * raw_field(times)

    amax = min(0.01 * ctx.f0, 500.0)
    return _Eff("path_anomaly", "dipoles", "world", fn, amax, amax / 10, {"objects": len(centres)})


def _tx_supply_dip(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    dur = max(ctx.duration, 1.0)
    period = dur / rng.uniform(8, 40)
    duty = rng.uniform(0.15, 0.35)
    if duty * period < 4 * ctx.dt:
        period = 4 * ctx.dt / duty
    if dur / period < 6:
        return None
    ph = rng.uniform(0, period)
    e = _unit(rng.normal(size=3))
    while np.ptp(e) < 0.8:
        e = _unit(rng.normal(size=3))
    f0 = ctx.f0

    def fn(c: _Ctx, times: np.ndarray, m: np.ndarray, bp: np.ndarray, a: float) -> np.ndarray:
        pulse = ((c.tau(times) + ph) % period < duty * period).astype(float)
        return m - a / f0 * pulse[:, None] * e * m

    return _Eff("tx_supply_dip", "ratiometric", "axis", fn, 0.002 * f0, 0.0002 * f0,
                {"period_s": period, "duty": duty})


def _solar_array(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    if ctx.P.orbit is None:
        return None
    normals = np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, -1.0, 0], [0, 0, 1.0]])
    loops = _unit(rng.normal(size=(5, 3))) * rng.uniform(0.3, 1.0, (5, 1)) * (rng.random((5, 1)) < 0.8)
    sun = ctx.P.orbit["sun"]

    def raw_field(times, rot):
        s_b = np.einsum("nji,j->ni", rot, sun)
        lit = np.interp(times, ctx.P.grid, ctx.P.series["sunlit"])
        return (np.maximum(0, s_b @ normals.T) * lit[:, None]) @ loops
    scale = 1 / _peak_norm(raw_field(ctx.t, ctx.P.rot(ctx.t)))

    def fn(c: _Ctx, times: np.ndarray, r: np.ndarray, a: float) -> np.ndarray:
        return a * scale * raw_field(times, r)

    return _Eff("solar_array", "strings", "body", fn, 300.0, 30.0)


def _pressure_stress(rng: np.random.Generator, ctx: _Ctx) -> _Eff | None:
    if "depth" not in ctx.P.series:
        return None
    e = _unit(rng.normal(size=3))
    base = ctx.P.at("depth", ctx.t)
    mean = base.mean()
    scale = 1 / float(np.abs(base - mean).max() + 1e-300)
    f0 = ctx.f0

    def fn(c: _Ctx, times: np.ndarray, m: np.ndarray, bp: np.ndarray, a: float) -> np.ndarray:
        dp = scale * (c.P.at("depth", times) - mean)
        return m + a / f0 * dp[:, None] * e * m

    return _Eff("pressure_stress", "magnetoelastic", "axis", fn, 0.002 * f0, 0.0002 * f0)


_FACTORIES: dict[str, Callable[[np.random.Generator, _Ctx], _Eff | None]] = {
    "temperature": _temperature, "field_drift": _field_drift, "offset_drift": _offset_drift, "lag": _lag,
    "nonlinearity": _nonlinearity, "cross_field": _cross_field, "reference_heading": _reference_heading,
    "adc_dnl": _adc_dnl, "throttle_current": _throttle_current, "core_gradient": _core_gradient,
    "excitation_crosstalk": _excitation_crosstalk, "vibration_noise": _vibration_noise,
    "path_anomaly": _path_anomaly, "tx_supply_dip": _tx_supply_dip, "solar_array": _solar_array,
    "pressure_stress": _pressure_stress}


# ------------------------------------------------------------------------------------------------ forward model
def _chain(ctx: _Ctx, times: np.ndarray, effs: list[tuple[_Eff, float]]) -> np.ndarray:
    """Noise-free readings (before the converter) at the given times."""
    s = ctx.S
    bw = ctx.world(times)
    for e, a in effs:
        if e.stage == "world":
            bw = bw + e.fn(ctx, times, a)
    rot = ctx.P.rot(times)
    bp = np.einsum("nji,nj->ni", rot, bw) @ s.soft.T + s.hard
    for e, a in effs:
        if e.stage == "body":
            bp = bp + e.fn(ctx, times, rot, a)
    m = bp @ s.axes.T
    for e, a in effs:
        if e.stage == "axis":
            m = e.fn(ctx, times, m, bp, a)
    raw = m * s.gain + s.offset
    for e, a in effs:
        if e.stage == "raw":
            raw = raw + e.fn(ctx, times, a)
    return raw


def _record(ctx: _Ctx, effs: list[tuple[_Eff, float]]) -> tuple[np.ndarray, np.ndarray]:
    analog = [(e, a) for e, a in effs if e.stage == "analog"]
    raw = analog[0][0].fn(ctx, lambda times: _chain(ctx, times, effs), analog[0][1]) if analog \
        else _chain(ctx, ctx.t, effs)
    for stage in ("adc", "digital"):
        for e, a in effs:
            if e.stage == stage:
                raw = e.fn(ctx, raw, a)
    fref = ctx.fref0.copy()
    for e, a in effs:
        if e.stage == "ref":
            fref = fref + e.fn(ctx, a)
    return raw, fref


def _scalar(ctx: _Ctx, raw: np.ndarray, fref: np.ndarray) -> np.ndarray:
    return np.linalg.norm((raw - ctx.c) @ ctx.ainv.T, axis=1) - fref


# ------------------------------------------------------------------------------------------------ visibility
def _bases(ctx: _Ctx) -> dict[str, np.ndarray]:
    b = ctx.b0
    norm = np.linalg.norm(b, axis=1)
    u = b / norm[:, None]
    iu = np.triu_indices(3)
    cal = np.column_stack([norm * u[:, i] * u[:, j] for i, j in zip(*iu)] + [u[:, i] for i in range(3)])
    leg = _legendre(ctx.t, POLY_DEGREE)
    out = {"cal": cal}
    if ctx.temp_log is not None:
        out["temperature"] = cal * (ctx.temp_log - ctx.temp_log.mean())[:, None]
    if ctx.P.orbit is not None:
        wdir = _unit(ctx.world(ctx.t))
        out["field_drift"] = np.column_stack([wdir[:, k:k + 1] * leg for k in range(3)])
    else:
        out["field_drift"] = leg
    out["offset_drift"] = np.column_stack([u[:, k:k + 1] * leg for k in range(3)])
    eps = 1e-3 * ctx.dt
    deriv = (_chain(ctx, ctx.t + eps, []) - _chain(ctx, ctx.t - eps, [])) / (2 * eps)
    w = u @ ctx.ainv  # w[:, i] = u . C[:, i]
    out["lag"] = w * deriv
    m = ctx.raw0 - ctx.c
    out["nonlinearity"] = np.column_stack([w * m ** 2, w * m ** 3])
    return out


def _fixed_vector(ctx: _Ctx, raw: np.ndarray) -> np.ndarray:
    d = (raw - ctx.raw0) @ ctx.ainv.T
    return d - d.mean(0)


@dataclass
class _Sized:
    eff: _Eff
    amp: float
    vis: float
    beyond: float
    contrib: np.ndarray  # scalar residual contribution (turning) or vector deviation (fixed)


def _size(ctx: _Ctx, eff: _Eff, measure: Callable[[np.ndarray], float], contribution: Callable,
          target: float, bounds: tuple[float, float]) -> tuple[float, float, np.ndarray] | None:
    a = eff.unit
    y = contribution(a)
    v = measure(y)
    for _ in range(6):
        if not np.isfinite(v) or v <= 1e-9:
            return None
        if abs(v / target - 1) < 0.08:
            break
        a = a * target / v
        if a > eff.amax * 1.000001:
            return None
        y = contribution(a)
        v = measure(y)
    if not bounds[0] <= v <= bounds[1]:
        return None
    return a, v, y


# ------------------------------------------------------------------------------------------------ assembly
def _choose(index: int, rng: np.random.Generator) -> tuple[str, tuple[str, ...], tuple[str, ...]]:
    """(category, library effects, outside effects) of a case: the category and, for single, outside and fixed
    cases, the effect follow the index so that every block covers them; the rest is drawn."""
    block, k = divmod(index, 24)
    category = PATTERN[k]
    nth = PATTERN[:k].count(category)
    turning = tuple(e for e in LIBRARY)
    if category == "single":
        return category, (LIBRARY[(nth + block) % 6],), ()
    if category in ("pair", "triple"):
        size = 2 if category == "pair" else 3
        return category, tuple(str(x) for x in rng.choice(turning, size, replace=False)), ()
    if category == "outside":
        return category, (), (OUTSIDE[(6 * block + nth) % len(OUTSIDE)],)
    if category == "outside_plus":
        out = OUTSIDE[(2 * block + nth + 5) % len(OUTSIDE)]
        allowed = [e for e in LIBRARY if not (REFERENCE_NEEDED.get(e) and REFERENCE_NEEDED.get(out)
                                              and REFERENCE_NEEDED[e] != REFERENCE_NEEDED[out])]
        return category, (str(rng.choice(allowed)),), (out,)
    if category == "fixed":
        return category, (FIXED_EFFECTS[(2 * block + nth) % 4],), ()
    if category == "too_short":
        pick = rng.integers(len(LIBRARY) + 1)
        return category, ((LIBRARY[pick],) if pick < len(LIBRARY) else ()), ()
    return category, (), ()


def _context(rng: np.random.Generator, schedule: str, n: int, names: tuple[str, ...]) -> _Ctx | None:
    P = _BUILDERS[schedule](rng, n)
    needs = {REFERENCE_NEEDED[e] for e in names if e in REFERENCE_NEEDED}
    if len(needs) > 1:
        return None
    ref = needs.pop() if needs else str(rng.choice(P.ref_options))
    if ref not in P.ref_options:
        return None
    S = _sensor(rng, min([NOISE_CAP.get(e, 5.0) for e in names] + [5.0]))
    f0 = rng.uniform(20000, 65000)
    incl, decl = rng.uniform(-80, 80) * DEG, rng.uniform(-30, 30) * DEG
    bdir = np.array([np.cos(incl) * np.cos(decl), np.cos(incl) * np.sin(decl), np.sin(incl)])
    sigma_ref = 0.0
    if P.orbit is not None:
        dipole = P.orbit["dipole"]
        field_fn = dipole
        f0 = float(np.median(np.linalg.norm(dipole(P.t), axis=1)))
        fref0 = np.linalg.norm(dipole(P.t), axis=1)
    elif ref == "measured":
        tt = P.grid - P.grid[0]
        nat = rng.uniform(1, 20) * _wander(rng, tt, 1800 if schedule == "observatory" else 300)
        grid = P.grid

        def field_fn(times: np.ndarray) -> np.ndarray:
            return (f0 + np.interp(times, grid, nat))[:, None] * bdir
        fref0 = f0 + np.interp(P.t, grid, nat)
        sigma_ref = rng.uniform(0.01, 0.05)
    else:
        def field_fn(times: np.ndarray) -> np.ndarray:
            return np.broadcast_to(f0 * bdir, (len(times), 3))
        fref0 = np.full(len(P.t), f0)
    step = P.grid[1] - P.grid[0]
    env = P.series["env"]
    core = _lowpass(env, step, rng.uniform(0, 120))
    temp_log = None
    if any(e in names for e in ("temperature", "core_gradient")) or rng.random() < 0.75:
        therm = _lowpass(env, step, rng.uniform(0, 120))
        res = float(rng.choice([0.01, 0.0625, 0.1]))
        temp_log = np.round((np.interp(P.t, P.grid, therm) + rng.normal(0, rng.uniform(0.005, 0.03), len(P.t)))
                            / res) * res
    if "sun" in P.series and rng.random() < 0.5:
        heat_in = P.series["sun"]
    else:
        heat_in = _lowpass((rng.random(len(P.grid) // max(1, int(30 / step)) + 2) < 0.5).astype(float).repeat(
            max(1, int(30 / step)))[:len(P.grid)], step, 5.0)
    heat2 = _lowpass(heat_in, step, rng.uniform(30, 300))
    heat2 = heat2 - heat2.mean()
    heat2 /= max(np.abs(heat2).max(), 1e-12)
    noise = float(np.sqrt(S.sigma ** 2 + S.lsb ** 2 / 12 + sigma_ref ** 2))
    dt = float(np.median(np.diff(P.t))) if len(P.t) > 1 else 1.0
    ctx = _Ctx(P, S, P.t, float(f0), bdir, field_fn, fref0, core, temp_log, heat2, noise, dt)
    a = np.diag(S.gain) @ S.axes @ S.soft
    ctx.ainv = np.linalg.inv(a)
    ctx.c = S.gain * (S.axes @ S.hard) + S.offset
    ctx.raw0 = _chain(ctx, P.t, [])
    ctx.b0 = (ctx.raw0 - ctx.c) @ ctx.ainv.T
    ctx.m0 = (ctx.raw0 - S.offset) / S.gain
    ctx.ref_kind, ctx.sigma_ref = ref, sigma_ref
    return ctx


def _spikes(rng: np.random.Generator, ctx: _Ctx, fixed: bool) -> tuple[np.ndarray, np.ndarray, float, str] | None:
    n = len(ctx.t)
    count = int(rng.integers(5, 13))
    form = str(rng.choice(["single_axis", "vector", "power_of_two"]))
    rows: list[int] = []
    tries = 0
    while len(rows) < count and tries < 2000:
        r = int(rng.integers(3, n - 3))
        if all(abs(r - q) >= 6 for q in rows):
            rows.append(r)
        tries += 1
    if len(rows) < 5:
        return None
    rows_a = np.sort(np.array(rows))
    spikes = np.zeros((len(rows_a), 3))
    sizes = []
    for j, r in enumerate(rows_a):
        for _ in range(20):
            target = rng.uniform(12, 40) * ctx.noise
            d = _unit(rng.normal(size=3)) if form == "vector" else np.eye(3)[int(rng.integers(3))] * rng.choice([-1, 1])
            gain = float(np.linalg.norm(ctx.ainv @ d) if fixed else np.abs(_unit(ctx.b0[r]) @ (ctx.ainv @ d)))
            if gain < 0.2:
                continue
            size = target / gain
            if form == "power_of_two":
                size = 2.0 ** np.ceil(np.log2(size))
            if size > 0.2 * ctx.f0:
                continue
            s = size * d
            if fixed:
                eff = float(np.linalg.norm(ctx.ainv @ s))
            else:
                raw = ctx.raw0[r] + s
                eff = abs(float(np.linalg.norm(ctx.ainv @ (raw - ctx.c)) - np.linalg.norm(ctx.b0[r])))
            if eff >= OUTLIER_MIN_SIGMA * ctx.noise:
                spikes[j] = s
                sizes.append(eff / ctx.noise)
                break
        else:
            return None
    return rows_a, spikes, float(min(sizes)), form


def _confoundable(ctx: _Ctx, sized: dict[str, _Sized], bases: dict[str, np.ndarray], fixed: bool,
                  names: tuple[str, ...]) -> tuple[tuple[str, str], ...]:
    pairs: set[tuple[str, str]] = set()
    noise = ctx.noise
    if fixed:
        if set(names) & {"offset_drift", "field_drift"}:
            pairs.add(("field_drift", "offset_drift"))
        leg = _legendre(ctx.t, POLY_DEGREE)
        q_time = _orth(leg)
        for name in names:
            if name == "outliers":
                continue
            y = sized[name].contrib
            thr = max(3.0, 0.3 * sized[name].vis)
            if name == "temperature":
                rem = np.sqrt(np.mean(np.sum(_remove(q_time, y) ** 2, axis=1))) / noise
                if rem < thr:
                    pairs |= {("offset_drift", "temperature"), ("field_drift", "temperature")}
            elif ctx.temp_log is not None:
                q_t = _orth(np.column_stack([np.ones(len(ctx.t)), ctx.temp_log]))
                rem = np.sqrt(np.mean(np.sum(_remove(q_t, y) ** 2, axis=1))) / noise
                if rem < thr:
                    pairs.add(tuple(sorted((name, "temperature"))))  # type: ignore[arg-type]
        return tuple(sorted(pairs))
    cache: dict[str, np.ndarray] = {}
    for name in names:
        if name == "outliers":
            continue
        y = sized[name].contrib
        thr = max(3.0, 0.3 * sized[name].vis)
        for other in LIBRARY:
            if other in (name, "outliers") or other not in bases:
                continue
            if other not in cache:
                cache[other] = _orth(np.column_stack([bases["cal"], bases[other]]))
            q = cache[other]
            if _rms(_remove(q, y)) / noise < thr:
                pairs.add(tuple(sorted((name, other))))  # type: ignore[arg-type]
    return tuple(sorted(pairs))


_FAILURES: list[str] = []  # why records were drawn again (for inspection; bounded)


def _fail(reason: str) -> Case | None:
    """Note why a record is drawn again; None."""
    if len(_FAILURES) < 10000:
        _FAILURES.append(reason)
    return None


def _attempt(rng: np.random.Generator, index: int, category: str, lib: tuple[str, ...], out: tuple[str, ...],
             attempt: int) -> Case | None:
    fixed = category == "fixed"
    if fixed:
        schedule = FIXED_SCHEDULE
    else:
        allowed = [s for s in SCHEDULES if all(s in OUTSIDE_SCHEDULES.get(o, SCHEDULES) for o in out)]
        schedule = str(rng.choice(allowed))
    short = category == "too_short"
    n = int(rng.integers(8, 15)) if short else int(rng.integers(300, 2001))
    names = lib + out
    ctx = _context(rng, schedule, n, names)
    if ctx is None:
        return _fail("reference")
    effects: dict[str, _Eff] = {}
    for name in names:
        if name == "outliers":
            continue
        e = _FACTORIES[name](rng, ctx)
        if e is None:
            return _fail(f"{name}: not applicable")
        effects[name] = e
    sized: dict[str, _Sized] = {}
    spikes = None
    notes_eff: dict[str, dict] = {}
    if short:
        effs = [(e, rng.uniform(0.2, 0.6) * e.amax) for e in effects.values()]
        for e, a in effs:
            notes_eff[e.name] = {"form": e.form, "amplitude": a}
        if "outliers" in lib:
            rows = np.array([int(rng.integers(1, n - 1))])
            spikes = (rows, np.array([_unit(rng.normal(size=3)) * 30 * ctx.noise]), 30.0, "vector")
    else:
        bases = {} if fixed else _bases(ctx)
        q_cal = np.zeros((len(ctx.t), 0)) if fixed else _orth(bases["cal"])
        q_all = q_cal
        if out:
            q_all = _orth(np.column_stack([bases[k] for k in bases]))

        def contribution_of(e: _Eff) -> Callable[[float], np.ndarray]:
            def f(a: float) -> np.ndarray:
                raw, fref = _record(ctx, [(e, a)])
                if fixed:
                    return _fixed_vector(ctx, raw)
                return _scalar(ctx, raw, fref) - _scalar(ctx, ctx.raw0, ctx.fref0)
            return f

        def vis_of(y: np.ndarray) -> float:
            if fixed:
                return float(np.sqrt(np.mean(np.sum(y ** 2, axis=1)))) / ctx.noise
            return _rms(_remove(q_cal, y)) / ctx.noise

        def beyond_of(y: np.ndarray) -> float:
            return _rms(_remove(q_all, y)) / ctx.noise

        for name, e in effects.items():
            if name in OUTSIDE:
                lo, hi = (4.5, 6.0) if name == "vibration_noise" else (5.0, 13.0)
                got = _size(ctx, e, beyond_of, contribution_of(e), rng.uniform(lo, hi), BEYOND_RANGE)
                if got is None:
                    return _fail(f"{name}: not visible beyond the library at a plausible size ({schedule})")
                a, b, y = got
                v = vis_of(y)
                sized[name] = _Sized(e, a, v, b, y)
            else:
                got = _size(ctx, e, vis_of, contribution_of(e), rng.uniform(5.0, 18.0), VISIBLE_RANGE)
                if got is None:
                    return _fail(f"{name}: not visible at a plausible size ({schedule})")
                a, v, y = got
                sized[name] = _Sized(e, a, v, float("nan"), y)
            raw_e, _ = _record(ctx, [(e, a)])
            moved = np.linalg.norm(raw_e - ctx.raw0, axis=1).max()
            if name not in ("vibration_noise", "lag") and moved > 0.01 * ctx.f0:
                return _fail(f"{name}: moves the readings by more than 1 % of the field ({schedule})")
            notes_eff[name] = {"form": e.form, "amplitude": a, "amax": e.amax, **e.info}
        if "outliers" in lib:
            spikes = _spikes(rng, ctx, fixed)
            if spikes is None:
                return _fail("outliers: no isolated visible spikes")
            notes_eff["outliers"] = {"form": spikes[3], "count": len(spikes[0])}
        effs = [(s.eff, s.amp) for s in sized.values()]
    raw, fref = _record(ctx, effs)
    S = ctx.S
    raw = raw + rng.normal(0, S.sigma, raw.shape)
    if S.lsb > 0:
        raw = np.round(raw / S.lsb) * S.lsb
    if spikes is not None:
        raw[spikes[0]] += spikes[1]
    ref_kind = ctx.ref_kind
    if ref_kind == "measured":
        fref = np.round((fref + rng.normal(0, ctx.sigma_ref, len(fref))) / 0.01) * 0.01
    gravity = None
    if rng.random() < ctx.P.gravity_p:
        down = np.einsum("nji,j->ni", ctx.P.rot(ctx.t), np.array([0.0, 0.0, 1.0]))
        gravity = _unit(down + rng.normal(0, ctx.P.gravity_noise, down.shape))
    visible = {k: s.vis for k, s in sized.items()}
    if spikes is not None and not short:
        visible["outliers"] = spikes[2]
    present = () if short else tuple(e for e in LIBRARY if e in lib)
    outside = () if short else out
    acceptable = tuple(e for e in LIBRARY if e in lib or any(e in ACCEPTABLE_FOR.get(o, ()) for o in outside))
    confoundable = () if short else _confoundable(ctx, sized, bases, fixed, present)
    notes = {
        "noise_nT": ctx.noise, "sigma_axis_nT": S.sigma, "lsb_nT": S.lsb, "field_nT": ctx.f0,
        "true_C": ctx.ainv.tolist(), "true_offset_nT": ctx.c.tolist(), "reference": ref_kind,
        "sampling": ctx.P.sampling, "dt_median_s": ctx.dt, "duration_s": ctx.duration, "attempt": attempt,
        "visible_sigma": visible,
        "beyond_library_sigma": {k: s.beyond for k, s in sized.items() if k in OUTSIDE},
        "effects": notes_eff,
        "outlier_rows": spikes[0].tolist() if spikes is not None else [],
        "inclination_deg": float(np.degrees(np.arcsin(ctx.bdir[2]))),
    }
    if ctx.P.orbit is not None:
        notes["orbit"] = {k: v for k, v in ctx.P.orbit.items() if not callable(v)}
    return Case(index=index, category=category, raw_nT=raw, f_ref_nT=np.asarray(fref, float), t_s=ctx.t.copy(),
                temp_C=ctx.temp_log, gravity=gravity, present=present, outside=outside, acceptable=acceptable,
                expect_unexplained=bool(outside), confoundable=confoundable, schedule=schedule, notes=notes)


DRAWS = 5
"""``make_case`` draws a pair's, a triple's or an outside_plus's library effects again at most this many times."""


def make_case(index: int, root: int = 2026) -> Case:
    """The blind record number ``index`` of the stream seeded by ``root`` (deterministic)."""
    rng = np.random.default_rng(np.random.SeedSequence([root, index]))
    category, lib, out = _choose(index, rng)
    tried = []
    for draw in range(DRAWS):
        # after 60 failed attempts the drawn parts of the case are drawn again (the library effects of a pair, a triple
        # or an outside_plus; the platform of every kind, by the attempts themselves): a combination that cannot be
        # made visible at a plausible size is not a record (case 2600's caesium heading error beside a nonlinearity)
        for attempt in range(60):
            case = _attempt(rng, index, category, lib, out, 60 * draw + attempt)
            if case is not None:
                if tried:
                    case.notes["redrawn_from"] = tried
                return case
        tried.append([list(lib), list(out)])
        if category in ("pair", "triple", "outside_plus"):
            category, lib, out = _choose(index, rng)
    raise RuntimeError(f"case {index}: no plausible visible record in {60 * DRAWS} attempts ({category}, {lib}, {out})")

"""A fifth forward model of a tri-axial fluxgate in the geomagnetic field: a blind source of cases for the
diagnosis, written from the physics with numpy and scipy only.  It shares no code with magbench (its simulator,
diagnosis or calibrators) nor with the other four generators; from tests/independent_forward.py it reuses only
the ``Case`` record, so that tests/independent_scoring.py scores its cases unchanged.

Sensor.  The housing's attitude ``R(t)`` (housing to north-east-down world) is a closed-form function of time for
every schedule, so that delays and integrating windows are evaluated exactly.  Inside the housing a platform soft
iron ``S`` (symmetric, within 2.5 % of the identity) and hard iron ``h`` (up to 800 nT) act on the field; the
triad's axes are the rows of ``N = T(a, b, c) Q``: ``T`` a triad whose y axis leans by ``a`` towards x and whose z
axis leans by ``b`` and ``c`` towards x and y (up to 10 mrad each), ``Q`` a mounting rotation of up to 1 deg;
gains ``K`` (0.95-1.05) and electronic zeros ``o`` (up to 500 nT): ``raw = K N (S B_body + h) + o + noise``.  The
true calibration is ``B = C (raw - c)`` with ``C = (diag(K) N S)^-1``, ``c = diag(K) N h + o``
(``notes["true_C"]``, ``notes["true_offset_nT"]``).  White noise of 0.15-3 nT per axis (log-uniform, each axis
within 30 % of the others), in a third of the records an ADC grid of 0.5-2 times the noise; ``notes["noise_nT"]``
is the white level of the scalar residual (``notes["noise_vector_nT"]`` of a corrected component).  The field is
22,000-64,000 nT at an inclination of 5-80 deg (either hemisphere).  The scalar reference is a model value (a
constant), a remote station that follows the natural variation of the field's magnitude (0.02-0.1 nT noise), or a
nearby scalar sensor (out of the platform's own fields) doing the same; that natural variation is along the field
(a change of magnitude only) and so no effect.  A record with a ``field_drift`` or a ``lever_dipole`` never has a
nearby reference (it would see them).  The logged temperature is a thermometer lagging the environment with its
own time constant (5-120 s; the sensor core lags it with another, 30-900 s), with its own noise and a 0.0625 or
0.01 degC resolution.  Gravity, where an accelerometer or inclinometer gives it, is the unit vector down in the
housing frame with 0.002-0.02 noise.

Attitude schedules (``SCHEDULES``, none among the earlier generators'):
- parafoil: a sonde under a parafoil descending in a spiral: turn rate stepped by the brake servo (reversals
  included), bank following the turn rate (atan(V r / g)), canopy-payload pendulum in roll and pitch; the air
  warms with the descent (lapse rate, sometimes an inversion).  2-10 Hz, regular or jittered.
- rover: a rough-terrain rover: straight drives with terrain pitch and roll following the distance travelled
  and a regional slope resolved by the heading, stops with point turns of 30-180 deg, drive vibration; the
  temperature follows the day and the sun on its side.  0.3-3 Hz, regular, jittered or with gaps.
- swimmer: a sensor on a swimmer's back doing pool laps: stroke roll of 35-55 deg, kick pitch, yaw wiggle,
  a flip turn at each wall (a forward somersault and a heading reversal), rests upright at the wall; the sensor
  cools from the air to the water.  4-20 Hz, regular, jittered or in bursts.
- turntable: a sensor mounted at a random orientation on a turntable whose platter wobbles (tilted 1-6 deg on
  its spindle), its base moved by hand between 3-6 wedge tilts, the spindle sometimes reversing; lab air
  conditioning cycles and the spindle motor warms.  1-10 Hz.
- sling_load: a load on a 10-40 m line under a helicopter: pendulum swing, trailing angle growing with the
  square of the airspeed through hover, transit and hover again, the line's twist winding and unwinding (90-720
  deg), course changes; the air temperature follows the altitude and the downwash in hover.  No gravity logged.
- stabilised_mast: a sensor on a ship's gyro-stabilised mast: the ship's heading with course changes and yaw
  hunting; the stabiliser leaves a few % of the ship's roll and pitch, everything beyond its travel limit, and a
  limit cycle; a nearly level platform turning about one axis (the calibrators' level-vehicle case).  0.2-2 Hz.
- figure_eight: a hand-held figure-eight done badly: a 1:2 Lissajous in yaw and pitch, coupled roll, amplitude
  wandering and pausing, the user turning round slowly, hand tremor; the device warms in the hand.  10-50 Hz,
  jittered.
- seafloor (the ``fixed`` category): a sensor in a pressure case on the seabed, one attitude, 2-24 h at one
  sample per 4-120 s, regular or with gaps; the case cools to the bottom water after deployment and the bottom
  water follows the tide.
Sampling is regular, jittered (the time stamps are the true sample times), regular with 2-5 dropped stretches, or
in bursts; 300-2200 rows (8-14 for ``too_short``).

Library effects (the names the diagnosis may use), in this generator's own parametrisations:
- temperature: offsets (up to 20 nT/degC), gains (up to 300 ppm/degC, a common and a per-axis part) and the triad's
  angles a, b, c (up to 60 urad/degC), any of them alone or mixed, linear in the core temperature (the
  environment through the core's own lag, not the thermometer's).
- field_drift: a world-frame variation the reference does not follow: a sudden impulse with its recovery, a Pc5
  wave packet (Gaussian envelope, 1-3 periods), a bay, or a curved trend; its direction within 60 deg of the field
  on a turning sensor (across it a drift hardly moves the magnitude), any on a fixed one.  Peak up to min(1 % F,
  500 nT).
- offset_drift: the electronic zeros drifting: capacitor soakage after power-on (two exponentials per axis),
  ageing (a polynomial), wandering (a slow Ornstein-Uhlenbeck process, time constant at least a third of the
  record), or creep (logarithmic).  Peak up to min(1 % F, 300 nT).
- lag: axes converted one after another (skew of up to a quarter sample each), per-axis RC filters (first
  order, time constants up to half a sample, evaluated by Gauss-Laguerre quadrature of the attitude's closed
  form), or per-axis integrating windows (the mean over up to a sample period, Gauss-Legendre quadrature): every
  equivalent delay within half a median sample period.
- nonlinearity: per-axis quadratic-and-cubic transfer, a purely even (quadratic) transfer, or an arctangent
  saturation; the largest deviation at the field's magnitude within 0.8 % of F.
- outliers: 5-12 isolated spikes (one axis, or a random direction), rows at least 4 apart, each moving the
  scalar residual (a fixed sensor's corrected vector) by 12-40 times the noise.

Effects outside the library (``OUTSIDE``, at least one in the ``outside`` and ``outside_plus`` records; a
schedule offers only those it can physically carry, ``_COMPATIBLE``), each chosen to resemble a library effect;
``ACCEPTABLE_FOR`` lists what is not wrong to name, decided from the physics and erring towards strictness:
- gain_sag: a ratiometric converter whose reference follows the battery: the gains sag with the discharge and
  the load (per axis, differently, some up), up to 3000 ppm.  Resembles offset or field drift and temperature.
  Nothing acceptable: it is no offset, no field and no temperature.
- thermal_hysteresis: the zeros follow the core temperature through a play (backlash) of 0.3-2.5 degC, at most
  0.4 of its range (stress in the potting relaxing differently warming and cooling).  Physically the sensor's
  temperature dependence: ``temperature`` is acceptable; the hysteretic part stays unexplained.
- lever_dipole: the sensor on a lever arm (0.05-0.4 m) about the rotation centre near a ferrous object (a
  dipole 0.4-2 m away, fixed in the world): the field it sees depends on its attitude through its position.
  Resembles nonlinearity and field drift.  Nothing acceptable (a change with attitude, not in time).
- torque_current: a motor near the sensor (spindle, wheels, stabiliser torquers, brake servo) whose current
  follows the platform's acceleration, rate and friction: a body-fixed field.  Resembles lag and offset
  drift.  Nothing.
- gravity_gain: the gains follow the gravity components (the sensor's weight stressing its cores on a compliant
  mount), up to 500 ppm per g.  Resembles nonlinearity (an attitude-dependent scale).  Nothing.
- flicker_offsets: 1/f-like noise of the zeros (exponent 0.9-1.3) on each axis.  Its slow part is the zeros
  drifting: ``offset_drift`` is acceptable; the faster part stays unexplained.
- scanner_iron: a hard iron on a part turning at 0.3-20 Hz (a radar scanner, a lidar head, a fan, a current
  meter's rotor), its speed swept slowly, aliased by the sampling.  Resembles offset drift or noise.  Nothing.
- solar_current: solar-panel strings whose currents follow each panel's sun incidence and passing cloud: a
  body-fixed field depending on the attitude relative to the sun.  Resembles temperature (the sun also heats)
  and soft iron.  Nothing.
- vibrate_motor: a vibration motor or pump switched on 3-6 times for 15-60 consecutive samples (a body-fixed
  field with a ripple).  Resembles outliers and offset steps; not isolated spikes.  Nothing.
- crossover_step: one or two axes' feedback with a crossover step at zero field (``x + d tanh(x / w)``, d up to 50
  nT).  The sensor's transfer beyond linear, so ``nonlinearity`` is acceptable; the step is not quadratic or
  cubic and stays unexplained.

Visibility (``present`` holds only effects a perfect analyst could see).  Every effect is built in physical units
and its contribution is computed exactly: the noise-free forward model with and without it, both corrected with
the true calibration (the scalar residual on a turning sensor; a fixed sensor's corrected vector about its mean).
What a perfect calibration absorbs (least squares on the nine linearised directions ``|B| u_i u_j`` and ``u_i``,
u the unit field in the housing frame) is removed, and the amplitude is scaled, iterating for effects not linear
in it, so that the RMS of the rest is 5-16 times the noise (``VISIBLE_RANGE``); the amplitude must stay within its
physical bound (``_Effect.amax``), and no effect may move the readings by more than 1 % of F (RMS), otherwise the
record is drawn again (another schedule among those that can carry the effects, sampling, sensor and forms) and,
after six such records, the effects too.  Effects that are small at a plausible size are given a quieter sensor
(``NOISE_CAP``: white noise of at most 0.3 nT with a thermal hysteresis, a crossover step or a gravity gain).
Outliers are sized spike by spike instead.  An outside effect is scaled on what remains after the calibration
and every library effect's linearised model together (``_Analyst.bases``: the logged temperature and its rate
each times the nine calibration directions; Legendre polynomials of time to degree 12 for a field drift, which on
a turning sensor moves the magnitude as a function of time; each ``u_i`` times Legendre polynomials to degree 6
for an offset drift; each axis's time derivative, and the reference's, for a lag; each axis's square and cube for
a nonlinearity), the largest 1 % of what remains left out (the library's outliers could take them): that RMS is
5-13 times the noise (``BEYOND_RANGE``), so ``expect_unexplained`` is honest.  Two library effects are
``confoundable`` when what remains of a present one after the calibration and the other's model is below max(3
noise, 30 % of its visible size) (for every other library effect, present or not); on a fixed sensor an offset
drift and a field drift always are (a body-fixed drift and a world-fixed drift of a sensor that does not turn
move the readings alike), and temperature with either by the same rule (polynomials of degree 6 per axis).
``too_short`` records carry no effect or one library effect at a plausible size; nothing is present (nothing is
visible), the effect is acceptable.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from independent_forward import Case
from numpy.polynomial import legendre
from scipy.signal import lfilter
from scipy.spatial.transform import Rotation

LIBRARY = ("temperature", "field_drift", "offset_drift", "nonlinearity", "outliers", "lag")
OUTSIDE = ("gain_sag", "thermal_hysteresis", "lever_dipole", "torque_current", "gravity_gain", "flicker_offsets",
           "scanner_iron", "solar_current", "vibrate_motor", "crossover_step")
ACCEPTABLE_FOR = {"thermal_hysteresis": ("temperature",), "flicker_offsets": ("offset_drift",),
                  "crossover_step": ("nonlinearity",)}
SCHEDULES = ("parafoil", "rover", "swimmer", "turntable", "sling_load", "stabilised_mast", "figure_eight", "seafloor")
MOVING = SCHEDULES[:-1]
FIXED_LIBRARY = ("temperature", "field_drift", "offset_drift", "outliers")
PATTERN = ("single", "outside", "clean", "pair", "fixed", "outside_plus", "single", "outside", "too_short", "triple",
           "clean", "single", "outside", "pair", "fixed", "outside_plus", "single", "outside", "clean", "pair",
           "single", "outside", "fixed", "outside_plus")
VISIBLE_RANGE = (5.0, 16.0)
BEYOND_RANGE = (5.0, 13.0)
VISIBLE_FLOOR = 4.0  # what the tests check
NOISE_CAP = {"thermal_hysteresis": 0.3, "crossover_step": 0.3, "gravity_gain": 0.3}  # nT: small effects, quiet sensors
NMAX = 2200
_COMPATIBLE = {
    "parafoil": ("gain_sag", "thermal_hysteresis", "torque_current", "gravity_gain", "flicker_offsets", "solar_current",
                 "vibrate_motor", "crossover_step"),
    "rover": ("gain_sag", "thermal_hysteresis", "torque_current", "gravity_gain", "flicker_offsets", "scanner_iron",
              "solar_current", "vibrate_motor", "crossover_step"),
    "swimmer": ("gain_sag", "thermal_hysteresis", "gravity_gain", "flicker_offsets", "vibrate_motor", "crossover_step"),
    "turntable": ("gain_sag", "thermal_hysteresis", "lever_dipole", "torque_current", "gravity_gain", "flicker_offsets",
                  "scanner_iron", "vibrate_motor", "crossover_step"),
    "sling_load": ("gain_sag", "thermal_hysteresis", "gravity_gain", "flicker_offsets", "solar_current",
                   "vibrate_motor", "crossover_step"),
    "stabilised_mast": ("gain_sag", "thermal_hysteresis", "torque_current", "flicker_offsets", "scanner_iron",
                        "solar_current", "vibrate_motor", "crossover_step"),
    "figure_eight": ("gain_sag", "thermal_hysteresis", "lever_dipole", "gravity_gain", "flicker_offsets",
                     "vibrate_motor", "crossover_step"),
    "seafloor": ("thermal_hysteresis", "flicker_offsets", "scanner_iron", "vibrate_motor"),
}
DEG = np.pi / 180.0


# ----------------------------------------------------------------------------------------------- helpers
def _step(x):
    """A smooth unit step, 0 at -inf and 1 at +inf."""
    return 0.5 * (1.0 + np.tanh(x))


def _sech2(x):
    """sech(x)^2 without overflow: the derivative of tanh."""
    e = np.exp(-2.0 * np.abs(x))
    return 4.0 * e / (1.0 + e) ** 2


def _istep(x):
    """The integral of ``_step`` from -inf to x."""
    ax = np.abs(x)
    return 0.5 * x + 0.5 * (ax + np.log1p(np.exp(-2.0 * ax)) - np.log(2.0)) + 0.5 * np.log(2.0)


class _Sines:
    """A sum of sinusoids (a closed-form smooth random process) with its derivatives."""

    def __init__(self, rng, k, period_lo, period_hi, rms, slope=1.0):
        self.f = 1.0 / np.exp(rng.uniform(np.log(period_lo), np.log(period_hi), k))
        a = rng.uniform(0.5, 1.0, k) * (self.f / self.f.max()) ** (-0.5 * slope)
        self.a = a * rms / np.sqrt(0.5 * np.sum(a ** 2))
        self.p = rng.uniform(0, 2 * np.pi, k)

    def __call__(self, t, d=0):
        w = 2 * np.pi * self.f
        arg = np.outer(np.asarray(t, float), w) + self.p
        if d == 0:
            return np.sin(arg) @ self.a
        if d == 1:
            return np.cos(arg) @ (self.a * w)
        return -np.sin(arg) @ (self.a * w ** 2)


def _lag_series(tg, x, tau):
    """First-order lag of x sampled on the uniform grid tg (exact for x linear between grid points)."""
    if tau <= 0:
        return x.copy()
    e = np.exp(-(tg[1] - tg[0]) / tau)
    y, _ = lfilter([1.0 - e], [1.0, -e], x, zi=[e * x[0]])
    return y


def _play(x, w):
    """Play (backlash) operator of half-width w."""
    y = np.empty_like(x)
    y[0] = x[0]
    for k in range(1, len(x)):
        y[k] = min(max(y[k - 1], x[k] - w), x[k] + w)
    return y


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x)))) if np.size(x) else 0.0


def _span(basis):
    """An orthonormal basis of the columns' span (directions below 1e-10 of the largest dropped)."""
    scale = np.sqrt(np.mean(basis ** 2, axis=0))
    scale[scale == 0] = 1.0
    u, s, _ = np.linalg.svd(basis / scale, full_matrices=False)
    return u[:, s > 1e-10 * s[0]]


def _remove(y, basis):
    """What least squares on ``basis`` (columns) leaves of y."""
    if basis is None or basis.shape[1] == 0:
        return y
    u = _span(basis)
    return y - u @ (u.T @ y)


def _unit(v):
    return v / np.linalg.norm(v)


def _rand_unit(rng):
    return _unit(rng.normal(size=3))


# -------------------------------------------------------------------------------------------- schedules
@dataclass
class _Sched:
    kind: str
    span: float
    rate: float
    att: Callable
    temp_env: Callable
    samplings: tuple
    gravity_p: float
    drive: Callable | None = None
    sun: tuple | None = None  # (azimuth, elevation) of the sun, radians
    gravity_noise: float = 0.005
    extra: dict = field(default_factory=dict)


def _euler(yaw, pitch, roll):
    return Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll]))


def _steps(rng, times, deltas, widths):
    """Closed-form sum of smooth steps and its derivative."""
    times, deltas, widths = map(np.asarray, (times, deltas, widths))

    def f(t, d=0):
        x = (np.asarray(t, float)[:, None] - times) / widths
        if d == 0:
            return _step(x) @ deltas
        return (0.5 * _sech2(x) / widths) @ deltas
    return f


def _sched_parafoil(rng):
    span = rng.uniform(300, 1200)
    rate = rng.uniform(2, 10)
    m = int(rng.integers(2, 7))
    rates = [rng.choice([-1, 1]) * rng.uniform(5, 30) * DEG]
    for _ in range(m):
        r = rng.uniform(5, 30) * DEG
        rates.append(-np.sign(rates[-1]) * r if rng.random() < 0.5 else np.sign(rates[-1]) * r)
    rates = np.array(rates)
    tk = np.sort(rng.uniform(0.1, 0.9, m)) * span
    w = rng.uniform(1.0, 4.0, m)
    dr = np.diff(rates)
    psi0 = rng.uniform(-np.pi, np.pi)
    v = rng.uniform(8, 15)
    pend_p, pend_a = rng.uniform(2, 4), rng.uniform(3, 10) * DEG
    pend_ph = rng.uniform(0, 2 * np.pi, 2)
    slow = _Sines(rng, 3, 60, 300, 0.3)
    gust = _Sines(rng, 6, 3, 40, rng.uniform(1, 3) * DEG)
    theta0 = rng.uniform(2, 8) * DEG

    def turn_rate(t):
        return rates[0] + _step((np.asarray(t)[:, None] - tk) / w) @ dr

    def yaw(t):
        t = np.asarray(t, float)
        return psi0 + rates[0] * t + (w * (_istep((t[:, None] - tk) / w) - _istep(-tk / w))) @ dr

    def att(t):
        t = np.asarray(t, float)
        r = turn_rate(t)
        mod = 1 + slow(t)
        roll = np.arctan(v * r / 9.81) + pend_a * mod * np.sin(2 * np.pi * t / pend_p + pend_ph[0])
        pitch = theta0 + 0.6 * pend_a * mod * np.sin(2 * np.pi * t / (0.9 * pend_p) + pend_ph[1]) + gust(t)
        return _euler(yaw(t), pitch, roll)

    h0, vd = rng.uniform(2000, 6000), rng.uniform(3, 7)
    t_ground, lapse = rng.uniform(-5, 30), rng.uniform(5.5, 7.5) / 1000
    inv_h, inv_a, inv_w = rng.uniform(300, 3000), rng.uniform(0, 3) * (rng.random() < 0.5), rng.uniform(100, 400)

    def temp_env(t):
        h = np.maximum(h0 - vd * np.asarray(t, float), 0)
        return t_ground - lapse * h + inv_a * np.exp(-0.5 * ((h - inv_h) / inv_w) ** 2)

    def drive(t):  # the brake servo's current: the turn rate's changes
        x = (np.asarray(t, float)[:, None] - tk) / w
        return (0.5 * _sech2(x)) @ np.abs(dr) / max(np.abs(dr).max(), 1e-9) + 0.1

    sun = (rng.uniform(-np.pi, np.pi), rng.uniform(10, 60) * DEG)
    return _Sched("parafoil", span, rate, att, temp_env, ("regular", "jittered"), 0.6, drive, sun, 0.01)


def _sched_rover(rng):
    span = rng.uniform(900, 5400)
    rate = rng.uniform(0.3, 3)
    # alternating drives and stops
    drives, stops = [], []
    t = rng.uniform(0, 60)
    while t < span:
        d = rng.uniform(60, 600)
        drives.append((t, min(t + d, span + 100)))
        t += d
        s = rng.uniform(20, 200)
        stops.append((t, t + s))
        t += s
    a = np.array([d[0] for d in drives])
    b = np.array([d[1] for d in drives])
    tau = 3.0
    v = rng.uniform(0.1, 1.0)
    sc = np.array([(s0 + s1) / 2 for s0, s1 in stops])
    sw = np.array([(s1 - s0) / 6 for s0, s1 in stops])
    dpsi = rng.choice([-1, 1], len(stops)) * rng.uniform(30, 180, len(stops)) * DEG
    heading = _steps(rng, sc, dpsi, sw)
    psi0 = rng.uniform(-np.pi, np.pi)
    terr_p = _Sines(rng, 8, 2, 50, rng.uniform(3, 10) * DEG)
    terr_r = _Sines(rng, 8, 2, 50, rng.uniform(3, 10) * DEG)
    slope, slope_az = rng.uniform(2, 10) * DEG, rng.uniform(-np.pi, np.pi)
    vib_f = rng.uniform(2, 8)

    def mask(t):
        x = np.asarray(t, float)[:, None]
        return (_step((x - a) / tau) - _step((x - b) / tau)).sum(axis=1)

    def dist(t):
        x = np.asarray(t, float)[:, None]
        return v * (tau * (_istep((x - a) / tau) - _istep((x - b) / tau))).sum(axis=1)

    def att(t):
        t = np.asarray(t, float)
        psi = psi0 + heading(t)
        s = dist(t)
        m = mask(t)
        pitch = terr_p(s) + slope * np.cos(psi - slope_az) + 0.3 * DEG * m * np.sin(2 * np.pi * vib_f * t)
        roll = terr_r(s) + slope * np.sin(psi - slope_az)
        return _euler(psi, pitch, roll)

    t_mean, day_a, day_off = rng.uniform(-40, 30), rng.uniform(5, 15), rng.uniform(0, 86400)
    sun_b = rng.uniform(1, 5)
    sun = (rng.uniform(-np.pi, np.pi), rng.uniform(15, 60) * DEG)

    def temp_env(t):
        t = np.asarray(t, float)
        return (t_mean + day_a * np.sin(2 * np.pi * (t + day_off) / 86400)
                + sun_b * 0.5 * (1 + np.cos(psi0 + heading(t) - sun[0])))

    def drive(t):  # wheel torque: climbing, rolling resistance, skid turns
        t = np.asarray(t, float)
        psi = psi0 + heading(t)
        pitch = terr_p(dist(t)) + slope * np.cos(psi - slope_az)
        return mask(t) * (0.4 + 2.0 * np.sin(pitch)) + 3.0 * np.abs(heading(t, 1))

    return _Sched("rover", span, rate, att, temp_env, ("regular", "jittered", "gaps"), 0.7, drive, sun, 0.01)


def _sched_swimmer(rng):
    span = rng.uniform(120, 600)
    rate = rng.uniform(4, 20)
    lap = rng.choice([25.0, 50.0]) / rng.uniform(0.8, 1.6)
    turns, rests, t, k = [], [], rng.uniform(2, 10), 0
    set_len = int(rng.integers(4, 9))
    while t < span + lap:
        t += lap * rng.uniform(0.95, 1.05)
        k += 1
        if k % set_len == 0:
            r = rng.uniform(10, 30)
            rests.append((t + 1, t + 1 + r))
            t += r
        turns.append(t)
    turns = np.array(turns)
    tw = rng.uniform(0.25, 0.5)
    flips = _steps(rng, turns, np.full(len(turns), np.pi), np.full(len(turns), tw))
    somersault = _steps(rng, turns - 0.3, np.full(len(turns), 2 * np.pi), np.full(len(turns), tw * 0.8))
    ra = np.array([r[0] for r in rests]) if rests else np.array([1e9])
    rb = np.array([r[1] for r in rests]) if rests else np.array([1e9 + 1])

    def resting(t):
        x = np.asarray(t, float)[:, None]
        return (_step((x - ra) / 2.0) - _step((x - rb) / 2.0)).sum(axis=1)

    f = rng.uniform(0.4, 0.7)
    roll_a = rng.uniform(35, 55) * DEG
    ph = rng.uniform(0, 2 * np.pi, 3)
    psi0 = rng.uniform(-np.pi, np.pi)
    wig = _Sines(rng, 4, 3, 30, 3 * DEG)

    def att(t):
        t = np.asarray(t, float)
        rest = resting(t)
        swim = 1 - rest
        yaw = psi0 + flips(t) + swim * 5 * DEG * np.sin(2 * np.pi * f * t + ph[0]) + wig(t)
        pitch = (swim * 3 * DEG * np.sin(4 * np.pi * f * t + ph[1]) + somersault(t)
                 - rest * 70 * DEG)
        roll = swim * roll_a * np.sin(2 * np.pi * f * t + ph[2])
        return _euler(yaw, pitch, roll)

    t_water, t_air, tau = rng.uniform(25, 29), rng.uniform(18, 34), rng.uniform(30, 120)

    def temp_env(t):
        t = np.asarray(t, float)
        return t_water + (t_air - t_water) * np.exp(-t / tau) + 0.5 * resting(t)

    return _Sched("swimmer", span, rate, att, temp_env, ("regular", "jittered", "burst"), 0.6, None, None, 0.02)


def _sched_turntable(rng):
    span = rng.uniform(300, 2400)
    rate = rng.uniform(1, 10)
    k = int(rng.integers(3, 7))
    bases = [Rotation.identity() if rng.random() < 0.5 else Rotation.from_rotvec(
        _unit(np.r_[rng.normal(size=2), 0]) * rng.uniform(5, 30) * DEG)]
    for _ in range(k - 1):
        bases.append(Rotation.from_rotvec(_unit(np.r_[rng.normal(size=2), 0]) * rng.uniform(0, 70) * DEG)
                     * Rotation.from_rotvec([0, 0, rng.uniform(-np.pi, np.pi)]))
    tk = (np.arange(1, k) + rng.uniform(-0.2, 0.2, k - 1)) * span / k
    wk = rng.uniform(5, 15, k - 1)
    rel = [(bases[i].inv() * bases[i + 1]).as_rotvec() for i in range(k - 1)]
    omegas = [rng.choice([-1, 1]) * rng.uniform(3, 30) * DEG]
    for _ in range(k - 1):
        om = rng.uniform(3, 30) * DEG
        omegas.append(om * (np.sign(omegas[-1]) if rng.random() < 0.6 else -np.sign(omegas[-1])))
    domega = np.diff(omegas)
    flutter_a, flutter_f = rng.uniform(0.1, 0.6) * DEG, rng.uniform(0.5, 3)
    wob = Rotation.from_rotvec(_unit(np.r_[rng.normal(size=2), 0]) * rng.uniform(1, 6) * DEG)
    mount = Rotation.random(random_state=rng)

    def theta(t, d=0):
        t = np.asarray(t, float)
        x = (t[:, None] - tk) / wk
        if d == 0:
            return (omegas[0] * t + (wk * (_istep(x) - _istep(-tk / wk))) @ domega
                    + flutter_a * np.sin(2 * np.pi * flutter_f * t))
        if d == 1:
            return omegas[0] + _step(x) @ domega + flutter_a * 2 * np.pi * flutter_f * np.cos(2 * np.pi * flutter_f * t)
        return (0.5 * _sech2(x) / wk) @ domega - flutter_a * (2 * np.pi * flutter_f) ** 2 * np.sin(
            2 * np.pi * flutter_f * t)

    def att(t):
        t = np.asarray(t, float)
        r = bases[0]
        for i in range(k - 1):
            r = r * Rotation.from_rotvec(np.outer(_step((t - tk[i]) / wk[i]), rel[i]))
        return r * Rotation.from_rotvec(np.outer(theta(t), [0, 0, 1.0])) * wob * mount

    hv_p, hv_a = rng.uniform(600, 1800), rng.uniform(0.3, 1.5)
    warm, warm_tau = rng.uniform(1, 4), rng.uniform(300, 1000)
    t_lab, hv_ph = rng.uniform(18, 24), rng.uniform(0, 2 * np.pi)

    def temp_env(t):
        t = np.asarray(t, float)
        x = 2 * np.pi * t / hv_p + hv_ph
        return t_lab + hv_a * (np.sin(x) - 0.3 * np.sin(2 * x) + 0.1 * np.sin(3 * x)) + warm * (1 - np.exp(-t / warm_tau))

    jmot, bvis, fric = rng.uniform(0.5, 3), rng.uniform(0.5, 2), rng.uniform(0.2, 1)

    def drive(t):
        return jmot * theta(t, 2) / (20 * DEG) + bvis * theta(t, 1) / (20 * DEG) + fric * np.tanh(theta(t, 1) / DEG)

    s = _Sched("turntable", span, rate, att, temp_env, ("regular", "jittered"), 0.4, drive, None, 0.003)
    s.extra["arm_m"] = rng.uniform(0.05, 0.3)
    return s


def _sched_sling(rng):
    span = rng.uniform(240, 900)
    rate = rng.uniform(2, 10)
    length = rng.uniform(10, 40)
    per = 2 * np.pi * np.sqrt(length / 9.81)
    t1, t2 = rng.uniform(0.1, 0.3) * span, rng.uniform(0.6, 0.85) * span
    vmax = rng.uniform(20, 40)
    wacc = rng.uniform(15, 40)

    def speed(t):
        t = np.asarray(t, float)
        return vmax * (_step((t - t1) / wacc) - _step((t - t2) / wacc))

    trail_k = rng.uniform(10, 20) * DEG / vmax ** 2
    amod_p, amod_r = _Sines(rng, 3, 30, 200, 0.3), _Sines(rng, 3, 30, 200, 0.3)
    ap, ar = rng.uniform(2, 8) * DEG, rng.uniform(2, 8) * DEG
    php, phr = rng.uniform(0, 2 * np.pi, 2)
    tw_a, tw_p, tw_ph = rng.uniform(90, 720) * DEG, rng.uniform(60, 300), rng.uniform(0, 2 * np.pi)
    m = int(rng.integers(1, 4))
    course = _steps(rng, np.sort(rng.uniform(0.2, 0.8, m)) * span, rng.uniform(-120, 120, m) * DEG, rng.uniform(5, 20, m))
    psi0 = rng.uniform(-np.pi, np.pi)

    def att(t):
        t = np.asarray(t, float)
        pitch = trail_k * speed(t) ** 2 + ap * (1 + amod_p(t)) * np.sin(2 * np.pi * t / per + php)
        roll = ar * (1 + amod_r(t)) * np.sin(2 * np.pi * t / (per * 1.02) + phr)
        yaw = psi0 + course(t) + tw_a * np.sin(2 * np.pi * t / tw_p + tw_ph)
        return _euler(yaw, pitch, roll)

    t0, climb = rng.uniform(-10, 30), rng.uniform(200, 1500)
    down = rng.uniform(1, 3)

    def temp_env(t):
        t = np.asarray(t, float)
        alt = climb * (_step((t - t1) / 60) - _step((t - t2) / 60))
        hover = 1 - speed(t) / vmax
        return t0 - 0.0065 * alt + down * hover

    sun = (rng.uniform(-np.pi, np.pi), rng.uniform(10, 60) * DEG)
    return _Sched("sling_load", span, rate, att, temp_env, ("regular", "jittered"), 0.0, None, sun, 0.0)


def _sched_mast(rng):
    span = rng.uniform(1200, 7200)
    rate = rng.uniform(0.2, 2)
    m = int(rng.integers(2, 7))
    course = _steps(rng, np.sort(rng.uniform(0.05, 0.95, m)) * span, rng.choice([-1, 1], m) * rng.uniform(20, 180, m) * DEG,
                    rng.uniform(30, 150, m))
    psi0 = rng.uniform(-np.pi, np.pi)
    hunt_a, hunt_p, hunt_ph = rng.uniform(1, 3) * DEG, rng.uniform(10, 30), rng.uniform(0, 2 * np.pi)
    p_roll = rng.uniform(8, 15)
    roll_s = _Sines(rng, 4, p_roll * 0.85, p_roll * 1.15, rng.uniform(5, 25) * DEG / np.sqrt(2), slope=0)
    pitch_s = _Sines(rng, 3, 5, 9, rng.uniform(2, 5) * DEG / np.sqrt(2), slope=0)
    leak, lim = rng.uniform(0.02, 0.1), rng.uniform(8, 15) * DEG
    lc_a, lc_f = rng.uniform(0.2, 1.0) * DEG, rng.uniform(1, 3)
    mount = Rotation.random(random_state=rng)

    def resid(x):
        return leak * x + (x - lim * np.tanh(x / lim))

    def att(t):
        t = np.asarray(t, float)
        psi = psi0 + course(t) + hunt_a * np.sin(2 * np.pi * t / hunt_p + hunt_ph)
        roll = resid(roll_s(t)) + lc_a * np.sin(2 * np.pi * lc_f * t)
        pitch = resid(pitch_s(t)) + 0.5 * lc_a * np.cos(2 * np.pi * lc_f * t)
        return _euler(psi, pitch, roll) * mount

    t_mean, day_a, day_off = rng.uniform(0, 30), rng.uniform(2, 8), rng.uniform(0, 86400)
    sun = (rng.uniform(-np.pi, np.pi), rng.uniform(15, 60) * DEG)
    sun_b = rng.uniform(1, 5)

    def temp_env(t):
        t = np.asarray(t, float)
        return (t_mean + day_a * np.sin(2 * np.pi * (t + day_off) / 86400)
                + sun_b * 0.5 * (1 + np.cos(psi0 + course(t) - sun[0])))

    ka, kb = rng.uniform(0.5, 2), rng.uniform(0.2, 1)

    def drive(t):  # the stabiliser's torquers hold the platform against the ship's roll and pitch
        return ka * roll_s(t, 2) / (10 * DEG) + kb * roll_s(t, 1) / (10 * DEG) + 0.5 * ka * pitch_s(t, 2) / (10 * DEG)

    return _Sched("stabilised_mast", span, rate, att, temp_env, ("regular", "jittered", "gaps"), 0.5, drive, sun, 0.003)


def _sched_figure8(rng):
    span = rng.uniform(40, 240)
    rate = rng.uniform(10, 50)
    f = rng.uniform(0.2, 0.8)
    a0, b0, c0 = rng.uniform(30, 80) * DEG, rng.uniform(15, 45) * DEG, rng.uniform(10, 60) * DEG
    amod = _Sines(rng, 4, 5, 40, 0.2)
    npause = int(rng.integers(0, 4))
    pc = rng.uniform(0.1, 0.9, npause) * span
    pw = rng.uniform(2, 6, npause)

    def moving(t):
        x = np.asarray(t, float)[:, None]
        return 1 - (_step((x - pc + pw) / 0.7) - _step((x - pc - pw) / 0.7)).sum(axis=1) if npause else np.ones(len(t))

    turns = rng.uniform(-2, 2)
    wander = _Sines(rng, 4, 10, 60, 10 * DEG)
    psi0 = rng.uniform(-np.pi, np.pi)
    tremor = _Sines(rng, 6, 1 / 9, 1 / 5, rng.uniform(0.3, 1) * DEG, slope=0)
    tremor2 = _Sines(rng, 6, 1 / 9, 1 / 5, rng.uniform(0.3, 1) * DEG, slope=0)
    ph = rng.uniform(0, 2 * np.pi, 3)
    pitch0 = rng.uniform(-30, 30) * DEG
    mount = Rotation.from_rotvec(_rand_unit(rng) * rng.uniform(0, 20) * DEG)

    def att(t):
        t = np.asarray(t, float)
        g = moving(t) * (1 + amod(t))
        w = 2 * np.pi * f * t
        yaw = psi0 + 2 * np.pi * turns * t / span + wander(t) + g * a0 * np.sin(w + ph[0])
        pitch = pitch0 + g * b0 * np.sin(2 * w + ph[1]) + tremor(t)
        roll = g * c0 * np.sin(w + ph[2]) + tremor2(t)
        return _euler(yaw, pitch, roll) * mount

    t_amb, t_hand, tau = rng.uniform(5, 25), rng.uniform(30, 33), rng.uniform(60, 300)

    def temp_env(t):
        return t_hand + (t_amb - t_hand) * np.exp(-np.asarray(t, float) / tau)

    s = _Sched("figure_eight", span, rate, att, temp_env, ("jittered",), 0.7, None, None, 0.02)
    s.extra["arm_m"] = rng.uniform(0.1, 0.4)
    return s


def _sched_seafloor(rng):
    span = rng.uniform(2, 24) * 3600
    dt = rng.uniform(4, 120)
    dt = max(dt, span / NMAX)
    if span / dt < 300:
        dt = span / rng.uniform(300, 600)
    rot = Rotation.from_euler("ZYX", [rng.uniform(-np.pi, np.pi), rng.uniform(-10, 10) * DEG, rng.uniform(-10, 10) * DEG])
    mount = Rotation.random(random_state=rng)
    r = rot * mount

    def att(t):
        return Rotation.from_quat(np.tile(r.as_quat(), (len(np.atleast_1d(t)), 1)))

    t_bot, t_surf, tau = rng.uniform(1, 12), rng.uniform(5, 28), rng.uniform(0.5, 3) * 3600
    tide_a, tide_ph = rng.uniform(0.05, 0.5), rng.uniform(0, 2 * np.pi)

    def temp_env(t):
        t = np.asarray(t, float)
        return t_bot + (t_surf - t_bot) * np.exp(-t / tau) + tide_a * np.sin(2 * np.pi * t / 44712 + tide_ph)

    return _Sched("seafloor", span, 1.0 / dt, att, temp_env, ("regular", "gaps"), 0.5, None, None, 0.002)


_SCHED_MAKERS = {"parafoil": _sched_parafoil, "rover": _sched_rover, "swimmer": _sched_swimmer,
                 "turntable": _sched_turntable, "sling_load": _sched_sling, "stabilised_mast": _sched_mast,
                 "figure_eight": _sched_figure8, "seafloor": _sched_seafloor}


def _times(kind, span, rate, rng, n_fixed=None):
    if n_fixed is not None:
        t = np.sort(rng.uniform(0, span, n_fixed))
        return t, "short"
    n = int(span * rate)
    if n > NMAX:
        rate = NMAX / span
        n = NMAX
    n = max(n, 300)
    rate = n / span
    dt = 1.0 / rate
    t = np.arange(n) * dt
    if kind == "jittered":
        t = np.sort(t + rng.uniform(-0.3, 0.3, n) * dt)
        t -= t[0]
    elif kind == "gaps":
        n_extra = int(n * rng.uniform(0.1, 0.25))
        t = np.arange(n + n_extra) * span / (n + n_extra)
        keep = np.ones(len(t), bool)
        k = int(rng.integers(2, 6))
        for _ in range(k):
            ln = int(len(t) * rng.uniform(0.02, 0.25 / k))
            s = int(rng.integers(10, len(t) - ln - 10))
            keep[s:s + ln] = False
        t = t[keep]
    elif kind == "burst":
        m = int(rng.integers(20, 100))
        gap = rng.uniform(0.5, 3) * m * dt
        starts = np.arange(0, span, m * dt + gap)
        t = (starts[:, None] + np.arange(m) * dt).ravel()
        t = t[t < span]
        if len(t) < 300:
            t = np.arange(n) * dt
            kind = "regular"
    return t, kind


# ---------------------------------------------------------------------------------------------- records
class _Rec:
    """A record's physics: schedule, sampling, field, reference, sensor, noise, temperature."""

    def __init__(self, rng, sched_kind, short=False, no_colocated=False, noise_cap=3.0):
        s = _SCHED_MAKERS[sched_kind](rng)
        self.sched = s
        sampling = rng.choice(s.samplings)
        self.t, self.sampling = _times(sampling, s.span, s.rate, rng, int(rng.integers(8, 15)) if short else None)
        self.n = len(self.t)
        self.dt = float(np.median(np.diff(self.t)))
        self.fixed = sched_kind == "seafloor"
        # field
        self.F0 = rng.uniform(22000, 64000)
        inc = rng.choice([-1, 1]) * rng.uniform(5, 80) * DEG
        dec = rng.uniform(-np.pi, np.pi)
        self.bhat = np.array([np.cos(inc) * np.cos(dec), np.cos(inc) * np.sin(dec), np.sin(inc)])
        refs = ["model", "remote"] + ([] if no_colocated else ["colocated"])
        self.ref = str(rng.choice(refs))
        self.nat = _Sines(rng, 4, max(s.span / 3, 60), max(s.span * 3, 600), rng.uniform(2, 20)) if self.ref != "model" else None
        self.ref_sig = 0.0 if self.ref == "model" else rng.uniform(0.02, 0.1)
        # sensor
        self.K = rng.uniform(0.95, 1.05, 3)
        self.ang = rng.uniform(-0.01, 0.01, 3)
        self.Q = Rotation.from_rotvec(_rand_unit(rng) * rng.uniform(0, 1) * DEG).as_matrix()
        e = rng.uniform(-0.025, 0.025, (3, 3))
        self.S = np.eye(3) + 0.5 * (e + e.T)
        self.h = rng.uniform(-800, 800, 3)
        self.o = rng.uniform(-500, 500, 3)
        sig0 = np.exp(rng.uniform(np.log(0.1), np.log(noise_cap))) if noise_cap < 3.0 else np.exp(
            rng.uniform(np.log(0.15), np.log(3.0)))
        self.sig = sig0 * rng.uniform(0.7, 1.3, 3)
        self.lsb = sig0 * rng.uniform(0.5, 2.0) if rng.random() < 1 / 3 else None
        m0 = np.diag(self.K) @ _triad(self.ang[None])[0] @ self.Q @ self.S
        self.C = np.linalg.inv(m0)
        self.c = np.diag(self.K) @ _triad(self.ang[None])[0] @ self.Q @ self.h + self.o
        # temperature: environment, core and thermometer on a fine grid
        t0 = self.t[0] - 30 * self.dt - 1.0
        t1 = self.t[-1] + 1.0
        self.tg = np.linspace(t0, t1, 20000)
        env = s.temp_env(np.maximum(self.tg, 0.0))
        self.tau_core = min(rng.uniform(30, 900), max(self.t[-1], 1) / 4)
        self.tau_log = rng.uniform(5, 120)
        self.Tcore_g = _lag_series(self.tg, env, self.tau_core)
        tlog = np.interp(self.t, self.tg, _lag_series(self.tg, env, self.tau_log))
        res = 0.0625 if rng.random() < 0.5 else 0.01
        self.temp_log = np.round((tlog + rng.normal(0, rng.uniform(0.003, 0.02), self.n)) / res) * res
        self.temp_res = res
        self.rng = rng

    def T_core(self, t):
        return np.interp(t, self.tg, self.Tcore_g) - float(np.mean(np.interp(self.t, self.tg, self.Tcore_g)))

    def F_world(self, t):
        f = self.F0 + (self.nat(t) if self.nat is not None else 0.0)
        return np.outer(np.ones(len(t)) * f, self.bhat) if np.ndim(f) else np.tile(self.bhat * f, (len(t), 1))

    def f_ref(self):
        return self.F0 + (self.nat(self.t) if self.ref != "model" else np.zeros(self.n))


def _triad(ang):
    """Triad rows for angles (n, 3): y leaning by a towards x, z by b and c towards x and y."""
    a, b, c = ang[:, 0], ang[:, 1], ang[:, 2]
    n = len(a)
    m = np.zeros((n, 3, 3))
    m[:, 0, 0] = 1.0
    m[:, 1, 0], m[:, 1, 1] = np.sin(a), np.cos(a)
    zc = np.sqrt(np.maximum(1 - np.sin(b) ** 2 - np.sin(c) ** 2, 0))
    m[:, 2, 0], m[:, 2, 1], m[:, 2, 2] = np.sin(b), np.sin(c), zc
    return m


def _sense(rec: _Rec, t, effs):
    """Noise-free sensor outputs at times t (before any timing effect and sample glitches)."""
    t = np.asarray(t, float)
    R = rec.sched.att(t)
    Bw = rec.F_world(t)
    for e in effs:
        Bw = e.world(rec, t, R, Bw)
    Bb = R.inv().apply(Bw)
    Bp = Bb @ rec.S.T + rec.h
    for e in effs:
        Bp = e.body(rec, t, R, Bp)
    K = np.tile(rec.K, (len(t), 1))
    ang = np.tile(rec.ang, (len(t), 1))
    o = np.tile(rec.o, (len(t), 1))
    for e in effs:
        K, ang, o = e.sensor(rec, t, R, K, ang, o)
    N = _triad(ang) @ rec.Q
    core = K * np.einsum("nij,nj->ni", N, Bp)
    for e in effs:
        core = e.transfer(rec, core)
    return core + o


def _raw_nf(rec, effs, t=None):
    t = rec.t if t is None else t
    lag = [e for e in effs if e.name == "lag"]
    rest = [e for e in effs if e.name != "lag"]
    y = lag[0].timing(rec, t, lambda tt: _sense(rec, tt, rest)) if lag else _sense(rec, t, rest)
    for e in effs:
        y = e.rows(rec, y)
    return y


# ---------------------------------------------------------------------------------------------- effects
class _Effect:
    name = ""
    library = True

    def __init__(self, rec, rng):
        self.amp = 1.0
        self.form = ""
        self.params = {}

    amax = np.inf

    def world(self, rec, t, R, Bw):
        return Bw

    def body(self, rec, t, R, Bp):
        return Bp

    def sensor(self, rec, t, R, K, ang, o):
        return K, ang, o

    def transfer(self, rec, core):
        return core

    def rows(self, rec, y):
        return y


class _Temperature(_Effect):
    name = "temperature"

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        self.form = str(rng.choice(["offsets", "gains", "angles", "mixed", "all"]))
        f = self.form
        self.co = rng.uniform(-1, 1, 3) * (f in ("offsets", "mixed", "all"))
        self.cg = (rng.uniform(-0.5, 0.5) + rng.uniform(-0.5, 0.5, 3)) * (f in ("gains", "mixed", "all"))
        self.ca = rng.uniform(-1, 1, 3) * (f in ("angles", "all"))
        self.amp = 1.0
        self.amax = 20.0

    def sensor(self, rec, t, R, K, ang, o):
        dT = rec.T_core(t)[:, None]
        return (K * (1 + self.amp * 15e-6 * self.cg * dT), ang + self.amp * 3e-6 * self.ca * dT,
                o + self.amp * self.co * dT)


class _FieldDrift(_Effect):
    name = "field_drift"

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        self.form = str(rng.choice(["impulse", "pulsation", "bay", "trend"]))
        span = rec.t[-1] - rec.t[0]
        t0 = rec.t[0]
        if rec.fixed:
            self.dir = _rand_unit(rng)
        else:
            while True:
                d = _rand_unit(rng)
                if abs(d @ rec.bhat) > 0.5:
                    break
            self.dir = d
        if self.form == "impulse":
            c, rise, rec_tau = t0 + rng.uniform(0.2, 0.6) * span, rng.uniform(0.005, 0.03) * span, rng.uniform(0.1, 0.5) * span

            def g(t):
                x = np.asarray(t, float) - c
                return _step(x / rise) * np.exp(-np.maximum(x, 0) / rec_tau)
        elif self.form == "pulsation":
            per = span / rng.uniform(1, 3)
            c, w, ph = t0 + rng.uniform(0.3, 0.7) * span, rng.uniform(0.2, 0.5) * span, rng.uniform(0, 2 * np.pi)

            def g(t):
                x = np.asarray(t, float) - c
                return np.exp(-0.5 * (x / w) ** 2) * np.sin(2 * np.pi * x / per + ph)
        elif self.form == "bay":
            c, w = t0 + rng.uniform(0.3, 0.7) * span, rng.uniform(0.1, 0.25) * span
            asym = rng.uniform(0.5, 2)

            def g(t):
                x = np.asarray(t, float) - c
                return -np.exp(-0.5 * (x / (w * np.where(x > 0, asym, 1))) ** 2)
        else:
            p1, p2 = rng.uniform(-1, 1), rng.uniform(-1, 1)

            def g(t):
                u = 2 * (np.asarray(t, float) - t0) / span - 1
                return p1 * u + p2 * (1.5 * u ** 2 - 0.5)
        peak = np.max(np.abs(g(rec.t)))
        self.g = lambda t: g(t) / peak
        self.amax = min(0.01 * rec.F0, 500.0)

    def world(self, rec, t, R, Bw):
        return Bw + self.amp * np.outer(self.g(t), self.dir)


class _OffsetDrift(_Effect):
    name = "offset_drift"

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        self.form = str(rng.choice(["soak", "ageing", "wander", "creep"]))
        t0, span = rec.t[0], rec.t[-1] - rec.t[0]
        tg = rec.tg
        if self.form == "soak":
            a, b = rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3)
            t1, t2 = rng.uniform(0.05, 0.2) * span, rng.uniform(0.3, 1.0) * span
            x = (np.maximum(tg - t0, 0))[:, None]
            d = a * (1 - np.exp(-x / t1)) + b * (1 - np.exp(-x / t2))
        elif self.form == "ageing":
            u = (2 * (tg - t0) / span - 1)[:, None]
            d = rng.uniform(-1, 1, 3) * u + rng.uniform(-0.7, 0.7, 3) * u ** 2 + rng.uniform(-0.3, 0.3, 3) * u ** 3
        elif self.form == "wander":
            tau = rng.uniform(1 / 3, 2) * span
            dtg = tg[1] - tg[0]
            e = np.exp(-dtg / tau)
            z = rng.normal(size=(len(tg), 3)) * np.sqrt(1 - e * e)
            d = np.empty_like(z)
            d[0] = rng.normal(size=3)
            for k in range(1, len(tg)):
                d[k] = e * d[k - 1] + z[k]
            # smooth: a slow process, no sample-to-sample jitter
            kern = np.exp(-0.5 * (np.arange(-200, 201) / 80.0) ** 2)
            kern /= kern.sum()
            d = np.column_stack([np.convolve(np.pad(d[:, i], 200, mode="edge"), kern, "valid") for i in range(3)])
        else:
            tau = rng.uniform(0.005, 0.1) * span
            d = rng.uniform(-1, 1, 3) * np.log1p(np.maximum(tg - t0 + rng.uniform(0, 0.05) * span, 0)[:, None] / tau)
        at = np.column_stack([np.interp(rec.t, tg, d[:, i]) for i in range(3)])
        d = d - at.mean(axis=0)
        at = at - at.mean(axis=0)
        self.d = d / np.abs(at).max()
        self.amax = min(0.01 * rec.F0, 300.0)

    def sensor(self, rec, t, R, K, ang, o):
        return K, ang, o + self.amp * np.column_stack([np.interp(t, rec.tg, self.d[:, i]) for i in range(3)])


_LAGUERRE = np.polynomial.laguerre.laggauss(10)
_LEGENDRE = np.polynomial.legendre.leggauss(6)


class _Lag(_Effect):
    name = "lag"

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        self.form = str(rng.choice(["skew", "rc", "window"]))
        if self.form == "skew":
            self.c = rng.permutation([0.0, 0.5, 1.0])  # equivalent delay per axis, x amp
        else:
            c = rng.uniform(0, 1, 3)
            c[rng.integers(3)] = 1.0
            if rng.random() < 0.5:
                c[rng.integers(3)] = 0.0
            self.c = c
        self.amp = 0.2 * rec.dt
        self.amax = 0.5 * rec.dt  # the largest equivalent delay

    def timing(self, rec, t, f):
        d = self.amp * self.c
        if self.form == "skew":
            return np.column_stack([f(t - d[i])[:, i] for i in range(3)])
        if self.form == "rc":  # y = int_0^inf f(t - tau x) e^-x dx
            x, w = _LAGUERRE
            out = np.zeros((len(t), 3))
            for xk, wk in zip(x, w):
                out += wk * np.column_stack([f(t - d[i] * xk)[:, i] for i in range(3)])
            return out
        x, w = _LEGENDRE  # mean over [t - W, t], W = 2 d (equivalent delay d)
        out = np.zeros((len(t), 3))
        for xk, wk in zip(x, w):
            out += 0.5 * wk * np.column_stack([f(t - d[i] * (1 - xk))[:, i] for i in range(3)])
        return out


class _Nonlinearity(_Effect):
    name = "nonlinearity"

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        self.form = str(rng.choice(["poly", "even", "arctan"]))
        self.q = rng.uniform(-1, 1, 3)
        self.k = rng.uniform(-1, 1, 3) * (self.form == "poly")
        if self.form == "arctan":
            self.q = rng.uniform(0.3, 1, 3)
        self.F = rec.F0
        self.amp = 0.001 * rec.F0
        self.amax = 0.008 * rec.F0  # deviation at |x| = F

    def transfer(self, rec, core):
        x = core / self.F
        if self.form == "arctan":  # X atan(x / X) - x, deviation at x = F: -(amp q)
            out = core.copy()
            for i in range(3):
                dev = self.amp * self.q[i] / self.F
                if dev <= 0:
                    continue
                # X such that X atan(1/X) = 1 - dev, i.e. approx 1/(3 X^2) = dev
                X = 1 / np.sqrt(3 * dev)
                for _ in range(20):
                    g = X * np.arctan(1 / X) - (1 - dev)
                    dg = np.arctan(1 / X) - (1 / X) / (1 + 1 / X ** 2)
                    X -= g / dg
                out[:, i] = self.F * X * np.arctan(x[:, i] / X)
            return out
        return core + self.amp * (self.q * x ** 2 + self.k * x ** 3)


class _Outliers(_Effect):
    name = "outliers"

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        self.form = str(rng.choice(["axis", "vector"]))
        n = rec.n
        k = int(rng.integers(5, 13))
        rows: list[int] = []
        for _ in range(200):
            r = int(rng.integers(3, n - 3))
            if all(abs(r - q) >= 4 for q in rows):
                rows.append(r)
            if len(rows) == k:
                break
        self.rows_ = np.array(sorted(rows))
        self.targets = rng.uniform(12, 40, len(rows)) * rng.choice([-1, 1], len(rows))
        self.vec = None
        self.rng = rng
        self.amax = 0.2 * rec.F0

    def build(self, rec, raw0, sigma):
        """Spike vectors (raw units) sized on the clean record."""
        rng = self.rng
        B = (raw0 - rec.c) @ rec.C.T
        u = B / np.linalg.norm(B, axis=1, keepdims=True)
        vec = np.zeros((len(self.rows_), 3))
        for j, r in enumerate(self.rows_):
            for _ in range(100):
                v = np.eye(3)[rng.integers(3)] if self.form == "axis" else _rand_unit(rng)
                cv = rec.C @ v
                if rec.fixed or abs(u[r] @ cv) >= 0.4 * np.linalg.norm(cv):
                    break
            if rec.fixed:
                s = abs(self.targets[j]) * sigma / np.linalg.norm(cv) * np.sign(self.targets[j])
            else:
                s = self.targets[j] * sigma / (u[r] @ cv)
            vec[j] = s * v
        self.vec = vec

    def rows(self, rec, y):
        if self.vec is None or len(y) != rec.n:
            return y
        y = y.copy()
        y[self.rows_] += self.vec
        return y


# outside effects
class _GainSag(_Effect):
    name, library = "gain_sag", False

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        span, t0 = rec.t[-1] - rec.t[0], rec.t[0]
        tg = rec.tg
        a, b, tau = rng.uniform(0.3, 1), rng.uniform(0, 1), rng.uniform(0.05, 0.3) * span
        load = rec.sched.drive(np.maximum(tg, 0)) if rec.sched.drive is not None else None
        if load is None:
            load = _Sines(rng, 5, span / 20, span / 2, 1.0)(tg)
            load = np.maximum(load, 0)
        load = np.abs(load)
        load = _lag_series(tg, load, 0.02 * span)
        v = (-a * (tg - t0) / span - b * (1 - np.exp(-np.maximum(tg - t0, 0) / tau))
             - rng.uniform(0.3, 1) * load / max(load.max(), 1e-9))
        v = v - v.mean()
        self.v = v / np.ptp(v)
        kap = rng.uniform(-1, 1, 3) + rng.uniform(-0.3, 0.3)
        self.kap = kap / np.abs(kap).max()
        self.form = "discharge"
        self.amp = 500.0
        self.amax = 3000.0

    def sensor(self, rec, t, R, K, ang, o):
        return K * (1 + self.amp * 1e-6 * self.kap * np.interp(t, rec.tg, self.v)[:, None]), ang, o


class _ThermalHysteresis(_Effect):
    name, library = "thermal_hysteresis", False

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        T = rec.Tcore_g
        w = min(rng.uniform(0.3, 2.5), 0.4 * np.ptp(T))
        p = _play(T, w)
        self.p = p - p.mean()
        self.co = rng.uniform(-1, 1, 3)
        self.co /= np.abs(self.co).max()
        self.form = f"play {w:.2f} degC"
        self.amp = 2.0
        self.amax = 20.0

    def sensor(self, rec, t, R, K, ang, o):
        return K, ang, o + self.amp * self.co * np.interp(t, rec.tg, self.p)[:, None]


class _LeverDipole(_Effect):
    name, library = "lever_dipole", False

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        self.arm = _rand_unit(rng) * rec.sched.extra.get("arm_m", 0.2)
        self.pos = _rand_unit(rng) * rng.uniform(0.4, 2.0)
        self.m = _rand_unit(rng)
        self.form = f"dipole at {np.linalg.norm(self.pos):.2f} m"
        self.amp = 1.0  # A m^2
        self.amax = 50.0

    def world(self, rec, t, R, Bw):
        r = R.apply(np.tile(self.arm, (len(t), 1))) - self.pos
        d = np.linalg.norm(r, axis=1, keepdims=True)
        rh = r / d
        return Bw + 100.0 * self.amp * (3 * (rh @ self.m)[:, None] * rh - self.m) / d ** 3


class _TorqueCurrent(_Effect):
    name, library = "torque_current", False

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        self.dir = _rand_unit(rng)
        x = rec.sched.drive(rec.t)
        self.norm = max(np.abs(x).max(), 1e-9)
        self.form = "motor current"
        self.amp = 10.0
        self.amax = 0.02 * rec.F0

    def body(self, rec, t, R, Bp):
        return Bp + self.amp * np.outer(rec.sched.drive(t) / self.norm, self.dir)


class _GravityGain(_Effect):
    name, library = "gravity_gain", False

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        self.G = rng.uniform(-1, 1, (3, 3))
        self.form = "magnetoelastic"
        self.amp = 100.0
        self.amax = 500.0

    def sensor(self, rec, t, R, K, ang, o):
        g = R.inv().apply(np.tile([0, 0, 1.0], (len(t), 1)))
        return K * (1 + self.amp * 1e-6 * g @ self.G.T), ang, o


class _FlickerOffsets(_Effect):
    name, library = "flicker_offsets", False

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        m = len(rec.tg)
        alpha = rng.uniform(0.9, 1.3)
        f = np.fft.rfftfreq(m)
        amp = np.zeros_like(f)
        amp[1:] = f[1:] ** (-alpha / 2)
        x = np.column_stack([np.fft.irfft(amp * (rng.normal(size=len(f)) + 1j * rng.normal(size=len(f))), m)
                             for _ in range(3)])
        at = np.column_stack([np.interp(rec.t, rec.tg, x[:, i]) for i in range(3)])
        x = (x - at.mean(axis=0)) / at.std(axis=0)
        self.x = x
        self.form = f"1/f^{alpha:.2f}"
        self.amp = 3.0
        self.amax = 30.0  # RMS nT

    def sensor(self, rec, t, R, K, ang, o):
        return K, ang, o + self.amp * np.column_stack([np.interp(t, rec.tg, self.x[:, i]) for i in range(3)])


class _ScannerIron(_Effect):
    name, library = "scanner_iron", False

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        lo, hi = {"stabilised_mast": (0.3, 0.8), "rover": (5, 20), "turntable": (20, 50), "seafloor": (0.3, 3)}.get(
            rec.sched.kind, (0.3, 3))
        # aliased by regular sampling to a slow beat (at least 20 cycles in the record, at most a tenth of the
        # sampling rate): jittered time stamps would scatter the phase into noise, so it needs regular sampling
        fs, span = 1.0 / rec.dt, rec.t[-1] - rec.t[0]
        f_alias = rng.uniform(min(20 / span, 0.05 * fs), 0.1 * fs) * rng.choice([-1, 1])
        self.f0 = max(round(rng.uniform(lo, hi) / fs), 1) * fs + f_alias
        self.sweep = rng.uniform(0.001, 0.02) * self.f0
        self.sp = rng.uniform(0.3, 1) * (rec.t[-1] - rec.t[0])
        a = _rand_unit(rng)
        e1 = _unit(np.cross(a, _rand_unit(rng)))
        self.e1, self.e2 = e1, np.cross(a, e1)
        self.dc = rng.uniform(-0.3, 0.3) * a
        self.form = f"{self.f0:.2f} Hz, alias {f_alias:.4f} Hz"
        self.amp = 10.0
        self.amax = 0.01 * rec.F0 if rec.sampling in ("regular", "gaps", "burst") else 0.0

    def body(self, rec, t, R, Bp):
        ph = 2 * np.pi * self.f0 * t + 2 * np.pi * self.sweep * self.sp / (2 * np.pi) * np.sin(2 * np.pi * t / self.sp)
        return Bp + self.amp * (np.outer(np.cos(ph), self.e1) + np.outer(np.sin(ph), self.e2) + self.dc)


class _SolarCurrent(_Effect):
    name, library = "solar_current", False

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        az, el = rec.sched.sun
        self.sun = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), -np.sin(el)])  # NED: up is -z
        k = int(rng.integers(2, 5))
        self.normals = np.array([_rand_unit(rng) for _ in range(k)])
        self.fields = np.array([_rand_unit(rng) * rng.uniform(0.3, 1) for _ in range(k)])
        self.cloud = _Sines(rng, 4, 30, 600, 0.15)
        self.form = f"{k} panels"
        self.amp = 10.0
        self.amax = 0.01 * rec.F0

    def body(self, rec, t, R, Bp):
        s = R.inv().apply(np.tile(self.sun, (len(t), 1)))
        inc = np.maximum(s @ self.normals.T, 0) * np.clip(1 + self.cloud(t), 0.2, 1.3)[:, None]
        return Bp + self.amp * inc @ self.fields


class _VibrateMotor(_Effect):
    name, library = "vibrate_motor", False

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        k = int(rng.integers(3, 7))
        n = rec.n
        starts, lens = [], []
        for _ in range(100):
            ln = int(rng.integers(15, 61))
            s = int(rng.integers(5, max(n - ln - 5, 6)))
            if all(s + ln + 5 < a or s > a + b + 5 for a, b in zip(starts, lens)):
                starts.append(s)
                lens.append(ln)
            if len(starts) == k:
                break
        ti = rec.t
        self.a = np.array([ti[s] - 0.5 * rec.dt for s in starts])
        self.b = np.array([ti[min(s + ln, n - 1)] - 0.5 * rec.dt for s, ln in zip(starts, lens)])
        self.tau = 0.15 * rec.dt
        self.dir = _rand_unit(rng)
        self.rip = rng.uniform(0.05, 0.3)
        self.fr = rng.uniform(0.05, 0.4) / rec.dt
        self.form = f"{len(starts)} bursts"
        self.amp = 10.0
        self.amax = 0.02 * rec.F0

    def body(self, rec, t, R, Bp):
        x = np.asarray(t, float)[:, None]
        env = (_step((x - self.a) / self.tau) - _step((x - self.b) / self.tau)).sum(axis=1)
        return Bp + self.amp * np.outer(env * (1 + self.rip * np.sin(2 * np.pi * self.fr * t)), self.dir)


class _CrossoverStep(_Effect):
    name, library = "crossover_step", False

    def __init__(self, rec, rng):
        super().__init__(rec, rng)
        ax = rng.permutation(3)[: int(rng.integers(1, 3))]
        self.s = np.zeros(3)
        self.s[ax] = rng.choice([-1, 1], len(ax)) * rng.uniform(0.5, 1, len(ax))
        self.w = rng.uniform(20, 300)
        self.form = f"axes {sorted(ax.tolist())} w {self.w:.0f} nT"
        self.amp = 5.0
        self.amax = 50.0

    def transfer(self, rec, core):
        return core + self.amp * self.s * np.tanh(core / self.w)


_EFFECTS = {c.name: c for c in (_Temperature, _FieldDrift, _OffsetDrift, _Lag, _Nonlinearity, _Outliers, _GainSag,
                                _ThermalHysteresis, _LeverDipole, _TorqueCurrent, _GravityGain, _FlickerOffsets,
                                _ScannerIron, _SolarCurrent, _VibrateMotor, _CrossoverStep)}


# ------------------------------------------------------------------------------------------ visibility
class _Analyst:
    """The perfect analyst's view of a record: clean readings, calibration directions, library bases."""

    def __init__(self, rec: _Rec, temp_logged: bool):
        self.rec = rec
        self.raw0 = _raw_nf(rec, [])
        B = (self.raw0 - rec.c) @ rec.C.T
        self.Bmag = np.linalg.norm(B, axis=1)
        self.u = B / self.Bmag[:, None]
        u = self.u
        lsbv = (rec.lsb ** 2 / 12) if rec.lsb is not None else 0.0
        var = rec.sig ** 2 + lsbv
        self.sigma = float(np.sqrt(np.mean((u @ rec.C) ** 2 @ var) + rec.ref_sig ** 2))
        self.sigma_v = float(np.sqrt(np.mean(rec.C ** 2 @ var)))
        n = rec.n
        iu = np.triu_indices(3)
        self.cal = np.column_stack([self.Bmag * u[:, i] * u[:, j] for i, j in zip(*iu)] + [u])
        z = np.zeros(n)

        def per_axis(cols):
            return np.column_stack([np.concatenate([c if k == i else z for k in range(3)]) for c in cols for i in range(3)])
        if rec.fixed:  # a fixed sensor's corrected vector about its mean
            self.cal = per_axis([np.ones(n)])
        span = rec.t[-1] - rec.t[0]
        x = 2 * (rec.t - rec.t[0]) / span - 1
        T = rec.temp_log - rec.temp_log.mean()
        dT = np.gradient(_smooth_rows(rec.temp_log, rec.t), rec.t)
        bases = {}
        if not rec.fixed:
            if temp_logged:
                bases["temperature"] = np.column_stack([self.cal * T[:, None], self.cal * dT[:, None]])
            bases["field_drift"] = legendre.legvander(x, 12)[:, 1:]
            p6 = legendre.legvander(x, 6)[:, 1:]
            bases["offset_drift"] = np.column_stack([u[:, [i]] * p6 for i in range(3)])
            eps = 1e-3 * rec.dt
            draw = (_raw_nf(rec, [], rec.t + eps) - _raw_nf(rec, [], rec.t - eps)) / (2 * eps)
            g = u @ rec.C
            cols = [g[:, i] * draw[:, i] for i in range(3)]
            if rec.ref != "model":
                cols.append(np.gradient(rec.f_ref(), rec.t))
            bases["lag"] = np.column_stack(cols)
            xr = self.raw0 / rec.F0
            bases["nonlinearity"] = np.column_stack([g[:, i] * xr[:, i] ** p for i in range(3) for p in (2, 3)])
        else:
            p6 = legendre.legvander(x, 6)[:, 1:]
            if temp_logged:
                bases["temperature"] = per_axis([T, dT])
            bases["field_drift"] = per_axis(list(p6.T))
            bases["offset_drift"] = bases["field_drift"]
        self.bases = bases
        self._spans = {}

    def left(self, d, *names):
        """What the calibration and the named library models together leave of d."""
        if names not in self._spans:
            self._spans[names] = _span(np.column_stack([self.cal] + [self.bases[k] for k in names]))
        u = self._spans[names]
        return d - u @ (u.T @ d)

    def delta(self, effs):
        """The visible part of effs' contribution, with what the calibration absorbs removed."""
        rec = self.rec
        raw = _raw_nf(rec, effs)
        B = (raw - rec.c) @ rec.C.T
        d = (B - (self.raw0 - rec.c) @ rec.C.T).T.ravel() if rec.fixed else np.linalg.norm(B, axis=1) - self.Bmag
        return self.left(d), raw

    def noise(self):
        return self.sigma_v if self.rec.fixed else self.sigma

    def beyond(self, d):
        """RMS of what remains after every library effect's model, the largest 1 % left out."""
        r = self.left(d, *sorted(self.bases))
        a = np.sort(np.abs(r))
        keep = a[: int(np.floor(0.99 * len(a)))]
        return _rms(keep)


def _smooth_rows(x, t):
    """A thermometer's readings smoothed over about a minute (or 9 rows) for its rate."""
    k = max(3, min(int(60 / max(np.median(np.diff(t)), 1e-3)), 9) | 1)
    kern = np.ones(k) / k
    return np.convolve(np.pad(x, k // 2, mode="edge"), kern, "valid")


def _scale(an: _Analyst, eff: _Effect, target: float, beyond: bool) -> tuple[bool, float, str]:
    """Scale eff's amplitude so that its visible (or beyond-library) RMS is target x noise."""
    sig = an.noise()
    rec = an.rec
    if eff.name == "outliers":
        eff.build(rec, an.raw0, sig)
        if np.abs(eff.vec).max() > eff.amax:
            return False, 0.0, "spike too large"
        return True, float(np.min(np.abs(eff.targets))), ""
    v = 0.0
    for _ in range(8):
        d, raw = an.delta([eff])
        v = (an.beyond(d) if beyond else _rms(d)) / sig
        if v <= 1e-9:
            return False, 0.0, "invisible"
        ratio = target / v
        if abs(ratio - 1) < 0.03:
            break
        new = eff.amp * ratio
        if new > eff.amax * 1.5:
            return False, v, "beyond its bound"
        eff.amp = new
    if eff.amp > eff.amax:
        return False, v, "beyond its bound"
    if _rms(raw - an.raw0) > 0.01 * rec.F0:
        return False, v, "moves the readings by more than 1 % of F"
    lo = BEYOND_RANGE[0] if beyond else VISIBLE_RANGE[0]
    if v < 0.8 * lo:
        return False, v, "not reached"
    return True, v, ""


# ------------------------------------------------------------------------------------------ the case
def _draw_effects(category, rng):
    lib_pool = FIXED_LIBRARY if category == "fixed" else LIBRARY
    out_pool = _COMPATIBLE["seafloor"] if category == "fixed" else OUTSIDE
    lib, out = [], []
    if category == "single":
        lib = list(rng.choice(lib_pool, 1, replace=False))
    elif category == "pair":
        lib = list(rng.choice(lib_pool, 2, replace=False))
    elif category == "triple":
        lib = list(rng.choice(lib_pool, 3, replace=False))
    elif category == "outside":
        out = list(rng.choice(out_pool, 2 if rng.random() < 0.2 else 1, replace=False))
    elif category == "outside_plus":
        lib = list(rng.choice(lib_pool, 1))
        out = list(rng.choice(out_pool, 1))
    elif category == "fixed":
        lib = list(rng.choice(lib_pool, 2 if rng.random() < 0.3 else 1, replace=False))
        if rng.random() < 0.3:
            out = list(rng.choice(out_pool, 1))
    return [str(x) for x in lib], [str(x) for x in out]


def make_case(index: int, root: int = 2026) -> Case:
    """The blind record ``index`` (deterministic from index and root)."""
    rng = np.random.default_rng([root, 5, index])
    category = PATTERN[index % len(PATTERN)]
    failures: list[str] = []
    lib: list[str] = []
    out: list[str] = []
    for attempt in range(60):
        if attempt % 6 == 0:  # the effects are drawn again after six records that could not show them
            lib, out = _draw_effects(category, rng)
            if category == "too_short":
                lib = [str(rng.choice(LIBRARY))] if rng.random() < 0.5 else []
        kinds = ["seafloor"] if category == "fixed" else [k for k in MOVING if all(o in _COMPATIBLE[k] for o in out)]
        if not kinds:
            lib, out = _draw_effects(category, rng)
            failures.append(f"no schedule carries {out}")
            continue
        kind = str(rng.choice(kinds))
        names = lib + out
        needs_temp = any(n in ("temperature", "thermal_hysteresis") for n in names)
        no_coloc = any(n in ("field_drift", "lever_dipole") for n in names)
        cap = min([NOISE_CAP.get(n, 3.0) for n in names] + [3.0])
        rec = _Rec(rng, kind, short=category == "too_short", no_colocated=no_coloc, noise_cap=cap)
        temp_logged = needs_temp or rng.random() < 0.85
        effs = [_EFFECTS[n](rec, rng) for n in names]
        if category == "too_short":
            for e in effs:
                if e.name == "outliers":  # one or two spikes of 30 noise
                    e.rows_ = np.sort(rng.choice(rec.n, int(rng.integers(1, 3)), replace=False))
                    e.vec = np.array([_rand_unit(rng) for _ in e.rows_]) * 30 * rec.sig.mean()
                else:
                    e.amp = min(e.amax, 1e9) * rng.uniform(0.1, 0.5) if np.isfinite(e.amax) else e.amp
            return _finish(index, category, rec, effs, [], [], temp_logged, {}, rng, attempt, failures)
        an = _Analyst(rec, temp_logged)
        ok = True
        info = {}
        for e in effs:
            lo, hi = BEYOND_RANGE if not e.library else VISIBLE_RANGE
            target = float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
            good, v, why = _scale(an, e, target, beyond=not e.library)
            if not good:
                failures.append(f"{kind}/{e.name}/{e.form}: {why}")
                ok = False
                break
            info[e.name] = {"form": e.form, "amp": float(e.amp), ("beyond_sigma" if not e.library else "visible_sigma"): v}
        if not ok:
            continue
        # visible sizes (after calibration) of each library effect, and the pairs the record cannot separate
        conf = set()
        for e in effs:
            if not e.library or e.name == "outliers":
                continue
            d, _ = an.delta([e])
            vis = _rms(d)
            info[e.name]["visible_sigma"] = vis / an.noise()
            thresh = max(3 * an.noise(), 0.3 * vis)
            for other in LIBRARY:
                if other in (e.name, "outliers"):
                    continue
                if other in ("lag", "nonlinearity") and rec.fixed:
                    continue
                if other not in an.bases:
                    continue
                left = _rms(an.left(d, other))
                if left < thresh:
                    conf.add(tuple(sorted((e.name, other))))
            if rec.fixed and e.name in ("offset_drift", "field_drift"):
                conf.add(("field_drift", "offset_drift"))
        for e in effs:  # outside effects: their size beyond the calibration (for the notes)
            if not e.library:
                d, _ = an.delta([e])
                info[e.name]["visible_sigma"] = _rms(d) / an.noise()
        lib_present = [e.name for e in effs if e.library]
        outside = [e.name for e in effs if not e.library]
        return _finish(index, category, rec, effs, lib_present, outside, temp_logged,
                       {"effects": info, "confoundable": sorted(conf), "noise": an.noise()}, rng, attempt, failures,
                       conf=tuple(sorted(conf)))
    raise RuntimeError(f"case {index}: no record after 60 attempts: {failures[-5:]}")


def _finish(index, category, rec, effs, present, outside, temp_logged, info, rng, attempt, failures, conf=()):
    raw = _raw_nf(rec, effs)
    noise = rng.normal(size=raw.shape) * rec.sig
    raw = raw + noise
    if rec.lsb is not None:
        raw = np.round(raw / rec.lsb) * rec.lsb
    f_ref = rec.f_ref() + (rng.normal(0, rec.ref_sig, rec.n) if rec.ref_sig > 0 else 0.0)
    if rec.ref != "model":
        f_ref = np.round(f_ref, 2)
    gravity = None
    s = rec.sched
    if rng.random() < s.gravity_p:
        g = rec.sched.att(rec.t).inv().apply(np.tile([0, 0, 1.0], (rec.n, 1)))
        g = g + rng.normal(size=g.shape) * s.gravity_noise
        gravity = g / np.linalg.norm(g, axis=1, keepdims=True)
    names = [e.name for e in effs]
    acceptable = set(present)
    for o in outside:
        acceptable.update(ACCEPTABLE_FOR.get(o, ()))
    if category == "too_short":
        acceptable.update(n for n in names if n in LIBRARY)
    C, c = rec.C, rec.c
    notes = {"true_C": C.tolist(), "true_offset_nT": c.tolist(), "noise_nT": info.get("noise"),
             "noise_vector_nT": float(np.sqrt(np.mean(rec.C ** 2 @ (rec.sig ** 2)))), "F0_nT": rec.F0,
             "sampling": rec.sampling, "reference": rec.ref, "n": rec.n, "span_s": float(rec.t[-1] - rec.t[0]),
             "attempts": attempt + 1, "failures": failures[-10:], "effects": info.get("effects", {}),
             "drawn": names, "temperature_logged": bool(temp_logged), "gravity": gravity is not None}
    return Case(index=index, category=category, raw_nT=raw, f_ref_nT=np.asarray(f_ref, float) * np.ones(rec.n),
                t_s=rec.t.copy(), temp_C=rec.temp_log.copy() if temp_logged else None, gravity=gravity,
                present=tuple(present), outside=tuple(outside), acceptable=tuple(sorted(acceptable)),
                expect_unexplained=bool(outside), confoundable=tuple(conf), schedule=rec.sched.kind, notes=notes)

"""A third forward model of a fluxgate in the geomagnetic field: the held-out source of blind cases written in
round 5 by another hand, from the physics and numpy only.  It shares no code with magbench's simulator, its
diagnosis or calibrators, nor with the first two generators' effects and schedules (it reuses only their
``Case`` record, imported from tests/independent_forward.py).

Sensor.  Three fluxgate axes with their own unit vectors in the body frame (non-orthogonal by up to ~1 deg), a
scale factor and an offset each, behind a constant soft iron and hard iron of the platform:
``raw_i = g_i * u_i . (S B_body + h) + o_i + noise``, white noise of 0.1-5 nT per axis, sometimes an ADC with a
least significant bit of up to twice the noise.  The reference field is 20,000-65,000 nT at an inclination of
up to 75 deg; the scalar reference ``F`` is a co-located Overhauser or proton magnetometer (with its own small
noise and resolution, following the field's natural variation) or a model value (a constant).

Attitude schedules (new): a ship rolling in a seaway with course changes, a quadcopter hovering with yaw spins
and pilot's tilts, a car lapping a closed circuit (mostly yaw, small pitch and roll), a hand-rotated calibration
dance with pauses, a free-tumbling body (precession, nutation, spin), a moored buoy in waves swinging round its
mooring, and a fixed sensor (hours at low rates, no rotation) for the ``fixed`` category.  Sampling regular,
jittered (the time stamps are the true sample times) or with dropouts.

Library effects (the diagnosis may name them), in this generator's own physical forms:
- temperature: offsets (nT/degC), scale factors (ppm/degC) and axis directions (rad/degC) following the sensor
  core's temperature, which is the logged board thermometer's temperature or a lagged version of it (thermal
  lag); the thermometer has its own noise and resolution (0.0625 or 0.01 degC).  The temperature comes from the
  platform's environment (warm-up, HVAC cycling, sun and eclipse, a daily cycle, random wander).
- field_drift: a geomagnetic variation (a substorm bay, a long-period pulsation, a trend; for the ship, crustal
  anomalies along its track) that the scalar reference does not follow (a model value) or follows only in part
  (a remote station).
- offset_drift: slow offsets in the sensor frame: logarithmic creep after a magnetic shock, viscous relaxation
  of a magnetised part, ageing of the electronics (a polynomial).
- lag: a multiplexed ADC sampling the axes one after another (sample skew), per-axis analog anti-alias RC
  filters with mismatched time constants, or per-axis sinc^3 decimation filters of different lengths.
- nonlinearity: a quadratic-and-cubic transfer per axis, or soft core saturation (X tanh(b/X)) per axis.
- outliers: single-sample spikes (EMI) or flipped high bits of the ADC word, isolated, spread over the record.

Effects outside the library (``OUTSIDE``), each chosen to resemble a library effect; for each, what a careful
analyst may legitimately name (``ACCEPTABLE_FOR``), decided from the physics and erring towards strictness:
- servo_current: an actuator holding a load against gravity draws a current that follows the body's tilt, plus
  a friction term that follows the sign of the rotation rate; its field is body-fixed.  Resembles a soft iron
  and a lag.  Nothing acceptable: it is neither a delay nor the sensor's response.
- rate_actuator: a differential motor / rudder current proportional to the body rate (and its square): a
  body-fixed field following the rotation rate.  Resembles a lag (rate-dependent); it is not a delay.
  Nothing acceptable.
- rotor_magnet: a hard iron turning with a propeller, wheel, shaft or fan, aliased by the sampling to a low
  frequency (sampling regular so that the alias is coherent).  Resembles an offset drift or a lag.  Nothing.
- relay_load: a load switched on and off two to five times (a pump, a light), its current's field body-fixed,
  with an RC transient.  Resembles an offset drift; a switch is not a drift (docs/CONTRACT.md).  Nothing.
- thermal_soft_iron: a soft-iron part whose permeability peaks with temperature (a Hopkinson peak), so its
  induced field follows the logged temperature non-linearly.  Physically a temperature effect of the
  platform: ``temperature`` is acceptable; the part beyond a linear temperature dependence is unexplained.
- boom_gradient: the sensor on a lever arm about the rotation centre in a field gradient (steel nearby): the
  field it sees depends on attitude quadratically through its position.  Resembles a nonlinearity.  Nothing.
- eddy_housing: eddy currents in a conducting housing whose axis is tilted from the sensor axes oppose the
  field's change: the field inside is a lagged (first-order filtered) version of the outside along the
  housing's principal directions.  Physically a lag: ``lag`` is acceptable; the tilted (cross-axis) part is
  outside the per-axis lag and stays unexplained.
- hysteresis: a magnetically hard part with hysteresis (a play operator on the field along it): a rate-
  independent memory.  Resembles a lag and a nonlinearity; it is neither a delay nor the sensor's transfer.
  Nothing acceptable.
- cross_axis_nonlin: the feedback of one axis disturbing another core (b_j += k b_i |b_i|): the sensor's
  response beyond linear, but across axes.  ``nonlinearity`` is acceptable (the response is not linear); the
  cross-axis part is outside a per-axis transfer and stays unexplained.
- mains_alias: 50/60 Hz from the platform's own wiring (body-fixed), aliased by a sample rate a little off a
  sub-multiple of the mains frequency to a slow beat with at least 20 cycles in the record.  Resembles an
  offset drift (a body-fixed field changing in time) but is not slow.  Nothing.  (Mains hum from the world,
  by contrast, would be a field change seen by the sensor and not the reference: a field_drift; not used.)
- heater_pwm: a thermostat's heater cycling (at least 10 cycles), its current's field body-fixed; the logged
  thermometer is the ambient one, not the heated block's, so the temperature does not follow the heater.
  Resembles an offset drift and switching.  Nothing.
- polarisation_pulses: a proton magnetometer on the platform polarises its sample with a coil for 25-50 % of
  each cycle; the coil's field is body-fixed and periodic.  Resembles offset jumps; not sparse enough to be
  outliers.  Nothing.

Visibility (``present`` holds only effects a perfect analyst could see).  Every effect is built with a unit
amplitude, its contribution to the scalar residual is computed exactly (the forward model with and without
it, corrected with the true calibration), and its amplitude is then scaled so that what remains of it after a
perfect calibration fit (a least-squares fit of the nine calibration directions of the scalar residual,
linearised about the truth) has an RMS of 4-20 times the noise (``VISIBLE`` = 3 is the floor checked by the
tests).  For a fixed sensor the same is done on the vector readings about their mean.  Outliers are built
spike by spike: each spike moves the scalar residual (a fixed sensor's reading) by at least 10 times the noise,
and there are at least five.  Sizes stay physically plausible (``_Record.implausible``): no effect moves the
readings by more than 1 % of the field (RMS), a delay stays within half a sample period, a temperature
coefficient within 30 nT/degC and 300 ppm/degC, an eddy-current time constant within 50 ms, a saturation field
above twice the field; an effect that cannot be seen at a plausible size is drawn again with another shape, and
failing that the record is rebuilt on another platform (a slow car cannot show an eddy current).
An outside effect is scaled so that what remains of it after the calibration and
every library effect's model together (the union of their linearised bases) is 4-15 times the noise: then a
remainder the library cannot explain is there to see, and ``expect_unexplained`` is honest.  Two library
effects are ``confoundable`` in a record when what remains of the present one after the calibration and the
other's model is below max(3 noise, 30 % of its visible size); on a fixed sensor an offset drift and a field
drift are always confoundable (a field that turns and offsets that drift move the readings alike), and
temperature with both when the temperature's effect is explained by a smooth function of time.
"""
from __future__ import annotations

import numpy as np
from independent_forward import Case

LIBRARY = ("temperature", "field_drift", "offset_drift", "lag", "nonlinearity", "outliers")
OUTSIDE = ("servo_current", "rate_actuator", "rotor_magnet", "relay_load", "thermal_soft_iron", "boom_gradient",
           "eddy_housing", "hysteresis", "cross_axis_nonlin", "mains_alias", "heater_pwm", "polarisation_pulses")
ACCEPTABLE_FOR = {"thermal_soft_iron": ("temperature",), "eddy_housing": ("lag",),
                  "cross_axis_nonlin": ("nonlinearity",)}
SCHEDULES = ("ship", "quad_hover", "car_circuit", "hand_dance", "tumble", "buoy")
FAST = ("quad_hover", "hand_dance", "tumble")
FIXED_EFFECTS = ("temperature", "field_drift", "offset_drift", "outliers")
# one block of 24 consecutive cases: 2 clean, 6 single, 2 pair, 2 triple, 6 outside, 2 outside_plus,
# 2 too_short, 2 fixed (the second generator's mix), in this generator's own order
PATTERN = ("clean", "single", "outside", "pair", "single", "outside", "fixed", "single", "outside_plus", "triple",
           "outside", "too_short", "clean", "single", "outside", "single", "pair", "outside", "fixed", "single",
           "outside_plus", "triple", "outside", "too_short")
VISIBLE = 3.0  # the visibility floor, in noise units
DEG = np.pi / 180.0
X_FS = 1.0e5  # the sensor's full-scale field, nT
_LAG_NODES, _LAG_WEIGHTS = np.polynomial.laguerre.laggauss(8)


# --------------------------------------------------------------------------------------- rotations
def _elementary(axis: int, a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    if axis == 0:
        m = [[o, z, z], [z, c, -s], [z, s, c]]
    elif axis == 1:
        m = [[c, z, s], [z, o, z], [-s, z, c]]
    else:
        m = [[c, -s, z], [s, c, z], [z, z, o]]
    return np.moveaxis(np.array(m), -1, 0)


def _ypr(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """Body-to-world rotations (n, 3, 3): heading about the world's up axis, then pitch, then roll."""
    return _elementary(2, yaw) @ _elementary(1, pitch) @ _elementary(0, roll)


def _skew(v: np.ndarray) -> np.ndarray:
    z = np.zeros(len(v))
    return np.moveaxis(np.array([[z, -v[:, 2], v[:, 1]], [v[:, 2], z, -v[:, 0]], [-v[:, 1], v[:, 0], z]]), -1, 0)


def _expmap(v: np.ndarray) -> np.ndarray:
    """Rotation matrices from rotation vectors (n, 3) (Rodrigues)."""
    th = np.linalg.norm(v, axis=1)
    k = v / np.where(th > 1e-15, th, 1.0)[:, None]
    kx = _skew(k)
    return (np.eye(3)[None] + np.sin(th)[:, None, None] * kx
            + (1.0 - np.cos(th))[:, None, None] * (kx @ kx))


def _logmap(r: np.ndarray) -> np.ndarray:
    c = np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0)
    th = float(np.arccos(c))
    if th < 1e-12:
        return np.zeros(3)
    if th > np.pi - 1e-6:  # half-turn: the axis from the symmetric part
        m = (r + np.eye(3)) / 2.0
        axis = m[:, int(np.argmax(np.diag(m)))]
        return th * axis / np.linalg.norm(axis)
    w = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    return th * w / (2.0 * np.sin(th))


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    a, b, c, d = q / np.linalg.norm(q)
    return np.array([[a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
                     [2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)],
                     [2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d]])


def _unit(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def _step(x: np.ndarray) -> np.ndarray:
    """Minimum-jerk step from 0 to 1 over x in [0, 1]."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (10.0 - 15.0 * x + 6.0 * x * x)


def _dstep(x: np.ndarray) -> np.ndarray:
    inside = (x > 0.0) & (x < 1.0)
    return np.where(inside, 30.0 * x * x * (1.0 - x) ** 2, 0.0)


def _steps(t: np.ndarray, centres: np.ndarray, widths: np.ndarray, deltas: np.ndarray) -> np.ndarray:
    x = (t[:, None] - centres[None]) / widths[None] + 0.5
    return (_step(x) * deltas).sum(1)


def _dsteps(t: np.ndarray, centres: np.ndarray, widths: np.ndarray, deltas: np.ndarray) -> np.ndarray:
    x = (t[:, None] - centres[None]) / widths[None] + 0.5
    return (_dstep(x) / widths * deltas).sum(1)


# --------------------------------------------------------------------------------------- attitude schedules
# Each returns (fs in Hz, attitude function of time, duration in s).  Attitudes are analytic in time so that a
# filter or a sample skew can evaluate them anywhere.
def _ship(rng: np.random.Generator, n: int):
    fs = min(float(rng.choice([1.0, 2.0, 4.0, 5.0, 10.0])), n / 300.0)
    dur = n / fs
    k = int(rng.integers(2, 6))
    centres = np.sort(rng.uniform(0.05, 0.95, k)) * dur
    widths = rng.uniform(0.04, 0.15, k) * dur
    deltas = rng.choice([-1.0, 1.0], k) * rng.uniform(0.5, 1.5, k) * 2 * np.pi
    deltas *= max(1.0, 4 * np.pi / np.abs(deltas).sum())  # at least two full turns in all
    yaw0, yaw_a, yaw_p = rng.uniform(0, 2 * np.pi), rng.uniform(1, 4) * DEG, rng.uniform(8, 20)
    ar, pr, ap, pp, pm = rng.uniform(5, 25) * DEG, rng.uniform(6, 16), rng.uniform(2, 8) * DEG, rng.uniform(4, 9), \
        rng.uniform(60, 300)
    heel = rng.uniform(0.3, 1.5)  # rad of heel per rad/s of turn
    ph = rng.uniform(0, 2 * np.pi, 6)

    def att(t):
        yaw = yaw0 + _steps(t, centres, widths, deltas) + yaw_a * np.sin(2 * np.pi * t / yaw_p + ph[0])
        rate = _dsteps(t, centres, widths, deltas)
        roll = (ar * (1 + 0.3 * np.sin(2 * np.pi * t / pm + ph[1])) * np.sin(2 * np.pi * t / pr + ph[2])
                + 0.3 * ar * np.sin(2 * np.pi * t / (0.71 * pr) + ph[3]) - heel * rate)
        pitch = ap * np.sin(2 * np.pi * t / pp + ph[4]) + 0.3 * ap * np.sin(2 * np.pi * t / (1.37 * pp) + ph[5])
        return _ypr(yaw, pitch, roll)

    return fs, att, dur


def _bumps(t, centres, widths, amps):
    x = np.clip((t[:, None] - centres[None]) / widths[None] + 0.5, 0.0, 1.0)
    return (np.sin(np.pi * x) ** 2 * amps).sum(1)


def _quad_hover(rng: np.random.Generator, n: int):
    fs = min(float(rng.choice([25.0, 50.0, 100.0])), n / 40.0)
    dur = n / fs
    k = int(rng.integers(2, 7))
    centres = np.sort(rng.uniform(0.05, 0.95, k)) * dur
    widths = np.minimum(rng.uniform(2, 8, k), 0.8 * dur / k)
    deltas = rng.choice([-1.0, 1.0], k) * rng.uniform(1.0, 2.5, k) * 2 * np.pi
    m = int(rng.integers(3, 7))
    mc = rng.uniform(0.03, 0.97, m) * dur
    mw = np.minimum(rng.uniform(1.5, 5, m), 0.5 * dur / m)
    ma = rng.choice([-1.0, 1.0], m) * rng.uniform(12, 35, m) * DEG
    on_pitch = rng.random(m) < 0.5
    wf, wa, wp = rng.uniform(0.1, 2.0, (2, 6)), rng.uniform(0.3, 2.0, (2, 6)) * DEG, rng.uniform(0, 2 * np.pi, (2, 6))
    yaw0, yaw_drift = rng.uniform(0, 2 * np.pi), rng.normal(0, 0.5) * DEG

    def att(t):
        yaw = yaw0 + yaw_drift * t + _steps(t, centres, widths, deltas)
        wob = [(wa[j][None] * np.sin(2 * np.pi * wf[j][None] * t[:, None] + wp[j][None])).sum(1) for j in range(2)]
        pitch = wob[0] + _bumps(t, mc[on_pitch], mw[on_pitch], ma[on_pitch])
        roll = wob[1] + _bumps(t, mc[~on_pitch], mw[~on_pitch], ma[~on_pitch])
        return _ypr(yaw, pitch, roll)

    return fs, att, dur


def _car_circuit(rng: np.random.Generator, n: int):
    fs = min(float(rng.choice([10.0, 20.0, 25.0, 50.0])), n / 60.0)
    dur = n / fs
    lap = min(rng.uniform(30, 120), dur / 2.5)
    a, c = rng.uniform(0, 0.3), rng.uniform(0, 2 * np.pi)
    kk = np.array([2.0, 3.0, 4.0])
    b, cb = rng.uniform(0, 0.12, 3) / kk, rng.uniform(0, 2 * np.pi, 3)
    sense, yaw0 = rng.choice([-1.0, 1.0]), rng.uniform(0, 2 * np.pi)
    lean, grade, gph = rng.uniform(1, 4) * DEG, rng.uniform(0.5, 3, 3) * DEG, rng.uniform(0, 2 * np.pi, 3)

    def att(t):
        w = 2 * np.pi / lap
        phi = w * t + a * np.sin(w * t + c)
        dphi = w * (1 + a * np.cos(w * t + c))
        yaw = yaw0 + sense * (phi + (b[None] * np.sin(kk[None] * phi[:, None] + cb[None])).sum(1))
        rate = sense * dphi * (1 + (kk[None] * b[None] * np.cos(kk[None] * phi[:, None] + cb[None])).sum(1))
        roll = -lean * rate / w
        pitch = (grade[None] * np.sin(np.arange(1, 4)[None] * phi[:, None] + gph[None])).sum(1)
        return _ypr(yaw, pitch, roll)

    return fs, att, dur


def _hand_dance(rng: np.random.Generator, n: int):
    fs = min(float(rng.choice([10.0, 20.0, 25.0, 50.0])), n / 60.0)
    dur = n / fs
    starts, hold_end, trans = [], [], []
    poses = [_random_rotation(rng)]
    t = -10.0
    while t < dur + 10.0:
        pause, move = rng.uniform(0.5, 4.0), rng.uniform(1.0, 3.5)
        starts.append(t)
        hold_end.append(t + pause)
        trans.append(move)
        poses.append(_random_rotation(rng))
        t += pause + move
    p = np.array(poses)
    vs = np.array([_logmap(p[i].T @ p[i + 1]) for i in range(len(starts))])
    st, he, tr = np.array(starts), np.array(hold_end), np.array(trans)
    amp, ftr, ph = rng.uniform(0.1, 0.5) * DEG, rng.uniform(6, 12), rng.uniform(0, 2 * np.pi, 3)

    def att(tt):
        i = np.clip(np.searchsorted(st, tt, "right") - 1, 0, len(st) - 1)
        s = _step((tt - he[i]) / tr[i])
        tremor = amp * np.sin(2 * np.pi * ftr * tt[:, None] * np.array([1.0, 1.13, 0.91]) + ph)
        return p[i] @ _expmap(s[:, None] * vs[i]) @ _expmap(tremor)

    return fs, att, dur


def _tumble(rng: np.random.Generator, n: int):
    fs = min(float(rng.choice([1.0, 2.0, 5.0, 10.0])), n / 200.0)
    dur = n / fs
    wp = max(rng.uniform(3, 20) * DEG, 2.5 * 2 * np.pi / dur)  # precession: at least 2.5 turns
    nut, ws = rng.uniform(20, 80) * DEG, rng.choice([-1.0, 1.0]) * rng.uniform(0, 25) * DEG
    a, b, q = rng.uniform(0, 2 * np.pi), rng.uniform(0, 2 * np.pi), _random_rotation(rng)

    def att(t):
        return q[None] @ _elementary(2, wp * t + a) @ _elementary(0, np.full_like(t, nut)) @ _elementary(2, ws * t + b)

    return fs, att, dur


def _buoy(rng: np.random.Generator, n: int):
    fs = min(float(rng.choice([2.0, 4.0, 5.0, 8.0])), n / 400.0)
    dur = n / fs
    fp = rng.uniform(0.08, 0.2)
    f = rng.uniform(0.07, 0.35, 24)
    amp = np.sqrt(f ** -5.0 * np.exp(-1.25 * (fp / f) ** 4))
    amp /= np.sqrt((amp ** 2).sum() / 2.0)
    r_rms = rng.uniform(4, 14) * DEG
    ar, ap = amp * r_rms, amp * r_rms * rng.uniform(0.6, 1.2)
    phr, php = rng.uniform(0, 2 * np.pi, 24), rng.uniform(0, 2 * np.pi, 24)
    yaw0, swing = rng.uniform(0, 2 * np.pi), rng.choice([-1.0, 1.0]) * rng.uniform(1, 2) * 2 * np.pi
    sc, sw = rng.uniform(0.3, 0.7) * dur, rng.uniform(0.3, 0.7) * dur
    vane, pv, phv = rng.uniform(5, 25) * DEG, rng.uniform(40, 200), rng.uniform(0, 2 * np.pi)

    def att(t):
        roll = (ar[None] * np.sin(2 * np.pi * f[None] * t[:, None] + phr[None])).sum(1)
        pitch = (ap[None] * np.sin(2 * np.pi * f[None] * t[:, None] + php[None])).sum(1)
        yaw = yaw0 + swing * _step((t - sc) / sw + 0.5) + vane * np.sin(2 * np.pi * t / pv + phv)
        return _ypr(yaw, pitch, roll)

    return fs, att, dur


def _fixed(rng: np.random.Generator, n: int):
    dur = rng.uniform(2.0, 20.0) * 3600.0
    r = _random_rotation(rng)

    def att(t):
        return np.broadcast_to(r, (len(t), 3, 3)).copy()

    return n / dur, att, dur


SCHEDULE_FUNCTIONS = {"ship": _ship, "quad_hover": _quad_hover, "car_circuit": _car_circuit,
                      "hand_dance": _hand_dance, "tumble": _tumble, "buoy": _buoy, "fixed": _fixed}


def _times(rng: np.random.Generator, fs: float, n: int, kind: str) -> np.ndarray:
    t0 = rng.uniform(0, 50)
    if kind == "regular":
        return t0 + np.arange(n) / fs
    if kind == "jittered":
        return t0 + (np.arange(n) + rng.uniform(-0.2, 0.2, n)) / fs
    m = int(n * rng.uniform(1.03, 1.15))  # dropouts: a few blocks and some single samples lost
    keep = np.ones(m, bool)
    extra = m - n
    blocks = int(rng.integers(2, 6))
    for length in rng.multinomial(extra // 2, np.ones(blocks) / blocks):
        if length:
            s = int(rng.integers(1, m - length - 1))
            keep[s:s + length] = False
    inner = np.flatnonzero(keep[1:-1]) + 1
    lose = max(0, int(keep.sum()) - n)
    keep[rng.choice(inner, size=min(lose, len(inner) - 2), replace=False)] = False
    return t0 + np.flatnonzero(keep) / fs


def _legendre(t: np.ndarray, degrees) -> np.ndarray:
    x = 2.0 * (t - t[0]) / max(t[-1] - t[0], 1e-9) - 1.0
    return np.stack([np.polynomial.legendre.Legendre.basis(d)(x) for d in degrees], axis=1)


def _lowpass(x: np.ndarray, dt: float, tau: float) -> np.ndarray:
    if tau <= 0:
        return x.copy()
    a = 1.0 - np.exp(-dt / tau)
    y = np.empty_like(x)
    y[0] = x[0]
    for i in range(1, len(x)):
        y[i] = y[i - 1] + a * (x[i] - y[i - 1])
    return y


def _orthonormal(cols: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the columns' span (rank-revealing, through the normal matrix's eigenvectors)."""
    norms = np.linalg.norm(cols, axis=0)
    a = cols[:, norms > 1e-12] / norms[norms > 1e-12]
    lam, v = np.linalg.eigh(a.T @ a)
    keep = lam > 1e-10 * lam.max()
    return a @ (v[:, keep] / np.sqrt(lam[keep]))


def _remainder(s: np.ndarray, q: np.ndarray) -> np.ndarray:
    """What is left of s (n,) or (n, k) after a least-squares fit of the orthonormal columns q."""
    return s - q @ (q.T @ s)


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def _bspline2(x: np.ndarray) -> np.ndarray:
    """The density of the sum of three unit uniform delays (a sinc^3 decimation filter's impulse response)."""
    return np.where(x < 1, x * x / 2, np.where(x < 2, (-2 * x * x + 6 * x - 3) / 2, (3 - x) ** 2 / 2))


_SINC_X = (np.arange(12) + 0.5) * 3.0 / 12
_SINC_W = _bspline2(_SINC_X) / _bspline2(_SINC_X).sum()
ROTOR_HZ = {"ship": (2.0, 5.0), "quad_hover": (60.0, 150.0), "car_circuit": (5.0, 15.0), "hand_dance": (30.0, 80.0),
            "tumble": (20.0, 100.0), "buoy": (2.0, 10.0)}


def _remembered(att, keep: int = 6):
    """``att``, remembering its last ``keep`` answers by the exact times asked (a record's readings, its effects'
    signatures and their scaling ask for the attitude at the same times many times over): the same arrays, computed
    once.  Each answer is a copy, as a fresh call's would be."""
    cache: dict[tuple, np.ndarray] = {}

    def at(tt: np.ndarray) -> np.ndarray:
        arr = np.asarray(tt)
        key = (arr.shape, arr.dtype.str, np.ascontiguousarray(arr).tobytes())
        if key not in cache:
            if len(cache) >= keep:
                del cache[next(iter(cache))]
            cache[key] = att(tt)
        return cache[key].copy()

    return at


# --------------------------------------------------------------------------------------- one record's physics
class _Record:
    """The field, the platform, the sensor and the effects of one record; readings at any times."""

    def __init__(self, rng: np.random.Generator, schedule: str, n: int):
        self.rng, self.schedule, self.fixed = rng, schedule, schedule == "fixed"
        self.fs, att, self.dur = SCHEDULE_FUNCTIONS[schedule](rng, n)
        self.att = _remembered(att)
        self.n = n
        self.F0 = rng.uniform(20000.0, 65000.0)
        self.inc = rng.choice([-1.0, 1.0]) * rng.uniform(5.0, 75.0) * DEG
        self.dec = rng.uniform(-30.0, 30.0) * DEG
        ci = np.cos(self.inc)
        self.B0 = self.F0 * np.array([ci * np.cos(self.dec), ci * np.sin(self.dec), -np.sin(self.inc)])  # x east-ish, z up
        u = np.eye(3) + rng.normal(0.0, 0.4 * DEG, (3, 3)) * (1.0 - np.eye(3))
        self.U = u / np.linalg.norm(u, axis=1, keepdims=True)  # rows: the axes' unit vectors in the body frame
        self.g = 1.0 + rng.normal(0.0, 0.02, 3)
        self.o = rng.normal(0.0, 300.0, 3)
        a = rng.normal(0.0, 0.01, (3, 3))
        self.S = np.eye(3) + (a + a.T) / 2.0  # the platform's constant soft iron
        self.h = rng.normal(0.0, 200.0, 3)  # and hard iron
        self.sigma = np.exp(rng.uniform(np.log(0.1), np.log(5.0))) * rng.uniform(0.8, 1.2, 3)
        self.lsb = float(self.sigma.mean() * rng.uniform(0.3, 2.0)) if rng.random() < 0.4 else 0.0
        self.ref_kind = str(rng.choice(["overhauser", "proton", "model"], p=[0.4, 0.35, 0.25]))
        self.rng_ref_sigma = rng.uniform(0.01, 0.1) if self.ref_kind == "overhauser" else rng.uniform(0.05, 0.5)
        self.nat_amp = 0.0
        self.nat_v = (_unit(rng), _unit(rng))
        self.nat_p, self.nat_ph = rng.uniform(0.5, 2.0) * self.dur, rng.uniform(0, 2 * np.pi)
        self.follow = 1.0
        self.mains_hz, self.alias_hz = 50.0, 0.0
        self.with_eddy = False
        self.follow_decided = False
        self.gain: dict[str, float] = {}
        self.par: dict[str, dict] = {}
        self.form: dict[str, str] = {}
        self.t = np.zeros(0)
        self.tgrid: np.ndarray | None = None
        self.T_board = self.T_core = np.zeros(0)
        self.T0 = 20.0
        m = np.diag(self.g) @ self.U @ self.S
        self.C = np.linalg.inv(m)  # the true calibration: B = C (raw - o_eff)
        self.o_eff = self.o + np.diag(self.g) @ self.U @ self.h

    # ---------------------------------------------------------------- noise
    def noise_vector(self) -> float:
        return float(np.sqrt(np.mean(self.sigma ** 2) + self.lsb ** 2 / 12.0))

    def ref_noise(self) -> tuple[float, float]:
        return {"overhauser": (self.rng_ref_sigma, 0.01), "proton": (self.rng_ref_sigma, 0.1),
                "model": (0.0, 0.1)}[self.ref_kind]

    def noise_scalar(self) -> float:
        s, res = self.ref_noise()
        return float(np.sqrt(self.noise_vector() ** 2 + s ** 2 + res ** 2 / 12.0))

    def noise(self) -> float:
        return self.noise_vector() if self.fixed else self.noise_scalar()

    # ---------------------------------------------------------------- temperature
    def make_temperature(self, strong: bool) -> None:
        rng, t = self.rng, self.t
        span = max(t[-1] - t[0], 1.0)
        grid = np.linspace(t[0] - 0.3 * span - 10.0, t[-1] + 10.0, 4000)
        dt = grid[1] - grid[0]
        x = grid - t[0]
        temp = np.full_like(grid, rng.uniform(-5.0, 35.0))
        if strong or rng.random() < 0.6:  # warm-up of the electronics / the enclosure
            temp += rng.uniform(1.0, 8.0) * (1.0 - np.exp(-np.clip(x, 0, None) / (rng.uniform(0.1, 0.6) * span)))
        if rng.random() < 0.6:  # HVAC / engine-room cycling
            temp += rng.uniform(0.3, 3.0) * np.sin(2 * np.pi * x / (rng.uniform(0.1, 0.5) * span) + rng.uniform(0, 6.3))
        if self.schedule == "tumble":  # sun and eclipse
            sq = np.sign(np.sin(2 * np.pi * x / (rng.uniform(0.2, 0.5) * span) + rng.uniform(0, 6.3)))
            temp += rng.uniform(2.0, 10.0) * _lowpass(sq, dt, 0.05 * span)
        if self.schedule == "fixed":  # the daily cycle
            temp += rng.uniform(1.0, 6.0) * np.sin(2 * np.pi * (grid / 86400.0 + rng.uniform(0, 1)))
        if self.schedule == "hand_dance":  # warmed by the hand
            temp += rng.uniform(0.5, 3.0) * (1.0 - np.exp(-np.clip(x, 0, None) / (0.3 * span)))
        wander = _lowpass(rng.normal(0.0, 1.0, len(grid)), dt, rng.uniform(0.02, 0.1) * span)
        temp += rng.uniform(0.05, 0.5) * wander / max(_rms(wander), 1e-12)
        inside = (grid >= t[0]) & (grid <= t[-1])
        ptp = np.ptp(temp[inside])
        if strong and ptp < 3.0:
            mid = temp[inside].mean()
            temp = mid + (temp - mid) * 3.0 / max(ptp, 1e-6)
        self.tgrid, self.T_board = grid, temp
        self.T_core = temp.copy()
        self.T0 = float(np.mean(np.interp(t, grid, temp)))
        self.log_sigma = rng.uniform(0.01, 0.08)
        self.log_res = float(rng.choice([0.0625, 0.01]))

    def set_thermal_lag(self, tau: float) -> None:
        assert self.tgrid is not None
        self.T_core = _lowpass(self.T_board, self.tgrid[1] - self.tgrid[0], tau)
        self.T0 = float(np.mean(np.interp(self.t, self.tgrid, self.T_core)))

    def t_core(self, tt: np.ndarray) -> np.ndarray:
        assert self.tgrid is not None
        return np.interp(tt, self.tgrid, self.T_core)

    def logged_temperature(self) -> np.ndarray:
        assert self.tgrid is not None
        raw = np.interp(self.t, self.tgrid, self.T_board) + self.rng.normal(0.0, self.log_sigma, len(self.t))
        return np.round(raw / self.log_res) * self.log_res

    # ---------------------------------------------------------------- the field and the platform
    def natural(self, tt: np.ndarray) -> np.ndarray:
        if self.nat_amp == 0.0:
            return np.zeros((len(tt), 3))
        a = np.sin(2 * np.pi * tt / self.nat_p + self.nat_ph)[:, None] * self.nat_v[0]
        b = ((tt - self.t[0]) / self.dur - 0.5)[:, None] * self.nat_v[1]
        return self.nat_amp * (a + b)

    def drift(self, tt: np.ndarray) -> np.ndarray:
        p = self.par["field_drift"]
        x = (tt - self.t[0]) / p["span"]
        f = self.form["field_drift"]
        if f == "bay":
            s = np.exp(-(((x - p["c"]) / p["w"]) ** 2))[:, None] * p["v1"]
        elif f == "pulsation":
            s = (np.sin(2 * np.pi * x * p["cycles"] + p["ph"]) * (0.7 + 0.3 * np.sin(np.pi * x)))[:, None] * p["v1"]
        elif f == "trend":
            s = (x - 0.5)[:, None] * p["v1"] + 0.5 * ((x - 0.5) ** 2)[:, None] * p["v2"]
        else:  # crustal anomalies under a ship's track
            s = sum(np.exp(-(((x - c) / w) ** 2))[:, None] * v for c, w, v in zip(p["cs"], p["ws"], p["vs"]))
        return s

    def world(self, tt: np.ndarray, on: frozenset, reference: bool = False) -> np.ndarray:
        b = self.B0 + self.natural(tt)
        if "field_drift" in on:
            b = b + (self.follow if reference else 1.0) * self.gain["field_drift"] * self.drift(tt)
        return b

    def f_true(self, tt: np.ndarray, on: frozenset) -> np.ndarray:
        return np.linalg.norm(self.world(tt, on, reference=True), axis=1)

    def rates(self, tt: np.ndarray) -> np.ndarray:
        """Body angular rates (rad/s) from the attitude function."""
        h = 1e-3
        w = np.transpose(self.att(tt - h), (0, 2, 1)) @ self.att(tt + h)
        return np.stack([w[:, 2, 1] - w[:, 1, 2], w[:, 0, 2] - w[:, 2, 0], w[:, 1, 0] - w[:, 0, 1]], 1) / (4 * h)

    def body(self, tt: np.ndarray, on: frozenset) -> tuple[np.ndarray, np.ndarray]:
        r = self.att(tt)
        bw = self.world(tt, on)
        if "boom_gradient" in on:  # the sensor at r @ arm from the pivot, in a gradient G (nT/m)
            p = self.par["boom_gradient"]
            bw = bw + self.gain["boom_gradient"] * (r @ p["arm"]) @ p["G"].T
        return np.einsum("nji,nj->ni", r, bw), r

    def disturbance(self, tt: np.ndarray, on: frozenset, bb: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Body-fixed fields of the platform's own sources (effects outside the library)."""
        d = np.zeros((len(tt), 3))
        for name in sorted(on):
            p, g = self.par.get(name), self.gain.get(name, 0.0)
            if name == "servo_current":
                up = r[:, 2, :]  # the world's up axis in the body frame
                w = self.rates(tt) @ p["n"]
                cur = up @ p["n"] + p["a2"] * np.tanh(w / p["w0"])
                d += g * cur[:, None] * p["v"]
            elif name == "rate_actuator":
                w = self.rates(tt) @ p["c"]
                d += g * (w + p["c2"] * w * np.abs(w) / p["wref"])[:, None] * p["v"]
            elif name == "rotor_magnet":
                phi = 2 * np.pi * p["f"] * tt + p["pm"] * np.sin(2 * np.pi * tt / p["pw"])
                d += g * (np.cos(phi)[:, None] * p["e1"] + np.sin(phi)[:, None] * p["e2"])
            elif name == "relay_load":
                s = np.zeros(len(tt))
                for k, tk in enumerate(p["times"]):
                    s += (1.0 if k % 2 == 0 else -1.0) / (1.0 + np.exp(-np.clip((tt - tk) / p["tau"], -50, 50)))
                d += g * s[:, None] * p["v"]
            elif name == "heater_pwm":
                frac = ((tt - p["t0"]) / p["P"]) % 1.0
                duty = p["d0"] + p["d1"] * np.sin(2 * np.pi * tt / p["pd"])
                s = (frac < duty) * (1.0 - np.exp(-frac * p["P"] / p["soft"]))
                d += g * s[:, None] * p["v"]
            elif name == "polarisation_pulses":
                frac = ((tt - p["t0"]) / p["P"]) % 1.0
                tau = p["tau"] / p["P"]
                s = np.where(frac < p["duty"], 1.0 - np.exp(-frac / tau), np.exp(-(frac - p["duty"]) / tau))
                d += g * s[:, None] * p["v"]
            elif name == "mains_alias":
                amp = np.cos(2 * np.pi * p["fm"] * tt + p["ph"]) * (1.0 + 0.3 * np.sin(2 * np.pi * tt / p["pl"]))
                d += g * amp[:, None] * p["v"]
            elif name == "hysteresis":
                d += g * np.interp(tt, self.t, p["m"])[:, None] * p["v"]
            elif name == "thermal_soft_iron":
                chi = np.exp(-(((self.t_core(tt) - p["tp"]) / p["w"]) ** 2))
                d += g * chi[:, None] * (bb @ p["S2"].T)
        return d

    def at_core(self, tt: np.ndarray, on: frozenset, eddy: bool = True) -> np.ndarray:
        bb, r = self.body(tt, on)
        bc = bb @ self.S.T + self.h + self.disturbance(tt, on, bb, r)
        if eddy and "eddy_housing" in on:  # b_e = -T int_0^inf exp(-s/tau) dB/dt(t - s) ds
            p, h = self.par["eddy_housing"], 1e-4
            acc = np.zeros_like(bc)
            for u, w in zip(_LAG_NODES, _LAG_WEIGHTS):
                ts = tt - p["tau"] * u
                acc += w * (self.at_core(ts + h, on, False) - self.at_core(ts - h, on, False)) / (2 * h)
            bc = bc - p["tau"] * acc @ (self.gain["eddy_housing"] * p["T"]).T
        return bc

    def axes(self, tt: np.ndarray, on: frozenset) -> np.ndarray:
        """Each axis's output before its electronics' filtering and sampling."""
        bc = self.at_core(tt, on)
        scale, off = np.broadcast_to(self.g, bc.shape), np.broadcast_to(self.o, bc.shape)
        if "temperature" in on:
            p, gt = self.par["temperature"], self.gain["temperature"]
            dT = self.t_core(tt) - self.T0
            u = self.U[None] + gt * dT[:, None, None] * p["E"][None]
            b = np.einsum("nij,nj->ni", u, bc)
            scale = self.g * (1.0 + gt * p["k"] * dT[:, None])
            off = self.o + gt * p["c"] * dT[:, None]
        else:
            b = bc @ self.U.T
        if "nonlinearity" in on:
            p, gn = self.par["nonlinearity"], self.gain["nonlinearity"]
            if self.form["nonlinearity"] == "poly":
                b = b + gn * X_FS * (p["e2"] * (b / X_FS) ** 2 + p["e3"] * (b / X_FS) ** 3)
            else:  # soft saturation of each core
                s = np.sqrt(gn)
                b = p["X"] / s * np.tanh(s * b / p["X"])
        if "cross_axis_nonlin" in on:
            p, gc = self.par["cross_axis_nonlin"], self.gain["cross_axis_nonlin"]
            b0 = b.copy()
            b = b.copy()
            for i, j, k in p["pairs"]:
                b[:, j] += gc * k * b0[:, i] * np.abs(b0[:, i]) / X_FS
        y = scale * b + off
        if "offset_drift" in on:
            y = y + self.gain["offset_drift"] * self.offset_shape(tt)
        return y

    def offset_shape(self, tt: np.ndarray) -> np.ndarray:
        p, f = self.par["offset_drift"], self.form["offset_drift"]
        x = np.clip((tt - self.t[0]) / p["span"], -0.5, None)
        if f == "log_creep":
            s = np.log1p(np.clip(x, 0, None) / p["tau"]) / np.log1p(1.0 / p["tau"])
            return s[:, None] * p["d"]
        if f == "viscous":
            return (1.0 - np.exp(-np.clip(x, 0, None) / p["tau"]))[:, None] * p["d"]
        return (x - 0.5)[:, None] * p["d"] + ((x - 0.5) ** 2)[:, None] * p["d2"]

    def electronics(self, tt: np.ndarray, on: frozenset) -> np.ndarray:
        if "lag" not in on:
            return self.axes(tt, on)
        p, gl, f = self.par["lag"], self.gain["lag"], self.form["lag"]
        y = np.empty((len(tt), 3))
        for i in range(3):
            if f == "mux":  # axis i converted p["skew"][i] after the time stamp
                y[:, i] = self.axes(tt + gl * p["skew"][i], on)[:, i]
            elif f == "rc":
                y[:, i] = sum(w * self.axes(tt - gl * p["tau"][i] * u, on)[:, i] for u, w in zip(_LAG_NODES, _LAG_WEIGHTS))
            else:  # sinc^3 decimation over 3 W_i
                y[:, i] = sum(w * self.axes(tt - gl * p["W"][i] * x, on)[:, i] for x, w in zip(_SINC_X, _SINC_W))
        return y

    def residual(self, raw: np.ndarray, fref: np.ndarray) -> np.ndarray:
        return np.linalg.norm((raw - self.o_eff) @ self.C.T, axis=1) - fref

    def signature(self, names: tuple[str, ...]) -> np.ndarray:
        """An effect's own contribution: to the scalar residual (a rotating sensor) or to the readings (fixed)."""
        key = tuple((x, self.gain[x], id(self.par[x])) for x in sorted(names))
        if key not in self.sig_cache:
            on = frozenset(names)
            raw = self.electronics(self.t, on)
            sig = raw - self.raw0 if self.fixed else self.residual(raw, self.f_true(self.t, on)) - self.res0
            self.sig_cache = {key: sig} | {k: v for k, v in list(self.sig_cache.items())[-8:]}
        return self.sig_cache[key]

    # ---------------------------------------------------------------- effects: shapes of a unit amplitude
    def add(self, name: str) -> None:
        """Draw an effect's physical shape (its amplitude is set later by ``scale_to``)."""
        rng, span, t = self.rng, max(self.t[-1] - self.t[0], 1.0), self.t
        bdir = self.B0 / self.F0
        start = {"nonlinearity": 1e-4, "eddy_housing": 0.05, "thermal_soft_iron": 1e-3, "cross_axis_nonlin": 1e-4}
        self.gain[name] = start.get(name, 1.0)

        def field_vector() -> np.ndarray:  # a field change with a good part along the field (seen by |B|)
            if self.fixed:
                return _unit(rng)
            u = _unit(rng)
            u -= (u @ bdir) * bdir
            v = rng.choice([-1.0, 1.0]) * bdir * rng.uniform(0.6, 1.0) + u / np.linalg.norm(u) * rng.uniform(0.0, 0.8)
            return v / np.linalg.norm(v)

        if name == "temperature":
            f = str(rng.choice(["offset_gain", "offset_gain_axes", "core_lag"]))
            e = rng.normal(0.0, 5e-6, (3, 3)) * (1.0 - np.eye(3)) if f != "offset_gain" else np.zeros((3, 3))
            self.par[name] = {"c": rng.normal(0.0, 1.0, 3), "k": rng.normal(0.0, 20e-6, 3), "E": e}
            self.par[name]["tau_th"] = rng.uniform(0.03, 0.15) * span if f == "core_lag" else 0.0
            self.set_thermal_lag(self.par[name]["tau_th"])
        elif name == "field_drift":
            forms = ["bay", "pulsation", "trend"] + (["anomaly"] if self.schedule == "ship" else [])
            f = str(rng.choice(forms))
            self.par[name] = {"span": span, "c": rng.uniform(0.3, 0.7), "w": rng.uniform(0.1, 0.3), "v1": field_vector(),
                              "v2": field_vector(), "cycles": rng.uniform(1.5, 4.0), "ph": rng.uniform(0, 2 * np.pi),
                              "cs": rng.uniform(0.1, 0.9, 3), "ws": rng.uniform(0.03, 0.1, 3),
                              "vs": [field_vector() for _ in range(3)]}
            if self.follow_decided:
                pass
            elif self.fixed:
                self.follow = float(rng.choice([0.0, rng.uniform(0.2, 0.7), 1.0]))
            else:  # a rotating sensor sees only the part of |B| that the reference does not follow
                self.follow = 0.0 if rng.random() < 0.4 else rng.uniform(0.2, 0.7)
            self.follow_decided = True
            if self.follow == 0.0:
                self.ref_kind = "model"
            elif self.ref_kind == "model":
                self.ref_kind = "overhauser"  # a remote station
            if self.ref_kind == "model":
                self.nat_amp = 0.0
        elif name == "offset_drift":
            f = str(rng.choice(["log_creep", "viscous", "ageing"]))
            d = _unit(rng)
            if self.fixed:  # mostly across the readings' direction (along it, a fixed sensor sees a field change)
                reading = np.mean(self.raw0 - self.o, axis=0)
                reading /= np.linalg.norm(reading)
                while abs(d @ reading) > 0.7:
                    d = _unit(rng)
            tau = rng.uniform(0.01, 0.3) if f == "log_creep" else rng.uniform(0.2, 1.0)
            self.par[name] = {"span": span, "tau": tau, "d": d, "d2": _unit(rng) * rng.uniform(0.0, 0.7)}
        elif name == "lag":
            f = "mux" if self.with_eddy else str(rng.choice(["mux", "rc", "sinc3"]))  # (nested filters: slow)
            w = np.ones(3)
            w[rng.integers(3)] = rng.uniform(1.5, 2.5)
            self.par[name] = {"skew": rng.permutation([0.0, 1.0, 2.0]) * 1e-3, "tau": rng.uniform(0.5, 1.5, 3) * 1e-3,
                              "W": w * 1e-3}
        elif name == "nonlinearity":
            f = str(rng.choice(["poly", "tanh"]))
            self.par[name] = {"e2": rng.normal(0.0, 1.0, 3), "e3": rng.normal(0.0, 1.0, 3),
                              "X": X_FS * rng.uniform(0.8, 1.25, 3)}
        elif name == "outliers":
            f = "bitflips" if self.lsb > 0 and rng.random() < 0.5 else "spikes"
            self.par[name] = {}
        elif name == "servo_current":
            f = "holding_and_friction"
            self.par[name] = {"n": _unit(rng), "v": _unit(rng), "a2": rng.uniform(0.3, 1.0), "w0": rng.uniform(0.05, 0.3)}
        elif name == "rate_actuator":
            f = "rate_current"
            c = np.array([0.0, 0.0, 1.0]) + 0.5 * _unit(rng)
            c /= np.linalg.norm(c)
            wref = _rms(self.rates(t) @ c) + 1e-3
            self.par[name] = {"c": c, "v": _unit(rng), "c2": rng.uniform(0.0, 1.0), "wref": wref}
        elif name == "rotor_magnet":
            f = "aliased_rotor"
            lo, hi = ROTOR_HZ[self.schedule]
            k = max(1, round(rng.uniform(lo, hi) / self.fs))
            fa = rng.uniform(max(20.0 / span, 0.002 * self.fs), self.fs / 10.0) * rng.choice([-1.0, 1.0])
            e1 = _unit(rng)
            e2 = np.cross(e1, _unit(rng))
            e2 /= np.linalg.norm(e2)
            self.par[name] = {"f": k * self.fs + fa, "alias_Hz": abs(fa), "e1": e1, "e2": e2,
                              "pm": rng.uniform(0.0, 0.5), "pw": rng.uniform(0.2, 0.5) * span}
        elif name == "relay_load":
            f = "relay"
            ntr = int(rng.integers(2, 6))
            while True:
                times = np.sort(rng.uniform(0.05, 0.95, ntr))
                if np.all(np.diff(times) > 0.05):
                    break
            self.par[name] = {"times": t[0] + times * span, "tau": rng.uniform(0.05, 2.0), "v": _unit(rng)}
        elif name == "heater_pwm":
            f = "thermostat"
            period = min(rng.uniform(20.0, 200.0), span / 10.0)
            self.par[name] = {"P": period, "t0": rng.uniform(0, period), "d0": rng.uniform(0.3, 0.7),
                              "d1": rng.uniform(0.0, 0.2), "pd": rng.uniform(0.5, 2.0) * span,
                              "soft": min(0.5, 0.05 * period), "v": _unit(rng)}
        elif name == "polarisation_pulses":
            f = "proton_polarisation"
            period = max(rng.uniform(1.0, 6.0), 3.0 / self.fs)
            self.par[name] = {"P": period, "t0": rng.uniform(0, period), "duty": rng.uniform(0.25, 0.5),
                              "tau": 0.02 * period, "v": _unit(rng)}
        elif name == "mains_alias":
            f = "wiring_hum"
            self.par[name] = {"fm": self.mains_hz, "ph": rng.uniform(0, 2 * np.pi), "pl": rng.uniform(0.2, 1.0) * span,
                              "v": _unit(rng), "alias_Hz": self.alias_hz}
        elif name == "hysteresis":
            f = "play_operator"
            a = _unit(rng)
            hfield = self.body(t, frozenset())[0] @ a
            r = rng.uniform(0.05, 0.3) * np.ptp(hfield)
            y, state = np.empty_like(hfield), hfield[0]
            for i, x in enumerate(hfield):
                state = min(max(state, x - r), x + r)
                y[i] = state
            self.par[name] = {"a": a, "v": _unit(rng), "m": (y - y.mean()) / max(np.ptp(hfield), 1.0), "width_nT": r}
        elif name == "thermal_soft_iron":
            f = "hopkinson_peak"
            tc = self.t_core(t)
            lo, hi = tc.min(), tc.max()
            s2 = rng.normal(0.0, 1.0, (3, 3))
            s2 = s2 + s2.T
            self.par[name] = {"S2": s2 / np.linalg.norm(s2), "tp": lo + rng.uniform(0.3, 0.7) * (hi - lo),
                              "w": rng.uniform(0.15, 0.35) * (hi - lo)}
        elif name == "boom_gradient":
            f = "lever_arm"
            g = rng.normal(0.0, 1.0, (3, 3))
            g = g + g.T
            g -= np.trace(g) / 3.0 * np.eye(3)  # curl- and divergence-free
            self.par[name] = {"G": g / np.linalg.norm(g), "arm": _unit(rng) * rng.uniform(0.2, 1.0)}
        elif name == "eddy_housing":
            f = "tilted_housing"
            q = _expmap((_unit(rng) * rng.uniform(25.0, 65.0) * DEG)[None])[0]
            a = rng.uniform(0.1, 0.5)
            self.par[name] = {"T": q @ np.diag([1.0, a, a]) @ q.T, "tau": rng.uniform(2e-3, 30e-3), "tilt_axis": q[:, 0]}
        elif name == "cross_axis_nonlin":
            f = "feedback_crosstalk"
            pairs = []
            for _ in range(2):
                i, j = rng.choice(3, 2, replace=False)
                pairs.append((int(i), int(j), float(rng.normal(0.0, 1.0))))
            self.par[name] = {"pairs": pairs}
        else:
            raise ValueError(name)
        self.form[name] = f

    # ---------------------------------------------------------------- what a perfect analyst could see
    def prepare(self, temp_log: np.ndarray | None) -> None:
        """The noise-free readings without any effect, and the linearised bases of the calibration and of each
        library effect's model (what a perfect analyst would fit)."""
        t, n = self.t, len(self.t)
        empty: frozenset = frozenset()
        self.raw0 = self.electronics(t, empty)
        self.f0 = self.f_true(t, empty)
        self.res0 = self.residual(self.raw0, self.f0)
        span = max(t[-1] - t[0], 1.0)
        tl = None if temp_log is None else temp_log - temp_log.mean()
        dtm = float(np.median(np.diff(t)))
        tf = None if tl is None else np.stack([_lowpass(tl, dtm, tau) for tau in (0.0, span / 20, span / 5)], 1)
        fam: dict[str, np.ndarray] = {}
        if self.fixed:
            self.cal = np.ones((n, 1))
            fam["offset_drift"] = fam["field_drift"] = _legendre(t, range(1, 5))
            if tf is not None:
                fam["temperature"] = tf
            self.orthonormalise(fam)
            return
        bh = (self.raw0 - self.o_eff) @ self.C.T
        b = bh / np.linalg.norm(bh, axis=1, keepdims=True)
        m = b @ self.C  # d|B|/d raw_i
        self.sens = m
        quad = np.stack([b[:, i] * b[:, j] for i in range(3) for j in range(i, 3)], 1)
        self.cal = np.hstack([quad, b])
        fam["field_drift"] = _legendre(t, range(1, 7))
        p = _legendre(t, range(1, 5))
        fam["offset_drift"] = (m[:, :, None] * p[:, None, :]).reshape(n, -1)
        h = 1e-3
        db = ((self.electronics(t + h, empty) - self.electronics(t - h, empty)) @ self.C.T) / (2 * h)
        fam["lag"] = b * db
        x = (self.raw0 - self.o_eff) / self.F0
        fam["nonlinearity"] = np.hstack([m * x ** 2, m * x ** 3, m * x ** 5])
        if tl is not None and tf is not None:
            fam["temperature"] = np.hstack([(m[:, :, None] * tf[:, None, :]).reshape(n, -1), quad * tl[:, None]])
        self.orthonormalise(fam)

    def orthonormalise(self, fam: dict[str, np.ndarray]) -> None:
        self.fam = fam
        self.q_cal = _orthonormal(self.cal)
        self.q_with = {y: _orthonormal(np.hstack([self.cal, cols])) for y, cols in fam.items()}
        self.q_union = _orthonormal(np.hstack([self.cal] + list(fam.values())))
        self.sig_cache: dict[tuple, np.ndarray] = {}

    def size(self, s: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.sum(s * s, axis=1)))) if s.ndim == 2 else _rms(s)

    def visible(self, name: str) -> float:
        """RMS of an effect after a perfect calibration fit (a fixed sensor: of its readings about their mean)."""
        return self.size(_remainder(self.signature((name,)), self.q_cal))

    def beyond_library(self, name: str) -> float:
        """RMS of an effect after the calibration and every library effect's model together."""
        return self.size(_remainder(self.signature((name,)), self.q_union))

    def implausible(self, name: str) -> str:
        """Why the effect's size, as scaled, is not physically plausible ('' when it is).  Every effect must move
        the readings by at most 1 % of the field (RMS about its mean); a delay must stay within half a sample
        period (and 0.5 s), an eddy-current time constant within 50 ms, a core's saturation field above twice
        the field."""
        g, p, f = self.gain[name], self.par[name], self.form[name]
        if name == "lag":
            key = {"mux": "skew", "rc": "tau", "sinc3": "W"}[f]
            delay = g * float(np.max(p[key])) * (1.5 if f == "sinc3" else 1.0)
            if delay > min(0.5, 0.5 / self.fs):
                return f"delay {delay:.3g} s"
        if name == "temperature" and (g * np.max(np.abs(p["c"])) > 30.0 or g * np.max(np.abs(p["k"])) > 300e-6):
            return "temperature coefficient"  # above 30 nT/degC or 300 ppm/degC
        if name == "eddy_housing" and g * p["tau"] > 0.05:
            return "eddy time constant"
        if name == "nonlinearity" and f == "tanh" and g > (float(np.min(p["X"])) / (2 * self.F0)) ** 2:
            return "saturation field"
        if name == "outliers":
            return ""
        change = self.electronics(self.t, frozenset([name])) - self.raw0
        size = self.size(change - change.mean(axis=0))
        return f"reading change {size:.0f} nT" if size > 0.01 * self.F0 else ""

    def scale_to(self, name: str, target: float, metric) -> float:
        v = metric(name)
        for _ in range(4):
            if not np.isfinite(v) or v <= 0:
                raise RuntimeError(f"{name}: no visible contribution")
            if abs(v / target - 1.0) < 0.03:
                break
            self.gain[name] *= target / v
            v = metric(name)
        return v

    def confoundable(self, present: tuple[str, ...], noise: float) -> set[tuple[str, str]]:
        pairs: set[tuple[str, str]] = set()
        for x in present:
            if x == "outliers":
                continue
            s = self.signature((x,))
            vis = self.size(_remainder(s, self.q_cal))
            threshold = max(VISIBLE * noise, 0.3 * vis)
            if self.fixed and x in ("offset_drift", "field_drift"):
                pairs.add(("field_drift", "offset_drift"))  # a field that turns and offsets that drift move alike
            for y, q in self.q_with.items():
                if y == x or (self.fixed and {x, y} == {"offset_drift", "field_drift"}):
                    continue
                if self.size(_remainder(s, q)) < threshold:
                    pairs.add(tuple(sorted((x, y))))  # type: ignore[arg-type]
                    if self.fixed and y in ("offset_drift", "field_drift"):
                        pairs.add(tuple(sorted((x, "field_drift" if y == "offset_drift" else "offset_drift"))))  # type: ignore[arg-type]
        return pairs

    def add_outliers(self, raw: np.ndarray, noise: float) -> tuple[np.ndarray, float]:
        rng, n = self.rng, len(raw)
        count = max(5, int(n * rng.uniform(0.002, 0.015)))
        cand = np.sort(rng.choice(np.arange(3, n - 3), size=min(n - 6, 3 * count), replace=False))
        idx: list[int] = []
        for c in cand:
            if not idx or c - idx[-1] >= 4:
                idx.append(int(c))
        idx = sorted(rng.choice(idx, size=min(count, len(idx)), replace=False).tolist())
        raw = raw.copy()
        impacts = []
        for i in idx:
            if self.fixed:
                axis, sens = int(rng.integers(3)), 1.0
            else:
                axis = int(np.argmax(np.abs(self.sens[i])))
                sens = float(abs(self.sens[i, axis]))
            if self.form["outliers"] == "bitflips":
                word = int(round(raw[i, axis] / self.lsb))
                k = int(np.ceil(np.log2(12.0 * noise / (sens * self.lsb)))) + int(rng.integers(0, 3))
                k = max(k, 0)
                word = word - (1 << k) if (word >> k) & 1 else word + (1 << k)
                new = word * self.lsb
            else:
                new = raw[i, axis] + rng.choice([-1.0, 1.0]) * rng.uniform(12.0, 60.0) * noise / sens
            impacts.append(abs(new - raw[i, axis]) * sens / noise)
            raw[i, axis] = new
        self.par["outliers"].update(count=len(idx), rows=idx)
        return raw, float(min(impacts))


# --------------------------------------------------------------------------------------- the cases
def _choose(index: int, rng: np.random.Generator) -> tuple[str, tuple[str, ...], tuple[str, ...], str]:
    block, pos = divmod(index, len(PATTERN))
    category = PATTERN[pos]
    slot = PATTERN[:pos].count(category)  # its occurrence within the block
    present: tuple[str, ...] = ()
    outside: tuple[str, ...] = ()
    if category == "single":
        present = (LIBRARY[(slot + block) % len(LIBRARY)],)
    elif category in ("pair", "triple"):
        present = tuple(str(x) for x in rng.choice(LIBRARY, 2 if category == "pair" else 3, replace=False))
    elif category == "outside":
        outside = (OUTSIDE[(6 * block + slot) % len(OUTSIDE)],)
    elif category == "outside_plus":
        outside = (OUTSIDE[int(rng.integers(len(OUTSIDE)))],)
        present = (LIBRARY[int(rng.integers(len(LIBRARY)))],)
    elif category == "fixed":
        present = (FIXED_EFFECTS[(2 * block + slot) % len(FIXED_EFFECTS)],)
    schedule = "fixed" if category == "fixed" else SCHEDULES[int(rng.integers(len(SCHEDULES)))]
    if "eddy_housing" in outside and schedule not in FAST:  # eddy fields of a plausible size need fast rotation
        schedule = FAST[int(rng.integers(len(FAST)))]
    return category, present, outside, schedule


def make_case(index: int, root: int = 2026) -> Case:
    """Blind case ``index``: its readings and its truth (deterministic in index and root)."""
    rng = np.random.default_rng([root, index, 3])
    category, present, outside, schedule = _choose(index, rng)
    if category == "too_short":
        return _too_short(index, rng, schedule)
    for _ in range(8):
        case = _build(index, rng, category, present, outside, schedule)
        if case is not None:
            return case
        if schedule != "fixed":  # the effects could not be made visible at a plausible size: another platform
            choices = FAST if "eddy_housing" in outside else SCHEDULES
            schedule = choices[int(rng.integers(len(choices)))]
    raise RuntimeError(f"case {index}: no plausible record")


def _build(index: int, rng: np.random.Generator, category: str, present: tuple[str, ...], outside: tuple[str, ...],
           schedule: str) -> Case | None:
    n = int(np.exp(rng.uniform(np.log(300), np.log(20000)))) if schedule != "fixed" else int(rng.integers(300, 12000))
    rec = _Record(rng, schedule, n)
    if "mains_alias" in outside:  # a sample rate just off a sub-multiple of the mains: a slow beat
        rec.mains_hz = float(rng.choice([50.0, 60.0]))
        fs0 = min(rec.fs, 40.0)
        k = max(1, round(rec.mains_hz / fs0))
        rec.alias_hz = rng.uniform(max(25.0 / (n / fs0), 0.002 * fs0), fs0 / 10.0)
        rec.fs = (rec.mains_hz - rec.alias_hz) / k
    coherent = bool({"mains_alias", "rotor_magnet"} & set(outside))
    sampling = str(rng.choice(["regular", "dropouts"] if coherent else ["regular", "jittered", "dropouts"]))
    rec.t = _times(rng, rec.fs, n, sampling)
    rec.dur = float(rec.t[-1] - rec.t[0])
    if rec.ref_kind != "model" and not rec.fixed:
        rec.nat_amp = rng.uniform(0.0, 15.0)  # the field's natural variation, which a co-located reference follows
    needs_temp = "temperature" in present or "thermal_soft_iron" in outside
    logged = needs_temp or rng.random() < (0.5 if rec.fixed else 0.4)
    if logged:
        rec.make_temperature(strong=needs_temp)
    rec.raw0 = rec.electronics(rec.t, frozenset())  # (used to orient a fixed sensor's offset drift)
    rec.with_eddy = "eddy_housing" in outside
    if "field_drift" in present:  # decides the reference (a model value has no natural variation to follow)
        rec.add("field_drift")
        rec.raw0 = rec.electronics(rec.t, frozenset())
    temp_log = rec.logged_temperature() if logged else None
    rec.prepare(temp_log)
    noise = rec.noise()
    visible: dict[str, float] = {}
    physical: dict[str, float] = {}
    for name in present:
        rec.add(name)
        if name == "outliers":
            continue
        target = np.exp(rng.uniform(np.log(4.0), np.log(20.0))) * noise
        for attempt in range(3):
            if attempt:
                rec.add(name)  # another shape: this one needed an implausible size to be seen
            visible[name] = rec.scale_to(name, target, rec.visible) / noise
            if not rec.implausible(name):
                break
        else:
            return None
    remainder: dict[str, float] = {}
    for name in outside:
        target = np.exp(rng.uniform(np.log(4.0), np.log(15.0))) * noise
        for _ in range(4):
            rec.add(name)
            rem = rec.scale_to(name, target, rec.beyond_library)
            tot = rec.visible(name)
            # a shape mostly explained by library effects, or needing an implausible size, is drawn again
            if tot / rem <= 10.0 and not rec.implausible(name):
                break
        else:
            return None
        remainder[name], visible[name] = rem / noise, tot / noise
    confound = sorted(rec.confoundable(present, noise))
    on = frozenset(present + outside)
    raw = rec.electronics(rec.t, on) + rng.normal(0.0, 1.0, (len(rec.t), 3)) * rec.sigma
    if rec.lsb:
        raw = np.round(raw / rec.lsb) * rec.lsb
    if "outliers" in present:
        raw, visible["outliers"] = rec.add_outliers(raw, noise)
    ref_sigma, ref_res = rec.ref_noise()
    fref = rec.f_true(rec.t, on) + rng.normal(0.0, 1.0, len(rec.t)) * ref_sigma
    fref = np.round(fref / ref_res) * ref_res
    gravity = None
    if rng.random() < (0.5 if schedule in ("quad_hover", "car_circuit", "hand_dance") else 0.25):
        gravity = rec.att(rec.t)[:, 2, :] * 9.80665 + rng.normal(0.0, 0.02, (len(rec.t), 3))
    for name in present + outside:
        physical[name] = float(rec.gain[name])
    acceptable = tuple(dict.fromkeys(present + tuple(a for o in outside for a in ACCEPTABLE_FOR.get(o, ()))))
    notes = {"generator": 3, "n": len(rec.t), "fs_Hz": rec.fs, "sampling": sampling, "duration_s": rec.dur,
             "field_nT": rec.F0, "inclination_deg": rec.inc / DEG, "reference": rec.ref_kind,
             "reference_follows_drift": rec.follow if "field_drift" in present else None,
             "noise_nT": noise, "sigma_nT": rec.sigma.tolist(), "lsb_nT": rec.lsb,
             "true_C": rec.C.tolist(), "true_offset_nT": rec.o_eff.tolist(),
             "forms": dict(rec.form), "amplitude": physical, "visible_sigma": visible, "beyond_library_sigma": remainder,
             "temperature_logged": logged, "gravity": gravity is not None}
    if "outliers" in present:
        notes["outlier_rows"] = list(rec.par["outliers"]["rows"])
    if "lag" in present:
        p, g = rec.par["lag"], rec.gain["lag"]
        key = {"mux": "skew", "rc": "tau", "sinc3": "W"}[rec.form["lag"]]
        notes["lag_s"] = (g * np.asarray(p[key])).tolist()
    return Case(index=index, category=category, raw_nT=raw, f_ref_nT=fref, t_s=rec.t.copy(), temp_C=temp_log,
                gravity=gravity, present=present, outside=outside, acceptable=acceptable,
                expect_unexplained=bool(outside), confoundable=tuple(confound), schedule=schedule, notes=notes)


def _too_short(index: int, rng: np.random.Generator, schedule: str) -> Case:
    """A handful of readings: fewer than the nine calibration parameters need."""
    rec = _Record(rng, schedule, 2000)
    k = int(rng.integers(3, 10))
    rec.t = np.sort(rng.uniform(0.0, rec.dur, k))
    if rec.ref_kind != "model":
        rec.nat_amp = rng.uniform(0.0, 15.0)
    raw = rec.electronics(rec.t, frozenset()) + rng.normal(0.0, 1.0, (k, 3)) * rec.sigma
    if rec.lsb:
        raw = np.round(raw / rec.lsb) * rec.lsb
    ref_sigma, ref_res = rec.ref_noise()
    fref = np.round((rec.f_true(rec.t, frozenset()) + rng.normal(0.0, 1.0, k) * ref_sigma) / ref_res) * ref_res
    notes = {"generator": 3, "n": k, "noise_nT": rec.noise(), "true_C": rec.C.tolist(),
             "true_offset_nT": rec.o_eff.tolist(), "reference": rec.ref_kind}
    return Case(index=index, category="too_short", raw_nT=raw, f_ref_nT=fref, t_s=rec.t.copy(), temp_C=None,
                gravity=None, present=(), outside=(), acceptable=(), expect_unexplained=False, confoundable=(),
                schedule=schedule, notes=notes)

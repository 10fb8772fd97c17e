"""A second independent forward model of a three-axis magnetometer, for an honest HELD-OUT estimate of the
diagnosis (never for tuning it).  It imports numpy only and, from tests/independent_forward.py, nothing but the
``Case`` record (so that tests/independent_scoring.py scores its cases unchanged).  Its physics is written
separately: other attitude schedules, other sampling, other noise, other sensor error sizes and other
parametrisations of every effect, inside and outside the diagnosis's library.

Sensor (docs/CONTRACT.md section 1): ``raw = K P^-1 (I + S) B_body + o + noise``; P the adaptive-GA paper's
lower-triangular matrix, K the scales, o the offsets, S a small symmetric soft iron of the platform (a linear
soft iron keeps the record an ellipsoid, so it is part of the static model).  The world frame is
north-east-down; the field is ``F(t) * b_world`` with F(t) the reference magnitude: constant, or a slowly
varying observatory reference that the ambient field follows exactly (only a *local* change the reference
does not see is a ``field_drift``).

Sizes: every effect is scaled so that its *visible* part -- the change it makes to the corrected field
magnitude, with everything a static nine-parameter ellipsoid could absorb projected out to first order
(the span of u_i u_j and u_i, u the unit field direction in the body frame) -- has an RMS of ``snr`` times the
white noise, snr drawn in 8..20 for each effect.  For a fixed sensor (one attitude) the visible part is the
change of the corrected vector about its mean instead (a change across the field moves the vector readings but
hardly the magnitude).  Outliers are sized per bad sample instead.  An effect whose
physically bounded parameter cannot reach half of that size is not counted as present (it stays acceptable,
and is listed in ``notes["too_small"]``).

Schedules: ``figure_eight`` (a vehicle flying a lemniscate, banking with its turn rate), ``handheld`` (a wave
of the hand: a slow random rotation with a physiological tremor on top), ``pendulum`` (a re-kicked damped
pendulum whose swing plane precesses and whose string twists), ``platform_survey`` (a turntable stepping
through headings with irregular pauses, at a few tilts), ``gimbal`` (three slow gimbal axes at incommensurate
rates), ``fixed`` (one attitude, hours long).  Sampling: jittered, bursty, regular with dropped stretches, or
Poisson; 300..2000 rows (8..13 for too_short).  Noise: white (per-axis level), plus in some records a flicker
(1/f) component and an ADC quantisation; clean records may carry a logger that repeats values.
The logged temperature is a 1/16-degree thermometer that lags the sensor's true temperature a little; the
true temperature is a warm-up, a (possibly compressed) day cycle, a bang-bang heater, or weather.

Library effects (own parametrisations): temperature -- offset, scale (common and per axis) and/or alignment
angles linear in the TRUE temperature; field_drift -- a world-frame geomagnetic variation (diurnal, storm bay,
pulsation, ramp) the reference does not follow; offset_drift -- electronics zero drifting linearly or as a
random walk; nonlinearity -- per-axis quadratic, cubic or tanh soft saturation of the sensed field;
outliers -- isolated spikes, EMI bursts of 2-4 samples, single-axis ADC bit flips; lag -- a multiplexed
converter's axis skew, one channel's boxcar FIR, or first-order filters on one or two channels.

Outside effects (each resembling some library effect): battery_load (a current loop's field following a
stepped, bursty load), motor_stray (winding current ~ speed^2 plus the rotor magnet's aliased rotation),
sagging_soft_iron (a hanging steel part magnetised by the field along its gravity-following axis),
mount_flex (alignment angles bending with the gravity components), range_clip (a channel's converter
rails), slew_limit (the feedback loop's maximum rate), gain_switch (one range switch: gain and zero jump),
vibration_alias (a mast vibrating in a field gradient, aliased by the sampling), remanence (perming during a
pause: an offset jump then a logarithmic viscous decay), heater_pwm (a PWM heater's loop current sampled at
random phases), telegraph_noise (popcorn noise: one channel's zero flipping between two levels),
thermal_gradient (offsets following the RATE of temperature), eddy_housing (a conducting can's per-axis
high-pass lag), passing_object (a moving dipole in the world frame: physically a field drift, counted so).
"""
# ruff: noqa: B023  (the size-fitting lambdas are called at once, inside the loop turn that made them)
from __future__ import annotations

import numpy as np
from independent_forward import Case  # the record type only: the scorer accepts it

LIBRARY = ("temperature", "field_drift", "offset_drift", "nonlinearity", "outliers", "lag")
OUTSIDE = ("battery_load", "motor_stray", "sagging_soft_iron", "mount_flex", "range_clip", "slew_limit",
           "gain_switch", "vibration_alias", "remanence", "heater_pwm", "telegraph_noise", "thermal_gradient",
           "eddy_housing", "passing_object")
# outside effects of which a library name is physically right (naming it is not wrong)
ACCEPTABLE_FOR = {"remanence": ("offset_drift",),        # the offset does drift after the jump (magnetic viscosity)
                  "thermal_gradient": ("temperature",),  # a thermal effect, on the temperature's rate
                  "eddy_housing": ("lag",),              # its first-order part is a per-axis delay
                  "passing_object": ("field_drift",)}    # an ambient field change the reference does not follow
# outside effects that ARE that library effect (to first order, the record cannot tell): counted as present
BECOMES = {"passing_object": "field_drift"}
SCHEDULES = ("figure_eight", "handheld", "pendulum", "platform_survey", "gimbal")
CATEGORIES = ("clean", "single", "single", "pair", "outside", "outside", "outside_plus", "triple", "too_short",
              "fixed", "single", "outside")  # the first generator's mix and order, so that tables compare
FIXED_POOL = ("temperature", "field_drift", "offset_drift", "outliers")
PLUS_POOL = tuple(e for e in OUTSIDE if e not in BECOMES)
TWO_PI = 2.0 * np.pi


def plan(index: int, root: int = 2027) -> tuple[str, str, list[str]]:
    """(category, schedule, effects chosen) of a case, from its own random stream (cheap: no physics)."""
    rng = np.random.default_rng(np.random.SeedSequence([root, index, 1]))
    category = CATEGORIES[index % len(CATEGORIES)]

    def pick(pool, m):
        return [str(x) for x in rng.choice(pool, size=m, replace=False)]

    chosen: list[str] = []
    if category == "single":
        chosen = pick(LIBRARY, 1)
    elif category == "pair":
        chosen = pick(LIBRARY, 2)
    elif category == "triple":
        chosen = pick(LIBRARY, 3)
    elif category == "fixed":
        chosen = pick(FIXED_POOL, 1)
    elif category == "outside":
        chosen = pick(OUTSIDE, 1)
    elif category == "outside_plus":
        chosen = pick(PLUS_POOL, 1) + pick(LIBRARY, 1)
    kind = "fixed" if category == "fixed" else str(rng.choice(SCHEDULES))
    return category, kind, chosen


# ------------------------------------------------------------------------------------------ geometry
def _axis_rot(axis: int, a) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a), np.sin(a)
    out = np.zeros(a.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out[..., axis, axis] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., i, j] = -s
    out[..., j, i] = s
    return out


def _expmap(v) -> np.ndarray:
    """Rotation matrices from rotation vectors (Rodrigues), shape (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    th = np.linalg.norm(v, axis=-1)[..., None, None]
    k = np.zeros(v.shape + (3,))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    safe = np.where(th < 1e-12, 1.0, th)
    a = np.where(th < 1e-12, 1.0, np.sin(safe) / safe)
    b = np.where(th < 1e-12, 0.5, (1 - np.cos(safe)) / safe ** 2)
    return np.eye(3) + a * k + b * (k @ k)


def _unit(x: np.ndarray) -> np.ndarray:
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def _paper_p(a, b, g) -> np.ndarray:
    a, b, g = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float), np.asarray(g, float))
    p = np.zeros(a.shape + (3, 3))
    p[..., 0, 0] = np.cos(a) * np.cos(g)
    p[..., 1, 0] = np.sin(g)
    p[..., 1, 1] = np.cos(b)
    p[..., 2, 0] = np.sin(a) * np.cos(g)
    p[..., 2, 1] = np.sin(b)
    p[..., 2, 2] = 1.0
    return p


def _smooth(x: np.ndarray, rng, terms: int, f_lo: float, f_hi: float) -> np.ndarray:
    """A smooth random signal of unit RMS: sinusoids of random frequency (cycles per unit of x), reddened."""
    f = rng.uniform(f_lo, f_hi, terms)
    amp = rng.normal(0, 1, terms) * (f_lo / f)
    y = (amp * np.sin(TWO_PI * f * x[:, None] + rng.uniform(0, TWO_PI, terms))).sum(axis=1)
    y = y - y.mean()
    return y / (np.sqrt(np.mean(y ** 2)) + 1e-300)


def _interp(tf: np.ndarray, x: np.ndarray, t: np.ndarray) -> np.ndarray:
    if x.ndim == 1:
        return np.interp(t, tf, x)
    return np.stack([np.interp(t, tf, x[:, j]) for j in range(x.shape[1])], axis=1)


def _lowpass(x: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """First-order causal low-pass (time constant tau) on a regular grid, started in equilibrium; via FFT."""
    x2 = x if x.ndim == 2 else x[:, None]
    m = len(x2)
    if tau < 0.05 * dt:
        return x.copy()
    length = int(min(4 * m, np.ceil(12 * tau / dt) + 1))
    ker = np.exp(-np.arange(length) * dt / tau)
    ker /= ker.sum()
    pad = np.vstack([np.repeat(x2[:1], length - 1, axis=0), x2])
    nfft = 1 << int(np.ceil(np.log2(len(pad) + length)))
    y = np.fft.irfft(np.fft.rfft(pad, nfft, axis=0) * np.fft.rfft(ker, nfft)[:, None], nfft, axis=0)
    y = y[length - 1:length - 1 + m]
    return y if x.ndim == 2 else y[:, 0]


# ------------------------------------------------------------------------------------------ schedules
def _schedule(kind: str, rng) -> tuple[float, np.ndarray, np.ndarray]:
    """(duration s, fine time grid, body-to-world rotations on it)."""
    mount = _expmap(rng.normal(0, 1, 3) * rng.uniform(0, np.pi) / np.sqrt(3))
    if kind == "fixed":
        dur = float(rng.uniform(1, 20) * 3600)
        tf = np.linspace(0, dur, 2000)
        rot = np.broadcast_to(_expmap(rng.normal(0, 1.5, 3)), (len(tf), 3, 3)).copy()
        return dur, tf, rot
    nf = 16000
    if kind == "figure_eight":  # lemniscate track, coordinated turns, gentle climbs and dives
        dur = float(rng.uniform(300, 1800))
        tf = np.linspace(0, dur, nf)
        u = tf / dur
        loops = rng.uniform(3, 8)
        s = TWO_PI * loops * u + 0.3 * _smooth(u, rng, 4, 0.5, 2.0)  # speed varies a little
        heading = np.unwrap(np.arctan2(np.cos(2 * s), np.cos(s))) + rng.uniform(0, TWO_PI)
        rate = np.gradient(heading, tf)
        bank = np.radians(rng.uniform(15, 50)) * rate / np.max(np.abs(rate))
        pitch = np.radians(rng.uniform(3, 15)) * np.sin(TWO_PI * rng.uniform(2, 6) * u + rng.uniform(0, TWO_PI))
        rot = _axis_rot(2, heading) @ _axis_rot(1, pitch) @ _axis_rot(0, bank) @ _expmap(rng.normal(0, 0.05, 3))
        return dur, tf, rot
    if kind == "handheld":  # a hand waving the sensor about, with tremor (8-12 Hz) and small jerks
        dur = float(rng.uniform(40, 180))
        tf = np.linspace(0, dur, nf)
        slow = np.stack([_smooth(tf, rng, 6, 0.03, rng.uniform(0.15, 0.4)) for _ in range(3)], 1)
        slow *= rng.uniform(1.5, 3.0)
        tremor = np.stack([_smooth(tf, rng, 5, 8.0, 12.0) for _ in range(3)], 1) * rng.uniform(0.005, 0.03)
        return dur, tf, _expmap(slow) @ _expmap(tremor) @ mount
    if kind == "pendulum":  # re-kicked damped swing, precessing swing plane, twisting string
        dur = float(rng.uniform(120, 900))
        tf = np.linspace(0, dur, nf)
        omega = np.sqrt(9.81 / rng.uniform(0.4, 3.0))
        kicks = np.sort(np.concatenate([[0.0], rng.uniform(0, dur, int(rng.integers(1, 6)))]))
        amps = np.radians(rng.uniform(25, 70, len(kicks)))
        j = np.searchsorted(kicks, tf, side="right") - 1
        since = tf - kicks[j]
        theta = amps[j] * np.exp(-since / rng.uniform(30, 200)) * np.cos(omega * since)
        az = rng.uniform(0, TWO_PI) + rng.uniform(-1, 1) * 0.02 * tf
        twist = rng.uniform(1, 4) * np.sin(TWO_PI * tf / rng.uniform(20, 60)) + rng.uniform(-0.05, 0.05) * tf
        rot = _axis_rot(2, az) @ _axis_rot(0, theta) @ _axis_rot(2, -az) @ _axis_rot(2, twist) @ mount
        return dur, tf, rot
    if kind == "platform_survey":  # turntable: heading steps with irregular pauses, at a few tilts
        dur = float(rng.uniform(0.5, 4) * 3600)
        tf = np.linspace(0, dur, nf)
        m = int(rng.choice([6, 8, 12, 16]))
        tilts = np.radians(rng.choice(np.arange(-75, 91, 15), size=int(rng.integers(3, 6)), replace=False))
        heads = np.concatenate([(np.arange(m) * TWO_PI / m + rng.uniform(0, TWO_PI)) for _ in tilts])
        tilt_seq = np.repeat(tilts, m)
        w = rng.exponential(1.0, len(heads)) + 0.5
        edges = np.concatenate([[0], np.cumsum(w) / w.sum() * dur])
        k = np.clip(np.searchsorted(edges, tf, side="right") - 1, 0, len(heads) - 1)
        move = 0.15 * (edges[k + 1] - edges[k])
        x = np.clip((tf - edges[k]) / move, 0, 1)
        ramp = 0.5 * (1 - np.cos(np.pi * x))
        prev_h = np.where(k > 0, heads[np.maximum(k - 1, 0)], heads[0])
        prev_t = np.where(k > 0, tilt_seq[np.maximum(k - 1, 0)], tilt_seq[0])
        dh = (heads[k] - prev_h + np.pi) % TWO_PI - np.pi
        heading = prev_h + dh * ramp
        tilt = prev_t + (tilt_seq[k] - prev_t) * ramp
        return dur, tf, _axis_rot(2, heading) @ _axis_rot(0, tilt) @ mount
    # gimbal: outer (azimuth) turns, middle nods, inner turns; slow, incommensurate
    dur = float(rng.uniform(0.3, 3) * 3600)
    tf = np.linspace(0, dur, nf)
    u = tf / dur
    outer = TWO_PI * rng.uniform(1, 4) * u + rng.uniform(0, TWO_PI)
    middle = rng.uniform(0.6, 1.5) * np.sin(TWO_PI * rng.uniform(0.5, 3) * u + rng.uniform(0, TWO_PI))
    inner = TWO_PI * rng.uniform(2, 8) * u + rng.uniform(0, TWO_PI)
    return dur, tf, _axis_rot(2, outer) @ _axis_rot(1, middle) @ _axis_rot(0, inner) @ mount


def _sample_times(n: int, dur: float, rng) -> tuple[np.ndarray, str]:
    mode = str(rng.choice(["jitter", "bursty", "gaps", "poisson"]))
    if mode == "jitter":
        x = np.sort(np.arange(n) + rng.normal(0, 0.2, n))
    elif mode == "bursty":  # a logger that wakes up, takes a quick burst, sleeps
        sizes = []
        while sum(sizes) < n:
            sizes.append(int(rng.integers(8, 61)))
        sizes[-1] -= sum(sizes) - n
        sizes = np.array([s for s in sizes if s > 0])
        sleeps = rng.exponential(1.0, len(sizes)) * 1.5 * n / len(sizes)
        starts = np.cumsum(sleeps + np.concatenate([[0.0], sizes[:-1] * 0.25]))
        x = np.concatenate([a + np.arange(s) * 0.25 for a, s in zip(starts, sizes)])
    elif mode == "gaps":  # regular, with a few dropped stretches
        keep = np.ones(n + n // 3, bool)
        for _ in range(int(rng.integers(2, 9))):
            a = int(rng.integers(1, len(keep) - 2))
            keep[a:a + int(rng.integers(3, max(4, n // 12)))] = False
        x = np.flatnonzero(keep)[:n].astype(float)
        if len(x) < n:
            x = np.concatenate([x, x[-1] + 1 + np.arange(n - len(x))])
    else:
        x = np.cumsum(rng.exponential(1.0, n))
    x = np.sort(x)
    x = x + 1e-6 * np.arange(n)  # strictly increasing
    x = (x - x[0]) / (x[-1] - x[0]) if n > 1 else np.zeros(1)
    return dur * x, mode


def _temperature(tf: np.ndarray, dur: float, rng) -> tuple[np.ndarray, str]:
    """The sensor's true temperature on the fine grid."""
    u = tf / dur
    kind = str(rng.choice(["warm_up", "day_cycle", "heater", "weather"]))
    if kind == "warm_up":  # electronics warming towards equilibrium
        temp = rng.uniform(-5, 25) + rng.uniform(5, 25) * (1 - np.exp(-u / rng.uniform(0.1, 0.6)))
        temp += 0.1 * _smooth(u, rng, 4, 1, 4)
    elif kind == "day_cycle":  # sun and shade; a compressed cycle for short records
        period = 86400.0 if dur >= 4 * 3600 else dur / rng.uniform(0.6, 2.0)
        temp = rng.uniform(0, 25) + rng.uniform(3, 12) * np.sin(TWO_PI * tf / period + rng.uniform(0, TWO_PI))
        temp += 0.3 * _smooth(u, rng, 5, 2, 8)
    elif kind == "heater":  # bang-bang thermostat, from a cold start or near its set point
        amb = rng.uniform(-5, 25)
        setp = amb + rng.uniform(8, 20)
        gain = (setp - amb) * rng.uniform(1.3, 2.5)
        band = rng.uniform(0.3, 1.5)
        tau = dur / rng.uniform(5, 20)
        nc = 3000
        dtc = dur / (nc - 1)
        temp_c = np.empty(nc)
        temp_now = amb if rng.random() < 0.5 else setp + rng.uniform(-band, band)
        on = temp_now < setp
        a = min(1.0, dtc / tau)
        for i in range(nc):
            temp_c[i] = temp_now
            temp_now += (amb + (gain if on else 0.0) - temp_now) * a
            if on and temp_now > setp + band:
                on = False
            elif not on and temp_now < setp - band:
                on = True
        temp = np.interp(tf, np.linspace(0, dur, nc), temp_c)
    else:  # weather: a ramp and slow wander
        temp = rng.uniform(-10, 30) + rng.uniform(-8, 8) * u + rng.uniform(1, 6) * _smooth(u, rng, 5, 0.5, 3)
    return temp, kind


def _cheb_r2(x: np.ndarray, y: np.ndarray, deg: int) -> float:
    """R^2 of y (n,) or (n,k) on a Chebyshev polynomial of degree deg in x."""
    y2 = y if y.ndim == 2 else y[:, None]
    span = np.ptp(x)
    if span <= 0 or len(x) <= deg + 2:
        return 0.0
    z = 2 * (x - x.min()) / span - 1
    basis = np.polynomial.chebyshev.chebvander(z, deg)
    coef, *_ = np.linalg.lstsq(basis, y2, rcond=None)
    res = y2 - basis @ coef
    tot = ((y2 - y2.mean(0)) ** 2).sum()
    return float(1 - (res ** 2).sum() / tot) if tot > 0 else 1.0


# ------------------------------------------------------------------------------------------ the case
def make_case(index: int, root: int = 2027, *, noise_free: bool = False) -> Case:  # noqa: C901
    category, kind, chosen = plan(index, root)
    rng = np.random.default_rng(np.random.SeedSequence([root, index, 2]))
    n = int(rng.integers(8, 14)) if category == "too_short" else int(rng.integers(300, 2001))
    dur, tf, rot_f = _schedule(kind, rng)
    dtf = tf[1] - tf[0]
    t, sampling = _sample_times(n, dur, rng)

    # the ambient field and its reference
    f0 = float(rng.uniform(22000, 67000))
    inc, dec = np.radians(rng.uniform(-75, 75)), np.radians(rng.uniform(-25, 25))
    b_hat = np.array([np.cos(inc) * np.cos(dec), np.cos(inc) * np.sin(dec), np.sin(inc)])
    observatory = bool(rng.random() < 0.4)
    fref_f = f0 + (rng.uniform(2, 30) * _smooth(tf / dur, rng, 4, 0.2, 1.5) if observatory else 0.0) * np.ones_like(tf)
    dir_f = np.einsum("nji,j->ni", rot_f, b_hat)  # R^T b: the field's direction in the body frame
    grav_f = rot_f[:, 2, :]  # R^T (0, 0, 1): gravity (down) in the body frame
    u_s = _unit(_interp(tf, dir_f, t))
    g_s = _unit(_interp(tf, grav_f, t))
    f_ref = np.interp(t, tf, fref_f)
    b_body = f_ref[:, None] * u_s

    # the sensor's static errors, by quality class
    q = int(rng.integers(0, 3))
    ang = rng.normal(0, [0.001, 0.005, 0.02][q], 3)
    k = 1 + rng.normal(0, [0.002, 0.01, 0.04][q], 3)
    o = rng.normal(0, [20.0, 200.0, 1500.0][q], 3)
    soft = np.zeros((3, 3))
    if rng.random() < 0.6:
        a = rng.normal(0, rng.uniform(0.002, 0.03), (3, 3))
        soft = 0.5 * (a + a.T)
    p_inv = np.linalg.inv(_paper_p(*ang))
    m_true = np.diag(k) @ p_inv @ (np.eye(3) + soft)
    corr = np.linalg.inv(m_true)
    sensed = b_body @ m_true.T  # field along the sensor axes, before the offset
    sensed_f = (fref_f[:, None] * dir_f) @ m_true.T
    raw_clean = sensed + o

    sigma_ax = float(np.exp(rng.uniform(np.log(0.3), np.log(8.0)))) * rng.uniform(0.8, 1.2, 3)
    sigma = float(np.mean(sigma_ax))
    temp_true_f, temp_kind = _temperature(tf, dur, rng)
    temp_true = np.interp(t, tf, temp_true_f)
    tau_log = rng.uniform(0, 0.02) * dur if temp_kind != "heater" else rng.uniform(0, 0.003) * dur
    temp_log = np.interp(t, tf, _lowpass(temp_true_f, dtf, tau_log)) + rng.normal(0, 0.02, n)
    temp_log = np.round(temp_log / 0.0625) * 0.0625  # a digital thermometer's 1/16 degree
    temp_r2_time = _cheb_r2(t, temp_log, 6)

    # the visible size of a perturbation of the readings
    basis = np.column_stack([u_s[:, 0] ** 2, u_s[:, 1] ** 2, u_s[:, 2] ** 2, u_s[:, 0] * u_s[:, 1],
                             u_s[:, 0] * u_s[:, 2], u_s[:, 1] * u_s[:, 2], u_s, np.ones(n)])
    uu, sv, _ = np.linalg.svd(basis, full_matrices=False)
    qb = uu[:, sv > 1e-8 * sv[0]]

    def magnitude_change(delta: np.ndarray) -> np.ndarray:
        d = np.linalg.norm((sensed + delta) @ corr.T, axis=1) - f_ref
        return d - qb @ (qb.T @ d)

    def visible(delta: np.ndarray) -> float:
        if kind == "fixed":  # one attitude: the vector readings show a change in any direction
            db = delta @ corr.T
            return float(np.sqrt(np.mean(np.sum((db - db.mean(0)) ** 2, axis=1))))
        return float(np.sqrt(np.mean(magnitude_change(delta) ** 2)))

    def fit_size(build, target: float, c0: float = 1.0, cmax: float = np.inf):
        c = c0
        for _ in range(5):
            v = visible(build(c))
            if v <= 0:
                return c, 0.0
            c_new = min(c * target / v, cmax)
            if abs(c_new / c - 1) < 1e-3:
                c = c_new
                break
            c = c_new
        return c, visible(build(c))

    def bisect_size(build, target: float, lo: float, hi: float, increasing: bool):
        """For an effect not linear in its parameter: visible size monotone in it; bisection (log)."""
        for _ in range(22):
            mid = np.sqrt(lo * hi)
            v = visible(build(mid))
            if (v < target) == increasing:
                lo = mid
            else:
                hi = mid
        c = np.sqrt(lo * hi)
        return c, visible(build(c))

    def to_body_world(vec_world_f: np.ndarray) -> np.ndarray:  # world-frame field on the grid -> body, at t
        return _interp(tf, np.einsum("nji,nj->ni", rot_f, vec_world_f), t)

    omega_rms = float(np.sqrt(np.mean(np.sum(np.gradient(dir_f, tf, axis=0) ** 2, axis=1)))) + 1e-12

    present: list[str] = []
    outside: list[str] = []
    acceptable: set[str] = set()
    confound: set[frozenset] = set()
    notes: dict = {"schedule": kind, "sampling": sampling, "n": n, "duration_s": dur, "noise_nT": sigma,
                   "noise_axes_nT": sigma_ax.tolist(), "planned": list(chosen), "temp_profile": temp_kind,
                   "temp_log_lag_s": tau_log, "temp_r2_time": temp_r2_time, "observatory_reference": observatory,
                   "correction": corr, "offset": o, "effects": {}, "too_small": []}
    total = np.zeros((n, 3))
    post: list = []  # effects applied to the final readings (after noise): (name, function)
    invisible: list[str] = []

    def record(name: str, delta: np.ndarray | None, target: float, got: float, **info) -> None:
        nonlocal total
        notes["effects"][name] = {"target_nT": target, "visible_nT": got, "snr": got / sigma, **info}
        if delta is not None:
            total = total + delta
        if got < 0.5 * target:
            invisible.append(name)

    def field_drift_pairs(delta: np.ndarray) -> None:
        """The library pairs a local field change cannot be told from, in this record."""
        if _cheb_r2(temp_log, magnitude_change(delta), 5) >= 0.9:  # |B| follows the logged temperature
            confound.add(frozenset(("field_drift", "temperature")))
        if kind == "fixed":  # one attitude: a vector change across the field is an offset drift's
            db = delta @ corr.T
            along = db @ u_s[0]
            across = db - along[:, None] * u_s[0]
            if np.sum((across - across.mean(0)) ** 2) > 0.25 * np.sum((along - along.mean()) ** 2):
                confound.add(frozenset(("field_drift", "offset_drift")))

    for name in (chosen if category not in ("clean", "too_short") else []):
        snr = float(rng.uniform(8, 20))
        target = snr * sigma
        if name == "temperature":
            d_temp = temp_true - temp_true.mean()
            terms = []
            a_off = rng.normal(0, 1, 3)
            terms.append(lambda c, a_off=a_off: c * d_temp[:, None] * a_off)
            s_vec = rng.normal(0, 1) + rng.normal(0, 0.5, 3)
            terms.append(lambda c, s_vec=s_vec: c * 1e-6 * d_temp[:, None] * s_vec * sensed)
            d_ang = rng.normal(0, 1, 3)

            def align_term(c, d_ang=d_ang):
                angles = ang + c * 1e-6 * d_temp[:, None] * d_ang
                m_t = np.diag(k) @ np.linalg.inv(_paper_p(angles[:, 0], angles[:, 1], angles[:, 2])) @ (np.eye(3) + soft)
                return np.einsum("nij,nj->ni", m_t, b_body) - sensed
            terms.append(align_term)
            w = rng.dirichlet([1.0, 1.0, 0.7])
            if rng.random() < 0.3:
                w[2] = 0.0
            cs = [1.0 / max(visible(f(1.0)), 1e-12) * wi for f, wi in zip(terms, w)]
            c, got = fit_size(lambda c: sum(f(c * ci) for f, ci in zip(terms, cs)), target)
            delta = sum(f(c * ci) for f, ci in zip(terms, cs))
            record(name, delta, target, got, weights_offset_scale_alignment=w.tolist())
            if temp_r2_time >= 0.9 and kind != "fixed":  # the temperature follows a smooth function of time
                confound.add(frozenset(("temperature", "offset_drift")))
                if _cheb_r2(t, magnitude_change(delta), 6) >= 0.8:  # a time-only change of |B|: a field drift's
                    confound.add(frozenset(("temperature", "field_drift")))
            elif temp_r2_time >= 0.9:  # one attitude: the direction the readings move in says which drift
                db = delta @ corr.T
                along = db @ u_s[0]
                across = db - along[:, None] * u_s[0]
                ratio = np.sum((across - across.mean(0)) ** 2) / max(np.sum((along - along.mean()) ** 2), 1e-300)
                confound.add(frozenset(("temperature", "offset_drift" if ratio > 0.25 else "field_drift")))
        elif name == "field_drift":
            shape = str(rng.choice(["diurnal", "bay", "pulsation", "ramp"]))
            u = tf / dur
            # a geomagnetic variation changes the total field to first order: a part along the field, and
            # parts across it up to 0.8 of that (each with its own phase where it oscillates)
            perp = np.linalg.qr(np.column_stack([b_hat, rng.normal(0, 1, (3, 2))]))[0][:, 1:].T
            dirs = np.vstack([b_hat * rng.choice([-1, 1]), perp * rng.uniform(0, 0.8, 2)[:, None]])
            if shape == "diurnal":
                period = 86400.0 if dur >= 4 * 3600 else dur / rng.uniform(0.5, 1.8)
                waves = np.stack([np.sin(TWO_PI * tf / period + rng.uniform(0, TWO_PI)) for _ in range(3)], 1)
                vec_f = waves @ dirs
            elif shape == "bay":
                t0, wid = rng.uniform(0.1, 0.6) * dur, rng.uniform(0.05, 0.3) * dur
                x = np.clip((tf - t0) / wid, 0, None)
                vec_f = (x * np.exp(1 - x))[:, None] * dirs.sum(axis=0)
            elif shape == "pulsation":
                f = rng.uniform(2, 6) / dur
                env = np.exp(-0.5 * ((u - rng.uniform(0.3, 0.7)) / rng.uniform(0.15, 0.4)) ** 2)
                waves = np.stack([np.sin(TWO_PI * f * tf + rng.uniform(0, TWO_PI)) for _ in range(3)], 1)
                vec_f = env[:, None] * (waves @ dirs)
            else:
                vec_f = (u + rng.uniform(-0.8, 0.8) * u ** 2)[:, None] * dirs.sum(axis=0)
            base = to_body_world(vec_f) @ m_true.T
            c, got = fit_size(lambda c: c * base, target)
            delta = c * base
            record(name, delta, target, got, shape=shape, world_amplitude_nT=float(c * np.abs(vec_f).max()))
            field_drift_pairs(delta)
        elif name == "offset_drift":
            shape = str(rng.choice(["linear", "random_walk", "walk_and_linear"]))
            u = tf / dur
            walk = np.cumsum(rng.normal(0, 1, (len(tf), 3)), axis=0)
            walk = _lowpass(walk, dtf, 0.002 * dur)
            line = (u - 0.5)[:, None] * rng.normal(0, 1, 3)
            drift_f = {"linear": line, "random_walk": walk / np.abs(walk).max(),
                       "walk_and_linear": line + 0.5 * walk / np.abs(walk).max()}[shape]
            base = _interp(tf, drift_f, t)
            base = base - base.mean(0)
            c, got = fit_size(lambda c: c * base, target)
            delta = c * base
            record(name, delta, target, got, shape=shape)
            if _cheb_r2(temp_log, delta, 5) >= 0.9:
                confound.add(frozenset(("offset_drift", "temperature")))
            if kind == "fixed":
                db = delta @ corr.T
                along = db @ u_s[0]
                across = db - along[:, None] * u_s[0]
                if np.sum(across ** 2) < 0.25 * np.sum(along ** 2):
                    confound.add(frozenset(("offset_drift", "field_drift")))
        elif name == "nonlinearity":
            shape = str(rng.choice(["quadratic", "cubic", "mixed", "soft_saturation"]))
            mask = np.zeros(3)
            mask[rng.choice(3, size=int(rng.integers(1, 4)), replace=False)] = 1
            full = rng.uniform(60000, 100000)
            x = sensed / full
            q2, q3 = rng.normal(0, 1, 3) * mask, rng.normal(0, 1, 3) * mask
            if shape == "soft_saturation":
                def build(c, mask=mask, full=full):
                    fs = full / np.sqrt(max(c, 1e-12))
                    return (fs * np.tanh(sensed / fs) - sensed) * mask
                c, got = bisect_size(build, target, 1e-6, 3.0, increasing=True)
            else:
                shape_f = {"quadratic": q2 * x ** 2, "cubic": q3 * x ** 3, "mixed": q2 * x ** 2 + q3 * x ** 3}[shape]

                def build(c, shape_f=shape_f, full=full):
                    return c * full * shape_f
                c, got = fit_size(build, target, 1e-4)
            record(name, build(c), target, got, shape=shape, axes=mask.tolist())
        elif name == "outliers":
            shape = str(rng.choice(["spikes", "bursts", "bit_flips"]))
            m = max(3, int(round(n * rng.uniform(0.005, 0.02))))
            rows: list[int] = []
            if shape == "spikes":
                rows = sorted(int(r) for r in rng.choice(n, m, replace=False))
                hits = []
                for r in rows:
                    v = np.zeros(3)
                    axes = [int(rng.integers(3))] if rng.random() < 0.6 else [0, 1, 2]
                    v[axes] = rng.choice([-1, 1], len(axes)) * target * rng.uniform(1.5, 4.0, len(axes))
                    hits.append((r, v))
            elif shape == "bursts":
                hits = []
                for _ in range(max(2, m // 3)):
                    r0 = int(rng.integers(0, n - 4))
                    for r in range(r0, r0 + int(rng.integers(2, 5))):
                        hits.append((r, rng.normal(0, 1, 3) * target * rng.uniform(1.5, 4.0)))
                        rows.append(r)
            else:
                lsb_adc = rng.uniform(0.005, 0.05)
                hits = []
                rows = sorted(int(r) for r in rng.choice(n, m, replace=False))
                for r in rows:
                    bit = int(round(np.log2(target * rng.uniform(1.5, 4.0) / lsb_adc)))
                    hits.append((r, (int(rng.integers(3)), bit, lsb_adc)))

            def apply_outliers(readings, hits=hits, shape=shape):
                out = readings.copy()
                for r, v in hits:
                    if shape == "bit_flips":
                        axis, bit, lsb = v
                        code = int(np.round(out[r, axis] / lsb)) + (1 << 23)
                        out[r, axis] = ((code ^ (1 << bit)) - (1 << 23)) * lsb
                    else:
                        out[r] += v
                return out
            post.append((name, apply_outliers))
            record(name, None, target, target, shape=shape, rows=sorted(set(rows)))
        elif name == "lag":
            shape = str(rng.choice(["mux_skew", "fir_one_axis", "iir_axes"]))
            axis = int(rng.integers(3))
            perm = rng.permutation(3).astype(float)
            spread = rng.uniform(0.5, 1.5, 3)
            iir_mask = np.zeros(3)
            iir_mask[rng.choice(3, size=int(rng.integers(1, 3)), replace=False)] = 1

            def build(c, shape=shape, axis=axis, perm=perm, spread=spread, iir_mask=iir_mask):
                now = _interp(tf, sensed_f, t)
                if shape == "mux_skew":  # a multiplexed converter samples the axes one after another
                    late = np.stack([np.interp(t - c * perm[j], tf, sensed_f[:, j]) for j in range(3)], 1)
                    return late - now
                if shape == "fir_one_axis":  # one channel through a boxcar FIR of window c (group delay c/2)
                    sub = (np.arange(24) + 0.5) / 24  # the window's mean, by the midpoint rule
                    back = np.interp(t[:, None] - c * sub[None, :], tf, sensed_f[:, axis]).mean(axis=1)
                    out = np.zeros((n, 3))
                    out[:, axis] = back - now[:, axis]
                    return out
                filt = np.stack([_lowpass(sensed_f[:, j], dtf, c * spread[j]) if iir_mask[j] else sensed_f[:, j]
                                 for j in range(3)], 1)
                return _interp(tf, filt, t) - now
            c, got = bisect_size(build, target, 1e-8 / omega_rms, min(0.03 * dur, 3.0 / omega_rms), increasing=True)
            record(name, build(c), target, got, shape=shape, delay_s=float(c))
        # ------------------------------------------------------------------ outside the library
        elif name == "battery_load":  # a magnetised battery / supply loop: field proportional to load current
            cur = np.zeros(len(tf))
            for ts in np.sort(rng.uniform(0, dur, int(rng.integers(4, 16)))):
                cur[tf >= ts] = rng.uniform(0, 1)
            for _ in range(int(rng.integers(3, 13))):  # radio transmit bursts
                a = rng.uniform(0, dur)
                cur[(tf >= a) & (tf < a + rng.uniform(0.002, 0.03) * dur)] += rng.uniform(0.5, 1.5)
            base = np.interp(t, tf, cur)[:, None] * _unit(rng.normal(0, 1, 3)) @ m_true.T
            c, got = fit_size(lambda c: c * base, target)
            record(name, c * base, target, got)
        elif name in ("motor_stray", "vibration_alias"):
            knots = np.sort(np.concatenate([[0, dur], rng.uniform(0, dur, int(rng.integers(4, 10)))]))
            speed_f = np.interp(tf, knots, rng.uniform(0.2, 1.0, len(knots)))
            freq = (rng.uniform(30, 150) if name == "motor_stray" else rng.uniform(15, 90)) * speed_f
            phase_f = TWO_PI * np.concatenate([[0.0], np.cumsum(0.5 * (freq[1:] + freq[:-1]) * dtf)])
            phase_f = phase_f + np.cumsum(rng.normal(0, 0.02, len(tf)))  # not a pure tone
            phase = np.interp(t, tf, phase_f)
            speed = np.interp(t, tf, speed_f)
            if name == "motor_stray":  # winding current ~ speed^2 (drag), plus the rotor magnet turning
                e1, e2 = np.linalg.qr(rng.normal(0, 1, (3, 2)))[0].T
                mix = rng.uniform(0.2, 0.8)
                body = (mix * speed[:, None] ** 2 * _unit(rng.normal(0, 1, 3))
                        + (1 - mix) * (np.cos(phase)[:, None] * e1 + np.sin(phase)[:, None] * e2))
            else:  # a mast vibrating in the vehicle's field gradient, amplitude ~ engine speed^2, aliased
                body = (speed ** 2 * np.sin(phase))[:, None] * _unit(rng.normal(0, 1, 3))
            base = body @ m_true.T
            c, got = fit_size(lambda c: c * base, target)
            record(name, c * base, target, got)
        elif name == "sagging_soft_iron":  # a steel part hanging with gravity; field induced along its axis
            r_hat = _unit(rng.normal(0, 1, 3))
            part = _unit(g_s + rng.uniform(0.2, 1.5) * _unit(rng.normal(0, 1, 3)))
            dip = 3 * (part @ r_hat)[:, None] * r_hat - part
            base = (np.sum(part * b_body, axis=1)[:, None] * dip) @ m_true.T
            c, got = fit_size(lambda c: c * base, target, 1e-3)
            record(name, c * base, target, got)
        elif name == "mount_flex":  # the bracket bends under gravity: the axes' angles follow the tilt
            kmat = rng.normal(0, 1, (3, 3))

            def build(c, kmat=kmat):
                angles = ang + c * g_s @ kmat.T
                m_t = np.diag(k) @ np.linalg.inv(_paper_p(angles[:, 0], angles[:, 1], angles[:, 2])) @ (np.eye(3) + soft)
                return np.einsum("nij,nj->ni", m_t, b_body) - sensed
            c, got = fit_size(build, target, 1e-4)
            record(name, build(c), target, got)
        elif name == "range_clip":  # one or two axes on a lower range: the converter rails at +-L
            mask = np.zeros(3, bool)
            mask[rng.choice(3, size=1 if rng.random() < 0.6 else 2, replace=False)] = True
            peak = np.abs(raw_clean[:, mask]).max()

            def build(lim, mask=mask):
                out = np.zeros((n, 3))
                out[:, mask] = np.clip(raw_clean[:, mask], -lim, lim) - raw_clean[:, mask]
                return out
            lim, got = bisect_size(build, target, 0.3 * peak, peak, increasing=False)
            post.append((name, lambda r, lim=lim, mask=mask: np.where(mask, np.clip(r, -lim, lim), r)))
            record(name, None, target, got, limit_nT=float(lim), axes=mask.tolist())
        elif name == "slew_limit":  # the feedback loop cannot follow faster than S nT/s
            stride = max(1, len(tf) // 4000)
            tc, hc = tf[::stride], sensed_f[::stride]
            dtc = tc[1] - tc[0]
            rate_max = float(np.abs(np.diff(hc, axis=0)).max() / dtc)

            def slewed(s):
                y = np.empty_like(hc)
                y[0] = hc[0]
                step = s * dtc
                prev = hc[0].copy()
                for i in range(1, len(hc)):
                    prev = prev + np.clip(hc[i] - prev, -step, step)
                    y[i] = prev
                return y

            def build(s):
                return _interp(tc, slewed(s) - hc, t)
            s_lim, got = bisect_size(build, target, 1e-3 * rate_max, rate_max, increasing=False)
            record(name, build(s_lim), target, got, slew_nT_per_s=float(s_lim))
        elif name == "gain_switch":  # a range switch: the gain (and the zero) jump once
            ts = rng.uniform(0.25, 0.75) * dur
            step = (t >= ts).astype(float)[:, None]
            dk = rng.normal(1, 0.5) * np.ones(3) if rng.random() < 0.5 else np.eye(3)[int(rng.integers(3))]
            base = step * (sensed * dk * 1e-3 + rng.normal(0, 0.5, 3) * 1e-3 * f0 / 50)
            c, got = fit_size(lambda c: c * base, target)
            record(name, c * base, target, got, switch_s=float(ts))
        elif name == "remanence":  # perming by a strong field during a pause: a jump, then a viscous decay
            gaps = np.diff(t)
            inside = (t[:-1] > 0.15 * dur) & (t[:-1] < 0.75 * dur)
            i = int(np.argmax(np.where(inside, gaps, -1))) if inside.any() else n // 2
            te = 0.5 * (t[i] + t[min(i + 1, n - 1)])
            after = np.clip(t - te, 0, None)
            viscous = 1 - rng.uniform(0.05, 0.2) * np.log1p(after / (rng.uniform(0.001, 0.02) * dur))
            decay = np.where(t > te, np.clip(viscous, 0, None), 0)
            base = decay[:, None] * rng.normal(0, 1, 3)
            c, got = fit_size(lambda c: c * base, target)
            record(name, c * base, target, got, exposure_s=float(te))
        elif name == "heater_pwm":  # a PWM-driven heater's current loop, sampled at the logger's instants
            f_pwm = rng.uniform(0.5, 40)
            duty = np.clip(0.5 + 0.3 * _smooth(t / dur, rng, 3, 0.5, 3), 0.05, 0.95)
            on = ((f_pwm * t + rng.uniform()) % 1.0) < duty
            base = on.astype(float)[:, None] * _unit(rng.normal(0, 1, 3)) @ m_true.T
            c, got = fit_size(lambda c: c * base, target)
            record(name, c * base, target, got, pwm_Hz=float(f_pwm))
        elif name == "telegraph_noise":  # popcorn noise: one channel's zero flips between two levels
            axes = rng.choice(3, size=1 if rng.random() < 0.7 else 2, replace=False)
            dwell = rng.uniform(0.005, 0.05) * dur
            flips = np.cumsum(rng.exponential(dwell, int(4 * dur / dwell) + 4))
            state = (np.searchsorted(flips, t) % 2).astype(float) * 2 - 1
            base = np.zeros((n, 3))
            base[:, axes] = state[:, None] * rng.choice([-1, 1], len(axes))
            c, got = fit_size(lambda c: c * base, target)
            record(name, c * base, target, got)
        elif name == "thermal_gradient":  # offsets from a gradient across the head, ~ the rate of temperature
            rate_f = _lowpass(np.gradient(temp_true_f, tf), dtf, rng.uniform(0.001, 0.01) * dur)
            base = np.interp(t, tf, rate_f)[:, None] * rng.normal(0, 1, 3)
            c, got = fit_size(lambda c: c * base, target)
            record(name, c * base, target, got)
            if _cheb_r2(t, base, 6) >= 0.9:  # a smooth offset change in time: the offsets do drift
                acceptable.add("offset_drift")
        elif name == "eddy_housing":  # a conducting can: field changes reach the core delayed (axial vs radial)
            ax = int(rng.integers(3))
            taus = np.full(3, np.exp(rng.uniform(np.log(0.005), np.log(1.0))))  # radial; then the axial one
            taus[ax] = np.exp(rng.uniform(np.log(0.005), np.log(1.0)))
            shares = rng.uniform(0.2, 1.0, 3)
            bf = fref_f[:, None] * dir_f
            hp = bf - np.stack([_lowpass(bf[:, j], dtf, taus[j]) for j in range(3)], 1)
            base = _interp(tf, hp * shares, t) @ m_true.T
            first = (_interp(tf, np.gradient(bf, tf, axis=0) * taus * shares, t)) @ m_true.T
            c, got = fit_size(lambda c: -c * base, target, 0.1, cmax=1.0)
            delta = -c * base
            beyond = visible(delta + c * first) / max(got, 1e-12)  # what a pure per-axis delay leaves
            record(name, delta, target, got, taus_s=taus.tolist(), beyond_first_order=beyond)
            if beyond < 0.3:  # the delay is all there is to see: it is a per-axis lag
                notes["effects"][name]["becomes"] = "lag"
        elif name == "passing_object":  # a car or a ship passing: a dipole in the world frame
            mom = _unit(rng.normal(0, 1, 3))
            tc, wid = rng.uniform(0.2, 0.8) * dur, rng.uniform(0.03, 0.15) * dur
            path = _unit(rng.normal(0, 1, 3))
            side = _unit(np.cross(path, rng.normal(0, 1, 3)))
            r = side[None, :] + ((tf - tc) / wid)[:, None] * path[None, :]
            rn = np.linalg.norm(r, axis=1, keepdims=True)
            rh = r / rn
            vec_f = (3 * np.sum(rh * mom, axis=1, keepdims=True) * rh - mom) / rn ** 3
            base = to_body_world(vec_f) @ m_true.T
            c, got = fit_size(lambda c: c * base, target)
            record(name, c * base, target, got, closest_s=float(tc))
            field_drift_pairs(c * base)
        if name in LIBRARY:
            acceptable.add(name)
            if name not in invisible:
                present.append(name)
        else:
            acceptable.update(ACCEPTABLE_FOR.get(name, ()))
            becomes = BECOMES.get(name) or notes["effects"].get(name, {}).get("becomes")
            if name in invisible:
                pass
            elif becomes:
                acceptable.add(becomes)
                if becomes not in present:
                    present.append(becomes)
            else:
                outside.append(name)
    notes["too_small"] = invisible

    # readings: clean + effects, noise (white, some flicker), converter rails, outliers, quantisation, holds
    readings = raw_clean + total
    flicker = 0.0
    if not noise_free:
        noise = rng.normal(0, 1, (n, 3)) * sigma_ax
        if category not in ("clean", "too_short") and rng.random() < 0.2 and n > 16:
            flicker = rng.uniform(0.2, 0.5)
            spec = np.fft.rfft(rng.normal(0, 1, (n, 3)), axis=0)
            freqs = np.arange(spec.shape[0], dtype=float)
            freqs[0] = np.inf
            pink = np.fft.irfft(spec / np.sqrt(freqs)[:, None], n, axis=0)
            pink = pink / pink.std(axis=0) * sigma_ax * flicker
            noise += pink
        readings = readings + noise
    for name, fn in post:
        if name == "range_clip":
            readings = fn(readings)
    for name, fn in post:
        if name == "outliers":
            readings = fn(readings)
    lsb = 0.0
    if not noise_free and rng.random() < 0.25:
        lsb = float(sigma * rng.uniform(0.3, 2.0))
        readings = np.round(readings / lsb) * lsb
    if not noise_free and category == "clean" and rng.random() < 0.25:  # a logger that repeats its last value
        hold = rng.random(n) < rng.uniform(0.05, 0.3)
        hold[0] = False
        readings = readings[np.maximum.accumulate(np.where(hold, 0, np.arange(n)))]
        notes["held_fraction"] = float(hold.mean())
    notes["flicker_ratio"] = flicker
    notes["lsb_nT"] = lsb

    gravity = None
    if rng.random() < 0.5:
        acc_noise = 0.03 if kind == "handheld" else 0.005
        gravity = g_s + rng.normal(0, acc_noise, (n, 3))
    confound_pairs = tuple(tuple(sorted(p)) for p in sorted(confound, key=lambda s: sorted(s))
                           if set(p) <= set(LIBRARY))
    return Case(index=index, category=category, raw_nT=readings, f_ref_nT=f_ref, t_s=t, temp_C=temp_log,
                gravity=gravity, present=tuple(present), outside=tuple(outside),
                acceptable=tuple(sorted(acceptable | set(present))), expect_unexplained=bool(outside),
                confoundable=confound_pairs, schedule=kind, notes=notes)

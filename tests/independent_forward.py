"""A second forward model of a fluxgate in the geomagnetic field, written from the physics and sharing no
code with magbench's simulator or diagnosis (it imports numpy only): the independent source of blind cases
for the sim-to-real diagnosis (tests/test_diagnosis_independent.py, tests/independent_blind_table.py).

The sensor follows docs/CONTRACT.md section 1 (``raw = K P^-1 B + o + noise``, P the adaptive-GA paper's
lower-triangular non-orthogonality matrix), or the axis-projection model ``raw = K A B + o`` (A = P^T).
Attitudes are rotation matrices built here from yaw, pitch and roll; the field is a constant vector of
random inclination and declination.  Effects are parametrized in physical units, each scaled to a stated
multiple of the noise (``snr``) so that a case says whether it should be visible at all.

Effects the diagnosis has in its library (the names it may claim): temperature, field_drift,
offset_drift, nonlinearity, outliers, lag.  Effects outside it, chosen because they resemble library
effects: a platform field that turns with heading, a hard iron on a rotating part, a current loop that
switches on, a gravity-following body field, a lagged soft iron, a field gradient seen through a lever arm,
eddy currents, hysteresis, clipping, coloured noise alone, mains hum aliased to a low frequency, and a
temperature-dependent alignment (physically a temperature effect: ``temperature`` is a right name for it).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

LIBRARY = ("temperature", "field_drift", "offset_drift", "nonlinearity", "outliers", "lag")
OUTSIDE = ("heading_field", "rotating_iron", "switch_on", "gravity_field", "lagged_soft_iron", "gradient",
           "eddy", "hysteresis", "clipping", "coloured_noise", "hum", "temp_alignment")
ACCEPTABLE_FOR = {"temp_alignment": ("temperature",)}  # outside effects that are physically a library effect


@dataclass(frozen=True)
class Case:
    """One blind record and its truth."""

    index: int
    category: str
    raw_nT: np.ndarray
    f_ref_nT: np.ndarray
    t_s: np.ndarray
    temp_C: np.ndarray | None
    gravity: np.ndarray | None
    present: tuple[str, ...]  # library effects truly present (and large enough to see)
    outside: tuple[str, ...]  # effects outside the library present
    acceptable: tuple[str, ...]  # names that are not wrong
    expect_unexplained: bool
    confoundable: tuple[tuple[str, str], ...] = ()
    schedule: str = ""
    notes: dict = field(default_factory=dict)

    @property
    def too_short(self) -> bool:
        return self.category == "too_short"


# --------------------------------------------------------------------------------------- rotations
def rotation(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """Body-to-world rotation matrices (n, 3, 3), aerospace z-y-x order: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cy, sy, cp, sp, cr, sr = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    r = np.empty((len(yaw), 3, 3))
    r[:, 0, 0] = cy * cp
    r[:, 0, 1] = cy * sp * sr - sy * cr
    r[:, 0, 2] = cy * sp * cr + sy * sr
    r[:, 1, 0] = sy * cp
    r[:, 1, 1] = sy * sp * sr + cy * cr
    r[:, 1, 2] = sy * sp * cr - cy * sr
    r[:, 2, 0] = -sp
    r[:, 2, 1] = cp * sr
    r[:, 2, 2] = cp * cr
    return r


def schedule(kind: str, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t_s, yaw, pitch, roll) of an attitude schedule."""
    span = float(rng.uniform(300.0, 3600.0))
    t = np.sort(rng.uniform(0, span, n)) if kind == "irregular" else np.linspace(0.0, span, n)
    u = t / span
    if kind == "sphere":  # random attitudes, independent of time
        yaw, pitch, roll = rng.uniform(-np.pi, np.pi, n), np.arcsin(rng.uniform(-1, 1, n)), rng.uniform(-np.pi, np.pi, n)
    elif kind == "tumble" or kind == "irregular":  # smooth tumbling through many attitudes
        w = rng.uniform(3.0, 8.0, 3)
        ph = rng.uniform(0, 2 * np.pi, 3)
        yaw = np.pi * np.sin(2 * np.pi * w[0] * u + ph[0])
        pitch = 1.2 * np.sin(2 * np.pi * w[1] * u + ph[1])
        roll = np.pi * np.sin(2 * np.pi * w[2] * u + ph[2])
    elif kind == "turntable":  # full turns at a few tilts
        tilts = rng.uniform(-1.2, 1.2, 6)
        block = np.minimum((u * 6).astype(int), 5)
        yaw = 2 * np.pi * ((u * 6) % 1.0) * 2
        pitch, roll = tilts[block], 0.5 * tilts[::-1][block]
    elif kind == "vehicle":  # slow heading changes, small pitch and roll
        yaw = np.cumsum(rng.normal(0, 0.02, n)) + 2 * np.pi * rng.uniform(0.5, 2.0) * u
        pitch, roll = 0.08 * np.sin(2 * np.pi * 7 * u), 0.1 * np.sin(2 * np.pi * 5 * u + 1)
    elif kind == "steps":  # a few distinct attitudes, each held
        k = 12
        att = rng.uniform(-np.pi, np.pi, (k, 3)) * np.array([1.0, 0.45, 1.0])
        idx = np.minimum((u * k).astype(int), k - 1)
        yaw, pitch, roll = att[idx, 0], att[idx, 1], att[idx, 2]
    elif kind == "fixed":
        yaw, pitch, roll = np.full(n, 0.3), np.full(n, 0.05), np.full(n, -0.02)
    else:
        raise ValueError(kind)
    return t, yaw, pitch, roll


def paper_p(alpha: float, beta: float, gamma: float) -> np.ndarray:
    """The adaptive-GA paper's correction matrix P (docs/CONTRACT.md section 1)."""
    ca, sa, cb, sb, cg, sg = np.cos(alpha), np.sin(alpha), np.cos(beta), np.sin(beta), np.cos(gamma), np.sin(gamma)
    return np.array([[ca * cg, 0.0, 0.0], [sg, cb, 0.0], [sa * cg, sb, 1.0]])


def pink_noise(n: int, rng: np.random.Generator) -> np.ndarray:
    """Unit-RMS 1/f noise by spectral shaping."""
    spec = np.fft.rfft(rng.standard_normal(n))
    f = np.arange(len(spec), dtype=float)
    f[0] = 1.0
    x = np.fft.irfft(spec / np.sqrt(f), n)
    return x / x.std()


def smooth_step(u: np.ndarray) -> np.ndarray:
    return 0.5 * (1 - np.cos(np.pi * np.clip(u, 0, 1)))


# --------------------------------------------------------------------------------------- one record
def make_case(index: int, root: int = 2026) -> Case:
    rng = np.random.default_rng(np.random.SeedSequence([root, index]))
    categories = ("clean", "single", "single", "pair", "outside", "outside", "outside_plus", "triple", "too_short",
                  "fixed", "single", "outside")
    category = categories[index % len(categories)]
    n = int(rng.integers(8, 14)) if category == "too_short" else int(rng.choice([400, 600, 900, 1200]))
    kind = "fixed" if category == "fixed" else str(rng.choice(["sphere", "tumble", "turntable", "vehicle", "steps",
                                                                 "irregular"]))
    t, yaw, pitch, roll = schedule(kind, n, rng)
    rot = rotation(yaw, pitch, roll)
    f_earth = float(rng.uniform(25000, 65000))
    inc, dec = np.radians(rng.uniform(20, 70)), np.radians(rng.uniform(-20, 20))
    b_world = f_earth * np.array([np.cos(inc) * np.cos(dec), np.cos(inc) * np.sin(dec), np.sin(inc)])
    b_body = np.einsum("nji,j->ni", rot, b_world)  # R^T b
    g_body = np.einsum("nji,j->ni", rot, np.array([0.0, 0.0, 1.0]))
    noise = float(rng.uniform(0.5, 6.0))
    span = t[-1] - t[0] if n > 1 else 1.0
    u = (t - t[0]) / max(span, 1e-9)
    temp = 20 + rng.uniform(5, 25) * smooth_step(u) + 0.3 * rng.standard_normal(n)  # logged temperature
    present: list[str] = []
    outside: list[str] = []
    confound: list[tuple[str, str]] = []
    notes: dict = {"schedule": kind, "noise_nT": noise, "n": n}

    # the sensor's static errors (paper model or axis projection)
    alpha, beta, gamma = rng.normal(0, 0.01, 3)
    k = 1 + rng.normal(0, 0.02, 3)
    o = rng.normal(0, 300, 3)
    p_mat = paper_p(alpha, beta, gamma)
    axis_model = bool(rng.random() < 0.3)
    mix = p_mat.T if axis_model else np.linalg.inv(p_mat)
    extra_body = np.zeros((n, 3))  # fields added in the body frame before the sensor's errors
    offset_t = np.tile(o, (n, 1))
    scale_t = np.tile(k, (n, 1))
    b_seen = b_body.copy()

    def pick(pool, m):
        return list(rng.choice(pool, size=m, replace=False))

    if category in ("single", "fixed"):
        chosen = pick(("temperature", "field_drift", "offset_drift", "nonlinearity", "outliers", "lag"), 1)
    elif category == "pair":
        chosen = pick(("temperature", "field_drift", "offset_drift", "nonlinearity", "outliers", "lag"), 2)
    elif category == "triple":
        chosen = pick(("temperature", "field_drift", "nonlinearity", "outliers", "lag"), 3)
    elif category == "outside_plus":
        chosen = pick(OUTSIDE[:9], 1) + pick(("temperature", "nonlinearity", "outliers"), 1)
    elif category == "outside":
        chosen = pick(OUTSIDE, 1)
    else:
        chosen = []
    if kind == "fixed":
        chosen = [c for c in chosen if c in ("temperature", "field_drift", "offset_drift", "outliers")]
    snr = float(rng.uniform(8.0, 20.0))
    amp = snr * noise  # each effect's size in the residual, nT
    for name in chosen:
        if name == "temperature":
            dtemp = temp - temp.mean()
            scale_t = scale_t * (1 + (amp / f_earth) * dtemp[:, None] / np.ptp(dtemp) * rng.choice([-1, 1], 3) * 2)
            offset_t = offset_t + amp * 2 * dtemp[:, None] / np.ptp(dtemp) * rng.normal(0, 1, 3)
            confound.append(("temperature", "offset_drift"))
            confound.append(("temperature", "field_drift"))
        elif name == "field_drift":  # the ambient field changes; the reference does not follow
            drift = amp * 2 * (np.sin(2 * np.pi * rng.uniform(0.3, 1.5) * u + rng.uniform(0, 6)))
            b_seen = b_seen * (1 + drift / f_earth)[:, None]
        elif name == "offset_drift":
            offset_t = offset_t + amp * 2 * smooth_step(u)[:, None] * rng.normal(0, 1, 3)
            confound.append(("offset_drift", "temperature"))
        elif name == "nonlinearity":
            c2 = rng.normal(0, 1, 3) * amp * 2
            c3 = rng.normal(0, 1, 3) * amp * 2
            x = b_body / f_earth
            extra_body += c2 * x * x + c3 * x ** 3
        elif name == "outliers":
            m = max(3, n // 60)
            rows = rng.choice(n, m, replace=False)
            notes["outlier_rows"] = rows.tolist()
            spikes = np.zeros((n, 3))
            spikes[rows] = rng.normal(0, 1, (m, 3)) * noise * rng.uniform(40, 200)
            extra_body += spikes
        elif name == "lag":  # one axis sampled late: the others interpolated at the earlier time
            dt = float(rng.uniform(0.3, 1.0)) * span / n
            ax = int(rng.integers(0, 3))
            b_seen[:, ax] = np.interp(t - dt, t, b_seen[:, ax])
            notes["lag_s"] = dt
        # effects outside the library
        elif name == "heading_field":  # a platform iron that turns with heading only (sensor tilts on a gimbal)
            tilt = rotation(np.zeros(n), pitch, roll)
            extra_body += np.einsum("nji,j->ni", tilt, rng.normal(0, 1, 3)) * amp * 1.5
        elif name == "rotating_iron":  # a rotor in the body spinning at its own rate
            w = 2 * np.pi * rng.uniform(2, 6) / span
            a0 = rng.normal(0, 1, 3) * amp * 1.5
            extra_body += np.column_stack([a0[0] * np.cos(w * t), a0[0] * np.sin(w * t), np.full(n, a0[2])])
        elif name == "switch_on":
            t_on = t[0] + float(rng.uniform(0.3, 0.7)) * span
            extra_body += (t >= t_on)[:, None] * rng.normal(0, 1, 3) * amp * 2
            notes["switch_on_s"] = t_on
        elif name == "gravity_field":  # a pendulous part: its field in the body frame follows the gravity direction
            # (a field linear in g_body is a constant world vector, which a scale absorbs: the part swings, so its
            # field grows with the tilt)
            tilt = np.sqrt(np.clip(g_body[:, 0] ** 2 + g_body[:, 1] ** 2, 0, None))
            extra_body += (tilt[:, None] * g_body) * rng.normal(0, 1, 3) * amp * 3
        elif name == "lagged_soft_iron":
            tau = float(rng.uniform(5, 30)) * span / n
            induced = np.empty_like(b_body)
            induced[0] = b_body[0]
            for i in range(1, n):  # first-order response to the field seen
                a = np.exp(-(t[i] - t[i - 1]) / tau)
                induced[i] = a * induced[i - 1] + (1 - a) * b_body[i]
            extra_body += (induced - b_body) * 0.03 * rng.normal(1, 0.2, 3)
        elif name == "gradient":  # sensor on a lever arm in a gradient field
            g = rng.normal(0, 1, (3, 3))
            g = (g + g.T) / 2
            g -= np.trace(g) / 3 * np.eye(3)
            arm = rng.normal(0, 1, 3)
            pos_world = np.einsum("nij,j->ni", rot, arm)
            dbw = pos_world @ g.T
            dbw *= amp * 2 / max(np.std(dbw), 1e-9)
            extra_body += np.einsum("nji,nj->ni", rot, dbw)
        elif name == "eddy":  # eddy currents oppose the change of the field seen in the body
            db = np.gradient(b_body, t, axis=0)
            extra_body += -db * (amp * 2 / max(np.std(db), 1e-9))
        elif name == "hysteresis":  # magnetization lags the field's history on each axis
            direction = np.sign(np.gradient(b_body, t, axis=0))
            extra_body += direction * amp * 1.5
        elif name == "clipping":  # an ADC limit just below the largest readings
            notes["clip"] = True
        elif name == "coloured_noise":
            extra_body += np.column_stack([pink_noise(n, rng) for _ in range(3)]) * noise * 4
        elif name == "hum":  # mains hum aliased to a low frequency on one axis
            f_alias = rng.uniform(5, 20) / span
            hum = np.zeros((n, 3))
            hum[:, int(rng.integers(0, 3))] = amp * 2 * np.sin(2 * np.pi * f_alias * t)
            extra_body += hum
        elif name == "temp_alignment":  # the angles change with temperature
            dtemp = (temp - temp.mean()) / np.ptp(temp)
            da = (amp * 3 / f_earth) * dtemp
            p_t = np.stack([paper_p(alpha + d, beta - d, gamma + 0.5 * d) for d in da])
            mix_t = np.transpose(p_t, (0, 2, 1)) if axis_model else np.linalg.inv(p_t)
            b_seen = np.einsum("nij,nj->ni", mix_t @ np.linalg.inv(mix), b_seen)
        if name in LIBRARY:
            present.append(name)
        elif name in OUTSIDE:
            outside.append(name)

    readings = np.einsum("ij,nj->ni", mix, b_seen + extra_body) * scale_t + offset_t
    readings += noise * rng.standard_normal((n, 3))
    if "clipping" in outside:
        limit = np.percentile(np.abs(readings), 93)
        readings = np.clip(readings, -limit, limit)
    lsb = float(rng.choice([0.0, 0.0, 1.0, 3.0])) if category == "clean" else 0.0
    if lsb:
        readings = np.round(readings / lsb) * lsb
        notes["lsb_nT"] = lsb
    held = 0.0
    if category == "clean" and rng.random() < 0.3:  # a logger that repeats its last value
        hold = rng.random(n) < 0.3
        hold[0] = False
        idx = np.maximum.accumulate(np.where(hold, 0, np.arange(n)))
        readings = readings[idx]
        held = float(hold.mean())
        notes["held_fraction"] = held
    f_ref = np.full(n, f_earth)
    acceptable = set(present) | {a for e in outside for a in ACCEPTABLE_FOR.get(e, ())}
    if "temp_alignment" in outside:
        present.append("temperature")  # it is a temperature effect: naming it is right, missing it a miss
        outside.remove("temp_alignment")
        confound.append(("temperature", "offset_drift"))
    expect_unexplained = bool(outside)
    return Case(index=index, category=category, raw_nT=readings, f_ref_nT=f_ref, t_s=t, temp_C=temp,
                gravity=g_body if rng.random() < 0.5 else None, present=tuple(present), outside=tuple(outside),
                acceptable=tuple(sorted(acceptable)), expect_unexplained=expect_unexplained,
                confoundable=tuple(confound), schedule=kind, notes=notes)

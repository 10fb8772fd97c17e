"""The blind check of the diagnosis, with cases written independently of the effect classes it fits:
its own attitude generator (integrated random angular rates), its own sensor (a general 3x3 response
near identity plus offset), its own parametrization of every effect, and a drawn noise level (0.3-5 nT),
sample count (200-3000), attitude coverage (full, hemisphere, band) and duration.  Every case has a
``temp`` column (it carries an effect only when the label says so).  The diagnosis is always told the
``nine`` base model (a fixed choice, not taken from the label).

Kinds: ``none``; in-library singles (temperature with or without a thermal lag, field_drift,
nonlinearity as a polynomial or as tanh saturation, outliers as Student-t bursts, offset_drift, lag as a
true time shift); look-alikes (a temperature that follows time, saturation); pairs; and three kinds
outside the library (a degree 7-9 attitude ripple, a periodic interference fixed in the sensor frame,
hysteresis).  Each effect's size is drawn as a multiple (3-12) of the noise in the total field."""
from __future__ import annotations

import numpy as np

from magbench.simulate.dataset import Dataset

BLIND_SEED = 1000
SINGLES = ("temperature", "field_drift", "nonlinearity", "outliers", "offset_drift", "lag")
PAIRS = (("temperature", "outliers"), ("offset_drift", "field_drift"), ("nonlinearity", "temperature"),
         ("lag", "outliers"), ("field_drift", "nonlinearity"))
OUTSIDE = ("ripple", "interference", "hysteresis")
SNR_RANGE = (3.0, 12.0)


def blind_kinds() -> tuple[str, ...]:
    """The labels of the cycle: none, the singles, the pairs (joined by '+'), the kinds outside."""
    return ("none",) + SINGLES + tuple("+".join(p) for p in PAIRS) + tuple(f"outside:{k}" for k in OUTSIDE)


def _attitudes(rng, n, t, coverage):
    rate = np.cumsum(rng.normal(0, 1, (n, 3)), axis=0)
    rate = rate / np.std(rate, axis=0) * rng.uniform(0.5, 2.0) * (30.0 / max(t[-1], 1.0))
    if coverage == "band":
        rate[:, :2] *= 0.15
    elif coverage == "hemisphere":
        rate[:, 2] *= 0.4
    # attitude i is step i (the rotation vector rate_i dt) after attitude i - 1: q_i = s_i s_(i-1) ... s_1, the
    # running products of the steps' quaternions by a doubling scan (log2 n whole-array products)
    from scipy.spatial.transform import Rotation  # here: the diagnosis imports this module, and never draws cases

    q = np.empty((n, 4))
    q[0] = (0.0, 0.0, 0.0, 1.0)
    q[1:] = Rotation.from_rotvec(rate[1:] * np.diff(t)[:, None]).as_quat()
    shift = 1
    while shift < n:
        q[shift:] = _quaternion_product(q[shift:], q[:-shift])
        shift *= 2
    return Rotation.from_quat(q)


def _quaternion_product(p, q):
    """Row by row p q (scalar last, as scipy's Rotation): the rotation q followed by p."""
    pv, pw, qv, qw = p[:, :3], p[:, 3:], q[:, :3], q[:, 3:]
    return np.concatenate([pw * qv + qw * pv + np.cross(pv, qv), pw * qw - np.sum(pv * qv, axis=1, keepdims=True)],
                          axis=1)


def _temperature(rng, t):
    span = rng.uniform(2.0, 25.0)
    u = t / t[-1]
    shape = rng.integers(3)
    if shape == 0:
        prof = 1 - np.exp(-rng.uniform(1, 5) * u)
    elif shape == 1:
        prof = np.sin(2 * np.pi * rng.uniform(0.5, 3) * u + rng.uniform(0, 6.3))
    else:
        prof = np.cumsum(rng.normal(size=len(t)))
        prof = np.convolve(prof, np.ones(25) / 25, mode="same")
    prof = (prof - prof.min()) / max(np.ptp(prof), 1e-12)
    return rng.uniform(5, 30) + span * prof


def _lagged(t, x, tau):
    """x (1-D) through a first-order lag of time constant tau: a recurrence, looped over Python floats."""
    a = (1 - np.exp(-np.diff(t) / tau)).tolist()
    values = np.asarray(x, dtype=float).tolist()
    out = values[:1]
    for ai, xi in zip(a, values[1:]):
        out.append(out[-1] + ai * (xi - out[-1]))
    return np.array(out)


def _effect(kind, rng, t, temp, b_sensor, lin, f):
    """(vector change of the readings, change of the field unseen by the reference) of one effect."""
    n = len(t)
    u = t / t[-1]
    zero = np.zeros_like(lin)
    if kind == "temperature":
        tt = _lagged(t, temp, rng.uniform(0.02, 0.2) * t[-1]) if rng.random() < 0.5 else temp
        dtemp = tt - tt.mean()
        return rng.normal(0, 1, 3) * dtemp[:, None] + 1e-4 * rng.normal(0, 1, 3) * dtemp[:, None] * lin, None
    if kind == "field_drift":
        drift = sum(rng.normal() * np.sin(2 * np.pi * rng.uniform(0.3, 3) * u + rng.uniform(0, 6.3)) for _ in range(3))
        direction = b_sensor / np.linalg.norm(b_sensor, axis=1, keepdims=True)
        return drift[:, None] * direction, drift
    if kind == "nonlinearity":
        x = lin / f
        if rng.random() < 0.5:
            return f * (rng.normal(0, 1, 3) * x**2 + rng.normal(0, 1, 3) * x**3), None
        sat = rng.uniform(1.5, 3.0)
        return f * (np.tanh(sat * x) / sat - x), None  # soft saturation (a look-alike of the cubic)
    if kind == "outliers":
        vec = zero.copy()
        k = max(5, int(rng.uniform(0.01, 0.06) * n))
        idx = rng.choice(n, k, replace=False)
        vec[idx] = rng.standard_t(2, (k, 3))
        return vec, None
    if kind == "offset_drift":
        return np.column_stack([np.polyval(rng.normal(0, 1, 3), u) + rng.normal() * np.sin(np.pi * u * rng.uniform(0.5, 1.5))
                                for _ in range(3)]), None
    if kind == "lag":
        shift = rng.normal(0, 1, 3) * np.median(np.diff(t)) * 2
        out = np.column_stack([np.interp(t - shift[a], t, lin[:, a]) for a in range(3)])
        return out - lin, None
    if kind == "ripple":
        unit = lin / np.linalg.norm(lin, axis=1, keepdims=True)
        deg = int(rng.integers(7, 10))
        az, el = np.arctan2(unit[:, 1], unit[:, 0]), np.arcsin(np.clip(unit[:, 2], -1, 1))
        return (np.cos(deg * az + rng.uniform(0, 6.3)) * np.cos(deg * el))[:, None] * unit, None
    if kind == "interference":
        period = t[-1] / rng.uniform(30, 80)
        return np.sin(2 * np.pi * t / period)[:, None] * rng.normal(0, 1, 3), None
    if kind == "hysteresis":
        du = np.gradient(lin, t, axis=0)
        return np.tanh(du / (np.std(du, axis=0) * 0.1)) * rng.normal(0, 1, 3), None
    raise ValueError(kind)


def blind_dataset(i: int) -> tuple[str, str, Dataset]:
    """Case i: (label, the base model the diagnosis is told, data)."""
    rng = np.random.default_rng(BLIND_SEED + i)
    kinds = blind_kinds()
    label = kinds[i % len(kinds)]
    n = int(np.exp(rng.uniform(np.log(200), np.log(3000))))
    sigma = float(np.exp(rng.uniform(np.log(0.3), np.log(5.0))))
    duration = rng.uniform(600, 3600)
    t = np.sort(rng.uniform(0, duration, n))
    t[0] = 0.0
    coverage = rng.choice(["full", "hemisphere", "band"], p=[0.5, 0.3, 0.2])
    rot = _attitudes(rng, n, t, coverage)
    f = rng.uniform(35000, 60000)
    inc, dec = np.radians(rng.uniform(-70, 70)), np.radians(rng.uniform(0, 360))
    b_ned = f * np.array([np.cos(inc) * np.cos(dec), np.cos(inc) * np.sin(dec), np.sin(inc)])
    b_sensor = rot.apply(b_ned, inverse=True)
    a = np.eye(3) + rng.normal(0, 0.01, (3, 3))
    offset = rng.normal(0, 300, 3)
    lin = b_sensor @ a.T
    temp = _temperature(rng, t)
    raw = lin.copy()
    names = [] if label == "none" else label.removeprefix("outside:").split("+")
    for name in names:
        vec, _ = _effect(name, rng, t, temp, b_sensor, lin, f)
        unit = lin / np.linalg.norm(lin, axis=1, keepdims=True)
        proj = np.einsum("ij,ij->i", vec, unit)
        if name == "outliers":
            scale = rng.uniform(20, 100) * sigma / max(np.median(np.abs(proj[proj != 0])), 1e-12)
        else:
            scale = rng.uniform(*SNR_RANGE) * sigma / max(np.sqrt(np.mean((proj - proj.mean()) ** 2)), 1e-12)
        raw = raw + scale * vec
    raw = raw + offset + rng.normal(0, sigma, raw.shape)
    data = Dataset(raw, f_ref_nT=np.full(n, f), t_s=t, temp_C=temp,
                   meta={"blind_case": i, "noise_nT": sigma, "coverage": str(coverage)})
    return label, "nine", data


def classify(label: str, verdict: str) -> str:
    """right / partly / honest_unexplained / wrong / missed (none or insufficient_data on an effect) /
    false_alarm (an effect or unexplained on clean data).  An ``a|b`` (the data cannot tell a from b) names
    whichever of the two is in the label, and is wrong when neither is."""
    parts = verdict.split("+")
    unexplained = "unexplained" in parts
    truth = set() if label == "none" or label.startswith("outside:") else set(label.split("+"))
    named = set()
    for part in parts:
        if part not in ("unexplained", "none", "insufficient_data"):
            group = set(part.split("|"))
            named |= (group & truth) or {part}
    if label == "none":
        return "right" if verdict == "none" else ("missed" if verdict == "insufficient_data" else "false_alarm")
    if label.startswith("outside:"):
        if not named:
            return "right" if unexplained else "missed"
        return "partly" if unexplained else "wrong"
    if not named:
        return "honest_unexplained" if unexplained else "missed"
    if named == truth:
        return "right" if not unexplained else "partly"
    return "partly" if named & truth else "wrong"


def category(label: str) -> str:
    if label == "none":
        return "clean"
    if label.startswith("outside:"):
        return "outside the library"
    return "pair" if "+" in label else "single"

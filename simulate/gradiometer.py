"""Seed 001's two-fluxgate magnetic gradiometer: the sensor pair and its simulator.

Seed 001: Jin Huanghuang, Zhuang Zhihong, Wang Hong, "基于磁梯度测量的磁校准方法" (a magnetic
calibration method based on magnetic gradient measurement), Aero Weaponry 2024 (1): 117-121,
DOI 10.12132/ISSN.1673-5048.2023.0100.  Equation numbers below are the paper's.

One sensor (section 1, eq. 1-4): ``Bm = K · R · Br + Bh + Bn`` (eq. 4), with ``R`` the
non-orthogonality matrix of Fig. 1 (OZ' = OZ; OY' in the YOZ plane at angle alpha from OY; OX' at
angle beta from the XOZ plane, its projection at angle gamma from OX; eq. 1-2), ``K`` the diagonal
scale-factor matrix (eq. 3), ``Bh`` the hard-iron/zero-offset vector and ``Bn`` white noise.

Two sensors on one rigid body (section 2, eq. 5-7): each sensor's ideal frame is tilted from the
mechanical frame by its installation error (``R1a``, ``R2a``), and sensor 2's mechanical frame by the
alignment error ``Rg`` between the two sensors, so that

    M1 = R1a (K1 R1)^-1,   M2 = Rg R2a (K2 R2)^-1          (eq. 6-7)

map each sensor's readings (less its offset) to the common body frame.  With a zero geomagnetic
gradient both sensors see the same ambient field at the same time, so its fluctuation in time (up to
200 nT, Fig. 2) cancels in the gradient while it corrupts any single-sensor fit that assumes a
constant magnitude.

Simulation conditions (section 4.1) and what we chose where the paper is silent (marked *ours*):
inclination 50 deg, declination -5 deg, total field 50 000 nT (*ours*; the paper's value is in its
Fig. 6); sensor 1 non-orthogonality 0.1 deg, scale error 0.5 %, B1h = [100, 100, 0] nT, installation
(Z axis) error 0.05 deg; sensor 2 non-orthogonality 0.05 deg, scale error 0.4 %, B2h = [-200, 100, 0] nT,
installation error 0.05 deg; Rg = 0.5 deg about X then 0.5 deg about Y.  The signs of the scale errors
and the axes of the installation tilts are *ours*.  The noise level is not given (the paper neglects
noise, "averaging many samples"); see ``DEFAULT_NOISE_NT``.

The calibrations are in ``magbench.calibrators.methods.gradiometer``, the experiment and its command in
``magbench.benchmarks.gradiometer``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from magbench import paper
from magbench.errors import InputError, check_int, check_nonneg  # noqa: F401  (check_int, check_nonneg: this module's API too)

from .attitude import full_sphere, tumble
from .dataset import readonly_copy
from .field import ConstantField, VaryingField

DEFAULT_FIELD = ConstantField.from_angles(50_000.0, 50.0, -5.0)
"""Section 4.1: inclination 50 deg, declination -5 deg (east positive); 50 000 nT is ours."""

# Seed 001's record settings, defined once in magbench.paper (the command line reads them without
# importing the simulator)
DEFAULT_NOISE_NT = paper.GRADIOMETER_NOISE_NT
DEFAULT_FLUCTUATION_NT = paper.GRADIOMETER_FLUCTUATION_NT
DEFAULT_POINTS = paper.GRADIOMETER_POINTS
DEFAULT_DURATION_S = paper.GRADIOMETER_DURATION_S
MIN_POINTS = paper.GRADIOMETER_MIN_POINTS
MAX_POINTS = 1_000_000
"""The most attitudes a gradiometer record is simulated with: 1e6 take about 6 s and 0.4 GB; 1e8 would need about
37 GB (``--points`` had no limit)."""

ATTITUDES = ("tumble", "sphere")
"""Attitude sequences the simulator offers (see ``simulate_gradiometer``)."""


def nonorthogonality_matrix(alpha, beta, gamma) -> np.ndarray:
    """Seed 001, eq. 1 (Fig. 1): the rows are the sensor's actual axes OX', OY', OZ' in its ideal
    orthogonal frame, so ``Bm = R · Br`` projects the field on them (eq. 2 is its small-angle form
    ``[[1, beta, gamma], [0, 1, alpha], [0, 0, 1]]``)."""
    ca, sa, cb, sb, cg, sg = (np.cos(alpha), np.sin(alpha), np.cos(beta), np.sin(beta),
                              np.cos(gamma), np.sin(gamma))
    return np.array([[cb * cg, sb, cb * sg], [0.0, ca, sa], [0.0, 0.0, 1.0]])


def _tuple3(v, name) -> tuple:
    t = tuple(float(x) for x in np.ravel(v))
    if len(t) != 3 or not all(math.isfinite(x) for x in t):
        raise InputError(f"{name} must be 3 finite numbers, got {v!r}")
    return t


@dataclass(frozen=True)
class FluxgateErrors:
    """One sensor's static errors (seed 001, eq. 1-4) and its installation error (eq. 6).

    ``nonorth_deg`` = (alpha, beta, gamma) of Fig. 1; ``scale`` = (Kx, Ky, Kz) of eq. 3 (dimensionless);
    ``hard_iron_nT`` = Bh of eq. 4; ``mount_deg`` = rotation vector (degrees) of the installation
    error R_ia (sensor ideal frame -> mechanical frame).
    """

    nonorth_deg: tuple = (0.0, 0.0, 0.0)
    scale: tuple = (1.0, 1.0, 1.0)
    hard_iron_nT: tuple = (0.0, 0.0, 0.0)
    mount_deg: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        for name in ("nonorth_deg", "scale", "hard_iron_nT", "mount_deg"):
            object.__setattr__(self, name, _tuple3(getattr(self, name), name))
        if min(self.scale) <= 0:
            raise InputError(f"scale factors must be positive, got {self.scale}")

    @property
    def forward(self) -> np.ndarray:
        """K · R of eq. 4: ideal-frame field -> readings before offset."""
        return np.diag(self.scale) @ nonorthogonality_matrix(*np.radians(self.nonorth_deg))

    @property
    def mount(self) -> np.ndarray:
        """R_ia of eq. 6 (sensor ideal frame -> mechanical frame)."""
        return Rotation.from_rotvec(np.radians(self.mount_deg)).as_matrix()

    def as_dict(self) -> dict:
        return {"nonorth_deg": list(self.nonorth_deg), "scale": list(self.scale),
                "hard_iron_nT": list(self.hard_iron_nT), "mount_deg": list(self.mount_deg)}


@dataclass(frozen=True)
class GradiometerParams:
    """Two sensors on one rigid body plus the alignment error Rg between them (seed 001, eq. 6).

    ``alignment_deg`` = (about X, about Y): Rg is a rotation about X, then about Y (section 4.1).
    The body (mechanical) frame is sensor 1's mechanical frame.  The true calibration of eq. 10 is
    (``m1``, ``m2``, ``sensor1.hard_iron_nT``, ``sensor2.hard_iron_nT``).
    """

    sensor1: FluxgateErrors = field(default_factory=FluxgateErrors)
    sensor2: FluxgateErrors = field(default_factory=FluxgateErrors)
    alignment_deg: tuple = (0.0, 0.0)

    def __post_init__(self):
        a = tuple(float(x) for x in np.ravel(self.alignment_deg))
        if len(a) != 2 or not all(math.isfinite(x) for x in a):
            raise InputError(f"alignment_deg must be 2 finite angles (about X, then Y), got {self.alignment_deg!r}")
        object.__setattr__(self, "alignment_deg", a)

    @classmethod
    def paper(cls) -> GradiometerParams:
        """Section 4.1's values (Mag-03MS typical errors); signs and tilt axes are ours."""
        s1 = FluxgateErrors((0.1, 0.1, 0.1), (1.005, 0.995, 1.005), (100.0, 100.0, 0.0), (0.05, 0.0, 0.0))
        s2 = FluxgateErrors((0.05, 0.05, 0.05), (0.996, 1.004, 1.004), (-200.0, 100.0, 0.0), (0.0, 0.05, 0.0))
        return cls(s1, s2, (0.5, 0.5))

    @property
    def alignment(self) -> np.ndarray:
        """Rg: rotation about X then about Y (extrinsic), sensor 2 mechanical frame -> body frame."""
        return Rotation.from_euler("xy", self.alignment_deg, degrees=True).as_matrix()

    def to_sensor(self, i: int) -> np.ndarray:
        """Body field -> sensor i's ideal frame: R1a^T, or (Rg R2a)^T."""
        if i == 1:
            return self.sensor1.mount.T
        return (self.alignment @ self.sensor2.mount).T

    def forward(self, i: int) -> np.ndarray:
        """Body field -> readings of sensor i before offset: K_i R_i (to-sensor rotation) (eq. 4, 6)."""
        s = self.sensor1 if i == 1 else self.sensor2
        return s.forward @ self.to_sensor(i)

    @property
    def m1(self) -> np.ndarray:
        """M1 = R1a (K1 R1)^-1 (eq. 6-7)."""
        return np.linalg.inv(self.forward(1))

    @property
    def m2(self) -> np.ndarray:
        """M2 = Rg R2a (K2 R2)^-1 (eq. 6-7)."""
        return np.linalg.inv(self.forward(2))

    @property
    def h1_nT(self) -> np.ndarray:
        """B1h of eq. 4, 10."""
        return np.array(self.sensor1.hard_iron_nT)

    @property
    def h2_nT(self) -> np.ndarray:
        """B2h of eq. 4, 10."""
        return np.array(self.sensor2.hard_iron_nT)

    def as_dict(self) -> dict:
        return {"sensor1": self.sensor1.as_dict(), "sensor2": self.sensor2.as_dict(),
                "alignment_deg": list(self.alignment_deg), "m1": self.m1.tolist(), "m2": self.m2.tolist()}


@dataclass(frozen=True)
class GradiometerDataset:
    """A simulated record: both sensors' readings at the same times (read-only arrays), with the ground
    truth (``params``, ``field_body_nT``)."""

    t_s: np.ndarray                  # sample times (n,)
    raw1_nT: np.ndarray              # sensor 1's readings B1m (n, 3)
    raw2_nT: np.ndarray              # sensor 2's readings B2m (n, 3)
    field_body_nT: np.ndarray        # true ambient field in the body frame at each sample (n, 3)
    params: GradiometerParams        # the true sensor errors
    field_ned_nT: tuple              # the constant part of the ambient field (NED)
    fluctuation_nT: float
    noise_nT: float
    seed: int | None
    attitude: str

    def __post_init__(self):
        for name in ("t_s", "raw1_nT", "raw2_nT", "field_body_nT"):
            object.__setattr__(self, name, readonly_copy(getattr(self, name)))

    def __len__(self) -> int:
        return len(self.t_s)

    @property
    def f_ref_nT(self) -> float:
        """The constant reference magnitude a single-sensor fit assumes (the base field's), nT."""
        return float(np.linalg.norm(self.field_ned_nT))

    @property
    def f_true_nT(self) -> np.ndarray:
        """The true magnitude of the ambient field at each sample (it fluctuates), nT."""
        return np.linalg.norm(self.field_body_nT, axis=1)


def simulate_gradiometer(params: GradiometerParams | None = None, n_points: int = DEFAULT_POINTS,
                         fluctuation_nT: float = DEFAULT_FLUCTUATION_NT, noise_nT: float = DEFAULT_NOISE_NT,
                         field: ConstantField = DEFAULT_FIELD, duration_s: float = DEFAULT_DURATION_S,
                         attitude: str = "tumble", seed: int | None = 0) -> GradiometerDataset:
    """The rigid two-sensor body rotated through ``n_points`` attitudes over ``duration_s`` in a uniform
    ambient field fluctuating by up to ``fluctuation_nT`` (seed 001, Fig. 2 and 6), each reading
    ``B_im = K_i R_i B_ir + B_ih + noise`` (eq. 4) with ``B_1r = R1a^T B``, ``B_2r = (Rg R2a)^T B``
    (eq. 6).  ``attitude``: ``tumble`` (a smooth random rotation path; the field changes while the body
    turns, as in a real rotation procedure) or ``sphere`` (independent uniform rotations).  ``params``
    defaults to the paper's (``GradiometerParams.paper``)."""
    params = GradiometerParams.paper() if params is None else params
    n = check_int(n_points, "n_points", MIN_POINTS)
    if n > MAX_POINTS:  # a typed zero too many: refused before gigabytes of simulation
        raise InputError(f"n_points must be at most {MAX_POINTS:,}, got {n:,}")
    fluct = check_nonneg(fluctuation_nT, "fluctuation_nT")
    noise = check_nonneg(noise_nT, "noise_nT")
    duration = check_nonneg(duration_s, "duration_s")
    if duration <= 0:
        raise InputError("duration_s must be positive")
    if attitude not in ATTITUDES:
        raise InputError(f"attitude must be one of {', '.join(ATTITUDES)}, got {attitude!r}")
    rng = np.random.default_rng(seed)
    att = tumble(n, rng, duration_s=duration) if attitude == "tumble" else full_sphere(n, rng, duration / n)
    b_ned = VaryingField(field, amplitude_nT=fluct).at(att.t_s, rng) if fluct > 0 else field.at(att.t_s)
    b_body = att.rotation.apply(b_ned, inverse=True)
    noise1, noise2 = rng.normal(0.0, 1.0, size=(2, n, 3)) * noise
    raw1 = b_body @ params.forward(1).T + params.h1_nT + noise1
    raw2 = b_body @ params.forward(2).T + params.h2_nT + noise2
    return GradiometerDataset(att.t_s, raw1, raw2, b_body, params, field.vector_nT, fluct, noise, seed, attitude)

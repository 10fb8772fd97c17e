"""Attitude schedules: the orientation of the sensor body in the North-East-Down frame.

Each schedule returns an ``Attitudes``: body-to-NED rotations, sample times and, where the schedule has
one, the turntable/vehicle heading.  The field seen by the sensor is ``B_body = R^T · B_ned``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from scipy.spatial.transform import Rotation


def _rotation():
    """SciPy's ``Rotation``, imported when a schedule is first built (scipy.spatial costs about 0.1 s, which
    a command that only calibrates a file should not pay)."""
    from scipy.spatial.transform import Rotation

    return Rotation


@dataclass(frozen=True)
class Attitudes:
    rotation: Rotation  # body -> NED, one per sample
    t_s: np.ndarray
    heading_deg: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.t_s)

    def body_field(self, b_ned_nT: np.ndarray) -> np.ndarray:
        """B_body = R^T · B_ned for each sample (``b_ned_nT`` of shape (3,) or (n, 3))."""
        b = np.array(np.broadcast_to(np.asarray(b_ned_nT, dtype=float), (len(self), 3)))
        return self.rotation.apply(b, inverse=True)


def turntable(n_steps: int = 36, step_deg: float = 10.0, tilt_deg: float = 0.0, tilt_azimuth_deg: float = 0.0,
              start_deg: float = 0.0, dwell_s: float = 10.0) -> Attitudes:
    """Seed 000, section 3: a non-magnetic turntable turned in ``step_deg`` steps about its axis.

    The sensor's Z axis lies along the table axis; ``tilt_deg`` tilts that axis from the vertical
    towards the azimuth ``tilt_azimuth_deg``.
    """
    heading = start_deg + step_deg * np.arange(n_steps)
    spin = _rotation().from_euler("z", heading[:, None], degrees=True)
    tilt = _rotation().from_euler("zyz", [tilt_azimuth_deg, tilt_deg, -tilt_azimuth_deg], degrees=True)
    return Attitudes(tilt * spin, dwell_s * np.arange(n_steps, dtype=float), np.mod(heading, 360.0))


def full_sphere(n: int, rng: np.random.Generator, dt_s: float = 1.0) -> Attitudes:
    """Uniformly distributed random rotations (Haar measure)."""
    return Attitudes(_rotation().random(n, random_state=rng), dt_s * np.arange(n, dtype=float))


def cap(n: int, rng: np.random.Generator, max_tilt_deg: float = 90.0, dt_s: float = 1.0) -> Attitudes:
    """Body Z axis uniform on the spherical cap within ``max_tilt_deg`` of the vertical (90 = hemisphere),
    heading uniform."""
    cos_max = np.cos(np.radians(max_tilt_deg))
    tilt = np.degrees(np.arccos(rng.uniform(cos_max, 1.0, n)))
    azimuth = rng.uniform(0.0, 360.0, n)
    heading = rng.uniform(0.0, 360.0, n)
    rot = _rotation().from_euler("zyz", np.column_stack([azimuth, tilt, heading - azimuth]), degrees=True)
    return Attitudes(rot, dt_s * np.arange(n, dtype=float), np.mod(heading, 360.0))


def vehicle(n: int, rng: np.random.Generator, pitch_roll_deg: float = 5.0, turns: float = 1.0,
            dt_s: float = 1.0) -> Attitudes:
    """Seed 004's regime: a land vehicle driving ``turns`` full circles (yaw covers 360 degrees) with
    pitch and roll of a few degrees (smooth, bounded by ``pitch_roll_deg``)."""
    t = dt_s * np.arange(n, dtype=float)
    yaw = np.linspace(0.0, 360.0 * turns, n, endpoint=False) + rng.uniform(0, 360)
    phase = rng.uniform(0, 2 * np.pi, 4)
    u = np.linspace(0, 2 * np.pi * max(turns, 1.0), n, endpoint=False)
    pitch = pitch_roll_deg * (0.6 * np.sin(3 * u + phase[0]) + 0.4 * np.sin(7 * u + phase[1]))
    roll = pitch_roll_deg * (0.6 * np.sin(2 * u + phase[2]) + 0.4 * np.sin(5 * u + phase[3]))
    rot = _rotation().from_euler("ZYX", np.column_stack([yaw, pitch, roll]), degrees=True)
    return Attitudes(rot, t, np.mod(yaw, 360.0))


def tumble(n: int, rng: np.random.Generator, duration_s: float = 600.0, n_harmonics: int = 4) -> Attitudes:
    """A smooth tumble in time: the rotation vector follows a random smooth path (sum of sinusoids)
    whose length sweeps [0, pi], so the body visits all orientations over the record."""
    t = np.linspace(0.0, duration_s, n, endpoint=False)
    u = t / duration_s
    k = np.arange(1, n_harmonics + 1)
    coef = rng.normal(size=(3, n_harmonics)) / k
    phase = rng.uniform(0, 2 * np.pi, size=(3, n_harmonics))
    path = np.sum(coef[None] * np.sin(2 * np.pi * k[None, None] * u[:, None, None] + phase[None]), axis=2)
    path /= np.max(np.linalg.norm(path, axis=1))
    return Attitudes(_rotation().from_rotvec(np.pi * path), t)

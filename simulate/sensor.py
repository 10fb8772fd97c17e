"""The fluxgate error model of CONTRACT section 1 and of seed 000 (Lu et al. 2014, eq. 1-2).

Two forward conventions, both named:

* ``paper`` (default): ``raw = K · P^-1 · B + o + noise``; the correction ``B = P · K^-1 · (raw - o)``
  is exact (seed 000, eq. 2).
* ``axis_projection``: ``raw = K · A · B + o + noise`` with ``A = P^T`` (each reading is the projection
  of the field on a unit axis vector).  Its exact correction is ``(K A)^-1``, which is not lower
  triangular; reported in canonical form its angles have the opposite sign to first order.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from magbench.errors import InputError
from magbench.simulate.dataset import real_array  # the project's one conversion of numbers given by a caller

MODELS = ("offset", "diag", "angles", "nine")
"""Model names, simplest first: ``offset`` (ox, oy, oz; P = I, K = I: MATLAB magcal's ``eye``), ``diag``
(scales and offsets; P = I: magcal's ``diag``), ``angles`` (alpha, beta, gamma; K = I, o = 0: seed 000's
3-parameter model) and ``nine`` (angles + scales + offsets).  Every model is the nine-parameter vector
with some entries held at their neutral values (angles 0, scales 1, offsets 0): ``FREE[model]`` lists the
free entries, and ``embed``/``ErrorParams.to_vector`` map between a model's vector and the nine-vector."""

NINE_NAMES = ("alpha_rad", "beta_rad", "gamma_rad", "kx", "ky", "kz", "ox_nT", "oy_nT", "oz_nT")

FREE = {
    "offset": (6, 7, 8),
    "diag": (3, 4, 5, 6, 7, 8),
    "angles": (0, 1, 2),
    "nine": tuple(range(9)),
}
"""Indices of each model's free parameters in the nine-vector (the others are held at NEUTRAL)."""

NEUTRAL = (0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0)
"""The nine-vector of no correction: the values the fixed entries of a model are held at."""

PARAM_NAMES = {model: tuple(NINE_NAMES[i] for i in free) for model, free in FREE.items()}


def embed(x, model: str) -> np.ndarray:
    """A model's parameter vector(s) (p,) or (m, p) as nine-vector(s) (9,) or (m, 9): the linear embedding
    that holds the entries the model does not estimate at their neutral values."""
    if model not in FREE:
        raise ValueError(f"unknown model {model!r}; expected one of {MODELS}")
    x = np.asarray(x, dtype=float)
    if model == "nine":
        return x
    out = np.empty(x.shape[:-1] + (9,))
    out[...] = NEUTRAL
    out[..., list(FREE[model])] = x
    return out


def paper_matrix(alpha, beta, gamma) -> np.ndarray:
    """The correction matrix P(alpha, beta, gamma) of seed 000, eq. 2 (broadcasts over arrays).

    P = [[cos a cos g, 0, 0], [sin g, cos b, 0], [sin a cos g, sin b, 1]]
    """
    a, b, g = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (alpha, beta, gamma)))
    out = np.zeros(a.shape + (3, 3))
    cg = np.cos(g)
    out[..., 0, 0] = np.cos(a) * cg
    out[..., 1, 0] = np.sin(g)
    out[..., 2, 0] = np.sin(a) * cg
    out[..., 1, 1] = np.cos(b)
    out[..., 2, 1] = np.sin(b)
    out[..., 2, 2] = 1.0
    return out


def ul_factor(w: np.ndarray) -> np.ndarray:
    """Lower-triangular M with positive diagonal such that ``M^T M = W`` (W symmetric positive definite).

    With J the exchange matrix, ``J W J = L L^T`` (Cholesky) gives ``M = J L^T J``.
    """
    w = np.asarray(w, dtype=float)
    j = np.eye(3)[::-1]
    low = np.linalg.cholesky(j @ w @ j)
    return j @ low.T @ j


def _number(value, name: str) -> float:
    """``value`` as a finite float, else ``InputError`` naming ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise InputError(f"{name} must be finite, got {v}")
    return v


def _three_numbers(values, name: str) -> tuple[float, float, float]:
    """``values`` as three finite floats (x, y, z), else ``InputError`` naming ``name``."""
    try:
        items = tuple(values)
    except TypeError:
        raise InputError(f"{name} must be three numbers (x, y, z), got {values!r}") from None
    if len(items) != 3:
        raise InputError(f"{name} must be three numbers (x, y, z), got {len(items)}: {values!r}")
    a, b, c = (_number(v, name) for v in items)
    return a, b, c


def readings_array(raw_nT) -> np.ndarray:
    """Readings to correct as a float array of shape (n, 3) or (3,) (one reading), else ``InputError``: a (4, 3, 1)
    array had broadcast into (4, 3, 3), ``None`` had become a reading of NaN, a number a 3-vector, and a complex
    reading lost its imaginary part without a word (``dataset.real_array``, which it calls, refuses complex values and
    a None among numbers)."""
    if raw_nT is None or isinstance(raw_nT, (str, bytes)):
        raise InputError(f"readings to correct must be numbers of shape (n, 3) or (3,), got {type(raw_nT).__name__}")
    raw = real_array(raw_nT, "readings to correct")
    if raw.shape[-1:] != (3,) or raw.ndim > 2:
        raise InputError(f"readings to correct must have shape (n, 3) or (3,) (bx, by, bz), got shape {raw.shape}")
    return raw


@dataclass(frozen=True)
class ErrorParams:
    """The nine calibration parameters of CONTRACT section 1, in the paper's convention.

    ``matrix`` is the correction ``M = P · K^-1`` (lower triangular); ``correct(raw) = M (raw - o)``.
    """

    alpha_rad: float = 0.0
    beta_rad: float = 0.0
    gamma_rad: float = 0.0
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    offset_nT: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self):
        for name in ("scale", "offset_nT"):
            object.__setattr__(self, name, _three_numbers(getattr(self, name), name))
        for name in ("alpha_rad", "beta_rad", "gamma_rad"):
            object.__setattr__(self, name, _number(getattr(self, name), name))
        if not all(k > 0 for k in self.scale):
            raise InputError(f"scale must be three positive numbers (the axes' gains), got {self.scale}")

    @property
    def matrix(self) -> np.ndarray:
        """M = P(alpha, beta, gamma) · K^-1."""
        return paper_matrix(self.alpha_rad, self.beta_rad, self.gamma_rad) / np.asarray(self.scale)[None, :]

    def correct(self, raw_nT: np.ndarray) -> np.ndarray:
        """B = P · K^-1 · (raw - o) (CONTRACT section 1; seed 000 eq. 2 when K = I, o = 0)."""
        return (readings_array(raw_nT) - np.asarray(self.offset_nT)) @ self.matrix.T

    def to_vector(self, model: str = "nine") -> np.ndarray:
        """Parameter vector in the order of ``PARAM_NAMES[model]``."""
        if model not in FREE:
            raise ValueError(f"unknown model {model!r}; expected one of {MODELS}")
        nine = np.array([self.alpha_rad, self.beta_rad, self.gamma_rad, *self.scale, *self.offset_nT])
        return nine[list(FREE[model])]

    @classmethod
    def from_vector(cls, x, model: str = "nine") -> ErrorParams:
        """The parameters of a model's vector; the entries the model does not estimate are neutral."""
        x = embed(np.asarray(x, dtype=float), model).tolist()  # Python floats, as the fields hold them
        return cls(x[0], x[1], x[2], tuple(x[3:6]), tuple(x[6:9]))

    @classmethod
    def from_correction(cls, c: np.ndarray, offset_nT=(0.0, 0.0, 0.0)) -> ErrorParams:
        """Canonical decomposition of a general correction matrix C (CONTRACT section 1).

        W = C^T C is factored as W = M^T M with M lower triangular and positive diagonal; then
        kz = 1/M22, beta = atan2(M21, M11), ky = 1/hypot(M11, M21), kx = 1/|M[:,0]|,
        gamma = asin(M10 kx), alpha = atan2(M20, M00).  The orthogonal part of C, which scalar
        data cannot see, is dropped.
        """
        c = np.asarray(c, dtype=float)
        m = ul_factor(c.T @ c)
        kz = 1.0 / m[2, 2]
        beta = np.arctan2(m[2, 1], m[1, 1])
        ky = 1.0 / np.hypot(m[1, 1], m[2, 1])
        kx = 1.0 / np.linalg.norm(m[:, 0])
        gamma = np.arcsin(np.clip(m[1, 0] * kx, -1.0, 1.0))
        alpha = np.arctan2(m[2, 0], m[0, 0])
        return cls(alpha, beta, gamma, (kx, ky, kz), tuple(np.asarray(offset_nT, dtype=float)))

    def fits_model(self, model: str, atol: float = 0.0) -> bool:
        """Whether the entries ``model`` holds fixed are at their neutral values (within ``atol``)."""
        nine = self.to_vector("nine")
        fixed = [i for i in range(9) if i not in FREE[model]]
        return bool(np.all(np.abs(nine[fixed] - np.asarray(NEUTRAL)[fixed]) <= atol))

    def as_dict(self) -> dict:
        return {
            "alpha_rad": self.alpha_rad,
            "beta_rad": self.beta_rad,
            "gamma_rad": self.gamma_rad,
            "scale": list(self.scale),
            "offset_nT": list(self.offset_nT),
            "matrix": self.matrix.tolist(),
        }


Convention = Literal["paper", "axis_projection"]


@dataclass(frozen=True)
class SensorModel:
    """A simulated tri-axial fluxgate: error parameters, noise, quantization and forward convention.

    ``measure`` implements ``raw = K · P^-1 · B + o + noise`` (``paper``) or ``raw = K · P^T · B + o +
    noise`` (``axis_projection``), then rounds to ``quantization_nT`` when that is positive.
    """

    errors: ErrorParams = field(default_factory=ErrorParams)
    noise_nT: float = 0.0
    quantization_nT: float = 0.0
    convention: Convention = "paper"

    def __post_init__(self):
        if self.convention not in ("paper", "axis_projection"):
            raise ValueError(f"unknown sensor convention {self.convention!r}: use 'paper' or 'axis_projection'")
        if self.noise_nT < 0 or self.quantization_nT < 0:
            raise ValueError("noise_nT and quantization_nT must be non-negative")

    def forward_matrix(self) -> np.ndarray:
        """The linear map from the true field (sensor body frame) to the readings before offset."""
        e = self.errors
        p = paper_matrix(e.alpha_rad, e.beta_rad, e.gamma_rad)
        k = np.diag(e.scale)
        if self.convention == "paper":
            return k @ np.linalg.inv(p)
        return k @ p.T

    def true_correction(self) -> ErrorParams:
        """The parameters a perfect calibrator reports (canonical form of the exact inverse)."""
        if self.convention == "paper":
            return self.errors
        return ErrorParams.from_correction(np.linalg.inv(self.forward_matrix()), self.errors.offset_nT)

    def linear(self, b_body_nT: np.ndarray) -> np.ndarray:
        """Noise-free readings K P^-1 B + o (or K P^T B + o)."""
        return np.asarray(b_body_nT, dtype=float) @ self.forward_matrix().T + np.asarray(self.errors.offset_nT)

    def measure(self, b_body_nT: np.ndarray, rng: np.random.Generator | None = None) -> np.ndarray:
        return self.add_noise(self.linear(b_body_nT), rng)

    def add_noise(self, raw: np.ndarray, rng: np.random.Generator | None = None) -> np.ndarray:
        """White noise of ``noise_nT`` per axis, then quantization to ``quantization_nT``."""
        raw = np.asarray(raw, dtype=float)
        if self.noise_nT > 0:
            if rng is None:
                raise ValueError("a noisy sensor needs an rng (np.random.default_rng(seed))")
            raw = raw + rng.normal(0.0, self.noise_nT, size=raw.shape)
        if self.quantization_nT > 0:
            raw = np.round(raw / self.quantization_nT) * self.quantization_nT
        return raw


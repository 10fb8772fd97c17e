"""A record for the effects' fitted-form tests: readings of a 50,000 nT field at random directions with offsets,
as effect ``Columns`` over 600 s and 10-35 °C, with its normalization and the forward model's context."""
from __future__ import annotations

import numpy as np

from magbench.simulate.effects import Columns, Normalization

OFFSET_NT = np.array([120.0, -80.0, 40.0])


def sphere_record(rng: np.random.Generator, n: int) -> tuple[np.ndarray, Columns, Normalization, dict]:
    """(effect-free readings, their Columns, the Normalization, the context a forward effect reads)."""
    b = rng.normal(size=(n, 3))
    lin = 50000.0 * b / np.linalg.norm(b, axis=1, keepdims=True) + OFFSET_NT
    d = Columns(lin, np.full(n, 50000.0), t_s=np.linspace(0.0, 600.0, n), temp_C=np.linspace(10.0, 35.0, n))
    norm = Normalization.of(d)
    ctx = {"t_s": d.t_s, "temp_C": d.temp_C, "offset_nT": tuple(OFFSET_NT), "f_nT": norm.f0_nT}
    return lin, d, norm, ctx

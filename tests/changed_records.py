"""Records of the built-in scenarios whose sensor changes halfway (written from what happens to a sensor, not from the
diagnosis): an axis's gain, its sign, two axes swapped; optionally beside a steadily warming logged temperature."""
from __future__ import annotations

import numpy as np

from magbench.simulate import simulate
from magbench.simulate.dataset import Dataset


def changed_halfway(scenario: str, seed: int, change: str, warming: bool = False) -> Dataset:
    """``change``: ``gain x`` followed by a factor (``gain 1.01``), ``sign z`` (wires reversed), or ``swap ab`` with
    two axes among x, y, z (``swap xy``); from the middle sample on.  ``warming``: a logged temperature rising 15 C
    steadily over the record (0.05 C of noise), which the readings do not follow."""
    d = simulate(scenario, seed)
    raw = d.raw_nT.copy()
    half = len(raw) // 2
    kind, arg = change.split(" ", 1)
    if kind == "gain":
        raw[half:, 0] *= float(arg)
    elif kind == "sign":
        axis = "xyz".index(arg)
        raw[half:, axis] *= -1.0
    elif kind == "swap":
        a, b = ("xyz".index(c) for c in arg)
        raw[half:, [a, b]] = raw[half:, [b, a]]
    else:
        raise ValueError(change)
    temp = d.temp_C
    if warming:
        rng = np.random.default_rng(seed + 100)
        ramp = (d.t_s - d.t_s.min()) / np.ptp(d.t_s)
        temp = 20.0 + 15.0 * ramp + rng.normal(0.0, 0.05, len(raw))
    return Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s, temp_C=temp)

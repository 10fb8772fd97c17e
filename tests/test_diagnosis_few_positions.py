"""A sensor moved between a few held positions (not turned through a band of attitudes) whose attitudes cannot
determine the base model: the weak prior absorbs whatever the positions show, so the diagnosis cannot say `none`
(it did, with a power statement of 0.9 nT, on two alternating positions: a hostile-input probe of session 22).
Negative control: a level turntable (a band of headings) is still answered `none`."""
from __future__ import annotations

import numpy as np

from magbench.benchmarks.diagnosis import MIN_DIRECTIONS, diagnose, distinct_directions
from magbench.simulate import attitude
from magbench.simulate.dataset import Dataset
from magbench.simulate.field import ConstantField
from magbench.simulate.sensor import ErrorParams, SensorModel

FIELD = ConstantField.from_angles(50000.0, 55.0, 3.0)
NINE = ErrorParams(0.012, -0.008, 0.015, (1.021, 0.984, 1.008), (152.0, -218.0, 85.0))


def _positions(k: int, n: int = 300, seed: int = 0) -> Dataset:
    rng = np.random.default_rng(seed)
    att = attitude.full_sphere(k, rng)
    b = att.body_field(np.asarray(FIELD.vector_nT))[np.arange(n) % k]  # the positions visited in turn
    raw = SensorModel(NINE, noise_nT=2.0).measure(b, rng)
    return Dataset(raw, f_ref_nT=np.full(n, 50000.0), t_s=np.arange(n, dtype=float))


def test_two_alternating_positions_are_insufficient_data():
    data = _positions(2)
    assert distinct_directions(data.raw_nT) == 2
    r = diagnose(data)
    assert r["verdict"] == "insufficient_data" and r["attitude"] == "insufficient_data"
    assert "2 distinct directions" in r["attitude_reason"]


def test_a_level_turntable_is_still_answered():
    rng = np.random.default_rng(1)
    att = attitude.turntable(400, 360.0 / 400)
    raw = SensorModel(NINE, noise_nT=1.0).measure(att.body_field(np.asarray(FIELD.vector_nT)), rng)
    data = Dataset(raw, f_ref_nT=np.full(400, 50000.0), t_s=np.arange(400, dtype=float))
    assert distinct_directions(raw) >= MIN_DIRECTIONS
    r = diagnose(data)
    assert r["verdict"] == "none" and "attitude_reason" not in r


def test_distinct_directions_counts_cells_not_noise():
    data = _positions(5, n=500)
    assert distinct_directions(data.raw_nT) == 5  # 2 nT of noise on 50000 nT: far inside a 1 degree cell

"""A fit judged against noise it did not make, also when consecutive samples are at unrelated attitudes (a
full-sphere record sampled at random attitudes): there the time neighbours' differences carry the misfit of
anything that follows the attitude, so a step of the offsets must be found by its shape."""
import numpy as np
import pytest

from magbench.calibrators import make
from magbench.simulate import simulate
from magbench.simulate.dataset import Dataset


def _stepped(seed: int, jump) -> Dataset:
    d = simulate("sphere9", seed=seed)
    raw = np.array(d.raw_nT)
    raw[len(raw) // 2:] += np.asarray(jump, dtype=float)
    return Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_offsets_that_jump_halfway_are_rejected_and_located(seed):
    res = make("lsq").fit(_stepped(seed, [800.0, -600.0, 0.0]))
    assert not res.accepted
    text = " ".join(res.rejections)
    assert "a step in the residual at row 150" in text and "jump by about" in text


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_negative_control_the_same_records_without_the_jump_are_accepted(seed):
    res = make("lsq").fit(_stepped(seed, [0.0, 0.0, 0.0]))
    assert res.accepted, res.rejections

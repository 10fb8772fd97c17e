"""Loops that were rewritten for speed, against the plain forms they replaced (kept here as the reference):
the first-order lag on irregular times (Python floats instead of numpy scalars: bit-identical) and the blind
check's integrated attitudes (a doubling scan of quaternion products instead of composing one step at a time:
equal to rounding)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from magbench.benchmarks.diagnosis import blind
from magbench.simulate.effects import first_order_lag


def _lag_reference(t_s, x, tau_s):
    order = np.argsort(t_s, kind="stable")
    ts, xs = t_s[order], np.asarray(x, dtype=float)[order]
    a = 1.0 - np.exp(-np.diff(ts) / tau_s)
    out = np.empty_like(xs)
    out[0] = xs[0]
    for i in range(1, len(xs)):
        out[i] = out[i - 1] + a[i - 1] * (xs[i] - out[i - 1])
    res = np.empty_like(out)
    res[order] = out
    return res


@pytest.mark.parametrize("seed", range(6))
def test_first_order_lag_on_irregular_times_is_bit_identical(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 2000))
    t = np.cumsum(rng.uniform(0.1, 0.5, n))
    if seed % 2:
        rng.shuffle(t)  # rows not in time order
    tau = float(rng.uniform(0.1, 50.0))
    for x in (rng.normal(size=n) * 1e3, rng.normal(size=(n, 3))):
        assert np.array_equal(first_order_lag(t, x, tau), _lag_reference(t, x, tau))
    # the negative control: another time constant gives other numbers
    x = rng.normal(size=n)
    assert not np.array_equal(first_order_lag(t, x, tau), _lag_reference(t, x, 1.5 * tau))


def test_first_order_lag_of_one_sample_is_that_sample():
    assert first_order_lag(np.array([0.0, 0.0 + 1e-3]), np.array([2.0, 2.0]), 1.0).tolist() == [2.0, 2.0]
    one = first_order_lag(np.array([3.0]), np.array([5.0]), 1.0)
    assert one.tolist() == [5.0]


@pytest.mark.parametrize("n", [2, 3, 17, 1000])
def test_blind_attitudes_equal_the_step_by_step_composition(n):
    t = np.cumsum(np.random.default_rng(n).uniform(0.05, 0.5, n))
    got = blind._attitudes(np.random.default_rng(5), n, t, "full")
    rng = np.random.default_rng(5)  # the same draws, composed one step at a time
    rate = np.cumsum(rng.normal(0, 1, (n, 3)), axis=0)
    rate = rate / np.std(rate, axis=0) * rng.uniform(0.5, 2.0) * (30.0 / max(t[-1], 1.0))
    rots = [Rotation.identity()]
    for i in range(1, n):
        rots.append(Rotation.from_rotvec(rate[i] * (t[i] - t[i - 1])) * rots[-1])
    expected = Rotation.concatenate(rots)
    assert np.abs(got.as_matrix() - expected.as_matrix()).max() < 1e-12
    assert len(got) == n
    if n > 2:  # the negative control: the steps in the other order are another path
        wrong = [Rotation.identity()]
        for i in range(1, n):
            wrong.append(wrong[-1] * Rotation.from_rotvec(rate[i] * (t[i] - t[i - 1])))
        assert np.abs(got.as_matrix() - Rotation.concatenate(wrong).as_matrix()).max() > 1e-6

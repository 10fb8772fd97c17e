"""Spikes are named ``outliers`` only when they come at random times: an interference that recurs with a period (a
radio transmitting in bursts that load the sensor's supply, a heater's cycle) puts its events at nearly equal gaps,
which random glitches do not (``naming.regular_events``).  Written from the physics: a tumbling sensor in a constant
field, white noise, and either supply dips every 29 s or glitches at random rows."""
import numpy as np
from scipy.spatial.transform import Rotation

from magbench.benchmarks.diagnosis import diagnose
from magbench.benchmarks.diagnosis.naming import SPIKE_PERIOD_ALPHA, regular_events, spikes_isolated
from magbench.simulate.dataset import Dataset

B = np.array([21000.0, -2500.0, 43000.0])


def test_periodic_events_are_regular_and_random_ones_are_not():
    ts = np.arange(2000.0)
    assert regular_events(np.arange(7.0, 2000.0, 61.0), ts) < 1e-6
    jitter = np.random.default_rng(0).normal(0, 2.0, 32)
    assert regular_events(np.sort(np.arange(7.0, 2000.0, 61.0)[:32] + jitter), ts) < 1e-6
    rng = np.random.default_rng(1)
    ps = np.array([regular_events(np.sort(rng.choice(ts, int(rng.integers(5, 40)), replace=False)), ts)
                   for _ in range(400)])
    assert np.mean(ps <= SPIKE_PERIOD_ALPHA) <= 0.01  # random times refused about once in a thousand
    assert np.mean(ps <= 0.5) > 0.3  # the control: the p-values of random times spread over (0, 1]


def test_too_few_or_too_dense_events_are_not_tested():
    ts = np.arange(100.0)
    assert regular_events(np.array([10.0, 30.0, 50.0, 70.0]), ts) == 1.0
    assert regular_events(np.arange(0.0, 100.0, 2.0), ts) == 1.0


def test_isolated_spikes_at_a_period_fail_only_the_regularity():
    n = 1500
    t = np.arange(n) * 0.6
    periodic = np.zeros(n, bool)
    periodic[np.arange(20, n, 49)] = True
    ok, _, failed = spikes_isolated(periodic, t)
    assert not ok and failed == ("regular",)
    random_rows = np.zeros(n, bool)
    random_rows[np.random.default_rng(3).choice(n, 30, replace=False)] = True
    ok, _, failed = spikes_isolated(random_rows, t)
    assert ok and failed == ()


def test_bursts_at_a_period_are_refused_where_bursts_at_random_times_pass():
    """Abrupt bursts of 5 samples (a radio's transmissions) pass the burst test of glitches; every 32 samples they
    fail the regularity test alone.  The control: the same bursts at random times pass (the change is that test)."""
    rng = np.random.default_rng(0)
    n = 960
    t = np.arange(n) * 0.9
    u = np.array([0.4, 0.1, 0.9]) / np.linalg.norm([0.4, 0.1, 0.9])
    raw = 48000 * u + rng.normal(0, 1.0, (n, 3))
    periodic = ((np.arange(n) + 7) % 32) < 5
    ok, _, failed = spikes_isolated(periodic, t, raw, rng.normal(0, 0.5, n) + 12.0 * periodic)
    assert not ok and failed == ("regular",)
    starts = np.sort(rng.choice(np.arange(10, n - 10, 8), 30, replace=False))
    scattered = np.zeros(n, bool)
    for a in starts:
        scattered[a:a + 5] = True
    ok, _, failed = spikes_isolated(scattered, t, raw, rng.normal(0, 0.5, n) + 12.0 * scattered)
    assert ok and failed == (), failed


def tumbling(kind: str, seed: int = 0, n: int = 1500):
    """A sensor tumbling slowly about a wandering axis at 1.6 Hz, ideal apart from 1 nT of white noise; ``kind``
    'dips': each axis's scale factor changes by a few parts in 10^3 (some up, some down) during 4-s bursts every
    29.3 s (a radio loading the supply); 'glitches': 8 rows at random get a spike of 40-80 nT on one axis."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 1.6
    rate = np.cumsum(rng.normal(0, 0.02, (n, 3)), axis=0) + np.array([0.3, 0.2, 0.25])
    rot = Rotation.from_rotvec(np.zeros(3))
    mats = []
    for i in range(n):
        mats.append(rot)
        rot = rot * Rotation.from_rotvec(rate[i] / 1.6)
    body = np.stack([m.inv().apply(B) for m in mats])
    raw = body + rng.normal(0, 1.0, body.shape)
    if kind == "dips":
        burst = ((t + 3.0) % 29.3) < 4.0
        raw[burst] *= 1.0 + np.array([2.5e-3, -2.0e-3, 1.5e-3])
    else:
        rows = rng.choice(n, 8, replace=False)
        raw[rows, rng.integers(0, 3, 8)] += rng.choice([-1.0, 1.0], 8) * rng.uniform(40, 80, 8)
    return Dataset(raw, f_ref_nT=np.full(n, np.linalg.norm(B)), t_s=t)


def test_supply_dips_at_a_period_are_not_outliers():
    verdict = diagnose(tumbling("dips"))["verdict"]
    assert "outliers" not in verdict and verdict != "none", verdict


def test_glitches_at_random_rows_are_outliers():
    """The negative control: the same sensor with glitches at random rows."""
    assert "outliers" in diagnose(tumbling("glitches"))["verdict"]

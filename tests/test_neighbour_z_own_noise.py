"""``floor.neighbour_z`` asks whether a residual depends on the neighbouring readings (a reading mixed with its
neighbours: a lag at random attitudes).  Noise must not: the current reading's own noise along the field is the
residual's noise, so the test may not regress on the reading itself, only on its direction.  Written from the
physics: a walker's sensor, its gait turning it between consecutive samples at 4 Hz, ideal apart from white noise."""
import numpy as np
from scipy.spatial.transform import Rotation

from magbench.benchmarks.diagnosis.floor import neighbour_z

B = np.array([18000.0, 1500.0, 46000.0])


def walker(n=1200, noise=2.0, seed=0, lag_share=0.0):
    """(residual |B_seen| - F, readings) of a sensor carried by a walker: heading changes at corners, a gait that
    pitches at the step frequency (1.9 Hz) and rolls and yaws at half of it, sampled at 4 Hz with jitter; white
    noise on each axis.  ``lag_share``: one axis reads a mix of this sample and the one before (a lag)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 4.0 + rng.normal(0, 0.01, n)
    heading = np.cumsum(rng.choice([0.0, 0.0, 0.0, 0.5, -0.5], n) * (rng.random(n) < 0.01)) + 0.02 * np.sin(0.1 * t)
    step = 2 * np.pi * 1.9 * t
    angles = np.column_stack([heading + 0.15 * np.sin(step / 2), 0.2 * np.sin(step), 0.12 * np.sin(step / 2 + 1)])
    body = Rotation.from_euler("zyx", angles).inv().apply(B)
    seen = body.copy()
    if lag_share:
        seen[1:, 0] = (1 - lag_share) * body[1:, 0] + lag_share * body[:-1, 0]
    raw = seen + rng.normal(0, noise, seen.shape)
    return np.linalg.norm(raw, axis=1) - np.linalg.norm(B), raw


def test_a_clean_walker_does_not_follow_its_neighbours():
    for seed in range(4):
        r, raw = walker(seed=seed)
        assert neighbour_z(r - r.mean(), raw) < 3.0, seed


def test_the_old_regressors_find_the_noise_itself():
    """The negative control: the same clean residual tested with the columns the test had before (the reading itself
    times each neighbour, beside the direction's and the neighbours' own products and the memory terms) is far from
    noise: the bias the change removed."""
    from scipy.signal import lfilter
    from scipy.stats import norm

    from magbench.benchmarks.diagnosis.floor import MEMORY_SAMPLES
    from magbench.simulate.effects import f_test_p

    r, raw = walker()
    scale = float(np.median(np.linalg.norm(raw, axis=1)))
    idx = np.arange(1, len(r) - 1)
    here, prev, nxt = raw[idx] / scale, raw[idx - 1] / scale, raw[idx + 1] / scale
    cur = here / np.linalg.norm(here, axis=1)[:, None]
    cols = [np.ones(len(idx))] + [cur[:, a] * nb[:, b] for nb in (prev, nxt) for a in range(3) for b in range(3)]
    cols += [nb[:, a] * nb[:, b] for nb in (prev, nxt) for a in range(3) for b in range(a, 3)]
    cols += [here[:, a] * nb[:, b] for nb in (prev, nxt) for a in range(3) for b in range(3)]
    for tau in MEMORY_SAMPLES:
        w = np.exp(-1.0 / tau)
        past = lfilter([0.0, 1.0 - w], [1.0, -w], raw, axis=0)[idx] / scale
        cols += [cur[:, a] * past[:, b] for a in range(3) for b in range(3)]
    design = np.column_stack(cols)
    y = r[idx] - r.mean()
    rss1 = float(np.sum((y - design @ np.linalg.lstsq(design, y, rcond=None)[0]) ** 2))
    p = f_test_p(float(np.sum((y - y.mean()) ** 2)), rss1, design.shape[1] - 1, len(y) - design.shape[1])
    assert float(norm.isf(max(p, 1e-300))) > 10.0
    assert neighbour_z(r - r.mean(), raw) < 3.0


def test_a_lag_still_follows_its_neighbours():
    r, raw = walker(lag_share=0.3, noise=0.5)
    assert neighbour_z(r - r.mean(), raw) > 5.0

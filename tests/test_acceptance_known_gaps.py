"""Known gaps of the acceptance checks, each a strict xfail: the test states what should hold, fails today, and turns
into a failure of the suite (XPASS) the day a change makes it hold, so that the gap's closing is noticed and this file
updated.  Found by a hostile probe with its own forward model (2026-11-28); the readings are written out here from the
physics (CONTRACT section 1: raw = K P^-1 B + o), not by ``magbench.simulate``."""
import numpy as np
import pytest

import magbench
from magbench.simulate.dataset import Dataset

NAMES = ["alpha_rad", "beta_rad", "gamma_rad", "kx", "ky", "kz", "ox_nT", "oy_nT", "oz_nT"]


def _sensor(rng, body):
    truth = np.array([0.004, -0.003, 0.005, 1.01, 0.99, 1.02, 120.0, -80.0, 60.0])
    a, b, g = truth[:3]
    p = np.array([[np.cos(a) * np.cos(g), 0, 0], [np.sin(g), np.cos(b), 0], [np.sin(a) * np.cos(g), np.sin(b), 1.0]])
    return truth, body @ (np.diag(truth[3:6]) @ np.linalg.inv(p)).T + truth[6:]


@pytest.mark.xfail(strict=True, reason="the structure test's fixed ratio (3 times the noise estimated apart from the "
                   "fit) does not tighten with the number of readings: a smooth misfit of 1.3-2.8 times the noise "
                   "passes, and the deviations state the noise only (a significance test that scales with n, or "
                   "deviations widened by the misfit's possible bias, would close it)")
def test_a_small_quadratic_nonlinearity_is_not_accepted_far_from_the_truth():
    """Each axis reads c (raw - o)² more, 3 nT at full field, on 1 nT of noise, at 1000 random attitudes: the offsets
    absorb most of it (a residual of 1.23-1.28 nT).  No accepted answer should lie beyond 5 stated deviations (today
    5 of 5 are accepted 27-28 deviations off)."""
    wrong = 0
    for seed in range(5):
        rng = np.random.default_rng(seed)
        u = rng.normal(size=(1000, 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        truth, raw = _sensor(rng, 50_000.0 * u)
        raw = raw + rng.choice([-1.0, 1.0], 3) * 3.0 / 50_000.0 ** 2 * (raw - truth[6:]) ** 2
        raw = raw + rng.normal(0.0, 1.0, raw.shape)
        res = magbench.calibrate(Dataset(raw, f_ref_nT=np.full(1000, 50_000.0), t_s=np.arange(1000.0)))
        z = np.abs(res.x - truth) / np.array([res.uncertainty[k] for k in NAMES])
        wrong += bool(res.accepted and z.max() > 5.0)
    assert wrong == 0

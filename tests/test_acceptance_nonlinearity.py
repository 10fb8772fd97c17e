"""A smooth misfit the structure test cannot see: the axes responding quadratically (each reading raw_k + c_k (raw_k -
o_k)²), a few nT at full field on 1 nT of noise.  The residual passes (1.23-1.28 nT against the fixed ratio of 3 times
the noise), the offsets absorb most of the nonlinearity, and the answer had been accepted 27-28 deviations from the
truth (found by a hostile probe with its own forward model, 2026-11-28).  ``acceptance.nonlinearity_shift`` tests the
three quadratic columns against the model's own (F test at 1e-6) and adds each parameter's shift when they are fitted
to its stated deviation.  The readings are written out here from the physics (CONTRACT section 1: raw = K P^-1 B + o),
not by ``magbench.simulate``."""
import numpy as np
import pytest

import magbench
from magbench.errors import InputError
from magbench.simulate.dataset import Dataset

NAMES = ["alpha_rad", "beta_rad", "gamma_rad", "kx", "ky", "kz", "ox_nT", "oy_nT", "oz_nT"]


def _sensor(body):
    truth = np.array([0.004, -0.003, 0.005, 1.01, 0.99, 1.02, 120.0, -80.0, 60.0])
    a, b, g = truth[:3]
    p = np.array([[np.cos(a) * np.cos(g), 0, 0], [np.sin(g), np.cos(b), 0], [np.sin(a) * np.cos(g), np.sin(b), 1.0]])
    return truth, body @ (np.diag(truth[3:6]) @ np.linalg.inv(p)).T + truth[6:]


def _worst(amplitude_nT: float, seeds=range(5)) -> list[tuple[bool, float, bool]]:
    out = []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        u = rng.normal(size=(1000, 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        truth, raw = _sensor(50_000.0 * u)
        raw = raw + rng.choice([-1.0, 1.0], 3) * amplitude_nT / 50_000.0 ** 2 * (raw - truth[6:]) ** 2
        raw = raw + rng.normal(0.0, 1.0, raw.shape)
        res = magbench.calibrate(Dataset(raw, f_ref_nT=np.full(1000, 50_000.0), t_s=np.arange(1000.0)))
        z = np.abs(res.x - truth) / np.array([res.uncertainty[k] for k in NAMES])
        out.append((res.accepted, float(z.max()), any("a quadratic response of the axes" in w for w in res.warnings)))
    return out


def test_a_small_quadratic_nonlinearity_is_stated_in_the_deviations(monkeypatch):
    """3 nT at full field: every answer accepted, said, and within 3 stated deviations of the truth.  Negative
    control: without the test, the same answers 27-28 deviations off, and nothing said."""
    from magbench.calibrators import acceptance

    for accepted, z, said in _worst(3.0):
        assert accepted and said and z < 3.0, (accepted, z, said)
    monkeypatch.setattr(acceptance, "nonlinearity_shift", lambda *args: (None, None))
    for accepted, z, said in _worst(3.0):
        assert accepted and not said and z > 20.0, (accepted, z, said)


@pytest.mark.parametrize("scenario", ["sphere9", "cap9", "tumble9", "tumble9q", "tumble3", "vehicle9"])
def test_no_nonlinearity_is_said_of_a_sensor_without_one(scenario):
    """The F test at 1e-6 says nothing on the simulator's linear sensors over 20 records each, on near-planar ones
    (vehicle9: not tested, the model being undetermined there, whose linearization had claimed 3.5e4 nT on z) too."""
    for seed in range(20):
        try:
            res = magbench.calibrate(magbench.simulate(scenario, seed=seed))
        except InputError:
            continue
        assert not any("a quadratic response of the axes" in w for w in res.warnings), (scenario, seed)

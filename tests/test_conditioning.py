"""Every calibrator warns when the attitude coverage leaves the problem ill-conditioned."""
import pytest

from magbench.calibrators import available
from magbench.errors import InputError
from magbench.simulate import simulate

NINE = sorted(n for n, c in available().items() if "nine" in c.supported_models)


@pytest.mark.parametrize("name", NINE)
def test_vehicle_coverage_is_flagged_with_the_condition_number_and_bound(name):
    cls = available()[name]
    cal = cls(**{**cls.checking_params(), "model": "nine", "seed": 0})
    data = simulate("vehicle9", 0)
    try:
        result = cal.fit(data)
    except InputError as exc:  # a refusal must say why
        assert "condition" in str(exc) or "ellipsoid" in str(exc), str(exc)
        return
    flagged = [w for w in result.warnings if w.startswith("ill-conditioned attitude coverage")]
    assert flagged, result.warnings
    assert "condition number" in flagged[0] and "Cramér-Rao" in flagged[0]


@pytest.mark.parametrize("name", NINE)
def test_full_sphere_is_not_flagged(name):
    cls = available()[name]
    cal = cls(**{**cls.checking_params(), "model": "nine", "seed": 0})
    result = cal.fit(simulate("sphere9", 0))
    assert not [w for w in result.warnings if "ill-conditioned" in w]


def test_noise_from_repeated_attitudes_and_from_time_is_independent_of_the_fit():
    """The acceptance checks' independent noise: repeated attitudes (no time column) and neighbours in time
    both give the simulated 3 nT, whatever structure the residual has across attitudes."""
    import numpy as np

    from magbench.calibrators.acceptance import independent_noise

    rng = np.random.default_rng(0)
    directions = rng.normal(size=(60, 3))
    raw = np.repeat(50000.0 * directions / np.linalg.norm(directions, axis=1)[:, None], 8, axis=0)
    structure = np.repeat(rng.normal(scale=200.0, size=60), 8)  # a misfit per attitude, 200 nT
    r = structure + rng.normal(scale=3.0, size=len(raw))
    raw = raw + rng.normal(scale=3.0, size=raw.shape)
    sigma, how, _ = independent_noise(r, raw, None, 50000.0)
    assert how == "repeats" and 2.5 < sigma < 3.5
    t = np.arange(len(r), dtype=float)
    sigma, how, order = independent_noise(r[::-1], raw[::-1], t[::-1], 50000.0)  # rows in reverse time order
    assert how == "time" and 2.5 < sigma < 10 and order[0] == len(t) - 1  # dwells of 8: the 200 nT steps hardly count
    shuffled = rng.permutation(len(t))
    sigma, how, _ = independent_noise(r[shuffled], raw[shuffled], t, 50000.0)
    assert how == "time" and sigma > 100  # negative control: a residual that jumps between samples is not noise-free
    smooth = 100 * np.sin(t / 50.0) + rng.normal(scale=3.0, size=len(t))
    sigma, how, _ = independent_noise(smooth, raw, t, 50000.0)
    assert how == "time" and 2.5 < sigma < 3.5
    sigma, how, _ = independent_noise(smooth, rng.normal(size=raw.shape) * 50000, None, 50000.0)
    assert how == "rows"  # no repeats, no time: file order, with a warning in the result

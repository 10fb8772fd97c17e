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


def test_random_attitudes_are_judged_against_their_nearest_attitudes():
    """Consecutive samples at unrelated attitudes: the time neighbours' differences hold the misfit of anything
    that follows the attitude (a nine-parameter fit leaving 44 nT of a nonlinearity on a 2 nT sensor was accepted
    silently).  The residual is judged against its scatter about the nearest attitudes instead: a clean record is
    1.0 times it (a warning says a drift in time would not be seen), a strong nonlinearity 4-5 times (rejected,
    beyond STRUCTURE_RATIO, as structure that follows the attitude).  A continuous path (tumble9) and a turntable
    (lu2014) keep the time neighbours (the controls)."""
    from magbench.simulate.effects import EFFECTS
    from magbench.simulate.scenarios import get_scenario

    for scenario in ("sphere9", "cap9"):
        res = make("lsq").fit(simulate(scenario, seed=1))
        assert res.accepted
        said = [w for w in res.warnings if "consecutive samples are at unrelated attitudes (roughness" in w]
        assert said and ("judged against its scatter about the 5 nearest attitudes" in said[0]
                         or "judged against the time neighbours' scatter (lower than" in said[0]), res.warnings
        bent = get_scenario(scenario).with_effects(EFFECTS["nonlinearity"](quadratic=(4e-3, -3e-3, 2.5e-3))).build(1)
        res = make("lsq").fit(bent)
        assert not res.accepted
        assert any("from the 5 nearest attitudes" in w and "follows the attitude" in w for w in res.rejections), \
            res.rejections
    for scenario, model in (("tumble9", "nine"), ("lu2014", "angles")):
        res = make("lsq", model=model).fit(simulate(scenario, seed=1))
        assert not any("attitudes (roughness" in w or "nearest attitudes" in w for w in res.warnings), res.warnings


def test_attitude_neighbour_noise_is_the_noise_on_a_clean_sphere_and_cancels_smooth_structure():
    from magbench.calibrators.acceptance import attitude_neighbour_noise, attitude_neighbours

    rng = np.random.default_rng(0)
    u = rng.normal(size=(3000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    noise = rng.normal(0, 2.0, 3000)
    smooth = 40.0 * (u[:, 0] ** 2 - 1 / 3)  # a quadratic in the direction
    near = attitude_neighbours(u * 5e4)
    assert attitude_neighbour_noise(noise, near) == pytest.approx(2.0, rel=0.1)
    assert attitude_neighbour_noise(noise + smooth, near) < 3.0  # the structure mostly cancels
    assert np.std(noise + smooth) > 5 * 2.0


def test_roughness_on_windows_of_a_long_record_agrees_with_the_whole():
    from magbench.numerics import roughness

    rng = np.random.default_rng(0)
    t = np.arange(50_000, dtype=float)
    walk = np.cumsum(rng.normal(0, 0.01, (50_000, 3)), axis=0) + [1.0, 0.0, 0.0]
    shuffled = rng.normal(0, 1, (50_000, 3))
    for raw in (walk, shuffled):
        assert roughness(t, raw, max_rows=20_000) == pytest.approx(roughness(t, raw), rel=0.05)
    assert roughness(t, shuffled, max_rows=20_000) > 1.6 and roughness(t, walk, max_rows=20_000) < 1.1

"""A calibration of a record whose sensor changed mid-record is no calibration of either part: it is rejected also at
random attitudes, where the noise is judged against each reading's nearest attitudes.  Over the whole record those
neighbours come from both parts, whose residuals follow the attitude differently, so their scatter held the change
as noise (sphere9 with z's sign flipped, x's gain up 1 % or x and y swapped halfway was accepted with 110-200 nT of
residual on a 2 nT sensor, its angles off by up to 2800"); within the halves or thirds in time they cancel it
(``acceptance.TIME_BLOCKS``).  A drift in time moves both noise estimates there, and is fitted instead
(``acceptance.drift_in_time``).  The records come from ``tests/changed_records.py`` (written from what happens to a
sensor); the controls are the same records intact and with 50 nT of white noise, which is noise, not a change."""
import numpy as np
import pytest
from changed_records import changed_halfway

from magbench.calibrators import make
from magbench.calibrators.acceptance import attitude_neighbour_noise, attitude_neighbours, blocked_attitude_neighbours
from magbench.simulate import simulate
from magbench.simulate.dataset import Dataset

CHANGES = ("sign z", "gain 1.01", "swap xy")


@pytest.mark.parametrize("scenario", ["sphere9", "cap9"])
@pytest.mark.parametrize("change", CHANGES)
@pytest.mark.parametrize("seed", [0, 1])
def test_a_sensor_changed_halfway_at_random_attitudes_is_rejected(scenario, change, seed):
    res = make("lsq").fit(changed_halfway(scenario, seed, change))
    assert not res.accepted
    assert any("times the noise estimated independently of the fit" in w and "within its halves or thirds in time" in w
               for w in res.rejections), res.rejections


@pytest.mark.parametrize("scenario", ["sphere9", "cap9"])
@pytest.mark.parametrize("seed", [0, 1])
def test_a_sign_flipped_over_the_middle_third_is_rejected(scenario, seed):
    """Wires reversed for the middle third of the record only: over the halves both sides mix, over the thirds they
    do not."""
    d = simulate(scenario, seed)
    raw = d.raw_nT.copy()
    n = len(raw)
    raw[n // 3:2 * n // 3, 2] *= -1.0
    res = make("lsq").fit(Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s))
    assert not res.accepted
    assert any("within its halves or thirds in time" in w for w in res.rejections), res.rejections


@pytest.mark.parametrize("scenario", ["sphere9", "cap9"])
@pytest.mark.parametrize("seed", [0, 1])
def test_negative_controls_intact_and_white_noise_are_accepted(scenario, seed):
    d = simulate(scenario, seed)
    assert make("lsq").fit(d).accepted
    rng = np.random.default_rng(seed)
    noisy = Dataset(d.raw_nT + rng.normal(0.0, 50.0, d.raw_nT.shape), f_ref_nT=d.f_ref_nT, t_s=d.t_s)
    res = make("lsq").fit(noisy)
    assert res.accepted, res.rejections


def test_block_neighbours_are_within_their_half_and_see_the_noise():
    """Each sampled reading's nearest attitudes lie in its own half of the time order; on a clean sphere the scatter
    about them is the noise (as over the whole record), and a residual that flips sign halfway, at the same
    attitudes, cancels within the halves and not over the record."""
    d = simulate("sphere9", 3)
    order = np.argsort(d.t_s, kind="stable")
    rows, nearest = blocked_attitude_neighbours(d.raw_nT, order)
    half = len(order) // 2
    first = np.isin(rows, order[:half])
    assert first.sum() == half and (~first).sum() == len(order) - half
    assert np.array_equal(first[nearest], np.repeat(first[:, None], nearest.shape[1], axis=1))
    rng = np.random.default_rng(0)
    noise = rng.normal(0.0, 2.0, len(order))
    whole = attitude_neighbours(d.raw_nT)
    for near in (whole, (rows, nearest)):
        assert 1.7 < attitude_neighbour_noise(noise, near) < 2.3
    u = d.raw_nT / np.linalg.norm(d.raw_nT, axis=1)[:, None]
    flipped = 100.0 * u[:, 0] * np.where(np.isin(np.arange(len(u)), order[half:]), -1.0, 1.0) + noise
    assert attitude_neighbour_noise(flipped, whole) > 20.0
    assert attitude_neighbour_noise(flipped, (rows, nearest)) < 10.0


def _drifting(scenario: str, seed: int, offsets_nT=(0.0, 0.0, 0.0), field_nT: float = 0.0) -> Dataset:
    """The record with its offsets drifting linearly by ``offsets_nT`` over it, or the field changing by ``field_nT``
    while the reference keeps its values."""
    d = simulate(scenario, seed)
    ramp = (d.t_s - d.t_s.min()) / np.ptp(d.t_s)
    raw = d.raw_nT + ramp[:, None] * np.asarray(offsets_nT, dtype=float)
    raw = raw * (1.0 + field_nT * ramp / d.f_ref_nT)[:, None]
    return Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s)


@pytest.mark.parametrize("scenario", ["sphere9", "cap9"])
@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("drift", [{"offsets_nT": (300.0, -200.0, 100.0)}, {"field_nT": 150.0}])
def test_a_drift_in_time_at_random_attitudes_is_rejected(scenario, seed, drift):
    """At random attitudes a drift moves both noise estimates with it (time neighbours and nearest attitudes lie
    far apart in the other variable): offsets drifting by 300 nT were accepted at 60 nT of residual on a 2 nT sensor.
    ``acceptance.drift_in_time`` fits it instead.  A drift of the field itself is common to every attitude, so the
    time neighbours see it already (their rejection judges it against their noise)."""
    res = make("lsq").fit(_drifting(scenario, seed, **drift))
    assert not res.accepted
    said = "drifts in time:" if "offsets_nT" in drift else "times the noise estimated independently of the fit"
    assert any(said in w for w in res.rejections), res.rejections


def test_drift_check_leaves_the_noise_of_a_clean_record():
    """The control: on clean random-attitude records the drift's columns leave the noise (they fit nothing), so the
    check never rejects them, and it is not asked on a continuous path (tumble9, where the time neighbours see a
    drift themselves)."""
    from magbench.calibrators.acceptance import drift_in_time
    from magbench.calibrators.core.objective import ScalarObjective

    for seed in range(4):
        d = simulate("sphere9", seed)
        res = make("lsq").fit(d)
        assert res.accepted
        obj = ScalarObjective(d.raw_nT, d.f_ref_nT, "nine")
        r = obj.residuals(res.x)
        info: dict = {}
        assert drift_in_time(obj, res.x, r, d.t_s, float(np.sqrt(np.mean(r * r))), 0.0, info) is None
        assert 0.8 < info["drift_check"]["rms_left_nT"] / 2.0 < 1.1
    d = _drifting("tumble9", 0, offsets_nT=(300.0, -200.0, 100.0))
    res = make("lsq").fit(d)
    assert not res.accepted and not any("drifts in time" in w for w in res.rejections), res.rejections


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("where", ["half", "middle third"])
def test_a_level_vehicle_whose_z_sign_flips_is_rejected_at_the_jump(seed, where):
    """On a level vehicle z's readings are nearly constant, so its sign flipped reads as the vehicle turned over: one
    calibration fits both parts (3-6 nT on a 2 nT sensor; the two 'caps' even make the attitudes look covered) and was
    accepted with its angles 2400" off.  Only the jump between two consecutive rows shows it (``path_jump``)."""
    d = simulate("vehicle9", seed)
    raw = d.raw_nT.copy()
    n = len(raw)
    rows = slice(n // 2, n) if where == "half" else slice(n // 3, 2 * n // 3)
    raw[rows, 2] *= -1.0
    res = make("lsq").fit(Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s))
    assert not res.accepted
    jumps = [w for w in res.rejections if "the readings' direction jumps by" in w]
    assert jumps and f"between rows {rows.start - 1} and {rows.start}" in jumps[0], res.rejections


def test_path_jump_controls():
    """No jump on intact continuous paths (tumble9, vehicle9), on random attitudes (every step large), across a gap
    in time (the move was not logged), or on a record of held attitudes (the moves between holds are not logged)."""
    from magbench.calibrators.acceptance import path_jump

    for scenario in ("tumble9", "vehicle9", "sphere9"):
        d = simulate(scenario, 0)
        assert path_jump(d.raw_nT, d.t_s) is None
    d = simulate("vehicle9", 0)
    raw, t = d.raw_nT.copy(), d.t_s.copy()
    half = len(raw) // 2
    raw[half:, 2] *= -1.0
    assert path_jump(raw, t) is not None
    t[half:] += 60.0  # a minute unlogged: the sensor may have been turned over
    assert path_jump(raw, t) is None
    rng = np.random.default_rng(0)
    directions = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1]], dtype=float)
    held = np.repeat(directions, 40, axis=0) * 5e4 + rng.normal(0.0, 2.0, (240, 3))
    assert path_jump(held, np.arange(240.0)) is None


@pytest.mark.parametrize("scenario", ["sphere9", "cap9"])
@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("change", ["sign z", "gain 1.01", "offsets drifting", "intact"])
def test_without_a_time_column_the_rows_in_file_order_are_judged_the_same_way(scenario, seed, change):
    """No t column (the shots of a handheld calibration): the rows are taken in file order, where consecutive rows at
    unrelated attitudes hold the structure in their differences, so every such record was accepted (sign flipped,
    gain stepped, offsets drifting: 60-200 nT on a 2 nT sensor).  The nearest attitudes, over the file and its halves
    and thirds, and the drift fit along the rows judge them now; the intact records stay accepted."""
    if change == "offsets drifting":
        d = _drifting(scenario, seed, offsets_nT=(300.0, -200.0, 100.0))
    elif change == "intact":
        d = simulate(scenario, seed)
    else:
        d = changed_halfway(scenario, seed, change)
    res = make("lsq").fit(Dataset(d.raw_nT, f_ref_nT=d.f_ref_nT))
    assert res.accepted == (change == "intact"), res.rejections
    if change == "offsets drifting":
        assert any("drifts along the rows (no t column" in w for w in res.rejections), res.rejections

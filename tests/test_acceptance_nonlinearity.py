"""A smooth misfit the structure test cannot see: the axes responding quadratically (each reading raw_k + c_k (raw_k -
o_k)²) or cubically (raw_k + e_k (raw_k - o_k)³, a fluxgate's own, odd-order, nonlinearity), a few nT at full field on
1 nT of noise.  The residual passes (1.23-1.28 nT against the fixed ratio of 3 times the noise), the offsets absorb
most of a quadratic response and the scales most of a cubic one, and the answers had been accepted 27-28 (quadratic,
found by a hostile probe with its own forward model, 2026-11-28) and 40-110 (cubic, 10 nT) deviations from the truth.
``acceptance.nonlinearity_shift`` tests the quadratic and the cubic columns against the model's own (F tests at 5e-7
each) and adds each parameter's shift when the significant ones are fitted to its stated deviation.  The readings are
written out here from the physics (CONTRACT section 1: raw = K P^-1 B + o), not by ``magbench.simulate``."""
import numpy as np
import pytest

import magbench
from magbench.errors import InputError
from magbench.simulate.dataset import Dataset

NAMES = ["alpha_rad", "beta_rad", "gamma_rad", "kx", "ky", "kz", "ox_nT", "oy_nT", "oz_nT"]


def _unscaled(body, truth):
    """The body field through the paper's non-orthogonality P^-1 (CONTRACT section 1), before the axes' gains."""
    a, b, g = truth[:3]
    p = np.array([[np.cos(a) * np.cos(g), 0, 0], [np.sin(g), np.cos(b), 0], [np.sin(a) * np.cos(g), np.sin(b), 1.0]])
    return body @ np.linalg.inv(p).T


def _sensor(body):
    truth = np.array([0.004, -0.003, 0.005, 1.01, 0.99, 1.02, 120.0, -80.0, 60.0])
    return truth, truth[3:6] * _unscaled(body, truth) + truth[6:]


def _worst(amplitude_nT: float, order: int = 2, seeds=range(5)) -> list[tuple[bool, float, bool]]:
    out = []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        u = rng.normal(size=(1000, 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        truth, raw = _sensor(50_000.0 * u)
        raw = raw + rng.choice([-1.0, 1.0], 3) * amplitude_nT / 50_000.0 ** order * (raw - truth[6:]) ** order
        raw = raw + rng.normal(0.0, 1.0, raw.shape)
        res = magbench.calibrate(Dataset(raw, f_ref_nT=np.full(1000, 50_000.0), t_s=np.arange(1000.0)))
        z = np.abs(res.x - truth) / np.array([res.uncertainty[k] for k in NAMES])
        out.append((res.accepted, float(z.max()), any("response of the axes fits" in w for w in res.warnings)))
    return out


@pytest.mark.parametrize(("order", "amplitude_nT"), [(2, 3.0), (3, 10.0)])
def test_a_small_nonlinearity_is_stated_in_the_deviations(monkeypatch, order, amplitude_nT):
    """3 nT at full field (quadratic) or 10 nT (cubic): every answer accepted, said, and within 3 stated deviations of
    the truth.  Negative control: without the test, the same answers more than 20 deviations off (27-28 and 40-110),
    and nothing said."""
    from magbench.calibrators import acceptance

    for accepted, z, said in _worst(amplitude_nT, order):
        assert accepted and said and z < 3.0, (accepted, z, said)
    monkeypatch.setattr(acceptance, "nonlinearity_shift", lambda *args, **kwargs: (None, None))
    for accepted, z, said in _worst(amplitude_nT, order):
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
        assert not any("response of the axes fits" in w for w in res.warnings), (scenario, seed)


def test_no_nonlinearity_is_claimed_on_an_axis_a_near_planar_path_barely_moves(monkeypatch):
    """Generator 3 (root 2026) case 228: a clean moored buoy, 3292 readings, its vertical axis barely moved (its
    quadratic column 0.03 % outside the model's span).  Fitted anyway, that column had claimed 807 nT on z (F test p
    6e-10) and widened the z offset's deviation from 19 nT to 1408.  Negative control: the column tested again."""
    from independent_forward3 import make_case

    from magbench.calibrators import acceptance

    case = make_case(228, 2026)
    assert case.category == "clean"
    data = Dataset(case.raw_nT, f_ref_nT=case.f_ref_nT, t_s=case.t_s)

    def fit():
        res = magbench.calibrate(data)
        return res.accepted, any("response of the axes fits" in w for w in res.warnings), res.uncertainty["oz_nT"]

    accepted, said, oz = fit()
    assert accepted and not said and oz < 50.0, (accepted, said, oz)
    monkeypatch.setattr(acceptance, "NONLINEARITY_OUTSIDE", 0.0)
    data = Dataset(case.raw_nT, f_ref_nT=case.f_ref_nT, t_s=case.t_s)  # a new record: nothing cached
    accepted, said, oz = fit()
    assert accepted and said and oz > 500.0, (accepted, said, oz)


def _cross_on_a_cap(amplitude_nT: float, seeds=range(5)) -> list[tuple[bool, float, bool]]:
    """Each axis reading the product of the other two (raw_x + h_x d_y d_z, ...: the field across an axis changes its
    reading) at ``amplitude_nT`` at full field, 1000 readings on a 70-degree cap, 1 nT of noise."""
    out = []
    for seed in seeds:
        rng = np.random.default_rng(100 + seed)
        z = rng.uniform(np.cos(np.radians(70.0)), 1.0, 1000)
        phi = rng.uniform(0.0, 2.0 * np.pi, 1000)
        s = np.sqrt(1.0 - z * z)
        truth, raw = _sensor(50_000.0 * np.column_stack([s * np.cos(phi), s * np.sin(phi), z]))
        d = raw - truth[6:]
        cross = np.column_stack([d[:, 1] * d[:, 2], d[:, 0] * d[:, 2], d[:, 0] * d[:, 1]]) / 50_000.0 ** 2
        raw = raw + rng.choice([-1.0, 1.0], 3) * amplitude_nT * cross + rng.normal(0.0, 1.0, raw.shape)
        res = magbench.calibrate(Dataset(raw, f_ref_nT=np.full(1000, 50_000.0), t_s=np.arange(1000.0)))
        zs = np.abs(res.x - truth) / np.array([res.uncertainty[k] for k in NAMES])
        out.append((res.accepted, float(zs.max()), any("cross-axis" in w for w in res.warnings)))
    return out


def test_a_cross_axis_response_on_a_cap_is_stated_in_the_deviations(monkeypatch):
    """30 nT at full field on a 70-degree cap: on a sphere the answer stays within its deviations (the columns are
    nearly orthogonal to the model's), on a cap the offsets absorb it.  Every answer accepted, said, and within 3
    stated deviations; negative control: without the cross-axis columns, more than 20 deviations off, nothing said."""
    from magbench.calibrators import acceptance

    for accepted, z, said in _cross_on_a_cap(30.0):
        assert accepted and said and z < 3.0, (accepted, z, said)
    monkeypatch.setattr(acceptance, "RESPONSES", acceptance.RESPONSES[:2])
    for accepted, z, said in _cross_on_a_cap(30.0):
        assert accepted and not said and z > 20.0, (accepted, z, said)


def _unsettled(amplitude_nT: float, seeds=range(5)) -> list[tuple[bool, float, bool]]:
    """Readings logged before the sensor's filter settled after each move (a first-order filter, y_i = y_{i-1} + (s_i
    - y_{i-1}) / (1 + tau), tau set so that the error is ``amplitude_nT`` at the median move), 1000 random attitudes on a
    sphere, 1 nT of noise: each reading keeps part of the previous attitude's."""
    out = []
    for seed in seeds:
        rng = np.random.default_rng(200 + seed)
        u = rng.normal(size=(1000, 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        truth, raw = _sensor(50_000.0 * u)
        s = raw - truth[6:]
        tau = amplitude_nT / float(np.median(np.linalg.norm(np.diff(s, axis=0), axis=1)))
        y = np.empty_like(s)
        y[0] = s[0]
        for i in range(1, len(s)):
            y[i] = y[i - 1] + (s[i] - y[i - 1]) / (1.0 + tau)
        raw = truth[6:] + y + rng.normal(0.0, 1.0, s.shape)
        res = magbench.calibrate(Dataset(raw, f_ref_nT=np.full(1000, 50_000.0), t_s=np.arange(1000.0)))
        zs = np.abs(res.x - truth) / np.array([res.uncertainty[k] for k in NAMES])
        out.append((res.accepted, float(zs.max()), any("previous-reading" in w for w in res.warnings)))
    return out


def test_a_reading_that_keeps_part_of_the_previous_attitude_is_stated_in_the_deviations(monkeypatch):
    """3 nT at full field: at random attitudes the previous reading is unrelated to this one, so the memory is a
    shrunk scale plus noise-like scatter, and the answers had been accepted 9 (n 300) to 24 (n 2000) deviations off
    with nothing said (found by a hostile probe, 2026-11-28).  Every answer accepted, said, within 3 deviations;
    negative control: without the previous reading's columns, more than 5 deviations off and nothing said."""
    from magbench.calibrators import acceptance

    for accepted, z, said in _unsettled(3.0):
        assert accepted and said and z < 3.0, (accepted, z, said)
    monkeypatch.setattr(acceptance, "RESPONSES", acceptance.RESPONSES[:3])
    for accepted, z, said in _unsettled(3.0):
        assert accepted and not said and z > 5.0, (accepted, z, said)


def test_the_reading_before_follows_the_time_column():
    """Rows out of time order take the row before in time (a logger restarted, files joined); rows in order, or no
    time column, the row before in the file; the first has none (-1)."""
    from magbench.calibrators.acceptance import neighbour_rows

    def previous_rows(t_s, n):
        return neighbour_rows(t_s, n)[0]

    assert previous_rows(np.array([0.0, 2.0, 1.0, 3.0]), 4).tolist() == [-1, 2, 0, 1]
    assert previous_rows(np.array([0.0, 1.0, 1.0, 2.0]), 4).tolist() == [-1, 0, 1, 2]
    assert previous_rows(None, 3).tolist() == [-1, 0, 1]


def _turning_path(n: int) -> np.ndarray:
    """The field's direction in the body along a path turning three times about an axis that wobbles about the body's
    z (rates 5 and 3 per record), the field 18 degrees from z at the start: one rotation step per reading."""
    e = np.array([0.3, 0.0, 0.95]) / np.hypot(0.3, 0.95)
    step = np.radians(3 * 360.0 / n)
    rot, out = np.eye(3), np.empty((n, 3))
    for i in range(n):
        out[i] = rot.T @ e
        w = np.array([0.3 * np.sin(i * 2 * np.pi / n * 5), 0.3 * np.cos(i * 2 * np.pi / n * 3), 1.0])
        w /= np.linalg.norm(w)
        k = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
        rot = rot @ (np.eye(3) + np.sin(step) * k + (1 - np.cos(step)) * k @ k)
    return out


def _backlash_on_a_turn(half_width_nT: float, seeds=range(5)) -> list[tuple[bool, float, bool]]:
    """Backlash on each axis (the reading stays until the field has moved ``half_width_nT`` away: y_k = clip(y_k',
    s_k - h, s_k + h)) along ``_turning_path``, 2000 readings one second apart, 1 nT of noise."""
    out = []
    body = 50_000.0 * _turning_path(2000)
    for seed in seeds:
        rng = np.random.default_rng(300 + seed)
        truth, raw = _sensor(body)
        s = raw - truth[6:]
        y = np.empty_like(s)
        y[0] = s[0]
        for i in range(1, len(s)):
            y[i] = np.clip(y[i - 1], s[i] - half_width_nT, s[i] + half_width_nT)
        raw = truth[6:] + y + rng.normal(0.0, 1.0, s.shape)
        res = magbench.calibrate(Dataset(raw, f_ref_nT=np.full(len(s), 50_000.0), t_s=np.arange(float(len(s)))))
        zs = np.abs(res.x - truth) / np.array([res.uncertainty[k] for k in NAMES])
        out.append((res.accepted, float(zs.max()), any("lag" in w and "response of the axes" in w
                                                       for w in res.warnings)))
    return out


def test_backlash_along_a_turning_path_is_stated_in_the_deviations(monkeypatch):
    """1 nT of backlash along a turning path lags each axis behind the field: the answers had been accepted 5.5-7.7
    deviations off with nothing said (a hostile probe's path, 2026-11-28; on a path closer to one cone, 17.5 +- 5
    degrees from the turning axis, 9-32 deviations, and still nothing said: a gap left).  The rate of change from the
    readings either side (a lag's column, free of this reading's noise) finds it: every answer accepted, said, within
    3 deviations.  Negative control: without that column, beyond 5 and nothing said."""
    from magbench.calibrators import acceptance

    results = _backlash_on_a_turn(1.0)
    for accepted, z, said in results:
        assert accepted and said and z < 3.0, (accepted, z, said)
    monkeypatch.setattr(acceptance, "RESPONSES", acceptance.RESPONSES[:3])
    controls = _backlash_on_a_turn(1.0)
    assert all(accepted and not said for accepted, _, said in controls), controls
    assert max(z for _, z, _ in controls) > 5.0, controls


def _tumbling_path(n: int, rng: np.random.Generator) -> np.ndarray:
    """The field's direction in the body along a free tumble: four turns in all, one rotation step per reading about an
    axis that wanders (a random walk of 0.15 per step, renormalized)."""
    e = np.array([0.3, 0.0, 0.95]) / np.hypot(0.3, 0.95)
    step = np.radians(4 * 360.0 / n)
    rot, out = np.eye(3), np.empty((n, 3))
    w = rng.normal(size=3)
    for i in range(n):
        out[i] = rot.T @ e
        w = w / np.linalg.norm(w) + 0.15 * rng.normal(size=3)
        w /= np.linalg.norm(w)
        k = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
        rot = rot @ (np.eye(3) + np.sin(step) * k + (1 - np.cos(step)) * k @ k)
    return out


def _warming_gains(amplitude_nT: float, seeds=range(6), with_temperature: bool = True, cycle: bool = False
                   ) -> list[tuple[bool, float, bool]]:
    """Each axis's gain following a warm-up along a ``_tumbling_path``: 2000 readings one second apart, the logged
    temperature rising 15 degrees C as 1 - exp(-t / 500 s) (0.05 C of logging noise), each gain changing by
    ``amplitude_nT`` at full field over that rise (its sign drawn per axis), 1 nT of noise.  The truth is the sensor at
    the record's mean temperature (the gains' time mean).  Without the temperature column the record is the same
    readings.  ``cycle``: the temperature goes once round a cycle (sin(2 pi t / 2000 s)) instead."""
    out = []
    t = np.arange(2000.0)
    rise = np.sin(2 * np.pi * t / 2000.0) if cycle else 1.0 - np.exp(-t / 500.0)
    for seed in seeds:
        rng = np.random.default_rng(700 + seed)
        body = 50_000.0 * _tumbling_path(2000, rng)
        truth, _ = _sensor(body)
        sign = rng.choice([-1.0, 1.0], 3)
        gains = truth[3:6] * (1.0 + sign * amplitude_nT / 50_000.0 * rise[:, None])
        truth = truth.copy()
        truth[3:6] = gains.mean(axis=0)
        raw = gains * _unscaled(body, truth) + truth[6:] + rng.normal(0.0, 1.0, body.shape)
        temp = 20.0 + 15.0 * rise + rng.normal(0.0, 0.05, len(t))
        res = magbench.calibrate(Dataset(raw, f_ref_nT=np.full(len(t), 50_000.0), t_s=t,
                                         temp_C=temp if with_temperature else None))
        zs = np.abs(res.x - truth) / np.array([res.uncertainty[k] for k in NAMES])
        out.append((res.accepted, float(zs.max()), any("temperature gain" in w for w in res.warnings)))
    return out


def test_gains_that_follow_a_logged_temperature_are_stated_in_the_deviations():
    """3 nT at full field of gain change over a warm-up, on a tumbling path, with the temperature in the file: the
    answers had been accepted up to 16 deviations from the sensor at the mean temperature, the temperature column
    unread (6 of these 10 seeds beyond 5; a hostile probe's forward model, 2026-11-28: 11 of 20).  The temperature's
    columns (each axis's gain and zero times T - T̄) find it: every answer accepted, said, within 3 deviations (at
    most 2.4 over 10 seeds).  Negative control: the same readings without their temperature column, beyond 5 and no
    temperature said."""
    results = _warming_gains(3.0)
    for accepted, z, said in results:
        assert accepted and said and z < 3.0, (accepted, z, said)
    controls = _warming_gains(3.0, with_temperature=False)
    assert all(accepted and not said for accepted, _, said in controls), controls
    assert max(z for _, z, _ in controls) > 5.0, controls


def test_a_steady_temperature_asks_for_no_temperature_columns():
    """A logged temperature that does not change (a thermostat: a range below 1 C) adds no columns: the answer and
    its deviations are those of the same record without it."""
    body = 50_000.0 * _turning_path(600)
    rng = np.random.default_rng(5)
    truth, raw = _sensor(body)
    raw = raw + rng.normal(0.0, 1.0, raw.shape)
    t = np.arange(600.0)
    plain = magbench.calibrate(Dataset(raw, f_ref_nT=np.full(600, 50_000.0), t_s=t))
    steady = magbench.calibrate(Dataset(raw, f_ref_nT=np.full(600, 50_000.0), t_s=t, temp_C=np.full(600, 21.5)))
    assert np.array_equal(plain.x, steady.x)
    assert plain.uncertainty == steady.uncertainty and plain.warnings == steady.warnings


def test_gains_that_follow_a_temperature_cycle_are_stated_in_the_deviations():
    """The same gains following a temperature cycle: the temperature's kinds are significant together with others
    (their p-values both 0: the two sets had once been compared as arrays, and the fit raised ValueError on 8 of 20
    of a probe's records).  Every answer accepted, said, within 3 deviations."""
    for accepted, z, said in _warming_gains(3.0, cycle=True):
        assert accepted and said and z < 3.0, (accepted, z, said)

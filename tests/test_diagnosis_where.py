"""'Where' in two dimensions and per axis: a switch-on is placed in time, a structure along one body axis is
seen on that axis, and the attitude x time map separates an attitude from a time structure."""
import numpy as np

from magbench.benchmarks.diagnosis.wheremap import attitude_time_map, axis_projections, change_points


def _unit(n, rng):
    u = rng.normal(size=(n, 3))
    return u / np.linalg.norm(u, axis=1)[:, None]


def test_a_switch_on_is_located_within_2_percent_of_the_record():
    rng = np.random.default_rng(1)
    n = 1500
    t = np.sort(rng.uniform(0, 1800.0, n))
    r = rng.normal(0, 2.0, n) + 12.0 * (t >= 722.0)
    found = change_points(r, t, 2.0)
    assert found and abs(found[0]["time_s"] - 722.0) <= 0.02 * 1800.0
    assert abs(found[0]["size_nT"] - 12.0) < 1.0


def test_negative_control_white_noise_has_no_change_point():
    rng = np.random.default_rng(2)
    t = np.linspace(0, 1000, 2000)
    assert change_points(rng.normal(0, 2.0, 2000), t, 2.0) == []


def test_structure_along_one_axis_is_seen_on_that_axis():
    rng = np.random.default_rng(3)
    u = _unit(2000, rng)
    r = 5.0 * u[:, 1] + rng.normal(0, 1.0, 2000)
    shares = axis_projections(r, u)
    assert shares["y_explained_pct"] > 80 and shares["x_explained_pct"] < 5 and shares["z_explained_pct"] < 5


def test_the_map_tells_attitude_from_time():
    rng = np.random.default_rng(4)
    n = 3000
    u, t = _unit(n, rng), np.linspace(0, 3600, n)
    attitude = attitude_time_map(6.0 * u[:, 0] + rng.normal(0, 1, n), u, t)
    timely = attitude_time_map(6.0 * np.sin(t / 600) + rng.normal(0, 1, n), u, t)
    assert attitude["attitude_explained_pct"] > 50 > attitude["time_explained_pct"]
    assert timely["time_explained_pct"] > 50 > timely["attitude_explained_pct"]

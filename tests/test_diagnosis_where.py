"""'Where' in two dimensions and per axis: a switch-on is placed in time, a structure along one body axis is
seen on that axis, and the attitude x time map separates an attitude from a time structure."""
import numpy as np
import pytest

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


def test_the_switch_scan_from_sums_equals_a_least_squares_fit_per_candidate():
    import numpy as np

    from magbench.benchmarks.diagnosis.wheremap import MIN_SEGMENT, STEP_GRID, body_field_step

    rng = np.random.default_rng(1)
    n = 2000
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    t = np.sort(rng.uniform(0, 1000, n))
    r = rng.normal(0, 1, n) + (t > 620) * (u @ np.array([30.0, -20.0, 10.0]))
    best = None  # the reference: every candidate's own least-squares fit of [u H, u, 1]
    base = np.column_stack([u, np.ones(n)])
    for q in np.linspace(0.02, 0.98, STEP_GRID):
        on = t >= np.quantile(t, q)
        if on.sum() < MIN_SEGMENT or (~on).sum() < MIN_SEGMENT:
            continue
        cols = np.column_stack([u * on[:, None], base])
        coef = np.linalg.lstsq(cols, r, rcond=None)[0]
        sse = float(np.sum((r - cols @ coef) ** 2))
        if best is None or sse < best[0]:
            cut = int(np.argmax(on))
            best = (sse, 0.5 * (t[cut - 1] + t[cut]), coef[:3])
    step = body_field_step(r, u, t, 1.0)
    assert step["time_s"] == pytest.approx(best[1])
    assert np.allclose(step["vector_nT"], best[2], atol=1e-6)

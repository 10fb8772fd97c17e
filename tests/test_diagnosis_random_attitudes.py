"""Records at random attitudes (consecutive samples unrelated in attitude): the noise floor from the residual of
the fit with every effect free (``floor.model_floor``), and the time-shift signature that needs readings changing
continuously (``naming.roughness``).  Each rule with a record it must name and one it must reject."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from independent_forward import make_case  # noqa: E402

from magbench.benchmarks.diagnosis import diagnose  # noqa: E402
from magbench.benchmarks.diagnosis.floor import (  # noqa: E402
    attitude_floor,
    model_floor,
    neighbour_z,
    time_difference_floor,
)
from magbench.benchmarks.diagnosis.naming import ROUGHNESS_MAX, roughness  # noqa: E402
from magbench.simulate.dataset import Dataset  # noqa: E402


def _run(i: int) -> dict:
    c = make_case(i, 2026)
    return diagnose(Dataset(c.raw_nT, f_ref_nT=c.f_ref_nT, t_s=c.t_s, temp_C=c.temp_C), gravity=c.gravity)


def _sphere(n: int, rng: np.random.Generator) -> np.ndarray:
    u = rng.normal(size=(n, 3))
    return 50_000.0 * u / np.linalg.norm(u, axis=1)[:, None]


def test_roughness_tells_random_attitudes_from_continuous_motion():
    rng = np.random.default_rng(1)
    t = np.arange(600.0)
    assert roughness(t, _sphere(600, rng)) > ROUGHNESS_MAX  # sqrt(3) for unrelated samples
    a = 2 * np.pi * t / 200.0
    smooth = 50_000.0 * np.column_stack([np.cos(a), np.sin(a), 0.3 + 0 * a]) + rng.normal(0, 1.0, (600, 3))
    assert roughness(t, smooth) < ROUGHNESS_MAX


def _floor_inputs(rng, n=900):
    raw = _sphere(n, rng)
    t = np.arange(float(n))
    r_base = rng.normal(0, 20.0, n)  # the base residual's time differences carry attitude structure: 20 nT
    fl = time_difference_floor(r_base, t)
    return raw, t, fl


def test_model_floor_replaces_a_floor_inflated_by_attitude_structure():
    rng = np.random.default_rng(2)
    raw, t, fl = _floor_inputs(rng)
    out = model_floor(fl, rng.normal(0, 2.0, len(t)), t, raw, 40, np.zeros(len(t), bool))
    assert out["noise_floor_nT"] == pytest.approx(2.0, rel=0.15)
    # negative control: a model residual as large as the base one leaves the floor alone
    same = model_floor(fl, rng.normal(0, 20.0, len(t)), t, raw, 40, np.zeros(len(t), bool))
    assert same["noise_floor_nT"] == fl["noise_floor_nT"]


def test_model_floor_is_refused_when_the_residual_follows_the_motion_between_samples():
    rng = np.random.default_rng(3)
    raw, t, fl = _floor_inputs(rng)
    step = np.r_[0.0, np.linalg.norm(np.diff(raw, axis=0), axis=1)]
    r_model = rng.normal(0, 1.0, len(t)) * (0.5 + step / step.mean()) * 2.0  # a reading mixed with the previous one
    out = model_floor(fl, r_model, t, raw, 40, np.zeros(len(t), bool))
    assert abs(out["floor_motion_z"]) > 3
    assert out["noise_floor_nT"] == fl["noise_floor_nT"]


def test_a_nonlinearity_at_random_attitudes_is_named_and_a_clean_record_stays_none():
    out = _run(178)  # sphere, nonlinearity: the base floor was 4.7 times the noise and the verdict none
    assert out["verdict"] == "nonlinearity", out["verdict"]
    assert "effect free" in out["floor_method"]
    clean = _run(120)  # sphere, clean
    assert clean["verdict"] == "none", clean["verdict"]


def test_lag_terms_at_random_attitudes_are_not_named_but_a_lag_on_a_tumble_is():
    eddy = _run(617)  # sphere, eddy currents (outside the library): the lag terms fit them
    assert eddy["verdict"] == "unexplained", eddy["verdict"]
    row = next(e for e in eddy["naming"]["evidence"] if e["name"] == "lag")
    assert not row["named"] and row["roughness"] > ROUGHNESS_MAX
    mixed = _run(919)  # sphere, lag + field drift + temperature: no nonlinearity for the square of the mixed reading
    assert "nonlinearity" not in mixed["verdict"] and "lag" not in mixed["verdict"], mixed["verdict"]
    assert _run(62)["verdict"] == "lag"  # tumble: continuous motion


def test_model_floor_is_refused_when_the_residual_depends_on_the_neighbouring_readings():
    rng = np.random.default_rng(4)
    raw, t, fl = _floor_inputs(rng)
    white = rng.normal(0, 2.0, len(t))
    assert abs(neighbour_z(white, raw)) < 3  # noise: no dependence
    # a product of the reading with the previous one (the second-order term of a reading mixed with its neighbour)
    prev = np.r_[raw[:1], raw[:-1]]
    mixed = white + 12.0 * raw[:, 0] * prev[:, 1] / 50_000.0 ** 2  # a few nT, below the 20 nT of the base floor
    assert neighbour_z(mixed, raw) > 3
    out = model_floor(fl, mixed, t, raw, 40, np.zeros(len(t), bool))
    assert out["noise_floor_nT"] == fl["noise_floor_nT"]


def test_model_floor_is_refused_when_the_residual_remembers_where_the_sensor_pointed():
    rng = np.random.default_rng(5)
    raw, t, fl = _floor_inputs(rng)
    white = rng.normal(0, 2.0, len(t))
    u = raw / np.linalg.norm(raw, axis=1)[:, None]
    induced = np.zeros_like(raw)  # a field induced with a lag of ten samples, at random attitudes
    for i in range(1, len(t)):
        induced[i] = 0.9 * induced[i - 1] + 0.1 * raw[i - 1]
    lagged = white + 2e-4 * np.einsum("ij,ij->i", u, induced)  # a few nT, below the 20 nT of the base floor
    assert abs(neighbour_z(white, raw)) < 3 and neighbour_z(lagged, raw) > 3
    assert model_floor(fl, lagged, t, raw, 40, np.zeros(len(t), bool))["noise_floor_nT"] == fl["noise_floor_nT"]


def test_a_residual_that_follows_the_neighbouring_readings_at_random_attitudes_is_unexplained():
    # a rotating iron part at random attitudes: the floor (time differences) holds the structure, so the remainder
    # test reads 'none'; the full fit's residual depends on the neighbouring readings, which noise does not
    out = _run(341)
    assert out["floor_neighbour_z"] > 3.0
    assert out["verdict"] == "unexplained" and out["remainder_follows_neighbours"]
    # negative controls at random attitudes: a clean record stays 'none', a named temperature gains no 'unexplained'
    clean = _run(108)
    assert clean["verdict"] == "none" and "remainder_follows_neighbours" not in clean
    single = _run(22)
    assert single["verdict"] == "temperature"


def _attitudes(n, rng):
    """Random attitudes: the body-frame field and gravity directions of n uniformly drawn rotations."""
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    w, x, y, z = q.T
    rot = np.stack([np.column_stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)]),
                    np.column_stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)]),
                    np.column_stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])], axis=1)
    b = np.einsum("nji,j->ni", rot, np.array([0.5, 0.0, 0.866]))
    g = np.einsum("nji,j->ni", rot, np.array([0.0, 0.0, 1.0]))
    return b, g


def test_attitude_floor_cancels_a_field_that_follows_gravity_but_not_noise():
    rng = np.random.default_rng(6)
    n = 900
    b, g = _attitudes(n, rng)
    structure = 15.0 * g[:, 0] * g[:, 2] + 10.0 * b[:, 1] * g[:, 1]  # a smooth function of the attitude, ~7 nT RMS
    r = structure + rng.normal(0, 2.0, n)
    t = np.arange(float(n))
    fl = time_difference_floor(r, t)  # random attitudes: the time differences hold the structure
    assert fl["noise_floor_nT"] > 5.0
    spikes = np.zeros(n, bool)
    out = attitude_floor(fl, r, b, g, 20, spikes)
    assert out["noise_floor_nT"] < 3.5 and "neighbours in attitude" in out["floor_method"]
    # negative control: white noise alone keeps its floor (the attitude floor is no lower)
    white = rng.normal(0, 2.0, n)
    fl_white = time_difference_floor(white, t)
    assert attitude_floor(fl_white, white, b, g, 20, spikes)["noise_floor_nT"] == fl_white["noise_floor_nT"]
    # ... and a residual that follows the neighbouring readings keeps the floor it has
    follows = dict(fl, floor_neighbour_z=5.0)
    assert attitude_floor(follows, r, b, g, 20, spikes)["noise_floor_nT"] == fl["noise_floor_nT"]


def test_body_fields_tied_to_gravity_at_random_attitudes_are_unexplained_not_none():
    # sphere records with an accelerometer: a gravity-following body field, a heading (tilt) field, a gradient
    # through a lever arm; the time floor held them (4-15 times the noise) and the verdict was none
    for i in (520, 35, 640):
        out = _run(i)
        assert out["verdict"] == "unexplained", (i, out["verdict"])
        assert "neighbours in attitude" in out["floor_method"]
    assert _run(120)["verdict"] == "none"  # clean, sphere, with gravity

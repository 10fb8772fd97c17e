"""The pieces that keep the diagnosis right on messy records: time derivatives and a noise floor that
survive irregular sampling, a fit that never ends worse than it started, a robust base start against
spikes of thousands of nT, the thermal time constant between grid points, and the quintic of soft
saturation.  Each test has a negative control: the naive method it replaces fails the same check."""
import numpy as np
import pytest

from magbench.benchmarks.diagnosis import diagnose
from magbench.benchmarks.diagnosis.blind import blind_dataset, category, classify
from magbench.benchmarks.diagnosis.floor import _interpolation_errors, time_difference_floor
from magbench.simulate.effects import (
    NonlinearityEffect,
    TemperatureEffect,
    first_order_lag,
    local_derivatives,
    robust_sigma,
    time_derivative,
)


def _irregular_times(rng, n, duration=600.0):
    t = np.sort(rng.uniform(0.0, duration, n))
    t[0] = 0.0
    return t


def test_local_derivatives_are_exact_for_a_quadratic_on_irregular_times():
    rng = np.random.default_rng(0)
    t = _irregular_times(rng, 400)
    x = 3.0 + 0.5 * t - 0.002 * t**2
    d1, d2 = local_derivatives(t, x)
    assert np.allclose(d1, 0.5 - 0.004 * t, atol=1e-6) and np.allclose(d2, -0.004, atol=1e-6)


def test_local_derivatives_leave_each_sample_out_of_its_own_derivative():
    rng = np.random.default_rng(1)
    t = _irregular_times(rng, 200)
    x = np.sin(t / 50.0)
    kicked = x.copy()
    kicked[100] += 1000.0
    assert local_derivatives(t, kicked)[0][100] == pytest.approx(local_derivatives(t, x)[0][100], abs=1e-9)


def test_local_derivatives_keep_noise_bounded_where_central_differences_explode():
    rng = np.random.default_rng(2)
    t = _irregular_times(rng, 2000)
    x = np.sin(t / 40.0) * 100.0 + rng.normal(0.0, 1.0, len(t))
    true = np.cos(t / 40.0) * 100.0 / 40.0
    err_local = robust_sigma(local_derivatives(t, x)[0] - true)
    err_central = robust_sigma(time_derivative(t, x) - true)  # negative control: np.gradient on uneven t
    assert err_local < 0.5 * err_central, (err_local, err_central)


def test_floor_from_interpolation_is_not_inflated_by_smooth_structure_on_irregular_times():
    rng = np.random.default_rng(3)
    t = _irregular_times(rng, 3000)
    sigma = 0.5
    r = 30.0 * np.sin(2 * np.pi * t / 15.0) + rng.normal(0.0, sigma, len(t))
    floor = time_difference_floor(r, t)["noise_floor_nT"]
    assert floor == pytest.approx(sigma, rel=0.1)
    plain = robust_sigma(np.diff(r, 2)) / np.sqrt(6.0)  # negative control: second differences as if even
    assert plain > 1.3 * sigma, plain


def test_interpolation_errors_on_even_sampling_are_the_second_differences():
    r = np.random.default_rng(4).normal(size=50)
    e1 = _interpolation_errors(r, None, 1)
    assert np.allclose(e1, -np.diff(r, 2) / np.sqrt(6.0))


def test_quintic_basis_is_orthogonal_on_the_sphere_to_constant_reading_and_lower_orders():
    x = np.linspace(-1.0, 1.0, 200_001)  # a component of a uniform direction is uniform on [-1, 1]
    terms = [np.ones_like(x), x, *NonlinearityEffect.basis(x)]
    gram = np.array([[np.trapezoid(a * b, x) for b in terms] for a in terms])
    off = gram - np.diag(np.diag(gram))
    assert np.abs(off).max() < 1e-8


def test_thermal_time_constant_between_grid_points_is_refined():
    from magbench.benchmarks.diagnosis.vector import Diagnosis
    from magbench.simulate.scenarios import get_scenario

    data = get_scenario("tumble9q").build(7)
    span = float(np.ptp(data.t_s))
    tau = 0.06 * span  # between the grid's 0.03 and 0.1
    effect = TemperatureEffect(time_constant_s=tau)
    data = get_scenario("tumble9q").with_effects(effect).build(7)
    r = Diagnosis(data, base="nine").run()
    fitted = r["effect_info"]["temperature"]["thermal_time_constant_s"]
    assert fitted == pytest.approx(tau, rel=0.25), (fitted, tau)
    assert r["verdict"] == "temperature|offset_drift"  # the temperature follows time: said with its look-alike
    assert first_order_lag(data.t_s, data.temp_C, fitted).shape == data.temp_C.shape


def test_spikes_of_thousands_of_nT_on_narrow_coverage_get_a_robust_base_and_are_named():
    label, base, data = blind_dataset(25)  # a band of attitudes, Student-t spikes up to 2000 nT, and a lag
    assert label == "lag+outliers"
    r = diagnose(data, base=base)
    assert r["base_fit"] == "ransac"
    assert "outliers" in r["selected"], r["verdict"]
    # the lsq start pulled by the spikes had scales of 1.4 to 2 and offsets of 10^4 nT; the sensor is near identity
    assert all(abs(r["base_params"][k] - 1.0) < 0.05 for k in ("kx", "ky", "kz")), r["base_params"]


def test_the_extended_fit_never_ends_worse_than_it_started():
    from magbench.benchmarks.diagnosis.vector import Diagnosis

    label, base, data = blind_dataset(25)
    captured = {}

    class Spy(Diagnosis):
        @staticmethod
        def _spikes(model, x_lin, every):
            captured.update(model=model, x=x_lin, every=every)
            return Diagnosis._spikes(model, x_lin, every)

    Spy(data, base=base).run()
    model, x0, every = captured["model"], captured["x"], captured["every"]
    free = model.free_indices(every)
    keep = np.ones(len(data), bool)
    blocks = model._fit_blocks(None)
    sse0 = model._normal_equations(x0, free, keep, blocks)[0]
    x1 = model.fit(x0, free, keep=keep, iterations=3)
    assert model._normal_equations(x1, free, keep, blocks)[0] <= sse0


@pytest.fixture(scope="module")
def blind45():
    out = []
    for i in range(45):
        label, base, data = blind_dataset(i)
        out.append((label, classify(label, diagnose(data, base=base)["verdict"])))
    return out


def test_blind_check_rates_on_three_cycles(blind45):
    by = {}
    for label, outcome in blind45:
        by.setdefault(category(label), []).append(outcome)
    # The naming rule confirms an effect on time- and attitude-blocked folds before naming it (precision
    # first: on the independent forward model, tests/test_diagnosis_independent.py, wrong names fell from 17
    # to 2 in 48 records).  On this generator's faster-varying drifts that costs recall (single effects 92 ->
    # 72 %, pairs 84 -> 40 % fully right); what it misses it calls unexplained, and it names nothing wrong.
    assert all(o == "right" for o in by["clean"]), by["clean"]
    assert sum(o == "right" for o in by["single"]) >= 0.7 * len(by["single"]), by["single"]
    assert sum(o == "right" for o in by["pair"]) >= 0.35 * len(by["pair"]), by["pair"]
    assert all("wrong" not in by[c] for c in by), by


def test_first_order_lead_undoes_a_thermometer_lag_on_quantized_irregular_readings():
    """A thermometer that lags the sensor logs its temperature through a first-order lag (here solved on a fine
    grid, independently of the library's filter) and rounds it to 1/16 degC; the lead recovers the sensor's."""
    from magbench.simulate.effects import first_order_lead

    rng = np.random.default_rng(5)
    fine = np.linspace(0.0, 3600.0, 360_001)
    true = 20.0 + 12.0 * (1 - np.exp(-fine / 900.0)) + 1.5 * np.sin(2 * np.pi * fine / 700.0)
    tau = 120.0
    logged_fine = np.empty_like(true)
    logged_fine[0] = true[0]
    a = (fine[1] - fine[0]) / tau
    for i in range(1, len(fine)):  # d logged / dt = (true - logged) / tau
        logged_fine[i] = logged_fine[i - 1] + a * (true[i - 1] - logged_fine[i - 1])
    t = _irregular_times(rng, 1500, 3600.0)
    logged = np.round(np.interp(t, fine, logged_fine) / 0.0625) * 0.0625
    truth = np.interp(t, fine, true)
    inner = (t > 300.0) & (t < 3300.0)
    err_log = float(np.sqrt(np.mean((logged - truth)[inner] ** 2)))
    err_lead = float(np.sqrt(np.mean((first_order_lead(t, logged, tau) - truth)[inner] ** 2)))
    assert err_log > 0.5  # negative control: the log itself is off by the lag
    assert err_lead < 0.15 * err_log, (err_lead, err_log)
    assert np.allclose(first_order_lag(t, logged, -tau), first_order_lead(t, logged, tau))


@pytest.mark.parametrize("index", [70, 274])
def test_a_thermometer_that_lags_the_sensor_is_fitted_as_a_negative_time_constant(index):
    """The second independent generator logs a board thermometer that lags the sensor's temperature (its own
    first-order lag, ``temp_log_lag_s``); the fitted thermal time constant is that lag with a minus sign."""
    r, case = _independent(index, generator=2)
    assert list(case.present) == ["temperature"]
    fitted = r["effect_info"]["temperature"]["thermal_time_constant_s"]
    assert fitted == pytest.approx(-case.notes["temp_log_lag_s"], rel=0.1), fitted
    assert "temperature" in r["selected"], r["verdict"]


@pytest.mark.parametrize("index", [1168, 1179])
def test_a_lead_is_not_fitted_where_no_thermometer_lags(index):
    """Negative controls from the first independent generator (no thermometer lag): a field switched on (1168) and a
    field drift beside spikes (1179).  Offered freely, a lead's bump at the temperature's fastest change fitted both
    at the largest lead allowed and named temperature for them; a lead must beat the best lag and lie inside the grid."""
    r, case = _independent(index, generator=1)
    assert "temperature" not in case.present
    assert r["effect_info"]["temperature"]["thermal_time_constant_s"] >= 0.0
    assert "temperature" not in r["verdict"], r["verdict"]


def _independent(index: int, generator: int):
    """(the diagnosis, the case) of an independent generator's record (tests/independent_cases.py)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from independent_cases import run_case

    return run_case(index, generator)

"""A sensor's range switch (its axes' gains and zeros jumping once) is not a temperature coefficient
(``naming.range_switch_explains``, used by ``Diagnosis._range_switch`` while the logged temperature does not jump):
the second independent generator's ``gain_switch`` was named ``temperature`` in 7 of its records.  The residuals are
written here from the physics of a fluxgate at random attitudes; the controls are a smooth change of the field's
magnitude and an ambient field that steps once (equal gains, no zero jump), which are not a switch of the sensor."""
import numpy as np
import pytest

from magbench.benchmarks.diagnosis.naming import range_switch_explains

N = 900
F_NT = 50000.0


def _attitudes(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, 1800.0, N)
    u = rng.normal(size=(N, 3))
    return t, u / np.linalg.norm(u, axis=1)[:, None]


def _smooth_sse(r: np.ndarray, t: np.ndarray) -> float:
    """The sum of squares a smooth scalar drift (a degree-12 Legendre series of time) leaves."""
    design = np.polynomial.legendre.legvander(2 * t / t[-1] - 1, 12)
    return float(np.sum((r - design @ np.linalg.lstsq(design, r, rcond=None)[0]) ** 2))


def test_a_range_switch_is_found_at_its_time():
    rng = np.random.default_rng(3)
    t, u = _attitudes(rng)
    on = (t >= 700.0).astype(float)
    gains = np.array([4e-4, -1e-4, 2e-4]) * F_NT  # nT: each axis's gain jump times the field
    r = on * ((u * u) @ gains - u @ np.array([6.0, -4.0, 5.0])) + rng.normal(0.0, 1.0, N)
    switch = range_switch_explains(r, u, t, _smooth_sse(r, t))
    assert switch is not None
    assert switch["time_s"] == pytest.approx(700.0, abs=0.02 * 1800.0)
    assert np.allclose(switch["gain_jumps_nT"], gains, atol=1.5)


@pytest.mark.parametrize("kind", ["smooth magnitude", "ambient step"])
def test_negative_controls_a_field_that_changes_is_not_a_switch(kind):
    rng = np.random.default_rng(4)
    t, u = _attitudes(rng)
    if kind == "smooth magnitude":  # the field's magnitude wandering smoothly: the step explains too little of it
        r = 15.0 * np.sin(2 * np.pi * t / 700.0) + rng.normal(0.0, 1.0, N)
    else:  # the ambient field stepping once: every axis alike, no zero jump (the jump test refuses it)
        r = 12.0 * (t >= 700.0) + rng.normal(0.0, 1.0, N)
    assert range_switch_explains(r, u, t, _smooth_sse(r, t)) is None


def test_a_switch_of_the_alignment_is_found_with_the_calibration_before_it_free():
    """Axes swapped or remounted: the cross terms u_i u_j jump too.  The residual is taken at a fit of the whole
    record, so the calibration before the switch sits between the two (half the jump below, half above)."""
    rng = np.random.default_rng(5)
    t, u = _attitudes(rng)
    on = (t >= 900.0).astype(float)
    cross = u[:, [0, 0, 1]] * u[:, [1, 2, 2]]
    jump = cross @ np.array([30.0, -20.0, 10.0]) + (u * u) @ np.array([15.0, -10.0, 0.0]) - u @ np.array([8.0, 0.0, -6.0])
    r = (on - 0.5) * jump + rng.normal(0.0, 1.0, N)
    switch = range_switch_explains(r, u, t, _smooth_sse(r, t))
    assert switch is not None and switch["time_s"] == pytest.approx(900.0, abs=0.02 * 1800.0)


def test_negative_control_a_gain_that_follows_a_steady_warming_is_not_a_switch():
    """A temperature coefficient on a steady warming changes the gains along a ramp: any step at its middle takes
    75 % of it, short of STEP_SHARE of what the smooth change takes."""
    rng = np.random.default_rng(6)
    t, u = _attitudes(rng)
    ramp = t / t[-1] - 0.5
    r = ramp * ((u * u) @ np.array([40.0, -20.0, 25.0]) + u @ np.array([10.0, -5.0, 0.0])) + rng.normal(0.0, 1.0, N)
    design = np.polynomial.legendre.legvander(2 * t / t[-1] - 1, 1)
    temperature_like = np.column_stack([design[:, 1:] * (u * u), design[:, 1:] * u, u, u * u, np.ones(N)])
    sse_effect = float(np.sum((r - temperature_like @ np.linalg.lstsq(temperature_like, r, rcond=None)[0]) ** 2))
    assert range_switch_explains(r, u, t, sse_effect) is None

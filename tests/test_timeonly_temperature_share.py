"""A fixed sensor's drift across its readings keeps ``temperature`` among its alternatives only when the logged
temperature can take the drift's shape: it follows time and, through its best first-order lag, takes at least
THERMAL_SHARE_OF_TREND of what the smooth trend takes (or fits the trend as well).  A thermometer that warms
smoothly beside a field that oscillates is no alternative: a temperature coefficient moves the readings along the
temperature's own shape.  Written from the physics (a pier-mounted sensor beside a scalar reference that reports a
model value), and checked on the independent generators' development records."""
import numpy as np
import pytest
from independent_cases import run_case

from magbench.benchmarks.diagnosis import diagnose
from magbench.benchmarks.diagnosis.timeonly import TEMPERATURE_FOLLOWS_TIME_R2, THERMAL_SHARE_OF_TREND
from magbench.simulate.dataset import Dataset

B = np.array([19000.0, -1200.0, 45000.0])
F = float(np.linalg.norm(B))


def pier(kind: str, seed: int = 0, n: int = 1500, hours: float = 3.0) -> Dataset:
    """A fixed sensor whose thermometer warms smoothly by 4 degC (a hut in the morning sun), with either a field that
    oscillates (``field``: three cycles along a direction of its own, turning the field) or offsets that follow the
    temperature (``thermal``: 5 nT/degC along a body direction), on 1 nT of white noise."""
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0.0, hours * 3600.0, n))
    u = t / t[-1]
    temp = 18.0 + 4.0 * (1.0 - np.exp(-3.0 * u)) + rng.normal(0, 0.01, n)
    direction = rng.normal(0, 1, 3)
    direction /= np.linalg.norm(direction)
    change = 25.0 * np.sin(2 * np.pi * 3.0 * u + rng.uniform(0, 6)) if kind == "field" else 5.0 * (temp - temp.mean())
    raw = B + change[:, None] * direction + rng.normal(0, 1.0, (n, 3))
    return Dataset(raw, f_ref_nT=np.full(n, F), t_s=t, temp_C=temp)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_warming_thermometer_is_no_alternative_to_an_oscillating_field(seed):
    r = diagnose(pier("field", seed))
    d = r["time_only"]["drift_direction"]
    # the control of the change: the temperature follows time, which alone used to put it among the alternatives
    assert d["temperature_follows_time_r2"] >= TEMPERATURE_FOLLOWS_TIME_R2
    assert d["temperature_share_of_trend"] < THERMAL_SHARE_OF_TREND
    assert r["verdict"] == "offset_drift|field_drift"


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_offsets_that_follow_the_warming_keep_temperature(seed):
    r = diagnose(pier("thermal", seed))
    assert "temperature" in r["verdict"].replace("|", "+").split("+")


@pytest.mark.parametrize("generator, index, verdict", [
    (2, 21, "offset_drift|field_drift"),  # a field drift; the temperature takes 0.11 of its trend
    (4, 15, "offset_drift|field_drift"),  # a field drift; 0.32
    (4, 462, "offset_drift|field_drift"),  # an offset drift; 0.25
    (2, 93, "offset_drift|temperature|field_drift"),  # a true temperature that follows time: kept
    (4, 102, "offset_drift|temperature|field_drift"),  # the same, on the fourth generator
])
def test_independent_fixed_records(generator, index, verdict):
    result, case = run_case(index, generator)
    assert case.category == "fixed"
    assert result["verdict"] == verdict

"""A fixed sensor's drift faster than a smooth trend of degree 6 (a geomagnetic pulsation, a substorm's bays) is still
a drift: the trend's degree rises until what it leaves no longer follows its time neighbours (``_trend_fit``), and the
F test sees it.  Written from the physics: an observatory-like fixed sensor beside a scalar reference that reports a
constant (a model value), the field varying in the world frame."""
import numpy as np

from magbench.benchmarks.diagnosis import diagnose
from magbench.benchmarks.diagnosis.timeonly import TREND_DEGREE, _trend_fit
from magbench.simulate.dataset import Dataset

B = np.array([19000.0, -1200.0, 45000.0])
F = float(np.linalg.norm(B))


def pulsating(amplitude_nT=20.0, cycles=14.0, noise=1.0, seed=0, n=1500, hours=2.0):
    """``cycles`` of a field oscillation over the record (a Pc5-like pulsation with a slowly varying amplitude), along
    a direction of its own (it turns the field as well as changing its magnitude), on white noise."""
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0.0, hours * 3600.0, n))
    u = t / t[-1]
    direction = rng.normal(0, 1, 3)
    direction /= np.linalg.norm(direction)
    wave = amplitude_nT * (0.6 + 0.4 * np.sin(np.pi * u)) * np.sin(2 * np.pi * cycles * u + rng.uniform(0, 6))
    raw = B + wave[:, None] * direction + rng.normal(0, noise, (n, 3))
    temp = 20.0 + 0.3 * rng.standard_normal(n).cumsum() / np.sqrt(n)  # a thermometer that wanders a little
    return Dataset(raw, f_ref_nT=np.full(n, F), t_s=t, temp_C=temp)


def test_a_pulsation_is_a_drift():
    r = diagnose(pulsating())
    direction = r["time_only"]["drift_direction"]
    assert direction["trend_degree"] > TREND_DEGREE
    assert "field_drift" in r["verdict"].split("|") and "offset_drift" in r["verdict"]  # turns: either, said as a|b
    assert "drift" in r["time_verdict"]
    assert any("field_drift" in c["alternatives"] for c in r["confounded"])


def test_degree_six_alone_misses_it():
    """The negative control of the change: the same record's trend at degree 6 leaves a residual whose lag-1
    correlation is far above the level at which the degree is raised (the F test then saw 'no significant drift')."""
    d = pulsating()
    x = d.raw_nT - d.raw_nT.mean(axis=0)
    u = 2 * (d.t_s - d.t_s[0]) / np.ptp(d.t_s) - 1
    degree = _trend_fit(u, x)[0]
    six = np.polynomial.legendre.legvander(u, TREND_DEGREE)
    left = x - six @ np.linalg.lstsq(six, x, rcond=None)[0]
    rho = max(float(np.corrcoef(left[:-1, j], left[1:, j])[0, 1]) for j in range(3))
    assert rho > 0.8 and degree > TREND_DEGREE


def test_noise_alone_is_not_a_drift():
    """White noise is not a drift at any degree: the degree is not raised, nothing is named."""
    for seed in range(6):
        r = diagnose(pulsating(amplitude_nT=0.0, seed=seed))
        assert r["verdict"] == "insufficient_data", (seed, r["verdict"])
        assert r["time_verdict"] == "constant"
        assert r["time_only"]["drift_direction"]["trend_degree"] == TREND_DEGREE


def test_a_wandering_thermometer_is_no_alternative_to_a_pulsation():
    """The thermometer of the record wanders; through a first-order lag it fits a smooth trend of degree 6 (which
    misses the pulsation) about as well as that trend does, but it takes little of the pulsation itself: the
    temperature is not among the alternatives."""
    r = diagnose(pulsating())
    direction = r["time_only"]["drift_direction"]
    assert direction["temperature_share_of_trend"] < 0.5
    assert "temperature" not in r["verdict"]

"""A dead axis (one column stuck at 0 while the sensor turns) is no calibrated sensor: on a record of random
attitudes its scatter about the neighbours (~12,000 nT) was taken for the noise floor, and the diagnosis said
``none`` with 15,700 nT of residual.  A floor above FLOOR_MAX_OF_FIELD of the field is no magnetometer's noise: the
remainder is then unexplained, with the reason (``floor_implausible``), never ``none``."""
import subprocess
import sys

import pytest

from magbench.benchmarks.diagnosis import diagnose
from magbench.benchmarks.diagnosis.vector import FLOOR_MAX_OF_FIELD
from magbench.simulate import simulate
from magbench.simulate.dataset import Dataset


def _dead(scenario: str, axis: int) -> Dataset:
    d = simulate(scenario, 1)
    raw = d.raw_nT.copy()
    raw[:, axis] = 0.0
    return Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s, temp_C=d.temp_C)


@pytest.mark.parametrize("scenario", ["sphere9", "cap9"])
@pytest.mark.parametrize("axis", [0, 2])
def test_a_dead_axis_at_random_attitudes_is_unexplained_with_the_floor_said_implausible(scenario, axis):
    report = diagnose(_dead(scenario, axis))
    assert report["verdict"] == "unexplained"
    assert report["noise_floor_nT"] > FLOOR_MAX_OF_FIELD * 5e4
    assert report["remainder_significant"] and "no magnetometer is that noisy" in report["floor_implausible"]


@pytest.mark.parametrize("scenario", ["sphere9", "cap9"])
def test_the_same_records_intact_are_none(scenario):
    """The negative control: the live record's floor is its noise, far below the limit, and nothing is left."""
    report = diagnose(simulate(scenario, 1))
    assert report["noise_floor_nT"] < 0.001 * 5e4
    assert report["verdict"] == "none" and "floor_implausible" not in report


@pytest.mark.parametrize("scenario", ["tumble9", "vehicle9", "lu2014"])
def test_a_dead_axis_on_a_smooth_path_is_unexplained_against_a_true_floor(scenario):
    report = diagnose(_dead(scenario, 2))
    assert report["verdict"] == "unexplained"
    assert report["rms_base_nT"] > 100 * report["noise_floor_nT"]


def test_the_command_says_why(tmp_path):
    path = tmp_path / "dead.csv"
    _dead("sphere9", 2).to_csv(path)
    p = subprocess.run([sys.executable, "-m", "magbench", "diagnose", str(path)], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert "the noise floor is implausible" in p.stdout and "verdict: unexplained" in p.stdout

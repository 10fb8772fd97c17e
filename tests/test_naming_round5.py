"""An offset drift of a finer shape than its cubic (a wandering offset) leaves no remainder beside its name, and a
time effect is tested on attitude-blocked folds of several smaller regions each (a slowly turning gimbal visits a
region of directions over long stretches of time, which a time effect was asked to bridge).  Records come from the
second independent forward model (tests/independent_forward2.py, its development cases 0-479)."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from independent_forward2 import make_case  # noqa: E402

from magbench.benchmarks.diagnosis import diagnose  # noqa: E402
from magbench.benchmarks.diagnosis.naming import attitude_blocks  # noqa: E402
from magbench.simulate.dataset import Dataset  # noqa: E402


def run_case(index: int) -> tuple[dict, object]:
    assert index < 480  # the second generator's development cases only
    case = make_case(index, 2026)
    data = Dataset(case.raw_nT, f_ref_nT=case.f_ref_nT, t_s=case.t_s, temp_C=case.temp_C)
    return diagnose(data, gravity=case.gravity), case


def test_a_wandering_offset_is_named_without_a_remainder():
    result, case = run_case(433)  # a random walk on top of a linear drift of the offsets
    assert case.present == ("offset_drift",) and not case.outside
    assert result["verdict"] == "offset_drift"
    finer = result["remainder_finer_drift"]
    assert not finer["remainder_significant"] and finer["degree"] > 3


def test_negative_control_a_remainder_the_finer_drift_does_not_explain_stays():
    result, case = run_case(304)  # a thermal gradient (outside the library) read as a drift of the offsets
    assert case.outside == ("thermal_gradient",)
    assert result["verdict"].endswith("+unexplained") and "offset_drift" in result["verdict"]
    assert result["remainder_finer_drift"]["remainder_significant"]


def test_attitude_blocks_are_several_regions_per_fold():
    rng = np.random.default_rng(0)
    u = rng.normal(size=(2000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    label = attitude_blocks(u, 5, 0)
    assert set(label.tolist()) == set(range(5))
    one = attitude_blocks(u, 5, 0, cycles=1)  # one region per fold: the fold's directions are one cap
    many = attitude_blocks(u, 5, 0, cycles=4)
    spread = [np.linalg.norm(u[lab == f].mean(axis=0)) for lab in (one, many) for f in range(5)]
    assert min(spread[:5]) > 0.5 and max(spread[5:]) < min(spread[:5])  # four caps per fold average out


@pytest.mark.parametrize("index", [26, 109])  # a field drift on a slowly turning gimbal
def test_a_field_drift_on_a_gimbal_is_named(index):
    result, case = run_case(index)
    assert case.present == ("field_drift",) and case.schedule == "gimbal"
    assert result["verdict"] == "field_drift"


@pytest.mark.parametrize("index", [401, 131])  # structure outside the library on the same schedule
def test_negative_control_structure_on_a_gimbal_is_not_named_a_time_effect(index):
    result, case = run_case(index)
    assert case.schedule == "gimbal" and not case.present
    assert result["verdict"] == "unexplained"

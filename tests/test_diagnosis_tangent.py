"""A base fit that its tangent space does not describe (parameters pinned at a bound on nearly planar attitudes)
gives held-out residuals far below its own in-sample residual: the held-out tests then mean nothing, and a
record whose in-sample residual is far above the floor is not called 'none'."""
import sys
from pathlib import Path

import pytest

from magbench.benchmarks.diagnosis import diagnose
from magbench.simulate.dataset import Dataset

sys.path.insert(0, str(Path(__file__).resolve().parent))
from independent_forward import make_case  # noqa: E402


def run(index):
    case = make_case(index, 2026)
    d = Dataset(case.raw_nT, f_ref_nT=case.f_ref_nT, t_s=case.t_s, temp_C=case.temp_C)
    return case, diagnose(d, gravity=case.gravity)


@pytest.mark.parametrize("index", [568, 89])  # a rotating iron, eddy currents: on a vehicle's nearly planar attitudes
def test_an_untrusted_tangent_with_a_large_in_sample_residual_is_unexplained_not_none(index):
    case, r = run(index)
    assert case.schedule == "vehicle" and case.outside
    assert r["rms_base_nT"] < 0.5 * r["rms_fit_nT"]  # held-out far below in-sample: the tangent is wrong
    assert r["verdict"] == "unexplained" and r["tangent_untrusted"]["in_sample_remainder_z"] > 6


def test_negative_control_a_clean_vehicle_record_stays_none():
    case, r = run(96)
    assert case.category == "clean" and case.schedule == "vehicle"
    assert r["verdict"] == "none" and "tangent_untrusted" not in r


def test_negative_control_a_clean_record_with_an_untrusted_tangent_but_a_modest_in_sample_excess_stays_none():
    case, r = run(1656)  # a vehicle, the fit pinned at a bound; its in-sample residual 1.4 floors (z 3.8)
    assert case.category == "clean" and r["rms_base_nT"] < 0.5 * r["rms_fit_nT"]
    assert r["verdict"] == "none" and "tangent_untrusted" not in r

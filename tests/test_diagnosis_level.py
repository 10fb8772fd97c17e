"""A sensor that turned, but about one axis only (a level vehicle): the calibrators refuse its attitudes (the z axis's
scale and offset cannot be told apart), yet it is not a fixed sensor.  The diagnosis holds the directions the attitudes
leave free with the weak prior on scales and angles (the weakest that keeps the fit plausible) and answers the whole
question, not the time question only.  Records from the third independent generator (tests/independent_forward3.py,
which shares no code with magbench); the fixed sensor is the negative control."""
import sys
from pathlib import Path

import numpy as np
import pytest

from magbench.benchmarks.diagnosis import attitude_refusal, diagnose, turned
from magbench.simulate.dataset import Dataset

sys.path.insert(0, str(Path(__file__).resolve().parent))
import independent_forward3 as forward  # noqa: E402


def _data(index: int) -> tuple[object, Dataset]:
    case = forward.make_case(index, 2026)
    return case, Dataset(case.raw_nT, f_ref_nT=case.f_ref_nT, t_s=case.t_s, temp_C=case.temp_C)


@pytest.mark.parametrize(("index", "expected"), [(240, "none"), (62, "unexplained")])
def test_a_level_vehicle_is_diagnosed_with_the_weak_prior(index, expected):
    case, data = _data(index)
    assert case.schedule in ("quad_hover", "car_circuit")
    assert attitude_refusal(data, "nine") is not None and turned(data)  # refused by the calibrators, but it turned
    r = diagnose(data, gravity=case.gravity)
    assert r["kind"] == "vector" and r["base_fit"] == "weak prior" and r["attitude_coverage"].startswith("degenerate")
    assert r["verdict"] == expected, r["verdict"]
    p = r["base_params"]
    assert all(abs(p[k] - 1.0) < 0.3 for k in ("kx", "ky", "kz")), p  # plausible: the prior holds the free valley


def test_a_fixed_sensor_still_gets_the_time_only_answer():
    case, data = _data(6)
    assert case.category == "fixed"
    assert not turned(data)
    r = diagnose(data, gravity=case.gravity)
    assert r["kind"] == "time_only" and r["attitude"] == "insufficient_data"


def test_turned_measures_the_spread_of_the_directions():
    rng = np.random.default_rng(0)
    b = np.array([20000.0, 0.0, 45000.0])
    fixed = b + rng.normal(0, 5.0, (500, 3))
    heading = np.linspace(0, 2 * np.pi, 500)
    level = np.column_stack([20000 * np.cos(heading), 20000 * np.sin(heading), np.full(500, 45000.0)])
    f = np.full(500, float(np.linalg.norm(b)))
    assert not turned(Dataset(fixed, f_ref_nT=f))
    assert turned(Dataset(level, f_ref_nT=f))


def test_a_drift_on_a_level_vehicle_is_said_with_its_look_alike():
    """A field drift beside a lag and a temperature effect on a level car circuit (1077): named alone it came back as
    an offset drift (the z offset's drift moves the magnitude alike at every heading); it is said with its look-alike.
    Beyond the generator's development cases (``independent_cases.DEVELOPMENT_CASES``): round 7 developed the level
    path on the 36 level records of cases 0-2399, none of them below 480 a drift, and says so in the blind table's
    history (tests/independent_blind_table.py); the held-out block 2400-3359 was not looked at."""
    case, data = _data(1077)
    assert "field_drift" in case.present and "offset_drift" not in case.present
    r = diagnose(data, gravity=case.gravity)
    groups = [set(g.split("|")) for g in r["verdict"].split("+")]
    assert {"offset_drift", "field_drift"} in groups, r["verdict"]
    assert {"offset_drift"} not in groups and {"field_drift"} not in groups
    assert any(c["alternatives"][:2] in (["offset_drift", "field_drift"], ["field_drift", "offset_drift"])
               and "attitude_coverage" in c["evidence"] for c in r["confounded"])


def test_a_level_vehicle_with_a_reference_that_does_not_belong_is_refused():
    """The level path fits with a prior, not through a calibrator, so it checks the reference itself: a reference
    ten times the readings (wrong units) or one that jumps is bad input, refused as the calibrators refuse it (it
    answered with a fit residual of 6e5 nT).  Negative control: the same record with its own reference."""
    from magbench.errors import InputError

    case, data = _data(240)
    assert diagnose(data, gravity=case.gravity)["verdict"] == "none"
    f_ref = np.asarray(data.f_ref_nT, dtype=float)
    jump = f_ref.copy()
    jump[len(jump) // 2:] *= 0.8
    for ref, says in ((f_ref * 10, "times the reference"), (jump, "reference jumps")):
        with pytest.raises(InputError, match=says):
            diagnose(Dataset(data.raw_nT, f_ref_nT=ref, t_s=data.t_s, temp_C=data.temp_C), gravity=case.gravity)

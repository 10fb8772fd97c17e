"""A field drift must show its own signature whenever it is named, not only on the second look: one scalar series
common to every attitude visited at the same time.  When a body-fixed drift of the same time basis explains more of
the residual and the scalar series adds nothing beyond it, the structure turns with the body (a drifting offset, a
field that follows the turn rate), not with the field, and ``field_drift`` is refused (``Diagnosis._field_signature``).

The records come from the independent forward models (tests/independent_forward2.py and independent_forward3.py,
their development cases 0-479), which share no code with the diagnosis; the controls are true field drifts on a
car's laps, which must still be named."""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import independent_cases  # noqa: E402

from magbench.benchmarks.diagnosis.naming import SIGNATURE_Z  # noqa: E402


def test_a_rate_actuator_beside_a_lag_on_a_circuit_is_not_a_field_drift():
    result, case = independent_cases.run_case(332, generator=3)
    assert case.outside == ("rate_actuator",) and "field_drift" not in case.present
    assert "field_drift" not in result["verdict"], result["verdict"]
    row = independent_cases.evidence_row(result, "field_drift")
    assert not row["named"]
    if "tangent_step_ratio" in row:  # since round 15 refused before its signature is asked: the model's own fit of
        assert row["tangent_step_ratio"] > 10  # base + field drift on these laps is far from the tangent model's
        return
    sig = row["signature"]
    assert sig["z_body_beyond_scalar"] > SIGNATURE_Z >= sig["z_scalar_beyond_body"], row


def test_a_drifting_offset_beside_outliers_is_not_also_a_field_drift():
    result, case = independent_cases.run_case(147, generator=2)
    assert set(case.present) == {"outliers", "offset_drift"}
    assert "field_drift" not in result["verdict"] and "offset_drift" in result["verdict"], result["verdict"]


@pytest.mark.parametrize("index", [67])
def test_negative_control_a_field_drift_on_a_car_circuit_is_still_named(index):
    """Case 271, a control here before round 15, is no longer named: the model's own fit of base + field drift leaves
    2.0 nT where the tangent model, in which its held-out tests were made, gives 0.51 nT (the floor 0.49 nT), and the
    naming does not trust tests made in a linearisation that does not hold (``Diagnosis._tangent_trust``)."""
    result, case = independent_cases.run_case(index, generator=3)
    assert case.present == ("field_drift",)
    assert result["verdict"] == "field_drift", result["naming"]["evidence"]
    row = independent_cases.evidence_row(result, "field_drift")
    if index == 271:  # (case 67's laps pause: held attitudes, tested within the holds instead)
        sig = row["signature"]
        assert sig["tested"] and sig["z_body_beyond_scalar"] <= SIGNATURE_Z, sig  # a body-fixed drift does no better

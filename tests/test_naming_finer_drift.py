"""An offset drift of a finer shape than its cubic (a wandering offset) leaves no remainder beside its name; a
remainder that shape does not explain stays.  Records come from the second independent forward model
(tests/independent_forward2.py, its development cases 0-479), which shares no code with the diagnosis."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import independent_cases  # noqa: E402


def run_case(index: int) -> tuple[dict, object]:
    return independent_cases.run_case(index, generator=2)


def test_a_wandering_offset_is_named_without_a_remainder():
    result, case = run_case(433)  # a random walk on top of a linear drift of the offsets
    assert case.present == ("offset_drift",) and not case.outside
    assert result["verdict"] == "offset_drift"
    finer = result["remainder_finer_drift"]
    assert not finer["remainder_significant"] and finer["degree"] > 3


def test_negative_control_a_remainder_the_finer_drift_does_not_explain_stays():
    # an offset drift beside a sagging soft iron (outside the library).  (Case 304 was used here: a thermal gradient
    # read as a drift of the offsets; a switching of a body-fixed field between two levels now explains it, and
    # no drift is named there.)
    result, case = run_case(42)
    assert case.outside == ("sagging_soft_iron",) and case.present == ("offset_drift",)
    assert result["verdict"] == "offset_drift+unexplained"
    assert result["remainder_finer_drift"]["remainder_significant"]

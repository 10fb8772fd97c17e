"""An offset drift of a finer shape than its cubic (a wandering offset) leaves no remainder beside its name; a
remainder that shape does not explain stays.  Records come from the second independent forward model
(tests/independent_forward2.py, its development cases 0-479), which shares no code with the diagnosis."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from independent_forward2 import make_case  # noqa: E402

from magbench.benchmarks.diagnosis import diagnose  # noqa: E402
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

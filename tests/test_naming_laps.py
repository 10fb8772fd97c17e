"""A time shift on laps of one circuit: where every attitude is revisited at the same rate of change and the
nonlinearity cannot be tested, a lag's structure follows the attitude as a nonlinearity's would, and the
diagnosis says ``lag|nonlinearity`` (``naming.revisit_rate_share``).  Records come from the independent forward
models (tests/independent_forward2.py and 3), which share no code with the diagnosis; each case has its control."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import independent_forward2  # noqa: E402
import independent_forward3  # noqa: E402

import magbench.benchmarks.diagnosis.vector as vector_module  # noqa: E402
from magbench.benchmarks.diagnosis import diagnose  # noqa: E402
from magbench.benchmarks.diagnosis.naming import revisit_rate_share  # noqa: E402
from magbench.simulate.dataset import Dataset  # noqa: E402


def _diagnose(case):
    return diagnose(Dataset(case.raw_nT, f_ref_nT=case.f_ref_nT, t_s=case.t_s, temp_C=case.temp_C),
                    gravity=case.gravity)


def test_a_nonlinearity_on_laps_of_a_car_circuit_is_not_named_alone():
    """The third generator's case 76: a nonlinearity on a level car lapping a circuit.  Before round 30 the
    nonlinearity could not be tested there and a lag took its place (``lag|nonlinearity``); now it is tested on the
    nearly planar path, and said ``nonlinearity|lag`` (every attitude revisited at one rate), with the revisits' rate
    share as evidence.  Negative control: without the rule the same record is named ``nonlinearity`` alone."""
    case = independent_forward3.make_case(76, 2026)
    out = _diagnose(case)
    assert out["verdict"].split("+")[0] == "nonlinearity|lag"
    entry = next(c for c in out["confounded"] if c["alternatives"] == ["nonlinearity", "lag"])
    assert entry["evidence"]["revisit_rate_share"] < 0.05 and "speed" in entry["separate_by"]
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(vector_module, "LAP_RATE_SHARE", 0.0)
        assert _diagnose(case)["verdict"].split("+")[0] == "nonlinearity"


def test_a_lag_on_laps_where_the_nonlinearity_is_untested_is_said_with_it():
    """The third generator's case 4105: a lag on a car circuit whose path the nonlinearity's screen refuses; the lag is
    said ``lag|nonlinearity`` (``_lag_on_laps``).  Negative control: without the rule, ``lag`` alone."""
    case = independent_forward3.make_case(4105, 2026)
    out = _diagnose(case)
    assert "nonlinearity" in out["not_tested"]
    assert out["verdict"].split("+")[0] == "lag|nonlinearity"
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(vector_module, "LAP_RATE_SHARE", 0.0)
        assert _diagnose(case)["verdict"].split("+")[0] == "lag"


def test_a_lag_on_a_figure_eight_flown_by_hand_is_still_named():
    """Control: the second generator's case 575, a lag on a figure eight flown by hand (revisits at rates that
    differ by a fifth), is named `lag` with no lap confound."""
    out = _diagnose(independent_forward2.make_case(575, 2026))
    assert "lag" in out["verdict"].split("+")
    assert not any(c["alternatives"] == ["lag", "nonlinearity"] for c in out["confounded"])


def test_revisit_rate_share_tells_laps_at_one_speed_from_laps_at_several():
    """Ten laps of a tilted circle at one speed: revisits come at the same rate (share near 0).  The same laps at
    speeds alternating between 1 and 2: the share is large.  Noise-free readings, even sampling."""
    def laps(speeds):
        phase = np.concatenate([np.linspace(0, 2 * np.pi, 400, endpoint=False) for _ in speeds])
        t = np.concatenate([np.arange(400) / s + 400 * k for k, s in enumerate(speeds)])
        b = 48000.0 * np.column_stack([np.cos(phase) * 0.8, np.sin(phase) * 0.8, np.full_like(phase, 0.6)])
        return b, t

    same = revisit_rate_share(*laps([1.0] * 10))
    varied = revisit_rate_share(*laps([1.0, 2.0] * 5))
    assert same is not None and same < 0.01
    assert varied is not None and varied > 0.3

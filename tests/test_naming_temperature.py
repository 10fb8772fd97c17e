"""A temperature effect that changes the alignment of the axes, not only their offsets and gains: the library's
temperature effect fits the angles' temperature coefficients when the record supports them, and names such a
record ``temperature`` without ``+unexplained``; a record of a few held attitudes, which gives those
coefficients no leverage, keeps the offset-and-scale form.  And the dominance rule measures what is left with
the effects fitted that passed the held-out tests but are refused for their signature.  Records come from the
independent forward model (tests/independent_forward.py), which shares no code with the diagnosis."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from effect_records import OFFSET_NT, sphere_record  # noqa: E402
from independent_cases import run_case  # noqa: E402
from independent_scoring import score  # noqa: E402

from magbench.benchmarks.diagnosis.naming import undominated  # noqa: E402
from magbench.simulate.effects import TemperatureEffect  # noqa: E402


def test_the_alignment_form_undoes_a_temperature_dependent_alignment():
    """Readings whose axes' mutual angles change with temperature, corrected with the fitted form (its
    alignment columns beside the base's offsets and scales), give back the readings without the effect."""
    rng = np.random.default_rng(5)
    lin, d, norm, ctx = sphere_record(rng, 300)
    o = OFFSET_NT
    forward = TemperatureEffect((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (40.0, -25.0, 30.0), ref_C=norm.temp0_C)
    raw = forward.readings(lin, ctx, rng)
    assert np.sqrt(np.mean((raw - lin) ** 2)) > 5.0
    g = TemperatureEffect._columns_for(raw - o, d.temp_C - norm.temp0_C)
    e, *_ = np.linalg.lstsq(g.reshape(-1, g.shape[2]), (raw - lin).reshape(-1), rcond=None)
    assert np.allclose(e[6:], forward.alignment_urad_per_C, rtol=0.01)
    assert np.sqrt(np.mean((raw - g @ e - lin) ** 2)) < 0.05
    off = TemperatureEffect._columns_for(raw - o, d.temp_C - norm.temp0_C, alignment=False)
    assert not off[:, :, 6:].any() and np.array_equal(off[:, :, :6], g[:, :, :6])


@pytest.mark.parametrize("index", [227, 383, 1187])  # irregular sampling, random attitudes, tumbling
def test_a_temperature_dependent_alignment_is_named_temperature_without_unexplained(index):
    result, case = run_case(index)
    assert case.present == ("temperature",) and case.outside == () and case.category == "outside"
    assert result["effect_info"]["temperature"]["alignment_fitted"]
    assert result["verdict"] in ("temperature", "temperature|offset_drift", "offset_drift|temperature")
    assert score(case, result["verdict"]).score == 1.0


@pytest.mark.parametrize("index", [1226, 2338])  # offsets and gains that follow temperature, 12 held attitudes
def test_negative_control_held_attitudes_keep_the_offset_and_scale_form(index):
    """Twelve held attitudes, each seen over one stretch of temperature: the alignment coefficients have no
    leverage (they cannot be told from structure tied to each hold), and three more free coefficients made the
    attitude-blocked folds extrapolate wildly (the record came back 'unexplained' when they were always fitted)."""
    result, case = run_case(index)
    assert case.present == ("temperature",) and case.schedule == "steps"
    info = result["effect_info"]["temperature"]
    assert not info["alignment_fitted"] and info["alignment_p"] > TemperatureEffect.ALIGNMENT_P
    assert abs(result["fitted_params"]["aTxy_urad_per_C"]) == 0.0
    assert result["verdict"] == "temperature"


@pytest.mark.parametrize("index", [2095, 1599, 534, 426])  # nonlinearity beside a field drift; a lag and a
# nonlinearity; spikes beside readings clipped at a range limit on a turntable; spikes beside a lagged soft iron on
# held attitudes
def test_negative_control_other_structure_does_not_buy_alignment_coefficients(index):
    """A static response to the attitude, a drift in time or a time shift of the axes is not a change of the
    alignment with temperature: the F test is made beside their forms (and without clipped readings), and no
    temperature is named."""
    result, case = run_case(index)
    assert "temperature" not in case.present
    assert not result["effect_info"]["temperature"]["alignment_fitted"]
    assert "temperature" not in result["verdict"]


def test_the_remainder_of_the_dominance_rule_is_taken_with_the_modelled_effects_fitted():
    def row(name, own):
        return {"name": name, "named": True, "families": {f: {"own_rms_nT": own, "z": 9.0}
                                                            for f in ("random", "time-blocked")}}

    def remainder_of(names):  # a time shift refused for its signature fits most of what is left
        left = 2.0 if "lag" in names else 12.0
        return {"remainder_nT": left, "remainder_significant": True}

    evidence = [row("temperature", 5.0)]
    assert undominated(evidence, ["temperature"], remainder_of, modelled=("lag",)) == ["temperature"]
    assert evidence[0]["named"]
    control = [row("temperature", 5.0)]  # the control: nothing modelled beside it, the structure dominates
    assert undominated(control, ["temperature"], remainder_of) == []
    assert "left unexplained" in control[0]["why"]


@pytest.mark.parametrize("index", [78, 222])  # temperature beside eddy currents at random attitudes
def test_temperature_beside_a_structure_a_refused_time_shift_fits_is_named_with_unexplained(index):
    result, case = run_case(index)
    assert case.present == ("temperature",) and case.outside == ("eddy",)
    lag = next(r for r in result["naming"]["evidence"] if r["name"] == "lag")
    assert not lag["named"] and "roughness" in lag
    assert result["verdict"] == "temperature+unexplained"


def test_a_drift_folded_into_temperature_is_modelled_only_while_the_temperature_effect_is_named():
    """Case 2093 (clipping on held attitudes): the offset drift folded into the temperature effect made the remainder
    small while the temperature effect itself was dropped, and a field drift was named for the clipping."""
    def row(name, own, **extra):
        return {"name": name, "named": True, **extra,
                "families": {f: {"own_rms_nT": own, "z": 9.0} for f in ("random", "time-blocked")}}

    def remainder_of(names):
        return {"remainder_nT": 4.4 if "offset_drift" in names else 103.0, "remainder_significant": True}

    evidence = [row("field_drift", 20.0), row("temperature", 3.5), row("offset_drift", 10.0, folded_into="temperature")]
    evidence[2]["named"] = False
    assert undominated(evidence, ["field_drift", "temperature"], remainder_of, modelled=("offset_drift",)) == []
    assert "left unexplained" in evidence[0]["why"] and "left unexplained" in evidence[1]["why"]

"""A sensor that changes once mid-record (an axis's gain jumping, x and y swapped) while the logged temperature rises
steadily is no temperature effect.  A steady warming is split 75 % by any step at its middle, which the range-switch
rule had read as the temperature itself jumping (so it explained the jump), and its switch had no alignment terms and
no free calibration before the switch: sphere9 and cap9 with such a change and a warming logged came back
``temperature`` or ``temperature+unexplained`` in 4 of 8 records (wrong names).  The control: a true temperature
effect (tumble9q's, whose logged temperature also rises with time) is still named."""
import sys
from pathlib import Path

import pytest

from magbench.benchmarks.diagnosis import diagnose
from magbench.simulate.effects import TemperatureEffect
from magbench.simulate.scenarios import get_scenario

sys.path.insert(0, str(Path(__file__).resolve().parent))
from changed_records import changed_halfway  # noqa: E402


@pytest.mark.parametrize("scenario", ["sphere9", "cap9"])
@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("change", ["gain 1.005", "swap xy"])
def test_a_change_mid_record_beside_a_steady_warming_is_not_temperature(scenario, seed, change):
    report = diagnose(changed_halfway(scenario, seed, change, warming=True))
    assert "temperature" not in report["verdict"], report["verdict"]


@pytest.mark.parametrize("seed", [1, 3])
def test_negative_control_a_true_temperature_effect_is_named(seed):
    data = get_scenario("tumble9q").with_effects(TemperatureEffect()).build(seed)
    assert "temperature" in diagnose(data)["verdict"]

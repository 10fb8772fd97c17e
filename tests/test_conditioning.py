"""Every calibrator warns when the attitude coverage leaves the problem ill-conditioned."""
import pytest

from magbench.calibrators import available
from magbench.errors import InputError
from magbench.simulate import simulate

NINE = sorted(n for n, c in available().items() if "nine" in c.supported_models)


@pytest.mark.parametrize("name", NINE)
def test_vehicle_coverage_is_flagged_with_the_condition_number_and_bound(name):
    cls = available()[name]
    cal = cls(**{**cls.checking_params(), "model": "nine", "seed": 0})
    data = simulate("vehicle9", 0)
    try:
        result = cal.fit(data)
    except InputError as exc:  # a refusal must say why
        assert "condition" in str(exc) or "ellipsoid" in str(exc), str(exc)
        return
    flagged = [w for w in result.warnings if w.startswith("ill-conditioned attitude coverage")]
    assert flagged, result.warnings
    assert "condition number" in flagged[0] and "Cramér-Rao" in flagged[0]


@pytest.mark.parametrize("name", NINE)
def test_full_sphere_is_not_flagged(name):
    cls = available()[name]
    cal = cls(**{**cls.checking_params(), "model": "nine", "seed": 0})
    result = cal.fit(simulate("sphere9", 0))
    assert not [w for w in result.warnings if "ill-conditioned" in w]

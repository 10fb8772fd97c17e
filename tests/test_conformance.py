"""The conformance battery over every registered calibrator (calibrators.checks)."""
import pytest

from magbench.calibrators import available
from magbench.calibrators.checks import iter_checks

CASES = [(name, check, model) for name, cls in sorted(available().items())
         for _, check, model in iter_checks(cls)]


@pytest.mark.parametrize("name,check,model", CASES, ids=[f"{n}-{m}-{c.__name__}" for n, c, m in CASES])
def test_conformance(name, check, model):
    check(available()[name], model)


def test_battery_covers_every_calibrator():
    names = {c[0] for c in CASES}
    assert names == set(available())
    assert {"lsq", "ellipsoid", "aga", "aga-lm", "ga", "rga", "aco", "nlopt"} <= names


def test_battery_catches_a_broken_calibrator():
    """A calibrator that returns a wrong answer must fail the recovery check (the battery can fail)."""
    import numpy as np

    from magbench.calibrators import Calibrator, SolveOutput, check_calibrator

    class Broken(Calibrator):
        name = "broken-test"
        supported_models = ("angles",)

        def _solve(self, problem):
            return SolveOutput(np.array([0.05, 0.0, 0.0]))  # off by 0.034 rad in alpha

    with pytest.raises(AssertionError, match="known errors not recovered|rms only"):
        check_calibrator(Broken)


def test_battery_catches_a_constructor_that_works():
    from magbench.calibrators import Calibrator, check_calibrator
    from magbench.calibrators.lsq import LeastSquares

    class Busy(LeastSquares):
        name = "busy-test"

        def __init__(self, model="nine", seed=0, budget=None, init="auto", tol=1e-12, max_nfev=200):
            super().__init__(model, seed, budget, init, tol, max_nfev)
            self.cache_ = {}

    with pytest.raises(AssertionError, match="not hyper-parameters"):
        check_calibrator(Busy, models=["angles"])
    assert issubclass(Busy, Calibrator)

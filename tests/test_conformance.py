"""The conformance battery over every registered calibrator (magbench.calibrators.checks), and a
negative control for every check: a deliberately broken calibrator that the check must reject."""
import numpy as np
import pytest

from magbench.calibrators import BudgetExhausted, Calibrator, SolveOutput, available, check_calibrator
from magbench.calibrators import checks as C
from magbench.calibrators.checks import iter_checks
from magbench.calibrators.core import loop
from magbench.calibrators.core.algebra import ellipsoid_params
from magbench.calibrators.methods.lsq import LeastSquares

CASES = [(name, check, model) for name, cls in sorted(available().items())
         for _, check, model in iter_checks(cls)]


@pytest.mark.parametrize("name,check,model", CASES, ids=[f"{n}-{m}-{c.__name__}" for n, c, m in CASES])
def test_conformance(name, check, model):
    check(available()[name], model)


def test_battery_covers_every_calibrator_and_check():
    names = {c[0] for c in CASES}
    assert names == set(available())
    assert {"lsq", "ellipsoid", "aga", "aga-lm", "ga", "rga", "aco", "nlopt", "ransac", "tls", "ttls", "cmaes",
            "de"} <= names
    assert {c[1] for c in CASES} == set(C.CHECKS)


# -- negative controls: one broken calibrator per check ----------------------------------------------


class _Good(Calibrator):
    """A correct minimal calibrator (Levenberg-Marquardt through the counter) to break in one way at a time."""

    name = "good-control"
    supported_models = ("angles",)

    def _solve(self, problem):
        from magbench.calibrators.methods.lsq import levenberg_marquardt

        sol = yield from levenberg_marquardt(problem, problem.x0)
        return SolveOutput(sol.x)


class ReadsAroundTheCounter(_Good):
    """Reaches through the Problem to the private objective's readings and fits them directly."""

    name = "reads-around"
    supported_models = ("nine",)

    def _solve(self, problem):
        objective = problem._evaluator._objective
        params = ellipsoid_params(objective.raw_nT, objective.f_ref_nT)
        return SolveOutput(params.to_vector("nine"))


class EvaluatesUncounted(_Good):
    """Runs its search on the uncounted objective, then reports the answer."""

    name = "uncounted"

    def _solve(self, problem):
        from scipy.optimize import least_squares

        sol = least_squares(problem._evaluator._objective.residuals, problem.x0, method="lm")
        return SolveOutput(sol.x)


class ChangesItsHyperparameters(LeastSquares):
    name = "tunes-itself"

    def _solve(self, problem):
        self.max_nfev = 50  # "adapts" its own setting during the fit
        return (yield from super()._solve(problem))


class WorseThanStart(_Good):
    name = "worse"

    def _solve(self, problem):
        yield loop.value(problem.x0 + 0.05)
        return SolveOutput(problem.x0 + 0.05)


class IgnoresItsSeed(_Good):
    name = "ignores-seed"
    stochastic = True

    def _solve(self, problem):
        rng = np.random.default_rng(0)  # not problem.rng
        x = problem.x0 + rng.normal(0, 1e-3, (50, 3))
        f = yield loop.values(x)
        return SolveOutput(x[np.argmin(f)] if f.min() < (yield loop.value(problem.x0)) else problem.x0)


class UsesGlobalRandomState(IgnoresItsSeed):
    name = "global-random"

    def _solve(self, problem):
        x = problem.x0 + np.random.normal(0, 1e-3, (50, 3))  # noqa: NPY002 (the bug under test)
        f = yield loop.values(x)
        return SolveOutput(x[np.argmin(f)] if f.min() < (yield loop.value(problem.x0)) else problem.x0)


class OverrunsItsBudget(_Good):
    name = "overruns"

    def _solve(self, problem):
        best = problem.x0
        for _ in range(100):
            try:
                yield loop.values(problem.x0 + np.zeros((10, 3)))
            except BudgetExhausted:
                continue  # swallows the counter's stop and keeps asking
        return SolveOutput(best)


class BusyConstructor(LeastSquares):
    name = "busy"

    def __init__(self, model="nine", seed=0, budget=None, init="auto", tol=1e-12, max_nfev=200, bounded=True):
        super().__init__(model, seed, budget, init, tol, max_nfev, bounded)
        self.cache_ = {}


class ConvertingConstructor(LeastSquares):
    name = "converts"

    def __init__(self, model="nine", seed=0, budget=None, init="auto", tol=1e-12, max_nfev=200, bounded=True):
        super().__init__(model, seed, budget, init, float(tol) * 1.0, max_nfev, bounded)
        self.tol = float(tol) + 0.0


class StarArgs(_Good):
    name = "star-args"

    def __init__(self, *args, model="angles", seed=0, budget=None):
        super().__init__(model=model, seed=seed, budget=budget)


class WrongAnswer(_Good):
    name = "wrong"

    def _solve(self, problem):
        yield loop.value(np.array([0.05, 0.0, 0.0]))
        return SolveOutput(np.array([0.05, 0.0, 0.0]))  # off by 0.034 rad in alpha


class AcceptsAnything(_Good):
    name = "accepts-anything"

    def validate(self, dataset):
        return []


class PeeksThenConfirms(_Good):
    """The honeypot's prey: fits the readings it finds by introspection, then has its answer evaluated once
    through the counter so that the counting checks see it."""

    name = "peeks"
    supported_models = ("nine",)

    def _solve(self, problem):
        objective = problem._evaluator._objective
        x = ellipsoid_params(objective.raw_nT, objective.f_ref_nT).to_vector("nine")
        yield loop.value(x)
        yield loop.value(x)
        return SolveOutput(x)


class EditsItsCounters(_Good):
    """Does its work honestly, then rewrites the evaluator's counters to look cheap."""

    name = "edits-counters"

    def _solve(self, problem):
        out = yield from super()._solve(problem)
        object.__setattr__(problem._evaluator, "_n_f", 2)
        object.__setattr__(problem._evaluator, "_n_j", 0)
        return out


class RaisesItsBudget(_Good):
    """Replaces its budget by a larger one, then searches as long as it likes."""

    name = "raises-budget"

    def _solve(self, problem):
        from magbench.calibrators import Budget

        object.__setattr__(problem._evaluator, "_budget", Budget(max_evaluations=10**9))
        for _ in range(10):
            yield loop.values(problem.x0 + np.zeros((10, 3)))
        return (yield from super()._solve(problem))


class ReplacedFit(_Good):
    name = "replaced-fit"


# going around Calibrator's guard on purpose: what check_entry_point_intact must catch
type.__setattr__(ReplacedFit, "fit", lambda self, data, **kw: None)


class WrongShape(_Good):
    name = "wrong-shape"

    def _solve(self, problem):
        yield loop.value(problem.x0)
        return SolveOutput(np.zeros(2))


CONTROLS = [
    (ReadsAroundTheCounter, C.check_counts_through_the_counter, "nine", "did not come through the objective"),
    (EvaluatesUncounted, C.check_counts_through_the_counter, "angles", "the objective computed"),
    (EditsItsCounters, C.check_counts_through_the_counter, "angles", "the objective computed"),
    (PeeksThenConfirms, C.check_no_hidden_data, "nine", "decoy readings"),
    (RaisesItsBudget, C.check_budget_respected, "angles", "with a budget of 37"),
    (ReplacedFit, C.check_entry_point_intact, "angles", "is not Calibrator.fit"),
    (ChangesItsHyperparameters, C.check_fit_keeps_hyperparameters, "angles", "max_nfev"),
    (WorseThanStart, C.check_not_worse_than_start, "angles", "solver's answer has rms"),
    (IgnoresItsSeed, C.check_seed_used, "angles", "seed is ignored"),
    (UsesGlobalRandomState, C.check_deterministic, "angles", "differ"),
    (OverrunsItsBudget, C.check_budget_respected, "angles", "after the counter said the budget was spent"),
    (BusyConstructor, C.check_hyperparameters, "angles", "not hyper-parameters"),
    (ConvertingConstructor, C.check_hyperparameters, "angles", "does not store tol as given"),
    (StarArgs, C.check_hyperparameters, "angles", r"\*args"),
    (WrongAnswer, C.check_recovers_known_errors, "angles", "known errors not recovered|rms only"),
    (AcceptsAnything, C.check_refuses_bad_input, "angles", "did not refuse"),
    (WrongShape, C.check_answer_is_a_vector, "angles", "not a finite vector"),
]


@pytest.mark.parametrize("broken,check,model,message", CONTROLS, ids=[c[0].__name__ for c in CONTROLS])
def test_check_rejects_its_negative_control(broken, check, model, message):
    with pytest.raises(AssertionError, match=message):
        check(broken, model)


@pytest.mark.parametrize("check", C.CHECKS, ids=[c.__name__ for c in C.CHECKS])
def test_every_check_has_a_negative_control_and_passes_the_good_one(check):
    assert check in {c[1] for c in CONTROLS}, f"{check.__name__} has no negative control"
    check(_Good, "angles")  # the unbroken control passes: the check is not simply always failing


def test_the_whole_battery_rejects_a_calibrator_that_reads_around_the_counter():
    with pytest.raises(AssertionError, match="check_counts_through_the_counter"):
        check_calibrator(ReadsAroundTheCounter)


def test_an_iterative_calibrator_sees_no_readings():
    from magbench.calibrators import Problem

    seen = {}

    class Peek(_Good):
        name = "peek"

        def _solve(self, problem):
            seen["problem"] = problem
            return (yield from super()._solve(problem))

    Peek(model="angles").fit(C.check_dataset("angles"))
    problem = seen["problem"]
    assert type(problem) is Problem
    for name in ("raw_nT", "f_ref_nT", "objective", "raw", "values", "value", "residuals", "jacobian", "gradient",
                 "normal_equations", "algebraic_start"):
        assert not hasattr(problem, name)
    with pytest.raises(AttributeError):
        problem.raw_nT = np.zeros((3, 3))  # __slots__: nothing can be attached either


def test_a_closed_form_calibrator_gets_read_only_copies():
    seen = {}

    class Look(Calibrator):
        name = "look"
        supported_models = ("nine",)
        closed_form = True

        def _solve(self, problem):
            seen["problem"] = problem
            return SolveOutput(ellipsoid_params(problem.raw_nT, problem.f_ref_nT).to_vector("nine"))

    data = C.check_dataset("nine")
    res = Look().fit(data)
    problem = seen["problem"]
    assert not problem.raw_nT.flags.writeable and not problem.f_ref_nT.flags.writeable
    assert not np.shares_memory(problem.raw_nT, data.raw_nT)
    assert res.evaluation_mode == "closed-form" and res.as_dict()["evaluation_mode"] == "closed-form"


def test_fit_cannot_be_overridden():
    with pytest.raises(TypeError, match="one entry point"):
        class OwnFit(_Good):  # noqa: F841
            def fit(self, dataset):
                return None


def test_fit_cannot_be_replaced_after_class_creation():
    class Honest(_Good):
        name = "honest"

    with pytest.raises(TypeError, match="cannot be replaced"):
        Honest.fit = lambda self, data: None
    with pytest.raises(TypeError, match="cannot be replaced"):
        Calibrator.fit = lambda self, data: None
    with pytest.raises(TypeError, match="cannot be replaced"):
        Honest(model="angles").fit = lambda data: None
    with pytest.raises(TypeError, match="cannot be deleted"):
        del Honest._fit_dataset
    assert Honest.fit is Calibrator.fit


def test_the_framework_flags_a_replaced_budget_outside_the_battery():
    res = RaisesItsBudget(model="angles", budget=40).fit(C.check_dataset("angles"))
    assert not res.accepted and any("replaced its evaluation budget" in r for r in res.rejections)


def test_jacobians_are_charged_p_evaluation_equivalents():
    from magbench.calibrators import make

    res = make("lsq", model="nine").fit(C.check_dataset("nine"))
    assert res.n_jacobians > 0
    assert res.n_evaluations == res.n_function_evaluations + 9 * res.n_jacobians
    d = res.as_dict()
    assert (d["n_evaluations"], d["n_function_evaluations"], d["n_jacobians"]) == \
        (res.n_evaluations, res.n_function_evaluations, res.n_jacobians)
    # the budget is in the same unit: a Jacobian that does not fit in what is left is refused
    assert res.n_evaluations > 11
    small = make("lsq", model="nine", budget=11).fit(C.check_dataset("nine"))
    assert small.n_evaluations <= 11 and small.status == "budget"

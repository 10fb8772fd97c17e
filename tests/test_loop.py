"""calibrators/core/loop.py: strategies ask, the framework evaluates, counts, tells and stops them."""
import re
from pathlib import Path

import numpy as np
import pytest

from magbench.calibrators import Budget, Calibrator, SolveOutput, Termination, loop, make
from magbench.calibrators import checks as C
from magbench.calibrators.core.evaluator import BudgetExhausted, Evaluator
from magbench.calibrators.core.objective import ScalarObjective
from magbench.errors import InputError
from magbench.numerics import lm_iterations, lm_normal


class Countdown(Calibrator):
    """Asks for one population per iteration and reports a measure that halves each time."""

    name = "countdown"
    supported_models = ("angles",)

    def __init__(self, model="angles", seed=0, budget=None, iterations: int = 50, tol: float = 0.0):
        super().__init__(model=model, seed=seed, budget=budget)
        self.iterations = iterations
        self.tol = tol

    def termination_settings(self):
        return {"max_iterations": self.iterations, "tol": self.tol}

    def _solve(self, problem):
        measure, n = 1.0, 0
        while True:
            yield loop.values(problem.x0 + problem.rng.normal(0, 1e-4, (4, 3)))
            n += 1
            measure /= 2
            reason = yield loop.iteration(measure)
            if reason:
                return SolveOutput(problem.best_x, status=reason, nit=n)


def test_the_framework_stops_a_strategy_at_its_iterations():
    res = Countdown(iterations=7).fit(C.check_dataset("angles"))
    assert res.nit == 7 and res.status == "max_iterations"
    assert res.n_function_evaluations == 1 + 7 * 4  # the start, then 7 populations of 4
    assert res.extra["iterations"] == 7 and res.extra["stopped_by"] == "max_iterations"
    assert res.extra["termination"]["max_iterations"] == 7


def test_the_framework_compares_the_measure_with_the_tolerance():
    res = Countdown(iterations=50, tol=1e-3).fit(C.check_dataset("angles"))
    assert res.status == "converged" and res.nit == 10  # 2**-10 < 1e-3 <= 2**-9
    assert res.extra["stopped_by"] == "converged"


def test_a_strategy_cannot_ask_for_what_is_not_a_request():
    class Rogue(Countdown):
        name = "rogue"

        def _solve(self, problem):
            yield ("objective", None)
            return SolveOutput(problem.x0)

    with pytest.raises(TypeError, match="it may ask for one of values, value"):
        Rogue().fit(C.check_dataset("angles"))


def test_a_strategy_that_swallows_the_budget_forever_is_closed_and_reported():
    class Stubborn(Countdown):
        name = "stubborn"

        def _solve(self, problem):
            while True:  # never returns: the framework must end it
                try:
                    yield loop.values(problem.x0 + np.zeros((5, 3)))
                except BudgetExhausted:
                    continue

    res = Stubborn(budget=12).fit(C.check_dataset("angles"))
    assert res.status == "budget" and res.n_evaluations <= 12
    assert res.n_overrun_calls == loop.OVERRUN_LIMIT
    assert not res.accepted or res.n_overrun_calls  # the battery's budget check names the overruns
    with pytest.raises(AssertionError, match="after the counter said the budget was spent"):
        C.check_budget_respected(Stubborn, "angles")


def test_a_strategy_may_end_its_search_when_told_the_budget_is_spent():
    class Tidy(Countdown):
        name = "tidy"

        def _solve(self, problem):
            try:
                while True:
                    yield loop.values(problem.x0 + np.zeros((5, 3)))
            except BudgetExhausted:
                return SolveOutput(problem.best_x, status="tidy", message="told the budget was spent")

    res = Tidy(budget=12).fit(C.check_dataset("angles"))
    assert res.status == "tidy" and res.n_evaluations == 12 and res.n_overrun_calls == 0


def test_termination_refuses_limits_out_of_range_in_the_methods_words():
    with pytest.raises(InputError, match="countdown: max_iterations must be a positive integer"):
        Countdown(iterations=0).fit(C.check_dataset("angles"))  # no termination_params: the field's name
    # methods that declare their ranges (calibrators/params.py) refuse them at make(), in the same words
    with pytest.raises(InputError, match=r"^ga: hyper-parameter generations must be an int >= 1, not 0$"):
        make("ga", generations=0)
    with pytest.raises(InputError, match=r"^aga: hyper-parameter delta_g must be a float >= 0, not -1.0$"):
        make("aga", delta_g=-1.0)
    with pytest.raises(InputError, match=r"^aco: hyper-parameter tol must be a float >= 0"):
        make("aco", tol=-1.0)
    with pytest.raises(ValueError):
        Termination(max_evaluations=-3)
    assert Termination(tol=0.0).reason_to_stop(5, 10, 0.0) == ""  # tol 0: no convergence stop


@pytest.mark.parametrize("method,options", [("nlopt", {}), ("nlopt", {"algorithm": "LD_LBFGS"}), ("de", {})])
def test_callback_libraries_run_recast_and_stop_at_the_budget(method, options):
    data = C.check_dataset("nine")
    full = make(method, model="nine", **options).fit(data)
    assert full.status != "budget" and full.n_evaluations > 100
    budget = full.n_evaluations // 2
    cut = make(method, model="nine", budget=budget, **options).fit(data)
    assert cut.status == "budget" and cut.n_evaluations <= budget and cut.n_overrun_calls == 0
    assert cut.rms_after_nT <= cut.rms_before_nT
    again = make(method, model="nine", budget=budget, **options).fit(data)
    assert np.array_equal(again.x, cut.x)  # the same seed, the same numbers


def test_recast_hands_library_errors_back_to_the_strategy():
    def run(ask):
        ask(loop.value(np.zeros(3)))
        raise RuntimeError("the library failed")

    search = loop.recast(run)
    assert next(search).kind == "value"
    with pytest.raises(RuntimeError, match="the library failed"):
        search.send(1.0)


def test_closing_a_recast_strategy_unwinds_the_library():
    unwound = []

    def run(ask):
        try:
            while True:
                ask(loop.value(np.zeros(3)))
        finally:
            unwound.append(True)

    search = loop.recast(run)
    next(search)
    search.send(1.0)
    search.close()
    assert unwound == [True]


def test_lm_normal_is_lm_iterations_driven_by_a_function():
    data = C.check_dataset("nine")
    obj = ScalarObjective(data.raw_nT, data.f_ref_nT, "nine")
    x0 = np.array([0, 0, 0, 1, 1, 1, 0, 0, 0], dtype=float)
    direct = lm_normal(obj.normal_equations, x0, max_iter=30)
    steps = lm_iterations(x0, max_iter=30)
    asked = []
    try:
        x = next(steps)
        while True:
            asked.append(x)
            x = steps.send(obj.normal_equations(x))
    except StopIteration as done:
        driven = done.value
    assert np.array_equal(direct[0], driven[0]) and direct[2] == driven[2] == len(asked)


def test_lsq_through_the_loop_is_lm_on_the_counted_normal_equations():
    """The strategy's answer and count equal Levenberg-Marquardt run directly on a counting evaluator."""
    data = C.check_dataset("nine")
    res = make("lsq", model="nine", init="identity", bounded=False).fit(data)
    ev = Evaluator(ScalarObjective(data.raw_nT, data.f_ref_nT, "nine"), Budget())
    x0 = np.array([0, 0, 0, 1, 1, 1, 0, 0, 0], dtype=float)
    ev.values(x0[None, :])
    x, _, calls = lm_normal(ev.normal_equations, x0, tol=1e-12, max_iter=199)
    assert res.n_jacobians == calls == ev.n_jacobians
    assert np.allclose(res.solver_x, x, rtol=0, atol=1e-9)


def test_the_readme_example_calibrator_passes_the_battery():
    text = Path(__file__).resolve().parents[1].joinpath("README.md").read_text()
    block = re.search(r"```python\n(import numpy as np\nfrom scipy.optimize import minimize\n.*?)```", text, re.S)
    assert block, "the README's own-calibrator example is missing"
    code = block.group(1).replace("@register", "")  # not registered: the registry stays as it is
    namespace: dict = {}
    exec(compile(code, "README.md", "exec"), namespace)  # noqa: S102 - the README's own example
    res = namespace["NelderMead"](model="angles").fit(C.check_dataset("angles"))
    assert res.n_evaluations > 50 and res.accepted


def test_an_old_style_calibrator_is_told_how_to_ask():
    class OldStyle(Countdown):
        name = "old-style"

        def _solve(self, problem):
            return SolveOutput(problem.x0 if problem.value(problem.x0) >= 0 else None)

    with pytest.raises(AttributeError, match=r"a strategy that asks the framework, e.g. `f = yield loop.value\(x\)`"):
        OldStyle().fit(C.check_dataset("angles"))


def test_a_budget_stop_says_how_many_iterations_the_framework_counted():
    res = make("cmaes", budget=777).fit(C.check_dataset("nine"))
    assert res.status == "budget" and res.extra["stopped_by"] == "budget"
    assert res.extra["iterations"] == (777 - 1) // 10  # whole generations of 10 after the start, before the cut


def test_a_library_in_recast_sees_the_callers_context():
    def run(ask):
        return np.geterr()["divide"]

    with np.errstate(divide="raise"):
        search = loop.recast(run)
        with pytest.raises(StopIteration) as done:
            next(search)
    assert done.value.value == "raise"


def test_lm_does_not_take_a_negative_decrement_for_an_optimum():
    from magbench.numerics import at_optimum

    a = np.array([[1.0, 0.0], [0.0, -1e-30]])  # numerically singular, solve does not raise
    g = np.array([0.0, 1e-10])
    assert float(g @ np.linalg.solve(a, g)) < 0
    assert not at_optimum(a, g, cost=1.0, tol=1e-12, atol=0.0)
    assert at_optimum(np.eye(2), np.array([1e-7, 0.0]), cost=1.0, tol=1e-12, atol=0.0)  # a true optimum

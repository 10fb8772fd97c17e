"""The conformance battery: checks every calibrator must pass (scikit-learn's ``check_estimator``).

``check_calibrator(MyCalibrator)`` runs them all and raises ``AssertionError`` naming the failed check;
``iter_checks`` yields (name, calibrator, check) for ``pytest.mark.parametrize``.  This is how a user
makes a regression test that known error angles are recovered.
"""
from __future__ import annotations

import copy
from contextlib import contextmanager
from dataclasses import replace
from functools import cache

import numpy as np

from magbench import paper
from magbench.errors import InputError
from magbench.simulate import attitude
from magbench.simulate.dataset import Dataset, Truth
from magbench.simulate.field import ConstantField
from magbench.simulate.sensor import PARAM_NAMES, ErrorParams, SensorModel

from .base import SEALED, Calibrator, expose_decoys
from .core.evaluator import Budget, Evaluator, audit_evaluations

CHECK_ERRORS = {
    "offset": ErrorParams(offset_nT=(152.0, -218.0, 85.0)),
    "diag": ErrorParams(scale=(1.021, 0.984, 1.008), offset_nT=(152.0, -218.0, 85.0)),
    "angles": ErrorParams(**paper.TABLE1_ANGLES_RAD),
    "nine": ErrorParams(0.012, -0.008, 0.015, (1.021, 0.984, 1.008), (152.0, -218.0, 85.0)),
}


@cache
def check_dataset(model: str, noise_nT: float = 0.05, n: int = 240, seed: int = 12345) -> Dataset:
    """Low-noise full-sphere data with known errors for the battery."""
    rng = np.random.default_rng(seed)
    field = ConstantField.from_angles(50000.0, 55.0, 3.0)
    att = attitude.full_sphere(n, rng)
    sensor = SensorModel(CHECK_ERRORS[model], noise_nT=noise_nT)
    raw = sensor.measure(att.body_field(np.asarray(field.vector_nT)), rng)
    truth = Truth(sensor.true_correction(), sensor, field.vector_nT, scenario=f"check_{model}", seed=seed)
    return Dataset(raw, f_ref_nT=field.total_nT, t_s=att.t_s, truth=truth)


def _instance(calibrator, model: str, **overrides) -> Calibrator:
    cls: type[Calibrator] = calibrator if isinstance(calibrator, type) else type(calibrator)
    params = {} if isinstance(calibrator, type) else calibrator.get_params()
    params = {**params, **cls.checking_params(), "model": model, **overrides}
    return cls(**params)


def check_hyperparameters(calibrator, model):
    """The constructor stores its arguments, untouched, and nothing else (scikit-learn's ``clone`` check):
    no ``*args``, ``get_params`` round-trips, every stored value *is* the object passed in, and no other
    attribute is set."""
    cls = calibrator if isinstance(calibrator, type) else type(calibrator)
    try:
        names = cls._param_names()
    except TypeError as exc:
        raise AssertionError(str(exc)) from None
    cal = _instance(calibrator, model)
    params = cal.get_params()
    assert set(names) == set(params)
    again = cls(**params)
    changed = [k for k, v in again.get_params().items() if v is not params[k]]
    assert not changed, f"the constructor does not store {', '.join(changed)} as given (it converts or copies them)"
    assert set(vars(cal)) == set(params), \
        f"the constructor sets attributes that are not hyper-parameters: {set(vars(cal)) ^ set(params)}"


def check_recovers_known_errors(calibrator, model):
    """On low-noise full-sphere data the solver's own answer (before ``fit``'s safety clamp) recovers the
    known angles (and scale, offset) within the calibrator's declared ``check_tolerance`` (flat, or per
    model), and the residual is at least halved."""
    cal = _instance(calibrator, model)
    data = check_dataset(model)
    res = cal.fit(data)
    tol = type(cal).check_tolerance
    tol = tol.get(model, tol) if isinstance(tol.get(model), dict) else tol
    assert res.solver_rms_nT <= 0.5 * res.rms_before_nT, \
        f"rms only {res.rms_before_nT:.3g} -> {res.solver_rms_nT:.3g} nT on low-noise data"
    truth = data.truth.params
    err = np.abs(res.solver_x - truth.to_vector(model))
    names = PARAM_NAMES[model]
    kind = {"_rad": "angle_rad", "_nT": "offset_nT"}
    limits = np.array([tol[kind.get(name[-4:], kind.get(name[-3:], "scale"))] for name in names])
    bad = [f"{names[i]} off by {err[i]:.3g} (tolerance {limits[i]:.3g})" for i in np.flatnonzero(~(err <= limits))]
    assert not bad, "known errors not recovered: " + "; ".join(bad)


def check_deterministic(calibrator, model):
    """Same seed, same numbers (no global random state, no clock)."""
    a = _instance(calibrator, model, seed=7).fit(check_dataset(model))
    b = _instance(calibrator, model, seed=7).fit(check_dataset(model))
    assert np.array_equal(a.solver_x, b.solver_x), f"two fits with seed 7 differ: {a.solver_x} vs {b.solver_x}"
    assert a.n_evaluations == b.n_evaluations, "two fits with the same seed counted different evaluations"


def check_seed_used(calibrator, model):
    """A stochastic calibrator's run depends on its seed: two seeds give different searches (answers or
    convergence traces).  One that draws from a fixed or private generator fails here."""
    cal = _instance(calibrator, model)
    if not cal.is_stochastic():
        return
    a = _instance(calibrator, model, seed=1).fit(check_dataset(model))
    b = _instance(calibrator, model, seed=2).fit(check_dataset(model))
    same_x = np.array_equal(a.solver_x, b.solver_x)
    same_trace = a.trace == b.trace
    assert not (same_x and same_trace), "seeds 1 and 2 give the very same run: the seed is ignored"


def check_fit_keeps_hyperparameters(calibrator, model):
    """``fit`` leaves the calibrator's hyper-parameters as they were (no fitted state, no tuning of its
    own settings)."""
    cal = _instance(calibrator, model)
    before = copy.deepcopy(cal.get_params())
    cal.fit(check_dataset(model))
    after = cal.get_params()
    changed = [k for k in before if not _same(before[k], after[k])]
    assert not changed, f"fit changed the hyper-parameter(s) {', '.join(changed)}"
    assert set(vars(cal)) == set(before), f"fit added attributes {set(vars(cal)) - set(before)}"


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(a, b)
    return a == b


class _Tally:
    """The battery's own count of the work the shared objective does for one fit, kept outside the
    evaluator (so that a calibrator editing the evaluator's counters or budget is caught)."""

    def __init__(self):
        self.f = 0
        self.jacobians = 0


class _CountingObjective:
    """Stands between the ``Evaluator`` and its objective during a battery fit: counts every value,
    residual vector and Jacobian the objective computes (whoever asks: the evaluator, or a calibrator that
    reached around it), and otherwise behaves as the objective."""

    def __init__(self, objective, tally: _Tally):
        object.__setattr__(self, "_inner", objective)
        object.__setattr__(self, "_tally", tally)

    def __getattr__(self, name):
        return getattr(self._inner, name)

    def __setattr__(self, name, value):
        setattr(self._inner, name, value)

    def values(self, x, *args, **kwargs):
        self._tally.f += np.atleast_2d(np.asarray(x)).shape[0]
        return self._inner.values(x, *args, **kwargs)

    def residuals(self, x):
        self._tally.f += 1
        return self._inner.residuals(x)

    def jacobian(self, x):
        self._tally.jacobians += 1
        return self._inner.jacobian(x)

    def normal_equations(self, x, *args, **kwargs):
        self._tally.f += 1
        self._tally.jacobians += 1
        return self._inner.normal_equations(x, *args, **kwargs)

    def gradient(self, x):
        self._tally.jacobians += 1
        return self._inner.gradient(x)


@contextmanager
def _independent_count():
    """Within this block every new ``Evaluator`` computes through a ``_CountingObjective``; yields the
    ``_Tally`` of all of them."""
    tally = _Tally()
    original = Evaluator.__init__

    def counted_init(self, objective, budget=None, clock=True):
        original(self, _CountingObjective(objective, tally), budget, clock)

    Evaluator.__init__ = counted_init  # type: ignore[method-assign]
    try:
        yield tally
    finally:
        Evaluator.__init__ = original  # type: ignore[method-assign]


def check_counts_through_the_counter(calibrator, model):
    """Every evaluation is counted, and counted by the framework: the result's ``n_function_evaluations``,
    ``n_jacobians`` and ``n_evaluations`` (evaluation-equivalents: p per Jacobian) equal the battery's own
    count of the work the objective did, kept outside the evaluator (a calibrator that edits the counters,
    or evaluates around them, is caught); a counted calibrator's answer is a point the counter evaluated
    (so it cannot be computed from readings fetched around the counter) and it counts at least one
    evaluation besides the framework's start; a closed-form one says so in its evaluation mode."""
    cal = _instance(calibrator, model)
    with _independent_count() as tally, audit_evaluations() as log:
        res = cal.fit(check_dataset(model))
    p = len(PARAM_NAMES[model])
    assert (res.n_function_evaluations, res.n_jacobians) == (tally.f, tally.jacobians), \
        (f"the result reports {res.n_function_evaluations} evaluations and {res.n_jacobians} Jacobians; the "
         f"objective computed {tally.f} and {tally.jacobians}")
    assert res.n_evaluations == tally.f + p * tally.jacobians, \
        f"n_evaluations {res.n_evaluations} is not {tally.f} + {p} x {tally.jacobians} evaluation-equivalents"
    if cal.closed_form:
        assert res.evaluation_mode == "closed-form", "a closed-form calibrator must report the mode 'closed-form'"
        return
    assert res.evaluation_mode == "counted"
    seen = np.vstack(log.points) if log.points else np.empty((0, len(res.solver_x)))
    assert len(seen) >= 2, "no evaluation besides the framework's start: the answer did not come through the objective"
    scale = np.maximum(np.abs(res.solver_x), 1.0)
    hit = np.all(np.abs(seen - res.solver_x) <= 1e-12 * scale, axis=1)
    assert hit.any(), ("the solver's answer was never evaluated through the counter: it was computed "
                       "around it (from the readings, or an uncounted objective)")


def _decoy(raw_nT: np.ndarray, f_ref_nT: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Readings of a different sensor (offsets moved by thousands of nT, gains by 10 %): what a calibrator
    that reaches around its ``Problem`` to the readings would fit instead of the real ones."""
    return raw_nT * np.array([1.1, 0.92, 1.05]) + np.array([3000.0, -2000.0, 1500.0]), np.array(f_ref_nT)


def check_no_hidden_data(calibrator, model):
    """The honeypot: while the solver runs, the readings reachable by introspection (the shared objective's
    public ``raw_nT`` and ``f_ref_nT``) are replaced by a decoy sensor's.  A calibrator that sees the data
    only through its ``Problem`` (and a closed-form one through ``ReadingsProblem``) gives the very same
    answer; one that fetched the readings around the counter fits the decoy and its answer changes."""
    plain = _instance(calibrator, model, seed=3).fit(check_dataset(model))
    with expose_decoys(_decoy):
        baited = _instance(calibrator, model, seed=3).fit(check_dataset(model))
    assert np.array_equal(plain.solver_x, baited.solver_x), \
        ("the answer changed when decoy readings were placed where introspection finds them: the calibrator "
         f"reads the data around its Problem ({plain.solver_x} -> {baited.solver_x})")


def check_entry_point_intact(calibrator, model):
    """``fit`` is the framework's (it validates, counts and checks): the class neither defines nor replaced
    it, even after creation by going around ``Calibrator``'s guard."""
    cls = calibrator if isinstance(calibrator, type) else type(calibrator)
    for name in SEALED:
        assert getattr(cls, name) is getattr(Calibrator, name), f"{cls.__name__}.{name} is not Calibrator.{name}"
    inst = calibrator if not isinstance(calibrator, type) else _instance(calibrator, model)
    assert not set(SEALED) & set(vars(inst)), "the instance carries its own fit"


def check_answer_is_a_vector(calibrator, model):
    """The solver's own answer is a finite vector of the model's length (the one thing about the result
    that the calibrator, not the framework, controls)."""
    cal = _instance(calibrator, model)
    res = cal.fit(check_dataset(model))
    p = len(PARAM_NAMES[model])
    assert res.solver_x.shape == (p,) and np.all(np.isfinite(res.solver_x)), \
        f"the solver returned {res.solver_x!r}, not a finite vector of {p} parameters ({res.status}: " \
        f"{'; '.join(res.warnings)})"


def check_not_worse_than_start(calibrator, model):
    """The solver's own answer (before ``fit``'s safety clamp) is never worse than no calibration, even
    with a tiny budget (scipy's test_no_increase)."""
    for overrides in ({}, {"budget": Budget(max_evaluations=5)}):
        cal = _instance(calibrator, model, **overrides)
        res = cal.fit(check_dataset(model))
        assert res.solver_rms_nT <= res.rms_before_nT + 1e-9, \
            f"the solver's answer has rms {res.solver_rms_nT} > {res.rms_before_nT} before, with " \
            f"{overrides or 'defaults'}"


def check_budget_respected(calibrator, model):
    """An evaluation budget is never exceeded, and the solver stops when the counter says the budget is
    spent (a solver that swallows ``BudgetExhausted`` and keeps asking is caught); the count is
    re-checked against the points the counter actually saw (nevergrad's ``xpbase`` re-check)."""
    cal = _instance(calibrator, model, budget=Budget(max_evaluations=37))
    with _independent_count() as tally:
        res = cal.fit(check_dataset(model))
    spent = tally.f + len(PARAM_NAMES[model]) * tally.jacobians
    assert res.n_evaluations <= 37 and spent <= 37, \
        f"{max(res.n_evaluations, spent)} evaluation-equivalents with a budget of 37"
    assert res.n_overrun_calls == 0, \
        f"the solver asked {res.n_overrun_calls} more time(s) after the counter said the budget was spent"


def check_refuses_bad_input(calibrator, model):
    """NaN rows, too few points and a missing reference are refused with an InputError."""
    cal = _instance(calibrator, model)
    data = check_dataset(model)
    raw = np.array(data.raw_nT)
    raw[3, 1] = np.nan
    cases = {
        "NaN row": replace(data, raw_nT=raw),
        "too few points": replace(data, raw_nT=data.raw_nT[:2], f_ref_nT=data.f_ref_nT[:2], t_s=None),
        "no reference": replace(data, f_ref_nT=None),
    }
    for what, bad in cases.items():
        try:
            cal.fit(bad)
        except InputError:
            continue
        except Exception as exc:  # a crash is not a refusal
            raise AssertionError(f"{what}: fit did not refuse with InputError "
                                 f"({type(exc).__name__}: {exc})") from exc
        raise AssertionError(f"{what}: fit did not refuse with InputError")


CHECKS = (check_hyperparameters, check_entry_point_intact, check_recovers_known_errors, check_deterministic,
          check_seed_used, check_fit_keeps_hyperparameters, check_counts_through_the_counter, check_no_hidden_data,
          check_answer_is_a_vector, check_not_worse_than_start, check_budget_respected, check_refuses_bad_input)


def iter_checks(calibrator, models=None):
    """Yield (id, check, model) for every check and every model the calibrator supports."""
    cls = calibrator if isinstance(calibrator, type) else type(calibrator)
    for model in models or cls.supported_models:
        for check in CHECKS:
            yield f"{cls.name}-{model}-{check.__name__}", check, model


def check_calibrator(calibrator, models=None) -> list[str]:
    """Run the whole battery; raise ``AssertionError`` naming the first failing check, else return
    the names of the checks passed."""
    passed = []
    for ident, check, model in iter_checks(calibrator, models):
        try:
            check(copy.deepcopy(calibrator) if not isinstance(calibrator, type) else calibrator, model)
        except AssertionError as exc:
            raise AssertionError(f"{ident}: {exc}") from exc
        passed.append(ident)
    return passed

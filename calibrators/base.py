"""The one interface of every calibrator.

A calibrator's constructor stores hyper-parameters and nothing else (scikit-learn's convention: the
signature *is* the configuration).  ``fit(dataset)`` validates the data, builds the shared counted
objective, calls the algorithm's ``_solve`` and returns an immutable ``CalibrationResult``; no fitted
state is kept on the calibrator.
"""
from __future__ import annotations

import contextvars
import functools
import hashlib
import importlib
import inspect
import math
import sys
import threading
import time
import weakref
from collections.abc import Generator
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import partial
from typing import Any, ClassVar

import numpy as np

from magbench.errors import FitError, InputError
from magbench.numerics import median, repeated_rows, systematic_rows, time_column_note
from magbench.simulate.dataset import Dataset
from magbench.simulate.sensor import MODELS, PARAM_NAMES, ErrorParams

from .acceptance import (  # noqa: F401  (MIN_RESIDUAL_DOF: the fits' minimum, read here by validate)
    DEFAULT_LIMITS,
    MIN_RESIDUAL_DOF,
    SEARCH_STOPPED_SHORT,
    AcceptanceLimits,
    assess,
    reference_problems,
    time_key,
)
from .artifacts import Calibration, zero_readings
from .core.evaluator import Budget, BudgetExhausted, Evaluator
from .core.loop import Stopped, Termination, drive
from .core.objective import ScalarObjective, identity_vector
from .core.problem import (  # noqa: F401
    PHYSICAL_BOX,
    POPULATION_OFFSET_FRACTION,
    Problem,
    ReadingsProblem,
    SolveOutput,
    population_box,
    search_bounds,
)
from .fisher import coverage, crb_std, one_pass
from .inputs import algebraic_vector, as_dataset, magnitude_spikes
from .params import BUDGET, SEED, Options, as_budget, validate_params


@dataclass(frozen=True)
class CalibrationResult:
    """What ``fit`` returns: the estimate in CONTRACT section 1 form and how it was obtained.

    Names follow ``scipy.optimize.OptimizeResult`` where they overlap (``x``, ``success``, ``status``,
    ``message``, ``fun``, ``nit``).  Counts come from the framework's one evaluator, never from the
    calibrator: ``n_evaluations`` in evaluation-equivalents (the budget's unit: one per objective value or
    residual vector, p per Jacobian or gradient of p free parameters), ``n_function_evaluations`` and
    ``n_jacobians`` separately (scipy's ``nfev`` and ``njev``).
    """

    method: str
    model: str
    params: ErrorParams
    x: np.ndarray
    success: bool
    status: str
    message: str
    fun: float
    n_evaluations: int
    n_jacobians: int
    nit: int
    runtime_s: float
    seed: int | None
    rms_before_nT: float
    rms_after_nT: float
    warnings: tuple[str, ...] = ()
    hyperparameters: dict = field(default_factory=dict)
    trace: tuple[tuple[int, float, float], ...] = ()
    extra: dict = field(default_factory=dict)
    evaluation_mode: str = "counted"  # "counted", or "closed-form" (reads the readings; count not comparable)
    solver_x: np.ndarray | None = None  # what _solve returned, before fit's safety clamp
    solver_rms_nT: float = float("nan")  # the residual RMS at solver_x
    n_overrun_calls: int = 0  # calls the solver made after the counter said the budget was spent
    accepted: bool = True  # every acceptance check passed (calibrators/acceptance.py)
    rejections: tuple[str, ...] = ()  # why not, one cause per entry
    reference: dict = field(default_factory=dict)  # the reference magnitude used and its source
    # Cramér-Rao standard deviation of every estimated parameter at the estimate and the estimated noise
    uncertainty: dict = field(default_factory=dict)
    noise_nT: float = float("nan")  # the noise those deviations assume (residual RMS of the data's optimum)
    model_choice: dict | None = None  # model "auto": the candidates, their held-out RMS and the reason
    data_digest: str = ""  # sha256 of the readings and reference fitted (calibration files name their data)
    n_points: int = 0
    n_function_evaluations: int = 0  # objective values and residual vectors computed

    def __post_init__(self):
        for name in ("x", "solver_x"):
            value = getattr(self, name)
            if value is None:
                continue
            arr = np.array(value, dtype=float)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def matrix(self) -> np.ndarray:
        return self.params.matrix

    def correct(self, raw_nT: np.ndarray) -> np.ndarray:
        """Apply the estimated correction B = M (raw - o) to readings (n, 3)."""
        return self.params.correct(raw_nT)

    def calibration(self):
        """This result as a ``Calibration`` (the saved artifact, ``calibrators/artifacts.py``)."""
        return Calibration.from_result(self)

    def to_json(self) -> str:
        """The calibration file's text (schema ``magbench.calibration``; ``artifacts.load_calibration``)."""
        return self.calibration().to_json()

    def as_dict(self) -> dict:
        """The JSON form of CONTRACT section 3 (``magbench calibrate --json``)."""
        p = self.params
        return {
            "method": self.method,
            "model": self.model,
            "alpha_rad": p.alpha_rad,
            "beta_rad": p.beta_rad,
            "gamma_rad": p.gamma_rad,
            "scale": list(p.scale),
            "offset_nT": list(p.offset_nT),
            "matrix": p.matrix.tolist(),
            "rms_before_nT": self.rms_before_nT,
            "rms_after_nT": self.rms_after_nT,
            "runtime_s": self.runtime_s,
            "n_evaluations": self.n_evaluations,
            "evaluation_mode": self.evaluation_mode,
            "n_function_evaluations": self.n_function_evaluations,
            "n_jacobians": self.n_jacobians,
            "nit": self.nit,
            "seed": self.seed,
            "success": self.success,
            "status": self.status,
            "message": self.message,
            "fun": self.fun,
            "warnings": list(self.warnings),
            "accepted": self.accepted,
            "rejections": list(self.rejections),
            "reference": dict(self.reference),
            "uncertainty": {k: (float(v) if np.isfinite(v) else None) for k, v in self.uncertainty.items()},
            "noise_nT": float(self.noise_nT) if np.isfinite(self.noise_nT) else None,
            "n_points": self.n_points,
            "data_digest": self.data_digest,
            **({"model_choice": self.model_choice} if self.model_choice is not None else {}),
            "hyperparameters": {k: _jsonable(v) for k, v in self.hyperparameters.items()},
            **({"extra": {k: _jsonable(v) for k, v in self.extra.items()}} if self.extra else {}),
        }


def _jsonable(v):
    if isinstance(v, Budget):
        return {"max_evaluations": v.max_evaluations, "max_time_s": v.max_time_s}
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    return v


NO_REFERENCE = ("no reference magnitude: give f_ref_nT= (a number or one per row), field= (a number of nT, or 'auto'), "
                "or data with their own f_ref")

MODEL_CHOOSER: list = []
"""The function behind ``model="auto"``, installed by ``calibrators.modelselect`` (which compares the candidate
models with lsq, a method: the framework's base cannot import it without a cycle, so the dependency is
inverted).  Importing any module of ``magbench.calibrators`` imports the package, which installs it."""

SEALED = ("fit", "_fit_dataset")
"""The framework's entry points: no subclass defines them, and no one replaces them on a class or instance."""


class _Sealed(type):
    """Metaclass of ``Calibrator``: ``fit`` and ``_fit_dataset`` cannot be assigned or deleted on any
    calibrator class after its creation (``Cls.fit = ...`` raises ``TypeError``)."""

    def __setattr__(cls, name, value):
        if name in SEALED:
            raise TypeError(f"{cls.__name__}.{name} cannot be replaced: Calibrator.fit is the one entry point "
                            "(it validates the data, counts every evaluation and checks the answer)")
        super().__setattr__(name, value)

    def __delattr__(cls, name):
        if name in SEALED:
            raise TypeError(f"{cls.__name__}.{name} cannot be deleted")
        super().__delattr__(name)


def import_first(modules: tuple[str, ...]) -> bool:
    """Import those of ``modules`` this process has not imported yet; whether there were any."""
    missing = [m for m in modules if m not in sys.modules]
    for name in missing:
        importlib.import_module(name)
    return bool(missing)


class Calibrator(metaclass=_Sealed):
    """Base class: subclasses set ``name``, list their hyper-parameters as keyword arguments of
    ``__init__`` (stored as attributes of the same names, nothing else) and implement ``_solve``."""

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    supported_models: ClassVar[tuple[str, ...]] = MODELS
    stochastic: ClassVar[bool] = False
    # A closed-form calibrator reads the readings in _solve (an algebraic fit) and says so: its _solve
    # gets a ReadingsProblem and its rows report the evaluation mode "closed-form".  Every other
    # calibrator sees the data only through the counted objective.
    closed_form: ClassVar[bool] = False
    # A robust calibrator screens outliers itself: the acceptance check then warns instead of rejecting.
    robust: ClassVar[bool] = False
    acceptance: ClassVar[AcceptanceLimits] = DEFAULT_LIMITS
    # What each hyper-parameter may be (calibrators/params.py); a subclass extends it with its own
    # (``_parameter_constraints = {**Calibrator._parameter_constraints, "population": [Interval(Integral, 2, None)]}``).
    # Hyper-parameters without an entry are checked against the constructor's annotations.
    _parameter_constraints: ClassVar[dict] = {"model": [Options(MODELS + ("auto",))], "seed": list(SEED),
                                              "budget": list(BUDGET)}
    # Tolerances the conformance battery allows this method on low-noise data (angle rad, scale, nT).
    check_tolerance: ClassVar[dict] = {"angle_rad": 2e-5, "scale": 2e-5, "offset_nT": 0.5}
    # Modules the solver imports on first use (pycma: 1-1.5 s, SciPy's optimizers): a one-time cost of the process,
    # not of a fit, paid by ``one_time_setup`` before the clock starts.
    imports: ClassVar[tuple[str, ...]] = ()

    def __init__(self, model: str = "nine", seed: int | None = 0, budget: Budget | None = None):
        self.model = model
        self.seed = seed
        self.budget = budget

    def __setattr__(self, name, value):
        if name in SEALED:
            raise TypeError(f"{type(self).__name__}.{name} cannot be replaced on an instance either")
        super().__setattr__(name, value)

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if "fit" in cls.__dict__ or "_fit_dataset" in cls.__dict__:
            raise TypeError(f"{cls.__name__} overrides fit(): Calibrator.fit is the one entry point (it validates "
                            "the data, counts every evaluation and checks the answer); implement _solve instead")

    def one_time_setup(self) -> bool:
        """What this calibrator's solver would otherwise do once per process inside a fit (import its first-use
        modules, ``imports``; a GA loads or compiles the kernel its run will use), done by ``fit`` before its
        clock starts, so that ``runtime_s`` is the search's alone; the fit that paid for it gives the seconds in
        ``extra["one_time_s"]``.  Returns whether anything was done now."""
        return import_first(self.imports)

    # -- configuration ------------------------------------------------------------------------
    @classmethod
    def _param_names(cls) -> list[str]:
        """The constructor's keyword arguments (scikit-learn's ``_get_param_names``: no ``*args``)."""
        return list(_param_names_of(cls))

    def search_box(self) -> dict:
        """Keyword arguments of ``search_bounds`` for this calibrator: the physical box by default;
        population methods narrow it from their hyper-parameters (``population_box``)."""
        return dict(PHYSICAL_BOX)

    def is_stochastic(self) -> bool:
        """Whether the answer depends on the seed (the battery then checks that it does)."""
        return self.stochastic

    def get_params(self) -> dict:
        return {k: getattr(self, k) for k in self._param_names()}

    @classmethod
    def check_param_names(cls, params: dict) -> None:
        """Refuse hyper-parameters the constructor does not have (``InputError`` naming them)."""
        unknown = set(params) - set(cls._param_names())
        if unknown:
            raise InputError(f"{cls.name} has no hyper-parameter {', '.join(sorted(unknown))}; "
                             f"it has {', '.join(cls._param_names())}")

    @classmethod
    def check_param_values(cls, params: dict) -> None:
        """Refuse hyper-parameter values that break the class's declared ``_parameter_constraints``, and,
        for those without one, values of the wrong type judged by the constructor's annotations
        (``population: int`` refuses ``"abc"`` and ``2.5``; ``float`` takes integers; ``X | None`` takes
        None); annotations naming other types are not checked.  Values found valid are remembered
        (``_VALID_PARAMS``): every fit checks its calibrator's again."""
        key = _params_key(cls, params)
        if key is not None and key in _VALID_PARAMS:
            return
        validate_params(cls.name or cls.__name__, cls._parameter_constraints, params)
        annotated = _annotated_types(cls)
        for name, value in params.items():
            if name not in annotated or name in cls._parameter_constraints:
                continue
            allowed = annotated[name]
            if allowed is None or isinstance(value, allowed) and not (isinstance(value, bool) and bool not in allowed):
                if isinstance(value, float) and not math.isfinite(value):
                    raise InputError(f"{cls.name}: hyper-parameter {name} must be finite, not {value}")
                continue
            names = {t.__name__ for t in allowed} - {"NoneType"} | ({"None"} if type(None) in allowed else set())
            wanted = " or ".join(sorted(names))
            raise InputError(f"{cls.name}: hyper-parameter {name} must be {wanted}, not {value!r}")
        problem = cls._params_together({**_init_defaults(cls), **params})
        if problem:
            raise InputError(f"{cls.name}: {problem}")
        if key is not None:
            if len(_VALID_PARAMS) >= VALID_PARAMS_SIZE:
                _VALID_PARAMS.clear()
            _VALID_PARAMS[key] = True

    @classmethod
    def _params_together(cls, params: dict) -> str | None:
        """What is wrong with hyper-parameters that are valid one by one but not together (``elitism`` of
        ``population``), or None; ``params`` holds every hyper-parameter (the defaults where not given).  A
        subclass with such constraints overrides it; a limit that depends on the data stays in ``_solve``."""
        return None

    def set_params(self, **params) -> Calibrator:
        """A new calibrator with some hyper-parameters changed (the original is untouched)."""
        self.check_param_names(params)
        self.check_param_values(params)
        return type(self)(**{**self.get_params(), **params})

    @classmethod
    def checking_params(cls) -> dict:
        """Hyper-parameters that make the conformance battery cheap (scikit-learn's
        ``set_checking_parameters``)."""
        return {}

    def min_points(self, model: str) -> int:
        """The fewest readings this method can work with for ``model`` (the framework asks for at least
        ``MIN_RESIDUAL_DOF`` more than the model's parameters besides, whatever a method says here)."""
        return len(PARAM_NAMES[model]) + 1

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"

    # -- fitting ------------------------------------------------------------------------------
    def validate(self, dataset: Dataset) -> list[str]:
        """Refuse data this calibrator cannot use (``InputError``); return warnings."""
        model = self.model
        if model not in MODELS:
            raise InputError(f"unknown model {model!r}: use one of {', '.join(MODELS)} or auto")
        if model not in self.supported_models:
            raise InputError(f"{self.name} estimates the {'/'.join(self.supported_models)} model, "
                             f"not {model!r}; use model='{self.supported_models[0]}'")
        if not isinstance(dataset, Dataset):
            raise InputError(f"{self.name} needs a Dataset with bx, by, bz readings")
        n = len(dataset)
        need = max(self.min_points(model), len(PARAM_NAMES[model]) + MIN_RESIDUAL_DOF)
        if n < need:
            raise InputError(f"{n} points are too few for {self.name} with the {model} model "
                             f"(it needs at least {need}: {len(PARAM_NAMES[model])} parameters and "
                             f"{MIN_RESIDUAL_DOF} readings more, or the residual cannot say whether the fit is right)")
        if not dataset.has_reference:  # non-finite readings first, else the missing reference
            raise InputError(input_problems(dataset))
        known = _DatasetCache.of(dataset)  # what follows depends on the readings and reference alone: once per record
        distinct = known.get("distinct_rows", lambda: n - int(repeated_rows(dataset.raw_nT).sum()))
        if distinct < need:
            raise InputError(f"only {distinct} distinct reading{'s' if distinct != 1 else ''} in {n} rows (every other "
                             f"row repeats the reading before it exactly): too few for {self.name} with the {model} "
                             f"model (it needs at least {need})")
        bad = data_problem(dataset, known)
        if bad:
            raise InputError(bad)
        dead = known.get("dead_axis", lambda: dead_axis(dataset.raw_nT))
        if dead:
            raise InputError(dead)
        field_nT = known.get("field_nT", lambda: median(dataset.f_ref_nT))
        report = known.get(("coverage", model), lambda: coverage(
            ScalarObjective(dataset.raw_nT, dataset.f_ref_nT, model), identity_vector(model), field_nT))
        if report["refusal"]:
            raise InputError(report["refusal"])
        warnings = [report["warning"]] if report["warning"] else []
        spread = known.get("reference_spread", lambda: np.ptp(dataset.f_ref_nT) / field_nT)
        if spread > 0.05:
            warnings.append(f"the reference magnitude varies by {100 * spread:.1f} % over the record")
        note = time_column_note(dataset.t_s)  # not cached: the cache is keyed by the readings and reference alone
        if note:
            warnings.append(note)
        return warnings

    def fit(self, data, *, f_ref_nT=None, field=None, units: str = "nT") -> CalibrationResult:
        """Calibrate on ``data``; the data are read, never changed.  The one entry point: subclasses
        implement ``_solve`` and cannot override ``fit``.

        ``data``: a ``Dataset``, an (N, 3) array of readings or a pandas DataFrame with ``bx, by, bz``
        columns (``units`` applies to those two; default nT).  The reference magnitude: ``f_ref_nT=`` (a
        scalar or one value per row), ``field=`` (a number of nT, or ``"auto"``: estimated from the readings,
        MATLAB magcal's ``expmfs``; the overall gain then stays relative, see ``calibrators/inputs.py``),
        else the data's own (a Dataset's ``f_ref_nT``, a DataFrame's ``f_ref`` column).  With the model
        ``auto`` the candidate models are compared first (``calibrators/modelselect.py``)."""
        params = self.get_params()
        self.check_param_values(params)
        dataset = as_dataset(data, f_ref_nT=f_ref_nT, field=field, units=units, model=self.model)
        with one_blas_thread():
            if self.model == "auto":
                if not MODEL_CHOOSER:
                    raise InputError("model auto needs magbench.calibrators.modelselect, which installs the chooser")
                return MODEL_CHOOSER[0](self, dataset)
            return self._fit_dataset(dataset, params)

    def _fit_dataset(self, dataset: Dataset, params: dict | None = None) -> CalibrationResult:
        warnings = self.validate(dataset)
        known = _DatasetCache.again(dataset)
        field_nT = known.get("field_nT", lambda: median(dataset.f_ref_nT))
        if dataset.meta.get("reference_ignored") and "reference_estimated" not in dataset.meta:
            warnings.append(dataset.meta["reference_ignored"])
        if dataset.meta.get("input_notes"):  # the reader's (``simulate.dataset.column_notes``)
            warnings.append(str(dataset.meta["input_notes"]))
        model = self.model
        objective = ScalarObjective(dataset.raw_nT, dataset.f_ref_nT, model)
        budget = as_budget(self.budget)
        evaluator = Evaluator(objective, budget, clock=False)  # its time budget counts from the start's evaluation
        box = self.search_box()
        lower, upper = search_bounds(model, field_nT, **box)
        x0 = identity_vector(model)
        start = None if model == "angles" else partial(_algebraic_start, dataset.raw_nT, dataset.f_ref_nT, model)
        termination = self.termination(budget)
        problem: Problem
        if self.closed_form:
            problem = ReadingsProblem(evaluator, model, x0, lower, upper, None, self.seed, dataset.raw_nT,
                                      dataset.f_ref_nT, termination)
        else:
            problem = Problem(evaluator, model, x0, lower, upper, None, self.seed, termination)  # its rng made when asked
        stopped: Stopped | None = None  # how the strategy's search ended (None: no strategy ran)
        setup_t0 = time.perf_counter()  # one-time costs first, on a clock of their own (``one_time_setup``)
        one_time_s = time.perf_counter() - setup_t0 if self.one_time_setup() else 0.0
        t0 = time.perf_counter()
        try:
            if not self.closed_form:
                # The start is the first counted evaluation, so the counter's best point (what a run cut
                # short by its budget returns) is never worse than no calibration; a time budget counts from
                # after it (a budget spent before the first evaluation left no point to return).
                evaluator.values(x0[None, :])
            evaluator.start_clock()
            with _decoys_exposed(objective):
                out = self._solve(problem)
                if isinstance(out, Generator):  # a strategy: the framework evaluates what it asks for
                    out, stopped = drive(out, evaluator, termination, start)
        except BudgetExhausted as exc:
            if evaluator.best_x is None:  # a closed form whose time budget was spent before its first evaluation
                out = SolveOutput(x0.copy(), status="budget", message=f"stopped before any evaluation: {exc}",
                                  success=False)
            else:
                out = SolveOutput(evaluator.best_x, status="budget", message=f"stopped: {exc}", success=True)
            stopped = Stopped(getattr(exc, "iterations", 0), "budget")
        except FitError as exc:  # the readings do not take the method's form: spikes among them, if any, said beside it
            spikes = magnitude_spikes(dataset.raw_nT) if self.name != "ransac" else None
            if spikes is None:
                raise
            raise FitError(f"{exc}; but {spikes}") from exc
        if not isinstance(out, SolveOutput):
            out = SolveOutput(out, status="no_output", message=f"{self.name}'s _solve returned {type(out).__name__}, "
                              "not a SolveOutput", success=False)
        runtime = time.perf_counter() - t0

        solver_x, bad_shape = _solver_point(out.x, len(x0))
        f_start = known.get(("f_start", model), lambda: float(np.mean(objective.residuals(x0) ** 2)))
        with np.errstate(all="ignore"):  # one pass at the answer serves F and every acceptance check
            at = one_pass(objective, solver_x)
        f_solver = float(np.add.reduce(at.r * at.r) / len(at.r))  # np.mean(r ** 2): its sum and division, without its wrapper
        x, f_x, success, status = solver_x, f_solver, out.success, out.status
        if bad_shape or not np.isfinite(f_x) or f_x > f_start:
            what = bad_shape or f"ended worse than no calibration (F {f_x:.6g} > {f_start:.6g})"
            warnings.append(f"{self.name} {what}; the identity is returned")
            x, f_x, success, status = x0.copy(), f_start, False, "worse_than_start"
            with np.errstate(all="ignore"):
                at = one_pass(objective, x)
        warnings += self._solution_warnings(objective, x)
        physical = (lower, upper) if box == PHYSICAL_BOX else search_bounds(model, field_nT, **PHYSICAL_BOX)
        info: dict = {}
        rejections, notes = assess(objective, x, improved=status != "worse_than_start", robust=self.robust,
                                   closed_form=self.closed_form, physical_box=physical, limits=self.acceptance,
                                   info=info, t_s=dataset.t_s, at=at, memo=known.get, temp_C=dataset.temp_C,
                                   reference_estimated="reference_estimated" in dataset.meta)
        uncertainty, noise = _uncertainty(info.get("inliers", objective), x, info.get("noise_nT"),
                                          info.get("crb_std_at"), info.get("uncertainty_inflation", 1.0))
        if not self.closed_form:
            bound = _at_bounds(x, lower, upper, model)
            if bound:  # far from the optimum because the box excludes it, not because the search stopped short
                names = bound[0].split(" ended on")[0]
                rejections = [r.replace(SEARCH_STOPPED_SHORT, f"the optimum lies outside {self.name}'s search box "
                                        f"({names} ended on its bound): a box too small for this sensor (its *_range "
                                        "settings), or a reference or units that are wrong") for r in rejections]
            rejections += bound
        rejections += _budget_breaches(evaluator, budget)
        warnings += notes
        extra = dict(out.extra)
        if one_time_s:
            extra["one_time_s"] = one_time_s
        sampling = _acceptance_sampling(known.peek(("coverage", model)), info)
        if sampling:
            extra["acceptance_sampling"] = sampling
        return CalibrationResult(
            method=self.name, model=model, params=ErrorParams.from_vector(x, model), x=x,
            success=bool(success), status=status, message=out.message, fun=float(f_x),
            n_evaluations=evaluator.n_evaluations, n_jacobians=evaluator.n_jacobians,
            n_function_evaluations=evaluator.n_function_evaluations, nit=int(out.nit),
            runtime_s=runtime, seed=self.seed, rms_before_nT=float(np.sqrt(f_start)),
            rms_after_nT=float(np.sqrt(f_x)), warnings=tuple(warnings),
            hyperparameters=self.get_params() if params is None else params, trace=tuple(evaluator.trace),
            extra={**extra, **_stop_record(termination, stopped)},
            evaluation_mode="closed-form" if self.closed_form else "counted",
            solver_x=solver_x, solver_rms_nT=float(np.sqrt(f_solver)) if np.isfinite(f_solver) else float("nan"),
            n_overrun_calls=evaluator.n_overrun_calls, accepted=not rejections, rejections=tuple(rejections),
            reference=dict(known.get(("reference_of", *_reference_meta(dataset)), lambda: _reference_of(dataset))),
            uncertainty=uncertainty, noise_nT=noise,
            data_digest=known.digest, n_points=len(dataset))

    def _solution_warnings(self, objective: ScalarObjective, x: np.ndarray) -> list[str]:
        names = PARAM_NAMES[self.model]
        if "kx" in names:
            i = names.index("kx")
            if (x[i:i + 3] <= 0).any():
                return ["a scale factor is not positive: the estimate is not physical"]
        return []

    def termination(self, budget: Budget) -> Termination:
        """When this calibrator's search stops (``core/loop.py``): the comparison's ``budget`` and the
        method's own limits from ``termination_settings``, in the one object the framework enforces."""
        settings = self.termination_settings()  # raises InputError itself where it checks
        try:
            return Termination(budget=budget, **settings)
        except ValueError as exc:  # a hyper-parameter out of its range (a negative tol, zero generations)
            text = str(exc)
            field = next((f for f in ("max_iterations", "max_evaluations", "tol") if text.startswith(f + " ")), "")
            hyper = self.termination_params.get(field)
            text = hyper + text[len(field):].replace(" or None", "") if hyper else text
            raise InputError(f"{self.name}: {text}") from None

    def termination_settings(self) -> dict:
        """The method's ``Termination`` fields from its hyper-parameters (``max_iterations``,
        ``max_evaluations``, ``tol``, ``tol_meaning``); none by default."""
        return {}

    termination_params: ClassVar[dict] = {}
    """Which hyper-parameter gives each ``Termination`` field (``{"max_iterations": "generations"}``), so that
    a value out of range is refused in the hyper-parameter's name."""

    def _solve(self, problem: Any) -> Any:  # pragma: no cover - abstract
        """The method, handed a ``Problem`` (a ``ReadingsProblem`` when ``closed_form``): a strategy, i.e. a
        generator that asks for evaluations (``core/loop.py``) and returns a ``SolveOutput``; or, for a
        closed-form method, the ``SolveOutput`` itself."""
        raise NotImplementedError


_BLAS_CONTROLLER: list = []


@contextmanager
def one_blas_thread():
    """Within this block the BLAS libraries run on one thread (threadpoolctl, as scikit-learn does), the caller's own
    setting restored after it.  A fit's products are small or tall-skinny: a second OpenBLAS thread gains nothing
    (2e6 rows: 0.47 s on one thread, 0.51-0.62 s on two), and its spin-waiting costs a 300-point fit 0.3 ms of its 1.5
    ms on an idle host and, on a loaded one, up to 210 ms in one fit of ten.  The controller is made once, at the
    first fit (numpy's and SciPy's OpenBLAS are both loaded by then: ``magbench.simulate`` imports SciPy)."""
    if not _BLAS_CONTROLLER:
        from threadpoolctl import ThreadpoolController

        _BLAS_CONTROLLER.append(ThreadpoolController())
    with _BLAS_CONTROLLER[0].limit(limits=1, user_api="blas"):
        yield


def data_problem(dataset: Dataset, known: _DatasetCache | None = None) -> str | None:
    """Why these readings and this reference cannot be calibrated or diagnosed together, or None: ``input_problems``
    (non-finite or zero readings, a reference not finite and positive), then ``acceptance.reference_problems``
    (units, a corrupt row, a jumping reference).  None without a reference: each caller says that in its own words.
    ``known``: the record's cache (``validate``), else computed now.  One check for ``validate``, ``model="auto"``
    (before any candidate's numbers) and the diagnosis (before any of its paths)."""
    if not dataset.has_reference:
        return None

    def get(key, compute):
        return compute() if known is None else known.get(key, compute)

    return get("input_problems", lambda: input_problems(dataset)) or get(  # the jump check reads the times too
        ("reference_problems", time_key(dataset.t_s)), lambda: reference_problems(dataset.raw_nT, dataset.f_ref_nT,
                                                                                  dataset.t_s))


def dead_axis(raw_nT: np.ndarray) -> str | None:
    """Why the readings cannot be calibrated whatever the attitudes, or None: an axis that reads one value on every row
    (a dead, disconnected or stuck axis; the coverage check had called it 'degenerate attitude coverage' and asked for
    more rotation of a sensor that had rotated)."""
    constant = np.flatnonzero(np.ptp(raw_nT, axis=0) == 0) if len(raw_nT) > 1 else np.zeros(0, dtype=int)
    if not len(constant):
        return None
    if len(constant) == 3:
        return f"every reading is the same ({', '.join(f'{v:.6g}' for v in raw_nT[0])}): a stuck sensor"
    what = " and ".join(f"b{'xyz'[a]} reads {raw_nT[0, a]:.6g}" for a in constant)
    return (f"{what} on every row: a dead, disconnected or stuck axis, along which nothing can be calibrated "
            "(the other axes varied)")


def input_problems(dataset: Dataset) -> str | None:
    """Why no calibrator can use these readings and reference (non-finite readings, readings of exactly 0 on every
    axis, no reference, a reference not finite and positive), or None."""
    if not np.all(np.isfinite(dataset.raw_nT)):
        rows = np.flatnonzero(~np.all(np.isfinite(dataset.raw_nT), axis=1))
        return f"raw readings have NaN or infinite values in row(s) {', '.join(map(str, rows[:5]))}"
    zero = zero_readings(dataset.raw_nT)  # no direction, and a Jacobian of 0/0
    if zero:
        return zero
    if not dataset.has_reference:
        return NO_REFERENCE
    if not np.all(np.isfinite(dataset.f_ref_nT)) or np.any(dataset.f_ref_nT <= 0):
        return "the reference magnitude must be finite and positive on every row"
    return None


_ANNOTATION_TYPES = {"int": (int,), "float": (float, int), "str": (str,), "bool": (bool,), "None": (type(None),)}


def _annotation_types(annotation) -> tuple | None:
    """The Python types a simple annotation (``int``, ``float | None``, ...) allows, or None when it names
    something else (then nothing is checked)."""
    if annotation is inspect.Parameter.empty:
        return None
    text = annotation if isinstance(annotation, str) else getattr(annotation, "__name__", str(annotation))
    types: tuple = ()
    for part in (p.strip() for p in str(text).split("|")):
        if part not in _ANNOTATION_TYPES:
            return None
        types += _ANNOTATION_TYPES[part]
    return types


def _stop_record(termination: Termination, stopped: Stopped | None) -> dict:
    """What the result's ``extra`` says of a strategy's search: the termination the framework enforced, the
    iterations it counted and its reason to stop (absent: the strategy returned on its own); nothing for a
    closed-form method that asked for nothing."""
    if stopped is None:
        return {}
    out: dict = {"termination": termination.as_dict(), "iterations": stopped.iterations}
    if stopped.reason:
        out["stopped_by"] = stopped.reason
    return out


def _budget_breaches(evaluator: Evaluator, budget: Budget) -> list[str]:
    """The framework's re-check of its own counter after the solver returned (nevergrad's ``xpbase``): the
    budget object is the one it was given and the evaluation-equivalents spent are within it."""
    out = []
    if evaluator.budget is not budget:
        out.append("the calibrator replaced its evaluation budget; its counts cannot be trusted")
    if budget.max_evaluations is not None and evaluator.n_evaluations > budget.max_evaluations:
        out.append(f"{evaluator.n_evaluations} evaluation-equivalents exceed the budget of {budget.max_evaluations}")
    return out


_DECOYS: contextvars.ContextVar = contextvars.ContextVar("magbench_decoy_readings", default=None)


@contextmanager
def expose_decoys(make_decoy):
    """Within this block, while a solver runs, the shared objective's public ``raw_nT`` and ``f_ref_nT``
    hold ``make_decoy(raw_nT, f_ref_nT)`` instead of the readings (the objective computes from private
    references, so honest solvers see no difference).  The conformance battery's honeypot: a calibrator
    that reaches around its ``Problem`` to the readings fits the decoy, and its answer betrays it."""
    token = _DECOYS.set(make_decoy)
    try:
        yield
    finally:
        _DECOYS.reset(token)


@contextmanager
def _decoys_exposed(objective: ScalarObjective):
    make_decoy = _DECOYS.get()
    if make_decoy is None:
        yield
        return
    raw, f_ref = objective.raw_nT, objective.f_ref_nT
    objective.raw_nT, objective.f_ref_nT = make_decoy(raw, f_ref)
    try:
        yield
    finally:
        objective.raw_nT, objective.f_ref_nT = raw, f_ref


AT_BOUND_REL = 1e-6
"""A parameter within this fraction of its box's width from a bound is reported as on the bound."""


def _at_bounds(x: np.ndarray, lower: np.ndarray, upper: np.ndarray, model: str) -> list[str]:
    at = [name for name, v, lo, hi in zip(PARAM_NAMES[model], x.tolist(), lower.tolist(), upper.tolist())  # Python floats
          if v <= lo + AT_BOUND_REL * (hi - lo) or v >= hi - AT_BOUND_REL * (hi - lo)]
    if not at:
        return []
    return [f"{', '.join(at)} ended on the search bound: the data do not determine them (attitude coverage) "
            "or the search box is too small"]


def _reference_of(dataset: Dataset) -> dict:
    """The reference magnitude used and where it came from (CONTRACT section 3, ``reference``); with
    ``--field auto`` also ``estimated: true`` and what stays relative (``relative``)."""
    f = np.asarray(dataset.f_ref_nT, dtype=float)
    out = {"median_nT": float(np.median(f)), "min_nT": float(f.min()), "max_nT": float(f.max()),
           "source": dataset.meta.get("reference_source", "dataset f_ref_nT"),
           "estimated": "reference_estimated" in dataset.meta}
    if out["estimated"]:
        out["relative"] = dataset.meta["reference_estimated"]
    if dataset.meta.get("reference_ignored"):
        out["ignored"] = dataset.meta["reference_ignored"]
    return out


def data_digest(raw_nT: np.ndarray, f_ref_nT: np.ndarray | None) -> str:
    """sha256 of the readings and the reference as little-endian float64 (C order), prefixed ``sha256:``:
    the same numbers give the same digest, whatever file or array they came from."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(raw_nT, dtype="<f8").data)  # the bytes as they lie, not a copy
    if f_ref_nT is not None:
        h.update(np.ascontiguousarray(f_ref_nT, dtype="<f8").data)
    return "sha256:" + h.hexdigest()


class _DatasetCache:
    """Quantities of one dataset's readings and reference that do not depend on the calibrator's answer (the
    reference and coverage checks of ``validate``, the residual of no calibration), kept for the last
    ``SIZE`` datasets and keyed by ``data_digest``: the same numbers, from whatever array, find them; other
    numbers (a copy changed in place) do not.  The digest is computed once per fit: ``validate`` computes it
    (``of``) and the result of the same ``_fit_dataset`` call takes it from there (``again``)."""

    SIZE = 8
    _entries: dict[str, dict] = {}
    _lock = threading.Lock()
    _last = threading.local()

    def __init__(self, digest: str, values: dict):
        self.digest, self._values = digest, values

    @classmethod
    def of(cls, dataset: Dataset) -> _DatasetCache:
        """The entry of ``dataset``'s numbers (its digest computed now), remembered for ``again``."""
        digest = data_digest(dataset.raw_nT, dataset.f_ref_nT)
        with cls._lock:  # the most recently used last; the least recently used dropped
            values = cls._entries.pop(digest, None)
            if values is None:
                values = {}
                while len(cls._entries) >= cls.SIZE:
                    cls._entries.pop(next(iter(cls._entries)))
            cls._entries[digest] = values
        out = cls(digest, values)
        cls._last.value = (weakref.ref(dataset), weakref.ref(dataset.raw_nT), weakref.ref(dataset.f_ref_nT), out)
        return out

    @classmethod
    def again(cls, dataset: Dataset) -> _DatasetCache:
        """The entry ``of`` gave for these very arrays in this thread (``validate`` earlier in the same fit),
        else ``of(dataset)``."""
        last = getattr(cls._last, "value", None)
        cls._last.value = None
        if (last is not None and last[0]() is dataset and last[1]() is dataset.raw_nT
                and last[2]() is dataset.f_ref_nT):
            return last[3]
        return cls.of(dataset)

    def peek(self, key):
        """The cached value of ``key``, or None (nothing is computed or stored)."""
        return self._values.get(key)

    def get(self, key, compute):
        """The cached value of ``key``, computed by ``compute()`` the first time (an exception is not cached; a key
        that cannot be hashed, such as a dataset's meta holding a list, is not cached either)."""
        try:
            hash(key)
        except TypeError:
            return compute()
        if key not in self._values:
            self._values[key] = compute()
        return self._values[key]


def _reference_meta(dataset: Dataset) -> tuple:
    """What ``_reference_of`` reads of a dataset besides its reference: with the data digest, the key of its
    cached value."""
    meta = dataset.meta
    return (meta.get("reference_source"), meta.get("reference_estimated"), meta.get("reference_ignored"),
            "reference_estimated" in meta)


def _acceptance_sampling(coverage_report: dict | None, info: dict) -> dict:
    """Which acceptance checks judged a systematic sample of the rows, and to what precision (the result's
    ``extra["acceptance_sampling"]``; empty when every check read every row)."""
    out = {}
    if coverage_report and coverage_report.get("rows", 0) < coverage_report.get("of_rows", 0):
        m = coverage_report["rows"]
        out["coverage"] = {"rows": m, "of_rows": coverage_report["of_rows"],
                           "per_point_information_relative_se_for_cv_2": 2.0 / float(np.sqrt(m))}
    if "profile_sample" in info:
        out["profile"] = dict(info["profile_sample"])
    return out


def _uncertainty(objective: ScalarObjective, x: np.ndarray, noise_nT: float | None,
                 known: tuple[np.ndarray, np.ndarray] | None = None, inflation: float = 1.0) -> tuple[dict, float]:
    """Cramér-Rao standard deviation of every estimated parameter at ``x`` and the estimated noise (the
    residual RMS of the data's own optimum, degrees of freedom corrected; the estimate's own residual when
    the acceptance checks did not get that far), keyed by parameter name.  ``known``: (x', std) computed
    by the acceptance checks at the judge's optimum x' at that noise; used when ``x`` is within 1e-3
    standard deviations of x' (the bound is smooth in x: it is then the same to 1e-3).  Farther from x', each
    parameter's distance from it is added in quadrature: the answer's error is that distance plus the optimum's own,
    whose deviation the bound states.  A robust method trades efficiency for robustness (the fitness tests exempt it):
    ``ransac`` was accepted on 20 of 20 clean sphere9 records 5.4-15.6 of its bound's deviations from the truth,
    within 2.6 of these.  ``inflation``: the factor the checks widened the deviations by for samples that are not
    independent (``acceptance.widening``), applied here too."""
    names = PARAM_NAMES[objective.model]
    gap = judged = None
    if known is not None and noise_nT is not None and np.isfinite(noise_nT):
        at, judged = known
        gap = np.asarray(x, dtype=float) - at
        if np.isfinite(judged).all() and (np.abs(gap) <= 1e-3 * judged).all():
            return dict(zip(names, judged.tolist())), float(noise_nT)
    if noise_nT is None or not np.isfinite(noise_nT):
        n, p = objective.raw_nT.shape[0], len(names)
        r = objective.residuals(x)
        noise_nT = float(np.sqrt(np.sum(r * r) / max(n - p, 1)))
    field = float(np.median(objective.f_ref_nT))
    try:
        with np.errstate(all="ignore"):
            std = crb_std(objective, x, max(noise_nT * inflation, 1e-9 * field))
    except (np.linalg.LinAlgError, ValueError):
        std = np.full(len(names), np.nan)
    if gap is not None and judged is not None:  # the judge's deviations hold what it added (a nonlinearity's shift)
        std = np.hypot(np.fmax(std, judged), gap)
    return {name: float(v) for name, v in zip(names, std)}, float(noise_nT)


@functools.cache
def _init_signature(cls) -> inspect.Signature:
    """A calibrator class's constructor signature, read once per class (every fit reads its parameters)."""
    return inspect.signature(cls.__init__)


@functools.cache
def _param_names_of(cls) -> tuple[str, ...]:
    """``Calibrator._param_names`` of a class, read once per class (every fit reads them; a constructor that
    takes ``*args`` is refused each time)."""
    sig = _init_signature(cls)
    if any(p.kind == p.VAR_POSITIONAL for p in sig.parameters.values()):
        raise TypeError(f"{cls.__name__}.__init__ takes *args: calibrators list every hyper-parameter "
                        "as a keyword argument")
    return tuple(p.name for p in sig.parameters.values() if p.name != "self" and p.kind != p.VAR_KEYWORD)


_VALID_PARAMS: dict = {}
"""Hyper-parameters ``Calibrator.check_param_values`` found valid, keyed by ``_params_key`` (every fit checks its
calibrator's again: 10-25 us of Python at each fit, a sixtieth of lsq's whole fit at 300 points)."""
VALID_PARAMS_SIZE = 256
"""``_VALID_PARAMS`` is emptied when it holds this many."""


def _params_key(cls, params: dict) -> tuple | None:
    """The class and every hyper-parameter's name, type and value, or None when a value cannot be hashed (it is
    then checked every time).  The type is part of the key: ``1``, ``1.0`` and ``True`` are equal in Python,
    not as hyper-parameters."""
    key = (cls, tuple((name, type(value), value) for name, value in params.items()))
    try:
        hash(key)
    except TypeError:
        return None
    return key


@functools.cache
def _init_defaults(cls) -> dict:
    """A calibrator class's constructor defaults, read once per class (read-only by convention)."""
    return {p.name: p.default for p in _init_signature(cls).parameters.values() if p.default is not inspect.Parameter.empty}


@functools.cache
def _annotated_types(cls) -> dict[str, tuple | None]:
    """The Python types each constructor parameter's annotation allows (``_annotation_types``), read once per class
    (every fit checks its hyper-parameters)."""
    return {name: _annotation_types(p.annotation) for name, p in _init_signature(cls).parameters.items()}


def _solver_point(x, p: int) -> tuple[np.ndarray, str]:
    """The solver's answer as a float vector of length p, and what is wrong with it ('' if nothing)."""
    try:
        arr = np.array(x, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        return np.full(p, np.nan), f"returned {type(x).__name__}, not a parameter vector"
    if arr.shape != (p,):
        return np.full(p, np.nan), f"returned a vector of shape {arr.shape}, not ({p},)"
    return arr, ""


START_ROWS = 200_000
"""The closed-form start of a longer record is fitted on a systematic sample of this many rows in file order
(``numerics.systematic_rows``): it is only where the iterative search begins (which then reads every row),
and the ellipsoid's (10, n) design on 2e6 rows cost 0.5 s and 160 MB."""


def _algebraic_start(raw_nT: np.ndarray, f_ref_nT: np.ndarray, model: str) -> np.ndarray | None:
    """The closed-form start of a model: the ellipsoid (``nine``), the axis-aligned ellipsoid (``diag``),
    the sphere (``offset``), or None where the readings fit no such shape; on at most ``START_ROWS`` rows."""
    rows = systematic_rows(raw_nT.shape[0], START_ROWS)
    return algebraic_vector(raw_nT[rows], np.asarray(f_ref_nT)[rows], model)




"""The one interface of every calibrator.

A calibrator's constructor stores hyper-parameters and nothing else (scikit-learn's convention: the
signature *is* the configuration).  ``fit(dataset)`` validates the data, builds the shared counted
objective, calls the algorithm's ``_solve`` and returns an immutable ``CalibrationResult``; no fitted
state is kept on the calibrator.
"""
from __future__ import annotations

import inspect
import time
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from magbench.errors import InputError
from magbench.simulate.dataset import Dataset
from magbench.simulate.sensor import MODELS, PARAM_NAMES, ErrorParams

from .fisher import coverage
from .objective import Budget, BudgetExhausted, CountedObjective, ScalarObjective, identity_vector



@dataclass(frozen=True)
class CalibrationResult:
    """What ``fit`` returns: the estimate in CONTRACT section 1 form and how it was obtained.

    Names follow ``scipy.optimize.OptimizeResult`` where they overlap (``x``, ``success``, ``status``,
    ``message``, ``fun``, ``nit``); ``n_evaluations`` counts objective evaluations through the shared
    counter, ``n_jacobians`` the analytic Jacobian/gradient evaluations.
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

    def __post_init__(self):
        x = np.array(self.x, dtype=float)
        x.setflags(write=False)
        object.__setattr__(self, "x", x)

    @property
    def matrix(self) -> np.ndarray:
        return self.params.matrix

    def correct(self, raw_nT: np.ndarray) -> np.ndarray:
        """Apply the estimated correction B = M (raw - o) to readings (n, 3)."""
        return self.params.correct(raw_nT)

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
            "n_jacobians": self.n_jacobians,
            "nit": self.nit,
            "seed": self.seed,
            "success": self.success,
            "status": self.status,
            "message": self.message,
            "fun": self.fun,
            "warnings": list(self.warnings),
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


@dataclass
class Problem:
    """What an algorithm sees: the counted objective, the start point, bounds, the data and an rng."""

    objective: CountedObjective
    model: str
    x0: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    raw_nT: np.ndarray
    f_ref_nT: np.ndarray
    rng: np.random.Generator
    seed: int | None


@dataclass(frozen=True)
class SolveOutput:
    x: np.ndarray
    status: str = "converged"
    message: str = ""
    nit: int = 0
    success: bool = True
    extra: dict = field(default_factory=dict)


def default_bounds(model: str, f_ref_nT: np.ndarray, angle_range_rad: float = 0.1, scale_range: float = 0.1,
                   offset_range_nT: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Search box for population methods: angles +-``angle_range_rad`` (seed 000, step 1: 0.1 rad); for
    ``nine`` also scale 1 +- ``scale_range`` and offsets +-``offset_range_nT`` (default 10 % of the
    reference magnitude)."""
    lo = [-angle_range_rad] * 3
    hi = [angle_range_rad] * 3
    if model == "nine":
        offset = 0.1 * float(np.median(f_ref_nT)) if offset_range_nT is None else offset_range_nT
        lo += [1.0 - scale_range] * 3 + [-offset] * 3
        hi += [1.0 + scale_range] * 3 + [offset] * 3
    return np.array(lo), np.array(hi)


class Calibrator:
    """Base class: subclasses set ``name``, list their hyper-parameters as keyword arguments of
    ``__init__`` (stored as attributes of the same names, nothing else) and implement ``_solve``."""

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    supported_models: ClassVar[tuple[str, ...]] = MODELS
    stochastic: ClassVar[bool] = False
    # Tolerances the conformance battery allows this method on low-noise data (angle rad, scale, nT).
    check_tolerance: ClassVar[dict] = {"angle_rad": 2e-5, "scale": 2e-5, "offset_nT": 0.5}

    def __init__(self, model: str = "nine", seed: int | None = 0, budget: Budget | None = None):
        self.model = model
        self.seed = seed
        self.budget = budget

    # -- configuration ------------------------------------------------------------------------
    @classmethod
    def _param_names(cls) -> list[str]:
        sig = inspect.signature(cls.__init__)
        return [p.name for p in sig.parameters.values()
                if p.name != "self" and p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)]

    def get_params(self) -> dict:
        return {k: getattr(self, k) for k in self._param_names()}

    @classmethod
    def check_param_names(cls, params: dict) -> None:
        """Refuse hyper-parameters the constructor does not have (``InputError`` naming them)."""
        unknown = set(params) - set(cls._param_names())
        if unknown:
            raise InputError(f"{cls.name} has no hyper-parameter {', '.join(sorted(unknown))}; "
                             f"it has {', '.join(cls._param_names())}")

    def set_params(self, **params) -> "Calibrator":
        """A new calibrator with some hyper-parameters changed (the original is untouched)."""
        self.check_param_names(params)
        return type(self)(**{**self.get_params(), **params})

    @classmethod
    def checking_params(cls) -> dict:
        """Hyper-parameters that make the conformance battery cheap (scikit-learn's
        ``set_checking_parameters``)."""
        return {}

    def min_points(self, model: str) -> int:
        return len(PARAM_NAMES[model]) + 1

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"

    # -- fitting ------------------------------------------------------------------------------
    def validate(self, dataset: Dataset) -> list[str]:
        """Refuse data this calibrator cannot use (``InputError``); return warnings."""
        model = self.model
        if model not in MODELS:
            raise InputError(f"unknown model {model!r}: use one of {', '.join(MODELS)}")
        if model not in self.supported_models:
            raise InputError(f"{self.name} estimates the {'/'.join(self.supported_models)} model, "
                             f"not {model!r}; use --model {self.supported_models[0]}")
        if not isinstance(dataset, Dataset):
            raise InputError(f"{self.name} needs a Dataset with bx, by, bz readings")
        n = len(dataset)
        need = self.min_points(model)
        if n < need:
            raise InputError(f"{n} points are too few for {self.name} with the {model} model "
                             f"(it needs at least {need})")
        if not np.all(np.isfinite(dataset.raw_nT)):
            rows = np.flatnonzero(~np.all(np.isfinite(dataset.raw_nT), axis=1))
            raise InputError(f"raw readings have NaN or infinite values in row(s) "
                             f"{', '.join(map(str, rows[:5]))}")
        if not dataset.has_reference:
            raise InputError("no reference magnitude: give an f_ref column, --field NT, "
                             "--igrf LAT,LON,ALT_KM,YYYY-MM-DD, or a '# field_nT:' line")
        if not np.all(np.isfinite(dataset.f_ref_nT)) or np.any(dataset.f_ref_nT <= 0):
            raise InputError("the reference magnitude must be finite and positive on every row")
        report = coverage(ScalarObjective(dataset.raw_nT, dataset.f_ref_nT, model), identity_vector(model))
        if report["refusal"]:
            raise InputError(report["refusal"])
        warnings = [report["warning"]] if report["warning"] else []
        spread = np.ptp(dataset.f_ref_nT) / np.median(dataset.f_ref_nT)
        if spread > 0.05:
            warnings.append(f"the reference magnitude varies by {100 * spread:.1f} % over the record")
        return warnings

    def fit(self, dataset: Dataset) -> CalibrationResult:
        """Calibrate on ``dataset``; the data are read, never changed."""
        warnings = self.validate(dataset)
        model = self.model
        objective = ScalarObjective(dataset.raw_nT, dataset.f_ref_nT, model)
        counted = CountedObjective(objective, self.budget)
        lower, upper = default_bounds(model, dataset.f_ref_nT)
        x0 = identity_vector(model)
        problem = Problem(counted, model, x0, lower, upper, dataset.raw_nT, dataset.f_ref_nT,
                          np.random.default_rng(self.seed), self.seed)
        t0 = time.perf_counter()
        try:
            out = self._solve(problem)
        except BudgetExhausted as exc:
            if counted.best_x is None:
                raise
            out = SolveOutput(counted.best_x, status="budget", message=f"stopped: {exc}", success=True)
        runtime = time.perf_counter() - t0

        x = np.asarray(out.x, dtype=float)
        f_start, f_x = objective.values(np.vstack([x0, x]), exact=True)
        success, status, message = out.success, out.status, out.message
        if not np.isfinite(f_x) or f_x > f_start:
            warnings.append(f"{self.name} ended worse than no calibration (F {f_x:.6g} > {f_start:.6g}); "
                            "the identity is returned")
            x, f_x, success, status = x0.copy(), f_start, False, "worse_than_start"
        warnings += self._solution_warnings(objective, x)
        if out.extra.get("at_bounds"):
            warnings.append(f"{', '.join(out.extra['at_bounds'])} ended on the physical bound: the data do not "
                            "determine them (attitude coverage)")
        return CalibrationResult(
            method=self.name, model=model, params=ErrorParams.from_vector(x, model), x=x,
            success=bool(success), status=status, message=message, fun=float(f_x),
            n_evaluations=counted.n_evaluations, n_jacobians=counted.n_jacobians, nit=int(out.nit),
            runtime_s=runtime, seed=self.seed, rms_before_nT=float(np.sqrt(f_start)),
            rms_after_nT=float(np.sqrt(f_x)), warnings=tuple(warnings),
            hyperparameters=self.get_params(), trace=tuple(counted.trace), extra=dict(out.extra))

    def _solution_warnings(self, objective: ScalarObjective, x: np.ndarray) -> list[str]:
        if self.model == "nine":
            x_k = x[3:6]
            if np.any(x_k <= 0):
                return ["a scale factor is not positive: the estimate is not physical"]
        return []

    def _solve(self, problem: Problem) -> SolveOutput:  # pragma: no cover - abstract
        raise NotImplementedError

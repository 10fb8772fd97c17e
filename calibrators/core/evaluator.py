"""The one evaluation counter (pymoo's ``Evaluator``, COCO's observer) and the budget it enforces."""
from __future__ import annotations

import contextvars
import math
import time
from contextlib import contextmanager
from dataclasses import dataclass
from numbers import Integral, Real

import numpy as np

from magbench.errors import InputError


@dataclass(frozen=True)
class Budget:
    """One budget type for every calibrator: evaluations of the objective and/or wall time."""

    max_evaluations: int | None = None
    max_time_s: float | None = None

    def __post_init__(self):
        # an int and a finite positive number, by type as well as value ('10' had raised a TypeError from '<', 1.5 one
        # from a slice inside the fit, and nan had acted as no budget)
        m, t = self.max_evaluations, self.max_time_s
        if m is not None and (not isinstance(m, Integral) or isinstance(m, bool) or m < 1):
            raise InputError(f"max_evaluations must be at least 1 (an int), got {m!r}")
        if t is not None and (not isinstance(t, Real) or isinstance(t, bool) or not 0 < t < math.inf):
            raise InputError(f"max_time_s must be a finite positive number of seconds, got {t!r}")


class BudgetExhausted(Exception):
    """Raised by the counter when the budget is spent; the calibrator returns the best seen."""


_AUDIT: contextvars.ContextVar[Audit | None] = contextvars.ContextVar("magbench_evaluation_audit", default=None)


class Audit:
    """What every ``Evaluator`` created inside ``audit_evaluations`` saw: the parameter vectors whose
    objective value or residuals it computed (``points``, one (m, p) array per call) and the points of its
    Jacobians and gradients (``jacobian_points``).  Kept apart from the evaluator's own counters, so that
    the conformance battery can re-check the counts a result reports (nevergrad's ``xpbase`` re-check)."""

    def __init__(self):
        self.points: list[np.ndarray] = []
        self.jacobian_points: list[np.ndarray] = []

    def __iter__(self):  # the function-evaluated points, call by call
        return iter(self.points)

    def __len__(self) -> int:
        return len(self.points)

    @property
    def n_function_evaluations(self) -> int:
        return int(sum(len(x) for x in self.points))

    @property
    def n_jacobians(self) -> int:
        return len(self.jacobian_points)


@contextmanager
def audit_evaluations():
    """Within this block every ``Evaluator`` also keeps each parameter vector it evaluates in the ``Audit``
    this context manager yields.  The conformance battery uses it to check that the answer a solver
    returns went through the counter; outside it nothing is recorded and nothing costs."""
    log = Audit()
    token = _AUDIT.set(log)
    try:
        yield log
    finally:
        _AUDIT.reset(token)


class Evaluator:
    """The one evaluation counter (pymoo's ``Evaluator``, COCO's observer): every objective value,
    residual vector and Jacobian a calibrator sees passes through it.

    Counts in evaluation-equivalents, the budget's unit (CONTRACT section 3): one per parameter vector
    whose value or residuals are computed (``n_function_evaluations``), and p per Jacobian or gradient of
    the p free parameters (``n_jacobians``; the finite-difference convention: a forward-difference
    Jacobian costs p evaluations), so that a method that uses derivatives pays for them like one that
    does not.  ``n_evaluations = n_function_evaluations + p * n_jacobians``.

    Enforces the ``Budget`` exactly (a batch that would overrun it is evaluated only up to the budget, a
    Jacobian that does not fit in what is left is refused, then ``BudgetExhausted`` is raised); counts the
    calls a solver makes after it was told the budget is spent (``n_overrun_calls``: a solver that
    swallows ``BudgetExhausted`` and keeps asking is caught); keeps the best point seen and a convergence
    trace of (evaluation-equivalents, best F, batch mean F) per call.  The objective itself is private: a
    calibrator gets a ``Problem`` that exposes only the counted functions.
    """

    __slots__ = ("_objective", "_budget", "_n_f", "_n_j", "n_overrun_calls", "_exhausted", "best_x", "best_f",
                 "trace", "_audit", "_t0")

    def __init__(self, objective, budget: Budget | None = None, clock: bool = True):
        self._objective = objective
        self._budget = budget or Budget()
        self._n_f = 0
        self._n_j = 0
        self.n_overrun_calls = 0
        self._exhausted = False
        self.best_x: np.ndarray | None = None
        self.best_f = np.inf
        self.trace: list[tuple[int, float, float]] = []
        self._audit = _AUDIT.get()
        self._t0: float | None = time.perf_counter() if clock else None  # None: the time budget waits for start_clock

    @property
    def budget(self) -> Budget:
        return self._budget

    def start_clock(self) -> None:
        """The time budget counts from now (an evaluator made with ``clock=False`` checks no time before): ``fit``
        evaluates the start first, then starts the clock as the strategy takes over (a time budget spent before the
        first evaluation had let the counter's own ``BudgetExhausted`` escape from ``fit``, with no point to
        return)."""
        self._t0 = time.perf_counter()

    @property
    def n_params(self) -> int:
        return self._objective.n_params

    @property
    def n_function_evaluations(self) -> int:
        return self._n_f

    @property
    def n_jacobians(self) -> int:
        return self._n_j

    @property
    def jacobian_cost(self) -> int:
        """Evaluation-equivalents one Jacobian or gradient costs: the number of free parameters."""
        return int(self._objective.n_params)

    @property
    def n_evaluations(self) -> int:
        """Evaluation-equivalents spent: function evaluations plus p per Jacobian."""
        return self._n_f + self.jacobian_cost * self._n_j

    def _refuse(self, why: str):
        if self._exhausted:
            self.n_overrun_calls += 1
        self._exhausted = True
        raise BudgetExhausted(why)

    def _allowance(self, m: int, jacobians: int = 0) -> int:
        """How many of ``m`` function evaluations may be made now (with ``jacobians`` Jacobians, which must
        fit whole); raises ``BudgetExhausted`` when nothing may."""
        b = self._budget
        if self._exhausted:
            self._refuse("the budget was already spent")
        if b.max_evaluations is None and b.max_time_s is None:
            return m
        if b.max_time_s is not None and self._t0 is not None and time.perf_counter() - self._t0 >= b.max_time_s:
            self._refuse(f"time budget of {b.max_time_s} s reached")
        if b.max_evaluations is None:
            return m
        left = b.max_evaluations - self.n_evaluations
        need_j = jacobians * self.jacobian_cost
        if left <= 0 or need_j > left or (need_j and left - need_j < m):
            self._refuse(f"evaluation budget of {b.max_evaluations} evaluation-equivalents reached")
        return min(m, left - need_j)

    @property
    def evaluations_left(self) -> int | None:
        b = self._budget
        return None if b.max_evaluations is None else max(0, b.max_evaluations - self.n_evaluations)

    def _record(self, x: np.ndarray, f: np.ndarray) -> None:
        self._n_f += len(f)
        if self._audit is not None:
            self._audit.points.append(np.array(x, dtype=float, copy=True))
        i = f.argmin()
        fi = f[i]
        if fi != fi:  # argmin prefers NaN: look again among the finite values
            finite = np.where(np.isfinite(f), f, np.inf)
            i = finite.argmin()
            fi = finite[i]
        if fi < self.best_f:
            self.best_f = float(fi)
            self.best_x = x[i].copy()
        self.trace.append((self.n_evaluations, self.best_f, f.sum() / len(f)))

    def _record_jacobian(self, x: np.ndarray) -> None:
        self._n_j += 1
        if self._audit is not None:
            self._audit.jacobian_points.append(np.array(x, dtype=float, copy=True))

    def values(self, x: np.ndarray) -> np.ndarray:
        """F for a population (m, p) -> (m,); costs m evaluations."""
        if not (isinstance(x, np.ndarray) and x.ndim == 2 and x.dtype == np.float64):
            x = np.atleast_2d(np.asarray(x, dtype=float))
        k = self._allowance(x.shape[0])
        x_k = x[:k] if k < x.shape[0] else x
        f = self._objective.values(x_k)
        self._record(x_k, f)
        if k < x.shape[0]:
            self._refuse(f"evaluation budget of {self._budget.max_evaluations} evaluation-equivalents reached")
        return f

    def value(self, x: np.ndarray) -> float:
        """F at one point; costs one evaluation.  The single-point path of ``values`` (what local methods
        call thousands of times): the direct form of the residuals, recorded without building a population."""
        x = np.asarray(x, dtype=float)
        if self._exhausted or self._budget.max_evaluations is not None or self._budget.max_time_s is not None:
            self._allowance(1)
        r = self._objective.residuals(x)
        r *= r
        f = float(np.add.reduce(r) / r.size)  # np.mean's own sum and division, to the last bit, without its checks
        self._n_f += 1
        if self._audit is not None:
            self._audit.points.append(np.array(x[None, :], dtype=float, copy=True))
        if f < self.best_f:
            self.best_f = f
            self.best_x = x.copy()
        self.trace.append((self.n_evaluations, self.best_f, f))
        return f

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Residual vector at one point; costs one evaluation."""
        self._allowance(1)
        r = self._objective.residuals(x)
        self._record(np.asarray(x, dtype=float)[None, :], np.array([np.mean(r * r)]))
        return r

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """The residuals' Jacobian (n, p) at one point; costs p evaluation-equivalents."""
        self._allowance(0, jacobians=1)
        self._record_jacobian(np.asarray(x, dtype=float))
        return self._objective.jacobian(x)

    def normal_equations(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """``(J^T J, J^T r, r^T r)`` at one point: one evaluation and one Jacobian (1 + p)."""
        self._allowance(1, jacobians=1)
        out = self._objective.normal_equations(x)
        self._record_jacobian(np.asarray(x, dtype=float))
        n = self._objective.raw_nT.shape[0]
        self._record(np.asarray(x, dtype=float)[None, :], np.array([out[2] / n]))
        return out

    @property
    def n_points(self) -> int:
        return self._objective.raw_nT.shape[0]

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dF/dx at one point; costs p evaluation-equivalents, as a forward-difference gradient would."""
        self._allowance(0, jacobians=1)
        self._record_jacobian(np.asarray(x, dtype=float))
        return self._objective.gradient(x)

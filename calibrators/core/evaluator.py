"""The one evaluation counter (pymoo's ``Evaluator``, COCO's observer) and the budget it enforces."""
from __future__ import annotations

import contextvars
import time
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Budget:
    """One budget type for every calibrator: evaluations of the objective and/or wall time."""

    max_evaluations: int | None = None
    max_time_s: float | None = None

    def __post_init__(self):
        if self.max_evaluations is not None and self.max_evaluations < 1:
            raise ValueError("max_evaluations must be at least 1")
        if self.max_time_s is not None and self.max_time_s <= 0:
            raise ValueError("max_time_s must be positive")


class BudgetExhausted(Exception):
    """Raised by the counter when the budget is spent; the calibrator returns the best seen."""


_AUDIT: contextvars.ContextVar[list | None] = contextvars.ContextVar("magbench_evaluation_audit", default=None)


@contextmanager
def audit_evaluations():
    """Within this block every ``Evaluator`` also keeps each parameter vector it evaluates, in the list
    this context manager yields (one (m, p) array per call).  The conformance battery uses it to check
    that the answer a solver returns went through the counter (nevergrad's benchmark re-checks the
    optimizer's calls the same way); outside it nothing is recorded and nothing costs."""
    log: list = []
    token = _AUDIT.set(log)
    try:
        yield log
    finally:
        _AUDIT.reset(token)


class Evaluator:
    """The one evaluation counter (pymoo's ``Evaluator``, COCO's observer): every objective value,
    residual vector and Jacobian a calibrator sees passes through it.

    Counts every parameter vector evaluated (one per population row, one per residual vector) and the
    Jacobian/gradient evaluations separately; enforces the ``Budget`` exactly (a batch that would overrun
    it is evaluated only up to the budget, then ``BudgetExhausted`` is raised); counts the calls a solver
    makes after it was told the budget is spent (``n_overrun_calls``: a solver that swallows
    ``BudgetExhausted`` and keeps asking is caught); keeps the best point seen and a convergence trace of
    (evaluations, best F, batch mean F) per call.  The objective itself is private: a calibrator gets a
    ``Problem`` that exposes only the counted functions.
    """

    def __init__(self, objective, budget: Budget | None = None):
        self._objective = objective
        self.budget = budget or Budget()
        self.n_evaluations = 0
        self.n_jacobians = 0
        self.n_overrun_calls = 0
        self._exhausted = False
        self.best_x: np.ndarray | None = None
        self.best_f = np.inf
        self.trace: list[tuple[int, float, float]] = []
        self._audit = _AUDIT.get()
        self._t0 = time.perf_counter()

    @property
    def n_params(self) -> int:
        return self._objective.n_params

    def _refuse(self, why: str):
        if self._exhausted:
            self.n_overrun_calls += 1
        self._exhausted = True
        raise BudgetExhausted(why)

    def _allowance(self, m: int) -> int:
        b = self.budget
        if self._exhausted:
            self._refuse("the budget was already spent")
        if b.max_evaluations is None and b.max_time_s is None:
            return m
        if b.max_time_s is not None and time.perf_counter() - self._t0 >= b.max_time_s:
            self._refuse(f"time budget of {b.max_time_s} s reached")
        if b.max_evaluations is None:
            return m
        left = b.max_evaluations - self.n_evaluations
        if left <= 0:
            self._refuse(f"evaluation budget of {b.max_evaluations} reached")
        return min(m, left)

    @property
    def evaluations_left(self) -> int | None:
        b = self.budget
        return None if b.max_evaluations is None else max(0, b.max_evaluations - self.n_evaluations)

    def _record(self, x: np.ndarray, f: np.ndarray) -> None:
        self.n_evaluations += len(f)
        if self._audit is not None:
            self._audit.append(np.array(x, dtype=float, copy=True))
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

    def values(self, x: np.ndarray) -> np.ndarray:
        """F for a population (m, p) -> (m,); counts m evaluations."""
        if not (isinstance(x, np.ndarray) and x.ndim == 2 and x.dtype == np.float64):
            x = np.atleast_2d(np.asarray(x, dtype=float))
        k = self._allowance(x.shape[0])
        x_k = x[:k] if k < x.shape[0] else x
        f = self._objective.values(x_k)
        self._record(x_k, f)
        if k < x.shape[0]:
            self._refuse(f"evaluation budget of {self.budget.max_evaluations} reached")
        return f

    def value(self, x: np.ndarray) -> float:
        return float(self.values(np.asarray(x, dtype=float)[None, :])[0])

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Residual vector at one point; counts one evaluation."""
        self._allowance(1)
        r = self._objective.residuals(x)
        self._record(np.asarray(x, dtype=float)[None, :], np.array([np.mean(r * r)]))
        return r

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        self._allowance(0)
        self.n_jacobians += 1
        return self._objective.jacobian(x)

    def normal_equations(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """``(J^T J, J^T r, r^T r)`` at one point: one counted evaluation and one Jacobian."""
        self._allowance(1)
        out = self._objective.normal_equations(x)
        self.n_jacobians += 1
        n = self._objective.raw_nT.shape[0]
        self._record(np.asarray(x, dtype=float)[None, :], np.array([out[2] / n]))
        return out

    @property
    def n_points(self) -> int:
        return self._objective.raw_nT.shape[0]

    def gradient(self, x: np.ndarray) -> np.ndarray:
        self._allowance(0)
        self.n_jacobians += 1
        return self._objective.gradient(x)

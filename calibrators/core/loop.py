"""The framework's evaluation loop: calibrators are strategies that ask, the framework evaluates and tells.

nevergrad's ask/tell and pymoo's ``Evaluator``: an iterative calibrator's ``_solve`` is a generator.  It
yields a request (an ``Ask``: a population, a point, a residual vector, a Jacobian, a gradient, the
normal equations, the closed-form start, or the end of an iteration) and is sent the answer.  Only
``drive`` evaluates, through the one ``Evaluator``, so every count is the framework's: a strategy holds no
objective, no evaluator and no readings, and cannot evaluate anything itself.

One ``Termination`` holds when a search stops: the budget (evaluation-equivalents and wall time, enforced
by the evaluator on every request), the iterations or generations, the strategy's own evaluation cap and
its convergence tolerance.  A strategy marks the end of each iteration with ``iteration(measure)``
(``measure``: its convergence statistic, compared with the tolerance by the framework); the reply is the
reason to stop (``"max_iterations"``, ``"max_evaluations"``, ``"converged"``) or ``""`` to go on.

Libraries that call an objective themselves (SciPy, NLopt) run under ``recast``: the library runs in a
greenlet whose callback asks the framework, so they too are strategies (nevergrad's ``RecastOptimizer``,
without a thread: a switch costs about a microsecond).
"""
from __future__ import annotations

import contextvars
from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from greenlet import GreenletExit, greenlet

from .evaluator import Budget, BudgetExhausted, Evaluator


class Ask(NamedTuple):
    """One request of a strategy: ``kind`` (one of ``KINDS``) and its argument (a point, a population, an
    iteration's convergence measure, or None)."""

    kind: str
    arg: Any = None


KINDS = ("values", "value", "residuals", "jacobian", "gradient", "normal_equations", "start", "iteration")
"""What a strategy may ask for; what each costs is the ``Evaluator``'s (CONTRACT section 3)."""


def values(x: np.ndarray) -> Ask:
    """F (seed 000, eq. 3) of a population (m, p): m evaluations; the reply is (m,)."""
    return Ask("values", x)


def value(x: np.ndarray) -> Ask:
    """F at one point: one evaluation; the reply is a float."""
    return Ask("value", x)


def residuals(x: np.ndarray) -> Ask:
    """The per-point residuals ``|M (raw - o)| - F`` at one point: one evaluation; the reply is (n,)."""
    return Ask("residuals", x)


def jacobian(x: np.ndarray) -> Ask:
    """The residuals' Jacobian (n, p): p evaluation-equivalents."""
    return Ask("jacobian", x)


def gradient(x: np.ndarray) -> Ask:
    """dF/dx (p,): p evaluation-equivalents."""
    return Ask("gradient", x)


def normal_equations(x: np.ndarray) -> Ask:
    """``(J^T J, J^T r, r^T r)`` accumulated in bounded memory: one evaluation and one Jacobian (1 + p)."""
    return Ask("normal_equations", x)


START = Ask("start")
"""The closed-form fit as a start point: the reply is ``(x, F)`` (one evaluation) or None where the readings
fit no such shape (``nine``: the ellipsoid; ``diag``: the axis-aligned ellipsoid; ``offset``: the sphere)."""


def iteration(measure: float = np.inf) -> Ask:
    """The end of an iteration or generation, with the strategy's convergence statistic (``inf``: none yet);
    the reply is the reason to stop, or ``""``."""
    return Ask("iteration", float(measure))


@dataclass(frozen=True)
class Termination:
    """When a search stops, in one place (pymoo's termination object), held and checked by the framework.

    ``budget``: the comparison's budget (evaluation-equivalents and wall time), enforced exactly by the
    evaluator on every request; a count over it is a rejection.  ``max_iterations``: iterations or
    generations (``iteration`` marks); ``max_evaluations``: the strategy's own cap on the
    evaluation-equivalents its search spends (the framework's evaluation of the start excluded), checked at
    each ``iteration`` mark; ``tol``: the strategy's convergence tolerance (its measure at or below it
    stops the search; None or 0: no such stop), whose meaning ``tol_meaning`` says."""

    budget: Budget = Budget()
    max_iterations: int | None = None
    max_evaluations: int | None = None
    tol: float | None = None
    tol_meaning: str = ""

    def __post_init__(self):
        for name in ("max_iterations", "max_evaluations"):
            v = getattr(self, name)
            if v is not None and (not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 1):
                raise ValueError(f"{name} must be a positive integer or None, not {v!r}")
        if self.tol is not None and not (np.isfinite(self.tol) and self.tol >= 0):
            raise ValueError(f"tol must be finite and >= 0, not {self.tol!r}")

    def reason_to_stop(self, iterations: int, spent: int, measure: float) -> str:
        """Why the search stops after ``iterations`` marks with ``spent`` evaluation-equivalents of its own
        and the convergence ``measure``; ``""`` to go on."""
        if self.tol and measure <= self.tol:
            return "converged"
        if self.max_iterations is not None and iterations >= self.max_iterations:
            return "max_iterations"
        if self.max_evaluations is not None and spent >= self.max_evaluations:
            return "max_evaluations"
        return ""

    def as_dict(self) -> dict:
        b = self.budget
        return {"max_evaluations_budget": b.max_evaluations, "max_time_s": b.max_time_s,
                "max_iterations": self.max_iterations, "max_evaluations": self.max_evaluations, "tol": self.tol,
                **({"tol_meaning": self.tol_meaning} if self.tol_meaning else {})}


class Stopped(NamedTuple):
    """What ``drive`` saw of a search: its iterations and the framework's reason to stop ("" if the strategy
    returned on its own)."""

    iterations: int
    reason: str


OVERRUN_LIMIT = 100
"""Requests a strategy may make after being told the budget is spent before the framework closes it."""


def drive(search: Generator, evaluator: Evaluator, termination: Termination,
          start: Callable[[], np.ndarray | None] | None = None) -> tuple[Any, Stopped]:
    """Run the strategy ``search`` to its end: evaluate each request through ``evaluator`` (which counts it
    and enforces the budget) and send the answer back; at each ``iteration`` mark send the reason to stop.
    Returns what the strategy returned and how it stopped.

    When the budget is spent the evaluator's ``BudgetExhausted`` is thrown into the strategy, which may
    return what it has; if it does not, the exception propagates (the caller returns the best point the
    counter saw).  A strategy that keeps asking after that is counted (``n_overrun_calls``) and closed after
    ``OVERRUN_LIMIT`` requests."""
    table: dict[str, Callable[[Any], Any]] = {
        "values": evaluator.values, "value": evaluator.value, "residuals": evaluator.residuals,
        "jacobian": evaluator.jacobian, "gradient": evaluator.gradient,
        "normal_equations": evaluator.normal_equations,
    }
    spent0 = evaluator.n_evaluations
    iterations, reason, overruns = 0, "", 0
    send = search.send
    try:
        request = send(None)
        while True:
            if not isinstance(request, tuple) or not request or request[0] not in KINDS:
                search.close()
                raise TypeError(f"a strategy asked for {request!r}: it may ask for one of {', '.join(KINDS)} "
                                "(calibrators.core.loop)")
            kind = request[0]
            try:
                if kind == "iteration":
                    iterations += 1
                    reply: Any = termination.reason_to_stop(iterations, evaluator.n_evaluations - spent0,
                                                            request[1])
                    reason = reply or reason
                elif kind == "start":
                    x = start() if start is not None else None
                    reply = None if x is None else (x, float(evaluator.values(x[None, :])[0]))
                else:
                    reply = table[kind](request[1])
            except BudgetExhausted as exc:
                overruns += 1
                if overruns > OVERRUN_LIMIT:
                    search.close()
                    raise
                request = search.throw(exc)
                continue
            request = send(reply)
    except StopIteration as done:
        return done.value, Stopped(iterations, reason)
    except BudgetExhausted as exc:  # the strategy did not end on its own: say how far it got
        exc.iterations = iterations  # type: ignore[attr-defined]
        raise


def asks(kind: str, points: Generator[Any, Any, Any]) -> Generator[Ask, Any, Any]:
    """A generator of bare points (such as ``numerics.lm_iterations``) as a strategy: each point it yields is
    asked for as ``kind`` and the answer sent back; returns what it returns."""
    try:
        x = next(points)
        while True:
            x = points.send((yield Ask(kind, x)))
    except StopIteration as done:
        return done.value


def recast(run: Callable[[Callable[[Ask], Any]], Any]) -> Generator[Ask, Any, Any]:
    """A callback-driven library as a strategy (nevergrad's ``RecastOptimizer``, in a greenlet rather than a
    thread): ``run(ask)`` runs the library, whose objective callback calls ``ask(request)`` and gets the
    framework's answer.  Exceptions the framework throws in (``BudgetExhausted``) are raised inside the
    callback, so the library unwinds through its own error handling; whatever ``run`` returns is returned."""
    def body():
        return ("done", run(ask))

    child = greenlet(body)
    child.gr_context = contextvars.copy_context()  # the library sees the caller's context (np.errstate, ...)

    def ask(request: Ask):
        return child.parent.switch(("ask", request))

    message = child.switch()
    while True:
        tag, payload = message
        if tag == "done":
            return payload
        try:
            reply = yield payload
        except GeneratorExit:
            _unwind(child)
            raise
        except BaseException as exc:  # noqa: BLE001 - handed to the library, which raises it in the callback
            message = child.throw(exc)
            continue
        message = child.switch(reply)


def _unwind(child) -> None:
    """End a library's greenlet that is waiting in its callback (the framework closed the strategy)."""
    for _ in range(OVERRUN_LIMIT):
        if child.dead:
            return
        try:
            child.throw(GreenletExit)
        except BaseException:  # noqa: BLE001 - GreenletExit, or what the library turned it into: it has ended
            return

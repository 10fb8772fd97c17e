"""Declarative hyper-parameter constraints (scikit-learn's ``_parameter_constraints`` and
``validate_parameter_constraints``, ``sklearn/utils/_param_validation.py``): each calibrator declares, beside
its constructor, what each hyper-parameter may be; one function checks them for every entry point
(``make``, ``set_params``, ``fit``, ``calibrate --param``, ``compare``'s ``ga:budget=5000``), with messages
in Python's words.  A constraint is a Python type, ``None``, an ``Interval`` or an ``Options``; a
hyper-parameter is valid when it satisfies any one of its constraints."""
from __future__ import annotations

import math
from dataclasses import dataclass
from numbers import Integral, Real

from magbench.errors import MAX_SEED, InputError

from .core.evaluator import Budget


def _bound(x: float) -> str:
    """An interval's end as written in a message: integers in full (2**64 - 1 is not 1.84467e+19), floats short."""
    return str(x) if isinstance(x, int) else f"{x:g}"


@dataclass(frozen=True)
class Interval:
    """A number of ``kind`` (``Integral`` or ``Real``) between ``left`` and ``right`` (None: unbounded),
    ``closed`` on "both", "left", "right" or "neither" ends; never NaN or infinite."""

    kind: type
    left: float | None
    right: float | None
    closed: str = "both"

    def accepts(self, value) -> bool:
        if isinstance(value, bool) or not isinstance(value, self.kind):
            return False
        if self.kind is Integral:
            v: float = int(value)  # type: ignore[call-overload]  # an Integral (checked above), compared exactly
        else:
            v = float(value)  # type: ignore[arg-type]  # a Real, checked above
            if not math.isfinite(v):
                return False
        lo_ok = self.left is None or (v >= self.left if self.closed in ("both", "left") else v > self.left)
        hi_ok = self.right is None or (v <= self.right if self.closed in ("both", "right") else v < self.right)
        return lo_ok and hi_ok

    def __str__(self) -> str:
        what = "an int" if self.kind is Integral else "a float"
        lo = "" if self.left is None else ("[" if self.closed in ("both", "left") else "(") + _bound(self.left)
        hi = "" if self.right is None else _bound(self.right) + ("]" if self.closed in ("both", "right") else ")")
        if self.left is not None and self.right is not None:
            return f"{what} in {lo}, {hi}"
        if self.left is not None:
            return f"{what} {'>=' if self.closed in ('both', 'left') else '>'} {_bound(self.left)}"
        if self.right is not None:
            return f"{what} {'<=' if self.closed in ('both', 'right') else '<'} {_bound(self.right)}"
        return what


@dataclass(frozen=True)
class Options:
    """One of a fixed set of values."""

    values: tuple

    def accepts(self, value) -> bool:
        return isinstance(value, type(self.values[0])) and value in self.values

    def __str__(self) -> str:
        return "one of " + ", ".join(repr(v) for v in self.values)


BUDGET = (Interval(Integral, 1, None), Budget, None)
"""An evaluation budget: a number of evaluation-equivalents (an int), a ``Budget``, or None (none)."""
SEED = (Interval(Integral, 0, MAX_SEED), None)
PROBABILITY = [Interval(Real, 0, 1)]
AT_LEAST_ONE = [Interval(Integral, 1, None)]
MAX_POPULATION = 1_000_000
"""The largest population (individuals, ants, archive, contestants) a method takes: a million points of nine
parameters per generation; 1e30 had reached numpy as 'maximum allowed dimension exceeded', and 1e7 with a budget
of 1000 evaluations ran for 133 s."""
POPULATION = [Interval(Integral, 1, MAX_POPULATION)]
NON_NEGATIVE = [Interval(Real, 0, None)]
POSITIVE = [Interval(Real, 0, None, "neither")]
BOX = {"angle_range_rad": [Interval(Real, 0, math.pi / 2, "right")], "scale_range": [Interval(Real, 0, 1, "neither")],
       "offset_range_nT": [*POSITIVE, None]}
"""The population methods' search box (``core.problem.population_box``): angles within +-90 degrees, scales
1 +- ``scale_range`` (positive), offsets within +- ``offset_range_nT`` (None: from the field)."""


def _accepts(constraint, value) -> bool:
    if constraint is None:
        return value is None
    if isinstance(constraint, (Interval, Options)):
        return constraint.accepts(value)
    if isinstance(constraint, type):
        if constraint is float:
            return isinstance(value, Real) and not isinstance(value, bool) and math.isfinite(float(value))
        if constraint is int:
            return isinstance(value, Integral) and not isinstance(value, bool)
        return isinstance(value, constraint)
    raise TypeError(f"unknown constraint {constraint!r}")


def _describe(constraint) -> str:
    if constraint is None:
        return "None"
    if isinstance(constraint, type):
        return {"float": "a float", "int": "an int", "str": "a str", "bool": "a bool"}.get(
            constraint.__name__, f"a {constraint.__name__}")
    return str(constraint)


def validate_params(owner: str, constraints: dict, params: dict) -> None:
    """Raise ``InputError`` for the first hyper-parameter in ``params`` that satisfies none of its
    constraints (names without constraints are not checked here)."""
    for name, value in params.items():
        allowed = constraints.get(name)
        if allowed is None:
            continue
        if not isinstance(allowed, (tuple, list)):
            allowed = (allowed,)
        if any(_accepts(c, value) for c in allowed):
            continue
        wanted = " or ".join(_describe(c) for c in allowed)
        raise InputError(f"{owner}: hyper-parameter {name} must be {wanted}, not {value!r}")


def as_budget(budget) -> Budget:
    """The ``Budget`` a hyper-parameter ``budget`` stands for: an int is a number of evaluation-equivalents."""
    if budget is None:
        return Budget()
    if isinstance(budget, Budget):
        return budget
    if isinstance(budget, Integral) and not isinstance(budget, bool) and int(budget) >= 1:
        return Budget(max_evaluations=int(budget))
    raise InputError(f"budget must be an int >= 1 (evaluation-equivalents) or a Budget, not {budget!r}")

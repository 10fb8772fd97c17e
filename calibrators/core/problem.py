"""What a solver is handed: the ``Problem`` (start, box, rng, termination; no objective, no readings), its
closed-form variant ``ReadingsProblem``, the ``SolveOutput`` it returns, and the one bounds function."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from magbench.numerics import median
from magbench.simulate.dataset import readonly_copy
from magbench.simulate.sensor import FREE

from .evaluator import Evaluator
from .loop import Termination


class Problem:
    """What a calibrator's ``_solve`` (a strategy, ``core/loop.py``) is handed (pymoo's algorithm sees only
    its problem): the model, the start point ``x0``, the search box ``lower``/``upper`` (from
    ``search_bounds``, the one bounds function), the rng and seed, the ``termination`` the framework
    enforces, and what the counter knows (read only).  It holds no readings and cannot evaluate anything:
    a strategy asks (``loop.values``, ``loop.normal_equations``, ``loop.START``, ...) and the framework
    evaluates, counts and tells.
    """

    __slots__ = ("model", "x0", "lower", "upper", "_rng", "seed", "termination", "_evaluator")

    def __init__(self, evaluator: Evaluator, model: str, x0: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                 rng: np.random.Generator | None, seed: int | None, termination: Termination | None = None):
        self._evaluator = evaluator
        self.model = model
        self.x0 = readonly_copy(x0)
        self.lower = readonly_copy(lower)
        self.upper = readonly_copy(upper)
        self._rng = rng
        self.seed = seed
        self.termination = termination if termination is not None else Termination(budget=evaluator.budget)

    def __getattr__(self, name: str):
        if name in _ASKED_NOW:  # the counted functions a Problem offered before magbench 0.3
            raise AttributeError(f"Problem has no {name!r}: a calibrator's _solve is a strategy that asks the "
                                 f"framework, e.g. `f = yield loop.{_ASKED_NOW[name]}` (calibrators.core.loop; "
                                 "README, 'Your own calibrator')")
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @property
    def rng(self) -> np.random.Generator:
        """The run's generator: the one given, else ``np.random.default_rng(seed)`` made when first asked for (a
        deterministic method never pays for it)."""
        if self._rng is None:
            self._rng = np.random.default_rng(self.seed)
        return self._rng

    @property
    def n_points(self) -> int:
        """How many readings the objective sums over (their number, not their values)."""
        return self._evaluator.n_points

    # what the counter knows
    @property
    def n_params(self) -> int:
        return len(self.x0)

    @property
    def n_evaluations(self) -> int:
        return self._evaluator.n_evaluations

    @property
    def jacobian_cost(self) -> int:
        """Evaluation-equivalents one Jacobian or gradient costs (the number of free parameters)."""
        return self._evaluator.jacobian_cost

    @property
    def evaluations_left(self) -> int | None:
        """Evaluations the budget still allows (None: no evaluation budget)."""
        return self._evaluator.evaluations_left

    @property
    def max_time_s(self) -> float | None:
        return self._evaluator.budget.max_time_s

    @property
    def best_x(self) -> np.ndarray | None:
        """The best point evaluated so far (None before the first evaluation)."""
        x = self._evaluator.best_x
        return None if x is None else x.copy()


_ASKED_NOW = {"values": "values(x)", "value": "value(x)", "residuals": "residuals(x)", "jacobian": "jacobian(x)",
              "gradient": "gradient(x)", "normal_equations": "normal_equations(x)", "algebraic_start": "START"}


class ReadingsProblem(Problem):
    """What a closed-form calibrator's ``_solve`` sees (one that declares ``closed_form = True``): the
    ``Problem`` plus read-only copies of the readings ``raw_nT`` (n, 3) and reference ``f_ref_nT`` (n,).
    Its rows report the evaluation mode ``closed-form``: a count of objective evaluations does not
    describe its cost."""

    __slots__ = ("raw_nT", "f_ref_nT")

    def __init__(self, evaluator, model, x0, lower, upper, rng, seed, raw_nT, f_ref_nT, termination=None):
        super().__init__(evaluator, model, x0, lower, upper, rng, seed, termination)
        self.raw_nT = readonly_copy(raw_nT)
        self.f_ref_nT = readonly_copy(f_ref_nT)


@dataclass(frozen=True)
class SolveOutput:
    x: Any  # the parameter vector; anything else (None, a wrong shape) is caught by fit
    status: str = "converged"
    message: str = ""
    nit: int = 0
    success: bool = True
    extra: dict = field(default_factory=dict)


PHYSICAL_BOX = {"angle_range_rad": 0.5, "scale_min": 0.5, "scale_max": 2.0, "offset_fraction": 2.0}
"""Where a sensor can physically be: angles within 0.5 rad, scales 0.5..2, offsets within twice the field.
Scalar data admit degenerate 'far-centre' solutions (huge scale and offset that shrink the residual
below the noise) when the attitudes cover few directions; this box excludes them."""

POPULATION_OFFSET_FRACTION = 0.1
"""Offsets the population methods search: +-10 % of the reference magnitude unless given in nT."""


def search_bounds(model: str, f_ref_nT, angle_range_rad: float, scale_min: float = 1.0, scale_max: float = 1.0,
                  offset_range_nT: float | None = None, offset_fraction: float = POPULATION_OFFSET_FRACTION
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The one bounds function: the search box ``(lower, upper)`` every ``_solve`` is handed.

    Angles +-``angle_range_rad`` (seed 000, section 2.2 step 1: 0.1 rad), scales in [``scale_min``,
    ``scale_max``] and offsets +-``offset_range_nT`` (default ``offset_fraction`` times the median reference
    magnitude; ``f_ref_nT`` may be that median already, a number), for the entries the model estimates.  Each
    calibrator names its box in ``search_box()``."""
    lo = [-angle_range_rad] * 3
    hi = [angle_range_rad] * 3
    if model != "angles":
        if offset_range_nT is None:
            typical = float(f_ref_nT) if np.ndim(f_ref_nT) == 0 else median(f_ref_nT)
            offset = offset_fraction * typical
        else:
            offset = offset_range_nT
        lo += [scale_min] * 3 + [-offset] * 3
        hi += [scale_max] * 3 + [offset] * 3
        free = list(FREE[model])
        lo, hi = [lo[i] for i in free], [hi[i] for i in free]
    return np.array(lo, dtype=float), np.array(hi, dtype=float)


def population_box(cal) -> dict:
    """``search_box()`` of the population methods, from their hyper-parameters ``angle_range_rad``,
    ``scale_range`` (scale 1 +- it) and ``offset_range_nT``."""
    return {"angle_range_rad": cal.angle_range_rad, "scale_min": 1.0 - cal.scale_range,
            "scale_max": 1.0 + cal.scale_range, "offset_range_nT": cal.offset_range_nT}

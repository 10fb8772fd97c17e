"""magbench's calibrators: one interface, one shared objective and counter, a registry.

>>> from magbench.calibrators import make
>>> result = make("lsq", model="nine").fit(dataset)          # doctest: +SKIP
>>> result = make("lsq", model="auto").fit(raw_nT, field="auto")  # (N, 3) array, no reference  # doctest: +SKIP
>>> open("cal.json", "w").write(result.to_json())             # doctest: +SKIP
>>> load_calibration("cal.json").correct(other_raw_nT)        # doctest: +SKIP
"""
from magbench.simulate.sensor import ErrorParams

from .artifacts import Calibration, export, load_calibration
from .base import CalibrationResult, Calibrator
from .checks import check_calibrator
from .core import loop
from .core.evaluator import Budget, BudgetExhausted, Evaluator, audit_evaluations
from .core.loop import Termination
from .core.objective import ScalarObjective
from .core.problem import Problem, ReadingsProblem, SolveOutput, search_bounds
from .methods._gakernel import prefer_compiled as prefer_compiled_kernels
from .modelselect import choose_model  # noqa: F401  (installs the chooser behind model='auto')
from .registry import ENTRY_POINT_GROUP, available, get, make, register

__all__ = [
    "ErrorParams", "CalibrationResult", "Calibrator", "Problem", "ReadingsProblem",
    "SolveOutput", "search_bounds", "Budget", "BudgetExhausted", "Evaluator", "audit_evaluations",
    "ScalarObjective", "ENTRY_POINT_GROUP", "available", "get", "make", "register",
    "check_calibrator", "Calibration", "load_calibration", "export", "prefer_compiled_kernels", "loop",
    "Termination",
]



"""The core room: the shared objective (seed 000, eq. 3), the one evaluator that counts every evaluation
against the budget, the loop that owns the search (strategies ask, the framework evaluates and tells) with
its one termination object, the problem a strategy is handed, and the closed-form quadric algebra.  It
imports no calibration method."""
from . import loop
from .evaluator import Budget, BudgetExhausted, Evaluator, audit_evaluations
from .loop import Ask, Termination, drive
from .objective import ScalarObjective
from .problem import Problem, ReadingsProblem, SolveOutput, search_bounds

__all__ = ["Budget", "BudgetExhausted", "Evaluator", "audit_evaluations", "ScalarObjective", "Problem",
           "ReadingsProblem", "SolveOutput", "search_bounds", "loop", "Ask", "Termination", "drive"]

"""``sphere``: the offset-only calibration by the least-squares sphere (the hard-iron fit of
CoMPASLab's magyc ``sphere`` and of MATLAB magcal's ``eye`` option): the readings' centre is the offset;
scale and non-orthogonality are taken as ideal.  The linear form ``|r|² = 2 r·c + (R² - |c|²)``
(e.g. Vasconcelos et al. 2011, eq. 8) is solved in closed form."""
from __future__ import annotations

from ..base import Calibrator
from ..core.algebra import sphere_fit
from ..core.problem import ReadingsProblem, SolveOutput


class SphereFit(Calibrator):
    """Least-squares sphere: offsets only, closed form, no iterations."""

    name = "sphere"
    summary = "least-squares sphere: offsets only (magyc sphere, magcal eye), closed form"
    supported_models = ("offset",)
    check_tolerance = {"angle_rad": 1e-4, "scale": 1e-4, "offset_nT": 1.0}
    closed_form = True

    def __init__(self, model: str = "offset", seed: int | None = 0, budget=None):
        super().__init__(model=model, seed=seed, budget=budget)

    def _solve(self, problem: ReadingsProblem) -> SolveOutput:
        centre, radius = sphere_fit(problem.raw_nT)
        return SolveOutput(centre, status="closed_form", message=f"algebraic sphere, radius {radius:.6g} nT")

"""``twostep``: TWOSTEP, the attitude-independent calibration of Alonso and Shuster (2002): "TWOSTEP: a fast
robust algorithm for attitude-independent magnetometer-bias determination", J. Astronaut. Sci. 50(4),
433-451, and its complete (nine-parameter) form, "Complete linear attitude-independent magnetometer
calibration", J. Astronaut. Sci. 50(4), 477-490.

The measurement is ``z_k = |B_k|² - |H_k|²`` (reading B, reference magnitude |H| = F).  With the
correction ``H = M (B - o)`` and ``W = M^T M = I + E`` it is ``z_k = -B_k^T E B_k + 2 B_k^T c - |c|_W``,
``c = W o``: linear in (E, c) but for the last term, which the *centred* first step removes by subtracting
the means (their eq. 14-18 for the bias; eq. 23-28 for E and c), so that one linear solve gives the
centred estimate (``centred_estimate`` states how the gain is recovered when F is constant).  The second
step corrects the centring's approximation by Gauss-Newton iterations on the full nonlinear model from that
start; here they run on the framework's counted scalar residual
``|M (B - o)| - F`` (each iteration one counted evaluation and one Jacobian, charged p evaluations), the
first-order form of ``z_k / (2 F_k)``, so that the second step's cost is counted like every other method's.
"""
from __future__ import annotations

import numpy as np

from magbench.errors import FitError
from magbench.numerics import lm_iterations
from magbench.simulate.sensor import ErrorParams

from ..base import Calibrator
from ..core import loop
from ..core.evaluator import BudgetExhausted
from ..core.problem import ReadingsProblem, SolveOutput
from ..params import AT_LEAST_ONE, NON_NEGATIVE


def centred_estimate(raw_nT: np.ndarray, f_ref_nT: np.ndarray, model: str) -> np.ndarray:
    """TWOSTEP's first (centred) step: the model's parameter vector (``nine`` or ``offset``).

    Centring removes the constant ``|c|_W`` and, where the reference is constant, with it the overall gain:
    the centred equations determine (W, c) up to a common factor.  W is therefore solved with its trace
    fixed (a linear constraint), the offset is ``o = W^-1 c``, and the gain is the least-squares factor that
    makes ``(B - o)^T W (B - o)`` match ``F²``."""
    b = np.asarray(raw_nT, dtype=float)
    f = np.broadcast_to(np.asarray(f_ref_nT, dtype=float), (len(b),))
    scale = float(np.median(f))
    bn, fn = b / scale, f / scale  # conditioning: units of the field
    x, y, w = bn.T
    f2 = fn * fn
    if model == "offset":  # W = I: |B|² - F² = 2 B.o - |o|², centred
        design = np.column_stack([2 * x, 2 * y, 2 * w])
        z = np.sum(bn * bn, axis=1) - f2
        theta, *_ = np.linalg.lstsq(design - design.mean(axis=0), z - z.mean(), rcond=None)
        if not np.all(np.isfinite(theta)):
            raise FitError("the readings do not determine TWOSTEP's centred estimate")
        return theta * scale
    # B^T W B - 2 B^T c - mu F² = const, centred, with trace W = 3: w_xx = a, w_yy = b, w_zz = 3 - a - b
    cols = [x * x - w * w, y * y - w * w, 2 * x * y, 2 * x * w, 2 * y * w, -2 * x, -2 * y, -2 * w]
    varies = np.ptp(f2) > 1e-9
    if varies:
        cols.append(-f2)
    design = np.column_stack(cols)
    rhs = -3.0 * w * w
    theta, *_ = np.linalg.lstsq(design - design.mean(axis=0), rhs - rhs.mean(), rcond=None)
    if not np.all(np.isfinite(theta)):
        raise FitError("the readings do not determine TWOSTEP's centred estimate")
    a, bb, h, g, fz = theta[:5]
    wmat = np.array([[a, h, g], [h, bb, fz], [g, fz, 3.0 - a - bb]])
    if np.any(np.linalg.eigvalsh(wmat) <= 0):
        raise FitError("TWOSTEP's centred estimate is not positive definite (too little attitude coverage)")
    offset_n = np.linalg.solve(wmat, theta[5:8])
    d = bn - offset_n
    q = np.einsum("ij,jk,ik->i", d, wmat, d)
    gain = float(q @ f2 / (q @ q))
    if not gain > 0:
        raise FitError("TWOSTEP's centred estimate has no positive gain")
    m = np.linalg.cholesky(gain * wmat).T  # any M with M^T M = W: the canonical form fixes the rotation
    return ErrorParams.from_correction(m, offset_n * scale).to_vector("nine")


class TwoStep(Calibrator):
    """TWOSTEP (Alonso & Shuster 2002): the centred linear estimate, then Gauss-Newton on the counted
    scalar residual."""

    name = "twostep"
    summary = "TWOSTEP (Alonso & Shuster 2002): centred linear estimate + Gauss-Newton"
    supported_models = ("offset", "nine")
    check_tolerance = {"angle_rad": 2e-5, "scale": 2e-5, "offset_nT": 0.5}
    closed_form = True  # its first step reads the readings; the second is counted

    _parameter_constraints = {**Calibrator._parameter_constraints, "max_iterations": AT_LEAST_ONE, "tol": NON_NEGATIVE}

    def __init__(self, model: str = "nine", seed: int | None = 0, budget=None, max_iterations: int = 50,
                 tol: float = 1e-12):
        super().__init__(model=model, seed=seed, budget=budget)
        self.max_iterations = max_iterations
        self.tol = tol

    def termination_settings(self) -> dict:
        return {"tol": None, "tol_meaning": f"the Gauss-Newton step's own: the sum of squares or the step changes by "
                                            f"less than {self.tol:g} relative, at most {self.max_iterations} steps"}

    def _solve(self, problem: ReadingsProblem):
        x1 = centred_estimate(problem.raw_nT, problem.f_ref_nT, self.model)
        x1 = np.clip(x1, problem.lower, problem.upper)
        try:
            x, _, calls = yield from loop.asks("normal_equations", lm_iterations(
                x1, problem.lower, problem.upper, tol=self.tol, max_iter=self.max_iterations))
        except BudgetExhausted:  # no budget for the second step: the best point it evaluated, else the first step
            best = problem.best_x
            return SolveOutput(x1 if best is None else best, status="budget",
                               message="stopped by the budget in the second step")
        return SolveOutput(x, status="converged", message=f"centred estimate + {calls} Gauss-Newton evaluations",
                           nit=calls)

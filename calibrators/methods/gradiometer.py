"""Calibration of seed 001's two-fluxgate magnetic gradiometer by gradient measurement.

Seed 001: Jin Huanghuang, Zhuang Zhihong, Wang Hong, "基于磁梯度测量的磁校准方法", Aero Weaponry
2024 (1): 117-121.  Equation numbers below are the paper's; the sensor model and the simulator are in
``magbench.simulate.gradiometer``, the experiment in ``magbench.benchmarks.gradiometer``.

With a zero geomagnetic gradient the calibrated gradient of eq. 6

    Gr = M1 (B1m - B1h) - M2 (B2m - B2h)

is zero at every attitude theta (eq. 7-8): 24 unknowns (M1, M2, B1h, B2h; eq. 9-10).

Procedure (section 3)
---------------------
(a) one ellipsoid fit per sensor (``ellipsoid_calibration``), scaled to the constant reference
    magnitude, which gives ``M_i`` up to a rotation and ``B_ih``;
(b) eq. 8 split into its three rows (eq. 11); row i of M1 and row i of M2 (6 genes) found by its own
    genetic algorithm, 3 GAs in all (``ga_gradient_calibration``); the hard-iron vectors are the
    ellipsoid fit's (point (2)); fitness = modulus of the 12-term vector of eq. 11's left side at 12
    attitudes picked from the record (point (3)); initial population in a neighbourhood of the
    ellipsoid fit's matrices.

The GA operators are not given in the paper.  Each row GA is the project's real-coded GA loop
(``calibrators.genetic.real_ga``) on a ``Problem`` whose objective (``RowObjective``, eq. 11) is counted
by an ``Evaluator``: tournament selection and BLX-alpha crossover as in ``RealGA``, the Gaussian mutation
shrinking over the run of ``ElitistRealGA``, elitism; a whole population is evaluated in one numpy
product.  Also ours, not the paper's: a closed-form least-squares reference (``lsq_reference``), the
single-sensor fits plus the best relative rotation (``rotated_ellipsoid``) and the gauge fix of the GA's
answer (``gauge_fixed``): the gradient condition fixes M1 and M2 only up to a common 3x3 matrix (any
``(C M1, C M2)`` also satisfies eq. 7).
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, ClassVar

import numpy as np

from magbench.errors import InputError
from magbench.simulate.dataset import readonly_copy
from magbench.simulate.gradiometer import GradiometerParams, check_int, check_nonneg
from magbench.simulate.sensor import ul_factor

from ..core.algebra import fit_ellipsoid
from ..core.evaluator import Budget, BudgetExhausted, Evaluator
from ..core.loop import Termination, drive
from ..core.problem import Problem
from .genetic import ElitistRealGA, RealGA, real_ga

ROW_MODEL = "gradient_row"
"""``Problem.model`` of a row GA: the 6 genes (m_i1, m_i2, m_i3, m'_i1, m'_i2, m'_i3) of eq. 11."""

N_ROWS = 3
"""Eq. 11, i = 1, 2, 3: one GA per row of M1 and M2."""

PAPER_ROTATIONS = 12
"""Section 3, point (3): the fitness uses 12 attitudes picked from the record."""

MIN_ROTATIONS = 3
"""Fewest attitudes a row fitness may use (three independent field directions)."""

DEFAULT_NEIGHBOURHOOD = 0.02
"""Half-width of the search box (and initial population) around the ellipsoid fit's matrix rows (ours;
point (3) says "an appropriate neighbourhood")."""

MIN_POPULATION = 4
"""Smallest population ``real_ga`` runs (two pairs of parents)."""

MUTATION_SHRINK_POWER = 2.0
"""The Gaussian mutation's sigma shrinks as (1 - t)^2 over the run (ours)."""

GA_DEFAULTS: dict[str, Any] = {
    "population": 60,
    "generations": 150,
    "n_rotations": PAPER_ROTATIONS,
    "neighbourhood": DEFAULT_NEIGHBOURHOOD,
    "pc": 0.9,
    "pm": 0.2,
    "blx_alpha": 0.3,
    "mutation_scale": 0.1,   # Gaussian mutation sigma, fraction of the box, shrinking as (1 - t)^2
    "tournament": 2,
    "elitism": 2,
}
"""The options of ``ga_gradient_calibration`` (and of the experiment): ``RowGA``'s settings plus the
number of attitudes in the fitness and the neighbourhood."""


# --------------------------------------------------------------------------------------------------
# The calibration and the simple ones
# --------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class GradientCalibration:
    """M1, M2, B1h, B2h of eq. 10: ``B_ir = M_i (B_im - B_ih)``."""

    m1: np.ndarray
    m2: np.ndarray
    h1_nT: np.ndarray
    h2_nT: np.ndarray
    method: str
    info: dict = field(default_factory=dict)

    def __post_init__(self):
        for name in ("m1", "m2", "h1_nT", "h2_nT"):
            object.__setattr__(self, name, readonly_copy(getattr(self, name)))

    def corrected(self, raw1_nT, raw2_nT) -> tuple[np.ndarray, np.ndarray]:
        """Eq. 10: both sensors' readings (n, 3) in the common frame."""
        return (np.asarray(raw1_nT) - self.h1_nT) @ self.m1.T, (np.asarray(raw2_nT) - self.h2_nT) @ self.m2.T

    def gradient(self, raw1_nT, raw2_nT) -> np.ndarray:
        """Left side of eq. 8 at each sample, shape (n, 3)."""
        b1, b2 = self.corrected(raw1_nT, raw2_nT)
        return b1 - b2

    def as_dict(self) -> dict:
        return {"method": self.method, "m1": self.m1.tolist(), "m2": self.m2.tolist(),
                "b1h_nT": self.h1_nT.tolist(), "b2h_nT": self.h2_nT.tolist()}


def uncalibrated() -> GradientCalibration:
    """No calibration: ``B_ir = B_im``."""
    return GradientCalibration(np.eye(3), np.eye(3), np.zeros(3), np.zeros(3), "raw")


def true_calibration(params: GradiometerParams) -> GradientCalibration:
    """The exact solution of eq. 7 for simulated sensors: M1, M2 of eq. 6-7 and the true B1h, B2h."""
    return GradientCalibration(params.m1, params.m2, params.h1_nT, params.h2_nT, "truth")


def ellipsoid_calibration(raw1_nT, raw2_nT, f_ref_nT: float) -> GradientCalibration:
    """Step (a): one Li-Griffiths ellipsoid fit per sensor (``fit_ellipsoid``), scaled to the constant
    ``f_ref_nT`` that a single-sensor method assumes.  ``W = F^2 A = M^T M`` fixes M only up to a
    rotation; we report the canonical lower-triangular factor (CONTRACT section 1), i.e. each sensor
    in its own frame: a single-sensor fit cannot see R1a, R2a nor Rg (eq. 6)."""
    f = float(f_ref_nT)
    out = []
    for raw in (raw1_nT, raw2_nT):
        shape, center = fit_ellipsoid(raw)
        out.append((ul_factor(f * f * shape), center))
    return GradientCalibration(out[0][0], out[1][0], out[0][1], out[1][1], "ellipsoid")


def best_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Orthogonal Procrustes: the rotation Q minimizing ||Q a - b|| (a, b of shape (3, k))."""
    u, _, vt = np.linalg.svd(b @ a.T)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def lsq_reference(raw1_nT, raw2_nT, start: GradientCalibration) -> GradientCalibration:
    """Ours, not the paper's: sensor 1 as ``start`` (its ellipsoid fit) defines the common frame; M2 and
    B2h by linear least squares of ``M1 (B1m - B1h) = M2 B2m - M2 B2h`` on the whole record (closed
    form, deterministic; eq. 7 with the gauge fixed)."""
    raw1, raw2 = np.asarray(raw1_nT, dtype=float), np.asarray(raw2_nT, dtype=float)
    y = (raw1 - start.h1_nT) @ start.m1.T
    x = np.column_stack([raw2, np.ones(len(raw2))])
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    m2 = coef[:3].T
    h2 = -np.linalg.solve(m2, coef[3])
    return GradientCalibration(start.m1, m2, start.h1_nT, h2, "lsq_ours")


def rotated_ellipsoid(ell: GradientCalibration, raw1_nT, raw2_nT) -> GradientCalibration:
    """Ours, a diagnostic: the single-sensor ellipsoid fits plus the best relative rotation between the
    two corrected sensors (orthogonal Procrustes over the record).  It separates what the single-sensor
    fits cannot see (the alignment Rg, R1a, R2a of eq. 6) from what the field fluctuation does to them."""
    b1, b2 = ell.corrected(raw1_nT, raw2_nT)
    q = best_rotation(b2.T, b1.T)
    return GradientCalibration(ell.m1, q @ ell.m2, ell.h1_nT, ell.h2_nT, "ellipsoid_rotated_ours")


def gauge_fixed(cal: GradientCalibration, reference: GradientCalibration) -> GradientCalibration:
    """Ours, not the paper's: eq. 7 holds for ``(C M1, C M2)`` with any 3x3 ``C``, so each of the paper's
    GAs lands anywhere on a 3-dimensional valley of its 6-gene box and the absolute scale and frame of
    its M1, M2 drift by up to the neighbourhood (+-2 %, i.e. up to ~1000 nT on each sensor's field).
    Re-expressing the solution in ``reference``'s sensor-1 matrix, ``C = M1_ref M1^-1``, keeps the
    gradient (multiplied by C ~ I) and restores the single-sensor fit's absolute calibration."""
    c = reference.m1 @ np.linalg.inv(cal.m1)
    return GradientCalibration(reference.m1, c @ cal.m2, cal.h1_nT, cal.h2_nT, cal.method + "_gauge_fixed_ours",
                               dict(cal.info))


# --------------------------------------------------------------------------------------------------
# The paper's three 6-gene GAs (section 3, eq. 11)
# --------------------------------------------------------------------------------------------------

class RowObjective:
    """Eq. 11 at the chosen attitudes, the objective of each row GA (the same for the three rows: only
    their search boxes differ).

    Genes x = (m_i1, m_i2, m_i3, m'_i1, m'_i2, m'_i3); residuals ``r_j = x[:3]·d1_j - x[3:]·d2_j`` over
    the k attitudes, ``d_i = B_im - B_ih`` (k, 3); ``F = mean(r_j²)``, the convention of every objective
    the ``Evaluator`` counts.  The paper's fitness (point (3)) is the modulus ``|r| = sqrt(k F)``
    (``modulus``), a monotone function of F: selection and elitism rank both alike.
    """

    n_params = 6

    def __init__(self, d1_nT: np.ndarray, d2_nT: np.ndarray):
        self._design = np.ascontiguousarray(np.hstack([d1_nT, -np.asarray(d2_nT)]))  # (k, 6): r = design @ x
        self.k = self._design.shape[0]

    def values(self, x: np.ndarray) -> np.ndarray:
        """F for a population (m, 6) -> (m,), one matrix product."""
        r = x @ self._design.T
        return np.einsum("mk,mk->m", r, r) / self.k

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Eq. 11's left side at each attitude, (k,)."""
        return self._design @ np.asarray(x, dtype=float)

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """d r / d x (k, 6): eq. 11 is linear in the genes."""
        return self._design.copy()

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dF/dx = (2/k) J^T r."""
        return 2.0 * self._design.T @ self.residuals(x) / self.k

    def modulus(self, f) -> np.ndarray:
        """The paper's fitness (point (3)), nT, from F."""
        return np.sqrt(self.k * np.asarray(f, dtype=float))


@dataclass(frozen=True)
class RowGA:
    """Settings and operators of each of the three 6-gene GAs, run by ``genetic.real_ga`` (the loop of
    ``RealGA``).  Seed 001 names the steps of Fig. 5 (initial population, evaluation, selection,
    crossover, mutation, stop) but not the operators; ours: ``tournament`` selection and BLX-alpha
    crossover (``blx_alpha``) with probability ``pc`` as in ``RealGA``, Gaussian mutation of a fraction
    ``pm`` of the children with sigma = ``mutation_scale`` of the box x (1 - t)^2 as in ``ElitistRealGA``,
    the ``elitism`` best kept, ``generations`` generations of ``population`` individuals."""

    population: int = GA_DEFAULTS["population"]
    generations: int = GA_DEFAULTS["generations"]
    pc: float = GA_DEFAULTS["pc"]
    pm: float = GA_DEFAULTS["pm"]
    blx_alpha: float = GA_DEFAULTS["blx_alpha"]
    mutation_scale: float = GA_DEFAULTS["mutation_scale"]
    tournament: int = GA_DEFAULTS["tournament"]
    elitism: int = GA_DEFAULTS["elitism"]

    name: ClassVar[str] = "gradiometer row GA"
    nonuniform_b: ClassVar[float] = MUTATION_SHRINK_POWER
    _select = RealGA._select
    _crossover = RealGA._crossover
    _mutate = ElitistRealGA._mutate

    def __post_init__(self):
        for key, minimum in (("population", MIN_POPULATION), ("generations", 1), ("tournament", 1), ("elitism", 0)):
            object.__setattr__(self, key, check_int(getattr(self, key), key, minimum))
        for key in ("pc", "pm", "blx_alpha", "mutation_scale"):
            object.__setattr__(self, key, check_nonneg(getattr(self, key), key))
        if self.elitism >= self.population:
            raise InputError(f"elitism must be below the population ({self.population}), got {self.elitism}")
        if self.tournament > self.population:
            raise InputError(f"tournament must not exceed the population, got {self.tournament}")
        if self.pc > 1 or self.pm > 1:
            raise InputError(f"pc and pm are probabilities in [0, 1], got pc={self.pc}, pm={self.pm}")


def check_ga_options(options: dict, n_points: int) -> dict:
    """``GA_DEFAULTS`` updated by ``options``, checked (``InputError`` on unknown keys and bad values)
    for a record of ``n_points`` attitudes."""
    unknown = sorted(set(options) - set(GA_DEFAULTS))
    if unknown:
        raise InputError(f"unknown GA option(s) {', '.join(unknown)}; expected some of {', '.join(GA_DEFAULTS)}")
    ga = {**GA_DEFAULTS, **options}
    keys = [f.name for f in fields(RowGA)]
    settings = RowGA(**{k: ga[k] for k in keys})
    ga.update({k: getattr(settings, k) for k in keys})
    ga["n_rotations"] = _check_rotations(ga["n_rotations"], n_points)
    ga["neighbourhood"] = _check_neighbourhood(ga["neighbourhood"])
    return ga


def _check_rotations(n_rotations, n_points: int) -> int:
    n_rotations = check_int(n_rotations, "n_rotations", 1)
    if not MIN_ROTATIONS <= n_rotations <= n_points:
        raise InputError(f"n_rotations must be between {MIN_ROTATIONS} and the number of points ({n_points}), "
                         f"got {n_rotations}")
    return n_rotations


def _check_neighbourhood(neighbourhood) -> float:
    neighbourhood = check_nonneg(neighbourhood, "neighbourhood")
    if not neighbourhood > 0:
        raise InputError(f"neighbourhood must be positive, got {neighbourhood}")
    return neighbourhood


@dataclass(frozen=True)
class _RowResult:
    x: np.ndarray
    best_f: float          # F of the best individual (nan: the row was not searched)
    history: list          # best F after each generation
    status: str


def _row_share(counter: Evaluator, rows_left: int) -> int | None:
    """The evaluations one of the ``rows_left`` remaining GAs may spend: an equal share of what the
    calibration's budget has left (None: no evaluation budget)."""
    left = counter.evaluations_left
    return None if left is None else left // rows_left


def _solve_row(counter: Evaluator, settings: RowGA, x0: np.ndarray, neighbourhood: float,
               rng: np.random.Generator, share: int | None) -> _RowResult:
    """One GA of eq. 11 within +-``neighbourhood`` of ``x0``, counted by ``counter`` through a row
    evaluator (its own best point and budget share)."""
    if share == 0:
        return _RowResult(x0, float("nan"), [], "not run: budget spent")
    row_counter = Evaluator(counter, Budget(max_evaluations=share) if share is not None else None)
    termination = Termination(budget=row_counter.budget, max_iterations=int(settings.generations))
    problem = Problem(row_counter, ROW_MODEL, x0, x0 - neighbourhood, x0 + neighbourhood, rng, None, termination)
    try:
        out, _ = drive(real_ga(problem, settings), row_counter, termination)
        x, status = out.x, "max_generations"
    except BudgetExhausted:
        x, status = row_counter.best_x, "budget"  # type: ignore[assignment]  # None only before any evaluation
        if row_counter.evaluations_left != 0:  # the calibration's budget (time) ran out, not the share
            status = "budget: stopped"
    if x is None:
        return _RowResult(x0, float("nan"), [], status)
    return _RowResult(np.asarray(x, dtype=float), row_counter.best_f, [b for _, b, _ in row_counter.trace], status)


def ga_gradient_calibration(raw1_nT, raw2_nT, start: GradientCalibration, rng: np.random.Generator,
                            n_rotations: int = PAPER_ROTATIONS, neighbourhood: float = DEFAULT_NEIGHBOURHOOD,
                            budget: Budget | None = None, **ga) -> GradientCalibration:
    """Step (b), seed 001 section 3: eq. 8 split into its three rows (eq. 11), each solved by its own
    6-gene GA (``RowGA``, options ``ga``): row i of M1 and row i of M2, the hard-iron vectors fixed at
    ``start``'s (point (2)), fitness = modulus of eq. 11's left side at ``n_rotations`` attitudes picked
    at random from the record (point (3): 12), initial population and search box within
    +-``neighbourhood`` of ``start``'s matrix rows.

    Every fitness evaluation goes through one ``Evaluator``, whose count is ``info["n_evaluations"]``;
    ``budget`` bounds the three GAs together (each gets an equal share of the evaluations left when it
    starts).  A row whose GA is not run keeps ``start``'s values."""
    settings = RowGA(**ga)
    raw1, raw2 = np.asarray(raw1_nT, dtype=float), np.asarray(raw2_nT, dtype=float)
    n_rotations = _check_rotations(n_rotations, len(raw1))
    neighbourhood = _check_neighbourhood(neighbourhood)
    pick = np.sort(rng.choice(len(raw1), size=n_rotations, replace=False))
    objective = RowObjective(raw1[pick] - start.h1_nT, raw2[pick] - start.h2_nT)
    counter = Evaluator(objective, budget)
    m1, m2 = np.array(start.m1), np.array(start.m2)
    rows, stopped = [], False
    for i in range(N_ROWS):  # three independent GAs (eq. 11, i = 1, 2, 3)
        x0 = np.concatenate([start.m1[i], start.m2[i]])
        share = 0 if stopped else _row_share(counter, N_ROWS - i)
        row = _solve_row(counter, settings, x0, neighbourhood, rng, share)
        stopped = stopped or row.status == "budget: stopped"
        m1[i], m2[i] = row.x[:3], row.x[3:]
        rows.append(row)
    info = {"n_evaluations": counter.n_evaluations,
            "best_fitness_nT": [float(objective.modulus(r.best_f)) for r in rows],
            "rotations": pick.tolist(),
            "history": [objective.modulus(r.history).tolist() for r in rows],
            "status": [r.status for r in rows]}
    return GradientCalibration(m1, m2, start.h1_nT, start.h2_nT, "ga", info)

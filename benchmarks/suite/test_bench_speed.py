"""Speed targets of the calibrators issue, measured side by side with pytest-benchmark.

Run with ``python -m magbench.benchmarks.speed`` (writes results/speed.md and results/benchmarks/speed.json).
Peers (PyGAD, mealpy) are development-only: ``pip install pygad && pip install --no-deps mealpy opfunu``
(mealpy's metadata pins numpy<=1.26, which NLopt 2.11 cannot use; it runs on numpy 2).
"""
import numpy as np
import pytest

from magbench.calibrators import make
from magbench.calibrators.base import population_box, search_bounds
from magbench.calibrators.objective import ScalarObjective

GENERATIONS = 1000
POPULATION = 80
ACO_ITERATIONS = 1000  # 50 + 20 * 1000 = 20,050 evaluations for both ant colonies


def _box(data):
    """The very box ga's _solve is handed (angles +-0.1 rad, scale 1 +-0.1, offsets +-10 % of F), for the peers."""
    return search_bounds("nine", data.f_ref_nT, **population_box(make("ga", model="nine")))


@pytest.mark.benchmark(group="aga: seed 000 configuration, 80 x 1000 generations, 36 points, angles")
def test_aga_paper_configuration(benchmark, lu2014):
    cal = make("aga", model="angles", max_generations=GENERATIONS)
    res = benchmark.pedantic(cal.fit, args=(lu2014,), rounds=20, iterations=1, warmup_rounds=1)
    assert res.n_evaluations == POPULATION * GENERATIONS
    benchmark.extra_info.update(evaluations=res.n_evaluations, rms_after_nT=res.rms_after_nT)


@pytest.mark.benchmark(group="ga vs PyGAD: 80 x 1000 generations, sphere9 (300 points, nine)")
def test_ga_magbench(benchmark, sphere9):
    cal = make("ga", model="nine", population=POPULATION, generations=GENERATIONS)
    res = benchmark.pedantic(cal.fit, args=(sphere9,), rounds=10, iterations=1, warmup_rounds=1)
    benchmark.extra_info.update(evaluations=res.n_evaluations, rms_after_nT=res.rms_after_nT)


def _pygad(benchmark, sphere9, batch: bool, rounds: int):
    """PyGAD with the same population, generations, data, box and objective (the population form)."""
    pygad = pytest.importorskip("pygad")
    obj = ScalarObjective(sphere9.raw_nT, sphere9.f_ref_nT, "nine")
    lo, hi = _box(sphere9)
    span = hi - lo

    def fitness(ga, solutions, idx):
        return -obj.values(lo + np.atleast_2d(solutions) * span, exact=False)

    def fitness_one(ga, solution, idx):
        return float(fitness(ga, solution, idx)[0])

    def run():
        ga = pygad.GA(num_generations=GENERATIONS - 1, num_parents_mating=POPULATION // 2,
                      fitness_func=fitness if batch else fitness_one, fitness_batch_size=POPULATION if batch else None,
                      sol_per_pop=POPULATION, num_genes=9, init_range_low=0.0, init_range_high=1.0,
                      gene_space={"low": 0.0, "high": 1.0}, random_seed=0, suppress_warnings=True)
        ga.run()
        return ga

    ga = benchmark.pedantic(run, rounds=rounds, iterations=1)
    best = -ga.best_solution(ga.last_generation_fitness)[1]
    benchmark.extra_info.update(rms_after_nT=float(np.sqrt(best)))


@pytest.mark.benchmark(group="ga vs PyGAD: 80 x 1000 generations, sphere9 (300 points, nine)")
def test_ga_pygad(benchmark, sphere9):
    """PyGAD given the vectorized objective (fitness_batch_size = population: one call per generation,
    as magbench's ga makes)."""
    _pygad(benchmark, sphere9, batch=True, rounds=3)


@pytest.mark.benchmark(group="ga vs PyGAD: 80 x 1000 generations, sphere9 (300 points, nine)")
def test_ga_pygad_per_solution(benchmark, sphere9):
    """PyGAD as its documentation shows it: the fitness function called once per solution (the default)."""
    _pygad(benchmark, sphere9, batch=False, rounds=2)


@pytest.mark.benchmark(group="aco vs mealpy ACOR: 20,050 evaluations, sphere9 (300 points, nine)")
def test_aco_magbench(benchmark, sphere9):
    cal = make("aco", model="nine", archive_size=50, ants=20, iterations=ACO_ITERATIONS)
    res = benchmark.pedantic(cal.fit, args=(sphere9,), rounds=10, iterations=1, warmup_rounds=1)
    benchmark.extra_info.update(evaluations=res.n_evaluations, rms_after_nT=res.rms_after_nT)


@pytest.mark.benchmark(group="aco vs mealpy ACOR: 20,050 evaluations, sphere9 (300 points, nine)")
def test_aco_mealpy(benchmark, sphere9):
    """mealpy's OriginalACOR with the same archive (pop_size 50), ants per iteration (sample_count 20)
    and iterations, on the same objective and box."""
    pytest.importorskip("mealpy")
    from mealpy import ACOR, FloatVar

    obj = ScalarObjective(sphere9.raw_nT, sphere9.f_ref_nT, "nine")
    lo, hi = _box(sphere9)
    problem = {"obj_func": lambda x: float(obj.values(np.asarray(x)[None, :], exact=False)[0]),
               "bounds": FloatVar(lb=lo.tolist(), ub=hi.tolist()), "minmax": "min", "log_to": None}

    def run():
        model = ACOR.OriginalACOR(epoch=ACO_ITERATIONS, pop_size=50, sample_count=20, intent_factor=0.1, zeta=0.85)
        best = model.solve(problem, seed=0)
        return model, best

    model, best = benchmark.pedantic(run, rounds=1, iterations=1)
    benchmark.extra_info.update(evaluations=int(model.nfe_counter), rms_after_nT=float(np.sqrt(best.target.fitness)))

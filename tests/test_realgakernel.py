"""The real-coded GAs' generation kernel (calibrators/_gakernel.py, ``ga`` and seed 002's ``rga``): the
numba loops and the numpy arrays give bit-identical results, and the numpy version keeps the operators'
semantics (children inside the box, elites unchanged, the non-uniform step shrinking with t)."""
import contextlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from magbench.calibrators import make
from magbench.calibrators.core.evaluator import Budget, BudgetExhausted, Evaluator
from magbench.calibrators.core.loop import Termination, drive
from magbench.calibrators.core.objective import ScalarObjective
from magbench.calibrators.core.problem import Problem
from magbench.calibrators.methods import _gakernel as K
from magbench.calibrators.methods import genetic
from magbench.simulate import simulate

LAST_UNIFORM = np.nextafter(1.0, 0.0)
OPERATORS = [(s, c, mu) for s in (K.TOURNAMENT, K.RANK_SUS) for c in (K.BLX, K.SCATTERED)
             for mu in (K.NONUNIFORM, K.GAUSSIAN)]


def _loops():
    kernel = K.real_generation_kernel()
    if kernel is K.real_generation_numpy:
        pytest.skip("numba is not installed: only the numpy kernel runs")
    return kernel


def _run(kernel, f, pop, u, z, ops, tournament=2, alpha=0.3, pc=0.9, pm=0.1, shrink=0.5, elitism=1, lo=None,
         span=None):
    m, p = pop.shape
    lo = np.linspace(-1.0, 1.0, p) if lo is None else lo
    span = np.linspace(0.5, 2.0, p) if span is None else span
    out_pop, out_x = np.full((m, p), np.nan), np.full((m, p), np.nan)
    s, c, mu = ops
    kernel(f, pop, u, z, s, tournament, c, alpha, pc, mu, pm, shrink, elitism, lo, span, out_pop, out_x)
    return out_pop, out_x


def _same(f, pop, u, z, ops, **kw):
    pop_l, x_l = _run(_loops(), f, pop, u, z, ops, **kw)
    pop_n, x_n = _run(K.real_generation_numpy, f, pop, u, z, ops, **kw)
    np.testing.assert_array_equal(pop_l.view(np.int64), pop_n.view(np.int64))  # bit for bit
    np.testing.assert_array_equal(x_l.view(np.int64), x_n.view(np.int64))
    assert np.all((pop_n >= 0.0) & (pop_n <= 1.0))  # children inside the box
    return pop_n


def _fitness_cases(rng, m):
    f = rng.exponential(50.0, m)
    with_nan, with_inf = f.copy(), f.copy()
    with_nan[rng.integers(m)] = np.nan
    with_inf[rng.integers(m)] = np.inf
    return [f, np.full(m, 0.1), rng.integers(0, 3, m).astype(float), with_nan, with_inf, np.full(m, np.nan)]


def _uniforms(rng, n):
    u = rng.random(n)
    edges = u.copy()
    edges[rng.integers(0, n, max(1, n // 5))] = 0.0
    edges[rng.integers(0, n, max(1, n // 5))] = LAST_UNIFORM
    return [u, edges, np.floor(u * 4) / 4, np.zeros(n), np.full(n, LAST_UNIFORM)]


@pytest.mark.parametrize("ops", OPERATORS)
@pytest.mark.parametrize("m", [1, 2, 3, 7, 80, 81])
@pytest.mark.parametrize("p", [1, 9])
def test_numba_and_numpy_agree_bit_for_bit(ops, m, p):
    rng = np.random.default_rng([m, p, *ops])
    for tournament in (1, 2, 3):
        n = K.real_uniforms_needed(m, p, ops[0], tournament, ops[1], ops[2])
        for elitism in sorted({0, 1, min(2, m), m}):
            for f in _fitness_cases(rng, m):
                for u in _uniforms(rng, n):
                    pop = rng.random((m, p))
                    pop[rng.random((m, p)) < 0.1] = 0.0
                    pop[rng.random((m, p)) < 0.1] = 1.0
                    _same(f, pop, u, rng.standard_normal(m * p), ops, tournament=tournament, elitism=elitism,
                          alpha=float(rng.choice([0.0, 0.3])), shrink=float(rng.choice([0.0, 0.2, 1.0, 3.0])))


@pytest.mark.parametrize("ops", OPERATORS)
def test_numba_and_numpy_agree_at_extreme_rates_and_flat_boxes(ops):
    rng = np.random.default_rng(11)
    m, p = 80, 9
    n = K.real_uniforms_needed(m, p, ops[0], 2, ops[1], ops[2])
    flat = np.zeros(p)
    flat[::2] = 1.0  # lower == upper on the other genes
    for pc in (0.0, 1.0):
        for pm in (0.0, 1.0, 0.5):
            for _ in range(5):
                _same(rng.exponential(5.0, m), rng.random((m, p)), rng.random(n), rng.standard_normal(m * p), ops,
                      pc=pc, pm=pm, span=flat, lo=np.full(p, 3.0))


@settings(max_examples=200, deadline=None)
@given(m=st.integers(1, 30), p=st.integers(1, 5), ops=st.sampled_from(OPERATORS), tournament=st.integers(1, 4),
       elitism=st.integers(0, 30), seed=st.integers(0, 2**32 - 1), alpha=st.floats(0.0, 1.0),
       b=st.floats(0.0, 6.0), t=st.floats(0.0, 0.999), f_values=st.lists(st.floats(0.0, 1e6), min_size=1, max_size=3))
def test_numba_and_numpy_agree_on_any_input(m, p, ops, tournament, elitism, seed, alpha, b, t, f_values):
    rng = np.random.default_rng(seed)
    u = rng.random(K.real_uniforms_needed(m, p, ops[0], tournament, ops[1], ops[2]))
    f = rng.choice(np.array(f_values), m)  # few distinct values: ties are common
    _same(f, rng.random((m, p)), u, rng.standard_normal(m * p), ops, tournament=tournament, elitism=min(elitism, m),
          alpha=alpha, shrink=(1.0 - t) ** b)


def test_uniform_layout_tiles_the_draw():
    for m, p, ops, k in [(80, 9, OPERATORS[0], 2), (81, 9, OPERATORS[-1], 2), (1, 1, OPERATORS[3], 5)]:
        parts = sorted(K.real_uniform_layout(m, p, ops[0], k, ops[1], ops[2]).values(), key=lambda s: s.start)
        assert parts[0].start == 0
        assert all(a.stop == b.start for a, b in zip(parts, parts[1:]))
        assert parts[-1].stop == K.real_uniforms_needed(m, p, ops[0], k, ops[1], ops[2])


def _numpy(f, pop, u, ops, z=None, **kw):
    z = np.zeros(pop.size) if z is None else z
    return _run(K.real_generation_numpy, f, pop, u, z, ops, **kw)[0]


@pytest.mark.parametrize("ops", OPERATORS)
def test_elites_are_carried_unchanged_best_first(ops):
    rng = np.random.default_rng(3)
    m, p = 8, 4
    pop = rng.random((m, p))
    f = np.array([5.0, 1.0, 3.0, 1.0, 9.0, 0.5, np.nan, 7.0])
    u = rng.random(K.real_uniforms_needed(m, p, ops[0], 2, ops[1], ops[2]))
    for elitism in (1, 3, m):
        children = _numpy(f, pop, u, ops, pm=1.0, elitism=elitism)
        order = [5, 1, 3, 2, 0, 7, 4, 6][:elitism]  # ties: the lower index; NaN last
        np.testing.assert_array_equal(children[m - elitism:], pop[order])


def test_tournament_picks_the_better_and_no_crossover_copies_the_parents():
    m, p = 4, 2
    pop = np.arange(m * p, dtype=float).reshape(m, p) / 10
    f = np.array([3.0, 2.0, 1.0, 0.0])
    ops = (K.TOURNAMENT, K.BLX, K.NONUNIFORM)
    u = np.zeros(K.real_uniforms_needed(m, p, *ops[:1], 2, *ops[1:]))
    u[:8] = np.repeat([0.0, 0.3, 0.6, 0.9], 2) + np.tile([0.0, 0.2], 4)  # contests (0, 0) (1, 2) (2, 3) (3, 3)
    u[8:10] = LAST_UNIFORM  # no pair crosses (pc < 1)
    u[-m * p:] = LAST_UNIFORM  # no gene mutates
    children = _numpy(f, pop, u, ops, pc=0.9, elitism=0)
    np.testing.assert_array_equal(children, pop[[0, 2, 3, 3]])  # pairs (0, 3), (2, 3): children copied


def test_blx_children_in_the_widened_interval_and_alpha_zero_between_the_parents():
    rng = np.random.default_rng(5)
    m, p = 80, 9
    ops = (K.TOURNAMENT, K.BLX, K.NONUNIFORM)
    n = K.real_uniforms_needed(m, p, ops[0], 2, ops[1], ops[2])
    pop = 0.25 + 0.5 * rng.random((m, p))  # widened intervals stay inside [0, 1]: no clipping
    f = rng.random(m)
    for alpha in (0.0, 0.3):
        for _ in range(20):
            u = rng.random(n)
            u[-m * p:] = LAST_UNIFORM  # no mutation
            layout = K.real_uniform_layout(m, p, ops[0], 2, ops[1], ops[2])
            cand = (u[layout["select"]] * m).astype(int).reshape(-1, 2)
            mates = np.where(f[cand[:, 0]] < f[cand[:, 1]], cand[:, 0], cand[:, 1])
            children = _numpy(f, pop, u, ops, pc=1.0, alpha=alpha, elitism=0)
            pa, pb = pop[mates[:40]], pop[mates[40:]]
            lo, hi = np.minimum(pa, pb), np.maximum(pa, pb)
            width = (hi - lo) * alpha + 1e-15
            for half in (children[:40], children[40:]):
                assert np.all((half >= lo - width) & (half <= hi + width))


def test_nonuniform_step_shrinks_with_t():
    """Michalewicz's step (distance) * (1 - r^((1 - t/T)^b)): the same draws move a gene less later in the run."""
    rng = np.random.default_rng(8)
    m, p, b = 80, 9, 3.0
    ops = (K.TOURNAMENT, K.BLX, K.NONUNIFORM)
    n = K.real_uniforms_needed(m, p, ops[0], 2, ops[1], ops[2])
    u, pop, f = rng.random(n), rng.random((m, p)), rng.random(m)
    base = _numpy(f, pop, u, ops, pm=0.0, elitism=0)
    moves = [np.abs(_numpy(f, pop, u, ops, pm=0.3, shrink=(1.0 - t) ** b, elitism=0) - base).sum()
             for t in (0.0, 0.5, 0.9, 0.999)]
    assert moves[0] > 0 and all(a > b for a, b in zip(moves, moves[1:]))


def test_gaussian_mutation_adds_sigma_z_to_the_mutated_rows():
    m, p = 4, 3
    ops = (K.RANK_SUS, K.SCATTERED, K.GAUSSIAN)
    n = K.real_uniforms_needed(m, p, ops[0], 1, ops[1], ops[2])
    pop, f = np.full((m, p), 0.5), np.arange(m, dtype=float)
    u = np.zeros(n)
    u[-m:] = [0.0, LAST_UNIFORM, 0.0, LAST_UNIFORM]  # rows 0 and 2 mutate
    z = np.array([1.0, -1.0, 0.5, 2.0, -2.0, 0.25])
    children = _numpy(f, pop, u, ops, z=z, pm=0.5, shrink=0.1, elitism=0)
    np.testing.assert_array_equal(children[[1, 3]], 0.5)
    np.testing.assert_array_equal(children[[0, 2]], 0.5 + 0.1 * z.reshape(2, p))


@pytest.mark.parametrize("name", ["ga", "rga"])
def test_fit_gives_the_same_numbers_on_either_backend(name, monkeypatch):
    _loops()
    data = simulate("sphere9", 0)
    cal = make(name, model="nine", population=21, generations=40)
    compiled = cal.fit(data)
    monkeypatch.setattr(K, "real_generation_kernel", lambda: K.real_generation_numpy)
    plain = cal.fit(data)
    np.testing.assert_array_equal(compiled.x, plain.x)
    assert compiled.n_evaluations == plain.n_evaluations == 40 * 21 + 1  # + the start


def test_other_operators_run_their_own_loop():
    """An object that is not a ``RealGA`` (seed 001's ``RowGA``) or overrides an operator keeps its operators."""

    class Custom(genetic.RealGA):
        def _select(self, f, n, rng):
            return np.zeros(n, dtype=np.intp)

    assert genetic._kernel_operators(Custom()) is None
    assert genetic._kernel_operators(make("ga")) == (K.TOURNAMENT, K.BLX, K.NONUNIFORM)
    assert genetic._kernel_operators(make("rga")) == (K.RANK_SUS, K.SCATTERED, K.GAUSSIAN)
    data = simulate("sphere9", 0)
    res = Custom(model="nine", population=8, generations=5).fit(data)
    assert res.n_evaluations == 8 * 5 + 1


def _stopped_run(data, budget: int, generations: int = 150, before: bool = False):
    """``real_ga`` of ``ga`` on sphere9's objective, stopped by an evaluation budget (or by its generations);
    returns the best point, the evaluations spent and the next uniforms its rng gives."""
    ga = make("ga", population=20, generations=generations)
    counter = Evaluator(ScalarObjective(data.raw_nT, data.f_ref_nT, "nine"), Budget(max_evaluations=budget))
    termination = Termination(budget=counter.budget, max_iterations=generations)
    lower = np.array([-0.1] * 3 + [0.9] * 3 + [-2000.0] * 3)
    upper = np.array([0.1] * 3 + [1.1] * 3 + [2000.0] * 3)
    rng = np.random.default_rng(11)
    if before:  # a small-range integer first: half of a 64-bit draw stays buffered in the generator
        rng.integers(0, 10)
    problem = Problem(counter, "nine", (lower + upper) / 2, lower, upper, rng, None, termination)
    with contextlib.suppress(BudgetExhausted):  # the budget ends the search: the counter keeps its best point
        drive(genetic.real_ga(problem, ga), counter, termination)
    return counter.best_x, counter.n_evaluations, np.concatenate([rng.random(5), rng.integers(0, 1000, 5)])


@pytest.mark.parametrize("budget,before,block_uniforms", [(20 * 7 + 5, False, None), (20 * 64 + 20 * 3, False, None),
                                                          (20 * 150, False, None), (10 ** 6, False, None),
                                                          (20 * 7 + 5, True, None), (20 * 40 + 7, False, 2000)])
def test_block_draws_equal_per_generation_draws_and_a_stopped_run_gives_back_the_rest(budget, before, block_uniforms,
                                                                                      monkeypatch):
    """The numpy kernel draws and prepares up to 64 generations' uniforms at once (``_numpy_block_loop``): the
    same points as one draw per generation, and a run stopped inside a block (the budget spent) leaves its rng
    where one draw per generation leaves it (what draws next, as seed 001's next GA, draws the same numbers).
    Also with half of a 64-bit draw buffered before the run (which ``advance`` alone clears), and with blocks capped
    by their size (``BLOCK_UNIFORMS``: a large population's blocks are a few generations).  Negative control: the
    per-generation path, forced by saying the rng cannot be rewound."""
    monkeypatch.setenv(K.KERNEL_ENV, "numpy")
    if block_uniforms:
        monkeypatch.setattr(genetic, "BLOCK_UNIFORMS", block_uniforms)
    data = simulate("sphere9", 0)
    block = _stopped_run(data, budget, before=before)
    assert block[1] == min(budget, 20 * 150)
    monkeypatch.setattr(genetic, "_rewindable", lambda rng: False)
    per_generation = _stopped_run(data, budget, before=before)
    np.testing.assert_array_equal(block[0], per_generation[0])
    assert block[1] == per_generation[1]
    np.testing.assert_array_equal(block[2], per_generation[2])

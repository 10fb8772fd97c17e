"""The AGA's generation kernel (calibrators/_gakernel.py, seed 000 section 2.2 steps 2-5): the numba
loops and the numpy arrays give bit-identical results, and the numpy version does what the paper says."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from magbench.calibrators import make
from magbench.calibrators.methods import _gakernel
from magbench.simulate import simulate

LAST_UNIFORM = np.nextafter(1.0, 0.0)  # the largest double rng.random can return
N_UNIFORMS = _gakernel.uniforms_needed(80, 30, False)  # the paper's generation: 80 strings of 3 x 10 bits


def _loops():
    kernel = _gakernel.generation_kernel()
    if kernel is _gakernel.generation_numpy:
        pytest.skip("numba is not installed: only the numpy kernel runs")
    return kernel


def _run(kernel, f, pop, u, nb, per_bit, elitism, rates=(0.9, 0.6, 0.1, 0.001)):
    m, p = pop.shape
    lo, step = np.linspace(-0.1, 0.0, p), np.linspace(1e-3, 2e-3, p)
    out_pop, out_x = np.full_like(pop, -1), np.full((m, p), np.nan)
    stats = kernel(f, pop, u, lo, step, nb, *rates, per_bit, elitism, out_pop, out_x)
    return stats, out_pop, out_x


def _assert_same(f, pop, u, nb, per_bit, elitism, rates=(0.9, 0.6, 0.1, 0.001)):
    (avg_l, max_l), pop_l, x_l = _run(_loops(), f, pop, u, nb, per_bit, elitism, rates)
    (avg_n, max_n), pop_n, x_n = _run(_gakernel.generation_numpy, f, pop, u, nb, per_bit, elitism, rates)
    np.testing.assert_array_equal(np.array([avg_l, max_l]).view(np.int64), np.array([avg_n, max_n]).view(np.int64))
    np.testing.assert_array_equal(pop_l, pop_n)
    np.testing.assert_array_equal(x_l.view(np.int64), x_n.view(np.int64))  # bit for bit, NaNs included
    assert pop_n.min() >= 0 and pop_n.max() < 2**nb
    return pop_n


def _fitness_cases(rng, m):
    f = rng.exponential(50.0, m)
    tiny = np.full(m, 3.0)
    tiny[rng.integers(m)] = np.nextafter(3.0, 0.0)  # f_max - f_avg of a rounding error
    with_inf = f.copy()
    with_inf[rng.integers(m)] = np.inf  # G = 0: a sector of no width
    with_nan = f.copy()
    with_nan[rng.integers(m)] = np.nan
    return {"random": f, "all equal": np.full(m, 0.1), "one differs by an ulp": tiny, "inf": with_inf,
            "all inf": np.full(m, np.inf), "nan": with_nan, "zero": np.zeros(m),
            "ties": rng.integers(0, 3, m).astype(float)}


def _uniform_cases(rng, n):
    u = rng.random(n)
    edges = u.copy()
    edges[rng.integers(0, n, max(1, n // 5))] = 0.0
    edges[rng.integers(0, n, max(1, n // 5))] = LAST_UNIFORM
    return {"random": u, "edges": edges, "coarse (ties)": np.floor(u * 4) / 4, "all zero": np.zeros(n),
            "all last": np.full(n, LAST_UNIFORM)}


@pytest.mark.parametrize("m", [1, 2, 3, 7, 80, 81, 300])
@pytest.mark.parametrize("p, nb", [(3, 10), (1, 1), (9, 7), (2, 16), (3, 62)])
@pytest.mark.parametrize("per_bit", [False, True])
def test_numba_and_numpy_agree_bit_for_bit(m, p, nb, per_bit):
    rng = np.random.default_rng([m, p, nb, per_bit])
    length = p * nb
    n = _gakernel.uniforms_needed(m, length, per_bit)
    for elitism in sorted({0, 1, m // 2, m}):
        for f in _fitness_cases(rng, m).values():
            for u in _uniform_cases(rng, n).values():
                pop = rng.integers(0, 2**nb, (m, p), dtype=np.int64)
                _assert_same(f, pop, u, nb, per_bit, elitism)


@pytest.mark.parametrize("rates", [(1.0, 1.0, 1.0, 1.0), (0.0, 0.0, 0.0, 0.0), (0.6, 0.9, 0.001, 0.1)])
def test_numba_and_numpy_agree_at_extreme_rates(rates):
    rng = np.random.default_rng(7)
    for per_bit in (False, True):
        n = _gakernel.uniforms_needed(80, 30, per_bit)
        for _ in range(20):
            _assert_same(rng.exponential(5.0, 80), rng.integers(0, 1024, (80, 3)), rng.random(n), 10, per_bit, 1, rates)


@settings(max_examples=200, deadline=None)
@given(m=st.integers(1, 40), p=st.integers(1, 4), nb=st.integers(1, 20), per_bit=st.booleans(),
       elitism=st.integers(0, 3), seed=st.integers(0, 2**32 - 1),
       f_values=st.lists(st.floats(0.0, 1e6), min_size=1, max_size=3))
def test_numba_and_numpy_agree_on_any_input(m, p, nb, per_bit, elitism, seed, f_values):
    rng = np.random.default_rng(seed)
    u = rng.random(_gakernel.uniforms_needed(m, p * nb, per_bit))
    f = rng.choice(np.array(f_values), m)  # few distinct values: ties and equal fitness are common
    _assert_same(f, rng.integers(0, 2**nb, (m, p), dtype=np.int64), u, nb, per_bit, min(elitism, m))


def test_uniform_layout_tiles_the_draw():
    for m, length, per_bit in [(80, 30, False), (81, 30, False), (80, 30, True), (1, 1, True)]:
        parts = sorted(_gakernel.uniform_layout(m, length, per_bit).values(), key=lambda s: s.start)
        assert parts[0].start == 0
        assert all(a.stop == b.start for a, b in zip(parts, parts[1:]))
        assert parts[-1].stop == _gakernel.uniforms_needed(m, length, per_bit)


def _numpy_generation(f, pop, u, nb=10, per_bit=False, elitism=0, rates=(0.9, 0.6, 0.1, 0.001)):
    return _run(_gakernel.generation_numpy, f, pop, u, nb, per_bit, elitism, rates)


def test_uniform_fitness_gives_f_max_equal_f_avg_and_p1():
    """Eq. 4-5's 0/0 case: a uniform population has f_max == f_avg exactly, and then Pc = pc1, Pm = pm1."""
    m = 80
    (g_avg, g_max), _, _ = _numpy_generation(np.full(m, 0.1), np.zeros((m, 3), np.int64), np.zeros(N_UNIFORMS))
    assert g_avg == g_max == 1.0 / 1.1
    # with pc1 = pm1 = 1 and pc2 = pm2 = 0 every pair crosses (u = 0 < 1) and every child mutates
    u = np.zeros(N_UNIFORMS)
    u[-m:] = LAST_UNIFORM  # single_bit: the last bit of the string
    pop = np.zeros((m, 3), np.int64)
    _, children, _ = _numpy_generation(np.full(m, 0.1), pop, u, rates=(1.0, 0.0, 1.0, 0.0))
    np.testing.assert_array_equal(children, np.tile([0, 0, 1], (m, 1)))


def test_roulette_picks_by_fitness_share():
    """Eq. 9: an individual holding all the fitness (the others G = 0) is every mate; with crossover and
    mutation off the next generation is the selected mates."""
    m, rng = 10, np.random.default_rng(0)
    pop = rng.integers(0, 1024, (m, 3))
    f = np.full(m, np.inf)
    f[4] = 1.0
    u = rng.random(_gakernel.uniforms_needed(m, 30, False))
    _, children, _ = _numpy_generation(f, pop, u, rates=(0.0, 0.0, 0.0, 0.0))
    np.testing.assert_array_equal(children, np.tile(pop[4], (m, 1)))
    # the spins land on sector i when cum[i-1] <= u * total < cum[i]
    f = np.array([0.0, 1.0, 3.0])  # G = 1, 1/2, 1/4: sectors [0, 4/7), [4/7, 6/7), [6/7, 1)
    u = np.zeros(_gakernel.uniforms_needed(3, 2 * 10, False))
    u[:3] = [0.5, 0.6, 0.9]  # pair (0, 1), the third copied
    pop = np.arange(3)[:, None] * np.ones((1, 2), np.int64)
    _, children, _ = _numpy_generation(f, pop, u, rates=(0.0, 0.0, 0.0, 0.0))
    np.testing.assert_array_equal(children[:, 0], [0, 1, 2])


def test_single_point_crossover_swaps_the_tail():
    """Step 4: a cut at c exchanges string positions c..length-1 (the bits after the cut), MSB first."""
    m, nb = 2, 4
    pop = np.array([[0b0000, 0b0000], [0b1111, 0b1111]], np.int64)
    u = np.zeros(_gakernel.uniforms_needed(m, 2 * nb, False))
    u[0:2] = 0.0, LAST_UNIFORM  # spins: the first sector, then the last
    u[2] = 0.0  # the pair crosses
    u[3] = 2.5 / 7  # cut = 1 + floor(2.5/7 * 7) = 3
    f = np.array([1.0, 1.0])
    _, children, _ = _numpy_generation(f, pop, u, nb=nb, rates=(1.0, 1.0, 0.0, 0.0))
    np.testing.assert_array_equal(children, [[0b0001, 0b1111], [0b1110, 0b0000]])


def test_elitism_copies_the_best_first():
    rng = np.random.default_rng(3)
    pop = rng.integers(0, 1024, (8, 3))
    f = np.array([5.0, 1.0, 3.0, 1.0, 9.0, 0.5, 2.0, 7.0])
    _, children, _ = _numpy_generation(f, pop, rng.random(_gakernel.uniforms_needed(8, 30, False)), elitism=3)
    np.testing.assert_array_equal(children[:3], pop[[5, 1, 3]])  # ties: the first


def test_aga_gives_the_same_numbers_on_either_backend(monkeypatch):
    """Same seed, same result whether the kernel runs compiled (numba) or as numpy."""
    _loops()
    data = simulate("lu2014", 0)
    cal = make("aga", model="angles", max_generations=60, k_max=60)
    compiled = cal.fit(data)
    monkeypatch.setattr(_gakernel, "generation_kernel", lambda: _gakernel.generation_numpy)
    plain = cal.fit(data)
    np.testing.assert_array_equal(compiled.x, plain.x)
    assert compiled.n_evaluations == plain.n_evaluations == 60 * 80 + 1
    assert compiled.extra["mean_fitness"] == plain.extra["mean_fitness"]

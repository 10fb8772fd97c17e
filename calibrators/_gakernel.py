"""One generation of seed 000's adaptive binary GA (Lu et al. 2014, section 2.2, steps 2-5), as a
deterministic function of the population's bits, its objective values and the generation's uniforms.

The AGA draws every random number a generation needs in one call (``rng.random(uniforms_needed(...))``,
laid out as ``uniform_layout`` says) and hands them here with the objective values F the counted
evaluator returned; the kernel computes the fitness, breeds the next generation and decodes it into
the parameters the evaluator is asked about next.  It evaluates nothing itself.

The kernel is written twice, with bit-identical results (tests/test_gakernel.py): ``generation_numpy``,
whole-population arrays, and ``_generation_loops``, the same steps as loops that ``generation_kernel``
compiles with numba (imported there, on the first AGA run, never at import time; compiled once per
machine and cached).  Without numba the numpy version runs: the same seed gives the same numbers on
either backend.

Shared arguments of both versions:

``f`` (m,) F of eq. 3 for the current population; ``pop`` (m, p) int64, the current population, one
``nb``-bit integer per gene (the string s of eq. 7 held gene by gene, most significant bit first);
``u`` the generation's uniforms in [0, 1); ``lo``, ``step`` (p,) the box's lower bound and grid step
(eq. 6); ``pc1, pc2, pm1, pm2`` the adaptive probabilities' bounds (eq. 4, 5); ``per_bit`` the
mutation form (False: one random bit of a mutated individual, True: each bit with probability Pm);
``elitism`` how many of the current generation's best replace the first children (0 in the paper).
Outputs are written to ``out_pop`` (m, p) (the next generation) and ``out_x`` (m, p) (its decoded
parameters, eq. 7); the return value is ``(mean G, max G)`` of the current generation.
"""
from __future__ import annotations

import functools

import numpy as np


def adaptive_probability(f: np.ndarray, f_max: float, f_avg: float, p1: float, p2: float) -> np.ndarray:
    """Seed 000, eq. 4 and 5: ``p = p1 - (p1 - p2)(f - f_avg)/(f_max - f_avg)`` for ``f >= f_avg``, else p1.

    When every individual has the same fitness (f_max == f_avg) the formula is 0/0; the paper's rule (1)
    of section 2.1 ("when the individuals' fitness becomes uniform or sticks at a local optimum, raise
    Pc and Pm") decides it: ``p = p1`` for all.
    """
    spread = f_max - f_avg
    if spread <= 0:
        return np.full(np.shape(f), p1)
    return np.where(f >= f_avg, p1 - (p1 - p2) * (f - f_avg) / spread, p1)


def uniform_layout(m: int, length: int, per_bit: bool) -> dict[str, slice]:
    """Which of a generation's uniforms each step uses (m individuals, ``length`` bits per string):
    roulette spins (step 3), per pair a crossover draw and a cut draw (step 4), and for mutation
    (step 5) per individual a draw and the bit it flips (``single_bit``) or one draw per bit
    (``per_bit``).  Step 4's random pairing needs no draw of its own: the spins are independent, so
    pairing spin k with spin m/2 + k pairs the selected individuals uniformly at random (the same
    distribution as shuffling them first)."""
    half = m // 2
    mut = m + 2 * half
    parts = {"spin": slice(0, m), "cross": slice(m, m + half), "cut": slice(m + half, mut)}
    if per_bit:
        parts["flip"] = slice(mut, mut + m * length)
    else:
        parts["mutate"] = slice(mut, mut + m)
        parts["bit"] = slice(mut + m, mut + 2 * m)
    return parts


def uniforms_needed(m: int, length: int, per_bit: bool) -> int:
    """How many uniforms one generation draws (see ``uniform_layout``)."""
    return max(s.stop for s in uniform_layout(m, length, per_bit).values())


def _mean_within(total: float, m: int, g_min: float, g_max: float) -> float:
    """The mean fitness ``total / m``, kept within [g_min, g_max] as a mean is (a rounded sum can leave
    it, and an all-equal population must give f_max == f_avg exactly, the 0/0 case of eq. 4-5)."""
    g_avg = total / m
    if g_avg > g_max:
        g_avg = g_max
    if g_avg < g_min:
        g_avg = g_min
    return g_avg


def generation_numpy(f, pop, u, lo, step, nb, pc1, pc2, pm1, pm2, per_bit, elitism, out_pop, out_x):
    """Seed 000 section 2.2, steps 2-5 (and the optional elitism, not in the paper), on whole arrays.

    Step 2: G = 1/(1 + F) (eq. 8; F >= 0, inf or NaN).  Step 3: roulette wheel (eq. 9), m independent
    spins.  Step 4: random pairs (spin k with spin m/2 + k; an odd one out is copied), single-point
    crossover at a cut in 1..length-1 with the Pc of eq. 4 at the larger fitness of the pair.  Step 5:
    mutation with the Pm of eq. 5 at the individual's fitness before crossover.  Arguments and outputs:
    the module docstring.
    """
    m, p = pop.shape
    half, length = m // 2, p * nb
    parts = uniform_layout(m, length, per_bit)
    g = 1.0 / (1.0 + f)  # eq. 8
    cum = np.cumsum(g)
    g_max = float(g.max())
    g_avg = _mean_within(float(cum[-1]), m, float(g.min()), g_max)
    # step 3: the wheel's sectors are the cumulative fitness; a spin u lands in the first sector past u * total
    mates = np.minimum(np.searchsorted(cum, u[parts["spin"]] * cum[-1], side="right"), m - 1)
    g_mates = g[mates]
    # step 4: pair k is (k, half + k)
    out_pop[:] = pop[mates]
    pa, pb = out_pop[:half], out_pop[half:2 * half]
    pc = adaptive_probability(np.maximum(g_mates[:half], g_mates[half:2 * half]), g_max, g_avg, pc1, pc2)
    cut = np.where(u[parts["cross"]] < pc, 1 + (u[parts["cut"]] * (length - 1)).astype(np.int64), length)
    # a cut at c swaps the string positions >= c: in gene j (positions j*nb .. j*nb+nb-1) its lowest
    # clip((j+1)*nb - c, 0, nb) bits; c = length swaps none
    swapped = np.clip(np.arange(1, p + 1) * nb - cut[:, None], 0, nb)
    diff = (pa ^ pb) & ((1 << swapped) - 1)
    pa ^= diff
    pb ^= diff
    # step 5
    pm = adaptive_probability(g_mates, g_max, g_avg, pm1, pm2)
    if per_bit:
        flips = u[parts["flip"]].reshape(m, p, nb) < pm[:, None, None]
        out_pop ^= (flips << np.arange(nb - 1, -1, -1)).sum(axis=2)
    else:
        pos = (u[parts["bit"]] * length).astype(np.int64)
        rows = np.flatnonzero(u[parts["mutate"]] < pm)
        out_pop[rows, pos[rows] // nb] ^= 1 << (nb - 1 - pos[rows] % nb)
    if elitism:  # not in the paper: the best individuals (ties: the first) replace the first children
        out_pop[:elitism] = pop[np.argsort(-g, kind="stable")[:elitism]]
    np.multiply(out_pop, step, out=out_x)  # eq. 7
    out_x += lo
    return g_avg, g_max


_COUNTING_MAX = 256  # the loops' roulette counts sectors up to this population size, then bisects


def _generation_loops(f, pop, u, lo, step, nb, pc1, pc2, pm1, pm2, per_bit, elitism, out_pop, out_x):
    """``generation_numpy`` (seed 000 section 2.2, steps 2-5) as loops, for numba: the same arithmetic in
    the same order, so the results are bit-identical.  Arguments and outputs: the module docstring."""
    m, p = pop.shape
    half, length = m // 2, p * nb
    mut = m + 2 * half
    g = np.empty(m)
    cum = np.empty(m)
    total, g_max, g_min, nan = 0.0, -np.inf, np.inf, False
    for i in range(m):  # step 2, eq. 8
        gi = 1.0 / (1.0 + f[i])
        g[i] = gi
        total += gi
        cum[i] = total
        nan = nan or gi != gi
        g_max = gi if gi > g_max else g_max
        g_min = gi if gi < g_min else g_min
    if nan:
        g_max, g_min = np.nan, np.nan
    g_avg = total / m  # _mean_within, inlined
    if g_avg > g_max:
        g_avg = g_max
    if g_avg < g_min:
        g_avg = g_min
    spread = g_max - g_avg

    def adaptive(fv, p1, p2):  # eq. 4, 5 (adaptive_probability for one individual)
        if spread <= 0:
            return p1
        if fv >= g_avg:
            return p1 - (p1 - p2) * (fv - g_avg) / spread
        return p1

    # step 3: roulette wheel, eq. 9: spin i lands in the first sector whose cumulative fitness exceeds
    # u_i * total (np.searchsorted(cum, u * total, side="right"), clipped to m - 1): for a small population
    # by counting the sectors it passes (no branch to mispredict), else by bisection
    mates = np.empty(m, np.int64)
    for i in range(m):
        v = u[i] * total
        if m <= _COUNTING_MAX:
            a = 0
            for j in range(m):
                a += not cum[j] > v
            a = min(a, m - 1)
        else:
            a, b = 0, m - 1
            while a < b:
                c = (a + b) // 2
                if cum[c] > v:
                    b = c
                else:
                    a = c + 1
        mates[i] = a
        for j in range(p):
            out_pop[i, j] = pop[a, j]
    # step 4: pair k is (k, half + k)
    for k in range(half):
        ga, gb = g[mates[k]], g[mates[half + k]]
        fp = ga if (ga > gb or ga != ga) else gb  # np.maximum: NaN wins
        cut = length
        if u[m + k] < adaptive(fp, pc1, pc2):
            cut = 1 + int(u[m + half + k] * (length - 1))
        for j in range(p):
            swapped = min(max((j + 1) * nb - cut, 0), nb)
            diff = (out_pop[k, j] ^ out_pop[half + k, j]) & ((1 << swapped) - 1)
            out_pop[k, j] ^= diff
            out_pop[half + k, j] ^= diff
    # step 5
    for i in range(m):
        pm = adaptive(g[mates[i]], pm1, pm2)
        if per_bit:
            for pos in range(length):
                if u[mut + i * length + pos] < pm:
                    out_pop[i, pos // nb] ^= 1 << (nb - 1 - pos % nb)
        elif u[mut + i] < pm:
            pos = int(u[mut + m + i] * length)
            out_pop[i, pos // nb] ^= 1 << (nb - 1 - pos % nb)
    if elitism:  # the best individuals (ties: the first) replace the first children
        best = np.argsort(-g, kind="mergesort")
        for r in range(elitism):
            for j in range(p):
                out_pop[r, j] = pop[best[r], j]
    for i in range(m):  # eq. 7
        for j in range(p):
            out_x[i, j] = out_pop[i, j] * step[j] + lo[j]
    return g_avg, g_max


@functools.cache
def generation_kernel():
    """The kernel to run: ``_generation_loops`` compiled by numba (cached on disk where numba finds a
    writable place, else compiled in memory), or ``generation_numpy`` when numba does not import."""
    try:
        import numba
    except ImportError:
        return generation_numpy
    try:
        return numba.njit(cache=True, nogil=True)(_generation_loops)
    except RuntimeError:  # no writable cache location: compile for this process only
        return numba.njit(nogil=True)(_generation_loops)

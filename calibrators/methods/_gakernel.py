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
import math
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any, NamedTuple

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


@functools.lru_cache(maxsize=64)
def uniform_layout(m: int, length: int, per_bit: bool) -> Mapping[str, slice]:
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
    return MappingProxyType(parts)  # cached (one per run's shape, asked every generation): read-only


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


def _smoke(kernel) -> None:
    """One tiny generation with the argument types ``AdaptiveGA._solve`` passes (compiles the loops, or
    raises where numba cannot)."""
    m, p, nb = 4, 2, 3
    for per_bit in (False, True):
        kernel(np.arange(m, dtype=float), np.zeros((m, p), dtype=np.int64),
               np.full(uniforms_needed(m, p * nb, per_bit), 0.25), np.zeros(p), np.ones(p), nb, 0.9, 0.6, 0.1,
               0.001, per_bit, 1, np.empty((m, p), dtype=np.int64), np.empty((m, p)))


KERNEL_ENV = "MAGBENCH_GA_KERNEL"
"""``numpy``, ``numba`` or ``auto`` (the default): which version of the GA kernels runs.  The two give the
same numbers (tests/test_gakernel.py, tests/test_realgakernel.py); only the time differs."""
NUMPY_GENERATION_S = 2.5e-4
"""Seconds the numpy kernel takes per generation of 80 individuals (measured: 1000 generations in 0.25 s,
objective included); about twice the compiled kernel's."""
CACHE_LOAD_S = 0.6
"""Seconds importing numba and loading a cached kernel cost a process (0.4-1 s measured)."""
COMPILE_S = 15.0
"""Seconds compiling a kernel costs when numba has no cache of it (once per machine)."""
_PREFER_COMPILED = [False]
_RUNS: dict[str, int] = {}


def prefer_compiled(flag: bool = True) -> None:
    """Say that this process will run many GA fits (a campaign's worker): the compiled kernels then run
    from the first fit on, their one-time cost paid by the campaign's untimed warm-up."""
    _PREFER_COMPILED[0] = bool(flag)


def _cached_on_disk(loops) -> bool:
    """Whether numba's on-disk cache holds ``loops``, so that loading costs ``CACHE_LOAD_S`` rather than
    ``COMPILE_S``: its index file where numba looks (``NUMBA_CACHE_DIR`` when set; else ``__pycache__``
    beside this module, then the user-wide cache), under numba's subdirectory name for this folder."""
    import hashlib
    import os
    from pathlib import Path

    here = Path(__file__).resolve()
    pattern = f"{here.stem}.{loops.__name__}-*.nbi"
    sub = f"{here.parent.name}_{hashlib.sha1(str(here.parent).encode()).hexdigest()}"
    if os.environ.get("NUMBA_CACHE_DIR"):
        places = [Path(os.environ["NUMBA_CACHE_DIR"]) / sub]
    else:
        user = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "numba" / sub
        places = [here.parent / "__pycache__", user]
    return any(any(place.glob(pattern)) for place in places if place.is_dir())


def choose(loops, generations: int, population: int) -> str:
    """``"numba"`` or ``"numpy"`` for a run of ``generations`` x ``population``: numba when ``KERNEL_ENV``
    says so, when its kernel is loaded already, when the process will run many fits (``prefer_compiled``),
    from the second run of a kernel in a process on, or when the numpy kernel's expected time exceeds the
    one-time cost (``CACHE_LOAD_S``, or ``COMPILE_S`` without a cache); else numpy, so that a single
    command does not pay a 0.4-1 s cache load (or a compile) for a run the numpy kernel does in 0.25 s."""
    import os

    mode = os.environ.get(KERNEL_ENV, "auto").strip().lower()
    if mode in ("numpy", "numba"):
        return mode
    if _LOADED.get(loops.__name__) or _PREFER_COMPILED[0] or _RUNS.get(loops.__name__, 0) >= 1:
        return "numba"
    expected = generations * max(population, 1) / 80.0 * NUMPY_GENERATION_S
    if expected <= min(CACHE_LOAD_S, COMPILE_S):  # numpy whatever numba's disk cache holds: not looked for
        return "numpy"
    return "numba" if expected > (CACHE_LOAD_S if _cached_on_disk(loops) else COMPILE_S) else "numpy"


_LOADED: dict[str, bool] = {}


def _compiled(loops, smoke, fallback):
    """``loops`` compiled by numba (cached on disk where numba finds a writable place, else compiled in
    memory) and checked by ``smoke``; ``fallback`` (the numpy version, same numbers) when numba does not
    import or cannot compile it.  A one-line notice on stderr says when a compile is about to happen."""
    try:
        import numba
    except ImportError:
        return fallback
    if not _cached_on_disk(loops):
        _compile_notice(loops)
    _LOADED[loops.__name__] = True
    try:
        try:
            kernel = numba.njit(cache=True, nogil=True)(loops)
        except RuntimeError:  # no writable cache location: compile for this process only
            kernel = numba.njit(nogil=True)(loops)
        smoke(kernel)
    except Exception:  # noqa: BLE001  (a numba that cannot compile here: the numpy version runs)
        return fallback
    return kernel


NOTICE_ENV = "MAGBENCH_COMPILE_NOTICE"
"""Set to ``given`` by a process that announced the compiles for the workers it starts (they stay quiet)."""


def _compile_notice(loops) -> None:
    """One line on stderr before numba compiles ``loops`` (unless the parent process said it already)."""
    import os
    import sys

    if os.environ.get(NOTICE_ENV) == "given":
        return
    sys.stderr.write(f"magbench: compiling the GA kernel ({loops.__name__.strip('_')}) with numba, once per "
                     f"machine (a few seconds to a minute)\n")
    sys.stderr.flush()


KERNEL_USERS = {"aga": "binary", "aga-lm": "binary", "ga": "real", "rga": "real"}
"""The built-in methods that run a GA kernel, and which."""


def announce_compiles(methods) -> bool:
    """For a process about to start workers that will run ``methods``: the compile notice of each GA kernel
    they use (``KERNEL_USERS``) that is not in numba's disk cache, said once here.  Returns whether the
    workers should keep quiet (set ``NOTICE_ENV`` to ``given`` in them); this process's own environment is
    not changed.  Other methods use no GA kernel; a plug-in GA's workers speak for themselves."""
    import importlib.util

    kinds = {KERNEL_USERS[m] for m in methods if m in KERNEL_USERS}
    if not kinds or importlib.util.find_spec("numba") is None:
        return False
    for kind, loops in (("binary", _generation_loops), ("real", _real_generation_loops)):
        if kind in kinds and not _cached_on_disk(loops):
            _compile_notice(loops)
    return True


def load_if_chosen(loops, kernel, generations: int, population: int) -> bool:
    """Before a timed run of ``generations`` x ``population``: when ``choose`` picks numba for it and the compiled
    ``loops`` are not loaded yet, load (or compile) them now through ``kernel`` (``generation_kernel`` or
    ``real_generation_kernel``), so that the run's clock does not pay for it.  Returns whether that happened.
    ``choose`` changes nothing, so the run's own choice is the same."""
    if _LOADED.get(loops.__name__) or choose(loops, generations, population) != "numba":
        return False
    kernel()
    return True


@functools.cache
def generation_kernel():
    """The AGA's kernel: ``_generation_loops`` compiled, or ``generation_numpy`` (``_compiled``)."""
    return _compiled(_generation_loops, _smoke, generation_numpy)


def generation_kernel_for(generations: int, population: int):
    """The AGA's kernel for a run of that size (``choose``): compiled or numpy, the same numbers."""
    use = choose(_generation_loops, generations, population)
    _RUNS[_generation_loops.__name__] = _RUNS.get(_generation_loops.__name__, 0) + 1
    return generation_kernel() if use == "numba" else generation_numpy


# ---------------------------------------------------------------------------------------------------------
# The real-coded GAs (``RealGA``, ``ga``; seed 002's ``ElitistRealGA``, ``rga``): one generation's
# selection, crossover, mutation, clipping to the box and elitism, as a deterministic function of the
# population (genes normalized to [0, 1] over the box), its objective values and the generation's random
# numbers, which ``real_ga`` draws in one ``rng.random`` call (laid out as ``real_uniform_layout`` says),
# plus, for the Gaussian mutation, one ``rng.standard_normal`` call for the rows that mutate.  Written
# twice, bit-identical (tests/test_realgakernel.py): ``real_generation_numpy`` and ``_real_generation_loops``
# (compiled by ``real_generation_kernel``).
#
# Arguments of both versions: ``f`` (m,) the objective values of ``pop`` (m, p), the current population
# in [0, 1]; ``u`` the generation's uniforms; ``z`` the standard normals of the mutated rows (Gaussian
# mutation; row after row, p per row); ``selection`` (TOURNAMENT with ``tournament`` contestants, or
# RANK_SUS), ``crossover`` (BLX with ``alpha``, or SCATTERED) applied to a pair with probability ``pc``,
# ``mutation`` (NONUNIFORM or GAUSSIAN) with probability ``pm`` and ``shrink`` (NONUNIFORM: the exponent
# (1 - t/T)^b; GAUSSIAN: the standard deviation at generation t), ``elitism`` the number of best
# individuals copied into the last rows, ``lo``, ``span`` (p,) the box.  Outputs: ``out_pop`` (m, p) the
# next generation in [0, 1], ``out_x`` (m, p) its parameters lo + out_pop * span.
#
# Order: the population is ranked once (stable sort of f, NaN last: the best is the smallest value, ties
# the lower index); a tournament's winner is its best-ranked contestant, the elites are the first ranks.
# ---------------------------------------------------------------------------------------------------------

TOURNAMENT, RANK_SUS = 0, 1
BLX, SCATTERED = 0, 1
NONUNIFORM, GAUSSIAN = 0, 1


@functools.lru_cache(maxsize=64)
def real_uniform_layout(m: int, p: int, selection: int, tournament: int, crossover: int,
                        mutation: int) -> Mapping[str, slice]:
    """Which of a generation's uniforms each step uses (m individuals of p genes; half = ceil(m/2) pairs
    of parents, the second child of the last pair dropped when m is odd): selection (TOURNAMENT: k
    contestants for each of the 2 half parents; RANK_SUS: the pointers' offset and one sort key per
    parent for the shuffle), one crossover draw per pair, the crossover's draws (BLX: one blend factor per
    gene of each child; SCATTERED: one pick per gene of each pair), and mutation's (NONUNIFORM: one per
    gene; GAUSSIAN: one per child)."""
    half = (m + 1) // 2
    sizes = {"select": 2 * half * tournament} if selection == TOURNAMENT else {"offset": 1, "shuffle": 2 * half}
    sizes["cross"] = half
    sizes["blend" if crossover == BLX else "pick"] = m * p if crossover == BLX else half * p
    sizes["mutate"] = m * p if mutation == NONUNIFORM else m
    parts, start = {}, 0
    for name, size in sizes.items():
        parts[name] = slice(start, start + size)
        start += size
    return MappingProxyType(parts)  # cached (one per run's shape, asked every generation): read-only


def real_uniforms_needed(m: int, p: int, selection: int, tournament: int, crossover: int, mutation: int) -> int:
    """How many uniforms one generation draws (see ``real_uniform_layout``)."""
    return max(s.stop for s in real_uniform_layout(m, p, selection, tournament, crossover, mutation).values())


def _pow_each(r: np.ndarray, e: np.ndarray) -> np.ndarray:
    """``r ** e`` element by element (``e`` one exponent per element) with the C library's ``pow``, as the compiled
    loops call it (numpy's own vectorized power may differ in the last bit)."""
    return np.fromiter(map(math.pow, r.tolist(), e.tolist()), dtype=float, count=r.size)


class RealDraws(NamedTuple):
    """What B generations of the real-coded GA take from their uniforms alone, before any population is
    known (``real_prepare``): per generation, the tournaments' contestants or the rank-SUS pointers' offset
    and shuffle, which pairs cross, the BLX blend factors or the scattered swaps, and the non-uniform
    mutation's hits with their steps (``hits[at[g]:at[g + 1]]`` flat indices into generation g's children,
    ``up`` their direction, ``delta`` their step) or the Gaussian mutation's rows.  Each field an array, or None
    where the generation's operators do not use it."""

    contestants: Any  # (B, tournament, n) int64: generation g's c-th contestants (TOURNAMENT)
    offsets: Any      # (B,) the pointers' offset (RANK_SUS)
    shuffle: Any      # (B, n) the order of the picked parents (RANK_SUS)
    cross: np.ndarray  # (B, half) bool
    blend: Any        # (B, m, p) BLX factors s in [-alpha, 1 + alpha]
    swap: Any         # (B, half, p) bool (SCATTERED)
    hits: Any         # flat indices of the mutated genes, generation after generation (NONUNIFORM)
    at: Any           # (B + 1,) where each generation's hits start
    up: Any           # their direction: 1.0 towards the upper bound, 0.0 towards the lower (NONUNIFORM)
    delta: Any        # their step 1 - r^shrink (NONUNIFORM)
    mutated: Any      # (B, m) bool: the rows a Gaussian mutation moves (GAUSSIAN)


def real_prepare(u, m, p, selection, tournament, crossover, alpha, pc, mutation, pm, shrinks) -> RealDraws:
    """The population-independent part of ``real_generation_numpy`` for B generations at once: ``u`` (B, k)
    their uniforms (row g: generation g's, laid out as ``real_uniform_layout`` says) and ``shrinks`` (B,) the
    non-uniform exponents (unused for GAUSSIAN).  Every number is computed by the operations
    ``real_generation_numpy`` applies to one generation, element by element, so the generations bred from it
    by ``real_apply`` are bit-identical to one call per generation: a run draws its uniforms for many
    generations in one ``rng.random`` call (the same stream), and prepares them in a few whole-block
    operations rather than a few dozen small ones per generation."""
    b = u.shape[0]
    half = (m + 1) // 2
    n = 2 * half
    parts = real_uniform_layout(m, p, selection, tournament, crossover, mutation)
    contestants = offsets = shuffle = blend = swap = hits = at = up = delta = mutated = None
    if selection == TOURNAMENT:
        drawn = np.minimum((u[:, parts["select"]] * m).astype(np.int64), m - 1).reshape(b, n, tournament)
        contestants = np.ascontiguousarray(drawn.transpose(0, 2, 1))  # one contiguous row per contestant
    else:
        offsets = u[:, parts["offset"].start]
        shuffle = np.argsort(u[:, parts["shuffle"]], axis=1, kind="stable")
    cross = u[:, parts["cross"]] < pc
    if crossover == BLX:
        blend = u[:, parts["blend"]].reshape(b, m, p) * (1.0 + 2.0 * alpha)
        blend -= alpha
    else:
        swap = ~(u[:, parts["pick"]].reshape(b, half, p) < 0.5) & cross[:, :, None]
    w = u[:, parts["mutate"]]
    if mutation == NONUNIFORM:
        q = min(pm, 1.0)
        gen, hits = np.nonzero(w < q)  # generation after generation, each one's genes in order
        v = w[gen, hits] / q * 2.0
        up = (v >= 1.0).astype(float)  # 1.0 towards the upper bound, 0.0 towards the lower
        delta = 1.0 - _pow_each(v - up, np.asarray(shrinks, dtype=float)[gen])
        at = np.searchsorted(gen, np.arange(b + 1))
    else:
        mutated = w < pm
    return RealDraws(contestants, offsets, shuffle, cross, blend, swap, hits, at, up, delta, mutated)


def real_apply(f, pop, draws: RealDraws, g, z, shrink, elitism, lo, span, out_pop, out_x):
    """Generation g of ``draws`` bred from ``pop`` and its values ``f`` (the population-dependent part of
    ``real_generation_numpy``; ``z`` and ``shrink`` the Gaussian mutation's normals and standard deviation)."""
    m, p = pop.shape
    half = (m + 1) // 2
    n = 2 * half
    order = f.argsort(kind="stable")
    rank = np.empty(m, np.int64)
    rank[order] = np.arange(m)
    if draws.contestants is not None:
        cand = draws.contestants[g]
        best = rank[cand[0]]
        for c in range(1, cand.shape[0]):
            np.minimum(best, rank[cand[c]], out=best)
        mates = order[best]  # the best-ranked contestant of each tournament
    else:
        cum = np.cumsum(1.0 / np.sqrt(rank + 1.0))
        pointers = (draws.offsets[g] + np.arange(n)) / n * cum[-1]
        picked = np.minimum(np.searchsorted(cum, pointers, side="left"), m - 1)
        mates = picked[draws.shuffle[g]]
    parents = pop[mates]  # pair k: parents[k] and parents[half + k]
    pa, pb = parents[:half], parents[half:]
    second = m - half  # the second children kept
    cross = draws.cross[g]
    out_pop[:] = parents[:m]  # the first children pa, the second pb[:second]
    if draws.blend is not None:
        s = draws.blend[g]  # used once: scaled in place
        d = pb - pa
        if second == half and out_pop.flags.c_contiguous:  # both children of every pair as (2, half, p) views
            pairs = s.reshape(2, half, p)
            pairs *= d
            pairs += pa
            np.copyto(out_pop.reshape(2, half, p), pairs, where=cross[None, :, None])
        else:
            s[:half] *= d
            s[half:] *= d[:second]
            s[:half] += pa
            s[half:] += pa[:second]
            rows = np.concatenate((cross, cross[:second]))
            out_pop[rows] = s[rows]
    else:
        swap = draws.swap[g]
        out_pop[:half][swap] = pb[swap]
        out_pop[half:][swap[:second]] = pa[:second][swap[:second]]
    if draws.hits is not None:
        lo_at, hi_at = draws.at[g], draws.at[g + 1]
        hit = draws.hits[lo_at:hi_at]
        flat = out_pop.reshape(-1)
        c = flat[hit]
        flat[hit] = c + (draws.up[lo_at:hi_at] - c) * draws.delta[lo_at:hi_at]
    else:
        rows = np.flatnonzero(draws.mutated[g])
        out_pop[rows] += shrink * z[:len(rows) * p].reshape(len(rows), p)
    np.maximum(out_pop, 0.0, out=out_pop)
    np.minimum(out_pop, 1.0, out=out_pop)
    if elitism == 1:
        out_pop[m - 1] = pop[order[0]]
    elif elitism:
        out_pop[m - elitism:] = pop[order[:elitism]]
    np.multiply(out_pop, span, out=out_x)
    out_x += lo


def real_generation_numpy(f, pop, u, z, selection, tournament, crossover, alpha, pc, mutation, pm, shrink,
                          elitism, lo, span, out_pop, out_x):
    """One generation of the real-coded GA (seed 002, section 3.3: selection, crossover, mutation and an
    elite carried over), on whole arrays: ``real_prepare`` of its uniforms, then ``real_apply``.  Arguments
    and outputs: the comment above ``TOURNAMENT``.

    Selection: TOURNAMENT, the best-ranked of ``tournament`` individuals drawn with replacement; RANK_SUS,
    rank scaling (weight 1/sqrt(rank)) and stochastic universal sampling (pointers (u0 + j)/n of the
    cumulative weight, then shuffled by sorting n uniforms).  Parents k and half + k form pair k; the pair
    crosses with probability ``pc`` (else the children are the parents, copied).  BLX-alpha (Eshelman &
    Schaffer 1993): child = pa + (pb - pa) s, s = u (1 + 2 alpha) - alpha uniform in [-alpha, 1 + alpha].
    SCATTERED: each gene of the first child from pa or pb at even odds, the second child the other one.
    NONUNIFORM (Michalewicz 1992): a gene hit (w < pm) moves towards 0 (w/pm < 1/2) or 1 by the distance
    times 1 - r^((1 - t/T)^b), with r = 2 w/pm (mod 1) the uniform left in the hit draw.  GAUSSIAN: a
    child mutated (w < pm) gets sigma z added to each gene.  Then clipping to [0, 1], and the elites
    (first ranks, best first) replace the last children.
    """
    draws = real_prepare(u[None, :], pop.shape[0], pop.shape[1], selection, tournament, crossover, alpha, pc,
                         mutation, pm, (shrink,))
    real_apply(f, pop, draws, 0, z, shrink, elitism, lo, span, out_pop, out_x)


def _real_generation_loops(f, pop, u, z, selection, tournament, crossover, alpha, pc, mutation, pm, shrink,
                           elitism, lo, span, out_pop, out_x):
    """``real_generation_numpy`` (seed 002 section 3.3's generation) as loops, for numba: the same
    arithmetic in the same order, so the results are bit-identical."""
    m, p = pop.shape
    half = (m + 1) // 2
    n = 2 * half
    second = m - half
    order = np.argsort(f, kind="mergesort")
    rank = np.empty(m, np.int64)
    for r in range(m):
        rank[order[r]] = r
    mates = np.empty(n, np.int64)
    if selection == TOURNAMENT:
        for i in range(n):
            best = -1
            for c in range(tournament):
                a = min(int(u[i * tournament + c] * m), m - 1)
                if best < 0 or rank[a] < rank[best]:
                    best = a
            mates[i] = best
        at = n * tournament
    else:
        cum = np.empty(m)
        total = 0.0
        for i in range(m):
            total += 1.0 / np.sqrt(rank[i] + 1.0)
            cum[i] = total
        picked = np.empty(n, np.int64)
        a = 0
        for j in range(n):  # the pointers increase: one sweep finds the first sector reaching each
            v = (u[0] + j) / n * total
            while a < m - 1 and cum[a] < v:
                a += 1
            picked[j] = a
        shuffle = np.argsort(u[1:1 + n], kind="mergesort")
        for j in range(n):
            mates[j] = picked[shuffle[j]]
        at = 1 + n
    cross_at = at
    at += half
    scale = 1.0 + 2.0 * alpha
    for k in range(half):
        a, b = mates[k], mates[half + k]
        crosses = u[cross_at + k] < pc
        for j in range(p):
            xa, xb = pop[a, j], pop[b, j]
            c1, c2 = xa, xb
            if crosses:
                if crossover == BLX:
                    d = xb - xa
                    c1 = (u[at + k * p + j] * scale - alpha) * d + xa
                    if k < second:
                        c2 = (u[at + (half + k) * p + j] * scale - alpha) * d + xa
                elif not u[at + k * p + j] < 0.5:
                    c1, c2 = xb, xa
            out_pop[k, j] = c1
            if k < second:
                out_pop[half + k, j] = c2
    at += m * p if crossover == BLX else half * p
    if mutation == NONUNIFORM:
        q = min(pm, 1.0)
        for i in range(m):
            for j in range(p):
                w = u[at + i * p + j]
                if w < q:
                    v = w / q * 2.0
                    up = 1.0 if v >= 1.0 else 0.0
                    delta = 1.0 - (v - up) ** shrink
                    c = out_pop[i, j]
                    out_pop[i, j] = c + (up - c) * delta
    else:
        row = 0
        for i in range(m):
            if u[at + i] < pm:
                for j in range(p):
                    out_pop[i, j] += shrink * z[row * p + j]
                row += 1
    for i in range(m):
        for j in range(p):
            c = out_pop[i, j]
            if c < 0.0:
                c = 0.0
            if c > 1.0:
                c = 1.0
            out_pop[i, j] = c
    for r in range(elitism):
        for j in range(p):
            out_pop[m - elitism + r, j] = pop[order[r], j]
    for i in range(m):
        for j in range(p):
            out_x[i, j] = out_pop[i, j] * span[j] + lo[j]


def _real_smoke(kernel) -> None:
    """One tiny generation of every operator combination, with the argument types ``real_ga`` passes
    (compiles the loops, or raises where numba cannot)."""
    m, p = 4, 2
    f, pop, lo, span = np.arange(m, dtype=float), np.full((m, p), 0.5), np.zeros(p), np.ones(p)
    for selection in (TOURNAMENT, RANK_SUS):
        for crossover in (BLX, SCATTERED):
            for mutation in (NONUNIFORM, GAUSSIAN):
                u = np.full(real_uniforms_needed(m, p, selection, 2, crossover, mutation), 0.25)
                kernel(f, pop, u, np.zeros(m * p), selection, 2, crossover, 0.3, 0.9, mutation, 0.1, 0.5, 1,
                       lo, span, np.empty((m, p)), np.empty((m, p)))


@functools.cache
def real_generation_kernel():
    """The real-coded GA's kernel: ``_real_generation_loops`` compiled, or ``real_generation_numpy``
    (``_compiled``)."""
    return _compiled(_real_generation_loops, _real_smoke, real_generation_numpy)


def real_generation_kernel_for(generations: int, population: int):
    """The real-coded GA's kernel for a run of that size (``choose``): compiled or numpy, the same numbers."""
    use = choose(_real_generation_loops, generations, population)
    _RUNS[_real_generation_loops.__name__] = _RUNS.get(_real_generation_loops.__name__, 0) + 1
    return real_generation_kernel() if use == "numba" else real_generation_numpy

"""The few statistics the diagnosis asks of ``scipy.stats`` and ``scipy.signal`` on every record, computed without
importing either (together about 0.4 s of a one-off ``magbench diagnose`` of 0.85 s): the normal and Poisson tails
and the F test's through ``scipy.special``, the functions ``scipy.stats`` itself calls; Spearman's rank correlation
as ``scipy.stats.spearmanr`` forms it (average ranks, then ``numpy.corrcoef``); and the one-pole low-pass that the
floor's neighbour test filters with, as ``scipy.signal.lfilter`` runs it.  Each gives ``scipy.stats``' or
``scipy.signal``'s number to the last bit on the arguments the diagnosis passes (tests/test_lightstats.py compares
them on grids that include the edges)."""
from __future__ import annotations

import sys

import numpy as np


def normal_sf(x: float) -> float:
    """``scipy.stats.norm.sf(x)``: P(Z > x) for a standard normal Z (``special.ndtr(-x)``)."""
    from scipy.special import ndtr

    return float(ndtr(-float(x)))


def normal_cdf(x: float) -> float:
    """``scipy.stats.norm.cdf(x)``: P(Z <= x) (``special.ndtr(x)``)."""
    from scipy.special import ndtr

    return float(ndtr(float(x)))


def normal_isf(q: float) -> float:
    """``scipy.stats.norm.isf(q)``: the z with P(Z > z) = q; inf at q = 0, -inf at q = 1, NaN outside [0, 1]."""
    from scipy.special import ndtri

    q = float(q)
    if q == 0.0:
        return np.inf
    if q == 1.0:
        return -np.inf
    if not 0.0 < q < 1.0:
        return np.nan
    return -float(ndtri(q)) + 0.0  # scipy adds the location 0 (a -0.0 at q = 0.5 becomes +0.0)


def poisson_sf(k: float, mu: float) -> float:
    """``scipy.stats.poisson.sf(k, mu)``: P(N > k) for N ~ Poisson(mu) (``special.pdtrc(floor(k), mu)``); 1 for
    k < 0, NaN for mu < 0 or NaN."""
    from scipy.special import pdtrc

    k, mu = float(k), float(mu)
    if not mu >= 0.0 or np.isnan(k):
        return np.nan
    if k < 0.0:
        return 1.0
    if k == np.inf:
        return 0.0
    return float(pdtrc(np.floor(k), mu))


def f_sf(x: float, dfn: float, dfd: float) -> float:
    """``scipy.stats.f.sf(x, dfn, dfd)``: the F distribution's upper tail (``special.fdtrc``); 1 at x <= 0, 0 at
    x = inf, NaN for degrees of freedom that are not positive."""
    from scipy.special import fdtrc

    x, dfn, dfd = float(x), float(dfn), float(dfd)
    if not (dfn > 0.0 and dfd > 0.0) or np.isnan(x):
        return np.nan
    if x <= 0.0:
        return 1.0
    if x == np.inf:
        return 0.0
    return float(fdtrc(dfn, dfd, x))


def average_ranks(a: np.ndarray) -> np.ndarray:
    """``scipy.stats.rankdata(a)`` of a 1-D array without NaN: ranks from 1, ties given their mean rank."""
    a = np.asarray(a)
    n = a.size
    order = np.argsort(a, kind="mergesort")
    sorted_a = a[order]
    new = np.empty(n, dtype=bool)  # the first of each group of equal values
    if n:
        new[0] = True
        np.not_equal(sorted_a[1:], sorted_a[:-1], out=new[1:])
    first = np.flatnonzero(new)
    ends = np.append(first[1:], n)  # one past each group's last position
    mean_rank = (first + 1 + ends) / 2.0  # positions first..ends-1 hold ranks first+1..ends
    ranks = np.empty(n, dtype=float)
    ranks[order] = np.repeat(mean_rank, ends - first)
    return ranks


def spearman_rho(a: np.ndarray, b: np.ndarray) -> float:
    """``scipy.stats.spearmanr(a, b).statistic`` for two 1-D samples: the Pearson correlation of their average ranks
    (``numpy.corrcoef``); NaN when either is constant, has a NaN, or there are fewer than two pairs."""
    x = np.column_stack((np.asarray(a), np.asarray(b)))
    if x.shape[0] <= 1:
        return np.nan
    if (x[:, 0][0] == x[:, 0]).all() or (x[:, 1][0] == x[:, 1]).all() or np.isnan(x).any():
        return np.nan
    ranked = np.column_stack((average_ranks(x[:, 0]), average_ranks(x[:, 1])))
    return float(np.corrcoef(ranked, rowvar=False)[1, 0])


LOWPASS_LOOP_ROWS = 50_000
"""``one_pole_lowpass`` runs its own loop up to this many rows while ``scipy.signal`` is not imported (50,000 rows of
3 columns: about 0.1 s, against 0.3-0.4 s for the import), ``lfilter`` above or once it is."""


def one_pole_lowpass(x: np.ndarray, w: float) -> np.ndarray:
    """``scipy.signal.lfilter([0, 1 - w], [1, -w], x, axis=0)`` for x (n, d): y[0] = 0, y[i] = w y[i-1] + (1 - w)
    x[i-1] (the state updated as lfilter's transposed direct form II does: (1 - w) x[i] - (-w) y[i], so the same
    numbers to the last bit)."""
    x = np.asarray(x, dtype=float)
    if x.shape[0] > LOWPASS_LOOP_ROWS or "scipy.signal" in sys.modules:
        from scipy.signal import lfilter

        return np.asarray(lfilter([0.0, 1.0 - w], [1.0, -w], x, axis=0))
    b1, a1 = 1.0 - w, -w
    out = np.empty_like(x)
    cols = x.T.tolist()
    for j, col in enumerate(cols):
        state = 0.0
        ys = [0.0] * len(col)
        for i, xi in enumerate(col):
            y = state + 0.0 * xi
            ys[i] = y
            state = b1 * xi - a1 * y
        out[:, j] = ys
    return out

"""``magbench.lightstats`` gives scipy.stats' and scipy.signal's numbers to the last bit (the diagnosis's verdicts must
not move because a one-off process skips their imports), on grids that include the edges; and a one-off ``diagnose``
of a plain record imports neither, while a record with spikes (whose tests are scipy.stats' rank and KS tests) does."""
import subprocess
import sys
import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import signal, stats

from magbench import lightstats as L


def same(a, b) -> bool:
    """Equal to the last bit, NaN equal to NaN, and the same sign of zero."""
    a, b = np.float64(a), np.float64(b)
    return bool(np.array_equal(a, b, equal_nan=True) and np.signbit(a) == np.signbit(b))


EDGES = [0.0, -0.0, np.inf, -np.inf, np.nan]


def test_normal_tails_are_scipys():
    for z in [*np.linspace(-40.0, 40.0, 4001), *EDGES]:
        assert same(L.normal_sf(z), stats.norm.sf(z)), z
        assert same(L.normal_cdf(z), stats.norm.cdf(z)), z
    qs = [*np.logspace(-300, 0, 3001), *np.random.default_rng(0).uniform(size=2000), 0.5, -0.1, 1.1, *EDGES]
    for q in qs:
        assert same(L.normal_isf(q), stats.norm.isf(q)), q


def test_poisson_and_f_tails_are_scipys():
    for k in range(-3, 60):
        for mu in [0.0, 1e-12, 1e-5, 0.3, 1.0, 2.5, 10.0, 40.0, 100.0, np.nan, -1.0]:
            for kk in (k, k + 0.5):
                assert same(L.poisson_sf(kk, mu), stats.poisson.sf(kk, mu)), (kk, mu)
    for x in [*np.logspace(-8, 4, 400), 0.0, -1.0, np.inf, np.nan]:
        for dfn in (1, 2, 8, 9, 20, 50):
            for dfd in (1.0, 3.0, 7.5, 100.0, 299.0, 1000.0):
                assert same(L.f_sf(x, dfn, dfd), stats.f.sf(x, dfn, dfd)), (x, dfn, dfd)


def test_spearman_is_scipys_with_ties_constants_and_nans():
    rng = np.random.default_rng(1)
    for trial in range(400):
        n = int(rng.integers(0, 300))
        a, b = rng.normal(size=n), rng.normal(size=n)
        if trial % 3 == 0:  # ties
            a, b = np.round(a, 1), np.round(np.abs(b), 0)
        if trial % 7 == 0 and n:
            b[:] = 1.0  # constant
        if trial % 11 == 0 and n:
            a[0] = np.nan
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            expected = stats.spearmanr(a, b).statistic
        assert same(L.spearman_rho(a, b), expected), trial
    ranks_ties = L.average_ranks(np.array([3.0, 1.0, 3.0, 2.0, 3.0]))
    assert ranks_ties.tolist() == [4.0, 1.0, 4.0, 2.0, 4.0]


@pytest.mark.parametrize("own_loop", [True, False], ids=["own-loop", "control-lfilter"])
def test_one_pole_lowpass_is_lfilters(monkeypatch, own_loop):
    """The loop (what a one-off process runs) and the path through lfilter both equal lfilter to the last bit."""
    if own_loop:  # the loop runs while scipy.signal is not imported (here it is): the module sees no modules
        monkeypatch.setattr(L, "sys", SimpleNamespace(modules={}))
    rng = np.random.default_rng(2)
    for _ in range(60):
        n = int(rng.integers(1, 2000))
        x = rng.normal(size=(n, 3)) * rng.choice([1.0, 1e4, 5e4]) + rng.choice([0.0, 5e4])
        w = float(np.exp(-1.0 / rng.uniform(0.5, 50.0)))
        assert np.array_equal(L.one_pole_lowpass(x, w), signal.lfilter([0.0, 1.0 - w], [1.0, -w], x, axis=0))


DIAGNOSE = """
import contextlib, io, sys
from magbench.benchmarks.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    code = main(["diagnose", {path!r}, "--json"])
print(code, "scipy.stats" in sys.modules, "scipy.signal" in sys.modules)
"""


@pytest.mark.parametrize("spikes", [False, True], ids=["plain", "control-spikes"])
def test_a_one_off_diagnose_skips_scipy_stats_and_signal(tmp_path, spikes):
    """Together 0.3-0.4 s of a one-off ``diagnose`` (about half of it) on a record that needs neither; the control,
    a record with spikes, runs scipy.stats' rank and Kolmogorov-Smirnov tests on them."""
    from magbench.simulate import simulate

    d = simulate("tumble9q", 0)
    raw = d.raw_nT.copy()
    if spikes:
        rows = np.random.default_rng(3).choice(len(raw), 12, replace=False)
        raw[rows] += 800.0
    path = tmp_path / "rec.csv"
    np.savetxt(path, np.column_stack([d.t_s, *raw.T, d.f_ref_nT]), delimiter=",", header="t,bx,by,bz,f_ref",
               comments="")
    out = subprocess.run([sys.executable, "-c", DIAGNOSE.format(path=str(path))], capture_output=True, text=True,
                         check=True)
    code, stats_loaded, signal_loaded = out.stdout.split()
    assert code == "0"
    assert stats_loaded == str(spikes)
    assert signal_loaded == "False"

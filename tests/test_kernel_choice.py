"""Which GA kernel runs (numba's compiled one or numpy's, the same numbers): numpy for a single short run
whose compile or cache load would cost more than the run, numba for a campaign or from a second run on,
and a one-line notice before a compile."""
from __future__ import annotations

import pytest

from magbench.calibrators.methods import _gakernel as K


@pytest.fixture(autouse=True)
def fresh(monkeypatch):
    monkeypatch.delenv(K.KERNEL_ENV, raising=False)
    monkeypatch.setattr(K, "_PREFER_COMPILED", [False])
    monkeypatch.setattr(K, "_RUNS", {})
    monkeypatch.setattr(K, "_LOADED", {})


def test_a_single_default_run_uses_numpy(monkeypatch):
    monkeypatch.setattr(K, "_cached_on_disk", lambda loops: True)
    assert K.choose(K._real_generation_loops, 1000, 80) == "numpy"  # 0.25 s of numpy < a 0.6 s cache load
    assert K.choose(K._real_generation_loops, 20000, 80) == "numba"  # 5 s of numpy > the load


def test_without_a_cache_only_a_long_run_compiles(monkeypatch):
    monkeypatch.setattr(K, "_cached_on_disk", lambda loops: False)
    assert K.choose(K._generation_loops, 20000, 80) == "numpy"  # 5 s < a 15 s compile
    assert K.choose(K._generation_loops, 200000, 80) == "numba"


def test_repeated_use_and_campaigns_use_numba(monkeypatch):
    monkeypatch.setattr(K, "_cached_on_disk", lambda loops: True)
    assert K.real_generation_kernel_for(1000, 80) is K.real_generation_numpy
    assert K.choose(K._real_generation_loops, 1000, 80) == "numba"  # the second run in this process
    K._RUNS.clear()
    K.prefer_compiled()
    assert K.choose(K._generation_loops, 10, 4) == "numba"


def test_the_environment_decides_when_set(monkeypatch):
    monkeypatch.setenv(K.KERNEL_ENV, "numpy")
    K.prefer_compiled()
    assert K.choose(K._generation_loops, 10**6, 80) == "numpy"
    monkeypatch.setenv(K.KERNEL_ENV, "numba")
    assert K.choose(K._generation_loops, 1, 2) == "numba"


def _tiny(a):
    return a + 1


def test_a_compile_is_announced_in_one_line(capsys, monkeypatch):
    pytest.importorskip("numba")
    monkeypatch.setattr(K, "_cached_on_disk", lambda loops: False)
    kernel = K._compiled(_tiny, lambda k: k(1.0), None)
    err = capsys.readouterr().err
    assert kernel(1.0) == 2.0
    assert err.count("\n") == 1 and "compiling the GA kernel" in err and "once per machine" in err
    monkeypatch.setattr(K, "_cached_on_disk", lambda loops: True)
    K._compiled(_tiny, lambda k: k(1.0), None)
    assert capsys.readouterr().err == ""  # a cache load is not announced


def test_the_index_of_numbas_cache_is_found():
    K.real_generation_kernel()  # compiled (or loaded) and cached on disk where numba can write
    pytest.importorskip("numba")
    assert K._cached_on_disk(K._real_generation_loops)
    assert not K._cached_on_disk(_tiny)


def test_a_campaign_announces_the_compiles_once_for_all_its_workers(capsys, monkeypatch):
    pytest.importorskip("numba")
    monkeypatch.delenv(K.NOTICE_ENV, raising=False)
    monkeypatch.setattr(K, "_cached_on_disk", lambda loops: False)
    assert K.announce_compiles({"lsq", "ga"})  # the parent, before its workers: the real-coded kernel only
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "real_generation_loops" in err
    assert K.NOTICE_ENV not in __import__("os").environ  # the parent's environment is left alone
    monkeypatch.setenv(K.NOTICE_ENV, "given")  # what the campaign's worker initializer sets
    K._compiled(_tiny, lambda k: k(1.0), None)  # a worker compiling: it stays quiet
    assert capsys.readouterr().err == ""
    monkeypatch.delenv(K.NOTICE_ENV)
    assert not K.announce_compiles({"lsq", "ellipsoid"})  # no GA: nothing said, workers not silenced
    assert capsys.readouterr().err == ""

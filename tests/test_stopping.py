"""Early stops of the population calibrators: cmaes and aco end a converged search instead of
burning a fixed budget, without losing quality against lsq's optimum; turning the stop off restores the
fixed budget.  And reproduce's per-phase wall-time report."""
import numpy as np
import pytest

from magbench.calibrators import make
from magbench.errors import InputError
from magbench.simulate import simulate


@pytest.fixture(scope="module")
def sphere9():
    return simulate("sphere9", 0)


@pytest.fixture(scope="module")
def lsq_rms(sphere9):
    return make("lsq", model="nine").fit(sphere9).rms_after_nT


def test_aco_stops_when_its_archive_has_converged(sphere9, lsq_rms):
    res = make("aco", model="nine", seed=0).fit(sphere9)
    assert res.status == "converged" and res.nit < 4000
    assert res.n_evaluations == 51 + 20 * res.nit  # the start, the archive, the ants
    assert abs(res.rms_after_nT / lsq_rms - 1) < 1e-5


def test_aco_tol_zero_runs_every_iteration(sphere9):
    res = make("aco", model="nine", seed=0, iterations=300, tol=0.0).fit(sphere9)
    assert res.status == "max_iterations" and res.nit == 300 and res.n_evaluations == 51 + 20 * 300


def test_aco_early_stop_is_the_same_search_cut_short(sphere9):
    """The stop only ends the loop: the same seed gives the same best point as the full run had then."""
    short = make("aco", model="nine", seed=3).fit(sphere9)
    full = make("aco", model="nine", seed=3, iterations=short.nit, tol=0.0).fit(sphere9)
    np.testing.assert_array_equal(short.params.to_vector("nine"), full.params.to_vector("nine"))


def test_aco_refuses_a_negative_tol(sphere9):
    with pytest.raises(InputError, match="tol"):
        make("aco", model="nine", tol=-1.0).fit(sphere9)


def test_cmaes_stops_on_the_relative_flatness(sphere9, lsq_rms):
    res = make("cmaes", model="nine", seed=0).fit(sphere9)
    assert res.status == "converged" and "tolfun_rel" in res.message
    assert abs(res.rms_after_nT / lsq_rms - 1) < 1e-5
    off = make("cmaes", model="nine", seed=0, tolfun_rel=0.0).fit(sphere9)
    assert "tolfun_rel" not in off.message and off.n_evaluations > res.n_evaluations


def test_cmaes_refuses_a_negative_tolfun_rel(sphere9):
    with pytest.raises(InputError, match="tolfun_rel"):
        make("cmaes", model="nine", tolfun_rel=-1.0).fit(sphere9)


def test_reproduce_reports_the_wall_time_of_each_phase(tmp_path):
    from magbench.benchmarks.reproduce import PhaseClock, write_timing

    clock = PhaseClock()
    clock.start("first")
    clock.start("second")
    clock.start("first")  # a phase entered twice adds up
    clock.stop()
    assert list(clock.seconds) == ["first", "second"] and all(s >= 0 for s in clock.seconds.values())
    text = write_timing(clock, tmp_path, jobs=2, quick=True).read_text()
    assert "| first |" in text and "| second |" in text and "| total |" in text and "--jobs 2" in text


def test_reproduce_times_seed_000_table_2s_diagnosis_under_its_phase(tmp_path, monkeypatch):
    """The diagnosis phase records how long Table 2's diagnosis takes (issue 17: at most 5 s), listed under the
    phase; a note outside any phase is dropped.  The blind check is stubbed (it has its own tests)."""
    import re

    from magbench.benchmarks import reproduce as rep

    monkeypatch.setattr(rep, "blind_check", lambda *a, **k: "(the blind check, stubbed)")
    clock = rep.PhaseClock()
    clock.note("outside", 1.0)
    clock.start("diagnosis")
    rep.diagnosis_reports(tmp_path, blind_n=2, clock=clock)
    clock.stop()
    label, seconds = clock.parts["diagnosis"][0]
    assert "Table 2" in label and 0 < seconds < 60
    lines = clock.lines()
    assert re.search(r"\| &nbsp;&nbsp;of which seed 000's Table 2 diagnosed \(5 s at most\) \| \d+\.\d \|", "\n".join(lines))
    assert not any("outside" in ln for ln in lines)

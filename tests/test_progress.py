"""Progress on stderr: plain periodic lines when stderr is not a terminal (no carriage returns in logs)."""
from __future__ import annotations

import io

from magbench.benchmarks import progress


def test_plain_lines_without_carriage_returns(monkeypatch):
    clock = iter(range(0, 1000, 3))  # each call of the clock: 3 s later
    monkeypatch.setattr(progress.time, "monotonic", lambda: float(next(clock)))
    out = io.StringIO()
    with progress.PlainProgress(20, "runs", "run", stream=out, every_s=10.0, show_after_s=2.0) as bar:
        for _ in range(20):
            bar.update(1)
    text = out.getvalue()
    assert "\r" not in text
    lines = text.splitlines()
    assert 2 <= len(lines) <= 8 and lines[-1].startswith("runs: 20/20 run (100 %)")
    assert len(set(lines)) == len(lines)  # the end is not printed twice


def test_a_resumed_bar_says_where_it_starts():
    out = io.StringIO()
    progress.PlainProgress(24, "runs", "run", initial=3, stream=out).close()
    assert out.getvalue().startswith("runs: 3/24 run (12 %) done earlier")


def test_a_short_phase_prints_nothing():
    out = io.StringIO()
    with progress.PlainProgress(5, "figures", "fig", stream=out) as bar:
        bar.update(5)
    assert out.getvalue() == ""


def test_the_kind_follows_stderr(monkeypatch):
    monkeypatch.setattr(progress.sys, "stderr", io.StringIO())  # not a terminal
    assert isinstance(progress.progress_bar(3, "x"), progress.PlainProgress)
    assert not isinstance(progress.progress_bar(3, "x", enabled=False), progress.PlainProgress)

    class Tty(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setattr(progress.sys, "stderr", Tty())
    assert type(progress.progress_bar(3, "x")).__name__ == "tqdm"


def test_a_slow_phase_says_so_and_a_fast_one_does_not():
    import time

    out = io.StringIO()
    with progress.slow_phase("fast", stream=out, after_s=0.5):
        pass
    assert out.getvalue() == ""
    with progress.slow_phase("slow work", stream=out, after_s=0.05):
        time.sleep(0.2)
    lines = out.getvalue().splitlines()
    assert lines[0] == "magbench: slow work ..." and lines[1].startswith("magbench: slow work: done in")
    quiet = io.StringIO()
    with progress.slow_phase("slow work", enabled=False, stream=quiet, after_s=0.01):
        time.sleep(0.05)
    assert quiet.getvalue() == ""


def test_the_comparison_tables_drawn_beside_the_figures_are_announced(tmp_path, capsys):
    """A campaign's comparison tables (prepared while the figures are drawn) took 30-50 s of a 16-method
    campaign with no line at all: the phase now says so, on one and on two processes."""
    import time

    from magbench.benchmarks.figures import make_figures

    for jobs in (1, 2):
        make_figures(tmp_path, formats=(), progress=True, jobs=jobs, prepare=lambda: time.sleep(2.3))
        err = capsys.readouterr().err
        assert "\r" not in err
        lines = err.splitlines()
        assert lines[0] == "magbench: the method comparison's tables (expected running times, ECDFs, paired tests) ..."
        assert lines[1].startswith("magbench: the method comparison's tables") and " done in " in lines[1]

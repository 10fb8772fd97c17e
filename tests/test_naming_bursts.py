"""Glitches that come in short bursts (an interference event, a garbled packet: a few consecutive samples) are
outliers, while runs of large residuals that rise and fall through their neighbours (the peaks of a structured
residual) or that sit where an axis reads most with the magnitude short (saturation) are not.  Records come from
the second independent forward model (tests/independent_forward2.py, its development cases 0-479), which shares
no code with the diagnosis."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import independent_cases  # noqa: E402

from magbench.benchmarks.diagnosis.naming import glitch_bursts, spike_runs, spikes_isolated  # noqa: E402


def run_case(index: int) -> tuple[dict, object]:
    return independent_cases.run_case(index, generator=2)


def burst_record(rng, rise: bool = False, n: int = 1500):
    """Noise of 1 nT with four runs of three spikes at random times (``rise``: each run flanked by samples at half
    its peak, as the peaks of a structured residual are); readings of a slowly turning sensor."""
    t = np.arange(n, dtype=float)
    r = rng.normal(0.0, 1.0, n)
    spikes = np.zeros(n, bool)
    for start in (180, 530, 910, 1270):
        spikes[start:start + 3] = True
        r[start:start + 3] += 60.0 * rng.choice([-1.0, 1.0])
        if rise:
            r[start - 1] += 0.5 * r[start + 1]
            r[start + 3] += 0.5 * r[start + 1]
    phase = 2 * np.pi * t / 400.0
    raw = 50000.0 * np.column_stack([np.cos(phase) * 0.8, np.sin(phase) * 0.8, np.full(n, 0.6)])
    return t, r, spikes, raw


def test_spike_runs_are_found_in_order():
    s = np.array([0, 1, 1, 0, 0, 1, 0, 1, 1, 1], bool)
    assert spike_runs(s) == [(1, 3), (5, 6), (7, 10)]


def test_short_abrupt_bursts_at_random_times_are_glitches():
    t, r, spikes, raw = burst_record(np.random.default_rng(3))
    assert not spikes_isolated(spikes, t, raw)[0]  # without the residual: runs, as before
    assert spikes_isolated(spikes, t, raw, r)[0]
    assert glitch_bursts(spikes, r, raw)


def test_negative_control_runs_that_rise_through_their_neighbours_are_structure():
    t, r, spikes, raw = burst_record(np.random.default_rng(3), rise=True)
    assert not glitch_bursts(spikes, r, raw)
    assert not spikes_isolated(spikes, t, raw, r)[0]


def test_negative_control_long_runs_and_runs_at_the_record_ends_are_not_bursts():
    t, r, spikes, raw = burst_record(np.random.default_rng(3))
    long = spikes.copy()
    long[530:545] = True
    r[530:545] = 60.0
    assert not glitch_bursts(long, r, raw)  # fifteen samples: a state of the sensor, not a glitch
    edge = spikes.copy()
    edge[:3] = True
    r[:3] = 60.0
    assert not glitch_bursts(edge, r, raw)  # its onset is not in the record


def test_negative_control_short_magnitudes_where_an_axis_reads_most_are_saturation():
    t, r, spikes, raw = burst_record(np.random.default_rng(3))
    for a, b in spike_runs(spikes):
        raw[a:b, 0] = 1.001 * np.abs(raw[:, 0]).max()  # the x axis at its largest reading ...
        r[a:b] = -60.0  # ... and the magnitude short
    assert not glitch_bursts(spikes, r, raw)


@pytest.mark.parametrize("index", [37, 62])  # glitches in bursts of two to four samples
def test_bursts_of_glitches_are_named_outliers(index):
    result, case = run_case(index)
    assert case.present == ("outliers",) and case.notes["effects"]["outliers"]["shape"] == "bursts"
    assert result["verdict"] == "outliers"


@pytest.mark.parametrize("index", [23, 244])  # readings clipped at a range limit, in short runs
def test_negative_control_clipped_runs_are_not_named_outliers(index):
    result, case = run_case(index)
    assert case.outside == ("range_clip",) and not case.present
    assert "outliers" not in result["verdict"] and result["verdict"] == "unexplained"

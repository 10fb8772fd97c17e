"""Readings clipped at a converter's rail (an axis stopping at its range, for every attitude beyond it) are no
library effect: left in, the diagnosis read them as structure at the attitudes nearest the axis and named
``nonlinearity`` (sphere9 and cap9 clipped at 80 % of an axis's largest reading: ``nonlinearity+unexplained``, a
wrong name, in 2 of 4 records).  ``floor.rail_rows`` finds them, the rest of the record is diagnosed, and the verdict
says ``unexplained`` beside what it names, the rails in ``clipped``."""
import hashlib
import subprocess
import sys

import numpy as np
import pytest

from magbench.benchmarks.diagnosis import diagnose, with_unexplained
from magbench.benchmarks.diagnosis.floor import rail_rows
from magbench.simulate import simulate
from magbench.simulate.dataset import Dataset


def _clipped(scenario: str, seed: int, axis: int = 0, share: float = 0.8) -> tuple[Dataset, int]:
    d = simulate(scenario, seed)
    raw = d.raw_nT.copy()
    lim = share * np.abs(raw[:, axis]).max()
    n_clipped = int((np.abs(raw[:, axis]) >= lim).sum())
    raw[:, axis] = np.clip(raw[:, axis], -lim, lim)
    return Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s, temp_C=d.temp_C), n_clipped


@pytest.mark.parametrize("scenario", ["sphere9", "cap9", "tumble9", "vehicle9"])
@pytest.mark.parametrize("seed", [0, 1])
def test_clipped_readings_are_left_out_and_said_unexplained(scenario, seed):
    data, n_clipped = _clipped(scenario, seed)
    report = diagnose(data)
    assert report["verdict"] == "unexplained", report["verdict"]
    assert report["clipped_rows_left_out"] == n_clipped
    assert {r["axis"] for r in report["clipped"]} == {"x"}
    assert "nonlinearity" not in report["verdict"]
    assert report["rms_base_nT"] < 3 * report["noise_floor_nT"]  # the rest is the sensor's noise


@pytest.mark.parametrize("scenario", ["sphere9", "cap9", "tumble9", "vehicle9"])
def test_intact_records_have_no_rail(scenario):
    """The negative control: a continuous reading takes its extreme value once."""
    data = simulate(scenario, 0)
    assert rail_rows(data.raw_nT) is None
    report = diagnose(data)
    assert "clipped" not in report and report["verdict"] == "none"


def test_a_coarse_grid_is_no_rail():
    """Readings rounded to 50 nT repeat every value; the extremes do not pile up beyond the other values."""
    raw = np.round(simulate("sphere9", 0).raw_nT / 50.0) * 50.0
    assert rail_rows(raw) is None


def test_an_attitude_held_at_an_extreme_is_no_rail():
    """Ten identical readings at the largest x, but at one attitude (a turntable's pause, noise below the grid):
    the other axes do not spread, so it is no rail."""
    raw = simulate("sphere9", 0).raw_nT.copy()
    top = int(np.argmax(raw[:, 0]))
    raw[:10] = raw[top]
    assert rail_rows(raw) is None


def test_the_command_says_which_rows_and_leaves_the_file_alone(tmp_path):
    path = tmp_path / "clipped.csv"
    _clipped("sphere9", 1)[0].to_csv(path)
    before = hashlib.sha1(path.read_bytes()).hexdigest()
    p = subprocess.run([sys.executable, "-m", "magbench", "diagnose", str(path)], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert "clipped readings:" in p.stdout and "verdict: unexplained" in p.stdout
    assert hashlib.sha1(path.read_bytes()).hexdigest() == before


def test_a_record_whose_rest_cannot_be_diagnosed_gets_the_whole_records_figures_and_no_name(tmp_path):
    """lu2014 clipped at 80 % of x: without the 16 clipped readings the turntable's attitudes determine nothing, so
    the whole record is diagnosed, clipped readings included, and nothing is named (exit 0, not a refusal: the
    input is a real record, and its clipping is the answer)."""
    data, n_clipped = _clipped("lu2014", 0)
    report = diagnose(data)
    assert report["clipped_rows_left_out"] == 0 and sum(r["rows"] for r in report["clipped"]) == n_clipped
    assert "the rest cannot be diagnosed" in report["clipped_statement"]
    assert report["verdict"] in ("unexplained", "insufficient_data") and report["selected"] == []
    path = tmp_path / "clipped_turntable.csv"
    data.to_csv(path)
    p = subprocess.run([sys.executable, "-m", "magbench", "diagnose", str(path)], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert "the rest cannot be diagnosed" in p.stdout


def test_a_second_axis_at_the_same_rail_is_clipped_too():
    """One converter range: z piles up at its rail, and x reaches the same level twice (too few to be found alone)."""
    raw = simulate("sphere9", 0).raw_nT.copy()
    level = 0.8 * np.abs(raw[:, 2]).max()
    raw[:, 2] = np.clip(raw[:, 2], -level, level)
    top = np.argsort(raw[:, 0])[-2:]
    raw[top, 0] = level
    mask, rails = rail_rows(raw)
    assert mask[top].all() and {r["axis"] for r in rails} == {"x", "z"}


@pytest.mark.parametrize("verdict, expected", [
    ("none", "unexplained"), ("unexplained", "unexplained"), ("insufficient_data", "insufficient_data"),
    ("lag", "lag+unexplained"), ("lag+unexplained", "lag+unexplained"),
    ("offset_drift|temperature", "offset_drift|temperature+unexplained")])
def test_with_unexplained(verdict, expected):
    assert with_unexplained(verdict) == expected


def test_the_figure_shows_the_rows_the_verdict_is_about(tmp_path):
    """The residual figure is drawn on the rows diagnosed (it had shown the clipped readings' 6000 nT beside a
    verdict about the others), and its title says how many were left out."""
    from magbench.benchmarks.diagnosis import diagnosed_rows

    data, n_clipped = _clipped("sphere9", 1)
    report = diagnose(data)
    assert len(diagnosed_rows(data, report)) == report["n_points"] == len(data) - n_clipped
    intact = simulate("sphere9", 1)
    assert diagnosed_rows(intact, diagnose(intact)) is intact
    path = tmp_path / "clipped.csv"
    data.to_csv(path)
    figure = tmp_path / "clipped.png"
    p = subprocess.run([sys.executable, "-m", "magbench", "diagnose", str(path), "--figure", str(figure)],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert figure.stat().st_size > 10_000

"""The sim-to-real diagnosis, checked blind: each dataset carries a randomly drawn effect (or none) that
the diagnosis is not told."""
import json
import subprocess
import sys
from dataclasses import replace
from importlib import resources

import numpy as np
import pytest

from magbench.benchmarks.diagnosis import Diagnosis, blind_dataset, diagnose
from magbench.calibrators import make
from magbench.simulate.effects import effect_names, random_effect
from magbench.simulate.scenarios import get_scenario


def blind_case(i: int):
    return blind_dataset(i)


def ground_truth_shrink(data, base: str, result: dict) -> float:
    """The share of the gap removed when the true effect is taken out: the same readings with the same
    noise but no effect, calibrated with the base model on the same folds."""
    clean = replace(data, raw_nT=data.truth.raw_without_effects_nT, f_ref_nT=np.linalg.norm(
        data.truth.field_ned_nT) * np.ones(len(data)))
    rms_clean = Diagnosis(clean, base).heldout_base(make("lsq", model=base).fit(clean).x).rms_nT
    return 100.0 * (result["rms_base_nT"] - rms_clean) / (result["rms_base_nT"] - data.truth.sensor.noise_nT)


@pytest.fixture(scope="module")
def blind():
    cases = []
    for i in range(42):
        kind, base, data = blind_case(i)
        result = diagnose(data, base=base)  # the data only: the truth is not passed
        cases.append((kind, base, data, result))
    return cases


def test_blind_verdicts_are_at_least_90_percent_correct(blind):
    wrong = [(k, r["verdict"]) for k, _, _, r in blind if r["verdict"] != k]
    assert 1 - len(wrong) / len(blind) >= 0.9, wrong


def test_blind_shrinkage_of_the_true_effect_matches_the_ground_truth(blind):
    checked = 0
    for kind, base, data, result in blind:
        if kind == "none" or result["verdict"] != kind:
            continue
        reported = next(e for e in result["effects"] if e["name"] == kind)["shrink_pct"]
        truth = ground_truth_shrink(data, base, result)
        assert abs(reported - truth) <= 0.15 * truth, (kind, reported, truth)
        checked += 1
    assert checked >= 25


def test_an_effect_outside_the_library_is_not_claimed():
    rng = np.random.default_rng(77)
    for i in range(6):
        effect = random_effect("attitude_ripple", rng)
        data = get_scenario("tumble9q").with_effects(effect).build(500 + i)
        result = diagnose(data, base="nine")
        assert result["verdict"] not in effect_names(in_library=True), (effect, result["verdict"], result["effects"][:2])


def test_clean_data_gives_none_and_json_keys():
    result = diagnose(get_scenario("tumble9q").build(3), base="nine")
    assert result["verdict"] == "none"
    for key in ("base_model", "rms_base_nT", "noise_floor_nT", "verdict", "effects"):
        assert key in result
    for e in result["effects"]:
        assert {"name", "rms_heldout_nT", "shrink_pct", "significant"} <= set(e)
    json.dumps(result)


def test_resimulation_with_the_fitted_effect_matches_the_observation(blind):
    for kind, base, data, result in blind:
        if kind in ("temperature", "offset") and result["verdict"] == kind:
            rs = result["resimulation"]
            assert rs["remaining_gap_pct"] < 15.0, rs
            assert rs["gap_without_effect_pct"] > 50.0, rs


def test_diagnose_command_on_the_paper_table2_scalar_series(tmp_path):
    path = resources.files("magbench.simulate").joinpath("data/lu2014_table2.csv")
    fig = tmp_path / "t2.png"
    p = subprocess.run([sys.executable, "-m", "magbench.benchmarks.cli", "diagnose", str(path), "--json", "--figure", str(fig)],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    h = out["localization"]["heading_harmonics"]
    assert h["2_per_rev_nT"] > 3 * h["1_per_rev_nT"]  # the paper's calibration leaves mostly 2 cycles/rev
    assert out["verdict"] == "scale" and fig.is_file()
    assert abs(out["rms_fit_nT"] - 57.81) < 0.01  # the RMS of the printed errors (PROVENANCE.md)


def test_diagnose_refuses_bad_input_in_one_line(tmp_path):
    csv = tmp_path / "noref.csv"
    data = get_scenario("tumble9q").build(1)
    replace(data, f_ref_nT=None, meta={}).to_csv(csv)
    p = subprocess.run([sys.executable, "-m", "magbench.benchmarks.cli", "diagnose", str(csv), "--no-figure"],
                       capture_output=True, text=True)
    assert p.returncode == 2 and "reference" in p.stderr and len(p.stderr.strip().splitlines()) == 1

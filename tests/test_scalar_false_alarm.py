"""A clean scalar series is ``none`` at the diagnosis's stated level: the floor of a short series is itself uncertain,
and the fixed factor 1.5 alone had called 25 clean 2 x 12-row series in 200 ``unexplained``."""
import numpy as np

from magbench.benchmarks.diagnosis import diagnose
from magbench.benchmarks.diagnosis.scalar import SCALAR_FALSE_ALARM, UNEXPLAINED_SIZE
from magbench.simulate.dataset import ScalarSeries


def _series(seed: int, rows: int = 24, structure_nT: float = 0.0) -> ScalarSeries:
    """Two turns of the table, white noise of 0.5 nT about the file's calibration, and (``structure_nT``) a slow
    wave in time that no library effect has (2.5 periods over the record: no heading harmonic, no cubic in time)."""
    rng = np.random.default_rng(seed)
    heading = np.tile(np.arange(0.0, 360.0, 720.0 / rows), 2)
    i = np.arange(rows)
    wave = structure_nT * np.sin(2 * np.pi * 2.5 * i / rows + rng.uniform(0, 2 * np.pi))
    return ScalarSeries(f_meas_nT=5e4 + wave + rng.normal(0.0, 0.5, rows), heading_deg=heading,
                        f_ref_nT=np.full(rows, 5e4), t_s=10.0 * i)


def test_clean_short_series_are_none_at_the_stated_level():
    verdicts = [diagnose(_series(seed))["verdict"] for seed in range(100)]
    assert set(verdicts) <= {"none", "unexplained"}  # nothing named on white noise
    # 1 % expected; at most 4 of 100 (the fixed factor alone: 8 of these 100)
    assert verdicts.count("unexplained") <= 4, verdicts.count("unexplained")


def test_structure_well_above_the_floor_is_still_unexplained_and_the_limit_is_in_the_json():
    """Control: a wave of 3 nT (4 times the noise in RMS) is unexplained in every series."""
    outs = [diagnose(_series(seed, structure_nT=3.0)) for seed in range(20)]
    assert all(o["verdict"] == "unexplained" for o in outs)
    limits = outs[0]["unexplained_limits"]
    assert limits["false_alarm"] == SCALAR_FALSE_ALARM == 0.01
    assert 1.8 < limits["base_over_floor"] < 2.5 and limits["base_over_floor"] >= UNEXPLAINED_SIZE  # 24 rows: 2.06


def test_an_exactly_constant_residual_names_nothing():
    """f_meas 3 nT above f_ref on every row: the floor had been 0 and the rounding of the leave-one-out residuals
    (1e-16 nT) had named an offset (z 3e16).  Control: the same with a real once-per-turn offset names it."""
    heading = np.arange(0.0, 360.0, 15.0)
    ref = np.full(24, 5e4)
    flat = diagnose(ScalarSeries(f_meas_nT=ref + 3.0, heading_deg=heading, f_ref_nT=ref))
    assert flat["verdict"] == "none" and "rounding" in flat["floor_method"]
    turning = ref + 3.0 + 30.0 * np.cos(np.radians(heading))
    assert diagnose(ScalarSeries(f_meas_nT=turning, heading_deg=heading, f_ref_nT=ref))["verdict"].startswith("offset")


def test_headings_a_thousandth_of_a_degree_apart_count_as_one():
    """Four headings taken three times each, 0.001 degree apart, had counted as 12 different headings and been
    diagnosed with a floor of 48 nT from the jumps between them (a 40 nT twice-per-turn error: none).  Control: twelve
    headings 30 degrees apart."""
    import pytest

    from magbench.errors import InputError

    clustered = np.concatenate([q + 1e-3 * np.arange(3) for q in (0.0, 90.0, 180.0, 270.0)])
    f = 5e4 + 40 * np.cos(np.radians(2 * clustered))
    with pytest.raises(InputError, match="only 4 different heading"):
        diagnose(ScalarSeries(f_meas_nT=f, heading_deg=clustered, f_ref_nT=np.full(12, 5e4)))
    spread = np.arange(0.0, 360.0, 30.0)
    noise = np.random.default_rng(0).normal(0, 0.5, 12)
    out = diagnose(ScalarSeries(f_meas_nT=5e4 + 40 * np.cos(np.radians(2 * spread)) + noise, heading_deg=spread,
                                f_ref_nT=np.full(12, 5e4)))
    assert out["verdict"].startswith("scale")

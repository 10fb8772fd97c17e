"""One glitch far beyond the noise (one reading of 300 off by 10^5 nT) barely moves the remainder's mean-square test
(its spread is the glitch's own: z 1.1), is too few for the outliers effect, and the record came back ``none``.  A
residual beyond what noise at the floor reaches in n samples (sqrt(2 ln n) + EXTREME_MARGIN_SIGMA floors) now makes
the remainder significant (``remainder_extreme`` says so), so the verdict is ``unexplained``."""
import numpy as np

from magbench.benchmarks.diagnosis import diagnose
from magbench.simulate import simulate
from magbench.simulate.dataset import Dataset


def _record(glitches=(), factor=3.0):
    d = simulate("sphere9", 2)
    raw = d.raw_nT.copy()
    raw[list(glitches)] *= factor
    return Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s)


def test_one_huge_glitch_is_not_none():
    report = diagnose(_record([100]))
    assert report["verdict"] == "unexplained"
    extreme = report["remainder_extreme"]
    assert extreme["worst_nT"] > 5e4 > extreme["bound_nT"]
    assert report["remainder_significant"]


def test_the_same_record_without_it_is_none():
    """The negative control: no glitch, nothing extreme, ``none``."""
    report = diagnose(_record())
    assert report["verdict"] == "none" and "remainder_extreme" not in report


def test_glitches_the_outliers_effect_names_are_outliers_not_an_extreme_remainder():
    """Ten glitches at random times (3 % of the samples) are what the outliers effect is for: named, and their
    residuals are its."""
    rows = np.sort(np.random.default_rng(4).choice(300, 10, replace=False))
    report = diagnose(_record(rows, factor=1.02))
    assert report["verdict"] == "outliers" and "remainder_extreme" not in report


def test_glitches_at_equal_intervals_are_not_outliers_and_not_none():
    """Ten glitches every 30 samples recur like an interference with a period, which the outliers effect refuses
    (CONTRACT); what they leave is unexplained, not ``none``."""
    report = diagnose(_record(np.arange(5, 300, 30), factor=1.02))
    assert report["verdict"] == "unexplained" and report["remainder_extreme"]["worst_nT"] > 500

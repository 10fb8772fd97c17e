"""The method-comparison statistics (magbench.benchmarks.comparison) on hand-made runs whose answers are
known, and on a small real campaign."""
import math

import numpy as np
import pandas as pd
import pytest

from magbench.benchmarks import comparison as cmp


def test_holm_matches_the_step_down_definition():
    p = np.array([0.01, 0.04, 0.03, 0.005])
    # sorted: 0.005*4 = 0.02, 0.01*3 = 0.03, 0.03*2 = 0.06, 0.04*1 = 0.04 -> monotone 0.06
    assert cmp.holm(p) == pytest.approx([0.03, 0.06, 0.06, 0.02])


def _runs(values: dict, n_eval=100, runtime=0.1):
    rows = []
    for conf, rms in values.items():
        for trial, v in enumerate(rms):
            rows.append({"scenario": "s", "method": conf.split()[0], "configuration": conf, "trial": trial,
                         "error": "", "n_evaluations": n_eval, "runtime_s": runtime, "rms_after_nT": v,
                         "evaluation_mode": "counted"})
    return pd.DataFrame(rows)


def test_ert_counts_unsuccessful_runs_like_coco():
    runs = _runs({"lsq": [1.0, 1.0, 1.0, 1.0], "ga": [1.0, 50.0, 1.0, 50.0]}, n_eval=100)
    traces = pd.DataFrame([
        {"scenario": "s", "configuration": "ga", "trial": t, "evaluations": e, "best_F": f}
        for t in range(4) for e, f in ((10, 1e4), (40, 2500.0 if t % 2 else 1.0), (100, 2500.0 if t % 2 else 1.0))])
    hits = cmp.hitting_times(runs, traces)
    ert = cmp.expected_running_time(hits)
    row = ert[(ert.configuration == "ga") & (ert.kind == "rms") & (ert.target == 2.0)].iloc[0]
    # two runs reach 2x the optimum after 40 evaluations, two never do and spend 100 each: (40+40+100+100)/2
    assert row.n_reached == 2 and row.ert_evaluations == pytest.approx(140.0)
    lsq = ert[(ert.configuration == "lsq") & (ert.target == 1.001)].iloc[0]
    assert lsq.success_rate == 1.0


def test_ecdf_is_monotone_and_ends_at_the_success_fraction():
    runs = _runs({"lsq": [1.0] * 4, "ga": [1.0, 50.0, 1.0, 50.0]})
    curves = cmp.ecdf(cmp.hitting_times(runs, None))
    ga = curves[curves.configuration == "ga"].sort_values("evaluations")
    assert np.all(np.diff(ga.fraction) >= 0)
    assert ga.fraction.iloc[-1] == pytest.approx(0.5)


def test_paired_test_finds_a_clearly_better_method_and_warns_with_few_trials():
    rng = np.random.default_rng(0)
    good = 1.0 + 0.01 * rng.random(20)
    runs = _runs({"lsq": good, "ga": good + 0.5 + 0.01 * rng.random(20)})
    tests, wins = cmp.paired_tests(runs)
    t = tests.iloc[0]
    assert t.significant and t.better == "lsq" and t.warning == ""
    assert wins[(wins.row == "lsq") & (wins.column == "ga")].win_rate.iloc[0] == 1.0
    few, _ = cmp.paired_tests(_runs({"lsq": good[:5], "ga": good[:5] + 0.5}))
    assert not few.iloc[0].significant and "too few" in few.iloc[0].warning
    assert t.verdict == "lsq better" and t.margin_nT == pytest.approx(0.01 * np.median(good), rel=1e-6)


def test_a_significant_but_tiny_difference_is_equivalent_not_better():
    """lsq 'better' than ga at a median of 4e-8 nT was no finding: below the practical margin (1 % of the
    optimum RMS), two one-sided tests call the pair equivalent."""
    rng = np.random.default_rng(1)
    good = 2.0 + 0.1 * rng.random(30)
    runs = _runs({"lsq": good, "ga": good + 4e-8 * (1 + rng.random(30))})
    t = cmp.paired_tests(runs)[0].iloc[0]
    assert t.significant and t.better == "" and t.verdict == "equivalent"
    # negative control: a difference of 10 % of the optimum is a practical one
    far = cmp.paired_tests(_runs({"lsq": good, "ga": good * 1.1}))[0].iloc[0]
    assert far.verdict == "lsq better"


def test_performance_profile_gives_the_best_method_one_at_tau_one():
    ert = pd.DataFrame([
        {"scenario": s, "configuration": c, "kind": "rms", "target": cmp.PROFILE_TARGET, "ert_evaluations": v,
         "closed_form": False}
        for s, vals in (("a", {"x": 10, "y": 100}), ("b", {"x": 50, "y": 25})) for c, v in vals.items()])
    prof = cmp.performance_profile(ert)
    at1 = prof[prof.tau == 1.0].set_index("configuration").fraction
    assert at1["x"] == 0.5 and at1["y"] == 0.5
    at10 = prof[prof.tau >= 10].groupby("configuration").fraction.min()
    assert at10["x"] == 1.0 and at10["y"] == 1.0


def test_write_comparison_on_a_campaign(tmp_path):
    from magbench.benchmarks.campaign import Campaign, MethodSpec, run_campaign

    run_campaign(Campaign(("lu2014",), (MethodSpec("lsq"), MethodSpec("cmaes", (("max_evaluations", 600),))),
                          trials=3, seed=1), tmp_path, progress=False)
    written = cmp.write_comparison(tmp_path)
    names = {p.name for p in written}
    assert {"ert.csv", "ecdf.csv", "anytime.csv", "profile.csv", "paired_tests.csv", "win_rate.csv",
            "comparison.md", "ecdf.png", "anytime.png", "profile.png"} <= names
    text = (tmp_path / "comparison.md").read_text()
    assert "too few trials" in text and "| calibrator |" in text
    ert = pd.read_csv(tmp_path / "comparison" / "ert.csv")
    # lsq's answer is each trial's optimum, so it reaches every RMS target; the angle targets (multiples of the
    # Cramér-Rao deviation) are met by chance at the tightest level
    assert (ert[(ert.configuration == "lsq") & (ert.kind == "rms")].success_rate == 1).all()
    assert not math.isnan(ert.ert_evaluations.iloc[0])


def test_budgets_expand_iterative_methods_and_force_clears_the_comparison(tmp_path, capsys):
    from magbench.benchmarks.cli import main

    out = tmp_path / "c"
    assert main(["compare", "--scenarios", "sphere9", "--methods", "lsq", "ga", "ellipsoid", "--budgets", "100",
                 "1000", "--trials", "2", "--out", str(out), "--quiet", "--no-figures"]) == 0
    runs = pd.read_csv(out / "runs.csv", keep_default_na=False)
    assert set(runs.configuration) == {"ellipsoid", "ga budget=100", "ga budget=1000", "lsq budget=100",
                                       "lsq budget=1000"}
    ga = runs[runs.configuration == "ga budget=100"]
    assert (ga.n_evaluations <= 100).all()
    assert (out / "comparison" / "ert.csv").is_file()
    stale = out / "comparison" / "mine.txt"
    stale.write_text("not the campaign's")
    assert main(["compare", "--scenarios", "sphere9", "--methods", "lsq", "--trials", "2", "--out", str(out),
                 "--quiet", "--no-figures", "--force"]) == 0
    assert stale.is_file()  # --force clears only what the campaign writes
    assert main(["compare", "--scenarios", "sphere9", "--methods", "lsq", "--budgets", "0", "--trials", "2",
                 "--out", str(tmp_path / "d")]) == 2


@pytest.mark.parametrize("kind", ["continuous", "ties", "zeros", "large"])
def test_signed_rank_p_is_scipys_wilcoxon_with_split_zeros(kind):
    """The paired tests' own signed-rank p-value equals scipy.stats.wilcoxon(zero_method='zsplit') in each of
    its regimes: exact (no ties, n <= 50), exact over sign flips (ties or zeros, n <= 13), normal.  SciPy's own
    sign-flip test takes 0.25 s at n = 9 and 3 s at n = 13 with ties or zeros (a permutation test per alternative):
    there, one sample of the regime's last size rather than six (the test had taken 95 s of CI's 17 min)."""
    from scipy.stats import wilcoxon

    rng = np.random.default_rng({"continuous": 1, "ties": 2, "zeros": 3, "large": 4}[kind])
    for n in (1, 2, 5, 9, 13, 14, 20, 50, 51, 80):
        for _ in range(1 if n == 13 and kind in ("ties", "zeros") else 6):
            d = rng.standard_normal(n) + rng.normal() * 0.7
            if kind == "ties":
                d = np.round(d * 2) / 2
            elif kind == "zeros":
                d = rng.integers(-2, 3, n).astype(float)
            elif kind == "large":
                d = d * 1e-3 + 0.05
            if not np.any(d != 0):
                continue
            for alternative in ("two-sided", "greater", "less"):
                expected = float(wilcoxon(d, zero_method="zsplit", alternative=alternative).pvalue)
                assert cmp.signed_rank_p(d, alternative) == pytest.approx(expected, rel=1e-12, abs=1e-300), \
                    (n, alternative, d)


def test_signed_rank_p_rejects_an_unknown_alternative_and_is_nan_without_data():
    with pytest.raises(ValueError, match="alternative"):
        cmp.signed_rank_p(np.array([1.0, -2.0]), "bigger")
    assert math.isnan(cmp.signed_rank_p(np.array([])))

"""The harness: determinism, local processes and Dask give the same table, failures are rows."""
import json

import numpy as np
import pandas as pd
import pytest

from magbench.benchmarks.campaign import Campaign, MethodSpec, run_campaign
from magbench.benchmarks.tables import summarize

RUNTIME = ["runtime_s", "median_runtime_s"]


def small_campaign(**kw):
    methods = ("lsq", "ellipsoid", "nlopt", "aga-lm:max_generations=60:k_max=60", "ransac:sample_size=40")
    return Campaign(("lu2014", "sphere9"), tuple(MethodSpec.parse(m) for m in methods), trials=3, seed=11, **kw)


def _table(path):
    frame = pd.read_csv(path, keep_default_na=False)
    return frame.drop(columns=[c for c in RUNTIME if c in frame])


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    run_campaign(small_campaign(), out, jobs=1, progress=False)
    return out


def test_same_command_and_seed_give_identical_tables(serial, tmp_path):
    run_campaign(small_campaign(), tmp_path, jobs=1, progress=False)
    for name in ("runs.csv", "summary.csv", "traces.csv", "fields.csv"):
        pd.testing.assert_frame_equal(_table(serial / name), _table(tmp_path / name))
    a, b = (json.loads((d / "manifest.json").read_text()) for d in (serial, tmp_path))
    assert a["root_seed"] == b["root_seed"] == 11 and a["configurations"] == b["configurations"]


def test_other_seed_other_numbers(serial, tmp_path):
    c = small_campaign()
    run_campaign(Campaign(c.scenarios, c.methods, trials=3, seed=12), tmp_path, progress=False)
    assert not _table(serial / "runs.csv")["alpha_rad"].equals(_table(tmp_path / "runs.csv")["alpha_rad"])


def test_two_local_processes_give_the_same_table(serial, tmp_path):
    run_campaign(small_campaign(), tmp_path, jobs=2, progress=False)
    pd.testing.assert_frame_equal(_table(serial / "runs.csv"), _table(tmp_path / "runs.csv"))


def test_dask_local_cluster_gives_the_same_table(serial, tmp_path):
    import distributed  # a test dependency: the Dask path must be exercised, never skipped
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        run_campaign(small_campaign(), tmp_path, dask_address=cluster.scheduler_address, progress=False)
    pd.testing.assert_frame_equal(_table(serial / "runs.csv"), _table(tmp_path / "runs.csv"))


def test_failed_run_is_a_row_not_a_crash(serial):
    runs = pd.read_csv(serial / "runs.csv", keep_default_na=False)
    # a run that fails on its data (a sample of 40 of 300 readings is more than RANSAC's n/10): sphere9's 3
    # trials (lu2014 is an angles scenario, which ransac does not estimate); a configuration that can never
    # run is refused before the campaign (tests/test_params.py)
    bad = runs[runs["configuration"] == "ransac sample_size=40"]
    assert len(bad) == 3 and (bad["error"].str.contains("sample size q = 40 is outside")).all()
    good = runs[runs["configuration"] == "lsq"]
    assert (good["error"] == "").all()
    manifest = json.loads((serial / "manifest.json").read_text())
    assert {"scenario": "lu2014", "configuration": "ellipsoid",
            "reason": "ellipsoid does not estimate the angles model"} in manifest["skipped"]


def test_each_run_has_its_own_seed_and_methods_share_the_data(serial):
    runs = pd.read_csv(serial / "runs.csv", keep_default_na=False)
    assert runs["seed"].is_unique
    per_trial = runs.groupby(["scenario", "trial"])["data_seed"].nunique()
    assert (per_trial == 1).all()


def test_lsq_efficiency_against_the_bound(tmp_path):
    runs = run_campaign(Campaign(("sphere9",), (MethodSpec("lsq"),), trials=200, seed=5, traces=False), tmp_path,
                        jobs=2, progress=False)
    s = summarize(runs).iloc[0]
    assert s["efficiency_min_angle"] > 0.8, s[["efficiency_alpha", "efficiency_beta", "efficiency_gamma"]]
    assert np.isclose(s["success_rate"], 1.0)


def test_compare_command_writes_tables_figures_and_report(tmp_path):
    from magbench.benchmarks.cli import main

    out = tmp_path / "camp"
    assert main(["compare", "--scenarios", "lu2014", "--methods", "lsq", "nlopt", "--trials", "2", "--seed", "1",
                 "--out", str(out), "--quiet"]) == 0
    for name in ("runs.csv", "summary.csv", "summary.md", "summary.tex", "manifest.json", "report.html",
                 "figures/errors_lu2014.png", "figures/errors_lu2014.svg", "figures/field_heading_lu2014.png",
                 "figures/convergence_lu2014.svg"):
        assert (out / name).is_file(), name
    html = (out / "report.html").read_text()
    assert "data:image/png;base64," in html and "http://" not in html and "https://" not in html
    png = (out / "figures" / "errors_lu2014.png").read_bytes()
    from magbench.benchmarks.figures import make_figures

    make_figures(out)
    assert (out / "figures" / "errors_lu2014.png").read_bytes() == png
    # a second campaign into the same directory is refused, the first one kept
    assert main(["compare", "--scenarios", "lu2014", "--methods", "lsq", "--out", str(out), "--quiet"]) == 2
    assert (out / "report.html").read_text() == html


def test_lu2014_tables_from_a_campaign(tmp_path):
    """reproduce's seed 000 tables read the shipped Table 2 through the package and a campaign's runs."""
    from magbench.benchmarks.campaign import Campaign, MethodSpec, run_campaign
    from magbench.benchmarks.reproduce import lu2014_tables, paper_table2

    assert len(paper_table2()) == 35
    run_campaign(Campaign(("lu2014",), (MethodSpec("lsq"),), trials=2, seed=3), tmp_path, progress=False)
    text = lu2014_tables(tmp_path, tmp_path / "lu.md").read_text()
    assert "Table 1" in text and "Table 2" in text and "lsq" in text


def _rows(frame, scenarios, configurations):
    keep = frame[frame["scenario"].isin(scenarios) & frame["configuration"].isin(configurations)]
    keep = keep.drop(columns=[c for c in RUNTIME if c in keep]).dropna(axis=1, how="all")
    return keep[sorted(keep.columns)].sort_values(["scenario", "configuration", "trial"]).reset_index(drop=True)


def test_seeds_follow_identity_not_list_position(tmp_path):
    """Reordering scenarios and methods, and adding one of each, leaves every shared run identical."""
    a = Campaign(("lu2014", "sphere9"), tuple(MethodSpec.parse(m) for m in ("lsq", "aco:iterations=30")),
                 trials=2, seed=5)
    b = Campaign(("cap9", "sphere9", "lu2014"),
                 tuple(MethodSpec.parse(m) for m in ("ga:generations=20", "aco:iterations=30", "lsq")),
                 trials=2, seed=5)
    ra = run_campaign(a, tmp_path / "a", jobs=1, progress=False)
    rb = run_campaign(b, tmp_path / "b", jobs=1, progress=False)
    shared = (["lu2014", "sphere9"], ["lsq", "aco iterations=30"])
    left, right = _rows(ra, *shared), _rows(rb, *shared)
    assert len(left) == 8
    pd.testing.assert_frame_equal(left, right)
    # negative control: another root seed changes the shared runs
    c = Campaign(a.scenarios, a.methods, trials=2, seed=6)
    rc = run_campaign(c, tmp_path / "c", jobs=1, progress=False)
    assert not np.allclose(_rows(rc, *shared)["rms_after_nT"], left["rms_after_nT"])


def test_resume_with_added_methods_runs_only_the_new_configurations(tmp_path):
    methods = ("lsq", "ellipsoid")
    first = Campaign(("lu2014", "sphere9"), tuple(MethodSpec.parse(m) for m in methods), trials=2, seed=9)
    ra = run_campaign(first, tmp_path, jobs=1, progress=False)
    grown = Campaign(first.scenarios, first.methods + (MethodSpec.parse("tls"),), trials=2, seed=9)
    rb = run_campaign(grown, tmp_path, jobs=1, progress=False, resume=True)
    assert rb.attrs["n_resumed"] == len(ra) and rb.attrs["n_new"] == 2  # tls on sphere9 only (nine-parameter)
    assert set(rb["configuration"]) == {"lsq", "ellipsoid", "tls"}
    pd.testing.assert_frame_equal(_rows(rb, first.scenarios, methods), _rows(ra, first.scenarios, methods))
    assert json.loads((tmp_path / "manifest.json").read_text())["campaign"]["configurations"] == \
        ["lsq", "ellipsoid", "tls"]
    # another seed is not a grown campaign: refused
    with pytest.raises(Exception, match="another campaign"):
        run_campaign(Campaign(first.scenarios, grown.methods, trials=2, seed=10), tmp_path, jobs=1,
                     progress=False, resume=True)


def test_a_campaign_beyond_the_run_limit_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    """--trials 100000000 (a typed zero or two too many) built task descriptions for hours and gigabytes before
    the first run; it is refused at once (exit 2, the limit named, no folder made).  The limit counts scenarios x
    methods x trials (checked at a small limit: the campaign at it runs, one run more is refused)."""
    from magbench.benchmarks import campaign as campaign_module
    from magbench.benchmarks.cli import main as cli_main
    from magbench.errors import InputError

    out = tmp_path / "big"
    assert cli_main(["compare", "--scenarios", "sphere9", "tumble9", "--methods", "lsq", "ga", "--trials", "100000000",
                     "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "400,000,000 runs" in err and "limit of 1,000,000" in err and not out.exists()
    monkeypatch.setattr(campaign_module, "MAX_RUNS", 4)
    assert len(Campaign(("sphere9",), (MethodSpec("lsq"), MethodSpec("ga")), trials=2).tasks()[0]) == 4
    with pytest.raises(InputError, match="more than the limit of 4 runs"):
        Campaign(("sphere9",), (MethodSpec("lsq"),), trials=5).tasks()


def test_a_campaign_of_no_runs_is_refused_before_anything_is_written(tmp_path, capsys):
    """No scenario, no method, no trial, or only methods that do not apply to the scenarios: the tables of
    nothing were written and called a complete campaign, and the CLI's output phase then failed with pandas'
    EmptyDataError (exit 1).  Refused with the reason, and nothing written; one applicable pair runs (the control)."""
    from magbench.benchmarks.cli import main as cli_main
    from magbench.errors import InputError

    for camp in (Campaign((), (MethodSpec("lsq"),), trials=2), Campaign(("sphere9",), (), trials=2),
                 Campaign(("sphere9",), (MethodSpec("lsq"),), trials=0)):
        with pytest.raises(InputError, match="at least one scenario, one method and one trial"):
            run_campaign(camp, tmp_path / "none", progress=False)
    assert not (tmp_path / "none").exists()
    out = tmp_path / "skipped"
    assert cli_main(["compare", "--scenarios", "lu2014", "--methods", "merayo", "--trials", "2", "--out", str(out),
                     "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "no method of the campaign applies" in err and "merayo does not estimate the angles model" in err
    assert not out.exists()
    assert len(Campaign(("lu2014",), (MethodSpec("merayo"), MethodSpec("lsq")), trials=2).tasks()[0]) == 2

"""Hostile calibrations and output folders found by probing apply, report and compare (session of 2026-11-29): a
campaign's outputs replace a link standing at their name instead of writing through it; apply refuses a matrix that
mirrors or turns the axes and angles no sensor has, and keeps a calibration's text on its one comment line; each
beside its control."""
from __future__ import annotations

import json

import numpy as np
import pytest
from test_hostile_inputs import _refused, _run

from magbench.simulate import simulate


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    """A data file and its accepted lsq calibration."""
    from magbench.benchmarks.cli import main

    d = tmp_path_factory.mktemp("apply")
    simulate("sphere9", 0).to_csv(d / "s.csv")
    assert main(["calibrate", str(d / "s.csv"), "--method", "lsq", "--save", str(d / "cal.json")]) == 0
    return d


def _magcal(path, a, b=(152.0, -218.0, 85.0)):
    path.write_text(json.dumps({"A": np.asarray(a, dtype=float).tolist(), "b": list(b)}))
    return path


@pytest.mark.parametrize("a, fragment", [(-np.eye(3), "negative determinant"),
                                         (np.diag([1.0, 1.0, -1.0]), "negative determinant"),
                                         ([[0, 1, 0], [-1, 0, 0], [0, 0, 1]], "turns the axes by 90 degrees")])
def test_apply_refuses_a_matrix_that_mirrors_or_turns_the_axes(saved, capsys, a, fragment):
    cal = _magcal(saved / "bad.json", a)
    _refused(capsys, ["apply", cal, saved / "s.csv", "--out", saved / "o.csv", "--force"], fragment)
    ok = _magcal(saved / "ok.json", np.eye(3))  # control: the identity with offsets is a calibration
    code, _, err = _run(capsys, ["apply", ok, saved / "s.csv", "--out", saved / "o.csv", "--force"])
    assert code == 0, err


def test_apply_refuses_angles_no_sensor_has(saved, capsys):
    from magbench.simulate.sensor import ErrorParams

    cal = json.loads((saved / "cal.json").read_text())
    wild = ErrorParams(1.2, 0.0, 0.0, (1.0, 1.0, 1.0), (152.0, -218.0, 85.0))
    for name, value in {"alpha_rad": 1.2, "beta_rad": 0.0, "gamma_rad": 0.0, "kx": 1.0, "ky": 1.0, "kz": 1.0}.items():
        cal["parameters"][name]["value"] = value  # matrix and parameters agreeing, as a careful hand edit would
    cal["M"] = wild.matrix.tolist()
    path = saved / "wild.json"
    path.write_text(json.dumps(cal))
    _refused(capsys, ["apply", path, saved / "s.csv", "--out", saved / "o.csv", "--force"], "alpha_rad 1.2")


def test_apply_keeps_a_calibrations_text_on_its_comment_line(saved, capsys):
    cal = json.loads((saved / "cal.json").read_text())
    cal["method"] = "lsq)\n# units: uT\n# x: ("
    path = saved / "inject.json"
    path.write_text(json.dumps(cal))
    code, _, err = _run(capsys, ["apply", path, saved / "s.csv", "--out", saved / "o.csv", "--force"])
    assert code == 0, err
    lines = (saved / "o.csv").read_text().splitlines()
    assert not any(ln.startswith("# units:") for ln in lines)  # the text stays on the calibration's line
    assert any(ln.startswith("# calibration:") and "\\n# units: uT" in ln for ln in lines)


def test_a_link_at_an_outputs_name_is_replaced_not_written_through(tmp_path, capsys):
    out = tmp_path / "c"
    code, _, err = _run(capsys, ["compare", "--scenarios", "sphere9", "--methods", "lsq", "ellipsoid", "--trials",
                                 "2", "--quiet", "--no-figures", "--out", out])
    assert code == 0, err
    runs = (out / "runs.csv").read_bytes()
    victim = tmp_path / "victim.txt"
    victim.write_text("keep\n")
    for name, target in (("report.html", out / "runs.csv"), ("summary.md", victim)):
        (out / name).unlink(missing_ok=True)
        (out / name).symlink_to(target)
    code, _, err = _run(capsys, ["report", out, "--quiet"])
    assert code == 0, err
    assert (out / "runs.csv").read_bytes() == runs  # the campaign's own table kept
    assert victim.read_text() == "keep\n"
    assert not (out / "report.html").is_symlink() and (out / "report.html").read_text().startswith("<!DOCTYPE html>")


def test_a_parameter_given_twice_is_refused_not_overridden(saved, capsys):
    _refused(capsys, ["calibrate", saved / "s.csv", "--method", "ga", "--param", "budget=100", "--param",
                      "budget=20000"], "budget is given twice")
    _refused(capsys, ["compare", "--scenarios", "sphere9", "--methods", "ga:budget=10:budget=20", "--trials", "1",
                      "--out", saved / "c2"], "budget is given twice")


def test_gradiometer_points_have_a_limit(capsys):
    _refused(capsys, ["gradiometer", "--points", "100000000"], "at most 1,000,000")


def test_report_names_a_flag_column_that_holds_no_flag(tmp_path, capsys):
    out = tmp_path / "c"
    code, _, err = _run(capsys, ["compare", "--scenarios", "sphere9", "--methods", "lsq", "ellipsoid", "--trials",
                                 "2", "--quiet", "--no-figures", "--out", out])
    assert code == 0, err
    assert _run(capsys, ["report", out, "--quiet"])[0] == 0  # control
    lines = (out / "runs.csv").read_text().splitlines()
    col = lines[0].split(",").index("success")
    edited = [lines[0]] + [",".join("2" if i == col else c for i, c in enumerate(ln.split(","))) for ln in lines[1:]]
    (out / "runs.csv").write_text("\n".join(edited) + "\n")
    _refused(capsys, ["report", out, "--quiet"], "column success holds '2'")


def test_report_states_the_runs_not_an_edited_summary(tmp_path, capsys):
    out = tmp_path / "c"
    code, _, err = _run(capsys, ["compare", "--scenarios", "sphere9", "--methods", "lsq", "ellipsoid", "--trials",
                                 "2", "--quiet", "--no-figures", "--out", out])
    assert code == 0, err
    assert _run(capsys, ["report", out, "--quiet"])[0] == 0
    honest = (out / "report.html").read_text()
    lines = (out / "summary.csv").read_text().splitlines()
    col = lines[0].split(",").index("n_runs")
    lines[1:] = [",".join("77" if i == col else c for i, c in enumerate(ln.split(","))) for ln in lines[1:]]
    (out / "summary.csv").write_text("\n".join(lines) + "\n")
    assert _run(capsys, ["report", out, "--quiet"])[0] == 0
    assert (out / "report.html").read_text() == honest  # the edit does not reach the report
    (out / "summary.csv").write_text("garbage\n")
    assert _run(capsys, ["report", out, "--quiet"])[0] == 0
    assert (out / "report.html").read_text() == honest

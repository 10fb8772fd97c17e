"""The command line: contract keys, exit statuses, one-line refusals (never a traceback)."""
import json
import subprocess
import sys

import numpy as np
import pytest

from magbench.benchmarks.cli import main


def run(*args):
    """The installed console entry point, as a user runs it."""
    p = subprocess.run([sys.executable, "-m", "magbench.benchmarks.cli", *args], capture_output=True, text=True)
    return p.returncode, p.stdout, p.stderr


@pytest.fixture(scope="module")
def sphere_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("data") / "sphere9.csv"
    assert main(["simulate", "--scenario", "sphere9", "--seed", "3", "--out", str(path)]) == 0
    return path


def _refused(code, out, err):
    assert code == 2, (code, err)
    assert out == ""
    assert len(err.strip().splitlines()) == 1, err
    assert "Traceback" not in err


def test_list_json_has_every_section():
    code, out, err = run("list", "--json")
    assert code == 0 and err == ""
    obj = json.loads(out)
    assert {"calibrators", "models", "scenarios", "effects"} <= set(obj)
    assert {"lu2014", "sphere9"} <= {s["name"] for s in obj["scenarios"]}


def test_calibrate_json_contract_keys(sphere_csv):
    code, out, err = run("calibrate", str(sphere_csv), "--method", "lsq", "--json")
    assert code == 0, err
    obj = json.loads(out)
    for key in ("method", "model", "alpha_rad", "beta_rad", "gamma_rad", "scale", "offset_nT", "matrix",
                "rms_before_nT", "rms_after_nT", "runtime_s", "n_evaluations", "seed", "warnings"):
        assert key in obj
    assert len(obj["scale"]) == 3 and np.shape(obj["matrix"]) == (3, 3)


def _rewrite(src, dst, transform):
    lines = src.read_text().splitlines()
    dst.write_text("\n".join(transform(lines)) + "\n")
    return dst


def test_nan_row_refused(sphere_csv, tmp_path):
    def poison(lines):
        i = next(k for k, ln in enumerate(lines) if not ln.startswith("#")) + 5
        cells = lines[i].split(",")
        cells[2] = "nan"
        lines[i] = ",".join(cells)
        return lines

    bad = _rewrite(sphere_csv, tmp_path / "nan.csv", poison)
    code, out, err = run("calibrate", str(bad), "--method", "lsq")
    _refused(code, out, err)
    assert "line" in err and "non-finite" in err


def test_too_few_points_refused(sphere_csv, tmp_path):
    bad = _rewrite(sphere_csv, tmp_path / "few.csv", lambda lines: lines[:12])
    code, out, err = run("calibrate", str(bad), "--method", "lsq", "--model", "nine")
    _refused(code, out, err)
    assert "too few" in err


@pytest.mark.parametrize("unit,factor", [("uT", 1e-3), ("G", 1e-5)])
def test_file_in_other_units_read_as_nT_is_refused_and_read_with_units(sphere_csv, tmp_path, unit, factor):
    import pandas as pd

    frame = pd.read_csv(sphere_csv, comment="#")
    for c in ("bx", "by", "bz", "f_ref"):
        frame[c] *= factor
    path = tmp_path / f"{unit}.csv"
    frame.to_csv(path, index=False)
    code, out, err = run("calibrate", str(path), "--method", "lsq")
    _refused(code, out, err)
    assert f"--units {unit}" in err
    code, out, err = run("calibrate", str(path), "--method", "lsq", "--units", unit, "--json")
    assert code == 0, err
    assert json.loads(out)["rms_after_nT"] < 2.5


def test_missing_reference_refused_then_given(sphere_csv, tmp_path):
    def strip(lines):
        body = [ln for ln in lines if not ln.startswith("#")]
        head = body[0].split(",")
        k = head.index("f_ref")
        return [",".join(c for j, c in enumerate(ln.split(",")) if j != k) for ln in body]

    bad = _rewrite(sphere_csv, tmp_path / "noref.csv", strip)
    code, out, err = run("calibrate", str(bad), "--method", "lsq")
    _refused(code, out, err)
    assert "reference" in err
    code, out, err = run("calibrate", str(bad), "--method", "lsq", "--field", "50000", "--json")
    assert code == 0 and json.loads(out)["rms_after_nT"] < 2.5


def test_igrf_reference_option(sphere_csv, tmp_path):
    code, out, err = run("calibrate", str(sphere_csv), "--method", "lsq", "--igrf", "34.26,108.94,0.4,2013-06-27")
    assert code == 0, err  # the file's own f_ref column takes precedence
    code, out, err = run("calibrate", str(sphere_csv), "--method", "lsq", "--igrf", "34.26,108.94")
    _refused(code, out, err)


@pytest.mark.parametrize("args,needle", [
    (["calibrate", "/no/such/file.csv", "--method", "lsq"], "no such file"),
    (["calibrate", "{csv}", "--method", "nope"], "unknown calibrator"),
    (["calibrate", "{csv}", "--method", "ellipsoid", "--model", "angles"], "use --model nine"),
    (["calibrate", "{csv}", "--method", "lsq", "--param", "bogus=1"], "no hyper-parameter"),
    (["simulate", "--scenario", "nope", "--out", "x.csv"], "unknown scenario"),
    # only commas: a campaign of no runs was an internal error (EmptyDataError) that left a 'complete' folder
    (["compare", "--scenarios", ",", "--methods", "lsq", "--out", "{tmp}/c"], "--scenarios names none"),
    (["compare", "--scenarios", "sphere9", "--methods", ",", "--out", "{tmp}/c"], "--methods names none"),
    (["compare", "--scenarios", "sphere9", "--methods", "lsq:=3", "--out", "{tmp}/c"], "is not key=value"),
    (["calibrate"], "required"),
    (["frobnicate"], "invalid choice"),
])
def test_usage_errors_are_one_line(sphere_csv, tmp_path, args, needle):
    args = [a.replace("{csv}", str(sphere_csv)).replace("{tmp}", str(tmp_path)) for a in args]
    code, out, err = run(*args)
    _refused(code, out, err)
    assert needle in err
    assert not (tmp_path / "c").exists()  # refused before anything is written


def test_simulate_refuses_to_overwrite(sphere_csv):
    before = sphere_csv.read_bytes()
    code, out, err = run("simulate", "--scenario", "sphere9", "--out", str(sphere_csv))
    _refused(code, out, err)
    assert sphere_csv.read_bytes() == before


def test_degenerate_coverage_refused(tmp_path):
    path = tmp_path / "lu.csv"
    assert main(["simulate", "--scenario", "lu2014", "--out", str(path)]) == 0
    code, out, err = run("calibrate", str(path), "--method", "lsq", "--model", "nine")
    _refused(code, out, err)
    assert "degenerate attitude coverage" in err
    code, out, err = run("calibrate", str(path), "--method", "lsq", "--model", "angles", "--json")
    assert code == 0 and json.loads(out)["rms_after_nT"] < 1.5


def test_scalar_only_series_is_refused_by_calibrate(tmp_path):
    path = tmp_path / "t2.csv"
    path.write_text("heading_deg,f_meas,f_ref\n0,52069.25,51978.74\n10,52069.24,51978.74\n")
    code, out, err = run("calibrate", str(path), "--method", "lsq")
    _refused(code, out, err)
    assert "scalar-only" in err


def test_demo_runs_every_calibrator():
    code, out, err = run("demo", "--json")
    assert code == 0, err
    rows = json.loads(out)["rows"]
    from magbench.calibrators import available

    assert {r["method"] for r in rows} == set(available())
    lsq = [r for r in rows if r["method"] == "lsq" and r["scenario"] == "sphere9"][0]
    assert lsq["rms_after_nT"] < 2.5

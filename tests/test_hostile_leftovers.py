"""Leftovers of hostile probing (session of 2026-11-29, second pass): a damaged campaign manifest, exports beyond what
a flight controller takes, options that contradict each other, a magcal file that says it was rejected, an empty
--truth name, an unreachable Dask scheduler and metadata that forges a header line.  Each case gets exit 2 and one
line naming what is wrong (or a warning line where the output is still honest), beside its control, which still
works."""
from __future__ import annotations

import json

import pytest
from test_hostile_inputs import _refused, _run


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """A small finished campaign (tables only) and its manifest's text."""
    from magbench.benchmarks.cli import main

    out = tmp_path_factory.mktemp("leftovers") / "c"
    assert main(["compare", "--scenarios", "sphere9", "--methods", "lsq", "ellipsoid", "--trials", "2", "--quiet",
                 "--no-figures", "--out", str(out)]) == 0
    return out, (out / "manifest.json").read_text()


@pytest.mark.parametrize("damage, fragment", [
    (lambda text: text[:300], "not JSON"),  # cut short
    (lambda text: "[1, 2]\n", "JSON list, not an object"),
    (lambda text: "7\n", "JSON int, not an object"),
    (lambda text: "", "(empty)"),
])
def test_report_refuses_a_damaged_manifest(campaign, capsys, damage, fragment):
    out, good = campaign
    try:
        (out / "manifest.json").write_text(damage(good))
        err = _refused(capsys, ["report", out, "--quiet"], fragment)
        assert "manifest.json is damaged" in err and "--resume rewrites it" in err
    finally:
        (out / "manifest.json").write_text(good)
    code, _, err = _run(capsys, ["report", out, "--quiet"])  # control: the intact manifest
    assert code == 0 and err == "", err
    assert "root seed 0" in (out / "report.html").read_text()


def test_report_refuses_a_manifest_that_is_no_text(campaign, capsys):
    out, good = campaign
    try:
        (out / "manifest.json").write_bytes(b"\x00\xff\xfegarbage")
        _refused(capsys, ["report", out, "--quiet"], "not UTF-8 text")
    finally:
        (out / "manifest.json").write_text(good)


def test_report_without_a_manifest_says_what_it_cannot_know(campaign, capsys):
    out, good = campaign
    try:
        (out / "manifest.json").unlink()
        code, _, err = _run(capsys, ["report", out, "--quiet"])
        assert code == 0
        assert err.count("\n") == 1 and "warning:" in err and "manifest.json is missing" in err
        assert "No manifest.json: whether the campaign is complete" in (out / "report.html").read_text()
    finally:
        (out / "manifest.json").write_text(good)


def test_resume_rewrites_a_manifest_that_is_not_an_object(campaign, capsys):
    """A list or a number as manifest.json had been an internal error (AttributeError) of compare --resume."""
    out, good = campaign
    for text in ("[1, 2]\n", "7\n"):
        (out / "manifest.json").write_text(text)
        code, _, err = _run(capsys, ["compare", "--scenarios", "sphere9", "--methods", "lsq", "ellipsoid", "--trials",
                                     "2", "--quiet", "--no-figures", "--out", out, "--resume"])
        assert code == 0, err
        assert json.loads((out / "manifest.json").read_text())["root_seed"] == 0
    (out / "manifest.json").write_text(good)


def test_an_empty_truth_name_is_refused(tmp_path, capsys):
    for name in ("", "  "):
        _refused(capsys, ["simulate", "--scenario", "sphere9", "--seed", "0", "--out", tmp_path / "s.csv", "--truth",
                          name], "the --truth file name is empty")
        assert not (tmp_path / "s.csv").exists()  # refused before the data file is written
    code, _, err = _run(capsys, ["simulate", "--scenario", "sphere9", "--seed", "0", "--out", tmp_path / "s.csv",
                                 "--truth", tmp_path / "t.json"])  # control
    assert code == 0, err
    assert json.loads((tmp_path / "t.json").read_text())


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """A simulated file with its f_ref column, and the same readings without any reference (no f_ref, no field line)."""
    from magbench.simulate import simulate

    d = tmp_path_factory.mktemp("data")
    simulate("sphere9", 0).to_csv(d / "s.csv")
    lines = (d / "s.csv").read_text().splitlines()
    head = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
    keep = [i for i, c in enumerate(lines[head].split(",")) if c != "f_ref"]
    (d / "bare.csv").write_text("\n".join([ln for ln in lines[:head] if not ln.startswith("# field_nT")]
                                          + [",".join(ln.split(",")[i] for i in keep) for ln in lines[head:]]) + "\n")
    return d


def test_an_algorithm_given_twice_is_refused_not_overridden(data, capsys):
    """--param algorithm=Y beside --algorithm X had silently run X; --algorithm '' had silently run the default."""
    _refused(capsys, ["calibrate", data / "s.csv", "--method", "nlopt", "--algorithm", "LN_BOBYQA", "--param",
                      "algorithm=LN_SBPLX"], "both set the NLopt algorithm")
    _refused(capsys, ["calibrate", data / "s.csv", "--method", "nlopt", "--algorithm", ""], "unknown algorithm ''")
    for args in (["--algorithm", "LN_SBPLX"], ["--param", "algorithm=LN_SBPLX"]):  # controls: either alone
        code, out, err = _run(capsys, ["calibrate", data / "s.csv", "--method", "nlopt", "--json", *args])
        assert code == 0, err
        assert json.loads(out)["hyperparameters"]["algorithm"] == "LN_SBPLX"


@pytest.mark.parametrize("field", ["50000", "auto"])
def test_field_and_igrf_together_are_refused(data, capsys, field):
    """--igrf beside --field had been ignored, unread (a malformed --igrf too)."""
    for command in (["calibrate", data / "bare.csv", "--method", "lsq"], ["diagnose", data / "bare.csv"]):
        if field == "auto" and command[0] == "diagnose":
            continue  # diagnose's --field takes a number only
        _refused(capsys, [*command, "--field", field, "--igrf", "45,7,0,2020-01-01"], "--field and --igrf both give")
        _refused(capsys, [*command, "--field", field, "--igrf", "garbage"], "--field and --igrf both give")
    _refused(capsys, ["calibrate", data / "bare.csv", "--method", "lsq", "--igrf", ""], "--igrf wants")
    for ref in (["--field", field], ["--igrf", "45,7,0,2020-01-01"]):  # controls: either alone
        code, _, err = _run(capsys, ["calibrate", data / "bare.csv", "--method", "lsq", "--accept-any", *ref])
        assert code == 0, err
        assert "--igrf" in err if ref[0] == "--igrf" else "--igrf" not in err


def _magcal(path, **extra):
    path.write_text(json.dumps({"A": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "b": [152.0, -218.0, 85.0], **extra}))
    return path


def test_apply_refuses_a_magcal_file_that_says_it_was_rejected(data, tmp_path, capsys):
    """A magcal-style JSON with "accepted": false had been applied silently; magbench's own rejected JSON is refused
    unless --accept-any, and so is it now."""
    out = tmp_path / "o.csv"
    bad = _magcal(tmp_path / "rejected.json", accepted=False, rejections=["residual 40 times the noise"])
    _refused(capsys, ["apply", bad, data / "s.csv", "--out", out], "rejected by its acceptance checks when it was made "
                                                                    "(residual 40 times the noise)")
    assert not out.exists()
    _refused(capsys, ["apply", _magcal(tmp_path / "odd.json", accepted="no"), data / "s.csv", "--out", out],
             "entry 'accepted' must be true or false")
    code, _, err = _run(capsys, ["apply", bad, data / "s.csv", "--out", out, "--accept-any"])  # the override
    assert code == 0, err
    code, stdout, err = _run(capsys, ["apply", bad, data / "s.csv", "--out", out, "--accept-any", "--force", "--json"])
    assert any("applied by --accept-any" in w for w in json.loads(stdout)["warnings"])
    for ok in (_magcal(tmp_path / "plain.json"), _magcal(tmp_path / "accepted.json", accepted=True)):  # controls
        code, _, err = _run(capsys, ["apply", ok, data / "s.csv", "--out", out, "--force"])
        assert code == 0, err


def test_a_mat_magcal_file_says_it_was_rejected_too(tmp_path):
    import numpy as np
    from scipy.io import savemat

    from magbench.calibrators.artifacts import apply_problems, load_calibration

    savemat(tmp_path / "r.mat", {"A": np.eye(3), "b": np.array([[152.0, -218.0, 85.0]]), "accepted": False,
                                 "rejections": ["residual 40 times the noise"]})
    savemat(tmp_path / "ok.mat", {"A": np.eye(3), "b": np.array([[152.0, -218.0, 85.0]])})
    assert "residual 40 times the noise" in apply_problems(load_calibration(tmp_path / "r.mat"))[0]
    assert apply_problems(load_calibration(tmp_path / "ok.mat")) == []
    # two rejections (a char array), none (an empty array), a cell array, MATLAB's double 0 for false: each read,
    # none an internal error
    both = ["residual 40 times the noise", "offset beyond the box"]
    for name, extra in (("two", {"rejections": both}), ("none", {"rejections": np.array([])}),
                        ("cell", {"rejections": np.array(both, dtype=object)}), ("double", {"accepted": 0.0})):
        savemat(tmp_path / f"{name}.mat", {"A": np.eye(3), "b": np.array([[152.0, -218.0, 85.0]]), "accepted": False,
                                           **extra})
        cal = load_calibration(tmp_path / f"{name}.mat")
        assert cal.accepted is False and apply_problems(cal)
    assert load_calibration(tmp_path / "two.mat").rejections == tuple(both)
    assert load_calibration(tmp_path / "cell.mat").rejections == tuple(both)


@pytest.mark.parametrize("value", ["x\n# units: uT", "x\r# field_nT: 60000", "x\u2028# temp_unit: F", "x\x1b[2J"])
def test_dataset_metadata_stays_on_its_comment_line(tmp_path, value):
    """A line break in a meta value (or key) had written a metadata line of its own, read back as the file's."""
    from dataclasses import replace

    from magbench.simulate import simulate
    from magbench.simulate.dataset import read_csv

    data = simulate("sphere9", 0)
    replace(data, meta={**data.meta, "note": value, f"k{value}": 1}).to_csv(tmp_path / "m.csv")
    text = (tmp_path / "m.csv").read_text()
    comments = [ln for ln in text.split("\n") if ln.startswith("#")]
    assert len(comments) == len(data.meta) + 2  # one line per entry: none forged
    assert not any(ln.startswith(("# units", "# field_nT: 6", "# temp_unit")) for ln in comments)
    assert "\r" not in text and "\u2028" not in text and "\x1b" not in text
    back = read_csv(tmp_path / "m.csv")
    assert back.meta["note"] == value.encode("unicode_escape").decode("ascii").replace("\\\\", "\\")
    assert (back.raw_nT == read_csv(_control(tmp_path, data)).raw_nT).all()


def _control(tmp_path, data):
    """The same dataset with printable metadata, written as it always was."""
    data.to_csv(tmp_path / "plain.csv")
    assert (tmp_path / "plain.csv").read_text().startswith("".join(f"# {k}: {v}\n" for k, v in data.meta.items()))
    return tmp_path / "plain.csv"


def test_an_unreachable_dask_scheduler_leaves_nothing_behind(tmp_path, capsys, monkeypatch):
    """It had left a folder holding a checkpoint of no runs, which the same command without --dask then refused ('it
    holds an interrupted campaign'); the scheduler is now reached before anything is written."""
    from magbench.benchmarks import campaign as campaign_module

    monkeypatch.setattr(campaign_module, "DASK_CONNECT_S", 1)
    out = tmp_path / "c"
    argv = ["compare", "--scenarios", "sphere9", "--methods", "lsq", "--trials", "1", "--quiet", "--no-figures",
            "--out", out]
    _refused(capsys, [*argv, "--dask", "tcp://127.0.0.1:9"], "nothing was run or written")
    assert not out.exists()
    out.mkdir()  # a folder that was there stays, empty
    _refused(capsys, [*argv, "--dask", "tcp://127.0.0.1:9"], "cannot reach the Dask scheduler")
    assert out.is_dir() and not any(out.iterdir())
    code, _, err = _run(capsys, argv)  # control: the same campaign without --dask, in that folder
    assert code == 0, err
    checkpoint = (out / "runs.partial.jsonl").read_bytes()
    grown = ["compare", "--scenarios", "sphere9", "--methods", "lsq", "ellipsoid", "--trials", "1", "--quiet",
             "--no-figures", "--out", out, "--resume"]
    _refused(capsys, [*grown, "--dask", "tcp://127.0.0.1:9"], "nothing was run or written")
    assert (out / "runs.partial.jsonl").read_bytes() == checkpoint  # the campaign as it was
    code, stdout, err = _run(capsys, [*grown, "--json"])  # and it grows without --dask
    assert code == 0, err
    assert json.loads(stdout)["n_resumed"] == 1 and json.loads(stdout)["n_new"] == 1


def _offset_record(path, offset_nT, field_nT=100000.0):
    """A laboratory record (a coil's 100,000 nT, its '# field_nT:' line) of a sensor with these offsets."""
    import numpy as np

    from magbench.simulate import attitude
    from magbench.simulate.field import ConstantField
    from magbench.simulate.sensor import ErrorParams, SensorModel

    rng = np.random.default_rng(0)
    b = attitude.full_sphere(300, rng).body_field(np.asarray(ConstantField.from_angles(field_nT, 55.0, 3.0).vector_nT))
    raw = SensorModel(ErrorParams(0.012, -0.008, 0.015, (1.021, 0.984, 1.008), offset_nT), noise_nT=1.0).measure(b, rng)
    path.write_text(f"# field_nT: {field_nT}\nbx,by,bz\n" + "".join(",".join(f"{v:.4f}" for v in r) + "\n" for r in raw))
    return path


def test_exports_say_when_the_flight_controller_would_not_take_the_offsets(tmp_path, capsys):
    """Offsets beyond ArduPilot's COMPASS_OFFS_MAX or PX4's large-offset limit had been exported without a word."""
    wide = _offset_record(tmp_path / "wide.csv", (150000.0, 150000.0, 0.0))  # 2121 mG long, 1.5 G an axis
    huge = _offset_record(tmp_path / "huge.csv", (180000.0, 180000.0, 180000.0))  # 3118 mG long
    usual = _offset_record(tmp_path / "usual.csv", (1520.0, -2180.0, 850.0))
    out = tmp_path / "cal"

    err = _refused(capsys, ["calibrate", huge, "--method", "lsq", "--save", f"{out}.param"], "COMPASS_OFS would be 3118 mG")
    assert "largest COMPASS_OFFS_MAX" in err and not (tmp_path / "cal.param").exists()
    for save, fragment in (("cal.param", "beyond ArduPilot's default COMPASS_OFFS_MAX of 1800 mG"),
                           ("cal.params", "CAL_MAG0_XOFF 1.5 G, CAL_MAG0_YOFF 1.5 G are beyond the 1.3 G")):
        code, stdout, err = _run(capsys, ["calibrate", wide, "--method", "lsq", "--save", tmp_path / save, "--json"])
        assert code == 0 and (tmp_path / save).is_file(), err
        warned = [ln for ln in err.splitlines() if "warning:" in ln]
        assert len(warned) == 1 and fragment in warned[0], err
        assert any(fragment in w for w in json.loads(stdout)["warnings"])
    code, _, err = _run(capsys, ["calibrate", huge, "--method", "lsq", "--save", tmp_path / "huge.json"])
    assert code == 0 and "warning:" not in err, err  # magbench's JSON keeps what no flight controller takes
    for save in ("usual.param", "usual.params"):  # controls: a sensor's usual offsets, no word
        code, _, err = _run(capsys, ["calibrate", usual, "--method", "lsq", "--save", tmp_path / save])
        assert code == 0 and "warning:" not in err and (tmp_path / save).is_file(), err


def test_the_python_export_refuses_or_warns_too(tmp_path):
    import numpy as np

    from magbench.calibrators.artifacts import Calibration, export
    from magbench.errors import InputError
    from magbench.simulate.sensor import ErrorParams

    def cal(offset):
        p = ErrorParams(0.0, 0.0, 0.0, (1.0, 1.0, 1.0), offset)
        return Calibration(model="nine", matrix=p.matrix, offset_nT=offset, params=p)

    with pytest.raises(InputError, match="largest COMPASS_OFFS_MAX"):
        export(cal((180000.0, 180000.0, 180000.0)), tmp_path / "a", "ardupilot")
    with pytest.warns(UserWarning, match="default COMPASS_OFFS_MAX"):
        export(cal((150000.0, 150000.0, 0.0)), tmp_path / "b", "ardupilot")
    with pytest.warns(UserWarning, match="CAL_MAG0_ZOFF -1.4 G is beyond"):
        export(cal((0.0, 0.0, -140000.0)), tmp_path / "c", "px4")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        export(cal((1520.0, -2180.0, 850.0)), tmp_path / "d", "ardupilot")  # control
        assert np.isfinite(float((tmp_path / "d.param").read_text().split("COMPASS_OFS_X,")[1].split()[0]))

"""Calibrations as artifacts: a recording calibrated, saved, applied to a second
recording and exported to each format round-trips; the models offset/diag/auto; array and DataFrame
input; --field auto; uncertainties in every result."""
import json

import numpy as np
import pandas as pd
import pytest

from magbench.benchmarks.cli import main
from magbench.calibrators import make
from magbench.calibrators.artifacts import Calibration, apply_to_csv, export, load_calibration
from magbench.calibrators.checks import CHECK_ERRORS, check_dataset
from magbench.errors import InputError
from magbench.simulate import simulate
from magbench.simulate.sensor import PARAM_NAMES, ErrorParams

TOL_NT = 0.01


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec")
    a, b = d / "a.csv", d / "b.csv"
    assert main(["simulate", "--scenario", "sphere9", "--seed", "0", "--out", str(a)]) == 0
    assert main(["simulate", "--scenario", "sphere9", "--seed", "1", "--out", str(b)]) == 0
    return a, b


# -- the published correction formulas, written out independently of magbench's code ----------------------
def _params(path, sep):
    out = {}
    for line in path.read_text().splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        parts = line.split(sep)
        name, value = (parts[0], parts[1]) if sep == "," else (parts[2], parts[3])
        out[name] = float(value)
    return out


def ardupilot_correct(p, raw_mG, dtype=np.float64):
    """AP_Compass_Backend::correct_field: mag += offsets; mag *= scale_factor; mag = mat * mag."""
    mag = raw_mG.astype(dtype) + np.array([p["COMPASS_OFS_X"], p["COMPASS_OFS_Y"], p["COMPASS_OFS_Z"]], dtype=dtype)
    mag = mag * dtype(p["COMPASS_SCALE"])
    mat = np.array([[p["COMPASS_DIA_X"], p["COMPASS_ODI_X"], p["COMPASS_ODI_Y"]],
                    [p["COMPASS_ODI_X"], p["COMPASS_DIA_Y"], p["COMPASS_ODI_Z"]],
                    [p["COMPASS_ODI_Y"], p["COMPASS_ODI_Z"], p["COMPASS_DIA_Z"]]], dtype=dtype)
    return mag @ mat.T


def px4_correct(p, data_G, dtype=np.float64):
    """calibration::Magnetometer::Correct: _rotation * (_scale * (data - _offset)) (rotation none, no power
    compensation)."""
    off = np.array([p["CAL_MAG0_XOFF"], p["CAL_MAG0_YOFF"], p["CAL_MAG0_ZOFF"]], dtype=dtype)
    s = np.array([[p["CAL_MAG0_XSCALE"], p["CAL_MAG0_XODIAG"], p["CAL_MAG0_YODIAG"]],
                  [p["CAL_MAG0_XODIAG"], p["CAL_MAG0_YSCALE"], p["CAL_MAG0_ZODIAG"]],
                  [p["CAL_MAG0_YODIAG"], p["CAL_MAG0_ZODIAG"], p["CAL_MAG0_ZSCALE"]]], dtype=dtype)
    return (data_G.astype(dtype) - off) @ s.T


def test_calibrate_save_apply_and_export_round_trip(recordings, tmp_path, capsys):
    a, b = recordings
    code, out, err = run(capsys, "calibrate", a, "--method", "lsq", "--save", tmp_path / "cal", "--json")
    assert code == 0, err
    res = json.loads(out)
    assert res["saved"] == str(tmp_path / "cal.json")
    cal = load_calibration(tmp_path / "cal.json")
    assert cal.model == "nine" and cal.method == "lsq" and cal.accepted
    saved = json.loads((tmp_path / "cal.json").read_text())
    assert saved["schema"] == "magbench.calibration" and saved["schema_version"] == 1
    assert saved["data"]["digest"].startswith("sha256:") and saved["data"]["n_points"] == 300
    assert saved["reference"]["source"] and saved["magbench_version"]
    assert all(saved["parameters"][k]["std"] > 0 for k in PARAM_NAMES["nine"])

    # applied to a second recording: corrected columns added, every other line and column kept
    code, out, err = run(capsys, "apply", tmp_path / "cal.json", b, "--out", tmp_path / "b_cal.csv")
    assert code == 0, err
    src_lines = b.read_text().splitlines()
    out_lines = (tmp_path / "b_cal.csv").read_text().splitlines()
    meta = [line for line in src_lines if line.startswith("#")]
    assert out_lines[:len(meta)] == meta
    body = [line for line in out_lines if not line.startswith("#")]
    src_body = [line for line in src_lines if not line.startswith("#")]
    assert body[0] == src_body[0] + ",bx_cal,by_cal,bz_cal,f_cal"
    assert all(o.startswith(s + ",") for o, s in zip(body[1:], src_body[1:])) and len(body) == len(src_body)
    frame = pd.read_csv(tmp_path / "b_cal.csv", comment="#")
    raw = frame[["bx", "by", "bz"]].to_numpy()
    expected = cal.correct(raw)
    np.testing.assert_allclose(frame[["bx_cal", "by_cal", "bz_cal"]].to_numpy(), expected, atol=1e-4)
    np.testing.assert_allclose(frame["f_cal"], np.linalg.norm(expected, axis=1), atol=1e-4)
    assert np.sqrt(np.mean((frame["f_cal"] - frame["f_ref"]) ** 2)) < 2.5  # the noise, on data not fitted

    magnitude = np.linalg.norm(expected, axis=1)
    # MATLAB magcal: C = (D - b) * A, as .mat and as .json
    for name in ("cal_m.mat", "cal_m.json"):
        code, _, err = run(capsys, "calibrate", a, "--method", "lsq", "--save", tmp_path / name, "--export", "matlab")
        assert code == 0, err
        if name.endswith(".mat"):
            from scipy.io import loadmat

            m = loadmat(str(tmp_path / name))
        else:
            m = json.loads((tmp_path / name).read_text())
        corrected = (raw - np.asarray(m["b"], dtype=float).reshape(1, 3)) @ np.asarray(m["A"], dtype=float)
        assert np.max(np.abs(corrected - expected)) < TOL_NT
        assert np.max(np.abs(load_calibration(tmp_path / name).correct(raw) - expected)) < TOL_NT
    # json through Python
    again = Calibration.from_json((tmp_path / "cal.json").read_text())
    assert np.max(np.abs(again.correct(raw) - expected)) < TOL_NT
    # ArduPilot (milligauss, offsets added) and PX4 (gauss, offsets subtracted): same magnitude
    code, _, err = run(capsys, "calibrate", a, "--method", "lsq", "--save", tmp_path / "cal", "--export", "ardupilot")
    assert code == 0, err
    ap = _params(tmp_path / "cal.param", ",")
    assert set(ap) == {f"COMPASS_{k}_{a}" for k in ("OFS", "DIA", "ODI") for a in "XYZ"} | {"COMPASS_SCALE"}
    code, _, err = run(capsys, "calibrate", a, "--method", "lsq", "--save", tmp_path / "cal", "--export", "px4")
    assert code == 0, err
    px = _params(tmp_path / "cal.params", "\t")
    assert set(px) == {f"CAL_MAG0_{a}{k}" for k in ("OFF", "SCALE", "ODIAG") for a in "XYZ"}
    for dtype in (np.float64, np.float32):  # the autopilots compute in single precision
        f_ap = np.linalg.norm(ardupilot_correct(ap, raw / 100.0, dtype).astype(float), axis=1) * 100.0
        f_px = np.linalg.norm(px4_correct(px, raw / 1e5, dtype).astype(float), axis=1) * 1e5
        tol = TOL_NT if dtype is np.float64 else 0.05  # float32 carries 7 digits of a 50,000 nT field
        assert np.max(np.abs(f_ap - magnitude)) < tol, np.max(np.abs(f_ap - magnitude))
        assert np.max(np.abs(f_px - magnitude)) < tol, np.max(np.abs(f_px - magnitude))
    # the symmetric factor differs from M by the rotation scalar data cannot see: vectors differ, magnitudes not
    vec_ap = ardupilot_correct(ap, raw / 100.0) * 100.0
    assert np.max(np.abs(vec_ap - expected)) > 1.0


def test_round_trip_numbers_for_each_model(tmp_path):
    data, other = simulate("sphere9", 2), simulate("sphere9", 3)
    for model in ("offset", "diag", "angles", "nine"):
        res = make("lsq", model=model).fit(data)
        cal = Calibration.from_json(res.to_json())
        expected = res.correct(other.raw_nT)
        assert np.array_equal(cal.correct(other.raw_nT), expected)
        for fmt in ("json", "matlab", "ardupilot", "px4"):
            path = export(cal, tmp_path / f"{model}", fmt)
            if fmt == "ardupilot":
                f = np.linalg.norm(ardupilot_correct(_params(path, ","), other.raw_nT / 100.0), axis=1) * 100.0
            elif fmt == "px4":
                f = np.linalg.norm(px4_correct(_params(path, "\t"), other.raw_nT / 1e5), axis=1) * 1e5
            else:
                back = load_calibration(path).correct(other.raw_nT)
                assert np.max(np.abs(back - expected)) < TOL_NT, (model, fmt)
                f = np.linalg.norm(back, axis=1)
            assert np.max(np.abs(f - np.linalg.norm(expected, axis=1))) < TOL_NT, (model, fmt)


def test_loader_refuses_bad_files(tmp_path):
    res = make("lsq", model="diag").fit(check_dataset("diag"))
    good = json.loads(res.to_json())
    cases = {
        "other schema": {**good, "schema": "something.else"},
        "newer version": {**good, "schema_version": 99},
        "unknown model": {**good, "model": "sym"},
        "model mismatch": {**good, "parameters": {**good["parameters"], "alpha_rad": {"value": 0.01, "std": None,
                                                                                       "fixed": True}}},
        "M mismatch": {**good, "M": (np.array(good["M"]) * 1.01).tolist()},
        "missing M": {k: v for k, v in good.items() if k != "M"},
        "bad count": {**good, "data": {"n_points": "many"}},
        "bad data": {**good, "data": 5},
        "bad std": {**good, "parameters": {**good["parameters"], "kx": {**good["parameters"]["kx"], "std": "s"}}},
        "not an object": [1, 2],
    }
    for what, d in cases.items():
        path = tmp_path / f"{what.replace(' ', '_')}.json"
        path.write_text(json.dumps(d))
        with pytest.raises(InputError):
            load_calibration(path)
    # said in the file's terms, not numpy's ('inhomogeneous shape after 1 dimensions' for a ragged M)
    ragged = {**good, "M": [good["M"][0], good["M"][1], [0.0, 0.0, 1.0, 5.0]]}
    for what, d, message in (("ragged M", ragged, "M must be a 3x3 matrix of numbers"),
                             ("text in o_nT", {**good, "o_nT": [1.0, "a", None]}, "o_nT must be three numbers"),
                             ("missing o_nT", {k: v for k, v in good.items() if k != "o_nT"}, "missing entry 'o_nT'")):
        path = tmp_path / f"{what.replace(' ', '_')}.json"
        path.write_text(json.dumps(d))
        with pytest.raises(InputError, match=message):
            load_calibration(path)
    (tmp_path / "junk.json").write_text("{not json")
    with pytest.raises(InputError, match="not JSON"):
        load_calibration(tmp_path / "junk.json")
    with pytest.raises(InputError, match="no such"):
        load_calibration(tmp_path / "absent.json")


def test_apply_refuses_bad_input(recordings, tmp_path, capsys):
    a, b = recordings
    cal_path = tmp_path / "cal.json"
    cal_path.write_text(make("lsq").fit(simulate("sphere9", 0)).to_json())
    before = b.read_bytes()
    (tmp_path / "bad.json").write_text(json.dumps({"schema": "magbench.calibration", "schema_version": 7}))
    nocols = tmp_path / "nocols.csv"
    nocols.write_text("t,bx,by\n0,1,2\n")
    (tmp_path / "exists.csv").write_text("x\n")
    mixed = tmp_path / "mixed.csv"  # every 5th row in uT among nT rows, no f_ref column: refused all the same
    data = simulate("sphere9", 1)
    raw = data.raw_nT * np.where(np.arange(len(data.raw_nT)) % 5 == 0, 1e-3, 1.0)[:, None]
    mixed.write_text("t,bx,by,bz\n" + "".join(f"{i},{x!r},{y!r},{z!r}\n" for i, (x, y, z) in enumerate(raw)))
    cases = [
        ("apply", cal_path, mixed, "--out", tmp_path / "o4.csv"),  # rows in mixed units
        ("apply", tmp_path / "bad.json", b, "--out", tmp_path / "o1.csv"),  # newer schema
        ("apply", cal_path, nocols, "--out", tmp_path / "o2.csv"),  # missing columns
        ("apply", cal_path, b, "--out", b),  # the input itself
        ("apply", cal_path, b, "--out", tmp_path / "exists.csv"),  # exists, no --force
        ("apply", cal_path, b, "--out", tmp_path / "o3.csv", "--units", "uT"),  # magnitudes are not in uT
        ("apply", cal_path, b, "--out", tmp_path / "nodir" / "o.csv"),
    ]
    for argv in cases:
        code, out, err = run(capsys, *argv)
        assert code == 2, (argv, err)
        assert out == "" and len(err.strip().splitlines()) == 1 and err.startswith("magbench: "), err
    assert b.read_bytes() == before
    code, _, err = run(capsys, "apply", cal_path, b, "--out", tmp_path / "exists.csv", "--force")
    assert code == 0, err
    calibrated = tmp_path / "exists.csv"
    code, _, err = run(capsys, "apply", cal_path, calibrated, "--out", tmp_path / "twice.csv")
    assert code == 2 and "already" in err


def test_apply_in_other_units_keeps_the_unit(tmp_path):
    data = simulate("sphere9", 4)
    res = make("lsq").fit(data)
    cal = Calibration.from_json(res.to_json())
    src = tmp_path / "ut.csv"
    src.write_text("# note: in microtesla\nbx;by;bz;label\n" + "".join(
        f"{x / 1e3:.9f};{y / 1e3:.9f};{z / 1e3:.9f};row{i}\n" for i, (x, y, z) in enumerate(data.raw_nT)))
    info = apply_to_csv(cal, src, tmp_path / "out.csv", units="uT")
    assert info["units"] == "uT"
    frame = pd.read_csv(tmp_path / "out.csv", sep=";", comment="#")
    assert list(frame.columns) == ["bx", "by", "bz", "label", "bx_cal", "by_cal", "bz_cal", "f_cal"]
    assert frame["label"].iloc[7] == "row7"
    np.testing.assert_allclose(frame["f_cal"] * 1e3, np.linalg.norm(res.correct(frame[["bx", "by", "bz"]].to_numpy() * 1e3),
                                                                    axis=1), atol=TOL_NT)


def test_calibrate_refuses_to_overwrite_and_keeps_rejected_calibrations_unsaved(recordings, tmp_path, capsys):
    a, _ = recordings
    (tmp_path / "c.json").write_text("{}")
    code, out, err = run(capsys, "calibrate", a, "--method", "lsq", "--save", tmp_path / "c.json")
    assert code == 2 and "exists" in err and out == ""
    code, _, err = run(capsys, "calibrate", a, "--method", "lsq", "--save", tmp_path / "c.json", "--force")
    assert code == 0 and load_calibration(tmp_path / "c.json").model == "nine"
    code, _, err = run(capsys, "calibrate", a, "--method", "lsq", "--export", "px4")
    assert code == 2 and "--save" in err
    code, out, err = run(capsys, "calibrate", a, "--method", "lsq", "--save", tmp_path / "r.json", "--param",
                         "max_nfev=1", "--param", "init=identity")  # stopped short: rejected
    assert code == 3 and "not saved" in err and not (tmp_path / "r.json").exists()


def test_save_to_a_directory_is_refused_not_written_beside_it(recordings, tmp_path, capsys):
    """`--save DIR` and `--save DIR/` wrote DIR.json beside the directory (the extension added to its name):
    refused, naming a file in it; a name without an extension still gets one (the control)."""
    a, _ = recordings
    folder = tmp_path / "out"
    folder.mkdir()
    for target in (str(folder), str(folder) + "/", str(tmp_path / "new") + "/"):
        code, out, err = run(capsys, "calibrate", a, "--method", "lsq", "--save", target)
        assert code == 2 and out == "" and "give a file name in it" in err, (target, err)
    assert not (tmp_path / "out.json").exists() and not (tmp_path / "new").exists()
    assert list(folder.iterdir()) == []
    code, _, _ = run(capsys, "calibrate", a, "--method", "lsq", "--save", folder / "cal")
    assert code == 0 and (folder / "cal.json").is_file()


# -- models -------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("model", ["offset", "diag"])
def test_new_models_recover_their_errors_with_uncertainty(model):
    data = check_dataset(model, noise_nT=1.0)
    res = make("lsq", model=model).fit(data)
    assert res.accepted, res.rejections
    truth = CHECK_ERRORS[model].to_vector(model)
    z = (res.x - truth) / np.array([res.uncertainty[k] for k in PARAM_NAMES[model]])
    assert np.all(np.abs(z) < 4), z
    assert set(res.uncertainty) == set(PARAM_NAMES[model]) and 0.8 < res.noise_nT < 1.2
    assert ErrorParams.from_vector(res.x, model).fits_model(model)


def test_diag_is_not_identifiable_on_a_level_turntable():
    """The turntable turns about one axis: the vertical scale is not determined (refused or rejected)."""
    data = simulate("lu2014", 0)
    try:
        res = make("lsq", model="diag").fit(data)
    except InputError as exc:
        assert "degenerate" in str(exc)
    else:
        assert not res.accepted and any("not determined" in r for r in res.rejections)
    assert make("lsq", model="offset").fit(data).uncertainty  # offsets alone: a result with deviations


def _simulated(kind: str, seed: int = 5):
    errors = {"offset": ErrorParams(offset_nT=(310.0, -120.0, 95.0)),
              "diag": ErrorParams(scale=(1.02, 0.985, 1.01), offset_nT=(310.0, -120.0, 95.0)),
              "angles": ErrorParams(0.01, -0.008, 0.012),
              "nine": ErrorParams(0.01, -0.008, 0.012, (1.02, 0.985, 1.01), (310.0, -120.0, 95.0))}[kind]
    from magbench.simulate import attitude
    from magbench.simulate.dataset import Dataset
    from magbench.simulate.field import ConstantField
    from magbench.simulate.sensor import SensorModel

    rng = np.random.default_rng(seed)
    field = ConstantField.from_angles(48000.0, 60.0, 2.0)
    att = attitude.full_sphere(300, rng)
    raw = SensorModel(errors, noise_nT=2.0).measure(att.body_field(np.asarray(field.vector_nT)), rng)
    return Dataset(raw, f_ref_nT=field.total_nT)


@pytest.mark.parametrize("kind", ["offset", "diag", "angles", "nine"])
def test_auto_chooses_the_model_the_data_were_simulated_with(kind):
    res = make("lsq", model="auto").fit(_simulated(kind))
    choice = res.model_choice
    assert res.model == kind == choice["chosen"], choice["reason"]
    assert choice["requested"] == "auto" and choice["reason"].startswith(kind)
    assert {c["model"] for c in choice["candidates"]} == {"offset", "diag", "angles", "nine"}
    assert all(c["rms_heldout_nT"] is None or c["rms_heldout_nT"] > 0 for c in choice["candidates"])
    assert json.loads(json.dumps(res.as_dict()))["model_choice"]["chosen"] == kind


def test_auto_on_a_turntable_keeps_to_what_it_can_identify():
    res = make("lsq", model="auto").fit(simulate("lu2014", 0))
    assert res.model == "angles"
    nine = next(c for c in res.model_choice["candidates"] if c["model"] == "nine")
    assert not nine["eligible"] and "nine" in res.model_choice["reason"]


def test_auto_through_the_command_line(recordings, capsys):
    a, _ = recordings
    code, out, err = run(capsys, "calibrate", a, "--method", "lsq", "--model", "auto", "--json")
    assert code == 0, err
    d = json.loads(out)
    assert d["model"] == "nine" and d["model_choice"]["chosen"] == "nine" and d["model_choice"]["reason"]
    assert set(d["uncertainty"]) == set(PARAM_NAMES["nine"])


# -- inputs -------------------------------------------------------------------------------------------------
def test_fit_accepts_an_array_and_a_dataframe():
    data = simulate("sphere9", 0)
    ref = make("lsq").fit(data)
    from_array = make("lsq").fit(np.array(data.raw_nT), f_ref_nT=50000.0)
    from_rows = make("lsq").fit(np.array(data.raw_nT), f_ref_nT=np.array(data.f_ref_nT))
    frame = pd.DataFrame({"BX": data.raw_nT[:, 0] / 1e3, "by": data.raw_nT[:, 1] / 1e3,
                          "bz": data.raw_nT[:, 2] / 1e3, "other": "x"})
    from_frame = make("lsq").fit(frame, f_ref_nT=50000.0, units="uT")
    for res in (from_array, from_rows, from_frame):
        np.testing.assert_allclose(res.x, ref.x, rtol=1e-7, atol=1e-6)
        assert res.uncertainty and res.reference["median_nT"] == 50000.0
    assert "keyword" in from_array.reference["source"]
    with_col = make("lsq").fit(pd.DataFrame({"bx": data.raw_nT[:, 0], "by": data.raw_nT[:, 1],
                                             "bz": data.raw_nT[:, 2], "f_ref": data.f_ref_nT}))
    np.testing.assert_allclose(with_col.x, ref.x, rtol=1e-9)
    for bad, kwargs in ((np.zeros((10, 2)), {"f_ref_nT": 5e4}), (data.raw_nT, {}), ("abc", {"f_ref_nT": 5e4}),
                        (pd.DataFrame({"bx": [1.0]}), {"f_ref_nT": 5e4}), (data.raw_nT, {"f_ref_nT": [1.0, 2.0]}),
                        (data.raw_nT, {"field": "estimate"}), (data.raw_nT, {"f_ref_nT": 5e4, "field": 5e4})):
        with pytest.raises(InputError):
            make("lsq").fit(bad, **kwargs)


@pytest.mark.parametrize("model", ["offset", "diag", "angles", "nine"])
def test_field_auto_calibrates_relative_to_the_estimated_magnitude(model):
    data = _simulated(model)
    res = make("lsq", model=model).fit(np.array(data.raw_nT), field="auto")
    ref = res.reference
    assert ref["estimated"] and "relative" in ref and "estimated" in ref["source"]
    # the shape is found as with the reference; only the overall gain is relative to the estimate
    truth = _simulated(model)
    with_ref = make("lsq", model=model).fit(truth)
    gain = ref["median_nT"] / 48000.0
    assert abs(gain - 1) < 0.02
    corrected = res.correct(data.raw_nT)
    expected = with_ref.correct(data.raw_nT) * gain
    assert np.max(np.abs(np.linalg.norm(corrected, axis=1) - np.linalg.norm(expected, axis=1))) < 0.5
    assert res.rms_after_nT < 3.0


def test_field_auto_through_the_command_line(recordings, tmp_path, capsys):
    a, _ = recordings
    code, out, err = run(capsys, "calibrate", a, "--method", "lsq", "--field", "auto", "--json",
                         "--save", tmp_path / "auto")
    assert code == 0, err
    d = json.loads(out)
    assert d["reference"]["estimated"] and "relative" in d["reference"] and "estimated" in err
    saved = json.loads((tmp_path / "auto.json").read_text())
    assert saved["reference"]["estimated"] is True and "overall gain" in saved["reference"]["relative"]


def test_every_result_has_uncertainties():
    for name, model, scenario in (("ellipsoid", "nine", "sphere9"), ("lsq", "angles", "lu2014"),
                                  ("nlopt", "offset", "sphere9")):
        res = make(name, model=model).fit(simulate(scenario, 0))
        assert set(res.uncertainty) == set(PARAM_NAMES[model]) and np.isfinite(res.noise_nT)
        assert all(v > 0 for v in res.uncertainty.values())


def test_field_auto_on_a_level_turntable_uses_the_angles_estimate():
    """No sphere or ellipsoid fits planar readings: the magnitude is the angles model's mean corrected one."""
    data = simulate("lu2014", 0)
    res = make("lsq", model="auto").fit(np.array(data.raw_nT), field="auto")
    assert res.model == "angles" and res.accepted
    assert "plane" in res.reference["source"]
    assert abs(res.reference["median_nT"] - float(np.median(data.f_ref_nT))) < 5.0
    np.testing.assert_allclose(res.x, data.truth.params.to_vector("angles"), atol=2e-4)


def test_export_is_atomic_and_never_over_an_input(recordings, tmp_path):
    """Python API: an export onto a hard link of the data file is refused (by inode) and leaves it intact;
    a .mat export goes through a temporary file that does not remain; the input's digest is unchanged."""
    import hashlib
    import os

    a, _ = recordings
    before = hashlib.sha256(a.read_bytes()).hexdigest()
    cal = make("lsq", model="nine").fit(simulate("sphere9", 0)).calibration()
    link = tmp_path / "link.json"
    os.link(a, link)
    with pytest.raises(InputError, match="is the input file"):
        export(cal, link, "json", force=True, inputs=[a])
    assert hashlib.sha256(a.read_bytes()).hexdigest() == before
    for fmt in ("json", "matlab", "ardupilot", "px4"):
        path = export(cal, tmp_path / f"cal_{fmt}", fmt, inputs=[a])
        assert path.stat().st_size > 0
        if fmt in ("json", "matlab"):
            np.testing.assert_allclose(load_calibration(path).matrix, cal.matrix, atol=1e-12)
    assert not [p.name for p in tmp_path.iterdir() if ".tmp" in p.name]
    out = apply_to_csv(cal, a, tmp_path / "applied.csv")
    assert out["input_sha256"] == before

"""A hostile-input corpus: files and options a careless or hostile user gives ``magbench``, each with the
exit status and the message it must get (CONTRACT section 3: 0 success, 2 bad input with one line on
stderr, 3 a calibration that ran but is rejected).  Every case also checks that no traceback is printed,
that stdout stays clean on failure, and that the input file is not changed."""
from __future__ import annotations

import hashlib

import numpy as np
import pytest

from magbench.benchmarks.cli import main
from magbench.simulate import attitude
from magbench.simulate.field import ConstantField
from magbench.simulate.scenarios import get_scenario
from magbench.simulate.sensor import ErrorParams, SensorModel

F_NT = 50000.0
FIELD = ConstantField.from_angles(F_NT, 55.0, 3.0)
NINE = ErrorParams(0.012, -0.008, 0.015, (1.021, 0.984, 1.008), (152.0, -218.0, 85.0))
ANGLES_ONLY = ErrorParams(0.012, -0.008, 0.015)


def _sphere(n=300, seed=0, errors=NINE, noise=1.0):
    rng = np.random.default_rng(seed)
    att = attitude.full_sphere(n, rng)
    return SensorModel(errors, noise_nT=noise).measure(att.body_field(np.asarray(FIELD.vector_nT)), rng)


def _plane(n=36, errors=NINE, wobble_deg=0.0, seed=1):
    rng = np.random.default_rng(seed)
    att = attitude.turntable(n, 360.0 / n)
    b = att.body_field(np.asarray(FIELD.vector_nT))
    if wobble_deg:
        from scipy.spatial.transform import Rotation

        tilt = Rotation.from_rotvec(np.radians(wobble_deg) * rng.uniform(-1, 1, (n, 3)) * [1, 1, 0])
        b = tilt.apply(b)
    return SensorModel(errors, noise_nT=1.0).measure(b, rng)


def _csv(raw, f_ref=F_NT, header=("bx", "by", "bz", "f_ref"), sep=",", meta=("# field_nT: 50000",), fmt="{:.4f}",
         newline="\n"):
    cols = [raw[:, 0], raw[:, 1], raw[:, 2]]
    if "f_ref" in [h.lower() for h in header]:
        cols.append(np.broadcast_to(f_ref, (len(raw),)))
    lines = list(meta) + [sep.join(header)]
    lines += [sep.join(fmt.format(v) for v in row) for row in zip(*cols)]
    return newline.join(lines) + newline


RAW = _sphere()
GOOD = _csv(RAW)


def _edit_row(text, index, new):
    lines = text.splitlines()
    first = next(i for i, ln in enumerate(lines) if not ln.startswith("#")) + 1
    lines[first + index] = new
    return "\n".join(lines) + "\n"


def _spike(raw, rows, size):
    raw = raw.copy()
    raw[rows, 0] += size
    return raw


def _alternating_reference():
    f = np.where(np.arange(len(RAW)) % 2, 45000.0, 50000.0)
    return _csv(RAW, f_ref=f)


def _half_uT():
    raw = RAW.copy()
    raw[::2] /= 1000.0
    return _csv(raw, fmt="{:.6g}")


# (id, file content (str or bytes) or None for no file, extra arguments, expected status, message fragment)
CASES = [
    # encodings
    ("utf8-bom", "\ufeff" + GOOD, [], 0, ""),
    ("crlf", GOOD.replace("\n", "\r\n"), [], 0, ""),
    ("utf16", GOOD.encode("utf-16"), [], 2, "not UTF-8"),
    ("latin1-comment", ("# site: Zürich\n" + GOOD).encode("latin-1"), [], 2, "not UTF-8"),
    ("binary-garbage", bytes(range(256)) * 4, [], 2, "not UTF-8"),
    # delimiters and layout
    ("semicolon", _csv(RAW, sep=";"), [], 0, ""),
    ("tab", _csv(RAW, sep="\t"), [], 0, ""),
    ("header-comma-rows-semicolon", _csv(RAW, sep=";").replace("bx;by;bz;f_ref", "bx,by,bz,f_ref"), [], 2,
     "has 1 field(s) but the header names 4"),
    ("extra-field-in-a-row", _edit_row(GOOD, 5, "1,2,3,50000,9"), [], 2, "not a readable CSV"),
    ("spaces-around-values", GOOD.replace(",", " , "), [], 0, ""),
    ("quoted-header", GOOD.replace("bx,by,bz,f_ref", '"bx","by","bz","f_ref"'), [], 0, ""),
    ("blank-lines", GOOD.replace("\n", "\n\n", 20), [], 0, ""),
    # columns
    ("duplicate-any-case", GOOD.replace("bx,by,bz,f_ref", "BX,bx,bz,f_ref"), [], 2, "more than once"),
    ("duplicate-same-case", GOOD.replace("bx,by,bz,f_ref", "bx,by,bx,f_ref"), [], 2, "more than once"),
    ("missing-bz", GOOD.replace("bx,by,bz,f_ref", "bx,by,bq,f_ref"), [], 2, "lacks column"),
    ("no-header", "\n".join(GOOD.splitlines()[2:]) + "\n", [], 2, "lacks column"),
    ("extra-columns", GOOD.replace("\n", ",x\n").replace("bx,by,bz,f_ref,x", "bx,by,bz,f_ref,comment")
     .replace("# field_nT: 50000,x", "# field_nT: 50000"), [], 0, ""),
    ("upper-case-names", GOOD.replace("bx,by,bz,f_ref", "BX,BY,BZ,F_REF"), [], 0, ""),
    ("other-order", _csv(RAW[:, [2, 0, 1]], header=("bz", "bx", "by", "f_ref")), [], 0, ""),
    # units, ADC counts, references
    ("uT-read-as-nT", _csv(RAW / 1000.0, f_ref=50.0, fmt="{:.6g}", meta=()), [], 2, "look like uT"),
    ("uT-with-units", _csv(RAW / 1000.0, f_ref=50.0, fmt="{:.6g}", meta=()), ["--units", "uT"], 0, ""),
    ("gauss-with-units", _csv(RAW / 1e5, f_ref=0.5, fmt="{:.8g}", meta=()), ["--units", "G"], 0, ""),
    ("nT-read-as-uT", GOOD, ["--units", "uT"], 2, "implausible"),
    ("adc-counts", _csv(np.round(RAW / 3.0517578125), meta=(), fmt="{:.0f}"), [], 2, "times the reference"),
    ("f-ref-ten-times-off", _csv(RAW, f_ref=5000.0, meta=()), [], 2, "times the reference"),
    ("field-option-ten-times-off", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--field", "5000"], 2,
     "implausible"),
    ("half-rows-in-uT", _half_uT(), [], 2, "mixes units"),
    ("reference-alternating", _alternating_reference(), [], 2, "reference jumps"),
    ("f-ref-zero-row", _edit_row(GOOD, 7, "1000,2000,3000,0"), [], 2, "positive"),
    ("f-ref-negative", _csv(RAW, f_ref=-50000.0), [], 2, "positive"),
    ("meta-field-negative", _csv(RAW, header=("bx", "by", "bz"), meta=("# field_nT: -50000",)), [], 2,
     "positive number"),
    ("meta-field-text", _csv(RAW, header=("bx", "by", "bz"), meta=("# field_nT: fifty",)), [], 2, "not a number"),
    ("meta-field-zero", _csv(RAW, header=("bx", "by", "bz"), meta=("# field_nT: 0",)), [], 2, "positive number"),
    ("meta-field-inf", _csv(RAW, header=("bx", "by", "bz"), meta=("# field_nT: inf",)), [], 2, "positive number"),
    ("no-reference", _csv(RAW, header=("bx", "by", "bz"), meta=()), [], 2, "no reference"),
    ("meta-field-used", _csv(RAW, header=("bx", "by", "bz")), [], 0, ""),
    ("field-option-used", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--field", "50000"], 0, ""),
    ("field-option-negative", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--field", "-3"], 2, "positive"),
    ("field-option-nan", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--field", "nan"], 2, "positive"),
    # attitude coverage
    ("plane-36", _csv(_plane(36)), [], 2, "degenerate attitude coverage"),
    ("plane-3600", _csv(_plane(3600)), [], 2, "degenerate attitude coverage"),
    ("plane-wobbling-2deg", _csv(_plane(360, wobble_deg=2.0)), [], 3, "least-covered direction is not determined"),
    ("plane-wobbling-12deg", _csv(_plane(360, wobble_deg=12.0)), [], 0, ""),
    ("plane-angles-model", _csv(_plane(36, errors=ANGLES_ONLY)), ["--model", "angles"], 0, ""),
    ("one-attitude-repeated", _csv(np.repeat(RAW[:1], 50, axis=0)), [], 2, "degenerate attitude coverage"),
    ("hemisphere", _csv(get_scenario("cap9").build(0).raw_nT), [], 0, ""),
    # spikes and outliers
    ("spike-5e6-ellipsoid", _csv(_spike(RAW, [17], 5e6)), ["--method", "ellipsoid"], 3, "outliers"),
    ("spike-5e6-lsq", _csv(_spike(RAW, [17], 5e6)), [], 3, "ransac"),
    ("spike-5e6-ransac", _csv(_spike(RAW, [17], 5e6)), ["--method", "ransac"], 0, ""),
    ("spikes-500nT-10pct-lsq", _csv(_spike(RAW, np.arange(0, 300, 10), 500.0)), [], 3, "points are outliers"),
    ("spikes-500nT-10pct-ransac", _csv(_spike(RAW, np.arange(0, 300, 10), 500.0)), ["--method", "ransac"], 0, ""),
    # broken values
    ("overflow-1e300", _edit_row(GOOD, 9, "1e300,1,1,50000"), [], 2, "beyond any magnetic field"),
    ("absurd-1e12", _edit_row(GOOD, 9, "1e12,1,1,50000"), [], 2, "beyond any magnetic field"),
    ("nan-value", _edit_row(GOOD, 3, "nan,1,1,50000"), [], 2, "non-finite"),
    ("empty-cell", _edit_row(GOOD, 3, ",1,1,50000"), [], 2, "missing"),
    ("text-value", _edit_row(GOOD, 3, "abc,1,1,50000"), [], 2, "non-numeric"),
    ("inf-value", _edit_row(GOOD, 3, "inf,1,1,50000"), [], 2, "non-finite"),
    # empty and tiny
    ("empty-file", "", [], 2, "no header"),
    ("comments-only", "# field_nT: 50000\n# nothing else\n", [], 2, "no header"),
    ("header-only", "bx,by,bz,f_ref\n", [], 2, "no data rows"),
    ("five-rows", _csv(RAW[:5]), [], 2, "too few"),
    ("one-row", _csv(RAW[:1]), [], 2, "too few"),
    # options
    ("seed-negative", GOOD, ["--seed", "-5"], 2, "negative"),
    ("seed-text", GOOD, ["--seed", "x"], 2, "not an integer"),
    ("param-not-int", GOOD, ["--method", "aga", "--param", "population=abc"], 2, "must be int"),
    ("param-no-equals", GOOD, ["--param", "population"], 2, "KEY=VALUE"),
    ("param-unknown", GOOD, ["--param", "colour=3"], 2, "no hyper-parameter"),
    ("param-bool-as-int", GOOD, ["--param", "bounded=1"], 2, "must be bool"),
    ("method-unknown", GOOD, ["--method", "nope"], 2, "unknown calibrator"),
    ("model-unknown", GOOD, ["--model", "ten"], 2, "invalid choice"),
    ("units-unknown", GOOD, ["--units", "kT"], 2, "invalid choice"),
    ("igrf-1850", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--igrf", "34.26,108.94,0.4,1850-01-01"], 2,
     "outside IGRF-14"),
    ("igrf-2035", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--igrf", "34.26,108.94,0.4,2035-01-01"], 2,
     "outside IGRF-14"),
    ("igrf-altitude", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--igrf", "34.26,108.94,50000,2013-06-27"], 2,
     "implausible"),
    ("igrf-latitude", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--igrf", "95,108.94,0.4,2013-06-27"], 2,
     "latitude"),
    ("igrf-malformed", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--igrf", "34.26;108.94"], 2, "--igrf"),
    ("igrf-bad-date", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--igrf", "34.26,108.94,0.4,2013-13-45"], 2,
     "--igrf"),
    ("directory", "DIRECTORY", [], 2, "is a directory"),
    ("missing-file", None, [], 2, "no such file"),
]


def _bad_igrf_is_an_ordinary_reference():
    """Sanity: a valid --igrf date gives a reference in the geomagnetic range (the IGRF cases above fail
    on their date, place or form, not on the mechanism)."""
    from magbench.simulate.field import igrf_field

    return igrf_field(34.26, 108.94, 0.4, "2013-06-27").total_nT


def test_the_corpus_is_large_enough():
    assert len(CASES) >= 60
    assert len({c[0] for c in CASES}) == len(CASES)
    assert 45000 < _bad_igrf_is_an_ordinary_reference() < 56000


@pytest.mark.parametrize("ident,content,extra,status,fragment", CASES, ids=[c[0] for c in CASES])
def test_hostile_input(tmp_path, capsys, ident, content, extra, status, fragment):
    path = tmp_path / "input.csv"
    if content == "DIRECTORY":
        path.mkdir()
    elif content is not None:
        path.write_bytes(content if isinstance(content, bytes) else content.encode("utf-8"))
    before = hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else None
    args = ["calibrate", str(path)] + (["--method", "lsq"] if "--method" not in extra else []) + extra
    code = main(args)
    out, err = capsys.readouterr()
    assert code == status, f"{ident}: exit {code}, expected {status}; stderr: {err.strip()}"
    assert "Traceback" not in err + out
    lines = [ln for ln in err.splitlines() if ln.strip()]
    if status == 2:
        assert len(lines) == 1, f"{ident}: bad input must give one line on stderr, got {lines}"
        assert out == "", f"{ident}: nothing on stdout on bad input"
    if status == 3:
        causes = [ln for ln in lines if ln.startswith("magbench: calibration rejected:")]
        assert len(causes) == 1 and len(lines) <= 2, lines
    if status == 0:
        assert "REJECTED" not in out
    assert fragment in err, f"{ident}: {fragment!r} not in {err.strip()!r}"
    if before is not None:
        assert hashlib.sha256(path.read_bytes()).hexdigest() == before, "the input file was changed"


def test_json_output_of_a_rejection_is_whole_and_stdout_is_one_object(tmp_path, capsys):
    import json

    path = tmp_path / "spike.csv"
    path.write_text(_csv(_spike(RAW, [17], 5e6)))
    assert main(["calibrate", str(path), "--method", "lsq", "--json"]) == 3
    out, err = capsys.readouterr()
    obj = json.loads(out)
    assert obj["accepted"] is False and any("outliers" in r for r in obj["rejections"])
    assert obj["reference"]["source"] == "the file's f_ref column"
    for key in ("method", "model", "alpha_rad", "beta_rad", "gamma_rad", "scale", "offset_nT", "matrix",
                "rms_before_nT", "rms_after_nT", "runtime_s", "n_evaluations", "seed", "warnings"):
        assert key in obj
    assert main(["calibrate", str(path), "--method", "lsq", "--json", "--accept-any"]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert obj["accepted"] is False and any("accept-any" in w for w in obj["warnings"])


def test_simulate_refuses_out_equal_to_truth_and_keeps_the_data(tmp_path, capsys):
    out = tmp_path / "x.csv"
    assert main(["simulate", "--scenario", "sphere9", "--out", str(out)]) == 0
    before = out.read_bytes()
    assert main(["simulate", "--scenario", "sphere9", "--out", str(out), "--truth", str(tmp_path / "." / "x.csv"),
                 "--force"]) == 2
    assert "same file" in capsys.readouterr().err
    assert out.read_bytes() == before


def test_control_characters_in_names_are_not_echoed_raw(tmp_path, capsys):
    name = str(tmp_path / "evil\x1b[31mred\rname.csv")
    assert main(["calibrate", name, "--method", "lsq"]) == 2
    err = capsys.readouterr().err
    assert "\x1b" not in err and "\r" not in err and "\\x1b" in err


def test_igrf_warnings_never_reach_stdout(tmp_path, capsys):
    path = tmp_path / "v.csv"
    path.write_text(_csv(RAW, header=("bx", "by", "bz"), meta=()))
    code = main(["calibrate", str(path), "--method", "lsq", "--json", "--igrf", "34.26,108.94,0.4,1850-01-01"])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""

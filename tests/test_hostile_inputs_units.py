"""Hostile inputs found by probing the command line with files a user's tools write (session of 2026-11-29): each
case gets exit 2 and one line naming what the file is, or a warning where the file is readable but a number would
otherwise be silently wrong; each beside its control, the readable file it differs from, which still works."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
from test_hostile_inputs import _refused as _refused_once
from test_hostile_inputs import _run

from magbench.calibrators import make
from magbench.calibrators.base import dead_axis
from magbench.numerics import copied_runs
from magbench.simulate import attitude
from magbench.simulate.dataset import Dataset, check_thousands_dots, read_csv
from magbench.simulate.field import ConstantField
from magbench.simulate.sensor import ErrorParams, SensorModel

F_NT = 50000.0
FIELD = ConstantField.from_angles(F_NT, 55.0, 3.0)
NINE = ErrorParams(0.012, -0.008, 0.015, (1.021, 0.984, 1.008), (152.0, -218.0, 85.0))


def _sphere(n=300, seed=0):
    rng = np.random.default_rng(seed)
    att = attitude.full_sphere(n, rng)
    return np.array(SensorModel(NINE, noise_nT=1.0).measure(att.body_field(np.asarray(FIELD.vector_nT)), rng))


def _write(path, header, rows, meta=()):
    path.write_text("\n".join([*meta, header, *rows]) + "\n")
    return path


def _refused(capsys, args, fragment):
    """``test_hostile_inputs._refused`` (exit 2, one line holding ``fragment``, nothing on stdout), the file unchanged."""
    path = Path(args[1])
    before = hashlib.sha256(path.read_bytes()).hexdigest()
    err = _refused_once(capsys, args, fragment)
    assert hashlib.sha256(path.read_bytes()).hexdigest() == before
    return err


def _euro_int(v: float) -> str:
    return f"{int(round(v)):,d}".replace(",", ".")  # 47717 -> '47.717', -295 -> '-295'


def test_dot_thousands_readings_are_refused_by_name_with_or_without_units(tmp_path, capsys):
    raw = _sphere()
    rows = [";".join(_euro_int(v) for v in r) + ";50.000" for r in raw]
    path = _write(tmp_path / "euro.csv", "bx;by;bz;f_ref", rows)
    for units in ("nT", "uT"):  # read as uT, the rows of small components had been 1000 times too large
        _refused(capsys, ["calibrate", path, "--method", "lsq", "--units", units], "dot as the thousands separator")
        _refused(capsys, ["diagnose", path, "--units", units], "dot as the thousands separator")
    # control: the same readings in uT with three decimals (fractions below 1 where a component crosses zero)
    rows = [";".join(f"{v / 1000:.3f}" for v in r) + ";50.000" for r in raw]
    ok = _write(tmp_path / "ut.csv", "bx;by;bz;f_ref", rows)
    code, _, err = _run(capsys, ["calibrate", ok, "--method", "lsq", "--units", "uT"])
    assert code == 0, err


def test_the_dot_thousands_rule_leaves_decimal_files_alone():
    rng = np.random.default_rng(4)
    for scale, decimals in ((1.0, 1), (1.0, 3), (1e-3, 3), (1e-3, 1)):  # nT and uT files, coarse and fine
        raw = np.round(_sphere(seed=int(rng.integers(100))) * scale, decimals)
        check_thousands_dots(raw)  # no refusal
    phone = np.round(rng.normal(0, 30, (500, 3)) + [150.0, -120.0, 200.0], 1)  # uT, 0.1 resolution, hard iron
    check_thousands_dots(phone)


def test_readings_and_reference_in_two_units_are_named_whatever_units_is_given(tmp_path, capsys):
    raw = _sphere()
    rows = [",".join(f"{v:.3f}" for v in r) + ",50.0" for r in raw]  # readings nT, f_ref uT
    path = _write(tmp_path / "mixed.csv", "bx,by,bz,f_ref", rows)
    for units in ("nT", "uT"):  # the advice had looped between the two
        _refused(capsys, ["calibrate", path, "--method", "lsq", "--units", units], "written in different units")
    rows = [",".join(f"{v / 1000:.5f}" for v in r) + ",50000.0" for r in raw]  # readings uT, f_ref nT
    path = _write(tmp_path / "mixed2.csv", "bx,by,bz,f_ref", rows)
    _refused(capsys, ["calibrate", path, "--method", "lsq"], "written in different units")
    rows = [",".join(f"{v / 1000:.5f}" for v in r) + ",50.0" for r in raw]  # control: both in uT
    ok = _write(tmp_path / "ut.csv", "bx,by,bz,f_ref", rows)
    assert _run(capsys, ["calibrate", ok, "--method", "lsq", "--units", "uT"])[0] == 0


def test_numbers_split_at_a_comma_get_the_reason(tmp_path, capsys):
    raw = _sphere(30)
    rows = [",".join(f"{v:.1f}".replace(".", ",") for v in r) + ",50000,0" for r in raw]
    path = _write(tmp_path / "comma.csv", "bx,by,bz,f_ref", rows)
    _refused(capsys, ["calibrate", path, "--method", "lsq"], "split at a decimal comma or a thousands comma")
    rows = [",".join(f'"{v:,.1f}"' for v in r) + ',"50,000.0"' for r in raw]  # quoted: one field each
    path = _write(tmp_path / "quoted.csv", "bx,by,bz,f_ref", rows)
    _refused(capsys, ["calibrate", path, "--method", "lsq"], "commas between thousands")
    rows = [";".join(f"{v:.1f}".replace(".", ",") for v in r) + ";50.000,0" for r in raw]
    path = _write(tmp_path / "dots.csv", "bx;by;bz;f_ref", rows)
    _refused(capsys, ["calibrate", path, "--method", "lsq"], "decimal comma")


def test_a_units_row_a_spaced_header_no_header_and_tesla_are_named(tmp_path, capsys):
    raw = _sphere()
    rows = [",".join(f"{v:.3f}" for v in r) + ",50000" for r in raw]
    path = _write(tmp_path / "units.csv", "bx,by,bz,f_ref", ["nT,nT,nT,nT", *rows])
    _refused(capsys, ["calibrate", path, "--method", "lsq"], "a row of units")
    path = _write(tmp_path / "spaced.csv", "bx by bz f_ref", [r.replace(",", " ") for r in rows])
    _refused(capsys, ["calibrate", path, "--method", "lsq"], "separated by spaces")
    path = _write(tmp_path / "nohead.csv", rows[0], rows[1:])
    _refused(capsys, ["calibrate", path, "--method", "lsq"], "needs a header row")
    tesla = [",".join(f"{v * 1e-9:.6e}" for v in r) for r in raw]
    path = _write(tmp_path / "tesla.csv", "bx,by,bz", tesla)
    _refused(capsys, ["calibrate", path, "--method", "lsq", "--field", "50000"], "look like tesla")


def test_a_constant_axis_is_called_dead_not_poor_coverage(tmp_path, capsys):
    raw = _sphere()
    raw[:, 1] = 0.0
    rows = [",".join(f"{v:.3f}" for v in r) + ",50000" for r in raw]
    path = _write(tmp_path / "dead.csv", "bx,by,bz,f_ref", rows)
    for method in ("lsq", "ga"):
        _refused(capsys, ["calibrate", path, "--method", method], "by reads 0 on every row: a dead")
    assert dead_axis(_sphere()) is None  # control
    assert "stuck sensor" in dead_axis(np.ones((10, 3)))


def test_rows_written_twice_under_new_times_widen_the_deviations_as_without_times():
    raw = _sphere()
    twice = np.concatenate([raw, raw])
    fits = {}
    for name, t in (("renumbered", np.arange(600.0)), ("no t", None)):
        fits[name] = make("lsq").fit(Dataset(twice, f_ref_nT=F_NT, t_s=t))
        assert any("repeat another exactly" in w for w in fits[name].warnings), name
    once = make("lsq").fit(Dataset(raw, f_ref_nT=F_NT, t_s=np.arange(300.0)))
    assert not any("repeat another exactly" in w for w in once.warnings)  # control
    for name, fit in fits.items():  # the copies add no information: the stated deviations are one record's
        assert fit.uncertainty["alpha_rad"] == pytest.approx(once.uncertainty["alpha_rad"], rel=0.1), name
    # a logger holding its last value repeats in place, and a coarse converter anywhere: neither is a copy
    assert not copied_runs(np.repeat(raw, 2, axis=0), np.arange(600)).any()
    coarse = np.round(np.random.default_rng(1).normal(size=(600, 3)) * 2) * 3
    assert not copied_runs(coarse, np.arange(600)).any()


def test_a_glitched_heading_is_refused_and_turns_counted_on_are_read(tmp_path, capsys):
    rng = np.random.default_rng(5)
    heading = np.arange(0.0, 360.0, 10.0)
    f = F_NT + 30 * np.cos(np.radians(heading)) + rng.normal(0, 1, len(heading))

    def series(h, name):
        rows = [f"{a:.3f},{b:.3f},{F_NT:.1f}" for a, b in zip(h, f)]
        return _write(tmp_path / name, "heading_deg,f_meas,f_ref", rows)

    glitched = heading.copy()
    glitched[5] = 1e6
    _refused(capsys, ["diagnose", series(glitched, "glitch.csv")], "row 5")
    for h, name in ((heading + 720.0, "turns.csv"), (heading - 720.0, "minus.csv")):  # controls
        code, out, err = _run(capsys, ["diagnose", series(h, name), "--json"])
        assert code == 0, err
        assert json.loads(out)["verdict"]


def test_time_and_temperature_columns_under_other_names_are_named(tmp_path, capsys):
    raw = _sphere()
    rows = [f"{i * 1000.0:.1f}," + ",".join(f"{v:.3f}" for v in r) + ",50000" for i, r in enumerate(raw)]
    path = _write(tmp_path / "tms.csv", "t_ms,bx,by,bz,f_ref", rows)
    code, out, err = _run(capsys, ["calibrate", path, "--method", "lsq"])
    assert code in (0, 3) and "column 't_ms' is not read: the time column is named t" in out, out + err
    code, out, err = _run(capsys, ["diagnose", path, "--json"])
    assert "'t_ms' is not read" in json.loads(out)["input_notes"]
    ok = _write(tmp_path / "t.csv", "t,bx,by,bz,f_ref", [r.replace(f"{i * 1000.0:.1f},", f"{float(i):.1f},", 1)
                                                          for i, r in enumerate(rows)])
    code, out, err = _run(capsys, ["calibrate", ok, "--method", "lsq"])
    assert code in (0, 3) and "is not read" not in out + err  # control


def test_fahrenheit_is_flagged_and_converted_when_declared(tmp_path):
    raw = _sphere(600)
    t = np.arange(600.0)
    temp_c = 20 + 10 * np.sin(2 * np.pi * t / 600)
    warm = raw + 3.0 * (temp_c - temp_c.mean())[:, None]  # 3 nT per deg C on every axis

    def file(temp, meta, name):
        rows = [f"{a:.1f},{x:.4f},{y:.4f},{z:.4f},50000,{b:.4f}" for a, (x, y, z), b in zip(t, warm, temp)]
        return _write(tmp_path / name, "t,bx,by,bz,f_ref,temp", rows, meta)

    fahrenheit = temp_c * 1.8 + 32
    undeclared = read_csv(file(fahrenheit, (), "f.csv"))
    assert "'# temp_unit: F'" in undeclared.meta["input_notes"]
    declared = read_csv(file(fahrenheit, ("# temp_unit: F",), "f2.csv"))
    assert np.allclose(declared.temp_C, temp_c, atol=1e-3) and "input_notes" not in declared.meta
    kelvin = read_csv(file(temp_c + 273.15, ("# temp_unit: K",), "k.csv"))
    assert np.allclose(kelvin.temp_C, temp_c, atol=1e-3)
    celsius = read_csv(file(temp_c, (), "c.csv"))  # control: no note
    assert "input_notes" not in celsius.meta
    declared.to_csv(tmp_path / "again.csv")  # written back in deg C, and said so
    assert np.allclose(read_csv(tmp_path / "again.csv").temp_C, temp_c, atol=1e-3)
    with pytest.raises(Exception, match="names no temperature unit"):
        read_csv(file(temp_c, ("# temp_unit: rankine",), "r.csv"))

"""What a hostile-input probe of the command line found (session 22): the --save name's extension chooses the format
when --export is not given; --folds below 2 is refused by the option itself; and a time column that steps back or
repeats is said, by calibrate (a warning) and by diagnose (``time_column``), while a reversed one is only reversed."""
from __future__ import annotations

import json

import numpy as np
import pytest

from magbench.benchmarks.cli import main
from magbench.numerics import time_column_note
from magbench.simulate import simulate


@pytest.fixture(scope="module")
def sphere9_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("cli") / "sphere9.csv"
    simulate("sphere9", 0).to_csv(path)
    return path


def _with_times(src, dst, change) -> None:
    lines = src.read_text().splitlines()
    first = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
    header = lines[first].split(",")
    col = header.index("t")
    rows = [ln.split(",") for ln in lines[first + 1:]]
    t = change(np.array([float(r[col]) for r in rows]))
    for r, v in zip(rows, t):
        r[col] = repr(float(v))
    dst.write_text("\n".join(lines[:first + 1] + [",".join(r) for r in rows]) + "\n")


@pytest.mark.parametrize("name,first_line", [("cal.param", "# magbench"), ("cal.params", "# magbench")])
def test_the_extension_of_save_chooses_the_format(tmp_path, capsys, sphere9_csv, name, first_line):
    out = tmp_path / name
    assert main(["calibrate", str(sphere9_csv), "--method", "lsq", "--save", str(out)]) == 0
    text = out.read_text()
    assert text.startswith(first_line)
    assert ("COMPASS_OFS_X" in text) == (name == "cal.param") and ("CAL_MAG0_XOFF" in text) == (name == "cal.params")
    assert "saved ardupilot" in capsys.readouterr().out if name == "cal.param" else True


def test_a_mat_name_without_export_is_a_mat_file(tmp_path, capsys, sphere9_csv):
    out = tmp_path / "cal.mat"
    assert main(["calibrate", str(sphere9_csv), "--method", "lsq", "--save", str(out)]) == 0
    assert out.read_bytes().startswith(b"MATLAB 5.0 MAT-file")
    assert main(["calibrate", str(sphere9_csv), "--method", "lsq", "--save", str(tmp_path / "plain")]) == 0
    assert json.loads((tmp_path / "plain.json").read_text())["method"] == "lsq"  # no extension: json, as before


def test_folds_below_two_are_refused_by_the_option(capsys, sphere9_csv):
    assert main(["diagnose", str(sphere9_csv), "--folds", "1"]) == 2
    err = capsys.readouterr().err
    assert "argument --folds: 1 must be at least 2" in err and len(err.strip().splitlines()) == 1


def test_time_column_notes():
    t = np.arange(10.0)
    assert time_column_note(t) is None and time_column_note(t[::-1]) is None and time_column_note(None) is None
    back = np.concatenate([t, t + 5])  # a logger restarted 5 s on: overlapping stretches
    note = time_column_note(back)
    assert note is not None and "steps back 1 time" in note and "rows 9 and 10: 9 -> 5 s" in note
    coarse = np.repeat(t, 2)
    note = time_column_note(coarse)
    assert note is not None and "10 rows (53 %) repeat the previous row's t" in note
    assert time_column_note(np.concatenate([t, [9.0], t[10:]])) is not None  # one repeat in 10: 10 % of the rows
    assert time_column_note(np.concatenate([np.arange(200.0), [199.0]])) is None  # one in 200: below 1 %


def test_calibrate_and_diagnose_say_a_clock_that_stepped_back(tmp_path, capsys, sphere9_csv):
    stepped = tmp_path / "stepped.csv"
    _with_times(sphere9_csv, stepped, lambda t: np.where(np.arange(len(t)) >= 100, t - 50.0, t))
    assert main(["calibrate", str(stepped), "--method", "lsq", "--json"]) == 0
    fit = json.loads(capsys.readouterr().out)
    assert any("the t column steps back 1 time" in w for w in fit["warnings"])
    assert main(["diagnose", str(stepped), "--json"]) == 0
    assert "steps back 1 time" in json.loads(capsys.readouterr().out)["time_column"]
    # the same readings in reverse time order: nothing to say
    reversed_ = tmp_path / "reversed.csv"
    _with_times(sphere9_csv, reversed_, lambda t: t[::-1])
    assert main(["calibrate", str(reversed_), "--method", "lsq", "--json"]) == 0
    assert not any("t column" in w for w in json.loads(capsys.readouterr().out)["warnings"])
    assert main(["diagnose", str(reversed_), "--json"]) == 0
    assert "time_column" not in json.loads(capsys.readouterr().out)


def test_compare_refuses_figure_options_with_no_figures(tmp_path, capsys):
    args = ["compare", "--scenarios", "sphere9", "--methods", "lsq", "ellipsoid", "--trials", "1", "--out",
            str(tmp_path / "c"), "--no-figures", "--quiet"]
    assert main(args + ["--format", "png"]) == 2
    err = capsys.readouterr().err
    assert "--format sets the figures, which --no-figures leaves out" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "c").exists()  # refused before the campaign's folder is made
    assert main(args) == 0  # negative control


def test_a_field_line_that_disagrees_with_the_f_ref_column_is_said_not_used(tmp_path, capsys, sphere9_csv):
    """A file that says two fields ('# field_nT: 60000' beside an f_ref column of 50,000 nT) had its line ignored
    without a word; calibrate and diagnose now say which one they used.  The control: the simulated file's own line,
    which agrees with its column, is not mentioned."""
    text = sphere9_csv.read_text()
    assert "# field_nT: 50000" in text
    path = tmp_path / "two_fields.csv"
    path.write_text(text.replace("# field_nT: 50000", "# field_nT: 60000"))
    for cmd in (["calibrate", str(path), "--method", "lsq"], ["diagnose", str(path)]):
        assert main(cmd) in (0, 3)
        assert "'# field_nT: 60000.00' line was not used: its f_ref column (median 50000 nT) comes first" in \
            capsys.readouterr().out
    assert main(["calibrate", str(path), "--method", "lsq", "--json"]) in (0, 3)
    assert "field_nT: 60000" in json.loads(capsys.readouterr().out)["reference"]["ignored"]
    assert main(["calibrate", str(sphere9_csv), "--method", "lsq", "--json"]) == 0
    assert "ignored" not in json.loads(capsys.readouterr().out)["reference"]

"""Readings of exactly 0 on all three axes (a dropout, or a missing value a logger wrote as 0) have no direction, and
the Jacobian of |M (raw - o)| at them is 0/0: they crashed calibrate and diagnose with "internal error: LinAlgError:
Eigenvalues did not converge" (exit 1).  They are refused with the rows named, exit 2, the input untouched."""
import subprocess
import sys

import pytest

from magbench.benchmarks.diagnosis import diagnose
from magbench.calibrators import make
from magbench.errors import InputError
from magbench.simulate import simulate
from magbench.simulate.dataset import Dataset


def _with_zero_rows(rows=(7, 57, 107)):
    d = simulate("sphere9", 0)
    raw = d.raw_nT.copy()
    raw[list(rows)] = 0.0
    return d, raw


@pytest.mark.parametrize("method", ["lsq", "nlopt", "ellipsoid"])
def test_calibrators_refuse_zero_readings_naming_the_rows(method):
    d, raw = _with_zero_rows()
    with pytest.raises(InputError, match=r"exactly 0 on all three axes in 3 row\(s\) \(rows 7, 57, 107\)"):
        make(method).fit(Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s))
    # the negative control: a reading of 0 on two axes is a reading (along the third axis)
    raw[[7, 57, 107]] = [0.0, 0.0, 5e4]
    assert make(method).fit(Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s)).x is not None


def test_diagnose_refuses_zero_readings():
    d, raw = _with_zero_rows((3,))
    with pytest.raises(InputError, match=r"exactly 0 on all three axes in 1 row\(s\) \(row 3\)"):
        diagnose(Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s))


@pytest.mark.parametrize("command", [["calibrate", "--method", "nlopt"], ["diagnose"]])
def test_the_commands_say_it_in_one_line_with_exit_2(command, tmp_path):
    d, raw = _with_zero_rows(range(7, 300, 50))
    path = tmp_path / "zeros.csv"
    Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s).to_csv(path)
    before = path.read_bytes()
    p = subprocess.run([sys.executable, "-m", "magbench", command[0], str(path), *command[1:]], capture_output=True,
                       text=True)
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in p.stderr
    assert "6 row(s) (rows 7, 57, 107, 157, 207 (lines 9, 59, 109, 159, 209), ...)" in lines[0]
    assert path.read_bytes() == before  # the input is not changed


def test_apply_refuses_them_and_writes_nothing(tmp_path):
    """``apply`` had written 'calibrated' values for the dropout rows (the offsets turned: f_cal 279 nT in a 50,000 nT
    field); it refuses as calibrate does, and writes no output.  The control: the intact file is applied."""
    d, raw = _with_zero_rows((4, 9))
    cal = tmp_path / "cal.json"
    for name, readings in (("zeros.csv", raw), ("intact.csv", d.raw_nT)):
        Dataset(readings, f_ref_nT=d.f_ref_nT, t_s=d.t_s).to_csv(tmp_path / name)
    subprocess.run([sys.executable, "-m", "magbench", "calibrate", str(tmp_path / "intact.csv"), "--method", "lsq",
                    "--save", str(cal)], capture_output=True, check=True)
    for name, code in (("zeros.csv", 2), ("intact.csv", 0)):
        path, out = tmp_path / name, tmp_path / f"out_{name}"
        p = subprocess.run([sys.executable, "-m", "magbench", "apply", str(cal), str(path), "--out", str(out)],
                           capture_output=True, text=True)
        assert p.returncode == code, p.stderr
        assert out.exists() == (code == 0)
        if code:
            assert "exactly 0 on all three axes in 2 row(s) (rows 4, 9 (lines 6, 11))" in p.stderr  # rows, and lines

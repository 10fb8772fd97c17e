"""``import magbench`` exposes the main entry points, documented, without importing the heavy libraries."""
import subprocess
import sys

import numpy as np

import magbench


def test_the_entry_points_are_there_with_docstrings():
    for name in ("simulate", "read_csv", "make", "calibrate", "diagnose", "load_calibration"):
        obj = getattr(magbench, name)
        assert callable(obj) and (obj.__doc__ or "").strip(), name
    assert set(magbench.__all__) >= {"simulate", "read_csv", "make", "calibrate", "diagnose", "load_calibration"}


def test_simulate_calibrate_round_trip_from_the_top_level():
    data = magbench.simulate("sphere9", seed=1)
    result = magbench.calibrate(data, method="lsq", model="nine")
    assert result.accepted and result.rms_after_nT < 3.0
    assert np.allclose(result.correct(data.raw_nT).shape, data.raw_nT.shape)
    # the subpackage is still a package beside being callable
    assert magbench.simulate.ErrorParams is not None


def test_import_magbench_stays_light():
    code = ("import sys, magbench; heavy = [m for m in ('pandas', 'matplotlib', 'scipy', 'numba') if m in sys.modules];"
            "print(','.join(heavy))")
    out = subprocess.run([sys.executable, "-P", "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "", f"import magbench imported {out}"

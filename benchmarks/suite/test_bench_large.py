"""Large records, measured as a user meets them: whole ``magbench`` processes on generated files, wall
time by pytest-benchmark and peak memory (the child's maximum resident set) in ``extra_info``.  The
baseline in the same run is the same command on a tenth of the rows (time should grow linearly).

    python -m magbench.benchmarks.large          # writes results/large_inputs.md and the raw JSON
"""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from magbench.simulate import attitude
from magbench.simulate.field import ConstantField
from magbench.simulate.sensor import ErrorParams, SensorModel

SAMPLE_INTERVAL_S = 0.01
ERRORS = ErrorParams(0.012, -0.008, 0.015, (1.021, 0.984, 1.008), (152.0, -218.0, 85.0))
MEASURE = """
import resource, subprocess, sys, time
t0 = time.perf_counter()
p = subprocess.run(sys.argv[1:], capture_output=True, text=True)
wall = time.perf_counter() - t0
rss_kib = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
print(p.returncode, wall, rss_kib)
sys.stderr.write(p.stderr[-2000:])
"""


def _write(write_csv, path, n, seed=0):
    rng = np.random.default_rng(seed)
    field = ConstantField.from_angles(50000.0, 55.0, 3.0)
    att = attitude.tumble(n, rng, duration_s=n * SAMPLE_INTERVAL_S)  # smooth: neighbours in time are close
    raw = SensorModel(ERRORS, noise_nT=2.0).measure(att.body_field(np.asarray(field.vector_nT)), rng)
    t = att.t_s
    temp = 20.0 + 5.0 * np.sin(2 * np.pi * t / t[-1])
    write_csv(path, np.column_stack([t, raw, np.full(n, 50000.0), temp]), "t,bx,by,bz,f_ref,temp")
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory, write_csv):
    d = tmp_path_factory.mktemp("large")
    return {n: _write(write_csv, d / f"rows{n}.csv", n) for n in (200_000, 1_000_000, 2_000_000)}


def _run(benchmark, args):
    """One whole process per round; returns (exit status, wall s, peak RSS MiB) of the last round."""
    out = {}

    def once():
        p = subprocess.run([sys.executable, "-c", MEASURE, sys.executable, "-m", "magbench", *args],
                           capture_output=True, text=True, env={**os.environ, "PYTHONWARNINGS": "ignore"})
        code, wall, rss = p.stdout.split()
        out.update(code=int(code), wall_s=float(wall), peak_rss_mib=int(rss) / 1024.0)

    benchmark.pedantic(once, rounds=1, iterations=1)
    benchmark.extra_info.update(out)
    return out


@pytest.mark.benchmark(group="calibrate --method lsq, whole process")
@pytest.mark.parametrize("rows", [200_000, 2_000_000])
def test_calibrate_lsq(benchmark, files, rows):
    out = _run(benchmark, ["calibrate", str(files[rows]), "--method", "lsq", "--json"])
    benchmark.extra_info["rows"] = rows
    assert out["code"] in (0, 3)


@pytest.mark.benchmark(group="diagnose, whole process")
@pytest.mark.parametrize("rows", [200_000, 1_000_000])
def test_diagnose(benchmark, files, rows):
    out = _run(benchmark, ["diagnose", str(files[rows]), "--json"])
    benchmark.extra_info["rows"] = rows
    assert out["code"] == 0

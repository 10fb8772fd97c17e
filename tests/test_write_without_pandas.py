"""``Dataset.to_csv`` writes what pandas' ``to_csv(index=False, float_format=...)`` writes, byte for byte (NaN as an
empty field, infinities, negative zero, columns given as integers), without importing pandas; ``magbench simulate``
then runs without it (the control: the same process once pandas is imported says so)."""
import io
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from magbench.simulate import simulate
from magbench.simulate.dataset import Dataset
from magbench.simulate.scenarios import scenario_names


def pandas_text(d: Dataset, float_format: str) -> str:
    cols = {}
    if d.t_s is not None:
        cols["t"] = d.t_s
    cols["bx"], cols["by"], cols["bz"] = d.raw_nT.T
    for name, value in (("f_ref", d.f_ref_nT), ("temp", d.temp_C), ("heading_deg", d.heading_deg)):
        if value is not None:
            cols[name] = value
    buf = io.StringIO()
    for key, value in d.meta.items():
        buf.write(f"# {key}: {value}\n")
    pd.DataFrame(cols).to_csv(buf, index=False, float_format=float_format, lineterminator="\n")
    return buf.getvalue()


def awkward() -> list[Dataset]:
    rng = np.random.default_rng(0)
    raw = rng.normal(size=(40, 3)) * 1e5
    raw[0] = [np.nan, np.inf, -np.inf]
    raw[1] = [-0.0, -1e-6, 5e-5]
    raw[2] = [1e17, -1e-300, 123456789.123456]
    return [Dataset(raw, f_ref_nT=np.full(40, 5e4), t_s=np.arange(40), temp_C=rng.normal(size=40)),
            Dataset(raw, heading_deg=np.arange(40, dtype=np.int32), meta={"note": "integers"})]


@pytest.mark.parametrize("float_format", ["%.4f", "%.3f", "%g", "%.10e"])
def test_to_csv_is_pandas_byte_for_byte(tmp_path, float_format):
    for d in [simulate(name, 0) for name in scenario_names()] + awkward():
        path = tmp_path / "d.csv"
        d.to_csv(path, float_format=float_format)
        assert path.read_text() == pandas_text(d, float_format)


SIMULATE = """
import contextlib, io, sys
from magbench.benchmarks.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    code = main(["simulate", "--scenario", "tumble9", "--out", {path!r}])
print(code, "pandas" in sys.modules)
"""

@pytest.mark.parametrize("pandas_first", [False, True], ids=["simulate", "control-pandas-imported"])
def test_simulate_writes_without_pandas(tmp_path, pandas_first):
    code = ("import pandas\n" if pandas_first else "") + SIMULATE.format(path=str(tmp_path / "o.csv"))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["0", str(pandas_first)]

"""A solver's one-time costs (its first-use imports: pycma takes 1-1.5 s, SciPy's optimizers less; a GA's compiled
kernel, loaded or compiled) belong to the process, not to a fit: ``fit`` calls the calibrator's ``one_time_setup``
before its clock starts, and the fit that paid for it says so in ``extra["one_time_s"]`` (``calibrate`` prints it
beside the runtime).  Checked in fresh interpreters, where nothing has been imported or loaded yet."""
import importlib
import json
import subprocess
import sys

import pytest

from magbench.calibrators import available, get

FIRST_AND_SECOND = """
import json, sys
from magbench.simulate import simulate
from magbench.calibrators import make
d = simulate("sphere9", 0)
before = [m for m in {modules!r} if m in sys.modules]
first = make({method!r}, **{params!r}).fit(d)
second = make({method!r}, **{params!r}).fit(d)
print(json.dumps({{"before": before, "first": first.extra.get("one_time_s"), "second": second.extra.get("one_time_s"),
                  "after": [m for m in {modules!r} if m in sys.modules]}}))
"""


@pytest.mark.parametrize("method, params", [("cmaes", {"max_evaluations": 300}), ("de", {"generations": 5})])
def test_the_first_fit_reports_its_imports_and_the_second_none(method, params):
    modules = get(method).imports
    assert modules
    code = FIRST_AND_SECOND.format(modules=modules, method=method, params=params)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["before"] == []  # the registry and the simulator do not import them: the control
    assert got["first"] is not None and got["first"] > 0
    assert got["second"] is None
    assert got["after"] == list(modules)


def test_a_fit_in_a_process_that_has_them_reports_nothing():
    from magbench.simulate import simulate

    for name in get("cmaes").imports:
        importlib.import_module(name)
    res = get("cmaes")(max_evaluations=300).fit(simulate("sphere9", 0))
    assert "one_time_s" not in res.extra


@pytest.mark.parametrize("method", sorted(available()))
def test_every_declared_import_is_a_module(method):
    for name in get(method).imports:
        assert isinstance(name, str) and importlib.util.find_spec(name) is not None


GA_RUNS = """
import json
from magbench.simulate import simulate
from magbench.calibrators import make
from magbench.calibrators.methods import _gakernel
d = simulate("sphere9", 0)
runs = [make("ga", generations=50).fit(d) for _ in range(3)]
print(json.dumps({"one_time": [r.extra.get("one_time_s") for r in runs], "loaded": _gakernel._LOADED}))
"""


def test_a_ga_loads_its_compiled_kernel_before_the_clock():
    """A process's first GA run of this size breeds in numpy (no one-time cost: ``choose``), its second in numba,
    whose import and kernel load (or compile) ``one_time_setup`` pays before that run's clock; the third pays
    nothing."""
    pytest.importorskip("numba")
    out = subprocess.run([sys.executable, "-c", GA_RUNS], capture_output=True, text=True, check=True)
    got = json.loads(out.stdout.strip().splitlines()[-1])
    first, second, third = got["one_time"]
    assert first is None and second is not None and second > 0 and third is None
    assert got["loaded"] == {"_real_generation_loops": True}


DIAGNOSE = """
import contextlib, io, json, sys
from magbench.benchmarks.cli import main
buf = io.StringIO()
with contextlib.redirect_stdout(buf):
    code = main(["diagnose", {path!r}, "--json"])
used = "gravity_direction_explained_pct" in json.loads(buf.getvalue())["localization"]
print(code, "pandas" in sys.modules, used)
"""


@pytest.mark.parametrize("gravity, sep", [(False, ","), (True, ","), (True, ";"), (True, "\t")],
                         ids=["no-accelerometer", "accelerometer", "accelerometer-semicolons", "accelerometer-tabs"])
def test_diagnose_reads_accelerometer_columns_without_pandas(tmp_path, gravity, sep):
    """``diagnose`` reads a file's accelerometer columns as it reads its readings (``read_columns``), without pandas
    (its import was 0.15-0.2 s of a diagnose); with them the diagnosis localizes by the gravity direction, the
    control without them does not.  A file with semicolons or tabs had its ax, ay, az left out without a word (they
    were looked for in a header split at commas)."""
    import numpy as np

    from magbench.simulate import simulate

    d = simulate("sphere9", 0)
    cols = [d.t_s, *d.raw_nT.T, d.f_ref_nT]
    names = ["t", "bx", "by", "bz", "f_ref"]
    if gravity:
        cols += list(np.random.default_rng(0).normal(0, 1, (3, len(d))))
        names += ["AX", "ay", "Az"]  # any letter case
    path = tmp_path / "rec.csv"
    np.savetxt(path, np.column_stack(cols), delimiter=sep, header=sep.join(names), comments="")
    out = subprocess.run([sys.executable, "-c", DIAGNOSE.format(path=str(path))], capture_output=True, text=True,
                         check=True)
    assert out.stdout.split() == ["0", "False", str(gravity)]

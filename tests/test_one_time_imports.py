"""A solver's first-use imports (pycma takes 1-1.5 s, SciPy's optimizers less) are a one-time cost of the
process, not of a fit: ``fit`` imports a calibrator's ``imports`` before its clock starts, and the fit that
paid for them says so in ``extra["import_s"]`` (``calibrate`` prints it beside the runtime).  Checked in fresh
interpreters, where nothing has imported them yet."""
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
print(json.dumps({{"before": before, "first": first.extra.get("import_s"), "second": second.extra.get("import_s"),
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
    assert "import_s" not in res.extra


@pytest.mark.parametrize("method", sorted(available()))
def test_every_declared_import_is_a_module(method):
    for name in get(method).imports:
        assert isinstance(name, str) and importlib.util.find_spec(name) is not None

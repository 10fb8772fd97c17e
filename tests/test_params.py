"""One resolver for hyper-parameters (calibrators/params.py): the same constraints and the same budget
conversion from Python and from the command line, with messages in the words of each."""
import json

import pytest

from magbench.benchmarks.cli import main
from magbench.calibrators import Budget, make
from magbench.errors import InputError
from magbench.simulate import simulate


@pytest.fixture(scope="module")
def data():
    return simulate("sphere9", seed=1)


def test_budget_as_an_int_from_python(data):
    res = make("ga", budget=1000).fit(data)
    assert res.n_evaluations == 1000 and res.hyperparameters["budget"] == 1000
    assert make("ga", budget=Budget(max_evaluations=1000)).fit(data).n_evaluations == 1000


@pytest.mark.parametrize("method", ["ga", "aga", "rga", "aco", "cmaes", "de", "nlopt", "lsq", "aga-lm"])
def test_budget_from_the_command_line(tmp_path, capsys, method):
    path = tmp_path / "s.csv"
    assert main(["simulate", "--scenario", "sphere9", "--seed", "1", "--out", str(path)]) == 0
    capsys.readouterr()
    model = "angles" if method in ("aga", "aga-lm") else "nine"
    code = main(["calibrate", str(path), "--method", method, "--model", model, "--param", "budget=500", "--json",
                 "--accept-any"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["n_evaluations"] <= 500
    assert out["n_evaluations"] == out["n_function_evaluations"] + len(out["uncertainty"]) * out["n_jacobians"]


@pytest.mark.parametrize("value,wanted", [("abc", "an int >= 1 or a Budget or None"), (0, "an int >= 1"),
                                          (2.5, "an int >= 1"), (True, "an int >= 1")])
def test_bad_budget_is_refused_in_python_words(value, wanted):
    with pytest.raises(InputError, match=wanted) as err:
        make("ga", budget=value)
    assert "--" not in str(err.value)


def test_constraints_are_checked_at_fit_too(data):
    cal = make("lsq")
    object.__setattr__(cal, "seed", -1)  # set after construction, around make()
    with pytest.raises(InputError, match="seed must be an int >= 0 or None"):
        cal.fit(data)


def test_the_command_line_reports_a_bad_budget_on_one_line(tmp_path, capsys):
    path = tmp_path / "s.csv"
    assert main(["simulate", "--scenario", "sphere9", "--seed", "1", "--out", str(path)]) == 0
    capsys.readouterr()
    assert main(["calibrate", str(path), "--method", "ga", "--param", "budget=-3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "budget must be an int >= 1" in err[0]


def test_python_errors_speak_python_and_the_command_line_translates(tmp_path, capsys, data):
    with pytest.raises(InputError) as err:
        make("ellipsoid", model="angles").fit(data)
    assert "--" not in str(err.value) and "model='nine'" in str(err.value)
    with pytest.raises(InputError) as err:
        make("lsq").fit(data.raw_nT)  # no reference
    assert "--" not in str(err.value) and "f_ref_nT=" in str(err.value)
    path = tmp_path / "s.csv"
    assert main(["simulate", "--scenario", "sphere9", "--seed", "1", "--out", str(path)]) == 0
    capsys.readouterr()
    assert main(["calibrate", str(path), "--method", "ellipsoid", "--model", "angles"]) == 2
    assert "--model nine" in capsys.readouterr().err

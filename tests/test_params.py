"""One resolver for hyper-parameters (calibrators/params.py): the same constraints and the same budget
conversion from Python and from the command line, with messages in the words of each."""
import json
import re

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
    with pytest.raises(InputError, match=r"seed must be an int in \[0, 18446744073709551615\] or None"):
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


def _outside(interval):
    """Values just outside ``interval`` (each refused), of its own kind."""
    from numbers import Integral

    step = 1 if interval.kind is Integral else 1e-9
    out = []
    if interval.left is not None:
        out.append(interval.left - step if interval.closed in ("both", "left") else interval.left)
    if interval.right is not None:
        out.append(interval.right + step if interval.closed in ("both", "right") else interval.right)
    return [int(v) if interval.kind is Integral else float(v) for v in out]


def _declared_intervals():
    from magbench.calibrators import available
    from magbench.calibrators.params import Interval

    for name, cls in sorted(available().items()):
        for param, allowed in cls._parameter_constraints.items():
            intervals = [c for c in allowed if isinstance(c, Interval)]
            if len(intervals) == 1:
                for value in _outside(intervals[0]):
                    yield name, param, value


@pytest.mark.parametrize("name,param,value", list(_declared_intervals()))
def test_every_declared_range_refuses_a_value_just_outside_it(name, param, value):
    """scikit-learn's check_param_validation: each declared interval refuses the nearest value outside it,
    by make() and at fit (set after construction), in one line naming the parameter."""
    with pytest.raises(InputError, match=rf"{name}: hyper-parameter {param} must be") as err:
        make(name, **{param: value})
    assert "\n" not in str(err.value)


def test_every_calibrator_accepts_its_own_defaults():
    """The negative control of the ranges: every default satisfies its declared constraints."""
    from magbench.calibrators import available

    for name, cls in available().items():
        cal = make(name)
        cls.check_param_values(cal.get_params())


@pytest.mark.parametrize("name,params,words,control", [
    ("ga", {"elitism": 80}, "elitism (80) must be less than population (80)", {"elitism": 79}),
    ("rga", {"population": 6, "elitism": 6}, "must be less than population", {"population": 6, "elitism": 5}),
    ("aga", {"population": 81}, "population must be even", {"population": 82}),
    ("aga", {"population": 10, "elitism": 11}, "must be at most population", {"population": 10, "elitism": 10}),
    ("ransac", {"sample_size": 5}, "sample_size must be 0 (automatic) or at least 9", {"sample_size": 9}),
    ("nlopt", {"algorithm": "XYZ"}, "unknown algorithm 'XYZ'", {"algorithm": "LN_SBPLX"}),
    ("nlopt", {"algorithm": "LN_BOBYQA_X"}, "unknown algorithm", {"algorithm": "GN_ISRES"}),
])
def test_parameters_valid_alone_but_not_together_are_refused(name, params, words, control):
    with pytest.raises(InputError, match=re.escape(words)):
        make(name, **params)
    make(name, **control)  # the negative control, next to the limit


@pytest.mark.parametrize("spec,words", [
    ("ga:population=3", "population must be an int in [4, 1000000]"), ("ga:pc=2", "pc must be a float in [0, 1]"),
    ("ga:elitism=80", "must be less than population"), ("cmaes:sigma0=-1", "sigma0 must be a float in (0, 1]"),
    ("ga:seed=5", "seed is not a method's parameter in a campaign"),
    ("lsq:model=angles", "model is not a method's parameter in a campaign"),
])
def test_a_campaign_refuses_a_configuration_that_cannot_run_before_any_run(tmp_path, capsys, spec, words):
    """Before, each of these ran every trial to a failed row (fin 0 %) and the campaign exited 0."""
    out = tmp_path / "c"
    code = main(["compare", "--scenarios", "sphere9", "--methods", spec, "--trials", "1", "--out", str(out),
                 "--quiet", "--no-figures"])
    err = capsys.readouterr().err
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1, err
    assert not (out / "runs.csv").exists()


@pytest.mark.parametrize("item", ["seed=5", "model=angles"])
def test_calibrate_param_refuses_what_has_its_own_option(tmp_path, capsys, item):
    """--param seed=5 was an internal error (exit 1: make() got seed twice)."""
    path = tmp_path / "s.csv"
    assert main(["simulate", "--scenario", "sphere9", "--seed", "1", "--out", str(path)]) == 0
    capsys.readouterr()
    assert main(["calibrate", str(path), "--method", "ga", "--param", item]) == 2
    err = capsys.readouterr().err
    assert f"has its own option, --{item.split('=')[0]}" in err and len(err.strip().splitlines()) == 1

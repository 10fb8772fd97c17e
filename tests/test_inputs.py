"""What ``Calibrator.fit`` takes from Python (calibrators/inputs.py): arrays, lists and DataFrames of real
numbers; anything else is an ``InputError`` that says what is wrong, never a silently different number."""
import numpy as np
import pandas as pd
import pytest

from magbench.calibrators import make
from magbench.errors import InputError
from magbench.simulate import simulate

DATA = simulate("sphere9", 0)
F = 50000.0


@pytest.mark.parametrize("name,data,kwargs,words", [
    ("complex readings", DATA.raw_nT + 1j * DATA.raw_nT, {"f_ref_nT": F}, "readings must be real numbers, not complex"),
    ("one complex value in a list", [list(r) for r in DATA.raw_nT[:-1]] + [[1 + 2j, 0.0, 0.0]], {"f_ref_nT": F},
     "readings must be real numbers, not complex"),
    ("complex reference", DATA.raw_nT, {"f_ref_nT": F + 3j}, "the reference must be real numbers, not complex"),
    ("complex DataFrame column", pd.DataFrame(DATA.raw_nT + 1j, columns=["bx", "by", "bz"]), {"f_ref_nT": F},
     "DataFrame column bx must be real numbers, not complex"),
    ("text", [["a", "b", "c"]] * 20, {"f_ref_nT": F}, "readings must be numbers"),
    ("transposed", DATA.raw_nT.T, {"f_ref_nT": F}, "not of shape (3, 300)"),
])
def test_what_fit_refuses(name, data, kwargs, words):
    """Complex readings were cast to float with only numpy's warning: the fit of x + iy was x's."""
    with pytest.raises(InputError) as err:
        make("lsq").fit(data, **kwargs)
    assert words in str(err.value)


@pytest.mark.parametrize("data", [DATA.raw_nT, DATA.raw_nT.tolist(), DATA.raw_nT.astype(object),
                                  DATA.raw_nT.astype(np.float32), pd.DataFrame(DATA.raw_nT, columns=["bx", "by", "bz"])])
def test_what_fit_takes_gives_the_same_answer(data):
    """The negative controls: the same readings as floats, a list, objects, float32 or a DataFrame."""
    ref = make("lsq").fit(DATA.raw_nT, f_ref_nT=F)
    res = make("lsq").fit(data, f_ref_nT=F)
    assert res.rms_after_nT == pytest.approx(ref.rms_after_nT, rel=1e-4)  # float32 rounds 50000 nT to 0.004 nT


@pytest.mark.parametrize("column", ["raw_nT", "f_ref_nT", "t_s", "temp_C", "heading_deg"])
def test_a_dataset_refuses_complex_columns(column):
    """``Dataset`` (what diagnose() and every calibrator read) refuses complex values in any column."""
    from magbench.simulate.dataset import Dataset

    kwargs = {"raw_nT": DATA.raw_nT, "f_ref_nT": DATA.f_ref_nT}
    kwargs[column] = np.asarray(kwargs.get(column, np.zeros(len(DATA))), dtype=float) + 1j
    with pytest.raises(InputError, match=f"{column} must be real numbers, not complex"):
        Dataset(**kwargs)
    Dataset(**{k: v.real for k, v in kwargs.items()})  # the control


def _diagnose(**kwargs):
    from magbench.benchmarks.diagnosis import diagnose

    data = kwargs.pop("data", DATA)
    return diagnose(data, **kwargs)


@pytest.mark.parametrize("call,words", [
    (lambda: simulate("sphere9", -1), "seed must be an integer from 0 to 2**64 - 1, or None, got -1"),
    (lambda: simulate("sphere9", 1.5), "seed must be an integer from 0 to 2**64 - 1, or None, got 1.5"),
    (lambda: simulate("sphere9", 2**64), "seed must be an integer from 0 to 2**64 - 1, or None, got 18446744073709551616"),
    (lambda: make("nlopt", seed=2**64), "seed must be an int in [0, 18446744073709551615] or None"),
    (lambda: _diagnose(folds=2.5), "folds must be an integer, got 2.5"),
    (lambda: _diagnose(seed=-1), "seed must be at least 0, got -1"),
    (lambda: _diagnose(data=DATA.raw_nT), "diagnose takes a Dataset"),
    (lambda: _diagnose(gravity=np.ones((10, 3))), "gravity must be an (N, 3) array"),
    (lambda: _diagnose(gravity=np.full((300, 3), np.nan)), "gravity has 300 row(s) that are not a direction"),
    (lambda: _diagnose(gravity=np.zeros((300, 3))), "gravity has 300 row(s) that are not a direction"),
])
def test_library_entry_points_refuse_bad_values_in_their_own_words(call, words):
    """Before: numpy's ValueError/TypeError for a seed, IndexError for a gravity array of the wrong shape,
    LinAlgError (LAPACK printing on stderr) for NaN gravity, AttributeError for an array given to diagnose."""
    with pytest.raises(InputError) as err:
        call()
    assert words in str(err.value)


@pytest.mark.parametrize("kwargs,words", [
    ({"alpha_rad": float("nan")}, "alpha_rad must be finite"), ({"scale": (0, 1, 1)}, "scale must be three positive"),
    ({"scale": (1, 1)}, "scale must be three numbers (x, y, z), got 2"), ({"offset_nT": ("a", 0, 0)}, "must be a number"),
])
def test_error_params_refuse_what_is_not_a_sensor(kwargs, words):
    """ErrorParams(scale=(1, 1)) and a NaN angle were accepted (and simulated)."""
    from magbench.simulate.sensor import ErrorParams

    with pytest.raises(InputError) as err:
        ErrorParams(**kwargs)
    assert words in str(err.value)
    ErrorParams(alpha_rad=0.01, scale=(0.9, 1.0, 1.1), offset_nT=(5, -5, 0))  # the control


def test_library_controls_pass():
    """The negative controls of the refusals above."""
    assert len(simulate("sphere9", None)) == 300 and len(simulate("sphere9", np.int64(3))) == 300
    assert make("nlopt", seed=2**64 - 1, budget=50).fit(DATA).n_evaluations <= 50  # the largest seed NLopt takes
    assert _diagnose(folds=5.0, seed=np.int64(2), gravity=np.tile([0.0, 0.0, 9.8], (300, 1)))["verdict"]

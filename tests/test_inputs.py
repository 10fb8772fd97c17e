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

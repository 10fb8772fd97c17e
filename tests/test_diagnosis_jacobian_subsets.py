"""The diagnosis's fits form only the Jacobian columns of their free parameters (``ExtendedModel.residual_jacobian``
with ``free``) and keep a fit's rows in one column-major copy: the residuals, the columns and the normal equations
must be, to the bit, those formed from the whole Jacobian (its rows kept, then its free columns), as before.  The
layout matters: J^T J and J^T r of the same numbers in another memory order take another BLAS path and differ in the
last bits, which moved floors and z-values of the diagnosis in the 12th digit.  Records of the first independent
generator (tests/independent_forward.py): one with spikes, so that the fits keep a subset of the rows."""
import sys
from pathlib import Path

import numpy as np
import pytest

from magbench.benchmarks.diagnosis import diagnose
from magbench.benchmarks.diagnosis.model import ExtendedModel
from magbench.simulate.dataset import Dataset

sys.path.insert(0, str(Path(__file__).resolve().parent))
from independent_forward import make_case  # noqa: E402


@pytest.mark.parametrize("index", [2, 6])  # single outliers (spikes): the robust fits keep the other rows
def test_subset_jacobians_and_normal_equations_are_the_whole_jacobians_to_the_bit(index, monkeypatch):
    whole = ExtendedModel.residual_jacobian
    normal = ExtendedModel._normal_equations
    seen = {"subset": 0, "kept": 0}

    def residual_jacobian(self, x, sl, cols=None, free=None):
        r, jac = whole(self, x, sl, cols, free)
        if free is not None:
            r0, j0 = whole(self, x, sl, cols)
            assert np.array_equal(r, r0) and np.array_equal(jac, j0[:, free])
            seen["subset"] += 1
        return r, jac

    def normal_equations(self, x, free, keep, blocks):
        sse, a, b = normal(self, x, free, keep, blocks)
        a0, b0, sse0 = np.zeros((len(free), len(free))), np.zeros(len(free)), 0.0
        for sl, cols in blocks:  # the former formation: the whole Jacobian, its rows kept, then its free columns
            r, jac = whole(self, x, sl, cols)
            if keep is not None:
                r, jac = r[keep[sl]], jac[keep[sl]]
                seen["kept"] += 1
            jf = jac[:, free]
            a0 += jf.T @ jf
            b0 += jf.T @ r
            sse0 += float(r @ r)
        if self.prior_w.any():
            g = self.prior_gram(x)
            a0 += g[np.ix_(free, free)]
            b0 += g[free, self.p]
            sse0 += float(g[self.p, self.p])
        assert sse == sse0 and np.array_equal(a, a0) and np.array_equal(b, b0)
        return sse, a, b

    monkeypatch.setattr(ExtendedModel, "residual_jacobian", residual_jacobian)
    monkeypatch.setattr(ExtendedModel, "_normal_equations", normal_equations)
    case = make_case(index, 2026)
    assert "outliers" in case.present
    diagnose(Dataset(case.raw_nT, f_ref_nT=case.f_ref_nT, t_s=case.t_s, temp_C=case.temp_C), gravity=case.gravity)
    assert seen["subset"] > 0 and seen["kept"] > 0  # both paths were taken

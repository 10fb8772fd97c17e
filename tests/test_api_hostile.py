"""Hostile calls of the Python API that had answered wrongly or crashed (a probe of 1,510 calls, 2026-11-28), each
beside a control that must keep working.  The library's promise (docs/CONTRACT.md): bad input is an ``InputError``
with one clear line, never another exception from deep inside; a number it cannot stand behind is a rejection."""
import numpy as np
import pytest

import magbench
from magbench.errors import InputError
from magbench.simulate.dataset import Dataset


@pytest.fixture(scope="module")
def sphere():
    return magbench.simulate("sphere9", seed=1)


def _truth_z(result, data) -> float:
    names = ["alpha_rad", "beta_rad", "gamma_rad", "kx", "ky", "kz", "ox_nT", "oy_nT", "oz_nT"]
    truth = np.asarray(data.truth.params.to_vector("nine"))
    return max(abs(result.x[i] - truth[i]) / result.uncertainty[k] for i, k in enumerate(names))


def test_ten_readings_for_nine_parameters_are_refused_nineteen_taken(sphere):
    """10 readings for 9 parameters were accepted with deviations 70 times too small (the residual of 0.026 nT on a
    2 nT sensor was taken for the noise).  Now a fit needs 10 readings beyond its parameters; at 19 the stated
    deviations cover the truth (40 records, the worst parameter within 5.6 deviations)."""
    with pytest.raises(InputError, match=r"10 points are too few for lsq with the nine model \(it needs at least 19"):
        magbench.calibrate(sphere.raw_nT[:10], f_ref_nT=50000.0)
    worst = []
    for seed in range(1, 21):
        d = magbench.simulate("sphere9", seed=seed)
        res = magbench.calibrate(Dataset(d.raw_nT[:19], f_ref_nT=d.f_ref_nT[:19], truth=d.truth))
        assert res.accepted
        worst.append(_truth_z(res, d))
    assert max(worst) < 6.0


@pytest.mark.parametrize("method, settings", [("nlopt", {"algorithm": "GN_ORIG_DIRECT", "max_evaluations": 3000}),
                                              ("cmaes", {"budget": 800, "seed": 1})])
def test_a_search_cut_short_is_rejected_though_within_twice_the_optimum(sphere, method, settings):
    """3.44 nT against an optimum of 2.02 passed the ratio test (at most 2 times), with a scale 15 deviations off.
    The sum of squares above the optimum, in noise variances, is now held to the chi-square quantile of the
    parameters at 1e-6.  Control: every method run to its end on the same record is accepted."""
    res = magbench.calibrate(sphere, method=method, **settings)
    assert res.rms_after_nT < 2 * 2.02
    assert not res.accepted
    assert any("noise variances, more than the 44.8 that 9 parameters" in r for r in res.rejections)
    for control in ("lsq", "ga", "nlopt", "cmaes", "ellipsoid"):
        assert magbench.calibrate(sphere, method=control).accepted, control


@pytest.mark.parametrize("value", [1e12, 1e200, 1e300, 6e7])
def test_a_corrupt_row_far_beyond_any_sensor_s_range_is_refused_by_name(sphere, value):
    """A row of 1e12 nT left the diagnosis a noise floor of 0.002 nT and the verdict ``none``; 1e200 raised a
    LinAlgError in calibrate and diagnose.  More than 1000 times the median row is refused, the row named.
    Control: a spike 100 times the field (a MEMS part's range) is still a spike (a rejection, not a refusal)."""
    raw = sphere.raw_nT.copy()
    raw[3] = value
    for call in (lambda: magbench.calibrate(raw, f_ref_nT=5e4),
                 lambda: magbench.diagnose(Dataset(raw, f_ref_nT=sphere.f_ref_nT, t_s=sphere.t_s))):
        with pytest.raises(InputError, match=r"1 row\(s\) \(row 3\) have a magnitude more than 1000 times"):
            call()
    spike = sphere.raw_nT.copy()
    spike[3] = 2.9e6
    res = magbench.calibrate(spike, f_ref_nT=5e4)
    assert not res.accepted and "outliers" in res.rejections[0]
    assert magbench.diagnose(Dataset(spike, f_ref_nT=sphere.f_ref_nT, t_s=sphere.t_s))["verdict"] != "none"

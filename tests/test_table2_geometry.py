"""Table 2's geometry fit (``fit_geometry``, seed 000's turntable): the analytic Jacobian of the two series against
central differences at random geometries, the mountings' harmonics in one pass against ``harmonics`` mounting by
mounting, and the fit on the paper's Table 2 reaching the optimum that the numerical Jacobian's fit reached (its cost
within 1e-6 of it, or lower)."""
from importlib import resources

import numpy as np
import pytest

from magbench.benchmarks.diagnosis import scalar as S
from magbench.benchmarks.diagnosis.localize import harmonics
from magbench.simulate.dataset import read_csv

H = np.radians(np.arange(0.0, 360.0, 10.0))
F = 51978.74
P_AFTER = S.paper_matrix(*S._paper_angles())
NOMINAL = np.array([*S._paper_angles(), 1, 1, 1, 0, 0, 0, 0, 0, np.radians(55.0), 0, 0, 0, 0])
SPREAD = np.array([0.01] * 6 + [300.0] * 3 + [0.05, 0.05, 0.3, 2.0, 0.02, 0.002, 0.002])


@pytest.mark.parametrize("seed", range(6))
def test_the_jacobian_is_the_series_derivative(seed):
    theta = NOMINAL + np.random.default_rng(seed).normal(0.0, 1.0, 16) * SPREAD
    raw, _ = S._raw_jacobian(theta, H, F)
    assert np.allclose(raw, S._raw(theta, H, F), rtol=1e-13, atol=1e-9)
    jac = S._series_jacobian(theta, H, F, P_AFTER)
    for i in range(16):
        step = 1e-6 * max(1.0, abs(theta[i]))
        e = np.zeros(16)
        e[i] = step
        numeric = (np.concatenate(S._series(theta + e, H, F, P_AFTER))
                   - np.concatenate(S._series(theta - e, H, F, P_AFTER))) / (2 * step)
        assert np.allclose(jac[:, i], numeric, rtol=1e-5, atol=1e-6 * np.abs(numeric).max() + 1e-9), S.GEOMETRY_NAMES[i]


def test_the_mountings_in_one_pass_are_harmonics_mounting_by_mounting():
    rng = np.random.default_rng(1)
    thetas = np.tile(NOMINAL, (100, 1))
    thetas[:, 9:11] = rng.normal(0.0, 0.05, (100, 2))
    thetas[:, 11] = rng.uniform(0.3, 1.2, 100)
    thetas[:, 12] = rng.uniform(0.0, 2 * np.pi, 100)
    got = S._mounting_harmonics(thetas, H, F, P_AFTER)
    for theta, row in zip(thetas, got):
        b, a = S._series(theta, H, F, P_AFTER)
        amps = harmonics(np.degrees(H), b - a)
        assert np.allclose(row, [amps["1_per_rev_nT"], amps["2_per_rev_nT"]], rtol=1e-10, atol=1e-9)


NUMERICAL_JACOBIAN_COST = 19375.376873787307
"""Half the sum of squares (both series and the priors) at the numerical Jacobian's fit of Table 2 (before 2026-11-29)."""


def test_table2_reaches_the_optimum():
    series = read_csv(resources.files("magbench.simulate").joinpath("data/lu2014_table2.csv"), require_vector=False)
    g = S.fit_geometry(series)
    theta = np.array([g["fitted"][k] for k in S.GEOMETRY_NAMES])
    fb, fa = S._series(theta, np.radians(series.heading_deg), float(np.median(series.f_ref_nT)), P_AFTER)
    prior = S.GEOMETRY_PRIOR
    sd = np.array([prior["angle_rad"]] * 3 + [prior["scale"]] * 3 + [prior["offset_nT"]] * 3 + [prior["tilt_rad"]] * 2
                  + [np.inf, np.inf, prior["scale"]] + [prior["cubic"]] * 2)
    pulls = np.where(np.isfinite(sd), (theta - NOMINAL) / np.where(np.isfinite(sd), sd, 1.0), 0.0)
    cost = 0.5 * (np.sum((fb - series.extra["f_meas_before"]) ** 2) + np.sum((fa - series.extra["f_meas_after"]) ** 2)
                  + np.sum(pulls ** 2))
    assert cost <= NUMERICAL_JACOBIAN_COST * (1 + 1e-6)
    assert g["identifiable_combinations"] == 10

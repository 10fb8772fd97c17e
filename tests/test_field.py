import numpy as np
import pytest

from magbench.simulate.field import ConstantField, VaryingField, igrf_field


def test_igrf_against_published_test_value():
    """IGRF-14 test value computed with IAGA's Fortran igrf14syn (geodetic), as published in
    JuliaSpace/SatelliteToolboxGeomagneticField.jl test/IGRF14_test_geodetic.txt:
    2022.1, h 829.103 km, colatitude 46.47, longitude 114.85 -> X 17590.40262, Y -1731.07191,
    Z 33147.28408 nT.  (IGRF-13 would differ by about 22 nT.)"""
    f = igrf_field(90.0 - 46.47, 114.85, 829.103, "2022-02-06T12:00:00")
    np.testing.assert_allclose(f.vector_nT, [17590.40262, -1731.07191, 33147.28408], atol=0.5)


def test_constant_field_angles_round_trip():
    f = ConstantField.from_angles(51978.74, 52.46, -2.4)
    assert f.total_nT == pytest.approx(51978.74)
    assert f.inclination_deg == pytest.approx(52.46)
    assert f.declination_deg == pytest.approx(-2.4)


def test_varying_field_peak_and_seed():
    base = ConstantField.from_angles(50000.0, 60.0)
    t = np.linspace(0, 600, 601)
    a = VaryingField(base, amplitude_nT=200.0).at(t, np.random.default_rng(1))
    b = VaryingField(base, amplitude_nT=200.0).at(t, np.random.default_rng(1))
    np.testing.assert_array_equal(a, b)
    dev = np.linalg.norm(a - np.asarray(base.vector_nT), axis=1)
    assert dev.max() == pytest.approx(200.0)
    assert np.std(np.diff(dev)) < 20.0  # smooth, not white

"""The drifts' own signatures (``naming.scalar_series_signature``).  The second look at a field drift
(``Diagnosis._second_look``): a drift that fails the blocked folds only because its free Legendre terms run anywhere in
a left-out stretch is fitted again with a slope penalty, and is then named only on its own signature, one scalar
series common to every attitude at the same time.  An offset drift must be body-fixed (``Diagnosis._body_or_scalar``):
where one scalar series does as well, it is said ``offset_drift|field_drift``.  The signature is tested on synthetic
residuals, the rules on records of the third independent forward model (tests/independent_forward3.py, development
cases 0-479), which shares no code with the diagnosis."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from independent_cases import evidence_row, names, run_case  # noqa: E402

from magbench.benchmarks.diagnosis.model import slope_penalty  # noqa: E402
from magbench.benchmarks.diagnosis.naming import SIGNATURE_Z, scalar_series_signature  # noqa: E402


def test_the_slope_penalty_is_the_integral_of_the_squared_derivative():
    p = slope_penalty(5)
    tau = np.linspace(-1, 1, 200001)
    from numpy.polynomial import legendre
    for i, j in ((0, 0), (1, 3), (4, 4), (0, 2)):
        di = legendre.legval(tau, legendre.legder(np.eye(6)[i + 1]))
        dj = legendre.legval(tau, legendre.legder(np.eye(6)[j + 1]))
        assert p[i, j] == pytest.approx(np.trapezoid(di * dj, tau), rel=1e-6, abs=1e-6)
    assert p[0, 0] == pytest.approx(2.0) and p[4, 4] == pytest.approx(5 * 6)  # integral of (P_n')^2 is n (n + 1)


def _rotating(n=1500, seed=0):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 600.0, n)
    u = rng.normal(size=(n, 3))
    return rng, t, u / np.linalg.norm(u, axis=1)[:, None]


def test_a_scalar_series_is_told_from_a_body_fixed_drift_and_back():
    rng, t, u = _rotating()
    drift = 5.0 * np.sin(2 * np.pi * t / 400.0)
    scalar = scalar_series_signature(drift + rng.normal(0, 0.5, len(t)), u, t, 5, 0, 12)
    assert scalar["z_scalar_beyond_body"] > SIGNATURE_Z >= scalar["z_body_beyond_scalar"], scalar
    body = u @ np.array([1.0, -0.5, 0.3]) * drift[:, None].ravel()  # a body-fixed vector growing and shrinking
    fixed = scalar_series_signature(body + rng.normal(0, 0.5, len(t)), u, t, 5, 0, 12)
    assert fixed["z_body_beyond_scalar"] > SIGNATURE_Z >= fixed["z_scalar_beyond_body"], fixed


def test_too_few_samples_are_not_tested():
    _, t, u = _rotating(n=100)
    assert scalar_series_signature(np.zeros(100), u, t, 5, 0, 12)["tested"] is False


@pytest.mark.parametrize("index", [127, 355])  # a field drift on a moored buoy and in a hand-rotated dance
def test_a_field_drift_the_blocked_folds_fail_is_named_on_the_second_look(index):
    result, case = run_case(index, generator=3)
    assert case.present == ("field_drift",) and result["verdict"] == "field_drift", result["verdict"]
    row = evidence_row(result, "field_drift")
    assert row["named"] and row["failed_families"] and row["second_look"]["passed_blocked"]
    assert row["second_look"]["signature"]["z_scalar_beyond_body"] > SIGNATURE_Z


@pytest.mark.parametrize("index", [110, 446])  # a relay load on a car and on a hovering quadcopter (outside)
def test_negative_control_a_switched_load_passes_the_second_look_but_not_the_signature(index):
    result, case = run_case(index, generator=3)
    assert case.present == () and case.outside == ("relay_load",)
    assert "field_drift" not in names(result["verdict"]), result["verdict"]
    row = evidence_row(result, "field_drift")
    assert not row["named"] and row["second_look"]["passed_blocked"] and "signature" in row["why"]


def test_a_drift_on_a_hovering_quadcopter_cannot_be_told_body_fixed_or_scalar():
    """Level flight turning about the vertical only: a drift of the vertical offset and a change of the field's
    magnitude move the readings' magnitude alike; the third generator's field drift there is said as the pair."""
    result, case = run_case(109, generator=3)
    assert case.present == ("field_drift",) and case.schedule == "quad_hover"
    assert result["verdict"] == "offset_drift|field_drift", result["verdict"]
    pair = next(c for c in result["confounded"] if c["alternatives"] == ["offset_drift", "field_drift"])
    assert pair["evidence"]["z_body_beyond_scalar"] <= SIGNATURE_Z and "turn the sensor" in pair["separate_by"]


def test_negative_control_an_offset_drift_on_a_moored_buoy_is_body_fixed():
    result, case = run_case(28, generator=3)
    assert case.present == ("offset_drift",) and result["verdict"] == "offset_drift", result["verdict"]
    assert not any(c["alternatives"] == ["offset_drift", "field_drift"] for c in result["confounded"])

"""Calibrations accepted when they are wrong, counted on forward models written apart from magbench.

The records come from tests/independent_forward2.py and independent_forward3.py (no magbench code; their own
sensor, attitude, field and effect physics), on a root seed other than the one the acceptance limits were
studied on (2026).  Each record carries its true calibration ``B = C (raw - o)``.  Its truth in magbench's
nine parameters is the nine-parameter fit of the same record made noise- and effect-free: the true field along
the directions the record visits (``F u``, ``u`` from the true calibration) passed back through ``C`` and ``o``
(the scalar calibration determines ``C^T C`` and ``o`` only; any ellipsoid is a nine-parameter one).

An accepted calibration is *wrong* when one of its nine parameters is more than ``WRONG_Z`` of its stated
standard deviations (Cramér-Rao at the estimated noise) from that truth: the number beside it could not be stood
behind.  The headline is that count; beside it, the clean records accepted (the negative control of a judge that
rejects everything).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import independent_forward2  # noqa: E402
import independent_forward3  # noqa: E402

from magbench.calibrators import acceptance, make  # noqa: E402
from magbench.errors import InputError  # noqa: E402
from magbench.simulate.dataset import Dataset  # noqa: E402

ROOT = 7
WRONG_Z = 5.0
NAMES = ("alpha_rad", "beta_rad", "gamma_rad", "kx", "ky", "kz", "ox_nT", "oy_nT", "oz_nT")
BLOCKS = {"generator2": (independent_forward2, range(0, 144)), "generator3": (independent_forward3, range(0, 72))}


def _clean_readings(case) -> np.ndarray:
    """The true field along the directions the record visits (``F u``, ``u`` from the true calibration) passed
    back through the true ``C`` and ``o``: the record without noise or effects."""
    notes = case.notes
    c = np.asarray(notes["correction"] if "correction" in notes else notes["true_C"], dtype=float)
    o = np.asarray(notes["offset"] if "offset" in notes else notes["true_offset_nT"], dtype=float)
    b = (case.raw_nT - o) @ c.T
    u = b / np.linalg.norm(b, axis=1, keepdims=True)
    return (np.asarray(case.f_ref_nT, dtype=float)[:, None] * u) @ np.linalg.inv(c).T + o


def _truth(case) -> np.ndarray | None:
    f = np.asarray(case.f_ref_nT, dtype=float)
    clean = _clean_readings(case)
    try:
        fit = make("lsq").fit(Dataset(clean, f_ref_nT=f))
    except InputError:  # attitudes that determine no nine-parameter truth: no calibration is owed
        return None
    return np.asarray(fit.x, dtype=float) if fit.rms_after_nT < 1e-6 * float(np.median(f)) else None


def tally(generator, indices) -> dict:
    """Counts over the records (the fixed and too-short ones left out: no calibration is asked of them)."""
    out = {"records": 0, "accepted": 0, "wrong": 0, "clean": 0, "clean_accepted": 0, "wrong_cases": []}
    for i in indices:
        case = generator.make_case(i, ROOT)
        if case.category in ("fixed", "too_short"):
            continue
        truth = _truth(case)
        if truth is None:
            continue
        out["records"] += 1
        clean = case.category == "clean"
        out["clean"] += clean
        try:
            fit = make("lsq").fit(Dataset(case.raw_nT, f_ref_nT=case.f_ref_nT, t_s=case.t_s, temp_C=case.temp_C))
        except InputError:
            continue
        if not fit.accepted:
            continue
        out["accepted"] += 1
        out["clean_accepted"] += clean
        std = np.array([fit.uncertainty[name] for name in NAMES])
        z = np.abs(np.asarray(fit.x, dtype=float) - truth) / std
        if float(np.max(z)) > WRONG_Z:
            out["wrong"] += 1
            out["wrong_cases"].append((i, case.category, case.present + case.outside, float(np.max(z))))
    return out


@pytest.fixture(scope="module", params=list(BLOCKS), ids=list(BLOCKS))
def block(request):
    generator, indices = BLOCKS[request.param]
    return request.param, generator, indices


# what the block gives (3 and 0 when STRUCTURE_RATIO 3 was set, 2 with the quadratic response's test, 0 with the
# cubic's): a change that accepts more wrong answers fails
MOST_WRONG = {"generator2": 0, "generator3": 0}


def test_few_accepted_calibrations_are_wrong_and_clean_records_are_accepted(block):
    name, generator, indices = block
    t = tally(generator, indices)
    assert t["wrong"] <= MOST_WRONG[name], t["wrong_cases"]
    assert t["clean_accepted"] >= t["clean"] - 1, t


def test_negative_control_the_former_limit_accepts_wrong_answers(monkeypatch):
    """With the former limit (a residual up to 10 times the independent noise accepted), the same judge accepts
    calibrations whose parameters are tens of stated deviations off: the count above can fail.  (The polynomial
    response's test, added later, widens some of those answers' deviations as well: it is left out here, as then.)"""
    monkeypatch.setattr(acceptance, "STRUCTURE_RATIO", 10.0)
    monkeypatch.setattr(acceptance, "nonlinearity_shift", lambda *args, **kwargs: (None, None))
    generator, indices = BLOCKS["generator2"]
    assert tally(generator, indices)["wrong"] > MOST_WRONG["generator2"] + 3  # 5 (the limit: 3 when it was set)


def test_the_stated_deviation_covers_the_truth_on_a_near_planar_clean_record(monkeypatch):
    """A car on a circuit (2 degrees of tilt, 19,141 readings, clean): the scale and offset along the vertical
    are determined weakly.  The Cramér-Rao deviations are taken on the information scaled to unit diagonal; the
    raw information's condition number (4e15) let the pseudo-inverse drop that direction, which stated oz
    +-0.008 nT where the truth is 5 nT away (628 deviations; +-4.6 nT, 1.1 deviations, is the bound)."""
    from magbench.calibrators import fisher

    case = independent_forward3.make_case(0, ROOT)
    assert case.category == "clean"
    truth = _truth(case)
    data = Dataset(case.raw_nT, f_ref_nT=case.f_ref_nT, t_s=case.t_s)

    def worst_z() -> float:
        fit = make("lsq").fit(data)
        assert fit.accepted
        std = np.array([fit.uncertainty[name] for name in NAMES])
        return float(np.max(np.abs(np.asarray(fit.x, dtype=float) - truth) / std))

    assert worst_z() < 3.0
    monkeypatch.setattr(fisher, "unit_scale", lambda a: (a, np.ones(len(a))))  # the unscaled cut: the control
    assert worst_z() > 100.0


def _clean_twin(case, seed: int) -> Dataset:
    """The record's own attitudes, times and reference through its true calibration, with white noise at the
    generator's level and no effect: what the record would be without the effect."""
    clean = _clean_readings(case)
    noise = np.random.default_rng(seed).normal(0.0, float(case.notes["noise_nT"]), clean.shape)
    return Dataset(clean + noise, f_ref_nT=case.f_ref_nT, t_s=case.t_s)


@pytest.mark.parametrize("index", [37, 427])
def test_a_nonlinearity_that_changes_fast_along_a_smooth_path_is_rejected_against_revisited_attitudes(index):
    """Generator 3 (root 2026) cases 37 and 427: a tumble and a moored buoy, a nonlinearity of 10-13 times the noise.
    The path is smooth (the time neighbours are its neighbours in attitude) but brisk, so the misfit changes between
    samples and lifts the time neighbours' differences to its own size: the residual passed against them (0.75 and
    2.6 times) with kx 73 and ky 35 stated deviations from the truth.  About the attitudes the sensor came back to
    at other times the misfit cancels, and the residual is 6.3 and 4.9 times that scatter: rejected.  Control: the
    same attitudes, times and noise without the nonlinearity are accepted, with that ratio near 1."""
    case = independent_forward3.make_case(index, 2026)
    assert case.present == ("nonlinearity",) and case.schedule in ("tumble", "buoy")
    fit = make("lsq").fit(Dataset(case.raw_nT, f_ref_nT=case.f_ref_nT, t_s=case.t_s, temp_C=case.temp_C))
    assert not fit.accepted
    assert "attitudes the sensor came back to at other times" in fit.rejections[0]
    twin = _clean_twin(case, index)
    control = make("lsq").fit(twin)
    assert control.accepted
    objective = acceptance.ScalarObjective(twin.raw_nT, twin.f_ref_nT, "nine")
    r = objective.residuals(control.x)
    rms = float(np.sqrt(np.mean(r ** 2)))
    info: dict = {}
    assert acceptance.structure_check(objective, control.x, rms, float(np.median(twin.f_ref_nT)),
                                      np.arange(len(r)), twin.t_s, info)[0] == []
    assert 0.8 < rms / info["noise_revisits_nT"] < 1.25

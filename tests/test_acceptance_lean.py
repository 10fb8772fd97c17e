"""The lean acceptance checks decide as the full ones do: the profile test's quadratic shortcut,
the profile and coverage checks on a systematic sample of a long record, and the step search by the
Frisch-Waugh-Lovell form."""
from __future__ import annotations

import numpy as np
import pytest

from magbench.calibrators import acceptance, fisher, make
from magbench.calibrators.core.objective import ScalarObjective
from magbench.calibrators.core.problem import PHYSICAL_BOX, search_bounds
from magbench.simulate.dataset import Dataset
from magbench.simulate.scenarios import get_scenario, scenario_names


def _judged(d, model="nine"):
    obj = ScalarObjective(d.raw_nT, d.f_ref_nT, model)
    x0 = make("lsq", model=model).fit(d).x
    lo, hi = search_bounds(model, d.f_ref_nT, **PHYSICAL_BOX)
    x_ref, rms = acceptance.reference_fit(obj, x0, (lo, hi))
    n, p = len(d), len(x_ref)
    return obj, x_ref, rms * np.sqrt(n / (n - p)), float(np.median(d.f_ref_nT))


NINE = [s for s in scenario_names() if get_scenario(s).model == "nine"]


@pytest.mark.parametrize("scenario", NINE)
def test_the_profile_shortcut_gives_the_refits_verdict(scenario, monkeypatch):
    d = get_scenario(scenario).build(1)
    obj, x, noise, field = _judged(d)
    lean = acceptance.profile_offset(obj, x, noise, field)
    monkeypatch.setattr(acceptance, "PROFILE_LINEAR_MARGIN", np.inf)  # always refit
    full = acceptance.profile_offset(obj, x, noise, field)
    assert bool(lean) == bool(full)


def test_the_shortcut_is_taken_on_a_sphere_and_not_near_a_plane(monkeypatch):
    calls = []
    real = acceptance.lm_normal
    monkeypatch.setattr(acceptance, "lm_normal", lambda *a, **k: calls.append(1) or real(*a, **k))
    for scenario, refits in (("sphere9", False), ("vehicle9", True)):
        obj, x, noise, field = _judged(get_scenario(scenario).build(0))
        calls.clear()
        acceptance.profile_offset(obj, x, noise, field)
        assert bool(calls) == refits, scenario


def _long(scenario: str, copies: int, seed: int = 0) -> Dataset:
    """A long record: a scenario's attitudes repeated with fresh noise (2 nT per axis)."""
    d = get_scenario(scenario).build(seed)
    rng = np.random.default_rng(seed)
    raw = np.tile(d.raw_nT, (copies, 1)) + rng.normal(0.0, 2.0, (copies * len(d), 3))
    return Dataset(raw, f_ref_nT=np.tile(d.f_ref_nT, copies))


def _increase(messages: list[str]) -> float:
    text = messages[0]
    return float(text.split("raises the squared error by only ")[1].split(" noise variances")[0])


def test_a_sampled_profile_refit_decides_as_all_rows(monkeypatch):
    """Near a plane (the far-centre family: the increase is a fraction of one noise variance) the sample's
    likelihood ratio rejects as all rows' does, its increase within one noise variance."""
    d = _long("vehicle9", 150)
    assert len(d) > 2 * acceptance.PROFILE_ROWS
    obj, x, noise, field = _judged(d)
    sampled = acceptance.profile_offset(obj, x, noise, field)
    monkeypatch.setattr(acceptance, "PROFILE_ROWS", 10**9)
    every = acceptance.profile_offset(obj, x, noise, field)
    assert sampled and every
    assert abs(_increase(sampled) - _increase(every)) <= 1.0


def test_a_sampled_profile_refit_scales_a_large_increase(monkeypatch):
    """Far from a plane, refitted (the shortcut disabled): the sample's increase scaled to all rows is all
    rows' increase to a few per cent."""
    monkeypatch.setattr(acceptance, "PROFILE_LINEAR_MARGIN", np.inf)
    d = _long("cap9", 100)
    obj, x, noise, field = _judged(d)
    limits = acceptance.AcceptanceLimits(profile_chi2=1e12)  # reject, so that the message says the increase
    sampled = _increase(acceptance.profile_offset(obj, x, noise, field, limits))
    monkeypatch.setattr(acceptance, "PROFILE_ROWS", 10**9)
    every = _increase(acceptance.profile_offset(obj, x, noise, field, limits))
    assert sampled == pytest.approx(every, rel=0.05)


def test_a_sampled_coverage_check_reads_the_geometry_of_all_rows(monkeypatch):
    d = _long("cap9", 80)
    obj = ScalarObjective(d.raw_nT, d.f_ref_nT, "nine")
    x = np.array([0, 0, 0, 1, 1, 1, 0, 0, 0], dtype=float)
    sampled = fisher.coverage(obj, x)
    monkeypatch.setattr(fisher, "COVERAGE_ROWS", 10**9)
    every = fisher.coverage(obj, x)
    assert sampled["condition_number"] == pytest.approx(every["condition_number"], rel=0.02)
    for name, s in every["sigma_per_nT"].items():  # per point: the sample's sigma x sqrt(rows) is all rows'
        n_s = len(d.raw_nT[acceptance.systematic_rows(len(d), fisher.COVERAGE_ROWS)])
        assert sampled["sigma_per_nT"][name] * np.sqrt(n_s) == pytest.approx(s * np.sqrt(len(d)), rel=0.02)


def test_the_step_search_equals_the_joint_regression():
    """The Frisch-Waugh-Lovell gain at the best split equals the joint least-squares fit of the record's
    directions and the step columns at that split (negative control: a step at another row gains less)."""
    d = get_scenario("tumble9").build(0)
    raw = d.raw_nT.copy()
    raw[len(raw) // 3:] += np.array([300.0, -200.0, 100.0])
    obj = ScalarObjective(raw, d.f_ref_nT, "nine")
    x = make("lsq").fit(Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s)).x
    r = obj.residuals(x)
    order = np.argsort(d.t_s, kind="stable")
    step = acceptance.best_step(obj, x, r, order)
    assert step is not None and abs(step.index - len(raw) // 3) <= len(raw) // 50

    def joint_gain(k):
        j = obj.jacobian(x)[order]
        t = np.zeros((len(r), 3))
        t[k:] = -j[k:, 6:9]
        full = np.column_stack([j, t])
        coef = np.linalg.lstsq(full, r[order], rcond=None)[0]
        base = np.linalg.lstsq(j, r[order], rcond=None)[0]
        return float(r[order] @ (full @ coef)) - float(r[order] @ (j @ base))

    assert step.gain == pytest.approx(joint_gain(step.index), rel=1e-6)
    assert joint_gain(len(raw) // 10) < 0.5 * step.gain


def test_a_sampled_step_search_finds_the_step_of_all_rows(monkeypatch):
    d = get_scenario("tumble9").build(0)
    copies = 2 * acceptance.STEP_ROWS // len(d) + 7  # more than twice the rows the search reads
    rng = np.random.default_rng(3)
    raw = np.tile(d.raw_nT, (copies, 1)) + rng.normal(0.0, 2.0, (copies * len(d), 3))
    at = int(0.6 * len(raw))
    raw[at:] += np.array([0.0, 250.0, -150.0])
    f_ref = np.tile(d.f_ref_nT, copies)
    obj = ScalarObjective(raw, f_ref, "nine")
    x = make("lsq").fit(Dataset(raw, f_ref_nT=f_ref)).x
    r = obj.residuals(x)
    order = np.arange(len(raw))
    sampled = acceptance.best_step(obj, x, r, order)
    monkeypatch.setattr(acceptance, "STEP_ROWS", 10**9)
    every = acceptance.best_step(obj, x, r, order)
    k = -(-len(raw) // 200_000)
    assert sampled is not None and every is not None
    assert abs(sampled.index - every.index) <= 2 * k and abs(every.index - at) <= len(raw) // 50
    assert sampled.gain == pytest.approx(every.gain, rel=0.05)
    assert acceptance.step_dominates(sampled) == acceptance.step_dominates(every)

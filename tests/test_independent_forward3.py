"""Generator-only tests of tests/independent_forward3.py, the third, held-out blind generator: its records are
well formed, deterministic, have the stated mix, and their truth is honest (a clean record is noise after the
true calibration, every present effect is above its visibility floor).  No diagnosis is run here: the
generator's cases are kept blind until the engineer's one final run."""
from __future__ import annotations

from collections import Counter
from functools import cache

import independent_forward3 as g3
import numpy as np
import pytest
from independent_forward import Case

FIRST = 48
SAMPLE = [i for i in range(FIRST) if i != 13]  # case 13 (a long filtered record) alone takes seconds


@cache
def case(i: int) -> Case:
    return g3.make_case(i)


def true_residual(c: Case) -> np.ndarray:
    cmat, off = np.array(c.notes["true_C"]), np.array(c.notes["true_offset_nT"])
    return np.linalg.norm((c.raw_nT - off) @ cmat.T, axis=1) - c.f_ref_nT


def ellipsoid_residual(c: Case) -> np.ndarray:
    """A perfect-calibration fit: B = L (raw - o) with L upper triangular (the nine parameters a scalar reference
    can see), the least-squares optimum of |L (raw - o)| - F found by Gauss-Newton from the true calibration."""
    x, f = c.raw_nT, c.f_ref_nT
    cm = np.array(c.notes["true_C"])
    upper = np.linalg.cholesky(cm.T @ cm).T
    o = np.array(c.notes["true_offset_nT"])
    iu = np.triu_indices(3)
    p = np.concatenate([upper[iu], o])
    for _ in range(8):
        lm = np.zeros((3, 3))
        lm[iu] = p[:6]
        d = x - p[6:]
        b = d @ lm.T
        norm = np.linalg.norm(b, axis=1)
        r = norm - f
        u = b / norm[:, None]
        jac = np.column_stack([u[:, i] * d[:, j] for i, j in zip(*iu)] + [-(u @ lm)[:, j] for j in range(3)])
        p = p - np.linalg.lstsq(jac, r, rcond=1e-12)[0]
    lm = np.zeros((3, 3))
    lm[iu] = p[:6]
    return np.linalg.norm((x - p[6:]) @ lm.T, axis=1) - f


def test_deterministic_per_index_and_root():
    a, b, other = g3.make_case(3), g3.make_case(3), g3.make_case(3, root=7)
    for name in ("raw_nT", "f_ref_nT", "t_s"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert (a.category, a.present, a.outside, a.schedule) == (b.category, b.present, b.outside, b.schedule)
    assert not np.array_equal(a.t_s, other.t_s)


def test_mix_of_every_block_of_24():
    assert Counter(g3.PATTERN) == {"clean": 2, "single": 6, "pair": 2, "triple": 2, "outside": 6, "outside_plus": 2,
                                   "too_short": 2, "fixed": 2}
    rng = np.random.default_rng(0)
    for block in range(3):
        chosen = [g3._choose(24 * block + k, rng) for k in range(24)]
        assert [c[0] for c in chosen] == list(g3.PATTERN)
        assert sorted(c[1][0] for c in chosen if c[0] == "single") == sorted(g3.LIBRARY)
    first = [g3._choose(i, rng) for i in range(FIRST)]
    assert {o for c in first if c[0] == "outside" for o in c[2]} == set(g3.OUTSIDE)
    assert {c[1][0] for c in first if c[0] == "fixed"} == set(g3.FIXED_EFFECTS)
    assert len(g3.OUTSIDE) >= 10 and set(g3.ACCEPTABLE_FOR) <= set(g3.OUTSIDE)


def test_every_category_schedule_and_outside_effect_is_produced():
    made = [case(i) for i in SAMPLE]
    assert {c.category for c in made} == set(g3.PATTERN)
    assert {c.schedule for c in made} == set(g3.SCHEDULES) | {"fixed"}
    assert {o for c in made for o in c.outside} == set(g3.OUTSIDE)
    assert {p for c in made for p in c.present} == set(g3.LIBRARY)


@pytest.mark.parametrize("i", SAMPLE)
def test_record_shapes_units_and_truth(i):
    c = case(i)
    n = len(c.t_s)
    assert c.raw_nT.shape == (n, 3) and c.f_ref_nT.shape == (n,)
    assert np.all(np.isfinite(c.raw_nT)) and np.all(np.isfinite(c.f_ref_nT)) and np.all(np.diff(c.t_s) > 0)
    if c.category == "too_short":
        assert 3 <= n <= 9 and not c.present and not c.outside and not c.acceptable
    else:
        assert 300 <= n <= 20000
    field = c.f_ref_nT.mean()
    assert 20000 * 0.95 < field < 65000 * 1.05 and np.ptp(c.f_ref_nT) < 0.05 * field
    assert 0.7 < np.median(np.linalg.norm(c.raw_nT, axis=1)) / field < 1.3  # nT, not uT or counts
    if c.temp_C is not None:
        assert c.temp_C.shape == (n,) and np.all(np.abs(c.temp_C) < 80)
    if c.gravity is not None:
        assert c.gravity.shape == (n, 3)
        assert np.allclose(np.linalg.norm(c.gravity, axis=1), 9.80665, atol=0.2)
    assert set(c.present) <= set(c.acceptable) <= set(g3.LIBRARY)
    assert set(c.acceptable) - set(c.present) <= {a for o in c.outside for a in g3.ACCEPTABLE_FOR.get(o, ())}
    assert c.expect_unexplained == bool(c.outside)
    assert all(set(p) <= set(g3.LIBRARY) and len(set(p)) == 2 for p in c.confoundable)
    if c.category == "fixed":
        assert c.schedule == "fixed" and len(c.present) == 1 and not c.outside
        assert c.t_s[-1] - c.t_s[0] >= 2 * 3600 and c.t_s[-1] - c.t_s[0] <= 20 * 3600
    if "temperature" in c.present or "thermal_soft_iron" in c.outside:
        assert c.temp_C is not None and np.ptp(c.temp_C) >= 2.0
    expected = {"clean": (0, 0), "single": (1, 0), "pair": (2, 0), "triple": (3, 0), "outside": (0, 1),
                "outside_plus": (1, 1), "too_short": (0, 0), "fixed": (1, 0)}[c.category]
    assert (len(c.present), len(c.outside)) == expected


@pytest.mark.parametrize("i", [i for i in SAMPLE if g3.PATTERN[i % 24] not in ("clean", "too_short")])
def test_every_effect_is_above_its_visibility_floor(i):
    c = case(i)
    vis = c.notes["visible_sigma"]
    for name in c.present + c.outside:
        assert vis[name] >= g3.VISIBLE, (name, vis[name])
    for name in c.outside:  # and something no library effect explains
        assert c.notes["beyond_library_sigma"][name] >= g3.VISIBLE


@pytest.mark.parametrize("i", [i for i in SAMPLE if g3.PATTERN[i % 24] == "clean"])
def test_clean_records_are_noise_after_the_true_calibration(i):
    c = case(i)
    noise = c.notes["noise_nT"]
    rms = float(np.sqrt(np.mean(true_residual(c) ** 2)))
    assert 0.5 * noise < rms < 1.5 * noise
    fitted = float(np.sqrt(np.mean(ellipsoid_residual(c) ** 2)))
    assert fitted < 1.5 * noise


@pytest.mark.parametrize("i", [i for i in SAMPLE if g3.PATTERN[i % 24] == "single"])
def test_a_single_effect_is_seen_by_an_independent_calibration_fit(i):
    c = case(i)
    noise = c.notes["noise_nT"]
    res = ellipsoid_residual(c)
    if c.present == ("outliers",):  # isolated spikes, each at least 10 noise in the scalar residual
        rows = c.notes.get("outlier_rows") or []
        assert c.notes["visible_sigma"]["outliers"] >= 10
        assert np.sum(np.abs(res) > 6 * noise) >= 5
        assert len(rows) >= 5 and np.all(np.diff(rows) >= 4)
    else:
        assert float(np.sqrt(np.mean(res ** 2))) > 2.0 * noise


def test_fixed_outliers_and_drifts_visible_in_the_readings():
    for i in SAMPLE:
        c = case(i)
        if c.category != "fixed":
            continue
        if c.present == ("outliers",):
            jumps = np.abs(np.diff(c.raw_nT, axis=0)).max(axis=1)
            assert np.sum(jumps > 8 * c.notes["noise_nT"]) >= 10  # into and out of each spike
        if set(c.present) & {"offset_drift", "field_drift"}:
            assert ("field_drift", "offset_drift") in c.confoundable

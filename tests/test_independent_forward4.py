"""Generator-only checks of tests/independent_forward4.py, the fourth blind generator: its records are well
formed and deterministic, have the stated mix, and their truth is honest (a clean record is noise after the
true calibration; every present effect is within its visibility bounds).  No diagnosis is run here, and neither
the generator nor these tests import magbench."""
from __future__ import annotations

import ast
import sys
from collections import Counter
from functools import cache
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import independent_forward4 as g4  # noqa: E402
from independent_forward import Case  # noqa: E402
from independent_scoring import score  # noqa: E402

SAMPLE = range(48)  # two blocks of 24


@cache
def case(i: int) -> Case:
    return g4.make_case(i)


def true_residual(c: Case) -> np.ndarray:
    cmat, off = np.array(c.notes["true_C"]), np.array(c.notes["true_offset_nT"])
    return np.linalg.norm((c.raw_nT - off) @ cmat.T, axis=1) - c.f_ref_nT


def test_the_generator_imports_nothing_from_magbench():
    source = Path(g4.__file__).read_text(encoding="utf-8")
    modules = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            modules |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            modules.add((node.module or "").split(".")[0])
    assert modules <= {"__future__", "collections", "dataclasses", "numpy", "scipy", "independent_forward"}, modules
    assert not any("magbench" in line for line in source.splitlines() if line.lstrip().startswith(("import", "from")))


def test_deterministic_per_index_and_root():
    for i in (3, 6, 7, 13):
        a, b = g4.make_case(i), g4.make_case(i)
        for name in ("raw_nT", "f_ref_nT", "t_s"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        for name in ("temp_C", "gravity"):
            x, y = getattr(a, name), getattr(b, name)
            assert (x is None) == (y is None)
            if x is not None:
                np.testing.assert_array_equal(x, y)
        assert (a.category, a.present, a.outside, a.acceptable, a.confoundable, a.schedule) == \
            (b.category, b.present, b.outside, b.acceptable, b.confoundable, b.schedule)
    assert not np.array_equal(g4.make_case(3).raw_nT[:5], g4.make_case(3, root=7).raw_nT[:5])
    assert not np.array_equal(case(2).raw_nT[:5], case(14).raw_nT[:5])  # two clean records differ


def test_mix_of_every_block_of_24():
    assert Counter(g4.PATTERN) == {"clean": 2, "single": 6, "pair": 2, "triple": 2, "outside": 6, "outside_plus": 2,
                                   "too_short": 2, "fixed": 2}
    assert [case(i).category for i in range(24)] == list(g4.PATTERN)
    rng = np.random.default_rng(0)
    for block in range(4):
        chosen = [g4._choose(24 * block + k, rng) for k in range(24)]
        assert [c[0] for c in chosen] == list(g4.PATTERN)
        assert sorted(c[1][0] for c in chosen if c[0] == "single") == sorted(g4.LIBRARY)
        assert all(set(c[1]) <= set(g4.FIXED_EFFECTS) for c in chosen if c[0] == "fixed")
    outs = {c[2][0] for i in range(96) for c in [g4._choose(i, rng)] if c[0] == "outside"}
    assert outs == set(g4.OUTSIDE) and len(g4.OUTSIDE) >= 10
    assert set(g4.ACCEPTABLE_FOR) <= set(g4.OUTSIDE)
    assert all(set(v) <= set(g4.LIBRARY) for v in g4.ACCEPTABLE_FOR.values())


def test_schedules_are_new_and_produced():
    old = {"sphere", "tumble", "turntable", "vehicle", "steps", "irregular", "figure_eight", "handheld", "pendulum",
           "platform_survey", "gimbal", "ship", "quad_hover", "car_circuit", "hand_dance", "buoy"}
    assert not (set(g4.SCHEDULES) | {g4.FIXED_SCHEDULE}) & old
    made = {case(i).schedule for i in SAMPLE}
    assert made == set(g4.SCHEDULES) | {g4.FIXED_SCHEDULE}


@pytest.mark.parametrize("i", SAMPLE)
def test_record_shapes_units_and_truth(i):
    c = case(i)
    n = len(c.t_s)
    assert c.raw_nT.shape == (n, 3) and c.f_ref_nT.shape == (n,) and c.t_s.shape == (n,)
    assert np.all(np.isfinite(c.raw_nT)) and np.all(np.isfinite(c.f_ref_nT)) and np.all(np.diff(c.t_s) > 0)
    if c.category == "too_short":
        assert 8 <= n <= 14 and not c.present and not c.outside and not c.expect_unexplained
        assert len(c.acceptable) <= 1
    else:
        assert 300 <= n <= 2000
    assert 18000 < np.median(c.f_ref_nT) < 66000
    assert 0.9 < np.median(np.linalg.norm(c.raw_nT, axis=1) / c.f_ref_nT) < 1.1  # nT
    if c.temp_C is not None:
        assert c.temp_C.shape == (n,) and np.all(np.isfinite(c.temp_C))
    if c.gravity is not None:
        assert c.gravity.shape == (n, 3) and np.allclose(np.linalg.norm(c.gravity, axis=1), 1.0)
    assert c.schedule == "satellite" or np.ptp(c.f_ref_nT) < 100  # a model constant or a followed variation
    if c.notes.get("reference") == "model" and c.schedule != "satellite":
        assert np.ptp(c.f_ref_nT) == 0
    assert set(c.present) <= set(c.acceptable) <= set(g4.LIBRARY)
    if c.category != "too_short":
        assert set(c.acceptable) - set(c.present) <= {a for o in c.outside for a in g4.ACCEPTABLE_FOR.get(o, ())}
    assert c.expect_unexplained == bool(c.outside)
    assert set(c.outside) <= set(g4.OUTSIDE)
    assert all(len(set(p)) == 2 and set(p) <= set(g4.LIBRARY) and tuple(sorted(p)) == p for p in c.confoundable)
    expected = {"clean": (0, 0), "single": (1, 0), "pair": (2, 0), "triple": (3, 0), "outside": (0, 1),
                "outside_plus": (1, 1), "too_short": (0, 0), "fixed": (1, 0)}[c.category]
    assert (len(c.present), len(c.outside)) == expected
    if c.category == "fixed":
        assert c.schedule == g4.FIXED_SCHEDULE and set(c.present) <= set(g4.FIXED_EFFECTS)
        assert 2 * 3600 * 0.9 <= c.t_s[-1] - c.t_s[0] <= 20 * 3600 * 3
        if set(c.present) & {"offset_drift", "field_drift"}:
            assert ("field_drift", "offset_drift") in c.confoundable
    if "temperature" in c.present:
        assert c.temp_C is not None


@pytest.mark.parametrize("i", [i for i in SAMPLE if g4.PATTERN[i % 24] == "clean"])
def test_clean_records_are_noise_after_the_true_calibration(i):
    c = case(i)
    noise = c.notes["noise_nT"]
    rms = float(np.sqrt(np.mean(true_residual(c) ** 2)))
    assert 0.8 * noise < rms < 1.2 * noise, (rms, noise)
    assert not c.present and not c.outside and not c.acceptable and not c.confoundable


@pytest.mark.parametrize("i", [i for i in SAMPLE if g4.PATTERN[i % 24] not in ("clean", "too_short")])
def test_every_effect_is_within_its_visibility_bounds(i):
    c = case(i)
    vis, beyond = c.notes["visible_sigma"], c.notes["beyond_library_sigma"]
    lo, hi = g4.VISIBLE_RANGE
    for name in c.present:
        if name == "outliers":
            assert vis[name] >= g4.OUTLIER_MIN_SIGMA
        else:
            assert lo <= vis[name] <= hi, (name, vis[name])
    for name in c.outside:
        assert g4.BEYOND_RANGE[0] <= beyond[name] <= g4.BEYOND_RANGE[1], (name, beyond[name])
        assert vis[name] >= beyond[name] * 0.999


@pytest.mark.parametrize("i", [i for i in SAMPLE if "outliers" in case(i).present])
def test_outliers_are_isolated_large_spikes(i):
    c = case(i)
    rows = np.array(c.notes["outlier_rows"])
    assert len(rows) >= 5 and np.all(np.diff(rows) >= 4)
    noise = c.notes["noise_nT"]
    if c.category == "fixed":
        jumps = np.linalg.norm(np.diff(c.raw_nT, axis=0), axis=1)
        assert np.sum(jumps > 8 * noise) >= 2 * len(rows) - 2
    else:
        res = true_residual(c)  # each spike against its neighbours (other effects are smooth there)
        jump = [abs(res[r] - np.median(np.r_[res[r - 3:r], res[r + 1:r + 4]])) for r in rows]
        assert np.sum(np.array(jump) > 6 * noise) >= len(rows) - 1, jump


def test_a_perfect_verdict_scores_one_and_a_wrong_name_zero():
    for i in SAMPLE:
        c = case(i)
        if c.category == "clean":
            verdict = "none"
        elif c.category == "too_short":
            verdict = "insufficient_data"
        else:
            names = list(c.present) + (["unexplained"] if c.expect_unexplained else [])
            verdict = "+".join(names) if names else "unexplained"
        assert score(c, verdict).score == 1.0, (i, verdict)
        wrong = [e for e in g4.LIBRARY if e not in c.acceptable]
        if wrong and c.category != "too_short":
            assert score(c, verdict.replace("unexplained", "").strip("+") + "+" + wrong[0]).score == 0.0 \
                if c.category != "clean" else score(c, wrong[0]).score == 0.0

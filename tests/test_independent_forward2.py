"""Checks of the second independent forward model (tests/independent_forward2.py) alone: it shares no code
with magbench and these tests do not import magbench."""
from __future__ import annotations

import collections
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import independent_forward2 as gen  # noqa: E402
from independent_scoring import score  # noqa: E402

SAMPLE = range(0, 48)  # four turns of the category cycle: light on the CPU


@pytest.fixture(scope="module")
def cases():
    return {i: gen.make_case(i) for i in SAMPLE}


def test_no_magbench_in_the_generator():
    text = Path(gen.__file__).read_text(encoding="utf-8")
    assert "magbench" not in text.replace("magbench's", "")
    assert "import magbench" not in text and "from magbench" not in text


def test_reproducible_for_a_seed():
    for i in (1, 6, 9, 23):
        a, b = gen.make_case(i, 77), gen.make_case(i, 77)
        for field in ("raw_nT", "f_ref_nT", "t_s", "temp_C"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
        assert (a.present, a.outside, a.confoundable, a.acceptable) == (b.present, b.outside, b.confoundable,
                                                                      b.acceptable)
    assert not np.array_equal(gen.make_case(1, 77).raw_nT[:5], gen.make_case(1, 78).raw_nT[:5])


def test_categories_in_the_first_generators_proportions():
    counts = collections.Counter(gen.plan(i)[0] for i in range(1200))
    expected = collections.Counter(gen.CATEGORIES)
    assert counts == {c: 100 * m for c, m in expected.items()}
    assert expected == {"clean": 1, "single": 3, "pair": 1, "outside": 3, "outside_plus": 1, "triple": 1,
                        "too_short": 1, "fixed": 1}


def test_plan_matches_the_case(cases):
    for i, case in cases.items():
        category, kind, chosen = gen.plan(i)
        assert case.category == category and case.schedule == kind and case.notes["planned"] == chosen


def test_a_clean_noise_free_record_is_an_ellipsoid_of_radius_f():
    for i in range(0, 120, 12):
        case = gen.make_case(i, noise_free=True)
        assert case.category == "clean"
        corrected = (case.raw_nT - case.notes["offset"]) @ case.notes["correction"].T
        np.testing.assert_allclose(np.linalg.norm(corrected, axis=1), case.f_ref_nT, rtol=1e-10)


def test_shapes_and_finite_values(cases):
    for case in cases.values():
        n = len(case.t_s)
        assert case.raw_nT.shape == (n, 3) and case.f_ref_nT.shape == (n,) and case.temp_C.shape == (n,)
        assert (8 <= n <= 13) if case.too_short else (300 <= n <= 2000)
        assert np.all(np.diff(case.t_s) > 0)
        for arr in (case.raw_nT, case.f_ref_nT, case.t_s, case.temp_C):
            assert np.all(np.isfinite(arr))
        assert np.all(case.f_ref_nT > 20000) and np.all(case.f_ref_nT < 70000)
        if case.gravity is not None:
            assert case.gravity.shape == (n, 3) and np.all(np.isfinite(case.gravity))


def test_truth_is_consistent(cases):
    for case in cases.values():
        assert set(case.present) <= set(gen.LIBRARY) and set(case.outside) <= set(gen.OUTSIDE)
        assert set(case.present) <= set(case.acceptable)
        assert case.expect_unexplained == bool(case.outside)
        for pair in case.confoundable:
            assert len(pair) == 2 and set(pair) <= set(gen.LIBRARY)
        if case.category in ("clean", "too_short"):
            assert not case.present and not case.outside and not case.acceptable
        if case.category == "fixed":
            assert not case.outside
        for name, eff in case.notes["effects"].items():
            if name not in case.notes["too_small"]:
                assert 0.5 * 8 <= eff["snr"] <= 20.5, (case.index, name, eff)


def test_the_scorer_takes_the_cases(cases):
    for case in cases.values():
        if case.too_short:
            verdict = "insufficient_data"
        elif case.category == "clean":
            verdict = "none"
        else:
            names = list(case.present) + (["unexplained"] if case.expect_unexplained else [])
            verdict = "+".join(names) if names else "none"
        assert score(case, verdict).score == 1.0, (case.index, verdict)


def test_every_effect_occurs_in_the_first_2000_cases():
    seen = collections.Counter(e for i in range(2000) for e in gen.plan(i)[2])
    missing = (set(gen.LIBRARY) | set(gen.OUTSIDE)) - set(seen)
    assert not missing, missing
    assert min(seen[e] for e in gen.OUTSIDE) >= 10

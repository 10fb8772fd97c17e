"""The fifth independent forward model (tests/independent_forward5.py): deterministic, free of magbench code,
its truths consistent with its categories, and its effects visible.  Fast: a handful of records."""
import ast
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import independent_forward5 as g5  # noqa: E402

SOURCE = Path(g5.__file__)
CASES = (0, 1, 2, 3, 4, 5, 8, 9)  # single, outside, clean, pair, fixed, outside_plus, too_short, triple


@pytest.fixture(scope="module")
def cases():
    return {i: g5.make_case(i) for i in CASES}


def test_imports_no_magbench_nor_other_generators():
    tree = ast.parse(SOURCE.read_text(encoding="utf-8"))
    modules = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            modules.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            modules.add(node.module or "")
            if node.module == "independent_forward":
                assert [a.name for a in node.names] == ["Case"]
    roots = {m.split(".")[0] for m in modules}
    assert roots <= {"__future__", "dataclasses", "typing", "collections", "numpy", "scipy", "independent_forward"}, roots
    assert not any("magbench" in m or "simulate" in m for m in modules)


def test_deterministic(cases):
    for i in (2, 4):
        a, b = cases[i], g5.make_case(i)
        assert np.array_equal(a.raw_nT, b.raw_nT) and np.array_equal(a.t_s, b.t_s)
        assert np.array_equal(a.f_ref_nT, b.f_ref_nT)
        assert (a.temp_C is None) == (b.temp_C is None)
        assert a.present == b.present and a.outside == b.outside and a.confoundable == b.confoundable
    assert not np.array_equal(g5.make_case(2, root=7).raw_nT[:5], cases[2].raw_nT[:5])


def test_truths_consistent(cases):
    for i, c in cases.items():
        assert c.category == g5.PATTERN[i % len(g5.PATTERN)]
        n = len(c.t_s)
        assert c.raw_nT.shape == (n, 3) and c.f_ref_nT.shape == (n,) and np.all(np.diff(c.t_s) > 0)
        assert np.all(np.isfinite(c.raw_nT))
        assert set(c.present) <= set(g5.LIBRARY) and set(c.outside) <= set(g5.OUTSIDE)
        assert set(c.present) <= set(c.acceptable) <= set(g5.LIBRARY)
        for o in c.outside:
            assert set(g5.ACCEPTABLE_FOR.get(o, ())) <= set(c.acceptable)
        assert c.expect_unexplained == bool(c.outside)
        for a, b in c.confoundable:
            assert a in g5.LIBRARY and b in g5.LIBRARY and (a in c.present or b in c.present)
        if c.temp_C is not None:
            assert c.temp_C.shape == (n,)
        if "temperature" in c.present or "thermal_hysteresis" in c.outside:
            assert c.temp_C is not None
        if c.gravity is not None:
            assert c.gravity.shape == (n, 3) and np.allclose(np.linalg.norm(c.gravity, axis=1), 1)
        if c.category == "clean":
            assert not c.present and not c.outside and not c.acceptable
        elif c.category == "too_short":
            assert n <= 14 and not c.present and not c.outside
        elif c.category == "fixed":
            assert c.schedule == "seafloor" and c.present and set(c.present) <= set(g5.FIXED_LIBRARY)
        elif c.category in ("outside", "outside_plus"):
            assert c.outside and len(c.present) == (c.category == "outside_plus")
        else:
            assert len(c.present) == {"single": 1, "pair": 2, "triple": 3}[c.category] and not c.outside


def _calibration_directions(c):
    C, off = np.array(c.notes["true_C"]), np.array(c.notes["true_offset_nT"])
    B = (c.raw_nT - off) @ C.T
    mag = np.linalg.norm(B, axis=1)
    u = B / mag[:, None]
    cols = [mag * u[:, i] * u[:, j] for i in range(3) for j in range(i, 3)] + [u[:, i] for i in range(3)]
    return B, mag, np.column_stack(cols)


def test_effects_visible(cases):
    for c in cases.values():
        if c.category == "too_short":
            continue
        for name in c.present + c.outside:
            info = c.notes["effects"][name]
            size = info["beyond_sigma"] if name in g5.OUTSIDE else info["visible_sigma"]
            assert size >= g5.VISIBLE_FLOOR, (c.index, name, info)
        B, mag, cal = _calibration_directions(c)
        if c.schedule == "seafloor":
            rest = np.sqrt(np.mean((B - B.mean(axis=0)) ** 2)) / c.notes["noise_vector_nT"]
        else:
            r = mag - c.f_ref_nT
            coef, *_ = np.linalg.lstsq(cal, r, rcond=None)
            rest = np.std(r - cal @ coef) / c.notes["noise_nT"]
        if c.category == "clean":  # the true calibration leaves white noise of the stated level
            assert 0.8 < rest < 1.25, (c.index, rest)
        elif "outliers" not in c.present:  # an effect leaves several noise sigmas the calibration cannot take
            assert rest > 3, (c.index, c.present, c.outside, rest)

"""A sensor's neighbours in a field whose magnitude changes (a satellite along its orbit): the acceptance's nearest
attitudes are the nearest field vectors, direction and magnitude (``acceptance.magnitude_scale``).

The forward model is written here from the physics: a spinning body on a precessing cone, in a field whose direction
turns once and whose magnitude halves and comes back along the record (a dipole's field seen along an orbit), read
by a triad with a lower-triangular mixing, offsets, white noise of 1 nT and, where asked, a quadratic response of each
axis to the field along it.  At one direction and half the field a quadratic response reads a quarter as much: the
scatter about neighbours in direction alone holds it, and a residual of 10.8 nT on 1 nT of noise had been accepted
(the fourth independent generator's satellites: a quadratic response accepted 13 deviations from the truth)."""
from __future__ import annotations

import numpy as np
import pytest

from magbench.calibrators import acceptance, make
from magbench.calibrators.base import _DatasetCache
from magbench.simulate.dataset import Dataset


def _rz(a: np.ndarray) -> np.ndarray:
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _ry(a: np.ndarray) -> np.ndarray:
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def orbit_record(quadratic_nT: float, seed: int, n: int = 900) -> Dataset:
    """``n`` readings at 1 s; ``quadratic_nT``: each axis's quadratic response at 50,000 nT along it."""
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=float)
    phase = 2 * np.pi * t / n
    f = 37_500.0 + 12_500.0 * np.cos(phase)  # 50,000 nT down to 25,000 and back
    world = f[:, None] * np.column_stack([np.cos(phase), np.full(n, 0.3), np.sin(phase)]) / np.hypot(1.0, 0.3)
    body_to_world = _rz(2 * np.pi * t / 173.0) @ _ry(np.full(n, 0.6)) @ _rz(2 * np.pi * t / 9.7)  # cone, spin
    body = np.einsum("nji,nj->ni", body_to_world, world)
    mix = np.array([[1.012, 0.004, -0.006], [0.0, 0.991, 0.008], [0.0, 0.0, 1.005]])
    raw = body @ mix.T + np.array([120.0, -80.0, 45.0])
    raw += quadratic_nT * np.array([1.0, -0.7, 0.5]) * (body / 50_000.0) ** 2
    raw += rng.normal(0.0, 1.0, raw.shape)
    return Dataset(raw, f_ref_nT=f, t_s=t)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_quadratic_response_in_a_changing_field_is_rejected(seed):
    fit = make("lsq").fit(orbit_record(60.0, seed))
    assert not fit.accepted
    assert "came back to at other times" in fit.rejections[0]
    assert fit.rms_after_nT > 8.0  # ten times the noise: a residual no honest noise estimate passes


@pytest.mark.parametrize("seed", [0, 1])
def test_the_same_sensor_without_it_is_accepted(seed):
    fit = make("lsq").fit(orbit_record(0.0, seed))
    assert fit.accepted, fit.rejections
    assert fit.rms_after_nT < 1.1


def test_by_direction_alone_the_scatter_holds_the_response(monkeypatch):
    """The negative control: neighbours found by direction alone (the rule switched off) accept the same record."""
    monkeypatch.setattr(acceptance, "REFERENCE_VARIES", np.inf)
    monkeypatch.setattr(_DatasetCache, "_entries", type(_DatasetCache._entries)())  # no geometry found before
    fit = make("lsq").fit(orbit_record(60.0, 0))
    assert fit.accepted and fit.rms_after_nT > 8.0


def test_a_steady_reference_keeps_the_neighbours_by_direction():
    """Below REFERENCE_VARIES of the median the scale is not used: the neighbours are the directions' own."""
    rng = np.random.default_rng(3)
    raw = rng.normal(size=(400, 3)) * 5e4
    steady = 50_000.0 + rng.normal(0.0, 200.0, 400)  # 0.4 % of the field
    assert acceptance.magnitude_scale(steady) is None
    varying = np.linspace(30_000.0, 60_000.0, 400)
    scale = acceptance.magnitude_scale(varying)
    assert scale is not None and np.isclose(np.median(scale), 1.0)
    plain = acceptance.attitude_neighbours(raw)
    scaled = acceptance.attitude_neighbours(raw, scale=scale)
    assert plain is not None and scaled is not None
    assert not np.array_equal(plain[1], scaled[1])  # other neighbours where the magnitude differs
    # a constant scale leaves the nearest by direction unchanged (the same distances, shifted)
    same = acceptance.attitude_neighbours(raw, scale=np.ones(400))
    assert same is not None and np.array_equal(plain[1], same[1])


def test_scaled_neighbours_never_take_an_excluded_pair_while_others_are_left():
    """By field vector the similarities reach below -2 (|a|, |b| up to 2 here): an excluded pair (the row itself, a
    sample near in time) must still rank below every real one.  The same search with the row's own index excluded
    only, against a brute-force nearest by distance."""
    rng = np.random.default_rng(7)
    raw = rng.normal(size=(200, 3))
    scale = np.concatenate([np.full(100, 0.5), np.full(100, 2.0)])  # a field that quadruples
    nearest, enough = acceptance._nearest_directions(raw, None, scale)
    points = raw / np.linalg.norm(raw, axis=1)[:, None] * scale[:, None]
    dist = np.linalg.norm(points[:, None] - points[None], axis=2)
    np.fill_diagonal(dist, np.inf)
    brute = np.sort(np.argsort(dist, axis=1, kind="stable")[:, :acceptance.KNN_NEIGHBOURS], axis=1)
    assert enough.all() and not (nearest == np.arange(200)[:, None]).any()
    assert np.array_equal(nearest, brute)
    # where only far rows are left (a revisit search that excludes most), the far ones are chosen, not excluded ones:
    # row 0 points along +x at twice the field, the only rows it may take along -x at twice the field (a.b - |b|^2/2
    # of -6), the rest excluded
    pts = np.zeros((40, 3))
    pts[:, 0] = 1.0
    pts[30:, 0] = -1.0
    big = np.full(40, 2.0)

    def only_the_far(block: slice, m: int) -> np.ndarray:
        near = np.ones((len(range(m)[block]), m), dtype=bool)
        near[:, 30:] = False
        return near

    chosen, enough = acceptance._nearest_directions(pts, only_the_far, big)
    assert enough[0] and set(chosen[0]) <= set(range(30, 40))


def test_scaled_neighbours_among_some_rows_are_those_of_the_rows_alone():
    """``attitude_neighbours(raw, among, scale)`` (a record that repeats some readings) takes each row's scale with it."""
    rng = np.random.default_rng(8)
    raw = rng.normal(size=(300, 3)) * 5e4
    scale = np.linspace(0.6, 1.4, 300)
    among = rng.permutation(300)[:200]
    rows, nearest = acceptance.attitude_neighbours(raw, among, scale=scale)
    kept = np.sort(among)
    alone = acceptance.attitude_neighbours(raw[kept], scale=scale[kept])
    assert alone is not None and np.array_equal(np.asarray(rows), kept[alone[0]])
    assert np.array_equal(nearest, alone[1])

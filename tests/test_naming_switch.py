"""A load switched on and off is not an offset drift: a body-fixed field that switches between two levels at a few
times explains the residual as well as the smooth drift does, so ``offset_drift`` is refused and the structure is
``unexplained`` (``naming.step_explains``).  The records are written here from the physics (a sensor tumbling in a
constant field, a field fixed in its body), not with ``simulate``; the control is the same record with the body
field drifting smoothly, which must still be named."""
import numpy as np
import pytest

from magbench.benchmarks.diagnosis import diagnose
from magbench.benchmarks.diagnosis.naming import _two_level_states, step_explains
from magbench.simulate.dataset import Dataset

F_WORLD = np.array([18000.0, 1200.0, 45000.0])


def _tumble(n: int, span_s: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(times, body-from-world rotations) of a sensor turned smoothly through many attitudes."""
    t = np.linspace(0.0, span_s, n)
    rates = np.cumsum(rng.normal(0.0, 0.02, (n, 3)), axis=0) + rng.normal(0.0, 0.05, 3)
    rot = np.empty((n, 3, 3))
    rot[0] = np.eye(3)
    dt = t[1] - t[0]
    for i in range(1, n):  # a rotation by the rate vector over one step (Rodrigues)
        w = rates[i] * dt
        a = float(np.linalg.norm(w))
        k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / a
        rot[i] = (np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k) @ rot[i - 1]
    return t, rot


def _record(body_field: str, seed: int = 5) -> Dataset:
    rng = np.random.default_rng(seed)
    n = 1500
    t, rot = _tumble(n, 1500.0, rng)
    b = np.einsum("nij,j->ni", rot, F_WORLD)
    v = np.array([9.0, -6.6, 4.5])  # nT: the load's field in the body
    u = t / t[-1]
    if body_field == "switched":  # on at 20 %, off at 45 %, on at 70 % of the record, settling over 3 % of it
        level = sum((1.0 if k % 2 == 0 else -1.0) / (1.0 + np.exp(-(u - on) / 0.03)) for k, on in enumerate((0.2, 0.45, 0.7)))
    else:  # the same field drifting smoothly over the record
        level = 0.5 - 0.5 * np.cos(2 * np.pi * 1.3 * u)
    readings = b @ np.diag([1.01, 0.99, 1.005]).T + np.array([150.0, -90.0, 60.0]) + level[:, None] * v
    return Dataset(readings + rng.normal(0.0, 1.0, (n, 3)), f_ref_nT=np.full(n, np.linalg.norm(F_WORLD)), t_s=t)


def test_the_two_level_states_follow_the_cheaper_level_with_at_most_the_allowed_changes():
    e0 = np.array([0, 0, 5, 5, 0, 0, 5, 0], dtype=float)
    e1 = 5 - e0
    assert _two_level_states(e0, e1, 4).tolist() == [0, 0, 1, 1, 0, 0, 1, 0]
    assert _two_level_states(e0, e1, 2).tolist() == [0, 0, 1, 1, 0, 0, 0, 0]  # the dearer lone segment given up
    assert _two_level_states(e0, e1, 0).tolist() == [0] * 8


def test_a_load_switched_on_and_off_is_not_an_offset_drift():
    # its field settles over 45 s at each switching: a smooth drift follows it well enough to pass every held-out
    # test, and a single step explains too little of it (``SWITCH_REFITS = 0``: offset_drift was named)
    result = diagnose(_record("switched"))
    row = next(r for r in result["naming"]["evidence"] if r["name"] == "offset_drift")
    assert not row["named"] and len(row["step"]["times_s"]) == 3, row
    assert [round(x / 1500, 2) for x in row["step"]["times_s"]] == pytest.approx([0.2, 0.45, 0.7], abs=0.03)
    assert result["verdict"] == "unexplained"


def test_negative_control_the_same_field_drifting_smoothly_is_an_offset_drift():
    result = diagnose(_record("drifting"))
    assert result["verdict"] == "offset_drift", result["naming"]["evidence"]


def test_switchings_beyond_the_first_do_not_fit_the_noise_of_a_weak_drift():
    """A linear drift of the offsets about the noise's size, at random attitudes: the switchings search refuses it
    no more often than the single step does (uncharged, its extra switchings fit the noise: 85 against 26 of 100 at
    1.5 noise sigmas), and a load switched three times at that size is still found."""
    rng = np.random.default_rng(2)
    n = 400
    t = np.arange(n, dtype=float)
    tt = 2 * t / (n - 1) - 1
    refused = {1: 0, 6: 0}
    for _ in range(40):
        u = rng.normal(size=(n, 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        v = rng.normal(size=3)
        v *= 1.5 / np.linalg.norm(v)
        r = -(u @ v) * tt + rng.normal(size=n)
        cols = np.column_stack([u * tt[:, None], u, np.ones(n)])
        sse_drift = float(np.sum((r - cols @ np.linalg.lstsq(cols, r, rcond=None)[0]) ** 2))
        for most in refused:
            refused[most] += step_explains(r, u, t, sse_drift, most=most) is not None
    assert refused[6] <= refused[1] + 2, refused
    on = ((t > 100) & (t < 200)) | (t > 300)
    r = -(u @ v) * 4 * on + rng.normal(size=n)
    cols = np.column_stack([u * tt[:, None], u, np.ones(n)])
    sse_drift = float(np.sum((r - cols @ np.linalg.lstsq(cols, r, rcond=None)[0]) ** 2))
    step = step_explains(r, u, t, sse_drift)
    assert step is not None and len(step["times_s"]) == 3

"""At random attitudes a drift in time moves the noise floor with it: consecutive readings lie at unrelated attitudes
(their differences hold the drift's projection on each), and the nearest attitudes lie at unrelated times.  An offset
oscillating three times over sphere9 (150 nT on one axis: 60 nT of residual on a 2 nT sensor) left a floor of 50 nT
and a verdict of ``none``.  Random attitudes make the drift easy to fit instead (``floor.drift_floor``), so the floor
comes down to what a drift leaves and the remainder is seen.  A sensor changed over the middle third of the record
cancels between attitude neighbours of the same third (``floor.TIME_BLOCKS``).  Records written from what happens to
a sensor; the controls (intact, 50 nT of white noise) stay ``none``."""
import numpy as np
import pytest

from magbench.benchmarks.diagnosis import diagnose
from magbench.benchmarks.diagnosis.floor import drift_floor
from magbench.simulate import simulate
from magbench.simulate.dataset import Dataset


def _record(scenario: str, seed: int, kind: str) -> Dataset:
    d = simulate(scenario, seed)
    raw = d.raw_nT.copy()
    n = len(raw)
    if kind == "oscillating offset":
        raw[:, 1] += 150.0 * np.sin(2.0 * np.pi * 3.0 * np.arange(n) / n)
    elif kind == "sign flipped over the middle third":
        raw[n // 3:2 * n // 3, 2] *= -1.0
    elif kind == "white noise":
        raw += np.random.default_rng(seed).normal(0.0, 50.0, raw.shape)
    return Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s)


@pytest.mark.parametrize("scenario", ["sphere9", "cap9"])
@pytest.mark.parametrize("seed", [0, 2])
def test_an_offset_oscillating_at_random_attitudes_is_not_none(scenario, seed):
    report = diagnose(_record(scenario, seed, "oscillating offset"))
    assert report["verdict"] != "none", report["verdict"]
    assert report["remainder_significant"]
    # the floor comes down to what the drift leaves, or (seed 0) the residual follows the neighbouring readings,
    # which makes the remainder significant on its own
    assert report["noise_floor_nT"] < 30.0 < report["rms_base_nT"] or report.get("remainder_follows_neighbours")


@pytest.mark.parametrize("scenario,seed", [("sphere9", 1), ("sphere9", 2), ("cap9", 0), ("cap9", 1)])
def test_a_sign_flipped_over_the_middle_third_is_unexplained(scenario, seed):
    report = diagnose(_record(scenario, seed, "sign flipped over the middle third"))
    assert report["verdict"] == "unexplained", report["verdict"]


@pytest.mark.parametrize("scenario", ["sphere9", "cap9"])
@pytest.mark.parametrize("kind", ["intact", "white noise"])
def test_negative_controls_stay_none(scenario, kind):
    report = diagnose(_record(scenario, 1, kind))
    assert report["verdict"] == "none", report["verdict"]


def test_drift_floor_is_the_noise_without_a_drift_and_sees_through_one():
    rng = np.random.default_rng(0)
    n = 300
    t = np.sort(rng.uniform(0.0, 300.0, n))
    unit = rng.normal(size=(n, 3))
    unit /= np.linalg.norm(unit, axis=1)[:, None]
    noise = rng.normal(0.0, 2.0, n)
    assert 1.8 < drift_floor(noise, unit, t, 9) < 2.3
    drifting = noise + 100.0 * np.sin(2.0 * np.pi * t / 120.0) * unit[:, 1] + 0.3 * t
    assert 1.8 < drift_floor(drifting, unit, t, 9) < 2.6
    assert drift_floor(noise[:15], unit[:15], t[:15], 9) is None  # too short for one degree


@pytest.mark.parametrize("scenario", ["sphere9", "cap9"])
@pytest.mark.parametrize("kind", ["sign z halfway", "gain x halfway", "offsets drifting", "intact"])
def test_without_a_time_column_the_file_order_stands_in_for_time(scenario, kind):
    """No t column: the floor was the scatter about the nearest attitudes over the whole file, which held a change
    between its parts or a drift along it (sphere9 with z's sign flipped halfway: `none` at 200 nT against a 182 nT
    floor).  The halves and thirds of the file and a drift along its rows are taken too; the floor stays an upper
    bound, and the intact record stays `none`."""
    d = simulate(scenario, 0)
    raw = d.raw_nT.copy()
    n = len(raw)
    if kind == "sign z halfway":
        raw[n // 2:, 2] *= -1.0
    elif kind == "gain x halfway":
        raw[n // 2:, 0] *= 1.01
    elif kind == "offsets drifting":
        raw += np.linspace(0.0, 1.0, n)[:, None] * np.array([300.0, -200.0, 100.0])
    report = diagnose(Dataset(raw, f_ref_nT=d.f_ref_nT))
    assert report["floor_is_upper_bound"]
    assert report["verdict"] == ("none" if kind == "intact" else "unexplained"), report["verdict"]


@pytest.mark.parametrize("shape", [(300, 57), (60, 57), (58, 57), (20, 3), (57, 57), (10, 12)])
def test_residual_sum_of_squares_is_lstsq_s(shape):
    """The drift checks' sum of squares from one QR of [design | y] equals what np.linalg.lstsq leaves, for tall,
    barely tall, square and wide designs (the last two: lstsq itself)."""
    from magbench.numerics import residual_sum_of_squares

    rng = np.random.default_rng(shape[0] * 100 + shape[1])
    design, y = rng.normal(size=shape), rng.normal(size=shape[0])
    coef, *_ = np.linalg.lstsq(design, y, rcond=1e-10)
    left = y - design @ coef
    assert residual_sum_of_squares(design, y, 1e-10) == pytest.approx(float(left @ left), rel=1e-9, abs=1e-20)


def test_residual_sum_of_squares_rank_deficient_design_keeps_lstsq_s_cut():
    """A fixed attitude makes the drift's direction-cosine columns multiples of its time columns: the triangular
    factor's diagonal collapses and lstsq's rank cut decides, as before.  Negative control: plain Householder QR of
    that design removes extra directions of y (a smaller sum of squares), which the helper must not return."""
    from magbench.numerics import drift_columns, residual_sum_of_squares

    t = np.linspace(0.0, 100.0, 300)
    design = drift_columns(t, np.tile([0.6, 0.0, 0.8], (300, 1)), 12, constant=False)
    y = np.random.default_rng(3).normal(size=300)
    coef, *_ = np.linalg.lstsq(design, y, rcond=1e-10)
    left = y - design @ coef
    r = np.linalg.qr(np.column_stack([design, y]), mode="r")
    q = design.shape[1]
    assert residual_sum_of_squares(design, y, 1e-10) == pytest.approx(float(left @ left), rel=1e-9)
    assert float(r[q, q] ** 2) < 0.95 * float(left @ left)  # what the plain QR would have said


@pytest.mark.parametrize("shape", [(300, 9, 48), (60, 9, 40), (59, 9, 49), (20, 3, 5), (13, 6, 6), (12, 6, 5)])
def test_residual_sum_of_squares_beside_a_basis_is_the_whole_design_s(shape):
    """The drift check's sum of squares with the drift columns' basis made once (``orthonormal_basis``) and the
    Jacobian and residual projected off it equals what lstsq leaves on the whole design [extra | columns], for tall,
    barely tall (one row beyond the columns) and square designs (the last: lstsq itself, on the columns given again by
    the basis).  The basis keeps q and r, read-only, not the columns."""
    from magbench.numerics import orthonormal_basis, residual_sum_of_squares_beside

    m, p, k = shape
    rng = np.random.default_rng(m * 1000 + p * 10 + k)
    extra, columns, y = rng.normal(size=(m, p)), rng.normal(size=(m, k)), rng.normal(size=m)
    coef, *_ = np.linalg.lstsq(np.column_stack([extra, columns]), y, rcond=1e-10)
    left = y - np.column_stack([extra, columns]) @ coef
    basis = orthonormal_basis(columns)
    got = residual_sum_of_squares_beside(basis, extra, y, 1e-10)
    assert got == pytest.approx(float(left @ left), rel=1e-9, abs=1e-20)
    assert basis._fields == ("q", "r") and not basis.q.flags.writeable and not basis.r.flags.writeable
    assert np.allclose(basis.q @ basis.r, columns, rtol=0, atol=1e-12)


def test_residual_sum_of_squares_beside_a_basis_keeps_lstsq_s_cut():
    """A Jacobian column that lies in the drift columns' span (a fixed attitude: an offset's column is a multiple of
    the constant) or drift columns that collapse onto each other make the design rank deficient: lstsq's cut decides,
    as with the whole design's QR.  Negative control: the projected QR's own last diagonal entry, which the helper
    must not return there."""
    from magbench.numerics import drift_columns, orthonormal_basis, residual_sum_of_squares, residual_sum_of_squares_beside

    t = np.linspace(0.0, 100.0, 300)
    columns = drift_columns(t, np.tile([0.6, 0.0, 0.8], (300, 1)), 12, constant=False)
    rng = np.random.default_rng(4)
    extra, y = rng.normal(size=(300, 4)), rng.normal(size=300)
    basis = orthonormal_basis(columns)
    whole = np.column_stack([extra, columns])
    coef, *_ = np.linalg.lstsq(whole, y, rcond=1e-10)
    left = y - whole @ coef
    assert residual_sum_of_squares_beside(basis, extra, y, 1e-10) == pytest.approx(float(left @ left), rel=1e-9)
    assert residual_sum_of_squares(whole, y, 1e-10) == pytest.approx(float(left @ left), rel=1e-9)
    both = np.column_stack([extra, y]) - basis.q @ (basis.q.T @ np.column_stack([extra, y]))
    r = np.linalg.qr(both, mode="r")
    assert float(r[4, 4] ** 2) < 0.95 * float(left @ left)  # what the projected QR alone would have said


def test_the_drift_basis_kept_with_a_record_gives_the_numbers_computed_afresh():
    """``assess`` with the record's cache (``memo``: the drift basis made by the first fit, read by the next) says
    what it says without one, to the last bit, on a record whose offsets drift (rejected) and on an intact one."""
    from magbench.calibrators import make
    from magbench.calibrators.acceptance import assess
    from magbench.calibrators.core.objective import ScalarObjective
    from magbench.calibrators.core.problem import PHYSICAL_BOX, search_bounds

    for drifting in (False, True):
        d = simulate("sphere9", seed=5)
        raw = d.raw_nT + (np.linspace(0.0, 1.0, len(d))[:, None] * np.array([300.0, -200.0, 100.0]) if drifting else 0)
        d = Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s)
        x = make("lsq").fit(d).solver_x
        objective = ScalarObjective(d.raw_nT, d.f_ref_nT, "nine")
        box = search_bounds("nine", float(np.median(d.f_ref_nT)), **PHYSICAL_BOX)
        kept: dict = {}

        def memo(key, compute, kept=kept):
            if key not in kept:
                kept[key] = compute()
            return kept[key]

        said = []
        for m in (None, memo, memo):
            info: dict = {}
            out = assess(objective, x, improved=True, robust=False, closed_form=False, physical_box=box, info=info,
                         t_s=d.t_s, memo=m)
            said.append((out, info["drift_check"]))
        assert any(k[0] == "drift_basis" for k in kept)
        assert said[0] == said[1] == said[2]
        assert bool(said[0][0][0]) is drifting, said[0][0][0]


def test_one_record_s_two_time_columns_keep_two_drift_bases():
    """The record cache is keyed by the readings and reference: the drift basis (and the noise geometry) must be kept
    per time column.  The same drifting readings with their times in order and with the times shuffled: the second's
    answer after the first's is what it is alone."""
    from magbench.calibrators import make
    from magbench.calibrators.base import _DatasetCache

    d = simulate("sphere9", seed=6)
    raw = d.raw_nT + np.linspace(0.0, 1.0, len(d))[:, None] * np.array([300.0, -200.0, 100.0])
    shuffled = np.random.default_rng(0).permutation(np.asarray(d.t_s))
    first, second = Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s), Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=shuffled)
    _DatasetCache._entries.clear()
    alone = make("lsq").fit(second)
    _DatasetCache._entries.clear()
    before = make("lsq").fit(first)
    after = make("lsq").fit(second)
    assert any("drifts in time" in r for r in before.rejections)
    assert after.rejections == alone.rejections and after.accepted == alone.accepted
    assert not any("drifts in time" in r for r in alone.rejections)

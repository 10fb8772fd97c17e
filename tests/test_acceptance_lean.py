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


def _joint_gain(j: np.ndarray, t: np.ndarray, r: np.ndarray) -> float:
    """What the step columns ``t`` explain of ``r`` beyond the record's directions ``j`` (two least-squares fits)."""
    full = np.column_stack([j, t])
    coef = np.linalg.lstsq(full, r, rcond=None)[0]
    base = np.linalg.lstsq(j, r, rcond=None)[0]
    return float(r @ (full @ coef)) - float(r @ (j @ base))


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

    j = obj.jacobian(x)[order]

    def joint_gain(k):
        t = np.zeros((len(r), 3))
        t[k:] = -j[k:, 6:9]
        return _joint_gain(j, t, r[order])

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


def test_the_one_pass_judges_as_the_separate_computations():
    """assess given the pass at the answer (fisher.one_pass) gives what it computes without it, also when an
    outlier screening makes it judge another set of points (negative control: the pass at another point is
    not used)."""
    d = get_scenario("tumble9").build(2)
    raw = d.raw_nT.copy()
    raw[::41] += 4000.0
    obj = ScalarObjective(raw, d.f_ref_nT, "nine")
    box = search_bounds("nine", d.f_ref_nT, **PHYSICAL_BOX)
    for x in (make("lsq").fit(d).x, make("lsq").fit(Dataset(raw, f_ref_nT=d.f_ref_nT)).x):
        kw = dict(improved=True, robust=False, closed_form=False, physical_box=box, t_s=d.t_s)
        plain_info, lean_info, stale_info = {}, {}, {}
        plain = acceptance.assess(obj, x, info=plain_info, **kw)
        lean = acceptance.assess(obj, x, info=lean_info, at=fisher.one_pass(obj, x), **kw)
        stale = acceptance.assess(obj, x, info=stale_info, at=fisher.one_pass(obj, x + 1e-3), **kw)
        assert plain == lean == stale
        for key in ("noise_nT", "noise_independent_nT", "n_outliers"):
            assert plain_info[key] == pytest.approx(lean_info[key], rel=1e-9) == stale_info[key]


def test_the_pass_at_the_solvers_last_point_reuses_its_block_to_the_last_bit():
    """A one-block record's one_pass at the point normal_equations was last asked at (a local solver's answer)
    takes that block instead of computing it again, and gives what a fresh objective computes, bit for bit;
    at any other point (negative control: one ulp away) it computes its own."""
    d = get_scenario("sphere9").build(0)
    x = make("lsq").fit(d).x
    fresh = ScalarObjective(d.raw_nT, d.f_ref_nT, "nine").one_pass(x, True)
    for shifted in (False, True):
        obj = ScalarObjective(d.raw_nT, d.f_ref_nT, "nine")
        obj.normal_equations(np.nextafter(x, np.inf) if shifted else x.copy())
        computed = []
        block = obj._block
        obj._block = lambda *a, computed=computed, block=block: computed.append(1) or block(*a)  # type: ignore[method-assign]
        for a, b in zip(obj.one_pass(x, True), fresh):
            assert np.array_equal(a, b)
        assert len(computed) == int(shifted)  # the block taken only where it was computed


def test_the_cholesky_quadratic_forms_equal_the_lu_solves():
    rng = np.random.default_rng(5)
    a = rng.normal(size=(50, 3, 3))
    s = a @ a.transpose(0, 2, 1)
    s[7] = np.outer([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])  # singular: the ridge decides, or LU where a pivot fails
    c = rng.normal(size=(50, 3))
    ridge = 1e-10 * np.einsum("mii->m", s) / 3 + 1e-300
    lu = np.einsum("mi,mi->m", np.linalg.solve(s + ridge[:, None, None] * np.eye(3), c[:, :, None])[:, :, 0], c)
    chol = acceptance._quadratic_forms(s, ridge, c)
    assert np.allclose(np.delete(chol, 7), np.delete(lu, 7), rtol=1e-9)
    assert np.isfinite(chol[7]) and chol[7] == pytest.approx(lu[7], rel=1e-4)
    one = acceptance._quadratic_forms(s[:, :1, :1], ridge, c[:, :1])  # q = 1: the LU path
    assert np.allclose(one, c[:, 0] ** 2 / (s[:, 0, 0] + ridge), rtol=1e-12)


def test_the_step_search_of_a_model_without_offsets_equals_the_joint_regression():
    """angles: the step is of the mean (a column of ones after the split); the gain at the best split equals
    the joint fit's (negative control: a split far from the step gains less)."""
    d = get_scenario("tumble3").build(0)
    raw = d.raw_nT.copy()
    at = len(raw) // 2
    raw[at:] *= 1.002
    obj = ScalarObjective(raw, d.f_ref_nT, "angles")
    x = make("lsq", model="angles").fit(Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s)).x
    r = obj.residuals(x)
    order = np.argsort(d.t_s, kind="stable")
    step = acceptance.best_step(obj, x, r, order)
    assert step is not None and not step.offsets and abs(step.index - at) <= len(raw) // 50
    j = np.column_stack([np.ones(len(r)), obj.jacobian(x)])[order]

    def joint_gain(k):
        t = np.zeros((len(r), 1))
        t[k:] = 1.0
        return _joint_gain(j, t, r[order])

    assert step.gain == pytest.approx(joint_gain(step.index), rel=1e-6)
    assert joint_gain(len(raw) // 10) < 0.5 * step.gain


def test_a_dataset_changed_in_place_is_judged_on_its_new_numbers():
    """The per-dataset cache is keyed by the numbers (their digest): the same numbers in another array reuse
    it; the same array changed in place (here to a plane of attitudes) is refused as if new."""
    from magbench.calibrators import base
    from magbench.errors import InputError

    d = get_scenario("sphere9").build(4)
    calls = []
    real = base.coverage
    try:
        base.coverage = lambda *a, **k: calls.append(1) or real(*a, **k)
        first = make("lsq").fit(d)
        again = make("lsq").fit(Dataset(d.raw_nT.copy(), f_ref_nT=d.f_ref_nT.copy(), t_s=d.t_s))
        assert first.accepted and again.accepted and first.data_digest == again.data_digest
        assert len(calls) <= 1  # computed once for the numbers (or not at all, when an earlier test left them)
        planar = Dataset(np.array(d.raw_nT), f_ref_nT=d.f_ref_nT, t_s=d.t_s)
        assert make("lsq").fit(planar).accepted
        planar.raw_nT.setflags(write=True)  # a Dataset's arrays are read-only: forced, as a careless caller might
        planar.raw_nT[:, 2] = 1e-3 * np.arange(len(d))  # in place: a level turntable's readings (z not constant:
        # a constant axis is refused as dead before the coverage is asked)
        with pytest.raises(InputError, match="degenerate attitude coverage"):
            make("lsq").fit(planar)
    finally:
        base.coverage = real


def test_the_fast_median_is_numpys():
    from magbench.numerics import median, median_and_sigma, robust_sigma

    rng = np.random.default_rng(1)
    for n in (1, 2, 3, 10, 301, 1000):
        x = rng.standard_t(3, size=n)
        assert median(x) == np.median(x)
        assert median_and_sigma(x) == (np.median(x), robust_sigma(x))
    assert np.isnan(median(np.array([1.0, np.nan, 3.0])))


def test_a_sampled_profile_test_states_its_precision():
    """On more rows than PROFILE_ROWS the profile test refits a systematic sample: its rejection and the
    result say how many rows and to what precision the increase was scaled to all rows."""
    d = _long("vehicle9", 150)
    res = make("lsq").fit(d)
    text = " ".join(res.rejections)
    assert "refitted on a systematic sample of" in text and f"of {len(d):,} rows" in text
    sample = res.extra["acceptance_sampling"]["profile"]
    assert sample["rows"] <= acceptance.PROFILE_ROWS and sample["of_rows"] == len(d)
    # a conservative standard error (the sample's own refit agrees with all rows' to within one noise variance,
    # test_a_sampled_profile_refit_decides_as_all_rows): here the increase is about 3 of them below the threshold
    assert 0 < sample["increase_se_noise_variances"] < acceptance.DEFAULT_LIMITS.profile_chi2 / 2
    coverage = res.extra["acceptance_sampling"]["coverage"]  # the coverage check read a sample too
    assert coverage["rows"] <= fisher.COVERAGE_ROWS and coverage["of_rows"] == len(d)
    assert "acceptance_sampling" not in make("lsq").fit(get_scenario("vehicle9").build(0)).extra  # every row read


def test_the_cramer_rao_diagonal_is_pinvs():
    """``std_from_information`` (eigh, pinv's cut) gives pinv's diagonal, also for a singular information
    matrix (negative control: without the cut the singular direction blows up)."""
    d = get_scenario("sphere9").build(0)
    obj = ScalarObjective(d.raw_nT, d.f_ref_nT, "nine")
    x = make("lsq").fit(d).x
    info = fisher.fisher_information(obj, x, 1.0)
    assert np.allclose(fisher.std_from_information(info, 2.0), np.sqrt(np.diag(np.linalg.pinv(info / 4.0))),
                       rtol=1e-8)
    singular = info.copy()
    singular[:, 8] = singular[8, :] = 0.0
    want = np.sqrt(np.diag(np.linalg.pinv(singular)))
    got = fisher.std_from_information(singular, 1.0)
    assert np.allclose(got, want, rtol=1e-8) and got[8] == 0.0
    with np.errstate(divide="ignore"):
        assert not np.isfinite(np.sqrt(1.0 / np.linalg.eigvalsh(singular))).all()


def test_the_step_states_the_jump_that_was_made():
    d = get_scenario("tumble9").build(0)
    raw = d.raw_nT.copy()
    jump = np.array([300.0, -200.0, 100.0])
    raw[len(raw) // 3:] += jump
    obj = ScalarObjective(raw, d.f_ref_nT, "nine")
    x = make("lsq").fit(Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s)).x
    step = acceptance.best_step(obj, x, obj.residuals(x), np.argsort(d.t_s, kind="stable"))
    assert step is not None and step.offsets
    assert np.linalg.norm(step.jump) == pytest.approx(np.linalg.norm(jump), rel=0.1)


def test_the_lean_linear_algebra_gives_numpys_numbers_bit_for_bit():
    """The checks' shortcuts compute what numpy's own calls compute, to the last bit: ``fisher.eigh`` (the gufunc
    behind np.linalg.eigh, without its wrapper; the same error where it does not converge), the step search's
    running sums (``_sums_after``: two entries at a time, as complex numbers) against np.cumsum of each entry,
    and the medians against np.median."""
    from magbench.numerics import median_and_sigma

    rng = np.random.default_rng(11)
    for _ in range(200):
        a = rng.normal(size=(9, 14)) * 10.0 ** rng.uniform(-8, 8, size=(9, 1))
        a = a @ a.T
        for got, want in zip(fisher.eigh(a), np.linalg.eigh(a)):
            assert got.tobytes() == want.tobytes() and got.strides == want.strides

    def outcome(f, m):
        try:
            return [v.tobytes() for v in f(m)]
        except np.linalg.LinAlgError as exc:
            return str(exc)

    raised = 0
    for value in (np.nan, np.inf):
        for size in (3, 9):
            m = rng.normal(size=(size, size + 3))
            m = m @ m.T
            m[0, 0] = value
            assert outcome(fisher.eigh, m) == outcome(np.linalg.eigh, m)
            raised += isinstance(outcome(np.linalg.eigh, m), str)
    assert raised  # the error path is compared too
    for n, q, width in ((300, 3, 13), (301, 1, 11), (57, 3, 6), (40, 2, 5)):
        t, w = rng.normal(size=(q, n)), rng.normal(size=(width, n)) * 1e3
        w[:, ::7] = -0.0
        for edges in (np.arange(2, n - 1), np.array([1, 5, 6, n // 2, n - 1])):
            plain = np.cumsum(t[:, None, ::-1] * w[None, :, ::-1], axis=2)[:, :, n - 1 - edges]  # from the end
            got = acceptance._sums_after(t, w, edges)
            assert got.tobytes() == np.ascontiguousarray(plain).tobytes()
    for n in (1, 2, 3, 300, 301):
        x = rng.standard_t(2, size=n)
        m, s = median_and_sigma(x)
        assert m == np.median(x) and s == 1.4826 * np.median(np.abs(x - np.median(x)))
    for odd in ([1.0, np.nan, 2.0], [np.inf, np.inf, 1.0]):  # NaN among the values, an infinite median
        assert np.isnan(median_and_sigma(np.array(odd))[1])
    assert median_and_sigma(np.array([np.inf, 1.0, 2.0, 3.0])) == (2.5, 1.4826 * 1.0)


def test_hyper_parameters_found_valid_are_remembered_by_value_and_type():
    """``check_param_values`` remembers values it found valid (every fit checks them again): a value equal in
    Python but of another type (True for 1) is checked on its own and refused; an invalid value is never
    remembered."""
    from magbench.calibrators.base import _VALID_PARAMS
    from magbench.errors import InputError

    cls = type(make("lsq"))
    params = make("lsq", seed=1).get_params()
    cls.check_param_values(params)
    assert any(key[0] is cls for key in _VALID_PARAMS)
    for bad in (True, -1, 1.0):
        with pytest.raises(InputError, match="seed"):
            cls.check_param_values({**params, "seed": bad})
    with pytest.raises(InputError, match="max_nfev"):
        cls.check_param_values({**params, "max_nfev": 0})
    with pytest.raises(InputError, match="max_nfev"):  # refused again: a refusal is not remembered
        cls.check_param_values({**params, "max_nfev": 0})


def test_the_triangular_factor_is_numpys_qr():
    """``numerics.triangular_factor`` (the gufunc behind np.linalg.qr, without its wrapper) gives
    np.linalg.qr(a, mode="r") bit for bit: the same shape, zeros below the diagonal, the same numbers; input it does
    not take (integers, empty) goes to numpy's own call, and NaN comes out as numpy's does.  It must not import SciPy's
    linalg (0.27 s of a one-off calibrate, whose process had not loaded it)."""
    from magbench.numerics import triangular_factor

    rng = np.random.default_rng(5)
    for shape in ((300, 22), (300, 10), (2000, 3), (5, 5), (3, 7), (1, 1)):
        a = rng.normal(size=shape) * 10.0 ** rng.uniform(-6, 6, size=shape[1])
        got, want = triangular_factor(a), np.linalg.qr(a, mode="r")
        assert got.shape == want.shape and not np.tril(got, -1).any()
        assert got.tobytes() == np.ascontiguousarray(want).tobytes()
        scratch = np.asfortranarray(a)
        assert triangular_factor(scratch, scratch=True).tobytes() == np.ascontiguousarray(want).tobytes()
    view = rng.normal(size=(300, 10))[:, ::2]  # not contiguous
    assert triangular_factor(view).tobytes() == np.ascontiguousarray(np.linalg.qr(view, mode="r")).tobytes()
    for odd in (np.arange(12).reshape(4, 3), np.empty((0, 3)), np.array([[1.0, np.nan], [2.0, 3.0], [4.0, 5.0]])):
        with np.errstate(all="ignore"):
            want = np.linalg.qr(odd, mode="r")
            got = triangular_factor(odd)
        assert got.shape == want.shape and np.array_equal(got, want, equal_nan=True)
    import subprocess
    import sys

    probe = ("import sys; from magbench.numerics import triangular_factor; import numpy as np; "
             "triangular_factor(np.eye(4)); print('scipy.linalg' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "False"

"""Hostile calls of the Python API that had answered wrongly or crashed (a probe of 1,510 calls, 2026-11-28), each
beside a control that must keep working.  The library's promise (docs/CONTRACT.md): bad input is an ``InputError``
with one clear line, never another exception from deep inside; a number it cannot stand behind is a rejection."""
import numpy as np
import pytest

import magbench
from magbench.errors import InputError
from magbench.simulate.dataset import Dataset


@pytest.fixture(scope="module")
def sphere():
    return magbench.simulate("sphere9", seed=1)


def _truth_z(result, data) -> float:
    names = ["alpha_rad", "beta_rad", "gamma_rad", "kx", "ky", "kz", "ox_nT", "oy_nT", "oz_nT"]
    truth = np.asarray(data.truth.params.to_vector("nine"))
    return max(abs(result.x[i] - truth[i]) / result.uncertainty[k] for i, k in enumerate(names))


def test_ten_readings_for_nine_parameters_are_refused_nineteen_taken(sphere):
    """10 readings for 9 parameters were accepted with deviations 70 times too small (the residual of 0.026 nT on a
    2 nT sensor was taken for the noise).  Now a fit needs 10 readings beyond its parameters; at 19 the stated
    deviations cover the truth (40 records, the worst parameter within 5.6 deviations)."""
    with pytest.raises(InputError, match=r"10 points are too few for lsq with the nine model \(it needs at least 19"):
        magbench.calibrate(sphere.raw_nT[:10], f_ref_nT=50000.0)
    worst = []
    for seed in range(1, 21):
        d = magbench.simulate("sphere9", seed=seed)
        res = magbench.calibrate(Dataset(d.raw_nT[:19], f_ref_nT=d.f_ref_nT[:19], truth=d.truth))
        assert res.accepted
        worst.append(_truth_z(res, d))
    assert max(worst) < 6.0


@pytest.mark.parametrize("seed", range(3))
def test_readings_copied_near_their_attitudes_do_not_count_as_attitudes(seed):
    """10 readings and 9 near-copies of them (0.5 nT apart) pass the 19-reading minimum, and were accepted with a
    parameter 15 deviations from the truth: the copies hold the residual at their jitter.  The acceptance asks for 19
    distinct attitudes (readings 0.1 % of the field apart): rejected, saying so, with or without times and for a
    closed form too.  Control: 19 distinct attitudes of the same record are accepted."""
    d = magbench.simulate("sphere9", seed=seed)
    rng = np.random.default_rng(seed)
    idx = rng.choice(len(d), 10, replace=False)
    copies = rng.integers(0, 10, 9)
    raw = np.vstack([d.raw_nT[idx], d.raw_nT[idx][copies] + rng.normal(0.0, 0.5, (9, 3))])
    f = np.concatenate([d.f_ref_nT[idx], d.f_ref_nT[idx][copies]])
    for data in (Dataset(raw, f_ref_nT=f), Dataset(raw, f_ref_nT=f, t_s=np.arange(19.0))):
        res = magbench.calibrate(data)
        assert not res.accepted
        assert any(r.startswith(("the readings hold only 10 distinct attitudes",  # 9 once an outlier is screened
                                 "the readings hold only 9 distinct attitudes")) for r in res.rejections)
    assert any("distinct attitudes" in r for r in magbench.calibrate(Dataset(raw, f_ref_nT=f),
                                                                     method="ellipsoid").rejections)
    idx = rng.choice(len(d), 19, replace=False)
    control = magbench.calibrate(Dataset(d.raw_nT[idx], f_ref_nT=d.f_ref_nT[idx]))
    assert control.accepted, control.rejections


def test_a_robust_answer_s_deviations_cover_its_distance_from_the_optimum():
    """ransac (robust: the fitness tests exempt it) was accepted on clean records with a parameter 5.4-15.6 of its
    Cramér-Rao deviations from the truth: the bound is the optimum's, and its answer lies away from the optimum.  Its
    stated deviations now add that distance in quadrature: within 4 of them on 10 records.  Negative control: the
    bound alone at its answer leaves every record beyond 5.  lsq's answer is the optimum: its deviations are the
    bound's."""
    from magbench.calibrators.core.objective import ScalarObjective
    from magbench.calibrators.fisher import crb_std

    names = ["alpha_rad", "beta_rad", "gamma_rad", "kx", "ky", "kz", "ox_nT", "oy_nT", "oz_nT"]
    for seed in range(1, 11):
        d = magbench.simulate("sphere9", seed=seed)
        res = magbench.calibrate(d, method="ransac", seed=seed)
        assert res.accepted
        truth = np.asarray(d.truth.params.to_vector("nine"))
        assert _truth_z(res, d) < 4.0
        bound = crb_std(ScalarObjective(d.raw_nT, d.f_ref_nT, "nine"), res.x, res.noise_nT)
        assert np.max(np.abs(res.x - truth) / bound) > 5.0
        lsq = magbench.calibrate(d)
        bound = crb_std(ScalarObjective(d.raw_nT, d.f_ref_nT, "nine"), lsq.x, lsq.noise_nT)
        assert np.allclose([lsq.uncertainty[k] for k in names], bound, rtol=1e-3)


def test_representatives_are_the_greedy_pass_over_every_row_when_fewer_than_enough():
    """``numerics.representatives`` against the greedy pass written out over every row, on records of a few held
    attitudes (its samples find too few, and it looks at every row: the same rows); on many attitudes it stops at
    ``enough`` rows, each farther than the radius from the others."""
    from magbench.numerics import representatives

    def greedy(points, radius):
        kept: list[int] = []
        for i, p in enumerate(points):
            if all(np.linalg.norm(p - points[k]) > radius for k in kept):
                kept.append(i)
        return kept

    rng = np.random.default_rng(0)
    for holds, per in ((3, 400), (12, 50), (18, 2), (25, 3), (400, 1)):
        centres = rng.normal(size=(holds, 3)) * 50_000.0
        points = np.repeat(centres, per, axis=0) + rng.normal(0.0, 2.0, (holds * per, 3))
        points = points[rng.permutation(len(points))] if holds != 12 else points  # held in turn, or visited in any order
        chosen = representatives(points, 50.0, 19)
        if len(chosen) < 19:
            assert chosen.tolist() == greedy(points, 50.0), (holds, per)
        else:
            gaps = np.linalg.norm(points[chosen][:, None] - points[chosen][None], axis=2)
            assert (gaps[~np.eye(19, dtype=bool)] > 50.0).all()
    one = np.ones((5000, 3)) * 50_000.0
    one[-1] += 100.0  # the last row alone differs: every row is looked at
    assert representatives(one, 50.0, 19).tolist() == [0, 4999]


def _copies(seed: int, distinct: int, copies: int):
    d = magbench.simulate("sphere9", seed=seed)
    rng = np.random.default_rng(seed)
    idx = rng.choice(len(d), distinct, replace=False)
    which = rng.integers(0, distinct, copies)
    raw = np.vstack([d.raw_nT[idx], d.raw_nT[idx][which] + rng.normal(0.0, 0.5, (copies, 3))])
    return d, Dataset(raw, f_ref_nT=np.concatenate([d.f_ref_nT[idx], d.f_ref_nT[idx][which]]))


def test_copies_of_readings_widen_the_deviations_to_the_attitudes_noise(monkeypatch):
    """12 distinct readings and 20 near-copies (0.5 nT apart) of them: enough attitudes to be fitted (9 + 3), too few
    to judge by (under 9 + 10), so the deviations take the noise the attitudes' mean residuals show.  Over 20 records
    at most 1 accepted answer lies beyond 5 deviations; negative control: without the widening, 8 did.  Control:
    12 positions held for 60 samples each (white noise) are all accepted, within 3 deviations (the widening is about
    1 there; a rule of 19 distinct attitudes had rejected them all)."""
    from magbench.calibrators import acceptance
    from magbench.simulate.scenarios import SPHERE9_ERRORS
    from magbench.simulate.sensor import SensorModel

    def wrong() -> int:
        count = 0
        for seed in range(20):
            d, data = _copies(seed, 12, 20)
            res = magbench.calibrate(data)
            count += bool(res.accepted and _truth_z(res, d) > 5.0)
        return count

    assert wrong() <= 1
    sensor = SensorModel(SPHERE9_ERRORS, noise_nT=2.0)
    truth = np.asarray(sensor.true_correction().to_vector("nine"))
    names = ["alpha_rad", "beta_rad", "gamma_rad", "kx", "ky", "kz", "ox_nT", "oy_nT", "oz_nT"]
    for seed in range(5):
        rng = np.random.default_rng(seed)
        turns = rng.normal(size=(12, 3))
        turns /= np.linalg.norm(turns, axis=1)[:, None]
        body = np.repeat(turns * 50_000.0, 60, axis=0)
        raw = sensor.add_noise(sensor.linear(body), rng)
        res = magbench.calibrate(Dataset(raw, f_ref_nT=np.full(len(raw), 50_000.0), t_s=np.arange(len(raw), dtype=float)))
        assert res.accepted, res.rejections
        assert np.max(np.abs(res.x - truth) / np.array([res.uncertainty[k] for k in names])) < 3.0
    monkeypatch.setattr(acceptance, "few_attitudes_effect", lambda *args: 1.0)
    monkeypatch.setattr(acceptance, "nonlinearity_shift", lambda *args, **kwargs: (None, None))  # which widens some of them too
    assert wrong() >= 5


@pytest.mark.parametrize("method, settings", [("nlopt", {"algorithm": "GN_ORIG_DIRECT", "max_evaluations": 3000}),
                                              ("cmaes", {"budget": 800, "seed": 1})])
def test_a_search_cut_short_is_rejected_though_within_twice_the_optimum(sphere, method, settings):
    """3.44 nT against an optimum of 2.02 passed the ratio test (at most 2 times), with a scale 15 deviations off.
    The sum of squares above the optimum, in noise variances, is now held to the chi-square quantile of the
    parameters at 1e-6.  Control: every method run to its end on the same record is accepted."""
    res = magbench.calibrate(sphere, method=method, **settings)
    assert res.rms_after_nT < 2 * 2.02
    assert not res.accepted
    assert any("noise variances, more than the 44.8 that 9 parameters" in r for r in res.rejections)
    for control in ("lsq", "ga", "nlopt", "cmaes", "ellipsoid"):
        assert magbench.calibrate(sphere, method=control).accepted, control


@pytest.mark.parametrize("value", [1e12, 1e200, 1e300, 6e7])
def test_a_corrupt_row_far_beyond_any_sensor_s_range_is_refused_by_name(sphere, value):
    """A row of 1e12 nT left the diagnosis a noise floor of 0.002 nT and the verdict ``none``; 1e200 raised a
    LinAlgError in calibrate and diagnose.  More than 1000 times the median row is refused, the row named.
    Control: a spike 100 times the field (a MEMS part's range) is still a spike (a rejection, not a refusal)."""
    raw = sphere.raw_nT.copy()
    raw[3] = value
    for call in (lambda: magbench.calibrate(raw, f_ref_nT=5e4),
                 lambda: magbench.diagnose(Dataset(raw, f_ref_nT=sphere.f_ref_nT, t_s=sphere.t_s))):
        with pytest.raises(InputError, match=r"1 row\(s\) \(row 3\) have a magnitude more than 1000 times"):
            call()
    spike = sphere.raw_nT.copy()
    spike[3] = 2.9e6
    res = magbench.calibrate(spike, f_ref_nT=5e4)
    assert not res.accepted and "outliers" in res.rejections[0]
    assert magbench.diagnose(Dataset(spike, f_ref_nT=sphere.f_ref_nT, t_s=sphere.t_s))["verdict"] != "none"


def test_a_scalar_series_is_checked_before_it_is_diagnosed():
    """A reference of 1 nT against 5e4 measured, magnitudes in uT, or a negative reference came back as an ``offset``;
    a NaN as ``unexplained`` with NaN figures; bad shapes reached numpy.  Control: the same series in nT."""
    from magbench.simulate.dataset import ScalarSeries

    hd = np.arange(0, 360, 15.0)
    fm = 5e4 + 30 * np.cos(np.radians(hd))
    ref = np.full(24, 5e4)
    bad = {"reference magnitude is 1 nT": dict(f_meas_nT=fm, heading_deg=hd, f_ref_nT=np.ones(24)),
           "times the reference": dict(f_meas_nT=fm * 3, heading_deg=hd, f_ref_nT=ref),
           "0.001 times the reference": dict(f_meas_nT=fm / 1000, heading_deg=hd, f_ref_nT=ref),
           "must be positive": dict(f_meas_nT=fm, heading_deg=hd, f_ref_nT=-ref),
           r"f_meas_nT is NaN or infinite in row\(s\) 0": dict(f_meas_nT=np.r_[np.nan, fm[1:]], heading_deg=hd,
                                                                f_ref_nT=ref),
           r"heading_deg is NaN": dict(f_meas_nT=fm, heading_deg=np.r_[np.nan, hd[1:]], f_ref_nT=ref),
           "f_ref_nT has 23 values for 24 rows": dict(f_meas_nT=fm, heading_deg=hd, f_ref_nT=ref[:23]),
           "one value per row": dict(f_meas_nT=np.c_[fm, fm], heading_deg=hd, f_ref_nT=ref)}
    for message, columns in bad.items():
        with pytest.raises(InputError, match=message):
            magbench.diagnose(ScalarSeries(**columns))
    assert magbench.diagnose(ScalarSeries(f_meas_nT=fm, heading_deg=hd, f_ref_nT=ref))["verdict"] == "offset"
    with pytest.raises(InputError, match="--folds must be at most 8 for 24 readings"):  # had been taken silently
        magbench.diagnose(ScalarSeries(f_meas_nT=fm, heading_deg=hd, f_ref_nT=ref), folds=9)
    with pytest.raises(InputError, match="t_s"):  # the glitch check leaves text to the columns' own check
        magbench.diagnose(ScalarSeries(f_meas_nT=fm, heading_deg=hd, f_ref_nT=ref, t_s=["a"] * 24))


@pytest.mark.parametrize("readings", [np.ones((4, 3, 1)), None, 5.0, np.ones((4, 2)), np.ones(2), "abc",
                                      np.ones((3, 3)) + 1j])
def test_correct_takes_readings_of_shape_n_by_3_only(sphere, readings):
    """``correct`` broadcast (4, 3, 1) into (4, 3, 3), made NaN of None, a 3-vector of a number and dropped an
    imaginary part; a calibration loaded from its file did the same.  Control: (n, 3) and (3,)."""
    res = magbench.calibrate(sphere)
    for obj in (res, res.calibration()):
        with pytest.raises(InputError, match="readings to correct must"):
            obj.correct(readings)
        assert obj.correct(sphere.raw_nT[:5]).shape == (5, 3) and obj.correct(sphere.raw_nT[0]).shape == (3,)


def test_hyper_parameters_out_of_range_are_refused_by_make():
    """Each had passed ``make`` and failed inside a library (pycma's 'number of weights', numpy's 'maximum allowed
    dimension', SWIG's OverflowError, SciPy's unknown strategy) or run for minutes (a population of 1e7 on a budget of
    1000).  Control: the same methods with values in range."""
    from magbench.calibrators import make

    for name, params in [("cmaes", {"population": 1}), ("cmaes", {"population": 10**7, "max_evaluations": 1000}),
                         ("cmaes", {"population": 500, "max_evaluations": 100}), ("ga", {"population": 10**30}),
                         ("ga", {"tournament": 10**30}), ("aga", {"population": 10**30}), ("aco", {"ants": 10**30}),
                         ("aco", {"archive_size": 10**30}), ("de", {"popsize": 10**30}), ("nlopt", {"population": 10**30}),
                         ("de", {"strategy": "nonsense"}), ("de", {"mutation": -1}), ("twostep", {"max_iterations": -1}),
                         ("twostep", {"tol": -1.0})]:
        with pytest.raises(InputError):
            make(name, **params)
    for name, params in [("cmaes", {"population": 10}), ("de", {"mutation": (0.5, 1.0), "strategy": "rand1bin"}),
                         ("ga", {"tournament": 3}), ("twostep", {"max_iterations": 5})]:
        make(name, **params)


def test_tiny_settings_and_budgets_give_answers_not_internal_errors(sphere):
    """RANSAC with inlier_fraction 0.02 (w^9 = 5e-16 rounded 1 - w^9 to 1: ZeroDivisionError); ACO with q = 1e-310
    (eq. 7's factor overflowed: IndexError); a time budget spent before the first evaluation (the counter's own
    BudgetExhausted escaped from fit, for every method).  Now an answer each: the time-starved ones rejected."""
    from magbench.calibrators.core.evaluator import Budget

    assert magbench.calibrate(sphere, method="ransac", inlier_fraction=0.02, max_iterations=100).accepted
    assert magbench.calibrate(sphere, method="aco", q=1e-310).rms_after_nT < 3.0
    for method in ("lsq", "ga", "cmaes", "nlopt", "de"):
        res = magbench.calibrate(sphere, method=method, budget=Budget(max_time_s=1e-9))
        assert not res.accepted and res.status in ("budget", "maxtime_reached") and res.n_evaluations >= 1
    with pytest.raises(InputError, match="max_evaluations must be at least 1"):
        Budget(max_evaluations=0)


@pytest.mark.parametrize("call, message", [
    (lambda d: magbench.load_calibration(None), "named by a path"),
    (lambda d: magbench.load_calibration("a\0b"), "NUL byte"),
    (lambda d: magbench.read_csv(3), "named by a path"),
    (lambda d: magbench.calibrate(d, units=["nT"]), "unknown unit"),
    (lambda d: magbench.calibrate(d, method=["lsq"]), "named by a string"),
    (lambda d: Dataset(None), "got None"),
    (lambda d: Dataset(d.raw_nT, meta=[1, 2]), "meta must be a dict"),
    (lambda d: magbench.diagnose(Dataset(d.raw_nT, f_ref_nT=d.f_ref_nT, t_s=np.arange(300) * 1e300)), "beyond 1e\\+12"),
    (lambda d: magbench.diagnose(d, seed=2**70), "seed must be an integer from 0 to 2\\*\\*64 - 1"),
    (lambda d: magbench.calibrate(d.raw_nT / 1000, f_ref_nT=50.0), "reference magnitude is 50 nT"),
])
def test_wrong_types_and_units_are_input_errors(sphere, call, message):
    """Each had been a TypeError, ValueError, AttributeError or OverflowError from inside, or (readings in uT against a
    reference of 50) a refusal for 'degenerate attitude coverage' at a condition number of 1.6."""
    with pytest.raises(InputError, match=message):
        call(sphere)


def test_the_new_checks_keep_out_of_what_they_do_not_judge(sphere):
    """Found by a second probe of the fixes: the chi-square test had rejected a GA on exact readings at 0.004 nT
    (inside the rounding floor the ratio test leaves exact data); the corrupt-row check had blamed a reading for a
    reference row of 40 nT (the reference jump is the cause); ``model="auto"`` had met a 1e200 row in SciPy's tree."""
    p = sphere.truth.params
    u = np.random.default_rng(0).normal(size=(300, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    exact = np.linalg.solve(p.matrix, (u * 5e4).T).T + np.asarray(p.offset_nT)
    assert magbench.calibrate(exact, method="ga", f_ref_nT=5e4, seed=1).accepted
    ref = np.array(sphere.f_ref_nT)
    ref[3] = 40.0
    with pytest.raises(InputError, match="the reference jumps"):
        magbench.calibrate(Dataset(sphere.raw_nT, f_ref_nT=ref, t_s=sphere.t_s))
    raw = sphere.raw_nT.copy()
    raw[3] = 1e200
    with pytest.raises(InputError, match=r"row 3: 1e\+200 on one axis"):
        magbench.calibrate(raw, f_ref_nT=5e4, model="auto")


def test_edges_the_second_probe_found_at_the_new_checks(sphere, tmp_path):
    """Numeric strings and a one-number reference in a ScalarSeries are numbers (headings as strings had reached
    numpy's ufuncs); complex, uT and 1e300 columns are refused; None inside readings to correct is refused (it had
    become NaN); times at the float resolution of 1e9 s no longer break the diagnosis's rate localization; a
    calibration file whose reference is not a number is refused when read, not when used."""
    import json

    from magbench.simulate.dataset import ScalarSeries

    hd = np.arange(0, 360, 15.0)
    fm = 5e4 + 30 * np.cos(np.radians(hd))
    ref = np.full(24, 5e4)
    for ok in (dict(heading_deg=[str(h) for h in hd], f_ref_nT=ref), dict(heading_deg=hd, f_ref_nT=5e4),
               dict(heading_deg=hd, f_ref_nT=[str(v) for v in ref])):
        assert magbench.diagnose(ScalarSeries(f_meas_nT=fm, **ok))["verdict"] == "offset"
    for message, bad in (("complex", dict(f_meas_nT=fm + 1000j, heading_deg=hd, f_ref_nT=ref)),
                         ("reference magnitude is 50 nT", dict(f_meas_nT=fm / 1000, heading_deg=hd, f_ref_nT=ref / 1000)),
                         ("heading_deg has values beyond", dict(f_meas_nT=fm, heading_deg=hd * 1e300, f_ref_nT=ref))):
        with pytest.raises(InputError, match=message):
            magbench.diagnose(ScalarSeries(**bad))
    res = magbench.calibrate(sphere)
    with pytest.raises(InputError, match="a value is None"):
        res.correct([[1.0, None, 2.0]])
    assert res.correct([[1.0, 2.0, 3.0]]).shape == (1, 3)
    coarse = Dataset(sphere.raw_nT, f_ref_nT=sphere.f_ref_nT, t_s=1e9 + np.arange(300) * 1e-7)
    assert magbench.diagnose(coarse)["verdict"] in ("none", "unexplained")
    saved = json.loads(res.to_json())
    saved["reference"]["median_nT"] = "x"
    path = tmp_path / "cal.json"
    path.write_text(json.dumps(saved))
    with pytest.raises(InputError, match="reference.median_nT must be a positive number"):
        magbench.load_calibration(path)


def _ar1_on_a_path(seed: int, rho: float, n: int = 600):
    """A sensor of known truth turned along a smooth path (about 1.8 deg a sample) with AR(1) noise of unit variance:
    the readings written out from the model here (P lower triangular as CONTRACT section 1, raw = K P^-1 B + o)."""
    rng = np.random.default_rng(seed)
    truth = np.array([0.004, -0.003, 0.005, 1.01, 0.99, 1.02, 120.0, -80.0, 60.0])
    s = np.linspace(0.0, 1.0, n)
    theta = 2 * np.pi * 3 * s
    phi = np.pi * (0.5 + 0.45 * np.sin(2 * np.pi * 2.1 * s + rng.uniform(0, 6)))
    body = 50_000.0 * np.stack([np.sin(phi) * np.cos(theta), np.sin(phi) * np.sin(theta), np.cos(phi)], axis=1)
    a, b, g = truth[:3]
    p = np.array([[np.cos(a) * np.cos(g), 0, 0], [np.sin(g), np.cos(b), 0], [np.sin(a) * np.cos(g), np.sin(b), 1.0]])
    noise = np.zeros((n, 3))
    step = rng.normal(size=(n, 3))
    for i in range(1, n):
        noise[i] = rho * noise[i - 1] + np.sqrt(1 - rho ** 2) * step[i]
    raw = body @ (np.diag(truth[3:6]) @ np.linalg.inv(p)).T + truth[6:] + noise
    return truth, Dataset(raw, f_ref_nT=np.full(n, 50_000.0), t_s=np.arange(n) * 0.1)


def test_noise_correlated_over_a_wide_turn_widens_the_deviations(monkeypatch):
    """AR(1) noise (rho 0.8) on a path turning about 1.8 deg a sample: its level is reached over a turn too wide to
    tell it from a structure that follows the attitude, and the residual had been judged white (no warning): 9 of 10
    accepted answers lay beyond 5 deviations (up to 9.5).  Now the deviations are widened sqrt(k) times, said in a
    warning: none beyond 3.5.  Negative control: that level taken for no level again."""
    from magbench.calibrators import acceptance

    names = ["alpha_rad", "beta_rad", "gamma_rad", "kx", "ky", "kz", "ox_nT", "oy_nT", "oz_nT"]

    def wrong() -> tuple[int, int]:
        count = warned = 0
        for seed in range(10):
            truth, data = _ar1_on_a_path(seed, 0.8)
            res = magbench.calibrate(data)
            assert res.accepted
            warned += any("across more than 5 deg of turn" in w for w in res.warnings)
            count += bool(np.max(np.abs(res.x - truth) / np.array([res.uncertainty[k] for k in names])) > 5.0)
        return count, warned

    assert wrong() == (0, 10)
    original = acceptance.noise_correlation

    def as_before(*args):
        level = original(*args)
        return None if level is not None and level[2] else level

    monkeypatch.setattr(acceptance, "noise_correlation", as_before)
    monkeypatch.setattr(acceptance, "nonlinearity_shift", lambda *args, **kwargs: (None, None))  # which widens some of them too
    count, warned = wrong()
    assert count >= 7 and warned == 0


@pytest.mark.parametrize("kw", [{"max_evaluations": "10"}, {"max_evaluations": 1.5}, {"max_evaluations": float("nan")},
                                {"max_evaluations": True}, {"max_time_s": "1"}, {"max_time_s": float("nan")},
                                {"max_time_s": float("inf")}],
                         ids=["evals-text", "evals-fraction", "evals-nan", "evals-bool", "time-text", "time-nan",
                              "time-inf"])
def test_a_budget_of_the_wrong_type_is_refused_where_it_is_made(kw):
    """'10' had raised a TypeError from a comparison, 1.5 one from a slice inside the fit, nan had been no budget."""
    from magbench.calibrators.core.evaluator import Budget

    with pytest.raises(InputError, match="must be"):
        Budget(**kw)
    assert Budget(max_evaluations=np.int64(5)).max_evaluations == 5 and Budget(max_time_s=2).max_time_s == 2


@pytest.mark.parametrize("columns, message", [
    (dict(f_meas_nT=None), "f_meas_nT must be one value per row.*got None"),
    (dict(f_meas_nT=5e4), "got one number"),
    (dict(f_meas_nT=[[5e4, 5e4], [5e4]]), "rows of different lengths"),
    (dict(f_meas_nT="50000"), "got str"),
    (dict(f_meas_nT=np.full(24, 5e4), extra=[1, 2]), "extra must be a dict, got list"),
    (dict(f_meas_nT=np.full(24, 5e4), meta=None), "meta must be a dict, got NoneType")])
def test_a_scalar_series_without_rows_or_with_odd_side_tables_is_refused_in_one_line(columns, message):
    """Each had been an internal error (TypeError: len of None; AttributeError: a list's .get).  Control: the same
    series with its rows and dicts is diagnosed."""
    from magbench.simulate.dataset import ScalarSeries

    with pytest.raises(InputError, match=message):
        ScalarSeries(heading_deg=np.arange(0, 360, 15.0), f_ref_nT=np.full(24, 5e4), **columns)
    hd = np.arange(0, 360, 15.0)
    ok = ScalarSeries(f_meas_nT=5e4 + 30 * np.cos(np.radians(hd)), heading_deg=hd, f_ref_nT=np.full(24, 5e4),
                      extra={}, meta={})
    assert magbench.diagnose(ok)["verdict"] == "offset"


def test_a_scalar_row_far_from_its_reference_is_refused_by_row():
    """A dropout row at 1/520 of the field passed the 1/1000 glitch check and was diagnosed; now refused by row.
    Control: a spike of 20,000 nT (0.4 of the field) is a reading, diagnosed."""
    from magbench.simulate.dataset import ScalarSeries

    hd = np.arange(0, 360, 15.0)
    ref = np.full(24, 5e4)
    fm = 5e4 + 30 * np.cos(np.radians(hd))
    dropout = fm.copy()
    dropout[5] = 5e4 / 520
    with pytest.raises(InputError, match=r"f_meas_nT in row\(s\) 5 is outside 0.5-2 times its reference"):
        magbench.diagnose(ScalarSeries(f_meas_nT=dropout, heading_deg=hd, f_ref_nT=ref))
    spike = fm.copy()
    spike[5] += 2e4
    assert magbench.diagnose(ScalarSeries(f_meas_nT=spike, heading_deg=hd, f_ref_nT=ref))["verdict"]

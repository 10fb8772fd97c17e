"""The conformance battery: checks every calibrator must pass (scikit-learn's ``check_estimator``).

``check_calibrator(MyCalibrator)`` runs them all and raises ``AssertionError`` naming the failed check;
``iter_checks`` yields (name, calibrator, check) for ``pytest.mark.parametrize``.  This is how a user
makes a regression test that known error angles are recovered.
"""
from __future__ import annotations

import copy
from dataclasses import replace
from functools import lru_cache

import numpy as np

from magbench import paper
from magbench.simulate import attitude
from magbench.errors import InputError
from magbench.simulate.dataset import Dataset
from magbench.simulate.field import ConstantField
from magbench.simulate.sensor import PARAM_NAMES, ErrorParams, SensorModel

from .base import CalibrationResult, Calibrator
from .objective import Budget

CHECK_ERRORS = {
    "angles": ErrorParams(**paper.TABLE1_ANGLES_RAD),
    "nine": ErrorParams(0.012, -0.008, 0.015, (1.021, 0.984, 1.008), (152.0, -218.0, 85.0)),
}


@lru_cache(maxsize=None)
def check_dataset(model: str, noise_nT: float = 0.05, n: int = 240, seed: int = 12345) -> Dataset:
    """Low-noise full-sphere data with known errors for the battery."""
    rng = np.random.default_rng(seed)
    field = ConstantField.from_angles(50000.0, 55.0, 3.0)
    att = attitude.full_sphere(n, rng)
    sensor = SensorModel(CHECK_ERRORS[model], noise_nT=noise_nT)
    raw = sensor.measure(att.body_field(np.asarray(field.vector_nT)), rng)
    from magbench.simulate.dataset import Truth

    truth = Truth(sensor.true_correction(), sensor, field.vector_nT, scenario=f"check_{model}", seed=seed)
    return Dataset(raw, f_ref_nT=field.total_nT, t_s=att.t_s, truth=truth)


def _instance(calibrator, model: str, **overrides) -> Calibrator:
    cls = calibrator if isinstance(calibrator, type) else type(calibrator)
    params = {} if isinstance(calibrator, type) else calibrator.get_params()
    params = {**params, **cls.checking_params(), "model": model, **overrides}
    return cls(**params)


def check_hyperparameters(calibrator, model):
    """The constructor stores its arguments and nothing else: get_params round-trips."""
    cal = _instance(calibrator, model)
    params = cal.get_params()
    again = type(cal)(**params)
    assert again.get_params() == params, "get_params() does not round-trip through the constructor"
    assert set(vars(cal)) == set(params), \
        f"the constructor sets attributes that are not hyper-parameters: {set(vars(cal)) ^ set(params)}"


def check_recovers_known_errors(calibrator, model):
    """On low-noise full-sphere data the known angles (and scale, offset) are recovered within the
    calibrator's declared ``check_tolerance`` (flat, or per model), and the residual is at least halved."""
    cal = _instance(calibrator, model)
    data = check_dataset(model)
    res = cal.fit(data)
    tol = type(cal).check_tolerance
    tol = tol.get(model, tol) if isinstance(tol.get(model), dict) else tol
    assert res.rms_after_nT <= 0.5 * res.rms_before_nT, \
        f"rms only {res.rms_before_nT:.3g} -> {res.rms_after_nT:.3g} nT on low-noise data"
    truth = data.truth.params
    err = np.abs(res.x - truth.to_vector(model))
    names = PARAM_NAMES[model]
    limits = np.array([tol["angle_rad"]] * 3 + ([tol["scale"]] * 3 + [tol["offset_nT"]] * 3 if model == "nine" else []))
    bad = [f"{names[i]} off by {err[i]:.3g} (tolerance {limits[i]:.3g})" for i in np.flatnonzero(err > limits)]
    assert not bad, "known errors not recovered: " + "; ".join(bad)


def check_deterministic(calibrator, model):
    """Same seed, same numbers."""
    a = _instance(calibrator, model, seed=7).fit(check_dataset(model))
    b = _instance(calibrator, model, seed=7).fit(check_dataset(model))
    assert np.array_equal(a.x, b.x), f"two fits with seed 7 differ: {a.x} vs {b.x}"
    assert a.n_evaluations == b.n_evaluations, "two fits with the same seed counted different evaluations"


def check_input_not_mutated(calibrator, model):
    """fit reads the data and never changes them."""
    data = check_dataset(model, seed=99)
    raw = np.array(data.raw_nT, copy=True)
    writable = replace(data, raw_nT=raw)  # a dataset built from the user's array
    before = raw.copy()
    f_before = np.array(writable.f_ref_nT, copy=True)
    _instance(calibrator, model).fit(writable)
    assert np.array_equal(raw, before), "the user's raw array was changed"
    assert np.array_equal(writable.raw_nT, before), "the dataset's readings were changed"
    assert np.array_equal(writable.f_ref_nT, f_before), "the dataset's reference was changed"


def check_result_fields(calibrator, model):
    """The result is complete, finite and consistent with itself."""
    cal = _instance(calibrator, model)
    data = check_dataset(model)
    res = cal.fit(data)
    assert isinstance(res, CalibrationResult)
    assert res.method == cal.name and res.model == model
    assert res.x.shape == (len(PARAM_NAMES[model]),) and np.all(np.isfinite(res.x))
    assert np.all(np.array(res.params.scale) > 0), "scale factors must be positive"
    m = res.matrix
    assert np.allclose(np.triu(m, 1), 0.0), "the correction matrix must be lower triangular"
    assert np.allclose(m, res.params.matrix)
    rms = np.sqrt(np.mean((np.linalg.norm(res.correct(data.raw_nT), axis=1) - data.f_ref_nT) ** 2))
    assert np.isclose(rms, res.rms_after_nT, rtol=1e-9, atol=1e-9), "rms_after_nT disagrees with correct()"
    assert res.runtime_s >= 0 and res.n_evaluations >= 0 and res.seed == cal.seed
    assert isinstance(res.warnings, tuple) and all(isinstance(w, str) for w in res.warnings)
    d = res.as_dict()
    for key in ("method", "model", "alpha_rad", "beta_rad", "gamma_rad", "scale", "offset_nT", "matrix",
                "rms_before_nT", "rms_after_nT", "runtime_s", "n_evaluations", "seed", "warnings"):
        assert key in d, f"as_dict() lacks {key!r}"
    try:  # frozen
        res.fun = 0.0  # type: ignore[misc]
    except Exception:
        pass
    else:
        raise AssertionError("CalibrationResult must be immutable")


def check_not_worse_than_start(calibrator, model):
    """Never worse than no calibration, even with a tiny budget (scipy's test_no_increase)."""
    for overrides in ({}, {"budget": Budget(max_evaluations=5)}):
        cal = _instance(calibrator, model, **overrides)
        res = cal.fit(check_dataset(model))
        assert res.rms_after_nT <= res.rms_before_nT + 1e-9, \
            f"rms after {res.rms_after_nT} > before {res.rms_before_nT} with {overrides or 'defaults'}"


def check_budget_respected(calibrator, model):
    """An evaluation budget is never exceeded."""
    cal = _instance(calibrator, model, budget=Budget(max_evaluations=37))
    res = cal.fit(check_dataset(model))
    assert res.n_evaluations <= 37, f"{res.n_evaluations} evaluations with a budget of 37"


def check_refuses_bad_input(calibrator, model):
    """NaN rows, too few points and a missing reference are refused with an InputError."""
    cal = _instance(calibrator, model)
    data = check_dataset(model)
    raw = np.array(data.raw_nT)
    raw[3, 1] = np.nan
    cases = {
        "NaN row": replace(data, raw_nT=raw),
        "too few points": replace(data, raw_nT=data.raw_nT[:2], f_ref_nT=data.f_ref_nT[:2], t_s=None),
        "no reference": replace(data, f_ref_nT=None),
    }
    for what, bad in cases.items():
        try:
            cal.fit(bad)
        except InputError:
            continue
        raise AssertionError(f"{what}: fit did not refuse with InputError")


CHECKS = (check_hyperparameters, check_recovers_known_errors, check_deterministic, check_input_not_mutated,
          check_result_fields, check_not_worse_than_start, check_budget_respected, check_refuses_bad_input)


def iter_checks(calibrator, models=None):
    """Yield (id, check, model) for every check and every model the calibrator supports."""
    cls = calibrator if isinstance(calibrator, type) else type(calibrator)
    for model in models or cls.supported_models:
        for check in CHECKS:
            yield f"{cls.name}-{model}-{check.__name__}", check, model


def check_calibrator(calibrator, models=None) -> list[str]:
    """Run the whole battery; raise ``AssertionError`` naming the first failing check, else return
    the names of the checks passed."""
    passed = []
    for ident, check, model in iter_checks(calibrator, models):
        try:
            check(copy.deepcopy(calibrator) if not isinstance(calibrator, type) else calibrator, model)
        except AssertionError as exc:
            raise AssertionError(f"{ident}: {exc}") from exc
        passed.append(ident)
    return passed

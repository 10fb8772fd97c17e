"""Property tests (hypothesis): the error model's round trips and the canonical decomposition."""
import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from magbench.calibrators.core.objective import ScalarObjective, correction_matrices, correction_matrix_one
from magbench.simulate.sensor import ErrorParams, SensorModel

angle = st.floats(-0.1, 0.1)
scale = st.floats(0.8, 1.2)
offset = st.floats(-5000.0, 5000.0)
params_st = st.builds(lambda a, b, g, k, o: ErrorParams(a, b, g, k, o), angle, angle, angle,
                      st.tuples(scale, scale, scale), st.tuples(offset, offset, offset))
seeds = st.integers(0, 2**32 - 1)


def _fields(seed, n=20):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    return 50000.0 * v / np.linalg.norm(v, axis=1, keepdims=True)


@given(params_st, seeds)
def test_forward_then_correction_is_identity(params, seed):
    b = _fields(seed)
    raw = SensorModel(params).measure(b)
    np.testing.assert_allclose(params.correct(raw), b, atol=1e-6)


@given(params_st, seeds)
def test_axis_projection_model_is_corrected_in_magnitude_by_its_canonical_params(params, seed):
    b = _fields(seed)
    sensor = SensorModel(params, convention="axis_projection")
    corrected = sensor.true_correction().correct(sensor.measure(b))
    np.testing.assert_allclose(np.linalg.norm(corrected, axis=1), 50000.0, rtol=1e-10)


@given(params_st, seeds)
def test_canonical_decomposition_is_invariant_under_rotation(params, seed):
    q = Rotation.random(random_state=seed).as_matrix()
    back = ErrorParams.from_correction(q @ params.matrix, params.offset_nT)
    np.testing.assert_allclose(back.to_vector("nine"), params.to_vector("nine"), rtol=1e-9, atol=1e-11)


@given(params_st)
def test_vector_round_trip_and_batched_matrices(params):
    x = params.to_vector("nine")
    assert ErrorParams.from_vector(x, "nine") == params
    m, o = correction_matrices(np.vstack([x, x]), "nine")
    np.testing.assert_allclose(m[1], params.matrix, rtol=1e-12)
    np.testing.assert_allclose(o[0], params.offset_nT)


@given(params_st, seeds)
def test_objective_is_zero_at_the_truth_and_positive_elsewhere(params, seed):
    b = _fields(seed)
    raw = SensorModel(params).measure(b)
    obj = ScalarObjective(raw, 50000.0, "nine")
    x = params.to_vector("nine")
    other = x + np.r_[0.01, 0, 0, 0, 0, 0, 0, 0, 0]
    f = obj.values(np.vstack([x, other]))
    assert f[0] < 1e-12 * 50000.0**2 and f[1] > f[0]


@given(params_st, seeds, st.sampled_from(["offset", "diag", "angles", "nine"]))
def test_every_model_is_the_nine_vector_with_entries_held_fixed(params, seed, model):
    """A model's vector embeds into the nine-vector (the others neutral); the objective, its Jacobian and
    population values agree with the nine-parameter ones at the embedded point."""
    from magbench.simulate.sensor import FREE, embed

    x9 = params.to_vector("nine")
    x = x9[list(FREE[model])]
    embedded = ErrorParams.from_vector(x, model)
    assert embedded.fits_model(model) and np.array_equal(embedded.to_vector(model), x)
    raw = SensorModel(params).measure(_fields(seed))
    obj, nine = ScalarObjective(raw, 50000.0, model), ScalarObjective(raw, 50000.0, "nine")
    z = embed(x, model)
    np.testing.assert_allclose(obj.residuals(x), nine.residuals(z), rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(obj.jacobian(x), nine.jacobian(z)[:, list(FREE[model])], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(obj.values(np.vstack([x, x]), exact=False), nine.values(np.vstack([z, z]), exact=False),
                               rtol=1e-9, atol=1e-6)


@given(params_st, seeds, st.sampled_from(["offset", "diag"]))
def test_new_models_jacobian_matches_finite_differences(params, seed, model):
    from magbench.simulate.sensor import FREE

    raw = SensorModel(params).measure(_fields(seed))
    obj = ScalarObjective(raw, 50000.0, model)
    x = params.to_vector("nine")[list(FREE[model])]
    jac = obj.jacobian(x)
    for j in range(len(x)):
        h = 1e-6 * max(1.0, abs(x[j]))
        step = np.zeros(len(x))
        step[j] = h
        fd = (obj.residuals(x + step) - obj.residuals(x - step)) / (2 * h)
        np.testing.assert_allclose(jac[:, j], fd, rtol=1e-5, atol=1e-6 * 50000.0 / max(1.0, abs(x[j])))


@given(params_st, st.sampled_from(["offset", "diag", "angles", "nine"]),
       st.floats(-3.0, 3.0), st.floats(-2.0, 2.0))
def test_one_point_matrix_is_the_population_matrix_to_the_last_bit(params, model, wide, zero_scale):
    """``correction_matrix_one`` (the single-point path of NLopt, RANSAC, lsq's residuals and Jacobian)
    gives ``correction_matrices``' numbers bit for bit, also far outside the search box and at a zero scale
    (infinities and NaN in the same places); a control: a parameter 1e-6 off changes the matrix."""
    x = params.to_vector(model) * (1.0 + wide)
    if model in ("nine", "diag") and zero_scale > 1.0:
        x[3 if model == "nine" else 0] = 0.0
    with np.errstate(all="ignore"):
        mat, o = correction_matrix_one(x, model)
        mats, os_ = correction_matrices(x[None, :], model)
    assert np.array_equal(mat, mats[0], equal_nan=True) and np.array_equal(o, os_[0])
    if model != "offset" and np.isfinite(mat).all():
        y = x.copy()
        y[0] += 1e-6
        assert not np.array_equal(correction_matrix_one(y, model)[0], mat)

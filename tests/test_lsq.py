"""lsq reaches the Cramér-Rao bound; the foundation's done-when on sphere9 through the command line."""
import json

import numpy as np
import pytest

from magbench.benchmarks.cli import main
from magbench.calibrators import make
from magbench.calibrators.core.objective import ScalarObjective
from magbench.calibrators.fisher import crb_std
from magbench.simulate import simulate


def _normalized_angle_errors(seed):
    data = simulate("sphere9", seed)
    res = make("lsq", model="nine").fit(data)
    x_true = data.truth.params.to_vector("nine")
    sigma = crb_std(ScalarObjective(data.raw_nT, data.f_ref_nT, "nine"), x_true, noise_nT=2.0)
    return (res.x[:3] - x_true[:3]) / sigma[:3], sigma[:3]


def test_lsq_angle_errors_within_three_sigma_of_the_bound():
    z = np.array([_normalized_angle_errors(seed)[0] for seed in range(20)])
    assert np.all(np.abs(z) < 3.5), z
    assert np.mean(np.abs(z[:5]) < 3.0) == 1.0
    # efficiency: the spread of the errors matches the bound (chi-square, 60 draws)
    rms = np.sqrt(np.mean(z**2))
    assert 0.75 < rms < 1.3, rms


def test_bound_is_of_the_expected_order():
    _, sigma = _normalized_angle_errors(0)
    # 2 nT on 50000 nT over 300 directions: roughly 2 / 50000 / sqrt(300 / 15) ~ 9e-6 rad
    assert np.all((sigma > 3e-6) & (sigma < 2e-5)), sigma


def test_done_when_sphere9_through_the_command_line(tmp_path, capsys):
    csv = tmp_path / "s.csv"
    truth_file = tmp_path / "truth.json"
    assert main(["simulate", "--scenario", "sphere9", "--seed", "0", "--out", str(csv), "--truth",
                 str(truth_file)]) == 0
    capsys.readouterr()
    assert main(["calibrate", str(csv), "--method", "lsq", "--model", "nine", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    truth = json.loads(truth_file.read_text())
    for key in ("alpha_rad", "beta_rad", "gamma_rad"):
        assert abs(out[key] - truth[key]) < 3e-5, key
    np.testing.assert_allclose(out["scale"], truth["scale"], atol=5e-5)
    np.testing.assert_allclose(out["offset_nT"], truth["offset_nT"], atol=3.0)
    assert out["rms_after_nT"] < 2.2 < out["rms_before_nT"]


@pytest.mark.parametrize("seed", range(5))
def test_lsq_angles_on_lu2014(seed):
    data = simulate("lu2014", seed)
    res = make("lsq", model="angles").fit(data)
    np.testing.assert_allclose(res.x, data.truth.params.to_vector("angles"), atol=1e-4)
    assert res.rms_after_nT < 1.5 and res.rms_before_nT > 300

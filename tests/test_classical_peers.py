"""The classical scalar calibrations (twostep, merayo, sphere, sym) against lsq's optimum, the conformance
battery, and MATLAB magcal's documentation example (a general ellipsoid) with --field auto."""
import json

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from magbench.benchmarks.cli import main
from magbench.calibrators import available, check_calibrator, make
from magbench.simulate import simulate

PEERS = ("twostep", "merayo", "sphere", "sym")


def test_the_peers_are_registered_with_their_papers():
    cals = available()
    assert set(PEERS) <= set(cals)
    for name in PEERS:
        doc = cals[name].__module__
        assert doc.startswith("magbench.calibrators.methods.")
    import magbench.calibrators.methods.merayo as merayo
    import magbench.calibrators.methods.twostep as twostep

    assert "Alonso and Shuster (2002)" in twostep.__doc__ and "Merayo" in merayo.__doc__


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_nine_parameter_peers_reach_lsq_optimum_on_a_full_sphere(seed):
    data = simulate("sphere9", seed=seed)
    best = make("lsq", model="nine").fit(data).rms_after_nT
    for name in ("twostep", "merayo", "sym"):
        res = make(name).fit(data)
        assert res.accepted, (name, res.rejections)
        assert res.rms_after_nT <= 1.05 * best, (name, res.rms_after_nT, best)
    offset_best = make("lsq", model="offset").fit(data).rms_after_nT
    assert make("sphere").fit(data).rms_after_nT <= 1.05 * offset_best
    assert make("twostep", model="offset").fit(data).rms_after_nT <= 1.05 * offset_best


def test_negative_control_the_identity_is_far_from_the_optimum():
    """The 5 % criterion has teeth: no calibration at all is far outside it on these data."""
    data = simulate("sphere9", seed=1)
    res = make("lsq", model="nine").fit(data)
    assert res.rms_before_nT > 20 * res.rms_after_nT


def test_twostep_second_step_is_counted_and_charged():
    res = make("twostep").fit(simulate("sphere9", seed=4))
    assert res.n_jacobians >= 1 and res.n_evaluations == res.n_function_evaluations + 9 * res.n_jacobians


@pytest.mark.parametrize("name", PEERS)
def test_the_peers_pass_the_conformance_battery(name):
    check_calibrator(available()[name])


def magcal_example(path, seed=0, n=500, noise_uT=0.01):
    """MATLAB magcal's documentation example: readings on an ellipsoid of radii 30, 20 and 50 uT around
    (-50, 20, 100) uT, rotated; magcal reports expmfs = (30 * 20 * 50)^(1/3) = 31.0723 uT."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    rot = Rotation.from_euler("xyz", [20.0, -35.0, 50.0], degrees=True).as_matrix()
    d = (rot @ np.diag([30.0, 20.0, 50.0]) @ u.T).T + np.array([-50.0, 20.0, 100.0])
    d += noise_uT * rng.standard_normal(d.shape)
    pd.DataFrame(d, columns=["bx", "by", "bz"]).to_csv(path, index=False)


def test_magcal_documentation_example_with_sym_and_field_auto(tmp_path, capsys):
    path = tmp_path / "magcal.csv"
    magcal_example(path)
    assert main(["calibrate", str(path), "--units", "uT", "--method", "sym", "--field", "auto", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["accepted"] and out["reference"]["estimated"]
    assert round(out["extra"]["expmfs_nT"] / 1000.0, 2) == 31.07  # magcal: 31.0723
    assert abs(out["reference"]["median_nT"] / 1000.0 - 31.0723) < 5e-4
    # the corrected readings lie on the sphere of radius expmfs
    assert out["rms_after_nT"] < 0.05 * 1000.0
    # the relative gain of an estimated reference is no sign of wrong units: no mean-scale warning
    assert not any("mean scale factor" in w for w in out["warnings"])
    assert main(["calibrate", str(path), "--units", "uT", "--method", "sym", "--field", "auto"]) == 0
    err = capsys.readouterr().err
    assert "31.07" in err and "uT estimated from the readings" in err and "expmfs" in err


def test_a_fluxgate_model_names_the_physical_limit_it_exceeds(tmp_path, capsys):
    path = tmp_path / "magcal.csv"
    magcal_example(path)
    assert main(["calibrate", str(path), "--units", "uT", "--method", "ellipsoid", "--field", "auto"]) == 3
    err = capsys.readouterr().err
    assert "outside a fluxgate's physical range" in err and "limit" in err and "--method sym" in err

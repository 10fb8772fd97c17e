"""The effect registry (simulate.effects) is the single source of the effects: the simulator, `magbench list`
and the diagnosis's candidate effects all read it, and each class's fitted form inverts its forward model."""
import contextlib
import io
import json
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

from magbench.benchmarks.cli import main as cli
from magbench.benchmarks.diagnosis import candidate_effects, diagnose
from magbench.simulate.effects import (
    EFFECTS,
    Columns,
    Effect,
    effect_names,
    register_effect,
    unregister_effect,
)
from magbench.simulate.scenarios import get_scenario

sys.path.insert(0, str(Path(__file__).resolve().parent))
from effect_records import OFFSET_NT, sphere_record  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class ToyXDrift(Effect):
    """Toy: the x offset drifting linearly in time, raw_x += rate (t - t0)."""

    name: ClassVar[str] = "toy_x_drift"
    needs: ClassVar[tuple[str, ...]] = ("t",)
    fit_params: ClassVar[tuple[str, ...]] = ("rate_nT_per_s",)
    rate_nT_per_s: float = 0.3

    def readings(self, lin, ctx, rng):
        out = lin.copy()
        out[:, 0] += self.rate_nT_per_s * (ctx["t_s"] - ctx["t_s"].min())
        return out

    @classmethod
    def fit_readings(cls, u, e, d, norm):
        out = u.copy()
        out[:, 0] -= e[0] * (d.t_s - norm.t0_s)
        return out


@pytest.fixture
def toy():
    register_effect(ToyXDrift)
    try:
        yield ToyXDrift
    finally:
        unregister_effect(ToyXDrift.name)
    assert ToyXDrift.name not in EFFECTS


def _list_json() -> dict:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert cli(["list", "--json"]) == 0
    return json.loads(buf.getvalue())


def test_a_registered_effect_appears_everywhere_without_touching_another_file(toy):
    listed = {e["name"]: e for e in _list_json()["effects"]}
    assert listed[toy.name]["in_library"] and listed[toy.name]["needs"] == ["t"]
    assert toy.name in effect_names(in_library=True)

    data = get_scenario("tumble9q").with_effects(toy.name).build(4)  # the simulator switches it on by name
    drift = np.asarray(data.raw_nT) - data.truth.raw_without_effects_nT
    t = np.asarray(data.t_s)
    assert np.allclose(drift[:, 0], toy.rate_nT_per_s * (t - t.min())) and np.allclose(drift[:, 1:], 0.0)

    assert toy in candidate_effects("nine", Columns.of(data))
    result = diagnose(data, base="nine")
    assert result["verdict"] == toy.name, result["effects"][:2]
    assert result["winner_params"]["rate_nT_per_s"] == pytest.approx(toy.rate_nT_per_s, rel=0.05)


def test_the_toy_effect_is_gone_after_unregistering():
    assert "toy_x_drift" not in [e["name"] for e in _list_json()["effects"]]
    assert "toy_x_drift" not in effect_names()


def test_a_second_class_with_a_registered_name_is_refused():
    @dataclass(frozen=True)
    class Impostor(Effect):
        name: ClassVar[str] = "scale"

    with pytest.raises(ValueError, match="already registered"):
        register_effect(Impostor)
    assert EFFECTS["scale"] is not Impostor


def test_the_control_effect_stays_outside_the_library():
    ripple = EFFECTS["attitude_ripple"]
    assert not ripple.in_library and "attitude_ripple" not in effect_names(in_library=True)
    data = get_scenario("tumble9q").with_effects("attitude_ripple").build(0)
    assert ripple not in candidate_effects("nine", Columns.of(data))
    assert ripple not in candidate_effects("angles", Columns.of(data))


def test_library_names_follow_the_contract():
    assert set(effect_names(in_library=True)) >= {"scale", "offset", "temperature", "field_drift", "nonlinearity",
                                                   "outliers", "offset_drift", "lag"}


@pytest.mark.parametrize("name", ["temperature", "nonlinearity", "offset_drift"])
def test_the_fitted_form_undoes_the_forward_model(name):
    """Readings simulated with the effect's fitted parameters (``from_fit``), then corrected with its fitted
    form, give back the effect-free readings (to first order for the quadratic response)."""
    cls = EFFECTS[name]
    rng = np.random.default_rng(3)
    n = 200
    lin, d, norm, ctx = sphere_record(rng, n)
    o = OFFSET_NT
    forward = cls.random(rng, 1.0)
    raw = forward.readings(lin, ctx, rng)
    assert not np.allclose(raw, lin)
    dd = Columns(raw, d.f_ref_nT, d.t_s, d.temp_C)
    cls.prepare(dd, norm, np.zeros(n), (lin - o) / 50000.0)
    g, _ = cls.fit_columns(raw - o, dd, norm)
    scale_cols = np.einsum("ab,na->nab", np.eye(3), raw - o)
    g = np.concatenate([g, np.broadcast_to(np.eye(3), (n, 3, 3)), scale_cols], axis=2)  # offsets, scales: the base's
    e, *_ = np.linalg.lstsq(g.reshape(-1, g.shape[2]), (raw - lin).reshape(-1), rcond=None)
    undone = raw - g @ e
    assert np.sqrt(np.mean((undone - lin) ** 2)) < 0.05 * np.sqrt(np.mean((raw - lin) ** 2)) + 0.05


def test_no_dispatch_on_effect_names_outside_the_effect_classes():
    # ``scale`` and ``offset`` are also kinds of calibration parameter (CONTRACT section 1), compared as such
    names = "|".join(re.escape(n) for n in effect_names() if n not in ("scale", "offset"))
    pattern = re.compile(rf"""[!=]=\s*["']({names})["']|["']({names})["']\s*[!=]=""")
    offenders = []
    for path in REPO.rglob("*.py"):
        rel = path.relative_to(REPO)
        # the blind generator is written apart from the effect classes on purpose (its own parametrizations)
        skipped = (Path("simulate/effects.py"), Path("benchmarks/diagnosis/blind.py"))
        if rel.parts[0] in ("tests", ".git", "build", "dist", ".venv", ".ci-venv") or rel in skipped:
            continue
        offenders += [f"{rel}:{i}" for i, line in enumerate(path.read_text().splitlines(), 1) if pattern.search(line)]
    assert not offenders, offenders

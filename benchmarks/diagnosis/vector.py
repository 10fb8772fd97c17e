"""The diagnosis of a vector dataset (``magbench diagnose``, CONTRACT section 3):

1. calibrate with the base model (``angles`` or ``nine``) by ``lsq`` and localize the residual
   (``localize``);
2. estimate the noise floor without any model (``floor``);
3. add each applicable library effect in turn and score it on held-out folds (``scoring``);
4. give the verdict (``verdict``);
5. refit the winning effect on all the data and re-simulate it (``resimulate``).
"""
from __future__ import annotations

import numpy as np

from magbench.calibrators import make
from magbench.errors import InputError
from magbench.simulate.dataset import Dataset
from magbench.simulate.effects import EFFECTS, Columns, Normalization
from magbench.simulate.sensor import MODELS, PARAM_NAMES

from .floor import vector_floor
from .localize import localize
from .model import EffectModel
from .resimulate import resimulate
from .scoring import cross_validate, rms, score_vector_effects
from .verdict import verdict

DEFAULT_FOLDS = 5
MIN_POINTS_BEYOND_PARAMETERS = 10


class Diagnosis:
    """Runs the diagnosis of a vector dataset; ``run()`` returns the JSON-ready dict."""

    def __init__(self, data: Dataset, base: str = "nine", folds: int = DEFAULT_FOLDS, seed: int = 0):
        if base not in MODELS:
            raise InputError(f"unknown base model {base!r}: use angles or nine")
        if not data.has_reference:
            raise InputError("no reference magnitude: give an f_ref column, --field NT, --igrf ..., or '# field_nT:'")
        self.dataset, self.base, self.k, self.seed = data, base, folds, seed
        self.columns = Columns.of(data)
        self.norm = Normalization.of(self.columns)
        n, need = len(data), len(PARAM_NAMES[base]) + MIN_POINTS_BEYOND_PARAMETERS
        if n < need:
            raise InputError(f"{n} points are too few to diagnose with the {base} model (need at least {need})")

    def base_residual(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The ``lsq`` base calibration: its parameters, the scalar residual and the corrected field directions."""
        base_fit = make("lsq", model=self.base).fit(self.dataset)
        corrected = base_fit.correct(self.columns.raw_nT)
        r = np.linalg.norm(corrected, axis=1) - self.columns.f_ref_nT
        return base_fit.x, r, corrected / np.linalg.norm(corrected, axis=1, keepdims=True)

    def heldout_base(self, base_x: np.ndarray):
        """Held-out residuals of the base model alone (``scoring.HeldOut``)."""
        return cross_validate(self.base, None, self.columns, self.norm, base_x, self.k, self.seed)

    def run(self) -> dict:
        d = self.columns
        base_x, r_all, unit = self.base_residual()
        floor = vector_floor(unit, d, r_all)
        base_cv = self.heldout_base(base_x)
        effects = score_vector_effects(self.base, d, base_x, base_cv, floor, self.k, self.seed)
        n = len(r_all)
        result = verdict(effects, base_cv.rms_nT, floor, n)
        out = {"kind": "vector", "base_model": self.base, "n_points": n, "rms_fit_nT": rms(r_all),
               "rms_base_nT": base_cv.rms_nT, "noise_floor_nT": floor, "verdict": result, "effects": effects,
               "folds": self.k, "seed": self.seed,
               "localization": localize(r_all, unit, d, self.dataset.heading_deg, self.k, self.seed),
               "base_params": dict(zip(PARAM_NAMES[self.base], map(float, base_x)))}
        if any(e["name"] == result for e in effects):
            out.update(self.winner(result, base_x, floor, r_all, unit))
        return out

    def winner(self, name: str, base_x: np.ndarray, floor: float, r_obs: np.ndarray, unit: np.ndarray) -> dict:
        """The winning effect refitted on all the data, and its re-simulation."""
        model = EffectModel(self.base, EFFECTS[name], self.norm)
        x = model.effect.fit_model(model, self.columns, model.x0(base_x))
        return {"winner_params": dict(zip(model.names, map(float, x))),
                "resimulation": resimulate(model, x, self.columns, unit, self.dataset.heading_deg, floor, r_obs,
                                           self.seed)}

    def model_residuals(self, name: str, params: dict) -> np.ndarray:
        """The residual of base + effect ``name`` with the given (winner) parameters."""
        return EffectModel(self.base, EFFECTS[name], self.norm).residuals(np.array(list(params.values())), self.columns)

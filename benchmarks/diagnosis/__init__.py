"""The sim-to-real diagnosis (``magbench diagnose``, CONTRACT section 3): where the residual of a
calibration lies, which unmodelled effect causes it, and how far it shrinks once that effect is modelled.

The effects, forward and fitted, are the classes of the one registry ``magbench.simulate.effects``;
this package is the procedure, one concern per module:

* ``model``      the base correction plus one effect's fitted form, fitted by least squares;
* ``localize``   where the residual lies (attitude, time, temperature, distribution);
* ``floor``      the noise floor without any model;
* ``scoring``    cross-validated scoring of each candidate effect;
* ``verdict``    the verdict;
* ``resimulate`` the fitted effect re-simulated and compared with the observation;
* ``vector``     the procedure on a vector dataset (``Diagnosis``);
* ``scalar``     the procedure on a scalar turntable series (seed 000's Table 2);
* ``report``     the human table and the figure;
* ``blind``      the blind check's datasets.
"""
from __future__ import annotations

from magbench.simulate.dataset import ScalarSeries

from .blind import blind_dataset, blind_kinds
from .report import diagnosis_figure, diagnosis_text
from .scalar import diagnose_scalar
from .scoring import candidate_effects
from .vector import DEFAULT_FOLDS, Diagnosis

__all__ = ["Diagnosis", "blind_dataset", "blind_kinds", "candidate_effects", "diagnose", "diagnose_scalar",
           "diagnosis_figure", "diagnosis_text"]


def diagnose(data, base: str = "nine", folds: int = DEFAULT_FOLDS, seed: int = 0) -> dict:
    """Diagnose a vector ``Dataset`` or a scalar turntable ``ScalarSeries``."""
    if isinstance(data, ScalarSeries):
        return diagnose_scalar(data, folds=folds, seed=seed)
    return Diagnosis(data, base, folds, seed).run()

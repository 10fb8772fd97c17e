"""magbench: simulate tri-axial fluxgate magnetometers in the geomagnetic field and benchmark the
algorithms that calibrate them.

The main entry points, importable from here (loaded on first use, so that ``import magbench`` and the
``magbench`` command start fast):

* ``simulate(name, seed)``: a named scenario's ``Dataset`` with its ground truth (``magbench list``);
* ``read_csv(path, units="nT")``: a data file (docs/CONTRACT.md section 2) as a ``Dataset``;
* ``make(name, **hyperparameters)``: a registered calibrator; ``calibrate(data, method="lsq", ...)``: make
  one and fit it, returning an immutable ``CalibrationResult``;
* ``diagnose(data)``: the sim-to-real diagnosis (where the residual lies, which effect causes it);
* ``load_calibration(path)``: a saved calibration, to ``correct`` other readings.

One import namespace (docs/CONTRACT.md section 4): ``magbench.simulate`` (the forward model),
``magbench.calibrators`` (one interface, one counted objective, the registry and the conformance
battery) and ``magbench.benchmarks`` (the harness, the diagnosis and the ``magbench`` command).
The repository keeps these as its top-level folders ``simulate/``, ``calibrators/`` and
``benchmarks/``; ``pyproject.toml`` maps them under this package.

>>> import magbench
>>> data = magbench.simulate("sphere9", seed=1)                      # doctest: +SKIP
>>> result = magbench.calibrate(data, method="lsq", model="nine")    # doctest: +SKIP
>>> result.params.alpha_rad, result.rms_after_nT, result.accepted    # doctest: +SKIP
"""
from __future__ import annotations

import importlib

__version__ = "0.3.0"

_LAZY = {"simulate": ("magbench.simulate", None),  # the package, callable: simulate(name, seed)
         "read_csv": ("magbench.simulate.dataset", "read_csv"),
         "make": ("magbench.calibrators.registry", "make"),
         "diagnose": ("magbench.benchmarks.diagnosis", "diagnose"),
         "load_calibration": ("magbench.calibrators.artifacts", "load_calibration")}

__all__ = ["__version__", "calibrate", *_LAZY]


def calibrate(data, method: str = "lsq", *, f_ref_nT=None, field=None, units: str = "nT", **hyperparameters):
    """Calibrate ``data`` (a ``Dataset``, an (N, 3) array or a DataFrame) with the registered ``method`` and
    its hyper-parameters (``model="nine"``, ``budget=1000``, ``seed=...``); the reference as in
    ``Calibrator.fit``.  Returns the immutable ``CalibrationResult``."""
    make = __getattr__("make")
    return make(method, **hyperparameters).fit(data, f_ref_nT=f_ref_nT, field=field, units=units)


def __getattr__(name: str):
    """PEP 562: the entry points are imported on first use."""
    if name in _LAZY:
        module, attr = _LAZY[name]
        value = importlib.import_module(module)
        value = value if attr is None else getattr(value, attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'magbench' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))

"""magbench's forward model: field, attitudes, fluxgate errors, datasets and named scenarios.

The names below are loaded on first use (PEP 562), so that importing one light module (the error model,
the dataset reader) does not import the attitude schedules and SciPy's spatial package with it."""
import sys
from importlib import import_module
from types import ModuleType

_EXPORTS = {
    "attitude": ("Attitudes", "cap", "full_sphere", "tumble", "turntable", "vehicle"),
    "dataset": ("Dataset", "InputError", "ScalarSeries", "Truth", "read_csv", "write_truth"),
    "field": ("ConstantField", "VaryingField", "igrf_field"),
    "scenarios": ("Scenario", "get_scenario", "register_scenario", "scenario_names", "simulate"),
    "sensor": ("MODELS", "PARAM_NAMES", "ErrorParams", "SensorModel", "paper_matrix"),
}
_MODULE_OF = {name: module for module, names in _EXPORTS.items() for name in names}

__all__ = [name for names in _EXPORTS.values() for name in names]


def __getattr__(name: str):
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))


class _CallablePackage(ModuleType):
    """This package is also the entry point ``magbench.simulate(name, seed)`` (``scenarios.simulate``), so
    that ``import magbench; magbench.simulate("sphere9", seed=1)`` works beside ``magbench.simulate.X``."""

    def __call__(self, name: str, seed: int = 0):
        """The named scenario's ``Dataset`` with its ground truth (``magbench list`` names them)."""
        return self.simulate(name, seed)


sys.modules[__name__].__class__ = _CallablePackage

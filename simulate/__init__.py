"""magbench's forward model: field, attitudes, fluxgate errors, datasets and named scenarios.

The names below are loaded on first use (PEP 562), so that importing one light module (the error model,
the dataset reader) does not import the attitude schedules and SciPy's spatial package with it."""
from importlib import import_module

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

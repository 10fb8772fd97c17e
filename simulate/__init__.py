"""magbench's forward model: field, attitudes, fluxgate errors, datasets and named scenarios."""
from .attitude import Attitudes, cap, full_sphere, tumble, turntable, vehicle
from .dataset import Dataset, InputError, ScalarSeries, Truth, read_csv, write_truth
from .field import ConstantField, VaryingField, igrf_field
from .scenarios import Scenario, get_scenario, register_scenario, scenario_names, simulate
from .sensor import MODELS, PARAM_NAMES, ErrorParams, SensorModel, paper_matrix

__all__ = [
    "Attitudes", "cap", "full_sphere", "tumble", "turntable", "vehicle",
    "Dataset", "InputError", "ScalarSeries", "Truth", "read_csv", "write_truth",
    "ConstantField", "VaryingField", "igrf_field",
    "Scenario", "get_scenario", "register_scenario", "scenario_names", "simulate",
    "MODELS", "PARAM_NAMES", "ErrorParams", "SensorModel", "paper_matrix",
]

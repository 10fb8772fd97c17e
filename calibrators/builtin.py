"""Importing this module registers the built-in calibrators."""
from . import aco, cmaes, de, ellipsoid, genetic, lsq, nloptcal, ransac, tls  # noqa: F401

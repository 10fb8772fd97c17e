"""Importing this module registers the built-in calibrators."""
from . import aco, ellipsoid, genetic, lsq, nloptcal, ransac, tls  # noqa: F401

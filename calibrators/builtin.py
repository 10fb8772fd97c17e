"""Importing this module registers the built-in calibrators."""
from . import ellipsoid, lsq  # noqa: F401

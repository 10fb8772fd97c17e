"""The calibration methods: each module registers its calibrators with ``@register`` when imported.
Importing this package registers every built-in method."""
from . import aco, cmaes, de, ellipsoid, genetic, lsq, nloptcal, ransac, tls  # noqa: F401

"""The calibration methods: each module registers its calibrators with ``@register`` when imported.
Importing this package registers every built-in method."""
from . import aco, cmaes, de, ellipsoid, genetic, lsq, merayo, nloptcal, ransac, sphere, sym, tls, twostep  # noqa: F401

"""The built-in calibration methods, one module per method family.  ``BUILTINS`` lists their classes;
``calibrators.registry`` registers them (methods do not import the registry, so the layers stay acyclic)."""
from .aco import AntColony
from .cmaes import CMAES
from .de import DifferentialEvolution
from .ellipsoid import EllipsoidFit
from .genetic import AdaptiveGA, AdaptiveGAPolished, ElitistRealGA, RealGA
from .lsq import LeastSquares
from .merayo import Merayo
from .nloptcal import NLoptCalibrator
from .ransac import RansacEllipsoid
from .sphere import SphereFit
from .sym import SymmetricEllipsoid
from .tls import TotalLeastSquares, TruncatedTLS
from .twostep import TwoStep

BUILTINS = (AntColony, CMAES, DifferentialEvolution, EllipsoidFit, AdaptiveGA, AdaptiveGAPolished, RealGA, ElitistRealGA,
            LeastSquares, Merayo, NLoptCalibrator, RansacEllipsoid, SphereFit, SymmetricEllipsoid, TotalLeastSquares,
            TruncatedTLS, TwoStep)

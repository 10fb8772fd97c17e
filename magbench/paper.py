"""Constants of seed 000 (Lu et al. 2014, the adaptive-GA paper), defined once for the whole project."""
import math

TABLE1_ANGLES_RAD = {"alpha_rad": 0.0163, "beta_rad": -0.0139, "gamma_rad": 0.0131}
"""Table 1: the non-orthogonality angles the paper's AGA estimated for its fluxgate."""

ANGLE_RANGE_RAD = 0.1
"""Section 2.2, step 1: every angle is searched over -0.1 .. 0.1 rad."""

BITS_PER_PARAMETER = 10
"""Section 2.2, step 1: 10-bit binary coding of each parameter."""

RESOLUTION_RAD = 2 * ANGLE_RANGE_RAD / (2**BITS_PER_PARAMETER - 1)
"""Eq. 6: the coding step of the 10-bit grid over the angle range."""

POPULATION = 80
"""Section 2.2, step 1: population size M."""

ARCSEC_PER_RAD = 180.0 * 3600.0 / math.pi
"""Arc-seconds per radian (the paper's tables give angles in arc-seconds)."""

F_XIAN_NT = 51978.74
"""Section 3: the total field of the experiment site (Xi'an, 2013) in nT."""

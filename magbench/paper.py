"""Constants of the seed papers, defined once for the whole project: seed 000 (Lu et al. 2014, the
adaptive-GA paper) and the record settings of seed 001's gradiometer experiment."""
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

# Seed 001 (gradiometer calibration by GA): the simulated record's settings
GRADIOMETER_NOISE_NT = 1.1
"""White noise per axis of each sensor, nT (ours; the paper neglects noise and gives no level).  Chosen so
that the gradient residual after the GA lands at the paper's 1.85 nT on average over seeds: a perfect
calibration leaves sqrt(2) x 1.1 = 1.56 nT (both sensors' noise), and fitting each row on only 12 noisy
attitudes (point (3) of section 3) adds about 15 % on the rest of the record (3 effective unknowns per row
on 12 equations: sqrt(1 + 3/9)).  The paper's headline is therefore mostly a noise floor, not a property of
the GA; for a Mag-03MS (a few pT/sqrt(Hz)) 1.1 nT stands for the acquisition chain and the environment."""

GRADIOMETER_FLUCTUATION_NT = 200.0
"""Seed 001: largest deviation of the ambient field in time ( Fig. 2 and Fig. 6: up to 200 nT)."""

GRADIOMETER_POINTS = 400
"""Attitudes in a simulated record (ours)."""

GRADIOMETER_DURATION_S = 600.0
"""Length of a simulated record, s (ours)."""

GRADIOMETER_MIN_POINTS = 20
"""Fewest attitudes a record may have (the ellipsoid fits need 9, the GAs 12 distinct ones)."""

"""Effects that simple calibration models leave out: one class per effect, one registry (``EFFECTS``).

Names follow CONTRACT section 3: ``scale``, ``offset`` (relative to the ``angles`` model),
``temperature`` (offset, scale and the axes' alignment drifting with temperature, optionally through a
first-order thermal lag), ``field_drift`` (the ambient field changing in time, unseen by the reference), ``nonlinearity``
(per-axis quadratic and cubic response), ``outliers`` (sparse spikes, seed 003), ``offset_drift``
(offsets changing slowly in time, independent of temperature) and ``lag`` (a time shift between each
axis and the reference).  ``attitude_ripple`` is deliberately *outside* the library (``in_library =
False``: a high-order attitude-dependent error no library model can represent); the diagnosis must not
claim it.

Each class carries both sides of its effect:

* the **forward model** the simulator applies (``simulate.scenarios``), one hook per stage of

      field (NED, time) -> attitude -> linear sensor (K P^-1 B + o) -> effect on readings -> noise -> spikes

  (``field``, ``temperature``, ``readings``, ``spikes``; each returns its input unchanged by default);

* the **fitted form** the sim-to-real diagnosis adds to a base correction (``angles`` or ``nine``,
  CONTRACT section 1; ``benchmarks.diagnosis``).  Every library form is *linear* in its parameters e
  (measured from ``fit_start``), given as design columns computed from the data:

      v = raw - o - sum_k G_k e_k                      G: (n, 3, p) from ``fit_columns``
      r = |P(alpha, beta, gamma) K^-1 v| - F - H e      H: (n, p)    from ``fit_columns``

  so the extended fit has an analytic Jacobian (``-b^T M G`` and ``-H``, b the unit corrected field).
  ``scale`` and ``offset`` instead free the K and o entries of the base correction (``base_part``).
  A plug-in effect may give the older non-linear hooks ``fit_readings`` / ``fit_residual`` only; its
  columns are then their finite-difference derivatives at the start values.

  Data-derived inputs a form needs (the lagged temperature, the time derivative of the readings) are
  computed once on the whole record by ``prepare`` and kept in ``Columns.extra``.

Adding an effect is one new class decorated with ``@register_effect`` in this file (or in a plug-in):
the simulator (``Scenario.with_effects``), ``magbench list`` and the diagnosis's candidate effects all
read the registry.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import ClassVar

import numpy as np
from numpy.polynomial import legendre

from magbench.errors import InputError
from magbench.lightstats import f_sf
from magbench.numerics import MAD_TO_SIGMA, robust_sigma, systematic_rows  # noqa: F401  (re-exported)

from .field import ConstantField, VaryingField

PPM = 1e-6
SPIKE_SIGMA = 5.0
"""A sample further than this many robust sigmas (MAD) from the median residual is a spike (seed 003)."""
MIN_TEMPERATURE_SPAN_C = 1.0
"""Least temperature range (max - min) that makes a temperature effect identifiable."""
CLIP_MIN_REPEATS = 3
"""An axis is clipped when its largest (or smallest) reading occurs at least this many times exactly."""
HOLD_ANGLE_RAD = 0.005
"""Consecutive samples (in time) whose field directions differ by less than this belong to one hold."""
HOLD_MIN_SAMPLES = 10
HOLD_SHARE = 0.8
"""A record is one of held attitudes when at least this share of its samples lie in holds of at least
HOLD_MIN_SAMPLES samples."""
MIN_SPAN_S = 1e-9
"""Least time span used as a divisor (a record at one instant)."""
FD_STEP = 1e-3
"""Finite-difference step of the columns of a plug-in's non-linear fitted form."""


def first_order_lag(t_s: np.ndarray, x: np.ndarray, tau_s: float) -> np.ndarray:
    """x seen through a first-order lag of time constant ``tau_s`` (exact for piecewise-constant x between
    samples), in time order; x itself when tau_s == 0, and for tau_s < 0 the lag undone (``first_order_lead``)."""
    if tau_s < 0:
        return first_order_lead(t_s, x, -tau_s)
    if tau_s == 0:
        return np.asarray(x, dtype=float).copy()
    from scipy.signal import lfilter

    order = np.argsort(t_s, kind="stable")
    ts, xs = t_s[order], np.asarray(x, dtype=float)[order]
    dt = np.diff(ts)
    out = np.empty_like(xs)
    if len(dt) and np.allclose(dt, dt.mean(), rtol=1e-6, atol=0):  # uniform sampling: one IIR filter
        a = 1.0 - np.exp(-dt.mean() / tau_s)
        out[:], _ = lfilter([a], [1.0, -(1.0 - a)], xs, zi=[(1.0 - a) * xs[0]])
    else:
        out[:] = _lag_recurrence(1.0 - np.exp(-dt / tau_s), xs)
    res = np.empty_like(out)
    res[order] = out
    return res


def _lag_recurrence(a: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """``out[0] = xs[0]``, ``out[i] = out[i-1] + a[i-1] (xs[i] - out[i-1])`` (the first-order lag on irregular
    times; each column of a 2-D ``xs`` alone).  A recurrence, so a loop, over Python floats: the same IEEE
    operations in the same order as on numpy scalars, several times faster."""
    if xs.ndim > 1:
        return np.stack([_lag_recurrence(a, xs[:, j]) for j in range(xs.shape[1])], axis=1) if xs.shape[1] else xs.copy()
    if not len(xs):
        return xs.copy()
    steps, values = a.tolist(), xs.tolist()
    prev = values[0]
    out = [prev]
    append = out.append
    for ai, xi in zip(steps, values[1:]):
        prev = prev + ai * (xi - prev)
        append(prev)
    return np.array(out, dtype=float)


LEAD_SMOOTHING_OF_TAU = 0.25
"""``first_order_lead`` differentiates x smoothed both ways (zero phase) by a first-order lag of this share of its time
constant: a logged temperature comes in steps of its resolution (1/16 degC), whose differences are spikes."""


def first_order_lead(t_s: np.ndarray, x: np.ndarray, tau_s: float) -> np.ndarray:
    """The input of a first-order lag of time constant ``tau_s`` whose output is x: x + tau_s dx/dt (the inverse
    of ``first_order_lag``), the derivative taken on x smoothed forward and backward by a lag of
    LEAD_SMOOTHING_OF_TAU tau_s.  A thermometer that lags the sensor it sits beside (its own thermal mass, or a
    place the heat reaches later) logs the lagged temperature; the sensor's is this."""
    xs = np.asarray(x, dtype=float)
    if tau_s <= 0 or len(xs) < 3 or np.ptp(t_s) <= 0:
        return xs.copy()
    order = np.argsort(t_s, kind="stable")
    ts = np.asarray(t_s, dtype=float)[order]
    smooth_tau = LEAD_SMOOTHING_OF_TAU * tau_s
    forward = first_order_lag(ts, xs[order], smooth_tau)
    both = first_order_lag(ts[-1] + ts[0] - ts[::-1], forward[::-1], smooth_tau)[::-1]
    keep = np.r_[True, np.diff(ts) > 0]  # repeated time stamps: one derivative for them
    rate = np.interp(ts, ts[keep], np.gradient(both[keep], ts[keep])) if keep.sum() >= 2 else np.zeros_like(ts)
    out = np.empty_like(xs)
    out[order] = xs[order] + tau_s * rate
    return out


def base_freedom_columns(unit: np.ndarray, f0_nT: float = 1.0) -> np.ndarray:
    """The first-order freedom of the base correction: ten columns, one a row of ``unit`` (the field's unit
    direction u, n x 3), that a refit of the base correction's offsets, scales and angles takes in the magnitude
    residual, to first order: 1, f0 u_i u_j for i >= j ((x, x), (y, x), (y, y), (z, x), (z, y), (z, z): the scales and
    the angles between the axes, a symmetric form of u, times the field ``f0_nT``) and u_x, u_y, u_z (the offsets).
    What these columns fit, the base correction absorbs when it is fitted again beside an effect, so an effect's
    test (and a signature) is made beside them: only the part of it orthogonal to them is its own.  ``f0_nT`` scales
    the six product columns (to nT per unit of a scale or angle); it changes no span.  For a unit u the squares sum
    to the first column, so the ten span nine dimensions."""
    scaled = unit * f0_nT
    products = [unit[:, i] * scaled[:, j] for i in range(3) for j in range(i + 1)]
    return np.column_stack([np.ones(len(unit))] + products + [unit[:, j] for j in range(3)])


def _lstsq_sse(x: np.ndarray, y: np.ndarray) -> float:
    """Residual sum of squares of the least-squares fit of y on the columns of x (column-scaled normal
    equations above 100,000 rows, a QR-free solve that keeps memory at the size of x)."""
    if len(x) > 100_000:
        sc = np.sqrt(np.clip(np.einsum("nk,nk->k", x, x), 1e-300, None))
        xs = x / sc
        coef = np.linalg.lstsq(xs.T @ xs, xs.T @ y, rcond=1e-12)[0] / sc
    else:
        coef = np.linalg.lstsq(x, y, rcond=None)[0]
    return float(np.sum((y - x @ coef) ** 2))


def clipped(raw_nT: np.ndarray) -> np.ndarray:
    """Samples whose reading on some axis sits exactly at that axis's largest or smallest value, where that value
    repeats at least CLIP_MIN_REPEATS times: an ADC or range limit (saturation)."""
    out = np.zeros(len(raw_nT), dtype=bool)
    for a in range(raw_nT.shape[1]):
        col = raw_nT[:, a]
        for edge in (col.max(), col.min()):
            at = col == edge
            if at.sum() >= CLIP_MIN_REPEATS:
                out |= at
    return out


def holds(t_s: np.ndarray | None, unit: np.ndarray) -> np.ndarray | None:
    """The hold of each sample (labels in the samples' order) when the record is one of held attitudes (at least
    HOLD_SHARE of the samples in runs of at least HOLD_MIN_SAMPLES whose consecutive directions differ by less
    than HOLD_ANGLE_RAD), else None."""
    n = len(unit)
    if t_s is None or n < 2 * HOLD_MIN_SAMPLES:
        return None
    order = np.argsort(t_s, kind="stable")
    u = unit[order]
    step = np.arccos(np.clip(np.einsum("ij,ij->i", u[1:], u[:-1]), -1.0, 1.0))
    seg = np.concatenate([[0], np.cumsum(step > HOLD_ANGLE_RAD)])
    sizes = np.bincount(seg)
    if np.sum(sizes[sizes >= HOLD_MIN_SAMPLES]) < HOLD_SHARE * n:
        return None
    label = np.empty(n, dtype=int)
    label[order] = seg
    return label


def f_test_p(sse_small: float, sse_big: float, extra: int, dof: float) -> float:
    """p-value of the F test that ``extra`` more columns (residual sum of squares ``sse_big`` with ``dof``
    degrees of freedom left, against ``sse_small`` without them) explain nothing."""
    if dof <= 0 or sse_big <= 0:
        return 1.0
    stat = max(sse_small - sse_big, 0.0) / extra / (sse_big / dof)
    return f_sf(stat, extra, dof)


def time_derivative(t_s: np.ndarray, x: np.ndarray) -> np.ndarray:
    """d x / d t along time order (central differences; x may be (n,) or (n, k))."""
    order = np.argsort(t_s, kind="stable")
    ts = t_s[order]
    xs = np.asarray(x, dtype=float)[order]
    if len(ts) < 3 or np.ptp(ts) <= 0:
        return np.zeros_like(xs)
    ts = ts + np.arange(len(ts)) * 1e-12 * max(np.ptp(ts), 1.0)  # repeated times: a tiny spacing
    with np.errstate(divide="ignore", invalid="ignore"):  # times at the float resolution (1e9 s + 1e-7 s steps) stay tied
        g = np.gradient(xs, ts, axis=0)
    out = np.empty_like(g)
    out[order] = g
    return out


def local_derivatives(t_s: np.ndarray, x: np.ndarray, half_window: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """(d x / d t, d^2 x / d t^2) at each sample from a least-squares quadratic in time through its
    2 * half_window nearest neighbours in time order (a shifted window at the ends), sample i itself left
    out so that its noise cannot leak into a design column fitted to its own residual.  On irregular
    sampling this is what keeps the derivative usable: a central difference across two samples a
    millisecond apart divides their noise by that millisecond.  x may be (n,) or (n, k)."""
    xs_in = np.asarray(x, dtype=float)
    flat = xs_in.ndim == 1
    xv = xs_in[:, None] if flat else xs_in
    n = len(t_s)
    w = 2 * half_window
    d1, d2 = np.zeros_like(xv), np.zeros_like(xv)
    if n > w and np.ptp(t_s) > 0:
        order = np.argsort(t_s, kind="stable")
        ts, xo = t_s[order].astype(float), xv[order]
        start = np.clip(np.arange(n) - half_window, 0, n - 1 - w)
        idx = start[:, None] + np.arange(w + 1)[None, :]
        idx = idx[idx != np.arange(n)[:, None]].reshape(n, w)  # every window holds i once: drop it
        # each window in its own time unit (its farthest neighbour at 1): a time far from the rest (a glitched
        # timestamp of 2e8 s among seconds) had made the windows around it singular in one global unit
        dt = ts[idx] - ts[:, None]
        scale = np.max(np.abs(dt), axis=1)
        scale[scale == 0] = 1.0
        dt /= scale[:, None]
        basis = np.stack([np.ones_like(dt), dt, 0.5 * dt**2], axis=2)  # (n, w, 3)
        a = np.einsum("nwi,nwj->nij", basis, basis) + 1e-9 * np.eye(3)
        b = np.einsum("nwi,nwk->nik", basis, xo[idx])
        coef = np.linalg.solve(a, b)  # (n, 3, k)
        d1[order], d2[order] = coef[:, 1] / scale[:, None], coef[:, 2] / scale[:, None] ** 2
    return (d1[:, 0], d2[:, 0]) if flat else (d1, d2)


MIN_GAP_OF_MEDIAN = 0.5
"""``central_derivative`` takes as neighbours the nearest samples at least this share of the median spacing
away, so that two samples a millisecond apart do not divide their noise by that millisecond."""


def central_derivative(t_s: np.ndarray, x: np.ndarray) -> np.ndarray:
    """d x / d t at each sample by the three-point central difference on irregular times (the exact
    derivative of the parabola through the neighbours and the sample: weights -h2 / (h1 (h1 + h2)),
    (h2 - h1) / (h1 h2), h1 / (h2 (h1 + h2)) with h1, h2 the gaps to the left and right neighbour; on even
    sampling the sample's own weight is 0).  Neighbours closer than MIN_GAP_OF_MEDIAN of the median
    spacing are passed over; one-sided differences at the ends.  x may be (n,) or (n, k).  On 0.3-0.4 s
    irregular sampling it leaves a pure lag's derivative about 5x closer than a quadratic fitted to six
    neighbours without the sample (tests/test_diagnosis_floor.py)."""
    xs_in = np.asarray(x, dtype=float)
    flat = xs_in.ndim == 1
    xv = xs_in[:, None] if flat else xs_in
    n = len(t_s)
    out = np.zeros_like(xv)
    if n < 3 or np.ptp(t_s) <= 0:
        return out[:, 0] if flat else out
    order = np.argsort(t_s, kind="stable")
    ts, xo = t_s[order].astype(float), xv[order]
    gap = MIN_GAP_OF_MEDIAN * float(np.median(np.diff(ts)) or np.ptp(ts) / n)
    i = np.arange(n)
    left = np.searchsorted(ts, ts - gap, side="right") - 1  # the last sample at least `gap` earlier
    right = np.searchsorted(ts, ts + gap, side="left")  # the first sample at least `gap` later
    left = np.where(left < 0, i, left)
    right = np.where(right > n - 1, i, right)
    h1 = (ts - ts[left])[:, None]
    h2 = (ts[right] - ts)[:, None]
    both = (h1 > 0) & (h2 > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        central = (-h2 / (h1 * (h1 + h2)) * xo[left] + (h2 - h1) / (h1 * h2) * xo
                   + h1 / (h2 * (h1 + h2)) * xo[right])
        forward = (xo[right] - xo) / h2
        backward = (xo - xo[left]) / h1
    d = np.where(both, central, np.where(h2 > 0, forward, np.where(h1 > 0, backward, 0.0)))
    out[order] = d
    return out[:, 0] if flat else out


# ---------------------------------------------------------------------------------------------- data
@dataclass(frozen=True)
class Column:
    """A data column an effect needs (CONTRACT section 2 name), the ``Columns`` field that holds it, and
    the least spread (max - min) that makes it informative (any spread at all when ``min_span`` is 0)."""

    csv: str
    field: str
    min_span: float = 0.0

    def informative(self, d: Columns) -> bool:
        values = getattr(d, self.field)
        if values is None:
            return False
        span = float(np.ptp(values))
        return span > 0 and span >= self.min_span


COLUMNS = {c.csv: c for c in (Column("t", "t_s"), Column("temp", "temp_C", MIN_TEMPERATURE_SPAN_C))}


@dataclass
class Columns:
    """The columns the fitted forms use (a subset of a Dataset, e.g. one cross-validation fold); ``extra``
    holds per-sample arrays derived from the whole record (``Effect.prepare``)."""

    raw_nT: np.ndarray
    f_ref_nT: np.ndarray
    t_s: np.ndarray | None = None
    temp_C: np.ndarray | None = None
    extra: dict = field(default_factory=dict)

    @classmethod
    def of(cls, data) -> Columns:
        """The columns of a ``Dataset`` as plain arrays."""
        opt = lambda v: None if v is None else np.asarray(v, dtype=float)  # noqa: E731
        return cls(np.asarray(data.raw_nT, dtype=float), np.asarray(data.f_ref_nT, dtype=float), opt(data.t_s),
                   opt(data.temp_C))

    def take(self, idx) -> Columns:
        opt = lambda v: None if v is None else v[idx]  # noqa: E731
        return Columns(self.raw_nT[idx], self.f_ref_nT[idx], opt(self.t_s), opt(self.temp_C),
                       {k: v[idx] for k, v in self.extra.items()})

    def __len__(self) -> int:
        return self.raw_nT.shape[0]


@dataclass(frozen=True)
class Normalization:
    """Fixed from the full record, so that every fold gives the effect parameters the same meaning: the
    median reference F0, the time origin and span, the mean temperature."""

    f0_nT: float
    t0_s: float | None = None
    t_span_s: float | None = None
    temp0_C: float | None = None

    @classmethod
    def of(cls, d: Columns) -> Normalization:
        t0 = span = temp0 = None
        if d.t_s is not None:
            t0, span = float(d.t_s.min()), max(float(np.ptp(d.t_s)), MIN_SPAN_S)
        if d.temp_C is not None:
            temp0 = float(np.mean(d.temp_C))
        return cls(float(np.median(d.f_ref_nT)), t0, span, temp0)

    def tau(self, t_s: np.ndarray) -> np.ndarray:
        """Time mapped onto [-1, 1] (the Legendre domain)."""
        return 2.0 * (t_s - self.t0_s) / self.t_span_s - 1.0  # type: ignore[operator]


# ---------------------------------------------------------------------------------------------- registry
EFFECTS: dict[str, type[Effect]] = {}
"""The one effect registry: name -> class, in registration order."""


def register_effect(cls: type[Effect]) -> type[Effect]:
    """Class decorator: add an effect under ``cls.name``; a second class with the same name is refused."""
    if not cls.name:
        raise ValueError(f"{cls.__name__} has no 'name'")
    if EFFECTS.get(cls.name, cls) is not cls:
        raise ValueError(f"an effect named {cls.name!r} is already registered ({EFFECTS[cls.name].__qualname__})")
    EFFECTS[cls.name] = cls
    return cls


def unregister_effect(name: str) -> None:
    EFFECTS.pop(name, None)


def get_effect(name: str) -> type[Effect]:
    try:
        return EFFECTS[name]
    except KeyError:
        raise InputError(f"unknown effect {name!r}; known: {', '.join(EFFECTS)}") from None


def effect_names(in_library: bool | None = None) -> tuple[str, ...]:
    """Registered effect names; only those in (or outside) the fitted library when ``in_library`` is given."""
    return tuple(n for n, cls in EFFECTS.items() if in_library is None or cls.in_library == in_library)


def library_effects() -> tuple[type[Effect], ...]:
    """The effects the diagnosis may fit and claim."""
    return tuple(cls for cls in EFFECTS.values() if cls.in_library)


def make_effect(name: str, **params) -> Effect:
    """An effect by name with its default parameters, or those given."""
    return get_effect(name)(**params)


def random_effect(name: str, rng: np.random.Generator, strength: float = 1.0) -> Effect:
    """An effect of the named kind with random parameters (signs and axes drawn), scaled by ``strength``."""
    return get_effect(name).random(rng, strength)


def _signed(rng: np.random.Generator, k: int) -> np.ndarray:
    """k random signs times magnitudes uniform in [0.5, 1)."""
    return rng.choice([-1.0, 1.0], size=k) * rng.uniform(0.5, 1.0, size=k)


def _per_axis(values: np.ndarray) -> np.ndarray:
    """(n, k) values -> (n, 3, 3k) columns: value j on each axis in turn (axis-major: x's k, y's k, z's k)."""
    n, k = values.shape
    g = np.zeros((n, 3, 3 * k))
    for a in range(3):
        g[:, a, a * k:(a + 1) * k] = values
    return g


# ---------------------------------------------------------------------------------------------- base class
@dataclass(frozen=True)
class Effect:
    """An unmodelled effect: its forward model (instance hooks) and its fitted form (class hooks)."""

    name: ClassVar[str] = ""
    in_library: ClassVar[bool] = True  # False: forward only, never fitted nor claimed by the diagnosis
    needs: ClassVar[tuple[str, ...]] = ()  # dataset columns (CONTRACT section 2 names) the fitted form needs
    optional: ClassVar[tuple[str, ...]] = ()  # columns used when present (e.g. t for the thermal lag)
    included_in: ClassVar[tuple[str, ...]] = ()  # base models that already contain the effect
    base_part: ClassVar[str | None] = None  # "scale" or "offset": the effect frees those base entries
    unseen_by_reference: ClassVar[bool] = False  # the simulated reference stays at its initial value
    robust: ClassVar[bool] = False  # True: the effect is a set of samples explained away (spikes)
    fit_params: ClassVar[tuple[str, ...]] = ()  # extra parameters of the fitted form
    heading_harmonics: ClassVar[tuple[int, ...]] = ()  # cycles per revolution on a level turntable
    prepare_leaves_out_base_spikes: ClassVar[bool] = False
    """True: ``prepare`` leaves out the base residual's own spikes (``OutlierEffect.spike_mask(r_base)``) beside the
    ``spikes`` it is given, so ``spikes`` among them change nothing it computes (the diagnosis then prepares it once)."""

    def as_dict(self) -> dict:
        return {"name": self.name, **{k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}}

    @classmethod
    def describe(cls) -> str:
        return " ".join((cls.__doc__ or "").split())

    @classmethod
    def random(cls, rng: np.random.Generator, strength: float = 1.0) -> Effect:
        """An instance with random parameters scaled by ``strength`` (default: the default parameters)."""
        return cls()

    # -- forward model (simulator) ---------------------------------------------------------------
    def field(self, b_ned: np.ndarray, t_s: np.ndarray, rng) -> np.ndarray:
        return b_ned

    def readings(self, lin: np.ndarray, ctx: dict, rng) -> np.ndarray:
        """Noise-free readings (n, 3) -> readings with the effect; ``ctx`` has t_s, temp_C, offset_nT, f_nT."""
        return lin

    def spikes(self, raw: np.ndarray, rng) -> np.ndarray:
        return raw

    def temperature(self, t_s: np.ndarray, rng) -> np.ndarray | None:
        return None

    # -- fitted form (diagnosis) -----------------------------------------------------------------
    @classmethod
    def applicable(cls, base: str, d: Columns) -> bool:
        """Fittable on these data with this base model: in the library, not already in the base model, and
        every needed column present with some spread."""
        return cls.in_library and base not in cls.included_in and all(COLUMNS[c].informative(d) for c in cls.needs)

    @classmethod
    def missing(cls, d: Columns) -> list[str]:
        """The needed columns absent or without spread."""
        return [c for c in cls.needs if not COLUMNS[c].informative(d)]

    @classmethod
    def fit_start(cls) -> np.ndarray:
        """Start values of ``fit_params`` (the effect absent)."""
        return np.zeros(len(cls.fit_params))

    @classmethod
    def prepare(cls, d: Columns, norm: Normalization, r_base: np.ndarray, unit: np.ndarray,
                spikes: np.ndarray | None = None) -> dict:
        """Derived inputs computed once on the whole record (stored in ``d.extra``) and what was chosen
        there (returned, e.g. a fitted time constant); ``spikes``: samples known to be spikes, to be left out."""
        return {}

    @classmethod
    def fit_readings(cls, u: np.ndarray, e: np.ndarray, d: Columns, norm: Normalization) -> np.ndarray:
        """Offset-free readings (n, 3) -> readings with the effect removed (plug-in hook)."""
        return u

    @classmethod
    def fit_residual(cls, r: np.ndarray, e: np.ndarray, d: Columns, norm: Normalization) -> np.ndarray:
        """The scalar residual |B| - F -> the residual with the effect's contribution removed (plug-in hook)."""
        return r

    @classmethod
    def fit_columns(cls, u0: np.ndarray, d: Columns, norm: Normalization):
        """(G, H): v = u - G e (G (n, 3, p) or None) and r -= H e (H (n, p) or None), e measured from
        ``fit_start``; ``u0`` = raw minus the base offset.  By default the finite-difference columns of
        ``fit_readings`` and ``fit_residual`` at the start values (exact for forms linear in e)."""
        p = len(cls.fit_params)
        if p == 0:
            return None, None
        e0 = cls.fit_start()
        v0 = cls.fit_readings(u0, e0, d, norm)
        z = np.zeros(len(u0))
        s0 = cls.fit_residual(z, e0, d, norm)
        g, h = np.zeros((len(u0), 3, p)), np.zeros((len(u0), p))
        for k in range(p):
            step = FD_STEP * max(1.0, abs(e0[k]))
            e = e0.copy()
            e[k] += step
            g[:, :, k] = -(cls.fit_readings(u0, e, d, norm) - v0) / step
            h[:, k] = -(cls.fit_residual(z, e, d, norm) - s0) / step
        return (g if np.any(g) else None), (h if np.any(h) else None)

    @classmethod
    def from_fit(cls, e: np.ndarray, norm: Normalization, info: dict | None = None) -> Effect | None:
        """The forward effect with the fitted parameters (else None)."""
        return None

    @classmethod
    def resim_reference(cls, f_ref_nT: np.ndarray, e: np.ndarray, d: Columns, norm: Normalization) -> np.ndarray:
        """The reference a re-simulation of the fitted effect uses."""
        return f_ref_nT

    @classmethod
    def scalar_columns(cls, heading_rad: np.ndarray, tau: np.ndarray) -> list[np.ndarray] | None:
        """Design columns of the effect's first-order signature in a turntable's scalar series (``tau``: the
        time order mapped onto [-1, 1]); None when a scalar series cannot show it."""
        if not cls.heading_harmonics:
            return None
        return [f(k * heading_rad) for k in cls.heading_harmonics for f in (np.cos, np.sin)]


# ---------------------------------------------------------------------------------------------- the library
@register_effect
@dataclass(frozen=True)
class ScaleEffect(Effect):
    """Per-axis scale factors on top of an angles-model sensor: raw_j = k_j lin_j (about the offset). Frees
    K of the base correction."""

    name: ClassVar[str] = "scale"
    included_in: ClassVar[tuple[str, ...]] = ("nine",)
    base_part: ClassVar[str | None] = "scale"
    fit_params: ClassVar[tuple[str, ...]] = ("kx", "ky", "kz")
    heading_harmonics: ClassVar[tuple[int, ...]] = (2,)  # scale mismatch (and gamma): two cycles per revolution
    RANDOM_SIZE: ClassVar[float] = 0.01
    scale: tuple[float, float, float] = (1.01, 0.99, 1.005)

    @classmethod
    def random(cls, rng, strength=1.0):
        return cls(tuple(1.0 + strength * cls.RANDOM_SIZE * _signed(rng, 3)))

    def readings(self, lin, ctx, rng):
        o = np.asarray(ctx["offset_nT"])
        return (lin - o) * np.asarray(self.scale) + o

    @classmethod
    def fit_start(cls):
        return np.ones(3)

    @classmethod
    def fit_readings(cls, u, e, d, norm):
        return u / e

    @classmethod
    def from_fit(cls, e, norm, info=None):
        return cls(tuple(float(v) for v in e))


@register_effect
@dataclass(frozen=True)
class OffsetEffect(Effect):
    """Per-axis offsets (hard iron, zero-point bias) on top of an angles-model sensor. Frees o of the base
    correction."""

    name: ClassVar[str] = "offset"
    included_in: ClassVar[tuple[str, ...]] = ("nine",)
    base_part: ClassVar[str | None] = "offset"
    fit_params: ClassVar[tuple[str, ...]] = ("ox_nT", "oy_nT", "oz_nT")
    heading_harmonics: ClassVar[tuple[int, ...]] = (1,)  # hard iron / zero offsets: one cycle per revolution
    RANDOM_SIZE_NT: ClassVar[float] = 150.0
    offset_nT: tuple[float, float, float] = (150.0, -100.0, 80.0)

    @classmethod
    def random(cls, rng, strength=1.0):
        return cls(tuple(strength * cls.RANDOM_SIZE_NT * _signed(rng, 3)))

    def readings(self, lin, ctx, rng):
        return lin + np.asarray(self.offset_nT)

    @classmethod
    def fit_readings(cls, u, e, d, norm):
        return u - e

    @classmethod
    def from_fit(cls, e, norm, info=None):
        return cls(tuple(float(v) for v in e))


@register_effect
@dataclass(frozen=True)
class TemperatureEffect(Effect):
    """Offset, scale and alignment drifting linearly with temperature, optionally through a first-order
    thermal lag (time constant fitted when t is present):
    raw_j = o_j + o_T,j dT + (lin_j - o_j) + dT (k_T,j (lin_j - o_j) + sum_{i != j} a_T,ij (lin_i - o_i)),
    dT the lagged temperature minus its mean, a_T symmetric.  The a_T are the temperature coefficients of the
    angles between the axes (a fluxgate's cores and windings expand with their mounts, so the axes' mutual
    angles, not only their gains, change with temperature); only the symmetric part shows in a magnitude, the
    antisymmetric part being a rotation of the whole triad."""

    name: ClassVar[str] = "temperature"
    needs: ClassVar[tuple[str, ...]] = ("temp",)
    prepare_leaves_out_base_spikes: ClassVar[bool] = True
    optional: ClassVar[tuple[str, ...]] = ("t",)
    fit_params: ClassVar[tuple[str, ...]] = ("oTx_nT_per_C", "oTy_nT_per_C", "oTz_nT_per_C",
                                             "kTx_ppm_per_C", "kTy_ppm_per_C", "kTz_ppm_per_C",
                                             "aTxy_urad_per_C", "aTxz_urad_per_C", "aTyz_urad_per_C")
    AXIS_PAIRS: ClassVar[tuple[tuple[int, int], ...]] = ((0, 1), (0, 2), (1, 2))
    """The axis pairs of the alignment coefficients a_T (x-y, x-z, y-z), in the order of ``fit_params``."""
    LAG_GRID_OF_SPAN: ClassVar[tuple[float, ...]] = (-0.03, -0.01, -0.003, 0.0, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0)
    """Thermal time constants tried, as shares of the record's time span (the best on the whole record).  Negative:
    the thermometer lags the sensor (``first_order_lead``), by up to a few percent of the span (a board thermometer
    beside the sensor head); positive: the sensor lags the thermometer (a core inside its housing)."""
    LEAD_P: ClassVar[float] = 1e-3
    """A lead (the thermometer lagging the sensor) is fitted only when it beats the best lag (0 included) by an F test
    of its one extra degree of freedom at this level, and lies inside the grid (below 0.9 of its largest lead, never refined
    beyond it): a lead adds the temperature's rate to its shape, a bump where it changes fastest, which fits part of
    any slow structure (a field switched on, a soft iron that lags) best with the largest lead it is offered (on the
    first independent generator's records, without a thermometer lag, the leads chosen sat at the bound; a grid to 0.1
    of the span named temperature for a field drift there with a lead of 0.07, and gained two records of the second).
    Measured alternatives, all run on the three generators' 11,040 records: a level of 1e-20 (the residual the time
    constant is chosen on still holds the other effects, so its F statistic is not from white noise) gave one more
    wrong name on the second generator (a temperature effect without its lead left structure a nonlinearity took),
    though it kept the own-simulator blind check's case 174 (a nonlinearity beside a temperature effect, a false lead
    at 3.5e-15, said with ``+unexplained`` at this level); the test made beside the alignment test's nuisance columns
    gave two more on the first."""
    LAG_REFINE_ROWS: ClassVar[int] = 200_000
    ALIGNMENT_P: ClassVar[float] = 1e-3
    """The alignment coefficients a_T are fitted only when they explain the base residual beside the offset and
    scale coefficients on the whole record (an F test of the three, at this level, in ``prepare``): a record
    whose attitudes are a few held positions, visited each at one temperature, gives them no leverage, and
    three free coefficients there only make the form extrapolate wildly to directions it did not see."""
    ALIGNMENT_ROWS: ClassVar[int] = 50_000
    """The alignment test uses a systematic sample of at most this many rows (at this size a coefficient that
    matters is far beyond the level)."""
    RAMP_RATE: ClassVar[float] = 3.0  # warm-up time constant: a third of the record
    RIPPLE_C: ClassVar[float] = 1.5
    RIPPLE_CYCLES: ClassVar[float] = 2.3
    RANDOM_OFFSET_NT_PER_C: ClassVar[float] = 3.0
    RANDOM_SCALE_PPM_PER_C: ClassVar[float] = 60.0
    offset_nT_per_C: tuple[float, float, float] = (3.0, -2.0, 2.5)
    scale_ppm_per_C: tuple[float, float, float] = (60.0, -40.0, 30.0)
    alignment_urad_per_C: tuple[float, float, float] = (0.0, 0.0, 0.0)
    start_C: float = 10.0
    end_C: float = 35.0
    ref_C: float = 20.0
    time_constant_s: float = 0.0

    @classmethod
    def random(cls, rng, strength=1.0):
        offset = tuple(strength * cls.RANDOM_OFFSET_NT_PER_C * _signed(rng, 3))
        return cls(offset, tuple(strength * cls.RANDOM_SCALE_PPM_PER_C * _signed(rng, 3)))

    def temperature(self, t_s, rng):
        u = (t_s - t_s.min()) / max(np.ptp(t_s), MIN_SPAN_S)
        a = self.RAMP_RATE
        ramp = self.start_C + (self.end_C - self.start_C) * (1 - np.exp(-a * u)) / (1 - np.exp(-a))
        return ramp + self.RIPPLE_C * np.sin(2 * np.pi * self.RIPPLE_CYCLES * u + rng.uniform(0, 2 * np.pi))

    def readings(self, lin, ctx, rng):
        temp = np.asarray(ctx["temp_C"], dtype=float)
        if self.time_constant_s != 0 and ctx.get("t_s") is not None:  # negative: the thermometer lags the sensor
            temp = first_order_lag(np.asarray(ctx["t_s"]), temp, self.time_constant_s)
        dt = (temp - self.ref_C)[:, None]
        o = np.asarray(ctx["offset_nT"])
        mix = np.diag(np.asarray(self.scale_ppm_per_C, dtype=float))
        for (i, j), a in zip(self.AXIS_PAIRS, self.alignment_urad_per_C):
            mix[i, j] = mix[j, i] = a
        return o + np.asarray(self.offset_nT_per_C) * dt + (lin - o) + PPM * dt * ((lin - o) @ mix.T)

    @classmethod
    def _columns_for(cls, u0, dtemp, alignment=True):
        """G of the fitted form (offset, scale, alignment coefficients); the alignment columns zero (no
        information: the fit leaves them at 0) when ``alignment`` is false."""
        g = np.zeros((len(u0), 3, len(cls.fit_params)))
        for a in range(3):
            g[:, a, a] = dtemp
            g[:, a, 3 + a] = PPM * dtemp * u0[:, a]
        if alignment:
            for k, (i, j) in enumerate(cls.AXIS_PAIRS):
                g[:, i, 6 + k] = PPM * dtemp * u0[:, j]
                g[:, j, 6 + k] = PPM * dtemp * u0[:, i]
        return g

    @classmethod
    def prepare(cls, d, norm, r_base, unit, spikes=None):
        """The thermal time constant that lets the temperature columns (projected on the field direction,
        beside the first-order freedom of the base correction) explain most of the base residual on the whole
        record, spikes left out: the best of LAG_GRID_OF_SPAN, refined between its neighbours by a bounded
        search on log(tau) (records up to LAG_REFINE_ROWS rows; a grid point alone leaves a remainder of
        several noise sigmas when the true constant falls between two).  Then whether the alignment
        coefficients are fitted (ALIGNMENT_P)."""
        keep = ~OutlierEffect.spike_mask(r_base)
        if spikes is not None:
            keep &= ~spikes
        timed = d.t_s is not None and np.ptp(d.t_s) > 0
        span = float(np.ptp(d.t_s)) if timed else 0.0
        u0 = unit[keep] * norm.f0_nT
        lin = base_freedom_columns(unit[keep], norm.f0_nT)
        r = r_base[keep]
        def thermal_lag(k: int) -> tuple[float, np.ndarray]:
            """The best share of the span and its lagged temperature, with the first k temperature columns: the
            best lag (share >= 0) unless a lead (share < 0) beats it by an F test at LEAD_P."""
            cache: dict[float, tuple[float, np.ndarray]] = {}

            def sse(share: float) -> float:
                if share not in cache:
                    temp = first_order_lag(d.t_s, d.temp_C, share * span) if share != 0 else d.temp_C
                    x = np.einsum("na,nak->nk", unit[keep], cls._columns_for(u0, temp[keep] - norm.temp0_C)[:, :, :k])
                    cache[share] = (_lstsq_sse(np.column_stack([x, lin]), r), temp)
                return cache[share][0]

            def best_of(sign: float) -> float:
                """The best share of one sign (0 included), refined on log|share| between its grid neighbours
                (beside 0: down to a third of the smallest)."""
                side = sorted(abs(g) for g in cls.LAG_GRID_OF_SPAN if g * sign > 0)
                scores = [sse(sign * g) for g in [0.0, *side]]
                j = int(np.argmin(scores))
                best = sign * ([0.0, *side][j])
                if len(d) <= cls.LAG_REFINE_ROWS:
                    from scipy.optimize import minimize_scalar

                    # the best is [0, *side][j]: between its neighbours on the grid, on the log of the share
                    lo = side[j - 2] if j > 1 else side[0] / 3.0
                    if j == 0:  # the best is 0: up to the smallest share
                        hi = side[0]
                    elif j < len(side):
                        hi = side[j]
                    else:  # the largest share: a lag may go beyond the grid, a lead never (LEAD_P)
                        hi = side[-1] * (3.0 if sign > 0 else 1.0)
                    opt = minimize_scalar(lambda v: sse(sign * float(np.exp(v))), bounds=(np.log(lo), np.log(hi)),
                                          method="bounded", options={"xatol": 0.02})
                    share = sign * float(np.exp(opt.x))
                    if sse(share) < scores[j] * (1 - 1e-9):
                        best = share
                return best

            if not timed:
                sse(0.0)
                return 0.0, cache[0.0][1]
            lag, lead = best_of(1.0), best_of(-1.0)
            dof = len(r) - k - lin.shape[1] - 1
            inside = lead > 0.9 * min(cls.LAG_GRID_OF_SPAN)  # a lead at the grid's end is a shape, not a lag
            best = lead if inside and dof > 0 and f_test_p(sse(lag), sse(lead), 1, dof) < cls.LEAD_P else lag
            return best, cache[best][1]

        best, temp = thermal_lag(6)  # offsets and scales
        # held attitudes (a few positions, each held while the temperature moves on): each direction is seen over one
        # stretch of temperature only, and a change of the alignment with temperature cannot be told from structure
        # tied to each hold that settles in time (an induced field relaxing after each move)
        held = timed and holds(d.t_s, unit) is not None
        p_align = 1.0 if held else cls._alignment_p(d, norm, unit, r_base, keep, temp, lin)
        aligned = bool(p_align < cls.ALIGNMENT_P)
        if aligned:  # the time constant again, with the alignment coefficients
            best, temp = thermal_lag(len(cls.fit_params))
        d.extra["temp_eff_C"] = temp
        d.extra["temp_alignment_on"] = np.full(len(d), float(aligned))
        return {"thermal_time_constant_s": best * span, "alignment_fitted": aligned, "alignment_p": p_align}

    @classmethod
    def _alignment_p(cls, d, norm, unit, r_base, keep, temp, lin) -> float:
        """p-value of the F test of the alignment coefficients (ALIGNMENT_P) on the rows ``keep`` (a systematic
        sample of at most ALIGNMENT_ROWS of them), the temperature ``temp`` (lagged) and the base freedom ``lin``.
        The coefficients must explain what a static response to the attitude cannot (the per-axis response up to
        the fifth order: a quadratic form that changes with temperature is also a cubic one when the attitude
        and the temperature change together), nor a slow change in time of the field or of the offsets, nor a
        time shift of the axes (on a turntable its error is a quadratic form of the field that changes with the
        tilt, and so with the time and the temperature): a temperature that follows time would otherwise lend
        them whatever those leave.  Readings at an axis's range limit are left out: a clipped reading says
        nothing of the sensor's response, and on a turntable the clipping comes and goes with the tilt."""
        rows = np.flatnonzero(keep)
        sub = np.flatnonzero(~clipped(d.raw_nT[rows]))
        sub = sub[systematic_rows(len(sub), cls.ALIGNMENT_ROWS)]
        rows = rows[sub]
        b = unit[rows]
        cols = [np.einsum("na,nak->nk", b, cls._columns_for(b * norm.f0_nT, temp[rows] - norm.temp0_C)), lin[sub]]
        cols += [b[:, a:a + 1] * term[:, a:a + 1] for term in NonlinearityEffect.basis(b) for a in range(3)]
        if d.t_s is not None and np.ptp(d.t_s) > 0:
            slow = legendre.legvander(norm.tau(d.t_s[rows]), FieldDriftEffect.DEGREE)[:, 1:]
            rate = central_derivative(d.t_s, d.raw_nT)[rows]
            cols += [slow, b[:, :, None] * slow[:, None, :OffsetDriftEffect.DEGREE]] + [b * rate]
        x = np.column_stack([c.reshape(len(rows), -1) for c in cols])
        sse_without = _lstsq_sse(np.delete(x, [6, 7, 8], axis=1), r_base[rows])  # without the alignment columns
        sse_with = _lstsq_sse(x, r_base[rows])
        return f_test_p(sse_without, sse_with, 3, len(rows) - x.shape[1])

    @classmethod
    def fit_columns(cls, u0, d, norm):
        temp = d.extra.get("temp_eff_C", d.temp_C)
        on = d.extra.get("temp_alignment_on")
        return cls._columns_for(u0, temp - norm.temp0_C, alignment=on is None or bool(np.any(on))), None

    @classmethod
    def from_fit(cls, e, norm, info=None):
        tau = float((info or {}).get("thermal_time_constant_s", 0.0))
        return cls(tuple(map(float, e[:3])), tuple(map(float, e[3:6])), tuple(map(float, e[6:9])), ref_C=norm.temp0_C,
                   time_constant_s=tau)


@register_effect
@dataclass(frozen=True)
class FieldDriftEffect(Effect):
    """The ambient field varies in time (Jin, Zhuang & Wang 2024: up to 200 nT) while the reference magnitude stays at its
    initial value; fitted as Legendre polynomials of time added to the reference."""

    name: ClassVar[str] = "field_drift"
    needs: ClassVar[tuple[str, ...]] = ("t",)
    unseen_by_reference: ClassVar[bool] = True
    DEGREE: ClassVar[int] = 12  # Legendre polynomials of the time in the fitted form
    SCALAR_DEGREE: ClassVar[int] = 3  # a cubic in time on a short turntable series
    fit_params: ClassVar[tuple[str, ...]] = tuple(f"drift_L{j}_nT" for j in range(1, DEGREE + 1))
    RANDOM_AMPLITUDE_NT: ClassVar[tuple[float, float]] = (40.0, 80.0)
    N_COMPONENTS: ClassVar[int] = 3
    amplitude_nT: float = 60.0
    min_period_s: float = 300.0
    max_period_s: float = 3000.0

    @classmethod
    def random(cls, rng, strength=1.0):
        return cls(amplitude_nT=strength * rng.uniform(*cls.RANDOM_AMPLITUDE_NT))

    def field(self, b_ned, t_s, rng):
        var = VaryingField(ConstantField(tuple(b_ned[0])), self.amplitude_nT, self.min_period_s, self.max_period_s,
                           self.N_COMPONENTS)
        return b_ned + var.variation(t_s, rng)

    @classmethod
    def drift_nT(cls, e, t_s, norm):
        """sum_j c_j L_j(tau): the field change seen in the magnitude, without the constant L_0."""
        return legendre.legvander(norm.tau(t_s), len(e))[:, 1:] @ e

    @classmethod
    def fit_columns(cls, u0, d, norm):
        return None, legendre.legvander(norm.tau(d.t_s), cls.DEGREE)[:, 1:]

    @classmethod
    def resim_reference(cls, f_ref_nT, e, d, norm):
        return f_ref_nT - cls.drift_nT(e, d.t_s, norm)

    @classmethod
    def scalar_columns(cls, heading_rad, tau):
        return list(legendre.legvander(tau, cls.SCALAR_DEGREE)[:, 1:].T)


@register_effect
@dataclass(frozen=True)
class NonlinearityEffect(Effect):
    """Per-axis quadratic, cubic and quintic response, x = (lin - o) / F:
    raw_j = lin_j + F (q_j P2(x_j) + c_j P3(x_j) + s_j P5(x_j)), with the Legendre polynomials
    P2 = x^2 - 1/3, P3 = x^3 - 3 x / 5, P5 = x^5 - 10 x^3 / 9 + 5 x / 21 (monic).  A component of a uniformly
    distributed direction is uniform on [-1, 1], so every term is orthogonal on the sphere to a constant, to
    x itself and to the others: the fitted form cannot absorb an offset, a scale or a change of field
    magnitude along the reading (a physical u^3 response is P3 plus a scale change).  The quintic is soft
    saturation's next order: tanh(s x) / s - x = -s^2 x^3 / 3 + 2 s^4 x^5 / 15 - ..., whose x^5 share is
    several noise sigmas at s >= 2 where a cubic alone leaves it as a remainder."""

    name: ClassVar[str] = "nonlinearity"
    fit_params: ClassVar[tuple[str, ...]] = ("qx", "qy", "qz", "cx", "cy", "cz", "sx", "sy", "sz")
    heading_harmonics: ClassVar[tuple[int, ...]] = (3, 4)  # quadratic: 1 and 3 cycles/rev; cubic: 2 and 4
    RANDOM_SIZE: ClassVar[float] = 1e-3
    quadratic: tuple[float, float, float] = (8e-4, -6e-4, 5e-4)
    cubic: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quintic: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @classmethod
    def random(cls, rng, strength=1.0):
        kind = rng.integers(3)  # quadratic, cubic or both
        q = strength * cls.RANDOM_SIZE * _signed(rng, 3) * (kind != 1)
        c = strength * cls.RANDOM_SIZE * _signed(rng, 3) * (kind != 0)
        return cls(tuple(q), tuple(c))

    @staticmethod
    def basis(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        x2 = x * x
        return x2 - 1.0 / 3.0, (x2 - 0.6) * x, ((x2 - 10.0 / 9.0) * x2 + 5.0 / 21.0) * x

    def readings(self, lin, ctx, rng):
        o = np.asarray(ctx["offset_nT"])
        f = float(ctx["f_nT"])
        q2, c3, s5 = self.basis((lin - o) / f)
        return lin + f * (np.asarray(self.quadratic) * q2 + np.asarray(self.cubic) * c3 + np.asarray(self.quintic) * s5)

    @classmethod
    def fit_columns(cls, u0, d, norm):
        terms = cls.basis(u0 / norm.f0_nT)
        g = np.zeros((len(u0), 3, 9))
        for a in range(3):
            for k, term in enumerate(terms):
                g[:, a, 3 * k + a] = norm.f0_nT * term[:, a]
        return g, None

    @classmethod
    def from_fit(cls, e, norm, info=None):
        return cls(tuple(map(float, e[:3])), tuple(map(float, e[3:6])), tuple(map(float, e[6:9])))


@register_effect
@dataclass(frozen=True)
class OffsetDriftEffect(Effect):
    """Offsets changing slowly in time, independent of temperature: o_j(t) = o_j + sum_l a_jl L_l(tau),
    Legendre polynomials of degree 1 to 3 of the time."""

    name: ClassVar[str] = "offset_drift"
    needs: ClassVar[tuple[str, ...]] = ("t",)
    DEGREE: ClassVar[int] = 3
    fit_params: ClassVar[tuple[str, ...]] = tuple(f"o{a}_L{j}_nT" for a in "xyz" for j in (1, 2, 3))
    RANDOM_SIZE_NT: ClassVar[float] = 20.0
    coefficients_nT: tuple = ((15.0, -6.0, 3.0), (-10.0, 4.0, 0.0), (8.0, 0.0, -4.0))

    @classmethod
    def random(cls, rng, strength=1.0):
        c = strength * cls.RANDOM_SIZE_NT * _signed(rng, 3 * cls.DEGREE) / np.tile(np.arange(1, cls.DEGREE + 1), 3)
        return cls(tuple(tuple(map(float, row)) for row in c.reshape(3, cls.DEGREE)))

    def as_dict(self):
        return {"name": self.name, "coefficients_nT": [list(r) for r in self.coefficients_nT]}

    @classmethod
    def _basis(cls, t_s, norm_tau):
        return legendre.legvander(norm_tau, cls.DEGREE)[:, 1:]

    def readings(self, lin, ctx, rng):
        t = np.asarray(ctx["t_s"], dtype=float)
        tau = 2.0 * (t - t.min()) / max(np.ptp(t), MIN_SPAN_S) - 1.0
        return lin + self._basis(t, tau) @ np.asarray(self.coefficients_nT, dtype=float).T

    @classmethod
    def fit_columns(cls, u0, d, norm):
        return _per_axis(cls._basis(d.t_s, norm.tau(d.t_s))), None

    @classmethod
    def from_fit(cls, e, norm, info=None):
        return cls(tuple(tuple(map(float, row)) for row in np.asarray(e).reshape(3, cls.DEGREE)))


@register_effect
@dataclass(frozen=True)
class LagEffect(Effect):
    """A time shift of each axis: axis j reads the field of time t - lag_j; fitted to first order,
    raw_j = lin_j - lag_j dlin_j/dt.

    The reference is not shifted in the fitted form (it was, with a term -lag_ref dF_ref/dt): a reference that
    changes (an observatory's or a model's field) changes by tens of nT over minutes, so a shift of a few samples
    moves it by hundredths of an nT, far below any noise floor, and a term large enough to be seen is a shift of
    10^5 to 10^7 samples, longer than the record: not a shift but a free function of time (the reference's
    derivative) that fits any slow structure, which beside ``field_drift``'s time basis named ``lag`` and
    ``field_drift`` for structure outside the library on the independent blind records.  The forward model never
    shifted the reference either.  A clock offset between the sensor and a changing reference is still fitted: the
    axes' common shift s changes the corrected magnitude by -s d|B|/dt, the reference's own change where it follows
    the field."""

    name: ClassVar[str] = "lag"
    needs: ClassVar[tuple[str, ...]] = ("t",)
    prepare_leaves_out_base_spikes: ClassVar[bool] = True
    fit_params: ClassVar[tuple[str, ...]] = ("lag_x_s", "lag_y_s", "lag_z_s", "lag2_x_s2", "lag2_y_s2", "lag2_z_s2")
    """lag_j and the second-order terms lag_j^2 (fitted freely, so the form stays linear): a shift of a
    smooth signal is x(t - s) = x - s x' + s^2 x'' / 2 + ..."""
    shift_terms: ClassVar[tuple[str, ...]] = ("lag_x_s", "lag_y_s", "lag_z_s")
    """The first-order terms: a time shift of less than a few samples is carried by them, the second-order
    terms only correct it (the naming rule asks for this signature)."""
    RANDOM_LAG_S: ClassVar[float] = 0.05
    lag_s: tuple[float, float, float] = (0.05, 0.0, -0.03)

    @classmethod
    def random(cls, rng, strength=1.0):
        return cls(tuple(strength * cls.RANDOM_LAG_S * _signed(rng, 3)))

    def readings(self, lin, ctx, rng):
        t = np.asarray(ctx["t_s"], dtype=float)
        order = np.argsort(t, kind="stable")
        out = lin.copy()
        for a in range(3):
            out[order, a] = np.interp(t[order] - self.lag_s[a], t[order], lin[order, a])
        return out

    @classmethod
    def prepare(cls, d, norm, r_base, unit, spikes=None):
        """The time derivative of the readings, with samples that are spikes (given, or in the base
        residual) replaced by the interpolation of their neighbours in time first (a spike would otherwise
        corrupt the derivative of the samples on either side of it)."""
        raw = d.raw_nT
        spikes = OutlierEffect.spike_mask(r_base) | (False if spikes is None else spikes)
        if spikes.any() and (~spikes).sum() >= 3:
            order = np.argsort(d.t_s, kind="stable")
            ts, good = d.t_s[order], ~spikes[order]
            raw = raw.copy()
            bad = order[~good]
            for a in range(3):
                raw[bad, a] = np.interp(d.t_s[bad], ts[good], d.raw_nT[order[good], a])
        d.extra["draw_dt"], d.extra["draw_dt2"] = central_derivative(d.t_s, raw), local_derivatives(d.t_s, raw)[1]
        return {}

    @classmethod
    def fit_columns(cls, u0, d, norm):
        if "draw_dt" not in d.extra:
            d.extra["draw_dt"] = central_derivative(d.t_s, d.raw_nT)
            d.extra["draw_dt2"] = local_derivatives(d.t_s, d.raw_nT)[1]
        du, du2 = d.extra["draw_dt"], d.extra["draw_dt2"]
        g = np.zeros((len(u0), 3, 6))
        for a in range(3):
            g[:, a, a] = -du[:, a]
            g[:, a, 3 + a] = 0.5 * du2[:, a]
        return g, None

    @classmethod
    def from_fit(cls, e, norm, info=None):
        return cls(tuple(map(float, e[:3])))


@register_effect
@dataclass(frozen=True)
class OutlierEffect(Effect):
    """Sparse spikes (Luo et al.: 10 % of the points with 500 nT noise): a fraction of the samples get large
    Gaussian errors on every axis; fitted by explaining away the samples beyond 5 robust sigma."""

    name: ClassVar[str] = "outliers"
    robust: ClassVar[bool] = True
    MIN_SPIKES: ClassVar[int] = 3  # spikes found on held-out data before the effect counts ...
    MIN_SPIKE_SHARE: ClassVar[float] = 0.005  # ... and at least this share of the samples
    RANDOM_FRACTION: ClassVar[tuple[float, float]] = (0.03, 0.08)
    RANDOM_AMPLITUDE_NT: ClassVar[tuple[float, float]] = (200.0, 500.0)
    fraction: float = 0.05
    amplitude_nT: float = 300.0

    @classmethod
    def random(cls, rng, strength=1.0):
        fraction = rng.uniform(*cls.RANDOM_FRACTION)
        return cls(fraction=fraction, amplitude_nT=strength * rng.uniform(*cls.RANDOM_AMPLITUDE_NT))

    def spikes(self, raw, rng):
        n = raw.shape[0]
        k = max(1, int(round(self.fraction * n)))
        idx = rng.choice(n, size=k, replace=False)
        out = raw.copy()
        out[idx] += rng.normal(0.0, self.amplitude_nT, size=(k, 3))
        return out

    @classmethod
    def spike_mask(cls, r: np.ndarray, scale: float | None = None) -> np.ndarray:
        s = robust_sigma(r) if scale is None else scale
        return np.abs(r - np.median(r)) > SPIKE_SIGMA * s

    @classmethod
    def enough(cls, n_flagged: int, n: int) -> bool:
        """More spikes beyond SPIKE_SIGMA than Gaussian noise would give."""
        return n_flagged >= max(cls.MIN_SPIKES, cls.MIN_SPIKE_SHARE * n)


# ---------------------------------------------------------------------------------------------- outside the library
@register_effect
@dataclass(frozen=True)
class AttitudeRipple(Effect):
    """Outside the library: an error of high angular order in the sensor frame,
    amplitude * cos(order * azimuth) * sin(order * elevation) along the field direction."""

    name: ClassVar[str] = "attitude_ripple"
    in_library: ClassVar[bool] = False
    RANDOM_AMPLITUDE_NT: ClassVar[tuple[float, float]] = (20.0, 35.0)
    RANDOM_ORDER: ClassVar[tuple[int, int]] = (4, 7)  # integers from 4 to 6
    amplitude_nT: float = 25.0
    order: int = 5

    @classmethod
    def random(cls, rng, strength=1.0):
        amplitude = strength * rng.uniform(*cls.RANDOM_AMPLITUDE_NT)
        return cls(amplitude_nT=amplitude, order=int(rng.integers(*cls.RANDOM_ORDER)))

    def readings(self, lin, ctx, rng):
        o = np.asarray(ctx["offset_nT"])
        u = lin - o
        unit = u / np.linalg.norm(u, axis=1, keepdims=True)
        az, el = np.arctan2(unit[:, 1], unit[:, 0]), np.arcsin(np.clip(unit[:, 2], -1, 1))
        ripple = self.amplitude_nT * np.cos(self.order * az) * np.sin(self.order * el)
        return lin + ripple[:, None] * unit

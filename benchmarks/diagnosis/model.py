"""The base correction (CONTRACT section 1, always written as the nine-vector: angles, scales, offsets)
extended by any set of library effects (``simulate.effects``), with an analytic Jacobian:

    v = raw - o - sum_k G_k e_k            (G from ``Effect.fit_columns``)
    r = |P(alpha, beta, gamma) K^-1 v| - F - sum_k H_k e_k

dr/dtheta = b^T (dM/dtheta) v for the angles and scales, dr/do = -b^T M, dr/de = -b^T M G - H, b the unit
corrected field.  ``scale`` and ``offset`` free the K and o entries (``Effect.base_part``).

The model with every applicable effect is fitted once on the whole record (Gauss-Newton on normal
equations accumulated block by block, spikes trimmed); every sub-model (the base alone, base plus some
effects) is then the linear model of the tangent space at that point, with the left-out parameters held
at their neutral values.  Its fits on K-1 folds and residuals on the fold left out come from per-fold
Gram matrices of [J, r], so forward selection costs no refits.
"""
from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre

from magbench.simulate.effects import (
    PPM,
    Columns,
    Effect,
    FieldDriftEffect,
    Normalization,
    OffsetDriftEffect,
    OutlierEffect,
    robust_sigma,
)
from magbench.simulate.sensor import NEUTRAL, PARAM_NAMES, paper_matrix

BLOCK_ROWS = 65536
GN_ITERATIONS = 12
GN_TOLERANCE = 1e-10
TRIM_ROUNDS = 8  # re-trim until the spike mask settles (heavy-tailed spikes come out in layers)
LM_RIDGE_STEPS = 12  # tenfold ridge increases tried per Levenberg-Marquardt step
TRIM_ITERATIONS = 4  # per trim round (the rounds continue from the last point)
TRIM_TOLERANCE = 1e-6  # the spike mask needs the fit to a millionth of its sum of squares, not to rounding
STORE_J_BYTES = 400e6  # keep the Jacobian in memory (float32) below this size, else recompute it per pass
FIT_ROWS = 200_000  # the Gauss-Newton fit of the tangent point uses at most this many rows (``fit_subset``)
FIT_SEED = 17
NINE_NAMES = ("alpha_rad", "beta_rad", "gamma_rad", "kx", "ky", "kz", "ox_nT", "oy_nT", "oz_nT")
BASE_FREE = {"angles": (0, 1, 2), "nine": tuple(range(9))}
PART_INDEX = {"scale": (3, 4, 5), "offset": (6, 7, 8)}
FIT_RIDGE = 1e-8  # relative ridge of the Gauss-Newton steps (near-degenerate directions stay put)
RIDGE = 1e-10  # relative ridge on the scaled normal equations (columns without information)
BASE_PRIOR_SD = {"angle": 0.05, "scale": 0.1}
"""Standard deviations of the weak prior on the base correction (``ExtendedModel.set_prior``): rad, and relative."""


TIME_BASES = (FieldDriftEffect, OffsetDriftEffect)
"""Effects whose fitted form is Legendre polynomials of time (degrees 1 to their ``DEGREE``), one series or one per
axis (the offsets)."""


def slope_penalty(degree: int) -> np.ndarray:
    """P[i, j] = integral over [-1, 1] of L_i'(tau) L_j'(tau), i, j = 1 .. degree (Legendre polynomials; Gauss-Legendre
    quadrature, exact for these degrees)."""
    nodes, w = legendre.leggauss(degree + 2)
    der = np.stack([legendre.legval(nodes, legendre.legder(np.eye(degree + 1)[i])) for i in range(1, degree + 1)])
    return (der * w) @ der.T


def base_correction(x9: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """M = P(alpha, beta, gamma) K^-1 and the offset o of a nine-vector."""
    return paper_matrix(x9[0], x9[1], x9[2]) * (1.0 / x9[3:6])[None, :], np.asarray(x9[6:9], dtype=float)


def _dp(x9):
    a, b, g = x9[:3]
    ca, sa, cb, sb, cg, sg = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(g), np.sin(g)
    da = np.array([[-sa * cg, 0, 0], [0, 0, 0], [ca * cg, 0, 0]])
    db = np.array([[0, 0, 0], [0, -sb, 0], [0, cb, 0]])
    dg = np.array([[-ca * sg, 0, 0], [cg, 0, 0], [-sa * sg, 0, 0]])
    return da, db, dg


def solve_normal(a: np.ndarray, b: np.ndarray, ridge: float = RIDGE) -> np.ndarray:
    """x minimizing |A^(1/2) x - ...|: (A) x = b with column scaling and a tiny ridge (singular columns get 0)."""
    diag = np.clip(np.diag(a), 0, None)
    live = diag > 1e-24 * max(float(diag.max(initial=0.0)), 1e-300)  # columns with some information
    out = np.zeros(len(b))
    if not live.any():
        return out
    d = np.sqrt(diag[live])
    s = a[np.ix_(live, live)] / d[:, None] / d[None, :] + ridge * np.eye(int(live.sum()))
    try:
        y = np.linalg.solve(s, b[live] / d)
    except np.linalg.LinAlgError:
        y = np.linalg.lstsq(s, b[live] / d, rcond=1e-12)[0]
    out[live] = y / d
    return out


class ExtendedModel:
    """The base model plus effects (module docstring).  ``groups`` maps "base" and each effect name to its
    parameter indices; ``default`` holds the neutral values the left-out parameters keep."""

    def __init__(self, base: str, effects: list[type[Effect]], d: Columns, norm: Normalization, o0: np.ndarray,
                 info: dict | None = None):
        self.base, self.d, self.norm, self.o0 = base, d, norm, np.asarray(o0, dtype=float)
        self.effects = list(effects)
        self.info = info or {}
        self.groups = {"base": list(BASE_FREE[base])}
        names = list(NINE_NAMES)
        self.col_effects = []  # (class, first index)
        for cls in self.effects:
            if cls.base_part:
                self.groups[cls.name] = list(PART_INDEX[cls.base_part])
            else:
                self.groups[cls.name] = list(range(len(names), len(names) + len(cls.fit_params)))
                self.col_effects.append((cls, len(names)))
                names += list(cls.fit_params)
        self.names = names
        self.p = len(names)
        self.default = np.concatenate([np.asarray(NEUTRAL, dtype=float), np.zeros(self.p - 9)])
        self.prior_w = np.zeros(self.p)  # ``set_prior``: weights of the pseudo-rows w (x - default), nT per unit

    def set_prior(self, scale_nT: float) -> None:
        """A weak prior on the base correction's angles and scales (BASE_PRIOR_SD about their neutral values),
        as pseudo-rows of ``scale_nT`` times (x - neutral) / sd.  Physically a fluxgate's scale factors lie within
        a few percent of 1 and its axes within a degree or so of orthogonal; the prior is millions of times weaker
        than the data along every direction the attitudes determine, and holds only the directions they leave
        free (a vehicle's band of directions: the common scale and the z axis's scale against its offset, which a
        least-squares fit otherwise runs along to scales of 2 and offsets of 10^5 nT, shrinking the residual with
        the scale).  The same holds for an effect's scale terms (``*_ppm_per_C``), which scale the noise down
        over time along those directions: their prior is on the scale change over the temperature's range."""
        w = np.zeros(self.p)
        w[:3] = scale_nT / BASE_PRIOR_SD["angle"]
        w[3:6] = scale_nT / BASE_PRIOR_SD["scale"]
        # an effect's scale terms (ppm per degree of the logged temperature) move the scales along the same free
        # directions: the same prior on the scale change they make over the record's temperature range
        temp = self.d.extra.get("temp_eff_C", self.d.temp_C)
        span = float(np.ptp(temp)) if temp is not None and len(temp) else 0.0
        for i, name in enumerate(self.names):
            if name.endswith("_ppm_per_C") and span > 0:
                w[i] = scale_nT * PPM * span / BASE_PRIOR_SD["scale"]
        self.prior_w = w

    def prior_gram(self, x: np.ndarray) -> np.ndarray:
        """The (p + 1)^2 Gram matrix of the prior's pseudo-rows [J, r] at x (zeros without a prior)."""
        w = self.prior_w
        rp = w * (x - self.default)
        g = np.zeros((self.p + 1, self.p + 1))
        g[:self.p, :self.p] = np.diag(w * w)
        g[:self.p, self.p] = g[self.p, :self.p] = w * rp
        g[self.p, self.p] = float(rp @ rp)
        return g

    def smooth_gram(self, x: np.ndarray, weight: float) -> np.ndarray:
        """The (p + 1)^2 Gram matrix of a slope penalty on the time bases (``TIME_BASES``): ``weight`` (nT^2 per
        unit of the squared slope in normalized time) times the integral over the record of the squared time
        derivative of each drift, as pseudo-rows [J, r] at x (like ``prior_gram``: added to a fit's normal
        equations, never to a residual).  A left-out stretch is then bridged by the gentlest drift its edges allow,
        not by whatever a free degree-12 polynomial does where it saw no data."""
        g = np.zeros((self.p + 1, self.p + 1))
        for cls in TIME_BASES:
            idx = self.groups.get(cls.name)
            if not idx or weight <= 0:
                continue
            pen = slope_penalty(cls.DEGREE) * weight
            for start in range(0, len(idx), cls.DEGREE):  # each series of the effect (axis-major)
                sl = idx[start:start + cls.DEGREE]
                g[np.ix_(sl, sl)] += pen
        xe = x - self.default
        g[:self.p, self.p] = g[:self.p, :self.p] @ xe
        g[self.p, :self.p] = g[:self.p, self.p]
        g[self.p, self.p] = float(xe @ g[:self.p, :self.p] @ xe)
        return g

    # -- rows ---------------------------------------------------------------------------------
    def blocks(self):
        n = len(self.d)
        for s in range(0, n, BLOCK_ROWS):
            yield slice(s, min(n, s + BLOCK_ROWS))

    def columns(self, sl) -> list:
        """Effect columns (G, H) of the rows ``sl``."""
        d = self.d.take(sl)
        u0 = d.raw_nT - self.o0
        return [cls.fit_columns(u0, d, self.norm) for cls, _ in self.col_effects]

    def residual_jacobian(self, x: np.ndarray, sl, cols=None, free=None) -> tuple[np.ndarray, np.ndarray]:
        """r (m,) and J (m, p) of the rows ``sl`` at x; with ``free`` (sorted parameter indices), J's columns
        ``free`` alone, (m, len(free)): the same numbers as ``J[:, free]`` (each column is computed on its own; an
        effect none of whose parameters is free is skipped), for the fits that use no other (``_normal_equations``)
        and for residuals alone (``free=[]``)."""
        d = self.d.take(sl)
        cols = self.columns(sl) if cols is None else cols
        x9 = x[:9]
        m_mat, o = base_correction(x9)
        v = d.raw_nT - o
        for (cls, i0), (g, _h) in zip(self.col_effects, cols):
            part = x[i0:i0 + len(cls.fit_params)]
            if g is not None and part.any():  # an effect at zero moves nothing (v - 0 is v, to the bit)
                v = v - g @ part
        b = v @ m_mat.T
        nb = np.linalg.norm(b, axis=1)
        r = nb - d.f_ref_nT
        wanted = range(self.p) if free is None else free
        at = {j: c for c, j in enumerate(wanted)}  # parameter index -> column of the returned J
        bh = b / nb[:, None]
        w = bh @ m_mat  # b^T M, (m, 3)
        # column-major when subset, as ``J[:, free]`` is: the products a caller forms with it (J^T J, J^T r) then take
        # the same BLAS path and give the same bits
        jac = np.empty((len(r), len(at)), order="C" if free is None else "F")
        p_mat = paper_matrix(*x9[:3])
        for k, dp in enumerate(_dp(x9)):
            if k in at:
                jac[:, at[k]] = np.einsum("ni,ni->n", bh, v @ (dp * (1.0 / x9[3:6])[None, :]).T)
        for a in range(3):
            if 3 + a in at:  # d M / d k_a = -P[:, a] / k_a^2 in column a
                jac[:, at[3 + a]] = -(bh @ p_mat[:, a]) * v[:, a] / x9[3 + a] ** 2
            if 6 + a in at:
                jac[:, at[6 + a]] = -w[:, a]
        for (cls, i0), (g, h) in zip(self.col_effects, cols):
            k = len(cls.fit_params)
            if h is not None:
                r = r - h @ x[i0:i0 + k]
            mine = [(j - i0, at[j]) for j in range(i0, i0 + k) if j in at]
            if not mine:
                continue
            col = np.zeros((len(r), k))
            if g is not None:
                col -= np.einsum("na,nak->nk", w, g)
            if h is not None:
                col -= h
            for j, c in mine:
                jac[:, c] = col[:, j]
        return r, jac

    def residuals(self, x: np.ndarray) -> np.ndarray:
        return np.concatenate([self.residual_jacobian(x, sl, free=[])[0] for sl in self.blocks()])

    # -- the full fit ---------------------------------------------------------------------------
    def free_indices(self, names) -> list[int]:
        return sorted({i for nm in ["base", *names] for i in self.groups[nm]})

    def fit_subset(self) -> np.ndarray | None:
        """The rows the Gauss-Newton fit of the tangent point uses: all (None) up to FIT_ROWS, else a seeded
        random FIT_ROWS of them.  Statistically harmless: the point only has to be close to the optimum,
        since every sub-model is then solved on all rows in its tangent space (one more Gauss-Newton step,
        whose linearization error is second order in a distance of order noise / sqrt(FIT_ROWS))."""
        n = len(self.d)
        if n <= FIT_ROWS:
            return None
        return np.sort(np.random.default_rng(FIT_SEED).choice(n, FIT_ROWS, replace=False))

    def _fit_blocks(self, rows):
        """(rows of a block, its effect columns), the columns computed once (they do not depend on x)."""
        if rows is None:
            return [(sl, self.columns(sl)) for sl in self.blocks()]
        return [(rows[s:s + BLOCK_ROWS], self.columns(rows[s:s + BLOCK_ROWS])) for s in range(0, len(rows), BLOCK_ROWS)]

    def _normal_equations(self, x, free, keep, blocks) -> tuple[float, np.ndarray, np.ndarray]:
        """(sum of squares, J_F^T J_F, J_F^T r) at x over the rows ``keep`` of ``blocks``."""
        a = np.zeros((len(free), len(free)))
        bvec = np.zeros(len(free))
        sse = 0.0
        for sl, cols in blocks:
            r, jf = self.residual_jacobian(x, sl, cols, free)
            if keep is not None:
                r, jf = r[keep[sl]], np.compress(keep[sl], jf.T, axis=1).T  # column-major still, in one copy
            a += jf.T @ jf
            bvec += jf.T @ r
            sse += float(r @ r)
        if self.prior_w.any():  # the prior's pseudo-rows
            g = self.prior_gram(x)
            a += g[np.ix_(free, free)]
            bvec += g[free, self.p]
            sse += float(g[self.p, self.p])
        return sse, a, bvec

    def fit(self, x_start: np.ndarray, free: list[int], keep: np.ndarray | None = None, blocks=None,
            tol: float = GN_TOLERANCE, iterations: int = GN_ITERATIONS) -> np.ndarray:
        """Levenberg-Marquardt on the rows ``keep`` (a mask over all rows) for the ``free`` parameters:
        Gauss-Newton steps on the column-scaled normal equations, whose ridge grows tenfold (at most
        LM_RIDGE_STEPS times) until the sum of squares goes down and shrinks again after a success.  Every
        step is verified, so the answer is never worse than the start; the ridge, not a shorter step, is
        what tames the near-null directions of a model with every effect free (a plain Gauss-Newton step
        there moved an angle by 0.3 rad and raised the sum of squares by 10^6)."""
        blocks = self._fit_blocks(None) if blocks is None else blocks
        x = x_start.copy()
        sse, a, bvec = self._normal_equations(x, free, keep, blocks)
        ridge = FIT_RIDGE
        for _ in range(iterations):
            for _ in range(LM_RIDGE_STEPS):
                x_new = x.copy()
                x_new[free] -= solve_normal(a, bvec, ridge)
                sse_new, a_new, b_new = self._normal_equations(x_new, free, keep, blocks)
                if sse_new <= sse:
                    ridge = max(ridge / 10.0, FIT_RIDGE)
                    break
                if sse_new - sse <= tol * sse:  # converged: what is left is rounding
                    return x
                ridge *= 10.0
            else:
                return x  # no descent left at any damping: x is the optimum to the arithmetic's precision
            done = abs(sse - sse_new) <= tol * max(sse_new, 1e-300)
            x, sse, a, bvec = x_new, sse_new, a_new, b_new
            if done:
                break
        return x

    def fit_robust(self, x_start: np.ndarray, free: list[int]) -> tuple[np.ndarray, np.ndarray | None]:
        """The fit with samples beyond SPIKE_SIGMA robust sigma trimmed, re-trimmed until the mask settles
        (at most TRIM_ROUNDS times), starting from the spikes of ``x_start``'s residual; (x, spike mask over
        all rows).  On long records the fit uses a subset of the rows (``fit_subset``) and the mask then
        comes from one residual pass over all rows."""
        rows = self.fit_subset()
        blocks = self._fit_blocks(rows)
        n = len(self.d)
        sub = np.arange(n) if rows is None else rows
        x = x_start.copy()  # trimmed from the start: an untrimmed first fit with many free parameters bends
        spikes = None  # towards spikes of thousands of nT and leaves a scatter that hides them
        for _ in range(TRIM_ROUNDS):
            r = np.concatenate([self.residual_jacobian(x, sl, cols, [])[0] for sl, cols in blocks])
            new = np.zeros(n, bool)
            new[sub] = OutlierEffect.spike_mask(r)
            if spikes is not None and (np.array_equal(new, spikes) or (~new[sub]).sum() < 2 * len(free)):
                break
            spikes = new
            x = self.fit(x, free, keep=~spikes, blocks=blocks, tol=TRIM_TOLERANCE, iterations=TRIM_ITERATIONS)
        if rows is not None:
            spikes = OutlierEffect.spike_mask(self.residuals(x))
        return x, spikes

class Tangent:
    """Per-fold Gram matrices of [J, r] at the full fit x*, for all samples and for the spikes alone;
    every sub-model's fold fits and held-out residuals from them."""

    def __init__(self, model: ExtendedModel, x: np.ndarray, fold: np.ndarray, k: int, spikes: np.ndarray | None,
                 smooth: float = 0.0):
        """Rows are visited fold by fold (each fold's rows in blocks), so each block adds to one fold's
        Gram matrix; r and J are kept (J in float32) when small.  ``spikes`` None: the samples beyond
        SPIKE_SIGMA robust sigma of the residual at x.  ``smooth``: the time bases' slope penalty
        (``ExtendedModel.smooth_gram``) per sample, added to every fit's normal equations (0: none)."""
        self.model, self.x, self.fold, self.k = model, x, fold, k
        p1 = model.p + 1
        n = len(model.d)
        self.gram = np.zeros((k, p1, p1))
        self.gram_spk = np.zeros((k, p1, p1))
        self._rows = [(f, idx[s:s + BLOCK_ROWS]) for f in range(k) for idx in [np.flatnonzero(fold == f)]
                      for s in range(0, len(idx), BLOCK_ROWS)]
        self._store = n * model.p * 4 <= STORE_J_BYTES
        self._j = []
        self.r = np.empty(n)
        for f, idx in self._rows:
            r, jac = model.residual_jacobian(x, idx)
            self.r[idx] = r
            if self._store:
                self._j.append(jac.astype(np.float32))
            jr = np.column_stack([jac, r])
            self.gram[f] += jr.T @ jr
        self.prior = model.prior_gram(x)  # added to every fit's normal equations, never to a residual
        if smooth > 0:
            self.prior = self.prior + model.smooth_gram(x, smooth * n)
        self.spikes = OutlierEffect.spike_mask(self.r) if spikes is None else spikes
        sp = np.flatnonzero(self.spikes)
        if len(sp):
            r, jac = model.residual_jacobian(x, sp)
            jr = np.column_stack([jac, r])
            for f in range(k):
                z = jr[fold[sp] == f]
                self.gram_spk[f] += z.T @ z

    def _blocks(self):
        """(fold, rows, r, J) of every block at x."""
        for i, (f, idx) in enumerate(self._rows):
            jac = self._j[i] if self._store else self.model.residual_jacobian(self.x, idx)[1]
            yield f, idx, self.r[idx], jac

    def shift(self, free: list[int]) -> np.ndarray:
        """c: the left-out parameters moved from x* to their neutral values (zeros on the free ones)."""
        c = self.model.default - self.x
        c[free] = 0.0
        return c

    def fold_steps(self, names: list[str], robust: bool) -> tuple[list[int], np.ndarray, np.ndarray]:
        """(free indices, c, delta per fold (k, |free|)) of the sub-model base + ``names`` fitted on the
        other folds (the spikes left out of the fit when ``robust``)."""
        free = self.model.free_indices(names)
        c = self.shift(free)
        tot = self.gram.sum(axis=0) - (self.gram_spk.sum(axis=0) if robust else 0.0)
        deltas = np.zeros((self.k, len(free)))
        p = self.model.p
        for f in range(self.k):
            g = tot - self.gram[f] + (self.gram_spk[f] if robust else 0.0) + self.prior
            jj, jr = g[:p, :p], g[:p, p]
            jfy = jr[free] + jj[free] @ c  # J_F^T y, y = r* + J c
            deltas[f] = -solve_normal(jj[np.ix_(free, free)], jfy)
        return free, c, deltas

    def heldout(self, names: list[str], robust: bool) -> tuple[np.ndarray, int]:
        """Held-out residuals of base + ``names`` (spikes explained away, set to 0, when ``robust``) and the
        number of spikes so explained."""
        free, c, deltas = self.fold_steps(names, robust)
        out = np.empty(len(self.model.d))
        shift = np.tile(c, (self.k, 1))  # y + J_F delta_f = r + J (c + delta_f on the free entries)
        shift[:, free] += deltas
        for f, idx, r, jac in self._blocks():
            out[idx] = r + jac @ shift[f]
        n_spk = 0
        if robust:
            out[self.spikes] = 0.0
            n_spk = int(self.spikes.sum())
        return out, n_spk

    def fit_on(self, names: list[str], robust: bool, fold_ids) -> np.ndarray:
        """Parameters of base + ``names`` fitted on the folds ``fold_ids`` (one tangent step from x*)."""
        free = self.model.free_indices(names)
        c = self.shift(free)
        ids = list(fold_ids)
        g = self.gram[ids].sum(axis=0) - (self.gram_spk[ids].sum(axis=0) if robust else 0.0) + self.prior
        p = self.model.p
        jj, jr = g[:p, :p], g[:p, p]
        delta = -solve_normal(jj[np.ix_(free, free)], jr[free] + jj[free] @ c)
        x = self.x + c
        x[free] += delta
        return x

    def fit_rms(self, names: list[str]) -> float:
        """RMS on every sample of base + ``names`` fitted on every sample (from the Gram matrices)."""
        sse = self.sse_free(self.model.free_indices(names), robust=False)
        return float(np.sqrt(sse / max(len(self.model.d), 1)))

    def sse_free(self, free: list[int], robust: bool) -> float:
        """Sum of squares on every sample (the spikes left out when ``robust``) of the model whose free
        parameters are ``free`` (any subset of the parameters, the others at their neutral values), fitted
        on every sample (one tangent step, from the Gram matrices)."""
        c = self.shift(free)
        g = self.gram.sum(axis=0) - (self.gram_spk.sum(axis=0) if robust else 0.0)
        p = self.model.p
        jj, jr, rr = g[:p, :p], g[:p, p], g[p, p]
        jfy = jr[free] + jj[free] @ c
        gp = g + self.prior  # the step with the prior; the sum of squares of the data alone
        delta = -solve_normal(gp[np.ix_(free, free)], gp[free, p] + gp[free, :p] @ c)
        sse = rr + 2 * c @ jr + c @ jj @ c + 2 * delta @ jfy + delta @ jj[np.ix_(free, free)] @ delta
        return float(max(sse, 0.0))

    def full_fit(self, names: list[str], robust: bool) -> np.ndarray:
        """Parameters of base + ``names`` fitted on every fold."""
        return self.fit_on(names, robust, range(self.k))

    def linear_residuals(self, x: np.ndarray) -> np.ndarray:
        """The residual at ``x`` in the tangent model at x* (r* + J (x - x*)), the model every held-out residual
        and sum of squares here is computed in."""
        out = np.empty(len(self.model.d))
        step = x - self.x
        for _, idx, r, jac in self._blocks():
            out[idx] = r + jac @ step
        return out


def spike_scale(r: np.ndarray) -> float:
    return robust_sigma(r)


__all__ = ["ExtendedModel", "Tangent", "base_correction", "PARAM_NAMES"]

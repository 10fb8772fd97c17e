"""The one objective every calibrator minimizes, and the one counter that measures them all.

Seed 000, eq. 3: ``F(X) = (1/N) sum_i (|B1_i(X)| - |B_sc,i|)^2`` with ``B1_i = M(X) (raw_i - o)``
(CONTRACT section 1).  ``ScalarObjective`` evaluates a whole population ``X`` of shape (m, p) in one
numpy call; ``core.evaluator.Evaluator`` wraps it (as COCO's observer wraps a problem) so that evaluations,
budget and the convergence trace are measured the same way for every calibrator, whatever it does.
"""
from __future__ import annotations

import functools

import numpy as np

from magbench.simulate.sensor import FREE, PARAM_NAMES, ErrorParams, embed


def n_params(model: str) -> int:
    return len(PARAM_NAMES[model])


def identity_vector(model: str) -> np.ndarray:
    """The parameters of no calibration (zero angles and offsets, unit scales) for ``model``: a new array."""
    return _identity(model).copy()


@functools.cache
def _identity(model: str) -> np.ndarray:
    return ErrorParams().to_vector(model)


def base_model(model: str) -> str:
    """The form a model is computed in: ``angles`` (no scale, no offset: the 6-term quadric) or ``nine``
    (``offset`` and ``diag`` are the nine-parameter model with entries held fixed)."""
    return "angles" if model == "angles" else "nine"


def correction_matrices(x: np.ndarray, model: str) -> tuple[np.ndarray, np.ndarray]:
    """M = P(alpha, beta, gamma) K^-1 and offset o for each row of ``x`` (shape (m, p)).

    Returns M of shape (m, 3, 3) and o of shape (m, 3).
    """
    x = np.atleast_2d(np.asarray(x, dtype=float))
    if model in ("offset", "diag"):
        x, model = embed(x, model), "nine"
    m = x.shape[0]
    a, b, g = x[:, 0], x[:, 1], x[:, 2]
    if model == "nine":
        inv_k = 1.0 / x[:, 3:6]
        o = x[:, 6:9]
    else:
        inv_k = np.ones((m, 3))
        o = np.zeros((m, 3))
    cg = np.cos(g)
    mat = np.zeros((m, 3, 3))
    mat[:, 0, 0] = np.cos(a) * cg * inv_k[:, 0]
    mat[:, 1, 0] = np.sin(g) * inv_k[:, 0]
    mat[:, 2, 0] = np.sin(a) * cg * inv_k[:, 0]
    mat[:, 1, 1] = np.cos(b) * inv_k[:, 1]
    mat[:, 2, 1] = np.sin(b) * inv_k[:, 1]
    mat[:, 2, 2] = inv_k[:, 2]
    return mat, o


def correction_matrix_one(x: np.ndarray, model: str) -> tuple[np.ndarray, np.ndarray]:
    """``correction_matrices`` of one point ``x`` (shape (p,)): M (3, 3) and o (3,), the same numbers to the
    last bit (the same products in the same order, numpy's own cos and sin) without the population's
    bookkeeping, which was half the cost of a single evaluation (NLopt's calls, RANSAC's and lsq's single
    points, every residual and Jacobian block of the local solvers)."""
    x = np.asarray(x, dtype=float)
    if model in ("offset", "diag"):
        x, model = embed(x[None, :], model)[0], "nine"
    c = np.cos(x[:3]).tolist()
    s = np.sin(x[:3]).tolist()
    if model == "nine":
        ik0, ik1, ik2 = (1.0 / x[3:6]).tolist()
        o = x[6:9]
    else:
        ik0 = ik1 = ik2 = 1.0
        o = np.zeros(3)
    cg = c[2]
    mat = np.array([[c[0] * cg * ik0, 0.0, 0.0],
                    [s[2] * ik0, c[1] * ik1, 0.0],
                    [s[0] * cg * ik0, s[1] * ik1, ik2]])
    return mat, o


def quadric_coefficients(x: np.ndarray, model: str) -> np.ndarray:
    """Coefficients q (m, 10) such that ``|M (raw - o)|² = q · design(raw)`` for each row of ``x``.

    With W = M^T M: ``|M (r - o)|² = r^T W r - 2 (W o)^T r + o^T W o`` (the ellipsoid of the readings).
    For the lower-triangular M the six entries of W are written out, so a population costs a handful
    of vector operations and one matrix product with the (10, n) design.
    """
    if not (isinstance(x, np.ndarray) and x.ndim == 2 and x.dtype == np.float64):
        x = np.atleast_2d(np.asarray(x, dtype=float))
    if model in ("offset", "diag"):
        x, model = embed(x, model), "nine"
    xt = x.T
    angles = xt[:3].copy()  # contiguous: the trigonometric ufuncs run faster on it
    cos, sin = np.cos(angles), np.sin(angles)
    # The columns of P are unit vectors, so diag(P^T P) = 1 and W = K^-1 P^T P K^-1 has
    # W01 = (sin g cos b + sin a cos g sin b)/(kx ky), W02 = sin a cos g/(kx kz), W12 = sin b/(ky kz).
    # Rows of q are built in place (a population costs ~20 vector operations).
    q = np.empty((10 if model == "nine" else 6, x.shape[0]))
    np.multiply(sin[0], cos[2], out=q[4])
    np.multiply(q[4], sin[1], out=q[3])
    q[3] += sin[2] * cos[1]
    q[5] = sin[1]
    if model != "nine":
        q[:3] = 1.0
        return q.T
    ik = 1.0 / xt[3:6]
    np.multiply(ik, ik, out=q[:3])
    q[3:6] *= ik[_PAIR_A] * ik[_PAIR_B]
    o = xt[6:9]
    wo = (q[_W_INDEX].reshape(3, 3, -1) * o).sum(axis=1)  # W o
    np.multiply(wo, -2.0, out=q[6:9])
    q[9] = (wo * o).sum(axis=0)  # o^T W o
    return q.T


_PAIR_A, _PAIR_B = np.array([0, 0, 1]), np.array([1, 2, 2])  # (kx ky), (kx kz), (ky kz): W01, W02, W12
_W_INDEX = np.array([0, 3, 4, 3, 1, 5, 4, 5, 2])  # W as a 3x3 from the rows w00 w11 w22 w01 w02 w12


class ScalarObjective:
    """Scalar residuals ``r_i = |M (raw_i - o)| - F_i`` and their mean square (seed 000, eq. 3).

    Every model is computed as ``angles`` or ``nine`` (``base_model``): the ``offset`` and ``diag``
    vectors are embedded into the nine-vector (``sensor.embed``) and their Jacobian is the nine-parameter
    Jacobian's columns of the free entries, so residuals, Jacobian, normal equations and population values
    have one implementation."""

    def __init__(self, raw_nT: np.ndarray, f_ref_nT: np.ndarray, model: str):
        if model not in PARAM_NAMES:
            raise ValueError(f"unknown model {model!r}")
        self.raw_nT = np.asarray(raw_nT, dtype=float)
        f_ref = np.asarray(f_ref_nT, dtype=float)
        if f_ref.shape == self.raw_nT.shape[:1]:  # one per row already: a read-only view, as np.broadcast_to's (faster)
            f_ref = f_ref.view()
            f_ref.flags.writeable = False
        else:
            f_ref = np.broadcast_to(f_ref, (self.raw_nT.shape[0],))
        self.f_ref_nT = f_ref
        # The computations read these private references only: the public attributes are what other modules
        # read (acceptance, Fisher information); the conformance battery's honeypot replaces them with decoys
        # while a solver runs (calibrators/checks.py, check_no_hidden_data).
        self._raw, self._f_ref = self.raw_nT, self.f_ref_nT
        self.model = model
        self.base = base_model(model)
        self._free = None if model == self.base else list(FREE[model])  # Jacobian columns kept
        self.n_params = n_params(model)
        self._raw_t = np.ascontiguousarray(self._raw.T)  # (3, n): one contiguous row per axis
        self._design_cache: np.ndarray | None = None  # built on the first population call
        # A one-block record's last ``_block`` (x, r, J^T, weights) from ``normal_equations``: a local solver's last
        # point is where the acceptance checks' ``one_pass`` then looks, and finds that block already computed.
        self._last_block: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None

    @property
    def _design(self) -> np.ndarray:
        """The quadric design (6 or 10, n) of the population form, built once when first needed (local
        methods on large records never need it)."""
        if self._design_cache is None:
            x, y, z = self._raw.T
            cols = [x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z]
            if self.base == "nine":
                cols += [x, y, z, np.ones_like(x)]
            self._design_cache = np.ascontiguousarray(np.array(cols))
            self._design_mean = self._design_cache.mean(axis=1)
            self._f_scaled = 2.0 * self._f_ref / self._raw.shape[0]
            self._f2_mean = float(np.mean(self._f_ref**2))
        return self._design_cache

    def values(self, x: np.ndarray, exact: bool | None = None) -> np.ndarray:
        """F(X) of eq. 3 for each row of a population: (m, p) -> (m,).

        Expanded as ``mean(|c|²) - 2 mean(F |c|) + mean(F²)``: ``mean(|c|²)`` is the quadric applied to the
        mean design row, so a population costs one matrix product, one square root and one
        matrix-vector product.  The expansion loses about ``F² · 1e-16`` (~1e-6 nT²) to rounding, far
        below any noise floor but enough to confuse a local method's line search, so a single point
        (m = 1, what local methods ask for) and ``exact=True`` use the direct form (``exact=False``
        forces the expansion).
        """
        if exact or (exact is None and np.shape(x)[0] == 1):
            rows = np.atleast_2d(np.asarray(x, dtype=float))
            return np.array([np.mean(self.residuals(row) ** 2) for row in rows])
        q = quadric_coefficients(x, self.model)
        design = self._design
        n = design.shape[1]
        step = max(1, POPULATION_BLOCK_ELEMENTS // max(q.shape[0], 1))
        if n <= step:
            c2 = q @ design
            np.sqrt(c2, out=c2)  # |c|² >= 0 for any finite parameters; a NaN marks a broken candidate
            return q @ self._design_mean - c2 @ self._f_scaled + self._f2_mean
        # a long record: the (m, n) intermediate in blocks of columns, so that it stays in the cache and the
        # memory per call is bounded (time linear in n)
        cross = np.zeros(q.shape[0])
        for start in range(0, n, step):
            c2 = q @ design[:, start:start + step]
            np.sqrt(c2, out=c2)
            cross += c2 @ self._f_scaled[start:start + step]
        return q @ self._design_mean - cross + self._f2_mean

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Residuals at one point, computed directly as |M (raw - o)| - F (the reference form), block by block."""
        if self._raw.shape[0] <= CHUNK_ROWS:
            return self._residuals_one_block(x)
        mat, o = correction_matrix_one(x, self.model)
        out = np.empty(self._raw.shape[0])
        for rows in self._blocks():
            c = _lower_times(mat, self._raw_t[:, rows] - o[:, None])
            out[rows] = np.sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2])
        out -= self._f_ref
        return out

    def _residuals_one_block(self, x: np.ndarray) -> np.ndarray:
        """``residuals`` of a record of at most CHUNK_ROWS rows (what NLopt, RANSAC and every single point ask for,
        tens of thousands of times a search): the same operations on the same values in the same order (M's
        entries as ``correction_matrix_one`` forms them, the products of ``_lower_times``), so the same numbers to
        the last bit, without building M as an array or the block's bookkeeping."""
        x = np.asarray(x, dtype=float)
        if self.model in ("offset", "diag"):
            x = embed(x[None, :], self.model)[0]
        c = np.cos(x[:3]).tolist()
        s = np.sin(x[:3]).tolist()
        raw = self._raw_t
        if self.base == "nine":
            ik0, ik1, ik2 = (1.0 / x[3:6]).tolist()
            o0, o1, o2 = x[6:9].tolist()
            d0, d1, d2 = raw[0] - o0, raw[1] - o1, raw[2] - o2
        else:
            ik0 = ik1 = ik2 = 1.0
            d0, d1, d2 = raw[0] - 0.0, raw[1] - 0.0, raw[2] - 0.0
        cg = c[2]
        c0 = d0 * (c[0] * cg * ik0)
        c1 = (s[2] * ik0) * d0
        c1 += (c[1] * ik1) * d1
        c2 = (s[0] * cg * ik0) * d0
        c2 += (s[1] * ik1) * d1
        c2 += ik2 * d2
        c0 *= c0
        c1 *= c1
        c2 *= c2
        c0 += c1
        c0 += c2
        np.sqrt(c0, out=c0)
        c0 -= self._f_ref
        return c0

    def _block(self, x: np.ndarray, rows: slice) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Residuals r, the transposed Jacobian J^T (p, m) and the noise weights |M^T u|² of a block of rows.

        Analytic: dr/dθ = u^T (dM/dθ) d, dr/do = -u^T M, u = c/|c|, d = raw - o, c = M d.  Column 0 of M
        depends on alpha, gamma, kx; column 1 on beta, ky; column 2 on kz.  M is lower triangular, so the
        products are written out (a (m, 3) x (3, 3) BLAS call is slow for long m).
        """
        x = np.asarray(x, dtype=float)
        if self._free is not None:
            x = embed(x, self.model)
        mat, o = correction_matrix_one(x, self.base)
        d = self._raw_t[:, rows] - o[:, None]  # (3, m)
        c = _lower_times(mat, d)
        norm = np.sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2])
        u = c / norm
        a, b, g = x[:3]
        ik = 1.0 / x[3:6] if self.base == "nine" else np.ones(3)
        ca, sa, cb, sb, cg, sg = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(g), np.sin(g)
        jt = np.empty((len(x), d.shape[1]))
        jt[0] = (u[0] * (-sa * cg) + u[2] * (ca * cg)) * (ik[0] * d[0])
        jt[1] = (u[1] * (-sb) + u[2] * cb) * (ik[1] * d[1])
        jt[2] = (u[0] * (-ca * sg) + u[1] * cg + u[2] * (-sa * sg)) * (ik[0] * d[0])
        mtu = np.empty_like(u)  # M^T u (M lower triangular: M^T upper)
        mtu[0] = mat[0, 0] * u[0] + mat[1, 0] * u[1] + mat[2, 0] * u[2]
        mtu[1] = mat[1, 1] * u[1] + mat[2, 1] * u[2]
        mtu[2] = mat[2, 2] * u[2]
        if self.base == "nine":
            jt[3:6] = -mtu * d * ik[:, None]
            jt[6:9] = -mtu
        if self._free is not None:
            jt = jt[self._free]
        return norm - self._f_ref[rows], jt, mtu[0] * mtu[0] + mtu[1] * mtu[1] + mtu[2] * mtu[2]

    def _blocks(self):
        n = self._raw.shape[0]
        return [slice(i, min(i + CHUNK_ROWS, n)) for i in range(0, n, CHUNK_ROWS)]

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """d r_i / d x (n, p), analytic (see ``_block``), computed block by block."""
        out = np.empty((self.n_params, self._raw.shape[0]))
        for rows in self._blocks():
            out[:, rows] = self._block(x, rows)[1]
        return out.T

    def normal_equations(self, x: np.ndarray, weighted: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
        """``(J^T W J, J^T W r, r^T W r)`` accumulated over blocks of ``CHUNK_ROWS`` rows, so that the
        memory is bounded whatever the record's length (W = I, or 1/|M^T u|² with ``weighted``: the Fisher
        information per unit noise variance)."""
        p = self.n_params
        jtj, jtr, rtr = np.zeros((p, p)), np.zeros(p), 0.0
        blocks = self._blocks()
        for rows in blocks:
            r, jt, w = self._block(x, rows)
            if len(blocks) == 1:
                self._last_block = (np.array(x, dtype=float), r, jt, w)
            if weighted:
                jw = jt / w
                jtj += jw @ jt.T
                jtr += jw @ r
                rtr += float(r @ (r / w))
            else:
                jtj += jt @ jt.T
                jtr += jt @ r
                rtr += float(r @ r)
        return jtj, jtr, rtr

    def grams(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(J^T J, J^T W J)`` in one pass over the data (the two Gram matrices of ``normal_equations``)."""
        _, plain, _, _, weighted, _ = self.one_pass(x, keep_jacobian=False)
        return plain, weighted

    def one_pass(self, x: np.ndarray, keep_jacobian: bool
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray, np.ndarray | None]:
        """At ``x``, in one pass over the data block by block: the residuals r (n,), ``J^T J``, ``J^T r``,
        ``r^T r``, the Fisher information per unit noise variance ``J^T W J`` and, with ``keep_jacobian``,
        the Jacobian J (n, p) (memory bounded but for r and that Jacobian)."""
        x = np.array(x, dtype=float)
        n, p = self._raw.shape[0], self.n_params
        r = np.empty(n)
        keep = np.empty((p, n)) if keep_jacobian else None
        gram, fisher, grad, ss = np.zeros((p, p)), np.zeros((p, p)), np.zeros(p), 0.0
        blocks = self._blocks()
        last = self._last_block
        for rows in blocks:
            if len(blocks) == 1 and last is not None and np.array_equal(last[0], x):
                rb, jt, w = last[1:]  # the same block, to the last bit: normal_equations computed it at this x
            else:
                rb, jt, w = self._block(x, rows)
            r[rows] = rb
            if keep is not None:
                keep[:, rows] = jt
            gram += jt @ jt.T
            fisher += (jt / w) @ jt.T
            grad += jt @ rb
            ss += float(rb @ rb)
        return r, gram, grad, ss, fisher, None if keep is None else keep.T

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dF/dx of eq. 3: (2/N) J^T r."""
        return 2.0 * self.normal_equations(x)[1] / self._raw.shape[0]


def _lower_times(mat: np.ndarray, d: np.ndarray) -> np.ndarray:
    """M d for a lower-triangular 3x3 M and d of shape (3, m), written out."""
    c = np.empty_like(d)
    np.multiply(d[0], mat[0, 0], out=c[0])
    c[1] = mat[1, 0] * d[0] + mat[1, 1] * d[1]
    c[2] = mat[2, 0] * d[0] + mat[2, 1] * d[1] + mat[2, 2] * d[2]
    return c


POPULATION_BLOCK_ELEMENTS = 1 << 18
"""Largest (population x readings) block of the population objective (2 MiB of float64)."""
CHUNK_ROWS = 1 << 15
"""Rows per block of the Jacobian computations: a block of the (p, m) Jacobian stays in the cache."""



"""Motion on the closures: linear algebra of ``J_c x = rhs`` for any closed-loop model.

Pure array functions (no model): :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`
builds ``J_c`` (and the drift) and calls them. Two problems, each with two routes that
agree to 1e-10 (tested against an SVD null-space computation written in the tests):

* **completion** (:func:`complete`): given the values of some coordinates ``x[known]``,
  the other coordinates with ``J_c x = rhs`` and, where the closures leave them free
  (a rod spinning about its own axis between two ball joints), the least Euclidean norm
  ``|x[free]|``. Redundant (rank-deficient) rows are harmless. Given values that no
  motion can match raise :class:`~hexapod_pin.errors.InconsistentMotionError`.
* **projection** (:func:`project`): the motion ``x`` with ``J_c x = rhs`` closest to a
  given one in the metric ``|x - x0|_W`` (``W`` symmetric positive definite; the mass
  matrix makes it the kinetic-energy metric, the physical one: Gauss's principle).

Routes: ``"lstsq"`` (the direct one: a Householder QR where the unknowns are determined,
LAPACK's SVD least squares ``numpy.linalg.lstsq`` where they are not; for a projection a
Cholesky factor of ``W`` first) and ``"qp"`` (ProxSuite's dense
proximal QP on the independent rows of ``J_c``, chosen by a column-pivoted QR, because
redundant equality rows make the proximal iterations crawl; one ProxSuite problem per size
is kept per thread and updated). Every answer is checked (finite, constraint residual
relative to the data) before it is returned. :func:`row_basis` gives the bases of the
independent rows (range, null space, right inverse) from one compiled pivoted QR.

Units follow the caller: velocities (m/s, rad/s) or accelerations (m/s^2, rad/s^2) of
the tree coordinates, ``rhs`` in the closure-row units.
"""

from __future__ import annotations

import threading
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import proxsuite
import scipy.linalg

from ..errors import InconsistentMotionError, InputError, SingularityError, SolverError
from .compiled import jit

METHODS = ("lstsq", "qp")
#: a completion / projection is accepted when ``|J_c x - rhs|`` is below this, relative to
#: ``max(1, |rhs|, |J_c| |x|)`` (max-abs norms)
CONSISTENCY_RTOL = 1e-9
#: relative singular-value threshold for the independent rows (as ClosedLoopModel.rank)
ROW_RTOL = 1e-10
#: the QR route of :func:`least_squares` is taken when no diagonal entry of R is below this
#: fraction of the largest (else the SVD route gives the minimum-norm solution)
FULL_RANK_RTOL = 1e-8
#: ProxSuite's absolute accuracy on the (scaled) problems
QP_EPS = 1e-13


def check_method(method: str) -> str:
    """``method`` if it is one of :data:`METHODS`; raises InputError otherwise."""
    if method not in METHODS:
        raise InputError("method", method, f"expected one of {METHODS}")
    return method


def independent_rows(jac: np.ndarray, rtol: float = ROW_RTOL) -> np.ndarray:
    """Indices (sorted) of a maximal set of linearly independent rows of ``jac``.

    Chosen by a column-pivoted QR of ``jac^T``; a row counts when its pivot exceeds
    ``rtol`` times the largest one.
    """
    if jac.shape[0] == 0 or jac.shape[1] == 0:
        return np.zeros(0, dtype=int)
    return np.sort(row_basis(jac, rtol).rows)


class RowBasis(NamedTuple):
    """Bases attached to the independent rows of ``J`` (n_rows, n), from one pivoted QR.

    Attributes:
        rows: (r,) indices of a maximal set of independent rows, in pivot order.
        range: (n, r) orthonormal basis of the span of those rows (``J[rows]^T``).
        null: (n, n - r) orthonormal basis of the null space of ``J``.
        pinv: (n, r) the minimum-norm right inverse of ``J[rows]``: ``J[rows] pinv = I``.
    """

    rows: np.ndarray
    range: np.ndarray
    null: np.ndarray
    pinv: np.ndarray


def row_basis(jac: np.ndarray, rtol: float = ROW_RTOL) -> RowBasis:
    """:class:`RowBasis` of ``jac`` (rows of :func:`independent_rows`, the same ``rtol``).

    Householder QR of ``jac^T`` with column pivoting (largest remaining norm first, as
    LAPACK's dgeqp3), compiled: ``jac[rows]^T = Q1 R11``, rank where a pivot falls to
    ``rtol`` times the first.

    Raises:
        SolverError: non-finite entries in ``jac``.
    """
    jac = np.ascontiguousarray(jac, dtype=float)
    rank, piv, q_mat, pinv = row_basis_kernel(jac, rtol)
    if rank < 0:
        raise SolverError("closure row basis", "non-finite", "NaN or inf in the Jacobian")
    return RowBasis(piv[:rank], q_mat[:, :rank], q_mat[:, rank:], pinv)


@jit
def row_basis_kernel(jac, rtol):
    """(rank or -1 when not finite, pivots, Q (n, n), right inverse (n, rank)) of
    :func:`row_basis`."""
    m_rows, n = jac.shape
    a = np.ascontiguousarray(jac.T)                   # (n, m_rows): columns are the rows
    piv = np.arange(m_rows)
    steps = min(n, m_rows)
    vecs = np.zeros((n, steps))
    betas = np.zeros(steps)
    q_mat = np.eye(n)
    norms2, dots = np.zeros(m_rows), np.zeros(m_rows)
    if not np.all(np.isfinite(a)):
        return -1, piv, q_mat, np.zeros((n, 0))
    rank, first = 0, 0.0
    for j in range(steps):
        best, where = -1.0, j
        norms2[j:] = 0.0                              # rows of a are contiguous
        for i in range(j, n):
            for c in range(j, m_rows):
                norms2[c] += a[i, c] * a[i, c]
        for c in range(j, m_rows):
            if norms2[c] > best:
                best, where = norms2[c], c
        if where != j:
            for i in range(n):
                a[i, j], a[i, where] = a[i, where], a[i, j]
            piv[j], piv[where] = piv[where], piv[j]
        size = np.sqrt(best)
        if j == 0:
            first = size
        if not size > rtol * first or size == 0.0:
            break
        alpha = -size if a[j, j] >= 0.0 else size
        v = a[j:, j].copy()
        v[0] -= alpha
        vnorm2 = 0.0
        for i in range(v.shape[0]):
            vnorm2 += v[i] * v[i]
        beta = 2.0 / vnorm2 if vnorm2 > 0.0 else 0.0
        dots[j:] = 0.0
        for i in range(v.shape[0]):
            for c in range(j, m_rows):
                dots[c] += v[i] * a[j + i, c]
        for i in range(v.shape[0]):
            for c in range(j, m_rows):
                a[j + i, c] -= beta * dots[c] * v[i]
        vecs[j:, j] = v
        betas[j] = beta
        rank += 1
    qdots = np.empty(n)
    for j in range(rank - 1, -1, -1):                 # Q = H_0 H_1 ... H_(rank-1)
        qdots[:] = 0.0
        for i in range(j, n):
            for c in range(n):
                qdots[c] += vecs[i, j] * q_mat[i, c]
        for i in range(j, n):
            for c in range(n):
                q_mat[i, c] -= betas[j] * qdots[c] * vecs[i, j]
    # right inverse Q1 R11^-T: each of its rows y solves y R11^T = (that row of Q1)
    pinv = np.zeros((n, rank))
    for row in range(n):
        for k in range(rank - 1, -1, -1):
            acc = q_mat[row, k]
            for i in range(k + 1, rank):
                acc -= a[k, i] * pinv[row, i]
            pinv[row, k] = acc / a[k, k]
    return rank, piv, q_mat, pinv


def complete(jac: np.ndarray, rhs: np.ndarray, known: npt.ArrayLike, values: npt.ArrayLike,
             method: str = "lstsq", what: str = "motion",
             free: np.ndarray | None = None) -> np.ndarray:
    """Coordinates ``x`` with ``J_c x = rhs`` and ``x[known] = values``, least norm elsewhere.

    Args:
        jac: ``J_c``, shape (n_rows, n).
        rhs: right-hand side, shape (n_rows,) or (n_rows, k) for k problems at once.
        known: indices into ``x`` whose values are given (int array-like).
        values: their values, shape (len(known),) or (len(known), k).
        method: "lstsq" or "qp" (see the module docstring).
        what: a label for error messages.
        free: the complement of ``known``, sorted, when the caller has it (then
            ``known`` is trusted: distinct indices in range).

    Returns:
        x, shape (n,) or (n, k).

    Raises:
        InputError: shapes that do not match, NaN / inf, unknown method.
        InconsistentMotionError: no ``x`` keeps the closures with these values (the given
            coordinates over-determine the closures at this configuration: a singular
            configuration, or ``q`` not assembled).
    """
    check_method(method)
    n = jac.shape[1]
    known = np.asarray(known, dtype=int).reshape(-1)
    if free is None:
        if known.size and (known.min() < 0 or known.max() >= n
                           or np.unique(known).size < known.size):
            raise InputError("known", known, f"expected distinct indices in [0, {n})")
        free = np.setdiff1d(np.arange(n), known)
    rhs = np.asarray(rhs, dtype=float)
    values = np.asarray(values, dtype=float)
    single = rhs.ndim == 1
    rhs2 = rhs[:, None] if single else rhs
    if values.ndim <= 1 and values.size == known.size and single:
        values2 = values.reshape(known.size, 1)
    else:
        values2 = values
    if values2.shape != (known.size, rhs2.shape[1]):
        raise InputError("values", values, f"expected {known.size} values per problem")
    if method == "lstsq":
        # the kernel checks the data's finiteness first (worst == -2)
        out, worst, miss = _complete_kernel(np.ascontiguousarray(jac), np.ascontiguousarray(rhs2),
                                            known, free, np.ascontiguousarray(values2),
                                            CONSISTENCY_RTOL)
        if worst == -2:
            raise InputError("values", values, "NaN or inf")
        if worst >= 0:
            if not np.all(np.isfinite(out)):
                raise SolverError("closure motion", "non-finite", f"{what} has NaN or inf")
            raise InconsistentMotionError(what, miss)
    else:
        if not (np.all(np.isfinite(values2)) and np.all(np.isfinite(rhs2))):
            raise InputError("values", values, "NaN or inf")
        b = rhs2 - jac[:, known] @ values2
        out = np.empty((n, b.shape[1]))
        out[known] = values2
        out[free] = _min_norm_qp(jac[:, free], b)
        _verify(jac, out, rhs2, what)
    return out[:, 0] if single else out


def project(jac: np.ndarray, rhs: np.ndarray, x0: np.ndarray, metric: np.ndarray | None = None,
            method: str = "lstsq", what: str = "motion") -> np.ndarray:
    """The ``x`` closest to ``x0`` with ``J_c x = rhs``: minimise ``(x - x0)^T W (x - x0)``.

    Args:
        jac: ``J_c``, shape (n_rows, n).
        rhs: right-hand side (n_rows,).
        x0: the motion to project (n,).
        metric: ``W`` (n, n), symmetric positive definite; None: the identity.
        method: "lstsq" (Cholesky of ``W``, then the least-norm correction by SVD least
            squares) or "qp" (ProxSuite on the independent rows).
        what: a label for error messages.

    Returns:
        x (n,).

    Raises:
        SingularityError: ``W`` is not positive definite (e.g. the mass matrix of a tree
            with massless links): use the Euclidean metric.
        InconsistentMotionError: the rows ``J_c x = rhs`` have no solution.
    """
    check_method(method)
    n = jac.shape[1]
    if not (np.all(np.isfinite(x0)) and np.all(np.isfinite(rhs))):
        raise InputError(what, x0, "NaN or inf")
    miss = rhs - jac @ x0
    if metric is None:
        chol = None
    else:
        try:
            chol = np.linalg.cholesky(0.5 * (metric + metric.T))
        except np.linalg.LinAlgError:
            sv = np.linalg.eigvalsh(0.5 * (metric + metric.T))
            raise SingularityError("projection metric (positive definite needed)",
                                   float(sv[0])) from None
    if method == "lstsq":
        if chol is None:
            step = least_squares(jac, miss)
        else:
            # W = L L^T; with y = L^T d: min |y| s.t. J L^-T y = miss
            a_mat = scipy.linalg.solve_triangular(chol, jac.T, lower=True).T
            y = least_squares(a_mat, miss)
            step = scipy.linalg.solve_triangular(chol.T, y, lower=False)
    else:
        hess = np.eye(n) if metric is None else 0.5 * (metric + metric.T)
        step = _qp(hess, np.zeros(n), jac, miss[:, None], "projection")[:, 0]
    out = x0 + step
    _verify(jac, out[:, None], rhs[:, None], what)
    return out


def least_squares(a_mat: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Minimum-norm least-squares solution of ``a_mat x = rhs`` (rhs 1-D or 2-D).

    A Householder QR when ``a_mat`` has full column rank (the usual case: the closures
    determine the unknowns; its diagonal says so when no entry falls below
    ``FULL_RANK_RTOL`` of the largest), otherwise LAPACK's SVD least squares.
    """
    rows, cols = a_mat.shape
    if rows >= cols > 0:
        q_mat, r_mat = np.linalg.qr(a_mat)
        diag = np.abs(np.diagonal(r_mat))
        if diag.min() > FULL_RANK_RTOL * diag.max():
            return np.linalg.solve(r_mat, q_mat.T @ rhs)
    return np.linalg.lstsq(a_mat, rhs, rcond=None)[0]


# ------------------------------------------------------------------------------ helpers
@jit
def _complete_kernel(jac, rhs, known, free, values, rtol):
    """The "lstsq" route of :func:`complete`, compiled: (x, worst column or -1, its miss);
    -2 when ``rhs`` or ``values`` has NaN or inf.

    Same algorithm as :func:`least_squares` (QR when the free columns have full rank, SVD
    least squares with NumPy's default cut-off otherwise), then the check of
    :func:`_verify` (a non-finite x reports column 0 with an infinite miss).
    """
    n, k = jac.shape[1], rhs.shape[1]
    if not (np.all(np.isfinite(values)) and np.all(np.isfinite(rhs))):
        return np.zeros((n, k)), -2, np.inf
    b = rhs - jac[:, known] @ values
    a_free = np.ascontiguousarray(jac[:, free])
    rows, cols = a_free.shape
    sol = np.zeros((cols, k))
    if cols > 0:
        done = False
        if rows >= cols:
            q_mat, r_mat = np.linalg.qr(a_free)
            dmin, dmax = np.inf, 0.0
            for i in range(cols):
                d = abs(r_mat[i, i])
                dmin = min(dmin, d)
                dmax = max(dmax, d)
            if dmin > FULL_RANK_RTOL * dmax:
                sol = np.linalg.solve(r_mat, np.ascontiguousarray(q_mat.T) @ b)
                done = True
        if not done:
            sol = np.linalg.lstsq(a_free, b, rcond=max(rows, cols) * 2.220446049250313e-16)[0]
    out = np.empty((n, k))
    for i in range(known.shape[0]):
        out[known[i], :] = values[i, :]
    for i in range(cols):
        out[free[i], :] = sol[i, :]
    if not np.all(np.isfinite(out)):
        return out, 0, np.inf
    res = jac @ out - rhs
    jmax = np.max(np.abs(jac)) if jac.size else 0.0
    for col in range(k):
        miss = np.max(np.abs(res[:, col])) if res.shape[0] else 0.0
        scale = max(1.0, np.max(np.abs(rhs[:, col])) if rhs.shape[0] else 0.0,
                    jmax * np.max(np.abs(out[:, col])))
        if not miss <= rtol * scale:
            return out, col, miss
    return out, -1, 0.0


def _verify(jac: np.ndarray, x: np.ndarray, rhs: np.ndarray, what: str) -> None:
    if not np.all(np.isfinite(x)):
        raise SolverError("closure motion", "non-finite", f"{what} has NaN or inf")
    miss = np.max(np.abs(jac @ x - rhs), axis=0, initial=0.0)
    scale = np.maximum(1.0, np.maximum(np.max(np.abs(rhs), axis=0, initial=0.0),
                                       np.max(np.abs(jac), initial=0.0)
                                       * np.max(np.abs(x), axis=0, initial=0.0)))
    worst = int(np.argmax(miss / scale))
    if not miss[worst] <= CONSISTENCY_RTOL * scale[worst]:
        raise InconsistentMotionError(what, float(miss[worst]))


def _min_norm_qp(a_mat: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    n = a_mat.shape[1]
    if n == 0:
        return np.zeros((0, rhs.shape[1]))
    return _qp(np.eye(n), np.zeros(n), a_mat, rhs, "minimum-norm completion")


def _qp(hess: np.ndarray, grad: np.ndarray, a_mat: np.ndarray, rhs: np.ndarray,
        what: str) -> np.ndarray:
    """``min 1/2 x^T H x + g^T x`` s.t. ``A x = rhs[:, j]``, for each column j (ProxSuite).

    The redundant rows of ``A`` are dropped first (a consistent right-hand side keeps the
    same solution set); each row is scaled to unit norm. Success is judged from the
    verified residual of the caller, not from ProxSuite's status alone.
    """
    rows = independent_rows(a_mat)
    a_ind = a_mat[rows]
    norms = np.linalg.norm(a_ind, axis=1)
    a_ind = np.ascontiguousarray(a_ind / norms[:, None])
    n = a_mat.shape[1]
    qp, fresh = _cached_qp(n, rows.size)
    out = np.empty((n, rhs.shape[1]))
    for col in range(rhs.shape[1]):
        b = np.ascontiguousarray(rhs[rows, col] / norms)
        if col == 0:
            data = (np.ascontiguousarray(hess), np.ascontiguousarray(grad), a_ind, b)
            if fresh:
                qp.init(*data, None, None, None)
            else:
                qp.update(*data, None, None, None)
        else:
            qp.update(b=b)
        qp.solve()
        status = qp.results.info.status
        if status != proxsuite.proxqp.PROXQP_SOLVED:
            raise SolverError("proxsuite.proxqp.dense", str(status), f"{what}, column {col}")
        out[:, col] = qp.results.x
    return out


_QP_CACHE = threading.local()
#: ProxSuite problems kept per thread (one per size); past this many the cache is emptied
QP_CACHE_SIZE = 32


def _cached_qp(n: int, n_eq: int):
    """A ProxSuite dense QP of this size with this module's settings, kept per thread (a
    new QP costs twice an ``update``): (qp, fresh) where fresh QPs need ``init``."""
    cache = getattr(_QP_CACHE, "qps", None)
    if cache is None:
        cache = _QP_CACHE.qps = {}
    qp = cache.get((n, n_eq))
    if qp is not None:
        return qp, False
    if len(cache) >= QP_CACHE_SIZE:
        cache.clear()
    qp = cache[(n, n_eq)] = proxsuite.proxqp.dense.QP(n, n_eq, 0)
    qp.settings.eps_abs = QP_EPS
    qp.settings.eps_rel = 0.0
    qp.settings.verbose = False
    return qp, True

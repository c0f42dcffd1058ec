"""Compiled linear-algebra kernels of the generic closed-loop dynamics routes.

The residual checks every route runs before it returns (:func:`kkt_residuals`,
:func:`linear_residual`: relative to the largest term of each equation, ``inf`` on
non-finite data) and the structured solves of the inverse dynamics (LU, normal
equations, minimum-norm and weighted minimum-norm solutions, the box-constrained
active-set search of the bounded inverse-dynamics QP). Numba-compiled, allocation-light,
shapes as documented per function; nothing here verifies its own answer except where a
function says it returns a residual: the callers in :mod:`~hexapod_pin.core.dynamics`
verify on the full system.
"""

from __future__ import annotations

import math

import numpy as np

from .compiled import jit, jit_inline


def forward_residuals(mass: np.ndarray, bias: np.ndarray, tau: np.ndarray, jac: np.ndarray,
                      drift: np.ndarray, acc: np.ndarray, lam: np.ndarray,
                      out: np.ndarray) -> tuple[float, float]:
    """Relative residuals of ``M a + h - tau - J^T lam = 0`` and ``J a + drift = 0``:
    :func:`kkt_residuals` with the target ``-drift``. Returns ``(eom, closure)`` (also
    written to ``out``)."""
    return kkt_residuals(mass, bias, tau, jac, -drift, acc, lam, out)



@jit_inline
def diagonal_scaling(mat, n, out):
    """``out[i] = 1 / sqrt(max(mat[i, i], floor))`` for the leading (n, n) block, ``floor``
    1e-12 of the largest diagonal entry (1 when none is positive): the Jacobi scaling of the
    exact solves (a unit diagonal after scaling; an entry below the floor raised to it).
    Returns False when a diagonal entry is not finite."""
    big = 0.0
    for i in range(n):
        if not math.isfinite(mat[i, i]):
            return False
        big = max(big, mat[i, i])
    floor = 1e-12 * big if big > 0.0 else 1.0
    for i in range(n):
        out[i] = 1.0 / math.sqrt(max(mat[i, i], floor))
    return True


@jit_inline
def cholesky_lower(mat, n, low):
    """Cholesky ``mat = low low^T`` of the leading (n, n) block: the lower triangle of
    ``low`` written, the lower triangle of ``mat`` read (``low`` may be ``mat``: in place).
    Returns False when a pivot is not positive and finite (not positive definite, or NaN /
    inf). The one Cholesky of the compiled routes (linear solves, the drive effects'
    projection, the derivatives' reduced gain)."""
    for j in range(n):
        d = mat[j, j]
        for k in range(j):
            d -= low[j, k] * low[j, k]
        if not (d > 0.0 and math.isfinite(d)):
            return False
        d = math.sqrt(d)
        low[j, j] = d
        for i in range(j + 1, n):
            x = mat[i, j]
            for k in range(j):
                x -= low[i, k] * low[j, k]
            low[i, j] = x / d
    return True


@jit
def kkt_residuals(mass: np.ndarray, bias: np.ndarray, tau: np.ndarray, jac: np.ndarray,
                  target: np.ndarray, acc: np.ndarray, lam: np.ndarray,
                  out: np.ndarray) -> tuple[float, float]:
    """Relative residuals of ``M a + h - tau - J^T lam = 0`` and ``J a = target``.

    Reads only the upper triangle of ``mass`` (Pinocchio's ``crba`` and
    ``constraintDynamics`` fill that one), so a symmetric matrix or Pinocchio's
    half-filled ``data.M`` give the same result. The first residual is relative to the
    largest of ``|M a|``, ``|h - tau|``, ``|J^T lam|``, the second to ``max|J| max|a|``
    and ``max|target|`` (max-abs norms; 0 without rows). Non-finite data give inf.
    Returns ``(eom, closure)`` (also written to ``out``); allocates nothing.
    """
    nv = acc.shape[0]
    nr = jac.shape[0]
    eom_num = 0.0
    eom_den = 1e-300
    for i in range(nv):
        m_a = 0.0
        for j in range(i):
            m_a += mass[j, i] * acc[j]
        for j in range(i, nv):
            m_a += mass[i, j] * acc[j]
        force = 0.0
        for k in range(nr):
            force += jac[k, i] * lam[k]
        rest = bias[i] - tau[i]
        r = abs(m_a + rest - force)
        if not math.isfinite(r):
            eom_num = math.inf
        elif r > eom_num:
            eom_num = r
        eom_den = max(eom_den, abs(m_a), abs(rest), abs(force))
    linear_residual(jac, acc, target, out)     # out[1]: the closure rows' relative residual
    out[0] = eom_num / eom_den
    return out[0], out[1]


@jit
def linear_residual(mat: np.ndarray, x: np.ndarray, rhs: np.ndarray, out: np.ndarray) -> float:
    """``out = (max|mat x - rhs|, that over max(max|rhs|, max|mat| max|x|))`` (inf when not
    finite)."""
    n, m = mat.shape
    num = 0.0
    mmax = 0.0
    xmax = 0.0
    bmax = 0.0
    for j in range(m):
        xmax = max(xmax, abs(x[j]))
    for i in range(n):
        acc = 0.0
        for j in range(m):
            acc += mat[i, j] * x[j]
            mmax = max(mmax, abs(mat[i, j]))
        r = abs(acc - rhs[i])
        if not math.isfinite(r):
            num = math.inf
        elif r > num:
            num = r
        bmax = max(bmax, abs(rhs[i]))
    out[0] = num
    out[1] = num / max(bmax, mmax * xmax, 1e-300)
    return out[1]


@jit
def square_solve(mat: np.ndarray, rhs: np.ndarray, x: np.ndarray, out: np.ndarray) -> float:
    """``x = mat^-1 rhs`` (LU; raises numpy's LinAlgError when singular); returns the
    relative residual of :func:`linear_residual`."""
    x[:] = np.linalg.solve(mat, rhs)
    return linear_residual(mat, x, rhs, out)


@jit
def normal_solve(mat: np.ndarray, rhs: np.ndarray, x: np.ndarray, out: np.ndarray) -> float:
    """``x = (mat^T mat)^-1 mat^T rhs``, the least-squares solution of a tall ``mat`` of full
    column rank (LU of the normal matrix; raises numpy's LinAlgError when it is exactly
    singular); returns the relative residual of :func:`linear_residual` (small only when
    ``rhs`` is in the range of ``mat`` and the solve was accurate)."""
    x[:] = np.linalg.solve(mat.T @ mat, mat.T @ rhs)
    return linear_residual(mat, x, rhs, out)


@jit
def minimum_norm_solve(mat: np.ndarray, rhs: np.ndarray, x: np.ndarray,
                       out: np.ndarray) -> float:
    """``x = mat^T (mat mat^T)^-1 rhs``, the minimum-norm solution of a wide ``mat`` of full
    row rank (LU of the Gram matrix; raises numpy's LinAlgError when it is exactly
    singular); returns the relative residual of :func:`linear_residual`, which exposes a
    rank-deficient or ill-conditioned ``mat``."""
    return minimum_norm_dual_solve(mat, rhs, x, np.empty(mat.shape[0]), out)


@jit
def minimum_norm_dual_solve(mat: np.ndarray, rhs: np.ndarray, x: np.ndarray, z: np.ndarray,
                            out: np.ndarray) -> float:
    """:func:`minimum_norm_solve` that also writes ``z = (mat mat^T)^-1 rhs`` (``x = mat^T
    z``; ``z`` is the multiplier of the equation in ``min 1/2 |x|^2 s.t. mat x = rhs``)."""
    z[:] = np.linalg.solve(mat @ mat.T, rhs)
    x[:] = mat.T @ z
    return linear_residual(mat, x, rhs, out)


@jit
def weighted_minimum_norm_solve(mat: np.ndarray, rhs: np.ndarray, inv_w: np.ndarray,
                                held: np.ndarray, held_u: np.ndarray, x: np.ndarray,
                                z: np.ndarray, out: np.ndarray, rtol: float) -> float:
    """Weighted minimum-norm solution with held entries: ``x`` minimising
    ``sum_j (x_j / inv_w_j)^2`` subject to ``mat x = rhs`` and ``x_i = held_u_i`` for each
    ``i < held.size`` with ``held_i``.

    The free columns scaled by ``inv_w``, the minimum-norm solution ``y`` of the scaled
    system (:func:`minimum_norm_dual_solve`: ``x_free = inv_w y``, and ``z`` (nv,) the
    equation's multiplier: ``x_j / inv_w_j^2 = (mat^T z)_j`` on the free entries). When
    that solve fails or misses ``rtol`` (relative, :func:`linear_residual`; a singular
    Gram matrix), SVD least squares of the scaled system instead and ``z`` NaN. Returns
    the relative residual of the scaled free system (also in ``out``); inf, with ``x``
    NaN, when the data are not finite.
    """
    nv, ncol = mat.shape
    cols = np.empty(ncol, dtype=np.int64)
    target = rhs.copy()
    n_free = 0
    for j in range(ncol):
        if j < held.shape[0] and held[j]:
            x[j] = held_u[j]
            for i in range(nv):
                target[i] -= mat[i, j] * held_u[j]
        else:
            cols[n_free] = j
            n_free += 1
    scaled = np.empty((nv, n_free))
    for k in range(n_free):
        for i in range(nv):
            scaled[i, k] = mat[i, cols[k]] * inv_w[cols[k]]
    y = np.empty(n_free)
    try:
        miss = minimum_norm_dual_solve(scaled, target, y, z, out)
    except Exception:  # noqa: BLE001 - numba catches no narrower class (singular Gram)
        miss = math.inf
    if not miss <= rtol:
        z[:] = np.nan
        if not (np.all(np.isfinite(scaled)) and np.all(np.isfinite(target))):
            x[:] = np.nan
            out[:] = math.inf
            return math.inf
        y[:] = np.linalg.lstsq(scaled, target, max(nv, n_free) * 2.220446049250313e-16)[0]
        miss = linear_residual(scaled, y, target, out)
    for k in range(n_free):
        x[cols[k]] = y[k] * inv_w[cols[k]]
    return miss


@jit
def box_active_set_solve(mat: np.ndarray, rhs: np.ndarray, inv_w: np.ndarray,
                         bounds: np.ndarray, x: np.ndarray, z: np.ndarray, out: np.ndarray,
                         rtol: float, max_steps: int) -> int:
    """Active-set solve of ``min sum_j (x_j / inv_w_j)^2 / 2`` subject to ``mat x = rhs``
    and ``|x_i| <= bounds_i`` for ``i < bounds.size``, from ``x`` = the minimiser without
    the bounds (overwritten).

    Each step holds the entries of the active set at their bound (sign ``s_i`` of the
    entry when it joined) and solves the rest (:func:`weighted_minimum_norm_solve`); the
    bound multiplier of a held entry is ``mu_i = s_i ((mat^T z)_i - x_i / inv_w_i^2)``.
    When every free entry keeps its bound and every ``mu_i >= -rtol max|x_b|`` (``x_b``
    the bounded entries), ``x`` meets the KKT conditions of the convex problem: it is the
    minimiser, and the number of steps is returned. Otherwise the free entries past their
    bound join the set and those with ``mu_i`` below that leave it. Returns 0 (no
    certificate) after ``max_steps`` steps or when a step's Gram solve fails or misses
    ``rtol``.
    """
    n_b = bounds.shape[0]
    nv = mat.shape[0]
    held = np.zeros(n_b, dtype=np.bool_)
    held_u = np.zeros(n_b)
    for i in range(n_b):
        if abs(x[i]) > bounds[i]:
            held[i] = True
            held_u[i] = math.copysign(bounds[i], x[i])
    for step in range(1, max_steps + 1):
        if not weighted_minimum_norm_solve(mat, rhs, inv_w, held, held_u, x, z, out,
                                           rtol) <= rtol or not math.isfinite(z[0]):
            return 0
        size = 1e-300
        for i in range(n_b):
            size = max(size, abs(x[i]))
        changed = False
        for i in range(n_b):
            if held[i]:
                force = 0.0
                for k in range(nv):
                    force += mat[k, i] * z[k]
                mu = force - x[i] / (inv_w[i] * inv_w[i])
                if held_u[i] < 0.0:
                    mu = -mu
                if mu < -rtol * size:
                    held[i] = False
                    changed = True
            elif abs(x[i]) > bounds[i]:
                held[i] = True
                held_u[i] = math.copysign(bounds[i], x[i])
                changed = True
        if not changed:
            return step
    return 0


@jit
def within_bounds(u: np.ndarray, bounds: np.ndarray, rtol: float) -> bool:
    """Whether ``|u_i| <= bounds_i (1 + rtol)`` for every ``i`` (False on NaN)."""
    for i in range(u.shape[0]):
        if not abs(u[i]) <= bounds[i] * (1.0 + rtol):
            return False
    return True


#: status of :func:`nullspace_forward_solve`
NULLSPACE_OK, NULLSPACE_NOT_POSITIVE, NULLSPACE_NOT_FINITE = 0, 1, 2


@jit_inline
def _add_pseudo_inverse(left, right, sv, r, vec, out):
    """``out += sum_{i < r} right[:, i] (left[:, i] . vec) / sv[i]``: a rank-``r``
    pseudo-inverse of an SVD applied to ``vec`` (``left`` / ``right`` the singular vectors
    as columns; ``U, V`` for ``J^+``, ``V, U`` for ``J^+T``)."""
    for i in range(r):
        c = 0.0
        for k in range(vec.shape[0]):
            c += left[k, i] * vec[k]
        c /= sv[i]
        for j in range(out.shape[0]):
            out[j] += right[j, i] * c


@jit
def nullspace_forward_solve(mass: np.ndarray, bias: np.ndarray, tau: np.ndarray,
                            jac: np.ndarray, target: np.ndarray, rank: int,
                            acc: np.ndarray, lam: np.ndarray) -> int:
    """Exact solve of ``M a + h = tau + J^T lam``, ``J a = target`` for a ``J`` (nr, nv) of
    rank ``rank`` (redundant rows allowed), scaled by the problem's own magnitudes.

    The SVD ``J = U S V^T`` gives the particular solution ``a_p = V_r S_r^-1 U_r^T target``
    (``r = rank``), ``N = V[:, rank:]`` an orthonormal basis of the closures' null space,
    and the reduced system ``(N^T M N) z = N^T (tau - h - M a_p)`` solved by Cholesky
    after its Jacobi scaling (``E = diag(N^T M N)^(1/2)``, an entry below 1e-12 of the
    largest raised to it: unit diagonal whatever the masses), ``a = a_p + N z``. The
    multipliers solve ``J^T lam = M a + h - tau`` in the least-squares, minimum-norm sense
    on the same SVD. Reads only the upper triangle of ``mass``
    (Pinocchio's ``data.M``).

    Writes ``acc`` (nv,) and ``lam`` (nr,); returns :data:`NULLSPACE_OK`,
    :data:`NULLSPACE_NOT_POSITIVE` (``N^T M N`` not positive definite: the mass matrix
    is not positive on the motions the closures allow) or :data:`NULLSPACE_NOT_FINITE`.
    Does not verify the answer: the callers do, on the unscaled system.
    """
    nv = acc.shape[0]
    nr = jac.shape[0]
    m_full = np.empty((nv, nv))
    for i in range(nv):
        for j in range(i, nv):
            m_full[i, j] = mass[i, j]
            m_full[j, i] = mass[i, j]
    js = np.zeros((max(nr, 1), nv))
    ts = np.zeros(max(nr, 1))
    for k in range(nr):
        for j in range(nv):
            js[k, j] = jac[k, j]
        ts[k] = target[k]
    u, sv, vt = np.linalg.svd(js)
    r = min(rank, sv.shape[0]) if nr else 0
    a_p = np.zeros(nv)
    _add_pseudo_inverse(u, vt.T, sv, r, ts, a_p)                # V_r S_r^-1 U_r^T target
    m = nv - r
    basis = np.ascontiguousarray(vt[r:, :].T)          # (nv, m)
    red = basis.T @ (m_full @ basis)
    rhs = basis.T @ (tau - bias - m_full @ a_p)
    einv = np.empty(m)
    if not diagonal_scaling(red, m, einv):
        return NULLSPACE_NOT_FINITE
    for i in range(m):
        rhs[i] *= einv[i]
        for j in range(m):
            red[i, j] *= einv[i] * einv[j]
    # Cholesky of the scaled reduced matrix (lower triangle, in place), two triangular solves
    if not cholesky_lower(red, m, red):
        return NULLSPACE_NOT_POSITIVE
    z = rhs.copy()
    for i in range(m):
        for k in range(i):
            z[i] -= red[i, k] * z[k]
        z[i] /= red[i, i]
    for i in range(m - 1, -1, -1):
        for k in range(i + 1, m):
            z[i] -= red[k, i] * z[k]
        z[i] /= red[i, i]
    for i in range(m):
        z[i] *= einv[i]
    a = a_p + basis @ z
    for j in range(nv):
        acc[j] = a[j]
    # J^T lam = f: least squares on the same SVD
    for k in range(nr):
        lam[k] = 0.0
    if r:
        _add_pseudo_inverse(vt.T, u, sv, r, m_full @ a + bias - tau, lam)  # U_r S_r^-1 V_r^T f
    for j in range(nv):
        if not math.isfinite(acc[j]):
            return NULLSPACE_NOT_FINITE
    return NULLSPACE_OK


@jit
def reduced_kkt_solve(mass: np.ndarray, bias: np.ndarray, tau: np.ndarray, jac: np.ndarray,
                      target: np.ndarray, rows: np.ndarray, acc: np.ndarray,
                      lam: np.ndarray) -> int:
    """Exact solve of ``M a + h = tau + J^T lam``, ``J a = target`` on the independent rows
    ``rows`` of ``J`` (int array, sorted; the other multipliers are set to zero): the KKT
    system ``[M J_r^T; J_r 0] (a, -lam_r) = (tau - h, target_r)`` in scaled form
    (coordinates by ``diag(M)^(1/2)``, an entry below 1e-12 of the largest raised to it;
    rows of ``J_r`` normalised), by Gaussian elimination with partial pivoting. Reads only
    the upper triangle of ``mass``.

    Writes ``acc`` (nv,) and ``lam`` (nr,); returns :data:`NULLSPACE_OK`,
    :data:`NULLSPACE_NOT_POSITIVE` (a zero pivot: the system is singular on these rows) or
    :data:`NULLSPACE_NOT_FINITE`. Does not verify: the dropped rows hold only when they
    depend on the kept ones at this state, so the callers check every row
    (:func:`kkt_residuals`) and fall back to :func:`nullspace_forward_solve`.
    """
    nv = acc.shape[0]
    r = rows.shape[0]
    n = nv + r
    dinv = np.empty(nv)
    if not diagonal_scaling(mass, nv, dinv):
        return NULLSPACE_NOT_FINITE
    kkt = np.zeros((n, n))
    rhs = np.empty(n)
    for i in range(nv):
        for j in range(i, nv):
            kkt[i, j] = mass[i, j] * dinv[i] * dinv[j]
            kkt[j, i] = kkt[i, j]
        rhs[i] = (tau[i] - bias[i]) * dinv[i]
    rscale = np.empty(r)
    for k in range(r):
        row = rows[k]
        norm = 0.0
        for j in range(nv):
            x = jac[row, j] * dinv[j]
            norm += x * x
        norm = math.sqrt(norm)
        if not (norm > 0.0 and math.isfinite(norm)):
            return NULLSPACE_NOT_FINITE if not math.isfinite(norm) else NULLSPACE_NOT_POSITIVE
        rscale[k] = 1.0 / norm
        for j in range(nv):
            x = jac[row, j] * dinv[j] * rscale[k]
            kkt[nv + k, j] = x
            kkt[j, nv + k] = x
        rhs[nv + k] = target[row] * rscale[k]
    # Gaussian elimination with partial pivoting
    top = 0.0
    for i in range(n):
        for j in range(n):
            top = max(top, abs(kkt[i, j]))
    for c in range(n):
        p = c
        for i in range(c + 1, n):
            if abs(kkt[i, c]) > abs(kkt[p, c]):
                p = i
        if not abs(kkt[p, c]) > 1e-14 * top:
            return NULLSPACE_NOT_POSITIVE
        if p != c:
            for j in range(n):
                kkt[c, j], kkt[p, j] = kkt[p, j], kkt[c, j]
            rhs[c], rhs[p] = rhs[p], rhs[c]
        for i in range(c + 1, n):
            f = kkt[i, c] / kkt[c, c]
            if f != 0.0:
                for j in range(c, n):
                    kkt[i, j] -= f * kkt[c, j]
                rhs[i] -= f * rhs[c]
    for i in range(n - 1, -1, -1):
        x = rhs[i]
        for j in range(i + 1, n):
            x -= kkt[i, j] * rhs[j]
        rhs[i] = x / kkt[i, i]
    for j in range(nv):
        acc[j] = rhs[j] * dinv[j]
        if not math.isfinite(acc[j]):
            return NULLSPACE_NOT_FINITE
    for k in range(lam.shape[0]):
        lam[k] = 0.0
    for k in range(r):
        lam[rows[k]] = -rhs[nv + k] * rscale[k]
    return NULLSPACE_OK

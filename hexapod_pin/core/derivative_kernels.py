"""Compiled (numba) kernels of :mod:`hexapod_pin.core.dynamics_derivatives`: the motion of
many frames and its partial derivatives from the world joint Jacobian of the tree
(:func:`frame_rates_kernel`), the closures' rows among them (:func:`closure_rows_kernel`)
and the closure forces on the anchors' joints (:func:`anchor_forces_kernel`), the null-space
factor of the linearised KKT system
(:func:`reduced_gain_kernel`), and the chain after Pinocchio's RNEA derivatives: the
partials ``E_q``, ``E_v`` with the point closures' force turning and the factorisation
(:func:`linearize_kernel`), the verified solve of the linearised KKT system
(:func:`kkt_solve_kernel`, :func:`kkt_along_kernel`). The formulas: the docstrings of
``frame_rates`` and ``KKTLinearization`` and ``docs/derivations.md`` section 8.1.

Conventions: spatial motions are ``(linear, angular)``; ``J`` is Pinocchio's world-axes
joint Jacobian (``data.J`` of any pass at ``q``), passed transposed (nv, 6); the frame
outputs are (n, 6) and (n, 6, nv). Kernels never raise: they return a status.
"""

from __future__ import annotations

import math

import numpy as np

from .closure_motion import row_basis_kernel
from .compiled import jit
from .linear_kernels import cholesky_lower
from .pose import euler_rates


@jit
def _cross(a0, a1, a2, b0, b1, b2):
    """``a x b`` of two 3-vectors given by their components."""
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@jit
def _motion_cross(m, x, out):
    """``out = m x x`` (6,) of spatial motions ``m``, ``x`` (6,): ``(w x x_v + v x x_w, w x
    x_w)``."""
    c0, c1, c2 = _cross(m[3], m[4], m[5], x[0], x[1], x[2])
    d0, d1, d2 = _cross(m[0], m[1], m[2], x[3], x[4], x[5])
    out[0], out[1], out[2] = c0 + d0, c1 + d1, c2 + d2
    out[3], out[4], out[5] = _cross(m[3], m[4], m[5], x[3], x[4], x[5])


@jit
def _at_origin(block, k, c, src, o0, o1, o2):
    """``block[k, :, c] = (src_lin - o x src_ang, src_ang)``: a world-origin column moved to
    the point ``o``."""
    s0, s1, s2 = _cross(o0, o1, o2, src[3], src[4], src[5])
    block[k, 0, c] = src[0] - s0
    block[k, 1, c] = src[1] - s1
    block[k, 2, c] = src[2] - s2
    block[k, 3, c] = src[3]
    block[k, 4, c] = src[4]
    block[k, 5, c] = src[5]


@jit
def _add_cross(block, k, h, c, x0, x1, x2, y0, y1, y2):
    """``block[k, h:h+3, c] += x x y``."""
    s0, s1, s2 = _cross(x0, x1, x2, y0, y1, y2)
    block[k, h, c] += s0
    block[k, h + 1, c] += s1
    block[k, h + 2, c] += s2


@jit
def _rotate_back(block, k, nv, rot):
    """``block[k, 3-blocks, :] = R_k^T block[k, 3-blocks, :]``."""
    for c in range(nv):
        for h in (0, 3):
            y0, y1, y2 = block[k, h, c], block[k, h + 1, c], block[k, h + 2, c]
            for r in range(3):
                block[k, h + r, c] = rot[k, 0, r] * y0 + rot[k, 1, r] * y1 + rot[k, 2, r] * y2


@jit
def frame_rates_kernel(jac_t, v, a, joint_support, col_joint, col_parent, col_inner, joints,
                       support, rot, pos, world, acc, acc_q, acc_v, jac, vel, vel_q):
    """The :class:`~hexapod_pin.core.dynamics_derivatives.FrameRates` fields (written into
    ``acc, acc_q, acc_v, jac, vel, vel_q``, zeros on entry) of frames on ``joints`` (n,),
    supported by the coordinates where ``support`` (n, nv) is True, at world rotations
    ``rot`` (n, 3, 3) and origins ``pos`` (n, 3); world rows where ``world`` (n,).

    ``jac_t`` (nv, 6): ``J^T`` (C-contiguous; ``J`` depends on ``q`` only);
    ``joint_support`` (njoints, nv): the coordinates supporting each joint (row 0, the
    universe, empty); ``col_joint`` (nv,) the joint of each coordinate, ``col_parent``
    (nv,) its parent, ``col_inner`` (nv,) whether that parent is not the universe."""
    n_joints, nv = joint_support.shape
    ov = np.zeros((n_joints, 6))
    oa = np.zeros((n_joints, 6))
    for j in range(n_joints):                 # the joints' world spatial velocities
        for c in range(nv):
            if joint_support[j, c]:
                for r in range(6):
                    ov[j, r] += jac_t[c, r] * v[c]
    djac_t = np.empty((nv, 6))                # dJ_c = ov_i x J_c (Pinocchio's data.dJ)
    for c in range(nv):
        _motion_cross(ov[col_joint[c]], jac_t[c], djac_t[c])
    for j in range(n_joints):                 # ... and accelerations
        for c in range(nv):
            if joint_support[j, c]:
                for r in range(6):
                    oa[j, r] += jac_t[c, r] * a[c] + djac_t[c, r] * v[c]
    vt, at = np.empty(6), np.empty(6)
    vq, aq, av, extra = np.empty(6), np.empty(6), np.empty(6), np.empty(6)
    for k in range(joints.shape[0]):
        b = joints[k]
        o0, o1, o2 = pos[k, 0], pos[k, 1], pos[k, 2]
        for c in range(nv):
            if not support[k, c]:
                continue
            p = col_parent[c]
            for r in range(6):
                vt[r] = ov[p, r] - ov[b, r]
                at[r] = oa[p, r] - oa[b, r]
            _motion_cross(vt, jac_t[c], vq)
            _motion_cross(at, jac_t[c], aq)
            if col_inner[c]:
                _motion_cross(vt, djac_t[c], extra)
                for r in range(6):
                    aq[r] += extra[r]
            for r in range(6):
                av[r] = vq[r] + djac_t[c, r]
            # at the frame origin (the motion of the origin itself comes below)
            _at_origin(jac, k, c, jac_t[c], o0, o1, o2)
            _at_origin(vel_q, k, c, vq, o0, o1, o2)
            _at_origin(acc_q, k, c, aq, o0, o1, o2)
            _at_origin(acc_v, k, c, av, o0, o1, o2)
            for r in range(6):
                vel[k, r] += jac[k, r, c] * v[c]
                acc[k, r] += jac[k, r, c] * a[c] + 0.5 * acc_v[k, r, c] * v[c]
        for c in range(nv):       # + [x_ang]_x J_o,lin: the origin moves with the frame
            if not support[k, c]:
                continue
            j0, j1, j2 = jac[k, 0, c], jac[k, 1, c], jac[k, 2, c]
            _add_cross(vel_q, k, 0, c, vel[k, 3], vel[k, 4], vel[k, 5], j0, j1, j2)
            _add_cross(acc_q, k, 0, c, acc[k, 3], acc[k, 4], acc[k, 5], j0, j1, j2)
        if world[k]:              # classical: + w x v
            w0, w1, w2 = vel[k, 3], vel[k, 4], vel[k, 5]
            l0, l1, l2 = vel[k, 0], vel[k, 1], vel[k, 2]
            s0, s1, s2 = _cross(w0, w1, w2, l0, l1, l2)
            acc[k, 0] += s0
            acc[k, 1] += s1
            acc[k, 2] += s2
            for c in range(nv):
                if not support[k, c]:
                    continue
                _add_cross(acc_q, k, 0, c, w0, w1, w2, vel_q[k, 0, c], vel_q[k, 1, c],
                           vel_q[k, 2, c])
                _add_cross(acc_q, k, 0, c, -l0, -l1, -l2, vel_q[k, 3, c], vel_q[k, 4, c],
                           vel_q[k, 5, c])
                _add_cross(acc_v, k, 0, c, w0, w1, w2, jac[k, 0, c], jac[k, 1, c],
                           jac[k, 2, c])
                _add_cross(acc_v, k, 0, c, -l0, -l1, -l2, jac[k, 3, c], jac[k, 4, c],
                           jac[k, 5, c])
        else:                     # LOCAL axes: R^T x, R^T (dx + [x]_x J_o,ang)
            for c in range(nv):
                if not support[k, c]:
                    continue
                j0, j1, j2 = jac[k, 3, c], jac[k, 4, c], jac[k, 5, c]
                for h in (0, 3):
                    _add_cross(vel_q, k, h, c, vel[k, h], vel[k, h + 1], vel[k, h + 2],
                               j0, j1, j2)
                    _add_cross(acc_q, k, h, c, acc[k, h], acc[k, h + 1], acc[k, h + 2],
                               j0, j1, j2)
            _rotate_back(vel_q, k, nv, rot)
            _rotate_back(acc_q, k, nv, rot)
            _rotate_back(acc_v, k, nv, rot)
            _rotate_back(jac, k, nv, rot)
            for h in (0, 3):
                y0, y1, y2 = vel[k, h], vel[k, h + 1], vel[k, h + 2]
                z0, z1, z2 = acc[k, h], acc[k, h + 1], acc[k, h + 2]
                for r in range(3):
                    vel[k, h + r] = rot[k, 0, r] * y0 + rot[k, 1, r] * y1 + rot[k, 2, r] * y2
                    acc[k, h + r] = rot[k, 0, r] * z0 + rot[k, 1, r] * z1 + rot[k, 2, r] * z2


@jit
def reduced_gain_kernel(basis, mass, gain):
    """``gain = N L^-T`` (nv, m) with ``N^T M N = L L^T`` (Cholesky of the symmetrised
    ``N^T M N``; ``basis`` ``N`` (nv, m), ``mass`` ``M`` (nv, nv)), so that ``gain gain^T =
    N (N^T M N)^-1 N^T``. Returns 0, or 1 when ``N^T M N`` is not positive definite (or
    not finite)."""
    nv, m = basis.shape
    reduced = basis.T @ (mass @ basis)
    for i in range(m):                         # symmetrised (the lower triangle is read)
        for j in range(i):
            reduced[i, j] = 0.5 * (reduced[i, j] + reduced[j, i])
    low = np.zeros((m, m))
    if not cholesky_lower(reduced, m, low):
        return 1
    # gain = N L^-T: solve gain L^T = N row by row (forward substitution on L)
    for r in range(nv):
        for j in range(m):
            s = basis[r, j]
            for p in range(j):
                s -= gain[r, p] * low[j, p]
            gain[r, j] = s / low[j, j]
    return 0


@jit
def _max_abs(x):
    """Largest absolute entry of the 2-D ``x`` (0 when empty, NaN when any is NaN), as
    :func:`~hexapod_pin.core.checks.max_abs`."""
    out = 0.0
    for i in range(x.shape[0]):
        for j in range(x.shape[1]):
            val = abs(x[i, j])
            if math.isnan(val):
                return val
            out = max(out, val)
    return out


#: :func:`linearize_kernel`'s statuses: factored; ``N^T M N`` not positive definite;
#: rows not independent (or none: the caller's SVD route); NaN / inf in ``J_c``
LINEARIZED, NOT_POSITIVE, DEPENDENT_ROWS, NOT_FINITE = 0, 1, 2, 3


@jit
def point_turning_kernel(anchor_jac, forces, point_rows, point_anchors, out):
    """``out -= sum_k (J1_lin^T [l_k]_x J1_ang - J2_lin^T [l_k]_x J2_ang)`` (nv, nv): the
    world-held point closure forces ``l_k = forces[point_rows[3k:3k+3]]`` turning with
    their anchors (world Jacobians ``anchor_jac[point_anchors[2k]]`` and ``[2k+1]``, of
    ``anchor_jac`` (2 n, 6, nv))."""
    nv = out.shape[1]
    turned = np.empty((3, nv))
    for k in range(point_rows.shape[0] // 3):
        l0, l1, l2 = forces[point_rows[3 * k]], forces[point_rows[3 * k + 1]], \
            forces[point_rows[3 * k + 2]]
        for side in range(2):
            anchor = point_anchors[2 * k + side]
            sign = 1.0 if side == 0 else -1.0
            for c in range(nv):                  # [l]_x J_ang
                turned[0, c], turned[1, c], turned[2, c] = _cross(
                    l0, l1, l2, anchor_jac[anchor, 3, c], anchor_jac[anchor, 4, c],
                    anchor_jac[anchor, 5, c])
            for r in range(nv):                  # - sign J_lin^T [l]_x J_ang
                j0 = sign * anchor_jac[anchor, 0, r]
                j1 = sign * anchor_jac[anchor, 1, r]
                j2 = sign * anchor_jac[anchor, 2, r]
                if j0 == 0.0 and j1 == 0.0 and j2 == 0.0:
                    continue
                for c in range(nv):
                    out[r, c] -= j0 * turned[0, c] + j1 * turned[1, c] + j2 * turned[2, c]


@jit
def linearize_kernel(mass_up, dtau_dq, dtau_dv, anchor_jac, forces, point_rows,
                     point_anchors, damping, jac, rtol, mass, e_q, e_v):
    """The partials of ``E`` and the factors of ``KKTLinearization`` from Pinocchio's
    ``computeRNEADerivatives`` (``dtau_dq``, ``dtau_dv`` (nv, nv), ``mass_up``: ``M``
    filled on and above its diagonal) with the closure forces as external forces.

    Writes ``mass`` (symmetric ``M``), ``e_v = dtau_dv + diag(damping)`` and ``e_q =
    dtau_dq -`` the point forces' turning (:func:`point_turning_kernel`). Then factors
    ``J_c`` (``jac`` (n_rows, nv)): the pivoted QR of
    :func:`~hexapod_pin.core.closure_motion.row_basis_kernel` (``rtol``), and, when
    every row is independent, the null-space basis ``N``, ``J_c^+`` and ``G = N L^-T``
    (:func:`reduced_gain_kernel`).

    Returns ``(status, N, J_c^+, G, max |M|, max |J_c|)``, status one of
    :data:`LINEARIZED`, :data:`NOT_POSITIVE`, :data:`DEPENDENT_ROWS` (the factors then
    empty), :data:`NOT_FINITE`."""
    nv = mass.shape[0]
    for i in range(nv):
        for j in range(nv):
            mass[i, j] = mass_up[i, j] if j >= i else mass_up[j, i]
            e_q[i, j] = dtau_dq[i, j]
            e_v[i, j] = dtau_dv[i, j]
        e_v[i, i] += damping[i]
    point_turning_kernel(anchor_jac, forces, point_rows, point_anchors, e_q)
    n_rows = jac.shape[0]
    norm_m, norm_j = _max_abs(mass), _max_abs(jac)
    empty = np.zeros((nv, 0))
    if n_rows == 0 or n_rows > nv:
        return DEPENDENT_ROWS, empty, empty, empty, norm_m, norm_j
    rank, piv, q_mat, right = row_basis_kernel(jac, rtol)
    if rank < 0:
        return NOT_FINITE, empty, empty, empty, norm_m, norm_j
    if rank < n_rows:
        return DEPENDENT_ROWS, empty, empty, empty, norm_m, norm_j
    basis = np.ascontiguousarray(q_mat[:, rank:])
    pinv = np.empty((nv, n_rows))
    for i in range(rank):                        # J_c[rows] pinv = I, in range(J_c^T)
        pinv[:, piv[i]] = right[:, i]
    gain = np.empty(basis.shape)
    if reduced_gain_kernel(basis, mass, gain):
        return NOT_POSITIVE, basis, pinv, gain, norm_m, norm_j
    return LINEARIZED, basis, pinv, gain, norm_m, norm_j


@jit
def kkt_solve_kernel(mass, jac, pinv, gain, norm_m, norm_j, rhs_e, rhs_c):
    """``(da, dlambda, eom, con)``: ``M da - J_c^T dlambda = rhs_e``, ``J_c da = rhs_c``
    ((nv, k), (n_rows, k)) by ``da = J_c^+ rhs_c + G G^T (rhs_e - M J_c^+ rhs_c)``,
    ``dlambda = J_c^+T (M da - rhs_e)``, and the two residuals relative to ``max(1, |rhs|,
    |M| |da|)`` and ``max(1, |rhs_c|, |J_c| |da|)`` (``max |M|``, ``max |J_c|``: ``norm_m``,
    ``norm_j``; max-abs norms) that the caller checks."""
    da_p = pinv @ rhs_c
    da = da_p + gain @ (gain.T @ (rhs_e - mass @ da_p))
    force = mass @ da - rhs_e
    dlam = pinv.T @ force
    size = _max_abs(da)
    eom = _max_abs(force - jac.T @ dlam) / max(1.0, _max_abs(rhs_e), norm_m * size)
    con = _max_abs(jac @ da - rhs_c) / max(1.0, _max_abs(rhs_c), norm_j * size)
    return da, dlam, eom, con


@jit
def kkt_along_kernel(e_q, e_v, c_q, c_v, mass, jac, pinv, gain, norm_m, norm_j, dq, dv,
                     force):
    """:func:`kkt_solve_kernel` along state directions ``(dq, dv)`` (nv, k) with the
    generalised forces ``force`` (nv, k): ``rhs_e = force - E_q dq - E_v dv``, ``rhs_c =
    -(C_q dq + C_v dv)``."""
    rhs_e = force - e_q @ dq - e_v @ dv
    rhs_c = -(c_q @ dq) - c_v @ dv
    return kkt_solve_kernel(mass, jac, pinv, gain, norm_m, norm_j, rhs_e, rhs_c)


@jit
def closure_rows_kernel(acc_q, acc_v, jac, vel_q, rows1, rows2):
    """``(acc_q, acc_v, jac, vel_q)`` (n_rows, nv) of the closures: the rows ``rows1`` minus
    the rows ``rows2`` of the same fields (n, 6, nv) of the anchors' frame rates, rows
    counted in the flattened (6 n, nv) fields."""
    nv = acc_q.shape[2]
    n_rows = rows1.shape[0]
    out_q, out_v = np.empty((n_rows, nv)), np.empty((n_rows, nv))
    out_j, out_vq = np.empty((n_rows, nv)), np.empty((n_rows, nv))
    for i in range(n_rows):
        f1, r1, f2, r2 = rows1[i] // 6, rows1[i] % 6, rows2[i] // 6, rows2[i] % 6
        for c in range(nv):
            out_q[i, c] = acc_q[f1, r1, c] - acc_q[f2, r2, c]
            out_v[i, c] = acc_v[f1, r1, c] - acc_v[f2, r2, c]
            out_j[i, c] = jac[f1, r1, c] - jac[f2, r2, c]
            out_vq[i, c] = vel_q[f1, r1, c] - vel_q[f2, r2, c]
    return out_q, out_v, out_j, out_vq


@jit
def anchor_forces_kernel(rot, forces, point_rows, point_anchors, local, to_joints):
    """The anchors' spatial forces summed on their joints, (n_touched, 6) ``to_joints @
    local``: ``local`` (2 n, 6) (each anchor's axes; a weld's already set) gets a point
    closure's ``R1^T l_k`` on anchor 1 and ``-R2^T l_k`` on anchor 2 (``l_k =
    forces[point_rows[3k:3k+3]]`` in world axes, ``rot`` (2 n, 3, 3) the anchors' world
    rotations, anchors ``point_anchors[2k]``, ``[2k+1]``)."""
    for k in range(point_rows.shape[0] // 3):
        l0, l1, l2 = forces[point_rows[3 * k]], forces[point_rows[3 * k + 1]], \
            forces[point_rows[3 * k + 2]]
        for side in range(2):
            anchor = point_anchors[2 * k + side]
            sign = 1.0 if side == 0 else -1.0
            for r in range(3):
                local[anchor, r] = sign * (rot[anchor, 0, r] * l0 + rot[anchor, 1, r] * l1
                                           + rot[anchor, 2, r] * l2)
    return (to_joints @ local.reshape(-1)).reshape(-1, 6)


@jit
def small_inverse(b):
    """``b^-1`` (n, n) of a small square matrix by Gauss-Jordan elimination with partial
    pivoting (no LAPACK call: the derivatives' ``B`` are at most a few dozen wide); NaN
    where a pivot vanishes (``b`` exactly singular or not finite)."""
    n = b.shape[0]
    a = np.empty((n, n))
    inv = np.zeros((n, n))
    for r in range(n):
        inv[r, r] = 1.0
        for c in range(n):
            a[r, c] = b[r, c]
    for col in range(n):
        piv, best = col, abs(a[col, col])
        for r in range(col + 1, n):
            if abs(a[r, col]) > best:
                piv, best = r, abs(a[r, col])
        if not best > 0.0:
            inv[:, :] = np.nan
            return inv
        if piv != col:
            for c in range(n):
                a[col, c], a[piv, c] = a[piv, c], a[col, c]
                inv[col, c], inv[piv, c] = inv[piv, c], inv[col, c]
        for r in range(n):               # the pivot row unscaled: equal rows cancel exactly
            if r == col or a[r, col] == 0.0:
                continue
            f = a[r, col] / a[col, col]
            for c in range(n):
                a[r, c] -= f * a[col, c]
                inv[r, c] -= f * inv[col, c]
    for r in range(n):
        d = 1.0 / a[r, r]
        for c in range(n):
            inv[r, c] *= d
    return inv


@jit
def implicit_kernel(b, partials):
    """The implicit-function theorem for a map ``X(y, z)`` solved for ``z``: with the square
    ``b = dX/dz`` (n, n) and ``partials = dX/dy`` (n, k), the partials of ``z(y, X)``:
    ``(B^-1, -B^-1 partials, residual)`` (:func:`small_inverse`), ``residual`` the relative
    miss of ``b B^-1 = I`` (max-abs, over ``max(1, |b| |B^-1|)``; inf when anything is not
    finite, e.g. a singular ``b``)."""
    n = b.shape[0]
    inv = small_inverse(b)
    out = -(inv @ partials)
    check = b @ inv
    for i in range(n):
        check[i, i] -= 1.0
    miss = _max_abs(check)
    if not math.isfinite(miss) or not math.isfinite(_max_abs(out)):
        return inv, out, math.inf
    return inv, out, miss / max(1.0, _max_abs(b) * _max_abs(inv))


@jit
def pose_rates_kernel(pose, full_rotation):
    """The map (dim, dim) from pose-coordinate rates to the world tangent ``(dp,
    dtheta)`` of a pose (dim,): ``blockdiag(I, E(rpy))`` with all three angles in the
    pose (last, :func:`~hexapod_pin.core.pose.euler_rates`), else the identity."""
    n = pose.shape[0]
    out = np.eye(n)
    if full_rotation:
        euler_rates(pose[n - 2], pose[n - 1], out[n - 3:, n - 3:])
    return out


@jit
def forward_from_inverse_kernel(part, tau, u, pose, full_rotation):
    """The forward-dynamics derivatives of a square-actuated robot from its inverse-dynamics
    partials ``part`` (n, 4 n) (columns: world tangent, twist, twist_dot, wrench) at the
    forward-dynamics answer, by :func:`implicit_kernel` with ``B = d ID / d twist_dot``:
    ``(d_pose, d_world, d_twist, d_u, d_wrench, miss, force_miss)``, each derivative (n, n)
    C-contiguous, ``d_pose = d_world @`` :func:`pose_rates_kernel` of ``pose`` (n,),
    ``miss`` the solve's relative residual and ``force_miss`` the relative miss of the
    inverse dynamics' forces ``tau`` against the forces ``u`` (n,) the forward dynamics
    was given."""
    n = part.shape[0]
    others = np.empty((n, 3 * n))
    others[:, :2 * n] = part[:, :2 * n]
    others[:, 2 * n:] = part[:, 3 * n:]
    inv, sol, miss = implicit_kernel(np.ascontiguousarray(part[:, 2 * n:3 * n]), others)
    d_world = np.ascontiguousarray(sol[:, :n])
    scale, worst = 1.0, 0.0
    for i in range(n):
        scale = max(scale, abs(u[i]), abs(tau[i]))
        worst = max(worst, abs(tau[i] - u[i]))
    if not math.isfinite(worst):
        worst = math.inf
    return (d_world @ pose_rates_kernel(pose, full_rotation), d_world, np.ascontiguousarray(sol[:, n:2 * n]),
            inv, np.ascontiguousarray(sol[:, 2 * n:]), miss,
            worst / scale)

"""Compiled (numba) kernels of :mod:`hexapod_pin.core.dynamics_derivatives`: the motion of
many frames and its partial derivatives from the world joint Jacobian of the tree
(:func:`frame_rates_kernel`), and the null-space factor of the linearised KKT system
(:func:`reduced_gain_kernel`). The formulas: the docstrings of ``frame_rates`` and
``KKTLinearization`` and ``docs/derivations.md`` section 8.1.

Conventions: spatial motions are ``(linear, angular)``; ``J`` is Pinocchio's world-axes
joint Jacobian (``data.J`` of any pass at ``q``), passed transposed (nv, 6); the frame
outputs are (n, 6) and (n, 6, nv). Kernels never raise: they return a status.
"""

from __future__ import annotations

import math

import numpy as np

from .compiled import jit


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
    low = np.zeros((m, m))
    for j in range(m):
        diag = reduced[j, j]
        for p in range(j):
            diag -= low[j, p] * low[j, p]
        if not diag > 0.0 or not math.isfinite(diag):
            return 1
        low[j, j] = math.sqrt(diag)
        for i in range(j + 1, m):
            s = 0.5 * (reduced[i, j] + reduced[j, i])
            for p in range(j):
                s -= low[i, p] * low[j, p]
            low[i, j] = s / low[j, j]
    # gain = N L^-T: solve gain L^T = N row by row (forward substitution on L)
    for r in range(nv):
        for j in range(m):
            s = basis[r, j]
            for p in range(j):
                s -= gain[r, p] * low[j, p]
            gain[r, j] = s / low[j, j]
    return 0

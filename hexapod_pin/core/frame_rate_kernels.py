"""The compiled kernel of :func:`~hexapod_pin.core.dynamics_derivatives.frame_rates`: the
motion of many frames and its partial derivatives from the world-axes joint quantities of
one ``pin.computeForwardKinematicsDerivatives`` pass (``data.J``, ``data.dJ``), all frames
in one call (the formulas: that function's docstring and ``docs/derivations.md`` section
8.1).

Conventions: spatial motions are ``(linear, angular)``; ``J`` and ``dJ`` (6, nv) are
Pinocchio's world-axes joint Jacobian columns and their ``ov_i x J_c``; the frame outputs
are (n, 6) and (n, 6, nv).
"""

from __future__ import annotations

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
def frame_rates_kernel(jac_t, djac_t, v, a, joint_support, col_parent, col_inner, joints,
                       support, rot, pos, world, acc, acc_q, acc_v, jac, vel, vel_q):
    """The :class:`~hexapod_pin.core.dynamics_derivatives.FrameRates` fields (written into
    ``acc, acc_q, acc_v, jac, vel, vel_q``, zeros on entry) of frames on ``joints`` (n,),
    supported by the coordinates where ``support`` (n, nv) is True, at world rotations
    ``rot`` (n, 3, 3) and origins ``pos`` (n, 3); world rows where ``world`` (n,).

    ``jac_t``, ``djac_t`` (nv, 6): ``J^T`` and ``dJ^T`` (C-contiguous);
    ``joint_support`` (njoints, nv): the coordinates supporting each joint (row 0, the
    universe, empty); ``col_parent`` (nv,) the parent joint of each coordinate's joint,
    ``col_inner`` (nv,) whether that parent is not the universe."""
    n_joints, nv = joint_support.shape
    ov = np.zeros((n_joints, 6))
    oa = np.zeros((n_joints, 6))
    for j in range(n_joints):                 # the joints' world spatial motions
        for c in range(nv):
            if joint_support[j, c]:
                for r in range(6):
                    ov[j, r] += jac_t[c, r] * v[c]
                    oa[j, r] += jac_t[c, r] * a[c] + djac_t[c, r] * v[c]
    vt, at = np.empty(6), np.empty(6)
    vq, aq, extra = np.empty(6), np.empty(6), np.empty(6)
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
            # at the frame origin: lin - o x ang (the q-dependence of o comes below)
            for block, src in ((jac, jac_t[c]), (vel_q, vq), (acc_q, aq)):
                s0, s1, s2 = _cross(o0, o1, o2, src[3], src[4], src[5])
                block[k, 0, c] = src[0] - s0
                block[k, 1, c] = src[1] - s1
                block[k, 2, c] = src[2] - s2
                block[k, 3, c], block[k, 4, c], block[k, 5, c] = src[3], src[4], src[5]
            s0, s1, s2 = _cross(o0, o1, o2, vq[3] + djac_t[c, 3], vq[4] + djac_t[c, 4],
                                vq[5] + djac_t[c, 5])
            acc_v[k, 0, c] = vq[0] + djac_t[c, 0] - s0
            acc_v[k, 1, c] = vq[1] + djac_t[c, 1] - s1
            acc_v[k, 2, c] = vq[2] + djac_t[c, 2] - s2
            for r in range(3, 6):
                acc_v[k, r, c] = vq[r] + djac_t[c, r]
        for r in range(6):
            for c in range(nv):
                vel[k, r] += jac[k, r, c] * v[c]
                acc[k, r] += jac[k, r, c] * a[c] + 0.5 * acc_v[k, r, c] * v[c]
        for c in range(nv):       # + [x_ang]_x J_o,lin: the origin moves with the frame
            for block, x in ((vel_q, vel), (acc_q, acc)):
                s0, s1, s2 = _cross(x[k, 3], x[k, 4], x[k, 5], jac[k, 0, c], jac[k, 1, c],
                                    jac[k, 2, c])
                block[k, 0, c] += s0
                block[k, 1, c] += s1
                block[k, 2, c] += s2
        if world[k]:              # classical: + w x v
            w0, w1, w2 = vel[k, 3], vel[k, 4], vel[k, 5]
            l0, l1, l2 = vel[k, 0], vel[k, 1], vel[k, 2]
            s0, s1, s2 = _cross(w0, w1, w2, l0, l1, l2)
            acc[k, 0] += s0
            acc[k, 1] += s1
            acc[k, 2] += s2
            for c in range(nv):
                for block, src in ((acc_q, vel_q), (acc_v, jac)):
                    s0, s1, s2 = _cross(w0, w1, w2, src[k, 0, c], src[k, 1, c], src[k, 2, c])
                    t0, t1, t2 = _cross(l0, l1, l2, src[k, 3, c], src[k, 4, c], src[k, 5, c])
                    block[k, 0, c] += s0 - t0
                    block[k, 1, c] += s1 - t1
                    block[k, 2, c] += s2 - t2
        else:                     # LOCAL axes: R^T x, R^T (dx + [x]_x J_o,ang)
            for c in range(nv):
                j0, j1, j2 = jac[k, 3, c], jac[k, 4, c], jac[k, 5, c]
                for block, x in ((vel_q, vel), (acc_q, acc)):
                    for h in (0, 3):
                        s0, s1, s2 = _cross(x[k, h], x[k, h + 1], x[k, h + 2], j0, j1, j2)
                        block[k, h, c] += s0
                        block[k, h + 1, c] += s1
                        block[k, h + 2, c] += s2
            for block in (vel_q, acc_q, acc_v, jac):
                for c in range(nv):
                    for h in (0, 3):
                        y0, y1, y2 = block[k, h, c], block[k, h + 1, c], block[k, h + 2, c]
                        for r in range(3):
                            block[k, h + r, c] = rot[k, 0, r] * y0 + rot[k, 1, r] * y1 \
                                + rot[k, 2, r] * y2
            for x in (vel, acc):
                for h in (0, 3):
                    y0, y1, y2 = x[k, h], x[k, h + 1], x[k, h + 2]
                    for r in range(3):
                        x[k, h + r] = rot[k, 0, r] * y0 + rot[k, 1, r] * y1 + rot[k, 2, r] * y2

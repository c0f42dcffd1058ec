"""Compiled kernels of the generic closed-loop integrator
(:class:`~hexapod_pin.core.simulation.ClosedLoopIntegrator`).

The configuration rate of the supported joints, the RK4 stage update and weighted sum of
the stage rates, the renormalisation of unit quaternions and of unit ``(cos, sin)`` pairs,
the semi-implicit Euler update of vector-space models, the finiteness check of a state,
and the Gauss-Newton pass of the projection onto the closures (the step and the velocity
projection on the independent rows, with one factorisation). Conventions: Pinocchio's
``q`` / ``v``; ``joints`` rows ``(kind, idx_q, idx_v)`` with kind

* :data:`VECTOR` (0): one coordinate with ``qdot = v`` (1-DoF revolute / prismatic, and
  each coordinate of a ``SphericalZYX`` or ``Translation`` joint);
* :data:`FREE_FLYER` (1): ``q = (p, x, y, z, w)``, ``v = (v_lin, w)`` in the body frame;
* :data:`UNBOUNDED` (2): a continuous revolute joint, ``q = (cos t, sin t)``, ``v = t'``;
* :data:`SPHERICAL` (3): a ball joint, ``q = (x, y, z, w)``, ``v = w`` in the body frame;
* :data:`PLANAR` (4): ``q = (x, y, cos t, sin t)``, ``v = (v_x, v_y, t')`` in the joint's
  moving frame.

Numba-compiled; the updates write into the output arrays they are given, the
Gauss-Newton passes return the relative miss of their solve (``inf`` when not finite) and
the integrator verifies and raises.
"""

from __future__ import annotations

import math

import numpy as np

from .compiled import jit
from .constraint_views import gather_negated

#: joint kinds of the ``joints`` table (see the module docstring)
VECTOR, FREE_FLYER, UNBOUNDED, SPHERICAL, PLANAR = 0, 1, 2, 3, 4


@jit
def configuration_rate(q, v, joints, out):
    """``qdot`` (nq,) into ``out`` for the velocity ``v`` (nv,) at ``q``, per row
    ``(kind, idx_q, idx_v)`` of ``joints``: a vector coordinate (kind 0) ``qdot = v``; a
    free-flyer (kind 1, q = (p, x, y, z, w), v = (v_lin, w) in the body frame)
    ``p' = R v_lin`` and ``Q' = 1/2 Q (x) (w, 0)``; an unbounded revolute (kind 2,
    q = (c, s)) ``(c, s)' = (-s, c) v``; a ball joint (kind 3, q = (x, y, z, w), v = w in
    the body frame) ``Q' = 1/2 Q (x) (w, 0)``; a planar joint (kind 4, q = (x, y, c, s),
    v = (v_x, v_y, w) in its moving frame) ``(x, y)' = R(c, s) (v_x, v_y)``,
    ``(c, s)' = (-s, c) w``."""
    for k in range(joints.shape[0]):
        kind, iq, iv = joints[k, 0], joints[k, 1], joints[k, 2]
        if kind == 0:
            out[iq] = v[iv]
            continue
        if kind == 2:
            c, s, w = q[iq], q[iq + 1], v[iv]
            out[iq] = -s * w
            out[iq + 1] = c * w
            continue
        if kind == 4:
            c, s = q[iq + 2], q[iq + 3]
            vx, vy, w = v[iv], v[iv + 1], v[iv + 2]
            out[iq] = c * vx - s * vy
            out[iq + 1] = s * vx + c * vy
            out[iq + 2] = -s * w
            out[iq + 3] = c * w
            continue
        iw, ir = iv + 3, iq + 3          # a free-flyer: its angular part, its quaternion
        if kind == 3:
            iw, ir = iv, iq
        else:
            x, y, z, w = q[iq + 3], q[iq + 4], q[iq + 5], q[iq + 6]
            vx, vy, vz = v[iv], v[iv + 1], v[iv + 2]
            # p' = R v_lin (R of the unit quaternion)
            tx, ty = 2.0 * (y * vz - z * vy), 2.0 * (z * vx - x * vz)
            tz = 2.0 * (x * vy - y * vx)
            out[iq] = vx + w * tx + (y * tz - z * ty)
            out[iq + 1] = vy + w * ty + (z * tx - x * tz)
            out[iq + 2] = vz + w * tz + (x * ty - y * tx)
        x, y, z, w = q[ir], q[ir + 1], q[ir + 2], q[ir + 3]
        wx, wy, wz = v[iw], v[iw + 1], v[iw + 2]
        out[ir] = 0.5 * (w * wx + y * wz - z * wy)
        out[ir + 1] = 0.5 * (w * wy + z * wx - x * wz)
        out[ir + 2] = 0.5 * (w * wz + x * wy - y * wx)
        out[ir + 3] = -0.5 * (x * wx + y * wy + z * wz)


@jit
def _normalise_quaternions(q, quat):
    for k in range(quat.shape[0]):
        i = quat[k]
        inv = 1.0 / math.sqrt(q[i] ** 2 + q[i + 1] ** 2 + q[i + 2] ** 2 + q[i + 3] ** 2)
        for j in range(4):
            q[i + j] *= inv


@jit
def normalise_pairs(q, pairs):
    """Renormalise in place the unit ``(cos, sin)`` pairs of ``q`` starting at the indices
    ``pairs`` (unbounded revolute and planar joints)."""
    for k in range(pairs.shape[0]):
        i = pairs[k]
        inv = 1.0 / math.sqrt(q[i] ** 2 + q[i + 1] ** 2)
        q[i] *= inv
        q[i + 1] *= inv


@jit
def finite_state(q, v, tau):
    """Whether every entry of the 1-D arrays ``q``, ``v`` and ``tau`` is finite."""
    for x in (q, v, tau):
        for i in range(x.shape[0]):
            if not math.isfinite(x[i]):
                return False
    return True


@jit
def rk4_stage(q, v, qs, vs, vdot, h, w, joints, quat, q_out, v_out, rates):
    """One RK4 stage from the step's start ``(q, v)`` with the rates of the stage state
    ``(qs, vs)``: ``q_out = q + h qdot(qs, vs)`` (nq,; the quaternions starting at the
    indices ``quat`` renormalised) and ``v_out = v + h vdot`` (nv,); ``rates`` (nq + nv,)
    accumulates ``w (qdot, vdot)``."""
    nq = q.shape[0]
    configuration_rate(qs, vs, joints, q_out)
    for i in range(nq):
        d = q_out[i]
        rates[i] += w * d
        q_out[i] = q[i] + h * d
    for i in range(v.shape[0]):
        rates[nq + i] += w * vdot[i]
        v_out[i] = v[i] + h * vdot[i]
    _normalise_quaternions(q_out, quat)


@jit
def euler_update(q, v, acc, dt, q_out, v_out):
    """Semi-implicit Euler on 1-DoF joints (nq = nv): ``v_out = v + dt acc`` then
    ``q_out = q + dt v_out``."""
    for i in range(v.shape[0]):
        v_out[i] = v[i] + dt * acc[i]
        q_out[i] = q[i] + dt * v_out[i]


@jit
def rk4_combine(q, v, rates, h, quat, q_out, v_out):
    """The RK4 update ``q_out = q + h rates[:nq]`` (quaternions renormalised) and
    ``v_out = v + h rates[nq:]``."""
    nq = q.shape[0]
    for i in range(nq):
        q_out[i] = q[i] + h * rates[i]
    for i in range(v.shape[0]):
        v_out[i] = v[i] + h * rates[nq + i]
    _normalise_quaternions(q_out, quat)


@jit
def errors_gauss_newton_pass(views, jac, err, rows, v, step, v_new, out):
    """:func:`gauss_newton_pass` on the errors gathered from the live views ``views``
    (:func:`~hexapod_pin.core.constraint_views.gather_negated`, into ``err``)."""
    gather_negated(views, err)
    return gauss_newton_pass(jac, err, rows, v, step, v_new, out)


@jit
def gauss_newton_pass(jac, err, rows, v, step, v_new, out):
    """One compiled projection pass on the rows ``rows`` of ``J`` (n_rows, nv) and of the
    closure errors ``err``: ``step = -J_r^+ err_r`` and ``v_new = v - J_r^+ J_r v``
    (minimum norm, one Cholesky factorisation of the Gram matrix ``J_r J_r^T`` for both).
    ``out[0]`` = max-abs of ``err`` (all rows). Returns the larger relative miss of
    ``J_r step = -err_r`` and ``J_r v_new = 0`` (small only when the solves were
    accurate); ``inf`` when the Gram matrix is not numerically positive definite.

    Each row's products run over the columns from its first to its last nonzero entry
    (the entries outside are exact zeros: the same sums; a closure's row is zero on the
    joints that move neither of its anchors)."""
    n, nv = rows.shape[0], jac.shape[1]
    lo = np.empty(n, dtype=np.int64)
    hi = np.empty(n, dtype=np.int64)
    rhs = np.empty((n, 2))
    emax = 0.0
    for k in range(err.shape[0]):
        emax = max(emax, abs(err[k]))
    out[0] = emax
    jmax = 0.0
    for i in range(n):
        r = rows[i]
        first, last = nv, 0
        for k in range(nv):
            a = jac[r, k]
            if a != 0.0:
                if first == nv:
                    first = k
                last = k + 1
                jmax = max(jmax, abs(a))
            elif math.isnan(a):                    # NaN: keep it in the sums
                first = min(first, k)
                last = max(last, k + 1)
        lo[i], hi[i] = min(first, last), last
        rhs[i, 0] = -err[r]
        acc = 0.0
        for k in range(lo[i], hi[i]):
            acc += jac[r, k] * v[k]
        rhs[i, 1] = acc
    # lower Cholesky factor of the Gram matrix
    low = np.empty((n, n))
    for i in range(n):
        ri = rows[i]
        for j in range(i + 1):
            rj = rows[j]
            acc = 0.0
            for k in range(max(lo[i], lo[j]), min(hi[i], hi[j])):
                acc += jac[ri, k] * jac[rj, k]
            for k in range(j):
                acc -= low[i, k] * low[j, k]
            if i == j:
                if not acc > 0.0:
                    return math.inf
                low[i, i] = math.sqrt(acc)
            else:
                low[i, j] = acc / low[j, j]
    # sol = G^-1 rhs: forward then backward substitution, both columns (in place)
    sol = rhs.copy()
    for c in range(2):
        for i in range(n):
            acc = sol[i, c]
            for k in range(i):
                acc -= low[i, k] * sol[k, c]
            sol[i, c] = acc / low[i, i]
        for i in range(n - 1, -1, -1):
            acc = sol[i, c]
            for k in range(i + 1, n):
                acc -= low[k, i] * sol[k, c]
            sol[i, c] = acc / low[i, i]
    # step = J_r^T sol_0, v_new = v - J_r^T sol_1
    for j in range(nv):
        step[j] = 0.0
        v_new[j] = v[j]
    for i in range(n):
        r = rows[i]
        s0, s1 = sol[i, 0], sol[i, 1]
        for k in range(lo[i], hi[i]):
            step[k] += jac[r, k] * s0
            v_new[k] -= jac[r, k] * s1
    miss_s, miss_v, scale_s, scale_v = 0.0, 0.0, 0.0, 0.0
    for i in range(n):
        r = rows[i]
        row_s = 0.0
        row_v = 0.0
        for k in range(lo[i], hi[i]):
            row_s += jac[r, k] * step[k]
            row_v += jac[r, k] * v_new[k]
        miss_s = max(miss_s, abs(row_s - rhs[i, 0]))
        miss_v = max(miss_v, abs(row_v))
        scale_s = max(scale_s, abs(rhs[i, 0]))
        scale_v = max(scale_v, abs(rhs[i, 1]))
    vmax = 0.0
    for j in range(nv):
        vmax = max(vmax, abs(v[j]))
    rel_s = miss_s / max(scale_s, 1e-300)
    rel_v = miss_v / max(scale_v, jmax * vmax, 1e-300)
    if not (math.isfinite(rel_s) and math.isfinite(rel_v)):
        return math.inf
    return max(rel_s, rel_v)

"""Compiled (numba) kernels of the closed-form platform -> tree map, for single-state calls.

:class:`~hexapod_pin.platform_map.PlatformMap` writes the map in plain Python floats; it
stays the reference (and the route for the less frequent calls: tree states read back
from a configuration, the analytic derivatives, the simulator on the tree). The hot single-state routes of
:class:`~hexapod_pin.dynamics.HexapodDynamics` (inverse and forward dynamics, statics)
spend most of their time in that Python glue around a few cheap Pinocchio calls, so the
same equations are compiled here:

* :func:`tree_state`: pose (and twist, twist_dot) -> tree ``q``, ``v``, ``a`` (the
  equations of the :mod:`~hexapod_pin.platform_map` docstring), plus a leg buffer that
  the other kernels read;
* :func:`project`: ``G^T f - wrench`` (the platform wrench equivalent by virtual power to
  a tree generalised force);
* :func:`solve_forces`: ``J^T tau = rhs`` by LU with partial pivoting, and the
  multipliers of the equality-constrained minimum-effort QP (ProxSuite's warm start);
* :func:`reduced`, :func:`nullspace_forward`: ``M_x = G^T M G`` and ``G^T b`` from the
  tree mass matrix (block diagonal) and bias, the null-space forward dynamics solved by
  Cholesky;
* :func:`leg_forces`: the closure forces from the legs' tree rows;
* :func:`lu_solve6`: the 6x6 LU shared with :mod:`hexapod_pin.fast`.

Kernels return an integer status, never raise: the caller re-runs the Python route,
which raises the library's exception with its values. The tests check every kernel
against Pinocchio (closure residual, ``J_c v = 0``, ``J_c a = -drift``, virtual power)
and against :class:`~hexapod_pin.platform_map.PlatformMap`.

Compiled with ``@njit(cache=True)``: the machine code is cached in ``__pycache__`` next
to this file (or numba's user cache directory when that is read-only), so only the first
call after an install compiles (a few seconds).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ..core.compiled import all_finite
from ..errors import HexapodPinError
from .kinematics import GIMBAL_TOL

#: status codes
OK, UNREACHABLE, TYPE_I, GIMBAL, TYPE_II, NOT_PD = 0, 1, 2, 3, 4, 5

# geometry vector layout: per carriage i (9 values) k, m (3), u (3), l (2); points (9);
# leg length, type-I tolerance, gimbal tolerance
_CAR, _PTS, _LEN, _TYPE1, _GIMB = 0, 54, 63, 64, 65
GEO_SIZE = 66

# leg buffer rows (each row: 6 legs, carriage order)
_RX, _RY, _RZ, _NX, _NY, _NZ, _NU, _X, _Y, _RHO2, _EX, _DX, _DY, _DZ = range(14)
#: rows of the scratch of :func:`nullspace_forward`
FORWARD_WORK_ROWS = 41
#: rows of the leg buffer; ``buf[14, 0:9]`` holds ``R`` row-major
BUF_ROWS = 16
_ROT = 14

_jit = numba.njit(cache=True, error_model="numpy")


def pack_geometry(pmap) -> np.ndarray:
    """The constants of a :class:`~hexapod_pin.platform_map.PlatformMap` as a flat vector."""
    out = np.zeros(GEO_SIZE)
    for i, (k, mx, my, mz, ux, uy, uz, lx, ly) in enumerate(pmap._carriages):
        out[9 * i:9 * i + 9] = (k, mx, my, mz, ux, uy, uz, lx, ly)
    out[_PTS:_PTS + 9] = np.array(pmap._points, dtype=float).reshape(-1)
    out[_LEN], out[_TYPE1], out[_GIMB] = pmap.leg_length, pmap._type_one, GIMBAL_TOL
    return out


@_jit
def tree_state(geo, pose, twist, twist_dot, signs, level, q, v, a, buf):
    """Tree state of a platform state (home or any IK branch ``signs``).

    ``level`` 0: ``q`` only; 1: ``q``, ``v``; 2: ``q``, ``v``, ``a``. Returns OK, or
    -1 (a non-finite input), UNREACHABLE, TYPE_I, GIMBAL (the checks of
    :meth:`PlatformMap.legs`).
    """
    if not all_finite(pose):
        return -1
    if level >= 1 and not all_finite(twist):
        return -1
    if level >= 2 and not all_finite(twist_dot):
        return -1
    x, y, z, roll, pitch, yaw = pose[0], pose[1], pose[2], pose[3], pose[4], pose[5]
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    r00, r01, r02 = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    r10, r11, r12 = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
    r20, r21, r22 = -sp, cp * sr, cp * cr
    rot = buf[_ROT]
    rot[0], rot[1], rot[2], rot[3], rot[4], rot[5] = r00, r01, r02, r10, r11, r12
    buf[_ROT + 1, 0], buf[_ROT + 1, 1], buf[_ROT + 1, 2] = r20, r21, r22
    length = geo[_LEN]
    inv_len = 1.0 / length
    code = OK
    for i in range(6):
        c = 9 * i
        k = int(geo[c])
        px, py, pz = geo[_PTS + 3 * k], geo[_PTS + 3 * k + 1], geo[_PTS + 3 * k + 2]
        rx = r00 * px + r01 * py + r02 * pz
        ry = r10 * px + r11 * py + r12 * pz
        rz = r20 * px + r21 * py + r22 * pz
        ux, uy, uz, lx, ly = geo[c + 4], geo[c + 5], geo[c + 6], geo[c + 7], geo[c + 8]
        dx, dy, dz = x + rx - geo[c + 1], y + ry - geo[c + 2], z + rz - geo[c + 3]
        al = dx * ux + dy * uy + dz * uz
        disc = length * length - (dx * dx + dy * dy + dz * dz - al * al)
        if not disc >= 0.0:
            return UNREACHABLE
        qi = al + signs[i] * math.sqrt(disc)
        nx, ny, nz = dx - qi * ux, dy - qi * uy, dz - qi * uz
        nu = nx * ux + ny * uy + nz * uz
        if not abs(nu) >= geo[_TYPE1]:
            code = TYPE_I
        big_x = nz * inv_len
        big_y = -(nx * lx + ny * ly) * inv_len
        rho2 = big_x * big_x + big_y * big_y
        if code == OK and not rho2 >= geo[_GIMB]:
            code = GIMBAL
        ex = nu * inv_len
        buf[_RX, i], buf[_RY, i], buf[_RZ, i] = rx, ry, rz
        buf[_NX, i], buf[_NY, i], buf[_NZ, i], buf[_NU, i] = nx, ny, nz, nu
        buf[_X, i], buf[_Y, i], buf[_RHO2, i], buf[_EX, i] = big_x, big_y, rho2, ex
        q[3 * i] = qi
        q[3 * i + 1] = math.atan2(big_y, big_x)
        q[3 * i + 2] = math.atan2(ex, math.sqrt(rho2))
    if code != OK:
        return code
    q[18], q[19], q[20] = x, y, z
    # quaternion (x, y, z, w) of Rz(yaw) Ry(pitch) Rx(roll), w >= 0
    c1, s1 = math.cos(0.5 * roll), math.sin(0.5 * roll)
    c2, s2 = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    c3, s3 = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    qw = c1 * c2 * c3 + s1 * s2 * s3
    qx = s1 * c2 * c3 - c1 * s2 * s3
    qy = c1 * s2 * c3 + s1 * c2 * s3
    qz = c1 * c2 * s3 - s1 * s2 * c3
    if qw < 0.0:
        qx, qy, qz, qw = -qx, -qy, -qz, -qw
    q[21], q[22], q[23], q[24] = qx, qy, qz, qw
    if level < 1:
        return OK
    vx, vy, vz, wx, wy, wz = twist[0], twist[1], twist[2], twist[3], twist[4], twist[5]
    for i in range(6):
        c = 9 * i
        ux, uy, uz, lx, ly = geo[c + 4], geo[c + 5], geo[c + 6], geo[c + 7], geo[c + 8]
        rx, ry, rz = buf[_RX, i], buf[_RY, i], buf[_RZ, i]
        nx, ny, nz, nu = buf[_NX, i], buf[_NY, i], buf[_NZ, i], buf[_NU, i]
        big_x, big_y, rho2 = buf[_X, i], buf[_Y, i], buf[_RHO2, i]
        tx, ty, tz = vx + wy * rz - wz * ry, vy + wz * rx - wx * rz, vz + wx * ry - wy * rx
        qd = (nx * tx + ny * ty + nz * tz) / nu
        dx, dy, dz = tx - qd * ux, ty - qd * uy, tz - qd * uz
        buf[_DX, i], buf[_DY, i], buf[_DZ, i] = dx, dy, dz
        v[3 * i] = qd
        v[3 * i + 1] = (big_x * -(dx * lx + dy * ly) - big_y * dz) * inv_len / rho2
        v[3 * i + 2] = (dx * ux + dy * uy + dz * uz) * inv_len / math.sqrt(rho2)
    v[18] = r00 * vx + r10 * vy + r20 * vz
    v[19] = r01 * vx + r11 * vy + r21 * vz
    v[20] = r02 * vx + r12 * vy + r22 * vz
    v[21] = r00 * wx + r10 * wy + r20 * wz
    v[22] = r01 * wx + r11 * wy + r21 * wz
    v[23] = r02 * wx + r12 * wy + r22 * wz
    if level < 2:
        return OK
    ax, ay, az = twist_dot[0], twist_dot[1], twist_dot[2]
    bx, by, bz = twist_dot[3], twist_dot[4], twist_dot[5]
    for i in range(6):
        c = 9 * i
        ux, uy, uz, lx, ly = geo[c + 4], geo[c + 5], geo[c + 6], geo[c + 7], geo[c + 8]
        rx, ry, rz = buf[_RX, i], buf[_RY, i], buf[_RZ, i]
        nx, ny, nz, nu = buf[_NX, i], buf[_NY, i], buf[_NZ, i], buf[_NU, i]
        big_x, big_y, rho2, ex = buf[_X, i], buf[_Y, i], buf[_RHO2, i], buf[_EX, i]
        dx, dy, dz = buf[_DX, i], buf[_DY, i], buf[_DZ, i]
        # A_k = vdot + wdot x r + w x (w x r)
        cx, cy, cz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx
        tx = ax + by * rz - bz * ry + wy * cz - wz * cy
        ty = ay + bz * rx - bx * rz + wz * cx - wx * cz
        tz = az + bx * ry - by * rx + wx * cy - wy * cx
        qdd = (dx * dx + dy * dy + dz * dz + nx * tx + ny * ty + nz * tz) / nu
        ddx, ddy, ddz = tx - qdd * ux, ty - qdd * uy, tz - qdd * uz
        adot, bdot = v[3 * i + 1], v[3 * i + 2]
        d_x, d_y = dz * inv_len, -(dx * lx + dy * ly) * inv_len
        a[3 * i] = qdd
        a[3 * i + 1] = ((big_x * -(ddx * lx + ddy * ly) - big_y * ddz) * inv_len / rho2
                        - 2.0 * adot * (big_x * d_x + big_y * d_y) / rho2)
        a[3 * i + 2] = ((ddx * ux + ddy * uy + ddz * uz) * inv_len + ex * bdot * bdot) \
            / math.sqrt(rho2)
    # a_ff = (R^T (vdot - w x v), R^T wdot)
    px = ax - (wy * vz - wz * vy)
    py = ay - (wz * vx - wx * vz)
    pz = az - (wx * vy - wy * vx)
    a[18] = r00 * px + r10 * py + r20 * pz
    a[19] = r01 * px + r11 * py + r21 * pz
    a[20] = r02 * px + r12 * py + r22 * pz
    a[21] = r00 * bx + r10 * by + r20 * bz
    a[22] = r01 * bx + r11 * by + r21 * bz
    a[23] = r02 * bx + r12 * by + r22 * bz
    return OK


@_jit
def _rot(buf):
    r = buf[_ROT]
    s = buf[_ROT + 1]
    return r[0], r[1], r[2], r[3], r[4], r[5], s[0], s[1], s[2]


@_jit
def velocity_map(geo, buf, out):
    """``G`` (24, 6) with ``v_tree = G twist`` (see :meth:`PlatformMap.velocity_map`)."""
    inv_len = 1.0 / geo[_LEN]
    for i in range(24):
        for j in range(6):
            out[i, j] = 0.0
    for i in range(6):
        c = 9 * i
        ux, uy, uz, lx, ly = geo[c + 4], geo[c + 5], geo[c + 6], geo[c + 7], geo[c + 8]
        rx, ry, rz = buf[_RX, i], buf[_RY, i], buf[_RZ, i]
        nx, ny, nz, nu = buf[_NX, i], buf[_NY, i], buf[_NZ, i], buf[_NU, i]
        big_x, big_y, rho2 = buf[_X, i], buf[_Y, i], buf[_RHO2, i]
        inv_nu = 1.0 / nu
        cb = inv_len / math.sqrt(rho2)
        ca = -inv_len / rho2
        for row in range(3):
            if row == 0:
                gx, gy, gz = nx * inv_nu, ny * inv_nu, nz * inv_nu
            elif row == 1:
                gx, gy, gz = ca * big_x * lx, ca * big_x * ly, ca * big_y
            else:
                gx, gy, gz = (ux - nx * inv_nu) * cb, (uy - ny * inv_nu) * cb, \
                    (uz - nz * inv_nu) * cb
            r = 3 * i + row
            out[r, 0], out[r, 1], out[r, 2] = gx, gy, gz
            out[r, 3], out[r, 4], out[r, 5] = ry * gz - rz * gy, rz * gx - rx * gz, \
                rx * gy - ry * gx
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = _rot(buf)
    out[18, 0], out[18, 1], out[18, 2] = r00, r10, r20
    out[19, 0], out[19, 1], out[19, 2] = r01, r11, r21
    out[20, 0], out[20, 1], out[20, 2] = r02, r12, r22
    out[21, 3], out[21, 4], out[21, 5] = r00, r10, r20
    out[22, 3], out[22, 4], out[22, 5] = r01, r11, r21
    out[23, 3], out[23, 4], out[23, 5] = r02, r12, r22


@_jit
def project(geo, buf, force, wrench, has_wrench, out):
    """``out = G^T force - wrench`` (6,): world axes, about the platform origin."""
    inv_len = 1.0 / geo[_LEN]
    fx = fy = fz = mx = my = mz = 0.0
    for i in range(6):
        c = 9 * i
        ux, uy, uz, lx, ly = geo[c + 4], geo[c + 5], geo[c + 6], geo[c + 7], geo[c + 8]
        nx, ny, nz, nu = buf[_NX, i], buf[_NY, i], buf[_NZ, i], buf[_NU, i]
        big_x, big_y, rho2 = buf[_X, i], buf[_Y, i], buf[_RHO2, i]
        f_c, f_a, f_b = force[3 * i], force[3 * i + 1], force[3 * i + 2]
        f_b *= inv_len / math.sqrt(rho2)
        f_a *= -inv_len / rho2
        coef = (f_c - f_b) / nu
        f_ax = f_a * big_x
        gx = coef * nx + f_b * ux + f_ax * lx
        gy = coef * ny + f_b * uy + f_ax * ly
        gz = coef * nz + f_b * uz + f_a * big_y
        rx, ry, rz = buf[_RX, i], buf[_RY, i], buf[_RZ, i]
        fx += gx
        fy += gy
        fz += gz
        mx += ry * gz - rz * gy
        my += rz * gx - rx * gz
        mz += rx * gy - ry * gx
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = _rot(buf)
    a0, a1, a2, b0, b1, b2 = force[18], force[19], force[20], force[21], force[22], force[23]
    out[0] = fx + r00 * a0 + r01 * a1 + r02 * a2
    out[1] = fy + r10 * a0 + r11 * a1 + r12 * a2
    out[2] = fz + r20 * a0 + r21 * a1 + r22 * a2
    out[3] = mx + r00 * b0 + r01 * b1 + r02 * b2
    out[4] = my + r10 * b0 + r11 * b1 + r12 * b2
    out[5] = mz + r20 * b0 + r21 * b1 + r22 * b2
    if has_wrench:
        for j in range(6):
            out[j] -= wrench[j]


@_jit
def leg_forces(geo, buf, force, tau, out):
    """Force (world axes) of the platform on each leg tip, ``out`` (6, 3): leg i's three
    tree rows ``[u, u x n, b x n]^T lambda_i = (force_c - tau_i, force_a, force_b)``
    (:meth:`PlatformMap.leg_forces`), by Cramer's rule."""
    for i in range(6):
        c = 9 * i
        ux, uy, uz, lx, ly = geo[c + 4], geo[c + 5], geo[c + 6], geo[c + 7], geo[c + 8]
        nx, ny, nz = buf[_NX, i], buf[_NY, i], buf[_NZ, i]
        rho = math.sqrt(buf[_RHO2, i])
        bx, by, bz = buf[_X, i] * lx / rho, buf[_X, i] * ly / rho, buf[_Y, i] / rho
        c2x, c2y, c2z = uy * nz - uz * ny, uz * nx - ux * nz, ux * ny - uy * nx
        c3x, c3y, c3z = by * nz - bz * ny, bz * nx - bx * nz, bx * ny - by * nx
        y1, y2, y3 = force[3 * i] - tau[i], force[3 * i + 1], force[3 * i + 2]
        k23x, k23y, k23z = c2y * c3z - c2z * c3y, c2z * c3x - c2x * c3z, c2x * c3y - c2y * c3x
        k31x, k31y, k31z = c3y * uz - c3z * uy, c3z * ux - c3x * uz, c3x * uy - c3y * ux
        k12x, k12y, k12z = uy * c2z - uz * c2y, uz * c2x - ux * c2z, ux * c2y - uy * c2x
        det = ux * k23x + uy * k23y + uz * k23z
        out[i, 0] = (y1 * k23x + y2 * k31x + y3 * k12x) / det
        out[i, 1] = (y1 * k23y + y2 * k31y + y3 * k12y) / det
        out[i, 2] = (y1 * k23z + y2 * k31z + y3 * k12z) / det


@_jit
def force_matrix(buf, out):
    """``A^T`` (6, 6): column i is ``[n_i, r_k x n_i]``; ``J^T = A^T diag(1 / (n.u))``."""
    for i in range(6):
        rx, ry, rz = buf[_RX, i], buf[_RY, i], buf[_RZ, i]
        nx, ny, nz = buf[_NX, i], buf[_NY, i], buf[_NZ, i]
        out[0, i], out[1, i], out[2, i] = nx, ny, nz
        out[3, i], out[4, i], out[5, i] = ry * nz - rz * ny, rz * nx - rx * nz, rx * ny - ry * nx


@_jit
def jacobian_transpose(buf, out):
    """``J^T`` (6, 6) of the legs in the buffer: ``A^T diag(1 / (n.u))``."""
    force_matrix(buf, out)
    for i in range(6):
        inv = 1.0 / buf[_NU, i]
        for r in range(6):
            out[r, i] *= inv


@_jit
def check_solution(mat, x, rhs):
    """``(max |mat x - rhs|, max |x|, max |rhs|)`` of a 6x6 system."""
    res = big_x = big_b = 0.0
    for r in range(6):
        acc = -rhs[r]
        for c in range(6):
            acc += mat[r, c] * x[c]
        res = max(res, abs(acc))
        big_x = max(big_x, abs(x[r]))
        big_b = max(big_b, abs(rhs[r]))
    return res, big_x, big_b


@_jit
def lu_solve6(mat, rhs, pivot_rtol, perm):
    """Solve ``mat x = rhs`` (6 x 6) in place by LU with partial pivoting.

    ``rhs`` becomes ``x``; ``mat`` holds the factors (``P mat = L U``, unit ``L`` below the
    diagonal) and ``perm`` the row order (``(P y)[j] = y[perm[j]]``; pass
    ``np.arange(6)``). Returns OK, or TYPE_II when the smallest pivot is below
    ``pivot_rtol`` times the largest (or zero).
    """
    small, big = np.inf, 0.0
    for col in range(6):
        piv, best = col, abs(mat[col, col])
        for row in range(col + 1, 6):
            if abs(mat[row, col]) > best:
                piv, best = row, abs(mat[row, col])
        if piv != col:
            for j in range(6):
                mat[col, j], mat[piv, j] = mat[piv, j], mat[col, j]
            rhs[col], rhs[piv] = rhs[piv], rhs[col]
            perm[col], perm[piv] = perm[piv], perm[col]
        small, big = min(small, best), max(big, best)
        if best == 0.0:
            return TYPE_II
        for row in range(col + 1, 6):
            f = mat[row, col] / mat[col, col]
            mat[row, col] = f
            for j in range(col + 1, 6):
                mat[row, j] -= f * mat[col, j]
            rhs[row] -= f * rhs[col]
    if not small > pivot_rtol * big:
        return TYPE_II
    for row in range(5, -1, -1):
        acc = rhs[row]
        for j in range(row + 1, 6):
            acc -= mat[row, j] * rhs[j]
        rhs[row] = acc / mat[row, row]
    return OK


@_jit
def solve_forces(buf, rhs, pivot_rtol, tau, multipliers, lu, jac_t):
    """``J^T tau = rhs`` (6 equations) by LU with partial pivoting of ``A^T``.

    Also fills ``jac_t`` with ``J^T`` (6, 6).

    Also fills ``multipliers`` with ``y``, ``J y = -tau``: the equality multipliers of the
    QP ``min 1/2 |tau|^2 s.t. J^T tau = rhs`` (stationarity ``tau + J y = 0``, ProxSuite's
    sign convention). ``lu`` (6, 6) is scratch. Returns OK, or TYPE_II when the smallest
    pivot is below ``pivot_rtol`` times the largest (:meth:`PlatformMap.solve_forces`).
    """
    jacobian_transpose(buf, jac_t)
    force_matrix(buf, lu)
    for j in range(6):
        tau[j] = rhs[j]
    perm = np.arange(6)
    code = lu_solve6(lu, tau, pivot_rtol, perm)
    if code != OK:
        return code
    # tau = diag(n.u) s with A^T s = rhs
    for i in range(6):
        tau[i] *= buf[_NU, i]
    # J y = -tau with J = diag(1 / n.u) F^T (F = A^T, factored P F = L U):
    # F^T y = -(n.u) tau, F^T = U^T L^T P: solve U^T w = -(n.u) tau, L^T z = w, P y = z
    w = np.empty(6)
    for row in range(6):
        acc = -tau[row] * buf[_NU, row]
        for j in range(row):
            acc -= lu[j, row] * w[j]
        w[row] = acc / lu[row, row]
    for row in range(5, -1, -1):
        acc = w[row]
        for j in range(row + 1, 6):
            acc -= lu[j, row] * w[j]
        w[row] = acc
    for j in range(6):
        multipliers[perm[j]] = w[j]
    return OK


@_jit
def reduced(geo, buf, mass, bias, g_map, m_x, h_x):
    """``M_x = G^T M G`` (6, 6) and ``h_x = G^T bias`` (6,) from the tree's ``M`` (24, 24;
    upper triangle read, as ``pin.crba`` fills it) and a tree generalised force ``bias``.

    ``M`` is block diagonal (every leg chain and the free-flyer hang from the fixed
    world: blocks ``3 i .. 3 i + 2`` and ``18 .. 23``, checked once by
    :meth:`CompiledMap.check_mass_structure`), so only the blocks are read.
    """
    velocity_map(geo, buf, g_map)
    tmp = np.empty((24, 6))
    for r in range(24):
        start = 18 if r >= 18 else 3 * (r // 3)
        stop = 24 if r >= 18 else start + 3
        for j in range(6):
            acc = 0.0
            for c in range(start, stop):
                mrc = mass[r, c] if r <= c else mass[c, r]
                acc += mrc * g_map[c, j]
            tmp[r, j] = acc
    for i in range(6):
        for j in range(i, 6):
            acc = 0.0
            for r in range(24):
                acc += g_map[r, i] * tmp[r, j]
            m_x[i, j] = acc
            m_x[j, i] = acc
        acc = 0.0
        for r in range(24):
            acc += g_map[r, i] * bias[r]
        h_x[i] = acc


@_jit
def cholesky_solve(mat, rhs, out, scratch):
    """``out = mat^-1 rhs`` for a symmetric positive-definite (6, 6) ``mat`` (not changed);
    returns OK or NOT_PD."""
    for i in range(6):
        for j in range(6):
            scratch[i, j] = mat[i, j]
    for j in range(6):
        d = scratch[j, j]
        for k in range(j):
            d -= scratch[k, j] * scratch[k, j]
        if not d > 0.0:
            return NOT_PD
        d = math.sqrt(d)
        scratch[j, j] = d
        for c in range(j + 1, 6):
            t = scratch[j, c]
            for k in range(j):
                t -= scratch[k, j] * scratch[k, c]
            scratch[j, c] = t / d
    for r in range(6):
        t = rhs[r]
        for k in range(r):
            t -= scratch[k, r] * out[k]
        out[r] = t / scratch[r, r]
    for r in range(5, -1, -1):
        t = out[r]
        for k in range(r + 1, 6):
            t -= scratch[r, k] * out[k]
        out[r] = t / scratch[r, r]
    return OK


@_jit
def nullspace_forward(geo, buf, mass, bias, forces, wrench, has_wrench, acc0, work,
                      twist_dot, acc):
    """Null-space forward dynamics: ``M_x twist_dot = G^T (S^T tau + tau_ext - bias)``.

    Args:
        mass: the tree's ``M`` (24, 24; upper triangle read, as ``pin.crba`` fills it).
        bias: ``rnea(q, v, a_0)`` (24,): the bias at zero platform acceleration.
        forces: actuator forces (6,) on the carriage rows ``3 i``; wrench (6,) on the
            platform, world axes (used when ``has_wrench``).
        acc0: the tree acceleration ``a_0`` at ``twist_dot = 0`` (24,).
        work: scratch (FORWARD_WORK_ROWS, 6): rows 0-23 get ``G``, 24-29 ``M_x``.
        twist_dot (6,), acc (24,): outputs (``acc = G twist_dot + a_0``).

    Returns OK, -1 (non-finite forces or wrench) or NOT_PD.
    """
    g_map, m_x, scratch = work[0:24], work[24:30], work[30:36]
    h_x, rest = work[36], work[37:41].reshape(24)
    if not all_finite(forces) or (has_wrench and not all_finite(wrench)):
        return -1
    for r in range(24):
        rest[r] = -bias[r]
    for i in range(6):
        rest[3 * i] += forces[i]
    if has_wrench:
        wrench_to_tree(buf, wrench, rest)
    reduced(geo, buf, mass, rest, g_map, m_x, h_x)
    code = cholesky_solve(m_x, h_x, twist_dot, scratch)
    if code != OK:
        return code
    for r in range(24):
        s = acc0[r]
        for j in range(6):
            s += g_map[r, j] * twist_dot[j]
        acc[r] = s
    return OK


@_jit
def twist_dot_of(buf, twist, acc_ff, out):
    """``twist_dot = (R a_lin + w x v, R a_ang)`` from the free-flyer acceleration (6,)."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = _rot(buf)
    ax, ay, az, bx, by, bz = acc_ff[0], acc_ff[1], acc_ff[2], acc_ff[3], acc_ff[4], acc_ff[5]
    vx, vy, vz, wx, wy, wz = twist[0], twist[1], twist[2], twist[3], twist[4], twist[5]
    out[0] = r00 * ax + r01 * ay + r02 * az + wy * vz - wz * vy
    out[1] = r10 * ax + r11 * ay + r12 * az + wz * vx - wx * vz
    out[2] = r20 * ax + r21 * ay + r22 * az + wx * vy - wy * vx
    out[3] = r00 * bx + r01 * by + r02 * bz
    out[4] = r10 * bx + r11 * by + r12 * bz
    out[5] = r20 * bx + r21 * by + r22 * bz


@_jit
def wrench_to_tree(buf, wrench, out):
    """The free-flyer generalised force ``(R^T f, R^T m)`` of a world wrench into ``out[18:]``."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = _rot(buf)
    fx, fy, fz, mx, my, mz = wrench[0], wrench[1], wrench[2], wrench[3], wrench[4], wrench[5]
    out[18] += r00 * fx + r10 * fy + r20 * fz
    out[19] += r01 * fx + r11 * fy + r21 * fz
    out[20] += r02 * fx + r12 * fy + r22 * fz
    out[21] += r00 * mx + r10 * my + r20 * mz
    out[22] += r01 * mx + r11 * my + r21 * mz
    out[23] += r02 * mx + r12 * my + r22 * mz


class CompiledMap:
    """Preallocated buffers and the packed geometry for the kernels of one hexapod.

    Not thread-safe (one instance per robot; the buffers are reused across calls).

    Args:
        pmap: the :class:`~hexapod_pin.platform_map.PlatformMap`.
        signs: the IK branch (6 floats +1 / -1).
    """

    def __init__(self, pmap, signs):
        self.geo = pack_geometry(pmap)
        self.signs = np.asarray(signs, dtype=float).copy()
        self.buf = np.zeros((BUF_ROWS, 6))
        self.rhs = np.empty(6)
        self.tau = np.empty(6)
        self.multipliers = np.empty(6)
        self.lu = np.empty((6, 6))
        self.jt = np.empty((6, 6))
        self.work = np.empty((FORWARD_WORK_ROWS, 6))
        self.zero6 = np.zeros(6)
        self.v = np.empty(24)
        self.a = np.empty(24)

    @staticmethod
    def check_mass_structure(mass) -> None:
        """Raise unless the tree's mass matrix (24, 24) is block diagonal as
        :func:`reduced` assumes (legs ``3 i .. 3 i + 2``, free-flyer ``18 .. 23``)."""
        full = np.triu(mass) + np.triu(mass, 1).T
        mask = np.ones((24, 24), dtype=bool)
        for start, stop in [(3 * i, 3 * i + 3) for i in range(6)] + [(18, 24)]:
            mask[start:stop, start:stop] = False
        if np.any(full[mask] != 0.0):
            raise HexapodPinError("the compiled reduced dynamics needs a block-diagonal tree "
                                  "mass matrix (each leg chain and the platform attached to "
                                  "the world)")

    def tip_forces(self, pose, force, tau) -> np.ndarray:
        """(6, 3) :func:`leg_forces` at ``pose`` (its legs rebuilt in a fresh buffer, so
        that a result computed earlier can still ask for them)."""
        buf, q, out = np.empty((BUF_ROWS, 6)), np.empty(25), np.empty((6, 3))
        if tree_state(self.geo, pose, self.zero6, self.zero6, self.signs, 0, q, self.v,
                      self.a, buf) != OK:
            raise HexapodPinError(f"tip_forces: pose {pose.tolist()} refused by the "
                                  "compiled map (it was accepted before)")
        leg_forces(self.geo, buf, force, tau, out)
        return out

"""The hexapod's inverse-dynamics derivatives: its Newton-Euler closed form
(:mod:`~hexapod_pin.hexapod.kernels`) differentiated, compiled.

This is the hexapod's kernel behind the core chain rule
(:mod:`hexapod_pin.core.platform_derivatives`): the closed form supplies the partials of the
unbounded inverse-dynamics forces ``tau = ID(pose, twist, twist_dot, wrench)``
(:meth:`~hexapod_pin.core.closed_form.ClosedFormKernels.inverse_dynamics_partials`); the
core turns them into the robot's :class:`~hexapod_pin.core.results.InverseDynamicsDerivatives`
and, by the implicit-function theorem, into its forward-dynamics derivatives. A hexapod whose
passive coordinates carry effects (which the closed form does not model) gets both from the
core's tree route instead.

Columns (24): the world tangent ``(dp, dtheta)`` of the pose (``dp`` of the platform origin,
``R -> exp([dtheta]) R``, world axes), then the twist ``(v, w)``, the twist_dot ``(vdot,
wdot)`` and the wrench ``(f, m)``, all held in world axes. Per leg (conventions and symbols
of :mod:`~hexapod_pin.hexapod.kernels`; ``c = w x r``, ``e = dn/dt``), along a direction::

    dr = dtheta x r,   D = dp + dr,   dq = (n.D) / (n.u),   dn = D - dq u
    dV = dv + dw x r + w x dr,        dqd = (n.dV + dn.e) / (n.u),   de = dV - dqd u
    dA = dvdot + dwdot x r + wdot x dr + dw x c + w x (dw x r + w x dr)
    dqdd = (2 e.de + dn.A + n.dA - qdd dn.u) / (n.u)
    dc_i = (m_c + m_l/3) dqdd + (m_l/6) u.dA,   dF_i = (m_l/6) dqdd u + (m_l/3) dA

the platform equation ``A^T t = P`` (rows ``a_i = [n_i, r_i x n_i]``) gives ``A^T dt = dP -
sum_i t_i [dn_i, dr_i x n_i + r_i x dn_i]`` with ``dP = sum_i [dF_i, dr_i x F_i + r_i x
dF_i] + [m_p dvdot, d(I_w wdot + w x I_w w)] - dW`` (``d(I_w x) = dtheta x I_w x - I_w
(dtheta x x) + I_w dx``), and ``dtau_i = dc_i + (dn_i.u) t_i + (n_i.u) dt_i`` plus the
carriage's drive ``a dqdd + d dqd + K dq`` (a smooth friction ``c tanh(qd / eps)`` adds ``c
(1 - tanh^2) / eps dqd``; exact Coulomb friction is constant while sliding, and a carriage
at rest is refused: not differentiable). Exact up to round-off; the tests check every block
against Richardson central differences of ``robot.inverse_dynamics`` and against the
core's tree route (docs/derivations.md, section 8).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ..core import effects_projection as drv
from ..core.checks import vec6
from ..core.compiled import jit_fast as jit
from ..core.compiled import jit_inline
from . import kernels as K
from .kinematics import check_branch

__all__ = ["N_COLUMNS", "inverse_partials", "inverse_partials_kernel"]

#: the columns of the partials: world tangent, twist, twist_dot, wrench (6 each)
N_COLUMNS = 24


@jit_inline
def _column(geo, rot, wk, mats, twist, twist_dot, d, drives, rhs, out, col):
    """Column ``col`` of the partials along the direction ``d`` (24,) (module docstring),
    at the state left in ``wk`` / ``mats`` by :func:`~hexapod_pin.hexapod.kernels.
    inverse_dynamics`; ``rhs`` (6,) scratch."""
    m_l = geo[K.ML]
    m_leg, m_side, mu, m_p = geo[K.MC] + m_l / 3.0, m_l / 6.0, m_l / 3.0, geo[K.MP]
    hx, hy, hz = d[3], d[4], d[5]
    dwx, dwy, dwz = d[9], d[10], d[11]
    dax, day, daz = d[12], d[13], d[14]
    dbx, dby, dbz = d[15], d[16], d[17]
    wx, wy, wz = twist[3], twist[4], twist[5]
    bx, by, bz = twist_dot[3], twist_dot[4], twist_dot[5]
    for j in range(6):
        rhs[j] = -d[18 + j]
    for i in range(6):
        b = K.BLOCK * i
        ux, uy, uz = geo[b + K.UX], geo[b + K.UY], geo[b + K.UZ]
        rx, ry, rz = wk[K.RX, i], wk[K.RY, i], wk[K.RZ, i]
        nx, ny, nz = wk[K.NX, i], wk[K.NY, i], wk[K.NZ, i]
        ex, ey, ez = wk[K.DNX, i], wk[K.DNY, i], wk[K.DNZ, i]
        big_ax, big_ay, big_az = wk[K.AX, i], wk[K.AY, i], wk[K.AZ, i]
        fx, fy, fz = wk[K.FX, i], wk[K.FY, i], wk[K.FZ, i]
        inv, qdd, t = wk[K.INV, i], wk[K.QDD, i], wk[K.AXIAL, i]
        # position: dr = dtheta x r, D = dp + dr, dq, dn
        drx, dry, drz = hy * rz - hz * ry, hz * rx - hx * rz, hx * ry - hy * rx
        big_dx, big_dy, big_dz = d[0] + drx, d[1] + dry, d[2] + drz
        dq = (nx * big_dx + ny * big_dy + nz * big_dz) * inv
        dnx, dny, dnz = big_dx - dq * ux, big_dy - dq * uy, big_dz - dq * uz
        dnu = dnx * ux + dny * uy + dnz * uz
        # velocity: c = w x r, dc = dw x r + w x dr, dV = dv + dc
        cx, cy, cz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx
        dcx = dwy * rz - dwz * ry + wy * drz - wz * dry
        dcy = dwz * rx - dwx * rz + wz * drx - wx * drz
        dcz = dwx * ry - dwy * rx + wx * dry - wy * drx
        dvx, dvy, dvz = d[6] + dcx, d[7] + dcy, d[8] + dcz
        dqd = (nx * dvx + ny * dvy + nz * dvz + dnx * ex + dny * ey + dnz * ez) * inv
        dex, dey, dez = dvx - dqd * ux, dvy - dqd * uy, dvz - dqd * uz
        # acceleration: dA = dvdot + dwdot x r + wdot x dr + dw x c + w x dc
        d_ax = (dax + dby * rz - dbz * ry + by * drz - bz * dry + dwy * cz - dwz * cy
                + wy * dcz - wz * dcy)
        d_ay = (day + dbz * rx - dbx * rz + bz * drx - bx * drz + dwz * cx - dwx * cz
                + wz * dcx - wx * dcz)
        d_az = (daz + dbx * ry - dby * rx + bx * dry - by * drx + dwx * cy - dwy * cx
                + wx * dcy - wy * dcx)
        dqdd = (2.0 * (ex * dex + ey * dey + ez * dez)
                + dnx * big_ax + dny * big_ay + dnz * big_az
                + nx * d_ax + ny * d_ay + nz * d_az - qdd * dnu) * inv
        # end loads, and the platform equation's right-hand side less t da
        side = m_side * dqdd
        dfx, dfy, dfz = side * ux + mu * d_ax, side * uy + mu * d_ay, side * uz + mu * d_az
        gx, gy, gz = dfx - t * dnx, dfy - t * dny, dfz - t * dnz        # dF - t dn
        hfx, hfy, hfz = fx - t * nx, fy - t * ny, fz - t * nz            # F - t n
        rhs[0] += gx
        rhs[1] += gy
        rhs[2] += gz
        rhs[3] += dry * hfz - drz * hfy + ry * gz - rz * gy
        rhs[4] += drz * hfx - drx * hfz + rz * gx - rx * gz
        rhs[5] += drx * hfy - dry * hfx + rx * gy - ry * gx
        part = m_leg * dqdd + m_side * (ux * d_ax + uy * d_ay + uz * d_az) + dnu * t
        if drives:
            part += drv.inverse_load_rate(geo, K.DRIVES, i, wk[K.QD, i], dq, dqd, dqdd)
        out[i, col] = part
    # the platform body: m_p dvdot, d(I_w wdot + w x I_w w)
    rhs[0] += m_p * dax
    rhs[1] += m_p * day
    rhs[2] += m_p * daz
    iwd = K.inertia_world(geo, rot, bx, by, bz)
    iw = K.inertia_world(geo, rot, wx, wy, wz)
    y1 = K.inertia_world(geo, rot, dbx - (hy * bz - hz * by), dby - (hz * bx - hx * bz),
                          dbz - (hx * by - hy * bx))
    y2 = K.inertia_world(geo, rot, dwx - (hy * wz - hz * wy), dwy - (hz * wx - hx * wz),
                          dwz - (hx * wy - hy * wx))
    zx = hy * iw[2] - hz * iw[1] + y2[0]          # d(I_w w)
    zy = hz * iw[0] - hx * iw[2] + y2[1]
    zz = hx * iw[1] - hy * iw[0] + y2[2]
    rhs[3] += hy * iwd[2] - hz * iwd[1] + y1[0] + dwy * iw[2] - dwz * iw[1] + wy * zz - wz * zy
    rhs[4] += hz * iwd[0] - hx * iwd[2] + y1[1] + dwz * iw[0] - dwx * iw[2] + wz * zx - wx * zz
    rhs[5] += hx * iwd[1] - hy * iwd[0] + y1[2] + dwx * iw[1] - dwy * iw[0] + wx * zy - wy * zx
    K.solve_legs(geo, wk, mats, rhs)                                  # dt
    for i in range(6):
        out[i, col] += wk[K.NU, i] * rhs[i]


@jit
def inverse_partials_kernel(geo, signs, pose, twist, twist_dot, wrench, rot, wk, mats):
    """The unbounded inverse-dynamics forces ``tau`` (6,) and their partials ``out`` (6, 24)
    (columns: module docstring) of one state on the branch ``signs`` (the scratch ``rot``,
    ``wk``, ``mats`` of :func:`~hexapod_pin.hexapod.kernels.inverse_dynamics`, written as
    there).

    Returns ``(code, rest, tau, out)``: the status of
    :func:`~hexapod_pin.hexapod.kernels.inverse_dynamics` (the partials are written only
    when OK) and the first carriage whose exact Coulomb friction is at rest (-1: none;
    the partials are then not written)."""
    tau, out = np.empty(6), np.zeros((6, N_COLUMNS))
    code = K.inverse_dynamics(geo, signs, pose, twist, twist_dot, wrench, False, tau, rot,
                              wk, mats)
    if code != K.OK:
        return code, -1, tau, out
    drives = geo[K.DRIVES + drv.FLAG] != 0.0
    if drives:
        for i in range(6):
            if drv.at_rest(geo, K.DRIVES, i, wk[K.QD, i]):
                return K.OK, i, tau, out
    direction, rhs = np.empty(N_COLUMNS), np.empty(6)
    for col in range(N_COLUMNS):
        for j in range(N_COLUMNS):
            direction[j] = 0.0
        direction[col] = 1.0
        _column(geo, rot, wk, mats, twist, twist_dot, direction, drives, rhs, out, col)
    return K.OK, -1, tau, out


def inverse_partials(dynamics: Any, pose: npt.ArrayLike, twist: npt.ArrayLike,
                     twist_dot: npt.ArrayLike, wrench: npt.ArrayLike | None = None,
                     branch: npt.ArrayLike | None = None
                     ) -> tuple[np.ndarray, np.ndarray] | None:
    """The hexapod's :meth:`~hexapod_pin.core.closed_form.ClosedFormKernels.
    inverse_dynamics_partials`: ``(tau (6,), partials (6, 24))`` (columns: module
    docstring), or None when passive coordinates carry effects.

    Args:
        dynamics: the robot's :class:`~hexapod_pin.hexapod.dynamics.HexapodDynamics`.
        pose: ``(x, y, z, roll, pitch, yaw)`` (m, rad).
        twist: ``(v, w)`` world axes (m/s, rad/s).
        twist_dot: its time derivative (m/s^2, rad/s^2).
        wrench: ``(f, m)`` ON the platform, world axes, moment about the platform origin
            (N, N m); None: zero.
        branch: the IK branch (six +-1); None: home.

    Raises:
        InputError: bad shapes, NaN / inf; a carriage with Coulomb friction at rest (the
            dynamics is not differentiable there: stick / slip).
        UnreachablePoseError: a leg cannot reach the pose.
        SingularityError: a type-I, gimbal-lock or type-II singular pose.
    """
    closed_form = dynamics.closed_form
    geo = closed_form.dynamics_geo
    if geo[K.PASSIVE]:
        return None
    signs = closed_form.signs if branch is None else check_branch(branch)
    inputs = ((pose, "pose"), (twist, "twist"), (twist_dot, "twist_dot"), (wrench, "wrench"))
    pose_a, twist_a = vec6(pose, "pose"), vec6(twist, "twist")
    tdot_a = vec6(twist_dot, "twist_dot")
    wrench_a = K.ZERO6 if wrench is None else vec6(wrench, "wrench")
    s = closed_form.scratch
    code, rest, tau, out = inverse_partials_kernel(geo, signs, pose_a, twist_a, tdot_a,
                                                   wrench_a, s.rot, s.wk, s.mats)
    if code != K.OK:
        dynamics.refuse(code, inputs)
    if rest >= 0:
        raise drv.at_rest_error(twist, f"carriage {rest}", geo, K.DRIVES)
    return tau, out

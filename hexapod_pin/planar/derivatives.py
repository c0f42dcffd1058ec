"""The planar 3-PRR's inverse-dynamics derivatives: its closed form
(:mod:`~hexapod_pin.planar.kernels`) differentiated, compiled.

The planar robot's kernel behind the core chain rule
(:mod:`hexapod_pin.core.platform_derivatives`), as :mod:`hexapod_pin.hexapod.derivatives` is
the hexapod's: the closed form supplies the partials of the unbounded inverse-dynamics
forces (:meth:`~hexapod_pin.core.closed_form.ClosedFormKernels.inverse_dynamics_partials`),
the core assembles the derivatives and, by the implicit-function theorem, the
forward-dynamics ones. Effects on passive coordinates (which the closed form does not
model) and a state whose closed form misses its own residual check send the core to the
tree route instead.

Columns (12): the pose ``(x, y, theta)`` (in the plane its own world tangent), the twist,
the twist_dot and the wrench, world axes. Per leg ``k`` (symbols of
:mod:`~hexapod_pin.planar.kernels`; ``e = dn/dt = v + omega z x r - s' u``, ``b = a_xy +
alpha z x r + phi'^2 n - omega^2 r``), along a direction::

    dr = dtheta z x r,   D = dp + dr,   ds = (n.D) / nu,   dn = D - ds u
    dV = dv + domega z x r + omega z x dr,   ds' = (n.dV + dn.e) / nu,   de = dV - ds' u
    dphi' = (dn x e + n x de) / L^2
    db = da_xy + dalpha z x r + alpha z x dr + 2 phi' dphi' n + phi'^2 dn
         - 2 omega domega r - omega^2 dr
    beta = db - phi'' z x dn:   ds'' = (beta.n) / nu,   dphi'' = (u x beta) / nu

(``u s'' + (z x n) phi'' = b`` differentiated), then the Newton-Euler rows of
:func:`~hexapod_pin.planar.kernels.tree_forces` differentiated (``df``), and the tree rows
``f = S^T tau + J_c^T lambda + tau_ext`` differentiated: the same square system in ``(dtau,
dlambda)`` with the right-hand side ``df`` less the turning of the held closure forces,
``(z x dn_k).lambda_k`` on link ``k``'s row and ``-sum_k dr_k x lambda_k`` on the
platform's moment row, solved by :func:`~hexapod_pin.planar.kernels.solve_inverse` (its
type-II and residual checks included). The sliders' drives add
:func:`~hexapod_pin.core.effects_projection.inverse_load_rate`; a slider with exact Coulomb
friction at rest is refused (not differentiable). The tests check every block against
central differences of ``robot.inverse_dynamics`` and against the core's tree route
(docs/derivations.md, section 8).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ..core import effects_projection as drv
from ..core.checks import vector
from ..core.compiled import jit
from . import kernels as K
from .geometry import N_ACTUATORS

__all__ = ["N_COLUMNS", "inverse_partials", "inverse_partials_kernel"]

#: the columns of the partials: pose (world tangent), twist, twist_dot, wrench (3 each)
N_COLUMNS = 12


@jit
def _column(geo, buf, closure, twist, twist_dot, d, drives, force, info, rows, spare, out,
            col):
    """Column ``col`` of the partials along the direction ``d`` (12,) (module docstring)
    at the state in the leg buffer ``buf`` with the closure forces ``closure`` (3, 2) (the
    negated multipliers); ``force`` (9,), ``info``, ``rows`` (3,), ``spare`` (3, 2)
    scratch. Returns the status of :func:`~hexapod_pin.planar.kernels.solve_inverse`."""
    length = geo[K.G_LEN]
    length2 = length * length
    m_s, m_l = geo[K.G_MS], geo[K.G_ML]
    i_l = m_l * length2 / 12.0
    g = geo[K.G_G]
    dth, dom, dal = d[2], d[5], d[8]
    omega, alpha = twist[2], twist_dot[2]
    moment = 0.0
    for k in range(N_ACTUATORS):
        leg = buf[k]
        ux, uy = geo[7 * k + 2], geo[7 * k + 3]
        nx, ny, rx, ry, nu = leg[K.NX], leg[K.NY], leg[K.RX], leg[K.RY], leg[K.NU]
        sd, pd, sdd, pdd = leg[K.SD], leg[K.PD], leg[K.SDD], leg[K.PDD]
        lam_x, lam_y = -closure[k, 0], -closure[k, 1]
        # position
        drx, dry = -dth * ry, dth * rx
        big_dx, big_dy = d[0] + drx, d[1] + dry
        ds = (nx * big_dx + ny * big_dy) / nu
        dnx, dny = big_dx - ds * ux, big_dy - ds * uy
        # velocity: e = v + omega z x r - s' u
        ex = twist[0] - omega * ry - sd * ux
        ey = twist[1] + omega * rx - sd * uy
        dvx = d[3] - dom * ry - omega * dry
        dvy = d[4] + dom * rx + omega * drx
        dsd = (nx * dvx + ny * dvy + dnx * ex + dny * ey) / nu
        dex, dey = dvx - dsd * ux, dvy - dsd * uy
        dpd = (dnx * ey - dny * ex + nx * dey - ny * dex) / length2
        # acceleration: u s'' + (z x n) phi'' = b
        dbx = (d[6] - dal * ry - alpha * dry + 2.0 * pd * dpd * nx + pd * pd * dnx
               - 2.0 * omega * dom * rx - omega * omega * drx)
        dby = (d[7] + dal * rx + alpha * drx + 2.0 * pd * dpd * ny + pd * pd * dny
               - 2.0 * omega * dom * ry - omega * omega * dry)
        bx, by = dbx + pdd * dny, dby - pdd * dnx
        dsdd, dpdd = (bx * nx + by * ny) / nu, (ux * by - uy * bx) / nu
        # the Newton-Euler rows (tree_forces) differentiated
        ax = sdd * ux - 0.5 * (pdd * ny + pd * pd * nx)
        ay = sdd * uy + 0.5 * (pdd * nx - pd * pd * ny) + g
        dax = dsdd * ux - 0.5 * (dpdd * ny + pdd * dny + 2.0 * pd * dpd * nx + pd * pd * dnx)
        day = dsdd * uy + 0.5 * (dpdd * nx + pdd * dnx - 2.0 * pd * dpd * ny - pd * pd * dny)
        force[k] = m_s * dsdd + m_l * (dax * ux + day * uy)
        force[3 + k] = (i_l * dpdd + 0.5 * m_l * (dnx * ay + nx * day - dny * ax - ny * dax)
                        - (dnx * lam_y - dny * lam_x))          # less (z x dn).lambda
        moment += drx * lam_y - dry * lam_x                     # + dr x lambda
        out[k, col] = 0.0
        if drives:
            out[k, col] = drv.inverse_load_rate(geo, K.DRIVES, k, sd, ds, dsd, dsdd)
    m_p = geo[K.G_MP]
    force[6], force[7] = m_p * d[6], m_p * d[7]
    force[8] = geo[K.G_IP] * d[8] + moment
    status = K.solve_inverse(geo, buf, force, d[9:12], True, rows, spare, info)
    for k in range(N_ACTUATORS):
        out[k, col] += rows[k]
    return status


@jit
def inverse_partials_kernel(geo, idx, signs, pose, twist, twist_dot, wrench, has_wrench, buf,
                            info):
    """The unbounded inverse-dynamics forces ``tau`` (3,) of the closed form and their
    partials ``out`` (3, 12) (columns: module docstring) at one state on the branch
    ``signs`` (the arguments of :func:`~hexapod_pin.planar.kernels.inverse_dynamics`; the
    leg buffer ``buf`` and ``info`` written as there).

    Returns ``(status, rest, tau, out)``: the closed form's status (the partials are
    written only when OK) and the first slider whose exact Coulomb friction is at rest (-1:
    none; the partials are then not written)."""
    nv = K.I_ROW                     # the tree coordinates (idx before the row starts)
    q, v, a = np.empty(nv), np.empty(nv), np.empty(nv)
    tau, closure = np.empty(N_ACTUATORS), np.empty((N_ACTUATORS, 2))
    out = np.zeros((N_ACTUATORS, N_COLUMNS))
    status = K.inverse_dynamics(geo, idx, pose, twist, twist_dot, wrench, has_wrench, signs,
                                q, v, a, tau, closure, buf, info)
    if status != K.OK:
        return status, -1, tau, out
    drives = geo[K.DRIVES + drv.FLAG] != 0.0
    if drives:
        for k in range(N_ACTUATORS):
            if drv.at_rest(geo, K.DRIVES, k, buf[k, K.SD]):
                return K.OK, k, tau, out
    direction, force, scratch = np.empty(N_COLUMNS), np.empty(9), np.empty(K.INFO_SIZE)
    rows, spare = np.empty(N_ACTUATORS), np.empty((N_ACTUATORS, 2))
    for col in range(N_COLUMNS):
        direction[:] = 0.0
        direction[col] = 1.0
        status = _column(geo, buf, closure, twist, twist_dot, direction, drives, force,
                         scratch, rows, spare, out, col)
        if status != K.OK:
            return status, -1, tau, out
    return K.OK, -1, tau, out


def inverse_partials(dynamics: Any, pose: npt.ArrayLike, twist: npt.ArrayLike,
                     twist_dot: npt.ArrayLike, wrench: npt.ArrayLike | None = None,
                     branch: npt.ArrayLike | None = None
                     ) -> tuple[np.ndarray, np.ndarray] | None:
    """The planar robot's :meth:`~hexapod_pin.core.closed_form.ClosedFormKernels.
    inverse_dynamics_partials`: ``(tau (3,), partials (3, 12))`` (columns: module
    docstring), or None (effects on passive coordinates, or a state the closed form cannot
    verify: the core's tree route answers).

    Args:
        dynamics: the robot's :class:`~hexapod_pin.planar.dynamics.PlanarDynamics`.
        pose: ``(x, y, theta)`` (m, rad).
        twist: ``(v_x, v_y, omega)`` world axes (m/s, rad/s).
        twist_dot: its time derivative (m/s^2, rad/s^2).
        wrench: ``(f_x, f_y, m_z)`` ON the platform, moment about its origin (N, N m);
            None: zero.
        branch: the IK branch (three +-1); None: home.

    Raises:
        InputError: bad shapes, NaN / inf; a slider with Coulomb friction at rest (the
            dynamics is not differentiable there: stick / slip).
        UnreachablePoseError: a leg cannot reach the pose.
        SingularityError: a type-I or type-II singular pose.
    """
    ws = dynamics.ws
    geo = ws.dynamics_geo
    if geo[K.PASSIVE]:
        return None
    inputs = ((pose, "pose"), (twist, "twist"), (twist_dot, "twist_dot"), (wrench, "wrench"))
    pose_a, twist_a = vector(pose, 3, "pose"), vector(twist, 3, "twist")
    tdot_a = vector(twist_dot, 3, "twist_dot")
    wrench_a = None if wrench is None else vector(wrench, 3, "wrench")
    status, rest, tau, out = inverse_partials_kernel(
        geo, ws.idx, ws.signs(branch), pose_a, twist_a, tdot_a,
        ws.zero3 if wrench_a is None else wrench_a, wrench_a is not None, ws.buf, ws.info)
    if status == K.RESIDUAL:
        return None
    if status != K.OK:
        dynamics.refuse(status, inputs)
    if rest >= 0:
        raise drv.at_rest_error(twist, f"slider {rest}", geo, K.DRIVES)
    return tau, out

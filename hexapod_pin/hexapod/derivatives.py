"""Analytic derivatives of the hexapod's closed-loop inverse dynamics.

``tau = ID(pose, twist, twist_dot, wrench)`` (the unbounded ``method="kkt"`` route of
:meth:`~hexapod_pin.hexapod.dynamics.HexapodDynamics.inverse_dynamics`) is the inverse in ``tau``
of the constrained forward dynamics ``twist_dot = FD(pose, twist, tau, wrench)``. The
implicit-function theorem turns the derivatives of ``FD``, which Pinocchio computes on
the tree with the loop closures (``pin.computeConstraintDynamicsDerivatives``: the
partials ``ddq_dq``, ``ddq_dv``, ``ddq_dtau`` of the tree acceleration), into those of
``ID``::

    d tau / d y         = -(d FD / d tau)^-1  d FD / d y     (y: pose, twist, wrench)
    d tau / d twist_dot =  (d FD / d tau)^-1                  (d FD / d tau = M_x^-1 J^T)

Chain rule through the tree. ``G`` (nv, 6) is the closed-form map ``v_tree = G twist``
(:func:`~hexapod_pin.hexapod.kernels.velocity_map`). A change of pose is a
world tangent ``delta = (dp, dtheta)``: ``dp`` the displacement of the platform origin,
``dtheta`` the rotation vector in world axes (``R -> exp([dtheta]) R``); in pose
coordinates ``dtheta = E(rpy) d(rpy)`` (:func:`~hexapod_pin.core.pose.euler_rates_matrix`).
With the twist ``(v, w)`` and the wrench ``(f, m)`` held in world axes::

    dq        = G delta                              (tree tangent, as pin.integrate)
    dv_legs   = d(G twist) along delta               (closed form per leg: _leg_rates)
    dv_ff     = (R^T [v]x dtheta, R^T [w]x dtheta)   (free flyer: v_ff = (R^T v, R^T w))
    dtau_ff   = (R^T [f]x dtheta, R^T [m]x dtheta)   (the wrench as free-flyer force)
    da        = ddq_dq dq + ddq_dv dv + ddq_dtau dtau_tree     (at the ID point)
    twist_dot = (R a_lin + w x v, R a_ang),  R a_ff = (vdot - w x v, wdot)
    d twist_dot = blockdiag(R, R) da_ff - ([vdot - w x v]x dtheta, [wdot]x dtheta)

and along the twist ``dv = G dtwist`` plus ``d(w x v)``; along the wrench ``dtau_ff =
(R^T df, R^T dm)``. One product of the platform rows of Pinocchio's partials (6, 72)
with that chain (72, 24) and one 6x6 LU solve give every derivative.

Checks made while building this (Pinocchio 4.1.0): ``computeConstraintDynamicsDerivatives``
is right for these loop closures (constraints between two moving joints): its three
partials match central differences of ``pin.constraintDynamics`` along ``pin.integrate``
(the tests repeat that check). ``getFrameVelocityDerivatives`` /
``getJointVelocityDerivatives`` with ``LOCAL_WORLD_ALIGNED`` do NOT match finite
differences of ``getFrameVelocity`` / ``getVelocity`` in that frame (LOCAL and WORLD
do); a first version differentiated the velocity closures ``J_c v = 0`` with the
LOCAL variant (``d(R_f v_loc) = R_f d v_loc - [R_f v_loc]x R_f J_loc,ang dq``) and agreed
with the closed form used here, which is faster.

Joint and drive effects (``robot.effects``): the ID point balances ``rnea - tau_e`` and
``FD`` runs with the tree force ``S^T tau + tau_ext + tau_e(q, v)`` (Pinocchio's partials
hold the armature); the effects' own derivatives join the chain's ``dtau_tree`` rows:
``dtau_e = (d tau_s / dq) dq - D dv`` (the core's ``spring_jacobian``: on the free-flyer the
springs' force is the energy gradient ``-D^T K dq``, whose Jacobian is more than ``-K
dDifference(ref, q)``; Coulomb friction is piecewise constant: its
derivative is zero away from ``v = 0``), the free-flyer rows rotated to the chain's world
axes.

Everything is exact up to round-off: no finite differences inside (but for springs on the
free-flyer, whose curvature block the core's ``spring_jacobian`` extrapolates, verified).
The tests check every block against central differences of
``robot.inverse_dynamics(..., method="kkt", bounded=False)`` on both geometries, and against
the core's route (``core.platform_derivatives.inverse_dynamics_derivatives``, the
implicit-function theorem on the core's KKT derivatives, which every loaded robot uses;
this closed form stays as the faster kernel). The per-robot workspace (Pinocchio data,
buffers) is shared between calls: not thread-safe, like the rest of the dynamics.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from scipy.linalg.lapack import dgesv

from ..core.checks import as_array, vec6
from ..core.pose import euler_rates_matrix
from ..core.results import InverseDynamicsDerivatives
from ..errors import HexapodPinError, SolverError
from . import kernels
from ..core.closed_loop import ClosedLoopModel
from ..core.dynamics_derivatives import spring_jacobian
from ..core.effects import effect_forces
from .geometry import HexapodGeometry, carriage_frames

__all__ = ["DerivativesWorkspace", "analytic_derivatives"]


class DerivativesWorkspace:
    """Pinocchio data, buffers and constants of one hexapod (each robot keeps one).

    Args:
        clm: the hexapod's :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`.
        closed_form: its :class:`~hexapod_pin.hexapod.kernels.ClosedForm`.
        indices: its :class:`~hexapod_pin.hexapod.robot.HexapodIndices`.
        geometry: its :class:`~hexapod_pin.hexapod.geometry.HexapodGeometry`.


    Relies on the tree layout that :class:`~hexapod_pin.hexapod.kernels.ClosedForm`
    checks: velocity rows ``(carriage_i, u_i_a, u_i_b)`` at ``3 i .. 3 i + 2`` for
    ``i = 0..5``, then the platform's free-flyer at 18..23; six point closures.
    """

    def __init__(self, clm: ClosedLoopModel, closed_form: kernels.ClosedForm,
                 indices: Any, geometry: HexapodGeometry) -> None:
        model = clm.model
        self.model = model
        self.clm = clm
        self.closed_form = closed_form
        self.scratch = kernels.Scratch()
        self.gmap = np.empty((24, 6))
        self.nv = model.nv
        self.act = np.asarray(clm.actuated_v, dtype=int)
        if (clm.n_rows != 18 or any(c.type != "point" for c in clm.closures)
                or self.act.tolist() != indices.carriage_v.tolist()):
            raise HexapodPinError("analytic derivatives need the hexapod's six point "
                                  f"closures and carriage actuation (got {clm.n_rows} "
                                  f"closure rows, actuated velocities {self.act.tolist()})")
        self.cms, self.cds = clm.pinocchio_constraints()
        self.data = model.createData()          # constraint dynamics and its derivatives
        self.kin = model.createData()           # rnea
        pin.initConstraintDynamics(model, self.data, self.cms, self.cds)
        self.prox = pin.ProximalSettings(1e-14, 0.0, 1)
        chains = geometry.chain_geometry
        self.lengths = chains.leg_lengths.tolist()
        # per carriage: the frame (u, l, w) of the carriage (geometry.carriage_frames)
        self.axes = [tuple(tuple(axis) for axis in frame.T.tolist())
                     for frame in carriage_frames(chains)]
        # rows (dq | dv | dtau_tree) x columns (world tangent | twist | wrench | tau); the
        # zeros and the actuation block stay, the rest is overwritten at each call
        chain = np.zeros((3 * self.nv, 24))
        eye3 = np.eye(3)
        chain[18:21, 0:3] = chain[21:24, 3:6] = eye3           # dq_ff (world axes)
        chain[42:45, 6:9] = chain[45:48, 9:12] = eye3          # dv_ff = d twist
        chain[66:69, 12:15] = chain[69:72, 15:18] = eye3       # dtau_ff = d wrench
        chain[2 * self.nv + self.act, 18:24] = np.eye(6)       # dtau_tree = S dtau
        self.chain = chain
        # skew entries [x]_(r, c) = s x_k, as (r, c, k, s); set at every call
        pattern = ((0, 1, 2, -1), (0, 2, 1, 1), (1, 0, 2, 1), (1, 2, 0, -1),
                   (2, 0, 1, -1), (2, 1, 0, 1))
        # dv_ff = ([v]x dtheta, [w]x dtheta), dtau_ff = ([f]x dtheta, [m]x dtheta)
        self.skew_rows = np.array([base + r for base in (42, 45, 66, 69)
                                   for r, _, _, _ in pattern])
        self.skew_cols = np.array([3 + c for _ in range(4) for _, c, _, _ in pattern])
        # twist_dot corrections: -[p]x, -[wdot]x in the dtheta columns (p = vdot - w x v),
        # +[w]x on dv, -[v]x on dw (rows of d vdot)
        self.fix_rows = np.array([base + r for base in (0, 3, 0, 0) for r, _, _, _ in pattern])
        self.fix_cols = np.array([base + c for base in (3, 3, 6, 9) for _, c, _, _ in pattern])
        self.eye6 = np.eye(6)

    @staticmethod
    def rot6(rot: Sequence[float]) -> np.ndarray:
        """``blockdiag(R, R)`` (6, 6) from the 9 row-major floats of ``R``."""
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = rot
        return np.array(((r00, r01, r02, 0.0, 0.0, 0.0), (r10, r11, r12, 0.0, 0.0, 0.0),
                         (r20, r21, r22, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, r00, r01, r02),
                         (0.0, 0.0, 0.0, r10, r11, r12), (0.0, 0.0, 0.0, r20, r21, r22)))


def analytic_derivatives(ws: DerivativesWorkspace, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         twist_dot: npt.ArrayLike,
                         wrench: npt.ArrayLike | None = None) -> InverseDynamicsDerivatives:
    """Analytic derivatives of the hexapod's inverse-dynamics actuator forces.

    The forces are those of ``robot.inverse_dynamics(pose, twist, twist_dot, wrench,
    method="kkt", bounded=False)`` (no actuator bounds); the derivatives come from the
    implicit-function theorem applied to Pinocchio's constrained forward dynamics and
    its derivatives on the tree with the loop closures (see the module docstring).
    Exact up to round-off.

    Args:
        ws: the robot's :class:`DerivativesWorkspace` (home IK branch).
        pose: ``(x, y, z, roll, pitch, yaw)`` (m, rad), shape (6,).
        twist: ``(v, w)`` of the platform origin, world axes (m/s, rad/s), (6,).
        twist_dot: time derivative of the twist (m/s^2, rad/s^2), (6,).
        wrench: ``(f, m)`` applied on the platform by the environment, world axes,
            moment about the platform origin (N, N m), (6,); default zero.

    Returns:
        :class:`InverseDynamicsDerivatives` (``actuator_forces``, ``d_pose``, ``d_world``,
        ``d_twist``, ``d_twist_dot``, ``d_wrench``; each derivative (6, 6), row i =
        carriage i).

    Raises:
        InputError: an argument is not a finite 6-vector.
        UnreachablePoseError: the pose cannot be reached.
        SingularityError: a leg perpendicular to its rail (type I), a leg along its
            rail (gimbal lock) or a type-II singularity.
        SolverError: Pinocchio's constrained dynamics returned non-finite values.
    """
    pose, twist = as_array(pose, (6,), "pose"), as_array(twist, (6,), "twist")
    twist_dot = as_array(twist_dot, (6,), "twist_dot")
    wrench_a = kernels.ZERO6 if wrench is None else vec6(as_array(wrench, (6,), "wrench"),
                                                         "wrench")
    model, data, ck, scr = ws.model, ws.data, ws.closed_form, ws.scratch

    # -- the inverse-dynamics point (closed-form tree state, one rnea, one 6x6 solve)
    q, v, acc = np.empty(25), np.empty(24), np.empty(24)
    code = kernels.tree_state(ck.geo, ck.signs, pose, twist, twist_dot, 2, q, v, acc,
                              scr.rot, scr.wk)
    if code != kernels.OK:
        raise kernels.error_of(code, ck.geo, scr.wk)
    force = pin.rnea(model, ws.kin, q, v, acc)
    effects = ws.clm.effects
    tau_e = effect_forces(model, effects, q, v, acc) if effects.has_forces else None
    if tau_e is not None:
        force -= tau_e
    rhs, tau = np.empty(6), np.empty(6)
    kernels.project(ck.geo, scr.rot, scr.wk, force, wrench_a, True, rhs)
    code = kernels.solve_forces(ck.geo, scr.wk, scr.mats, rhs, tau, np.empty(6),
                                np.empty((6, 6)))
    if code != kernels.OK:                     # type II
        raise kernels.error_of(code, ck.geo, scr.wk)
    wrench = wrench_a.tolist()
    twist_l, twist_dot = twist.tolist(), twist_dot.tolist()

    # -- constrained forward dynamics and its derivatives at (q, v, tau_tree)
    rot = scr.rot.tolist()
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rot
    fx, fy, fz, mx, my, mz = wrench
    tau_tree: list[float] = []
    for t in tau:
        tau_tree += (t, 0.0, 0.0)              # the carriages, then the free flyer (R^T f, R^T m)
    tau_tree += (r00 * fx + r10 * fy + r20 * fz, r01 * fx + r11 * fy + r21 * fz,
                 r02 * fx + r12 * fy + r22 * fz, r00 * mx + r10 * my + r20 * mz,
                 r01 * mx + r11 * my + r21 * mz, r02 * mx + r12 * my + r22 * mz)
    tau_full = np.array(tau_tree) if tau_e is None else np.array(tau_tree) + tau_e
    pin.constraintDynamics(model, data, q, v, tau_full, ws.cms, ws.cds, ws.prox)
    pin.computeConstraintDynamicsDerivatives(model, data, ws.cms, ws.cds, ws.prox)
    # platform rows of (ddq_dq | ddq_dv | ddq_dtau) (6, 72); their free-flyer columns
    # times blockdiag(R^T, R^T), so that the free-flyer rows of the chain are world-axes
    # quantities: dq_ff = R^T dp, R^T dtheta; dv_ff = R^T (v x dtheta, w x dtheta) ...
    partials = np.concatenate((data.ddq_dq[18:24], data.ddq_dv[18:24],
                               data.ddq_dtau[18:24]), axis=1)
    blocks = partials.reshape(6, 3, 8, 3)
    blocks[:, :, 6:8] = blocks[:, :, 6:8] @ np.array(rot).reshape(3, 3).T

    # -- the chain (72, 24): rows (dq | dv | dtau_tree), columns (world tangent | twist |
    #    wrench | tau); its constant part is set up once (see DerivativesWorkspace)
    kernels.velocity_map(ck.geo, scr.rot, scr.wk, ws.gmap)
    dv_rows = _leg_rates(ws, scr.wk, ws.gmap, twist_l, v.tolist())
    chain = ws.chain
    chain[0:18, 0:6] = chain[24:42, 6:12] = ws.gmap[:18]       # dq = G delta, dv = G dtwist
    chain[24:42, 0:6] = dv_rows                               # dv along delta, twist held
    vx, vy, vz, wx, wy, wz = twist_l
    chain[ws.skew_rows, ws.skew_cols] = (-vz, vy, vz, -vx, -vy, vx, -wz, wy, wz, -wx, -wy,
                                         wx, -fz, fy, fz, -fx, -fy, fx, -mz, my, mz, -mx,
                                         -my, mx)
    if tau_e is not None:
        chain = chain.copy()
        chain[48:72] += _effect_rows(ws, effects, q, np.array(rot).reshape(3, 3), chain)
    # d(twist_dot) (world) = blockdiag(R, R) d(a_ff) + the rotation of R a_ff along
    # dtheta (R a_ff = (vdot - w x v, wdot)) + d(w x v) / d twist
    rows = ws.rot6(rot) @ (partials @ chain)
    ax, ay, az, bx, by, bz = twist_dot
    px, py, pz = ax - (wy * vz - wz * vy), ay - (wz * vx - wx * vz), az - (wx * vy - wy * vx)
    rows[ws.fix_rows, ws.fix_cols] += (pz, -py, -pz, px, py, -px, bz, -by, -bz, bx, by, -bx,
                                       -wz, wy, wz, -wx, -wy, wx, vz, -vy, -vz, vx, vy, -vx)
    # implicit-function theorem: d tau = -(d twist_dot / d tau)^-1 d twist_dot / d (.)
    dxi_dtau = rows[:, 18:24].copy()                          # = M_x^-1 J^T
    rows[:, 18:24] = ws.eye6
    # (regular: the type-II test of the leg matrix passed above)
    _, _, sol, info = dgesv(dxi_dtau, rows)
    if info != 0 or not math.isfinite(sol.sum()):
        raise SolverError("pin.constraintDynamics / computeConstraintDynamicsDerivatives",
                          "non-finite derivatives", "the closures may be redundant")
    neg = -sol
    d_pose = neg[:, 0:6].copy()
    d_pose[:, 3:] = neg[:, 3:6] @ euler_rates_matrix(np.array(pose[3:]))
    return InverseDynamicsDerivatives(tau, d_pose, neg[:, 0:6], neg[:, 6:12],
                               sol[:, 18:24], neg[:, 12:18])


def _effect_rows(ws: DerivativesWorkspace, effects, q, rot, chain) -> np.ndarray:
    """The chain's ``dtau_tree`` rows (24, 24) of the effects: ``dtau_e = (d tau_s / dq) dq
    - D dv`` in the tree's local coordinates (the springs' Jacobian of the core,
    :func:`~hexapod_pin.core.dynamics_derivatives.spring_jacobian`: on the free-flyer the
    force is the energy gradient ``-D^T K dq`` and its Jacobian has a curvature term
    beyond ``-K dDifference``), with the free-flyer
    rows of ``dq``, ``dv`` (chain rows 18:24, 42:48) and of the result in world axes
    (``blockdiag(R, R)`` times the local ones, as the chain keeps them)."""
    nv = ws.nv
    rb = np.eye(nv)
    rb[18:21, 18:21] = rb[21:24, 21:24] = rot
    dq_local, dv_local = rb.T @ chain[0:nv], rb.T @ chain[nv:2 * nv]
    out = -effects.damping[:, None] * dv_local
    if effects.stiffness.any():
        out += spring_jacobian(ws.model, effects, q) @ dq_local
    return rb @ out


def _leg_rates(ws: DerivativesWorkspace, wk, gmap, twist, vel):
    """Leg rows of ``dv = d(G twist)`` along the six world tangents, from the legs in
    ``wk`` (:mod:`~hexapod_pin.hexapod.kernels` rows) and ``G`` (24, 6).

    Returns a list of 18 rows (6 floats each), rows ``3 i, 3 i + 1, 3 i + 2`` for the
    carriage, ``u_i_a`` and ``u_i_b`` velocities of leg ``i`` (columns ``(dp, dtheta)``).

    Per leg (carriage ``i`` on rail ``k``; the tree velocity of
    :func:`~hexapod_pin.hexapod.kernels.tree_velocity`), along ``delta = (dp,
    dtheta)`` with the twist held, the platform point moves by ``D = dp + dtheta x r``,
    the arm by ``dr = dtheta x r`` and the tip velocity ``V = v + w x r`` by
    ``dV = w x dr``. Every differential below is ``a.D + b.dr`` for 3-vectors ``a``,
    ``b``, i.e. the row ``[a, r x (a + b)]`` against ``delta``::

        dq_i = n.D / (n.u)            (a = g_c = n / (n.u): the rows of G are [g, r x g])
        c.dn = c.D - (c.u) dq_i       for dn = D - dq_i u
        d qdot_i = (V.dn + n.dV - qdot_i u.dn) / (n.u),      c.dV = (c x w).dr
        c.d(dn/dt) = c.dV - (c.u) d qdot_i
        X = n.w / L, Y = -n.l / L, rho^2 = X^2 + Y^2     ((u, l, w) the carriage frame)
        adot = -(X (dn/dt).l + Y (dn/dt).w) / (L rho^2),   bdot = (dn/dt).u / (L rho)

    differentiated term by term.
    """
    wx, wy, wz = twist[3:]
    K = kernels
    dv_rows = []
    cols = wk[[K.NX, K.NY, K.NZ, K.RX, K.RY, K.RZ, K.NU, K.XA, K.YA, K.RHO2, K.DNX, K.DNY,
               K.DNZ]].T.tolist()
    for i, ((ux, uy, uz), (lx, ly, lz), (kx, ky, kz)) in enumerate(ws.axes):
        length = ws.lengths[i]
        inv_len = 1.0 / length
        nx, ny, nz, rx, ry, rz, nu, big_x, big_y, rho2, ex, ey, ez = cols[i]   # ex: dn/dt
        rho = rho2 ** 0.5
        qdot, adot, bdot = vel[3 * i:3 * i + 3]
        tx, ty, tz = ex + qdot * ux, ey + qdot * uy, ez + qdot * uz   # V
        # the legs' rows [g, r x g] of G: g_c, g_a, g_b
        gcx, gcy, gcz = gmap[3 * i, :3]
        # d qdot: a = (V - (V.u) g_c - qdot (u - g_c)) / nu,  b = (n x w) / nu
        tu = tx * ux + ty * uy + tz * uz
        aqx = (tx - tu * gcx - qdot * (ux - gcx)) / nu
        aqy = (ty - tu * gcy - qdot * (uy - gcy)) / nu
        aqz = (tz - tu * gcz - qdot * (uz - gcz)) / nu
        bqx, bqy, bqz = (ny * wz - nz * wy) / nu, (nz * wx - nx * wz) / nu, \
            (nx * wy - ny * wx) / nu
        # dX (c = w / L, w = (kx, ky, kz) the frame's third axis), dY (c = -l / L), d rho^2
        cu = kx * ux + ky * uy + kz * uz
        axx, axy, axz = (kx - cu * gcx) * inv_len, (ky - cu * gcy) * inv_len, \
            (kz - cu * gcz) * inv_len
        cu = lx * ux + ly * uy + lz * uz
        ayx, ayy, ayz = (cu * gcx - lx) * inv_len, (cu * gcy - ly) * inv_len, \
            (cu * gcz - lz) * inv_len
        arx, ary, arz = 2.0 * (big_x * axx + big_y * ayx), 2.0 * (big_x * axy + big_y * ayy), \
            2.0 * (big_x * axz + big_y * ayz)
        # d adot: num = -X (dn/dt).l - Y (dn/dt).w, c = -(X l + Y w) on d(dn/dt)
        ndl, ndz = ex * lx + ey * ly + ez * lz, ex * kx + ey * ky + ez * kz
        cx, cy, cz = -(big_x * lx + big_y * kx), -(big_x * ly + big_y * ky), \
            -(big_x * lz + big_y * kz)
        cu = cx * ux + cy * uy + cz * uz
        k_a, k_r = 1.0 / (length * rho2), adot / rho2
        aax = (-ndl * axx - ndz * ayx - cu * aqx) * k_a - k_r * arx
        aay = (-ndl * axy - ndz * ayy - cu * aqy) * k_a - k_r * ary
        aaz = (-ndl * axz - ndz * ayz - cu * aqz) * k_a - k_r * arz
        bax = (cy * wz - cz * wy - cu * bqx) * k_a
        bay = (cz * wx - cx * wz - cu * bqy) * k_a
        baz = (cx * wy - cy * wx - cu * bqz) * k_a
        # d bdot: c = u on d(dn/dt)
        k_b, k_r = inv_len / rho, 0.5 * bdot / rho2
        abx, aby, abz = -aqx * k_b - k_r * arx, -aqy * k_b - k_r * ary, -aqz * k_b - k_r * arz
        bbx = (uy * wz - uz * wy - bqx) * k_b
        bby = (uz * wx - ux * wz - bqy) * k_b
        bbz = (ux * wy - uy * wx - bqz) * k_b
        for (ax, ay, az), (sx, sy, sz) in (((aqx, aqy, aqz), (bqx, bqy, bqz)),
                                           ((aax, aay, aaz), (bax, bay, baz)),
                                           ((abx, aby, abz), (bbx, bby, bbz))):
            sx, sy, sz = sx + ax, sy + ay, sz + az
            dv_rows.append((ax, ay, az, ry * sz - rz * sy, rz * sx - rx * sz,
                            rx * sy - ry * sx))
    return dv_rows

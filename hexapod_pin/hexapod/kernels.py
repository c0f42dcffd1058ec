"""The hexapod's closed form, written once: compiled (numba) kernels for one state.

Every closed-form route of the hexapod runs these kernels: the single-state methods
(kinematics, the tree state of the Pinocchio routes, the compiled dynamics), the batch
methods (:mod:`hexapod_pin.hexapod.batch` runs the same kernels over N states with
``numba.prange``) and the simulator (:mod:`hexapod_pin.hexapod.fast`). The Pinocchio tree
routes stay the independent reference the tests compare them with.

Conventions (those of :mod:`hexapod_pin.hexapod.geometry`): pose ``(x, y, z, roll, pitch,
yaw)`` (m, rad), ``R = Rz(yaw) Ry(pitch) Rx(roll)``; twist ``(v, w)`` of the platform
origin in world axes, ``twist_dot`` its plain time derivative; wrench ``(f, m)`` applied
ON the platform, world axes, moment about the platform origin (N, N m); actuator force
``tau_i`` on carriage ``i`` along ``+u_k`` (N); carriage ``i`` on rail ``k = i // 2``.

Per-chain geometry (:func:`pack_geometry`). Every kernel reads the geometry per chain, so
the ideal drawing and an as-built robot
(:class:`~hexapod_pin.hexapod.geometry.ChainGeometry`) run the same code: chain ``i`` has
the line point ``m_k := M_i = line_points[i] + sensor_offsets[i] u_i`` (the sensor
offset folded in, so ``c_i = M_i + q_i u_i``), the direction ``u_k := u_i``, the carriage
frame ``(u, l, w)`` with ``l = normalize(z x u)``, ``w = u x l`` (the frame of the
URDF's carriage joint; ``w = z`` for a horizontal rail), the leg length ``L := L_i`` and
the platform joint ``p_k := p_i`` (any point of the platform frame). Below, ``m_k, u_k,
p_k, r_k, L`` are per chain. The type-II measure keeps the nominal ``platform_radius``
as its length scale; the linear solves with ``A`` are scaled by the nominal
``leg_length`` (``L_ref``), so that the ideal robot's arithmetic is unchanged.

Legs (:func:`legs`). With ``r_k = R p_k`` and ``d_i = t + r_k - m_k``, carriage ``i`` sits
at ``q_i = u.d + s_i sqrt(L^2 - |d|^2 + (u.d)^2)`` (branch sign ``s_i``), its leg is
``n_i = d_i - q_i u_k`` and ``J[i] = [n_i, r_k x n_i] / (n_i . u_k)`` (``qdot = J twist``).
Rates: ``dn/dt = v + w x r - qdot u``; carriage accelerations
``qddot_i = (|dn/dt|^2 + n.A_k) / (n.u)`` with ``A_k = vdot + wdot x r + w x (w x r)``.

Tree state (:func:`tree_state`, the Pinocchio tree of ``urdf/hexapod.urdf.xacro``: per
carriage a prismatic joint, a universal joint ``u_i_a`` about ``u_k`` then ``u_i_b``, and
the platform's free-flyer). In the carriage frame ``(u, l, w)``, the unit
leg direction ``e = n / L = sin(b) u - sin(a) cos(b) l + cos(a) cos(b) w``, so
``b = atan2(e.u, rho)``, ``a = atan2(-e.l, e.w)``, ``rho^2 = X^2 + Y^2`` with ``X = e.w``,
``Y = -e.l``; the rates differentiate those, the free-flyer gets ``(R^T v, R^T w)`` and
``(R^T (vdot - w x v), R^T wdot)``. ``v_tree = G twist`` (:func:`velocity_map`) and ``G^T``
maps a tree generalised force to a platform wrench (:func:`project`).

Newton-Euler closed form (:func:`inverse_dynamics`, :func:`forward_dynamics`,
:func:`static_forces`): carriage = point mass ``m_c``; leg = uniform rod ``m_l`` without
axial inertia, dynamically equivalent to point masses ``m_l/6, 2 m_l/3, m_l/6`` at its
ends and middle, i.e. end loads ``c_i = (m_c + m_l/3) qddot_i + (m_l/6) u.A_k + (m_c +
m_l/2) g u_z`` on the carriage (the last term, the weight along the rail, vanishes for a
horizontal rail) and ``F_i = (m_l/6) qddot_i u + (m_l/3) A_k + (0, 0, m_l g / 2)`` at the
tip; the
rest of the leg force is axial, ``t_i n_i``. Platform (world axes, about its origin)::

    sum_i [F_i, r_k x F_i] + [m_p (vdot + g e_z), I_w wdot + w x I_w w] - wrench
        = sum_i t_i [n_i, r_k x n_i] = A^T t,           tau_i = c_i + t_i (n_i . u_k)

Forward dynamics solves the reduced equation ``M_x twist_dot = J^T tau + wrench - h_x``
(``M_x`` symmetric positive definite, by Cholesky). The closure force of leg ``i`` ON
the platform is ``t_i n_i - F_i``. Each leg is a uniform rod of its own length ``L_i``
(the point-mass split above holds for any length).

Drives (:mod:`hexapod_pin.core.effects_projection`): the effects of the carriages'
coordinates (``robot.effects``: armature ``a_i``, damping, Coulomb friction, springs) sit
in the packed geometry after the chains and scalars (:data:`DRIVES`, :func:`pack_geometry`)
and every dynamics kernel reads them there: inverse dynamics adds ``a_i qddot_i + d_i
qdot_i + K_i (q_i - r_i) + c_i sign(qdot_i)`` to ``tau_i`` (the closure forces do not
change: the drive acts on the carriage's own coordinate), the reduced dynamics add ``J^T
diag(a) J`` to ``M_x`` and ``J^T (a qddot_0 - drive force)`` to ``h_x`` (the armature is
inertia only: the weight along a tilted rail is the carriage's and the leg's, not the
rotor's), forward dynamics solves the friction of the carriages at rest
(:func:`~hexapod_pin.core.effects_projection.stick_slip`). A rigid robot (no drive effect)
skips all of it, so its numbers are those of the rigid kernels bit for bit.

Measures: type I where ``|n.u| / L_i < TYPE_I_TOL`` (a leg perpendicular to its rail); the
universal joint's gimbal lock where ``rho^2 < GIMBAL_TOL``; type II where the smallest
singular value of ``A_hat`` (rows ``[e_i, (r_k x e_i) / platform_radius]``, the measure of
:class:`~hexapod_pin.core.results.SingularityMeasures`) is below ``TYPE_II_TOL``: one test
(:func:`factor_legs`) for every route that solves with ``A``.

Kernels never raise: they return a status code (:data:`OK`, ...), and :func:`error_of`
turns a code into the library's exception with the offending values. Scratch arrays are
passed in (``rot`` (9,), ``wk`` (WK_ROWS, 6), ``mats`` (N_MATS, 6, 6)), so that the kernels
allocate nothing and run inside ``prange`` loops and the simulator.
"""

from __future__ import annotations

import math
import threading

import numpy as np

from ..core import effects_projection as drv
from ..core.body_regressor import body_regressor
from ..core.compiled import all_finite, all_within, jit_inline
from ..core.compiled import jit_fast as jit
from ..core.measures import TYPE_I_TOL, TYPE_II_TOL
from ..core.pose import quaternion_rpy, rotation_quat, rotation_rpy, rpy_of
from ..errors import (BatchSingularityError, BatchUnreachablePoseError, HexapodPinError,
                      SingularityError, SolverError, UnreachablePoseError)
from .geometry import HOME_SIGNS, carriage_frames
from ..core.kernel_status import (GAP, GIMBAL, NONFINITE, NOT_PD, OK, RESIDUAL,  # one numbering
                                  RESIDUAL_RTOL, SATURATED, STROKE, TYPE_I, TYPE_II,
                                  UNREACHABLE)

#: the home IK branch: even carriages on the smaller root
HOME_BRANCH = HOME_SIGNS
#: rail of each carriage
RAIL_OF = np.array([0, 0, 1, 1, 2, 2])
#: ``1 - cos(leg, rail)^2`` below which a leg lies along its rail (the universal joint is
#: in gimbal lock: the leg's spin and the tree angles are undefined)
GIMBAL_TOL = 1e-10
#: relative slack of the actuator bounds
BOUND_RTOL = 1e-9


# -- packed geometry: per carriage i a block of BLOCK values at BLOCK i, then scalars ---
# M (line point with the sensor offset folded in), the carriage frame (u, l, w), the
# platform joint p, the leg length, L_ref / L_i and the type-I tolerance TYPE_I_TOL L_i
(MX, MY, MZ, UX, UY, UZ, LX, LY, LZ, WX, WY, WZ, PX, PY, PZ, LENI, SCALE,
 TOL1) = range(18)
BLOCK = 18
# LEN: the reference (nominal) leg length L_ref, the scale of the leg-matrix solves
(LEN, MC, ML, MP, IA, IB, IC, GRAV, GIMB, TOL2, BOUND, HALF, GAP_MIN,
 RADIUS) = range(6 * BLOCK, 6 * BLOCK + 14)
#: 1.0 when passive coordinates (universal joints, the free flyer) carry effects, which the
#: kernels do not model: the Python routes then answer on the Pinocchio tree
PASSIVE = 6 * BLOCK + 14
#: where the carriages' drive vector starts
#: (:func:`~hexapod_pin.core.effects_projection.pack_drives`)
DRIVES = PASSIVE + 1
GEO_SIZE = DRIVES + drv.drive_size(6)

# -- rows of the per-leg work array wk (WK_ROWS, 6), carriage order ------------------------
(RX, RY, RZ, NX, NY, NZ, NU, Q, DISC, INV, QD, DNX, DNY, DNZ, DN2, A0X, A0Y, A0Z, QDD0,
 XA, YA, RHO2, EU, QDD, AX, AY, AZ, FX, FY, FZ, CC, AXIAL, RHS, RHS0, PERM, TMP,
 TMP2, FRIC) = range(38)
#: the eight rows of the stick / slip scratch
#: (:func:`~hexapod_pin.core.effects_projection.stick_slip`)
STICK = 38
WK_ROWS = STICK + 8
#: the matrices of the scratch ``mats``: three of the rigid kernels, four of stick / slip
N_MATS = 7
#: the zero 6-vector (twist, twist_dot or wrench at rest)
ZERO6 = np.zeros(6)


def pack_geometry(geometry, drives: np.ndarray | None = None,
                  passive: bool = False) -> np.ndarray:
    """The :class:`~hexapod_pin.hexapod.geometry.HexapodGeometry` as the flat float64
    vector (GEO_SIZE,) that every kernel reads: per chain its block (the joint-centre
    line's point ``M_i = line_points[i] + sensor_offsets[i] u_i``, the carriage frame
    ``(u, l, w)`` of :func:`~hexapod_pin.hexapod.geometry.carriage_frames`, the platform
    joint, the leg length ``L_i``, ``L_ref / L_i`` and ``TYPE_I_TOL L_i``), then the
    scalars (``L_ref`` the nominal ``leg_length``), the :data:`PASSIVE` flag (``passive``:
    effects on passive coordinates), then the carriages' drive vector ``drives``
    (:func:`~hexapod_pin.core.effects_projection.pack_drives`; default none: a rigid
    robot)."""
    g = geometry
    chains = g.chain_geometry
    frames = carriage_frames(chains)
    origins = chains.line_points + chains.sensor_offsets[:, None] * chains.line_directions
    out = np.zeros(GEO_SIZE)
    for i in range(6):
        length = float(chains.leg_lengths[i])
        out[BLOCK * i:BLOCK * (i + 1)] = (*origins[i], *frames[i].T.ravel(),
                                          *chains.platform_joints[i], length,
                                          g.leg_length / length, TYPE_I_TOL * length)
    ia, ib, ic = g.platform_inertia
    out[LEN:PASSIVE] = (g.leg_length, g.carriage_mass, g.leg_mass, g.platform_mass, ia, ib,
                         ic, g.gravity, GIMBAL_TOL, TYPE_II_TOL, g.max_actuator_force,
                         g.rail_half_length, g.carriage_min_gap, g.platform_radius)
    out[PASSIVE] = float(passive)
    if drives is not None:
        out[DRIVES:] = drives
    return out


class Scratch:
    """The scratch arrays of the kernels for one state (``rot``, ``wk``, ``mats``).

    Not thread-safe: one per robot and thread.
    """

    __slots__ = ("mats", "rot", "wk")

    def __init__(self):
        self.rot = np.empty(9)
        self.wk = np.zeros((WK_ROWS, 6))
        self.mats = np.empty((N_MATS, 6, 6))


class ClosedForm:
    """The closed form of one hexapod: its packed geometry (with the carriages' drives),
    home branch and kernel scratch (one per thread): the one cache object of the robot's
    compiled closed form, shared by its kinematics, dynamics and compiled fast path.

    Args:
        geometry: the :class:`~hexapod_pin.hexapod.geometry.HexapodGeometry`.
        indices: the tree's ``HexapodIndices`` (optional): checked against the joint order
            the tree kernels assume, ``(carriage_i, u_i_a, u_i_b)`` for ``i = 0..5`` then
            the platform's free-flyer (``q`` 25, ``v`` 24).
        model: the robot's :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`
            (optional): its effects (``model.effects``) give the drives of :attr:`geo`;
            an armature written into ``model.model.armature`` by hand is noticed at the
            next access of :attr:`geo` (one comparison of 24 numbers). Without it the
            robot is rigid.

    Raises:
        HexapodPinError: a tree of another layout.
    """

    def __init__(self, geometry, indices=None, model=None):
        self.geometry = geometry
        self._packed = None if model is None else drv.PackedDrives(
            model, lambda drives, passive: pack_geometry(geometry, drives, passive))
        #: the packed geometry as built (GEO_SIZE,): its geometry part is all that the
        #: kinematic kernels read; the dynamics kernels take :attr:`dynamics_geo`
        self.geo = pack_geometry(geometry) if self._packed is None else self._packed.vector
        self.signs = HOME_BRANCH.copy()
        self._local = threading.local()
        if indices is not None:
            legs3 = np.arange(18).reshape(6, 3)
            layout = [(indices.carriage_q, legs3[:, 0]), (indices.u_a_q, legs3[:, 1]),
                      (indices.u_b_q, legs3[:, 2]), (indices.carriage_v, legs3[:, 0]),
                      (indices.u_a_v, legs3[:, 1]), (indices.u_b_v, legs3[:, 2])]
            if (any(not np.array_equal(got, want) for got, want in layout)
                    or indices.platform_q != slice(18, 25)
                    or indices.platform_v != slice(18, 24)):
                raise HexapodPinError("the hexapod kernels expect the joint order of "
                                      "urdf/hexapod.urdf.xacro: (carriage_i, u_i_a, u_i_b) "
                                      f"for i = 0..5, then platform_joint; got {indices}")

    @property
    def dynamics_geo(self) -> np.ndarray:
        """The packed geometry (GEO_SIZE,) with the current drives of the model's effects
        (read-only use; a new array when the armature was written by hand since the last
        access): what the dynamics kernels read."""
        return self.geo if self._packed is None else self._packed.vector

    @property
    def scratch(self) -> Scratch:
        """The calling thread's kernel scratch (one per thread: the object may be shared)."""
        scratch = getattr(self._local, "scratch", None)
        if scratch is None:
            scratch = self._local.scratch = Scratch()
        return scratch

    def error(self, code: int) -> HexapodPinError:
        """:func:`error_of` for the state last computed in :attr:`scratch`."""
        return error_of(code, self.geo, self.scratch.wk, self.scratch.mats[1])

    def tip_forces(self, pose, force, tau, signs=None) -> np.ndarray:
        """(6, 3) force of the platform ON each leg tip (:func:`leg_forces`) at ``pose`` (6,)
        for a tree generalised force ``force`` (24,) and actuator forces ``tau`` (6,), on the
        IK branch ``signs`` (6,) (default home); the legs are rebuilt in a fresh scratch (a
        result may ask long after its call).

        Raises:
            HexapodPinError: the pose is refused (it was accepted when ``force`` was made).
        """
        rot, wk, out = np.empty(9), np.zeros((WK_ROWS, 6)), np.empty((6, 3))
        code = leg_state(self.geo, self.signs if signs is None else signs, pose, rot, wk)
        if code != OK:
            raise error_of(code, self.geo, wk)
        tree_angles(self.geo, wk)
        leg_forces(self.geo, wk, force, tau, out)
        return out

    def closure_residual(self, q) -> float:
        """:func:`closure_residual` of a tree configuration (25,) (m)."""
        return closure_residual(self.geo, np.ascontiguousarray(q, dtype=float))


# --------------------------------------------------------------------------------------
# legs, rates, accelerations
# --------------------------------------------------------------------------------------
@jit_inline
def _worse(code, new):
    """The more severe of two leg codes (UNREACHABLE > TYPE_I > GIMBAL > OK)."""
    if new != OK and (code == OK or new < code):
        return new
    return code


@jit_inline
def legs(geo, x, y, z, rot, signs, wk):
    """Inverse kinematics and leg vectors of a platform position and ``rot`` on the branch
    ``signs`` (6,). Fills rows RX..RZ (arms ``r_k``), NX..NZ (legs), NU (``n.u``), Q, DISC
    (the discriminant; a leg that cannot reach gets the nearest rail point, DISC < 0).
    Returns UNREACHABLE, TYPE_I, GIMBAL (the worst over the legs) or OK."""
    code = OK
    for i in range(6):
        b = BLOCK * i
        length = geo[b + LENI]
        px, py, pz = geo[b + PX], geo[b + PY], geo[b + PZ]
        ux, uy, uz = geo[b + UX], geo[b + UY], geo[b + UZ]
        rx = rot[0] * px + rot[1] * py + rot[2] * pz
        ry = rot[3] * px + rot[4] * py + rot[5] * pz
        rz = rot[6] * px + rot[7] * py + rot[8] * pz
        dx, dy, dz = x + rx - geo[b + MX], y + ry - geo[b + MY], z + rz - geo[b + MZ]
        along = dx * ux + dy * uy + dz * uz
        disc = length * length - (dx * dx + dy * dy + dz * dz) + along * along
        wk[DISC, i] = disc
        root = 0.0
        if disc >= 0.0:
            root = math.sqrt(disc)
        else:
            code = UNREACHABLE
        qi = along + signs[i] * root
        nx, ny, nz = dx - qi * ux, dy - qi * uy, dz - qi * uz
        nu = nx * ux + ny * uy + nz * uz
        wk[RX, i], wk[RY, i], wk[RZ, i] = rx, ry, rz
        wk[NX, i], wk[NY, i], wk[NZ, i] = nx, ny, nz
        wk[NU, i], wk[Q, i] = nu, qi
        if not abs(nu) >= geo[b + TOL1]:
            code = _worse(code, TYPE_I)
        else:
            nl = nx * geo[b + LX] + ny * geo[b + LY] + nz * geo[b + LZ]
            nw = nx * geo[b + WX] + ny * geo[b + WY] + nz * geo[b + WZ]
            if not (nw * nw + nl * nl) >= geo[GIMB] * length * length:
                code = _worse(code, GIMBAL)
    return code


@jit
def leg_state(geo, signs, pose, rot, wk):
    """:func:`legs` of a pose (6,): NONFINITE for a non-finite pose, else its code."""
    if not all_finite(pose):
        return NONFINITE
    rotation_rpy(pose[3], pose[4], pose[5], rot)
    return legs(geo, pose[0], pose[1], pose[2], rot, signs, wk)


@jit_inline
def rates(geo, twist, wk, drift):
    """Carriage rates QD (``J twist``), INV (``1 / n.u``), leg rates DNX..DNZ and, with
    ``drift``, ``|dn/dt|^2`` (DN2), ``w x (w x r)`` (A0X..A0Z) and the carriage
    accelerations at ``twist_dot = 0`` (QDD0)."""
    vx, vy, vz, wx, wy, wz = twist[0], twist[1], twist[2], twist[3], twist[4], twist[5]
    for i in range(6):
        b = BLOCK * i
        rx, ry, rz = wk[RX, i], wk[RY, i], wk[RZ, i]
        nx, ny, nz = wk[NX, i], wk[NY, i], wk[NZ, i]
        ux, uy, uz = geo[b + UX], geo[b + UY], geo[b + UZ]
        cx, cy, cz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx
        tx, ty, tz = vx + cx, vy + cy, vz + cz
        inv = 1.0 / wk[NU, i]
        wk[INV, i] = inv
        qd = (nx * tx + ny * ty + nz * tz) * inv
        wk[QD, i] = qd
        ex, ey, ez = tx - qd * ux, ty - qd * uy, tz - qd * uz
        wk[DNX, i], wk[DNY, i], wk[DNZ, i] = ex, ey, ez
        if drift:
            dn2 = ex * ex + ey * ey + ez * ez
            ax, ay, az = wy * cz - wz * cy, wz * cx - wx * cz, wx * cy - wy * cx
            wk[DN2, i] = dn2
            wk[A0X, i], wk[A0Y, i], wk[A0Z, i] = ax, ay, az
            wk[QDD0, i] = (dn2 + nx * ax + ny * ay + nz * az) * inv


@jit_inline
def tip_accelerations(wk, twist_dot):
    """Platform-point accelerations AX..AZ (``A_k``) and carriage accelerations QDD for a
    ``twist_dot`` (after :func:`rates` with ``drift``)."""
    ax, ay, az = twist_dot[0], twist_dot[1], twist_dot[2]
    bx, by, bz = twist_dot[3], twist_dot[4], twist_dot[5]
    for i in range(6):
        rx, ry, rz = wk[RX, i], wk[RY, i], wk[RZ, i]
        cx = wk[A0X, i] + ax + (by * rz - bz * ry)
        cy = wk[A0Y, i] + ay + (bz * rx - bx * rz)
        cz = wk[A0Z, i] + az + (bx * ry - by * rx)
        wk[AX, i], wk[AY, i], wk[AZ, i] = cx, cy, cz
        wk[QDD, i] = (wk[DN2, i] + wk[NX, i] * cx + wk[NY, i] * cy + wk[NZ, i] * cz) \
            * wk[INV, i]


@jit
def motion_state(geo, signs, pose, twist, other, wrench, rot, wk):
    """The common start of the dynamics kernels: the four input vectors finite, then
    ``R``, the legs and their rates (with drift); returns a code."""
    if not (all_finite(pose) and all_finite(twist) and all_finite(other)
            and all_finite(wrench)):
        return NONFINITE
    rotation_rpy(pose[3], pose[4], pose[5], rot)
    code = legs(geo, pose[0], pose[1], pose[2], rot, signs, wk)
    if code != OK:
        return code
    rates(geo, twist, wk, True)
    return OK


@jit_inline
def limits(geo, wk):
    """STROKE (``|q_i| > rail_half_length``), GAP (``q_2k+1 - q_2k < carriage_min_gap``)
    or OK, for the carriages in row Q."""
    for i in range(6):
        if abs(wk[Q, i]) > geo[HALF]:
            return STROKE
    for k in range(3):
        if wk[Q, 2 * k + 1] - wk[Q, 2 * k] < geo[GAP_MIN]:
            return GAP
    return OK


# --------------------------------------------------------------------------------------
# Jacobians
# --------------------------------------------------------------------------------------
@jit_inline
def jacobian(wk, out):
    """``J`` (6, 6): ``J[i] = [n_i, r_k x n_i] / (n_i . u_k)`` (after :func:`legs`)."""
    for i in range(6):
        rx, ry, rz = wk[RX, i], wk[RY, i], wk[RZ, i]
        nx, ny, nz = wk[NX, i], wk[NY, i], wk[NZ, i]
        inv = 1.0 / wk[NU, i]
        out[i, 0], out[i, 1], out[i, 2] = nx * inv, ny * inv, nz * inv
        out[i, 3] = (ry * nz - rz * ny) * inv
        out[i, 4] = (rz * nx - rx * nz) * inv
        out[i, 5] = (rx * ny - ry * nx) * inv


@jit
def jacobian_derivative(geo, wk, twist, out):
    """``dJ/dt`` (6, 6) along ``twist`` (after :func:`rates`): with ``dr = w x r``,
    ``dJ[i] = [dn, dr x n + r x dn] / (n.u) - J[i] (dn.u) / (n.u)``."""
    wx, wy, wz = twist[3], twist[4], twist[5]
    for i in range(6):
        b = BLOCK * i
        rx, ry, rz = wk[RX, i], wk[RY, i], wk[RZ, i]
        nx, ny, nz = wk[NX, i], wk[NY, i], wk[NZ, i]
        ex, ey, ez = wk[DNX, i], wk[DNY, i], wk[DNZ, i]
        inv = wk[INV, i]
        rate = (ex * geo[b + UX] + ey * geo[b + UY] + ez * geo[b + UZ]) * inv
        sx, sy, sz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx
        mx = sy * nz - sz * ny + ry * ez - rz * ey
        my = sz * nx - sx * nz + rz * ex - rx * ez
        mz = sx * ny - sy * nx + rx * ey - ry * ex
        out[i, 0] = (ex - nx * rate) * inv
        out[i, 1] = (ey - ny * rate) * inv
        out[i, 2] = (ez - nz * rate) * inv
        out[i, 3] = (mx - (ry * nz - rz * ny) * rate) * inv
        out[i, 4] = (my - (rz * nx - rx * nz) * rate) * inv
        out[i, 5] = (mz - (rx * ny - ry * nx) * rate) * inv


@jit
def leg_motion(geo, wk, with_acc, out):
    """Motion of the six rigid legs (after :func:`rates` and, with ``with_acc``,
    :func:`tip_accelerations`) into ``out`` (6, 6, 3): per leg the unit direction
    ``e``, centre of mass ``c_i + e L/2``, angular velocity ``w = e x de + lam e``
    (``lam = c (e x de).u / (1 - c^2)``, ``c = u.e``: the spin the universal joint
    imposes), centre-of-mass velocity ``qdot u + dn/2`` and, with ``with_acc``, the
    angular acceleration ``e x dde + dlam e + lam de`` and the centre-of-mass acceleration
    ``qddot u + ddn/2``. Returns GIMBAL where a leg lies along its rail, else OK."""
    for i in range(6):
        b = BLOCK * i
        inv_len = 1.0 / geo[b + LENI]
        ux, uy, uz = geo[b + UX], geo[b + UY], geo[b + UZ]
        nx, ny, nz, qi = wk[NX, i], wk[NY, i], wk[NZ, i], wk[Q, i]
        ex, ey, ez = nx * inv_len, ny * inv_len, nz * inv_len
        dx, dy, dz = wk[DNX, i] * inv_len, wk[DNY, i] * inv_len, wk[DNZ, i] * inv_len
        cosine = wk[NU, i] * inv_len
        gimbal = 1.0 - cosine * cosine
        if not gimbal >= geo[GIMB]:
            return GIMBAL
        px, py, pz = ey * dz - ez * dy, ez * dx - ex * dz, ex * dy - ey * dx
        sigma = px * ux + py * uy + pz * uz
        spin = cosine * sigma / gimbal
        qd = wk[QD, i]
        out[0, i, 0], out[0, i, 1], out[0, i, 2] = ex, ey, ez
        out[1, i, 0] = geo[b + MX] + qi * ux + 0.5 * nx
        out[1, i, 1] = geo[b + MY] + qi * uy + 0.5 * ny
        out[1, i, 2] = geo[b + MZ] + qi * uz + 0.5 * nz
        out[2, i, 0], out[2, i, 1], out[2, i, 2] = px + spin * ex, py + spin * ey, \
            pz + spin * ez
        out[3, i, 0] = qd * ux + 0.5 * wk[DNX, i]
        out[3, i, 1] = qd * uy + 0.5 * wk[DNY, i]
        out[3, i, 2] = qd * uz + 0.5 * wk[DNZ, i]
        if not with_acc:
            continue
        qdd = wk[QDD, i]
        ddx, ddy, ddz = wk[AX, i] - qdd * ux, wk[AY, i] - qdd * uy, wk[AZ, i] - qdd * uz
        fx, fy, fz = ddx * inv_len, ddy * inv_len, ddz * inv_len
        qx, qy, qz = ey * fz - ez * fy, ez * fx - ex * fz, ex * fy - ey * fx
        dcos = dx * ux + dy * uy + dz * uz
        dspin = ((dcos * sigma + cosine * (qx * ux + qy * uy + qz * uz)) / gimbal
                 + 2.0 * cosine * cosine * dcos * sigma / (gimbal * gimbal))
        out[4, i, 0] = qx + dspin * ex + spin * dx
        out[4, i, 1] = qy + dspin * ey + spin * dy
        out[4, i, 2] = qz + dspin * ez + spin * dz
        out[5, i, 0] = qdd * ux + 0.5 * ddx
        out[5, i, 1] = qdd * uy + 0.5 * ddy
        out[5, i, 2] = qdd * uz + 0.5 * ddz
    return OK


# --------------------------------------------------------------------------------------
# the leg matrix: one factorisation, one type-II test
# --------------------------------------------------------------------------------------
@jit_inline
def _lu_solve(lu, perm, vec, out):
    """``out = (P^T L U)^-1 vec`` for the factors of :func:`factor_legs`."""
    for j in range(6):
        out[j] = vec[int(perm[j])]
    for r in range(6):
        acc = out[r]
        for c in range(r):
            acc -= lu[r, c] * out[c]
        out[r] = acc
    for r in range(5, -1, -1):
        acc = out[r]
        for c in range(r + 1, 6):
            acc -= lu[r, c] * out[c]
        out[r] = acc / lu[r, r]


@jit_inline
def closure_matrix_hat(geo, wk, out):
    """``A_hat`` (6, 6), rows ``[e_i, (r_k x e_i) / platform_radius]``, ``e = n / L_i``."""
    for i in range(6):
        inv_len = 1.0 / geo[BLOCK * i + LENI]
        inv_rad = inv_len / geo[RADIUS]
        rx, ry, rz = wk[RX, i], wk[RY, i], wk[RZ, i]
        nx, ny, nz = wk[NX, i], wk[NY, i], wk[NZ, i]
        out[i, 0], out[i, 1], out[i, 2] = nx * inv_len, ny * inv_len, nz * inv_len
        out[i, 3] = (ry * nz - rz * ny) * inv_rad
        out[i, 4] = (rz * nx - rx * nz) * inv_rad
        out[i, 5] = (rx * ny - ry * nx) * inv_rad


@jit
def smallest_singular_value(mat):
    """The smallest singular value of a (6, 6) matrix, overwritten (one-sided Jacobi:
    orthogonalise the columns by plane rotations; their norms are the singular values,
    each to high relative accuracy)."""
    for _ in range(60):
        rotated = False
        for p in range(5):
            for q in range(p + 1, 6):
                alpha = beta = gamma = 0.0
                for r in range(6):
                    alpha += mat[r, p] * mat[r, p]
                    beta += mat[r, q] * mat[r, q]
                    gamma += mat[r, p] * mat[r, q]
                if gamma == 0.0 or abs(gamma) <= 1e-16 * math.sqrt(alpha * beta):
                    continue
                rotated = True
                zeta = (beta - alpha) / (2.0 * gamma)
                t = math.copysign(1.0, zeta) / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
                c = 1.0 / math.sqrt(1.0 + t * t)
                s = c * t
                for r in range(6):
                    a, b = mat[r, p], mat[r, q]
                    mat[r, p], mat[r, q] = c * a - s * b, s * a + c * b
        if not rotated:
            break
    small = np.inf
    for c in range(6):
        acc = 0.0
        for r in range(6):
            acc += mat[r, c] * mat[r, c]
        small = min(small, math.sqrt(acc))
    return small


@jit
def type_two_measure(geo, wk, scratch):
    """``sigma_min(A_hat)`` of the legs in ``wk`` (the type-II measure); ``scratch`` (6, 6)."""
    closure_matrix_hat(geo, wk, scratch)
    return smallest_singular_value(scratch)


@jit
def factor_legs(geo, wk, mats):
    """Factor ``A_hat^T`` (column i ``[e_i, (r_k x e_i) / platform_radius]``) by LU with
    partial pivoting into ``mats[0]`` (row order in wk[PERM]) and apply the type-II test:
    TYPE_II where ``sigma_min(A_hat) < TYPE_II_TOL``, else OK.

    The test is exact and cheap: ``1 / |A_hat^-1|_F <= sigma_min``, so a pose passes at
    once when that bound clears the tolerance; only below it are the singular values
    computed (:func:`smallest_singular_value`)."""
    lu, scratch = mats[0], mats[1]
    perm = wk[PERM]
    closure_matrix_hat(geo, wk, scratch)
    for r in range(6):
        perm[r] = r
        for c in range(6):
            lu[r, c] = scratch[c, r]
    singular = False
    for col in range(6):
        piv, best = col, abs(lu[col, col])
        for row in range(col + 1, 6):
            if abs(lu[row, col]) > best:
                piv, best = row, abs(lu[row, col])
        if best == 0.0:
            singular = True
            break
        if piv != col:
            for j in range(6):
                lu[col, j], lu[piv, j] = lu[piv, j], lu[col, j]
            perm[col], perm[piv] = perm[piv], perm[col]
        for row in range(col + 1, 6):
            f = lu[row, col] / lu[col, col]
            lu[row, col] = f
            for j in range(col + 1, 6):
                lu[row, j] -= f * lu[col, j]
    if singular:
        return TYPE_II
    unit, col = wk[TMP], wk[TMP2]
    frob = 0.0
    for j in range(6):
        for r in range(6):
            unit[r] = 0.0
        unit[j] = 1.0
        _lu_solve(lu, perm, unit, col)
        for r in range(6):
            frob += col[r] * col[r]
    tol = geo[TOL2]
    if frob * tol * tol <= 1.0:
        return OK
    if smallest_singular_value(scratch) < tol:
        return TYPE_II
    return OK


@jit_inline
def solve_legs(geo, wk, mats, rhs):
    """Solve ``A^T t = rhs`` in place (``A`` rows ``[n_i, r_k x n_i]``) with the factors of
    :func:`factor_legs`: ``A = diag(L_i) A_hat D^-1``, ``D = diag(1, 1, 1, 1/R, 1/R,
    1/R)``, so ``A_hat^T y = D rhs / L_ref`` and ``t_i = y_i L_ref / L_i``."""
    inv_len = 1.0 / geo[LEN]
    inv_rad = inv_len / geo[RADIUS]
    vec = wk[TMP]
    for j in range(3):
        vec[j] = rhs[j] * inv_len
        vec[3 + j] = rhs[3 + j] * inv_rad
    _lu_solve(mats[0], wk[PERM], vec, rhs)
    for i in range(6):
        rhs[i] *= geo[BLOCK * i + SCALE]


@jit_inline
def solve_transposed(geo, wk, mats, vec):
    """Solve ``J^T x = vec`` in place with the factors of :func:`factor_legs`: ``J =
    diag(1 / n_i.u_k) A``, so ``A^T t = vec`` (:func:`solve_legs`) and ``x_i = (n_i.u_k)
    t_i`` (the actuator forces of a platform wrench ``vec``)."""
    solve_legs(geo, wk, mats, vec)
    for i in range(6):
        vec[i] *= wk[NU, i]


# --------------------------------------------------------------------------------------
# Newton-Euler closed form
# --------------------------------------------------------------------------------------
@jit_inline
def add_point_force(out, rx, ry, rz, fx, fy, fz):
    """``out[0:6] += [f, r x f]``: a force ``f`` at ``r`` as a wrench about the origin."""
    out[0] += fx
    out[1] += fy
    out[2] += fz
    out[3] += ry * fz - rz * fy
    out[4] += rz * fx - rx * fz
    out[5] += rx * fy - ry * fx


@jit_inline
def end_loads(geo, wk):
    """Carriage loads CC (``c_i``) and tip loads FX..FZ (``F_i``) of the legs (after
    :func:`tip_accelerations`)."""
    m_l = geo[ML]
    m_leg, m_side, mu = geo[MC] + m_l / 3.0, m_l / 6.0, m_l / 3.0
    half_weight = 0.5 * m_l * geo[GRAV]
    rail_weight = (geo[MC] + 0.5 * m_l) * geo[GRAV]
    for i in range(6):
        b = BLOCK * i
        ux, uy, uz = geo[b + UX], geo[b + UY], geo[b + UZ]
        qdd, ax, ay, az = wk[QDD, i], wk[AX, i], wk[AY, i], wk[AZ, i]
        wk[CC, i] = m_leg * qdd + m_side * (ux * ax + uy * ay + uz * az) + rail_weight * uz
        side = m_side * qdd
        wk[FX, i] = side * ux + mu * ax
        wk[FY, i] = side * uy + mu * ay
        wk[FZ, i] = side * uz + mu * az + half_weight


@jit_inline
def inertia_world(geo, rot, vx, vy, vz):
    """``R I R^T v`` (3 floats)."""
    b0 = geo[IA] * (rot[0] * vx + rot[3] * vy + rot[6] * vz)
    b1 = geo[IB] * (rot[1] * vx + rot[4] * vy + rot[7] * vz)
    b2 = geo[IC] * (rot[2] * vx + rot[5] * vy + rot[8] * vz)
    return (rot[0] * b0 + rot[1] * b1 + rot[2] * b2, rot[3] * b0 + rot[4] * b1 + rot[5] * b2,
            rot[6] * b0 + rot[7] * b1 + rot[8] * b2)


@jit_inline
def platform_rhs(geo, rot, wk, twist, twist_dot, wrench, out):
    """``sum_i [F_i, r_k x F_i] + [m_p (vdot + g e_z), I_w wdot + w x I_w w] - wrench``."""
    for j in range(6):
        out[j] = -wrench[j]
    for i in range(6):
        add_point_force(out, wk[RX, i], wk[RY, i], wk[RZ, i], wk[FX, i], wk[FY, i], wk[FZ, i])
    m_p = geo[MP]
    out[0] += m_p * twist_dot[0]
    out[1] += m_p * twist_dot[1]
    out[2] += m_p * (twist_dot[2] + geo[GRAV])
    wx, wy, wz = twist[3], twist[4], twist[5]
    hx, hy, hz = inertia_world(geo, rot, wx, wy, wz)
    ix, iy, iz = inertia_world(geo, rot, twist_dot[3], twist_dot[4], twist_dot[5])
    out[3] += ix + wy * hz - wz * hy
    out[4] += iy + wz * hx - wx * hz
    out[5] += iz + wx * hy - wy * hx


@jit_inline
def check_bound(geo, tau, bounded):
    """SATURATED when ``bounded`` and some ``|tau_i|`` exceeds the bound, else OK."""
    if bounded and math.isfinite(geo[BOUND]):
        for i in range(6):
            if abs(tau[i]) > geo[BOUND] * (1.0 + BOUND_RTOL):
                return SATURATED
    return OK


@jit
def _axial_and_forces(geo, wk, mats, tau):
    """With the end loads and the platform right-hand side in wk[RHS]: the axial forces
    (AXIAL, ``A^T t = rhs``, the right-hand side kept in RHS0) and ``tau``."""
    code = factor_legs(geo, wk, mats)
    if code != OK:
        return code
    rhs = wk[RHS]
    for j in range(6):
        wk[RHS0, j] = rhs[j]
    solve_legs(geo, wk, mats, rhs)
    for i in range(6):
        wk[AXIAL, i] = rhs[i]
        tau[i] = wk[CC, i] + wk[NU, i] * rhs[i]
    return OK


@jit_inline
def _inverse_core(geo, rot, wk, mats, twist, twist_dot, wrench, tau):
    """The Newton-Euler inverse dynamics of the legs in ``wk`` (after :func:`rates` with
    drift and :func:`tip_accelerations`): end loads, the platform equation ``A^T t =
    rhs`` (axial forces, the type-II test), ``tau`` (6,) with the carriages' drives.
    Returns OK or TYPE_II."""
    end_loads(geo, wk)
    platform_rhs(geo, rot, wk, twist, twist_dot, wrench, wk[RHS])
    code = _axial_and_forces(geo, wk, mats, tau)
    if code != OK:
        return code
    if geo[DRIVES + drv.FLAG] != 0.0:
        for i in range(6):
            tau[i] += drv.inverse_load(geo, DRIVES, i, wk[Q, i], wk[QD, i], wk[QDD, i])
    return OK


@jit
def inverse_dynamics(geo, signs, pose, twist, twist_dot, wrench, bounded, tau, rot, wk,
                     mats):
    """Inverse dynamics (Newton-Euler closed form): fills ``tau`` (6,); the closure
    forces follow from :func:`closure_forces`. Returns a status code."""
    code = motion_state(geo, signs, pose, twist, twist_dot, wrench, rot, wk)
    if code != OK:
        return code
    tip_accelerations(wk, twist_dot)
    code = _inverse_core(geo, rot, wk, mats, twist, twist_dot, wrench, tau)
    if code != OK:
        return code
    return check_bound(geo, tau, bounded)


@jit
def inverse_verified(geo, wk, tau, closure):
    """Whether an inverse-dynamics answer (after :func:`_inverse_core` and
    :func:`closure_forces`) passes its checks: the platform equation it solved, ``A^T t =
    rhs``, holds to :data:`~hexapod_pin.core.kernel_status.RESIDUAL_RTOL` relative to
    the data (``max(1, |rhs|, |t_i| L_i (1 + |r_k|))``: a backward-error test, the size of
    each row of ``A`` times its unknown), and ``tau`` (6,) and ``closure`` (6, 3) are
    finite (False for any NaN)."""
    scale = 1.0
    for j in range(6):
        scale = max(scale, abs(wk[RHS0, j]))
    for i in range(6):
        arm = math.sqrt(wk[RX, i] ** 2 + wk[RY, i] ** 2 + wk[RZ, i] ** 2)
        scale = max(scale, abs(wk[AXIAL, i]) * geo[BLOCK * i + LENI] * (1.0 + arm))
    if not platform_residual(wk) <= RESIDUAL_RTOL * scale:
        return False
    for i in range(6):
        if not (math.isfinite(tau[i]) and math.isfinite(closure[i, 0])
                and math.isfinite(closure[i, 1]) and math.isfinite(closure[i, 2])):
            return False
    return True


@jit
def inverse_dynamics_tree(geo, signs, pose, twist, twist_dot, wrench, bounded, limit, q, v,
                          a, tau, closure, rot, wk, mats):
    """The single-state inverse dynamics in one call: the tree state ``q`` (25,), ``v``,
    ``a`` (24,) (:func:`tree_state_within`: the four inputs, passed unscanned, refused
    beyond ``limit`` or NaN / inf as NONFINITE), the Newton-Euler closed form
    (:func:`_inverse_core`: ``tau`` (6,)), the closure forces (6, 3) ON the platform
    (:func:`closure_forces`) and the answer's verification (:func:`inverse_verified`:
    RESIDUAL when it fails), then the bound test (SATURATED; ``bounded``). Returns the
    first status that is not OK, else OK."""
    if not all_within(wrench, limit):
        return NONFINITE
    code = tree_state_within(geo, signs, pose, twist, twist_dot, 2, q, v, a, rot, wk, limit)
    if code != OK:
        return code
    code = _inverse_core(geo, rot, wk, mats, twist, twist_dot, wrench, tau)
    if code != OK:
        return code
    closure_forces(wk, closure)
    if not inverse_verified(geo, wk, tau, closure):
        return RESIDUAL
    return check_bound(geo, tau, bounded)


@jit
def static_forces(geo, signs, pose, wrench, bounded, tau, rot, wk, mats):
    """Statics: :func:`inverse_dynamics` at rest; fills ``tau`` (6,), returns a code."""
    return inverse_dynamics(geo, signs, pose, ZERO6, ZERO6, wrench, bounded, tau, rot, wk,
                            mats)


@jit_inline
def closure_forces(wk, out):
    """Force (6, 3) of each leg ON the platform, world axes: ``t_i n_i - F_i``."""
    for i in range(6):
        t = wk[AXIAL, i]
        out[i, 0] = t * wk[NX, i] - wk[FX, i]
        out[i, 1] = t * wk[NY, i] - wk[FY, i]
        out[i, 2] = t * wk[NZ, i] - wk[FZ, i]


@jit_inline
def platform_residual(wk):
    """Max-abs of ``A^T t - rhs`` of the platform equation (after inverse dynamics)."""
    acc = wk[TMP]
    for j in range(6):
        acc[j] = -wk[RHS0, j]
    for i in range(6):
        t = wk[AXIAL, i]
        add_point_force(acc, wk[RX, i], wk[RY, i], wk[RZ, i], t * wk[NX, i], t * wk[NY, i],
                        t * wk[NZ, i])
    worst = 0.0
    for j in range(6):
        worst = max(worst, abs(acc[j]))
    return worst


@jit_inline
def reduced_core(geo, rot, twist, wk, mass, bias, jac_t):
    """Reduced dynamics ``J^T tau + wrench = M_x twist_dot + h_x`` of the legs in ``wk``
    (after :func:`rates` with drift): ``mass`` (6, 6) gets ``M_x``, ``bias`` (6,) ``h_x``,
    ``jac_t`` (6, 6) ``J^T``.

    ``M_x = J^T diag(m_c + m_l/3) J + (m_l/6) (J^T U + U^T J) + M_p`` (``U`` rows
    ``[u_k, r_k x u_k]``, ``M_p`` the platform plus point masses ``m_l/3`` at the six tips
    as one rigid body); ``h_x`` the right-hand side at ``twist_dot = 0``; the carriages'
    drives add ``J^T diag(a) J`` and ``J^T (a qddot_0 - drive force)``
    (:func:`~hexapod_pin.core.effects_projection.add_reduced`)."""
    m_l, m_p, g = geo[ML], geo[MP], geo[GRAV]
    mu = m_l / 3.0
    m_leg, m_side = geo[MC] + m_l / 3.0, m_l / 6.0
    rail_weight = (geo[MC] + 0.5 * m_l) * g
    h0, h1, h2, h3, h4, h5 = 0.0, 0.0, m_p * g, 0.0, 0.0, 0.0
    m00 = m01 = m02 = m03 = m04 = m05 = m11 = m12 = m13 = m14 = m15 = 0.0
    m22 = m23 = m24 = m25 = m33 = m34 = m35 = m44 = m45 = m55 = 0.0
    sx = sy = sz = 0.0
    pxx = pyy = pzz = pxy = pxz = pyz = 0.0
    for i in range(6):
        b = BLOCK * i
        rx, ry, rz = wk[RX, i], wk[RY, i], wk[RZ, i]
        nx, ny, nz, inv = wk[NX, i], wk[NY, i], wk[NZ, i], wk[INV, i]
        ux, uy, uz = geo[b + UX], geo[b + UY], geo[b + UZ]
        j0, j1, j2 = nx * inv, ny * inv, nz * inv
        j3, j4, j5 = (ry * nz - rz * ny) * inv, (rz * nx - rx * nz) * inv, \
            (rx * ny - ry * nx) * inv
        jac_t[0, i], jac_t[1, i], jac_t[2, i] = j0, j1, j2
        jac_t[3, i], jac_t[4, i], jac_t[5, i] = j3, j4, j5
        # the leg's share m_leg J J^T + m_side (J U^T + U J^T) = J W^T + V J^T with
        # V = m_side U, W = m_leg J + V
        v0, v1, v2 = m_side * ux, m_side * uy, m_side * uz
        v3, v4, v5 = ry * v2 - rz * v1, rz * v0 - rx * v2, rx * v1 - ry * v0
        w0, w1, w2 = m_leg * j0 + v0, m_leg * j1 + v1, m_leg * j2 + v2
        w3, w4, w5 = m_leg * j3 + v3, m_leg * j4 + v4, m_leg * j5 + v5
        m00, m01 = m00 + j0 * w0 + v0 * j0, m01 + j0 * w1 + v0 * j1
        m02, m03 = m02 + j0 * w2 + v0 * j2, m03 + j0 * w3 + v0 * j3
        m04, m05 = m04 + j0 * w4 + v0 * j4, m05 + j0 * w5 + v0 * j5
        m11, m12 = m11 + j1 * w1 + v1 * j1, m12 + j1 * w2 + v1 * j2
        m13, m14 = m13 + j1 * w3 + v1 * j3, m14 + j1 * w4 + v1 * j4
        m15 = m15 + j1 * w5 + v1 * j5
        m22, m23 = m22 + j2 * w2 + v2 * j2, m23 + j2 * w3 + v2 * j3
        m24, m25 = m24 + j2 * w4 + v2 * j4, m25 + j2 * w5 + v2 * j5
        m33, m34 = m33 + j3 * w3 + v3 * j3, m34 + j3 * w4 + v3 * j4
        m35 = m35 + j3 * w5 + v3 * j5
        m44, m45 = m44 + j4 * w4 + v4 * j4, m45 + j4 * w5 + v4 * j5
        m55 = m55 + j5 * w5 + v5 * j5
        sx += rx
        sy += ry
        sz += rz
        pxx += rx * rx
        pyy += ry * ry
        pzz += rz * rz
        pxy += rx * ry
        pxz += rx * rz
        pyz += ry * rz
        # bias: the end loads at the drift (twist_dot = 0): J^T c0 + [F0, r x F0]
        qdd0 = wk[QDD0, i]
        a0x, a0y, a0z = wk[A0X, i], wk[A0Y, i], wk[A0Z, i]
        c0 = m_leg * qdd0 + m_side * (ux * a0x + uy * a0y + uz * a0z) + rail_weight * uz
        f0 = m_side * qdd0
        fx, fy, fz = f0 * ux + mu * a0x, f0 * uy + mu * a0y, f0 * uz + mu * a0z + 0.5 * m_l * g
        h0 += j0 * c0 + fx
        h1 += j1 * c0 + fy
        h2 += j2 * c0 + fz
        h3 += j3 * c0 + ry * fz - rz * fy
        h4 += j4 * c0 + rz * fx - rx * fz
        h5 += j5 * c0 + rx * fy - ry * fx
    # the platform plus point masses mu at the six tips, as one rigid body
    sx, sy, sz = mu * sx, mu * sy, mu * sz
    total = m_p + 6.0 * mu
    trace = pxx + pyy + pzz
    ia, ib, ic = geo[IA], geo[IB], geo[IC]
    i00 = rot[0] * rot[0] * ia + rot[1] * rot[1] * ib + rot[2] * rot[2] * ic
    i11 = rot[3] * rot[3] * ia + rot[4] * rot[4] * ib + rot[5] * rot[5] * ic
    i22 = rot[6] * rot[6] * ia + rot[7] * rot[7] * ib + rot[8] * rot[8] * ic
    i01 = rot[0] * rot[3] * ia + rot[1] * rot[4] * ib + rot[2] * rot[5] * ic
    i02 = rot[0] * rot[6] * ia + rot[1] * rot[7] * ib + rot[2] * rot[8] * ic
    i12 = rot[3] * rot[6] * ia + rot[4] * rot[7] * ib + rot[5] * rot[8] * ic
    mass[0, 0], mass[0, 1], mass[0, 2] = m00 + total, m01, m02
    mass[0, 3], mass[0, 4], mass[0, 5] = m03, m04 + sz, m05 - sy
    mass[1, 1], mass[1, 2] = m11 + total, m12
    mass[1, 3], mass[1, 4], mass[1, 5] = m13 - sz, m14, m15 + sx
    mass[2, 2], mass[2, 3], mass[2, 4], mass[2, 5] = m22 + total, m23 + sy, m24 - sx, m25
    mass[3, 3] = m33 + mu * (trace - pxx) + i00
    mass[3, 4] = m34 + i01 - mu * pxy
    mass[3, 5] = m35 + i02 - mu * pxz
    mass[4, 4] = m44 + mu * (trace - pyy) + i11
    mass[4, 5] = m45 + i12 - mu * pyz
    mass[5, 5] = m55 + mu * (trace - pzz) + i22
    for r in range(6):
        for c in range(r):
            mass[r, c] = mass[c, r]
    # the gyroscopic moment w x (I_w w)
    wx, wy, wz = twist[3], twist[4], twist[5]
    hx = i00 * wx + i01 * wy + i02 * wz
    hy = i01 * wx + i11 * wy + i12 * wz
    hz = i02 * wx + i12 * wy + i22 * wz
    bias[0], bias[1], bias[2] = h0, h1, h2
    bias[3] = h3 + wy * hz - wz * hy
    bias[4] = h4 + wz * hx - wx * hz
    bias[5] = h5 + wx * hy - wy * hx
    if geo[DRIVES + drv.FLAG] != 0.0:
        drv.add_reduced(geo, DRIVES, 6, 6, jac_t, wk[Q], wk[QD], wk[QDD0], mass, bias)


@jit_inline
def cholesky_solve(mat, rhs, out, scratch):
    """``out = mat^-1 rhs`` for a symmetric positive-definite (6, 6) ``mat`` (upper
    triangle read, not changed); returns OK or NOT_PD."""
    for i in range(6):
        for j in range(i, 6):
            scratch[i, j] = mat[i, j]
    for j in range(6):
        d = scratch[j, j]
        for k in range(j):
            d -= scratch[k, j] * scratch[k, j]
        if not d > 0.0:
            return NOT_PD
        inv_d = 1.0 / math.sqrt(d)
        scratch[j, j] = inv_d
        for c in range(j + 1, 6):
            t = scratch[j, c]
            for k in range(j):
                t -= scratch[k, j] * scratch[k, c]
            scratch[j, c] = t * inv_d
    for r in range(6):
        t = rhs[r]
        for k in range(r):
            t -= scratch[k, r] * out[k]
        out[r] = t * scratch[r, r]
    for r in range(5, -1, -1):
        t = out[r]
        for k in range(r + 1, 6):
            t -= scratch[r, k] * out[k]
        out[r] = t * scratch[r, r]
    return OK


@jit_inline
def forward_core(geo, rot, twist, forces, wrench, wk, mats, out):
    """Forward dynamics at the legs in ``wk`` (rates done): ``out`` = ``twist_dot`` (6,)
    from ``M_x twist_dot = J^T tau + wrench - h_x``; ``mats[2]`` holds ``M_x``,
    ``mats[0]`` ``J^T``, wk[RHS] ``h_x``. With drives, the friction of the carriages at
    rest is solved (:func:`~hexapod_pin.core.effects_projection.stick_slip`; wk[FRIC]
    gets it). Returns OK, NOT_PD or RESIDUAL (the stick / slip QP)."""
    jac_t, mass, bias = mats[0], mats[2], wk[RHS]
    reduced_core(geo, rot, twist, wk, mass, bias, jac_t)
    rhs = wk[RHS0]
    for r in range(6):
        acc = wrench[r] - bias[r]
        for i in range(6):
            acc += jac_t[r, i] * forces[i]
        rhs[r] = acc
    if geo[DRIVES + drv.FLAG] != 0.0 and drv.any_at_rest(geo, DRIVES, 6, wk[QD], wk[FRIC]):
        return drv.stick_slip(geo, DRIVES, 6, 6, mass, jac_t, wk[QD], wk[QDD0], rhs, out,
                              wk[FRIC], mats[3:], wk[STICK:])
    return cholesky_solve(mass, rhs, out, mats[1])


@jit
def forward_dynamics(geo, signs, pose, twist, forces, wrench, twist_dot, qddot, rot, wk,
                     mats):
    """Forward dynamics: fills ``twist_dot`` (6,) and ``qddot`` (6,); returns a code."""
    code = motion_state(geo, signs, pose, twist, forces, wrench, rot, wk)
    if code != OK:
        return code
    code = forward_core(geo, rot, twist, forces, wrench, wk, mats, twist_dot)
    if code != OK:
        return code
    jac_t = mats[0]
    for i in range(6):
        s = wk[QDD0, i]
        for a in range(6):
            s += jac_t[a, i] * twist_dot[a]
        qddot[i] = s
    return OK


@jit
def forward_verified(wk, mats, twist_dot):
    """Whether a forward-dynamics answer of :func:`forward_core` (its Cholesky solve, no
    carriage at rest with friction) passes its checks: the equation it solved, ``M_x
    twist_dot = J^T tau + wrench - h_x`` (``mats[2]``, wk[RHS0]), holds to
    :data:`~hexapod_pin.core.kernel_status.RESIDUAL_RTOL` relative to its data
    (``max(1, |rhs|, |M_x| |twist_dot|)``: a backward-error test), and ``twist_dot`` is
    finite (False for any NaN)."""
    mass, rhs = mats[2], wk[RHS0]
    big_m, big_x, scale, worst = 0.0, 0.0, 1.0, 0.0
    for r in range(6):
        if not math.isfinite(twist_dot[r]):
            return False
        big_x = max(big_x, abs(twist_dot[r]))
        scale = max(scale, abs(rhs[r]))
        acc = -rhs[r]
        for c in range(6):
            big_m = max(big_m, abs(mass[r, c]))
            acc += mass[r, c] * twist_dot[c]
        worst = max(worst, abs(acc))
    return worst <= RESIDUAL_RTOL * max(scale, big_m * big_x)


@jit
def forward_dynamics_tree(geo, signs, pose, twist, forces, wrench, limit, q, v, a, twist_dot,
                          closure, rot, wk, mats):
    """The single-state forward dynamics in one call: the tree state ``q`` (25,), ``v``
    (24,) (:func:`tree_state_within`: the four inputs, passed unscanned, refused beyond
    ``limit`` or NaN / inf as NONFINITE), the reduced closed form (:func:`forward_core`:
    ``twist_dot`` (6,)), its verification (:func:`forward_verified`: RESIDUAL when it
    fails), the closure forces (6, 3) ON the platform (:func:`forward_closure_forces`) and
    the tree acceleration ``a`` (24,) of ``twist_dot``. For a robot whose carriages carry
    no effect force (damping, friction, springs; an armature is inertia: held). Returns
    the first status that is not OK (NOT_PD: ``M_x`` not positive definite), else OK."""
    if not (all_within(forces, limit) and all_within(wrench, limit)):
        return NONFINITE
    code = tree_state_within(geo, signs, pose, twist, ZERO6, 2, q, v, a, rot, wk, limit)
    if code != OK:
        return code
    code = forward_core(geo, rot, twist, forces, wrench, wk, mats, twist_dot)
    if code != OK:
        return code
    if not forward_verified(wk, mats, twist_dot):
        return RESIDUAL
    forward_closure_forces(geo, wk, twist_dot, forces, closure)
    tree_acceleration(geo, rot, wk, twist, twist_dot, v, a)
    for i in range(6):
        if not (math.isfinite(closure[i, 0]) and math.isfinite(closure[i, 1])
                and math.isfinite(closure[i, 2])):
            return RESIDUAL
    return OK


@jit
def forward_closure_forces(geo, wk, twist_dot, forces, out):
    """Closure forces (6, 3) ON the platform of a forward-dynamics answer (after
    :func:`forward_dynamics`): the end loads at the motion and the axial forces ``t_i =
    (tau_i - c_i - load_i) / (n.u)``, ``load_i = a_i qddot_i - drive force - friction at
    rest`` of the carriage's drive (zero without drives)."""
    tip_accelerations(wk, twist_dot)
    end_loads(geo, wk)
    drives = geo[DRIVES + drv.FLAG] != 0.0
    for i in range(6):
        load = 0.0
        if drives:
            load = (geo[DRIVES + drv.HEAD + drv.BLOCK * i + drv.ARM] * wk[QDD, i]
                    - drv.drive_force(geo, DRIVES, i, wk[Q, i], wk[QD, i]) - wk[FRIC, i])
        wk[AXIAL, i] = (forces[i] - wk[CC, i] - load) * wk[INV, i]
    closure_forces(wk, out)


@jit
def reduced_dynamics(geo, signs, pose, twist, mass, bias, jac, rot, wk, mats):
    """``M_x`` (6, 6), ``h_x`` (6,) and ``J`` (6, 6) of a state; returns a code."""
    code = motion_state(geo, signs, pose, twist, ZERO6, ZERO6, rot, wk)
    if code != OK:
        return code
    reduced_core(geo, rot, twist, wk, mass, bias, mats[0])
    for r in range(6):
        for c in range(6):
            jac[r, c] = mats[0][c, r]
    return OK


# --------------------------------------------------------------------------------------
# the Pinocchio tree: state, velocity map, projections
# --------------------------------------------------------------------------------------
@jit_inline
def tree_angles(geo, wk):
    """XA (``X = e.w``), YA (``Y = -e.l``), RHO2 (``X^2 + Y^2``), EU (``e.u``)."""
    for i in range(6):
        b = BLOCK * i
        inv_len = 1.0 / geo[b + LENI]
        nx, ny, nz = wk[NX, i], wk[NY, i], wk[NZ, i]
        big_x = (nx * geo[b + WX] + ny * geo[b + WY] + nz * geo[b + WZ]) * inv_len
        big_y = -(nx * geo[b + LX] + ny * geo[b + LY] + nz * geo[b + LZ]) * inv_len
        wk[XA, i], wk[YA, i] = big_x, big_y
        wk[RHO2, i] = big_x * big_x + big_y * big_y
        wk[EU, i] = wk[NU, i] * inv_len


@jit
def tree_configuration(pose, wk, q):
    """Tree ``q`` (25,): per carriage ``(q_i, a_i, b_i)``, then ``(t, quaternion x y z w)``
    (after :func:`legs` and :func:`tree_angles`)."""
    for i in range(6):
        q[3 * i] = wk[Q, i]
        q[3 * i + 1] = math.atan2(wk[YA, i], wk[XA, i])
        q[3 * i + 2] = math.atan2(wk[EU, i], math.sqrt(wk[RHO2, i]))
    q[18], q[19], q[20] = pose[0], pose[1], pose[2]
    qw, qx, qy, qz = quaternion_rpy(pose[3], pose[4], pose[5])
    q[21], q[22], q[23], q[24] = qx, qy, qz, qw


@jit_inline
def _rotate_back(rot, x, y, z, out, at):
    """``out[at:at + 3] = R^T (x, y, z)`` (world axes to platform axes)."""
    out[at] = rot[0] * x + rot[3] * y + rot[6] * z
    out[at + 1] = rot[1] * x + rot[4] * y + rot[7] * z
    out[at + 2] = rot[2] * x + rot[5] * y + rot[8] * z


@jit
def tree_velocity(geo, rot, wk, twist, v):
    """Tree ``v`` (24,) of a twist (after :func:`rates` and :func:`tree_angles`)."""
    for i in range(6):
        b = BLOCK * i
        inv_len = 1.0 / geo[b + LENI]
        ux, uy, uz = geo[b + UX], geo[b + UY], geo[b + UZ]
        lx, ly, lz = geo[b + LX], geo[b + LY], geo[b + LZ]
        wx, wy, wz = geo[b + WX], geo[b + WY], geo[b + WZ]
        dx, dy, dz = wk[DNX, i], wk[DNY, i], wk[DNZ, i]
        big_x, big_y, rho2 = wk[XA, i], wk[YA, i], wk[RHO2, i]
        v[3 * i] = wk[QD, i]
        v[3 * i + 1] = (big_x * -(dx * lx + dy * ly + dz * lz)
                        - big_y * (dx * wx + dy * wy + dz * wz)) * inv_len / rho2
        v[3 * i + 2] = (dx * ux + dy * uy + dz * uz) * inv_len / math.sqrt(rho2)
    _rotate_back(rot, twist[0], twist[1], twist[2], v, 18)
    _rotate_back(rot, twist[3], twist[4], twist[5], v, 21)


@jit
def tree_acceleration(geo, rot, wk, twist, twist_dot, v, a):
    """Tree ``a`` (24,) of a ``twist_dot`` (after :func:`tree_velocity` and
    :func:`tip_accelerations`)."""
    for i in range(6):
        b = BLOCK * i
        inv_len = 1.0 / geo[b + LENI]
        ux, uy, uz = geo[b + UX], geo[b + UY], geo[b + UZ]
        lx, ly, lz = geo[b + LX], geo[b + LY], geo[b + LZ]
        wx, wy, wz = geo[b + WX], geo[b + WY], geo[b + WZ]
        dx, dy, dz = wk[DNX, i], wk[DNY, i], wk[DNZ, i]
        big_x, big_y, rho2 = wk[XA, i], wk[YA, i], wk[RHO2, i]
        qdd = wk[QDD, i]
        ddx, ddy, ddz = wk[AX, i] - qdd * ux, wk[AY, i] - qdd * uy, wk[AZ, i] - qdd * uz
        adot, bdot = v[3 * i + 1], v[3 * i + 2]
        d_x = (dx * wx + dy * wy + dz * wz) * inv_len
        d_y = -(dx * lx + dy * ly + dz * lz) * inv_len
        a[3 * i] = qdd
        a[3 * i + 1] = ((big_x * -(ddx * lx + ddy * ly + ddz * lz)
                         - big_y * (ddx * wx + ddy * wy + ddz * wz)) * inv_len / rho2
                        - 2.0 * adot * (big_x * d_x + big_y * d_y) / rho2)
        a[3 * i + 2] = ((ddx * ux + ddy * uy + ddz * uz) * inv_len
                        + wk[EU, i] * bdot * bdot) / math.sqrt(rho2)
    vx, vy, vz, wx, wy, wz = twist[0], twist[1], twist[2], twist[3], twist[4], twist[5]
    ax, ay, az = twist_dot[0], twist_dot[1], twist_dot[2]
    bx, by, bz = twist_dot[3], twist_dot[4], twist_dot[5]
    px = ax - (wy * vz - wz * vy)
    py = ay - (wz * vx - wx * vz)
    pz = az - (wx * vy - wy * vx)
    _rotate_back(rot, px, py, pz, a, 18)
    _rotate_back(rot, bx, by, bz, a, 21)


@jit
def tree_state(geo, signs, pose, twist, twist_dot, level, q, v, a, rot, wk):
    """Tree state of a platform state on the branch ``signs``: ``level`` 0 ``q`` (25,);
    1 also ``v`` (24,); 2 also ``a`` (24,). Returns OK, NONFINITE, UNREACHABLE, TYPE_I
    or GIMBAL (the tree angles need a leg neither perpendicular to nor along its rail)."""
    if not all_finite(pose) or (level >= 1 and not all_finite(twist)) or (
            level >= 2 and not all_finite(twist_dot)):
        return NONFINITE
    rotation_rpy(pose[3], pose[4], pose[5], rot)
    code = legs(geo, pose[0], pose[1], pose[2], rot, signs, wk)
    if code != OK:
        return code
    tree_angles(geo, wk)
    tree_configuration(pose, wk, q)
    if level >= 1:
        tree_motion(geo, rot, wk, twist, twist_dot, level, v, a)
    return OK



@jit
def tree_state_within(geo, signs, pose, twist, twist_dot, level, q, v, a, rot, wk, limit):
    """:func:`tree_state` of inputs passed unscanned (float64 arrays as given): NONFINITE
    also when an entry that ``level`` reads exceeds ``limit`` in magnitude (NaN included),
    the scan of :func:`~hexapod_pin.core.checks.vec6` made in this call (the caller then
    names the input: :meth:`~hexapod_pin.core.closed_form.ClosedFormDynamics.refuse`)."""
    if not all_within(pose, limit) or (level >= 1 and not all_within(twist, limit)) or (
            level >= 2 and not all_within(twist_dot, limit)):
        return NONFINITE
    return tree_state(geo, signs, pose, twist, twist_dot, level, q, v, a, rot, wk)

@jit
def tree_motion(geo, rot, wk, twist, twist_dot, level, v, a):
    """Tree ``v`` (``level`` >= 1) and ``a`` (``level`` 2) of the legs in ``wk`` (after
    :func:`tree_angles`)."""
    rates(geo, twist, wk, level >= 2)
    tree_velocity(geo, rot, wk, twist, v)
    if level >= 2:
        tip_accelerations(wk, twist_dot)
        tree_acceleration(geo, rot, wk, twist, twist_dot, v, a)


@jit
def tree_configuration_unchecked(geo, signs, pose, q, rot, wk):
    """Tree ``q`` (25,) of a finite pose without the singularity checks (a leg that
    cannot reach returns UNREACHABLE); the closure error of the result, rebuilt from the
    tree angles, is :func:`closure_error`."""
    rotation_rpy(pose[3], pose[4], pose[5], rot)
    code = legs(geo, pose[0], pose[1], pose[2], rot, signs, wk)
    if code == UNREACHABLE:
        return code
    tree_angles(geo, wk)
    tree_configuration(pose, wk, q)
    return OK


@jit
def closure_residual(geo, q):
    """Max-abs gap (m) between each leg tip, placed by the tree's joints from ``q`` (25,),
    and its platform anchor: the closure residual in closed form."""
    qx, qy, qz, qw = q[21], q[22], q[23], q[24]
    rot = np.empty(9)
    rotation_quat(qw, qx, qy, qz, rot)
    worst = 0.0
    for i in range(6):
        b = BLOCK * i
        length = geo[b + LENI]
        px, py, pz = geo[b + PX], geo[b + PY], geo[b + PZ]
        ax = q[18] + rot[0] * px + rot[1] * py + rot[2] * pz
        ay = q[19] + rot[3] * px + rot[4] * py + rot[5] * pz
        az = q[20] + rot[6] * px + rot[7] * py + rot[8] * pz
        qc, qa, qb = q[3 * i], q[3 * i + 1], q[3 * i + 2]
        sb, cb = math.sin(qb), math.cos(qb)
        eu, el, ew = length * sb, -length * math.sin(qa) * cb, length * math.cos(qa) * cb
        ux, uy, uz = geo[b + UX], geo[b + UY], geo[b + UZ]
        lx, ly, lz = geo[b + LX], geo[b + LY], geo[b + LZ]
        wx, wy, wz = geo[b + WX], geo[b + WY], geo[b + WZ]
        worst = max(worst, abs(geo[b + MX] + qc * ux + eu * ux + el * lx + ew * wx - ax),
                    abs(geo[b + MY] + qc * uy + eu * uy + el * ly + ew * wy - ay),
                    abs(geo[b + MZ] + qc * uz + eu * uz + el * lz + ew * wz - az))
    return worst


@jit
def legs_from_tree(geo, q, pose, rot, wk):
    """Legs of an assembled tree configuration ``q`` (25,): leg vectors from the
    universal-joint angles (what the tree sees), the platform from its free-flyer; fills
    ``pose`` (6,) and ``wk`` as :func:`legs` (DISC left 0) and :func:`tree_angles`.
    Returns TYPE_I, GIMBAL or OK."""
    rotation_quat(q[24], q[21], q[22], q[23], rot)
    pose[0], pose[1], pose[2] = q[18], q[19], q[20]
    pose[3], pose[4], pose[5] = rpy_of(rot)
    code = OK
    for i in range(6):
        b = BLOCK * i
        length = geo[b + LENI]
        px, py, pz = geo[b + PX], geo[b + PY], geo[b + PZ]
        ux, uy, uz = geo[b + UX], geo[b + UY], geo[b + UZ]
        lx, ly, lz = geo[b + LX], geo[b + LY], geo[b + LZ]
        wx, wy, wz = geo[b + WX], geo[b + WY], geo[b + WZ]
        qc, qa, qb = q[3 * i], q[3 * i + 1], q[3 * i + 2]
        sb, cb = math.sin(qb), math.cos(qb)
        eu, el, ew = sb, -math.sin(qa) * cb, math.cos(qa) * cb
        nx, ny, nz = length * (eu * ux + el * lx + ew * wx), \
            length * (eu * uy + el * ly + ew * wy), length * (eu * uz + el * lz + ew * wz)
        nu = nx * ux + ny * uy + nz * uz
        wk[RX, i] = rot[0] * px + rot[1] * py + rot[2] * pz
        wk[RY, i] = rot[3] * px + rot[4] * py + rot[5] * pz
        wk[RZ, i] = rot[6] * px + rot[7] * py + rot[8] * pz
        wk[NX, i], wk[NY, i], wk[NZ, i], wk[NU, i], wk[Q, i], wk[DISC, i] = \
            nx, ny, nz, nu, qc, 0.0
        if not abs(nu) >= geo[b + TOL1]:
            code = _worse(code, TYPE_I)
        elif not ((nx * wx + ny * wy + nz * wz) ** 2 + (nx * lx + ny * ly + nz * lz) ** 2
                  >= geo[GIMB] * length * length):
            code = _worse(code, GIMBAL)
    tree_angles(geo, wk)
    return code


@jit
def velocity_map(geo, rot, wk, out):
    """``G`` (24, 6) with ``v_tree = G twist`` (after :func:`tree_angles`): leg rows
    ``[g, r_k x g]`` with ``g_carriage = n / (n.u)``, ``g_a = -(X l + Y w) / (L rho^2)``,
    ``g_b = (u - n / (n.u)) / (L rho)``; free-flyer rows ``blockdiag(R^T, R^T)``."""
    for i in range(24):
        for j in range(6):
            out[i, j] = 0.0
    for i in range(6):
        b = BLOCK * i
        inv_len = 1.0 / geo[b + LENI]
        ux, uy, uz = geo[b + UX], geo[b + UY], geo[b + UZ]
        lx, ly, lz = geo[b + LX], geo[b + LY], geo[b + LZ]
        wx, wy, wz = geo[b + WX], geo[b + WY], geo[b + WZ]
        rx, ry, rz = wk[RX, i], wk[RY, i], wk[RZ, i]
        nx, ny, nz = wk[NX, i], wk[NY, i], wk[NZ, i]
        big_x, big_y, rho2 = wk[XA, i], wk[YA, i], wk[RHO2, i]
        inv_nu = 1.0 / wk[NU, i]
        cb = inv_len / math.sqrt(rho2)
        ca = -inv_len / rho2
        for row in range(3):
            if row == 0:
                gx, gy, gz = nx * inv_nu, ny * inv_nu, nz * inv_nu
            elif row == 1:
                gx = ca * big_x * lx + ca * big_y * wx
                gy = ca * big_x * ly + ca * big_y * wy
                gz = ca * big_x * lz + ca * big_y * wz
            else:
                gx, gy, gz = (ux - nx * inv_nu) * cb, (uy - ny * inv_nu) * cb, \
                    (uz - nz * inv_nu) * cb
            r = 3 * i + row
            out[r, 0], out[r, 1], out[r, 2] = gx, gy, gz
            out[r, 3], out[r, 4], out[r, 5] = ry * gz - rz * gy, rz * gx - rx * gz, \
                rx * gy - ry * gx
    for j in range(3):
        out[18 + j, 0], out[18 + j, 1], out[18 + j, 2] = rot[j], rot[3 + j], rot[6 + j]
        out[21 + j, 3], out[21 + j, 4], out[21 + j, 5] = rot[j], rot[3 + j], rot[6 + j]


@jit
def project(geo, rot, wk, force, wrench, has_wrench, out):
    """``out = G^T force - wrench`` (6,): the platform wrench (world axes, about the
    platform origin) equivalent by virtual power to a tree generalised force (24,)."""
    for j in range(6):
        out[j] = 0.0
    for i in range(6):
        b = BLOCK * i
        inv_len = 1.0 / geo[b + LENI]
        ux, uy, uz = geo[b + UX], geo[b + UY], geo[b + UZ]
        lx, ly, lz = geo[b + LX], geo[b + LY], geo[b + LZ]
        wx, wy, wz = geo[b + WX], geo[b + WY], geo[b + WZ]
        nx, ny, nz = wk[NX, i], wk[NY, i], wk[NZ, i]
        big_x, big_y, rho2 = wk[XA, i], wk[YA, i], wk[RHO2, i]
        f_c, f_a, f_b = force[3 * i], force[3 * i + 1], force[3 * i + 2]
        f_b *= inv_len / math.sqrt(rho2)
        f_a *= -inv_len / rho2
        coef = (f_c - f_b) / wk[NU, i]
        f_ax, f_ay = f_a * big_x, f_a * big_y
        gx = coef * nx + f_b * ux + f_ax * lx + f_ay * wx
        gy = coef * ny + f_b * uy + f_ax * ly + f_ay * wy
        gz = coef * nz + f_b * uz + f_ax * lz + f_ay * wz
        add_point_force(out, wk[RX, i], wk[RY, i], wk[RZ, i], gx, gy, gz)
    a0, a1, a2, b0, b1, b2 = force[18], force[19], force[20], force[21], force[22], force[23]
    out[0] += rot[0] * a0 + rot[1] * a1 + rot[2] * a2
    out[1] += rot[3] * a0 + rot[4] * a1 + rot[5] * a2
    out[2] += rot[6] * a0 + rot[7] * a1 + rot[8] * a2
    out[3] += rot[0] * b0 + rot[1] * b1 + rot[2] * b2
    out[4] += rot[3] * b0 + rot[4] * b1 + rot[5] * b2
    out[5] += rot[6] * b0 + rot[7] * b1 + rot[8] * b2
    if has_wrench:
        for j in range(6):
            out[j] -= wrench[j]


@jit
def solve_forces(geo, wk, mats, rhs, tau, multipliers, jac_t):
    """``J^T tau = rhs`` (6 equations) with the leg factorisation (:func:`factor_legs`,
    the type-II test included); ``jac_t`` gets ``J^T`` and ``multipliers`` ``y`` with
    ``J y = -tau``: the equality multipliers of ``min 1/2 |tau|^2 s.t. J^T tau = rhs``
    (ProxSuite's sign convention). ``rhs`` is kept. Returns OK or TYPE_II."""
    code = factor_legs(geo, wk, mats)
    if code != OK:
        return code
    for j in range(6):
        tau[j] = rhs[j]
    solve_transposed(geo, wk, mats, tau)
    jacobian(wk, mats[1])
    for r in range(6):
        for c in range(6):
            jac_t[r, c] = mats[1][c, r]
    # J = diag(L_i / nu_i) A_hat D^-1 and A_hat = U^T L_f^T P: J y = -tau is
    # U^T w = -nu tau / L, L_f^T x = w, z = P^T x, y = D z
    lu, perm, w = mats[0], wk[PERM], wk[TMP]
    for row in range(6):
        inv_len = 1.0 / geo[BLOCK * row + LENI]
        acc = -tau[row] * wk[NU, row] * inv_len
        for j in range(row):
            acc -= lu[j, row] * w[j]
        w[row] = acc / lu[row, row]
    for row in range(5, -1, -1):
        acc = w[row]
        for j in range(row + 1, 6):
            acc -= lu[j, row] * w[j]
        w[row] = acc
    for j in range(6):
        multipliers[int(perm[j])] = w[j]
    for j in range(3, 6):
        multipliers[j] /= geo[RADIUS]
    return OK



@jit
def project_and_solve(geo, rot, wk, mats, force, wrench, has_wrench, rhs, tau, multipliers,
                      jac_t, passing):
    """:func:`project` into ``rhs`` then :func:`solve_forces`, in one call (the
    single-state inverse dynamics: one dispatch less). Returns OK, TYPE_II, or SATURATED
    when some ``|tau_i|`` exceeds ``passing`` (NaN included: the caller then checks the
    bounds one by one)."""
    project(geo, rot, wk, force, wrench, has_wrench, rhs)
    code = solve_forces(geo, wk, mats, rhs, tau, multipliers, jac_t)
    if code != OK:
        return code
    for i in range(6):
        if not abs(tau[i]) <= passing:
            return SATURATED
    return OK

@jit
def leg_forces(geo, wk, force, tau, out):
    """Force (6, 3) of the platform ON each leg tip, world axes (after
    :func:`tree_angles`): leg i's tree rows ``[u, u x n, b x n]^T lambda_i = (force_c -
    tau_i, force_a, force_b)`` (``b = (X l + Y w) / rho``, the second universal axis) by
    Cramer's rule."""
    for i in range(6):
        bl = BLOCK * i
        ux, uy, uz = geo[bl + UX], geo[bl + UY], geo[bl + UZ]
        lx, ly, lz = geo[bl + LX], geo[bl + LY], geo[bl + LZ]
        wx, wy, wz = geo[bl + WX], geo[bl + WY], geo[bl + WZ]
        nx, ny, nz = wk[NX, i], wk[NY, i], wk[NZ, i]
        rho = math.sqrt(wk[RHO2, i])
        big_x, big_y = wk[XA, i], wk[YA, i]
        bx = (big_x * lx + big_y * wx) / rho
        by = (big_x * ly + big_y * wy) / rho
        bz = (big_x * lz + big_y * wz) / rho
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


@jit
def reduced_tree(geo, rot, wk, mass, bias, g_map, m_x, h_x):
    """``M_x = G^T M G`` (6, 6) and ``h_x = G^T bias`` (6,) from the tree's ``M`` (24, 24;
    upper triangle read, as ``pin.crba`` fills it; block diagonal, see
    :func:`check_mass_structure`) and a tree generalised force ``bias``."""
    velocity_map(geo, rot, wk, g_map)
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


@jit
def wrench_to_tree(rot, wrench, out):
    """``out[18:24] += (R^T f, R^T m)``: the free-flyer generalised force of a wrench."""
    fx, fy, fz, mx, my, mz = wrench[0], wrench[1], wrench[2], wrench[3], wrench[4], wrench[5]
    for j in range(3):
        out[18 + j] += rot[j] * fx + rot[3 + j] * fy + rot[6 + j] * fz
        out[21 + j] += rot[j] * mx + rot[3 + j] * my + rot[6 + j] * mz


@jit
def nullspace_forward(geo, rot, wk, mass, bias, forces, wrench, has_wrench, acc0, work,
                      twist_dot, acc):
    """Null-space forward dynamics on the tree: ``M_x twist_dot = G^T (S^T tau + tau_ext -
    bias)`` with ``M`` (24, 24) from ``pin.crba`` and ``bias = rnea(q, v, a_0)``, ``a_0``
    the tree acceleration at ``twist_dot = 0``; ``acc = G twist_dot + a_0``. ``work``
    (36, 6) scratch: rows 0-23 get ``G``, 24-29 ``M_x``. Returns OK, NONFINITE or NOT_PD."""
    if not all_finite(forces) or (has_wrench and not all_finite(wrench)):
        return NONFINITE
    g_map, m_x, scratch = work[0:24], work[24:30], work[30:36]
    h_x, rest = wk[RHS], np.empty(24)
    for r in range(24):
        rest[r] = -bias[r]
    for i in range(6):
        rest[3 * i] += forces[i]
    if has_wrench:
        wrench_to_tree(rot, wrench, rest)
    reduced_tree(geo, rot, wk, mass, rest, g_map, m_x, h_x)
    code = cholesky_solve(m_x, h_x, twist_dot, scratch)
    if code != OK:
        return code
    for r in range(24):
        s = acc0[r]
        for j in range(6):
            s += g_map[r, j] * twist_dot[j]
        acc[r] = s
    return OK


@jit
def twist_dot_of(rot, twist, acc_ff, out):
    """``twist_dot = (R a_lin + w x v, R a_ang)`` from the free-flyer acceleration (6,)."""
    ax, ay, az, bx, by, bz = acc_ff[0], acc_ff[1], acc_ff[2], acc_ff[3], acc_ff[4], acc_ff[5]
    vx, vy, vz, wx, wy, wz = twist[0], twist[1], twist[2], twist[3], twist[4], twist[5]
    out[0] = rot[0] * ax + rot[1] * ay + rot[2] * az + wy * vz - wz * vy
    out[1] = rot[3] * ax + rot[4] * ay + rot[5] * az + wz * vx - wx * vz
    out[2] = rot[6] * ax + rot[7] * ay + rot[8] * az + wx * vy - wy * vx
    out[3] = rot[0] * bx + rot[1] * by + rot[2] * bz
    out[4] = rot[3] * bx + rot[4] * by + rot[5] * bz
    out[5] = rot[6] * bx + rot[7] * by + rot[8] * bz


@jit
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


def check_mass_structure(mass) -> None:
    """Raise unless the tree's mass matrix (24, 24) is block diagonal as
    :func:`reduced_tree` assumes (legs ``3 i .. 3 i + 2``, free-flyer ``18 .. 23``)."""
    full = np.triu(mass) + np.triu(mass, 1).T
    mask = np.ones((24, 24), dtype=bool)
    for start, stop in [(3 * i, 3 * i + 3) for i in range(6)] + [(18, 24)]:
        mask[start:stop, start:stop] = False
    if np.any(full[mask] != 0.0):
        raise HexapodPinError("the compiled reduced dynamics needs a block-diagonal tree "
                              "mass matrix (each leg chain and the platform attached to "
                              "the world)")


# --------------------------------------------------------------------------------------
# the dynamic regressor (the closed-form route of hexapod_pin.identification)
# --------------------------------------------------------------------------------------
#: columns of :func:`regressor`: Pinocchio's ten inertial parameters of each tree body,
#: in the tree's joint order (carriage_i, u_i_a (the cross), u_i_b (the leg) for
#: i = 0..5, then the platform)
N_INERTIAL = 190


@jit_inline
def _add_body(body, actuated, tree_row, col, sfx, sfy, sfz, snx, sny, snz, out):
    """``out[:, col:col + 10] += actuated[tree_row] (s_f . f + s_n . n)``: the body
    wrench columns ``body`` (6, 10) (``(f, n)``, body axes) as the tree generalised force
    of one joint (``s_f``, ``s_n``: its axis as it acts on the body's force and moment, in
    body axes), mapped to the actuators by the row ``actuated[tree_row]`` (6,) of ``G_a``."""
    for c in range(10):
        val = (sfx * body[0, c] + sfy * body[1, c] + sfz * body[2, c]
               + snx * body[3, c] + sny * body[4, c] + snz * body[5, c])
        if val != 0.0:
            for a in range(6):
                out[a, col + c] += actuated[tree_row, a] * val


@jit
def regressor(geo, signs, pose, twist, twist_dot, out, qd, qdd, rot, wk, mats, motion,
              actuated, body):
    """The inertial regressor ``Y`` (6, :data:`N_INERTIAL`) into ``out``: ``tau = Y pi``
    for the inertial parameters ``pi`` of every tree body (Pinocchio's convention, body
    frames; gravity included), and the carriage rates ``qd`` (6,) and accelerations
    ``qdd`` (6,) (the drive columns' variables). Scratch: ``motion`` (6, 6, 3),
    ``actuated`` (24, 6), ``body`` (6, 10). Returns OK, NONFINITE (inputs or ``Y``),
    UNREACHABLE, TYPE_I, GIMBAL or TYPE_II.

    The closed form's kinematics and projection: each body's angular velocity and
    acceleration and the classical acceleration of its origin from the legs
    (:func:`leg_motion`: the leg's ``w`` with its spin; the cross turns with the leg's
    component along ``u``; carriage, cross and leg have their origin at the joint centre
    ``c_i``, accelerating by ``qddot_i u``), the platform's from the twist; the body
    wrench linear in the parameters
    (:func:`~hexapod_pin.core.body_regressor.body_regressor`, in the frames of the
    URDF's links: carriage ``(u, l, w)``, cross ``(u, y_c, u x y_c)`` with the second
    universal axis ``y_c = (X l + Y w) / rho``, leg ``(y_c x e, y_c, e)``, platform
    ``R``); its tree generalised force (the carriage's, the cross's and the leg's force
    along ``u`` on the carriage joint, their moments about ``u`` on ``u_i_a``, the leg's
    about ``y_c`` on ``u_i_b``; the platform's wrench in body axes on its free flyer)
    mapped to the actuators by ``G_a^T = J^-T G^T`` (:func:`velocity_map`,
    :func:`solve_transposed`), the projection of the single-state inverse dynamics."""
    code = motion_state(geo, signs, pose, twist, twist_dot, ZERO6, rot, wk)
    if code != OK:
        return code
    tip_accelerations(wk, twist_dot)
    tree_angles(geo, wk)
    code = leg_motion(geo, wk, True, motion)
    if code != OK:
        return code
    code = factor_legs(geo, wk, mats)
    if code != OK:
        return code
    velocity_map(geo, rot, wk, actuated)
    for r in range(24):                                 # row r of G J^-1 = J^-T G[r]
        solve_transposed(geo, wk, mats, actuated[r])
    for a in range(6):
        qd[a], qdd[a] = wk[QD, a], wk[QDD, a]
        for c in range(N_INERTIAL):
            out[a, c] = 0.0
    g = geo[GRAV]
    for i in range(6):
        b = BLOCK * i
        ux, uy, uz = geo[b + UX], geo[b + UY], geo[b + UZ]
        lx, ly, lz = geo[b + LX], geo[b + LY], geo[b + LZ]
        wx, wy, wz = geo[b + WX], geo[b + WY], geo[b + WZ]
        inv_rho = 1.0 / math.sqrt(wk[RHO2, i])
        ca, sa = wk[XA, i] * inv_rho, wk[YA, i] * inv_rho
        yx, yy, yz = ca * lx + sa * wx, ca * ly + sa * wy, ca * lz + sa * wz
        zx, zy, zz = ca * wx - sa * lx, ca * wy - sa * ly, ca * wz - sa * lz
        ex, ey, ez = motion[0, i, 0], motion[0, i, 1], motion[0, i, 2]
        xx, xy, xz = yy * ez - yz * ey, yz * ex - yx * ez, yx * ey - yy * ex
        qdd_i = wk[QDD, i]
        ax, ay, az = qdd_i * ux, qdd_i * uy, qdd_i * uz + g      # c_i'' - gravity
        col = 30 * i
        # the carriage: its force along u on the carriage joint
        body_regressor(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, ax * ux + ay * uy + az * uz,
                       ax * lx + ay * ly + az * lz, ax * wx + ay * wy + az * wz, body)
        _add_body(body, actuated, 3 * i, col, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, out)
        # the cross: turns about u with the leg's rate about u
        om_x, om_y, om_z = motion[2, i, 0], motion[2, i, 1], motion[2, i, 2]
        al_x, al_y, al_z = motion[4, i, 0], motion[4, i, 1], motion[4, i, 2]
        body_regressor(om_x * ux + om_y * uy + om_z * uz, 0.0, 0.0,
                       al_x * ux + al_y * uy + al_z * uz, 0.0, 0.0,
                       ax * ux + ay * uy + az * uz, ax * yx + ay * yy + az * yz,
                       ax * zx + ay * zy + az * zz, body)
        _add_body(body, actuated, 3 * i, col + 10, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, out)
        _add_body(body, actuated, 3 * i + 1, col + 10, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, out)
        # the leg, in its frame (x_l, y_c, e); u in leg axes
        body_regressor(om_x * xx + om_y * xy + om_z * xz, om_x * yx + om_y * yy + om_z * yz,
                       om_x * ex + om_y * ey + om_z * ez,
                       al_x * xx + al_y * xy + al_z * xz, al_x * yx + al_y * yy + al_z * yz,
                       al_x * ex + al_y * ey + al_z * ez,
                       ax * xx + ay * xy + az * xz, ax * yx + ay * yy + az * yz,
                       ax * ex + ay * ey + az * ez, body)
        ul_x, ul_y = ux * xx + uy * xy + uz * xz, ux * yx + uy * yy + uz * yz
        ul_z = ux * ex + uy * ey + uz * ez
        _add_body(body, actuated, 3 * i, col + 20, ul_x, ul_y, ul_z, 0.0, 0.0, 0.0, out)
        _add_body(body, actuated, 3 * i + 1, col + 20, 0.0, 0.0, 0.0, ul_x, ul_y, ul_z, out)
        _add_body(body, actuated, 3 * i + 2, col + 20, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, out)
    # the platform: body axes (R^T), its wrench in body axes on the free flyer
    wb, db, ab = wk[TMP], wk[TMP2], wk[RHS0]
    _rotate_back(rot, twist[3], twist[4], twist[5], wb, 0)
    _rotate_back(rot, twist_dot[3], twist_dot[4], twist_dot[5], db, 0)
    _rotate_back(rot, twist_dot[0], twist_dot[1], twist_dot[2] + g, ab, 0)
    body_regressor(wb[0], wb[1], wb[2], db[0], db[1], db[2], ab[0], ab[1], ab[2], body)
    for j in range(6):                  # free-flyer row 18 + j: wrench component j
        for c in range(10):
            val = body[j, c]
            if val != 0.0:
                for a in range(6):
                    out[a, 180 + c] += actuated[18 + j, a] * val
    for a in range(6):
        for c in range(N_INERTIAL):
            if not math.isfinite(out[a, c]):
                return NONFINITE
    return OK


# --------------------------------------------------------------------------------------
# status codes -> exceptions
# --------------------------------------------------------------------------------------
def error_of(code: int, geo: np.ndarray, wk: np.ndarray, scratch: np.ndarray | None = None,
             index: int | None = None) -> HexapodPinError:
    """The library's exception for a kernel's status ``code``, with the offending values
    read from the legs in ``wk`` (``index``: the batch state, giving the Batch* variant).

    UNREACHABLE: the carriages that cannot reach and how short each leg is (m); TYPE_I:
    the leg nearest perpendicular to its rail and its ``|cos|``; GIMBAL: the leg along its
    rail and ``1 - cos^2``; TYPE_II: ``sigma_min(A_hat)``; RESIDUAL: the stick / slip QP of
    the carriages at rest did not converge (a :class:`SolverError`); other codes: an
    internal error (inputs are validated before the kernels run).
    """
    prefix = "" if index is None else f"state {index}: "
    if code == RESIDUAL:
        return SolverError("stick / slip of the carriages at rest (box QP)", "no convergence",
                           f"{prefix}Coulomb friction of the carriages at rest")
    length = geo[LENI:6 * BLOCK:BLOCK]
    if code == UNREACHABLE:
        bad = np.flatnonzero(~(wk[DISC] >= 0.0))
        short = np.sqrt(length[bad] * length[bad] - wk[DISC, bad]) - length[bad]
        short[~(short >= 0.0)] = np.inf        # the discriminant overflowed: out of range
        if index is None:
            return UnreachablePoseError(bad, short)
        return BatchUnreachablePoseError(index, bad, short)
    if code == TYPE_I:
        worst = int(np.argmin(np.abs(wk[NU, :6]) / length))
        what = (f"workspace Jacobian: type-I singularity, the leg of carriage {worst} is "
                "perpendicular to its rail")
        measure = "|cos| of the leg and its rail"
        value = abs(wk[NU, worst]) / length[worst]
    elif code == GIMBAL:
        cosine2 = (wk[NU, :6] / length) ** 2
        worst = int(np.argmax(cosine2))
        what = (f"leg of carriage {worst} lies along its rail (universal joint in gimbal "
                "lock)")
        measure = "1 - cos^2 of the leg and its rail"
        value = 1.0 - cosine2[worst]
    elif code == TYPE_II:
        what = ("leg matrix A_hat = [e_i, (r_k x e_i) / platform_radius] (type-II "
                "singularity)")
        measure = "smallest singular value"
        value = type_two_measure(geo, wk, np.empty((6, 6)) if scratch is None else scratch)
    else:
        return HexapodPinError(f"{prefix}internal: kernel status {code} for validated inputs")
    tol = {TYPE_I: TYPE_I_TOL, GIMBAL: GIMBAL_TOL, TYPE_II: TYPE_II_TOL}[code]
    if index is None:
        return SingularityError(what, value, tol, measure)
    return BatchSingularityError(index, what, value, tol, measure)

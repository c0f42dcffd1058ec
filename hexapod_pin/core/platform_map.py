"""The platform of a closed-loop model: which frame it is, which components of its
placement are the robot's pose, and the velocity- and acceleration-level maps between the
pose coordinates, the tree and the actuators at one configuration.

Conventions (those of every robot, :mod:`hexapod_pin.core.robot_api`):

* the platform frame's placement in the world is ``(p, R)``, ``R = Rz(yaw) Ry(pitch)
  Rx(roll)``; the full pose is ``(x, y, z, roll, pitch, yaw)`` (m, rad) and the robot's
  pose is the selection ``pose_axes`` of it, in that order (e.g. ``("x", "z", "pitch")``
  for a mechanism moving in the x-z plane);
* the twist is the same selection of ``(v, w)``: the velocity of the platform frame's
  origin and its angular velocity, both in world axes (Pinocchio's
  ``LOCAL_WORLD_ALIGNED``); ``twist_dot`` is its plain time derivative (the classical
  acceleration of the origin, the angular acceleration); a wrench is the same selection
  of ``(f, m)`` ON the platform, world axes, moment about the platform origin, and enters
  the tree as ``tau_ext = T^T wrench`` with ``T`` the twist rows below;
* the components left out of ``pose_axes`` must be held by the mechanism (its mobility
  equals the pose dimension), so that the selected pose determines the configuration
  locally.

Velocity maps (one state): ``N`` a basis of the closures' null space ``J_c N = 0``
(computed in scaled coordinates, see :class:`PlatformMap`), ``A = T N`` (dim, m) the
platform twist of each null-space motion and ``B = E_a N`` (n_act, m) its actuator
velocities (``E_a`` selects the actuated coordinates). The Jacobian of the robot is
``J = B A^-1`` (``actuator velocities = J twist``); ``A`` singular is a type-I
(inverse-kinematic) singularity (the actuators can move while the platform stays), ``B``
singular a type-II (direct-kinematic) one (the platform moves with the actuators
locked).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import DescriptionError, InconsistentMotionError, InputError
from .closed_loop import RANK_RTOL, ClosedLoopModel
from .pose import euler_rates_matrix, rpy_from_rotation

#: the six components of a platform placement, in the order of a full pose
POSE_AXES = ("x", "y", "z", "roll", "pitch", "yaw")
_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_LOCAL = pin.ReferenceFrame.LOCAL
#: relative residual accepted for the linear solves of the maps (their answers are
#: checked against the equations they solve)
MAP_RTOL = 1e-9
#: joints whose velocity coordinates are lengths (the others are angles)
_LINEAR_JOINTS = {"JointModelPX", "JointModelPY", "JointModelPZ",
                  "JointModelPrismaticUnaligned"}


def check_pose_axes(pose_axes: object) -> tuple[str, ...]:
    """``pose_axes`` as a tuple: a non-empty subset of :data:`POSE_AXES`, in that order,
    no repeats (a comma-separated string is accepted).

    Raises:
        InputError: anything else.
    """
    if isinstance(pose_axes, str):
        pose_axes = tuple(part.strip() for part in pose_axes.split(",") if part.strip())
    expected = f"a non-empty subset of {POSE_AXES}, in that order"
    try:
        axes: tuple[object, ...] = tuple(pose_axes)      # type: ignore[arg-type]
    except TypeError:
        raise InputError("pose_axes", pose_axes, expected) from None
    if not axes or any(a not in POSE_AXES for a in axes):
        raise InputError("pose_axes", pose_axes, expected)
    idx = [POSE_AXES.index(str(a)) for a in axes]
    if idx != sorted(set(idx)):
        raise InputError("pose_axes", pose_axes, expected + " (no repeats)")
    return tuple(str(a) for a in axes)


def angular_coordinates(model: pin.Model) -> np.ndarray:
    """Which velocity coordinates (nv,) are angular (rad/s); the others are linear (m/s)
    (a free-flyer: its three linear then three angular coordinates)."""
    out = np.ones(model.nv, dtype=bool)
    for jid in range(1, model.njoints):
        joint = model.joints[jid]
        name = joint.shortname()
        if name in _LINEAR_JOINTS:
            out[joint.idx_v] = False
        elif name in ("JointModelFreeFlyer", "JointModelTranslation"):
            out[joint.idx_v:joint.idx_v + 3] = False
        elif name == "JointModelPlanar":
            out[joint.idx_v:joint.idx_v + 2] = False
    return out


class VelocityMaps(NamedTuple):
    """The velocity-level maps at one configuration (see the module docstring).

    Attributes:
        q: the configuration (nq,).
        jac_c: ``J_c`` (n_rows, nv).
        twist_rows: ``T`` (dim, nv), ``twist = T v``.
        basis: ``N`` (nv, m), ``J_c N = 0`` (unscaled coordinates).
        a_map: ``A = T N`` (dim, m).
        b_map: ``B = E_a N`` (n_act, m).
        left: ``U_r`` of the scaled ``J_c`` (n_rows, r), for particular solutions.
        right: ``V_r`` (nv, r) and ``sv``: the ``r`` nonzero singular values.
    """

    q: np.ndarray
    jac_c: np.ndarray
    twist_rows: np.ndarray
    basis: np.ndarray
    a_map: np.ndarray
    b_map: np.ndarray
    left: np.ndarray
    right: np.ndarray
    sv: np.ndarray


class PlatformMap:
    """The platform frame and the pose selection of a closed-loop robot.

    Args:
        clm: the closed-loop model.
        frame: name (or id) of the platform frame.
        pose_axes: the selected components (:func:`check_pose_axes`).
        length: the characteristic length (m) that makes angular and linear coordinates
            comparable in the conditioning measures (scaled coordinates: angular
            velocities times ``length``).

    Raises:
        DescriptionError: no such frame.
        InputError: bad ``pose_axes`` or ``length``.
    """

    def __init__(self, clm: ClosedLoopModel, frame: str | int, pose_axes: object,
                 length: float) -> None:
        self.clm = clm
        self.model = clm.model
        try:
            self.frame = clm.frame_id(frame)
        except InputError:
            raise DescriptionError(clm.name, f"platform frame {frame!r} is not in the tree",
                                   str(frame)) from None
        self.frame_name = self.model.frames[self.frame].name
        self.axes = check_pose_axes(pose_axes)
        self.sel = np.array([POSE_AXES.index(a) for a in self.axes], dtype=int)
        self.dim = len(self.axes)
        #: which selected components are angles (wrapped to (-pi, pi] in differences)
        self.angular = self.sel >= 3
        self.length = float(length)
        #: which velocity coordinates are angular (nv,) bool
        self.angular_v = angular_coordinates(self.model)
        #: per velocity coordinate: ``length`` for an angular one, 1 for a linear one, so
        #: that ``v_scale * v`` is a velocity in m/s throughout
        self.v_scale = np.where(self.angular_v, self.length, 1.0)
        self.v_unscale = 1.0 / self.v_scale
        #: scale of each selected twist component (1 for linear, ``length`` for angular)
        self.twist_scale = np.where(self.angular, self.length, 1.0)
        act = clm.actuated_v
        self.actuated_v = act
        self.actuator_scale = self.v_scale[act]
        self.data = self.model.createData()

    # -- pose of a configuration ----------------------------------------------------------
    def full_pose(self, data: pin.Data) -> np.ndarray:
        """``(x, y, z, roll, pitch, yaw)`` of the platform frame from ``data.oMf`` (6,)."""
        placement = data.oMf[self.frame]
        return np.concatenate([placement.translation, rpy_from_rotation(placement.rotation)])

    def pose(self, q: np.ndarray) -> np.ndarray:
        """The selected pose (dim,) of a configuration (nq,)."""
        pin.framesForwardKinematics(self.model, self.data, q)
        return self.full_pose(self.data)[self.sel]

    def pose_error(self, pose: np.ndarray, target: np.ndarray) -> np.ndarray:
        """``pose - target`` (dim,), angles wrapped to (-pi, pi]."""
        err = pose - target
        ang = self.angular
        if ang.any():
            err[ang] = np.remainder(err[ang] + np.pi, 2.0 * np.pi) - np.pi
        return err

    def pose_rows(self, data: pin.Data, full_pose: np.ndarray) -> np.ndarray:
        """``d pose / d v`` (dim, nv): ``[J_lin; E(rpy)^-1 J_ang]`` selected, from the
        joint Jacobians in ``data`` (``E``: :func:`~hexapod_pin.core.pose.euler_rates_matrix`).

        Raises:
            InputError: a pose at pitch +-pi/2 (``E`` singular: roll and yaw coincide).
        """
        jac = pin.getFrameJacobian(self.model, data, self.frame, _LWA)
        if (self.sel >= 3).any():
            rates = euler_rates_matrix(full_pose[3:])
            if abs(np.cos(full_pose[4])) < 1e-6:
                raise InputError("pose", full_pose, "pitch at +-pi/2: roll and yaw are not "
                                                     "defined (gimbal lock)")
            jac = np.vstack([jac[:3], np.linalg.solve(rates, jac[3:])])
        return jac[self.sel]

    # -- velocity maps ------------------------------------------------------------------
    def velocity_maps(self, q: np.ndarray) -> VelocityMaps:
        """The maps of the module docstring at ``q`` (one kinematic pass, one SVD).

        The closures' null space is taken in scaled coordinates (``v_scale * v``) with
        the rank tolerance of :meth:`ClosedLoopModel.rank`; redundant closure rows are
        harmless.
        """
        clm = self.clm
        jac_c = clm.constraint_jacobian(q)
        # constraint_jacobian left the joint Jacobians of q in clm.data
        twist_rows = pin.getFrameJacobian(self.model, clm.data, self.frame, _LWA)[self.sel]
        nv = self.model.nv
        if clm.n_rows:
            scaled = jac_c * self.v_unscale
            u_mat, sv, vt = np.linalg.svd(scaled, full_matrices=True)
            tol = max(RANK_RTOL * sv[0], max(scaled.shape) * np.finfo(float).eps) \
                if sv.size else 0.0
            rank = int(np.sum(sv > tol))
        else:
            u_mat, sv, vt, rank = np.zeros((0, 0)), np.zeros(0), np.eye(nv), 0
        basis = self.v_unscale[:, None] * vt[rank:].T
        return VelocityMaps(q, jac_c, twist_rows, basis, twist_rows @ basis,
                            basis[self.actuated_v], u_mat[:, :rank],
                            self.v_unscale[:, None] * vt[:rank].T, sv[:rank])

    def particular(self, maps: VelocityMaps, rhs: np.ndarray, what: str) -> np.ndarray:
        """The least-norm (scaled) ``x`` with ``J_c x = rhs`` (nv,), checked.

        Raises:
            InconsistentMotionError: ``rhs`` outside the range of ``J_c``.
        """
        if not maps.sv.size:
            x = np.zeros(self.model.nv)
        else:
            x = maps.right @ ((maps.left.T @ rhs) / maps.sv)
        miss = float(np.max(np.abs(maps.jac_c @ x - rhs), initial=0.0))
        scale = max(1.0, float(np.max(np.abs(rhs), initial=0.0)))
        if not miss <= MAP_RTOL * scale:
            raise InconsistentMotionError(what, miss / scale)
        return x

    def frame_bias(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(gamma, bias)``: the closure drift (n_rows,) (``J_c a = -gamma``) and the
        selected classical acceleration of the platform frame at zero joint acceleration
        (dim,), from one kinematic pass."""
        clm = self.clm
        gamma = clm.constraint_drift(q, v)       # forwardKinematics(q, v, 0) in clm.data
        acc = pin.getFrameClassicalAcceleration(self.model, clm.data, self.frame, _LWA)
        return gamma, acc.vector[self.sel]

    def time_variation(self, maps: VelocityMaps, v: np.ndarray,
                       columns: np.ndarray) -> np.ndarray:
        """``dK/dt @ columns`` with ``K = [J_c; T]`` the stacked closure and twist rows and
        ``columns`` (nv, k), along the motion ``v`` (closure-consistent).

        Point rows: ``(dJ_1 - dJ_2) columns`` of the anchor points (world axes, from
        Pinocchio's frame Jacobian time variations); weld rows: ``(dJ_1 - dJ_2)`` of the
        LOCAL anchor Jacobians (exact at an assembled state moving with ``J_c v = 0``,
        where the relative placement is the identity and the derivative of its ``Jlog6``
        and adjoint vanish); twist rows: ``dT columns``.
        """
        model, data = self.model, self.data
        pin.computeJointJacobiansTimeVariation(model, data, maps.q, v)
        pin.updateFramePlacements(model, data)
        out = np.empty((self.clm.n_rows + self.dim, columns.shape[1]))
        for is_point, rows, f1, f2, _, _ in self.clm.closure_frames:
            if is_point:
                d1 = pin.getFrameJacobianTimeVariation(model, data, f1, _LWA)[:3]
                d2 = pin.getFrameJacobianTimeVariation(model, data, f2, _LWA)[:3]
            else:
                d1 = pin.getFrameJacobianTimeVariation(model, data, f1, _LOCAL)
                d2 = pin.getFrameJacobianTimeVariation(model, data, f2, _LOCAL)
            out[rows] = (d1 - d2) @ columns
        dt_rows = pin.getFrameJacobianTimeVariation(model, data, self.frame, _LWA)[self.sel]
        out[self.clm.n_rows:] = dt_rows @ columns
        return out


def solve_checked_square(mat: np.ndarray, rhs: npt.ArrayLike, what: str) -> np.ndarray:
    """``mat^-1 rhs`` for a square, regular ``mat``, verified (relative residual below
    :data:`MAP_RTOL`).

    Raises:
        InconsistentMotionError: the solve misses (a singular ``mat``).
    """
    rhs = np.asarray(rhs, dtype=float)
    x = _solve(mat, rhs, what)
    if not rhs.size:
        return x
    scale = max(1.0, float(np.abs(rhs).max()),
                float(np.abs(mat).max()) * float(np.abs(x).max()))
    miss = float(np.abs(mat @ x - rhs).max())
    if not miss <= MAP_RTOL * scale:
        raise InconsistentMotionError(what, miss / scale)
    return x


def _solve(mat: np.ndarray, rhs: np.ndarray, what: str) -> np.ndarray:
    """``np.linalg.solve``; an exactly singular ``mat`` is an InconsistentMotionError."""
    try:
        return np.linalg.solve(mat, rhs)
    except np.linalg.LinAlgError:
        raise InconsistentMotionError(what, float("inf")) from None


def solve_checked_columns(mat: np.ndarray, rhs: np.ndarray, what: str) -> np.ndarray:
    """:func:`solve_checked_square` of several right-hand sides (the columns of ``rhs``
    (n, k)) with one factorisation, each column verified on its own (as its own call
    would: relative residual below :data:`MAP_RTOL`).

    Raises:
        InconsistentMotionError: a column's solve misses (a singular ``mat``).
    """
    x = _solve(mat, rhs, what)
    if not rhs.size:
        return x
    scale = np.maximum(np.maximum(1.0, np.abs(rhs).max(axis=0)),
                       float(np.abs(mat).max()) * np.abs(x).max(axis=0))
    miss = np.abs(mat @ x - rhs).max(axis=0)
    bad = ~(miss <= MAP_RTOL * scale)
    if bad.any():
        raise InconsistentMotionError(what, float(np.max((miss / scale)[bad])))
    return x

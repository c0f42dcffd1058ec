"""The closed-loop dynamic regressor: actuator forces linear in the dynamic parameters.

For any robot of the library (the hexapod, the planar 3-PRR, any
:class:`~hexapod_pin.core.robot.ClosedLoopRobot`) and a platform state ``(pose, twist,
twist_dot)``::

    u = Y(q, v, a) pi + Y_d(v, a) pi_d                (n_act,)

with ``pi`` the inertial parameters of every body of the tree and ``pi_d`` the drive
parameters (:mod:`.parameters`). Derivation (tree coordinates, Pinocchio's ``q``, ``v``,
``a``; the conventions of :mod:`hexapod_pin.core.dynamics`):

1. the tree state: ``q`` from the robot's ``configuration(pose)`` (closures held to
   1e-12), ``v = N A^-1 twist`` and ``a = a_p + N A^-1 (twist_dot - bias - T a_p)`` with
   ``J_c a_p = -gamma`` (the maps of :mod:`hexapod_pin.core.platform_map`: ``N`` a basis
   of ``null(J_c)``, ``T`` the platform's twist rows, ``A = T N``), so that ``J_c v = 0``
   and ``J_c a + gamma = 0``;
2. on the tree, the rigid-body force is linear in the inertial parameters:
   ``M(q) a + h(q, v) = Y_tree(q, v, a) pi`` (``pin.computeJointTorqueRegressor``, nv x
   10 nb, gravity included);
3. closed-loop inverse dynamics solves ``S^T u + J_c^T lambda = Y_tree pi + tau_d`` (``S``
   selects the actuated coordinates ``clm.actuated_v``; ``tau_d`` the drive forces on
   them: ``armature_i qdd_i + viscous_i qd_i + coulomb_i sign(qd_i) + offset_i``). With
   ``G = N (S N)^-1`` (nv, n_act), the velocity map from actuated to all coordinates
   (``J_c G = 0``, ``S G = I``), multiplying by ``G^T`` removes the closure forces
   (``G^T J_c^T = 0``) and leaves ``u = G^T (Y_tree pi + tau_d)``, so::

       Y = G^T Y_tree,    Y_d = [diag(qdd) | diag(qd) | diag(sign(qd)) | I]  (kinds asked)

   (``G^T`` maps a drive force on actuated coordinate ``i`` to ``u_i`` alone). This is the
   same solve as the "kkt" route of :func:`~hexapod_pin.core.dynamics.inverse_dynamics_tree`
   when the actuators determine the motion (``S N`` square and regular); a redundantly
   actuated robot (more actuators than degrees of freedom) has no unique ``u`` and is
   refused.

The Coulomb column uses ``sign(qd_i)`` with ``sign(0) = 0``: at rest the friction force is
set by stick / slip and is not a function of the state; leave such samples out of
identification data. Joint effects on PASSIVE coordinates (damping, friction, armature of
unactuated joints) and springs are not parameters of the regressor.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..core.checks import as_array
from ..core.platform_map import PlatformMap, solve_checked_square
from ..core.robot_kinematics import RobotKinematics
from ..errors import DescriptionError, HexapodPinError, InputError, MotionSampleError
from .parameters import (
    DEFAULT_DRIVE,
    ParameterLayout,
    closed_loop_model,
    robot_home,
    robot_platform_frame,
    robot_pose_axes,
)


class TreeMotion(NamedTuple):
    """A platform state on the tree (module docstring, step 1).

    Attributes:
        q: configuration (nq,), every closure held.
        v: velocity (nv,), ``J_c v = 0``.
        a: acceleration (nv,), ``J_c a + gamma = 0``.
        actuated_map: ``G`` (nv, n_act), ``v = G qd`` for actuator velocities ``qd``.
    """

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    actuated_map: np.ndarray


class ClosedLoopRegressor:
    """The regressor of one robot (module docstring), with its scratch data: reuse one
    instance for many states. Not thread-safe (one per thread).

    Args:
        robot: a robot of the library.
        drive: the drive kinds of the columns (:data:`~.parameters.DRIVE_KINDS`).

    Attributes:
        layout: the :class:`~.parameters.ParameterLayout` of the columns.
        n_actuators: rows per state.

    Raises:
        ArgumentTypeError: not a robot of the library.
        InputError: bad ``drive``.
        DescriptionError: a redundantly actuated robot (more actuators than degrees of
            freedom: the forces are not determined by the motion).
    """

    def __init__(self, robot: object, drive: object = DEFAULT_DRIVE) -> None:
        clm = closed_loop_model(robot)
        self.robot = robot
        self.clm = clm
        self.layout = ParameterLayout.of(robot, drive)
        geometry = getattr(robot, "geometry", None)
        length = float(getattr(geometry, "characteristic_length", 1.0))
        self.platform = PlatformMap(clm, robot_platform_frame(robot), robot_pose_axes(robot),
                                    length)
        self.kinematics = RobotKinematics(clm, self.platform, robot_home(robot))
        self.dim = self.platform.dim
        self.n_actuators = clm.n_actuated
        if self.n_actuators != self.dim:
            raise DescriptionError(clm.name, f"{self.n_actuators} actuators for {self.dim} "
                                   "degrees of freedom: the actuator forces of a redundantly "
                                   "actuated robot are not determined by its motion, so no "
                                   "regressor gives them")
        self.data = clm.model.createData()
        self._eye = np.eye(self.n_actuators)

    # -- states ------------------------------------------------------------------------------
    def tree_motion(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                    twist_dot: npt.ArrayLike) -> TreeMotion:
        """The tree state of a platform state (module docstring, step 1).

        Raises:
            InputError: bad shapes, NaN / inf.
            UnreachablePoseError: the pose is out of reach.
            SingularityError: a singular pose.
        """
        twist = as_array(twist, (self.dim,), "twist")
        twist_dot = as_array(twist_dot, (self.dim,), "twist_dot")
        q = np.asarray(getattr(self.robot, "configuration")(pose), dtype=float)
        kin = self.kinematics
        maps = kin.regular_maps(q)
        v = kin.tree_velocity(maps, twist)
        a, _ = kin.tree_acceleration(maps, v, twist_dot)
        gmap = maps.basis @ solve_checked_square(maps.b_map, self._eye, "actuated velocity map")
        return TreeMotion(q, v, a, gmap)

    # -- regressor rows ----------------------------------------------------------------------
    def tree_regressor(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """``Y_tree`` (nv, 10 nb): ``M a + h = Y_tree pi`` on the tree (a copy)."""
        return np.array(pin.computeJointTorqueRegressor(self.clm.model, self.data, q, v, a))

    def rows_of(self, motion: TreeMotion) -> np.ndarray:
        """``[Y | Y_d]`` (n_act, layout.size) at a tree state (module docstring)."""
        out = np.empty((self.n_actuators, self.layout.size))
        n_in = self.layout.n_inertial
        out[:, :n_in] = motion.actuated_map.T @ self.tree_regressor(motion.q, motion.v,
                                                                    motion.a)
        act = self.clm.actuated_v
        qd, qdd = motion.v[act], motion.a[act]
        column = {"armature": qdd, "viscous": qd, "coulomb": np.sign(qd),
                  "offset": np.ones(self.n_actuators)}
        for kind in self.layout.drive:
            out[:, self.layout.drive_slice(kind)] = np.diag(column[kind])
        return out

    def rows(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
             twist_dot: npt.ArrayLike) -> np.ndarray:
        """``[Y | Y_d]`` (n_act, layout.size) of one platform state: ``u = rows @ params``
        (N, N m; parameters in :class:`~.parameters.ParameterLayout` order).

        Args:
            pose: (dim,) (m, rad).
            twist: (dim,) world axes (m/s, rad/s).
            twist_dot: (dim,) its time derivative.

        Raises:
            InputError: bad shapes, NaN / inf.
            UnreachablePoseError: the pose is out of reach.
            SingularityError: a singular pose.
        """
        return self.rows_of(self.tree_motion(pose, twist, twist_dot))

    def batch(self, poses: npt.ArrayLike, twists: npt.ArrayLike, twist_dots: npt.ArrayLike,
              times: npt.ArrayLike | None = None) -> np.ndarray:
        """The rows of N states stacked, shape (N n_act, layout.size): rows ``k n_act ..
        (k + 1) n_act`` are state ``k``'s (sample-major, the order of
        ``actuator_forces.reshape(-1)`` for forces of shape (N, n_act)).

        Args:
            poses: (N, dim) platform poses (m, rad).
            twists: (N, dim) their twists (world axes, m/s, rad/s).
            twist_dots: (N, dim) the twists' time derivatives.
            times: (N,) the samples' times (s), for error messages only (default: the
                row index).

        Raises:
            InputError: bad shapes, NaN / inf, different lengths.
            MotionSampleError: a state fails (``index``: its row; the cause, an
                :class:`~hexapod_pin.errors.UnreachablePoseError` or a singular pose, in
                ``error``).
        """
        poses = as_array(poses, (self.dim,), "poses", batch=True)
        twists = as_array(twists, (self.dim,), "twists", batch=True)
        twist_dots = as_array(twist_dots, (self.dim,), "twist_dots", batch=True)
        n = poses.shape[0]
        for name, arr in (("twists", twists), ("twist_dots", twist_dots)):
            if arr.shape[0] != n:
                raise InputError(name, arr, f"expected {n} rows (one per pose), got "
                                 f"{arr.shape[0]}")
        stamp = np.arange(n, dtype=float) if times is None else np.asarray(times, dtype=float)
        out = np.empty((n * self.n_actuators, self.layout.size))
        m = self.n_actuators
        for k in range(n):
            try:
                out[k * m:(k + 1) * m] = self.rows(poses[k], twists[k], twist_dots[k])
            except HexapodPinError as exc:
                raise MotionSampleError(k, float(stamp[k]), exc) from exc
        return out


def regressor(robot: object, pose: npt.ArrayLike, twist: npt.ArrayLike,
              twist_dot: npt.ArrayLike, drive: object = DEFAULT_DRIVE) -> np.ndarray:
    """The closed-loop regressor ``[Y | Y_d]`` (n_act, n_params) of one platform state:
    ``actuator_forces = regressor(...) @ parameters`` (module docstring; errors as
    :meth:`ClosedLoopRegressor.rows`)."""
    return ClosedLoopRegressor(robot, drive).rows(pose, twist, twist_dot)


def regressor_batch(robot: object, poses: npt.ArrayLike, twists: npt.ArrayLike,
                    twist_dots: npt.ArrayLike, drive: object = DEFAULT_DRIVE) -> np.ndarray:
    """The regressor of N states, (N n_act, n_params), sample-major
    (:meth:`ClosedLoopRegressor.batch`)."""
    return ClosedLoopRegressor(robot, drive).batch(poses, twists, twist_dots)

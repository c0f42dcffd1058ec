"""Forward-dynamics derivatives and linearised models of any robot in platform coordinates,
from the tree derivatives of :mod:`hexapod_pin.core.dynamics_derivatives` (one
implementation for the hexapod, the planar robot and every loaded robot: it reads only
the robot's model, platform frame, pose axes and ``configuration``).

A platform state ``(pose, twist)`` is the tree state ``q = configuration(pose)``, ``v = V
twist`` with ``V = N A^-1`` (``J_c V = 0``, ``T V = I``, ``T`` the platform's selected
``LOCAL_WORLD_ALIGNED`` twist rows, :mod:`~hexapod_pin.core.platform_map`); a wrench ``W``
(world axes, moment about the platform origin) is the generalised force ``T^T W``; the
platform acceleration ``twist_dot`` is the selected classical acceleration of the platform
frame, ``T a + bias``. Derivatives hold the twist and the wrench fixed in world axes:

* ``d_world``: along the pose displacement ``(dp, dtheta)`` (``dp`` of the platform
  origin, ``R -> exp(dtheta) R``, world axes), the tree moves along ``dq = V`` and the
  velocity with it, ``dv = dV[dq] twist = -K^+ (dK[dq] v)`` (``K = [J_c; T]``, full column
  rank at a regular pose), so ``d_world = P_q V + P_v dv + T da`` with ``da`` the tree
  derivative along ``(V, dv)`` and ``P`` the platform acceleration;
* ``d_twist = P_v V + T da(0, V)``; ``d_actuator_forces = T (da/dtau) S^T``;
  ``d_wrench = T (da/dtau) T^T`` (``= M_x^-1``, and ``d_actuator_forces = M_x^-1 J^T``);
* ``d_pose = d_world @ blockdiag(I, E(rpy))`` with all three angles in the pose (``w = E
  d(rpy)/dt``), ``d_world`` otherwise.

:func:`linearize` assembles them into the state-space model of ``x = (dp, dtheta,
twist)``. Equations and tests: ``docs/dynamics_derivatives.md``.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from ..errors import SingularityError
from .checks import as_array, max_abs
from .closed_loop import ClosedLoopModel
from .dynamics_common import characteristic_length
from .dynamics_derivatives import KKTLinearization, linearize_tree
from .measures import TREE_TYPE_I_TOL, inverse_condition
from .platform_map import MAP_RTOL, PlatformMap, solve_checked_square
from .pose import euler_rates_matrix, skew
from .robot_api import PoseLayout


class PlatformRobot(Protocol):
    """What this module reads from a robot (every robot of the library has it)."""

    model: ClosedLoopModel

    @property
    def pose_axes(self) -> tuple[str, ...]: ...

    @property
    def pose_layout(self) -> PoseLayout: ...

    @property
    def platform_frame_id(self) -> int: ...

    def configuration(self, pose: npt.ArrayLike, branch: Any = None) -> np.ndarray: ...


@dataclass(frozen=True)
class ForwardDynamicsDerivatives:
    """Derivatives of the platform acceleration produced by actuator forces, from
    ``robot.forward_dynamics_derivatives(pose, twist, actuator_forces, wrench)``; the
    forward counterpart of :class:`~hexapod_pin.core.results.InverseDynamicsDerivatives`.

    Rows: the components of ``twist_dot`` (m/s^2, rad/s^2, world axes). Every derivative
    holds the other arguments fixed; twist and wrench are held in world axes.

    Attributes:
        twist_dot: (dim,) the platform acceleration at the point.
        d_pose: ``d twist_dot / d pose`` (dim, dim) in the robot's pose coordinates
            (1/s^2, m/(rad s^2)).
        d_world: ``d twist_dot / d (dp, dtheta)`` (dim, dim): ``dp`` (m) the displacement
            of the platform origin, ``dtheta`` (rad) the rotation vector of ``exp(dtheta)
            R``, world axes; ``d_pose = d_world @ blockdiag(I, E(rpy))`` with all three
            angles in the pose, ``d_world = d_pose`` otherwise.
        d_twist: ``d twist_dot / d twist`` (dim, dim) (1/s).
        d_actuator_forces: ``d twist_dot / d u`` (dim, n_act) (``M_x^-1 J^T``).
        d_wrench: ``d twist_dot / d wrench`` (dim, dim) (``M_x^-1``, 1/kg, 1/(kg m^2)).
    """

    twist_dot: np.ndarray
    d_pose: np.ndarray
    d_world: np.ndarray
    d_twist: np.ndarray
    d_actuator_forces: np.ndarray
    d_wrench: np.ndarray


@dataclass(frozen=True)
class StateSpaceModel:
    """The continuous-time linearisation ``dx/dt = A x + B du`` of a robot's closed-loop
    dynamics at one state, from ``robot.linearize(pose, twist, actuator_forces, wrench)``.

    The state is ``x = (dp, dtheta, dtwist)`` (2 dim): the world pose displacement of
    :class:`ForwardDynamicsDerivatives` (the pose's linear components ``dp`` then its
    angles' ``dtheta``, in the robot's pose order) and the twist deviation (world axes);
    ``du`` the actuator-force deviation (n_act,). ``A = [[W, I], [d_world, d_twist]]``,
    ``B = [[0], [d_actuator_forces]]`` with ``W = 0`` except, when all three angles are
    in the pose, its rotation block ``[w]_x`` (``d dtheta/dt = dw + w x dtheta``: zero at
    rest, where ``A = [[0, I], [d_world, d_twist]]``).

    Attributes:
        a: ``A`` (2 dim, 2 dim).
        b: ``B`` (2 dim, n_act).
        pose: (dim,) the operating pose (m, rad).
        twist: (dim,) the operating twist (world axes).
        actuator_forces: (n_act,) the operating actuator forces (N, N m).
        wrench: (dim,) the wrench held (zeros for None).
        twist_dot: (dim,) the platform acceleration there (zero at an equilibrium).
        derivatives: the :class:`ForwardDynamicsDerivatives` it was built from.
    """

    a: np.ndarray
    b: np.ndarray
    pose: np.ndarray
    twist: np.ndarray
    actuator_forces: np.ndarray
    wrench: np.ndarray
    twist_dot: np.ndarray
    derivatives: ForwardDynamicsDerivatives


def platform_of(robot: PlatformRobot) -> PlatformMap:
    """The :class:`~hexapod_pin.core.platform_map.PlatformMap` of ``robot``'s platform frame
    and pose axes (length ``max(1 m, characteristic_length)``), one per model and thread
    (kept in ``robot.model.workspaces``)."""
    clm = robot.model
    key = ("platform_derivatives", threading.get_ident())
    cached = clm.workspaces.get(key)
    frame, axes = robot.platform_frame_id, tuple(robot.pose_axes)
    if cached is None or cached.frame != frame or cached.axes != axes:
        cached = clm.workspaces[key] = PlatformMap(clm, frame, axes,
                                                   max(1.0, characteristic_length(clm.model)))
    return cached


class PlatformLinearization:
    """The tree linearisation of one platform state and the platform rows over it."""

    def __init__(self, robot: PlatformRobot, pose: npt.ArrayLike, twist: npt.ArrayLike,
                 actuator_forces: npt.ArrayLike, wrench: npt.ArrayLike | None,
                 branch: Any) -> None:
        layout = robot.pose_layout
        dim = layout.dim
        self.layout = layout
        self.pose = as_array(pose, (dim,), "pose")
        self.twist = as_array(twist, (dim,), "twist")
        self.u = as_array(actuator_forces, (robot.model.n_actuated,), "actuator_forces")
        self.wrench = np.zeros(dim) if wrench is None else as_array(wrench, (dim,), "wrench")
        q = robot.configuration(self.pose, branch)
        plat = platform_of(robot)
        maps = plat.velocity_maps(q)
        if maps.a_map.shape != (dim, dim):
            raise SingularityError(f"closure mobility {maps.a_map.shape[1]} at this "
                                   f"configuration, pose dimension {dim}", 0.0)
        measure, _ = inverse_condition(plat.twist_scale[:, None] * maps.a_map, dim)
        if not measure >= TREE_TYPE_I_TOL:
            raise SingularityError("type-I singularity: the map from the closures' motion "
                                   "to the platform twist", measure, TREE_TYPE_I_TOL,
                                   "inverse condition number")
        self.vmap = maps.basis @ solve_checked_square(maps.a_map, np.eye(dim), "velocity map")
        v = self.vmap @ self.twist
        full = np.zeros(6)
        full[plat.sel] = self.wrench
        wrenches = [(plat.frame, full)] if wrench is not None else []
        self.tree: KKTLinearization = linearize_tree(robot.model, q, v, self.u,
                                                     frames=[plat.frame], wrenches=wrenches)
        rates, sel = self.tree.frames, plat.sel
        assert rates is not None
        self.acc, self.acc_q, self.acc_v = rates.acc[0][sel], rates.acc_q[0][sel], \
            rates.acc_v[0][sel]
        self.rows, self.vel_q = rates.jac[0][sel], rates.vel_q[0][sel]
        self.act = robot.model.actuated_v

    def transport(self) -> np.ndarray:
        """``dv`` (nv, dim) of the pose columns ``dq = V`` holding the twist: ``J_c dv =
        -d(J_c v)/dq V``, ``T dv = -d(T v)/dq V`` (verified)."""
        tree, vmap = self.tree, self.vmap
        y_c, y_t = -(tree.jv_q @ vmap), -(self.vel_q @ vmap)
        part = tree.pinv(y_c)
        dv = part + vmap @ (y_t - self.rows @ part)
        miss = max(max_abs(tree.jac @ dv - y_c), max_abs(self.rows @ dv - y_t))
        scale = max(1.0, max_abs(y_c), max_abs(y_t))
        if not miss <= MAP_RTOL * scale * 1e2:
            raise SingularityError("velocity transport: [J_c; T] dv = -dK V has no solution "
                                   "(a singular pose)", miss / scale)
        return dv

    def derivatives(self) -> ForwardDynamicsDerivatives:
        """The :class:`ForwardDynamicsDerivatives` of the module docstring."""
        tree, vmap, rows = self.tree, self.vmap, self.rows
        dv = self.transport()
        da_w, _ = tree.along(vmap, dv)
        d_world = self.acc_q @ vmap + self.acc_v @ dv + rows @ da_w
        da_t, _ = tree.along(np.zeros_like(vmap), vmap)
        d_twist = self.acc_v @ vmap + rows @ da_t
        d_tau, _ = tree.solve(np.eye(tree.model.nv), np.zeros((tree.clm.n_rows, tree.model.nv)))
        response = rows @ d_tau
        d_pose = d_world
        if self.layout.full_rotation:
            rates = np.eye(self.layout.dim)
            ang = self.layout.angular
            rates[np.ix_(ang, ang)] = euler_rates_matrix(self.pose[ang])
            d_pose = d_world @ rates
        return ForwardDynamicsDerivatives(self.acc.copy(), d_pose, d_world, d_twist,
                                          response[:, self.act], response @ rows.T)


def forward_dynamics_derivatives(robot: PlatformRobot, pose: npt.ArrayLike,
                                 twist: npt.ArrayLike, actuator_forces: npt.ArrayLike,
                                 wrench: npt.ArrayLike | None = None,
                                 branch: Any = None) -> ForwardDynamicsDerivatives:
    """Analytic derivatives of the platform acceleration (module docstring).

    Args:
        robot: any robot of the library.
        pose: (dim,) (m, rad).
        twist: (dim,) world axes (m/s, rad/s).
        actuator_forces: (n_act,) (N, N m).
        wrench: (dim,) on the platform, world axes, moment about its origin; None: zero.
        branch: passed to ``robot.configuration`` (None: the home working mode).

    Returns:
        :class:`ForwardDynamicsDerivatives`.

    Raises:
        InputError: bad shapes, NaN / inf; a coordinate with Coulomb friction at rest
            (non-smooth).
        UnreachablePoseError: the pose is out of reach.
        SingularityError: a type-I singular pose, a mobility other than the pose
            dimension, or a mass matrix singular on the closures.
        SolverError: a solve misses its equations.
    """
    return PlatformLinearization(robot, pose, twist, actuator_forces, wrench,
                                 branch).derivatives()


def linearize(robot: PlatformRobot, pose: npt.ArrayLike, twist: npt.ArrayLike,
              actuator_forces: npt.ArrayLike, wrench: npt.ArrayLike | None = None,
              branch: Any = None) -> StateSpaceModel:
    """The continuous-time :class:`StateSpaceModel` at a platform state (arguments and
    errors of :func:`forward_dynamics_derivatives`).

    Raises:
        InputError: see :func:`forward_dynamics_derivatives`.
        UnreachablePoseError: see :func:`forward_dynamics_derivatives`.
        SingularityError: see :func:`forward_dynamics_derivatives`.
        SolverError: see :func:`forward_dynamics_derivatives`.
    """
    lin = PlatformLinearization(robot, pose, twist, actuator_forces, wrench, branch)
    der = lin.derivatives()
    dim, n_act = lin.layout.dim, lin.u.size
    a_mat = np.zeros((2 * dim, 2 * dim))
    a_mat[:dim, dim:] = np.eye(dim)
    if lin.layout.full_rotation:
        ang = lin.layout.angular
        a_mat[np.ix_(ang, ang)] = skew(lin.twist[ang])
    a_mat[dim:, :dim] = der.d_world
    a_mat[dim:, dim:] = der.d_twist
    b_mat = np.zeros((2 * dim, n_act))
    b_mat[dim:] = der.d_actuator_forces
    return StateSpaceModel(a_mat, b_mat, lin.pose.copy(), lin.twist.copy(), lin.u.copy(),
                           lin.wrench.copy(), der.twist_dot, der)

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
twist)``. Equations and tests: ``docs/derivations.md`` (section 8).

One chain rule for every robot. A robot whose closed form supplies the analytic partials of
its inverse dynamics ``u = ID(pose, twist, twist_dot, wrench)``
(:meth:`~hexapod_pin.core.closed_form.ClosedFormKernels.inverse_dynamics_partials`: the
hexapod's Newton-Euler kernel) gets its inverse-dynamics derivatives from them, and its
forward-dynamics derivatives by the implicit-function theorem at ``twist_dot = FD(pose,
twist, u, wrench)`` (the robot's verified forward dynamics): ``ID(y, FD(y, u)) = u`` gives
``d FD / d y = -B^-1 d ID / d y`` (``y``: pose, twist, wrench) and ``d FD / d u = B^-1``
with ``B = d ID / d twist_dot = J^-T M_x`` (:func:`implicit_inverse`; ``B^-1 = M_x^-1
J^T``). Every other robot (and a closed-form robot whose passive coordinates carry
effects) gets its forward-dynamics derivatives from the tree as above, and its
inverse-dynamics derivatives by the same theorem the other way round (``d ID / d y = -(d
FD / d u)^-1 d FD / d y``). ``d_pose`` comes from ``d_world`` in both (:func:`pose_columns`).
"""

from __future__ import annotations

import dataclasses
import threading
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from ..errors import (
    InconsistentMotionError,
    InputError,
    NonFiniteResultError,
    SingularityError,
    SolverError,
)
from .checks import as_array, check_finite_result, max_abs
from .closed_form import ClosedFormDynamics
from .closed_loop import ClosedLoopModel
from .compiled import all_finite
from .derivative_kernels import forward_from_inverse_kernel, implicit_kernel, pose_rates_kernel
from .dynamics_common import characteristic_length
from .dynamics_derivatives import KKTLinearization, linearize_tree
from .effects_projection import batch_of_states
from .measures import TREE_TYPE_I_TOL, inverse_condition
from .platform_map import MAP_RTOL, PlatformMap, solve_checked_square
from .pose import skew
from .results import InverseDynamicsDerivatives, new_result
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
        ad: the discrete-time ``Ad`` (2 dim, 2 dim) of one simulation step of ``dt``
            (:class:`~hexapod_pin.core.step_jacobians.StepJacobians`), or None (no ``dt``
            asked).
        bd: the discrete-time ``Bd`` (2 dim, n_act), or None.
        dt: the step of ``ad`` and ``bd`` (s), or None.
        integrator: the integrator of ``ad`` and ``bd`` ("rk4", "semi_implicit_euler"), or
            None.
    """

    a: np.ndarray
    b: np.ndarray
    pose: np.ndarray
    twist: np.ndarray
    actuator_forces: np.ndarray
    wrench: np.ndarray
    twist_dot: np.ndarray
    derivatives: ForwardDynamicsDerivatives
    ad: np.ndarray | None = None
    bd: np.ndarray | None = None
    dt: float | None = None
    integrator: str | None = None


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
                                   f"configuration, pose dimension {dim}",
                                   abs(maps.a_map.shape[1] - dim), None,
                                   "|mobility - pose dimension|")
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
        dim, nv = vmap.shape[1], tree.model.nv
        # one solve for every column: along (V, dv), along (0, V), and the forces S^T, T^T
        dq_all = np.hstack([vmap, np.zeros_like(vmap)])
        dv_all = np.hstack([dv, vmap])
        force = np.zeros((nv, self.act.size))
        force[self.act, np.arange(self.act.size)] = 1.0
        rhs_e = np.hstack([-(tree.e_q @ dq_all + tree.e_v @ dv_all), force, rows.T])
        rhs_c = np.hstack([-(tree.c_q @ dq_all + tree.c_v @ dv_all),
                           np.zeros((tree.clm.n_rows, self.act.size + dim))])
        da, _ = tree.solve(rhs_e, rhs_c)
        d_world = self.acc_q @ vmap + self.acc_v @ dv + rows @ da[:, :dim]
        d_twist = self.acc_v @ vmap + rows @ da[:, dim:2 * dim]
        response = rows @ da[:, 2 * dim:]
        return ForwardDynamicsDerivatives(self.acc.copy(),
                                          pose_columns(self.layout, self.pose, d_world),
                                          d_world, d_twist,
                                          response[:, :self.act.size],
                                          response[:, self.act.size:])


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
    closed = _forward_by_closed_form(robot, pose, twist, actuator_forces, wrench, branch)
    if closed is not None:
        return closed                       # every number checked in its kernel
    return check_finite_result("forward_dynamics_derivatives", PlatformLinearization(
        robot, pose, twist, actuator_forces, wrench, branch).derivatives())


def pose_rates(layout: PoseLayout, pose: np.ndarray) -> np.ndarray:
    """The map (dim, dim) from pose-coordinate rates to the world tangent ``(dp, dtheta)``:
    ``blockdiag(I, E(rpy))`` with all three angles in the pose (``w = E d(rpy)/dt``,
    :func:`~hexapod_pin.core.pose.euler_rates`), the identity otherwise (a plane's angle is
    its own tangent coordinate); compiled
    (:func:`~hexapod_pin.core.derivative_kernels.pose_rates_kernel`)."""
    return pose_rates_kernel(np.asarray(pose, dtype=float), layout.full_rotation)


def pose_columns(layout: PoseLayout, pose: np.ndarray, d_world: np.ndarray) -> np.ndarray:
    """The pose-coordinate columns of derivatives along the world tangent ``(dp, dtheta)``:
    ``d_world @`` :func:`pose_rates` (a copy of ``d_world`` without all three angles)."""
    if not layout.full_rotation:
        return np.array(d_world, dtype=float)
    return d_world @ pose_rates(layout, pose)


def implicit_inverse(b: np.ndarray, partials: np.ndarray,
                     what: str) -> tuple[np.ndarray, np.ndarray]:
    """The implicit-function theorem for ``X(y, z)`` solved for ``z``: ``(B^-1, -B^-1
    partials)`` from the square ``b = dX/dz`` (n, n) and ``partials = dX/dy`` (n, k)
    (compiled, :func:`~hexapod_pin.core.derivative_kernels.implicit_kernel`; verified:
    ``b B^-1 = I`` to :data:`~hexapod_pin.core.platform_map.MAP_RTOL` relative).

    Raises:
        InconsistentMotionError: ``b`` singular (a type-II singularity), named ``what``.
    """
    inv, out, miss = implicit_kernel(np.ascontiguousarray(b, dtype=float),
                                     np.ascontiguousarray(partials, dtype=float))
    if not miss <= MAP_RTOL:
        raise InconsistentMotionError(what, miss)
    return inv, out


def closed_form_partials(robot: Any, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         twist_dot: npt.ArrayLike, wrench: npt.ArrayLike | None,
                         branch: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """``robot``'s closed-form inverse-dynamics partials ``(tau, partials (n_act, 4
    dim))`` (:meth:`~hexapod_pin.core.closed_form.ClosedFormKernels.inverse_dynamics_partials`),
    or None when it has none (a robot without a closed form, or whose closed form does not
    model its effects)."""
    dyn = getattr(robot, "dynamics", None)
    if not isinstance(dyn, ClosedFormDynamics):
        return None
    return dyn.inverse_dynamics_partials(pose, twist, twist_dot, wrench, branch)


def _forward_by_closed_form(robot: PlatformRobot, pose: npt.ArrayLike, twist: npt.ArrayLike,
                            actuator_forces: npt.ArrayLike, wrench: npt.ArrayLike | None,
                            branch: Any) -> ForwardDynamicsDerivatives | None:
    """:func:`forward_dynamics_derivatives` from the closed form's inverse-dynamics partials
    at the robot's verified forward-dynamics answer (module docstring), or None (no
    closed-form partials: the tree route answers)."""
    dyn = getattr(robot, "dynamics", None)
    if not isinstance(dyn, ClosedFormDynamics):
        return None
    forward = dyn.forward_dynamics(pose, twist, actuator_forces, wrench, branch=branch)
    got = dyn.inverse_dynamics_partials(pose, twist, forward.twist_dot, wrench, branch)
    if got is None:
        return None
    tau, part = got
    d_pose, d_world, d_twist, d_u, d_wrench, miss, force_miss = forward_from_inverse_kernel(
        part, tau, np.asarray(actuator_forces, dtype=float), np.asarray(pose, dtype=float),
        robot.pose_layout.full_rotation)
    if not force_miss <= 1e-8:
        raise SolverError("forward_dynamics_derivatives", "unverified",
                          "the inverse dynamics of the forward-dynamics answer misses the "
                          f"actuator forces by {force_miss:.3e} (relative)")
    if not miss <= MAP_RTOL:
        raise InconsistentMotionError("d ID / d twist_dot", miss)
    return new_result(ForwardDynamicsDerivatives, {
        "twist_dot": np.array(forward.twist_dot, dtype=float), "d_pose": d_pose,
        "d_world": d_world, "d_twist": d_twist, "d_actuator_forces": d_u,
        "d_wrench": d_wrench})


def robot_inverse_dynamics_derivatives(robot: Any, pose: npt.ArrayLike, twist: npt.ArrayLike,
                                       twist_dot: npt.ArrayLike,
                                       wrench: npt.ArrayLike | None = None
                                       ) -> InverseDynamicsDerivatives:
    """``robot.inverse_dynamics_derivatives`` of every robot (home working mode; module
    docstring): the closed form's partials where the robot has them, else the forces of
    ``robot.inverse_dynamics`` (unbounded) and :func:`inverse_dynamics_derivatives` (the
    implicit-function theorem on the tree's forward-dynamics derivatives).

    Raises:
        InputError: bad shapes, NaN / inf, redundant actuation, Coulomb friction at rest
            (not differentiable).
        UnreachablePoseError: the pose is out of reach.
        SingularityError: a singular pose (type II: InconsistentMotionError on the tree
            route).
        SolverError: a solve misses its equations.
    """
    name = "inverse_dynamics_derivatives"
    got = closed_form_partials(robot, pose, twist, twist_dot, wrench, None)
    if got is not None:
        tau, part = got
        if not (all_finite(tau) and all_finite(part.reshape(-1))):
            raise NonFiniteResultError(name, "d_world" if all_finite(tau)
                                       else "actuator_forces")
        dim = robot.pose_layout.dim
        d_world = part[:, :dim]
        return InverseDynamicsDerivatives(
            tau, pose_columns(robot.pose_layout, np.asarray(pose, dtype=float), d_world),
            d_world, part[:, dim:2 * dim], part[:, 2 * dim:3 * dim], part[:, 3 * dim:])
    branch = robot.configuration(pose) if getattr(robot, "branch_is_configuration",
                                                  False) else None
    forces = robot.inverse_dynamics(pose, twist, twist_dot, wrench, branch=branch,
                                    bounded=False, joint_wrenches=False).actuator_forces
    return check_finite_result(name, inverse_dynamics_derivatives(
        robot, pose, twist, twist_dot, forces, wrench, branch))


def inverse_dynamics_derivatives(robot: PlatformRobot, pose: npt.ArrayLike,
                                 twist: npt.ArrayLike, twist_dot: npt.ArrayLike,
                                 actuator_forces: npt.ArrayLike,
                                 wrench: npt.ArrayLike | None = None,
                                 branch: Any = None) -> InverseDynamicsDerivatives:
    """Analytic derivatives of the inverse-dynamics forces ``u = ID(pose, twist,
    twist_dot, wrench)`` (no bounds) by the implicit-function theorem on the forward
    dynamics ``twist_dot = FD(pose, twist, u, wrench)``: with ``B = d FD / d u`` (square,
    ``M_x^-1 J^T``), ``d u / d y = -B^-1 d FD / d y`` (``y``: pose, twist, wrench) and
    ``d u / d twist_dot = B^-1`` (``= J^-T M_x``; ``d u / d wrench = -J^-T``).

    Args:
        robot: any robot of the library.
        pose: (dim,) (m, rad).
        twist: (dim,) world axes.
        twist_dot: (dim,) world axes (m/s^2, rad/s^2).
        actuator_forces: (n_act,) the inverse-dynamics forces of that state (from the
            robot's verified route; checked: the forward dynamics with them must return
            ``twist_dot`` to 1e-8 relative).
        wrench: (dim,) on the platform, world axes; None: zero.
        branch: the working mode.

    Returns:
        :class:`~hexapod_pin.core.results.InverseDynamicsDerivatives`.

    Raises:
        InputError: bad shapes, NaN / inf, redundant actuation (``n_act != dim``), Coulomb
            friction at rest.
        UnreachablePoseError: the pose is out of reach.
        SingularityError: a singular pose.
        InconsistentMotionError: ``B`` singular (a type-II singularity).
        SolverError: the forces do not produce ``twist_dot``, or a solve misses its
            equations.
    """
    lin = PlatformLinearization(robot, pose, twist, actuator_forces, wrench, branch)
    dim = lin.layout.dim
    target = as_array(twist_dot, (dim,), "twist_dot")
    if lin.u.size != dim:
        raise InputError("actuator_forces", actuator_forces, f"{lin.u.size} actuators for "
                         f"a pose of dimension {dim}: the inverse dynamics is not a "
                         "function of the state (redundant actuation)")
    der = lin.derivatives()
    miss = max_abs(der.twist_dot - target)
    if not miss <= 1e-8 * max(1.0, max_abs(target), max_abs(der.twist_dot)):
        raise SolverError("inverse_dynamics_derivatives", "unverified",
                          f"the forward dynamics with these actuator forces misses "
                          f"twist_dot by {miss:.3e}")
    inv, sol = implicit_inverse(der.d_actuator_forces, np.concatenate(
        [der.d_world, der.d_twist, der.d_wrench], axis=1), "d twist_dot / d u")
    d_world = sol[:, :dim]
    return InverseDynamicsDerivatives(lin.u.copy(), pose_columns(lin.layout, lin.pose, d_world),
                                      d_world, sol[:, dim:2 * dim], inv, sol[:, 2 * dim:])


def forward_dynamics_derivatives_batch(robot: PlatformRobot, poses: npt.ArrayLike,
                                       twists: npt.ArrayLike, actuator_forces: npt.ArrayLike,
                                       wrenches: npt.ArrayLike | None = None,
                                       branch: Any = None) -> ForwardDynamicsDerivatives:
    """:func:`forward_dynamics_derivatives` of N states: a
    :class:`ForwardDynamicsDerivatives` whose arrays carry a leading axis N (``twist_dot``
    (N, dim), ``d_world`` (N, dim, dim), ``d_actuator_forces`` (N, dim, n_act), ...),
    row ``k`` the single-state answer of state ``k``.

    Args:
        robot: any robot of the library.
        poses: (N, dim) (m, rad).
        twists: (N, dim) world axes.
        actuator_forces: (N, n_act) (N, N m).
        wrenches: (N, dim) or None (zero).
        branch: the working mode of every state.

    Raises:
        InputError: bad shapes (rows that differ in number), NaN / inf, Coulomb friction
            at rest.
        BatchUnreachablePoseError: a pose out of reach (``index`` the first such row).
        BatchSingularityError: a singular state (``index``).
        SolverError: a solve misses its equations.
    """
    dim, n_act = robot.pose_layout.dim, robot.model.n_actuated
    p = as_array(poses, (dim,), "poses", batch=True)
    n = len(p)
    rows = [("twists", twists, dim), ("actuator_forces", actuator_forces, n_act)]
    if wrenches is not None:
        rows.append(("wrenches", wrenches, dim))
    arrays = []
    for name, value, width in rows:
        arr = as_array(value, (width,), name, batch=True)
        if len(arr) != n:
            raise InputError(name, value, f"expected {n} rows (one per pose), got {len(arr)}")
        arrays.append(arr)
    t, u = arrays[0], arrays[1]
    w = arrays[2] if wrenches is not None else None
    res = batch_of_states(n, lambda k: forward_dynamics_derivatives(
        robot, p[k], t[k], u[k], None if w is None else w[k], branch))
    return ForwardDynamicsDerivatives(
        *(np.array([getattr(r, f.name) for r in res]).reshape((n,) + shape) for f, shape in
          zip(dataclasses.fields(ForwardDynamicsDerivatives),
              [(dim,), (dim, dim), (dim, dim), (dim, dim), (dim, n_act), (dim, dim)])))


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
    layout = robot.pose_layout
    dim, n_act = layout.dim, robot.model.n_actuated
    pose_a, twist_a = as_array(pose, (dim,), "pose"), as_array(twist, (dim,), "twist")
    u = as_array(actuator_forces, (n_act,), "actuator_forces")
    wrench_a = np.zeros(dim) if wrench is None else as_array(wrench, (dim,), "wrench")
    der = forward_dynamics_derivatives(robot, pose_a, twist_a, u, wrench, branch)
    a_mat = np.zeros((2 * dim, 2 * dim))
    a_mat[:dim, dim:] = np.eye(dim)
    if layout.full_rotation:
        ang = layout.angular
        a_mat[np.ix_(ang, ang)] = skew(twist_a[ang])
    a_mat[dim:, :dim] = der.d_world
    a_mat[dim:, dim:] = der.d_twist
    b_mat = np.zeros((2 * dim, n_act))
    b_mat[dim:] = der.d_actuator_forces
    return StateSpaceModel(a_mat, b_mat, pose_a.copy(), twist_a.copy(), u.copy(),
                           wrench_a.copy(), der.twist_dot, der)

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

Two routes give the same matrix (``route``, :data:`ROUTES`): "tree" builds it as above
for any robot; "closed_form" asks the robot's closed form
(:class:`~hexapod_pin.core.closed_form.ClosedFormDynamics` with ``supplies_regressor``:
the hexapod's) for ``Y``, computed from its own body kinematics and force projection with
the Newton-Euler wrench of each body written linear in its ten parameters
(:mod:`hexapod_pin.core.body_regressor`), no Pinocchio call; the drive columns are the
same algebra on its actuator rates. The tests hold the two routes equal entry by entry
(1e-10 of each column's scale). "auto" (the default) takes the closed form where the
robot supplies one and the tree otherwise.

The Coulomb column uses ``sign(qd_i)`` with ``sign(0) = 0``: at rest the friction force is
set by stick / slip and is not a function of the state; leave such samples out of
identification data. Joint effects on PASSIVE coordinates (damping, friction, armature of
unactuated joints) and springs are not parameters of the regressor.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..core.checks import as_array
from ..core.closed_form import ClosedFormDynamics, ClosedFormRegressor
from ..core.closed_loop import ClosedLoopModel
from ..core.dynamics import dynamics_of
from ..core.effects import effect_forces
from ..core.platform_map import PlatformMap, solve_checked_square
from ..core.robot_kinematics import RobotKinematics
from ..errors import (
    BatchSingularityError,
    BatchUnreachablePoseError,
    DescriptionError,
    HexapodPinError,
    InputError,
    MotionSampleError,
)
from .parameters import (
    DEFAULT_DRIVE,
    EFFECT_FIELDS,
    ParameterLayout,
    closed_loop_model,
    robot_home,
    robot_platform_frame,
    robot_pose_axes,
)

#: a tree state given to :func:`closed_loop_regressor_tree` must keep the closures'
#: acceleration: ``|J_c a + gamma| <= ACCELERATION_RTOL (|J_c| |a| + |gamma| + 1)``
ACCELERATION_RTOL = 1e-9
#: the routes of the regressor (module docstring)
ROUTES = ("tree", "closed_form", "auto")


def _drive_columns(layout: ParameterLayout, on_actuated: np.ndarray, qd: np.ndarray,
                   qdd: np.ndarray, out: np.ndarray) -> None:
    """``out[..., drive columns] = P S^T Y_d``: the drive columns of the rows ``out`` (...,
    k, layout.size) for the actuated columns ``on_actuated`` (k, n_act) of the projection
    ``P`` and the actuator rates ``qd``, ``qdd`` (..., n_act) (one state, or a leading axis
    of states)."""
    column = {"armature": qdd, "viscous": qd, "coulomb": np.sign(qd),
              "offset": np.ones_like(qd)}
    for kind in layout.drive:
        out[..., layout.drive_slice(kind)] = on_actuated * column[kind][..., None, :]


def _stacked_rows(layout: ParameterLayout, actuated_v: np.ndarray, projection: np.ndarray,
                  y_tree: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``[P Y_tree | P S^T Y_d]`` (k, layout.size) for a projection ``P`` (k, nv) of the
    tree equation: ``G^T`` gives the actuator forces' rows, a basis of the unactuated
    motions (transposed) their balance rows (``P S^T`` the identity, resp. zero)."""
    out = np.empty((projection.shape[0], layout.size))
    out[:, :layout.n_inertial] = projection @ y_tree
    _drive_columns(layout, projection[:, actuated_v], v[actuated_v], a[actuated_v], out)
    return out


def _closed_form_of(robot: object, route: object, name: str) -> ClosedFormDynamics | None:
    """The closed form that gives the regressor of ``robot`` by ``route`` (None: the tree).

    Raises:
        InputError: an unknown route; "closed_form" for a robot whose closed form supplies
            no regressor.
    """
    if not isinstance(route, str) or route not in ROUTES:
        raise InputError("route", route, f"expected one of {ROUTES}")
    dyn = getattr(robot, "dynamics", None)
    supplied = isinstance(dyn, ClosedFormDynamics) and dyn.supplies_regressor
    if route == "closed_form" and not supplied:
        raise InputError("route", route, f"robot {name!r} has no closed form that supplies "
                         "a dynamic regressor: use route='tree' (or 'auto')")
    return dyn if supplied and route != "tree" else None     # type: ignore[return-value]


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
        route: "auto" (default: the closed form where the robot supplies one, the
            hexapod's, 40-70x faster; the tree otherwise), "tree" or "closed_form"
            (:data:`ROUTES`, module docstring): where :meth:`rows` and :meth:`batch` come
            from. The tree-state
            methods (:meth:`tree_motion`, :meth:`rows_of`) are the tree route's.

    Attributes:
        layout: the :class:`~.parameters.ParameterLayout` of the columns.
        n_actuators: rows per state.
        route: the route :meth:`rows` and :meth:`batch` take ("tree" or "closed_form";
            "auto" resolved).

    Raises:
        ArgumentTypeError: not a robot of the library.
        InputError: bad ``drive``; an unknown ``route``, or "closed_form" for a robot
            whose closed form supplies no regressor.
        DescriptionError: a redundantly actuated robot (more actuators than degrees of
            freedom: the forces are not determined by the motion).
    """

    def __init__(self, robot: object, drive: object = DEFAULT_DRIVE,
                 route: str = "auto") -> None:
        clm = closed_loop_model(robot)
        self.robot = robot
        self.clm = clm
        self.layout = ParameterLayout.of(robot, drive)
        self.closed_form = _closed_form_of(robot, route, clm.name)
        self.route = "tree" if self.closed_form is None else "closed_form"
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
                    twist_dot: npt.ArrayLike, branch: npt.ArrayLike | None = None) -> TreeMotion:
        """The tree state of a platform state (module docstring, step 1) on the robot's
        working mode ``branch`` (its ``configuration(pose, branch)``; default home).

        Raises:
            InputError: bad shapes, NaN / inf, a bad branch.
            UnreachablePoseError: the pose is out of reach.
            SingularityError: a singular pose.
        """
        twist = as_array(twist, (self.dim,), "twist")
        twist_dot = as_array(twist_dot, (self.dim,), "twist_dot")
        q = np.asarray(getattr(self.robot, "configuration")(pose, branch), dtype=float)
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
        y_tree = self.tree_regressor(motion.q, motion.v, motion.a)
        return _stacked_rows(self.layout, self.clm.actuated_v, motion.actuated_map.T, y_tree,
                             motion.v, motion.a)

    def rows(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
             twist_dot: npt.ArrayLike, branch: npt.ArrayLike | None = None) -> np.ndarray:
        """``[Y | Y_d]`` (n_act, layout.size) of one platform state: ``u = rows @ params``
        (N, N m; parameters in :class:`~.parameters.ParameterLayout` order), by
        :attr:`route`.

        Args:
            pose: (dim,) (m, rad).
            twist: (dim,) world axes (m/s, rad/s).
            twist_dot: (dim,) its time derivative.
            branch: the robot's working mode (its ``branch`` argument; default home).

        Raises:
            InputError: bad shapes, NaN / inf, a bad branch.
            UnreachablePoseError: the pose is out of reach.
            SingularityError: a singular pose.
        """
        if self.closed_form is None:
            return self.rows_of(self.tree_motion(pose, twist, twist_dot, branch))
        return self._closed_form_rows(self.closed_form.regressor(pose, twist, twist_dot,
                                                                 branch))

    def _closed_form_rows(self, cf: ClosedFormRegressor) -> np.ndarray:
        """``[Y | Y_d]`` of a closed form's regressor (one state, or N: (N, n_act, size))
        (``P = G^T`` maps each actuated coordinate's drive force to its own actuator)."""
        inertial = cf.inertial
        if inertial.shape[-1] != self.layout.n_inertial:
            raise DescriptionError(self.clm.name, f"the closed form's regressor has "
                                   f"{inertial.shape[-1]} inertial columns, the tree "
                                   f"{self.layout.n_inertial}")
        out = np.empty(inertial.shape[:-1] + (self.layout.size,))
        out[..., :self.layout.n_inertial] = inertial
        _drive_columns(self.layout, self._eye, cf.actuator_velocities,
                       cf.actuator_accelerations, out)
        return out

    def batch(self, poses: npt.ArrayLike, twists: npt.ArrayLike, twist_dots: npt.ArrayLike,
              times: npt.ArrayLike | None = None, branch: npt.ArrayLike | None = None) -> np.ndarray:
        """The rows of N states stacked, shape (N n_act, layout.size): rows ``k n_act ..
        (k + 1) n_act`` are state ``k``'s (sample-major, the order of
        ``actuator_forces.reshape(-1)`` for forces of shape (N, n_act)), by
        :attr:`route` (the closed form's compiled batch kernel; the tree route state by
        state).

        Args:
            poses: (N, dim) platform poses (m, rad).
            twists: (N, dim) their twists (world axes, m/s, rad/s).
            twist_dots: (N, dim) the twists' time derivatives.
            times: (N,) the samples' times (s), for error messages only (default: the
                row index).
            branch: the robot's working mode for every state (default home).

        Raises:
            InputError: bad shapes, NaN / inf, different lengths, a bad branch.
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
        m = self.n_actuators
        if self.closed_form is not None:
            try:
                cf = self.closed_form.regressor_batch(poses, twists, twist_dots, branch)
            except (BatchUnreachablePoseError, BatchSingularityError) as exc:
                raise MotionSampleError(exc.index, float(stamp[exc.index]), exc) from exc
            return self._closed_form_rows(cf).reshape(n * m, self.layout.size)
        out = np.empty((n * m, self.layout.size))
        for k in range(n):
            try:
                out[k * m:(k + 1) * m] = self.rows(poses[k], twists[k], twist_dots[k],
                                                   branch)
            except HexapodPinError as exc:
                raise MotionSampleError(k, float(stamp[k]), exc) from exc
        return out


@dataclass(frozen=True)
class TreeRegressorRows:
    """The closed-loop regressor at a tree state (:func:`closed_loop_regressor_tree`).

    For a motion the model performs (every motion keeping the closures when the actuators
    determine it; for an under-actuated model such as Cassie, one its unactuated
    directions allow, e.g. from forward dynamics)::

        actuator_forces = rows @ pi + known
        unactuated_rows @ pi + unactuated_known = 0

    Attributes:
        rows: ``[G^T Y_tree | Y_d]`` (n_act, n_params) (N or N m per parameter unit).
        known: ``G^T tau_known`` (n_act,) (N, N m): the actuator forces of the model's
            effects that are not parameters (springs; damping, friction and armature of
            passive coordinates; those of the actuated coordinates whose kind is not in
            ``drive``).
        unactuated_rows: ``Z^T [Y_tree | S^T Y_d]`` (k, n_params), ``Z`` an orthonormal
            basis (nv, k) of the closure-keeping motions with the actuators held
            (``J_c Z = 0``, ``S Z = 0``; k = 0 when the actuators determine the motion).
        unactuated_known: ``Z^T tau_known`` (k,).
    """

    rows: np.ndarray
    known: np.ndarray
    unactuated_rows: np.ndarray
    unactuated_known: np.ndarray


def _known_effect_force(clm: ClosedLoopModel, drive: tuple[str, ...], q: np.ndarray,
                        v: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``tau_known`` (nv,): armature times ``a`` minus the joints' effect forces
    (:func:`~hexapod_pin.core.effects.effect_forces`), the actuated coordinates' entries
    of the drive kinds in ``drive`` left out (they are parameters)."""
    changes = {}
    for kind, field in EFFECT_FIELDS.items():
        if kind in drive:
            values = np.array(getattr(clm.effects, field), dtype=float)
            values[clm.actuated_v] = 0.0
            changes[field] = values
    effects = clm.effects.replace(**changes) if changes else clm.effects
    out = effects.armature * a
    if effects.has_forces:
        out = out - effect_forces(clm.model, effects, q, v, a)
    return out


def closed_loop_regressor_tree(clm: ClosedLoopModel, q: npt.ArrayLike, v: npt.ArrayLike,
                               a: npt.ArrayLike,
                               drive: object = DEFAULT_DRIVE) -> TreeRegressorRows:
    """The closed-loop regressor at a tree state of any closed-loop model (no platform
    pose needed: Cassie), the tree-level form of :class:`ClosedLoopRegressor`.

    The equation of motion ``M a + h = Y_tree pi``, ``(M + diag(armature)) a + h -
    effects = S^T u + J_c^T lambda`` is projected (module docstring, step 3) with ``G``
    (nv, n_act), the actuated velocity map of
    :meth:`~hexapod_pin.core.closed_loop.ClosedLoopModel.actuated_velocity_map`
    (``J_c G = 0``, ``S G = I``; the least-norm one where the actuators leave motion
    free), and with a basis ``Z`` of the unactuated motions (``null(J_c) & null(S)``):
    see :class:`TreeRegressorRows`. Parameters in
    ``ParameterLayout.of_model(clm, drive)`` order.

    Args:
        clm: the closed-loop model (its tree's inertias are not used).
        q: configuration (nq,), closures assembled.
        v: velocity (nv,), ``J_c v = 0``.
        a: acceleration (nv,), ``J_c a + gamma = 0`` (to :data:`ACCELERATION_RTOL`).
        drive: the drive kinds of the columns (:data:`~.parameters.DRIVE_KINDS`).

    Raises:
        InputError: bad shapes, NaN / inf, bad ``drive``; ``q`` off the closures, ``v`` or
            ``a`` breaking them (the residual named).
        InconsistentMotionError: a configuration where the actuators cannot move
            independently (no ``G``).
    """
    layout = ParameterLayout.of_model(clm, drive)
    q, v, a = clm.check_q(q), clm.check_v(v), clm.check_v(a, "a")
    dynamics_of(clm).check_state(q, v)
    jac = clm.constraint_jacobian(q)
    gamma = clm.constraint_drift(q, v)
    miss = float(np.max(np.abs(jac @ a + gamma), initial=0.0))
    scale = float(np.max(np.abs(jac), initial=0.0) * np.max(np.abs(a)) +
                  np.max(np.abs(gamma), initial=0.0) + 1.0)
    if not miss <= ACCELERATION_RTOL * scale:
        raise InputError("a", a, f"breaks the closures: |J_c a + gamma| = {miss:.3g} "
                         f"above {ACCELERATION_RTOL:g} x {scale:.3g}")
    gmap = clm.actuated_velocity_map(q)
    _, sv, vt = np.linalg.svd(jac) if jac.shape[0] else (None, np.zeros(0), np.eye(clm.nv))
    rank = int(np.sum(sv > 1e-10 * sv[0])) if sv.size else 0
    basis = vt[rank:].T                                            # null(J_c)
    _, sv_a, vt_a = np.linalg.svd(basis[clm.actuated_v])
    rank_a = int(np.sum(sv_a > 1e-10 * sv_a[0])) if sv_a.size else 0
    unactuated = basis @ vt_a[rank_a:].T                           # null(J_c) & null(S)
    y_tree = np.array(pin.computeJointTorqueRegressor(clm.model, clm.model.createData(),
                                                      q, v, a))
    known = _known_effect_force(clm, layout.drive, q, v, a)
    return TreeRegressorRows(
        _stacked_rows(layout, clm.actuated_v, gmap.T, y_tree, v, a), gmap.T @ known,
        _stacked_rows(layout, clm.actuated_v, unactuated.T, y_tree, v, a),
        unactuated.T @ known)


def regressor(robot: object, pose: npt.ArrayLike, twist: npt.ArrayLike,
              twist_dot: npt.ArrayLike, drive: object = DEFAULT_DRIVE, *,
              route: str = "auto", branch: npt.ArrayLike | None = None) -> np.ndarray:
    """The closed-loop regressor ``[Y | Y_d]`` (n_act, n_params) of one platform state:
    ``actuator_forces = regressor(...) @ parameters`` (module docstring; ``route`` and
    errors as :class:`ClosedLoopRegressor` and its :meth:`~ClosedLoopRegressor.rows`)."""
    return ClosedLoopRegressor(robot, drive, route).rows(pose, twist, twist_dot, branch)


def regressor_batch(robot: object, poses: npt.ArrayLike, twists: npt.ArrayLike,
                    twist_dots: npt.ArrayLike, drive: object = DEFAULT_DRIVE, *,
                    route: str = "auto", branch: npt.ArrayLike | None = None) -> np.ndarray:
    """The regressor of N states, (N n_act, n_params), sample-major
    (:meth:`ClosedLoopRegressor.batch`)."""
    return ClosedLoopRegressor(robot, drive, route).batch(poses, twists, twist_dots,
                                                          branch=branch)

"""Result types shared by every parallel robot: one type per operation.

Every robot with the shared API (:class:`hexapod_pin.Hexapod`, :class:`hexapod_pin.Planar3PRR`,
and any robot added later, see :mod:`hexapod_pin.core.robot_api`) returns these, with the
same field names, shapes and sign conventions:

* actuator forces: ``(n_act,)``, the force (N) or torque (N m) on actuator ``i`` along its
  own positive direction, actuator order;
* closure forces: ``(n_chains, d)``, row ``i`` the force that chain ``i``'s last body (the
  leg or link) exerts ON the platform at its platform joint, world axes (N); ``d`` = 3 in
  space, 2 in the plane. The platform exerts the opposite force on the chain;
* ``twist_dot``: the plain time derivative of the platform twist (world axes);
* ``actuator_accelerations``: ``(n_act,)``, second derivative of the actuator coordinates.

Parts that cost a Pinocchio call or a conversion are computed on first access: a result
holds a *details* object (:class:`ResultDetails`) that computes them. A robot either passes
:class:`ComputedDetails` (values already known) or its own lazy implementation. The
dynamics results also carry their pose's conditioning (``singularity``, the robot's
:class:`SingularityMeasures` at the result's pose and branch), computed on first access by
a :class:`LazyConditioning` under the robot's lock.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType
from typing import Protocol, TypeVar

import numpy as np
import numpy.typing as npt

_NO_WRENCHES: Mapping[str, np.ndarray] = MappingProxyType({})


class ForwardDetails(Protocol):
    """What a forward-dynamics result computes on first access (each called at most once)."""

    def multipliers(self) -> np.ndarray:
        """Closure multipliers of the tree rows (n_rows,), see :mod:`hexapod_pin.core.dynamics`."""

    def closure_forces(self) -> np.ndarray:
        """Force of each chain ON the platform, (n_chains, d), world axes (N)."""


class ResultDetails(ForwardDetails, Protocol):
    """What an inverse-dynamics result computes on first access (each called at most once
    per result): the parts of :class:`ForwardDetails`, and the following."""

    def joint_wrenches(self) -> Mapping[str, np.ndarray]:
        """Joint name -> (6,) spatial force transmitted by that joint (empty if not asked)."""

    def residual(self) -> float:
        """Max-abs residual of the tree equation of motion with the returned forces."""


@dataclass(frozen=True)
class ComputedDetails:
    """:class:`ResultDetails` whose values are already known."""

    multipliers_: np.ndarray
    closure_forces_: np.ndarray
    residual_: float = 0.0
    joint_wrenches_: Mapping[str, np.ndarray] = field(default_factory=lambda: _NO_WRENCHES)

    def multipliers(self) -> np.ndarray:
        return self.multipliers_

    def closure_forces(self) -> np.ndarray:
        return self.closure_forces_

    def joint_wrenches(self) -> Mapping[str, np.ndarray]:
        return self.joint_wrenches_

    def residual(self) -> float:
        return float(self.residual_)


#: a result type (:func:`new_result`)
_R = TypeVar("_R")


def new_result(kind: type[_R], values: dict[str, object]) -> _R:
    """An instance of the frozen result dataclass ``kind`` holding ``values`` (every field,
    by name), made without the generated ``__init__`` (one ``object.__setattr__`` per
    field): the fast construction of the single-state routes. The instance is the same as
    ``kind(**values)``: same type, fields, ``cached_property`` parts and immutability (the
    class's ``__setattr__`` is untouched); ``tests/core/test_results.py`` checks the two
    against each other. Only for classes without ``__post_init__``."""
    obj: _R = object.__new__(kind)
    obj.__dict__.update(values)
    return obj


class LazyConditioning:
    """The singularity measures of a result's pose, computed on first call under the
    robot's lock (the measure routes share the robot's scratch) and kept.

    Args:
        singularity: the robot's ``singularity(pose, branch)`` (its kinematics component's
            method, the same the facade's ``robot.singularity`` serves).
        pose: the result's pose (dim,), an owned copy.
        branch: the branch the result was computed on (n_act signs), an owned copy.
        lock: the robot's lock (a ``threading.RLock``).
    """

    __slots__ = ("branch", "lock", "pose", "singularity", "value")

    def __init__(self, singularity: Callable[[npt.ArrayLike, npt.ArrayLike | None],
                                             SingularityMeasures],
                 pose: np.ndarray, branch: np.ndarray, lock: threading.RLock) -> None:
        self.singularity, self.pose, self.branch, self.lock = singularity, pose, branch, lock
        self.value: SingularityMeasures | None = None

    def __call__(self) -> SingularityMeasures:
        """The measures (:class:`SingularityMeasures`), computed once."""
        with self.lock:                     # the robot's scratch
            if self.value is None:
                self.value = self.singularity(self.pose, self.branch)
            return self.value


@dataclass(frozen=True, eq=False)
class InverseDynamicsResult:
    """Result of ``robot.inverse_dynamics(pose, twist, twist_dot, wrench)``.

    Attributes:
        actuator_forces: (n_act,) force (N) or torque (N m) on each actuator along its
            positive direction.
        configuration: the tree configuration ``q`` (nq,) of the pose (Pinocchio
            conventions).
        velocity: the tree velocity ``v`` (nv,) of the twist.
        acceleration: the tree acceleration ``a`` (nv,) of the twist derivative.
        method: the route taken.
        status: the solver's status.
        iterations: the solver's iterations (0 for a direct solve).
        closure_forces: (n_chains, d) force each chain exerts ON the platform at its
            platform joint, world axes (N) (computed on first access).
        multipliers: closure multipliers of the tree rows (n_rows,) (first access).
        joint_wrenches: joint name -> (6,) spatial force ``(f, m)`` that the parent body
            exerts on the child through that joint, in the joint's LOCAL frame (N, N m);
            empty unless requested (first access).
        residual: max-abs residual of ``M a + h - tau_ext - S^T tau - J_c^T lambda``
            (N, N m): round-off only (first access).
        singularity: the conditioning of the result's pose, :class:`SingularityMeasures`
            (equal to ``robot.singularity(pose, branch)``: how close the pose is to the
            thresholds below which the routes refuse it) (first access).
    """

    actuator_forces: np.ndarray
    configuration: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    method: str
    status: str
    iterations: int
    _details: ResultDetails = field(repr=False)
    _conditioning: Callable[[], SingularityMeasures] = field(repr=False)

    @cached_property
    def closure_forces(self) -> np.ndarray:
        return self._details.closure_forces()

    @cached_property
    def multipliers(self) -> np.ndarray:
        return self._details.multipliers()

    @cached_property
    def joint_wrenches(self) -> Mapping[str, np.ndarray]:
        return self._details.joint_wrenches()

    @cached_property
    def residual(self) -> float:
        return self._details.residual()

    @cached_property
    def singularity(self) -> SingularityMeasures:
        return self._conditioning()


@dataclass(frozen=True, eq=False)
class ForwardDynamicsResult:
    """Result of ``robot.forward_dynamics(pose, twist, actuator_forces, wrench)``.

    Attributes:
        twist_dot: time derivative of the platform twist, world axes (m/s^2, rad/s^2).
        actuator_accelerations: (n_act,) second derivative of the actuator coordinates.
        tree_acceleration: the tree acceleration ``a`` (nv,), Pinocchio conventions.
        method: the route taken.
        status: the solver's status.
        iterations: the solver's iterations (0 for a direct solve).
        closure_forces: (n_chains, d) force each chain exerts ON the platform, world axes
            (N) (computed on first access).
        multipliers: closure multipliers of the tree rows (n_rows,) (first access).
        singularity: the conditioning of the result's pose, :class:`SingularityMeasures`
            (equal to ``robot.singularity(pose, branch)``) (first access).
    """

    twist_dot: np.ndarray
    actuator_accelerations: np.ndarray
    tree_acceleration: np.ndarray
    method: str
    status: str
    iterations: int
    _details: ForwardDetails = field(repr=False)
    _conditioning: Callable[[], SingularityMeasures] = field(repr=False)

    @cached_property
    def closure_forces(self) -> np.ndarray:
        return self._details.closure_forces()

    @cached_property
    def multipliers(self) -> np.ndarray:
        return self._details.multipliers()

    @cached_property
    def singularity(self) -> SingularityMeasures:
        return self._conditioning()


@dataclass(frozen=True)
class ReducedDynamics:
    """Dynamics in platform coordinates: ``J^T tau + wrench = M_x twist_dot + h_x``.

    Unpacks as ``M_x, h_x = robot.reduced_dynamics(pose, twist)``.

    Attributes:
        mass_matrix: ``M_x = T^T M T`` (dim, dim), symmetric positive definite, with ``T``
            the map from the twist to the tree velocity.
        bias: ``h_x = T^T (M a_0 + h)`` (dim,): Coriolis, centrifugal and gravity terms,
            ``a_0`` the tree acceleration at ``twist_dot = 0``.
        jacobian: the workspace Jacobian ``J`` (n_act, dim), ``actuator velocities = J twist``.
        velocity_map: ``T`` (nv, dim), ``v = T twist``.
    """

    mass_matrix: np.ndarray
    bias: np.ndarray
    jacobian: np.ndarray
    velocity_map: np.ndarray

    def __iter__(self):
        return iter((self.mass_matrix, self.bias))


@dataclass(frozen=True)
class Energies:
    """Mechanical energies of the whole mechanism (J).

    The per-body parts are optional (empty / None unless the route computes them, e.g.
    :func:`hexapod_pin.core.energy.model_energies`); they take no part in ``==``. With
    them, ``sum(kinetic_per_body) + rotor_kinetic = kinetic`` and
    ``sum(potential_per_body) + spring_potential = potential``.

    Attributes:
        kinetic: ``1/2 v^T M v``, ``M`` with the drives' armature (the rotors' energy
            included).
        potential: gravity potential (zero when every centre of mass is at height zero)
            plus the joint springs' energy.
        total: their sum.
        bodies: the name of each body of the tree (one per joint, the link it moves with
            every link welded to it), or ``()``.
        kinetic_per_body: (n_bodies,) kinetic energy of each body (its links only, no
            rotor), or None.
        potential_per_body: (n_bodies,) gravity potential of each body, or None.
        rotor_kinetic: the rotors' kinetic energy ``1/2 sum(armature v^2)`` (part of
            ``kinetic``; 0.0 when the route does not split it out or there is no
            armature).
        spring_potential: the springs' energy ``1/2 sum(stiffness dq^2)`` (part of
            ``potential``; 0.0 when the route does not split it out or there are no
            springs).
    """

    kinetic: float
    potential: float
    total: float
    bodies: tuple[str, ...] = ()
    kinetic_per_body: np.ndarray | None = field(default=None, compare=False)
    potential_per_body: np.ndarray | None = field(default=None, compare=False)
    rotor_kinetic: float = 0.0
    spring_potential: float = 0.0


@dataclass(frozen=True)
class BatchInverseDynamics:
    """Result of ``robot.inverse_dynamics_batch`` for N states.

    Attributes:
        actuator_forces: (N, n_act), as in :class:`InverseDynamicsResult`.
        closure_forces: (N, n_chains, d) force each chain exerts ON the platform, world axes.
        residual: (N,) max-abs residual of the platform's equation of motion with those
            forces: round-off only.
    """

    actuator_forces: np.ndarray
    closure_forces: np.ndarray
    residual: np.ndarray


@dataclass(frozen=True)
class BatchForwardDynamics:
    """Result of ``robot.forward_dynamics_batch`` for N states.

    Attributes:
        twist_dot: (N, dim) time derivative of the platform twist, world axes.
        actuator_accelerations: (N, n_act) second derivative of the actuator coordinates.
        closure_forces: (N, n_chains, d) force each chain exerts ON the platform, world axes.
    """

    twist_dot: np.ndarray
    actuator_accelerations: np.ndarray
    closure_forces: np.ndarray


@dataclass(frozen=True)
class BatchReducedDynamics:
    """Reduced dynamics ``J^T tau + wrench = M_x twist_dot + h_x`` of N states.

    Attributes:
        mass_matrix: ``M_x`` (N, dim, dim), symmetric positive definite.
        bias: ``h_x`` (N, dim): velocity-product and gravity terms.
        jacobian: ``J`` (N, n_act, dim), ``actuator velocities = J twist``.
    """

    mass_matrix: np.ndarray
    bias: np.ndarray
    jacobian: np.ndarray

    def __iter__(self):
        return iter((self.mass_matrix, self.bias))


@dataclass(frozen=True)
class SingularityMeasures:
    """Distance-like measures of a pose from a parallel robot's singularities.

    Definitions (one for every robot, computed by :mod:`hexapod_pin.core.measures`), with
    the Jacobian ``J = B^-1 A`` (``actuator velocities = J twist``), ``B`` diagonal (the
    actuator direction against each chain's last link) and ``A`` the closure matrix with
    rows ``[e_i, r_i x e_i]`` (unit direction ``e_i`` of chain ``i``'s last link, ``r_i``
    the platform joint relative to the platform origin; in the plane the cross product is
    the scalar ``r_i x e_i``):

    Attributes:
        jacobian_singular_values: singular values of ``J``, descending, in the units of
            ``J`` (columns m/s and rad/s mixed, NOT scaled by any length); None at a
            type-I singularity, where ``J`` is unbounded.
        condition_number: ``sigma_max / sigma_min`` of that unscaled ``J``; ``inf`` at a
            type-I singularity or where ``sigma_min = 0``.
        type_one: the smallest ``|cos|`` between a chain's last link and its actuator
            direction, in [0, 1]; 0 at a type-I (inverse-kinematic) singularity.
        type_one_actuator: the actuator attaining ``type_one``.
        type_two: the smallest singular value of the dimensionless closure matrix
            ``A_hat`` with rows ``[e_i, (r_i x e_i) / characteristic_length]``; 0 at a
            type-II (direct-kinematic) singularity, where the platform can move with the
            actuators locked.
        type_two_singular_values: singular values of ``A_hat``, descending.
        characteristic_length: the length (m) dividing the angular columns of ``A_hat``
            (each robot's platform radius).
        type_one_threshold: the value of ``type_one`` below which every route refuses
            the pose with a ``SingularityError``
            (:data:`hexapod_pin.core.measures.TYPE_I_TOL`): below it the answers' relative
            accuracy is no longer guaranteed to :data:`~hexapod_pin.core.measures.ACCURACY`.
        type_two_threshold: the same for ``type_two``
            (:data:`~hexapod_pin.core.measures.TYPE_II_TOL`).
    """

    jacobian_singular_values: np.ndarray | None
    condition_number: float
    type_one: float
    type_one_actuator: int
    type_two: float
    type_two_singular_values: np.ndarray
    characteristic_length: float
    type_one_threshold: float = 0.0
    type_two_threshold: float = 0.0

    @property
    def regular(self) -> bool:
        """Whether the routes answer at this pose: both measures at or above their
        thresholds."""
        return self.type_one >= self.type_one_threshold and \
            self.type_two >= self.type_two_threshold


@dataclass(frozen=True)
class InverseKinematicsBatch:
    """Result of ``robot.inverse_kinematics_batch`` for N poses.

    Attributes:
        actuator_positions: (N, n_act). Where a chain cannot reach, that actuator holds
            the point nearest to reaching (finite, but not a solution).
        reachable: (N,) bool, every chain reaches its platform joint.
        within_stroke: (N,) bool, the actuator limits hold (evaluated on the positions
            as returned).
        ok: (N,) bool, ``reachable & within_stroke``: the rows where
            ``robot.inverse_kinematics`` would return instead of raise.
    """

    actuator_positions: np.ndarray
    reachable: np.ndarray
    within_stroke: np.ndarray
    ok: np.ndarray


@dataclass(frozen=True)
class JacobianBatch:
    """Result of ``robot.jacobian_batch`` for N poses.

    Attributes:
        jacobian: (N, n_act, dim), ``actuator velocities = J @ twist`` per pose; rows where
            ``ok`` is False are all zeros (never NaN or inf).
        actuator_positions: (N, n_act), as in :class:`InverseKinematicsBatch`.
        reachable: (N,) bool, every chain reaches.
        regular: (N,) bool, no type-I singularity (``type_one`` above the robot's tolerance).
        within_stroke: (N,) bool, the actuator limits hold.
        ok: (N,) bool, ``reachable & regular`` (stroke limits are not required).
    """

    jacobian: np.ndarray
    actuator_positions: np.ndarray
    reachable: np.ndarray
    regular: np.ndarray
    within_stroke: np.ndarray
    ok: np.ndarray


@dataclass(frozen=True)
class InverseDynamicsDerivatives:
    """Derivatives of the inverse-dynamics actuator forces (no bounds applied), from
    ``robot.inverse_dynamics_derivatives(pose, twist, twist_dot, wrench)``.

    Rows: actuator ``i`` (its force along its positive direction, N). Every derivative
    holds the other arguments fixed; twist, twist_dot and wrench are held in world axes.

    Attributes:
        actuator_forces: ``tau`` (n_act,) at the point (N).
        d_pose: ``d tau / d pose`` (n_act, dim) in the robot's pose coordinates (N/m, N/rad).
        d_world: ``d tau / d (dp, dtheta)`` (n_act, dim): ``dp`` (m) the displacement of the
            platform origin and ``dtheta`` (rad) the rotation vector, in world axes. In the
            plane the rotation angle is the pose's own, so ``d_world = d_pose``; in space
            ``d_pose = d_world @ blockdiag(I, E(rpy))`` (``E``:
            :func:`~hexapod_pin.core.pose.euler_rates_matrix`).
        d_twist: ``d tau / d twist`` (n_act, dim) (N s/m, N s/rad).
        d_twist_dot: ``d tau / d twist_dot`` (n_act, dim) (kg, kg m): ``J^-T M_x``.
        d_wrench: ``d tau / d wrench`` (n_act, dim) (1, 1/m): ``-J^-T``.
    """

    actuator_forces: np.ndarray
    d_pose: np.ndarray
    d_world: np.ndarray
    d_twist: np.ndarray
    d_twist_dot: np.ndarray
    d_wrench: np.ndarray

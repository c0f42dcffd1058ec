"""The contract of a robot's closed-form dynamics, and the plumbing every closed form shares.

A robot with a closed form (:class:`~hexapod_pin.hexapod.dynamics.HexapodDynamics`,
:class:`~hexapod_pin.planar.dynamics.PlanarDynamics`) subclasses :class:`ClosedFormDynamics`,
supplies its mechanics through the kernels of the contract :class:`ClosedFormKernels` and
inherits the rest: the actuator bounds and their check, the input and method
checks, the translation of kernel status codes (:mod:`~hexapod_pin.core.kernel_status`)
into library errors for single states and batches (the row ``index`` of a batch), the
batch drivers (argument checks, the compiled batch kernels where they model the robot's
joint effects, state by state on the single-state routes otherwise), the lazy parts of
results (:class:`TreeDetails`, computed by the robot's :class:`LazyParts`) and the
energies.

What a closed form must provide (the abstract :class:`ClosedFormKernels`):

* ``dim``, ``n_actuators``, ``closure_shape``: the pose size, the actuator count and the
  shape of a state's closure forces;
* ``tree_state(pose, twist, branch)``: the tree state ``(q (nq,), v (nv,))`` that keeps
  the closures;
* ``tau_ext(wrench, pose)``: the platform wrench as a tree generalised force (nv,);
* ``raise_kernel_status(code, inputs, info, index, pose)``: the robot's error for a kernel
  status (only the robot knows which leg or link is at fault);
* ``inverse_dynamics``, ``forward_dynamics``, ``reduced_dynamics``: the single-state
  routes (each builds its result from the kernels and the base's pieces);
* ``batch_kernels_apply``: whether the compiled batch kernels model the robot's joint
  effects (False when passive coordinates carry effects the kernels do not hold).

What a closed form may provide, and what the base derives when it does not:

=========================  ===============================================================
``static_forces``          :meth:`~ClosedFormDynamics.inverse_dynamics` at zero twist
                           and twist_dot
``inverse_batch_kernel``   the single-state inverse dynamics, state by state
``forward_batch_kernel``   the single-state forward dynamics ("nullspace"), state by state
``reduced_batch_kernel``   the single-state reduced dynamics, state by state
``static_batch_kernel``    ``inverse_batch_kernel`` at zero twists and twist_dots
``energies``               :func:`~hexapod_pin.core.energy.energy_totals` on
                           ``tree_state``
``regressor``              none (``supplies_regressor`` False): the dynamic regressor of
                           :mod:`hexapod_pin.identification` then comes from the tree
                           (``route="tree"``; ``"auto"`` falls back to it)
``regressor_batch_kernel`` ``regressor``, state by state
``inverse_dynamics_        the core's tree route (None): the analytic partials of the
partials``                 unbounded inverse dynamics, behind the core chain rule of
                           :mod:`~hexapod_pin.core.platform_derivatives`
=========================  ===============================================================

Conventions: those of :mod:`hexapod_pin.core.robot_api` (pose (dim,) in m and rad, twist
and wrench the same selection of ``(v, w)`` and ``(f, m)``, world axes, moment about the
platform origin; actuator forces (n_act,) in N or N m).
"""

from __future__ import annotations

import abc
import math
import threading
from collections.abc import Callable, Mapping, Sequence
from types import MappingProxyType
from typing import Any, NamedTuple, NoReturn

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import (ActuatorSaturationError, BatchActuatorSaturationError,
                      DescriptionError, InputError)
from . import kernel_status
from .checks import as_array, check_batch, flag, max_abs, vector
from .closed_loop import ClosedLoopModel
from .dynamics import ClosedLoopDynamics
from .effects_projection import batch_of_states, batch_row, stacked
from .energy import energy_totals
from .results import (BatchForwardDynamics, BatchInverseDynamics, BatchReducedDynamics,
                      Energies, ForwardDynamicsResult, InverseDynamicsResult,
                      LazyConditioning, ReducedDynamics, SingularityMeasures)
from .robot_api import FORWARD_DYNAMICS_METHODS, INVERSE_DYNAMICS_METHODS

#: relative slack of the actuator-bound check (``|tau| > bound (1 + BOUND_RTOL)``)
BOUND_RTOL = 1e-9

#: an input as given, with its name: ``(value, name)`` (for the errors that name it)
Inputs = Sequence[tuple[Any, str]]


class LazyParts(NamedTuple):
    """How a robot computes the lazy parts of its results (:class:`TreeDetails`): made once
    per robot and route, so that a result costs one small object.

    Attributes:
        dyn: the robot's :class:`~hexapod_pin.core.dynamics.ClosedLoopDynamics`.
        lock: the robot's lock (its Pinocchio data and scratch).
        tau_ext: the wrench on the tree (nv,) of the details, or None (the details' own
            array, or zero).
        closure: the closure forces of the details, or None (from the multipliers).
        to_multipliers: closure forces -> multipliers, or None.
        to_closure: multipliers -> closure forces, or None.
        fext: Pinocchio's external forces ``{joint id: pin.Force}`` of the details' wrench
            (or None) for the joint wrenches, or None (no external force).
    """

    dyn: ClosedLoopDynamics
    lock: Any
    tau_ext: Callable[[TreeDetails], np.ndarray] | None = None
    closure: Callable[[TreeDetails], np.ndarray] | None = None
    to_multipliers: Callable[[np.ndarray], np.ndarray] | None = None
    to_closure: Callable[[np.ndarray], np.ndarray] | None = None
    fext: Callable[[TreeDetails], dict[int, Any] | None] | None = None


class TreeDetails:
    """The parts of a closed-form dynamics result computed on first access
    (:class:`~hexapod_pin.core.results.ResultDetails`): the tree multipliers, the closure
    forces, the joint reaction wrenches and the residual of the tree equation of motion
    ``M a + h - tau_e - tau_ext = S^T tau + J_c^T lambda``, by the robot's
    :class:`LazyParts`.

    Args:
        parts: the robot's :class:`LazyParts`.
        state: ``(q, v, a)`` the tree state (nq,), (nv,), (nv,).
        tau: the actuator forces (n_act,) (N or N m).
        wrench: the wrench (dim,) on the platform, or None.
        pose: the pose (dim,) of the result (an owned copy), or None.
        signs: the branch of the result, or None.
        tau_ext: the wrench on the tree (nv,), or None (``parts.tau_ext``, else zero).
        multipliers: the tree multipliers (n_rows,), a callable of the details giving
            them (called once, under the lock), or None (from the closure forces).
        closure: the closure forces, or None (``parts.closure``, else from the
            multipliers).
        residual: the route's residual, or None to evaluate it on Pinocchio.
        force: the tree force ``rnea(q, v, a) - tau_e`` (nv,) when the route has it (the
            residual then reuses it).
        wanted: whether the joint wrenches were asked for (else they are empty).
    """

    __slots__ = ("_closure", "_multipliers", "_residual", "_tau_ext", "force", "parts",
                 "pose", "signs", "state", "tau", "wanted", "wrench")

    def __init__(self, parts: LazyParts, state: tuple[np.ndarray, np.ndarray, np.ndarray],
                 tau: np.ndarray, wrench: np.ndarray | None = None,
                 pose: np.ndarray | None = None, signs: np.ndarray | None = None, *,
                 tau_ext: np.ndarray | None = None, multipliers: Any = None,
                 closure: np.ndarray | None = None, residual: float | None = None,
                 force: np.ndarray | None = None, wanted: bool = True) -> None:
        self.parts, self.state, self.tau = parts, state, tau
        self.wrench, self.pose, self.signs = wrench, pose, signs
        self._tau_ext, self._multipliers, self._closure = tau_ext, multipliers, closure
        self._residual, self.force, self.wanted = residual, force, wanted

    def tau_ext(self) -> np.ndarray:
        """The wrench as a tree generalised force (nv,)."""
        if self._tau_ext is None:
            make = self.parts.tau_ext
            self._tau_ext = np.zeros(self.parts.dyn.nv) if make is None else make(self)
        return self._tau_ext

    def multipliers(self) -> np.ndarray:
        """The closure multipliers of the tree (n_rows,)."""
        if callable(self._multipliers):
            with self.parts.lock:           # the robot's Pinocchio data and scratch
                self._multipliers = self._multipliers(self)
        elif self._multipliers is None:
            self._multipliers = self.parts.to_multipliers(    # type: ignore[misc]
                self.closure_forces())
        return self._multipliers

    def closure_forces(self) -> np.ndarray:
        """The closure forces (the robot's ``closure_shape``)."""
        if self._closure is None:
            make = self.parts.closure
            if make is None:
                self._closure = self.parts.to_closure(self.multipliers())  # type: ignore[misc]
            else:
                with self.parts.lock:
                    self._closure = make(self)
        return self._closure

    def joint_wrenches(self) -> Mapping[str, np.ndarray]:
        """The reaction wrench of every tree joint (empty when not asked for)."""
        if not self.wanted:
            return MappingProxyType({})
        q, v, a = self.state
        make = self.parts.fext
        fext = None if make is None else make(self)
        multipliers = self.multipliers()
        with self.parts.lock:               # the robot's Pinocchio data
            table, _ = self.parts.dyn.joint_wrenches(q, v, a, multipliers, fext)
        return MappingProxyType(table)

    def residual(self) -> float:
        """The largest residual of the tree equation of motion (N or N m)."""
        if self._residual is None:
            q, v, a = self.state
            dyn = self.parts.dyn
            with self.parts.lock:           # the robot's Pinocchio data
                if self.force is not None:
                    full = np.array(self.force) - self.tau_ext()
                else:
                    full = pin.rnea(dyn.model, dyn.data, q, v, a) - self.tau_ext()
                    effect = dyn.effect_force_of_motion(q, v, a)   # the joint effects'
                    if effect is not None:
                        full -= effect
                jac = dyn.constraint_jacobian(q)
            full[dyn.clm.actuated_v] -= self.tau
            full -= jac.T @ self.multipliers()
            self._residual = max_abs(full)
        return float(self._residual)


class ClosedFormRegressor(NamedTuple):
    """A closed form's dynamic regressor (:meth:`ClosedFormDynamics.regressor`): the
    actuator forces of a platform state, linear in the inertial parameters of every body
    of the robot's tree, ``tau = inertial @ pi`` (gravity included, no drive effect), with
    the actuators' rates that the drive columns of
    :mod:`hexapod_pin.identification.regressor` need.

    One state: the shapes below; N states (:meth:`ClosedFormDynamics.regressor_batch`):
    a leading axis N.

    Attributes:
        inertial: (n_act, 10 nb) (N or N m per parameter unit): columns ten per tree body,
            the body of joint ``1 .. njoints - 1`` in joint order, Pinocchio's parameters
            ``(m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz)`` in the body
            (joint) frame about its origin (``pin.Inertia.toDynamicParameters``); rows the
            actuators in ``model.actuated_joints`` order.
        actuator_velocities: (n_act,) (m/s or rad/s).
        actuator_accelerations: (n_act,) (m/s^2 or rad/s^2).
    """

    inertial: np.ndarray
    actuator_velocities: np.ndarray
    actuator_accelerations: np.ndarray


class ClosedFormKernels(abc.ABC):
    """What a closed form supplies (the contract, see the module docstring): the abstract
    members below, and the sizes as class attributes.

    Attributes:
        dim: the pose size (class attribute).
        n_actuators: the actuator count (class attribute).
        closure_shape: the shape of one state's closure forces (class attribute).
    """

    dim: int
    n_actuators: int
    closure_shape: tuple[int, ...]

    @property
    @abc.abstractmethod
    def batch_kernels_apply(self) -> bool:
        """Whether the compiled batch kernels model the robot's joint effects (else the
        batches run state by state on the single-state routes)."""

    @abc.abstractmethod
    def tree_state(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                   branch: npt.ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Tree configuration ``q`` (nq,) and velocity ``v`` (nv,) of a platform pose and
        twist (dim,) on ``branch``, every closure kept."""

    @abc.abstractmethod
    def tau_ext(self, wrench: np.ndarray | None, pose: np.ndarray) -> np.ndarray:
        """The platform wrench (dim,) (or None: zero) as a tree generalised force (nv,) at
        ``pose`` (dim,)."""

    @abc.abstractmethod
    def raise_kernel_status(self, code: int, inputs: Inputs, info: np.ndarray | None = None,
                            index: int | None = None,
                            pose: np.ndarray | None = None) -> NoReturn:
        """Raise the library error of a kernel status ``code`` (not OK).

        Args:
            code: the status (:mod:`~hexapod_pin.core.kernel_status`).
            inputs: the inputs as given, ``(value, name)``, for an :class:`InputError`.
            info: the kernel's info vector of the state, if it has one.
            index: the row of a batch (Batch* errors), or None.
            pose: the refused state's pose (dim,), when a batch refused it.
        """

    @abc.abstractmethod
    def inverse_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         twist_dot: npt.ArrayLike, wrench: npt.ArrayLike | None = None, *,
                         branch: npt.ArrayLike | None = None, method: str = "kkt",
                         bounded: bool = True,
                         joint_wrenches: bool = True) -> InverseDynamicsResult:
        """Actuator forces (n_act,) that produce a platform motion."""

    @abc.abstractmethod
    def forward_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         actuator_forces: npt.ArrayLike, wrench: npt.ArrayLike | None = None,
                         *, branch: npt.ArrayLike | None = None,
                         method: str = "nullspace") -> ForwardDynamicsResult:
        """Platform acceleration (dim,) produced by actuator forces (n_act,)."""

    @abc.abstractmethod
    def reduced_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         branch: npt.ArrayLike | None = None) -> ReducedDynamics:
        """``J^T tau + wrench = M_x twist_dot + h_x`` at a platform state."""

    def inverse_dynamics_partials(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                                  twist_dot: npt.ArrayLike, wrench: npt.ArrayLike | None = None,
                                  branch: npt.ArrayLike | None = None
                                  ) -> tuple[np.ndarray, np.ndarray] | None:
        """The closed form's analytic derivatives of the unbounded inverse-dynamics forces,
        or None where it has none (or does not model the robot's effects): the core then
        derives them from the tree (:mod:`~hexapod_pin.core.platform_derivatives`).

        Returns:
            ``(tau, partials)``: the forces (n_act,) and their partials (n_act, 4 dim),
            columns the world tangent ``(dp, dtheta)`` of the pose (``R -> exp(dtheta)
            R``), the twist, the twist_dot and the wrench, all held in world axes.

        Raises:
            InputError: bad inputs; Coulomb friction at rest (not differentiable).
            UnreachablePoseError: the pose is out of reach.
            SingularityError: a singular pose.
        """
        return None


class ClosedFormDynamics(ClosedFormKernels):
    """The shared part of a closed-form robot's dynamics (see the module docstring): the
    component a robot facade delegates its dynamics methods to.

    Args:
        geometry: the robot's geometry (its ``max_actuator_force``, N or N m, inf: none).
        model: the robot's :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`.
        lock: the robot's lock (held by the facade's calls and by the lazy parts of
            results); default a new one.
        singularity: the robot's ``singularity(pose, branch)``, giving the results'
            conditioning.

    Attributes:
        geometry: the robot's geometry.
        model: the :class:`ClosedLoopModel`.
        lock: the robot's lock.
        singularity: the measures of a pose, for the results' lazy ``singularity``.
        limits: the actuator bounds (n_act,) or None (none).
        INVERSE_METHODS: the inverse-dynamics methods (class attribute).
        FORWARD_METHODS: the forward-dynamics methods (class attribute).
    """

    INVERSE_METHODS: tuple[str, ...] = INVERSE_DYNAMICS_METHODS
    FORWARD_METHODS: tuple[str, ...] = FORWARD_DYNAMICS_METHODS

    def __init__(self, geometry: Any, model: ClosedLoopModel, lock: Any | None,
                 singularity: Callable[[npt.ArrayLike, npt.ArrayLike | None],
                                       SingularityMeasures]) -> None:
        self.geometry, self.model = geometry, model
        self.singularity = singularity
        self.lock = threading.RLock() if lock is None else lock
        limit = geometry.max_actuator_force
        self.limits = None if not np.isfinite(limit) else np.full(self.n_actuators,
                                                                   float(limit))
        # the smallest bound with its slack (check_bounds' fast path)
        self._least_limit = np.inf if self.limits is None else \
            float((self.limits * (1.0 + BOUND_RTOL)).min())

    # -- checks, bounds, errors ------------------------------------------------------------
    def vector(self, value: npt.ArrayLike, name: str) -> np.ndarray:
        """``value`` as a C-contiguous float vector of the pose size (dim,), for the
        kernels (:func:`~hexapod_pin.core.checks.vector`: the finiteness of a float array
        is left to the kernels, whose refusal :meth:`refuse` turns into the error that
        names it).

        Raises:
            InputError: a bad shape or non-real values (NaN / inf of other inputs).
        """
        return vector(value, self.dim, name)

    @staticmethod
    def check_method(method: str, allowed: tuple[str, ...]) -> None:
        """Raise :class:`InputError` unless ``method`` is one of ``allowed``."""
        if method not in allowed:
            raise InputError("method", method, f"expected one of {allowed}")

    def bounds(self, bounded: bool) -> np.ndarray | None:
        """The actuator bounds (n_act,) (N or N m) enforced with ``bounded``, or None."""
        return self.limits if flag(bounded, "bounded") else None

    def passing_magnitude(self, bounds: np.ndarray | None) -> float:
        """A magnitude up to which every force passes :meth:`check_bounds` under ``bounds``
        (``inf`` without bounds, the smallest bound with its slack for the robot's own,
        -1 otherwise: check each), for a kernel that compares ``max |tau_i|`` with it."""
        if bounds is None:
            return math.inf
        return self._least_limit if bounds is self.limits else -1.0

    def check_bounds(self, tau: np.ndarray, bounds: np.ndarray | None) -> None:
        """Raise :class:`ActuatorSaturationError` (the needed forces, the bounds) when a
        force ``|tau_i|`` exceeds its bound by more than :data:`BOUND_RTOL` (relative)."""
        if bounds is None:
            return
        forces = tau.tolist()
        if bounds is self.limits and max(map(abs, forces)) <= self._least_limit:
            return                          # the common case, in one comparison
        slack = 1.0 + BOUND_RTOL
        if any(abs(t) > b * slack for t, b in zip(forces, bounds.tolist())):
            raise ActuatorSaturationError(tau, bounds)

    def refuse(self, code: int, inputs: Inputs) -> NoReturn:
        """Raise the error of a state the kernels refused: the :class:`InputError` of a
        non-finite input (by name), else :meth:`raise_kernel_status` of ``code``.

        Args:
            code: the kernel status.
            inputs: the inputs as given, ``(value, name)`` (None values skipped).

        Raises:
            InputError: a malformed input.
            UnreachablePoseError: see :meth:`raise_kernel_status`.
            SingularityError: see :meth:`raise_kernel_status`.
        """
        for value, name in inputs:
            if value is not None:
                as_array(value, (self.n_actuators if name == "actuator_forces"
                                 else self.dim,), name)
        self.raise_kernel_status(code, inputs)

    @staticmethod
    def overflow(motion: Sequence[tuple[np.ndarray | None, str]],
                 velocity_finite: bool) -> InputError:
        """The :class:`InputError` of finite inputs whose motion overflows double precision
        (a twist of 1e160: its square in the tree accelerations), naming the user's
        argument rather than the tree state or force it overflowed in: ``twist`` when the
        tree velocity overflowed, else the input of ``motion`` (``(checked array or None,
        name)``) largest in magnitude."""
        given = [(arr, name) for arr, name in motion if arr is not None]
        if velocity_finite:
            arr, name = max(given, key=lambda pair: max_abs(pair[0]))
        else:
            arr, name = next(pair for pair in given if pair[1] == "twist")
        return InputError(name, arr, "too large: the motion's tree velocities, accelerations "
                          "or forces overflow double precision")

    def raise_first(self, status: np.ndarray, infos: np.ndarray | None, poses: np.ndarray,
                    tau: np.ndarray | None = None, bounds: np.ndarray | None = None) -> None:
        """Raise the Batch* error of the first state (lowest index) that a batch kernel
        refused (``status`` (N,) not OK) or whose forces ``tau`` (N, n_act) exceed
        ``bounds``.

        Raises:
            BatchActuatorSaturationError: the first such state saturates.
            BatchUnreachablePoseError: its pose is out of reach (see
                :meth:`raise_kernel_status`).
            BatchSingularityError: it is singular (see :meth:`raise_kernel_status`).
        """
        bad = status != kernel_status.OK
        if tau is not None and bounds is not None:
            bad = bad | np.any(np.abs(tau) > bounds * (1.0 + BOUND_RTOL), axis=1)
        if not bad.any():
            return
        first = int(np.argmax(bad))
        if status[first] == kernel_status.OK and tau is not None and bounds is not None:
            raise BatchActuatorSaturationError(first, tau[first], bounds)
        self.raise_kernel_status(int(status[first]), (),
                                 None if infos is None else infos[first], index=first,
                                 pose=poses[first])

    def check_batch(self, **arrays: npt.ArrayLike | None) -> list[Any]:
        """:func:`check_batch` with this robot's sizes."""
        return check_batch(self.dim, self.n_actuators, **arrays)

    def conditioning(self, pose: np.ndarray, signs: np.ndarray) -> LazyConditioning:
        """The lazy conditioning of a result at ``pose`` (an owned copy) on the branch
        ``signs``."""
        return LazyConditioning(self.singularity, pose, np.array(signs, copy=True),
                                self.lock)

    # -- derived single-state routes ------------------------------------------------------
    def static_forces(self, pose: npt.ArrayLike, wrench: npt.ArrayLike | None = None, *,
                      branch: npt.ArrayLike | None = None,
                      bounded: bool = True) -> npt.NDArray[np.float64]:
        """Actuator forces (n_act,) holding the platform at rest at ``pose`` against
        gravity and the ``wrench`` (dim,) ON the platform: :meth:`inverse_dynamics` at zero
        twist and twist_dot (a closed form may supply its own).

        Raises:
            InputError: bad shape, non-finite or non-real values.
            UnreachablePoseError: the pose is out of reach.
            SingularityError: a singular pose.
            ActuatorSaturationError: with ``bounded``, forces beyond the bounds.
        """
        zero = np.zeros(self.dim)
        return self.inverse_dynamics(pose, zero, zero, wrench, branch=branch,
                                     bounded=bounded, joint_wrenches=False).actuator_forces

    def energies(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                 branch: npt.ArrayLike | None = None) -> Energies:
        """Kinetic and potential energy of the whole mechanism (J) at a platform state.

        Kinetic ``1/2 v^T (M + A) v`` (the rotors' armature included); potential ``sum m_b
        g h_b`` over every body's centre of mass (zero at height 0) plus the springs' ``sum
        K dq^2 / 2`` (:func:`~hexapod_pin.core.energy.energy_totals`), on
        :meth:`tree_state`.

        Args:
            pose: (dim,) (m, rad).
            twist: (dim,) world axes (m/s, rad/s).
            branch: the working mode (default home).

        Raises:
            InputError: bad shape, non-finite or non-real values.
            UnreachablePoseError: the pose is out of reach.
            SingularityError: a singular pose.
        """
        q, v = self.tree_state(pose, twist, branch)
        return self.tree_energies(q, v)

    def tree_energies(self, q: npt.ArrayLike, v: npt.ArrayLike) -> Energies:
        """:meth:`energies` from a tree state ``q`` (nq,), ``v`` (nv,) (Pinocchio
        conventions)."""
        kinetic, potential = energy_totals(self.model, q, v)
        return Energies(kinetic, potential, kinetic + potential)

    # -- the dynamic regressor (a closed form may supply it) -------------------------------
    #: whether the closed form supplies :meth:`regressor` (the closed-form route of
    #: :mod:`hexapod_pin.identification`'s regressor)
    supplies_regressor: bool = False

    def regressor(self, pose: npt.ArrayLike, twist: npt.ArrayLike, twist_dot: npt.ArrayLike,
                  branch: npt.ArrayLike | None = None) -> ClosedFormRegressor:
        """The closed form's dynamic regressor of one platform state
        (:class:`ClosedFormRegressor`), from its own body kinematics and force projection;
        a closed form that supplies it sets :attr:`supplies_regressor`.

        Args:
            pose: (dim,) (m, rad).
            twist: (dim,) world axes (m/s, rad/s).
            twist_dot: (dim,) its time derivative.
            branch: the working mode (default home).

        Raises:
            DescriptionError: this closed form supplies none (the base's answer).
            InputError: bad shapes, NaN / inf.
            UnreachablePoseError: the pose is out of reach.
            SingularityError: a singular state.
        """
        raise self.no_regressor()

    def no_regressor(self) -> DescriptionError:
        """The error of a closed form that supplies no :meth:`regressor`."""
        return DescriptionError(type(self).__name__, "this closed form supplies no dynamic "
                                "regressor: use the tree route (route='tree')")

    def regressor_batch_kernel(self, poses: np.ndarray, twists: np.ndarray,
                               twist_dots: np.ndarray,
                               branch: npt.ArrayLike | None = None) -> ClosedFormRegressor:
        """:meth:`regressor` of N checked states (N, dim); default: state by state."""
        res = batch_of_states(len(poses), lambda k: self.regressor(
            poses[k], twists[k], twist_dots[k], branch))
        return ClosedFormRegressor(*(np.array([r[f] for r in res]) for f in range(3)))

    def regressor_batch(self, poses: npt.ArrayLike, twists: npt.ArrayLike,
                        twist_dots: npt.ArrayLike,
                        branch: npt.ArrayLike | None = None) -> ClosedFormRegressor:
        """:meth:`regressor` of N states (leading axis N; one ``branch`` for all, default
        home), by the closed form's batch kernel.

        Raises:
            DescriptionError: this closed form supplies no regressor.
            InputError: bad shapes, NaN / inf, rows of different lengths.
            BatchUnreachablePoseError: a pose out of reach (the first such state,
                ``index``).
            BatchSingularityError: a singular state (the first, ``index``).
        """
        if not self.supplies_regressor:
            raise self.no_regressor()
        poses, twists, twist_dots = self.check_batch(poses=poses, twists=twists,
                                                     twist_dots=twist_dots)
        return self.regressor_batch_kernel(poses, twists, twist_dots, branch)

    # -- batch kernels (a closed form overrides those it has) -----------------------------
    def inverse_batch_kernel(self, poses: np.ndarray, twists: np.ndarray,
                             twist_dots: np.ndarray, wrenches: np.ndarray | None,
                             bounded: bool) -> BatchInverseDynamics:
        """Inverse dynamics of N checked states (N, dim); default: state by state."""
        res = batch_of_states(len(poses), lambda k: self.inverse_dynamics(
            poses[k], twists[k], twist_dots[k], batch_row(wrenches, k), bounded=bounded,
            joint_wrenches=False))
        return BatchInverseDynamics(stacked(res, "actuator_forces", (self.n_actuators,)),
                                    stacked(res, "closure_forces", self.closure_shape),
                                    stacked(res, "residual", ()))

    def forward_batch_kernel(self, poses: np.ndarray, twists: np.ndarray,
                             forces: np.ndarray,
                             wrenches: np.ndarray | None) -> BatchForwardDynamics:
        """Forward dynamics of N checked states; default: state by state."""
        res = batch_of_states(len(poses), lambda k: self.forward_dynamics(
            poses[k], twists[k], forces[k], batch_row(wrenches, k)))
        return BatchForwardDynamics(stacked(res, "twist_dot", (self.dim,)),
                                    stacked(res, "actuator_accelerations",
                                            (self.n_actuators,)),
                                    stacked(res, "closure_forces", self.closure_shape))

    def static_batch_kernel(self, poses: np.ndarray, wrenches: np.ndarray | None,
                            bounded: bool) -> np.ndarray:
        """Static forces (N, n_act) of N checked poses; default:
        :meth:`inverse_batch_kernel` at zero twists and twist_dots."""
        zero = np.zeros_like(poses)
        return self.inverse_batch_kernel(poses, zero, zero, wrenches, bounded).actuator_forces

    def reduced_batch_kernel(self, poses: np.ndarray,
                             twists: np.ndarray) -> BatchReducedDynamics:
        """Reduced dynamics of N checked states; default: state by state."""
        res = batch_of_states(len(poses), lambda k: self.reduced_dynamics(poses[k],
                                                                          twists[k]))
        return BatchReducedDynamics(stacked(res, "mass_matrix", (self.dim, self.dim)),
                                    stacked(res, "bias", (self.dim,)),
                                    stacked(res, "jacobian", (self.n_actuators, self.dim)))

    # -- batch drivers ------------------------------------------------------------------
    def inverse_dynamics_batch(self, poses: npt.ArrayLike, twists: npt.ArrayLike,
                               twist_dots: npt.ArrayLike, wrenches: npt.ArrayLike | None = None,
                               *, bounded: bool = True) -> BatchInverseDynamics:
        """:meth:`inverse_dynamics` ("kkt", home branch) of N states: the compiled batch
        kernel of the closed form (the same numbers as the single states to round-off), or
        the single-state route state by state when the kernels do not model the robot's
        joint effects.

        Args:
            poses: (N, dim) (m, rad).
            twists: (N, dim) world axes (m/s, rad/s).
            twist_dots: (N, dim) (m/s^2, rad/s^2).
            wrenches: (N, dim) ON the platform (N, N m), or None.
            bounded: raise for the first state beyond ``geometry.max_actuator_force``.

        Returns:
            :class:`~hexapod_pin.core.results.BatchInverseDynamics`.

        Raises:
            InputError: bad shapes, NaN / inf, rows of different lengths.
            BatchUnreachablePoseError: a pose out of reach, the first such state (a subclass
                of :class:`UnreachablePoseError`, with its ``index``).
            BatchSingularityError: a singular state, the first such state (``index``).
            BatchActuatorSaturationError: with ``bounded``, forces beyond the bounds
                (``index``).
        """
        bounded = flag(bounded, "bounded")
        poses, twists, twist_dots, wrenches = self.check_batch(
            poses=poses, twists=twists, twist_dots=twist_dots, wrenches=wrenches)
        if self.batch_kernels_apply:
            return self.inverse_batch_kernel(poses, twists, twist_dots, wrenches, bounded)
        return ClosedFormDynamics.inverse_batch_kernel(self, poses, twists, twist_dots,
                                                       wrenches, bounded)

    def forward_dynamics_batch(self, poses: npt.ArrayLike, twists: npt.ArrayLike,
                               actuator_forces: npt.ArrayLike,
                               wrenches: npt.ArrayLike | None = None) -> BatchForwardDynamics:
        """:meth:`forward_dynamics` ("nullspace", home branch) of N states: the reduced
        equation ``M_x twist_dot = J^T tau + wrench - h_x`` per state (compiled batch
        kernel, or state by state as :meth:`inverse_dynamics_batch`).

        Args:
            poses: (N, dim) (m, rad).
            twists: (N, dim) world axes (m/s, rad/s).
            actuator_forces: (N, n_act) (N or N m).
            wrenches: (N, dim) or None.

        Returns:
            :class:`~hexapod_pin.core.results.BatchForwardDynamics`.

        Raises:
            InputError: bad shape, non-finite or non-real values.
            BatchUnreachablePoseError: a pose out of reach.
            BatchSingularityError: a singular state.
        """
        poses, twists, forces, wrenches = self.check_batch(
            poses=poses, twists=twists, actuator_forces=actuator_forces, wrenches=wrenches)
        if self.batch_kernels_apply:
            return self.forward_batch_kernel(poses, twists, forces, wrenches)
        return ClosedFormDynamics.forward_batch_kernel(self, poses, twists, forces, wrenches)

    def static_forces_batch(self, poses: npt.ArrayLike, wrenches: npt.ArrayLike | None = None,
                            *, bounded: bool = True) -> npt.NDArray[np.float64]:
        """:meth:`static_forces` of N poses (N, dim): (N, n_act) forces (N or N m).

        Raises:
            InputError: bad shape, non-finite or non-real values.
            BatchUnreachablePoseError: a pose out of reach.
            BatchSingularityError: a singular state.
            BatchActuatorSaturationError: with ``bounded``, forces beyond
                ``geometry.max_actuator_force``.
        """
        bounded = flag(bounded, "bounded")
        poses, wrenches = self.check_batch(poses=poses, wrenches=wrenches)
        if self.batch_kernels_apply:
            return self.static_batch_kernel(poses, wrenches, bounded)
        res = batch_of_states(len(poses), lambda k: self.static_forces(
            poses[k], batch_row(wrenches, k), bounded=bounded))
        return np.array(res).reshape(len(poses), self.n_actuators)

    def reduced_dynamics_batch(self, poses: npt.ArrayLike,
                               twists: npt.ArrayLike) -> BatchReducedDynamics:
        """:meth:`reduced_dynamics` (home branch) of N states: ``M_x`` (N, dim, dim),
        ``h_x`` (N, dim), ``J`` (N, n_act, dim).

        Raises:
            InputError: bad shape, non-finite or non-real values.
            BatchUnreachablePoseError: a pose out of reach.
            BatchSingularityError: a singular state.
        """
        poses, twists = self.check_batch(poses=poses, twists=twists)
        if self.batch_kernels_apply:
            return self.reduced_batch_kernel(poses, twists)
        return ClosedFormDynamics.reduced_batch_kernel(self, poses, twists)

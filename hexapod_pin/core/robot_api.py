"""The API shared by every parallel robot of the library, as a documented protocol.

:class:`hexapod_pin.Hexapod` and :class:`hexapod_pin.Planar3PRR` (and any robot added
later) implement :class:`ParallelRobot` with the same method names, argument names,
defaults and result types (:mod:`hexapod_pin.core.results`); one parametrised test suite
(``tests/test_shared_api.py``) runs it over every robot.

Conventions (robot-neutral; each robot's README section gives its numbers):

* ``pose``: the platform's pose, shape ``(dim,)``: ``(x, y, z, roll, pitch, yaw)`` in space
  (m, rad; ``R = Rz(yaw) Ry(pitch) Rx(roll)``), ``(x, y, theta)`` in the plane;
* ``twist``: the platform's velocity ``(v, w)``, linear velocity of the platform origin and
  angular velocity, both in world axes, shape ``(dim,)``; ``twist_dot`` its plain time
  derivative;
* ``wrench``: ``(f, m)`` applied ON the platform by the environment, world axes, moment
  about the platform origin, shape ``(dim,)``;
* actuator positions, velocities, accelerations and forces: shape ``(n_act,)``, actuator
  order, each along the actuator's own positive direction (m or rad; N or N m);
* ``branch``: the inverse-kinematics root of each chain, ``n_act`` values +1 / -1; None: the
  robot's home branch;
* ``bounded``: whether ``|actuator force| <= geometry.max_actuator_force`` is enforced (a
  motion that needs more raises :class:`~hexapod_pin.errors.ActuatorSaturationError` with
  the forces it needs; never a clipped answer);
* ``method``: inverse dynamics ``"kkt"`` (default: the square system solved exactly) or
  ``"qp"`` (ProxSuite, certifying the bounds); forward dynamics ``"nullspace"`` (default),
  ``"pinocchio"``, ``"qp"`` or ``"kkt"``. Every route agrees with the others to 1e-10.
* batch methods take ``(N, dim)`` / ``(N, n_act)`` arrays and run the same compiled kernels
  as the single-state closed forms; errors name the first offending state (``index``).
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from .checks import check_finite_result
from .closed_loop import ClosedLoopModel
from .results import (BatchForwardDynamics, BatchInverseDynamics, BatchReducedDynamics,
                      Energies, ForwardDynamicsResult, InverseDynamicsDerivatives,
                      InverseDynamicsResult,
                      InverseKinematicsBatch, JacobianBatch, ReducedDynamics,
                      SingularityMeasures)

#: inverse-dynamics routes; the first is the default of every robot
INVERSE_DYNAMICS_METHODS = ("kkt", "qp")
#: forward-dynamics routes; the first is the default of every robot
FORWARD_DYNAMICS_METHODS = ("nullspace", "pinocchio", "qp", "kkt")

#: every name of the shared API (the parametrised test suite checks each robot has them)
SHARED_NAMES = (
    "default", "geometry", "model", "pose_dim", "n_actuators", "home_pose", "home_actuators",
    "home_configuration", "configuration", "pose_from_configuration", "actuator_positions",
    "inverse_kinematics", "forward_kinematics", "assembly_modes", "jacobian",
    "twist_from_actuator_velocities", "jacobian_derivative", "singularity",
    "inverse_dynamics", "forward_dynamics", "static_forces", "reduced_dynamics", "energies",
    "inverse_dynamics_derivatives", "inverse_kinematics_batch", "jacobian_batch",
    "inverse_dynamics_batch", "forward_dynamics_batch", "static_forces_batch",
    "reduced_dynamics_batch",
)


@runtime_checkable
class ParallelRobot(Protocol):
    """A parallel robot: a :class:`ClosedLoopModel` plus the closed forms of its platform.

    Attributes:
        geometry: the robot's design parameters (a frozen dataclass with, at least,
            ``max_actuator_force`` (N or N m; ``inf``: unbounded) and ``gravity`` (m/s^2)).
        model: the :class:`ClosedLoopModel` (Pinocchio tree + loop closures).
        pose_dim: 6 in space, 3 in the plane.
        n_actuators: number of actuated joints.
        home_pose: (dim,) the home pose; home_actuators: (n_act,) its actuator positions;
        home_configuration: (nq,) the tree configuration at home.
    """

    geometry: Any
    model: ClosedLoopModel
    pose_dim: int
    n_actuators: int

    @classmethod
    def default(cls) -> "ParallelRobot":
        """The robot with its default geometry."""

    @property
    def home_pose(self) -> np.ndarray: ...

    @property
    def home_actuators(self) -> np.ndarray: ...

    @property
    def home_configuration(self) -> np.ndarray: ...

    # -- configurations ----------------------------------------------------------------
    def configuration(self, pose, branch=None) -> np.ndarray:
        """Pinocchio ``q`` (nq,) of the tree for a pose, every closure held to 1e-12."""

    def pose_from_configuration(self, q) -> np.ndarray:
        """The platform pose (dim,) read from a tree configuration (nq,)."""

    def actuator_positions(self, q) -> np.ndarray:
        """The actuator positions (n_act,) read from a tree configuration (nq,)."""

    # -- kinematics ----------------------------------------------------------------------
    def inverse_kinematics(self, pose, branch=None, check_limits: bool = True) -> np.ndarray:
        """Actuator positions (n_act,) of a pose (closed form)."""

    def forward_kinematics(self, actuators, guess=None) -> np.ndarray:
        """The pose (dim,) of the assembly mode nearest ``guess`` (default: home)."""

    def assembly_modes(self, actuators) -> np.ndarray:
        """Every real assembly mode, shape (n_modes, dim) (n_modes may be 0)."""

    def jacobian(self, pose, branch=None) -> np.ndarray:
        """``J`` (n_act, dim) with ``actuator velocities = J @ twist``."""

    def twist_from_actuator_velocities(self, pose, actuator_velocities,
                                       branch=None) -> np.ndarray:
        """The twist (dim,) that gives the actuator velocities (``J^-1``)."""

    def jacobian_derivative(self, pose, twist, branch=None) -> np.ndarray:
        """``dJ/dt`` (n_act, dim) along the motion."""

    def singularity(self, pose, branch=None) -> SingularityMeasures:
        """Distances to type-I and type-II singularities (never raises at one)."""

    # -- dynamics ------------------------------------------------------------------------
    def inverse_dynamics(self, pose, twist, twist_dot, wrench=None, *, branch=None,
                         method: str = "kkt", bounded: bool = True,
                         joint_wrenches: bool = True) -> InverseDynamicsResult:
        """Actuator forces that produce a platform motion."""

    def forward_dynamics(self, pose, twist, actuator_forces, wrench=None, *, branch=None,
                         method: str = "nullspace") -> ForwardDynamicsResult:
        """Platform acceleration produced by actuator forces."""

    def static_forces(self, pose, wrench=None, *, branch=None,
                      bounded: bool = True) -> np.ndarray:
        """Actuator forces (n_act,) holding the platform at rest against gravity + wrench."""

    def reduced_dynamics(self, pose, twist, branch=None) -> ReducedDynamics:
        """``J^T tau + wrench = M_x twist_dot + h_x``."""

    def energies(self, pose, twist, branch=None) -> Energies:
        """Kinetic, potential and total energy of every body."""

    def inverse_dynamics_derivatives(self, pose, twist, twist_dot,
                                     wrench=None) -> InverseDynamicsDerivatives:
        """Derivatives of the actuator forces w.r.t. pose, twist, twist_dot and wrench."""

    # -- batches -------------------------------------------------------------------------
    def inverse_kinematics_batch(self, poses, branch=None) -> InverseKinematicsBatch: ...

    def jacobian_batch(self, poses, branch=None) -> JacobianBatch: ...

    def inverse_dynamics_batch(self, poses, twists, twist_dots, wrenches=None, *,
                               bounded: bool = True) -> BatchInverseDynamics: ...

    def forward_dynamics_batch(self, poses, twists, actuator_forces,
                               wrenches=None) -> BatchForwardDynamics: ...

    def static_forces_batch(self, poses, wrenches=None, *,
                            bounded: bool = True) -> np.ndarray: ...

    def reduced_dynamics_batch(self, poses, twists) -> BatchReducedDynamics: ...


class delegate:
    """A facade method served by one of the facade's components (composition), called under
    the facade's lock.

    ``inverse_dynamics = delegate("dynamics", HexapodDynamics.inverse_dynamics)`` in a
    class body makes ``robot.inverse_dynamics(...)`` call the component's method while
    holding ``robot.lock`` (a ``threading.RLock``): a robot object is safe to use from
    several threads at once, its calls taking turns (its Pinocchio data, compiled-kernel
    scratch and ProxSuite problems are shared by its methods; the computations hold the
    GIL, so threads could not run them side by side anyway). ``Robot.inverse_dynamics`` is
    the component's function (its docstring and signature for ``help`` and ``inspect``);
    the instance's wrapper is built on first access and kept on the instance. Every number
    the call returns is checked finite (:func:`~hexapod_pin.core.checks.check_finite_result`:
    :class:`~hexapod_pin.errors.NonFiniteResultError` instead of a NaN).

    Args:
        attribute: name of the facade's attribute holding the component.
        function: the component class's function to serve.
    """

    def __init__(self, attribute: str, function):
        self.attribute = attribute
        self.function = function
        self.__doc__ = function.__doc__

    def __set_name__(self, owner, name: str) -> None:
        self.name = name

    def __get__(self, obj, objtype=None):
        if obj is None:
            return self.function
        bound = getattr(getattr(obj, self.attribute), self.function.__name__)
        lock = obj.lock

        where = f"{type(obj).__name__}.{self.name}"

        def serialized(*args, **kwargs):
            with lock:
                out = bound(*args, **kwargs)
            return check_finite_result(where, out)

        serialized.__wrapped__ = bound
        serialized.__doc__ = self.function.__doc__
        serialized.__name__ = serialized.__qualname__ = self.name
        obj.__dict__[self.name] = serialized     # later lookups skip this descriptor
        return serialized

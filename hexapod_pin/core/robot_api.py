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

from collections.abc import Callable
from typing import Any, Concatenate, Generic, ParamSpec, Protocol, TypeVar, overload, \
    runtime_checkable

import numpy as np
import numpy.typing as npt

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
        home_pose: (dim,) the home pose.
        home_actuators: (n_act,) its actuator positions.
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
    def home_pose(self) -> npt.NDArray[np.float64]: ...

    @property
    def home_actuators(self) -> npt.NDArray[np.float64]: ...

    @property
    def home_configuration(self) -> npt.NDArray[np.float64]: ...

    # -- configurations ----------------------------------------------------------------
    def configuration(self, pose: npt.ArrayLike, branch: npt.ArrayLike | None = None
                      ) -> npt.NDArray[np.float64]:
        """Pinocchio ``q`` (nq,) of the tree for a pose, every closure held to 1e-12."""

    def pose_from_configuration(self, q: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """The platform pose (dim,) read from a tree configuration (nq,)."""

    def actuator_positions(self, q: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """The actuator positions (n_act,) read from a tree configuration (nq,)."""

    # -- kinematics ----------------------------------------------------------------------
    def inverse_kinematics(self, pose: npt.ArrayLike, branch: npt.ArrayLike | None = None,
                           check_limits: bool = True) -> npt.NDArray[np.float64]:
        """Actuator positions (n_act,) of a pose (closed form)."""

    def forward_kinematics(self, actuators: npt.ArrayLike,
                           guess: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
        """The pose (dim,) of the assembly mode nearest ``guess`` (default: home)."""

    def assembly_modes(self, actuators: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Every real assembly mode, shape (n_modes, dim) (n_modes may be 0)."""

    def jacobian(self, pose: npt.ArrayLike,
                 branch: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
        """``J`` (n_act, dim) with ``actuator velocities = J @ twist``."""

    def twist_from_actuator_velocities(self, pose: npt.ArrayLike,
                                       actuator_velocities: npt.ArrayLike,
                                       branch: npt.ArrayLike | None = None
                                       ) -> npt.NDArray[np.float64]:
        """The twist (dim,) that gives the actuator velocities (``J^-1``)."""

    def jacobian_derivative(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                            branch: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
        """``dJ/dt`` (n_act, dim) along the motion."""

    def singularity(self, pose: npt.ArrayLike,
                    branch: npt.ArrayLike | None = None) -> SingularityMeasures:
        """Distances to type-I and type-II singularities (never raises at one)."""

    # -- dynamics ------------------------------------------------------------------------
    def inverse_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         twist_dot: npt.ArrayLike, wrench: npt.ArrayLike | None = None, *,
                         branch: npt.ArrayLike | None = None, method: str = "kkt",
                         bounded: bool = True,
                         joint_wrenches: bool = True) -> InverseDynamicsResult:
        """Actuator forces that produce a platform motion."""

    def forward_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         actuator_forces: npt.ArrayLike, wrench: npt.ArrayLike | None = None,
                         *, branch: npt.ArrayLike | None = None,
                         method: str = "nullspace") -> ForwardDynamicsResult:
        """Platform acceleration produced by actuator forces."""

    def static_forces(self, pose: npt.ArrayLike, wrench: npt.ArrayLike | None = None, *,
                      branch: npt.ArrayLike | None = None,
                      bounded: bool = True) -> npt.NDArray[np.float64]:
        """Actuator forces (n_act,) holding the platform at rest against gravity + wrench."""

    def reduced_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         branch: npt.ArrayLike | None = None) -> ReducedDynamics:
        """``J^T tau + wrench = M_x twist_dot + h_x``."""

    def energies(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                 branch: npt.ArrayLike | None = None) -> Energies:
        """Kinetic, potential and total energy of every body."""

    def inverse_dynamics_derivatives(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                                     twist_dot: npt.ArrayLike, wrench: npt.ArrayLike | None = None
                                     ) -> InverseDynamicsDerivatives:
        """Derivatives of the actuator forces w.r.t. pose, twist, twist_dot and wrench."""

    # -- batches -------------------------------------------------------------------------
    def inverse_kinematics_batch(self, poses: npt.ArrayLike, branch: npt.ArrayLike | None = None
                                 ) -> InverseKinematicsBatch: ...

    def jacobian_batch(self, poses: npt.ArrayLike,
                       branch: npt.ArrayLike | None = None) -> JacobianBatch: ...

    def inverse_dynamics_batch(self, poses: npt.ArrayLike, twists: npt.ArrayLike,
                               twist_dots: npt.ArrayLike, wrenches: npt.ArrayLike | None = None,
                               *, bounded: bool = True) -> BatchInverseDynamics: ...

    def forward_dynamics_batch(self, poses: npt.ArrayLike, twists: npt.ArrayLike,
                               actuator_forces: npt.ArrayLike,
                               wrenches: npt.ArrayLike | None = None) -> BatchForwardDynamics: ...

    def static_forces_batch(self, poses: npt.ArrayLike, wrenches: npt.ArrayLike | None = None, *,
                            bounded: bool = True) -> npt.NDArray[np.float64]: ...

    def reduced_dynamics_batch(self, poses: npt.ArrayLike,
                               twists: npt.ArrayLike) -> BatchReducedDynamics: ...


#: the parameters (after ``self``) and the result of a delegated method
P = ParamSpec("P")
R = TypeVar("R")


class delegate(Generic[P, R]):
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

    Typing: the descriptor is generic in the component method's parameters ``P`` (after
    ``self``) and result ``R``, and its ``__get__`` is overloaded, so a type checker sees
    ``Robot.method`` as the component's function and ``robot.method`` as ``Callable[P, R]``:
    the facade's calls are checked against the component's annotations with no stub file
    to keep in step. At run time ``inspect.signature(robot.method)`` follows
    ``__wrapped__`` to the component's bound method (its annotations, without ``self``),
    and ``typing.get_type_hints`` reads the copied ``__annotations__``.

    Args:
        attribute: name of the facade's attribute holding the component.
        function: the component class's function to serve.
    """

    def __init__(self, attribute: str, function: Callable[Concatenate[Any, P], R]) -> None:
        self.attribute = attribute
        self.function = function
        self.__doc__ = function.__doc__

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    @overload
    def __get__(self, obj: None, objtype: type | None = None
                ) -> Callable[Concatenate[Any, P], R]: ...

    @overload
    def __get__(self, obj: object, objtype: type | None = None) -> Callable[P, R]: ...

    def __get__(self, obj: object | None, objtype: type | None = None
                ) -> Callable[Concatenate[Any, P], R] | Callable[P, R]:
        if obj is None:
            return self.function
        bound = getattr(getattr(obj, self.attribute), self.function.__name__)
        lock = getattr(obj, "lock")

        where = f"{type(obj).__name__}.{self.name}"

        def serialized(*args: P.args, **kwargs: P.kwargs) -> R:
            with lock:
                out = bound(*args, **kwargs)
            return check_finite_result(where, out)

        serialized.__wrapped__ = bound    # type: ignore[attr-defined]
        serialized.__doc__ = self.function.__doc__
        serialized.__name__ = serialized.__qualname__ = self.name
        serialized.__annotations__ = {key: value for key, value
                                      in getattr(self.function, "__annotations__", {}).items()
                                      if key != "self"}
        obj.__dict__[self.name] = serialized     # later lookups skip this descriptor
        return serialized

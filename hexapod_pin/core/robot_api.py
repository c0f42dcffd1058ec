"""The API shared by every parallel robot of the library, as a documented protocol.

:class:`hexapod_pin.Hexapod` and :class:`hexapod_pin.Planar3PRR` (and any robot added
later) implement :class:`ParallelRobot` with the same method names, argument names,
defaults and result types (:mod:`hexapod_pin.core.results`); one parametrised test suite
(``tests/test_shared_api.py``) runs it over every robot.

Conventions (robot-neutral; each robot's README section gives its numbers):

* ``pose``: the platform's pose, shape ``(dim,)``: the selection ``robot.pose_axes`` of
  ``(x, y, z, roll, pitch, yaw)`` (m, rad; ``R = Rz(yaw) Ry(pitch) Rx(roll)``), in that
  order: all six for the hexapod, ``("x", "y", "yaw")`` (``(x, y, theta)``) for the planar
  robot, e.g. ``("x", "z")`` for a five-bar in the x-z plane;
* ``twist``: the platform's velocity, the same selection of ``(v, w)``: linear velocity of
  the platform origin and angular velocity, both in world axes, shape ``(dim,)``;
  ``twist_dot`` its plain time derivative;
* ``wrench``: the same selection of ``(f, m)`` applied ON the platform by the environment,
  world axes, moment about the platform origin, shape ``(dim,)``;
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

import functools
from collections.abc import Callable, Sequence
from typing import Any, Concatenate, Generic, NamedTuple, ParamSpec, Protocol, TypeVar, \
    overload, runtime_checkable

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from .checks import as_array, check_finite_result
from ..errors import ArgumentTypeError, InputError
from .closed_loop import ClosedLoopModel
from .platform_map import POSE_AXES, check_pose_axes
from .pose import euler_rates_matrix
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
    "default", "geometry", "model", "pose_dim", "pose_axes", "n_actuators", "home_pose",
    "home_actuators", "home_configuration", "configuration", "pose_from_configuration",
    "actuator_positions", "inverse_kinematics", "forward_kinematics", "assembly_modes", "jacobian",
    "twist_from_actuator_velocities", "twist_from_configuration", "jacobian_derivative",
    "singularity",
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
        pose_dim: number of pose components (6 in space, 3 in the plane, ...).
        pose_axes: (read-only) the pose components, a subset of ``("x", "y", "z", "roll",
            "pitch", "yaw")`` in that order, ``pose_dim`` of them; the twist and the
            wrench are the same selection of ``(v, w)`` and ``(f, m)`` (world axes).
        n_actuators: number of actuated joints.
        home_pose: (dim,) the home pose.
        home_actuators: (n_act,) its actuator positions.
        home_configuration: (nq,) the tree configuration at home.
    """

    geometry: Any
    model: ClosedLoopModel
    pose_dim: int
    n_actuators: int

    @property
    def pose_axes(self) -> tuple[str, ...]: ...

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

    def twist_from_configuration(self, q: npt.ArrayLike,
                                 v: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """The platform twist (dim,) of a tree state ``(q, v)`` (no inverse kinematics:
        the twist of ``q``'s own working mode)."""

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


# -- the layout of a pose ------------------------------------------------------------------
#: the pose axes of a robot in space (the hexapod's; a pose of 6 values without axes)
SPACE_POSE_AXES = POSE_AXES
#: the pose axes of a robot in the plane (the planar 3-PRR's ``(x, y, theta)``; a pose of 3
#: values without axes)
PLANE_POSE_AXES = ("x", "y", "yaw")
#: the pose axes assumed from a pose's width alone (the two robots with a closed form)
DEFAULT_POSE_AXES = {6: SPACE_POSE_AXES, 3: PLANE_POSE_AXES}


def parallel_robot(robot: object, name: str = "robot") -> ParallelRobot:
    """``robot`` after checking that it has the shared API (:class:`ParallelRobot`).

    Raises:
        ArgumentTypeError: anything else (None, a string, a model), naming ``name``.
    """
    if not isinstance(robot, ParallelRobot):
        raise ArgumentTypeError(name, robot, "expected a robot of the shared API "
                                "(hexapod_pin.core.robot_api.ParallelRobot), got "
                                f"{type(robot).__name__}")
    return robot


class PoseLayout(NamedTuple):
    """Where the components of a robot's pose (and twist, twist derivative, wrench) sit.

    Attributes:
        axes: the pose axes, a subset of ``("x", "y", "z", "roll", "pitch", "yaw")`` in that
            order (``dim`` of them).
        linear: indices (into the pose) of the linear components ``x, y, z`` (m; twist:
            m/s, wrench: N), int array, possibly empty.
        angular: indices (into the pose) of the angles ``roll, pitch, yaw`` (rad; twist:
            the world angular velocity components ``wx, wy, wz``, rad/s; wrench: N m),
            possibly empty. Every linear index precedes every angular one.
        full_rotation: all three angles are in the pose: the orientation is a rotation in
            SO(3) (``R = Rz(yaw) Ry(pitch) Rx(roll)``) and the angular velocity is
            ``w = E(rpy) d(rpy)/dt``; otherwise each selected angle is a scalar whose rate
            is the matching component of ``w`` (exact for a rotation about that fixed
            world axis, the case of planar mechanisms).
        components: the index of each pose component in ``(x, y, z, roll, pitch, yaw)``
            (dim,): ``components[linear]`` are world axes 0..2 of the linear components,
            ``components[angular] - 3`` those of the angular ones.
    """

    axes: tuple[str, ...]
    linear: np.ndarray
    angular: np.ndarray
    full_rotation: bool
    components: np.ndarray

    @property
    def dim(self) -> int:
        """Number of pose components."""
        return len(self.axes)

    def names(self, full: Sequence[str]) -> tuple[str, ...]:
        """The selection of six names given in the order of ``(x, y, z, roll, pitch,
        yaw)``, e.g. ``("vx", "vy", "vz", "wx", "wy", "wz")`` -> ``("vx", "vz")`` for
        pose axes ``("x", "z")``."""
        return tuple(full[i] for i in self.components)

    def twists_from_poses(self, t: np.ndarray, poses: np.ndarray) -> np.ndarray:
        """Twists (N, dim) (m/s, rad/s, world axes) of poses (N, dim) sampled at times
        ``t`` (N,) (s), N >= 3, by second-order finite differences (``numpy.gradient``,
        also at the ends): ``v = dp/dt``; the angles unwrapped, then ``w = E(rpy)
        d(rpy)/dt`` with a full rotation, each angle's rate otherwise."""
        out = np.empty_like(poses, dtype=float)
        out[:, self.linear] = np.gradient(poses[:, self.linear], t, axis=0, edge_order=2)
        if self.angular.size:
            angles = np.unwrap(poses[:, self.angular], axis=0)
            rates = np.gradient(angles, t, axis=0, edge_order=2)
            if self.full_rotation:
                rates = np.einsum("nij,nj->ni", euler_rates_matrix(angles), rates)
            out[:, self.angular] = rates
        return out


#: largest |component| (m, rad) of a placement outside a robot's pose axes that
#: :func:`pose_vector` takes for zero (round-off of a composed placement)
PLACEMENT_TOL = 1e-9
#: the world axis of each angle
_ANGLE_AXIS = {"roll": 0, "pitch": 1, "yaw": 2}


def is_placement(value: object) -> bool:
    """Whether ``value`` is given as a placement: a ``pin.SE3`` or a 4x4 array-like (a
    homogeneous matrix)."""
    if isinstance(value, np.ndarray):           # the common case first: a pose vector
        return value.shape == (4, 4)
    if isinstance(value, (list, tuple)):
        return len(value) == 4 and all(
            isinstance(row, (list, tuple, np.ndarray)) and len(row) == 4 for row in value)
    return isinstance(value, pin.SE3)


def pose_vector(value: object, layout: PoseLayout, name: str = "pose") -> Any:
    """A pose as a robot's methods take it: ``value`` itself when it is a pose vector
    (checked by the method), or the pose vector (dim,) of a placement: a ``pin.SE3`` or a
    4x4 homogeneous matrix ``[[R, p], [0, 0, 0, 1]]`` of the platform frame in the world
    (``p`` m; ``R`` from platform axes to world axes).

    With all three angles in the pose axes the angles are ``(roll, pitch, yaw)`` of ``R =
    Rz(yaw) Ry(pitch) Rx(roll)`` (``pin.rpy.matrixToRpy``); with one angle, ``R`` must be a
    rotation about that world axis and the angle is its signed angle (in ``(-pi, pi]``);
    with none, ``R`` must be the identity. The position components outside the pose axes
    must be 0 (within :data:`PLACEMENT_TOL`), as must the angles of ``R`` outside them
    (e.g. for the planar robot's ``(x, y, yaw)``: ``z = 0`` and a rotation about z).

    Raises:
        InputError: a 4x4 matrix that is not homogeneous (last row not ``(0, 0, 0, 1)``,
            ``R`` not a rotation to 1e-9, NaN / inf), or components outside the pose axes
            that are not zero (naming them and their values).
    """
    if not is_placement(value):
        return value
    if isinstance(value, pin.SE3):
        rot, pos = np.array(value.rotation), np.array(value.translation)
    else:
        mat = as_array(value, (4, 4), name)
        if np.abs(mat[3] - (0.0, 0.0, 0.0, 1.0)).max() > PLACEMENT_TOL:
            raise InputError(name, value, "a homogeneous matrix has the last row (0, 0, 0, 1)")
        rot, pos = mat[:3, :3], mat[:3, 3]
    if np.abs(rot @ rot.T - np.eye(3)).max() > PLACEMENT_TOL or np.linalg.det(rot) <= 0.0:
        raise InputError(name, value, "its 3x3 block is not a rotation (R R^T = I, det R = 1)")
    angles = [a for a in layout.axes if a in _ANGLE_AXIS]
    full = np.empty(6)
    full[:3] = pos
    if len(angles) == 1:
        k = _ANGLE_AXIS[angles[0]]
        i, j = (k + 1) % 3, (k + 2) % 3
        full[3:] = 0.0
        full[3 + k] = np.arctan2(rot[j, i], rot[i, i])
        off_axis = max(abs(rot[k, k] - 1.0), abs(rot[k, i]), abs(rot[k, j]))
        if off_axis > PLACEMENT_TOL:
            others = ", ".join(a for a in _ANGLE_AXIS if a != angles[0])
            raise InputError(name, value, f"the pose axes {', '.join(layout.axes)} allow a "
                             f"rotation about the {'xyz'[k]} axis only: its rotation also "
                             f"turns about the axes of {others} (off-axis part "
                             f"{off_axis:.3g})")
    else:
        full[3:] = pin.rpy.matrixToRpy(rot)
    outside = [(axis, full[k]) for k, axis in enumerate(POSE_AXES)
               if axis not in layout.axes and abs(full[k]) > PLACEMENT_TOL]
    if outside:
        parts = ", ".join(f"{axis} = {v:.6g}" for axis, v in outside)
        raise InputError(name, value, f"the pose axes are {', '.join(layout.axes)}: the "
                         f"placement's other components must be zero, got {parts}")
    return full[layout.components]


#: what :func:`pose_layout` reads a layout from
PoseAxesSource = PoseLayout | ParallelRobot | Sequence[str] | str | int


def pose_layout(source: PoseAxesSource) -> PoseLayout:
    """The :class:`PoseLayout` of a robot, of its pose axes, or of a pose width.

    Args:
        source: a robot (its ``pose_axes``; a robot without them: the default axes of its
            ``pose_dim``), a sequence of pose axes (or a comma-separated string, checked
            as in :func:`~hexapod_pin.core.platform_map.check_pose_axes`), a pose width
            6 (:data:`SPACE_POSE_AXES`) or 3 (:data:`PLANE_POSE_AXES`), or a
            :class:`PoseLayout` (returned as it is).

    Raises:
        InputError: axes that are not a subset of ``(x, y, z, roll, pitch, yaw)`` in that
            order, or a width with no default axes (named ``pose_axes``).

    Example:
        >>> pose_layout(("x", "z")).linear, pose_layout(("x", "z")).components
        (array([0, 1]), array([0, 2]))
    """
    if isinstance(source, PoseLayout):
        return source
    axes_source: object = source
    if not isinstance(source, (str, Sequence, int, np.integer)):
        axes_source = getattr(source, "pose_axes", None)
        if axes_source is None:
            axes_source = getattr(source, "pose_dim", source)
    if isinstance(axes_source, (int, np.integer)) and not isinstance(axes_source, bool):
        if int(axes_source) not in DEFAULT_POSE_AXES:
            raise InputError("pose_axes", source, "no default pose axes for a pose of "
                             f"{int(axes_source)} values: give the robot or its pose axes")
        axes_source = DEFAULT_POSE_AXES[int(axes_source)]
    axes = check_pose_axes(axes_source)
    components = np.array([POSE_AXES.index(a) for a in axes], dtype=int)
    angular = np.flatnonzero(components >= 3)
    return PoseLayout(axes, np.flatnonzero(components < 3), angular, angular.size == 3,
                      components)


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

        # a robot facade's single-state methods: their poses may be placements
        layout = getattr(obj, "pose_layout", None) if _takes_pose(self.function) else None

        def serialized(*args: P.args, **kwargs: P.kwargs) -> R:
            if layout is not None and ((args and is_placement(args[0])) or "pose" in kwargs):
                args, kwargs = _pose_arguments(layout, args, kwargs)  # type: ignore[assignment]
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


def _pose_arguments(layout: PoseLayout, args: tuple, kwargs: dict) -> tuple[tuple, dict]:
    """A call's arguments with its ``pose`` (the first positional argument, or the keyword)
    converted from a placement (:func:`pose_vector`)."""
    if args:
        return (pose_vector(args[0], layout), *args[1:]), kwargs
    return args, {**kwargs, "pose": pose_vector(kwargs["pose"], layout)}


def takes_placement(method: Callable[..., R]) -> Callable[..., R]:
    """Decorator of a robot method ``(self, pose, ...)`` written on the facade itself (not
    a :class:`delegate`): its ``pose`` may be a placement too (:func:`pose_vector`, in the
    robot's ``pose_layout``), as for the delegated methods."""

    @functools.wraps(method)
    def wrapper(self: Any, *args: Any, **kwargs: Any) -> R:
        if (args and is_placement(args[0])) or "pose" in kwargs:
            args, kwargs = _pose_arguments(self.pose_layout, args, kwargs)
        return method(self, *args, **kwargs)

    return wrapper


def _takes_pose(function: Callable) -> bool:
    """Whether a robot method's first argument after ``self`` is ``pose`` (a single-state
    method: it takes a placement too, :func:`pose_vector`)."""
    code = getattr(function, "__code__", None)
    return code is not None and code.co_argcount >= 2 and code.co_varnames[1] == "pose"


def state_branch(robot: object, pose: np.ndarray, q: np.ndarray) -> object:
    """The ``branch`` under which ``robot``'s platform routes use the tree configuration
    ``q`` (nq,) at ``pose`` (its working mode): ``q`` itself for a robot whose branches are
    configurations (``branch_is_configuration``, a
    :class:`~hexapod_pin.core.robot.ClosedLoopRobot`), else ``robot.branch_of(pose,
    actuators)`` (the hexapod's and planar robot's +-1 signs), else None (home).

    Raises:
        InputError: ``q`` does not solve the inverse kinematics of ``pose`` (from
            ``branch_of``).
    """
    if getattr(robot, "branch_is_configuration", False):
        return q
    branch_of = getattr(robot, "branch_of", None)
    if branch_of is None:
        return None
    return branch_of(pose, robot.actuator_positions(q))     # type: ignore[attr-defined]

"""Any closed-loop model as a parallel robot: :class:`ClosedLoopRobot`.

``ClosedLoopRobot(model, platform="frame", pose_axes=(...))`` gives a
:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel` the whole shared API of the
library's robots (:class:`~hexapod_pin.core.robot_api.ParallelRobot`): inverse and
forward kinematics, assembly modes, Jacobians and their derivatives, singularity
measures, inverse and forward dynamics with every method, statics, reduced dynamics,
energies, inverse-dynamics derivatives and the batches, with no code specific to the
robot: everything is derived from the tree and its closures
(:mod:`~hexapod_pin.core.robot_kinematics`, :mod:`~hexapod_pin.core.robot_dynamics`,
conventions in :mod:`~hexapod_pin.core.platform_map`). Every answer is verified before it
is returned, or a typed error is raised.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import ArgumentTypeError, AssemblyError, DescriptionError
from .checks import bounds, real_number
from .closed_loop import ClosedLoopModel
from .platform_map import PlatformMap, check_pose_axes
from .robot_api import delegate, takes_placement
from .robot_base import RobotBase
from .robot_dynamics import RobotDynamics
from .robot_kinematics import RobotKinematics

#: an effort limit at or above this (or not positive) in a description means "none"
_NO_LIMIT = 1e30


@dataclass(frozen=True)
class RobotSpec:
    """What a :class:`ClosedLoopRobot` is made of (its ``geometry``).

    Attributes:
        name: the model's name.
        platform: the platform frame's name.
        pose_axes: the selected pose components, e.g. ``("x", "y", "z", "roll", "pitch",
            "yaw")``.
        max_actuator_force: bound on ``|u|`` (N or N m), a float or (n_act,) array;
            ``inf``: none (default: the actuated joints' effort limits in the description).
        gravity: magnitude of the model's gravity (m/s^2).
        characteristic_length: the length (m) relating angular and linear coordinates in
            the conditioning measures and tolerances.
    """

    name: str
    platform: str
    pose_axes: tuple[str, ...]
    max_actuator_force: float | np.ndarray
    gravity: float
    characteristic_length: float


def _home_candidates(model: ClosedLoopModel, n: int = 32) -> list[np.ndarray]:
    """Configurations that close the loops, assembled with every coordinate free from
    Pinocchio's neutral configuration and from ``n`` seeded random perturbations of it.

    Raises:
        AssemblyError: none assembles.
    """
    free = np.zeros(0, dtype=int)
    rng = np.random.default_rng(0)
    start, out = model.neutral(), []
    failure: AssemblyError | None = None
    for _ in range(n + 1):
        try:
            out.append(model.assemble(start, fixed=free, max_iter=100, restarts=0,
                                      method="newton").q)
        except AssemblyError as exc:
            failure = exc
        start = pin.integrate(model.model, model.neutral(), rng.uniform(-1.0, 1.0, model.nv))
    if not out:
        assert failure is not None
        raise failure
    return out


class ClosedLoopRobot(RobotBase):
    """A closed-loop model as a parallel robot (see the module docstring).

    ``branch`` (every platform-level method) is None (the working mode reached from home)
    or a tree configuration (nq,) to start from: :data:`branch_is_configuration`.

    Args:
        model: the :class:`ClosedLoopModel` (tree + closures + actuated joints).
        platform: the frame whose placement is the robot's pose.
        pose_axes: which components of that placement are the pose, a subset of
            ``("x", "y", "z", "roll", "pitch", "yaw")`` in that order (or a
            comma-separated string); the twist and the wrench are the same selection of
            ``(v, w)`` and ``(f, m)`` in world axes. The closed mechanism's mobility must
            equal their number.
        home: the home configuration (nq,); assembled with the actuators held when it
            does not close the loops. Default: of the configurations assembled (every
            coordinate free) from Pinocchio's neutral configuration and 32 seeded random
            perturbations of it, the best-conditioned (largest smallest singularity
            measure); pass ``home`` to choose the working and assembly modes yourself.
        max_actuator_force: bound on ``|u|`` (scalar or (n_act,), > 0, inf: none); default
            the effort limits of the actuated joints in the description.
        characteristic_length: (m) > 0; default the largest distance from the platform
            origin to a joint origin in Pinocchio's neutral configuration (1 m when all
            coincide).

    Attributes:
        geometry: the :class:`RobotSpec`.
        model: the :class:`ClosedLoopModel`.
        pose_dim: the number of pose components.
        n_actuators: the number of actuated joints.
        platform: the :class:`~hexapod_pin.core.platform_map.PlatformMap`.
        kinematics: the :class:`~hexapod_pin.core.robot_kinematics.RobotKinematics`.
        dynamics: the :class:`~hexapod_pin.core.robot_dynamics.RobotDynamics`.
        lock: serialises the robot's calls (a ``threading.RLock``).

    Raises:
        DescriptionError: no such frame, a mobility that differs from the pose dimension,
            a singular home, or a home that cannot be assembled.
        InputError: bad arguments.

    Example:
        >>> robot = ClosedLoopRobot(model, platform="tip", pose_axes=("x", "z"))
        >>> robot.inverse_kinematics(robot.home_pose + [0.01, 0.0])
    """

    #: ``branch`` arguments are start configurations (nq,), not +-1 signs
    branch_is_configuration = True

    def __init__(self, model: ClosedLoopModel, platform: str,
                 pose_axes: object = ("x", "y", "z", "roll", "pitch", "yaw"), *,
                 home: npt.ArrayLike | None = None,
                 max_actuator_force: npt.ArrayLike | None = None,
                 characteristic_length: float | None = None) -> None:
        if not isinstance(model, ClosedLoopModel):
            raise ArgumentTypeError("model", model, "expected a ClosedLoopModel, got "
                                    f"{type(model).__name__}")
        axes = check_pose_axes(pose_axes)
        self._init_facade(model)
        candidates = self._home(model, home)
        probe = PlatformMap(model, platform, axes, 1.0)
        length = self._length(model, probe.frame, model.neutral()) \
            if characteristic_length is None \
            else real_number(characteristic_length, "characteristic_length", minimum=0.0)
        self.platform = PlatformMap(model, platform, axes, length)
        home_q = candidates[0] if len(candidates) == 1 else self._best(candidates)
        self.kinematics = RobotKinematics(model, self.platform, home_q)
        maps = self.kinematics.maps(home_q)
        mobility = maps.basis.shape[1]
        if mobility != self.platform.dim:
            raise DescriptionError(model.name, f"the closed mechanism has mobility {mobility} "
                                   f"at home but pose_axes {axes} select {self.platform.dim} "
                                   "components: choose as many pose axes as degrees of "
                                   "freedom", "pose_axes")
        if model.n_actuated < mobility:
            raise DescriptionError(model.name, f"{model.n_actuated} actuated joints for "
                                   f"mobility {mobility}: the robot is under-actuated")
        meas = self.kinematics.measures(maps)
        if not meas.regular:
            raise DescriptionError(model.name, "the home configuration is singular "
                                   f"(type_one {meas.type_one:.3e}, type_two "
                                   f"{meas.type_two:.3e}): give another home")
        force = self._max_force(model, max_actuator_force)
        gravity = float(np.linalg.norm(model.model.gravity.linear))
        self.geometry = RobotSpec(model.name, self.platform.frame_name, axes, force, gravity,
                                  length)
        self.dynamics = RobotDynamics(model, self.kinematics, force, self.lock)
        #: number of pose components
        self.pose_dim: int = self.platform.dim
        #: number of actuated joints
        self.n_actuators: int = model.n_actuated

    # -- construction helpers ------------------------------------------------------------
    @staticmethod
    def _home(model: ClosedLoopModel, home: npt.ArrayLike | None) -> list[np.ndarray]:
        try:
            if home is None:
                return _home_candidates(model)
            q = model.check_q(home, "home")
            if float(np.max(np.abs(model.residual(q)), initial=0.0)) <= 1e-12:
                return [q.copy()]
            return [model.assemble(q).q]
        except AssemblyError as exc:
            raise DescriptionError(model.name, f"the home configuration does not assemble "
                                   f"({exc}): give home=") from None

    def _best(self, candidates: list[np.ndarray]) -> np.ndarray:
        """The best-conditioned candidate home (largest ``min(type_one, type_two)``) of the
        right mobility."""
        scored: list[tuple[float, int, np.ndarray]] = []
        for q in candidates:
            maps = self.platform.velocity_maps(q)
            if maps.basis.shape[1] != self.platform.dim:
                continue
            probe = RobotKinematics(self.model, self.platform, q)
            meas = probe.measures(maps)
            scored.append((min(meas.type_one, meas.type_two), len(scored), q))
        return max(scored)[2] if scored else candidates[0]

    @staticmethod
    def _length(model: ClosedLoopModel, frame: int, q: np.ndarray) -> float:
        data = model.model.createData()
        pin.framesForwardKinematics(model.model, data, q)
        origin = data.oMf[frame].translation
        dist = [float(np.linalg.norm(data.oMi[j].translation - origin))
                for j in range(1, model.model.njoints)]
        return max([d for d in dist if d > 0.0], default=1.0)

    @staticmethod
    def _max_force(model: ClosedLoopModel, value: npt.ArrayLike | None) -> float | np.ndarray:
        n = model.n_actuated
        if value is None:
            raw = np.array(model.model.effortLimit)[model.actuated_v]
            arr = np.where((raw > 0.0) & (raw < _NO_LIMIT), raw, math.inf)
        else:
            arr = bounds(value, n, "max_actuator_force")
        return float(arr[0]) if np.all(arr == arr[0]) else arr

    # -- the shared API --------------------------------------------------------------------
    def default(self) -> "ClosedLoopRobot":
        """A new robot on the same model, platform, pose axes and home configuration, with
        the default bounds and characteristic length (from the description)."""
        return ClosedLoopRobot(self.model, self.geometry.platform, self.geometry.pose_axes,
                               home=self.kinematics.home_q)

    def _with_model(self, model: ClosedLoopModel) -> "ClosedLoopRobot":
        """This robot (platform, pose axes, home, bounds, characteristic length) on
        ``model``."""
        spec = self.geometry
        return ClosedLoopRobot(model, spec.platform, spec.pose_axes, home=self.kinematics.home_q,
                               max_actuator_force=spec.max_actuator_force,
                               characteristic_length=spec.characteristic_length)

    def __repr__(self) -> str:
        return (f"ClosedLoopRobot({self.model.name!r}, platform={self.geometry.platform!r}, "
                f"pose_axes={self.geometry.pose_axes})")

    @property
    def pose_axes(self) -> tuple[str, ...]:
        """The pose components, ``geometry.pose_axes`` (a subset of ``("x", "y", "z",
        "roll", "pitch", "yaw")`` in that order)."""
        return self.geometry.pose_axes

    @property
    def platform_frame(self) -> str:
        """The platform frame's name, ``geometry.platform``."""
        return self.geometry.platform

    @property
    def platform_frame_id(self) -> int:
        """The Pinocchio id of the platform frame, as resolved when the robot was built."""
        return self.platform.frame

    @property
    def home_pose(self) -> npt.NDArray[np.float64]:
        """The pose (dim,) of the home configuration."""
        return self.kinematics.home_pose.copy()

    @property
    def home_actuators(self) -> npt.NDArray[np.float64]:
        """The actuator positions (n_act,) of the home configuration."""
        return self.kinematics.home_actuators.copy()

    @cached_property
    def home_configuration(self) -> npt.NDArray[np.float64]:
        """The home configuration (nq,), every closure held."""
        return self.kinematics.home_q.copy()

    configuration = delegate("kinematics", RobotKinematics.configuration)
    pose_from_configuration = delegate("kinematics", RobotKinematics.pose_from_configuration)
    actuator_positions = delegate("kinematics", RobotKinematics.actuator_positions)
    inverse_kinematics = delegate("kinematics", RobotKinematics.inverse_kinematics)
    forward_kinematics = delegate("kinematics", RobotKinematics.forward_kinematics)
    assembly_modes = delegate("kinematics", RobotKinematics.assembly_modes)
    search_assembly_modes = delegate("kinematics", RobotKinematics.search_assembly_modes)
    assembly_configurations = delegate("kinematics", RobotKinematics.assembly_configurations)
    jacobian = delegate("kinematics", RobotKinematics.jacobian)
    twist_from_actuator_velocities = delegate(
        "kinematics", RobotKinematics.twist_from_actuator_velocities)
    jacobian_derivative = delegate("kinematics", RobotKinematics.jacobian_derivative)
    singularity = delegate("kinematics", RobotKinematics.singularity)
    stroke_violations = delegate("kinematics", RobotKinematics.stroke_violations)
    check_stroke = delegate("kinematics", RobotKinematics.check_stroke)
    inverse_kinematics_batch = delegate("kinematics", RobotKinematics.inverse_kinematics_batch)
    jacobian_batch = delegate("kinematics", RobotKinematics.jacobian_batch)

    inverse_dynamics = delegate("dynamics", RobotDynamics.inverse_dynamics)
    forward_dynamics = delegate("dynamics", RobotDynamics.forward_dynamics)
    static_forces = delegate("dynamics", RobotDynamics.static_forces)
    reduced_dynamics = delegate("dynamics", RobotDynamics.reduced_dynamics)
    energies = delegate("dynamics", RobotDynamics.energies)
    inverse_dynamics_batch = delegate("dynamics", RobotDynamics.inverse_dynamics_batch)
    forward_dynamics_batch = delegate("dynamics", RobotDynamics.forward_dynamics_batch)
    static_forces_batch = delegate("dynamics", RobotDynamics.static_forces_batch)
    reduced_dynamics_batch = delegate("dynamics", RobotDynamics.reduced_dynamics_batch)

    def stroke_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """The actuator position limits ``(lower, upper)`` (n_act,) from the description
        (-inf / inf: none)."""
        return self.kinematics.lower.copy(), self.kinematics.upper.copy()

    @takes_placement
    def tree_velocity(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                      branch: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
        """The tree velocity (nv,) of a platform state, every closure kept."""
        with self.lock:
            return self.dynamics.state(pose, twist, branch).v.copy()



def tree_robot(robot: Any, model: ClosedLoopModel) -> ClosedLoopRobot:
    """``robot``'s mechanism on ``model`` (its tree, e.g. under another gravity) as a
    :class:`ClosedLoopRobot`: every route derived from the tree and its closures, with
    ``robot``'s platform frame, pose axes, home configuration, actuator force bounds and
    characteristic length (so that its singularity measures and thresholds are the
    robot's)."""
    return ClosedLoopRobot(model, robot.platform_frame, robot.pose_axes,
                           home=robot.home_configuration,
                           max_actuator_force=robot.geometry.max_actuator_force,
                           characteristic_length=robot.singularity(
                               robot.home_pose).characteristic_length)

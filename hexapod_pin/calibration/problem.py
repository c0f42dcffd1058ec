"""The identification problem: checked measurements, the residual function of either
measurement model over the 66 parameters, and the reference poses of the structural
identifiability test.

Measurements (:class:`Measurements`): N actuator readings (N, 6) (m) with either the
measured target poses (N, 6) in the instrument frame (m, rad), or the measured positions
(N, M, 3) of ``M`` = 1..3 target points in the instrument frame (m) together with those
points' coordinates (M, 3) in the target frame (m).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..core.checks import as_array, generator, of_type, real_number
from ..core.checks import count as check_count
from ..core.pose import rotation_from_rpy
from ..errors import InputError
from ..hexapod.robot import Hexapod
from .model import PointModel, closure_noise, measured_poses, pose_residuals
from .parameters import N_PARAMETERS, ParameterModel

#: half-ranges of the reference poses about home: translation (fraction of the platform
#: radius) and rotation (rad)
REFERENCE_TRANSLATION = 0.25
REFERENCE_ROTATION = 0.15
#: smallest |cos(leg, line)| of a reference pose
REFERENCE_MIN_COS = 0.2


@dataclass(frozen=True)
class Measurements:
    """Checked measurements (see the module doc).

    Attributes:
        actuators: readings (N, 6) (m).
        poses: measured target poses (N, 6) in the instrument frame, or None.
        points: measured target points (N, M, 3) in the instrument frame, or None.
        target_points: the points in the target frame (M, 3), or None.
    """

    actuators: np.ndarray
    poses: np.ndarray | None = None
    points: np.ndarray | None = None
    target_points: np.ndarray | None = None

    @property
    def count(self) -> int:
        """Number of measurements N."""
        return int(self.actuators.shape[0])

    @property
    def kind(self) -> str:
        """``"poses"`` or ``"points"``."""
        return "poses" if self.poses is not None else "points"

    def pose_array(self) -> np.ndarray:
        """The measured target poses (N, 6) in the instrument frame (m, rad).

        Raises:
            InputError: point measurements (no poses).
        """
        if self.poses is None:
            raise InputError("poses", None, "point measurements have no poses")
        return self.poses

    def point_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """The measured target points (N, M, 3) in the instrument frame and their
        coordinates (M, 3) in the target frame (m).

        Raises:
            InputError: pose measurements (no points), or points without target points.
        """
        if self.points is None or self.target_points is None:
            raise InputError("points", None, "pose measurements have no points")
        return self.points, self.target_points

    @classmethod
    def checked(cls, actuators: npt.ArrayLike | None, poses: npt.ArrayLike | None = None,
                points: npt.ArrayLike | None = None,
                target_points: npt.ArrayLike | None = None) -> Measurements:
        """Measurements from raw arrays.

        Args:
            actuators: readings (N, 6) (m); required (None is refused).
            poses: measured target poses (N, 6) in the instrument frame (m, rad), or None.
            points: measured target points (N, M, 3) in the instrument frame (m), or None.
            target_points: the points in the target frame (M, 3) (m), with ``points``.

        Raises:
            InputError: no readings, wrong shapes or non-finite values, both or neither
                of ``poses`` and ``points``, ``points`` without ``target_points`` (or with
                another number of points), more than three points, a count differing between
                the readings and the measurements, or no measurement.
        """
        if actuators is None:
            raise InputError("actuators", None, "the actuator readings (N, 6) are required")
        q = as_array(actuators, (6,), "actuators", batch=True)
        if q.shape[0] == 0:
            raise InputError("actuators", actuators, "no measurement")
        if (poses is None) == (points is None):
            raise InputError("poses", poses, "give either poses or points (not both)")
        if poses is not None:
            poses = as_array(poses, (6,), "poses", batch=True)
            if poses.shape[0] != q.shape[0]:
                raise InputError("poses", poses.shape, f"{poses.shape[0]} poses for "
                                 f"{q.shape[0]} actuator readings")
            if target_points is not None:
                raise InputError("target_points", target_points, "only with points")
            return cls(q, poses=poses)
        if target_points is None:
            raise InputError("target_points", None, "points need the target points (M, 3)")
        tp = as_array(target_points, (3,), "target_points", batch=True)
        if not 1 <= tp.shape[0] <= 3:
            raise InputError("target_points", tp.shape, "one to three points")
        pts = np.asarray(points, dtype=float) if not isinstance(points, np.ndarray) else points
        pts = as_array(pts.reshape(pts.shape[0], -1) if pts.ndim == 3 else pts,
                       (3 * tp.shape[0],), "points", batch=True).reshape(-1, tp.shape[0], 3)
        if pts.shape[0] != q.shape[0]:
            raise InputError("points", pts.shape, f"{pts.shape[0]} measurements for "
                             f"{q.shape[0]} actuator readings")
        return cls(q, points=pts, target_points=tp)


#: default measurement noise (standard deviations): target position (m), target
#: orientation (rad), actuator readings (m)
DEFAULT_NOISE = (1e-5, 2e-5, 1e-6)


def check_noise(noise: npt.ArrayLike) -> tuple[float, float, float]:
    """``noise`` as three standard deviations (position m, rotation rad, readings m).

    Raises:
        InputError: not three finite numbers >= 0 with a positive position or reading one.
    """
    values = as_array(noise, (3,), "noise")
    if np.any(values < 0.0) or not (values[0] > 0.0 or values[2] > 0.0):
        raise InputError("noise", noise, "expected three standard deviations >= 0 "
                         "(position m, rotation rad, readings m), position or readings > 0")
    return float(values[0]), float(values[1]), float(values[2])


class Problem:
    """Weighted residuals and their Jacobian over the 66 parameters.

    Pose measurements: each closure residual ``e_i`` is divided by its standard deviation
    under the measurement noise (:func:`~.model.closure_noise`, evaluated once at the
    start model so that the weights are constants), so that residuals of poses where a
    pose error moves a reading much (legs nearly perpendicular to their lines) count
    less. Point measurements: the point errors divided by the position noise.

    Args:
        params: the parameter model.
        data: the measurements.
        start_poses: for point measurements, world platform poses (N, 6) where the
            forward kinematics starts (e.g. the nominal robot's forward kinematics).
        noise: standard deviations (position m, rotation rad, readings m); only their
            ratios change the estimates.

    Attributes:
        weights: per residual (rows,), 1 / standard deviation (1/m).

    Raises:
        InputError: bad ``noise``, point measurements without ``start_poses``, or a
            measured pose where a leg of the start model is perpendicular to its line.
    """

    def __init__(self, params: ParameterModel, data: Measurements,
                 start_poses: np.ndarray | None = None,
                 noise: npt.ArrayLike = DEFAULT_NOISE):
        self.params = params
        self.data = data
        self.points: PointModel | None = None
        noise = check_noise(noise)
        if data.poses is None:                               # point measurements
            points, target_points = data.point_arrays()
            if start_poses is None:
                raise InputError("start_poses", None, "point measurements need the poses "
                                 "(N, 6) where the forward kinematics starts")
            self.points = PointModel(params, points, target_points, data.actuators,
                                     start_poses)
            self.weights = np.full(points.size, 1.0 / max(noise[0], 1e-300))
        else:
            sigma = closure_noise(params, np.zeros(N_PARAMETERS), data.poses, data.actuators,
                                  noise)
            if not np.all(np.isfinite(sigma) & (sigma > 0.0)):
                row = int(np.argwhere(~(np.isfinite(sigma) & (sigma > 0.0)))[0, 0])
                raise InputError("poses", data.poses[row], f"measurement {row}: a leg of the "
                                 "start model is perpendicular to its line there (or the "
                                 "noise is zero)")
            self.weights = 1.0 / sigma.ravel()
        self._theta: np.ndarray | None = None
        self._value: tuple[np.ndarray, np.ndarray] | None = None

    def evaluate(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Weighted residual vector (rows,) (dimensionless: standard deviations) and its
        Jacobian (rows, 66) at ``theta`` (the last evaluation is kept: least squares asks
        for both at the same point)."""
        if (self._theta is not None and self._value is not None
                and np.array_equal(theta, self._theta)):
            return self._value
        if self.points is None:
            res, jac = pose_residuals(self.params, theta, self.data.pose_array(),
                                      self.data.actuators)
        else:
            res, jac = self.points.residuals(theta)
        self._theta = theta.copy()
        self._value = (res.ravel() * self.weights, jac * self.weights[:, None])
        return self._value


def reference_poses(robot: Hexapod, count: int = 60, seed: int = 0, scale: float = 1.0) -> np.ndarray:
    """World platform poses (n <= count, 6) spread about the robot's home pose: uniform
    within ``scale * REFERENCE_TRANSLATION * platform_radius`` (m) and ``scale *
    REFERENCE_ROTATION`` (rad) per coordinate (a fixed seed), kept when reachable, within
    the strokes and with every leg at least ``acos(REFERENCE_MIN_COS)`` away from
    perpendicular to its line (a pose error moves the readings at most ``1 /
    REFERENCE_MIN_COS`` times as much).

    Raises:
        ArgumentTypeError: ``robot`` is not a :class:`~hexapod_pin.Hexapod`.
        InputError: ``count`` not an integer >= 1, ``seed`` not one >= 0, ``scale`` not a
            real number > 0.
    """
    robot = of_type(robot, Hexapod, "robot")
    count = check_count(count, "count")
    rng = generator(seed)
    scale = real_number(scale, "scale", minimum=0.0)
    half = scale * np.r_[np.full(3, REFERENCE_TRANSLATION * robot.geometry.platform_radius),
                         np.full(3, REFERENCE_ROTATION)]
    poses = robot.home_pose + rng.uniform(-1.0, 1.0, size=(count, 6)) * half
    batch = robot.inverse_kinematics_batch(poses)
    poses = poses[batch.ok]
    chains = robot.geometry.chain_geometry
    legs, _ = chains.legs(rotation_from_rpy(poses[:, 3:]), poses[:, :3],
                          batch.actuator_positions[batch.ok])
    cosine = np.abs(np.einsum("nia,ia->ni", legs, chains.line_directions)) / chains.leg_lengths
    return poses[np.min(cosine, axis=1) >= REFERENCE_MIN_COS]


def reference_measurements(robot: Hexapod, params: ParameterModel, kind: str,
                           target_points: np.ndarray | None,
                           count: int = 60) -> tuple[Measurements, np.ndarray]:
    """Exact measurements of the start model at :func:`reference_poses`, as the
    measurement model ``kind`` sees them, and the world poses used."""
    world = reference_poses(robot, count)
    q = robot.inverse_kinematics_batch(world).actuator_positions
    frames = params.frames(np.zeros(N_PARAMETERS))
    rot = rotation_from_rpy(world[:, 3:])
    if kind == "poses":
        return Measurements(q, poses=measured_poses(rot, world[:, :3], frames)), world
    if target_points is None:
        raise InputError("target_points", None, "point measurements need the target points")
    model = PointModel(params, np.zeros((len(world),) + target_points.shape), target_points,
                       q, world)
    pred, _, _ = model.predicted(np.zeros(N_PARAMETERS), world)
    return Measurements(q, points=pred, target_points=target_points), world

"""What a calibration gives: the estimates with their standard errors, the residual
summaries, the identified robots, and the validation of a model on held-out measurements.

Frames (:mod:`.model`): the robot's world ``W``, the platform ``P``, the instrument ``I``
and the target ``T``. A robot "commanded in the measurement frames" has its lines expressed
in ``I`` and its platform joints in ``T`` (:func:`measurement_chains`): its inverse
kinematics takes the target's pose measured in ``I``.

Validation errors: the readings predicted by the inverse kinematics of each measured pose
against the measured readings (m), and the target pose (or points) predicted by the
forward kinematics of the readings (started at the measured pose, or at home for points)
against the measured one (distance m, rotation angle rad).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

from ..core.pose import rotation_from_rpy
from ..errors import AssemblyError, InputError
from ..hexapod.geometry import ChainGeometry, HexapodGeometry
from ..hexapod.robot import Hexapod
from .identifiability import IdentifiabilityReport
from .parameters import Frames
from .problem import Measurements


@dataclass(frozen=True)
class ParameterEstimate:
    """One parameter of the calibration.

    Attributes:
        name: e.g. ``chain2.sensor_offset``.
        unit: ``m`` or ``rad``.
        group: its parameter group.
        deviation: identified value minus the start value (m or rad).
        std_error: its standard error (m or rad); None when not in the base set (held at
            the start value).
        identified: whether it is in the base set.
    """

    name: str
    unit: str
    group: str
    deviation: float
    std_error: float | None
    identified: bool


@dataclass(frozen=True)
class ResidualSummary:
    """Residuals of the measurement model (m: closure residuals in actuator units for
    poses, point errors for points).

    Attributes:
        rms: root mean square (m).
        max: largest absolute value (m).
        count: number of residuals.
        normalized_rms: RMS of the residuals divided by their standard deviations under
            the noise model (about 1 at the solution when the noise model is right).
    """

    rms: float
    max: float
    count: int
    normalized_rms: float

    @classmethod
    def of(cls, weighted: np.ndarray, weights: np.ndarray) -> ResidualSummary:
        """The summary of a weighted residual vector and its weights."""
        res = weighted / weights
        return cls(float(np.sqrt(np.mean(res ** 2))), float(np.max(np.abs(res))), res.size,
                   float(np.sqrt(np.mean(weighted ** 2))))


@dataclass(frozen=True)
class ModelErrors:
    """Errors of one model on validation measurements.

    Attributes:
        actuator_errors: predicted minus measured readings (n_ik, 6) (m), the predicted
            ones from the inverse kinematics of the measured pose (poses only; else None),
            at the rows ``ik_rows`` the model reaches.
        ik_rows: the measurement rows of ``actuator_errors`` (n_ik,) (poses only).
        position_errors: distance (n_fk,) (m) between the measured and the predicted target
            origin (poses) or the largest distance over the target points (points), the
            prediction being the forward kinematics of the readings, at the rows
            ``fk_rows`` where it assembles.
        rotation_errors: angle (n_fk,) (rad) between measured and predicted target
            orientation (poses only; else None).
        fk_rows: the measurement rows of ``position_errors`` (n_fk,).
        count: number of measurements.
    """

    actuator_errors: np.ndarray | None
    ik_rows: np.ndarray | None
    position_errors: np.ndarray
    rotation_errors: np.ndarray | None
    fk_rows: np.ndarray
    count: int

    def summary(self) -> dict[str, float]:
        """RMS and maximum of each error (m, rad), and how many rows each model could not
        reach (``ik_failures``) or assemble (``fk_failures``)."""
        out: dict[str, float] = {}
        for key, arr in (("actuator", self.actuator_errors), ("position", self.position_errors),
                         ("rotation", self.rotation_errors)):
            if arr is not None and arr.size:
                out[f"{key}_rms"] = float(np.sqrt(np.mean(arr ** 2)))
                out[f"{key}_max"] = float(np.max(np.abs(arr)))
        if self.ik_rows is not None:
            out["ik_failures"] = self.count - self.ik_rows.size
        out["fk_failures"] = self.count - self.fk_rows.size
        return out


@dataclass(frozen=True)
class ValidationReport:
    """Errors of the nominal and of the identified model on validation measurements.

    Attributes:
        nominal: errors of the start model (the nominal chains seen through the guessed
            frames, the instrument's registered by default): what the robot does before
            calibration with a registered instrument.
        identified: errors of the identified model (``CalibrationResult.robot``).
    """

    nominal: ModelErrors
    identified: ModelErrors


@dataclass(frozen=True)
class CalibrationResult:
    """The identified geometry and how well it is known.

    Frames: the identification works in the robot's world and platform frames; the
    measurements are poses of the target frame in the instrument frame.

    Attributes:
        robot: a :class:`Hexapod` COMMANDED IN THE MEASUREMENT FRAMES: its lines are
            expressed in the instrument frame and its platform joints in the target frame,
            so ``robot.inverse_kinematics(measured_pose)`` gives the readings that reach a
            pose measured by the instrument, and its forward kinematics gives the target's
            pose in the instrument frame. Kinematics only: its dynamics take gravity along
            the instrument's -z and the platform's centre of mass at the target origin,
            which is physical only when both frames coincide with the robot's; use
            :attr:`geometry` for dynamics.
        geometry: the identified :class:`HexapodGeometry` in the robot's world and
            platform frames (nominal masses and inertias; gravity along its -z). Where the
            instrument or target frame trades with the lines or joints (see
            ``identifiability``), those frames are held at their guesses and the robot's
            frames are defined through them.
        chains: ``geometry.chains``.
        instrument: identified pose of the instrument frame in the world (6,) (m, rad).
        target: identified pose of the target frame in the platform frame (6,) (m, rad).
        parameters: every requested parameter (:class:`ParameterEstimate`).
        covariance: covariance of the base parameters (n, n), order of ``identifiability.base``
            (m, rad).
        residuals_before: :class:`ResidualSummary` at the start.
        residuals_after: :class:`ResidualSummary` at the solution.
        identifiability: what the data identify
            (:class:`~hexapod_pin.calibration.identifiability.IdentifiabilityReport`).
        iterations: function evaluations of the least squares.
        status: scipy's ``least_squares`` status.
        message: scipy's ``least_squares`` message.
        measurement: ``"poses"`` or ``"points"``.
        target_points: the points in the target frame (M, 3) (m), or None (poses).
        nominal_geometry: the start model in the measurement frames (the geometry of
            :attr:`nominal_robot`).
    """

    robot: Hexapod
    geometry: HexapodGeometry
    chains: ChainGeometry
    instrument: np.ndarray
    target: np.ndarray
    parameters: tuple[ParameterEstimate, ...]
    covariance: np.ndarray
    residuals_before: ResidualSummary
    residuals_after: ResidualSummary
    identifiability: IdentifiabilityReport
    iterations: int
    status: int
    message: str
    measurement: str
    target_points: np.ndarray | None = None
    nominal_geometry: HexapodGeometry | None = field(default=None, repr=False)

    @cached_property
    def nominal_robot(self) -> Hexapod:
        """The start model commanded in the measurement frames (as :attr:`robot`), built
        on first use."""
        return Hexapod(self.nominal_geometry)

    def estimates(self) -> dict[str, float]:
        """Deviation of every requested parameter by name (m, rad)."""
        return {p.name: p.deviation for p in self.parameters}

    def standard_errors(self) -> dict[str, float]:
        """Standard error of every base parameter by name (m, rad)."""
        return {p.name: p.std_error for p in self.parameters if p.std_error is not None}

    def validate(self, poses: npt.ArrayLike | None = None, actuators: npt.ArrayLike | None = None, *,
                 points: npt.ArrayLike | None = None) -> ValidationReport:
        """Errors of the nominal and of the identified model on held-out measurements
        (same kind as the calibration's).

        Args:
            poses: measured target poses (N, 6) in the instrument frame (m, rad).
            actuators: the readings (N, 6) (m).
            points: for point calibrations, measured points (N, M, 3) instead of poses.

        Returns:
            :class:`ValidationReport`: per model the readings predicted for the measured
            poses (inverse kinematics), and the poses (or points) predicted for the
            readings (forward kinematics started at the measured pose, or at the
            nominal prediction for points) against the measurements.

        Raises:
            InputError: malformed measurements, or another kind than the calibration's.
        """
        data = Measurements.checked(actuators, poses, points, self.target_points
                                    if points is not None else None)
        if data.kind != self.measurement:
            raise InputError("validate", data.kind,
                             f"the calibration used {self.measurement}, not {data.kind}")
        return ValidationReport(model_errors(self.nominal_robot, data),
                                model_errors(self.robot, data))


def model_errors(robot: Hexapod, data: Measurements) -> ModelErrors:
    """Errors of a robot commanded in the measurement frames on measurements ``data``
    (rows it cannot reach or assemble are left out and counted)."""
    guesses = data.poses if data.poses is not None else np.tile(robot.home_pose,
                                                                (data.count, 1))
    fk_rows, predicted = [], []
    for k, (q, guess) in enumerate(zip(data.actuators, guesses)):
        try:
            predicted.append(robot.forward_kinematics(q, guess=guess))
        except AssemblyError:
            continue
        fk_rows.append(k)
    rows = np.array(fk_rows, dtype=int)
    pred = np.array(predicted).reshape(-1, 6)
    rot = rotation_from_rpy(pred[:, 3:])
    if data.poses is None:                                   # point measurements
        points, target_points = data.point_arrays()
        pts = pred[:, None, :3] + np.einsum("nab,mb->nma", rot, target_points)
        dist = np.max(np.linalg.norm(pts - points[rows], axis=2), axis=1)
        return ModelErrors(None, None, dist, None, rows, data.count)
    poses = data.poses
    batch = robot.inverse_kinematics_batch(poses)
    ik_rows = np.flatnonzero(batch.reachable)
    pos = np.linalg.norm(pred[:, :3] - poses[rows, :3], axis=1)
    rel = np.swapaxes(rot, 1, 2) @ rotation_from_rpy(poses[rows, 3:])
    angle = Rotation.from_matrix(rel).magnitude() if rows.size else np.empty(0)
    return ModelErrors(batch.actuator_positions[ik_rows] - data.actuators[ik_rows], ik_rows,
                       pos, angle, rows, data.count)


def measurement_chains(chains: ChainGeometry, frames: Frames) -> ChainGeometry:
    """The chains expressed in the instrument frame (lines) and in the target frame
    (platform joints): the geometry of a robot commanded in the measurement frames."""
    ri, ti = frames.instrument_rotation, frames.instrument_translation
    rt, tt = frames.target_rotation, frames.target_translation
    return ChainGeometry(line_points=(chains.line_points - ti) @ ri,
                         line_directions=chains.line_directions @ ri,
                         sensor_offsets=chains.sensor_offsets,
                         leg_lengths=chains.leg_lengths,
                         platform_joints=(chains.platform_joints - tt) @ rt)

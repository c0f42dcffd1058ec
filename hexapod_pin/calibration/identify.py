"""Kinematic calibration: identify the as-built geometry from measurements.

:func:`calibrate` fits the deviations of :mod:`.parameters` (per-chain lines, sensor
zeros, leg lengths, platform joints; the instrument and target frames) to measured target
poses or points and the actuator readings, by nonlinear least squares
(``scipy.optimize.least_squares``) with the analytic identification Jacobian of
:mod:`.model`, on the base parameter set of :mod:`.identifiability`.

Statistics: with ``m`` residuals, ``n`` base parameters and the residual vector ``r`` at
the solution, ``s^2 = |r|^2 / (m - n)`` and the covariance of the base parameters is
``s^2 (J^T J)^-1`` (``J`` the unscaled Jacobian of the base columns); the standard errors
are the square roots of its diagonal (m or rad). They assume independent residuals of
equal variance.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ..core.pose import rotation_from_rpy
from ..errors import AssemblyError, InputError, SolverError
from ..hexapod.geometry import ChainGeometry, HexapodGeometry
from ..hexapod.robot import Hexapod
from . import identifiability as ident
from .parameters import (
    DEFAULT_IDENTIFY,
    N_PARAMETERS,
    NAMES,
    PARAMETER_GROUPS,
    UNITS,
    Frames,
    ParameterModel,
    parameter_indices,
)
from .problem import DEFAULT_NOISE, Measurements, Problem, reference_measurements
from .registration import register_instrument

#: least-squares tolerances (scipy's ftol, xtol, gtol)
TOLERANCE = 1e-15


@dataclass(frozen=True)
class ParameterEstimate:
    """One parameter of the calibration.

    Attributes:
        name: e.g. ``chain2.sensor_offset``; unit: ``m`` or ``rad``; group: its group.
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
        rms: root mean square; max: largest absolute value; count: number of residuals.
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
        chains: ``geometry.chains``; instrument: identified pose of the instrument frame
            in the world (6,); target: identified pose of the target frame in the platform
            frame (6,) (m, rad).
        parameters: every requested parameter (:class:`ParameterEstimate`).
        covariance: covariance of the base parameters (n, n), order of ``identifiability.base``
            (m, rad).
        residuals_before, residuals_after: :class:`ResidualSummary` at the start and at
            the solution.
        identifiability: what the data identify
            (:class:`~hexapod_pin.calibration.identifiability.IdentifiabilityReport`).
        iterations: function evaluations of the least squares; status, message: scipy's.
        measurement: ``"poses"`` or ``"points"``; target_points: (M, 3) or None.
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
    identifiability: ident.IdentifiabilityReport
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

    def validate(self, poses=None, actuators=None, *, points=None) -> ValidationReport:
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
    guesses = data.poses if data.kind == "poses" else np.tile(robot.home_pose, (data.count, 1))
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
    if data.kind == "points":
        pts = pred[:, None, :3] + np.einsum("nab,mb->nma", rot, data.target_points)
        dist = np.max(np.linalg.norm(pts - data.points[rows], axis=2), axis=1)
        return ModelErrors(None, None, dist, None, rows, data.count)
    batch = robot.inverse_kinematics_batch(data.poses)
    ik_rows = np.flatnonzero(batch.reachable)
    pos = np.linalg.norm(pred[:, :3] - data.poses[rows, :3], axis=1)
    rel = np.swapaxes(rot, 1, 2) @ rotation_from_rpy(data.poses[rows, 3:])
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


def calibrate(robot: Hexapod, poses=None, actuators=None, *, points=None,
              target_points=None, identify: Sequence[str] | str = DEFAULT_IDENTIFY,
              instrument=None, target=None, noise=DEFAULT_NOISE,
              rcond: float = ident.RCOND, method: str = "lm",
              max_nfev: int = 200) -> CalibrationResult:
    """Identify the as-built geometry of ``robot`` from measurements.

    Args:
        robot: the nominal robot (its geometry is the start; ideal or as built).
        poses: measured poses (N, 6) of the target frame in the instrument frame
            (m, rad), or None with ``points``.
        actuators: the actuator readings at the measurements (N, 6) (m).
        points: measured positions (N, M, 3) of ``M`` = 1..3 target points in the
            instrument frame (m), instead of poses.
        target_points: the points' coordinates in the target frame (M, 3) (m).
        identify: parameter groups to identify (:data:`~.parameters.GROUPS`, ``"chains"``
            for all five chain groups); the others stay at their start values.
        instrument: guessed pose of the instrument frame in the robot's world (6,);
            default a rigid registration of the measurements onto the nominal forward
            kinematics of the readings
            (:func:`~hexapod_pin.calibration.registration.register_instrument`). When the
            instrument frame is not in the base set (it trades with the lines), the lines
            are identified in this guessed frame.
        target: guessed pose of the target frame in the platform frame (6,); default the
            platform frame.
        noise: standard deviations of the measurement noise (target position m, target
            orientation rad, readings m) that weight the residuals (see
            :class:`~.problem.Problem`); only their ratios change the estimates.
        rcond: relative singular-value threshold of the rank tests.
        method: ``"lm"`` (Levenberg-Marquardt) or ``"trf"`` (trust region).
        max_nfev: function evaluations at most.

    Returns:
        :class:`CalibrationResult`.

    Raises:
        InputError: not a Hexapod, malformed measurements or options.
        IdentifiabilityError: the measurements do not determine the base parameter set.
        SolverError: the least squares stops without converging (or see :func:`solve`).
        AssemblyError: (points) a forward kinematics fails on the current estimate.
        GeometryError: the identified geometry's home pose does not assemble (the
            as-built home is found by Newton from the ideal home pose).
    """
    if not isinstance(robot, Hexapod):
        raise InputError("robot", type(robot).__name__, "expected a Hexapod")
    if method not in ("lm", "trf"):
        raise InputError("method", method, "expected 'lm' or 'trf'")
    if not (isinstance(rcond, float) and 0.0 < rcond < 1.0):
        raise InputError("rcond", rcond, "expected a float in (0, 1)")
    data = Measurements.checked(actuators, poses, points, target_points)
    if instrument is None:
        instrument = register_instrument(robot, data, target)
    params = ParameterModel(robot.geometry.chain_geometry, instrument, target)
    columns = parameter_indices(identify)
    scales = params.scales
    base, structural = base_set(robot, params, columns, data.kind, data.target_points, rcond)
    starts = _world_of(robot, data) if data.kind == "points" else None
    problem = Problem(params, data, starts, noise)
    theta0 = np.zeros(N_PARAMETERS)
    res0, jac0 = problem.evaluate(theta0)
    base_sigma = ident.check_data(jac0 * scales, base, rcond, data.count, data.poses)
    sigma = np.linalg.svd((jac0 * scales)[:, columns], compute_uv=False)

    theta, cov, fit = solve(problem, base, scales, method, max_nfev, rcond)
    res, _ = problem.evaluate(theta)
    std = np.sqrt(np.diag(cov))
    where = {int(c): k for k, c in enumerate(base)}
    estimates = tuple(
        ParameterEstimate(NAMES[c], UNITS[c], PARAMETER_GROUPS[c], float(theta[c]),
                          None if int(c) not in where else float(std[where[int(c)]]),
                          int(c) in where) for c in columns)
    report = ident.IdentifiabilityReport(
        requested=tuple(NAMES[c] for c in columns), singular_values=sigma,
        rank=ident.numerical_rank(sigma, rcond), base=tuple(NAMES[c] for c in base),
        fixed=tuple(NAMES[c] for c in columns if int(c) not in where),
        unidentifiable=tuple(structural), base_singular_values=base_sigma,
        condition_number=float(base_sigma[0] / base_sigma[-1]), rcond=rcond)
    chains, frames = params.chains(theta), params.frames(theta)
    inst, targ = params.frame_poses(theta)
    nominal = measurement_chains(params.start, params.frames(np.zeros(N_PARAMETERS)))
    return CalibrationResult(
        robot=Hexapod(robot.geometry.with_chains(measurement_chains(chains, frames))),
        geometry=robot.geometry.with_chains(chains), chains=chains, instrument=inst,
        target=targ, parameters=estimates, covariance=cov,
        residuals_before=ResidualSummary.of(res0, problem.weights),
        residuals_after=ResidualSummary.of(res, problem.weights),
        identifiability=report, iterations=int(fit.nfev), status=int(fit.status),
        message=str(fit.message), measurement=data.kind, target_points=data.target_points,
        nominal_geometry=robot.geometry.with_chains(nominal))


def solve(problem: Problem, base: np.ndarray, scales: np.ndarray, method: str,
          max_nfev: int, rcond: float = ident.RCOND):
    """Least squares over the base parameters (scaled), from the start model.

    Returns:
        the deviations ``theta`` (66,), the covariance (n, n) of the base parameters
        (``s^2 (J^T J)^-1``, see the module doc) and scipy's result.

    Raises:
        SolverError: no convergence, a non-finite residual, or a base Jacobian that lost
            rank at the solution.
    """
    def theta_of(x: np.ndarray) -> np.ndarray:
        theta = np.zeros(N_PARAMETERS)
        theta[base] = x * scales[base]
        return theta

    fit = least_squares(lambda x: problem.evaluate(theta_of(x))[0], np.zeros(base.size),
                        jac=lambda x: problem.evaluate(theta_of(x))[1][:, base] * scales[base],
                        method=method, ftol=TOLERANCE, xtol=TOLERANCE, gtol=TOLERANCE,
                        max_nfev=max_nfev)
    if fit.status <= 0:
        raise SolverError("least_squares", str(fit.status), fit.message)
    theta = theta_of(fit.x)
    res, jac = problem.evaluate(theta)
    if not np.all(np.isfinite(res)):
        raise SolverError("least_squares", "non-finite", "residuals not finite at the solution")
    sigma = np.linalg.svd(jac[:, base] * scales[base], compute_uv=False)
    if ident.numerical_rank(sigma, rcond) < base.size:
        raise SolverError("least_squares", "rank lost",
                          "the base parameters are not determined at the solution")
    normal = jac[:, base].T @ jac[:, base]
    cov = float(res @ res) / (res.size - base.size) * np.linalg.inv(normal)
    return theta, cov, fit


def base_set(robot: Hexapod, params: ParameterModel, columns: np.ndarray, kind: str,
             target_points: np.ndarray | None, rcond: float) -> tuple[np.ndarray, list[str]]:
    """The base set among ``columns`` and the structural combinations in words, judged on
    the reference poses (:func:`~.problem.reference_measurements`) of the start model."""
    ref_data, ref_world = reference_measurements(robot, params, kind, target_points)
    _, ref_jac = Problem(params, ref_data, ref_world).evaluate(np.zeros(N_PARAMETERS))
    ref_scaled = ref_jac * params.scales
    base = ident.base_columns(ref_scaled, columns)
    null = ident.null_space(ref_scaled, columns, rcond)
    return base, ident.structural_text(null, columns, kind == "points")


def _world_of(robot: Hexapod, data: Measurements) -> np.ndarray:
    """World platform poses of the nominal robot for the readings (forward kinematics from
    home): where the point model's forward kinematics starts."""
    return np.array([robot.forward_kinematics(q) for q in data.actuators])

"""Kinematic calibration: identify the as-built geometry from measurements.

:func:`calibrate` fits the deviations of :mod:`.parameters` (per-chain lines, sensor
zeros, leg lengths, platform joints; the instrument and target frames) to measured target
poses or points and the actuator readings, by nonlinear least squares
(``scipy.optimize.least_squares``) with the analytic identification Jacobian of
:mod:`.model`, on the base parameter set of :mod:`.identifiability`; the result types are
those of :mod:`.results`.

Statistics: with ``m`` residuals, ``n`` base parameters and the residual vector ``r`` at
the solution, ``s^2 = |r|^2 / (m - n)`` and the covariance of the base parameters is
``s^2 (J^T J)^-1`` (``J`` the unscaled Jacobian of the base columns); the standard errors
are the square roots of its diagonal (m or rad). They assume independent residuals of
equal variance.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
from scipy.optimize import OptimizeResult, least_squares

from ..core.checks import as_array, count
from ..errors import InputError, SolverError
from ..hexapod.robot import Hexapod
from . import identifiability as ident
from .parameters import (
    DEFAULT_IDENTIFY,
    N_PARAMETERS,
    NAMES,
    PARAMETER_GROUPS,
    UNITS,
    ParameterModel,
    parameter_indices,
)
from .problem import DEFAULT_NOISE, Measurements, Problem, reference_measurements
from .registration import register_instrument
from .results import CalibrationResult, ParameterEstimate, ResidualSummary, measurement_chains

#: least-squares tolerances (scipy's ftol, xtol, gtol)
TOLERANCE = 1e-15


def calibrate(robot: Hexapod, poses: npt.ArrayLike | None = None, actuators: npt.ArrayLike | None = None, *,
              points: npt.ArrayLike | None = None, target_points: npt.ArrayLike | None = None,
              identify: Sequence[str] | str = DEFAULT_IDENTIFY,
              instrument: npt.ArrayLike | None = None, target: npt.ArrayLike | None = None,
              noise: npt.ArrayLike = DEFAULT_NOISE,
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
        InputError: not a Hexapod, malformed measurements or options (``instrument`` and
            ``target`` 6 finite numbers or None, ``identify`` group names, ``max_nfev`` an
            integer >= 1, ``rcond`` a float in (0, 1), ``method`` "lm" or "trf"), each
            naming the argument.
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
    max_nfev = count(max_nfev, "max_nfev", minimum=1)
    instrument = None if instrument is None else as_array(instrument, (6,), "instrument")
    target = None if target is None else as_array(target, (6,), "target")
    parameter_indices(identify)               # the groups checked before any computation
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
          max_nfev: int,
          rcond: float = ident.RCOND) -> tuple[np.ndarray, np.ndarray, OptimizeResult]:
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

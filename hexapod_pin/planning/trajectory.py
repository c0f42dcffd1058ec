"""Time-optimal motion along a path within the closed-loop limits: :func:`time_optimal`.

The path through the waypoints (:class:`~hexapod_pin.planning.path.GeometricPath`) is
sampled at a uniform grid of its parameter ``s`` (m); the limits become rows affine in
``(s_ddot, s_dot^2)`` from the robot's own batch inverse dynamics
(:mod:`hexapod_pin.planning.limits`); TOPP-RA (:mod:`hexapod_pin.planning.solver`) finds
the fastest ``s_dot(s)``; the timing follows from ``dt = 2 ds / (s_dot_k + s_dot_{k+1})``
(constant ``s_ddot`` on each segment).

Drive effects (``robot.effects``): armature and springs enter the coefficients exactly;
Coulomb friction is a constant ``f(s)`` while the path moves forward; viscous damping
is linear in ``s_dot``, and TOPP-RA's rows are affine in ``x = s_dot^2``, so its term is
linearised conservatively at a speed per grid point (:mod:`hexapod_pin.planning.limits`).
The planner starts from the profile without the damping term, then re-linearises at
the last profile's speeds until the duration changes by less than
:data:`DAMPING_RTOL` (at most :data:`DAMPING_ITERATIONS` solves; a linearisation that
closes the phase plane is retried at half the speeds). Every profile of these rows meets
the true limits; the result is then verified: the forces recomputed by the robot's own
``inverse_dynamics_batch`` (effects included) at every grid point must equal the planned
ones and keep the force bounds (else the bounds are tightened by the excess and the
plan repeated, at most :data:`VERIFY_ATTEMPTS` times, then
:class:`~hexapod_pin.errors.SolverError`).

A :class:`TimedTrajectory` holds the result at the grid points (``s_ddot`` of the
segment that starts there; the last point takes the last segment's) in the robot's
conventions (pose, twist ``(v, w)`` in world axes, ``twist_dot`` its plain derivative,
actuator forces along each actuator's positive direction) and samples the same motion at
any time (:meth:`TimedTrajectory.sample`, :meth:`TimedTrajectory.resample`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..core.robot_api import ParallelRobot, parallel_robot, pose_layout
from ..core.checks import count, of_type, real_array, real_number, within_magnitude
from ..errors import InfeasiblePathError, InputError, SolverError
from . import solver
from .limits import Limits, PathCoefficients, Payload, constraint_rows, path_coefficients
from .path import GeometricPath, PathSamples

#: default number of grid points
DEFAULT_GRID_POINTS = 1000
#: the most samples :meth:`TimedTrajectory.resample` makes
MAX_SAMPLES = 1e8
#: relative change of the duration at which the damping linearisation stops
DAMPING_RTOL = 1e-4
#: the most TOPP-RA solves of the damping linearisation
DAMPING_ITERATIONS = 30
#: the most plans with tightened bounds when the verification finds an excess
VERIFY_ATTEMPTS = 3
#: relative tolerance of the verification: planned against recomputed forces (of the
#: force scale), recomputed forces against their bounds
VERIFY_RTOL = 1e-7


@dataclass(frozen=True)
class PhaseProfile:
    """The solution in the phase plane ``(s, s_dot)`` at the grid points.

    Attributes:
        s: (N,) grid (m).
        s_dot: (N,) path speed (m/s).
        s_ddot: (N - 1,) path acceleration on each segment (m/s^2).
        controllable: (N, 2) the controllable set ``[lo, hi]`` of ``s_dot^2`` (m^2/s^2).
        max_velocity_curve: (N,) the largest ``s_dot^2`` any path acceleration allows at
            each grid point on its own (``inf`` where nothing bounds it).
    """

    s: np.ndarray
    s_dot: np.ndarray
    s_ddot: np.ndarray
    controllable: np.ndarray
    max_velocity_curve: np.ndarray


@dataclass(frozen=True, eq=False)
class TimedTrajectory:
    """A timed motion of the platform (N samples), in the robot's conventions.

    Attributes:
        t: (N,) times (s) from 0.
        poses: (N, dim) platform poses (m, rad), the robot's ``pose_axes``.
        twists: (N, dim) twists, the same selection of ``(v, w)``, world axes (m/s,
            rad/s).
        twist_dots: (N, dim) their time derivatives (m/s^2, rad/s^2).
        actuator_forces: (N, n_act) (N or N m), the payload and the drive effects
            included: the robot's inverse dynamics at each sample (at a sample where the
            path is at rest, Coulomb friction as inverse dynamics gives it to a joint that
            accelerates, ``-coulomb sign(a)``).
        actuator_velocities: (N, n_act) (m/s or rad/s).
        actuator_positions: (N, n_act) (m or rad).
        s: (N,) path parameter (m).
        s_dot: (N,) path speed (m/s).
        s_ddot: (N,) path acceleration (m/s^2).
        path: the :class:`GeometricPath`.
        phase: the :class:`PhaseProfile` of the solution (grid points).
        robot: the robot it was planned for.
        limits: the limits it was planned with.
        payload: the payload it was planned with.
    """

    t: np.ndarray
    poses: np.ndarray
    twists: np.ndarray
    twist_dots: np.ndarray
    actuator_forces: np.ndarray
    actuator_velocities: np.ndarray
    actuator_positions: np.ndarray
    s: np.ndarray
    s_dot: np.ndarray
    s_ddot: np.ndarray
    path: GeometricPath
    phase: PhaseProfile
    robot: ParallelRobot
    limits: Limits
    payload: Payload

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]`` (s)."""
        return float(self.t[-1] - self.t[0])

    def sample(self, times: npt.ArrayLike) -> TimedTrajectory:
        """The same motion at the given times (s), each clipped to ``[0, duration]``.

        Between grid points the path acceleration is that of the segment (a time on a
        grid point takes the segment that starts there); poses, twists and accelerations
        come from the path, the forces from the robot's ``inverse_dynamics_batch``.

        Raises:
            InputError: times that are not real numbers (as
                :func:`~hexapod_pin.core.checks.as_array`) or not one-dimensional.
        """
        times = within_magnitude(real_array(times, "times"), times, "times")
        if times.ndim > 1:
            raise InputError("times", times, f"expected a time or a 1-D array, got shape "
                             f"{times.shape}")
        times = times.ravel()
        grid_t, ph = self.phase_times(), self.phase
        times = np.clip(times, 0.0, grid_t[-1])
        k = np.clip(np.searchsorted(grid_t, times, side="right") - 1, 0, len(grid_t) - 2)
        tau = times - grid_t[k]
        u = ph.s_ddot[k]
        s_dot = np.maximum(ph.s_dot[k] + u * tau, 0.0)
        s = np.minimum(ph.s[k] + ph.s_dot[k] * tau + 0.5 * u * tau ** 2, ph.s[k + 1])
        return _assemble(self.robot, self.path, self.limits, self.payload, self.phase,
                         times, s, s_dot, u)

    def resample(self, rate: float) -> TimedTrajectory:
        """:meth:`sample` at ``rate`` (Hz) from 0 to the duration (both ends included).

        Raises:
            InputError: a rate that is not a real number > 0, or one giving more than
                :data:`MAX_SAMPLES` samples.
        """
        rate = real_number(rate, "rate", minimum=0.0)
        samples = self.duration * rate
        if samples > MAX_SAMPLES:
            raise InputError("rate", rate, f"{samples:.3g} samples over {self.duration:g} s:"
                             f" at most {MAX_SAMPLES:g}")
        return self.sample(np.linspace(0.0, self.duration, max(math.ceil(samples) + 1, 2)))

    def phase_times(self) -> np.ndarray:
        """(N_grid,) the times (s) of the grid points."""
        return _grid_times(self.phase)


def time_optimal(robot: ParallelRobot, waypoints: npt.ArrayLike, *, limits: Limits | None = None,
                 payload: Payload | None = None, start_speed: float = 0.0,
                 end_speed: float = 0.0, grid_points: int = DEFAULT_GRID_POINTS,
                 rotation_length: float | None = None) -> TimedTrajectory:
    """The fastest motion along the path through ``waypoints`` within the limits.

    Args:
        robot: a robot with the shared API (:class:`hexapod_pin.Hexapod`,
            :class:`hexapod_pin.Planar3PRR`, a :class:`hexapod_pin.ClosedLoopRobot` of any
            pose axes), on its home inverse-kinematics branch (that of its batch routes),
            with its drive effects (``robot.effects``: armature, damping, Coulomb
            friction and springs enter the force limits, module docstring).
        waypoints: (K, dim) poses (m, rad), K >= 2, one column per axis of
            ``robot.pose_axes`` in that order; the path is C2 through them
            (:mod:`hexapod_pin.planning.path`: a full rotation on SO(3) when the pose has
            all three angles, each angle as a scalar otherwise).
        limits: :class:`Limits`; default: the robot's actuator force bound only.
        payload: :class:`Payload` carried by the platform; default none.
        start_speed: path speed ``s_dot`` (m/s) at the start; default rest.
        end_speed: path speed ``s_dot`` (m/s) at the end; default rest.
        grid_points: number of grid points N of the path parameter (>= 3).
        rotation_length: length (m) weighting rotations in the path parameter; default
            the robot's characteristic length (its platform radius).

    Returns:
        :class:`TimedTrajectory` at the N grid points.

    Raises:
        InputError: malformed waypoints (a width other than ``robot.pose_dim``, NaN /
            inf: the error names the values), limits or speeds; no finite limit at all.
        InfeasiblePathError: a pose the robot cannot hold statically (or, with Coulomb
            friction, move through slowly) within its force limits, a pose out of reach
            or out of its strokes, a singular pose, an end or start speed the limits do
            not allow; it names the grid point.
        SolverError: the forces recomputed by the robot's inverse dynamics disagree with
            the planned ones, or keep exceeding the bounds (module docstring).
    """
    robot = parallel_robot(robot)
    limits = of_type(Limits() if limits is None else limits, Limits, "limits")
    payload = of_type(Payload() if payload is None else payload, Payload, "payload")
    payload.check(robot.pose_dim)
    grid_points = count(grid_points, "grid_points", minimum=3)
    start_speed = real_number(start_speed, "start_speed", minimum=0.0, strict=False)
    end_speed = real_number(end_speed, "end_speed", minimum=0.0, strict=False)
    if rotation_length is None:
        rotation_length = robot.singularity(robot.home_pose).characteristic_length
    rotation_length = real_number(rotation_length, "rotation_length", minimum=0.0)
    path = GeometricPath(waypoints, rotation_length, pose_layout(robot))
    if path.pose_dim != robot.pose_dim:
        raise InputError("waypoints", waypoints, f"expected poses of {robot.pose_dim} values")
    samples = path.sample(np.linspace(0.0, path.length, int(grid_points)))
    coeffs = path_coefficients(robot, samples, limits, payload)
    at_rest = np.zeros(len(samples.s), dtype=bool)
    at_rest[0], at_rest[-1] = start_speed == 0.0, end_speed == 0.0
    rows = constraint_rows(coeffs, robot, limits, at_rest=at_rest)
    if not np.any(rows) and not np.any(np.isfinite(coeffs.speed_bound)):
        raise InputError("limits", limits, "no finite limit: the motion is unbounded")
    plain = not (coeffs.damped or np.any(coeffs.force_f))
    scale = 1.0
    for _ in range(VERIFY_ATTEMPTS + 1):
        phase = _plan(coeffs, robot, limits, samples, start_speed, end_speed, at_rest,
                      scale)
        x, u = phase.s_dot ** 2, np.append(phase.s_ddot, phase.s_ddot[-1])
        twists = samples.tangents * phase.s_dot[:, None]
        twist_dots = samples.tangents * u[:, None] + samples.curvatures * x[:, None]
        forces = coeffs.forces(u, phase.s_dot)
        if plain:
            break
        excess = _verify(robot, limits, payload, samples, twists, twist_dots, forces)
        if excess <= 1.0 + VERIFY_RTOL:
            break
        scale /= excess
    else:
        raise SolverError("time_optimal", "verification",
                          f"the recomputed forces exceed their bounds by a factor {excess:.9g}"
                          f" after {VERIFY_ATTEMPTS} tightened plans")
    return TimedTrajectory(
        _grid_times(phase), samples.poses, twists, twist_dots, forces,
        coeffs.velocity_ratio * phase.s_dot[:, None], coeffs.actuator_positions,
        samples.s, phase.s_dot, u, path, phase, robot, limits, payload)


def _plan(coeffs: PathCoefficients, robot: ParallelRobot, limits: Limits,
          samples: PathSamples, start_speed: float, end_speed: float, at_rest: np.ndarray,
          scale: float) -> PhaseProfile:
    """The TOPP-RA profile; with damping, the conservative linearisation iterated (module
    docstring)."""
    rows = constraint_rows(coeffs, robot, limits, force_scale=scale, at_rest=at_rest)
    phase = _solve(rows, coeffs.speed_bound, samples, start_speed, end_speed)
    if not coeffs.damped:
        return phase
    speed, best, duration = phase.s_dot, None, np.inf
    for _ in range(DAMPING_ITERATIONS):
        floor = 1e-3 * max(float(np.max(speed)), 1e-12)
        rows = constraint_rows(coeffs, robot, limits, np.maximum(speed, floor), scale,
                               at_rest)
        try:
            phase = _solve(rows, coeffs.speed_bound, samples, start_speed, end_speed)
        except InfeasiblePathError:
            if best is not None:       # keep the best verified-conservative profile
                break
            speed = 0.5 * speed        # the linearisation closed the phase plane: slower
            continue
        new = float(_grid_times(phase)[-1])
        if best is not None and new > duration * (1.0 - DAMPING_RTOL):
            if new < duration:
                best, duration = phase, new
            break
        best, duration, speed = phase, new, phase.s_dot
    if best is None:
        raise InfeasiblePathError(0, samples.s[0], samples.poses[0],
                                  "no profile meets the force limits with the damping "
                                  "linearised at any speed")
    return best


def _verify(robot: ParallelRobot, limits: Limits, payload: Payload, samples: PathSamples,
            twists: np.ndarray, twist_dots: np.ndarray, forces: np.ndarray) -> float:
    """Recompute the grid forces with the robot's inverse dynamics (effects included):
    raise :class:`SolverError` where they differ from the planned ones, return the
    largest ratio of a force to its bound (1 when none is bounded)."""
    recomputed = robot.inverse_dynamics_batch(samples.poses, twists, twist_dots,
                                              payload.wrenches(robot, twist_dots),
                                              bounded=False).actuator_forces
    scale = max(1.0, float(np.max(np.abs(recomputed))))
    miss = float(np.max(np.abs(recomputed - forces)))
    if not miss <= VERIFY_RTOL * scale:
        k = int(np.argmax(np.max(np.abs(recomputed - forces), axis=1)))
        raise SolverError("time_optimal", "verification",
                          f"the planned forces {forces[k].tolist()} at grid point {k} differ "
                          f"from the robot's inverse dynamics {recomputed[k].tolist()} by "
                          f"{miss:.3e}")
    bound = limits.per_actuator(robot, planning=True)["force"]
    finite = np.isfinite(bound)
    if not np.any(finite):
        return 1.0
    return float(np.max(np.abs(recomputed[:, finite]) / bound[finite]))


def _solve(rows, speed_bound, samples, start_speed, end_speed) -> PhaseProfile:
    npts = len(samples.s)
    steps = np.diff(samples.s)
    lo, hi = np.empty(npts), np.empty(npts)
    status, k = solver.backward_pass(rows, steps, speed_bound, end_speed ** 2, lo, hi)
    if status != solver.OK:
        raise InfeasiblePathError(k, samples.s[k], samples.poses[k],
                                  "no speed here can still reach the end speed within the "
                                  "limits")
    x, u = np.empty(npts), np.empty(npts - 1)
    status, k = solver.forward_pass(rows, steps, lo, hi, start_speed ** 2, x, u)
    if status != solver.OK:
        raise InfeasiblePathError(0, samples.s[0], samples.poses[0],
                                  f"the start speed exceeds what the limits allow "
                                  f"(at most {np.sqrt(max(hi[0], 0.0)):.6g} m/s)")
    speed = np.sqrt(x)
    stall = np.flatnonzero(speed[:-1] + speed[1:] <= 0.0)
    if stall.size:
        k = int(stall[0])
        raise InfeasiblePathError(k, samples.s[k], samples.poses[k],
                                  "the robot cannot set off along the path from rest here "
                                  "within the limits")
    mvc = np.empty(npts)
    solver.max_velocity_curve(rows, speed_bound, mvc)
    return PhaseProfile(samples.s, speed, u, np.stack([lo, hi], axis=1), mvc)


def _grid_times(phase: PhaseProfile) -> np.ndarray:
    dt = 2.0 * np.diff(phase.s) / (phase.s_dot[:-1] + phase.s_dot[1:])
    return np.concatenate([[0.0], np.cumsum(dt)])


def _assemble(robot, path, limits, payload, phase, times, s, s_dot, s_ddot) -> TimedTrajectory:
    samples = path.sample(s)
    twists = samples.tangents * s_dot[:, None]
    twist_dots = samples.tangents * s_ddot[:, None] + samples.curvatures * (s_dot ** 2)[:, None]
    forces = robot.inverse_dynamics_batch(samples.poses, twists, twist_dots,
                                          payload.wrenches(robot, twist_dots),
                                          bounded=False).actuator_forces
    jac = robot.jacobian_batch(samples.poses)
    return TimedTrajectory(times, samples.poses, twists, twist_dots, forces,
                           np.einsum("nij,nj->ni", jac.jacobian, twists),
                           jac.actuator_positions, samples.s, s_dot, s_ddot, path, phase,
                           robot, limits, payload)

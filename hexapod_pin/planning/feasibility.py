"""Margins of a timed motion against the limits: :func:`check_feasibility`.

For N samples ``(t, pose, twist, twist_dot)`` the robot's batch routes give the actuator
forces (inverse dynamics, payload included), velocities (``J twist``) and accelerations
(forward dynamics driven by those forces), the platform's linear and angular speeds, and
whether each pose is within its strokes. A margin is ``bound - |value|`` (units of the
bound; negative where violated).

Uniform slow-down: played ``k`` times slower (``t -> k t``), velocities scale by ``1/k``
and accelerations by ``1/k^2``; so do the velocity-product terms of the dynamics, so the
forces are ``tau(k) = c + (tau - c) / k^2`` exactly, ``c`` the static forces (weight,
constant wrenches). The smallest ``k`` meeting every limit is then found in closed form
(``k < 1``: the motion could be played faster; ``inf``: a pose cannot be held statically).

With drive effects (``robot.effects``) damping scales by ``1/k`` and Coulomb friction
not at all, so ``tau(mu) = c_0 + c_1 mu + c_2 mu^2`` with ``mu = 1/k``; the three
coefficients of every sample follow exactly from the inverse dynamics at ``mu = 1, 1/2,
1/4`` (``c_0`` is then the force of a very slow motion: the static forces and the sliding
friction), and the slow-down is the first crossing of a bound: the smallest ``k`` from
which on every slower playback meets the force limits (an inverse dynamics at rest gives
a joint that accelerates the friction ``-coulomb sign(a)``: the formula holds at rest
samples too).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any
from dataclasses import dataclass

import numpy as np

from ..core.checks import of_type, real_number
from ..core.robot_api import ParallelRobot, parallel_robot, pose_layout
from ..errors import InputError
from ..motion import Motion, read_motion
from .limits import Limits, Payload
from .trajectory import TimedTrajectory

#: what :func:`check_feasibility` accepts as a motion
MotionSource = TimedTrajectory | Motion | str | os.PathLike[str] | Mapping[str, Any]


@dataclass(frozen=True)
class Violation:
    """The worst sample of a motion against one limit.

    Attributes:
        limit: "actuator_force", "actuator_velocity", "actuator_acceleration",
            "linear_speed", "angular_speed" or "stroke".
        index: the sample (0-based).
        time: its time (s).
        component: the actuator (or 0 for the platform speeds).
        value: the absolute value there.
        bound: the limit.
        excess: ``value - bound`` (> 0: violated; for "stroke" 1.0 when the stroke is
            left).
    """

    limit: str
    index: int
    time: float
    component: int
    value: float
    bound: float
    excess: float


@dataclass(frozen=True)
class FeasibilityReport:
    """Margins of a timed motion against its limits.

    Attributes:
        feasible: every limit holds at every sample (to the relative ``tolerance``).
        t: (N,) the sample times (s).
        values: limit name -> (N, c) absolute values (N, m/s, m/s^2, m/s, rad/s).
        bounds: limit name -> (c,) bounds (``inf``: none).
        margins: limit name -> (N, c) ``bound - value`` (negative where violated).
        within_stroke: (N,) bool.
        worst: the :class:`Violation` with the largest relative excess
            (``value / bound``), violated or not; None when no limit is finite.
        slow_down: the smallest uniform slow-down factor ``k`` (``t -> k t``) that meets
            every limit (``< 1``: could be played faster; ``inf``: a pose cannot be held
            statically, or a stroke is left).
        slow_down_reason: why no slow-down helps when ``slow_down`` is ``inf`` (the sample,
            the actuator and the forces at rest that exceed the bound, or the sample that
            leaves a stroke); ``""`` otherwise.
    """

    feasible: bool
    t: np.ndarray
    values: Mapping[str, np.ndarray]
    bounds: Mapping[str, np.ndarray]
    margins: Mapping[str, np.ndarray]
    within_stroke: np.ndarray
    worst: Violation | None
    slow_down: float
    slow_down_reason: str = ""


def motion_arrays(robot: ParallelRobot, motion: MotionSource
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """``(t, poses, twists, twist_dots, wrenches)`` of a motion given as a
    :class:`TimedTrajectory`, a :class:`~hexapod_pin.motion.Motion`, a motion file
    (:func:`~hexapod_pin.motion.read_motion`) or a mapping with ``t``, ``poses`` and
    optionally ``twists``, ``twist_dots``, ``wrenches``, each (N, dim) in the robot's pose
    axes. Missing rates come from the poses by second-order finite differences
    (:meth:`~hexapod_pin.core.robot_api.PoseLayout.twists_from_poses`: angles unwrapped;
    ``w = E(rpy) d(rpy)/dt`` when all three angles are in the pose, each angle's rate
    otherwise); a motion file is read with the robot's columns
    (:func:`~hexapod_pin.motion.read_motion` with ``robot``).

    Raises:
        InputError: missing keys, wrong shapes, fewer than 3 samples without rates.
        DescriptionError: a malformed motion file.
    """
    if isinstance(motion, (str, os.PathLike)):
        motion = read_motion(motion, robot)
    if isinstance(motion, (TimedTrajectory, Motion)):
        fields = {"t": motion.t, "poses": motion.poses, "twists": motion.twists,
                  "twist_dots": motion.twist_dots,
                  "wrenches": getattr(motion, "wrenches", None)}
    elif isinstance(motion, Mapping):
        fields = {key: motion.get(key) for key in ("t", "poses", "twists", "twist_dots",
                                                   "wrenches")}
    else:
        raise InputError("motion", motion, "expected a TimedTrajectory, Motion, motion file "
                                           "or mapping")
    if fields["t"] is None or fields["poses"] is None:
        raise InputError("motion", motion, "needs t and poses")
    t = np.asarray(fields["t"], dtype=float)
    dim = robot.pose_dim
    arrays = {}
    for key in ("poses", "twists", "twist_dots", "wrenches"):
        if fields[key] is not None:
            arr = np.asarray(fields[key], dtype=float)
            if arr.shape != (len(t), dim) or not np.all(np.isfinite(arr)):
                raise InputError(key, fields[key], f"expected ({len(t)}, {dim}) finite values")
            arrays[key] = arr
    if t.ndim != 1 or len(t) < 1 or np.any(np.diff(t) <= 0) or not np.all(np.isfinite(t)):
        raise InputError("t", t, "expected strictly increasing finite times")
    poses = arrays["poses"]
    twists, twist_dots = arrays.get("twists"), arrays.get("twist_dots")
    if (twists is None or twist_dots is None) and len(t) < 3:
        raise InputError("motion", motion, "at least 3 samples are needed to differentiate")
    if twists is None:
        twists = pose_layout(robot).twists_from_poses(t, poses)
    if twist_dots is None:
        twist_dots = np.gradient(twists, t, axis=0, edge_order=2)
    return t, poses, twists, twist_dots, arrays.get("wrenches")


def check_feasibility(robot: ParallelRobot, motion: MotionSource, *, limits: Limits | None = None,
                      payload: Payload | None = None,
                      tolerance: float = 1e-9) -> FeasibilityReport:
    """Margins of a timed motion against the limits (see the module docstring).

    Args:
        robot: a robot with the shared API.
        motion: see :func:`motion_arrays`; a motion's own ``wrenches`` act on the
            platform on top of the payload (constant in the slow-down).
        limits: :class:`Limits` (default: the robot's force bound).
        payload: :class:`Payload` (default: none).
        tolerance: relative excess still called feasible (``value <= bound (1 +
            tolerance)``); a time-optimal motion resampled between its grid points exceeds
            its bounds by a fraction of a percent that shrinks with the grid step.

    Returns:
        :class:`FeasibilityReport`.

    Raises:
        InputError: a malformed motion (shapes, non-finite values).
        DescriptionError: a malformed motion file.
        BatchUnreachablePoseError: a pose out of reach (the robot's batch error).
        BatchSingularityError: a singular pose (the robot's batch error).
    """
    robot = parallel_robot(robot)
    limits = of_type(Limits() if limits is None else limits, Limits, "limits")
    payload = of_type(Payload() if payload is None else payload, Payload, "payload")
    payload.check(robot.pose_dim)
    tolerance = real_number(tolerance, "tolerance", minimum=0.0, strict=False)
    t, poses, twists, twist_dots, extra = motion_arrays(robot, motion)
    n, layout = len(t), pose_layout(robot)
    bounds = limits.per_actuator(robot)

    def wrench(tdots):
        w = payload.wrenches(robot, tdots)
        if extra is None:
            return w
        return extra if w is None else w + extra

    zero = np.zeros_like(twists)
    forces = robot.inverse_dynamics_batch(poses, twists, twist_dots, wrench(twist_dots),
                                          bounded=False).actuator_forces
    static = robot.inverse_dynamics_batch(poses, zero, zero, wrench(zero),
                                          bounded=False).actuator_forces
    jac = robot.jacobian_batch(poses)
    velocities = np.einsum("nij,nj->ni", jac.jacobian, twists)
    values = {"actuator_force": np.abs(forces), "actuator_velocity": np.abs(velocities),
              "linear_speed": np.linalg.norm(twists[:, layout.linear], axis=1)[:, None],
              "angular_speed": np.linalg.norm(twists[:, layout.angular], axis=1)[:, None]}
    limit_of = {"actuator_force": bounds["force"], "actuator_velocity": bounds["velocity"],
                "linear_speed": bounds["linear_speed"],
                "angular_speed": bounds["angular_speed"]}
    if np.any(np.isfinite(bounds["acceleration"])):
        acc = robot.forward_dynamics_batch(poses, twists, forces,
                                           wrench(twist_dots)).actuator_accelerations
        values["actuator_acceleration"] = np.abs(acc)
        limit_of["actuator_acceleration"] = bounds["acceleration"]
    within = robot.inverse_kinematics_batch(poses).within_stroke if limits.strokes \
        else np.ones(n, dtype=bool)
    margins = {key: limit_of[key] - values[key] for key in values}
    feasible = bool(np.all(within)) and all(
        np.all(values[key] <= limit_of[key] * (1 + tolerance)) for key in values)
    poly = _speed_polynomial(robot, poses, twists, twist_dots, wrench, forces, static)
    slow, reason = _slow_down(t, poly, values, limit_of, within)
    return FeasibilityReport(feasible, t, values, limit_of, margins, within,
                             _worst(t, values, limit_of, within), slow, reason)


def _worst(t, values, bounds, within) -> Violation | None:
    if not np.all(within):
        k = int(np.argmin(within))
        return Violation("stroke", k, float(t[k]), 0, 1.0, 0.0, 1.0)
    best, best_ratio = None, -np.inf
    for key, vals in values.items():
        finite = np.isfinite(bounds[key])
        if not np.any(finite):
            continue
        ratio = np.where(finite, vals / np.where(finite, bounds[key], 1.0), -np.inf)
        k, j = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
        if ratio[k, j] > best_ratio:
            best_ratio = ratio[k, j]
            best = Violation(key, int(k), float(t[k]), int(j), float(vals[k, j]),
                             float(bounds[key][j]), float(vals[k, j] - bounds[key][j]))
    return best


def _speed_polynomial(robot, poses, twists, twist_dots, wrench, forces, static):
    """``(c_0, c_1, c_2)`` (N, n_act) each: the forces of the motion played at ``mu = 1/k``
    times its speed are ``c_0 + c_1 mu + c_2 mu^2`` (module docstring)."""
    effects = getattr(robot, "effects", None)
    if effects is None or not (effects.damping.any() or effects.coulomb.any()):
        return static, np.zeros_like(static), forces - static
    values = [forces]
    for mu in (0.5, 0.25):
        tdots = twist_dots * mu ** 2
        values.append(robot.inverse_dynamics_batch(poses, twists * mu, tdots, wrench(tdots),
                                                   bounded=False).actuator_forces)
    mus = np.array([1.0, 0.5, 0.25])
    vander = np.stack([np.ones(3), mus, mus ** 2], axis=1)
    coeffs = np.linalg.solve(vander, np.stack([v.reshape(-1) for v in values]))
    return tuple(row.reshape(forces.shape) for row in coeffs)


def _first_crossing(c0, c1, c2, bound):
    """The smallest ``mu > 0`` with ``|c0 + c1 mu + c2 mu^2| = bound`` (elementwise,
    ``inf`` where none; ``|c0| <= bound`` assumed)."""
    best = np.full(c0.shape, np.inf)
    scale = np.maximum(np.maximum(np.abs(c0), bound), 1.0)
    quadratic = np.abs(c2) > 1e-12 * scale
    linear = ~quadratic & (np.abs(c1) > 1e-12 * scale)
    with np.errstate(divide="ignore", invalid="ignore"):
        for target in (bound, -bound):
            k = c0 - target
            disc = c1 ** 2 - 4.0 * c2 * k
            root = np.sqrt(np.where(disc >= 0, disc, np.nan))
            for r in ((-c1 + root) / (2.0 * c2), (-c1 - root) / (2.0 * c2)):
                ok = quadratic & (disc >= 0) & (r > 0)
                best = np.where(ok, np.minimum(best, r), best)
            r = -k / c1
            best = np.where(linear & (r > 0), np.minimum(best, r), best)
    return best


def _slow_down(t, poly, values, bounds, within) -> tuple[float, str]:
    """The smallest uniform slow-down factor and, when none helps, why."""
    if not np.all(within):
        k = int(np.argmin(within))
        return float("inf"), f"sample {k} (t = {t[k]:.6g} s) leaves an actuator's stroke"
    needed = 0.0
    force_bound = bounds["actuator_force"]
    finite = np.isfinite(force_bound)
    if np.any(finite):
        c, c1, c2 = (part[:, finite] for part in poly)
        f = np.broadcast_to(force_bound[finite], c.shape)
        over = np.abs(c) > f
        if np.any(over):
            k, j = np.unravel_index(int(np.argmax(np.abs(c) / f)), c.shape)
            actuator = int(np.flatnonzero(finite)[j])
            return float("inf"), (f"holding the pose at rest (gravity and the payload, no "
                                  f"motion; with Coulomb friction: the slowest motion) "
                                  f"already needs {abs(c[k, j]):.6g} on actuator "
                                  f"{actuator} at sample {k} (t = {t[k]:.6g} s), above its "
                                  f"bound {f[k, j]:.6g}: no slow-down helps")
        # |c0 + c1 mu + c2 mu^2| <= f for mu = 1 / k in (0, mu_max]
        mu_max = float(np.min(_first_crossing(c, c1, c2, f)))
        needed = max(needed, 0.0 if mu_max == np.inf else 1.0 / max(mu_max, 1e-300))
    for key, power in (("actuator_velocity", 1), ("linear_speed", 1), ("angular_speed", 1),
                       ("actuator_acceleration", 2)):
        if key in values:
            with np.errstate(divide="ignore"):
                ratio = np.max(values[key] / bounds[key]) if values[key].size else 0.0
            needed = max(needed, float(ratio) ** (1.0 / power))
    return float(needed), ""

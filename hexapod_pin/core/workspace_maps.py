"""Workspace maps of any parallel robot: reachability, conditioning, singularity distances,
statics, force capability and sampled volumes over many poses.

Written against the shared protocol (:class:`~hexapod_pin.core.robot_api.ParallelRobot`)
only, so it runs on the hexapod, the planar 3-PRR and any robot loaded from a description
(``hexapod_pin.ClosedLoopRobot``) alike. The robot's batch routes do the work
(``jacobian_batch``, ``static_forces_batch``: compiled for the robots with a closed form,
pose by pose for the others); where a batch route refuses a chunk, its poses are taken one
by one. The per-pose measures are those of
:class:`hexapod_pin.hexapod.workspace.WorkspaceMeasures`, so that plots take either:

* ``reachable``: the inverse kinematics finds a configuration (every chain reaches);
  ``within_stroke``: the actuator positions respect the robot's position limits;
  ``regular``: the Jacobian route answers (no singularity below the robot's thresholds);
  ``ok``: all three;
* ``condition_number``: ``sigma_max / sigma_min`` of the workspace Jacobian ``J``
  (``actuator velocities = J @ twist``, mixed units, as returned by ``robot.jacobian``);
* ``type_one``, ``type_two``: the measures of ``robot.singularity(pose)``
  (:class:`~hexapod_pin.core.results.SingularityMeasures`: 0 at a type-I / type-II
  singularity);
* ``static_forces``: the actuator forces (N or N m) holding the pose at rest against
  gravity and a payload wrench, ``robot.static_forces(pose, payload, bounded=False)``.

Force limits and drive effects (``robot.effects``, :mod:`~hexapod_pin.core.effects`):
the bound of actuator ``i`` is the smaller of ``geometry.max_actuator_force`` and the
drive's ``effort_limit`` (:func:`actuator_force_bounds`); the static forces are the
robot's, springs included. Coulomb friction at rest makes the holding forces a band
(:func:`~hexapod_pin.core.holding.holding_band`): actuator ``i`` may need any force in
``[static_i - below_i, static_i + above_i]`` (``below``, ``above`` independent of the
wrench: the band is a translate of one set). :func:`force_capability` reports by default
the *guaranteed* capability, the whole band within the bounds (whatever force friction at
rest leaves to the actuators, and enough to break away in either direction): the bounds
shrink by the band's half-widths; ``friction="helping"`` counts on friction instead (the
band need only meet the bounds: a load that stays held once at rest, not one the
actuators could move off).

Poses, twists and wrenches follow :mod:`~hexapod_pin.core.robot_api`: the selection
``robot.pose_axes`` of ``(x, y, z, roll, pitch, yaw)`` (m, rad) and of ``(f, m)`` (N, N m,
world axes, moment about the platform origin). Rows outside the workspace (not ``ok``) carry
zeros (forces, ``sigma_min``, capability), ``inf`` (condition number) and ``False`` masks,
never NaN; :attr:`WorkspaceMap.failures` counts why.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import ArgumentTypeError, HexapodPinError, InputError, SingularityError
from .checks import as_array, count, generator, real_number
from .holding import holding_band
from .measures import condition_number
from .robot_api import ParallelRobot, parallel_robot

#: poses per chunk: the robot's batch routes run on this many at a time, and ``progress``
#: is called after each (small enough for a generic robot's inverse-kinematics cache to
#: serve the later stages of a chunk)
CHUNK = 64

#: a progress callback: called with the fraction of poses done, in (0, 1]
Progress = Callable[[float], object]

#: the most poses one call samples (memory: a few hundred bytes per pose)
MAX_POSES = 10 ** 7

#: an effort limit at or above this (N, N m) is none: what a URDF writes for "no limit"
NO_EFFORT_LIMIT = 1e30

#: how :func:`force_capability` treats Coulomb friction at rest
FRICTION_MODES = ("guaranteed", "helping")


@dataclass(frozen=True, eq=False)
class WorkspaceMap:
    """Per-pose results of :func:`evaluate`; arrays of length N unless stated.

    Attributes:
        poses: the poses (N, dim) (m, rad).
        actuator_positions: (N, n_act) (m or rad): the robot's answer, finite where a chain
            cannot reach (the nearest point, or the home positions: not a solution), zeros
            where the robot gave none.
        reachable: (N,) bool, see the module docstring.
        within_stroke: (N,) bool, see the module docstring.
        regular: (N,) bool, see the module docstring.
        ok: (N,) bool, ``reachable & within_stroke & regular``.
        condition_number: (N,) 2-norm condition number of ``J`` where ``ok``, inf elsewhere.
        sigma_min: (N,) smallest singular value of ``J`` where ``ok``, 0 elsewhere.
        type_one: (N,) the robot's type-I measure (0 where not reachable or not computed).
        type_two: (N,) the robot's type-II measure (0 where not reachable or not computed).
        static_forces: (N, n_act) actuator forces at rest (N or N m), zeros where not ``ok``
            or not computed.
        failures: why rows fail, reason -> number of rows (read-only): ``"unreachable"``,
            ``"stroke"``, ``"singular"`` (the first of the three that applies to a row
            not ``ok``), and ``"statics: <error>"``, ``"singularity: <error>"``,
            ``"kinematics: <error>"`` for a route that refused an otherwise usable row.
    """

    poses: np.ndarray
    actuator_positions: np.ndarray
    reachable: np.ndarray
    within_stroke: np.ndarray
    regular: np.ndarray
    ok: np.ndarray
    condition_number: np.ndarray
    sigma_min: np.ndarray
    type_one: np.ndarray
    type_two: np.ndarray
    static_forces: np.ndarray
    failures: Mapping[str, int]

    @property
    def q(self) -> np.ndarray:
        """``actuator_positions`` under the name of
        :class:`~hexapod_pin.hexapod.workspace.WorkspaceMeasures`."""
        return self.actuator_positions


@dataclass(frozen=True, eq=False)
class ForceCapabilityMap:
    """Largest payload scale per pose (see :func:`force_capability`).

    Attributes:
        scale: (N,) largest ``s >= 0`` such that the payload ``s * direction`` is held with
            ``|tau_i| <= bound_i`` (:func:`actuator_force_bounds`; with Coulomb friction
            the band as the ``friction`` mode asks); 0 where the pose is not ok, its
            statics failed or gravity alone already exceeds a bound; inf where no bounded
            actuator limits it.
        limiting_actuator: (N,) the actuator reaching its bound first, -1 where none does.
        base_forces: (N, n_act) actuator forces without payload (N or N m), the
            frictionless static forces (springs included).
        unit_forces: (N, n_act) actuator forces per unit of ``s``.
        feasible_without_payload: (N,) bool, ``ok`` and gravity alone within the bounds.
        ok: (N,) bool, the workspace mask ``ok`` of :func:`evaluate`.
        band_below: (N, n_act) how far friction at rest lets each force drop below the
            static one (N or N m; zeros without Coulomb friction or where not usable).
        band_above: (N, n_act) how far it lets each rise above (N or N m).
    """

    scale: np.ndarray
    limiting_actuator: np.ndarray
    base_forces: np.ndarray
    unit_forces: np.ndarray
    feasible_without_payload: np.ndarray
    ok: np.ndarray
    band_below: np.ndarray
    band_above: np.ndarray


@dataclass(frozen=True)
class VolumeEstimate:
    """A sampled volume and its standard error, in the units of the sampled box (the
    product of its sides' units: m^3 for a box of positions, m^2 rad for ``(x, y, yaw)``).

    Attributes:
        volume: estimate.
        std_error: one-sigma sampling error.
        n_samples: samples used.
        fraction: fraction of the sampled box inside the set.
        box_volume: volume of the sampled box.
    """

    volume: float
    std_error: float
    n_samples: int
    fraction: float
    box_volume: float


# -- input checks ----------------------------------------------------------------------------
_robot = parallel_robot


def _poses(robot: ParallelRobot, poses: npt.ArrayLike) -> np.ndarray:
    return np.array(as_array(poses, (robot.pose_dim,), "poses", batch=True), copy=True)


def _payload(payload: npt.ArrayLike | None, n: int, dim: int) -> np.ndarray | None:
    """The payload as (n, dim), or None."""
    if payload is None:
        return None
    raw = np.asarray(payload) if not isinstance(payload, np.ndarray) else payload
    if raw.ndim == 1:
        return np.broadcast_to(as_array(payload, (dim,), "payload"), (n, dim))
    arr = as_array(payload, (dim,), "payload", batch=True)
    if arr.shape[0] != n:
        raise InputError("payload", payload, f"expected ({dim},) or ({n}, {dim}), got "
                         f"{arr.shape}")
    return arr


def _progress(progress: Progress | None) -> Progress | None:
    if progress is not None and not callable(progress):
        raise ArgumentTypeError("progress", progress, "expected a callable(fraction) or None")
    return progress


def actuator_force_bounds(robot: ParallelRobot) -> np.ndarray:
    """The actuator force bounds (n_act,) (N or N m, joint side; ``inf``: none): the
    robot's ``geometry.max_actuator_force`` and, elementwise the smaller, the
    ``effort_limit`` of its drive effects (``robot.effects``; one of
    :data:`NO_EFFORT_LIMIT` or more counts as none)."""
    limit = np.broadcast_to(np.asarray(robot.geometry.max_actuator_force, dtype=float),
                            (robot.n_actuators,))
    effects = getattr(robot, "effects", None)
    if effects is not None:
        effort = np.asarray(effects.effort_limit, dtype=float)
        limit = np.minimum(limit, np.where(effort < NO_EFFORT_LIMIT, effort, np.inf))
    return np.array(limit, dtype=float)


def _band(robot: ParallelRobot, poses: np.ndarray, rows: np.ndarray, failures: Counter
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(below, above, done)``: the holding band's half-widths (n, n_act) at the selected
    rows (zeros elsewhere, and everywhere without Coulomb friction)."""
    n, n_act = poses.shape[0], robot.n_actuators
    below, above, done = np.zeros((n, n_act)), np.zeros((n, n_act)), rows.copy()
    effects = getattr(robot, "effects", None)
    if effects is None or not effects.has_coulomb:
        return below, above, done
    for k in np.flatnonzero(rows):
        try:
            band = holding_band(robot, poses[k])
        except HexapodPinError as exc:
            failures[f"friction: {type(exc).__name__}"] += 1
            done[k] = False
            continue
        below[k], above[k] = band.half_widths
    return below, above, done


# -- the stages of one chunk -----------------------------------------------------------------
def _kinematics(robot: ParallelRobot, poses: np.ndarray, failures: Counter
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(actuators (n, n_act), jacobians (n, n_act, dim), reachable, within, regular)``:
    the robot's ``jacobian_batch``, or pose by pose where it refuses the chunk."""
    n, n_act, dim = poses.shape[0], robot.n_actuators, robot.pose_dim
    try:
        jb = robot.jacobian_batch(poses)
        act, jac = np.asarray(jb.actuator_positions, float), np.asarray(jb.jacobian, float)
        reach, within, regular = (np.asarray(m, dtype=bool).copy()
                                  for m in (jb.reachable, jb.within_stroke, jb.regular))
    except InputError:
        raise
    except HexapodPinError:
        act, jac = np.zeros((n, n_act)), np.zeros((n, n_act, dim))
        reach, within, regular = (np.zeros(n, dtype=bool) for _ in range(3))
        for k, pose in enumerate(poses):
            act[k], jac[k], reach[k], within[k], regular[k] = _kinematics_one(robot, pose,
                                                                              failures)
    act = np.where(np.isfinite(act), act, 0.0)
    bad = ~np.all(np.isfinite(jac), axis=(1, 2)) & reach & regular
    if np.any(bad):
        failures["kinematics: non-finite Jacobian"] += int(np.count_nonzero(bad))
        regular &= ~bad
    jac = np.where(regular[:, None, None], np.nan_to_num(jac, posinf=0.0, neginf=0.0), 0.0)
    return act, jac, reach, within, regular


def _kinematics_one(robot: ParallelRobot, pose: np.ndarray, failures: Counter
                    ) -> tuple[np.ndarray, np.ndarray, bool, bool, bool]:
    n_act, dim = robot.n_actuators, robot.pose_dim
    try:
        act = robot.inverse_kinematics(pose, check_limits=False)
    except InputError:
        raise
    except HexapodPinError:
        return np.zeros(n_act), np.zeros((n_act, dim)), False, False, False
    try:
        robot.inverse_kinematics(pose, check_limits=True)
        within = True
    except HexapodPinError:
        within = False
    try:
        return act, robot.jacobian(pose), True, within, True
    except HexapodPinError as exc:
        if not isinstance(exc, SingularityError):
            failures[f"kinematics: {type(exc).__name__}"] += 1
        return act, np.zeros((n_act, dim)), True, within, False


def _statics(robot: ParallelRobot, poses: np.ndarray, wrenches: np.ndarray | None,
             rows: np.ndarray, failures: Counter) -> tuple[np.ndarray, np.ndarray]:
    """``(forces (n, n_act), done (n,) bool)`` at the selected rows (zeros elsewhere): the
    robot's ``static_forces_batch`` (unbounded), or pose by pose where it refuses."""
    n, n_act = poses.shape[0], robot.n_actuators
    forces, done = np.zeros((n, n_act)), np.zeros(n, dtype=bool)
    idx = np.flatnonzero(rows)
    if idx.size == 0:
        return forces, done
    sub_w = None if wrenches is None else np.ascontiguousarray(wrenches[idx])
    try:
        forces[idx] = robot.static_forces_batch(poses[idx], sub_w, bounded=False)
        done[idx] = True
    except InputError:
        raise
    except HexapodPinError:
        for k in idx:
            try:
                forces[k] = robot.static_forces(poses[k], None if wrenches is None
                                                else wrenches[k], bounded=False)
                done[k] = True
            except HexapodPinError as exc:
                failures[f"statics: {type(exc).__name__}"] += 1
    bad = done & ~np.all(np.isfinite(forces), axis=1)
    if np.any(bad):
        failures["statics: non-finite forces"] += int(np.count_nonzero(bad))
        done &= ~bad
    forces[~done] = 0.0
    return forces, done


def _singularity(robot: ParallelRobot, poses: np.ndarray, rows: np.ndarray,
                 failures: Counter) -> tuple[np.ndarray, np.ndarray]:
    """``(type_one, type_two)`` (n,) of ``robot.singularity`` at the selected rows."""
    t1, t2 = np.zeros(poses.shape[0]), np.zeros(poses.shape[0])
    for k in np.flatnonzero(rows):
        try:
            meas = robot.singularity(poses[k])
        except HexapodPinError as exc:
            failures[f"singularity: {type(exc).__name__}"] += 1
            continue
        if math.isfinite(meas.type_one) and math.isfinite(meas.type_two):
            t1[k], t2[k] = meas.type_one, meas.type_two
        else:
            failures["singularity: non-finite measure"] += 1
    return t1, t2


# -- the maps --------------------------------------------------------------------------------
def evaluate(robot: ParallelRobot, poses: npt.ArrayLike, payload: npt.ArrayLike | None = None,
             *, statics: bool = True, singularity: bool = True,
             progress: Progress | None = None) -> WorkspaceMap:
    """Reachability, conditioning, singularity distances and statics of many poses.

    Args:
        robot: any :class:`~hexapod_pin.core.robot_api.ParallelRobot`.
        poses: (N, dim) poses in the robot's pose coordinates (``robot.pose_axes``; m, rad).
        payload: wrench (dim,) applied ON the platform by the payload (the selection of
            ``(f, m)``: N, N m, world axes, moment about the platform origin), or (N, dim)
            one per pose; default none (gravity only).
        statics: compute ``static_forces`` (else zeros).
        singularity: compute ``type_one`` / ``type_two`` (else zeros); one
            ``robot.singularity`` call per reachable pose.
        progress: optional ``callable(fraction)``, called after each chunk of
            :data:`CHUNK` poses with the fraction done (the last call with 1.0; no call
            for N = 0).

    Returns:
        :class:`WorkspaceMap` (never NaN; see the module docstring for the meanings).

    Raises:
        ArgumentTypeError: ``robot`` is not a parallel robot, ``progress`` not callable.
        InputError: poses not (N, dim), payload not (dim,) or (N, dim), NaN / inf, or a
            pose the robot refuses as input (e.g. pitch +-pi/2 of a 6-D pose).

    Example:
        >>> m = evaluate(robot, sample_box(robot, 200, low, high, seed=0))
        >>> m.ok.mean(), m.condition_number[m.ok].max()
    """
    robot = _robot(robot)
    poses = _poses(robot, poses)
    wrenches = _payload(payload, poses.shape[0], robot.pose_dim)
    return _run(robot, poses, wrenches, statics, singularity, _progress(progress))[0]


def _run(robot: ParallelRobot, poses: np.ndarray, wrenches: np.ndarray | None, statics: bool,
         singularity: bool, report: Progress | None) -> tuple[WorkspaceMap, np.ndarray]:
    """:func:`evaluate` on checked inputs; also the rows whose statics were computed."""
    n, n_act = poses.shape[0], robot.n_actuators
    failures: Counter = Counter()
    done = np.zeros(n, dtype=bool)
    act = np.zeros((n, n_act))
    reach, within, regular, ok = (np.zeros(n, dtype=bool) for _ in range(4))
    cond, smin = np.full(n, np.inf), np.zeros(n)
    t1, t2, forces = np.zeros(n), np.zeros(n), np.zeros((n, n_act))
    for start in range(0, n, CHUNK):
        sl = slice(start, min(start + CHUNK, n))
        chunk = poses[sl]
        act[sl], jac, reach[sl], within[sl], regular[sl] = _kinematics(robot, chunk, failures)
        good = reach[sl] & within[sl] & regular[sl]
        ok[sl] = good
        if np.any(good):
            sv = np.linalg.svd(jac[good], compute_uv=False)
            smin[sl][good] = sv[:, -1]
            cond[sl][good] = condition_number(sv)
        if statics:
            forces[sl], done[sl] = _statics(robot, chunk,
                                            None if wrenches is None else wrenches[sl],
                                            good, failures)
        if singularity:
            t1[sl], t2[sl] = _singularity(robot, chunk, reach[sl], failures)
        if report is not None:
            report(sl.stop / n)
    failures.update({"unreachable": int(np.count_nonzero(~reach)),
                     "stroke": int(np.count_nonzero(reach & ~within)),
                     "singular": int(np.count_nonzero(reach & within & ~regular))})
    return WorkspaceMap(poses, act, reach, within, regular, ok, cond, smin, t1, t2, forces,
                        MappingProxyType({k: v for k, v in failures.items() if v})), done


def dexterity(measures: Any) -> np.ndarray:
    """The inverse condition number ``1 / cond(J)`` (N,) in [0, 1] of a workspace map
    (:class:`WorkspaceMap` or the hexapod's ``WorkspaceMeasures``): 0 where not ``ok``.

    Args:
        measures: anything with a ``condition_number`` array (N,) (inf where not ok).

    Returns:
        (N,) ``1 / condition_number``, 0 where it is inf.
    """
    cond = np.asarray(measures.condition_number, dtype=float)
    with np.errstate(divide="ignore"):
        return np.where(np.isfinite(cond) & (cond > 0), 1.0 / np.where(cond > 0, cond, 1.0),
                        0.0)


def force_capability(robot: ParallelRobot, poses: npt.ArrayLike, direction: npt.ArrayLike, *,
                     progress: Progress | None = None,
                     friction: str = "guaranteed") -> ForceCapabilityMap:
    """Largest payload along a wrench direction that the actuators can hold, per pose.

    Solves, per pose, the linear program ``max s`` s.t. ``-bound_i + below_i <= tau0_i +
    s tau1_i <= bound_i - above_i`` for every actuator i, where ``tau0`` holds gravity
    (springs included) and ``tau1`` the unit payload ``direction`` (``static_forces`` is
    affine in the wrench), ``bound`` is :func:`actuator_force_bounds` and ``below``,
    ``above`` the half-widths of the holding band of Coulomb friction at rest (zero
    without friction; module docstring). The LP is one-dimensional, so its exact
    solution is the smallest crossing over i.

    Args:
        robot: any :class:`~hexapod_pin.core.robot_api.ParallelRobot`; its bounds
            ``geometry.max_actuator_force`` (a float or (n_act,), inf: none) and its
            drives' ``effort_limit``.
        poses: (N, dim) poses (m, rad).
        direction: payload wrench direction (dim,) ON the platform (N, N m, world axes,
            about the platform origin), e.g. ``(0, 0, -m g, 0, 0, 0)`` for a mass m at the
            origin of a 6-D pose (then ``scale`` is in units of m). Any scale: the result
            scales inversely.
        progress: as in :func:`evaluate` (the fraction of the kinematics done).
        friction: with Coulomb friction at rest, "guaranteed" (default: the whole
            holding band within the bounds, ``below``, ``above`` the band's half-widths)
            or "helping" (the band need only meet the bounds: ``below`` and ``above``
            swapped and negated, friction holding part of the load).

    Returns:
        :class:`ForceCapabilityMap`.

    Raises:
        ArgumentTypeError: as in :func:`evaluate`.
        InputError: as in :func:`evaluate`, a zero direction, an unknown ``friction``.
    """
    robot = _robot(robot)
    direction = as_array(direction, (robot.pose_dim,), "direction")
    if not np.any(direction):
        raise InputError("direction", direction, "must not be zero")
    if friction not in FRICTION_MODES:
        raise InputError("friction", friction, f"expected one of {FRICTION_MODES}")
    poses = _poses(robot, poses)
    n = poses.shape[0]
    base, done0 = _run(robot, poses, None, True, False, _progress(progress))
    with_unit, done1 = _statics(robot, poses, np.broadcast_to(direction, (n, direction.size)),
                                done0, Counter())
    below, above, done2 = _band(robot, poses, done0 & done1, Counter())
    usable_rows = done0 & done1 & done2
    tau0 = np.where(usable_rows[:, None], base.static_forces, 0.0)
    tau1 = np.where(usable_rows[:, None], with_unit - base.static_forces, 0.0)
    below = np.where(usable_rows[:, None], below, 0.0)
    above = np.where(usable_rows[:, None], above, 0.0)
    limit = actuator_force_bounds(robot)[None, :]
    high, low = (limit - above, -limit + below) if friction == "guaranteed" else \
        (limit + below, -limit - above)
    feasible0 = usable_rows & np.all((tau0 <= high) & (tau0 >= low), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = np.where(tau1 > 0, (high - tau0) / tau1,
                         np.where(tau1 < 0, (low - tau0) / tau1, np.inf))
    bound = np.where(np.isnan(bound), np.inf, bound)
    limiting = np.argmin(bound, axis=1)
    scale = bound[np.arange(n), limiting]
    bounded = np.isfinite(scale)
    scale = np.where(feasible0, np.where(bounded, np.maximum(scale, 0.0), np.inf), 0.0)
    limiting = np.where(feasible0 & bounded, limiting, -1)
    return ForceCapabilityMap(scale, limiting, tau0, tau1, feasible0, base.ok, below, above)


# -- sampling --------------------------------------------------------------------------------
def _box(robot: ParallelRobot, low: npt.ArrayLike, high: npt.ArrayLike
         ) -> tuple[np.ndarray, np.ndarray]:
    dim = robot.pose_dim
    lo, hi = as_array(low, (dim,), "low"), as_array(high, (dim,), "high")
    if np.any(hi < lo):
        raise InputError("high", high, f"must be >= low {lo.tolist()} componentwise")
    return lo, hi


_rng = generator


def sample_box(robot: ParallelRobot, n: int, low: npt.ArrayLike, high: npt.ArrayLike,
               seed: int | np.random.Generator = 0) -> np.ndarray:
    """Uniform random poses in the box ``low <= pose <= high``, in pose coordinates.

    Args:
        robot: the robot (its ``pose_dim``).
        n: number of poses (>= 1).
        low: (dim,) lower corner (m, rad).
        high: (dim,) upper corner, ``>= low`` componentwise.
        seed: a non-negative integer seed (reproducible) or a ``numpy`` Generator.

    Returns:
        poses (n, dim).

    Raises:
        ArgumentTypeError: ``robot`` is not a parallel robot.
        InputError: a bad count, box or seed.
    """
    robot = _robot(robot)
    n = count(n, "n", minimum=1)
    if n > MAX_POSES:
        raise InputError("n", n, f"more than MAX_POSES = {MAX_POSES:.0e} poses")
    lo, hi = _box(robot, low, high)
    return _rng(seed).uniform(lo, hi, size=(n, robot.pose_dim))


def grid(robot: ParallelRobot, center: npt.ArrayLike, half_extent: npt.ArrayLike,
         n: int | tuple[int, ...]) -> np.ndarray:
    """Poses on a regular grid in pose coordinates, ``center +- half_extent``.

    Args:
        robot: the robot (its ``pose_dim``).
        center: (dim,) grid centre (m, rad).
        half_extent: (dim,) half side lengths, >= 0 (a component with one point may have
            0: it stays at its centre value).
        n: points per component (an int for all, or dim ints), >= 1; one point sits at
            the centre, more span ``[center - half, center + half]``.

    Returns:
        poses (prod(n), dim), the first component varying slowest.

    Raises:
        ArgumentTypeError: ``robot`` is not a parallel robot.
        InputError: bad shapes, counts, or a zero half extent with more than one point.
    """
    robot = _robot(robot)
    dim = robot.pose_dim
    mid = as_array(center, (dim,), "center")
    half = as_array(half_extent, (dim,), "half_extent")
    if np.any(half < 0):
        raise InputError("half_extent", half_extent, "must be >= 0")
    counts_in = [n] * dim if np.ndim(n) == 0 else list(np.ravel(np.asarray(n, dtype=object)))
    if len(counts_in) != dim or np.ndim(n) > 1:
        raise InputError("n", n, f"expected a positive integer or {dim} of them")
    counts = [count(c, "n", minimum=1) for c in counts_in]
    if any(c > 1 and h == 0 for c, h in zip(counts, half)):
        raise InputError("half_extent", half_extent, "a component with more than one point "
                         "needs a half extent > 0")
    axes = [np.linspace(c - h, c + h, m) if m > 1 else np.array([c])
            for c, h, m in zip(mid, half, counts)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, dim)


def volume_estimate(inside: np.ndarray, box: float) -> VolumeEstimate:
    """Monte-Carlo volume of a region from uniform samples of a box.

    Args:
        inside: (N,) bool, which samples lie in the region (N >= 1).
        box: the box's volume (the product of its sides, in their units).

    Returns:
        :class:`VolumeEstimate`: ``box * p`` with the binomial standard error
        ``box sqrt(p (1 - p) / N)``, ``p`` the fraction inside.
    """
    n = inside.size
    p = float(np.count_nonzero(inside)) / n
    return VolumeEstimate(box * p, box * math.sqrt(p * (1 - p) / n), n, p, box)


def volume(robot: ParallelRobot, n_samples: int, low: npt.ArrayLike, high: npt.ArrayLike,
           seed: int | np.random.Generator = 0, *, max_condition: float | None = None,
           progress: Progress | None = None) -> VolumeEstimate:
    """Monte-Carlo volume of the ``ok`` region inside a box of poses.

    A sample counts when :func:`evaluate` finds it ``ok`` (reachable, within the strokes,
    regular) and, with ``max_condition``, ``condition_number <= max_condition`` (the
    well-conditioned workspace). The standard error is the binomial one,
    ``box sqrt(p (1 - p) / n)``.

    Args:
        robot: any :class:`~hexapod_pin.core.robot_api.ParallelRobot`.
        n_samples: number of uniform samples (>= 1).
        low: (dim,) lower corner of the box (m, rad).
        high: (dim,) upper corner, ``> low`` componentwise.
        seed: as in :func:`sample_box` (the estimate is reproducible).
        max_condition: optional bound on the condition number (> 0).
        progress: as in :func:`evaluate`.

    Returns:
        :class:`VolumeEstimate` in the product of the pose components' units (m^2 for
        ``("x", "z")``, m^3 rad^3 for a 6-D pose).

    Raises:
        ArgumentTypeError: ``robot`` is not a parallel robot, ``progress`` not callable.
        InputError: a bad count, box, seed or threshold.
    """
    robot = _robot(robot)
    n_samples = count(n_samples, "n_samples")
    lo, hi = _box(robot, low, high)
    if np.any(hi <= lo):
        raise InputError("high", high, f"must be > low {lo.tolist()} componentwise")
    with np.errstate(over="ignore"):
        box = float(np.prod(hi - lo))
    if not (math.isfinite(box) and box > 0.0):
        raise InputError("high", high, f"the box from low {lo.tolist()} has volume {box:g} "
                         "(overflow or underflow): a box of finite, non-zero volume")
    limit = None if max_condition is None else real_number(max_condition, "max_condition",
                                                           minimum=0.0)
    poses = sample_box(robot, n_samples, lo, hi, seed)
    measures = evaluate(robot, poses, statics=False, singularity=False, progress=progress)
    inside = measures.ok if limit is None else measures.ok & (measures.condition_number
                                                              <= limit)
    return volume_estimate(inside, box)

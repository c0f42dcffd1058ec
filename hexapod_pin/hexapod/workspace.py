"""Workspace, dexterity and force capability of the hexapod, vectorised over poses.

Every function takes an (N, 6) array of poses ``(x, y, z, roll, pitch, yaw)``
(m, rad) and returns per-pose arrays; nothing loops over poses in Python (the
work is done in chunks of :data:`CHUNK` poses to bound memory, optionally on
several threads: numpy's linear algebra releases the GIL).

Measures per pose (definitions shared with :meth:`Hexapod.singularity`):

* ``reachable``: every leg reaches its platform point; ``within_stroke``: the
  carriages (home branch unless given) respect ``abs(q) <= rail_half_length`` and
  the carriage gap; ``regular``: no leg perpendicular to its rail; ``ok``: all three.
* ``condition_number``: ``sigma_max / sigma_min`` of the workspace Jacobian ``J``
  (``qdot = J @ twist``, mixed units, as returned by :meth:`Hexapod.jacobian`).
* ``type_one``: smallest ``|cos|`` between a leg and its rail (0 at a type-I
  singularity); ``type_two``: smallest singular value of the dimensionless
  matrix with rows ``[e_i, (r_k x e_i) / platform_radius]`` (0 at a type-II one).
* ``static_forces``: actuator forces (N) holding the pose at rest under gravity
  and a payload wrench (world axes, about the platform origin). By virtual
  power, ``J^T tau = -(w_payload + w_gravity)`` where ``w_gravity`` is the
  weight of the platform at its origin plus half the weight of each leg at its
  tip (a uniform leg's centre of mass moves at the mean velocity of its ends;
  the carriages of the ideal robot move horizontally and their weight does no work;
  on an as-built robot's tilted lines the weight along the line is carried too).
  The closed-form kernels compute it, for the ideal and as-built geometries alike.

Force capability (:func:`force_capability`) is an exact closed form of the
one-dimensional linear program ``max s`` s.t. ``|tau0 + s tau1| <= tau_max``.

Rows outside the workspace (not ``ok``) carry zeros (forces, capability, sigma_min),
``inf`` (condition number) and ``False`` masks: never NaN.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ..core.checks import as_array, generator
from ..core.measures import condition_number
from ..core.workspace_maps import VolumeEstimate, volume_estimate
from ..errors import HexapodPinError, InputError
from . import batch
from . import kernels as K
from .robot import Hexapod

#: poses processed per chunk (bounds the temporary memory to ~100 MB)
CHUNK = 65_536


@dataclass(frozen=True)
class WorkspaceMeasures:
    """Per-pose results of :func:`evaluate`; arrays of length N unless stated.

    Attributes:
        poses: the poses (N, 6).
        q: carriage positions (N, 6) (m) on the requested branch (finite even where
            a leg cannot reach: the nearest rail point).
        reachable: boolean mask (see the module doc).
        within_stroke: boolean mask (see the module doc).
        regular: boolean mask (see the module doc).
        ok: boolean mask (see the module doc).
        condition_number: 2-norm condition number of ``J`` where ``ok``; inf elsewhere
            (poses the robot cannot take are not analysed further).
        sigma_min: smallest singular value of ``J`` where ``ok``, 0 elsewhere.
        type_one: smallest leg-rail ``|cos|`` (0 where a leg cannot reach).
        type_two: type-II distance (0 where a leg cannot reach).
        static_forces: (N, 6) actuator forces at rest (N), zeros where not ok.
        branch: the branch signs used (6,) or (N, 6).
    """

    poses: np.ndarray
    q: np.ndarray
    reachable: np.ndarray
    within_stroke: np.ndarray
    regular: np.ndarray
    ok: np.ndarray
    condition_number: np.ndarray
    sigma_min: np.ndarray
    type_one: np.ndarray
    type_two: np.ndarray
    static_forces: np.ndarray
    branch: np.ndarray


def constant_orientation_grid(center: npt.ArrayLike, half_extent: npt.ArrayLike,
                              n: int | tuple[int, int, int],
                              orientation: npt.ArrayLike = (0.0, 0.0, 0.0)) -> np.ndarray:
    """Poses on a regular 3-D grid of positions with one orientation.

    Args:
        center: grid centre (3,) (m).
        half_extent: half side lengths (3,) (m), > 0.
        n: points per axis (int or three ints), >= 1.
        orientation: roll, pitch, yaw (rad).

    Returns:
        poses (n_x n_y n_z, 6), x varying slowest.
    """
    center = as_array(center, (3,), "center")
    half = as_array(half_extent, (3,), "half_extent")
    if np.any(half <= 0):
        raise InputError("half_extent", half_extent, "must be > 0")
    counts: tuple[Any, ...] = (n, n, n) if np.isscalar(n) else tuple(n)  # type: ignore[arg-type]
    if len(counts) != 3 or any(int(c) != c or c < 1 for c in counts):
        raise InputError("n", n, "expected a positive integer or three of them")
    axes = [np.linspace(c - h, c + h, int(m)) if m > 1 else np.array([c])
            for c, h, m in zip(center, half, counts)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    rpy = np.broadcast_to(as_array(orientation, (3,), "orientation"), grid.shape)
    return np.concatenate([grid, rpy], axis=1)


def orientation_grid(position: npt.ArrayLike, max_angle: float, n: int) -> np.ndarray:
    """Poses at one position with roll, pitch, yaw on an ``n^3`` grid in
    ``[-max_angle, max_angle]``."""
    position = as_array(position, (3,), "position")
    if not (math.isfinite(max_angle) and max_angle > 0):
        raise InputError("max_angle", max_angle, "must be finite and > 0")
    if int(n) != n or n < 1:
        raise InputError("n", n, "must be a positive integer")
    angles = np.linspace(-max_angle, max_angle, int(n)) if n > 1 else np.zeros(1)
    rpy = np.stack(np.meshgrid(angles, angles, angles, indexing="ij"), axis=-1).reshape(-1, 3)
    return np.concatenate([np.broadcast_to(position, rpy.shape), rpy], axis=1)


def evaluate(robot: Hexapod, poses: npt.ArrayLike, payload: npt.ArrayLike | None = None,
             branch: npt.ArrayLike | None = None, threads: int = 1, singularity: bool = True,
             statics: bool = True) -> WorkspaceMeasures:
    """Reachability, conditioning, singularity distances and statics of many poses.

    Args:
        robot: a :class:`hexapod_pin.Hexapod`.
        poses: (N, 6) poses (m, rad).
        payload: wrench (f, m) (6,) applied on the platform by the payload (world
            axes, moment about the platform origin), or (N, 6); default none.
        branch: IK branch (six signs, or (N, 6)); default the home branch.
        threads: worker threads over chunks (numpy releases the GIL in its
            linear algebra); 1 runs in the calling thread.
        singularity: compute ``type_one`` / ``type_two`` (else zeros).
        statics: compute ``static_forces`` (else zeros). With both False, only
            reachability, the Jacobian and its conditioning are computed (the
            fast path for large samples).

    Returns:
        :class:`WorkspaceMeasures`.

    Raises:
        InputError: malformed poses, payload, branch or threads.
    """
    poses = as_array(poses, (6,), "poses", batch=True)
    n = poses.shape[0]
    if payload is None:
        payload = np.zeros(6)
    payload = np.asarray(payload, dtype=float)
    payload = (as_array(payload, (6,), "payload") if payload.ndim == 1
               else as_array(payload, (6,), "payload", batch=True))
    if payload.ndim == 2 and payload.shape[0] != n:
        raise InputError("payload", payload, f"expected (6,) or ({n}, 6)")
    if int(threads) != threads or threads < 1:
        raise InputError("threads", threads, "must be a positive integer")
    signs = batch.batch_signs(branch, n)
    out = {name: np.empty(n, dtype=bool) for name in ("reachable", "within", "regular")}
    q = np.empty((n, 6))
    cond, smin, t1, t2 = (np.empty(n) for _ in range(4))
    forces = np.zeros((n, 6))

    def work(start: int) -> None:
        stop = min(start + CHUNK, n)
        sl = slice(start, stop)
        chunk_signs = signs[sl] if signs.shape[0] > 1 else signs
        chunk_payload = payload[sl] if payload.ndim == 2 else payload
        res = _chunk(robot, poses[sl], chunk_signs, chunk_payload, singularity, statics)
        q[sl], cond[sl], smin[sl], t1[sl], t2[sl], forces[sl] = res[:6]
        out["reachable"][sl], out["within"][sl], out["regular"][sl] = res[6:]

    starts = range(0, n, CHUNK)
    if threads == 1 or n <= CHUNK:
        for start in starts:
            work(start)
    else:
        with ThreadPoolExecutor(max_workers=int(threads)) as pool:
            list(pool.map(work, starts))
    ok = out["reachable"] & out["within"] & out["regular"]
    forces[~ok] = 0.0
    branch_used = signs if (branch is not None and np.ndim(branch) == 2) else signs[0]
    return WorkspaceMeasures(poses, q, out["reachable"], out["within"], out["regular"], ok,
                             cond, smin, t1, t2, forces, branch_used)


def _chunk(robot, poses, signs, payload, singularity: bool, statics: bool):
    geo = robot.kinematics.geo
    n = poses.shape[0]
    jb = batch.kinematics_batch(geo, poses, signs, with_jacobian=True)
    good = jb.ok & jb.within_stroke
    smin = np.zeros(n)
    cond = np.full(n, np.inf)
    if np.any(good):  # singular values only where the pose is ok (the rest stays 0 / inf)
        sv = np.linalg.svd(jb.jacobian[good], compute_uv=False)
        smin[good] = sv[:, -1]
        cond[good] = condition_number(sv)
    type_one = np.zeros(n)
    type_two = np.zeros(n)
    forces = np.zeros((n, 6))
    if singularity:
        cosine, a_hat = batch.closure_measures(geo, poses, signs)
        type_one = np.where(jb.reachable, cosine, 0.0)
        type_two = np.where(jb.reachable, np.linalg.svd(a_hat, compute_uv=False)[:, -1], 0.0)
    if statics and np.any(good):
        forces = _statics(robot, poses, signs, payload, good)
    return (jb.actuator_positions, cond, smin, type_one, type_two, forces,
            jb.reachable, jb.within_stroke, jb.regular)


def _statics(robot: Hexapod, poses: np.ndarray, signs: np.ndarray, payload: np.ndarray,
             good: np.ndarray) -> np.ndarray:
    """Static forces (N, 6) at the ``good`` poses, zeros elsewhere and where the statics
    refuse: the compiled kernels (``J^T tau = G^T (g + K dq) - payload``, the carriages'
    springs included) when they model the robot's effects, else (springs on the universal
    joints or the platform's free flyer) the robot's single-state statics, which hold them."""
    forces = np.zeros((poses.shape[0], 6))
    if robot.dynamics.batch_kernels_apply:
        tau, codes = batch.static_forces_codes(robot.closed_form.dynamics_geo, poses,
                                               np.atleast_2d(payload), False, signs)
        keep = good & (codes == K.OK)
        forces[keep] = tau[keep]
        return forces
    for i in np.flatnonzero(good):
        try:
            forces[i] = robot.static_forces(poses[i], payload if payload.ndim == 1
                                            else payload[i], bounded=False,
                                            branch=signs[i] if signs.shape[0] > 1 else signs[0])
        except HexapodPinError:
            pass          # refused (the kernels' zeros): not part of the usable workspace
    return forces


@dataclass(frozen=True)
class ForceCapability:
    """Largest payload scale per pose (see :func:`force_capability`).

    Attributes:
        scale: largest ``s >= 0`` (N,) such that the payload ``s * direction`` is
            held with ``abs(tau_i) <= max_actuator_force``; 0 where the pose is
            not ok or gravity alone already saturates an actuator.
        limiting_actuator: the actuator that reaches its bound first (N,), -1
            where none applies.
        base_forces: actuator forces without payload (N, 6) (N).
        unit_forces: actuator forces per unit payload scale (N, 6) (N).
        feasible_without_payload: (N,) bool, gravity alone within the bounds.
        ok: (N,) bool, the workspace mask of :func:`evaluate`.
    """

    scale: np.ndarray
    limiting_actuator: np.ndarray
    base_forces: np.ndarray
    unit_forces: np.ndarray
    feasible_without_payload: np.ndarray
    ok: np.ndarray


def force_capability(robot: Hexapod, poses: npt.ArrayLike, direction: npt.ArrayLike,
                     branch: npt.ArrayLike | None = None, threads: int = 1) -> ForceCapability:
    """Largest payload along a wrench direction that the actuators can hold, per pose.

    Solves, per pose, the linear program ``max s`` s.t. ``|tau0 + s tau1|_i <=
    max_actuator_force`` for all i, where ``tau0`` holds gravity and the springs of the
    joint effects (:func:`evaluate`'s statics) and ``tau1`` the unit payload ``direction``
    (wrench on the platform, world axes, about the origin). The LP is one-dimensional, so its exact solution is the smallest
    positive crossing ``(sign(tau1_i) tau_max - tau0_i) / tau1_i`` over i.

    Args:
        robot: a Hexapod.
        poses: (N, 6) poses.
        direction: payload wrench direction (6,), e.g. ``(0, 0, -m g, 0, 0, 0)``
            for a mass m at the origin (then ``scale`` is in units of m). Any
            scale: the result scales inversely.
        branch: as in :func:`evaluate`.
        threads: as in :func:`evaluate`.

    Raises:
        InputError: malformed inputs, a zero direction, or Coulomb friction or effort
            limits in the robot's effects (the generic
            :func:`hexapod_pin.core.workspace_maps.force_capability` models them).
    """
    direction = as_array(direction, (6,), "direction")
    if not np.any(direction):
        raise InputError("direction", direction, "must not be zero")
    effects = robot.effects
    if effects.coulomb.any() or np.any(effects.effort_limit < robot.geometry.max_actuator_force):
        raise InputError("robot", effects, "drive effects at rest (Coulomb friction, effort "
                         "limits) that these compiled maps do not model: use "
                         "hexapod_pin.core.workspace_maps.force_capability")
    base = evaluate(robot, poses, None, branch, threads, singularity=False)
    with_unit = evaluate(robot, base.poses, direction, branch, threads, singularity=False)
    tau0 = base.static_forces
    tau1 = with_unit.static_forces - tau0
    limit = robot.geometry.max_actuator_force
    feasible0 = base.ok & np.all(np.abs(tau0) <= limit, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = np.where(tau1 > 0, (limit - tau0) / tau1,
                         np.where(tau1 < 0, (-limit - tau0) / tau1, np.inf))
    bound = np.where(np.isfinite(bound), bound, np.inf)
    limiting = np.argmin(bound, axis=1)
    scale = bound[np.arange(bound.shape[0]), limiting]
    usable = feasible0 & np.isfinite(scale)
    scale = np.where(usable, np.maximum(scale, 0.0), 0.0)
    limiting = np.where(usable, limiting, -1)
    return ForceCapability(scale, limiting, tau0, np.where(base.ok[:, None], tau1, 0.0),
                           feasible0, base.ok)


def sample_poses(rng: np.random.Generator, n: int, low: npt.ArrayLike,
                 high: npt.ArrayLike) -> np.ndarray:
    """Uniform random poses in the box ``low <= pose <= high`` (each (6,)), shape (n, 6)."""
    low, high = as_array(low, (6,), "low"), as_array(high, (6,), "high")
    if np.any(high < low):
        raise InputError("high", high, "must be >= low componentwise")
    return rng.uniform(low, high, size=(int(n), 6))


def leg_reachable(robot: Hexapod, poses: npt.ArrayLike,
                  branch: npt.ArrayLike | None = None) -> np.ndarray:
    """Per-leg reach masks (N, 6): leg i can reach its platform point (strokes ignored)."""
    poses = as_array(poses, (6,), "poses", batch=True)
    out = np.empty((poses.shape[0], 6), dtype=bool)
    signs = batch.batch_signs(branch, poses.shape[0])
    for start in range(0, poses.shape[0], CHUNK):
        sl = slice(start, start + CHUNK)
        chunk_signs = signs[sl] if signs.shape[0] > 1 else signs
        out[sl] = batch.leg_reachable_batch(robot.kinematics.geo, poses[sl], chunk_signs)
    return out


def volume(robot: Hexapod, n_samples: int, center: npt.ArrayLike, half_extent: npt.ArrayLike,
           orientation: npt.ArrayLike = (0.0, 0.0, 0.0), max_condition: float | None = None,
           seed: int = 0, threads: int = 1, legs: npt.ArrayLike | None = None) -> VolumeEstimate:
    """Monte-Carlo volume of the constant-orientation workspace inside a box.

    A position counts when the pose is ``ok`` (reachable, within the strokes,
    regular) and, with ``max_condition``, ``cond(J) <= max_condition`` (the
    well-conditioned workspace). With ``legs`` (carriage indices), it counts
    instead when those legs reach their platform points, strokes ignored (the
    reachable set of a leg is then a cylinder of radius ``leg_length`` about
    its rail line, shifted by the platform point: a check with a closed form).
    The standard error is the binomial one, ``box * sqrt(p (1 - p) / n)``.

    Args:
        robot: a Hexapod.
        n_samples: number of uniform samples (>= 1).
        center: the box's centre (3,) (m).
        half_extent: the box's half side lengths (3,) (m).
        orientation: roll, pitch, yaw (rad).
        max_condition: optional threshold on the condition number.
        seed: random seed (the estimate is reproducible).
        threads: as in :func:`evaluate`.
        legs: optional carriage indices, see above.

    Returns:
        :class:`VolumeEstimate` (m^3).
    """
    if int(n_samples) != n_samples or n_samples < 1:
        raise InputError("n_samples", n_samples, "must be a positive integer")
    center = as_array(center, (3,), "center")
    half = as_array(half_extent, (3,), "half_extent")
    if np.any(half <= 0):
        raise InputError("half_extent", half_extent, "must be > 0")
    rng = generator(seed)
    pos = rng.uniform(center - half, center + half, size=(int(n_samples), 3))
    rpy = np.broadcast_to(as_array(orientation, (3,), "orientation"), pos.shape)
    poses = np.concatenate([pos, rpy], axis=1)
    if legs is not None:
        legs = np.atleast_1d(np.asarray(legs))
        if legs.size == 0 or not np.all(np.isin(legs, np.arange(6))):
            raise InputError("legs", legs, "expected carriage indices in 0..5")
        inside = np.all(leg_reachable(robot, poses)[:, legs.astype(int)], axis=1)
        return volume_estimate(inside, float(np.prod(2 * half)))
    measures = evaluate(robot, poses, threads=threads, singularity=False, statics=False)
    inside = measures.ok
    if max_condition is not None:
        inside = inside & (measures.condition_number <= max_condition)
    return volume_estimate(inside, float(np.prod(2 * half)))

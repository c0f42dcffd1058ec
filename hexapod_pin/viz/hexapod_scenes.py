"""Scenes of the hexapod from platform poses: configurations on chosen leg branches,
trajectories of poses, simulation results.

The generic scenes (:mod:`hexapod_pin.viz.scenes`) take Pinocchio configurations;
these helpers make them from platform poses through the robot's public API
(``robot.configuration(pose, branch)``, ``robot.inverse_kinematics(pose, branch,
check_limits)``, ``robot.model``).

Conventions: poses ``(x, y, z, roll, pitch, yaw)`` (m, rad), carriage positions
``q_i`` (m) along the rail direction ``u_k``, actuator forces (N) along ``+u_k``,
closure forces (N, world axes) of each leg on the platform; times in seconds.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..core.checks import as_array
from ..errors import InputError
from .meshcat_scene import Scene
from .scenes import check_times, keyframes, trajectory_scene


def hexapod_configurations(robot: Any, poses: ArrayLike,
                           carriages: ArrayLike | None = None) -> np.ndarray:
    """Pinocchio configurations (N, nq) of the hexapod for platform poses (N, 6).

    Args:
        robot: a :class:`hexapod_pin.Hexapod`.
        poses: platform poses (m, rad), shape (N, 6) or (6,).
        carriages: carriage positions (N, 6) or (6,) (m) the configurations must
            have: for each carriage the inverse-kinematics root nearest to it is
            taken (needed for assembly modes off the home branch); default the
            home branch.

    Raises:
        UnreachablePoseError: a pose out of reach.
        InputError: wrong shapes.
        AssemblyError: the closed form misses the closures.
    """
    poses = np.atleast_2d(as_array(poses, (6,), "poses", batch=np.ndim(poses) == 2))
    if carriages is None:
        return np.array([robot.configuration(p) for p in poses])
    carriages = np.atleast_2d(as_array(carriages, (6,), "carriages",
                                       batch=np.ndim(carriages) == 2))
    if len(carriages) != len(poses):
        raise InputError("carriages", carriages, f"expected {len(poses)} rows")
    out = []
    for pose, target in zip(poses, carriages):
        plus = robot.inverse_kinematics(pose, branch=np.ones(6), check_limits=False)
        minus = robot.inverse_kinematics(pose, branch=-np.ones(6), check_limits=False)
        branch = np.where(np.abs(plus - target) <= np.abs(minus - target), 1.0, -1.0)
        out.append(robot.configuration(pose, branch=branch))
    return np.array(out)


def hexapod_trajectory_scene(robot: Any, times: ArrayLike, poses: ArrayLike, *,
                             carriages: ArrayLike | None = None,
                             actuator_forces: ArrayLike | None = None,
                             fps: float | None = 30.0, **options: Any) -> Scene:
    """:func:`trajectory_scene` of the hexapod from platform poses.

    The samples are thinned to ``fps`` key frames first, then turned into
    Pinocchio configurations by :func:`hexapod_configurations`.

    Args:
        robot: a :class:`hexapod_pin.Hexapod`.
        times: sample times (N,), s, strictly increasing.
        poses: platform poses (N, 6) (m, rad).
        carriages: carriage positions (N, 6) (m) choosing the leg branches;
            default the home branch.
        actuator_forces: carriage forces (N, 6), N, drawn along the rails.
        fps: key frames per second; ``None`` keeps every sample.
        **options: passed on to :func:`trajectory_scene` (``caption``,
            ``frames``, ``force_scale``, ``closure_forces`` (N, 6, 3), ...).

    Raises:
        InputError: bad shape, non-finite or non-real values.
        UnreachablePoseError: a leg cannot reach the pose.
    """
    poses = as_array(poses, (6,), "poses", batch=True)
    t = check_times(times, len(poses))
    keep = keyframes(t, fps)
    carriages_kept = None
    if carriages is not None:
        carriages_kept = as_array(carriages, (6,), "carriages", batch=True)
        if len(carriages_kept) != len(poses):
            raise InputError("carriages", carriages, f"expected {len(poses)} rows")
        carriages_kept = carriages_kept[keep]
    qs = hexapod_configurations(robot, poses[keep], carriages_kept)
    if actuator_forces is not None:
        actuator_forces = as_array(actuator_forces, (len(poses), 6), "actuator_forces")[keep]
    closure_forces = options.pop("closure_forces", None)
    if closure_forces is not None:
        closure_forces = as_array(closure_forces, (len(poses), 6, 3), "closure_forces")[keep]
    return trajectory_scene(robot, t[keep], qs, actuator_forces=actuator_forces,
                            closure_forces=closure_forces, fps=None, **options)


def simulation_scene(robot: Any, trajectory: Any, *, forces: bool = True, **options: Any) -> Scene:
    """Animation of a simulated hexapod motion
    (:class:`hexapod_pin.hexapod.simulation.Trajectory`, or any object with its attributes).

    Reads the attributes ``times`` (N,) and either ``configurations`` (N, nq)
    (the simulated tree configurations, drawn as they are) or ``poses`` (N, 6)
    with ``q`` (N, 6) carriage positions choosing the leg branches; with
    ``forces``, also ``actuator_forces`` (N, 6).

    Raises:
        InputError: ``trajectory`` lacks those attributes or has wrong shapes.
    """
    try:
        times, poses = trajectory.times, trajectory.poses
    except AttributeError:
        raise InputError("trajectory", trajectory, "needs attributes times and poses") from None
    q = getattr(trajectory, "q", None)
    tau = getattr(trajectory, "actuator_forces", None) if forces else None
    configurations = getattr(trajectory, "configurations", None)
    if configurations is not None and np.shape(configurations)[-1:] == (robot.model.nq,):
        return trajectory_scene(robot, times, configurations, actuator_forces=tau, **options)
    return hexapod_trajectory_scene(robot, times, poses, carriages=q, actuator_forces=tau,
                                    **options)


def write_hexapod_trajectory_html(path: str | os.PathLike, robot: Any, times: ArrayLike,
                                  poses: ArrayLike, **options: Any) -> Path:
    """Write :func:`hexapod_trajectory_scene` (same arguments) to HTML; returns its path."""
    return hexapod_trajectory_scene(robot, times, poses, **options).write(path)


def write_simulation_html(path: str | os.PathLike, robot: Any, trajectory: Any,
                          **options: Any) -> Path:
    """Write :func:`simulation_scene` (same arguments) to HTML; returns its path."""
    return simulation_scene(robot, trajectory, **options).write(path)

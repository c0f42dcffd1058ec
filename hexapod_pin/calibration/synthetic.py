"""Synthetic calibration data: what an instrument would measure on a perturbed robot.

The controller commands world poses with the NOMINAL robot (its inverse kinematics gives
the readings ``q``); the TRUE (as-built) robot, driven to those readings, assembles
somewhere else. With ``route="pinocchio"`` that pose comes from the Pinocchio tree of the
true robot: the nominal tree configuration of the commanded pose with the carriages set
to ``q``, closed by :meth:`~hexapod_pin.core.closed_loop.ClosedLoopModel.assemble`
(carriages held) and read from the platform's free-flyer; with ``route="closed_form"``
from :func:`~hexapod_pin.hexapod.geometry.closure_pose` of the true chains. The
instrument then sees the target frame ``T_IT = T_WI^-1 T_WP T_PT`` (or target points),
with Gaussian noise: ``position_noise`` (m, per axis) on positions, ``rotation_noise``
(rad, per axis, a small rotation applied in the instrument frame) on orientations, and
``actuator_noise`` (m) on the readings.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

from ..core.checks import as_array, generator, of_type, real_number
from ..core.pose import rotation_from_rpy, rpy_from_rotation
from ..errors import AssemblyError, InputError
from ..hexapod.geometry import HexapodGeometry, closure_pose
from ..hexapod.robot import Hexapod
from .model import measured_poses
from .parameters import Frames

ROUTES = ("pinocchio", "closed_form")


@dataclass(frozen=True)
class SyntheticData:
    """Synthetic measurements.

    Attributes:
        commanded: the commanded world poses (N, 6) (m, rad).
        actuators: the readings (N, 6) (m), with their noise.
        true_poses: where the true platform is, world (N, 6).
        poses: measured target poses in the instrument frame (N, 6), noisy.
        exact_poses: the same without noise (N, 6).
        points: measured target points (N, M, 3) in the instrument frame, noisy, or None.
    """

    commanded: np.ndarray
    actuators: np.ndarray
    true_poses: np.ndarray
    poses: np.ndarray
    exact_poses: np.ndarray
    points: np.ndarray | None


def frames_of(instrument: npt.ArrayLike | None, target: npt.ArrayLike | None) -> Frames:
    """:class:`~.parameters.Frames` of two poses (6,) (None: the identity)."""
    inst = np.zeros(6) if instrument is None else as_array(instrument, (6,), "instrument")
    targ = np.zeros(6) if target is None else as_array(target, (6,), "target")
    return Frames(rotation_from_rpy(inst[3:]), inst[:3].copy(),
                  rotation_from_rpy(targ[3:]), targ[:3].copy())


def random_as_built(geometry: HexapodGeometry, scale: float = 1e-3,
                    seed: int | np.random.Generator = 0) -> HexapodGeometry:
    """A random as-built robot for simulation studies: ``geometry`` with independent
    Gaussian deviations of standard deviation ``scale`` in every chain parameter
    (:meth:`~hexapod_pin.hexapod.geometry.HexapodGeometry.as_built`: line points (m),
    line directions (rad, small rotations), sensor zero offsets (m), leg lengths (m),
    platform joints (m); drawn in that order).

    Args:
        geometry: the nominal geometry.
        scale: standard deviation of the deviations (m, or rad), >= 0.
        seed: an integer seed or a numpy ``Generator``.

    Returns:
        the as-built :class:`~hexapod_pin.hexapod.geometry.HexapodGeometry`.

    Raises:
        InputError: ``scale`` negative or not a finite number, ``seed`` neither an
            integer >= 0 nor a Generator.
    """
    scale = real_number(scale, "scale", minimum=0.0, strict=False)
    rng = generator(seed)
    return geometry.as_built(
        line_points=rng.normal(0.0, scale, (6, 3)),
        line_directions=rng.normal(0.0, scale, (6, 3)),
        sensor_offsets=rng.normal(0.0, scale, 6),
        leg_lengths=rng.normal(0.0, scale, 6),
        platform_joints=rng.normal(0.0, scale, (6, 3)))


def true_pose_pinocchio(nominal: Hexapod, true: Hexapod, pose: np.ndarray,
                        q: np.ndarray) -> np.ndarray:
    """The true robot's platform pose at readings ``q`` by its Pinocchio tree, started from
    the nominal tree configuration of ``pose``."""
    start = nominal.configuration(pose)
    start[true.indices.carriage_q] = q
    done = true.model.assemble(start)
    return true.pose_from_configuration(done.q)


def synthetic_measurements(robot: Hexapod, true_geometry: HexapodGeometry,
                           commanded: npt.ArrayLike, *, instrument: npt.ArrayLike | None = None,
                           target: npt.ArrayLike | None = None, target_points: npt.ArrayLike | None = None,
                           position_noise: float = 0.0, rotation_noise: float = 0.0,
                           actuator_noise: float = 0.0, seed: int = 0,
                           route: str = "pinocchio") -> SyntheticData:
    """Measurements of a perturbed robot (see the module doc).

    Args:
        robot: the nominal robot (computes the readings of the commanded poses).
        true_geometry: the as-built geometry that produces the measurements.
        commanded: world poses (N, 6) (m, rad) reachable by the nominal robot.
        instrument: true pose of the instrument frame in the world (6,), default identity.
        target: true pose of the target frame in the platform frame (6,), default identity.
        target_points: (M, 3) points in the target frame (m) to measure as well, or None.
        position_noise: standard deviation of the measured target positions (m).
        rotation_noise: standard deviation of the measured target orientations (rad).
        actuator_noise: standard deviation of the readings (m).
        seed: of the noise generator.
        route: ``"pinocchio"`` or ``"closed_form"``.

    Returns:
        :class:`SyntheticData`.

    Raises:
        InputError: malformed arguments, or a commanded pose the nominal robot cannot reach.
        AssemblyError: the true robot does not assemble at some readings.
    """
    robot = of_type(robot, Hexapod, "robot")
    true_geometry = of_type(true_geometry, HexapodGeometry, "true_geometry")
    if route not in ROUTES:
        raise InputError("route", route, f"expected one of {ROUTES}")
    for name, value in (("position_noise", position_noise), ("rotation_noise", rotation_noise),
                        ("actuator_noise", actuator_noise)):
        real_number(value, name, minimum=0.0, strict=False)
    rng = generator(seed)
    commanded = as_array(commanded, (6,), "commanded", batch=True)
    batch = robot.inverse_kinematics_batch(commanded)
    if not batch.ok.all():
        bad = int(np.flatnonzero(~batch.ok)[0])
        raise InputError("commanded", commanded[bad], f"pose {bad} is out of the nominal "
                         "robot's reach or strokes")
    q = batch.actuator_positions
    true = Hexapod(true_geometry) if route == "pinocchio" else None
    chains = true_geometry.chain_geometry
    world = np.empty_like(commanded)
    for k, (pose, qk) in enumerate(zip(commanded, q)):
        if true is not None:
            world[k] = true_pose_pinocchio(robot, true, pose, qk)
        else:
            found = closure_pose(chains, qk, pose)
            if found is None:
                raise AssemblyError(f"the true robot does not assemble at pose {k}",
                                    float("nan"), 0)
            world[k] = found
    frames = frames_of(instrument, target)
    rot = rotation_from_rpy(world[:, 3:])
    exact = measured_poses(rot, world[:, :3], frames)
    n = commanded.shape[0]
    noisy = exact.copy()
    noisy[:, :3] += rng.normal(scale=position_noise, size=(n, 3))
    turn = Rotation.from_rotvec(rng.normal(scale=rotation_noise, size=(n, 3))).as_matrix()
    noisy[:, 3:] = rpy_from_rotation(turn @ rotation_from_rpy(exact[:, 3:]))
    points = None
    if target_points is not None:
        tp = as_array(target_points, (3,), "target_points", batch=True)
        in_platform = tp @ frames.target_rotation.T + frames.target_translation
        world_pts = world[:, None, :3] + np.einsum("nab,mb->nma", rot, in_platform)
        points = (world_pts - frames.instrument_translation) @ frames.instrument_rotation
        points = points + rng.normal(scale=position_noise, size=points.shape)
    readings = q + rng.normal(scale=actuator_noise, size=q.shape)
    return SyntheticData(commanded, readings, world, noisy, exact, points)

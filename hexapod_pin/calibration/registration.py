"""A first guess of the instrument frame: a rigid registration of the measurements onto the
nominal robot.

The nominal forward kinematics of each reading places the target origin (pose
measurements) or the target points (point measurements) in the robot's world, with the
target frame at its guess; the instrument saw the same points in its own frame. The rigid
motion ``x_world = R x_instrument + t`` that fits them best in the least-squares sense is
the Kabsch (Procrustes) solution: with the centred point sets ``X`` (instrument) and ``Y``
(world), ``H = X^T Y = U S V^T`` and ``R = V diag(1, 1, det(V U^T)) U^T``.

With pose measurements the rotation is the chordal mean of ``R_WP R_PT R_IT^T`` over the
measurements (the orientations pin it far better than positions spread over a few
centimetres) and the translation the mean of ``x_world - R x_instrument``.

It puts the start of the identification within the deviations of the robot from its
drawing, wherever the instrument stands (a tracker metres away, turned by any angle).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..core.pose import rotation_from_rpy, rpy_from_rotation
from ..errors import AssemblyError
from ..hexapod.robot import Hexapod
from .problem import Measurements

#: fewest registered points (non-collinear ones are needed)
MIN_POINTS = 3


def rigid_fit(source: np.ndarray, destination: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rotation (3, 3) and translation (3,) with ``destination ~ R source + t`` in the
    least-squares sense (Kabsch; a proper rotation), for point sets (K, 3)."""
    cs, cd = source.mean(axis=0), destination.mean(axis=0)
    u, _, vt = np.linalg.svd((source - cs).T @ (destination - cd))
    fix = np.diag([1.0, 1.0, float(np.sign(np.linalg.det(vt.T @ u.T)) or 1.0)])
    rot = vt.T @ fix @ u.T
    return rot, cd - rot @ cs


def register_instrument(robot: Hexapod, data: Measurements,
                        target: npt.ArrayLike | None = None) -> np.ndarray:
    """A guess of the instrument pose in the robot's world (6,) (m, rad) from measurements.

    Args:
        robot: the nominal robot.
        data: the measurements.
        target: the guessed target pose in the platform frame (6,), default the identity.

    Returns:
        the pose ``(x, y, z, roll, pitch, yaw)``; the identity when fewer than
        :data:`MIN_POINTS` readings assemble on the nominal robot.
    """
    targ = np.zeros(6) if target is None else np.asarray(target, dtype=float)
    if data.poses is not None:
        local = targ[None, :3]                                     # target origin
    else:
        local = data.point_arrays()[1] @ rotation_from_rpy(targ[3:]).T + targ[:3]
    world, measured, turns = [], [], []
    for k, q in enumerate(data.actuators):
        try:
            pose = robot.forward_kinematics(q)
        except AssemblyError:
            continue
        rot = rotation_from_rpy(pose[3:])
        world.append(pose[:3] + local @ rot.T)
        if data.poses is not None:
            measured.append(data.poses[k, None, :3])
            # R_WI ~ R_WP R_PT R_IT^T for this measurement
            turns.append(rot @ rotation_from_rpy(targ[3:])
                         @ rotation_from_rpy(data.poses[k, 3:]).T)
        else:
            measured.append(data.point_arrays()[0][k])
    if len(world) < MIN_POINTS:
        return np.zeros(6)
    source, destination = np.concatenate(measured), np.concatenate(world)
    if turns:
        rot = nearest_rotation(np.sum(turns, axis=0))
        trans = np.mean(destination - source @ rot.T, axis=0)
    else:
        rot, trans = rigid_fit(source, destination)
    return np.concatenate([trans, rpy_from_rotation(rot)])


def nearest_rotation(mat: np.ndarray) -> np.ndarray:
    """The proper rotation nearest to ``mat`` (3, 3) in the Frobenius norm (the chordal
    mean of rotations whose sum is ``mat``)."""
    u, _, vt = np.linalg.svd(mat)
    return u @ np.diag([1.0, 1.0, float(np.sign(np.linalg.det(u @ vt)) or 1.0)]) @ vt

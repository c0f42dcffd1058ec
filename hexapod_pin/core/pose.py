"""Platform poses and twists: rotations and their conversions (vectorised numpy).

A pose is ``(x, y, z, roll, pitch, yaw)``: the position of the platform origin
in the world (m) and the rotation ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (rad) from
platform axes to world axes. A twist is ``(v, w)``: the linear velocity of the
platform origin and the angular velocity, both in world axes (m/s, rad/s).
"""

from __future__ import annotations

import math

import numpy as np



def rotation_from_rpy(rpy: np.ndarray) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` for ``rpy`` of shape (..., 3) -> (..., 3, 3)."""
    rpy = np.asarray(rpy, dtype=float)
    cr, sr = np.cos(rpy[..., 0]), np.sin(rpy[..., 0])
    cp, sp = np.cos(rpy[..., 1]), np.sin(rpy[..., 1])
    cy, sy = np.cos(rpy[..., 2]), np.sin(rpy[..., 2])
    out = np.empty(rpy.shape[:-1] + (3, 3))
    out[..., 0, 0] = cy * cp
    out[..., 0, 1] = cy * sp * sr - sy * cr
    out[..., 0, 2] = cy * sp * cr + sy * sr
    out[..., 1, 0] = sy * cp
    out[..., 1, 1] = sy * sp * sr + cy * cr
    out[..., 1, 2] = sy * sp * cr - cy * sr
    out[..., 2, 0] = -sp
    out[..., 2, 1] = cp * sr
    out[..., 2, 2] = cp * cr
    return out


def rotation_tuple(roll: float, pitch: float, yaw: float):
    """``Rz(yaw) Ry(pitch) Rx(roll)`` as nested tuples of plain floats (rows), for hot
    scalar code where small numpy arrays cost more than they save."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return ((cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
            (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
            (-sp, cp * sr, cp * cr))


def rpy_from_rotation(rot: np.ndarray) -> np.ndarray:
    """Inverse of :func:`rotation_from_rpy`, pitch in [-pi/2, pi/2]; (..., 3, 3) -> (..., 3).

    At pitch = +-pi/2 (gimbal lock) roll is set to 0 and yaw absorbs the rest.
    """
    rot = np.asarray(rot, dtype=float)
    pitch = np.arctan2(-rot[..., 2, 0], np.hypot(rot[..., 0, 0], rot[..., 1, 0]))
    roll = np.arctan2(rot[..., 2, 1], rot[..., 2, 2])
    yaw = np.arctan2(rot[..., 1, 0], rot[..., 0, 0])
    locked = np.hypot(rot[..., 0, 0], rot[..., 1, 0]) < 1e-12
    if np.any(locked):
        roll = np.where(locked, 0.0, roll)
        yaw = np.where(locked, np.arctan2(-rot[..., 0, 1], rot[..., 1, 1]), yaw)
    return np.stack([roll, pitch, yaw], axis=-1)


def euler_rates_matrix(rpy: np.ndarray) -> np.ndarray:
    """``E`` with ``w = E @ d(rpy)/dt`` (world-axes angular velocity), shape (..., 3, 3)."""
    rpy = np.asarray(rpy, dtype=float)
    cp, sp = np.cos(rpy[..., 1]), np.sin(rpy[..., 1])
    cy, sy = np.cos(rpy[..., 2]), np.sin(rpy[..., 2])
    out = np.zeros(rpy.shape[:-1] + (3, 3))
    out[..., 0, 0] = cy * cp
    out[..., 1, 0] = sy * cp
    out[..., 2, 0] = -sp
    out[..., 0, 1] = -sy
    out[..., 1, 1] = cy
    out[..., 2, 2] = 1.0
    return out


def skew(vec: np.ndarray) -> np.ndarray:
    """Cross-product matrix of ``vec`` (..., 3) -> (..., 3, 3)."""
    vec = np.asarray(vec, dtype=float)
    out = np.zeros(vec.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -vec[..., 2], vec[..., 1]
    out[..., 1, 0], out[..., 1, 2] = vec[..., 2], -vec[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -vec[..., 1], vec[..., 0]
    return out


def rotation_from_quaternion(x: float, y: float, z: float, w: float) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion ``(x, y, z, w)`` (Pinocchio's order)."""
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])

"""Platform poses and twists: the rotation conventions, written once.

A pose is ``(x, y, z, roll, pitch, yaw)``: the position of the platform origin
in the world (m) and the rotation ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (rad) from
platform axes to world axes. A twist is ``(v, w)``: the linear velocity of the
platform origin and the angular velocity, both in world axes (m/s, rad/s).
Quaternions are unit quaternions; :func:`rotation_quat` and :func:`quaternion_rpy` use
``(w, x, y, z)``, :func:`rotation_from_quaternion` Pinocchio's ``(x, y, z, w)``.

The conversions are compiled scalar kernels (:func:`rotation_rpy`, :func:`rotation_quat`,
:func:`quaternion_rpy`, :func:`rpy_of`: rotations as 9 row-major floats), called by the
robots' compiled closed forms; the array functions (:func:`rotation_from_rpy`,
:func:`rpy_from_rotation`, :func:`rotation_from_quaternion`) run the same kernels over
any number of rotations.
"""

from __future__ import annotations

import math

import numpy as np

from .compiled import LEAN_FLAGS, jit_inline, jit_lean, kernel


@jit_inline
def rotation_rpy(roll, pitch, yaw, rot):
    """``rot`` (9,) = ``Rz(yaw) Ry(pitch) Rx(roll)`` row-major."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rot[0], rot[1], rot[2] = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    rot[3], rot[4], rot[5] = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
    rot[6], rot[7], rot[8] = -sp, cp * sr, cp * cr


@jit_inline
def rotation_quat(w, x, y, z, rot):
    """``rot`` (9,) row-major of a quaternion ``(w, x, y, z)`` of any non-zero norm."""
    s = 2.0 / (w * w + x * x + y * y + z * z)
    rot[0], rot[1], rot[2] = 1.0 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)
    rot[3], rot[4], rot[5] = s * (x * y + z * w), 1.0 - s * (x * x + z * z), s * (y * z - x * w)
    rot[6], rot[7], rot[8] = s * (x * z - y * w), s * (y * z + x * w), 1.0 - s * (x * x + y * y)


@jit_inline
def quaternion_rpy(roll, pitch, yaw):
    """Unit quaternion ``(w, x, y, z)`` of ``Rz(yaw) Ry(pitch) Rx(roll)``, ``w >= 0``."""
    c1, s1 = math.cos(0.5 * roll), math.sin(0.5 * roll)
    c2, s2 = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    c3, s3 = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    qw = c1 * c2 * c3 + s1 * s2 * s3
    qx = s1 * c2 * c3 - c1 * s2 * s3
    qy = c1 * s2 * c3 + s1 * c2 * s3
    qz = c1 * c2 * s3 - s1 * s2 * c3
    if qw < 0.0:
        return -qw, -qx, -qy, -qz
    return qw, qx, qy, qz


@jit_inline
def rpy_of(rot):
    """``(roll, pitch, yaw)`` of ``rot`` (9,), pitch in [-pi/2, pi/2]; at gimbal lock
    roll = 0 and yaw takes the rest."""
    horizontal = math.hypot(rot[0], rot[3])
    pitch = math.atan2(-rot[6], horizontal)
    if horizontal < 1e-12:
        return 0.0, pitch, math.atan2(-rot[1], rot[4])
    return math.atan2(rot[7], rot[8]), pitch, math.atan2(rot[3], rot[0])


@kernel(LEAN_FLAGS, work=0)
def _rotations_rpy(rpy, out):
    for k in range(rpy.shape[0]):
        rotation_rpy(rpy[k, 0], rpy[k, 1], rpy[k, 2], out[k])


@kernel(LEAN_FLAGS, work=0)
def _rpys(rot, out):
    for k in range(rot.shape[0]):
        out[k, 0], out[k, 1], out[k, 2] = rpy_of(rot[k])


def rotation_from_rpy(rpy) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` for ``rpy`` of shape (..., 3) -> (..., 3, 3)."""
    rpy = np.asarray(rpy, dtype=float)
    flat = np.ascontiguousarray(rpy.reshape(-1, 3))
    out = np.empty((flat.shape[0], 9))
    _rotations_rpy(flat, out)
    return out.reshape(rpy.shape[:-1] + (3, 3))


def rpy_from_rotation(rot) -> np.ndarray:
    """Inverse of :func:`rotation_from_rpy`, pitch in [-pi/2, pi/2]; (..., 3, 3) -> (..., 3).

    At pitch = +-pi/2 (gimbal lock) roll is set to 0 and yaw absorbs the rest.
    """
    rot = np.asarray(rot, dtype=float)
    flat = np.ascontiguousarray(rot.reshape(-1, 9))
    out = np.empty((flat.shape[0], 3))
    _rpys(flat, out)
    return out.reshape(rot.shape[:-2] + (3,))


def rotation_from_quaternion(x: float, y: float, z: float, w: float) -> np.ndarray:
    """Rotation matrix (3, 3) of a quaternion ``(x, y, z, w)`` (Pinocchio's order)."""
    out = np.empty(9)
    rotation_quat(float(w), float(x), float(y), float(z), out)
    return out.reshape(3, 3)


@jit_inline
def euler_rates(pitch, yaw, out):
    """``out`` (3, 3) = ``E`` with ``w = E @ d(rpy)/dt`` (world-axes angular velocity of
    ``Rz(yaw) Ry(pitch) Rx(roll)``; ``E`` does not depend on the roll)."""
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    out[0, 0], out[0, 1], out[0, 2] = cy * cp, -sy, 0.0
    out[1, 0], out[1, 1], out[1, 2] = sy * cp, cy, 0.0
    out[2, 0], out[2, 1], out[2, 2] = -sp, 0.0, 1.0


@jit_lean
def _euler_rates_many(rpy, out):
    for k in range(rpy.shape[0]):
        euler_rates(rpy[k, 1], rpy[k, 2], out[k])


def euler_rates_matrix(rpy: np.ndarray) -> np.ndarray:
    """``E`` with ``w = E @ d(rpy)/dt`` (world-axes angular velocity), shape (..., 3, 3)
    (:func:`euler_rates`)."""
    rpy = np.asarray(rpy, dtype=float)
    flat = np.ascontiguousarray(rpy.reshape(-1, 3))
    out = np.empty((flat.shape[0], 3, 3))
    _euler_rates_many(flat, out)
    return out.reshape(rpy.shape[:-1] + (3, 3))


def skew(vec: np.ndarray) -> np.ndarray:
    """Cross-product matrix of ``vec`` (..., 3) -> (..., 3, 3)."""
    vec = np.asarray(vec, dtype=float)
    out = np.zeros(vec.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -vec[..., 2], vec[..., 1]
    out[..., 1, 0], out[..., 1, 2] = vec[..., 2], -vec[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -vec[..., 1], vec[..., 0]
    return out

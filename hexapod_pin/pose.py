"""Platform poses and twists: conversions and input checks (vectorised numpy).

A pose is ``(x, y, z, roll, pitch, yaw)``: the position of the platform origin
in the world (m) and the rotation ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (rad) from
platform axes to world axes. A twist is ``(v, w)``: the linear velocity of the
platform origin and the angular velocity, both in world axes (m/s, rad/s).
"""

from __future__ import annotations

import math

import numpy as np

from .errors import InputError


def as_array(value, shape_tail: tuple[int, ...], name: str, batch: bool = False) -> np.ndarray:
    """Check and convert a numeric input.

    Args:
        value: array-like.
        shape_tail: the expected shape (single) or trailing shape (batch).
        name: argument name for the error message.
        batch: when True, accept ``(N,) + shape_tail``.

    Raises:
        InputError: not numeric, wrong shape, or NaN / inf entries.
    """
    if type(value) is np.ndarray and value.dtype == np.float64 and value.flags.c_contiguous:
        arr = value                       # what np.ascontiguousarray would return
    else:
        try:
            arr = np.ascontiguousarray(value, dtype=float)
        except (TypeError, ValueError):
            raise InputError(name, value, "not numeric") from None
    expected = ("N",) + shape_tail if batch else shape_tail
    ok = (arr.ndim == len(shape_tail) + 1 and arr.shape[1:] == shape_tail) if batch \
        else arr.shape == shape_tail
    if not ok:
        raise InputError(name, value, f"expected shape {expected}, got {arr.shape}")
    if not np.isfinite(arr).all():
        bad = np.argwhere(~np.isfinite(arr))
        raise InputError(name, value, f"contains NaN or inf at {bad[:5].tolist()}")
    return arr


def vec6(value, name: str) -> np.ndarray:
    """A C-contiguous float64 (6,) array, for the compiled kernels' fast path.

    A float64 array of shape (6,) is passed through (copied only when not contiguous);
    anything else goes through :func:`as_array`. Finiteness of a passed-through array is
    NOT checked here: the kernels check it and the caller then re-validates with
    :func:`as_array`, which raises the :class:`InputError`.
    """
    if type(value) is np.ndarray and value.dtype == np.float64 and value.shape == (6,):
        return value if value.flags.c_contiguous else np.ascontiguousarray(value)
    return as_array(value, (6,), name)


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


def check_signs(branch, home: np.ndarray, name: str = "branch") -> np.ndarray:
    """Validate a branch: ``len(home)`` values, each +1 or -1; ``None`` -> a copy of ``home``.

    Raises:
        InputError: wrong length, or a value other than +1 / -1.
    """
    if branch is None:
        return np.array(home, dtype=float)
    expected = f"expected {len(home)} values, each +1 or -1"
    try:
        arr = np.asarray(branch, dtype=float)
    except (TypeError, ValueError):
        raise InputError(name, branch, expected) from None
    if arr.shape != (len(home),) or not np.all((arr == 1.0) | (arr == -1.0)):
        raise InputError(name, branch, expected)
    return arr

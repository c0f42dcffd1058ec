"""Geometric paths through platform waypoints: C2 in their parameter, rotations on SO(3).

A :class:`GeometricPath` maps the path parameter ``s`` (m, see below) to a platform pose
``x(s)`` and gives, in the robot's twist convention, the path tangent
``xi(s) = twist / s_dot`` and its derivative ``xi'(s) = d xi / ds``, so that along a
timing law ``s(t)``::

    twist     = xi(s) s_dot
    twist_dot = xi(s) s_ddot + xi'(s) s_dot^2

The pose is the selection ``pose_axes`` of ``(x, y, z, roll, pitch, yaw)`` of the robot
(:func:`~hexapod_pin.core.robot_api.pose_layout`; without axes, a pose of 6 values is
``(x, y, z, roll, pitch, yaw)`` and one of 3 values ``(x, y, theta)``). Interpolation (each
a natural cubic spline: C2 in ``s``, no curvature at the ends):

* linear components: componentwise cubic spline through the waypoint positions;
* a full rotation (all three angles in the pose, ``R = Rz(yaw) Ry(pitch) Rx(roll)``): a
  cubic spline of the exponential coordinates relative to the first waypoint,
  ``R(s) = R_0 exp([phi(s)]x)`` with ``phi_k = log(R_0^T R_k)``. It is C2 on SO(3)
  (``exp`` is smooth), passes through every waypoint, does not depend on the Euler-angle
  chart, and between two waypoints only it is the geodesic (constant axis). Every
  waypoint must lie less than pi (rad) from the first one. The world angular velocity
  per unit ``s`` is ``omega_s = R_0 J_l(phi) phi'`` with ``J_l`` the left Jacobian of
  SO(3); its derivative is computed in closed form (series near ``|phi| = 0``);
* otherwise each selected angle (e.g. ``theta`` in the plane): a cubic spline of the
  angle, the waypoint angles unwrapped first (consecutive differences below pi); its rate
  is the matching component of the angular velocity.

The parameter ``s`` runs over ``[0, length]`` with knots at the cumulative chord length
``sqrt(|dp|^2 + (rotation_length |dphi|)^2)`` between waypoints (m), where
``rotation_length`` (m) converts rotation angles to lengths (default: the robot's
characteristic length, its platform radius).
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from ..core.checks import MAX_MAGNITUDE, as_array, real_number
from ..core.description import file_path, read_text
from ..core.pose import rotation_from_rpy, rpy_from_rotation
from ..core.platform_map import POSE_AXES
from ..core.robot_api import SPACE_POSE_AXES, PoseAxesSource, PoseLayout, pose_layout
from ..core.text_formats import check_columns, load_json
from ..errors import DescriptionError, InputError

#: below this rotation angle (rad) the SO(3) Jacobian coefficients use their series
_SERIES_ANGLE = 1e-2
#: largest distance (rad) of a waypoint rotation from the first one
_MAX_ANGLE = np.pi - 1e-6


@dataclass(frozen=True)
class PathSamples:
    """The path and its derivatives at N values of ``s``.

    Attributes:
        s: (N,) path parameter (m).
        poses: (N, dim) platform poses (m, rad); with a full rotation the Euler angles are
            unwrapped along the samples.
        tangents: (N, dim) ``xi(s)``: the twist per unit path speed (world axes; m/m and
            rad/m).
        curvatures: (N, dim) ``xi'(s) = d xi / ds`` (1/m, rad/m^2).
    """

    s: np.ndarray
    poses: np.ndarray
    tangents: np.ndarray
    curvatures: np.ndarray


class GeometricPath:
    """A C2 path of the platform through waypoints (see the module docstring).

    Args:
        waypoints: (K, dim) poses (m, rad), K >= 2, one column per pose axis in the order
            of ``pose_axes``.
        rotation_length: length (m) weighting rotations in the knot spacing; > 0.
        pose_axes: the pose components: a robot (its ``pose_axes``), a sequence of axes
            (e.g. ``("x", "z")``) or a :class:`~hexapod_pin.core.robot_api.PoseLayout`;
            default from the waypoints' width: 6 ``(x, y, z, roll, pitch, yaw)``, 3
            ``(x, y, theta)``.

    Attributes:
        waypoints: (K, dim) the waypoints as given.
        knots: (K,) the parameter of each waypoint (m), ``knots[0] = 0``.
        length: ``knots[-1]`` (m).
        pose_dim: the number of pose components ``dim``.
        pose_axes: the pose axes (dim names).
        layout: the :class:`~hexapod_pin.core.robot_api.PoseLayout` of the pose.

    Raises:
        InputError: a wrong shape (a width other than the pose axes'; without axes, other
            than 6 or 3), NaN / inf, fewer than two waypoints, two consecutive equal
            waypoints, a rotation pi or more from the first waypoint, bad pose axes.
    """

    def __init__(self, waypoints: npt.ArrayLike, rotation_length: float,
                 pose_axes: PoseAxesSource | None = None) -> None:
        layout = _layout_of(waypoints, pose_axes)
        pts = as_array(waypoints, (layout.dim,), "waypoints", batch=True)
        if len(pts) < 2:
            raise InputError("waypoints", waypoints, "need at least two waypoints")
        rotation_length = real_number(rotation_length, "rotation_length", minimum=0.0)
        self.waypoints = pts.copy()
        self.layout = layout
        self.pose_axes = layout.axes
        self.pose_dim = layout.dim
        self.rotation_length = float(rotation_length)
        lin, ang = layout.linear, layout.angular
        positions = pts[:, lin]
        if layout.full_rotation:
            self._r0: np.ndarray = rotation_from_rpy(pts[0, ang])
            rel = np.einsum("ji,njk->nik", self._r0, rotation_from_rpy(pts[:, ang]))
            angles = Rotation.from_matrix(rel).as_rotvec()
            far = np.flatnonzero(np.linalg.norm(angles, axis=1) >= _MAX_ANGLE)
            if far.size:
                raise InputError("waypoints", pts[far[0]],
                                 f"waypoint {far[0]} is pi or more from the first rotation")
        else:
            self._r0 = np.eye(3)                  # unused: each angle is a scalar
            angles = np.unwrap(pts[:, ang], axis=0)
        steps = np.sqrt(np.sum(np.diff(positions, axis=0) ** 2, axis=1)
                        + (rotation_length ** 2) * np.sum(np.diff(angles, axis=0) ** 2, axis=1))
        same = np.flatnonzero(steps <= 1e-12)
        if same.size:
            raise InputError("waypoints", pts[same[0] + 1],
                             f"waypoints {same[0]} and {same[0] + 1} are equal")
        self.knots = np.concatenate([[0.0], np.cumsum(steps)])
        self.length = float(self.knots[-1])
        self._positions = CubicSpline(self.knots, positions, axis=0, bc_type="natural")
        self._angles = CubicSpline(self.knots, angles, axis=0, bc_type="natural")

    def sample(self, s: npt.ArrayLike) -> PathSamples:
        """Poses, tangents and curvatures at ``s`` (N,) (m), each clipped to [0, length].

        Raises:
            InputError: NaN / inf in ``s``.
        """
        s = np.clip(as_array(np.ravel(np.asarray(s, dtype=float)), (), "s", batch=True),
                    0.0, self.length)
        layout = self.layout
        p = [self._positions(s, nu) for nu in range(3)]
        f = [self._angles(s, nu) for nu in range(3)]
        if layout.full_rotation:
            rot = np.einsum("ij,njk->nik", self._r0, Rotation.from_rotvec(f[0]).as_matrix())
            omega, omega_s = _left_jacobian_terms(f[0], f[1], f[2])
            f = [np.unwrap(rpy_from_rotation(rot), axis=0), omega @ self._r0.T,
                 omega_s @ self._r0.T]
        out = []
        for lin_part, ang_part in zip(p, f):
            arr = np.empty((len(s), layout.dim))
            arr[:, layout.linear] = lin_part
            arr[:, layout.angular] = ang_part
            out.append(arr)
        return PathSamples(s, out[0], out[1], out[2])


def _layout_of(waypoints: npt.ArrayLike, pose_axes: PoseAxesSource | None) -> PoseLayout:
    """The layout of ``pose_axes``, or (None) the default of the waypoints' width, with
    the waypoints' shape checked against it.

    Raises:
        InputError: a shape that is not (K, dim) (named ``waypoints``), bad axes.
    """
    try:
        shape = np.shape(waypoints)
    except ValueError:                   # ragged rows
        shape = ()
    if pose_axes is None:
        if len(shape) != 2 or shape[1] not in (3, 6):
            raise InputError("waypoints", waypoints, "expected shape (K, 6) or (K, 3); give "
                                                     "pose_axes for other poses")
        return pose_layout(int(shape[1]))
    layout = pose_layout(pose_axes)
    if len(shape) != 2 or shape[1] != layout.dim:
        raise InputError("waypoints", waypoints,
                         f"expected shape (K, {layout.dim}): one column per pose axis "
                         f"{layout.axes}, got shape {shape}")
    return layout


def read_waypoints(path: str | os.PathLike[str],
                   pose_axes: PoseAxesSource = SPACE_POSE_AXES) -> np.ndarray:
    """Platform waypoints (K, dim) (m, rad) from a file: a CSV with a header naming at
    least the pose columns, one per pose axis (e.g. ``x, y, z, roll, pitch, yaw`` for the
    hexapod, ``x, z`` for a five-bar in the x-z plane; other columns, e.g. ``t``, are
    ignored; ``#`` comment lines allowed), or a JSON object with ``"pose"`` (K x dim), as in
    the motion files of :mod:`hexapod_pin.motion`.

    Args:
        path: the file (.csv / .txt or .json).
        pose_axes: the pose components (a robot, a sequence of axes or a
            :class:`~hexapod_pin.core.robot_api.PoseLayout`); default the hexapod's six.

    Raises:
        MissingFileError: the file does not exist.
        DescriptionError: another suffix, missing columns, pose columns
            of axes the robot does not have, repeated columns, a value that is not a finite
            number, rows of another width.
        InputError: bad pose axes.
    """
    names = pose_layout(pose_axes).axes
    path = Path(file_path(path))
    suffix = path.suffix.lower()
    if suffix not in (".json", ".csv", ".txt"):
        raise DescriptionError(str(path), "waypoint files are .csv or .json")
    text = read_text(path, "waypoint file")
    try:
        if suffix == ".json":
            data = load_json(text, str(path))
            poses = np.asarray(data["pose"], dtype=float)
        else:
            lines = [ln for ln in text.splitlines()
                     if ln.strip() and not ln.lstrip().startswith("#")]
            rows = list(csv.reader(lines))
            if not rows:
                raise DescriptionError(str(path), "no header row")
            header = check_columns(rows[0], str(path))
            missing = [name for name in names if name not in header]
            if missing:
                raise DescriptionError(str(path), f"missing columns {missing}")
            foreign = [h for h in header if h in POSE_AXES and h not in names]
            if foreign:         # another robot's pose: refused, not silently dropped
                raise DescriptionError(str(path), f"pose columns {foreign} are not this "
                                       f"robot's (its pose axes: {', '.join(names)})")
            cols = [header.index(name) for name in names]
            values = []
            for number, row in enumerate(rows[1:], start=1):
                try:
                    values.append([float(row[c]) for c in cols])
                except (ValueError, IndexError):
                    raise DescriptionError(str(path), f"waypoint {number} (data row {number}"
                                           f" after the header): expected {len(names)} "
                                           f"numbers in columns {', '.join(names)}, got {row}") from None
            poses = np.array(values, dtype=float).reshape(len(values), len(names))
    except DescriptionError:
        raise
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise DescriptionError(str(path), f"malformed waypoints: {exc}") from None
    if poses.ndim != 2 or poses.shape[1] != len(names):
        raise DescriptionError(str(path), f"expected rows of {len(names)} pose values "
                                          f"{names}, got shape {poses.shape}")
    bad = np.flatnonzero(~np.all(np.abs(poses) <= MAX_MAGNITUDE, axis=1))
    if bad.size:
        raise DescriptionError(str(path), f"waypoint {bad[0] + 1} has a value that is not "
                                          f"finite or beyond {MAX_MAGNITUDE:g}: "
                                          f"{poses[bad[0]].tolist()} ({', '.join(names)})")
    return poses


def _left_jacobian_terms(phi, dphi, ddphi):
    """``J_l(phi) phi'`` and its derivative along ``s``, rows (N, 3) (in R_0's axes).

    ``J_l = I + a K + b K^2`` with ``K = [phi]x``, ``a = (1 - cos t) / t^2``,
    ``b = (t - sin t) / t^3``, ``t = |phi|``. Then ``d/ds (J_l phi') = J_l phi'' +
    (phi . phi') (A1 w1 + B1 w2) + b phi' x w1`` with ``w1 = phi x phi'``,
    ``w2 = phi x w1``, ``A1 = a'(t) / t``, ``B1 = b'(t) / t``.
    """
    t2 = np.sum(phi * phi, axis=1)
    t = np.sqrt(t2)
    small = t < _SERIES_ANGLE
    tb = np.where(small, 1.0, t)
    sin_t, cos_t = np.sin(tb), np.cos(tb)
    a = np.where(small, 0.5 - t2 / 24 + t2 ** 2 / 720, (1 - cos_t) / tb ** 2)
    b = np.where(small, 1 / 6 - t2 / 120 + t2 ** 2 / 5040, (tb - sin_t) / tb ** 3)
    a1 = np.where(small, -1 / 12 + t2 / 180 - t2 ** 2 / 6720,
                  (tb * sin_t - 2 * (1 - cos_t)) / tb ** 4)
    b1 = np.where(small, -1 / 60 + t2 / 1260 - t2 ** 2 / 60480,
                  ((1 - cos_t) / tb ** 3 - 3 * (tb - sin_t) / tb ** 4) / tb)

    a, b = a[:, None], b[:, None]

    def jl(vec):
        w = _cross(phi, vec)
        return vec + a * w + b * _cross(phi, w)

    w1 = _cross(phi, dphi)
    w2 = _cross(phi, w1)
    dot = np.sum(phi * dphi, axis=1)[:, None]
    omega_s = jl(ddphi) + dot * (a1[:, None] * w1 + b1[:, None] * w2) + b * _cross(dphi, w1)
    return jl(dphi), omega_s


def _cross(u, v):
    """Row-wise cross product of (N, 3) arrays."""
    out = np.empty_like(u)
    out[:, 0] = u[:, 1] * v[:, 2] - u[:, 2] * v[:, 1]
    out[:, 1] = u[:, 2] * v[:, 0] - u[:, 0] * v[:, 2]
    out[:, 2] = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    return out

"""Maps of the Cartesian stiffness and of the lowest natural frequency over many poses, for
any robot: the hexapod, the planar 3-PRR and any robot loaded from a description.

Each pose is first sorted by the workspace map of :func:`hexapod_pin.core.workspace_maps.
evaluate` (the robot's batch kinematics: reachable, within the strokes, regular); at
the usable poses the robot's own ``vibration_modes(pose, actuator_stiffness)`` gives the
stiffness ``K_x = J^T K_a J + K_g`` under gravity and the modes of ``K_x phi = omega^2 M_x
phi`` (:mod:`hexapod_pin.core.stiffness`), pose by pose.

Measures (rows and columns of ``K_x``: the world tangent ``(dp, dtheta)`` in the robot's
pose order, :class:`~hexapod_pin.core.stiffness.CartesianStiffness`). An eigenvalue of the
whole ``K_x`` mixes N/m and N m/rad when the pose has both kinds of component, so the map
reports the two blocks apart:

* ``translational``: the smallest eigenvalue of the symmetric part of the block
  ``K_x[linear, linear]`` (N/m), the stiffness against a translation in the weakest
  direction with the orientation held;
* ``rotational``: the same of ``K_x[angular, angular]`` (N m/rad), against a rotation
  about the weakest axis with the position held;
* ``lowest_frequency``: the smallest natural frequency (Hz), mode shapes mixing both.

(The stiffness against a pure force with the orientation free is that of the compliance's
translational block, ``1 / max eig(C[linear, linear])``; a pose's
:attr:`~hexapod_pin.core.stiffness.CartesianStiffness.compliance` gives it.) Under a
large preload a block's smallest eigenvalue may be negative: the pose is statically
unstable in that direction. Rows without a result carry zeros and their
:attr:`StiffnessMap.status` says why, never NaN.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Protocol, cast

import numpy as np
import numpy.typing as npt

from ..errors import (
    ArgumentTypeError,
    HexapodPinError,
    InputError,
    SingularityError,
    UnreachablePoseError,
)
from . import workspace_maps
from .checks import as_array, count
from .robot_api import ParallelRobot, pose_layout
from .stiffness import CartesianStiffness, VibrationModes, actuator_stiffness_of

#: status codes of :attr:`StiffnessMap.status`: ``OK`` (stiffness and modes), ``UNREACHABLE``
#: (a chain cannot reach), ``STROKE`` (an actuator beyond its position limits), ``SINGULAR``
#: (a singular pose), ``UNSTABLE`` (``K_x`` computed but not positive semi-definite: no
#: frequencies), ``FAILED`` (a route refused the pose: :attr:`StiffnessMap.failures`)
OK, UNREACHABLE, STROKE, SINGULAR, UNSTABLE, FAILED = range(6)
#: the name of each status code
STATUS_NAMES = ("ok", "unreachable", "stroke", "singular", "unstable", "failed")

#: default half widths of a slice around its centre: 5 cm on lengths, 0.2 rad on angles
#: (the box of ``hexapod-pin workspace``)
DEFAULT_HALF_WIDTH = {"linear": 0.05, "angular": 0.2}
#: the most samples per side of a slice
MAX_RESOLUTION = 1001
#: the angular pose components (rad); the others are lengths (m)
ANGLES = ("roll", "pitch", "yaw")

#: a progress callback: called with the fraction of poses done, in (0, 1]
Progress = Callable[[float], object]


class StiffnessRobot(ParallelRobot, Protocol):
    """A robot of the shared API with the stiffness routes of
    :class:`~hexapod_pin.core.robot_base.RobotBase`."""

    def cartesian_stiffness(self, pose: npt.ArrayLike, actuator_stiffness: npt.ArrayLike,
                            wrench: npt.ArrayLike | None = None, *,
                            branch: Any = None) -> CartesianStiffness: ...

    def vibration_modes(self, pose: npt.ArrayLike, actuator_stiffness: npt.ArrayLike, *,
                        branch: Any = None) -> VibrationModes: ...


@dataclass(frozen=True, eq=False)
class StiffnessMap:
    """Per-pose stiffness and frequencies of :func:`stiffness_map`; N poses.

    Attributes:
        poses: (N, dim) the poses (m, rad).
        status: (N,) int, a code of :data:`STATUS_NAMES` per pose (:data:`OK` = 0).
        stiffness: (N, dim, dim) ``K_x`` (N/m, N/rad, N m/m, N m/rad by block) where the
            status is ``OK`` or ``UNSTABLE``, zeros elsewhere.
        translational: (N,) smallest eigenvalue of the symmetric translational block
            (N/m; module docstring) where ``K_x`` exists, 0 elsewhere; None for a pose
            without linear components.
        rotational: (N,) the same of the rotational block (N m/rad); None for a pose
            without angles.
        frequencies: (N, dim) natural frequencies (Hz, ascending) where ``OK``, zeros
            elsewhere.
        actuator_stiffness: (n_act,) ``k`` (N/m or N m/rad per actuator).
        pose_axes: the robot's pose axes (the columns of ``poses``).
        failures: reason -> number of rows (read-only): a status name for every status
            other than ``OK`` that occurs, and ``"<route>: <error>"`` for each refusal
            counted as ``FAILED``.
    """

    poses: np.ndarray
    status: np.ndarray
    stiffness: np.ndarray
    translational: np.ndarray | None
    rotational: np.ndarray | None
    frequencies: np.ndarray
    actuator_stiffness: np.ndarray
    pose_axes: tuple[str, ...]
    failures: Mapping[str, int]

    @property
    def ok(self) -> np.ndarray:
        """(N,) bool: stiffness and frequencies computed (status ``OK``)."""
        return np.asarray(self.status == OK)

    @property
    def has_stiffness(self) -> np.ndarray:
        """(N,) bool: ``K_x`` computed (status ``OK`` or ``UNSTABLE``)."""
        return np.isin(self.status, (OK, UNSTABLE))

    @property
    def lowest_frequency(self) -> np.ndarray:
        """(N,) the lowest natural frequency (Hz) where ``OK``, 0 elsewhere."""
        return np.array(self.frequencies[:, 0])


@dataclass(frozen=True, eq=False)
class StiffnessSlice:
    """A :class:`StiffnessMap` on a grid over one or two pose axes through a centre pose
    (:func:`stiffness_slice`).

    Attributes:
        axes: the one or two pose axes of the grid.
        coordinates: one array per axis, (n,) each (m or rad).
        center: (dim,) the centre pose: the fixed components and the grid's centre.
        map: the :class:`StiffnessMap` of the grid's poses, the first axis varying
            fastest (:meth:`grid` reshapes its arrays).
    """

    axes: tuple[str, ...]
    coordinates: tuple[np.ndarray, ...]
    center: np.ndarray
    map: StiffnessMap

    @property
    def shape(self) -> tuple[int, ...]:
        """The grid's shape: ``(n,)`` for one axis, ``(n_second, n_first)`` for two (rows
        of constant second coordinate, as an image)."""
        return tuple(len(c) for c in reversed(self.coordinates))

    def grid(self, values: np.ndarray) -> np.ndarray:
        """``values`` (N, ...) of the map, one row per pose, as an array of
        :attr:`shape` ``+ values.shape[1:]``."""
        arr = np.asarray(values)
        return arr.reshape(self.shape + arr.shape[1:])


def _robot(robot: object) -> StiffnessRobot:
    if not isinstance(robot, ParallelRobot) or not callable(getattr(robot, "vibration_modes",
                                                                    None)):
        raise ArgumentTypeError("robot", robot, "expected a robot of the shared API with "
                                "vibration_modes (hexapod_pin.core.robot_base.RobotBase), "
                                f"got {type(robot).__name__}")
    return cast(StiffnessRobot, robot)


def _progress(progress: Progress | None) -> Progress | None:
    if progress is not None and not callable(progress):
        raise ArgumentTypeError("progress", progress, "expected a callable(fraction) or None")
    return progress


def block_minimum(matrix: np.ndarray, rows: np.ndarray) -> float:
    """The smallest eigenvalue of the symmetric part of ``matrix[rows, rows]``."""
    block = matrix[np.ix_(rows, rows)]
    return float(np.linalg.eigvalsh(0.5 * (block + block.T))[0])


def _one(robot: StiffnessRobot, pose: np.ndarray, k: np.ndarray, branch: Any,
         failures: Counter) -> tuple[int, np.ndarray | None, np.ndarray | None]:
    """``(status, K_x or None, frequencies or None)`` of one kinematically usable pose."""
    try:
        modes = robot.vibration_modes(pose, k, branch=branch)
        return OK, modes.stiffness.matrix, modes.frequencies
    except InputError:
        raise
    except UnreachablePoseError:
        return UNREACHABLE, None, None
    except SingularityError:
        pass                          # a singular pose, or K_x not positive semi-definite
    except HexapodPinError as exc:
        failures[f"vibration_modes: {type(exc).__name__}"] += 1
        return FAILED, None, None
    try:
        return UNSTABLE, robot.cartesian_stiffness(pose, k, branch=branch).matrix, None
    except SingularityError:
        return SINGULAR, None, None
    except HexapodPinError as exc:
        failures[f"cartesian_stiffness: {type(exc).__name__}"] += 1
        return FAILED, None, None


def stiffness_map(robot: Any, poses: npt.ArrayLike, actuator_stiffness: npt.ArrayLike, *,
                  branch: Any = None, progress: Progress | None = None) -> StiffnessMap:
    """The Cartesian stiffness, its weakest translational and rotational values and the
    natural frequencies at many poses, under gravity (module docstring).

    Args:
        robot: any robot of the shared API (:class:`hexapod_pin.Hexapod`,
            :class:`hexapod_pin.Planar3PRR`, a :class:`hexapod_pin.ClosedLoopRobot`).
        poses: (N, dim) poses in the robot's pose axes (m, rad), e.g. from
            :func:`~hexapod_pin.core.workspace_maps.grid` or
            :func:`~hexapod_pin.core.workspace_maps.sample_box`.
        actuator_stiffness: ``k`` scalar or (n_act,) (N/m, N m/rad), >= 0.
        branch: the working mode (as ``robot.vibration_modes`` takes it; the workspace
            sorting uses the robot's home branch).
        progress: optional ``callable(fraction)``, called after each chunk of
            :data:`~hexapod_pin.core.workspace_maps.CHUNK` poses (the last call with 1.0).

    Returns:
        :class:`StiffnessMap` (the status of each pose; zeros, never NaN, where there is no
        result).

    Raises:
        ArgumentTypeError: ``robot`` is not a robot of the shared API, ``progress`` not
            callable.
        InputError: poses not (N, dim), NaN / inf, a bad ``actuator_stiffness``, a pose the
            robot refuses as input, Coulomb friction in the model (the static forces are
            then a band).
    """
    robot = _robot(robot)
    layout = pose_layout(robot)
    k = actuator_stiffness_of(actuator_stiffness, robot.n_actuators)
    poses = np.array(as_array(poses, (layout.dim,), "poses", batch=True), copy=True)
    report = _progress(progress)
    n, dim = poses.shape[0], layout.dim
    status = np.full(n, FAILED, dtype=int)
    kx, freq = np.zeros((n, dim, dim)), np.zeros((n, dim))
    failures: Counter = Counter()
    for start in range(0, n, workspace_maps.CHUNK):
        sl = slice(start, min(start + workspace_maps.CHUNK, n))
        ws = workspace_maps.evaluate(robot, poses[sl], statics=False, singularity=False)
        failures.update({f"workspace: {key}": v for key, v in ws.failures.items()
                         if key.startswith("kinematics")})
        status[sl] = np.where(~ws.reachable, UNREACHABLE,
                              np.where(~ws.within_stroke, STROKE,
                                       np.where(~ws.regular, SINGULAR, OK)))
        for row in sl.start + np.flatnonzero(ws.ok):
            status[row], matrix, values = _one(robot, poses[row], k, branch, failures)
            if matrix is not None:
                kx[row] = matrix
            if values is not None:
                freq[row] = values
        if report is not None:
            report(sl.stop / n)
    has = np.isin(status, (OK, UNSTABLE))
    blocks = {}
    for name, rows in (("linear", layout.linear), ("angular", layout.angular)):
        blocks[name] = None if rows.size == 0 else np.array(
            [block_minimum(kx[i], rows) if has[i] else 0.0 for i in range(n)])
    failures.update({STATUS_NAMES[c]: int(np.count_nonzero(status == c))
                     for c in range(1, len(STATUS_NAMES))})
    return StiffnessMap(poses, status, kx, blocks["linear"], blocks["angular"], freq, k,
                        tuple(layout.axes),
                        MappingProxyType({key: v for key, v in failures.items() if v}))


def default_slice_axes(robot: Any) -> tuple[str, ...]:
    """The axes of a slice by default: the robot's first two position axes, else its first
    two pose axes, else its only one."""
    own = tuple(robot.pose_axes)
    linear = [a for a in own if a not in ANGLES]
    return tuple(linear[:2]) if len(linear) >= 2 else own[:2]


def _slice_axes(robot: Any, axes: Sequence[str] | str | None) -> tuple[str, ...]:
    own = tuple(robot.pose_axes)
    if axes is None:
        return default_slice_axes(robot)
    picked = tuple(a.strip() for a in axes.split(",")) if isinstance(axes, str) \
        else tuple(axes)
    if not 1 <= len(picked) <= 2 or len(set(picked)) != len(picked) \
            or any(a not in own for a in picked):
        raise InputError("axes", axes, f"expected one or two distinct pose axes of the "
                         f"robot {own}")
    return picked


def _half_widths(axes: tuple[str, ...], half_width: npt.ArrayLike | None) -> np.ndarray:
    if half_width is None:
        return np.array([DEFAULT_HALF_WIDTH["angular" if a in ANGLES else "linear"]
                         for a in axes])
    given = np.ravel(np.asarray(half_width, dtype=object))
    width = as_array(np.repeat(given, len(axes)) if given.size == 1 else given,
                     (len(axes),), "half_width")
    if not np.all(width > 0):
        raise InputError("half_width", half_width, "must be > 0 (m, rad)")
    return np.array(width, dtype=float)


def stiffness_slice(robot: Any, actuator_stiffness: npt.ArrayLike,
                    axes: Sequence[str] | str | None = None, *,
                    center: npt.ArrayLike | None = None,
                    half_width: npt.ArrayLike | None = None,
                    resolution: int = 21, branch: Any = None,
                    progress: Progress | None = None) -> StiffnessSlice:
    """:func:`stiffness_map` on a regular grid over one or two pose axes, the other
    components at those of ``center``.

    Args:
        robot: any robot of the shared API.
        actuator_stiffness: ``k`` scalar or (n_act,) (N/m, N m/rad), >= 0.
        axes: one or two pose axes (a sequence or ``"a,b"``); default
            :func:`default_slice_axes`.
        center: (dim,) the pose the slice passes through (m, rad); default home.
        half_width: half sides of the grid around the centre (m or rad), one value or one
            per axis; default :data:`DEFAULT_HALF_WIDTH` by the kind of each axis.
        resolution: samples per side, 2 to :data:`MAX_RESOLUTION`.
        branch: the working mode.
        progress: as in :func:`stiffness_map`.

    Returns:
        :class:`StiffnessSlice`.

    Raises:
        ArgumentTypeError: as in :func:`stiffness_map`.
        InputError: bad axes, centre, half widths or resolution, or as in
            :func:`stiffness_map`.
    """
    robot = _robot(robot)
    picked = _slice_axes(robot, axes)
    own = tuple(robot.pose_axes)
    mid = np.array(robot.home_pose if center is None
                   else as_array(center, (len(own),), "center"), dtype=float)
    widths = _half_widths(picked, half_width)
    size = count(resolution, "resolution", minimum=2)
    if size > MAX_RESOLUTION:
        raise InputError("resolution", resolution, f"at most {MAX_RESOLUTION} per side")
    cols = [own.index(a) for a in picked]
    coords = tuple(mid[c] + np.linspace(-w, w, size) for c, w in zip(cols, widths))
    mesh = np.meshgrid(*coords)                 # (n2, n1) for two axes: rows = second axis
    poses = np.tile(mid, (mesh[0].size, 1))
    for c, values in zip(cols, mesh):
        poses[:, c] = values.ravel()
    result = stiffness_map(robot, poses, actuator_stiffness, branch=branch, progress=progress)
    return StiffnessSlice(picked, coords, mid, result)

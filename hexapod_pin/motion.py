"""Sampled platform motions: motion files, their rates, a reference circle, inverse
dynamics along a motion, and a simulation tracking the circle.

A :class:`Motion` holds N samples of the platform of a robot: times ``t`` (s), poses
(the robot's ``pose_axes`` of ``(x, y, z, roll, pitch, yaw)``, m, rad; ``R = Rz(yaw)
Ry(pitch) Rx(roll)``; all six for the hexapod) and, optionally, twists (the same selection
of ``(v, w)`` of the platform origin, m/s, rad/s, world axes), their time derivatives, the
wrench (the same selection of ``(f, m)``) applied on the platform (N, N m, world axes,
moment about the platform origin), the actuator positions ``q`` (m or rad), the actuator
forces (N or N m) and the max-abs closure residual (m).

Motion files (``hexapod-pin id``, ``view --trajectory``, ``plot``; written by
``simulate --out``), their columns named by :func:`motion_columns` from the robot's pose
axes and number of actuators (without a robot: the hexapod's, as below):

* CSV: a header row naming the columns, ``#`` comment lines allowed. Required: ``t``
  and the pose ``x, y, z, roll, pitch, yaw``. Optional groups (all columns of a group
  together): the twist ``vx, vy, vz, wx, wy, wz``, its derivative ``ax, ay, az,
  alphax, alphay, alphaz``, the wrench ``fx, fy, fz, mx, my, mz``, the actuator
  positions ``q0 .. q5``, the actuator forces ``tau0 .. tau5``; and ``residual``. A
  robot with other pose axes names the same selection of each group, e.g. a five-bar
  with pose axes ``("x", "z")`` and two actuators: ``t, x, z, vx, vz, ax, az, fx, fz,
  q0, q1, tau0, tau1``.
* JSON: ``{"t": [...], "pose": [[dim], ...], "twist": ..., "twist_dot": ...,
  "wrench": ..., "q": [[n_act], ...], "actuator_forces": ..., "closure_residual": ...}``.

Where the twist (or its derivative) is absent, :func:`motion_rates` computes it from
the poses by second-order finite differences (``numpy.gradient``, angles unwrapped),
with ``w = E(rpy) d(rpy)/dt`` (:func:`hexapod_pin.core.pose.euler_rates_matrix`) when
the pose has all three angles, each angle's rate otherwise
(:meth:`hexapod_pin.core.robot_api.PoseLayout.twists_from_poses`).

A measurement log (:func:`read_actuator_log`, read by ``hexapod-pin identify``) is the
same format with the pose optional and ``t``, ``q`` and the actuator forces required.

Files are written atomically (:func:`hexapod_pin.files.write_text_atomic`).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from .core.robot_api import INVERSE_DYNAMICS_METHODS, ParallelRobot, PoseLayout, pose_layout
from .core.simulation import resolve_integrator
from .core.text_formats import check_columns, check_values, load_json
from .errors import DescriptionError, HexapodPinError, InputError, MotionSampleError
from .files import file_path, read_text, write_text_atomic
from .hexapod import simulation
from .hexapod.fast import FastTrajectory, simulate_fast
from .hexapod.robot import Hexapod

#: column names of a motion CSV file
POSE_NAMES = ("x", "y", "z", "roll", "pitch", "yaw")
TWIST_NAMES = ("vx", "vy", "vz", "wx", "wy", "wz")
TWIST_DOT_NAMES = ("ax", "ay", "az", "alphax", "alphay", "alphaz")
WRENCH_NAMES = ("fx", "fy", "fz", "mx", "my", "mz")
Q_NAMES = tuple(f"q{i}" for i in range(6))
TAU_NAMES = tuple(f"tau{i}" for i in range(6))
MOTION_SUFFIXES = (".csv", ".json")

#: the controllers of :func:`simulate_circle` and their default time steps (s)
DEFAULT_DT = {"pid": 2.5e-4, "computed-torque": 1e-3, "none": 1e-3}
#: the simulators of :func:`simulate_circle`: "fast" the compiled one
#: (:func:`hexapod_pin.hexapod.fast.simulate_fast`: PID or no control), "python" the
#: Pinocchio tree route (:func:`hexapod_pin.hexapod.simulation.simulate`: every controller)
ENGINES = ("auto", "fast", "python")
#: largest tracking error (m) of a run holding home (radius 0) that still counts as tracking
HOLD_TOLERANCE = 0.005
#: most steps :func:`simulate_circle` takes (every step is recorded: memory grows with them)
MAX_STEPS = 2_000_000


@dataclass(frozen=True)
class Motion:
    """A sampled platform motion (see the module doc for units and frames).

    ``dim`` is the robot's ``pose_dim`` (6 for the hexapod) and ``n_act`` its
    ``n_actuators``; :meth:`check` validates the shapes against a robot (the functions
    of this module taking a robot call it).

    Attributes:
        t: (N,) times (s), strictly increasing.
        poses: (N, dim) platform poses (m, rad), the robot's ``pose_axes``.
        twists: (N, dim) twists (m/s, rad/s, world axes), or None.
        twist_dots: (N, dim) their time derivatives, or None.
        wrenches: (N, dim) wrenches on the platform (N, N m), or None.
        q: (N, n_act) actuator positions (m or rad), or None.
        actuator_forces: (N, n_act) actuator forces (N or N m), or None.
        closure_residual: (N,) max-abs closure residual (m), or None.
    """

    t: np.ndarray
    poses: np.ndarray
    twists: np.ndarray | None = None
    twist_dots: np.ndarray | None = None
    wrenches: np.ndarray | None = None
    q: np.ndarray | None = None
    actuator_forces: np.ndarray | None = None
    closure_residual: np.ndarray | None = None

    @property
    def times(self) -> np.ndarray:
        """Alias of ``t`` (the name simulation results and the viewer use)."""
        return self.t

    def check(self, robot: ParallelRobot | None = None) -> Motion:
        """This motion, its shapes checked against ``robot`` (default: the hexapod's 6
        pose components and 6 actuators).

        Returns:
            ``self``.

        Raises:
            InputError: ``t`` not (N,) strictly increasing, a field of another shape than
                (N, dim) (poses, twists, twist_dots, wrenches), (N, n_act) (q,
                actuator_forces) or (N,) (closure_residual), or NaN / inf; the error names
                the field and the shapes.
        """
        t = np.asarray(self.t, dtype=float)
        n = len(t) if t.ndim == 1 else -1
        if n < 1 or np.any(np.diff(t) <= 0) or not np.all(np.isfinite(t)):
            raise InputError("motion.t", self.t, "expected (N,) strictly increasing finite "
                                                 "times")
        columns = motion_columns(robot)
        dim, n_act = len(columns.pose), len(columns.q)
        expected = {"poses": (n, dim), "twists": (n, dim), "twist_dots": (n, dim),
                    "wrenches": (n, dim), "q": (n, n_act), "actuator_forces": (n, n_act),
                    "closure_residual": (n,)}
        for field, shape in expected.items():
            value = getattr(self, field)
            if value is None:
                continue
            arr = np.asarray(value, dtype=float)
            if arr.shape != shape:
                raise InputError(f"motion.{field}", value,
                                 f"expected shape {shape} (pose axes {columns.pose}, "
                                 f"{n_act} actuators), got {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise InputError(f"motion.{field}", value, "contains NaN or inf")
        return self

    @classmethod
    def from_trajectory(cls, trajectory: simulation.Trajectory | FastTrajectory | Any
                        ) -> Motion:
        """The samples of a simulation result (the hexapod's, or the generic
        :class:`~hexapod_pin.core.simulate.Trajectory` of any robot): times, poses,
        twists, actuator positions and forces, closure residual (its max abs per sample;
        None for a :class:`~hexapod_pin.hexapod.fast.FastTrajectory`, which integrates in
        platform coordinates where the closures hold by construction).

        Raises:
            InputError: not a simulation result, or a run without platform poses (a bare
                model's).
        """
        residual = getattr(trajectory, "closure_residual", None)
        if residual is not None:
            residual = np.asarray(residual, dtype=float)
            if residual.ndim == 2:
                residual = np.max(np.abs(residual), axis=1)
            residual = np.abs(residual)
        missing = [name for name in ("times", "poses", "twists", "q", "actuator_forces")
                   if not hasattr(trajectory, name)]
        if missing:
            raise InputError("trajectory", trajectory, f"not a simulation result (no "
                             f"{', '.join(missing)})")
        if trajectory.poses is None or trajectory.twists is None:
            raise InputError("trajectory", trajectory, "a run of a bare ClosedLoopModel has "
                             "no platform poses: a motion needs a robot's run")
        # the generic hexapod_pin.simulate Trajectory keeps the tree q apart from the
        # actuator positions; the hexapod's own results call the carriage positions q
        actuators = getattr(trajectory, "actuator_positions", None)
        return cls(np.asarray(trajectory.times, dtype=float),
                   np.asarray(trajectory.poses, dtype=float),
                   twists=np.asarray(trajectory.twists, dtype=float),
                   q=np.asarray(trajectory.q if actuators is None else actuators, dtype=float),
                   actuator_forces=np.asarray(trajectory.actuator_forces, dtype=float),
                   closure_residual=residual)


class Rates(NamedTuple):
    """Twists (N, dim) (m/s, rad/s, world axes) and their time derivatives (N, dim)."""

    twists: np.ndarray
    twist_dots: np.ndarray


class MotionForces(NamedTuple):
    """Forces along a motion.

    Attributes:
        actuator_forces: (N, n_actuated) (N or N m).
        closure_forces: (N, n_chains, d) force of each chain (leg) on the platform at its
            platform joint, world axes (N): the ``closure_forces`` of the robot's
            inverse-dynamics result (``d = 3`` for the hexapod).
    """

    actuator_forces: np.ndarray
    closure_forces: np.ndarray


class MotionColumns(NamedTuple):
    """The CSV column names of a robot's motion files (:func:`motion_columns`).

    Attributes:
        pose: the pose columns, the robot's ``pose_axes`` (e.g. ``("x", "z")``).
        twists: the same selection of ``vx, vy, vz, wx, wy, wz``.
        twist_dots: the same selection of ``ax, ay, az, alphax, alphay, alphaz``.
        wrenches: the same selection of ``fx, fy, fz, mx, my, mz``.
        q: ``q0 .. q{n_act - 1}``.
        actuator_forces: ``tau0 .. tau{n_act - 1}``.
    """

    pose: tuple[str, ...]
    twists: tuple[str, ...]
    twist_dots: tuple[str, ...]
    wrenches: tuple[str, ...]
    q: tuple[str, ...]
    actuator_forces: tuple[str, ...]

    def groups(self) -> dict[str, tuple[str, ...]]:
        """The optional groups: :class:`Motion` field -> its columns."""
        return {"twists": self.twists, "twist_dots": self.twist_dots,
                "wrenches": self.wrenches, "q": self.q,
                "actuator_forces": self.actuator_forces}


def motion_columns(robot: ParallelRobot | None = None) -> MotionColumns:
    """The column names of ``robot``'s motion files: its pose axes (selecting the twist,
    twist-derivative and wrench columns) and one ``q`` and ``tau`` column per actuator;
    default (no robot): the hexapod's :data:`POSE_NAMES`, ..., ``q0 .. q5``,
    ``tau0 .. tau5``.

    Example:
        >>> motion_columns(five_bar).pose, motion_columns(five_bar).twists
        (('x', 'z'), ('vx', 'vz'))
    """
    layout: PoseLayout = pose_layout(POSE_NAMES if robot is None else robot)
    n_act = 6 if robot is None else int(robot.n_actuators)
    return MotionColumns(layout.axes, layout.names(TWIST_NAMES), layout.names(TWIST_DOT_NAMES),
                         layout.names(WRENCH_NAMES), tuple(f"q{i}" for i in range(n_act)),
                         tuple(f"tau{i}" for i in range(n_act)))


_JSON_KEYS = {"twist": "twists", "twist_dot": "twist_dots", "wrench": "wrenches", "q": "q",
              "actuator_forces": "actuator_forces"}


# -- files ------------------------------------------------------------------------------
def read_motion(path: str | os.PathLike[str], robot: ParallelRobot | None = None) -> Motion:
    """Read a motion file (.csv / .txt or .json, see the module doc).

    Args:
        path: the file.
        robot: the robot whose motion it is: its pose axes and number of actuators name
            the CSV columns and fix the JSON shapes (:func:`motion_columns`); default the
            hexapod's (6 pose columns, 6 actuators), as files written before robots had
            pose axes.

    Returns:
        the :class:`Motion` (poses (N, dim), q and actuator forces (N, n_act)).

    Raises:
        MissingFileError: the file does not exist.
        DescriptionError: unknown suffix, missing or malformed columns,
            times not increasing, a shape that does not fit the robot, NaN / inf (the
            message names the file and column).
    """
    path = Path(file_path(path))
    columns = motion_columns(robot)
    if path.is_dir() or not path.is_file():
        read_text(path, "motion file")  # a folder or a missing file: its error
    suffix = path.suffix.lower()
    if suffix == ".json":
        return _motion_from_json(path, columns)
    if suffix in (".csv", ".txt"):
        return _motion_from_csv(path, columns)
    raise DescriptionError(str(path), "motion file must be .csv or .json")


def write_motion(path: str | os.PathLike[str], motion: Motion,
                 robot: ParallelRobot | None = None) -> Path:
    """Write a motion file (CSV or JSON by suffix) with every field that is set.

    Args:
        path: the file (.csv or .json).
        motion: the samples.
        robot: the robot whose motion it is: its pose axes and number of actuators name
            the CSV columns (:func:`motion_columns`); default the hexapod's.

    Returns:
        the path. The file is replaced atomically.

    Raises:
        InputError: a suffix other than .csv / .json, a folder that does not exist, a
            motion whose shapes do not fit the robot (:meth:`Motion.check`).
    """
    path = Path(path)
    columns = motion_columns(robot)
    motion.check(robot)
    fields = {field: getattr(motion, field) for field in columns.groups()}
    suffix = path.suffix.lower()
    if suffix == ".json":
        payload = {"t": motion.t.tolist(), "pose": motion.poses.tolist()}
        payload.update({key: fields[field].tolist() for key, field in _JSON_KEYS.items()
                        if fields[field] is not None})
        if motion.closure_residual is not None:
            payload["closure_residual"] = motion.closure_residual.tolist()
        text = json.dumps(payload)
    elif suffix == ".csv":
        header = ["t", *columns.pose]
        blocks = [motion.t[:, None], motion.poses]
        for field, names in columns.groups().items():
            if fields[field] is not None:
                header += names
                blocks.append(fields[field])
        if motion.closure_residual is not None:
            header.append("residual")
            blocks.append(motion.closure_residual[:, None])
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(header)
        writer.writerows(np.hstack(blocks).tolist())
        text = buffer.getvalue()
    else:
        raise InputError("path", str(path), "motion files are .csv or .json")
    return write_text_atomic(path, text)


def _csv_columns(path: Path) -> dict[str, np.ndarray]:
    """The columns of a CSV motion file by name (header row, then numbers)."""
    numbered = [(n, ln) for n, ln in enumerate(read_text(path).splitlines(), 1)
                if ln.strip() and not ln.lstrip().startswith("#")]
    if len(numbered) < 2:
        raise DescriptionError(str(path), "needs a header row and at least one data row")
    rows = list(csv.reader([ln for _, ln in numbered]))
    header = check_columns(rows[0], str(path), numbered[0][0])
    values = []
    for row_index, (row, (line, _)) in enumerate(zip(rows[1:], numbered[1:])):
        where = f"row {row_index} (line {line})"        # rows count from 0, as in errors of ID
        if len(row) != len(header):
            raise DescriptionError(str(path), f"{where} has {len(row)} values; every row "
                                              f"must have {len(header)} values (the header)")
        try:
            values.append([float(v) for v in row])
        except ValueError:
            column = next(h for h, v in zip(header, row) if not _is_number(v))
            raise DescriptionError(str(path), f"{where}, column {column!r}: "
                                              f"{row[header.index(column)].strip()!r} is not a "
                                              f"number", column) from None
    data = np.array(values, dtype=float)
    return {name: data[:, i] for i, name in enumerate(header)}


def _csv_group(path: Path, col: dict[str, np.ndarray],
               names: tuple[str, ...]) -> np.ndarray | None:
    """The (N, len(names)) block of a column group, None when none of it is there."""
    present = [n for n in names if n in col]
    if present and len(present) != len(names):
        raise DescriptionError(str(path), f"columns {list(names)} must come together",
                               present[0])
    return np.stack([col[n] for n in names], axis=1) if present else None


def _motion_from_csv(path: Path, columns: MotionColumns) -> Motion:
    col = _csv_columns(path)
    missing = [c for c in ("t",) + columns.pose if c not in col]
    if missing:
        raise DescriptionError(str(path), f"missing columns {missing} (header: {list(col)})")
    groups = {field: _csv_group(path, col, names) for field, names in columns.groups().items()}
    return _checked_motion(path, columns, col["t"],
                           np.stack([col[n] for n in columns.pose], axis=1),
                           residual=col.get("residual"), **groups)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _motion_from_json(path: Path, columns: MotionColumns) -> Motion:
    data = load_json(read_text(path), str(path))
    if not isinstance(data, dict) or "t" not in data or "pose" not in data:
        raise DescriptionError(str(path), 'expected an object with "t" and "pose"')
    try:
        arrays = {field: None if data.get(key) is None else np.asarray(data[key], dtype=float)
                  for key, field in _JSON_KEYS.items()}
        t = np.asarray(data["t"], dtype=float)
        poses = np.asarray(data["pose"], dtype=float)
        residual = data.get("closure_residual")
        residual = None if residual is None else np.asarray(residual, dtype=float)
    except (TypeError, ValueError) as exc:
        raise DescriptionError(str(path), f"non-numeric entries: {exc}") from None
    return _checked_motion(path, columns, t, poses, residual=residual, **arrays)


def _checked_motion(path: Path, columns: MotionColumns, t: np.ndarray, poses: np.ndarray,
                    residual: np.ndarray | None = None, **arrays: np.ndarray | None) -> Motion:
    residual = _check_arrays(path, columns, t, {"pose": poses, **arrays}, residual)
    return Motion(t, poses, closure_residual=residual, **arrays)


def _check_arrays(path: Path, columns: MotionColumns, t: np.ndarray,
                  arrays: dict[str, np.ndarray | None],
                  residual: np.ndarray | None = None) -> np.ndarray | None:
    """Check times, shapes and values of a file's arrays (None: absent); the residual
    as (N,)."""
    n = len(t) if t.ndim == 1 else 0
    if n == 0:
        raise DescriptionError(str(path), "t must be a non-empty list of times", "t")
    if n > 1 and np.any(np.diff(t) <= 0):
        raise DescriptionError(str(path), "t must be strictly increasing", "t")
    checks = {k: v for k, v in arrays.items() if v is not None}
    widths = {"pose": len(columns.pose), **{field: len(names)
                                            for field, names in columns.groups().items()}}
    for key, value in checks.items():
        if value.shape != (n, widths[key]):
            raise DescriptionError(str(path), f"{key} must have shape ({n}, {widths[key]}), "
                                              f"got {value.shape}", key)
    if residual is not None:
        residual = np.max(np.abs(residual), axis=1) if residual.ndim == 2 else residual
        if residual.shape != (n,):
            raise DescriptionError(str(path), f"closure_residual must have {n} values",
                                   "closure_residual")
    finite: dict[str, np.ndarray | None] = {**checks, "t": t, "closure_residual": residual}
    for key, item in finite.items():
        if item is not None:
            check_values(item, str(path), key)
    return residual


@dataclass(frozen=True)
class ActuatorLog:
    """A measurement log: actuator positions and forces sampled in time, and the platform
    poses when the file has them (:func:`read_actuator_log`).

    Attributes:
        t: (N,) times (s), strictly increasing.
        q: (N, n_act) actuator positions (m or rad).
        actuator_forces: (N, n_act) actuator forces (N or N m).
        poses: (N, dim) platform poses (m, rad), or None (the file has no pose columns).
    """

    t: np.ndarray
    q: np.ndarray
    actuator_forces: np.ndarray
    poses: np.ndarray | None = None


def read_actuator_log(path: str | os.PathLike[str],
                      robot: ParallelRobot | None = None) -> ActuatorLog:
    """Read the actuator positions and forces of a motion file whose pose columns are
    optional (a real robot's log: times, ``q0..``, ``tau0..``; other columns of the
    motion format are ignored).

    Args:
        path: the file (.csv / .txt: columns ``t``, ``q0..``, ``tau0..`` and optionally
            the pose; .json: keys ``"t"``, ``"q"``, ``"actuator_forces"`` and optionally
            ``"pose"``).
        robot: the robot whose motion it is (:func:`motion_columns`; default the
            hexapod's).

    Raises:
        MissingFileError: the file does not exist.
        DescriptionError: unknown suffix; missing time, position or force columns;
            malformed, non-finite or misshaped values; times not increasing (the message
            names the file and column).
    """
    path = Path(file_path(path))
    columns = motion_columns(robot)
    if path.is_dir() or not path.is_file():
        read_text(path, "motion file")  # a folder or a missing file: its error
    suffix = path.suffix.lower()
    if suffix in (".csv", ".txt"):
        col = _csv_columns(path)
        if "t" not in col:
            raise DescriptionError(str(path), f"missing column 't' (header: {list(col)})", "t")
        t = col["t"]
        arrays = {"pose": _csv_group(path, col, columns.pose),
                  "q": _csv_group(path, col, columns.q),
                  "actuator_forces": _csv_group(path, col, columns.actuator_forces)}
    elif suffix == ".json":
        data = load_json(read_text(path), str(path))
        if not isinstance(data, dict) or "t" not in data:
            raise DescriptionError(str(path), 'expected an object with "t"')
        try:
            t = np.asarray(data["t"], dtype=float)
            arrays = {key: None if data.get(key) is None else np.asarray(data[key],
                                                                           dtype=float)
                      for key in ("pose", "q", "actuator_forces")}
        except (TypeError, ValueError) as exc:
            raise DescriptionError(str(path), f"non-numeric entries: {exc}") from None
    else:
        raise DescriptionError(str(path), "motion file must be .csv or .json")
    q, forces = arrays["q"], arrays["actuator_forces"]
    if q is None or forces is None:
        key, names = ("q", columns.q) if q is None else \
            ("actuator_forces", columns.actuator_forces)
        raise DescriptionError(str(path), f"missing the actuator {key} (columns "
                                          f"{', '.join(names)})", key)
    _check_arrays(path, columns, t, arrays)
    return ActuatorLog(t, q, forces, arrays["pose"])


# -- rates and reference motions ---------------------------------------------------------
def motion_rates(motion: Motion, robot: ParallelRobot | None = None) -> Rates:
    """Twists and their derivatives (N, dim): from the motion, or by finite differences.

    Missing twists come from the poses (in the robot's pose axes): ``v = dp/dt`` and,
    when the pose has all three angles, ``w = E(rpy) d(rpy)/dt`` (world axes), else each
    angle's rate (:meth:`~hexapod_pin.core.robot_api.PoseLayout.twists_from_poses`), each
    derivative by ``numpy.gradient`` (second order, also at the ends) after unwrapping the
    angles; missing twist derivatives from the twists the same way.

    Args:
        motion: the samples.
        robot: the robot whose motion it is (its ``pose_axes``); default from the poses'
            width: 6 ``(x, y, z, roll, pitch, yaw)``, 3 ``(x, y, theta)``.

    Raises:
        DescriptionError: fewer than 3 samples where a derivative is needed.
        InputError: no robot and a pose width other than 6 or 3, or shapes that do not
            fit the robot (:meth:`Motion.check`).
    """
    if robot is not None:
        motion.check(robot)
    twists, twist_dots = motion.twists, motion.twist_dots
    if (twists is None or twist_dots is None) and len(motion.t) < 3:
        raise DescriptionError("motion", "at least 3 samples are needed to differentiate "
                                         "the poses (or give the twist columns)")
    if twists is None:
        layout = pose_layout(int(np.shape(motion.poses)[1]) if robot is None else robot)
        twists = layout.twists_from_poses(np.asarray(motion.t, dtype=float),
                                          np.asarray(motion.poses, dtype=float))
    if twist_dots is None:
        twist_dots = np.gradient(twists, motion.t, axis=0, edge_order=2)
    return Rates(twists, twist_dots)


def circle_reference(robot: Hexapod, radius: float,
                     period: float) -> simulation.ReferenceTrajectory:
    """The reference of :func:`circle_motion` and :func:`simulate_circle`: a callable
    ``t -> PlatformReference``.

    :class:`hexapod_pin.hexapod.simulation.CircleTrajectory` about ``robot.home_pose``
    for ``radius > 0``; the home pose at rest for ``radius == 0``.

    Raises:
        InputError: a negative or non-finite radius (named ``radius``), a non-positive or
            non-finite period (named ``period``).
    """
    if not (np.isfinite(radius) and radius >= 0):
        raise InputError("radius", radius, "need a finite radius >= 0 (m)")
    if not (np.isfinite(period) and period > 0):
        raise InputError("period", period, "need a finite period > 0 (s)")
    if radius > 0:
        return simulation.CircleTrajectory(robot.home_pose, radius, period)
    rest = simulation.PlatformReference(robot.home_pose, np.zeros(6), np.zeros(6))
    return lambda t: rest


def circle_motion(robot: Hexapod, radius: float, period: float, duration: float | None = None,
                  rate: float = 200.0) -> Motion:
    """A horizontal circle of the platform origin about home, sampled at ``rate`` (Hz).

    The samples of :func:`circle_reference` (position ``home + radius (cos(2 pi t / T),
    sin(2 pi t / T), 0)`` (m), orientation of home held) at ``t = 0 .. duration``
    (at least 3 samples), with the exact twists and their derivatives. ``duration``
    defaults to one period (s).

    Raises:
        InputError: ``radius < 0``, or a non-positive period, duration or rate (each named).
    """
    reference = circle_reference(robot, radius, period)        # checks radius and period
    duration = period if duration is None else duration
    if not (np.isfinite(duration) and duration > 0):
        raise InputError("duration", duration, "need a finite duration > 0 (s)")
    if not (np.isfinite(rate) and rate > 0):
        raise InputError("rate", rate, "need a finite rate > 0 (Hz)")
    t = np.linspace(0.0, duration, max(round(duration * rate) + 1, 3))
    samples = [reference(ti) for ti in t]
    return Motion(t, np.array([s.pose for s in samples]), np.array([s.twist for s in samples]),
                  np.array([s.twist_dot for s in samples]))


# -- kinematics and dynamics along a motion ----------------------------------------------
def actuators_along(robot: ParallelRobot, motion: Motion, check_limits: bool = False) -> np.ndarray:
    """Actuator positions (N, n_act) of the motion's poses (N, dim), by
    ``robot.inverse_kinematics`` (home branch), or ``motion.q`` when the motion has them.

    Args:
        robot: any robot with the shared API (its ``pose_axes`` and ``n_actuators`` fix
            the shapes).
        motion: the samples.
        check_limits: raise for a pose beyond the actuators' strokes.

    Raises:
        InputError: a motion whose shapes do not fit the robot (:meth:`Motion.check`).
        MotionSampleError: a pose out of reach (or beyond the strokes with
            ``check_limits``); it names the row and time and carries the library error.
    """
    motion.check(robot)
    if motion.q is not None:
        return motion.q
    out = []
    for n, pose in enumerate(motion.poses):
        try:
            out.append(robot.inverse_kinematics(pose, check_limits=check_limits))
        except HexapodPinError as exc:
            raise MotionSampleError(n, float(motion.t[n]), exc) from exc
    return np.array(out)


def inverse_dynamics_along(robot: ParallelRobot, motion: Motion,
                           method: str = INVERSE_DYNAMICS_METHODS[0],
                           progress: Callable[[int, int], None] | None = None
                           ) -> MotionForces:
    """Actuator and closure forces along a motion, by ``robot.inverse_dynamics`` per sample.

    Every pose is checked to be within reach first (``robot.inverse_kinematics``), so a
    pose out of reach is reported at its own row (the finite-difference rates of its
    neighbours would otherwise fail first). The twists and their derivatives are those
    of :func:`motion_rates` (in the robot's pose axes); the wrench of each sample is
    ``motion.wrenches[n]`` when given. Bounds on the actuator forces as the robot's
    default.

    Args:
        robot: any robot with the shared API (a :class:`hexapod_pin.Hexapod`, a
            :class:`hexapod_pin.Planar3PRR`, a :class:`hexapod_pin.ClosedLoopRobot`).
        motion: the samples.
        method: one of :data:`hexapod_pin.core.robot_api.INVERSE_DYNAMICS_METHODS`
            ("kkt", the default, or "qp").
        progress: called as ``progress(samples_done, samples_total)`` after each sample.

    Returns:
        :class:`MotionForces`.

    Raises:
        InputError: an unknown method, or a motion whose shapes do not fit the robot
            (:meth:`Motion.check`), before any sample is computed.
        DescriptionError: too few samples to differentiate the poses.
        MotionSampleError: a sample fails; it names the row and time, and carries the
            library error (e.g. :class:`UnreachablePoseError`,
            :class:`ActuatorSaturationError`).
    """
    if method not in INVERSE_DYNAMICS_METHODS:
        raise InputError("method", method,
                         f"expected one of {', '.join(INVERSE_DYNAMICS_METHODS)}")
    actuators_along(robot, dataclasses.replace(motion, q=None))
    twists, twist_dots = motion_rates(motion, robot)
    total = len(motion.t)
    taus, closures = [], []
    for n in range(total):
        wrench = None if motion.wrenches is None else motion.wrenches[n]
        try:
            result = robot.inverse_dynamics(motion.poses[n], twists[n], twist_dots[n],
                                            wrench=wrench, method=method)
        except HexapodPinError as exc:
            raise MotionSampleError(n, float(motion.t[n]), exc) from exc
        taus.append(np.asarray(result.actuator_forces, dtype=float))
        closures.append(np.asarray(result.closure_forces, dtype=float))
        if progress is not None:
            progress(n + 1, total)
    return MotionForces(np.array(taus), np.array(closures))


# -- simulation tracking a circle --------------------------------------------------------
@dataclass(frozen=True)
class CircleRun:
    """Result of :func:`simulate_circle`.

    Attributes:
        trajectory: the simulator's result
            (:class:`~hexapod_pin.hexapod.simulation.Trajectory` with ``engine="python"``,
            :class:`~hexapod_pin.hexapod.fast.FastTrajectory` with ``engine="fast"``).
        reference_poses: (n, 6) the reference pose at each sample (m, rad).
        tracking_error: largest distance (m) between the platform origin and its
            reference position; None without control (``controller="none"``).
        tolerance: the tracking error (m) above which the run counts as lost: the
            radius of the circle (:data:`HOLD_TOLERANCE` when holding home).
        status: the simulator's status ("completed", "stroke_limit", "carriage_gap",
            "failed"), or "tracking_lost" when a run that completed tracked worse than
            ``tolerance``.
        message: what happened (empty when the run completed and tracked).
        controller: "pid", "computed-torque" or "none". engine: "fast" or "python".
    """

    trajectory: simulation.Trajectory | FastTrajectory
    reference_poses: np.ndarray
    tracking_error: float | None
    tolerance: float
    status: str
    message: str
    controller: str
    engine: str

    @property
    def ok(self) -> bool:
        """Whether the run completed (its commands maybe clipped: status "saturated") and
        tracked its reference."""
        return self.status in ("completed", "saturated")


def simulate_circle(robot: Hexapod, duration: float, dt: float | None = None,
                    controller: str = "pid",
                    radius: float = 0.02, period: float = 2.0,
                    progress: Callable[[int, int], None] | None = None,
                    engine: str = "auto", integrator: str = "auto") -> CircleRun:
    """Simulate the hexapod tracking :func:`circle_reference` (a circle about home).

    Controllers: ``"pid"``, the joint-space PID with the Quanser gains
    (:class:`~hexapod_pin.hexapod.simulation.PIDController`; default step 0.25 ms,
    below its discrete stability limit); ``"computed-torque"``
    (:class:`~hexapod_pin.hexapod.simulation.ComputedTorqueController`, 1 ms);
    ``"none"``: no actuator force, the platform starts at rest at home and falls.

    A run that completes with a tracking error above the circle's radius (e.g. a PID
    step too long for its gains, forces pinned at their bound) gets the status
    ``"tracking_lost"``, never ``"completed"``.

    Args:
        robot: a :class:`hexapod_pin.Hexapod`.
        duration: simulated time (s).
        dt: step (s); default :data:`DEFAULT_DT` of the controller.
        controller: ``"pid"``, ``"computed-torque"`` or ``"none"``.
        radius: the circle's radius (m); 0 holds home.
        period: the circle's period (s).
        progress: passed to :func:`hexapod_pin.hexapod.simulation.simulate` (the python
            engine; the compiled loop reports nothing until it ends).
        engine: ``"fast"``: the compiled simulator
            (:func:`hexapod_pin.hexapod.fast.simulate_fast`, RK4 in platform coordinates,
            hundreds of times real time; PID or no control); ``"python"``: the Pinocchio
            tree route (:func:`hexapod_pin.hexapod.simulation.simulate`, every
            controller); ``"auto"`` (default): fast unless the controller is
            computed torque, the integrator is "stick_slip" or the joint effects sit on
            passive coordinates (which the compiled kernels do not model).
        integrator: one of :data:`hexapod_pin.core.simulation.INTEGRATORS`, "auto"
            (default: "stick_slip" with Coulomb friction, else "rk4",
            :func:`~hexapod_pin.core.simulation.resolve_integrator`); the fast engine
            takes "rk4" and "semi_implicit_euler".

    Returns:
        :class:`CircleRun`.

    Raises:
        InputError: an unknown controller or engine, computed torque on the fast engine,
            an integrator that does not take the robot's friction or engine
            (:func:`~hexapod_pin.core.simulation.resolve_integrator`),
            ``dt`` not in ``(0, duration]``, more than :data:`MAX_STEPS` steps, a bad
            circle.
    """
    if controller not in DEFAULT_DT:
        raise InputError("controller", controller, f"expected one of {', '.join(DEFAULT_DT)}")
    if engine not in ENGINES:
        raise InputError("engine", engine, f"expected one of {', '.join(ENGINES)}")
    stepper = resolve_integrator(robot.model, integrator)
    tree_only = stepper == "stick_slip" or not robot.effects.only_on(robot.model.actuated_v)
    if engine == "auto":
        engine = "python" if controller == "computed-torque" or tree_only else "fast"
    if engine == "fast" and controller == "computed-torque":
        raise InputError("engine", engine, "the compiled simulator runs the PID or no "
                                           "control; computed torque needs engine 'python'")
    if engine == "fast" and stepper == "stick_slip":
        raise InputError("integrator", stepper, "the compiled simulator steps rk4 or "
                                                "semi_implicit_euler; exact Coulomb friction "
                                                "(stick_slip) needs engine 'python'")
    if not (np.isfinite(duration) and duration > 0):
        raise InputError("duration", duration, "need a finite duration > 0 (s)")
    dt = DEFAULT_DT[controller] if dt is None else float(dt)
    if not (np.isfinite(dt) and 0 < dt <= duration):
        raise InputError("dt", dt, f"need 0 < dt <= duration (duration {duration})")
    if duration / dt > MAX_STEPS:
        raise InputError("duration", duration, f"{duration / dt:.3g} steps of dt = {dt:g} s: "
                                               f"more than {MAX_STEPS}; shorten the run or "
                                               f"lengthen the step")
    reference = circle_reference(robot, radius, period)
    traj: simulation.Trajectory | FastTrajectory
    if engine == "fast":
        if controller == "none":
            traj = simulate_fast(robot, duration, dt, pose0=robot.home_pose, twist0=np.zeros(6),
                                 integrator=stepper)
        else:
            traj = simulate_fast(robot, duration, dt, reference=reference, integrator=stepper)
    elif controller == "none":
        traj = simulation.simulate(robot, duration, dt, pose0=robot.home_pose,
                                   twist0=np.zeros(6), progress=progress, integrator=stepper)
    else:
        make = (simulation.PIDController if controller == "pid"
                else simulation.ComputedTorqueController)
        traj = simulation.simulate(robot, duration, dt, controller=make(robot, reference),
                                   reference=reference, progress=progress, integrator=stepper)
    references = np.array([reference(float(t)).pose for t in traj.times])
    tolerance = float(radius) if radius > 0 else HOLD_TOLERANCE
    error = None if controller == "none" else float(np.max(np.linalg.norm(
        np.asarray(traj.poses)[:, :3] - references[:, :3], axis=1)))
    status, message = str(traj.status), str(traj.message)
    if status in ("completed", "saturated") and error is not None and error > tolerance:
        status = "tracking_lost"
        saturated = float(np.mean(np.asarray(traj.saturated, dtype=bool)))
        message = (f"max tracking error {error:.4g} m exceeds {tolerance:.4g} m (the circle's "
                   f"radius); commands at their bound in {100 * saturated:.0f}% of the "
                   f"samples; a shorter step (dt = {dt:g} s) may help")
    return CircleRun(traj, references, error, tolerance, status, message, controller, engine)

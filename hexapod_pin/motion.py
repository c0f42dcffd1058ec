"""Sampled platform motions: motion files, their rates, a reference circle, inverse
dynamics along a motion, and a simulation tracking the circle.

A :class:`Motion` holds N samples of the platform: times ``t`` (s), poses
``(x, y, z, roll, pitch, yaw)`` (m, rad; ``R = Rz(yaw) Ry(pitch) Rx(roll)``) and,
optionally, twists ``(v, w)`` of the platform origin (m/s, rad/s, world axes), their
time derivatives, the wrench ``(f, m)`` applied on the platform (N, N m, world axes,
moment about the platform origin), the actuator positions ``q`` (m), the actuator
forces (N) and the max-abs closure residual (m).

Motion files (``hexapod-pin id``, ``view --trajectory``, ``plot``; written by
``simulate --out``):

* CSV: a header row naming the columns, ``#`` comment lines allowed. Required: ``t``
  and the pose ``x, y, z, roll, pitch, yaw``. Optional groups (all columns of a group
  together): the twist ``vx, vy, vz, wx, wy, wz``, its derivative ``ax, ay, az,
  alphax, alphay, alphaz``, the wrench ``fx, fy, fz, mx, my, mz``, the actuator
  positions ``q0 .. q5``, the actuator forces ``tau0 .. tau5``; and ``residual``.
* JSON: ``{"t": [...], "pose": [[6], ...], "twist": ..., "twist_dot": ...,
  "wrench": ..., "q": ..., "actuator_forces": ..., "closure_residual": ...}``.

Where the twist (or its derivative) is absent, :func:`motion_rates` computes it from
the poses by second-order finite differences (``numpy.gradient``, angles unwrapped),
with ``w = E(rpy) d(rpy)/dt`` (:func:`hexapod_pin.core.pose.euler_rates_matrix`).

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
from typing import NamedTuple

import numpy as np

from .core.pose import euler_rates_matrix
from .core.robot_api import INVERSE_DYNAMICS_METHODS, ParallelRobot
from .errors import DescriptionError, HexapodPinError, InputError, MotionSampleError
from .files import read_text, write_text_atomic
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

    Attributes:
        t: (N,) times (s), strictly increasing.
        poses: (N, 6) platform poses (m, rad).
        twists: (N, 6) twists (m/s, rad/s, world axes), or None.
        twist_dots: (N, 6) their time derivatives, or None.
        wrenches: (N, 6) wrenches on the platform (N, N m), or None.
        q: (N, 6) actuator positions (m), or None.
        actuator_forces: (N, 6) actuator forces (N), or None.
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

    @classmethod
    def from_trajectory(cls, trajectory: simulation.Trajectory | FastTrajectory) -> Motion:
        """The samples of a simulation result: times, poses, twists, actuator
        positions and forces, closure residual (its max abs per sample; None for a
        :class:`~hexapod_pin.hexapod.fast.FastTrajectory`, which integrates in platform
        coordinates where the closures hold by construction)."""
        residual = getattr(trajectory, "closure_residual", None)
        if residual is not None:
            residual = np.asarray(residual, dtype=float)
            if residual.ndim == 2:
                residual = np.max(np.abs(residual), axis=1)
            residual = np.abs(residual)
        return cls(np.asarray(trajectory.times, dtype=float),
                   np.asarray(trajectory.poses, dtype=float),
                   twists=np.asarray(trajectory.twists, dtype=float),
                   q=np.asarray(trajectory.q, dtype=float),
                   actuator_forces=np.asarray(trajectory.actuator_forces, dtype=float),
                   closure_residual=residual)


class Rates(NamedTuple):
    """Twists (N, 6) (m/s, rad/s, world axes) and their time derivatives (N, 6)."""

    twists: np.ndarray
    twist_dots: np.ndarray


class MotionForces(NamedTuple):
    """Forces along a motion.

    Attributes:
        actuator_forces: (N, n_actuated) (N).
        closure_forces: (N, n_closures, 3) force of each leg on the platform at its
            platform joint, world axes (N).
    """

    actuator_forces: np.ndarray
    closure_forces: np.ndarray


_JSON_KEYS = {"twist": "twists", "twist_dot": "twist_dots", "wrench": "wrenches", "q": "q",
              "actuator_forces": "actuator_forces"}
_CSV_GROUPS = {"twists": TWIST_NAMES, "twist_dots": TWIST_DOT_NAMES, "wrenches": WRENCH_NAMES,
               "q": Q_NAMES, "actuator_forces": TAU_NAMES}


# -- files ------------------------------------------------------------------------------
def read_motion(path: str | os.PathLike) -> Motion:
    """Read a motion file (.csv / .txt or .json, see the module doc).

    Raises:
        DescriptionError: missing file, unknown suffix, missing or malformed columns,
            times not increasing, NaN / inf (the message names the file and column).
    """
    path = Path(path)
    if not path.is_file():
        raise DescriptionError(str(path), "motion file not found")
    suffix = path.suffix.lower()
    if suffix == ".json":
        return _motion_from_json(path)
    if suffix in (".csv", ".txt"):
        return _motion_from_csv(path)
    raise DescriptionError(str(path), "motion file must be .csv or .json")


def write_motion(path: str | os.PathLike, motion: Motion) -> Path:
    """Write a motion file (CSV or JSON by suffix) with every field that is set.

    Returns:
        the path. The file is replaced atomically.

    Raises:
        InputError: a suffix other than .csv / .json, or a folder that does not exist.
    """
    path = Path(path)
    fields = {field: getattr(motion, field) for field in _CSV_GROUPS}
    suffix = path.suffix.lower()
    if suffix == ".json":
        payload = {"t": motion.t.tolist(), "pose": motion.poses.tolist()}
        payload.update({key: fields[field].tolist() for key, field in _JSON_KEYS.items()
                        if fields[field] is not None})
        if motion.closure_residual is not None:
            payload["closure_residual"] = motion.closure_residual.tolist()
        text = json.dumps(payload)
    elif suffix == ".csv":
        header = ["t", *POSE_NAMES]
        columns = [motion.t[:, None], motion.poses]
        for field, names in _CSV_GROUPS.items():
            if fields[field] is not None:
                header += names
                columns.append(fields[field])
        if motion.closure_residual is not None:
            header.append("residual")
            columns.append(motion.closure_residual[:, None])
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(header)
        writer.writerows(np.hstack(columns).tolist())
        text = buffer.getvalue()
    else:
        raise InputError("path", str(path), "motion files are .csv or .json")
    return write_text_atomic(path, text)


def _motion_from_csv(path: Path) -> Motion:
    numbered = [(n, ln) for n, ln in enumerate(read_text(path).splitlines(), 1)
                if ln.strip() and not ln.lstrip().startswith("#")]
    if len(numbered) < 2:
        raise DescriptionError(str(path), "needs a header row and at least one data row")
    rows = list(csv.reader([ln for _, ln in numbered]))
    header = [h.strip() for h in rows[0]]
    missing = [c for c in ("t",) + POSE_NAMES if c not in header]
    if missing:
        raise DescriptionError(str(path), f"missing columns {missing} (header: {header})")
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
    col = {name: data[:, i] for i, name in enumerate(header)}
    groups = {}
    for field, names in _CSV_GROUPS.items():
        present = [n for n in names if n in col]
        if present and len(present) != len(names):
            raise DescriptionError(str(path), f"columns {list(names)} must come together",
                                   present[0])
        groups[field] = np.stack([col[n] for n in names], axis=1) if present else None
    return _checked_motion(path, col["t"], np.stack([col[n] for n in POSE_NAMES], axis=1),
                           residual=col.get("residual"), **groups)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _motion_from_json(path: Path) -> Motion:
    try:
        data = json.loads(read_text(path))
    except json.JSONDecodeError as exc:
        raise DescriptionError(str(path), f"malformed JSON: {exc}") from None
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
    return _checked_motion(path, t, poses, residual=residual, **arrays)


def _checked_motion(path: Path, t: np.ndarray, poses: np.ndarray,
                    residual: np.ndarray | None = None, **arrays: np.ndarray | None) -> Motion:
    n = len(t) if t.ndim == 1 else 0
    if n == 0:
        raise DescriptionError(str(path), "t must be a non-empty list of times", "t")
    if n > 1 and np.any(np.diff(t) <= 0):
        raise DescriptionError(str(path), "t must be strictly increasing", "t")
    checks = {"pose": poses, **{k: v for k, v in arrays.items() if v is not None}}
    for key, value in checks.items():
        if value.shape != (n, 6):
            raise DescriptionError(str(path), f"{key} must have shape ({n}, 6), "
                                              f"got {value.shape}", key)
    if residual is not None:
        residual = np.max(np.abs(residual), axis=1) if residual.ndim == 2 else residual
        if residual.shape != (n,):
            raise DescriptionError(str(path), f"closure_residual must have {n} values",
                                   "closure_residual")
    finite: dict[str, np.ndarray | None] = {**checks, "t": t, "closure_residual": residual}
    for key, item in finite.items():
        if item is not None and not np.all(np.isfinite(item)):
            raise DescriptionError(str(path), "contains NaN or inf", key)
    return Motion(t, poses, closure_residual=residual, **arrays)


# -- rates and reference motions ---------------------------------------------------------
def motion_rates(motion: Motion) -> Rates:
    """Twists and their derivatives (N, 6): from the motion, or by finite differences.

    Missing twists come from the poses: ``v = dp/dt`` and ``w = E(rpy) d(rpy)/dt``
    (world axes), each derivative by ``numpy.gradient`` (second order, also at the
    ends) after unwrapping the angles; missing twist derivatives from the twists
    the same way.

    Raises:
        DescriptionError: fewer than 3 samples where a derivative is needed.
    """
    twists, twist_dots = motion.twists, motion.twist_dots
    if (twists is None or twist_dots is None) and len(motion.t) < 3:
        raise DescriptionError("motion", "at least 3 samples are needed to differentiate "
                                         "the poses (or give the twist columns)")
    if twists is None:
        angles = np.unwrap(motion.poses[:, 3:], axis=0)
        vel = np.gradient(motion.poses[:, :3], motion.t, axis=0, edge_order=2)
        rates = np.gradient(angles, motion.t, axis=0, edge_order=2)
        omega = np.einsum("nij,nj->ni", euler_rates_matrix(motion.poses[:, 3:]), rates)
        twists = np.hstack([vel, omega])
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
    """Actuator positions (N, n_act) of the motion's poses, by ``robot.inverse_kinematics``
    (home branch), or ``motion.q`` when the motion has them.

    Raises:
        MotionSampleError: a pose out of reach (or beyond the strokes with
            ``check_limits``); it names the row and time and carries the library error.
    """
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
    of :func:`motion_rates`; the wrench of each sample is ``motion.wrenches[n]`` when
    given. Bounds on the actuator forces as the robot's default.

    Args:
        robot: a robot with ``inverse_dynamics(pose, twist, twist_dot, wrench=, method=)``
            (a :class:`hexapod_pin.Hexapod` or :class:`hexapod_pin.Planar3PRR`).
        motion: the samples.
        method: one of :data:`hexapod_pin.core.robot_api.INVERSE_DYNAMICS_METHODS`
            ("kkt", the default, or "qp").
        progress: called as ``progress(samples_done, samples_total)`` after each sample.

    Returns:
        :class:`MotionForces`.

    Raises:
        InputError: an unknown method (before any sample is computed).
        DescriptionError: too few samples to differentiate the poses.
        MotionSampleError: a sample fails; it names the row and time, and carries the
            library error (e.g. :class:`UnreachablePoseError`,
            :class:`ActuatorSaturationError`).
    """
    if method not in INVERSE_DYNAMICS_METHODS:
        raise InputError("method", method,
                         f"expected one of {', '.join(INVERSE_DYNAMICS_METHODS)}")
    actuators_along(robot, dataclasses.replace(motion, q=None))
    twists, twist_dots = motion_rates(motion)
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
                    engine: str = "auto") -> CircleRun:
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
            computed torque.

    Returns:
        :class:`CircleRun`.

    Raises:
        InputError: an unknown controller or engine, computed torque on the fast engine,
            ``dt`` not in ``(0, duration]``, more than :data:`MAX_STEPS` steps, a bad
            circle.
    """
    if controller not in DEFAULT_DT:
        raise InputError("controller", controller, f"expected one of {', '.join(DEFAULT_DT)}")
    if engine not in ENGINES:
        raise InputError("engine", engine, f"expected one of {', '.join(ENGINES)}")
    if engine == "auto":
        engine = "python" if controller == "computed-torque" else "fast"
    if engine == "fast" and controller == "computed-torque":
        raise InputError("engine", engine, "the compiled simulator runs the PID or no "
                                           "control; computed torque needs engine 'python'")
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
            traj = simulate_fast(robot, duration, dt, pose0=robot.home_pose, twist0=np.zeros(6))
        else:
            traj = simulate_fast(robot, duration, dt, reference=reference)
    elif controller == "none":
        traj = simulation.simulate(robot, duration, dt, pose0=robot.home_pose,
                                   twist0=np.zeros(6), progress=progress)
    else:
        make = (simulation.PIDController if controller == "pid"
                else simulation.ComputedTorqueController)
        traj = simulation.simulate(robot, duration, dt, controller=make(robot, reference),
                                   reference=reference, progress=progress)
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

"""Measured motions for identification: actuator positions and forces sampled in time,
and the platform states derived from them.

Processing (:func:`states_from_motion`), zero-phase so that forces and states stay
aligned in time:

1. the actuator positions are low-pass filtered by a Butterworth filter (order
   :data:`FILTER_ORDER`, cut-off ``cutoff`` Hz, default :data:`DEFAULT_CUTOFF_RATIO` of
   the Nyquist frequency), run forward and backward (``scipy.signal.filtfilt``: no phase
   lag, the magnitude response squared). The forces are NOT filtered: their noise is
   white and least squares averages it, while a low-pass would smear the Coulomb force's
   steps at velocity reversals over the filter's length (a bias, not noise);
2. actuator velocities and accelerations by second-order central differences of the
   filtered positions (``numpy.gradient``, twice; the times may be non-uniform);
3. the samples within ``trim`` of each end are dropped (the filter's and the
   differences' end effects; default: three periods of the cut-off, ``ceil(3 rate /
   cutoff)`` samples);
4. poses: those given, else the forward kinematics of the filtered actuator positions,
   each started from the previous pose (the first from home); twists ``J^-1 qd`` and
   twist derivatives ``J^-1 (qdd - dJ/dt twist)`` from the robot's Jacobian at each pose.

Units: s, m or rad (actuator positions), N or N m (forces); the robot's pose layout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.signal

from ..core.checks import as_array, count, real_number
from ..errors import HexapodPinError, InputError, MotionSampleError

#: order of the Butterworth low-pass
FILTER_ORDER = 4
#: default cut-off as a fraction of the Nyquist frequency ``1 / (2 dt)``
DEFAULT_CUTOFF_RATIO = 0.2
#: default ``trim``: None, three periods of the cut-off
DEFAULT_TRIM = None


@dataclass(frozen=True)
class MotionData:
    """A measured motion.

    Attributes:
        times: (N,) strictly increasing (s).
        actuator_positions: (N, n_act) (m or rad).
        actuator_forces: (N, n_act) (N or N m).
        poses: (N, dim) the platform poses, or None (forward kinematics).
    """

    times: np.ndarray
    actuator_positions: np.ndarray
    actuator_forces: np.ndarray
    poses: np.ndarray | None = None


@dataclass(frozen=True)
class MotionStates:
    """Platform states and forces ready for the regressor.

    Attributes:
        times: (K,) (s).
        poses: (K, dim) platform poses (m, rad).
        twists: (K, dim) their twists (world axes, m/s, rad/s).
        twist_dots: (K, dim) the twists' time derivatives.
        actuator_forces: (K, n_act), as measured.
    """

    times: np.ndarray
    poses: np.ndarray
    twists: np.ndarray
    twist_dots: np.ndarray
    actuator_forces: np.ndarray


def check_motion(data: object, n_act: int, dim: int) -> MotionData:
    """A :class:`MotionData` with checked arrays.

    Raises:
        InputError: not a MotionData, bad shapes, NaN / inf, times not increasing,
            fewer than 3 samples, arrays of different lengths.
    """
    if not isinstance(data, MotionData):
        raise InputError("data", data, "expected a MotionData")
    times = as_array(data.times, (), "data.times", batch=True)
    if times.size < 3 or not np.all(np.diff(times) > 0):
        raise InputError("data.times", data.times, "expected 3 or more strictly increasing "
                         "times")
    pos = as_array(data.actuator_positions, (n_act,), "data.actuator_positions", batch=True)
    forces = as_array(data.actuator_forces, (n_act,), "data.actuator_forces", batch=True)
    poses = None if data.poses is None else \
        as_array(data.poses, (dim,), "data.poses", batch=True)
    for name, arr in (("data.actuator_positions", pos), ("data.actuator_forces", forces),
                      ("data.poses", poses)):
        if arr is not None and arr.shape[0] != times.size:
            raise InputError(name, arr, f"expected {times.size} rows (one per time), got "
                             f"{arr.shape[0]}")
    return MotionData(times, pos, forces, poses)


def low_pass(times: np.ndarray, values: np.ndarray, cutoff: float) -> np.ndarray:
    """``values`` (N, k) low-pass filtered along time, zero phase (module docstring, step
    1); the sampling rate is the mean of the times' spacing.

    Raises:
        InputError: a cut-off at or above the Nyquist frequency, or too few samples for
            the filter (``filtfilt`` needs more than ``3 (2 order + 1)``).
    """
    rate = (times.size - 1) / (times[-1] - times[0])
    if not cutoff < 0.5 * rate:
        raise InputError("cutoff", cutoff, f"must be below the Nyquist frequency "
                         f"{0.5 * rate:.6g} Hz")
    b, a = scipy.signal.butter(FILTER_ORDER, cutoff, fs=rate)
    if times.size <= 3 * max(a.size, b.size):
        raise InputError("data.times", times, f"{times.size} samples: the filter needs more "
                         f"than {3 * max(a.size, b.size)}")
    return np.asarray(scipy.signal.filtfilt(b, a, values, axis=0))


def resolve_cutoff(times: np.ndarray, cutoff: float | None) -> float:
    """The cut-off (Hz) of ``cutoff`` (> 0), or the default :data:`DEFAULT_CUTOFF_RATIO` of
    the Nyquist frequency of ``times`` when None.

    Raises:
        InputError: a cut-off that is not a positive number.
    """
    rate = (times.size - 1) / (times[-1] - times[0])
    return DEFAULT_CUTOFF_RATIO * 0.5 * rate if cutoff is None else \
        real_number(cutoff, "cutoff", minimum=0.0)


def resolve_trim(times: np.ndarray, cutoff: float, trim: int | None) -> int:
    """The samples dropped at each end: ``trim`` (>= 0), or three periods of the cut-off
    ``ceil(3 rate / cutoff)`` when None.

    Raises:
        InputError: a negative or non-integer ``trim``.
    """
    rate = (times.size - 1) / (times[-1] - times[0])
    return int(np.ceil(3.0 * rate / cutoff)) if trim is None else \
        count(trim, "trim", minimum=0)


def filtered_derivatives(times: np.ndarray, positions: np.ndarray,
                         cutoff: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions (N, k) low-pass filtered, and their first and second derivatives (module
    docstring, steps 1 and 2); a linear map of ``positions``."""
    pos = low_pass(times, positions, cutoff)
    vel = np.gradient(pos, times, axis=0, edge_order=2)
    return pos, vel, np.gradient(vel, times, axis=0, edge_order=2)


def _impulse_response(times: np.ndarray, cutoff: float
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The response of :func:`filtered_derivatives` (positions, velocities, accelerations,
    each (N,)) to a unit impulse at the middle sample: for a time-invariant pipeline on
    uniform times, the weights of the middle sample's outputs, reversed."""
    impulse = np.zeros((times.size, 1))
    impulse[times.size // 2, 0] = 1.0
    pos, vel, acc = filtered_derivatives(times, impulse, cutoff)
    return pos[:, 0], vel[:, 0], acc[:, 0]


def derivative_noise_gain(times: np.ndarray, cutoff: float) -> tuple[float, float]:
    """The standard deviations of the velocity and acceleration errors per unit of white
    position noise (1/s, 1/s^2) that :func:`filtered_derivatives` makes at the middle
    sample: the root sum of squares of that sample's weights (the pipeline's response to
    a unit impulse at each sample, by symmetry the response at the middle sample to an
    impulse there, for uniform times). For 1 um noise sampled at 500 Hz and cut at 50 Hz:
    7e-5 m/s and 0.016 m/s^2; at 2 kHz and the default 200 Hz: 2.8e-4 m/s and 0.25
    m/s^2 (the acceleration's grows as ``cutoff^2.5 / rate^0.5``).

    Raises:
        InputError: a cut-off at or above the Nyquist frequency, too few samples.
    """
    _, vel, acc = _impulse_response(times, cutoff)
    return float(np.sqrt(np.sum(vel ** 2))), float(np.sqrt(np.sum(acc ** 2)))


def position_noise_estimate(times: np.ndarray, positions: np.ndarray, cutoff: float,
                            trim: int) -> np.ndarray:
    """The white noise (n_act,) (m or rad) of sampled positions (N, n_act), estimated from
    what the low-pass removes: the residual ``positions - low_pass(positions)`` over the
    samples ``trim .. N - trim`` has the variance ``s^2 sum_k (delta_k - h_k)^2`` for
    white noise ``s`` (``h`` the filter's weights, :func:`_impulse_response`), and no part
    of a motion whose band lies well below the cut-off (the filtered-and-back Butterworth
    passes it to ``(f / cutoff)^8``). Content above the cut-off that is not white noise
    (vibration, a motion faster than the cut-off) reads as noise: an upper bound then.

    Raises:
        InputError: a cut-off at or above the Nyquist frequency, too few samples, nothing
            left after ``trim``.
    """
    if times.size <= 2 * trim:
        raise InputError("trim", trim, f"drops every one of the {times.size} samples")
    residual = (positions - low_pass(times, positions, cutoff))[trim:times.size - trim]
    pos = _impulse_response(times, cutoff)[0]
    unit = -pos
    unit[times.size // 2] += 1.0
    return np.sqrt(np.mean(residual ** 2, axis=0) / float(np.sum(unit ** 2)))


def states_from_motion(robot: object, data: object, cutoff: float | None = None,
                       trim: int | None = DEFAULT_TRIM) -> MotionStates:
    """The platform states and filtered forces of a measured motion (module docstring).

    Args:
        robot: a robot of the library.
        data: a :class:`MotionData`.
        cutoff: the low-pass cut-off (Hz, > 0); None: :data:`DEFAULT_CUTOFF_RATIO` of the
            Nyquist frequency.
        trim: samples dropped at each end (>= 0); None: three periods of the cut-off.

    Raises:
        InputError: bad data or options; nothing left after trimming.
        MotionSampleError: a sample's forward kinematics or Jacobian fails (its index
            and time; the cause in ``error``).
    """
    n_act = int(getattr(robot, "n_actuators"))
    dim = int(getattr(robot, "pose_dim"))
    data = check_motion(data, n_act, dim)
    t = data.times
    cut = resolve_cutoff(t, cutoff)
    trim = resolve_trim(t, cut, trim)
    pos, vel, acc = filtered_derivatives(t, data.actuator_positions, cut)
    forces = data.actuator_forces
    keep = np.arange(trim, t.size - trim)
    if keep.size < 1:
        raise InputError("trim", trim, f"drops every one of the {t.size} samples")
    poses = np.empty((keep.size, dim))
    twists = np.empty((keep.size, dim))
    twist_dots = np.empty((keep.size, dim))
    guess = np.asarray(getattr(robot, "home_pose"), dtype=float)
    for row, k in enumerate(keep):
        try:
            if data.poses is None:
                pose = np.asarray(robot.forward_kinematics(pos[k], guess=guess))  # type: ignore[attr-defined]
            else:
                pose = data.poses[k]
            jac = np.asarray(robot.jacobian(pose))                        # type: ignore[attr-defined]
            twist = np.linalg.solve(jac, vel[k])
            jdot = np.asarray(robot.jacobian_derivative(pose, twist))     # type: ignore[attr-defined]
            twist_dots[row] = np.linalg.solve(jac, acc[k] - jdot @ twist)
        except (HexapodPinError, np.linalg.LinAlgError) as exc:
            cause = exc if isinstance(exc, HexapodPinError) else \
                InputError("data", k, f"singular Jacobian ({exc})")
            raise MotionSampleError(int(k), float(t[k]), cause) from exc
        poses[row], twists[row] = pose, twist
        guess = pose
    return MotionStates(t[keep], poses, twists, twist_dots, forces[keep])

"""Controllers for :func:`hexapod_pin.core.simulate.simulate`, for any robot.

The controller protocol: ``controller(state, robot) -> u``, with ``state`` a
:class:`SimState` (the simulated state at one control instant), ``robot`` what
:func:`~hexapod_pin.core.simulate.simulate` was given (a
:class:`~hexapod_pin.core.robot_api.ParallelRobot` or a bare
:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`) and ``u`` the actuator forces
(n_act,) (N or N m, each along its actuator's positive direction), held over the next step
(zero-order hold). A controller with a ``reset()`` method is reset at the start of a run.

* :class:`ActuatorPID`: a PID per actuator on actuator positions;
* :class:`ComputedTorque`: computed torque in platform space through the robot's
  inverse dynamics (feedback linearisation: critically damped error dynamics for
  ``kd = 2 sqrt(kp)`` when the model is exact).

Platform errors (shared API conventions, :mod:`hexapod_pin.core.robot_api`): for a 6-D
pose ``e = (p_ref - p, log3(R_ref R^T))`` (world axes, m and rad) and ``e_dot = twist_ref -
twist``; for other pose dimensions (the plane: ``(x, y, theta)``) the plain differences
``pose_ref - pose`` and ``twist_ref - twist``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import InputError
from .checks import as_array, real_number
from .pose import rotation_from_rpy
from .robot_api import PoseLayout, pose_layout, state_branch


@dataclass(frozen=True)
class SimState:
    """The simulated state handed to a controller at one control instant.

    Attributes:
        t: time (s).
        q: the tree configuration (nq,) (Pinocchio conventions).
        v: the tree velocity (nv,) (Pinocchio conventions).
        actuator_positions: (n_act,) (m or rad), actuator order.
        actuator_velocities: (n_act,) (m/s or rad/s): the tree velocity at the actuated
            joints.
        pose: the platform pose (dim,) (m, rad), or None for a bare model.
        twist: the platform twist (dim,) ``(v, w)`` in world axes, or None for a bare
            model.
    """

    t: float
    q: np.ndarray
    v: np.ndarray
    actuator_positions: np.ndarray
    actuator_velocities: np.ndarray
    pose: np.ndarray | None
    twist: np.ndarray | None


class Controller(Protocol):
    """Anything callable as ``controller(state, robot) -> u`` (n_act,) (N or N m)."""

    def __call__(self, state: SimState, robot: Any) -> npt.ArrayLike: ...


#: an actuator reference: ``t -> (q_ref (n_act,), qd_ref (n_act,))`` (m or rad, per s)
ActuatorReference = Callable[[float], tuple[npt.ArrayLike, npt.ArrayLike]]


class ActuatorPID:
    """A PID per actuator on the actuator positions.

    ``u = kp e + ki integral(e) + kd e_dot`` with ``e = q_ref - q_act`` and ``e_dot =
    qd_ref - qd_act`` (actuator order). The integral is a forward sum over the control
    periods (the error of each instant held until the next). Gains may be scalars or
    (n_act,) arrays, each >= 0.

    Note: a discrete derivative term is stable only when ``kd dt / m < 2``, ``m`` the
    effective mass (or inertia) seen by the actuator; without ``ki`` gravity leaves a
    steady-state error ``u_gravity / kp``.

    Args:
        kp: proportional gain (N/m or N m/rad).
        kd: derivative gain (N s/m or N m s/rad).
        ki: integral gain (N/(m s) or N m/(rad s)); default 0.
        reference: the actuator positions to hold ((n_act,) constant, zero velocity), a
            callable ``t -> (q_ref (n_act,), qd_ref (n_act,))``, or None: hold the
            actuator positions of the first state the controller sees after a reset.

    Raises:
        InputError: a gain that is not a finite number >= 0 (or a non-finite /
            negative array), a reference that is neither None, an array nor callable.
    """

    def __init__(self, kp: npt.ArrayLike, kd: npt.ArrayLike, ki: npt.ArrayLike = 0.0,
                 reference: npt.ArrayLike | ActuatorReference | None = None) -> None:
        self.kp = _gain(kp, "kp")
        self.kd = _gain(kd, "kd")
        self.ki = _gain(ki, "ki")
        self._constant: np.ndarray | None = None
        self._reference: ActuatorReference | None = None
        if callable(reference):
            self._reference = reference
        elif reference is not None:
            if np.ndim(reference) != 1:
                raise InputError("reference", reference, "expected actuator positions "
                                 "(n_act,), a callable t -> (q_ref, qd_ref) or None")
            self._constant = as_array(reference, (np.size(reference),), "reference")
        self.reset()

    def reset(self) -> None:
        """Clear the integral (and the held positions of ``reference=None``)."""
        self._integral: np.ndarray | None = None
        self._last: tuple[float, np.ndarray] | None = None
        self._held: np.ndarray | None = self._constant

    def setpoints(self, state: SimState) -> tuple[np.ndarray, np.ndarray]:
        """The set-points ``(q_ref, qd_ref)`` (n_act,) each at ``state.t``.

        Raises:
            InputError: a reference of the wrong shape or with NaN / inf entries.
        """
        n = state.actuator_positions.shape[0]
        if self._reference is not None:
            q_ref, qd_ref = self._reference(state.t)
            return (as_array(q_ref, (n,), f"reference({state.t:g}) q_ref"),
                    as_array(qd_ref, (n,), f"reference({state.t:g}) qd_ref"))
        if self._held is None:
            self._held = state.actuator_positions.copy()
        if self._held.shape != (n,):
            raise InputError("reference", self._held, f"expected shape ({n},)")
        return self._held, np.zeros(n)

    def __call__(self, state: SimState, robot: Any = None) -> np.ndarray:
        """The actuator forces (n_act,) (N or N m) at ``state``.

        Raises:
            InputError: a reference or a gain array of the wrong shape.
        """
        q_ref, qd_ref = self.setpoints(state)
        err = q_ref - state.actuator_positions
        n = err.shape[0]
        for name in ("kp", "kd", "ki"):
            gain = getattr(self, name)
            if gain.ndim and gain.shape != (n,):
                raise InputError(name, gain, f"expected a scalar or shape ({n},)")
        if self._integral is None:
            self._integral = np.zeros(n)
        if self._last is not None:
            t_last, err_last = self._last
            self._integral = self._integral + err_last * (state.t - t_last)
        self._last = (state.t, err)
        return (self.kp * err + self.kd * (qd_ref - state.actuator_velocities)
                + self.ki * self._integral)


#: a platform reference: ``t -> (pose (dim,), twist (dim,), twist_dot (dim,))``, or an
#: object with those three attributes (e.g. the hexapod's ``PlatformReference``)
PlatformReferenceFn = Callable[[float], Any]


class ComputedTorque:
    """Computed-torque control in platform space through ``robot.inverse_dynamics``.

    ``u = ID(pose, twist, twist_dot_ref + kp e + kd e_dot)`` at the simulated pose and
    twist (the textbook feedback linearisation: with an exact model the platform error
    obeys ``e'' + kd e' + kp e = 0``, up to the zero-order hold), ``e`` and ``e_dot`` the
    platform errors of the module docstring. The inverse dynamics run unbounded
    (``bounded=False``): :func:`~hexapod_pin.core.simulate.simulate` clips the commands
    to the robot's bound and reports it.

    Args:
        reference: callable ``t -> (pose_ref, twist_ref, twist_dot_ref)`` (each (dim,);
            m, rad; world axes), or returning an object with attributes ``pose``,
            ``twist`` and ``twist_dot``.
        kp: position gain (1/s^2), >= 0.
        kd: velocity gain (1/s), >= 0.
        space: "platform" (the only space implemented).
        method: the inverse-dynamics route, "kkt" (default) or "qp".

    Raises:
        InputError: a gain that is not a finite number >= 0, an unknown space or
            method, a reference that is not callable.
    """

    def __init__(self, reference: PlatformReferenceFn, kp: float = 400.0, kd: float = 40.0,
                 space: str = "platform", method: str = "kkt") -> None:
        if not callable(reference):
            raise InputError("reference", reference, "expected a callable t -> "
                                                     "(pose, twist, twist_dot)")
        if space != "platform":
            raise InputError("space", space, "expected 'platform'")
        if method not in ("kkt", "qp"):
            raise InputError("method", method, "expected 'kkt' or 'qp'")
        self.reference = reference
        self.kp = real_number(kp, "kp", minimum=0.0, strict=False)
        self.kd = real_number(kd, "kd", minimum=0.0, strict=False)
        self.space = space
        self.method = method

    def targets(self, t: float, dim: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The reference ``(pose, twist, twist_dot)`` at ``t`` (s), each (dim,).

        Raises:
            InputError: a reference value of the wrong shape or with NaN / inf.
        """
        ref = self.reference(t)
        if hasattr(ref, "pose"):
            ref = (ref.pose, ref.twist, ref.twist_dot)
        try:
            pose, twist, twist_dot = ref
        except (TypeError, ValueError):
            raise InputError(f"reference({t:g})", ref, "expected (pose, twist, "
                                                       "twist_dot)") from None
        return (as_array(pose, (dim,), f"reference({t:g}) pose"),
                as_array(twist, (dim,), f"reference({t:g}) twist"),
                as_array(twist_dot, (dim,), f"reference({t:g}) twist_dot"))

    def __call__(self, state: SimState, robot: Any) -> np.ndarray:
        """The actuator forces (n_act,) (N or N m) at ``state``.

        Raises:
            InputError: a state without a platform (a bare model), a bad reference value.
            SingularityError: the simulated pose is singular (from the inverse dynamics).
        """
        if state.pose is None or state.twist is None:
            raise InputError("robot", robot, "ComputedTorque needs a robot with a platform "
                                             "(a ParallelRobot), not a bare model")
        dim = state.pose.shape[0]
        pose_ref, twist_ref, twist_dot_ref = self.targets(state.t, dim)
        err = platform_error(pose_ref, state.pose, pose_layout(robot))
        command = twist_dot_ref + self.kp * err + self.kd * (twist_ref - state.twist)
        # the dynamics of the simulated configuration's working mode
        result = robot.inverse_dynamics(state.pose, state.twist, command, method=self.method,
                                        bounded=False, joint_wrenches=False,
                                        branch=state_branch(robot, state.pose, state.q))
        return np.asarray(result.actuator_forces, dtype=float)


def platform_error(pose_ref: np.ndarray, pose: np.ndarray,
                   layout: PoseLayout | None = None) -> np.ndarray:
    """The platform error (dim,) from ``pose`` to ``pose_ref``, in twist coordinates.

    Args:
        pose_ref: the reference pose (dim,) (m, rad).
        pose: the actual pose (dim,).
        layout: the robot's :class:`~hexapod_pin.core.robot_api.PoseLayout`; default that
            of a 6-D pose (x, y, z, roll, pitch, yaw) or a planar (x, y, yaw) one.

    Returns:
        The linear components ``p_ref - p`` (m); with all three angles in the pose, the
        rotation vector ``log3(R_ref R^T)`` (rad) taking ``R`` to ``R_ref``, world axes
        (``R = Rz(yaw) Ry(pitch) Rx(roll)``); otherwise each angle's difference wrapped to
        (-pi, pi].
    """
    layout = pose_layout(pose.shape[0] if layout is None else layout)
    err = np.asarray(pose_ref, dtype=float) - pose
    ang = layout.angular
    if layout.full_rotation:
        rot = rotation_from_rpy(pose[ang])
        rot_ref = rotation_from_rpy(np.asarray(pose_ref, dtype=float)[ang])
        err[ang] = pin.log3(rot_ref @ rot.T)
    elif ang.size:
        err[ang] = np.remainder(err[ang] + np.pi, 2.0 * np.pi) - np.pi
    return err


def _gain(value, name: str) -> np.ndarray:
    """A gain >= 0 as a 0-d or 1-d float array."""
    if np.ndim(value) == 0:
        return np.asarray(real_number(value, name, minimum=0.0, strict=False))
    arr = as_array(value, (np.size(value),), name)
    if (arr < 0).any():
        raise InputError(name, value, "must be >= 0")
    return arr

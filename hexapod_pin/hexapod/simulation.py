"""Simulation of the closed-loop hexapod from a platform state: controllers and runs.

:func:`simulate` integrates the tree with :class:`~hexapod_pin.core.simulation.ClosedLoopIntegrator`
under given actuator forces or a controller (:class:`PIDController` with the Quanser gains,
or :class:`ComputedTorqueController` using :meth:`Hexapod.inverse_dynamics`), checks the
stroke limits and the carriage gap at every step, and returns a :class:`Trajectory`.
The library never prints: pass ``progress`` to follow a long run.
"""


from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..core.simulate import real_time_factor
from ..core.simulation import ClosedLoopIntegrator
from ..errors import ActuatorSaturationError, HexapodPinError, InputError, StrokeLimitError
from ..core.pose import rotation_from_quaternion, rotation_from_rpy, rpy_from_rotation
from ..core.checks import as_array, count, real_number
from .robot import Hexapod

#: closure residual above which a step is projected back onto the closures (m)
PROJECTION_TOL = 1e-10
_SUPPORTED_1DOF = {"JointModelRX", "JointModelRY", "JointModelRZ", "JointModelPX",
                   "JointModelPY", "JointModelPZ", "JointModelRevoluteUnaligned",
                   "JointModelPrismaticUnaligned"}
STATUSES = ("completed", "stroke_limit", "carriage_gap", "failed")


# --------------------------------------------------------------------------------------
# references and controllers
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PlatformReference:
    """A platform reference at one instant: pose (6,), twist (6,), twist_dot (6,)."""

    pose: np.ndarray
    twist: np.ndarray
    twist_dot: np.ndarray


class ReferenceTrajectory(Protocol):
    """Anything callable as ``reference(t) -> PlatformReference`` (t in s)."""

    def __call__(self, t: float) -> PlatformReference: ...


@dataclass(frozen=True)
class CircleTrajectory:
    """Platform origin on a horizontal circle, orientation held.

    ``p(t) = center + radius (cos(w t), sin(w t), 0)``, ``w = 2 pi / period``, with
    ``center`` the position part of ``center_pose`` and the orientation of
    ``center_pose`` held. Starts at ``center + (radius, 0, 0)``.

    Attributes:
        center_pose: (6,) (m, rad).
        radius: (m).
        period: (s).
    """

    center_pose: np.ndarray
    radius: float
    period: float

    def __post_init__(self):
        object.__setattr__(self, "center_pose", as_array(self.center_pose, (6,), "center_pose"))
        for name in ("radius", "period"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise InputError(name, value, "must be a positive number")

    def __call__(self, t: float) -> PlatformReference:
        w = 2.0 * np.pi / self.period
        c, s = np.cos(w * t), np.sin(w * t)
        r = self.radius
        pose = self.center_pose.copy()
        pose[:2] += r * np.array([c, s])
        twist = np.zeros(6)
        twist[:2] = r * w * np.array([-s, c])
        twist_dot = np.zeros(6)
        twist_dot[:2] = -r * w * w * np.array([c, s])
        return PlatformReference(pose, twist, twist_dot)


@dataclass(frozen=True)
class SimState:
    """The simulated state handed to a controller.

    Attributes:
        t: time (s).
        pose: platform pose (6,) (m, rad).
        twist: platform twist ``(v, w)``, world axes (6,).
        q: carriage positions (6,) (m).
        qdot: carriage velocities (6,) (m/s).
        configuration: the tree configuration (nq,) (Pinocchio conventions).
        velocity: the tree velocity (nv,).
    """

    t: float
    pose: np.ndarray
    twist: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    configuration: np.ndarray
    velocity: np.ndarray


Controller = Callable[[SimState, float], np.ndarray]

#: default derivative gain of the joint PID (N s/m): stable at the default step of 1 ms
PID_KD = 600.0
#: the most steps one run may take, and the most samples it may record (each sample of
#: :func:`simulate` holds the tree state, about 400 bytes for the hexapod)
MAX_STEPS = 10 ** 9
MAX_SAMPLES = 2 * 10 ** 6


class PIDController:
    """Joint-space PID per carriage tracking set-points from IK of a platform reference.

    ``tau = kp e + ki integral(e) + kd de/dt (+ static feed-forward)``, ``e = q_ref -
    q``, ``q_ref = IK(reference.pose)``, ``qdot_ref = J reference.twist``. The
    integral is a forward sum over the control periods. Defaults: the Quanser lab gains.

    Note: it runs once per step (zero-order hold). A discrete D term is stable only
    when ``kd dt / m < 2`` with ``m`` the effective carriage mass; for the default
    (placeholder) masses the effective masses are 0.6 - 1.5 kg. The default ``kd`` = 600
    (``kd dt / m`` = 1 at the default step of 1 ms) tracks a 2 cm circle to about 20 um
    without saturating; the Quanser lab's ``kd`` = 3000 needs ``dt`` below about 0.4 ms
    (at 1 ms it saturates nearly every step).

    Args:
        robot: the :class:`Hexapod`.
        reference: callable ``t -> PlatformReference``.
        kp: N/m. ki: N/(m s). kd: N s/m (each >= 0).
        feedforward: add the static forces of the reference pose.

    Raises:
        InputError: a gain that is not a finite number >= 0.
    """

    def __init__(self, robot: Hexapod, reference: ReferenceTrajectory, kp: float = 30000.0,
                 ki: float = 40000.0, kd: float = PID_KD, feedforward: bool = False) -> None:
        self.robot = robot
        self.reference = reference
        self.kp, self.ki, self.kd = (real_number(kp, "kp", minimum=0.0, strict=False),
                                     real_number(ki, "ki", minimum=0.0, strict=False),
                                     real_number(kd, "kd", minimum=0.0, strict=False))
        self.feedforward = feedforward
        self.integral = np.zeros(6)

    def reset(self) -> None:
        """Clear the integral."""
        self.integral = np.zeros(6)

    def setpoints(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Carriage set-points ``(q_ref, qdot_ref)`` at time t, each (6,)."""
        ref = self.reference(t)
        q_ref = self.robot.inverse_kinematics(ref.pose, check_limits=False)
        return q_ref, self.robot.jacobian(ref.pose) @ ref.twist

    def __call__(self, state: SimState, dt: float) -> np.ndarray:
        q_ref, qdot_ref = self.setpoints(state.t)
        err = q_ref - state.q
        out = self.kp * err + self.ki * self.integral + self.kd * (qdot_ref - state.qdot)
        self.integral = self.integral + err * dt
        if self.feedforward:
            out = out + self.robot.static_forces(self.reference(state.t).pose, bounded=False)
        return out


class ComputedTorqueController:
    """Computed-torque control in platform space with :meth:`Hexapod.inverse_dynamics`.

    ``tau = ID(pose, twist, twist_dot_ref + kd (twist_ref - twist) + kp e)`` with ``e =
    (p_ref - p, log3(R_ref R^T))`` (world axes), i.e. a critically damped second-order
    error dynamics for ``kd = 2 sqrt(kp)`` when the model is exact.

    Args:
        robot: the :class:`Hexapod`.
        reference: callable ``t -> PlatformReference``.
        kp: 1/s^2. kd: 1/s.
        method: inverse-dynamics route ("kkt" default, or "qp"); no bounds are applied
            here (the simulation's ``saturation`` policy handles them).
    """

    def __init__(self, robot: Hexapod, reference: ReferenceTrajectory, kp: float = 400.0,
                 kd: float = 40.0, method: str = "kkt") -> None:
        if method not in ("kkt", "qp"):
            raise InputError("method", method, "expected 'kkt' or 'qp'")
        self.robot = robot
        self.reference = reference
        self.kp = real_number(kp, "kp", minimum=0.0, strict=False)
        self.kd = real_number(kd, "kd", minimum=0.0, strict=False)
        self.method = method

    def reset(self) -> None:
        """Nothing to reset (stateless)."""

    def __call__(self, state: SimState, dt: float) -> np.ndarray:
        ref = self.reference(state.t)
        rot = rotation_from_rpy(state.pose[3:])
        rot_ref = rotation_from_rpy(ref.pose[3:])
        err = np.concatenate([ref.pose[:3] - state.pose[:3], pin.log3(rot_ref @ rot.T)])
        cmd = ref.twist_dot + self.kd * (ref.twist - state.twist) + self.kp * err
        # inverse dynamics at the simulated tree configuration itself (no IK round trip)
        with self.robot.lock:
            return self.robot.dynamics.actuator_forces_at(state.configuration, state.twist,
                                                          cmd, method=self.method)


# --------------------------------------------------------------------------------------
# trajectory and simulation
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Trajectory:
    """A simulated motion, sampled every recorded step (n samples).

    Attributes:
        times: (n,) (s).
        poses: (n, 6) platform poses (m, rad).
        twists: (n, 6) platform twists ``(v, w)``, world axes (m/s, rad/s).
        q: (n, 6) carriage positions (m).
        qdot: (n, 6) carriage velocities (m/s).
        actuator_forces: (n, 6) forces applied from each sample to the next (N) (the
            last row: the command computed at the final state).
        saturated: (n,) True where the command was clipped to the bound.
        closure_residual: (n,) max-abs closure residual after projection (m).
        configurations: (n, nq) tree configurations (for visualisation).
        velocities: (n, nv) tree velocities.
        reference_poses: (n, 6) reference poses when a reference was given, else (0, 6).
        status: "completed", "saturated" (completed, but some commands were clipped to
            the bound: the message gives the fraction of steps), "stroke_limit",
            "carriage_gap" or "failed".
        message: details of a stop (which carriage, which limit, which error).
        dt: the step (s).
        wall_time: seconds spent in the integration loop.
        integrator: the integrator that ran ("rk4", "semi_implicit_euler" or
            "stick_slip": "auto" resolved, :func:`~hexapod_pin.core.simulation.resolve_integrator`).
        dissipated_work: (n,) energy dissipated by the joint effects' damping and Coulomb
            friction since t = 0 (J, >= 0; the integrator's quadrature of their power,
            :attr:`~hexapod_pin.core.simulation.ClosedLoopIntegrator.dissipated`); zeros
            without them.
    """

    times: np.ndarray
    poses: np.ndarray
    twists: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    actuator_forces: np.ndarray
    saturated: np.ndarray
    closure_residual: np.ndarray
    configurations: np.ndarray
    velocities: np.ndarray
    reference_poses: np.ndarray
    status: str
    message: str
    dt: float
    wall_time: float
    integrator: str = ""
    dissipated_work: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        if self.dissipated_work.size == 0 and self.times.size:   # left out: none
            object.__setattr__(self, "dissipated_work", np.zeros(self.times.size))

    @property
    def real_time_factor(self) -> float:
        """Simulated time divided by wall time
        (:func:`hexapod_pin.core.simulate.real_time_factor`)."""
        return real_time_factor(self.times, self.wall_time)


def check_run_arguments(duration: float, dt: float, on_limit: str, saturation: str,
                        record_every: int) -> int:
    """Validate the run arguments shared by :func:`simulate` and
    :func:`hexapod_pin.hexapod.fast.simulate_fast`; returns ``record_every`` as an int.

    Raises:
        InputError: a ``duration`` / ``dt`` that is not a positive finite number, more
            than :data:`MAX_STEPS` steps or :data:`MAX_SAMPLES` recorded samples, an
            unknown ``on_limit`` ("stop" or "raise") or ``saturation`` ("clip", "raise" or
            "ignore"), a ``record_every`` that is not an integer >= 1.
    """
    duration = real_number(duration, "duration", minimum=0.0)
    dt = real_number(dt, "dt", minimum=0.0)
    if on_limit not in ("stop", "raise"):
        raise InputError("on_limit", on_limit, "expected 'stop' or 'raise'")
    if saturation not in ("clip", "raise", "ignore"):
        raise InputError("saturation", saturation, "expected 'clip', 'raise' or 'ignore'")
    record_every = count(record_every, "record_every")
    steps = duration / dt
    if steps > MAX_STEPS:
        raise InputError("dt", dt, f"duration / dt = {steps:.3g} steps, more than "
                         f"{MAX_STEPS:.0e}: a longer step or a shorter duration")
    if steps / record_every > MAX_SAMPLES:
        raise InputError("duration", duration, f"{steps / record_every:.3g} recorded "
                         f"samples, more than {MAX_SAMPLES:.0e}: raise record_every")
    return record_every


def saturation_status(saturated: np.ndarray, times: np.ndarray) -> tuple[str, str]:
    """The status ``("saturated", message)`` of a completed run whose recorded commands
    were clipped (``saturated`` (n,) bool per sample, ``times`` (n,) s), else
    ``("completed", "")``."""
    if not saturated.any():
        return "completed", ""
    first = float(times[int(np.argmax(saturated))])
    return "saturated", (f"actuator commands clipped to the bound at {saturated.mean():.2%} "
                         f"of the recorded steps (first at t = {first:.6g} s)")


def simulate(robot: Hexapod, duration: float, dt: float = 1e-3, *,
             pose0: npt.ArrayLike | None = None, twist0: npt.ArrayLike | None = None,
             actuator_forces: npt.ArrayLike | None = None, controller: Controller | None = None,
             wrench: npt.ArrayLike | None = None, reference: ReferenceTrajectory | None = None,
             method: str = "pinocchio", integrator: str = "auto",
             projection_tol: float = PROJECTION_TOL, check_limits: bool = True,
             on_limit: str = "stop", saturation: str = "clip", record_every: int = 1,
             progress: Callable[[int, int], None] | None = None,
             friction_regularisation: float | None = None) -> Trajectory:
    """Integrate the closed-loop dynamics of the hexapod.

    Args:
        robot: the :class:`Hexapod`.
        duration: simulated time (s).
        dt: step and control period (s).
        pose0: initial platform pose (default: home; with a ``reference``, its pose at
            t = 0).
        twist0: initial platform twist (default: at rest; with a ``reference``, its twist
            at t = 0).
        actuator_forces: used without a controller: (6,) constant, or a callable
            ``t -> (6,)`` (N); default zero (unactuated).
        controller: callable ``(SimState, dt) -> (6,)`` forces (N), called once per
            step (``reset()`` is called first when it has one).
        wrench: ``(f, m)`` on the platform (world axes, about its origin): (6,)
            constant or a callable ``SimState -> (6,)``; default none.
        reference: platform reference, only recorded (controllers carry their own).
        method: forward-dynamics route ("pinocchio", "qp", "kkt").
        integrator: one of :data:`~hexapod_pin.core.simulation.INTEGRATORS`: "auto"
            (default: "stick_slip" when the robot's joint effects have Coulomb friction,
            else "rk4"), "rk4", "semi_implicit_euler" or "stick_slip" (see
            :func:`~hexapod_pin.core.simulation.resolve_integrator`). The joint effects
            (``robot.effects``) act in every step.
        projection_tol: closure residual (m) above which a step is projected.
        check_limits: check the strokes and the carriage gap after every step.
        on_limit: "stop" (return with status "stroke_limit" / "carriage_gap") or
            "raise" (:class:`StrokeLimitError`).
        saturation: what to do with commands beyond ``geometry.max_actuator_force``:
            "clip" (the actuator saturates; recorded in ``saturated``), "raise"
            (:class:`ActuatorSaturationError`) or "ignore".
        record_every: record one sample every this many steps.
        progress: called as ``progress(steps_done, steps_total)`` about 100 times.
        friction_regularisation: ``v_eps`` (m/s or rad/s): Coulomb friction made smooth,
            ``-coulomb tanh(v / v_eps)`` (an approximation, any integrator); None: exact.

    Returns:
        :class:`Trajectory`. A dynamics or projection failure stops the run with
        status "failed" and the message.

    Raises:
        InputError: bad arguments.
        StrokeLimitError: with ``on_limit="raise"``.
        ActuatorSaturationError: with ``saturation="raise"``.
    """
    import time as _time

    record_every = check_run_arguments(duration, dt, on_limit, saturation, record_every)
    projection_tol = real_number(projection_tol, "projection_tol", minimum=0.0)
    if controller is not None and actuator_forces is not None:
        raise InputError("actuator_forces", actuator_forces, "give forces or a controller")
    if pose0 is None:
        pose0 = reference(0.0).pose if reference is not None else robot.home_pose
    if twist0 is None:
        twist0 = reference(0.0).twist if reference is not None else np.zeros(6)
    pose0, twist0 = as_array(pose0, (6,), "pose0"), as_array(twist0, (6,), "twist0")
    const_forces = None
    if actuator_forces is not None and not callable(actuator_forces):
        const_forces = as_array(actuator_forces, (6,), "actuator_forces")
    const_wrench = None
    if wrench is not None and not callable(wrench):
        const_wrench = as_array(wrench, (6,), "wrench")

    clm = robot.model
    idx = robot.indices
    geom = robot.geometry
    closed_form = robot.closed_form
    integ = ClosedLoopIntegrator(clm, method, integrator,
                                 residual=closed_form.closure_residual,
                                 friction_regularisation=friction_regularisation)
    with robot.lock:
        q_tree, v_tree = robot.dynamics.tree_state(pose0, twist0)
    q_tree = q_tree.copy()
    limit = geom.max_actuator_force
    act_v = clm.actuated_v
    ff_q, ff_v = idx.platform_q, robot.dynamics.platform_velocity_indices

    n_steps = max(1, round(duration / dt))
    n_rec = n_steps // record_every + 1
    rec_t = np.empty(n_rec)
    rec_q = np.empty((n_rec, clm.nq))
    rec_v = np.empty((n_rec, clm.nv))
    rec_f = np.zeros((n_rec, 6))
    rec_sat = np.zeros(n_rec, dtype=bool)
    rec_res = np.empty(n_rec)
    rec_lost = np.zeros(n_rec)
    lost = 0.0                          # J dissipated by damping and friction so far
    rec_ref = np.empty((n_rec, 6)) if reference is not None else np.empty((0, 6))
    status, message = "completed", ""
    if controller is not None and hasattr(controller, "reset"):
        controller.reset()

    def state_of(t, q, v) -> SimState:
        return _sim_state(robot, ff_v, t, q, v)

    def command(t, q, v):
        state = None
        if controller is not None:
            state = state_of(t, q, v)
            forces = as_array(controller(state, dt), (6,), "controller output")
        elif const_forces is not None:
            forces = const_forces
        elif actuator_forces is not None:
            forces = as_array(actuator_forces(t), (6,), "actuator_forces(t)")
        else:
            forces = np.zeros(6)
        sat = False
        if np.isfinite(limit) and np.any(np.abs(forces) > limit):
            if saturation == "raise":
                raise ActuatorSaturationError(forces, np.full(6, limit))
            if saturation == "clip":
                forces = np.clip(forces, -limit, limit)
                sat = True
        tau = np.zeros(clm.nv)
        tau[act_v] = forces
        if wrench is not None:
            w = const_wrench if const_wrench is not None else as_array(
                wrench(state if state is not None else state_of(t, q, v)), (6,), "wrench(state)")
            rot = rotation_from_quaternion(*q[ff_q][3:])
            tau[ff_v] += np.concatenate([rot.T @ w[:3], rot.T @ w[3:]])
        return forces, tau, sat

    q_tree, v_tree, res0 = integ.project(q_tree, v_tree, projection_tol)
    every = max(1, n_steps // 100)
    start = _time.perf_counter()
    t = 0.0
    k_rec = 0
    forces, tau, sat = command(t, q_tree, v_tree)
    rec_t[0], rec_q[0], rec_v[0], rec_f[0], rec_sat[0], rec_res[0] = t, q_tree, v_tree, forces, \
        sat, res0
    if reference is not None:
        rec_ref[0] = reference(0.0).pose
    half = geom.rail_half_length
    gap = geom.carriage_min_gap
    cq = idx.carriage_q
    for step in range(1, n_steps + 1):
        try:
            q_tree, v_tree, res = integ.step(q_tree, v_tree, tau, dt, projection_tol)
        except HexapodPinError as exc:
            status, message = "failed", f"at t = {t:.6g} s: {exc}"
            break
        t = step * dt
        lost += integ.dissipated
        if not (np.all(np.isfinite(q_tree)) and np.all(np.isfinite(v_tree))):
            status, message = "failed", f"at t = {t:.6g} s: non-finite state"
            break
        stop = ""
        if check_limits:
            qc = q_tree[cq]
            if np.any(np.abs(qc) > half):
                stop = "stroke_limit"
            elif np.any(qc[1::2] - qc[0::2] < gap):
                stop = "carriage_gap"
        if not stop:
            try:
                forces, tau, sat = command(t, q_tree, v_tree)
            except HexapodPinError as exc:
                if isinstance(exc, ActuatorSaturationError):
                    raise
                status, message = "failed", f"at t = {t:.6g} s: controller: {exc}"
                break
        if step % record_every == 0 or stop:
            k_rec += 1
            rec_t[k_rec], rec_q[k_rec], rec_v[k_rec], rec_res[k_rec] = t, q_tree, v_tree, res
            rec_lost[k_rec] = lost
            rec_f[k_rec], rec_sat[k_rec] = (forces, sat) if not stop else (rec_f[k_rec - 1],
                                                                             False)
            if reference is not None:
                rec_ref[k_rec] = reference(t).pose
        if stop:
            violations = robot.stroke_violations(q_tree[cq])
            if on_limit == "raise":
                raise StrokeLimitError(q_tree[cq], violations)
            status, message = stop, f"at t = {t:.6g} s: " + "; ".join(violations)
            break
        if progress is not None and (step % every == 0 or step == n_steps):
            progress(step, n_steps)
    wall = _time.perf_counter() - start
    n = k_rec + 1
    if status == "completed":
        status, message = saturation_status(rec_sat[:n], rec_t[:n])
    poses, twists = _platform_states(idx.platform_q, ff_v, rec_q[:n], rec_v[:n])
    return Trajectory(rec_t[:n].copy(), poses, twists, rec_q[:n, idx.carriage_q].copy(),
                      rec_v[:n, idx.carriage_v].copy(), rec_f[:n].copy(), rec_sat[:n].copy(),
                      rec_res[:n].copy(), rec_q[:n].copy(), rec_v[:n].copy(),
                      rec_ref[:n].copy() if reference is not None else rec_ref, status,
                      message, float(dt), wall, integ.integrator, rec_lost[:n].copy())


def _sim_state(robot, ff_v, t: float, q: np.ndarray, v: np.ndarray) -> SimState:
    """The controller's view of a tree state (pose, world twist, carriages)."""
    idx = robot.indices
    ff = q[idx.platform_q]
    rot = rotation_from_quaternion(*ff[3:])
    pose = np.concatenate([ff[:3], rpy_from_rotation(rot)])
    twist = np.concatenate([rot @ v[ff_v][:3], rot @ v[ff_v][3:]])
    return SimState(t, pose, twist, q[idx.carriage_q].copy(), v[idx.carriage_v].copy(), q, v)


def _platform_states(ff_q: slice, ff_v: np.ndarray, qs: np.ndarray, vs: np.ndarray):
    """Poses (n, 6) and world twists (n, 6) from tree states (n, nq), (n, nv)."""
    rots = np.stack([rotation_from_quaternion(*quat) for quat in qs[:, ff_q][:, 3:]])
    poses = np.concatenate([qs[:, ff_q][:, :3], rpy_from_rotation(rots)], axis=1)
    vff = vs[:, ff_v]
    twists = np.concatenate([np.einsum("nij,nj->ni", rots, vff[:, :3]),
                             np.einsum("nij,nj->ni", rots, vff[:, 3:])], axis=1)
    return poses, twists

"""Simulation of the closed-loop hexapod: integration, drift control, controllers.

Integration (:class:`ClosedLoopIntegrator`, generic over a :class:`ClosedLoopModel`
whose joints are 1-DoF or free-flyers):

* the state is the tree's ``(q, v)`` (Pinocchio conventions);
* classical fourth-order Runge-Kutta on ``q`` as a vector of ``R^nq`` and ``v``:
  ``qdot`` from ``v`` through the joint kinematics (1-DoF joints ``qdot = v``; a
  free-flyer ``p' = R v_lin``, quaternion ``Q' = 1/2 Q (x) (w_body, 0)``), ``vdot``
  from the constrained forward dynamics (``pin.constraintDynamics`` by default);
  the actuator forces and the wrench are held constant over a step (zero-order hold:
  the controller runs once per step, at the sample time);
* after each step, drift control by projection onto the constraint manifold: the
  quaternions are renormalised; when the closure residual ``r`` exceeds ``projection_tol``
  (default 1e-10 m),
  ``q`` gets Gauss-Newton corrections ``q <- q (+) (-J_c^+ r)`` (minimum norm over all
  coordinates; quadratic convergence, to round-off) and the velocity is projected,
  ``v <- v - J_c^+ J_c v``. RK4 drifts by about 1e-13 m per step in fast motions, so
  the projection runs every few hundred steps. The residual is checked after every step;
  the hexapod's :func:`simulate` checks it in closed form
  (:meth:`~hexapod_pin.platform_map.PlatformMap.closure_residual`, the same quantity).

Cost: an RK4 step is four ``pin.constraintDynamics`` calls plus Python glue (a few
hundred µs from Python on a small machine): a few times faster than real time at 1 kHz,
far from the 1000x of issue 5, which needs compiled code (no per-call Python).

The hexapod-level :func:`simulate` runs it from a platform state under given actuator
forces or a controller (:class:`PIDController` with the Quanser gains, or
:class:`ComputedTorqueController` using :meth:`Hexapod.inverse_dynamics`), checks the
stroke limits and the carriage gap at every step, and returns a :class:`Trajectory`.
The library never prints: pass ``progress`` to follow a long run.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import pinocchio as pin

from .closed_loop import ClosedLoopModel
from .dynamics import FORWARD_METHODS, dynamics_of
from .errors import ActuatorSaturationError, HexapodPinError, InputError, StrokeLimitError
from .pose import as_array, rotation_from_rpy, rpy_from_rotation

#: closure residual above which a step is projected back onto the closures (m)
PROJECTION_TOL = 1e-10
_SUPPORTED_1DOF = {"JointModelRX", "JointModelRY", "JointModelRZ", "JointModelPX",
                   "JointModelPY", "JointModelPZ", "JointModelRevoluteUnaligned",
                   "JointModelPrismaticUnaligned"}
INTEGRATORS = ("rk4", "semi_implicit_euler")
STATUSES = ("completed", "stroke_limit", "carriage_gap", "failed")


# --------------------------------------------------------------------------------------
# generic integrator
# --------------------------------------------------------------------------------------
class ClosedLoopIntegrator:
    """Fixed-step integrator of a closed-loop tree with projection onto the closures.

    Args:
        clm: the closed-loop model (joints: 1-DoF revolute / prismatic, or free-flyer).
        method: forward-dynamics route, "pinocchio" (default), "qp" or "kkt".
        integrator: "rk4" (classical Runge-Kutta, four dynamics calls per step) or
            "semi_implicit_euler" (one call per step; fast, first order, energy not
            conserved to better than O(dt)).
        residual: optional callable ``q -> max-abs closure residual`` (m) replacing the
            generic evaluation through Pinocchio's frames (e.g. the hexapod's closed form
            :meth:`~hexapod_pin.platform_map.PlatformMap.closure_residual`); it must
            return the same quantity as :meth:`ClosedLoopModel.residual`.

    Raises:
        InputError: an unsupported joint type, method or integrator.
    """

    def __init__(self, clm: ClosedLoopModel, method: str = "pinocchio",
                 integrator: str = "rk4", residual: Callable[[np.ndarray], float] | None = None):
        if method not in FORWARD_METHODS:
            raise InputError("method", method, f"expected one of {FORWARD_METHODS}")
        if integrator not in INTEGRATORS:
            raise InputError("integrator", integrator, f"expected one of {INTEGRATORS}")
        self.clm = clm
        self.dyn = dynamics_of(clm)
        self.method = method
        self.integrator = integrator
        self._residual_fn = residual
        model = clm.model
        self._ff: list[tuple[int, int]] = []      # (idx_q, idx_v) of free-flyers
        vec_q, vec_v = [], []
        for jid in range(1, model.njoints):
            joint = model.joints[jid]
            name = joint.shortname()
            if name == "JointModelFreeFlyer":
                self._ff.append((joint.idx_q, joint.idx_v))
            elif name in _SUPPORTED_1DOF:
                vec_q.append(joint.idx_q)
                vec_v.append(joint.idx_v)
            else:
                raise InputError("clm", name, "the integrator supports 1-DoF revolute / "
                                              "prismatic joints and free-flyers only")
        self._vec_q = np.array(vec_q, dtype=int)
        self._vec_v = np.array(vec_v, dtype=int)
        # contiguous blocks of 1-DoF coordinates are copied as slices (cheaper than indices)
        self._vec_slices = None
        if vec_q and vec_q == list(range(vec_q[0], vec_q[0] + len(vec_q))) and \
                vec_v == list(range(vec_v[0], vec_v[0] + len(vec_v))):
            self._vec_slices = (slice(vec_q[0], vec_q[0] + len(vec_q)),
                                slice(vec_v[0], vec_v[0] + len(vec_v)))
        self._fast = None

    # -- kinematics of the configuration vector -------------------------------------------
    def qdot(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Time derivative of ``q`` as a vector of ``R^nq`` for the velocity ``v``."""
        out = np.empty_like(q)
        if self._vec_slices is not None:
            out[self._vec_slices[0]] = v[self._vec_slices[1]]
        else:
            out[self._vec_q] = v[self._vec_v]
        for iq, iv in self._ff:
            x, y, z, w = q[iq + 3:iq + 7].tolist()
            vx, vy, vz, wx, wy, wz = v[iv:iv + 6].tolist()
            # p' = R v_lin (R of the unit quaternion)
            tx, ty, tz = 2.0 * (y * vz - z * vy), 2.0 * (z * vx - x * vz), 2.0 * (x * vy - y * vx)
            out[iq:iq + 7] = (vx + w * tx + (y * tz - z * ty), vy + w * ty + (z * tx - x * tz),
                              vz + w * tz + (x * ty - y * tx),
                              0.5 * (w * wx + y * wz - z * wy), 0.5 * (w * wy + z * wx - x * wz),
                              0.5 * (w * wz + x * wy - y * wx), -0.5 * (x * wx + y * wy + z * wz))
        return out

    def _normalise(self, q: np.ndarray) -> None:
        for iq, _ in self._ff:
            x, y, z, w = q[iq + 3:iq + 7].tolist()
            inv = 1.0 / math.sqrt(x * x + y * y + z * z + w * w)
            q[iq + 3:iq + 7] = (x * inv, y * inv, z * inv, w * inv)

    # -- dynamics ---------------------------------------------------------------------------
    def acceleration(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray,
                     checked: bool = True) -> np.ndarray:
        """Tree acceleration (nv,) for the generalised force ``tau`` (nv,).

        ``checked=False`` skips the per-call failure check of the direct Pinocchio call
        (the caller checks its final result and retries checked).
        """
        dyn = self.dyn
        if self.method == "pinocchio":
            fast = self._fast
            if fast is None:
                fast = self._fast = self._fast_call(q)
            if fast:
                acc = pin.constraintDynamics(*fast[0], q, v, tau, *fast[1])
                if not checked or math.isfinite(acc.sum()):
                    return acc.copy()
            return dyn._acceleration_pinocchio(q, v, tau)
        return dyn.forward(q, v, tau, self.method).a

    def _fast_call(self, q: np.ndarray):
        """Bound arguments of ``pin.constraintDynamics`` when the closures are not
        redundant (else ``()``: the generic route handles redundancy)."""
        dyn = self.dyn
        if dyn._ensure_rank(q) < dyn.n_rows:
            return ()
        if not dyn._pin_ready:
            dyn._init_pinocchio()
        return ((dyn.model, dyn.data), (dyn._cms, dyn._cds, dyn._prox_exact))

    def step(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, dt: float,
             projection_tol: float = PROJECTION_TOL):
        """One step of length ``dt`` (s) with ``tau`` (nv,) held; returns ``(q, v, residual)``.

        ``residual`` is the max-abs closure residual after the projection (m).

        Raises:
            AssemblyError: the projection does not converge.
        """
        if self.integrator == "rk4":
            q_new, v_new = self._rk4(q, v, tau, dt, checked=False)
            if not math.isfinite(v_new.sum()):
                q_new, v_new = self._rk4(q, v, tau, dt, checked=True)
        else:
            v_new = v + dt * self.acceleration(q, v, tau)
            q_new = pin.integrate(self.clm.model, q, dt * v_new)
        return self.project(q_new, v_new, projection_tol)

    def _rk4(self, q, v, tau, dt, checked: bool):
        qdot, normalise = self.qdot, self._normalise

        def acc(qs, vs):
            return self.acceleration(qs, vs, tau, checked)

        half = 0.5 * dt
        a1 = acc(q, v)
        d1 = qdot(q, v)
        q2, v2 = q + half * d1, v + half * a1
        normalise(q2)
        a2 = acc(q2, v2)
        d2 = qdot(q2, v2)
        q3, v3 = q + half * d2, v + half * a2
        normalise(q3)
        a3 = acc(q3, v3)
        d3 = qdot(q3, v3)
        q4, v4 = q + dt * d3, v + dt * a3
        normalise(q4)
        a4 = acc(q4, v4)
        d4 = qdot(q4, v4)
        sixth = dt / 6.0
        q_new = q + sixth * (d1 + d4 + 2.0 * (d2 + d3))
        v_new = v + sixth * (a1 + a4 + 2.0 * (a2 + a3))
        normalise(q_new)
        return q_new, v_new

    def residual(self, q: np.ndarray) -> float:
        """Max-abs closure residual at ``q`` (m / rad)."""
        if self._residual_fn is not None:
            return float(self._residual_fn(q))
        pin.framesForwardKinematics(self.clm.model, self.dyn.data, q)
        return float(np.max(np.abs(self._residual_from_data()), initial=0.0))

    def project(self, q: np.ndarray, v: np.ndarray, trigger: float = PROJECTION_TOL,
                max_iter: int = 8):
        """Project ``(q, v)`` onto the closures when the residual exceeds ``trigger``.

        Gauss-Newton steps ``q <- q (+) (-J_c^+ r)`` until the residual stops
        decreasing tenfold or falls below ``1e-3 trigger``, then ``v <- v - J_c^+ J_c v``.
        Returns ``(q, v, residual)``; untouched when the residual is below ``trigger``.

        Raises:
            AssemblyError: the residual stays above ``trigger`` after ``max_iter`` steps.
        """
        from .errors import AssemblyError

        err = self.residual(q)
        if err <= trigger:
            return q, v, err
        dyn = self.dyn
        model = self.clm.model
        for iteration in range(max_iter):
            jac = dyn.constraint_jacobian(q)
            res = self._residual_from_data()
            err = float(np.max(np.abs(res), initial=0.0))
            if not np.isfinite(err):
                break
            q_new = pin.integrate(model, q, -_pinv_apply(jac, res))
            err_new = self.residual(q_new)
            if not err_new < err:
                break
            q, err = q_new, err_new
            if err <= 1e-3 * trigger or err_new > 0.1 * err:
                break
        if not (err <= trigger):
            raise AssemblyError("projection onto the closures failed", err, max_iter, q)
        jac = dyn.constraint_jacobian(q)
        v = v - _pinv_apply(jac, jac @ v)
        return q, v, err

    def _residual_from_data(self) -> np.ndarray:
        data = self.dyn.data
        out = np.empty(self.dyn.n_rows)
        for is_point, rows, f1, f2, _, _ in self.dyn._closures:
            m1, m2 = data.oMf[f1], data.oMf[f2]
            out[rows] = (m1.translation - m2.translation if is_point
                         else pin.log6(m2.actInv(m1)).vector)
        return out


def _pinv_apply(jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``J^+ rhs`` (minimum norm) through ``J J^T``; least squares if that is singular."""
    try:
        sol = jac.T @ np.linalg.solve(jac @ jac.T, rhs)
        if np.isfinite(sol.sum()):
            return sol
    except np.linalg.LinAlgError:
        pass
    sol, *_ = np.linalg.lstsq(jac, rhs, rcond=None)
    return sol


def _quat_matrix(x, y, z, w) -> np.ndarray:
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


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
        configuration, velocity: the tree state (Pinocchio conventions).
    """

    t: float
    pose: np.ndarray
    twist: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    configuration: np.ndarray
    velocity: np.ndarray


Controller = Callable[[SimState, float], np.ndarray]


class PIDController:
    """Joint-space PID per carriage tracking set-points from IK of a platform reference.

    ``tau = kp e + ki integral(e) + kd de/dt (+ static feed-forward)``, ``e = q_ref -
    q``, ``q_ref = IK(reference.pose)``, ``qdot_ref = J reference.twist``. The
    integral is a forward sum over the control periods. Defaults: the Quanser lab gains.

    Note: it runs once per step (zero-order hold). A discrete D term is stable only
    when ``kd dt / m < 2`` with ``m`` the effective carriage mass; for the default
    (placeholder) masses the effective masses are 0.6 - 1.5 kg, so the Quanser gains
    need ``dt`` below about 0.4 ms (4 kHz).

    Args:
        robot: the :class:`Hexapod`.
        reference: callable ``t -> PlatformReference``.
        kp: N/m. ki: N/(m s). kd: N s/m.
        feedforward: add the static forces of the reference pose.
    """

    def __init__(self, robot, reference: ReferenceTrajectory, kp: float = 30000.0,
                 ki: float = 40000.0, kd: float = 3000.0, feedforward: bool = False):
        self.robot = robot
        self.reference = reference
        self.kp, self.ki, self.kd = float(kp), float(ki), float(kd)
        self.feedforward = feedforward
        self.integral = np.zeros(6)

    def reset(self) -> None:
        """Clear the integral."""
        self.integral = np.zeros(6)

    def setpoints(self, t: float):
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

    def __init__(self, robot, reference: ReferenceTrajectory, kp: float = 400.0,
                 kd: float = 40.0, method: str = "kkt"):
        if method not in ("kkt", "qp"):
            raise InputError("method", method, "expected 'kkt' or 'qp'")
        self.robot = robot
        self.reference = reference
        self.kp, self.kd = float(kp), float(kd)
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
        return self.robot._actuator_forces_at(state.configuration, state.twist, cmd,
                                              method=self.method)


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
        status: "completed", "stroke_limit", "carriage_gap" or "failed".
        message: details of a stop (which carriage, which limit, which error).
        dt: the step (s).
        wall_time: seconds spent in the integration loop.
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

    @property
    def real_time_factor(self) -> float:
        """Simulated time divided by wall time."""
        span = float(self.times[-1] - self.times[0]) if self.times.size else 0.0
        return span / self.wall_time if self.wall_time > 0 else float("inf")


def check_run_arguments(duration, dt, on_limit, saturation, record_every) -> int:
    """Validate the run arguments shared by :func:`simulate` and
    :func:`hexapod_pin.fast.simulate_fast`; returns ``record_every`` as an int.

    Raises:
        InputError: a non-positive or non-finite ``duration`` / ``dt``, an unknown
            ``on_limit`` ("stop" or "raise") or ``saturation`` ("clip", "raise" or
            "ignore"), ``record_every < 1``.
    """
    if not (np.isfinite(duration) and duration > 0):
        raise InputError("duration", duration, "must be a positive number")
    if not (np.isfinite(dt) and dt > 0):
        raise InputError("dt", dt, "must be a positive number")
    if on_limit not in ("stop", "raise"):
        raise InputError("on_limit", on_limit, "expected 'stop' or 'raise'")
    if saturation not in ("clip", "raise", "ignore"):
        raise InputError("saturation", saturation, "expected 'clip', 'raise' or 'ignore'")
    if int(record_every) < 1:
        raise InputError("record_every", record_every, "must be >= 1")
    return int(record_every)


def simulate(robot, duration: float, dt: float = 1e-3, *, pose0=None, twist0=None,
             actuator_forces=None, controller: Controller | None = None, wrench=None,
             reference: ReferenceTrajectory | None = None, method: str = "pinocchio",
             integrator: str = "rk4", projection_tol: float = PROJECTION_TOL,
             check_limits: bool = True, on_limit: str = "stop",
             saturation: str = "clip", record_every: int = 1,
             progress: Callable[[int, int], None] | None = None) -> Trajectory:
    """Integrate the closed-loop dynamics of the hexapod.

    Args:
        robot: the :class:`Hexapod`.
        duration: simulated time (s).
        dt: step and control period (s).
        pose0, twist0: initial platform state (default: home at rest; with a
            ``reference``, its state at t = 0).
        actuator_forces: used without a controller: (6,) constant, or a callable
            ``t -> (6,)`` (N); default zero (unactuated).
        controller: callable ``(SimState, dt) -> (6,)`` forces (N), called once per
            step (``reset()`` is called first when it has one).
        wrench: ``(f, m)`` on the platform (world axes, about its origin): (6,)
            constant or a callable ``SimState -> (6,)``; default none.
        reference: platform reference, only recorded (controllers carry their own).
        method: forward-dynamics route ("pinocchio", "qp", "kkt").
        integrator: "rk4" (default) or "semi_implicit_euler" (see the module doc).
        projection_tol: closure residual (m) above which a step is projected.
        check_limits: check the strokes and the carriage gap after every step.
        on_limit: "stop" (return with status "stroke_limit" / "carriage_gap") or
            "raise" (:class:`StrokeLimitError`).
        saturation: what to do with commands beyond ``geometry.max_actuator_force``:
            "clip" (the actuator saturates; recorded in ``saturated``), "raise"
            (:class:`ActuatorSaturationError`) or "ignore".
        record_every: record one sample every this many steps.
        progress: called as ``progress(steps_done, steps_total)`` about 100 times.

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

    ws = robot._workspace()
    clm = robot.model
    idx = robot.indices
    geom = robot.geometry
    pmap = robot._platform_map
    integ = ClosedLoopIntegrator(clm, method, integrator,
                                 residual=lambda q: pmap.closure_residual(q.tolist()))
    q_tree, v_tree = robot._tree_state_of(pose0, twist0)
    q_tree = q_tree.copy()
    limit = geom.max_actuator_force
    act_v = clm.actuated_v
    ff_q, ff_v = idx.platform_q, ws.ff_v

    n_steps = max(1, round(duration / dt))
    n_rec = n_steps // record_every + 1
    rec_t = np.empty(n_rec)
    rec_q = np.empty((n_rec, clm.nq))
    rec_v = np.empty((n_rec, clm.nv))
    rec_f = np.zeros((n_rec, 6))
    rec_sat = np.zeros(n_rec, dtype=bool)
    rec_res = np.empty(n_rec)
    rec_ref = np.empty((n_rec, 6)) if reference is not None else np.empty((0, 6))
    status, message = "completed", ""
    if hasattr(controller, "reset"):
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
            rot = _quat_matrix(*q[ff_q][3:])
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
    poses, twists = _platform_states(idx.platform_q, ff_v, rec_q[:n], rec_v[:n])
    return Trajectory(rec_t[:n].copy(), poses, twists, rec_q[:n, idx.carriage_q].copy(),
                      rec_v[:n, idx.carriage_v].copy(), rec_f[:n].copy(), rec_sat[:n].copy(),
                      rec_res[:n].copy(), rec_q[:n].copy(), rec_v[:n].copy(),
                      rec_ref[:n].copy() if reference is not None else rec_ref, status,
                      message, float(dt), wall)


def _sim_state(robot, ff_v, t: float, q: np.ndarray, v: np.ndarray) -> SimState:
    """The controller's view of a tree state (pose, world twist, carriages)."""
    idx = robot.indices
    ff = q[idx.platform_q]
    rot = _quat_matrix(*ff[3:])
    pose = np.concatenate([ff[:3], rpy_from_rotation(rot)])
    twist = np.concatenate([rot @ v[ff_v][:3], rot @ v[ff_v][3:]])
    return SimState(t, pose, twist, q[idx.carriage_q].copy(), v[idx.carriage_v].copy(), q, v)


def _platform_states(ff_q: slice, ff_v: np.ndarray, qs: np.ndarray, vs: np.ndarray):
    """Poses (n, 6) and world twists (n, 6) from tree states (n, nq), (n, nv)."""
    rots = np.stack([_quat_matrix(*quat) for quat in qs[:, ff_q][:, 3:]])
    poses = np.concatenate([qs[:, ff_q][:, :3], rpy_from_rotation(rots)], axis=1)
    vff = vs[:, ff_v]
    twists = np.concatenate([np.einsum("nij,nj->ni", rots, vff[:, :3]),
                             np.einsum("nij,nj->ni", rots, vff[:, 3:])], axis=1)
    return poses, twists

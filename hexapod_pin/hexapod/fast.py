"""Compiled drivers of the hexapod's closed form: single-state dynamics and simulation.

:class:`FastDynamics` calls the single-state kernels of :mod:`hexapod_pin.hexapod.kernels`
(Newton-Euler inverse dynamics, forward dynamics by the reduced equation ``M_x twist_dot =
J^T tau + wrench - h_x``, statics) with preallocated scratch and raises the library's
exceptions from their status codes. :func:`simulate_fast` and :class:`FastStepper`
integrate the dynamics in independent (platform) coordinates in one compiled loop
(:func:`simulate_kernel`) that calls the same kernels; the tests check them against the
Pinocchio routes of the hexapod to 1e-10 and against the tree simulator.

Conventions (those of the library): pose ``(x, y, z, roll, pitch, yaw)`` (m, rad) with
``R = Rz(yaw) Ry(pitch) Rx(roll)``; twist ``(v, w)`` of the platform origin, world axes;
``twist_dot`` its plain time derivative; ``tau_i`` the force on carriage i along ``+u_k``
(N), carriage order; wrench ``(f, m)`` applied on the platform by the environment, world
axes, moment about the platform origin (N, N m); home IK branch. The kernels read the
geometry per chain (:func:`~hexapod_pin.hexapod.kernels.pack_geometry`), so an as-built
robot runs the same code as the ideal one.

Simulation (:func:`simulate_fast`): state ``(p, Q, v, w)`` with ``Q`` the unit quaternion
of ``R`` (no gimbal lock), ``dp/dt = v``, ``dQ/dt = 1/2 (0, w) (x) Q`` (world angular
velocity), ``d(v, w)/dt = a`` from the forward dynamics. Forces are held over a step
(zero-order hold), either constant or a joint PID on carriage set-points (IK and
``J twist`` of a sampled platform reference, computed once per reference sample before
the loop; the law of :class:`~hexapod_pin.hexapod.simulation.PIDController`). Integrators:

``"rk4"`` (default)
    classical Runge-Kutta, four forward dynamics per step, the quaternion renormalised
    after the step; fourth order (the error falls 16x when ``dt`` halves). Caveat of the
    zero-order hold, not of RK4: a command held over the step lags by half a step on
    average, so an undamped stiff P-law (no ``kd``) gains energy.
``"rk2"``
    explicit midpoint, two forward dynamics per step; second order.
``"semi_implicit_euler"``
    one forward dynamics per step: ``(v, w)+ = (v, w) + dt a``, then ``p+ = p + dt v+``
    and ``Q+ = exp(dt w+) (x) Q`` (the scheme of MuJoCo's default Euler integrator for a
    free joint). First order; not symplectic here (the mass matrix depends on the pose):
    unactuated it slowly loses energy, also under an undamped P-law.

Independent coordinates keep the closures exactly (the tree is rebuilt from the pose), so
there is no drift to project.

Joint and drive effects (``robot.effects``): the kernels carry the carriages' drives
(armature, damping, Coulomb friction with stick / slip at rest, springs: see
:mod:`hexapod_pin.hexapod.kernels`), so :class:`FastDynamics` and the simulator include
them. Effects on passive coordinates (universal joints, the platform's free flyer) are not
modelled by the kernels: :class:`FastDynamics` then answers with the robot's Pinocchio
routes, and the simulator refuses the robot (:func:`hexapod_pin.core.simulate.simulate`
with ``backend="tree"`` integrates it). The result, :class:`FastTrajectory`, is a smaller
:class:`~hexapod_pin.hexapod.simulation.Trajectory` (no tree configurations; rebuild one
with ``robot.configuration(pose)``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from ..core.checks import as_array, check_finite_result, real_number
from ..core.compiled import all_finite
from ..errors import ActuatorSaturationError, HexapodPinError, InputError, StrokeLimitError
from ..core import effects_projection as drv
from . import kernels as K
from ..core.compiled import FAST_FLAGS, LEAN_FLAGS, jit_inline, kernel
from ..core.pose import quaternion_rpy, rotation_quat, rpy_of
from ..core.simulate import real_time_factor
from .kernels import (GAP, GIMBAL, NONFINITE, NOT_PD, OK, SATURATED, STROKE, TYPE_I, TYPE_II,
                      UNREACHABLE)
from .robot import Hexapod
from .simulation import (PID_KD, ReferenceTrajectory, check_run_arguments,
                         saturation_status)

__all__ = ["FastDynamics", "FastStepper", "FastTrajectory", "compiled_geometry",
           "fast_dynamics", "has_friction", "simulate_fast"]

_STATUS_OF_CODE = {STROKE: "stroke_limit", GAP: "carriage_gap"}
_ZERO6 = K.ZERO6

# -- simulation -------------------------------------------------------------------------
# integrators (codes of the kernel) and their explicit Runge-Kutta tableaux (diagonal:
# stage s is evaluated at state + _RK_A[s] dt k_{s-1}; the step is sum_s _RK_B[s] dt k_s)
RK4, SEMI_IMPLICIT_EULER, RK2 = range(3)
INTEGRATORS = {"rk4": RK4, "rk2": RK2, "semi_implicit_euler": SEMI_IMPLICIT_EULER}
_RK_A = np.array([[0.0, 0.5, 0.5, 1.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0]])
_RK_B = np.array([[1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0], [1.0, 0.0, 0.0, 0.0],
                  [0.0, 1.0, 0.0, 0.0]])
_RK_STAGES = np.array([4, 1, 2])


@jit_inline
def _carriages(geo, state, rot, wk, twist):
    """Legs (home branch) and rates of a state ``(p, Q (w, x, y, z), v, w)``; returns a
    code (stroke not checked)."""
    rotation_quat(state[3], state[4], state[5], state[6], rot)
    code = K.legs(geo, state[0], state[1], state[2], rot, K.HOME_BRANCH, wk)
    if code != OK:
        return code
    for j in range(6):
        twist[j] = state[7 + j]
    K.rates(geo, twist, wk, True)
    return OK


@kernel(FAST_FLAGS, work=1)
def _set_points(geo, ref_poses, ref_twists, feedforward, setpoints):
    """Carriage set-points of the reference rows into ``setpoints`` (3, m, 6): ``q``
    (IK), ``qdot`` (``J twist``) and, with ``feedforward``, the static forces of the pose
    (zero wrench), else zero. Returns ``(first_bad_row, code)``; ``first_bad_row = m``
    when all succeed."""
    rot, wk, mats = np.empty(9), np.zeros((K.WK_ROWS, 6)), np.empty((K.N_MATS, 6, 6))
    n_rows = setpoints.shape[1]
    for row in range(n_rows):
        code = K.leg_state(geo, K.HOME_BRANCH, ref_poses[row], rot, wk)
        if code != OK:
            return row, code
        K.rates(geo, ref_twists[row], wk, False)
        for i in range(6):
            setpoints[0, row, i], setpoints[1, row, i] = wk[K.Q, i], wk[K.QD, i]
            setpoints[2, row, i] = 0.0
        if feedforward:
            code = K.static_forces(geo, K.HOME_BRANCH, ref_poses[row], K.ZERO6, False,
                                   setpoints[2, row], rot, wk, mats)
            if code != OK:
                return row, code
    return n_rows, OK


@jit_inline
def _command(geo, wk, k, mode, forces_in, ref_q, ref_qd, ref_ff, bad_row, bad_code, gains,
             integral, dt, saturation, forces):
    """Actuator forces of step ``k`` into ``forces``; returns (code, saturated)."""
    if mode == 0:
        for i in range(6):
            forces[i] = forces_in[i]
    else:
        row = min(k, ref_q.shape[0] - 1)
        if row >= bad_row:
            return bad_code, False
        kp, ki, kd = gains[0], gains[1], gains[2]
        for i in range(6):
            err = ref_q[row, i] - wk[K.Q, i]
            forces[i] = kp * err + ki * integral[i] + kd * (ref_qd[row, i] - wk[K.QD, i])
            integral[i] += err * dt
            forces[i] += ref_ff[row, i]
    sat = False
    bound = geo[K.BOUND]
    if saturation != 2 and math.isfinite(bound):
        for i in range(6):
            if saturation == 1 and abs(forces[i]) > bound:
                return SATURATED, False
        for i in range(6):
            if abs(forces[i]) > bound:
                forces[i] = max(-bound, min(bound, forces[i]))
                sat = True
    return OK, sat


@jit_inline
def _record(record, n, state, wk, forces, sat, lost):
    rec_state, rec_q, rec_qd, rec_f, rec_sat, rec_lost = record
    for j in range(13):
        rec_state[n, j] = state[j]
    for i in range(6):
        rec_q[n, i], rec_qd[n, i], rec_f[n, i] = wk[K.Q, i], wk[K.QD, i], forces[i]
    rec_sat[n] = sat
    rec_lost[n] = lost


@jit_inline
def _euler_update(state, acc, dt):
    """Semi-implicit Euler on ``state`` in place: ``(v, w) += dt acc``, then ``p += dt v``
    and ``Q <- exp(dt w) (x) Q`` with the new ``(v, w)``; ``Q`` renormalised."""
    for j in range(6):
        state[7 + j] += dt * acc[j]
    for j in range(3):
        state[j] += dt * state[7 + j]
    wx, wy, wz = state[10], state[11], state[12]
    norm = math.sqrt(wx * wx + wy * wy + wz * wz)
    half = 0.5 * dt * norm
    if half < 1e-4:          # Taylor series: relative errors below half^4 / 120 < 1e-18
        h2 = half * half
        ew, s = 1.0 - h2 * (0.5 - h2 / 24.0), 0.5 * dt * (1.0 - h2 / 6.0)
    else:
        ew, s = math.cos(half), math.sin(half) / norm
    ex, ey, ez = s * wx, s * wy, s * wz
    qw, qx, qy, qz = state[3], state[4], state[5], state[6]
    qw, qx, qy, qz = (ew * qw - ex * qx - ey * qy - ez * qz, ew * qx + ex * qw + ey * qz - ez * qy,
                      ew * qy - ex * qz + ey * qw + ez * qx, ew * qz + ex * qy - ey * qx + ez * qw)
    inv = 1.0 / math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    state[3], state[4], state[5], state[6] = qw * inv, qx * inv, qy * inv, qz * inv


@kernel(LEAN_FLAGS, work=1)
def simulate_kernel(geo: np.ndarray, n_steps: int, dt: float, record_every: int, integrator: int,
                    mode: int, forces_in: np.ndarray, wrench: np.ndarray, setpoints: np.ndarray,
                    bad_row: int, bad_code: int, gains: np.ndarray, saturation: int,
                    check_limits: bool, work: tuple[np.ndarray, ...],
                    record: tuple[np.ndarray, ...],
                    last_forces: np.ndarray) -> tuple[int, int, int]:
    """Integration loop; returns ``(code, step, n_recorded)``.

    ``integrator``: RK4, SEMI_IMPLICIT_EULER or RK2. ``mode`` 0: constant forces, 1: PID
    on ``setpoints`` (3, m, 6) (carriage ``q``, ``qdot`` and feedforward forces of each
    reference row, from :func:`_set_points`; rows ``>= bad_row`` failed with
    ``bad_code``). ``saturation`` 0: clip, 1: raise (code SATURATED), 2: ignore.
    ``work``: scratch ``(vecs (4, 13), rot (9,), wk, mats (N_MATS, 6, 6), small (3, 6))``,
    ``vecs[0]`` the initial state. ``record``: ``(state, q, qdot, forces, saturated,
    dissipated)`` arrays of the samples (``dissipated``: the energy the carriages' drives
    dissipated since the start, J: the integrator's quadrature of their power, RK stages
    weighted by the tableau, an Euler step the work of the forces held at its start along
    the rates ``qdot + dt qddot``, as the tree simulator takes it). ``last_forces`` gets
    the last command computed (before clipping when it raised). One loop, one evaluation of
    the dynamics per pass (a step boundary or a Runge-Kutta stage), so that each helper is
    inlined once; no allocation (compiled without the reference-counting runtime).
    """
    vecs, rot, wk, mats, small = work
    state, point, incr, deriv = vecs[0], vecs[1], vecs[2], vecs[3]
    twist, acc, integral = small[0], small[1], small[2]
    rec_f = record[3]
    ref_q, ref_qd, ref_ff = setpoints[0], setpoints[1], setpoints[2]
    drives = geo[K.DRIVES + drv.FLAG] != 0.0
    lost = 0.0
    forces = last_forces
    for j in range(13):
        point[j] = state[j]
    for i in range(6):
        integral[i] = 0.0
    n_stages = _RK_STAGES[integrator]
    step, stage, n_rec = 0, 0, 0
    while True:
        code = _carriages(geo, point, rot, wk, twist)
        if code != OK:
            if stage == 0:
                return code, step, (n_rec + 1 if step > 0 else 0)
            return code, step + 1, n_rec + 1
        if stage == 0:
            # a step boundary: limits, command, recording
            stop = K.limits(geo, wk) if (check_limits and step > 0) else OK
            sat = False
            if stop == OK:
                code, sat = _command(geo, wk, step, mode, forces_in, ref_q, ref_qd, ref_ff,
                                     bad_row, bad_code, gains, integral, dt, saturation,
                                     forces)
                if code != OK:
                    if step == 0:
                        _record(record, 0, state, wk, _ZERO6, False, lost)
                    return code, step, n_rec + 1
            if step == 0:
                _record(record, 0, state, wk, forces, sat, lost)
            elif step % record_every == 0 or stop != OK:
                n_rec += 1
                if stop == OK:
                    _record(record, n_rec, state, wk, forces, sat, lost)
                else:                     # the stop state, with the previous command
                    _record(record, n_rec, state, wk, rec_f[n_rec - 1], False, lost)
            if stop != OK:
                return stop, step, n_rec + 1
            if step == n_steps:
                return OK, n_steps, n_rec + 1
        code = K.forward_core(geo, rot, twist, forces, wrench, wk, mats, acc)
        if code != OK:
            return code, step + 1, n_rec + 1
        if integrator == SEMI_IMPLICIT_EULER:
            _euler_update(state, acc, dt)
            stage = n_stages
            if drives:     # the held forces along the end rates qdot + dt qddot
                nxt = wk[K.STICK]
                for i in range(6):
                    s = wk[K.QDD0, i]
                    for r in range(6):
                        s += mats[0][r, i] * acc[r]
                    nxt[i] = wk[K.QD, i] + dt * s
                lost += dt * drv.dissipated_power(geo, K.DRIVES, 6, wk[K.QD], nxt)
        else:
            b = _RK_B[integrator, stage]
            if drives:
                lost += dt * b * drv.dissipated_power(geo, K.DRIVES, 6, wk[K.QD], wk[K.QD])
            qw, qx, qy, qz = point[3], point[4], point[5], point[6]
            wx, wy, wz = twist[3], twist[4], twist[5]
            deriv[0], deriv[1], deriv[2] = twist[0], twist[1], twist[2]
            deriv[3] = -0.5 * (wx * qx + wy * qy + wz * qz)
            deriv[4] = 0.5 * (qw * wx + wy * qz - wz * qy)
            deriv[5] = 0.5 * (qw * wy + wz * qx - wx * qz)
            deriv[6] = 0.5 * (qw * wz + wx * qy - wy * qx)
            for j in range(6):
                deriv[7 + j] = acc[j]
            stage += 1
            if stage < n_stages:
                a = _RK_A[integrator, stage] * dt
                for j in range(13):
                    incr[j] = (incr[j] if stage > 1 else 0.0) + b * deriv[j]
                    point[j] = state[j] + a * deriv[j]
            else:
                for j in range(13):
                    state[j] += dt * ((incr[j] if stage > 1 else 0.0) + b * deriv[j])
                inv = 1.0 / math.sqrt(state[3] ** 2 + state[4] ** 2 + state[5] ** 2
                                      + state[6] ** 2)
                for j in range(3, 7):
                    state[j] *= inv
        if stage == n_stages:
            if not all_finite(state):
                return NONFINITE, step + 1, n_rec + 1
            for j in range(13):
                point[j] = state[j]
            step += 1
            stage = 0



# --------------------------------------------------------------------------------------
# Python boundary
# --------------------------------------------------------------------------------------


def _vec6(value, name: str) -> np.ndarray:
    """A float64 (6,) array (finiteness is checked inside the kernels)."""
    if type(value) is np.ndarray and value.dtype == np.float64 and value.shape == (6,):
        return value
    return as_array(value, (6,), name)


class FastDynamics:
    """Compiled single-state dynamics of one hexapod (get it with :func:`fast_dynamics`).

    The Newton-Euler closed form of :mod:`~hexapod_pin.hexapod.kernels`: same conventions
    and answers as the Pinocchio routes of the hexapod (to round-off), leaner results
    (plain (6,) arrays, no tree state). Not thread-safe (one scratch per robot).

    Args:
        robot: the :class:`~hexapod_pin.Hexapod`.
    """

    def __init__(self, robot: Hexapod) -> None:
        self.robot = robot
        self.closed_form = robot.closed_form
        self.signs = K.HOME_BRANCH.copy()
        bound = float(robot.geometry.max_actuator_force)
        self._bounds = np.full(6, bound) if math.isfinite(bound) else None

    @property
    def geo(self) -> np.ndarray:
        """The robot's packed geometry with its current drives
        (``robot.closed_form.dynamics_geo``)."""
        return self.closed_form.dynamics_geo

    @property
    def _scratch(self) -> K.Scratch:
        """This thread's kernel scratch (the object is safe to share between threads)."""
        return self.closed_form.scratch

    def _fail(self, code: int, vectors: dict, tau=None):
        if code == SATURATED:
            raise ActuatorSaturationError(tau, self._bounds)  # type: ignore[arg-type]
        if code == NONFINITE:
            for name, value in vectors.items():
                as_array(value, (6,), name)
        raise K.error_of(code, self.geo, self._scratch.wk, self._scratch.mats[1])

    def inverse_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike, twist_dot: npt.ArrayLike,
                         wrench: npt.ArrayLike | None = None, bounded: bool = True) -> np.ndarray:
        """Actuator forces producing a platform motion (closed-loop inverse dynamics).

        As :meth:`Hexapod.inverse_dynamics` with ``method="kkt"``.

        Args:
            pose: (6,) (m, rad). twist: ``(v, w)`` world axes (m/s, rad/s), (6,).
            twist_dot: its time derivative (m/s^2, rad/s^2), (6,).
            wrench: ``(f, m)`` on the platform, world axes, about its origin (N, N m);
                default zero.
            bounded: raise when ``abs(tau) > geometry.max_actuator_force``.

        Returns:
            tau (6,) (N), force on carriage i along ``+u_k``.

        Raises:
            ActuatorSaturationError: with ``bounded``, a motion needing forces beyond
                ``geometry.max_actuator_force``.
            UnreachablePoseError: a leg cannot reach the pose.
            SingularityError: at a singular configuration.
            InputError: bad shape, non-finite or non-real values.
            NonFiniteResultError: inputs whose magnitudes overflow.
        """
        pose, twist, twist_dot = _vec6(pose, "pose"), _vec6(twist, "twist"), \
            _vec6(twist_dot, "twist_dot")
        geo = self.closed_form.dynamics_geo
        if geo[K.PASSIVE]:             # effects the kernels do not model: Pinocchio's route
            return self.robot.inverse_dynamics(pose, twist, twist_dot, wrench, bounded=bounded,
                                               joint_wrenches=False).actuator_forces
        wrench = _ZERO6 if wrench is None else _vec6(wrench, "wrench")
        tau, s = np.empty(6), self._scratch
        code = K.inverse_dynamics(geo, self.signs, pose, twist, twist_dot, wrench,
                                  bounded, tau, s.rot, s.wk, s.mats)
        if code:
            self._fail(code, {"pose": pose, "twist": twist, "twist_dot": twist_dot,
                              "wrench": wrench}, tau)
        return check_finite_result("FastDynamics.inverse_dynamics", tau, "actuator_forces")

    def forward_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         actuator_forces: npt.ArrayLike,
                         wrench: npt.ArrayLike | None = None) -> np.ndarray:
        """Platform acceleration produced by actuator forces (constrained forward dynamics).

        As :meth:`Hexapod.forward_dynamics` (``twist_dot`` only; for the carriage
        accelerations too, see :meth:`forward_dynamics_full`).

        Args:
            pose: (6,) (m, rad). twist: ``(v, w)`` world axes, (6,).
            actuator_forces: tau (6,) (N). wrench: (6,) or None.

        Returns:
            twist_dot (6,) (m/s^2, rad/s^2), world axes.

        Raises:
            UnreachablePoseError: a leg cannot reach the pose.
            SingularityError: at a singular configuration.
            InputError: bad shape, non-finite or non-real values.
            NonFiniteResultError: inputs whose magnitudes overflow.
        """
        return self.forward_dynamics_full(pose, twist, actuator_forces, wrench)[0]

    def forward_dynamics_full(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                              actuator_forces: npt.ArrayLike, wrench: npt.ArrayLike | None = None
                              ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """:meth:`forward_dynamics` returning ``(twist_dot, actuator_accelerations)``,
        each (6,)."""
        pose, twist = _vec6(pose, "pose"), _vec6(twist, "twist")
        forces = _vec6(actuator_forces, "actuator_forces")
        geo = self.closed_form.dynamics_geo
        if geo[K.PASSIVE]:             # effects the kernels do not model: Pinocchio's route
            res = self.robot.forward_dynamics(pose, twist, forces, wrench)
            return res.twist_dot, res.actuator_accelerations
        wrench = _ZERO6 if wrench is None else _vec6(wrench, "wrench")
        twist_dot, qddot, s = np.empty(6), np.empty(6), self._scratch
        code = K.forward_dynamics(geo, self.signs, pose, twist, forces, wrench,
                                  twist_dot, qddot, s.rot, s.wk, s.mats)
        if code:
            self._fail(code, {"pose": pose, "twist": twist, "actuator_forces": forces,
                              "wrench": wrench})
        check_finite_result("FastDynamics.forward_dynamics", twist_dot, "twist_dot")
        return twist_dot, check_finite_result("FastDynamics.forward_dynamics", qddot,
                                              "actuator_accelerations")

    def static_forces(self, pose: npt.ArrayLike, wrench: npt.ArrayLike | None = None,
                      bounded: bool = True) -> np.ndarray:
        """Actuator forces (6,) (N) holding the platform at rest at ``pose``.

        As :meth:`Hexapod.static_forces`. Raises the same exceptions.
        """
        pose = _vec6(pose, "pose")
        geo = self.closed_form.dynamics_geo
        if geo[K.PASSIVE]:             # effects the kernels do not model: Pinocchio's route
            return self.robot.static_forces(pose, wrench, bounded=bounded)
        wrench = _ZERO6 if wrench is None else _vec6(wrench, "wrench")
        tau, s = np.empty(6), self._scratch
        code = K.static_forces(geo, self.signs, pose, wrench, bounded, tau, s.rot, s.wk,
                               s.mats)
        if code:
            self._fail(code, {"pose": pose, "wrench": wrench}, tau)
        return check_finite_result("FastDynamics.static_forces", tau, "actuator_forces")


def compiled_geometry(robot: Hexapod, friction_regularisation: float | None = None
                      ) -> np.ndarray:
    """The packed geometry with the drives that the compiled simulator integrates
    (``robot.closed_form.dynamics_geo``, a hand-written armature noticed), with the smooth
    friction ``-c tanh(qd / v_eps)`` of a ``friction_regularisation`` ``v_eps`` (m/s, > 0).

    Raises:
        InputError: the robot's passive coordinates (universal joints, the platform's free
            flyer) carry joint effects, which the kernels do not model; exact Coulomb
            friction on the carriages without a ``friction_regularisation`` (explicit
            steps across ``qdot = 0`` flip ``sign(qdot)`` and chatter: the tree
            simulator's "stick_slip" integrator solves it); a ``friction_regularisation``
            that is not a finite number > 0.
    """
    geo = robot.closed_form.dynamics_geo
    if geo[K.PASSIVE]:
        raise InputError("robot", robot, "joint effects on passive coordinates "
                         f"{robot.model.effects.effective_coordinates().tolist()} (the "
                         "compiled simulator models the carriages' drives only): use "
                         "hexapod_pin.simulate(robot, ..., backend='tree')")
    if friction_regularisation is None:
        if has_friction(geo):
            raise InputError("friction_regularisation", None, "the carriages have exact "
                             "Coulomb friction, which the compiled integrators cannot step "
                             "(sign(qdot) flips across qdot = 0): give friction_"
                             "regularisation=v_eps, or simulate on the tree "
                             "(hexapod_pin.simulate, integrator 'stick_slip')")
        return geo
    eps = real_number(friction_regularisation, "friction_regularisation", minimum=0.0)
    geo = geo.copy()
    geo[K.DRIVES + drv.SMOOTH] = eps
    return geo


def has_friction(geo: np.ndarray) -> bool:
    """Whether the carriages' drives in a packed geometry have Coulomb friction."""
    start = K.DRIVES + drv.HEAD + drv.COUL
    return bool(np.any(geo[start:start + drv.BLOCK * 6:drv.BLOCK]))


def fast_dynamics(robot: Hexapod) -> FastDynamics:
    """The :class:`FastDynamics` of a hexapod: a light view of the robot's compiled closed
    form (``robot.closed_form``, which holds the packed geometry and the scratch)."""
    return FastDynamics(robot)


@dataclass(frozen=True)
class FastTrajectory:
    """Result of :func:`simulate_fast` (a smaller
    :class:`~hexapod_pin.hexapod.simulation.Trajectory`).

    Attributes:
        times: (n,) (s).
        poses: (n, 6) platform poses (m, rad).
        quaternions: (n, 4) platform orientation ``(x, y, z, w)``, Pinocchio's order.
        twists: (n, 6) platform twists ``(v, w)``, world axes (m/s, rad/s).
        q: (n, 6) carriage positions (m). qdot: (n, 6) carriage velocities (m/s).
        actuator_forces: (n, 6) forces applied from each sample to the next (N) (last
            row: the command at the final state, or the previous one after a stop).
        saturated: (n,) True where the command was clipped to the bound.
        status: "completed", "saturated" (completed with clipped commands), "stroke_limit",
            "carriage_gap" or "failed".
        message: details of a stop.
        dt: the step (s).
        wall_time: seconds spent in the compiled code (set-points of the reference, then
            the loop; the first calls of a process also load it from the disk cache, or
            run it interpreted or compile it: :mod:`hexapod_pin.core.tiers`).
        integrator: "rk4", "rk2" or "semi_implicit_euler".
        dissipated_work: (n,) energy dissipated by the carriages' damping and friction since
            t = 0 (J; the integrator's quadrature of their power, see
            :func:`simulate_kernel`); zeros without them.
    """

    times: np.ndarray
    poses: np.ndarray
    quaternions: np.ndarray
    twists: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    actuator_forces: np.ndarray
    saturated: np.ndarray
    status: str
    message: str
    dt: float
    wall_time: float
    integrator: str = "rk4"
    dissipated_work: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def real_time_factor(self) -> float:
        """Simulated time divided by wall time
        (:func:`hexapod_pin.core.simulate.real_time_factor`)."""
        return real_time_factor(self.times, self.wall_time)


def _sample_reference(reference, n_steps: int, dt: float):
    """Reference poses and twists (n_steps + 1, 6) from a callable or a pair of arrays."""
    if callable(reference):
        refs = [reference(k * dt) for k in range(n_steps + 1)]
        poses = np.array([as_array(r.pose, (6,), "reference pose") for r in refs])
        twists = np.array([as_array(r.twist, (6,), "reference twist") for r in refs])
        return poses, twists
    try:
        poses, twists = reference
    except (TypeError, ValueError):
        raise InputError("reference", reference, "expected a callable t -> "
                         "PlatformReference or a pair (poses, twists)") from None
    poses = as_array(poses, (6,), "reference poses", batch=True)
    twists = as_array(twists, (6,), "reference twists", batch=True)
    if poses.shape != twists.shape or poses.shape[0] < 1:
        raise InputError("reference", (poses.shape, twists.shape),
                         "poses and twists must have the same number (>= 1) of rows")
    return np.ascontiguousarray(poses), np.ascontiguousarray(twists)


def simulate_fast(robot: Hexapod, duration: float, dt: float = 1e-3, *,
                  pose0: npt.ArrayLike | None = None, twist0: npt.ArrayLike | None = None,
                  actuator_forces: npt.ArrayLike | None = None, wrench: npt.ArrayLike | None = None,
                  reference: ReferenceTrajectory | None = None, kp: float = 30000.0,
                  ki: float = 40000.0, kd: float = PID_KD, feedforward: bool = False,
                  check_limits: bool = True, on_limit: str = "stop", saturation: str = "clip",
                  record_every: int = 1, integrator: str = "rk4",
                  friction_regularisation: float | None = None) -> FastTrajectory:
    """Integrate the hexapod's dynamics in compiled code (in platform coordinates).

    Args:
        robot: the :class:`~hexapod_pin.Hexapod`.
        duration: simulated time (s). dt: step and control period (s).
        pose0: initial platform pose (default: home; with a ``reference``, its first
            sample).
        twist0: initial platform twist (default: at rest; with a ``reference``, its first
            sample).
        actuator_forces: constant (6,) forces (N) without a reference; default zero.
        wrench: constant ``(f, m)`` on the platform (world axes, about its origin), held
            in world axes (:func:`~hexapod_pin.hexapod.simulation.simulate` holds it in platform
            axes over a step: the two differ by O(dt)).
        reference: enables the joint PID of :class:`~hexapod_pin.hexapod.simulation.PIDController`
            (``tau = kp e + ki sum(e dt) + kd (qdot_ref - qdot)``, ``e = q_ref - q``,
            ``q_ref`` = IK of the reference pose, ``qdot_ref = J`` reference twist, both
            computed in compiled code for each sample before the loop): a callable
            ``t -> PlatformReference`` (sampled at ``k dt`` before the loop, in Python)
            or a pair of arrays ``(poses, twists)``, each (m, 6), sampled at ``k dt``
            (the last row is held when m < steps + 1).
        kp: N/m. ki: N/(m s). kd: N s/m (each a finite number >= 0; the default ``kd``
            keeps the discrete PID stable at the default step, see
            :class:`~hexapod_pin.hexapod.simulation.PIDController`). feedforward: add the
            static forces of the reference pose.
        check_limits: stop at the stroke limits / carriage gap (checked after each step).
        on_limit: "stop" (status "stroke_limit" / "carriage_gap") or "raise".
        saturation: "clip", "raise" or "ignore" (commands beyond the bound); a run with
            clipped commands ends with status "saturated" (the message gives the
            fraction of the recorded steps).
        record_every: record one sample every this many steps.
        integrator: "rk4" (default; 4 forward dynamics per step, fourth order), "rk2"
            (explicit midpoint; 2, second order) or "semi_implicit_euler" (1, first
            order; velocities first, then ``p += dt v``, ``Q = exp(dt w) Q``, as MuJoCo's
            Euler). Accuracy and energy behaviour: see the module docstring.
        friction_regularisation: ``v_eps`` (m/s, > 0): the carriages' Coulomb friction
            becomes ``-c tanh(qdot / v_eps)`` (an approximation; needed for exact friction,
            which explicit steps cannot take: :func:`compiled_geometry`). None: exact.

    Returns:
        :class:`FastTrajectory`. A singular or unreachable state stops the run with
        status "failed" and the reference route's message.

    Raises:
        InputError: bad shape, non-finite or non-real values; a robot whose passive
            coordinates carry joint effects (:func:`compiled_geometry`).
        StrokeLimitError: an actuator beyond its stroke (``on_limit="raise"``).
        ActuatorSaturationError: with ``saturation="raise"``, a command beyond
            ``geometry.max_actuator_force``.
    """
    record_every = check_run_arguments(duration, dt, on_limit, saturation, record_every)
    modes = {"clip": 0, "raise": 1, "ignore": 2}
    if not isinstance(integrator, str) or integrator not in INTEGRATORS:
        raise InputError("integrator", integrator, f"expected one of {tuple(INTEGRATORS)}")
    if reference is not None and actuator_forces is not None:
        raise InputError("actuator_forces", actuator_forces, "give forces or a reference")
    n_steps = max(1, round(duration / dt))
    if reference is not None:
        ref_poses, ref_twists = _sample_reference(reference, n_steps, dt)
        mode, forces_in = 1, _ZERO6
    else:
        ref_poses = ref_twists = np.zeros((1, 6))
        mode = 0
        forces_in = _ZERO6 if actuator_forces is None else as_array(actuator_forces, (6,),
                                                                    "actuator_forces")
    if pose0 is None:
        pose0 = ref_poses[0] if reference is not None else robot.home_pose
    if twist0 is None:
        twist0 = ref_twists[0] if reference is not None else np.zeros(6)
    pose0, twist0 = as_array(pose0, (6,), "pose0"), as_array(twist0, (6,), "twist0")
    wrench = _ZERO6 if wrench is None else as_array(wrench, (6,), "wrench")
    gains = np.array([real_number(gain, name, minimum=0.0, strict=False)
                      for gain, name in ((kp, "kp"), (ki, "ki"), (kd, "kd"))])
    feedforward = bool(feedforward)
    fd = fast_dynamics(robot)
    geo = compiled_geometry(robot, friction_regularisation)
    fd.static_forces(pose0, bounded=False)    # raises for an unreachable / singular pose0
    vecs = np.zeros((4, 13))
    vecs[0, :3] = pose0[:3]
    vecs[0, 3:7] = _quaternion_wxyz(pose0[3:])
    vecs[0, 7:] = twist0
    work = (vecs, np.empty(9), np.zeros((K.WK_ROWS, 6)), np.empty((K.N_MATS, 6, 6)),
            np.zeros((3, 6)))
    n_rec = n_steps // record_every + 2
    record = (np.empty((n_rec, 13)), np.empty((n_rec, 6)), np.empty((n_rec, 6)),
              np.empty((n_rec, 6)), np.zeros(n_rec, dtype=np.bool_), np.zeros(n_rec))
    last_forces = np.zeros(6)
    setpoints = np.zeros((3, min(len(ref_poses), n_steps + 1) if mode else 1, 6))
    start = time.perf_counter()
    bad_row, bad_code = _set_points(geo, ref_poses, ref_twists, feedforward, setpoints) \
        if mode else (setpoints.shape[1], OK)
    code, step, n = simulate_kernel(geo, n_steps, float(dt), record_every,
                                    INTEGRATORS[integrator], mode, forces_in, wrench,
                                    setpoints, bad_row, bad_code, gains, modes[saturation],
                                    bool(check_limits), work, record, last_forces)
    wall = time.perf_counter() - start
    rec_state, rec_q, rec_qd, rec_f, rec_sat, rec_lost = record
    if code == SATURATED:
        raise ActuatorSaturationError(last_forces, np.full(6, robot.geometry.max_actuator_force))
    if n == 0:              # the initial state itself failed (checked above: not expected)
        raise HexapodPinError(f"simulate_fast: initial state rejected (status {code})")
    steps = np.arange(n) * record_every
    if code in (STROKE, GAP):                       # the stop state is recorded
        steps[-1] = step
    times = steps * float(dt)
    rec_state = rec_state[:n]
    quat = rec_state[:, [4, 5, 6, 3]]
    poses = np.empty((n, 6))
    _poses_of(rec_state, poses)
    status, message = "completed", ""
    t_stop = float(step * dt)
    if code in (STROKE, GAP):
        violations = robot.stroke_violations(rec_q[n - 1])
        if on_limit == "raise":
            raise StrokeLimitError(rec_q[n - 1], violations)
        status, message = _STATUS_OF_CODE[code], f"at t = {t_stop:.6g} s: " + "; ".join(
            violations)
    elif code != OK:
        status, message = "failed", f"at t = {t_stop:.6g} s: {_describe(robot, code, poses[-1])}"
    else:
        status, message = saturation_status(rec_sat[:n], times)
    return FastTrajectory(times, poses, quat.copy(), rec_state[:, 7:].copy(), rec_q[:n].copy(),
                          rec_qd[:n].copy(), rec_f[:n].copy(), rec_sat[:n].copy(), status,
                          message, float(dt), wall, integrator, rec_lost[:n].copy())


class FastStepper:
    """Step the hexapod's dynamics one ``dt`` at a time from Python (a controller in the
    loop): the compiled loop of :func:`simulate_fast` run for one step per call, from a
    state it keeps, without the per-call set-up of :func:`simulate_fast`.

    Args:
        robot: the :class:`~hexapod_pin.Hexapod`.
        dt: the step (s).
        pose0: initial platform pose (default: home).
        twist0: initial platform twist (default: at rest).
        integrator: "semi_implicit_euler" (default, one evaluation per step), "rk2" or
            "rk4" (see :func:`simulate_fast`).
        check_limits: stop at the stroke limits / carriage gap (checked after each step).
        friction_regularisation: as in :func:`simulate_fast`.

    Raises:
        InputError: bad ``dt``, ``integrator`` or initial state, or joint effects it cannot
            step (:func:`compiled_geometry`).
        UnreachablePoseError: the initial pose cannot be reached.
        SingularityError: the initial pose is singular (as the reference routes raise it).

    Not thread-safe (the state and scratch arrays are reused).
    """

    def __init__(self, robot: Hexapod, dt: float = 1e-3, *, pose0: npt.ArrayLike | None = None,
                 twist0: npt.ArrayLike | None = None, integrator: str = "semi_implicit_euler",
                 check_limits: bool = True,
                 friction_regularisation: float | None = None) -> None:
        dt = real_number(dt, "dt", minimum=0.0)
        if not isinstance(integrator, str) or integrator not in INTEGRATORS:
            raise InputError("integrator", integrator, f"expected one of {tuple(INTEGRATORS)}")
        self.robot, self.dt, self.integrator = robot, float(dt), integrator
        self.check_limits = bool(check_limits)
        self.friction_regularisation = friction_regularisation
        compiled_geometry(robot, friction_regularisation)   # refuses what it cannot step
        self._work = (np.zeros((4, 13)), np.empty(9), np.zeros((K.WK_ROWS, 6)),
                      np.empty((K.N_MATS, 6, 6)), np.zeros((3, 6)))
        self._record = (np.empty((3, 13)), np.empty((3, 6)), np.empty((3, 6)),
                        np.empty((3, 6)), np.zeros(3, dtype=np.bool_), np.zeros(3))
        self._setpoints = np.zeros((3, 1, 6))
        self._gains = np.zeros(3)
        self._last = np.zeros(6)
        self.time = 0.0
        self.reset(robot.home_pose if pose0 is None else pose0,
                   np.zeros(6) if twist0 is None else twist0)

    def reset(self, pose: npt.ArrayLike, twist: npt.ArrayLike) -> None:
        """Set the platform state (pose (6,), m and rad; twist (6,), world axes) and the
        time to 0. Raises as the constructor."""
        pose, twist = as_array(pose, (6,), "pose"), as_array(twist, (6,), "twist")
        # raises if unreachable / singular
        fast_dynamics(self.robot).static_forces(pose, bounded=False)
        state = self._work[0][0]
        state[:3] = pose[:3]
        state[3:7] = _quaternion_wxyz(pose[3:])
        state[7:] = twist
        self.time = 0.0

    def step(self, actuator_forces: npt.ArrayLike, wrench: npt.ArrayLike | None = None) -> None:
        """Advance one ``dt`` with the forces (6,) (N) and the wrench (6,) on the platform
        (world axes, about its origin; default zero) held over the step.

        Raises:
            InputError: non-finite or badly shaped forces / wrench; joint effects on passive
                coordinates (an armature written there by hand since the start).
            StrokeLimitError: the step ends beyond a stroke limit or the carriage gap
                (with ``check_limits``); the state is that end state.
            SingularityError: the step met a singular configuration (the state is left at the
                start of the step).
            UnreachablePoseError: the step left the reachable poses (the state is left at the
                start of the step).
            HexapodPinError: any other failure of the step (the state is left at the start of
                the step).
        """
        forces = _vec6(actuator_forces, "actuator_forces")
        wrench = _ZERO6 if wrench is None else _vec6(wrench, "wrench")
        if not (all_finite(forces) and all_finite(wrench)):
            as_array(forces, (6,), "actuator_forces")
            as_array(wrench, (6,), "wrench")
        state = self._work[0][0]
        start = state.copy()
        geo = compiled_geometry(self.robot, self.friction_regularisation)
        code, _, n = simulate_kernel(geo, 1, self.dt, 1,
                                     INTEGRATORS[self.integrator],
                                     0, forces, wrench, self._setpoints, 1, OK, self._gains, 2,
                                     self.check_limits, self._work, self._record, self._last)
        if code == OK:
            self.time += self.dt
            return
        if code in (STROKE, GAP):
            self.time += self.dt
            q = self._record[1][n - 1]
            raise StrokeLimitError(q.copy(), self.robot.stroke_violations(q))
        state[:] = start
        raise HexapodPinError(f"FastStepper.step at t = {self.time:.6g} s: "
                              + _describe(self.robot, code, self.pose))

    @property
    def pose(self) -> np.ndarray:
        """Platform pose (6,) (m, rad)."""
        out = np.empty((1, 6))
        _poses_of(self._work[0][:1], out)
        return out[0]

    @property
    def twist(self) -> np.ndarray:
        """Platform twist ``(v, w)`` (6,), world axes (m/s, rad/s)."""
        return self._work[0][0, 7:].copy()


def _describe(robot, code: int, pose) -> str:
    """The reference route's message for the last state (its exception, if it raises),
    else the kernel's reason (the failure was at a Runge-Kutta stage of the next step)."""
    names = {UNREACHABLE: "pose unreachable", TYPE_I: "type-I singularity",
             GIMBAL: "universal joint in gimbal lock", TYPE_II: "type-II singularity",
             NOT_PD: "reduced mass matrix not positive definite", NONFINITE: "non-finite state"}
    try:
        fast_dynamics(robot).static_forces(pose, bounded=False)
    except HexapodPinError as exc:
        return str(exc)
    return f"{names.get(code, f'status {code}')} within the step from the last recorded state"


def _quaternion_wxyz(rpy) -> np.ndarray:
    """Unit quaternion ``(w, x, y, z)`` of roll, pitch, yaw (rad)."""
    return np.array(quaternion_rpy(float(rpy[0]), float(rpy[1]), float(rpy[2])))


@kernel(FAST_FLAGS, work=1)
def _poses_of(states, out):
    """Poses ``(x, y, z, roll, pitch, yaw)`` (n, 6) of recorded states ``(p, Q (w, x, y, z),
    ...)`` (:func:`hexapod_pin.core.pose.rpy_of`)."""
    rot = np.empty(9)
    for k in range(out.shape[0]):
        rotation_quat(states[k, 3], states[k, 4], states[k, 5], states[k, 6], rot)
        out[k, 0], out[k, 1], out[k, 2] = states[k, 0], states[k, 1], states[k, 2]
        out[k, 3], out[k, 4], out[k, 5] = rpy_of(rot)

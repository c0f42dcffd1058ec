"""Jacobians of one simulation step of any robot, in the state of the linearised model:
``x = (dp, dtheta, twist)`` (:mod:`~hexapod_pin.core.platform_derivatives`), from the
analytic KKT derivatives of :mod:`~hexapod_pin.core.dynamics_derivatives` by the chain rule
through the stages of the step of
:class:`~hexapod_pin.core.simulation.ClosedLoopIntegrator` (no finite differences).

One step maps ``(x_k, u_k)`` to ``x_{k+1}`` with ``u`` held over it (zero-order hold, the
``simulate`` step): the tree state ``q = configuration(pose)``, ``v = V twist``, one
"semi_implicit_euler" or "rk4" step of a fresh integrator (its projection onto the
closures included), and the platform state read back, ``pose' = pose_from_configuration(q')``,
``twist' = T(q') v'``. ``Ad = d x_{k+1} / d x_k`` and ``Bd = d x_{k+1} / d u_k`` (world
axes; the output pose displacement is ``(dp', dtheta')`` of the next pose, ``R' ->
exp(dtheta') R'``).

The chain rule, per stage (tree coordinates; ``q`` perturbed as a vector of ``R^nq``, the
integrator's own coordinates, mapped to and from the tangent by ``Phi(q) = d qdot / d v``):

* the dynamics of each stage state: ``da = K(q_s, v_s)^-1 (-(E_q dq + E_v dv) + S^T du,
  -(C_q dq + C_v dv))`` (:class:`~hexapod_pin.core.dynamics_derivatives.KKTLinearization`
  at the stage state, every direction: the stage states are off the closures, and the
  KKT rows are the library's there too);
* ``qdot = qdot(q, v)`` (bilinear in ``(q, v)``; a free-flyer's ``p' = R v_lin`` gives
  ``R (eta x v_lin)`` for a rotation ``eta``); the unit quaternions and ``(cos, sin)``
  pairs renormalised, ``d(x / |x|) = (I - n n^T) dx / |x|``;
* RK4: ``q' = q + dt/6 (qd_1 + 2 qd_2 + 2 qd_3 + qd_4)``, ``v' = v + dt/6 (a_1 + 2 a_2 + 2
  a_3 + a_4)``, stage ``k + 1`` at ``q + h qd_k``, ``v + h a_k``; semi-implicit Euler:
  ``v' = v + dt a(q, v)``, ``q' = integrate(q, dt v')`` (``pin.dIntegrate``);
* the projection onto the closures (and, with redundant rows, of the RK4 stage states):
  the velocity projection ``v -> P v`` (``P = I - J_c^+ J_c``) moves by ``P dv - d(J_c^+
  J_c)[dq] v`` with ``d(J^+ J) = P dJ^T J^+T + J^+ dJ P`` (``dJ[dq] x = d(J_c x)/dq dq``
  from one kinematic pass at velocity ``x``, ``dJ^T[dq] y = d(J_c^T y)/dq dq`` from the
  RNEA derivatives with ``y`` as closure forces); the first Gauss-Newton step ``c =
  -J_c^+ r`` moves by ``dc = -J_c^+ J_c dq + J_c^+ dJ[dq] z - P dJ^T[dq] J_c^+T z`` (``z =
  J_c^+ r``), carried through ``pin.dIntegrate``; the later steps, whose residual is the
  square of the one before, by the projector ``P`` at the returned ``q``; a weld's ``dr``
  is ``Jlog6(M21) J_rel dq`` (its residual ``log6(M21)``). Left out: terms of the order of
  the square of the drift the projection removes.

Coulomb friction and the "stick_slip" step are not differentiable (refused); damping,
springs and armature enter through the KKT derivatives. Equations and tests:
``docs/derivations.md`` (section 8).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import InputError
from .checks import real_number
from .closed_loop import RANK_RTOL, ClosedLoopModel
from .dynamics import dynamics_of
from .dynamics_derivatives import (
    KKTLinearization,
    closure_force_derivative,
    closure_rates,
    frame_rates,
    frame_set,
)
from .platform_derivatives import PlatformLinearization, PlatformRobot, platform_of
from .simulation import PROJECTION_TOL, ClosedLoopIntegrator

#: the integrators whose steps are differentiated
STEP_INTEGRATORS = ("rk4", "semi_implicit_euler")


@dataclass(frozen=True)
class StepJacobians:
    """The discrete-time linearisation ``dx_{k+1} = Ad dx_k + Bd du_k`` of one simulation
    step, from ``robot.step_jacobians(pose, twist, actuator_forces, dt, integrator=...)``.

    States ``x = (dp, dtheta, twist)`` as :class:`~hexapod_pin.core.platform_derivatives.
    StateSpaceModel` (world axes, the pose's linear components then its angles, then the
    twist); the output's pose displacement is taken at the next pose.

    Attributes:
        ad: ``Ad`` (2 dim, 2 dim).
        bd: ``Bd`` (2 dim, n_act) (per N or N m).
        dt: the step (s).
        integrator: "rk4" or "semi_implicit_euler".
        pose: (dim,) the pose at the start of the step (m, rad).
        twist: (dim,) the twist at the start (world axes).
        actuator_forces: (n_act,) held over the step (N, N m).
        next_pose: (dim,) the pose after the step.
        next_twist: (dim,) the twist after the step.
    """

    ad: np.ndarray
    bd: np.ndarray
    dt: float
    integrator: str
    pose: np.ndarray
    twist: np.ndarray
    actuator_forces: np.ndarray
    next_pose: np.ndarray
    next_twist: np.ndarray


class SteppedRobot(PlatformRobot, Protocol):
    """What :func:`step_jacobians` reads from a robot (every robot of the library)."""

    def pose_from_configuration(self, q: npt.ArrayLike) -> np.ndarray: ...


class _Coordinates:
    """The configuration vector as the integrator moves it: ``Phi(q)`` (nq, nv) with
    ``qdot = Phi(q) v``, the derivative of ``qdot`` in ``q``, the renormalisation."""

    def __init__(self, integ: ClosedLoopIntegrator) -> None:
        model = integ.clm.model
        self.integ, self.nv = integ, model.nv
        self.units: list[tuple[int, int]] = []       # (start, width) of the unit blocks
        self.free: list[tuple[int, int]] = []        # (idx_q, idx_v) of the free-flyers
        for joint in model.joints[1:]:
            name = joint.shortname()
            if name == "JointModelFreeFlyer":
                self.units.append((joint.idx_q + 3, 4))
                self.free.append((joint.idx_q, joint.idx_v))
            elif name == "JointModelSpherical":
                self.units.append((joint.idx_q, 4))
            elif name == "JointModelPlanar":
                self.units.append((joint.idx_q + 2, 2))
            elif name.startswith("JointModelRUB") or name == \
                    "JointModelRevoluteUnboundedUnaligned":
                self.units.append((joint.idx_q, 2))
        self.vector = not self.units
        self._last: tuple[bytes, np.ndarray, np.ndarray] | None = None

    def phi(self, q: np.ndarray) -> np.ndarray:
        """``Phi(q)`` (nq, nv): the configuration rate of each unit velocity (the last
        one kept)."""
        key = q.tobytes()
        if self._last is None or self._last[0] != key:
            eye = np.eye(self.nv)
            phi = np.array([self.integ.qdot(q, eye[k]) for k in range(self.nv)]).T
            self._last = (key, phi, np.linalg.pinv(phi))
        return self._last[1]

    def tangent(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """The tangent directions (nv, k) of ambient ones (nq, k) at a normalised ``q``
        (``Phi^+ dq``, exact on the unit blocks' tangent spaces)."""
        if self.vector:
            return dq
        self.phi(q)
        assert self._last is not None
        return self._last[2] @ dq

    def ambient(self, q: np.ndarray, t: np.ndarray) -> np.ndarray:
        """``Phi(q) t`` (nq, k)."""
        return t if self.vector else self.phi(q) @ t

    def rate_derivative(self, q: np.ndarray, v: np.ndarray, dq: np.ndarray, t: np.ndarray,
                        dv: np.ndarray) -> np.ndarray:
        """``d qdot`` (nq, k) for ``(dq, dv)`` at ``(q, v)`` (``t``: the tangent of
        ``dq``): ``Phi(q) dv`` plus the bilinear part ``qdot(dq, v) - qdot(0, v)``, a
        free-flyer's position rows ``R (eta x v_lin)`` instead."""
        out = self.ambient(q, dv)
        if self.vector:
            return out
        qdot = self.integ.qdot
        at_zero = qdot(np.zeros_like(q), v)
        plain = out.copy()
        for k in range(dq.shape[1]):
            out[:, k] += qdot(np.ascontiguousarray(dq[:, k]), v) - at_zero
        for iq, iv in self.free:
            rot = self.phi(q)[iq:iq + 3, iv:iv + 3]
            out[iq:iq + 3] = plain[iq:iq + 3] + rot @ np.cross(t[iv + 3:iv + 6].T,
                                                                 v[iv:iv + 3]).T
        return out

    def normalised(self, raw: np.ndarray, d_raw: np.ndarray) -> np.ndarray:
        """``d(normalise(raw))`` (nq, k) for ``d raw``."""
        out = d_raw.copy()
        for start, width in self.units:
            block = raw[start:start + width]
            norm = float(np.linalg.norm(block))
            unit = block / norm
            part = out[start:start + width]
            out[start:start + width] = (part - np.outer(unit, unit @ part)) / norm
        return out


class _ClosureTangent:
    """``J_c`` at ``q`` (world point rows), its least-norm solves and the second-order terms
    of the projection's derivative; the platform rows ``T`` and ``d(T v)/dq`` on request."""

    def __init__(self, clm: ClosedLoopModel, data: pin.Data, q: np.ndarray) -> None:
        self.clm, self.data, self.q = clm, data, q
        self.jac = self.velocity_q(np.zeros(clm.nv))[0]
        # d r / dq of the residual the Gauss-Newton step reads (log6(M21) for a weld:
        # Jlog6(M21) J_rel; a point's world p1 - p2: J_c itself)
        self._logs = [(c.rows, pin.Jlog6(data.oMf[c.frame2].actInv(data.oMf[c.frame1])))
                      for c in clm.closure_frames if not c.is_point]
        self._u = self._sv = self._vt = np.zeros((0, 0))
        if self.jac.shape[0]:
            u_mat, sv, vt = np.linalg.svd(self.jac, full_matrices=False)
            keep = sv > max(RANK_RTOL * sv[0], 1e-300)
            self._u, self._sv, self._vt = u_mat[:, keep], sv[keep], vt[keep]

    def velocity_q(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(J_c, d(J_c w)/dq)`` (n_rows, nv) each (one kinematic pass at ``q``)."""
        model, zero = self.clm.model, np.zeros(self.clm.nv)
        pin.computeJointJacobians(model, self.data, self.q)
        pin.updateFramePlacements(model, self.data)
        rates = closure_rates(self.clm, self.data, w, zero, self.q)
        return rates.jac, rates.vel_q

    def platform(self, frame: int, sel: np.ndarray, v: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
        """``(T, d(T v)/dq)`` (dim, nv) of the platform frame."""
        model, zero = self.clm.model, np.zeros(self.clm.nv)
        pin.computeJointJacobians(model, self.data, self.q)
        pin.updateFramePlacements(model, self.data)
        out = frame_rates(model, self.data, frame_set(self.clm, [frame]), v, zero,
                          np.ones(1, dtype=bool))
        return out.jac[0][sel], out.vel_q[0][sel]

    def pinv(self, rhs: np.ndarray) -> np.ndarray:
        """``J_c^+ rhs``."""
        if not self._sv.size:
            return np.zeros((self.jac.shape[1],) + rhs.shape[1:])
        scale = self._sv if rhs.ndim == 1 else self._sv[:, None]
        return self._vt.T @ ((self._u.T @ rhs) / scale)

    def pinv_t(self, rhs: np.ndarray) -> np.ndarray:
        """``J_c^+T rhs`` (n_rows,) for ``rhs`` (nv,)."""
        if not self._sv.size:
            return np.zeros(self.jac.shape[0])
        return self._u @ ((self._vt @ rhs) / self._sv)

    def project(self, t: np.ndarray) -> np.ndarray:
        """``P t = (I - J_c^+ J_c) t``."""
        return t - self.pinv(self.jac @ t)

    def turn(self, x: np.ndarray, y: np.ndarray, t: np.ndarray) -> np.ndarray:
        """``-J_c^+ (d(J_c x)/dq) t - P (d(J_c^T y)/dq) t``: minus ``d(J_c^+ J_c)[t]``
        applied to a vector ``u`` with ``x = P u``, ``y = J_c^+T u``
        (``d(J^+ J) = P dJ^T J^+T + J^+ dJ P``)."""
        out = -self.pinv(self.velocity_q(x)[1] @ t)
        if self._sv.size and np.any(y):
            out -= self.project(closure_force_derivative(self.clm, self.data, self.q, y) @ t)
        return out

    def velocity(self, v: np.ndarray, t: np.ndarray, dv: np.ndarray) -> np.ndarray:
        """The derivative of the velocity projection ``P(q) v`` along ``(t, dv)``."""
        return self.project(dv) + self.turn(self.project(v), self.pinv_t(v), t)

    def correction(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The Gauss-Newton step ``c = -J_c^+ r(q)`` and its derivative along ``t``:
        ``dc = -J_c^+ dr - d(J_c^+)[t] r`` (``dr = J_c t``, a weld's rows ``Jlog6(M21)
        J_rel t``), with ``d(J_c^+) r = -J_c^+ dJ z + P dJ^T J_c^+T z`` (``z = J_c^+ r``,
        ``r`` in the range of ``J_c``)."""
        z = self.pinv(self.clm.residual(self.q))
        dr = self.jac @ t
        for rows, jlog in self._logs:
            dr[rows] = jlog @ dr[rows]
        dc = -self.pinv(dr) - self.turn(-z, -self.pinv_t(z), t)
        return -z, dc


class _StepChain:
    """The forward pass of one integrator step and its derivatives (module docstring)
    along the input columns ``(t0, dv0, du)`` (tangent (nv, k), (nv, k), (n_act, k))."""

    def __init__(self, clm: ClosedLoopModel, integ: ClosedLoopIntegrator,
                 start: KKTLinearization, u: np.ndarray, dt: float) -> None:
        self.clm, self.integ, self.start, self.dt = clm, integ, start, dt
        self.coords = _Coordinates(integ)
        self.dyn = dynamics_of(clm)
        self.tau = np.zeros(clm.nv)
        self.tau[clm.actuated_v] = u
        self.data = clm.model.createData()
        self.redundant = start.rank < clm.n_rows

    def stage(self, q: np.ndarray, v: np.ndarray) -> KKTLinearization:
        """The KKT linearisation at a stage state (its acceleration and multipliers from
        the library's verified "kkt" route, the state unchecked)."""
        res = self.dyn.forward_unchecked(q, v, self.tau, "kkt")
        return KKTLinearization(self.clm, self.data, q, v, np.array(res.a),
                                np.array(res.multipliers), ())

    def acceleration(self, lin: KKTLinearization, t: np.ndarray, dv: np.ndarray,
                     du: np.ndarray) -> np.ndarray:
        """``da`` (nv, k) at ``lin``'s state along tangent ``t``, ``dv`` and ``du``."""
        force = np.zeros((self.clm.nv, du.shape[1]))
        force[self.clm.actuated_v] = du
        da, _ = lin.solve(force - (lin.e_q @ t + lin.e_v @ dv), -(lin.c_q @ t + lin.c_v @ dv))
        return da

    def euler(self, q, v, t0, dv0, du):
        """Semi-implicit Euler: ``(q', v', t', dv')`` before the projection."""
        lin, dt, model = self.start, self.dt, self.clm.model
        v_new = v + dt * lin.a
        dv_new = dv0 + dt * self.acceleration(lin, t0, dv0, du)
        step = dt * v_new
        q_new = pin.integrate(model, q, step)
        t_new = pin.dIntegrate(model, q, step, pin.ArgumentPosition.ARG0) @ t0 + \
            pin.dIntegrate(model, q, step, pin.ArgumentPosition.ARG1) @ (dt * dv_new)
        return q_new, v_new, t_new, dv_new

    def rk4(self, q, v, t0, dv0, du, tol):
        """Classical RK4 in ``R^nq`` (the integrator's stages, with redundant rows each
        stage state projected): ``(q', v', t', dv')`` before the final projection."""
        coords, dt = self.coords, self.dt
        dq0 = coords.ambient(q, t0)
        sum_q, sum_v = np.zeros(q.size), np.zeros(v.size)
        dsum_q, dsum_v = np.zeros_like(dq0), np.zeros_like(dv0)
        qs, vs, dqs, dvs, lin = q, v, dq0, dv0, self.start
        for h, w in ((0.5 * dt, 1.0), (0.5 * dt, 2.0), (dt, 2.0), (None, 1.0)):
            ts = coords.tangent(qs, dqs)
            da = self.acceleration(lin, ts, dvs, du)
            qd = self.integ.qdot(qs, vs)
            dqd = coords.rate_derivative(qs, vs, dqs, ts, dvs)
            sum_q += w * qd
            sum_v += w * lin.a
            dsum_q += w * dqd
            dsum_v += w * da
            if h is None:
                break
            raw = q + h * qd
            qs = self._normalise(raw)
            dqs = coords.normalised(raw, dq0 + h * dqd)
            vs, dvs = v + h * lin.a, dv0 + h * da
            if self.redundant:
                qs, vs, dqs, dvs = self._project_stage(qs, vs, dqs, dvs, tol)
            lin = self.stage(qs, vs)
        raw = q + dt / 6.0 * sum_q
        q_new = self._normalise(raw)
        dq_new = coords.normalised(raw, dq0 + dt / 6.0 * dsum_q)
        return q_new, v + dt / 6.0 * sum_v, coords.tangent(q_new, dq_new), \
            dv0 + dt / 6.0 * dsum_v

    def _normalise(self, raw: np.ndarray) -> np.ndarray:
        out = raw.copy()
        for start, width in self.coords.units:
            out[start:start + width] /= np.linalg.norm(out[start:start + width])
        return out

    def _project_stage(self, qs, vs, dqs, dvs, tol):
        """An RK4 stage state put back on the closures (the integrator's one Gauss-Newton
        pass, its velocity projected at the stage's ``q``, when its residual exceeds
        ``tol``) and the derivative."""
        if self.integ.residual(qs) <= tol:
            return qs, vs, dqs, dvs
        tan = _ClosureTangent(self.clm, self.data, qs)
        ts = self.coords.tangent(qs, dqs)
        dv_out = tan.velocity(vs, ts, dvs)
        v_out = tan.project(vs)
        q_out, t_out = self.position_step(tan, ts)
        return q_out, v_out, self.coords.ambient(q_out, t_out), dv_out

    def position_step(self, tan: _ClosureTangent, t: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
        """One Gauss-Newton step ``q (+) c`` from ``tan``'s ``q`` and the tangent it
        carries ``t`` to (``pin.dIntegrate``)."""
        model = self.clm.model
        step, dstep = tan.correction(t)
        q_out = pin.integrate(model, tan.q, step)
        return q_out, pin.dIntegrate(model, tan.q, step, pin.ArgumentPosition.ARG0) @ t + \
            pin.dIntegrate(model, tan.q, step, pin.ArgumentPosition.ARG1) @ dstep

    def finish(self, q_new, v_new, t_new, dv_new, tol, frame, sel):
        """The step's projection (the integrator's) and the platform state's derivatives:
        ``(q', v', T t', T dv' + d(T v')/dq t')``."""
        q_out, v_out, _ = self.integ.project(q_new, v_new, tol, velocity=True)
        if q_out is not q_new:
            # the first Gauss-Newton step differentiated, the later ones (their residual
            # the square of the last) as the projector at the end
            _, t_new = self.position_step(_ClosureTangent(self.clm, self.data, q_new), t_new)
        tan = _ClosureTangent(self.clm, self.data, q_out)
        if q_out is not q_new:
            t_new = tan.project(t_new)
        dv_out = tan.velocity(v_new, t_new, dv_new)
        rows, vel_q = tan.platform(frame, sel, v_out)
        return q_out, v_out, rows @ t_new, rows @ dv_out + vel_q @ t_new, rows @ v_out


def _checked_integrator(clm: ClosedLoopModel, integrator: object) -> str:
    if not (isinstance(integrator, str) and integrator in STEP_INTEGRATORS):
        raise InputError("integrator", integrator, f"expected one of {STEP_INTEGRATORS} "
                         "(the 'stick_slip' step is not differentiable)")
    if clm.effects.has_coulomb:
        raise InputError("integrator", integrator, "the model has Coulomb friction: its "
                         "steps (stick / slip) are not differentiable")
    return integrator


def step_jacobians(robot: SteppedRobot, pose: npt.ArrayLike, twist: npt.ArrayLike,
                   actuator_forces: npt.ArrayLike, dt: float, integrator: str = "rk4",
                   branch: Any = None, projection_tol: float = PROJECTION_TOL
                   ) -> StepJacobians:
    """Analytic Jacobians of one simulation step (module docstring).

    Args:
        robot: any robot of the library (it supplies ``pose_from_configuration``).
        pose: (dim,) the start pose (m, rad).
        twist: (dim,) the start twist, world axes (m/s, rad/s).
        actuator_forces: (n_act,) held over the step (N, N m).
        dt: the step (s), finite, > 0.
        integrator: "rk4" (default) or "semi_implicit_euler".
        branch: the working mode (as ``robot.configuration`` takes it).
        projection_tol: the integrator's projection trigger (m / rad).

    Returns:
        :class:`StepJacobians`.

    Raises:
        InputError: bad shapes, NaN / inf, a ``dt`` that is not finite and > 0, another
            integrator, a model with Coulomb friction.
        UnreachablePoseError: the pose is out of reach.
        SingularityError: a singular pose or a mass matrix singular on the closures.
        SolverError: a dynamics solve misses its equations.
        AssemblyError: the step's projection does not converge.
    """
    clm = robot.model
    integrator = _checked_integrator(clm, integrator)
    dt = real_number(dt, "dt", minimum=0.0)
    projection_tol = real_number(projection_tol, "projection_tol", minimum=0.0)
    plat_lin = PlatformLinearization(robot, pose, twist, actuator_forces, None, branch)
    start, vmap = plat_lin.tree, plat_lin.vmap
    dim, n_act, nv = plat_lin.layout.dim, plat_lin.u.size, clm.nv
    k = 2 * dim + n_act
    t0, dv0, du = np.zeros((nv, k)), np.zeros((nv, k)), np.zeros((n_act, k))
    t0[:, :dim] = vmap
    dv0[:, :dim] = plat_lin.transport()
    dv0[:, dim:2 * dim] = vmap
    du[:, 2 * dim:] = np.eye(n_act)
    integ = ClosedLoopIntegrator(clm, "kkt", integrator)
    chain = _StepChain(clm, integ, start, plat_lin.u, dt)
    q, v = start.q, start.v
    if integrator == "rk4":
        q_new, v_new, t_new, dv_new = chain.rk4(q, v, t0, dv0, du, projection_tol)
    else:
        q_new, v_new, t_new, dv_new = chain.euler(q, v, t0, dv0, du)
    plat = platform_of(robot)
    q_out, _, d_pose, d_twist, next_twist = chain.finish(q_new, v_new, t_new, dv_new,
                                                         projection_tol, plat.frame, plat.sel)
    jac = np.vstack([d_pose, d_twist])
    next_pose = np.asarray(robot.pose_from_configuration(q_out), dtype=float)
    return StepJacobians(jac[:, :2 * dim], jac[:, 2 * dim:], dt, integrator,
                         plat_lin.pose.copy(), plat_lin.twist.copy(), plat_lin.u.copy(),
                         next_pose, next_twist)

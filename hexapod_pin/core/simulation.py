"""Time integration of any closed-loop mechanism on its Pinocchio tree.

:class:`ClosedLoopIntegrator`, generic over a :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`
whose joints are 1-DoF or free-flyers:

* the state is the tree's ``(q, v)`` (Pinocchio conventions);
* classical fourth-order Runge-Kutta on ``q`` as a vector of ``R^nq`` and ``v``:
  ``qdot`` from ``v`` through the joint kinematics (1-DoF joints ``qdot = v``; a
  free-flyer ``p' = R v_lin``, quaternion ``Q' = 1/2 Q (x) (w_body, 0)``), ``vdot``
  from the constrained forward dynamics (``pin.constraintDynamics`` by default);
  the actuator forces and the wrench are held constant over a step (zero-order hold);
* after each step, drift control by projection onto the constraint manifold: the
  quaternions are renormalised; when the closure residual ``r`` exceeds ``projection_tol``
  (default 1e-10 m), ``q`` gets Gauss-Newton corrections ``q <- q (+) (-J_c^+ r)``
  (minimum norm over all coordinates) and the velocity is projected,
  ``v <- v - J_c^+ J_c v``.
"""


from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from ..errors import AssemblyError, InputError
from .closed_loop import ClosedLoopModel
from .dynamics import FORWARD_METHODS, dynamics_of, independent_rows

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
            :meth:`~hexapod_pin.hexapod.kernels.ClosedForm.closure_residual`); it must
            return the same quantity as :meth:`ClosedLoopModel.residual`.

    Raises:
        InputError: an unsupported joint type, method or integrator.
    """

    def __init__(self, clm: ClosedLoopModel, method: str = "pinocchio", integrator: str = "rk4",
                 residual: Callable[[np.ndarray], float] | None = None) -> None:
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
        self._redundant: bool | None = None
        self._rows: np.ndarray | None = None     # independent closure rows (projection)

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
        """Tree acceleration (nv,) for the generalised force ``tau`` (nv,), verified.

        Every answer satisfies the equation of motion and the closures at acceleration
        level to :data:`~hexapod_pin.core.dynamics.RESIDUAL_RTOL` (relative) or the
        route raises :class:`~hexapod_pin.errors.SolverError`. The "pinocchio" method
        runs one verified ``pin.constraintDynamics`` call and falls back to the exact
        KKT route when it is refused. ``checked`` is kept for callers; every call is
        checked.
        """
        dyn = self.dyn
        if self.method == "pinocchio":
            redundant = self._redundant
            if redundant is None:
                redundant = self._redundant = dyn.closure_rank(q) < dyn.n_rows
            acc, _ = dyn.pinocchio_call(q, v, tau, redundant)
            if acc is not None:
                return acc.copy()
        return dyn.forward_unchecked(q, v, tau, self.method).a

    def step(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, dt: float,
             projection_tol: float = PROJECTION_TOL) -> tuple[np.ndarray, np.ndarray, float]:
        """One step of length ``dt`` (s) with ``tau`` (nv,) held; returns ``(q, v, residual)``.

        ``residual`` is the max-abs closure residual after the projection (m).

        Raises:
            AssemblyError: the projection does not converge.
        """
        if self.integrator == "rk4":
            q_new, v_new = self._rk4(q, v, tau, dt)
        else:
            v_new = v + dt * self.acceleration(q, v, tau)
            q_new = pin.integrate(self.clm.model, q, dt * v_new)
        return self.project(q_new, v_new, projection_tol)

    def _rk4(self, q, v, tau, dt):
        qdot, normalise = self.qdot, self._normalise

        def acc(qs, vs):
            return self.acceleration(qs, vs, tau)

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
                max_iter: int = 8) -> tuple[np.ndarray, np.ndarray, float]:
        """Project ``(q, v)`` onto the closures when the residual exceeds ``trigger``.

        Gauss-Newton steps ``q <- q (+) (-J_c^+ r)`` on the independent closure rows (rows
        dependent on the others, exactly or to 1e-8, are left out once and for all) until
        the residual stops decreasing tenfold or falls below ``1e-3 trigger``, then
        ``v <- v - J_c^+ J_c v`` on the same rows.
        Returns ``(q, v, residual)``; untouched when the residual is below ``trigger``.

        Raises:
            AssemblyError: the residual stays above ``trigger`` after ``max_iter`` steps.
        """
        err = self.residual(q)
        if err <= trigger:
            return q, v, err
        dyn = self.dyn
        model = self.clm.model
        rows = self._rows
        for _ in range(max_iter):
            jac = dyn.constraint_jacobian(q)          # also updates the frame placements
            if rows is None:
                rows = self._rows = independent_rows(jac)
            res = self._residual_from_data()
            err = float(np.max(np.abs(res), initial=0.0))
            if not np.isfinite(err):
                break
            q_new = pin.integrate(model, q, -_pinv_apply(jac[rows], res[rows]))
            err_new = self.residual(q_new)
            if not err_new < err:
                break
            q, err, err_old = q_new, err_new, err
            if err <= 1e-3 * trigger or err > 0.1 * err_old:
                break
        if not (err <= trigger):
            raise AssemblyError("projection onto the closures failed", err, max_iter, q)
        jac = dyn.constraint_jacobian(q)[rows]
        v = v - _pinv_apply(jac, jac @ v)
        return q, v, err

    def _residual_from_data(self) -> np.ndarray:
        data = self.dyn.data
        out = np.empty(self.dyn.n_rows)
        for is_point, rows, f1, f2, _, _ in self.dyn.closure_frames:
            m1, m2 = data.oMf[f1], data.oMf[f2]
            out[rows] = (m1.translation - m2.translation if is_point
                         else pin.log6(m2.actInv(m1)).vector)
        return out


def _pinv_apply(jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``J^+ rhs`` (minimum norm): through ``J J^T`` when that solve reproduces ``rhs``
    (full row rank), else by SVD least squares (rank-deficient or ill-conditioned ``J``)."""
    try:
        sol = jac.T @ np.linalg.solve(jac @ jac.T, rhs)
        miss = np.max(np.abs(jac @ sol - rhs), initial=0.0)
        if math.isfinite(miss) and miss <= 1e-12 * max(1.0, np.max(np.abs(rhs), initial=0.0)):
            return sol
    except np.linalg.LinAlgError:
        pass
    sol, *_ = np.linalg.lstsq(jac, rhs, rcond=None)
    return sol

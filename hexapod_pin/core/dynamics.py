"""Dynamics of closed-loop mechanisms on their Pinocchio tree (robot-agnostic).

For any :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`:

* :func:`forward_dynamics_tree` -- tree acceleration and closure multipliers for given
  generalised forces, three routes: ``pin.constraintDynamics`` ("pinocchio"), the
  Gauss-principle QP solved by ProxSuite ("qp"), a numpy KKT solve ("kkt").
* :func:`inverse_dynamics_tree` -- actuator forces and closure multipliers for a given
  closure-consistent tree motion, as a ProxSuite QP with actuator bounds ("qp") or a
  linear solve ("kkt"). Pinocchio has no closed-loop inverse dynamics; this is it.
* :class:`ClosedLoopDynamics` -- the cached workspace behind both (Pinocchio data,
  constraint data, ProxSuite problems), reachable with :func:`dynamics_of`.

Equations and sign conventions (tree coordinates, Pinocchio's ``q``, ``v``, ``a``)::

    M(q) a + h(q, v) = tau + J_c(q)^T lambda          (equation of motion)
    J_c(q) a = -gamma(q, v)                            (closures at acceleration level)
    tau = S^T u + tau_ext                              (actuation + external loads)

``J_c`` and ``gamma`` are those of :meth:`ClosedLoopModel.constraint_jacobian` and
:meth:`ClosedLoopModel.constraint_drift` (point-closure rows in world axes). With that
row convention, ``J_c^T lambda`` is the generalised force the closures exert on the
tree, and for a point closure ``lambda_c`` (N, world axes) is the force that the body
of ``frame2`` exerts on the body of ``frame1`` at the joint (``-lambda_c`` acts on
``frame2``'s body). ``S`` selects the actuated velocity coordinates (``clm.actuated_v``).

For a weld the six multipliers pair with the ``log6`` rows (at an assembled
configuration, the spatial force in anchor-1 axes). Pinocchio's own ``lambda_c``
(LOCAL contact frames) is converted: ``lambda = R_c1 lambda_pin`` for a point.

Redundant closures (rank-deficient ``J_c``): the accelerations and actuator forces
stay unique and every route returns them; the multipliers are not unique and every
route returns the minimum-norm ones. The rank of ``J_c`` is evaluated at the first
call and assumed to be structural afterwards (re-evaluated whenever a route meets a
singular system).

"""

from __future__ import annotations

import math
import weakref
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pinocchio as pin
import proxsuite

from ..errors import ActuatorSaturationError, InputError, SolverError
from .checks import as_array, max_abs
from .closed_loop import ClosedLoopModel

FORWARD_METHODS = ("pinocchio", "qp", "kkt")
INVERSE_METHODS = ("qp", "kkt")

#: relative tolerance on equation residuals before a route is declared failed
RESIDUAL_RTOL = 1e-9
#: ProxSuite accuracy (absolute, on primal and dual residuals)
_QP_EPS = 1e-13
#: iteration cap of the tree QPs (redundant closure rows slow the proximal iterations down)
_QP_MAX_ITER = 1000
#: a stalled tree QP is accepted when its residuals are below this, relative to its data
_QP_ACCEPT = 1e-10
#: Pinocchio proximal settings used when the closures are redundant (the acceleration
#: converges in a few iterations; the multipliers are then polished to minimum norm)
_PIN_PROX_MU = 1e-6
_PIN_PROX_ITERS = 5
#: weight of the multipliers in the inverse-dynamics QP objective (relative to forces)
_LAMBDA_WEIGHT = 1e-2

QP_SOLVED = proxsuite.proxqp.PROXQP_SOLVED
QP_STATUS = {
    proxsuite.proxqp.PROXQP_SOLVED: "solved",
    proxsuite.proxqp.PROXQP_MAX_ITER_REACHED: "max_iter_reached",
    proxsuite.proxqp.PROXQP_PRIMAL_INFEASIBLE: "primal_infeasible",
    proxsuite.proxqp.PROXQP_DUAL_INFEASIBLE: "dual_infeasible",
    proxsuite.proxqp.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE: "solved_closest_primal_feasible",
    proxsuite.proxqp.PROXQP_NOT_RUN: "not_run",
}


class ClosureFrames(NamedTuple):
    """Where one closure sits in the tree: its type, rows and Pinocchio frame / joint ids."""

    is_point: bool
    rows: slice
    frame1: int
    frame2: int
    joint1: int
    joint2: int


# --------------------------------------------------------------------------------------
# results
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TreeForwardDynamics:
    """Result of :func:`forward_dynamics_tree`.

    Attributes:
        a: tree acceleration (nv,), Pinocchio convention (free-flyer part: derivative
            of the body-frame velocity).
        multipliers: closure multipliers (n_rows,), ``M a + h = tau + J_c^T multipliers``,
            rows as in :meth:`ClosedLoopModel.constraint_jacobian` (N for point rows,
            world axes). Minimum-norm when the closures are redundant.
        method: the route used ("pinocchio", "qp" or "kkt").
        status: "solved", or a note on how it was solved (redundant rows, fallback).
        iterations: solver iterations (0 for a direct solve).
        rank: rank of ``J_c`` assumed by the solve.
        constraint_residual: max-abs of ``J_c a + gamma`` (m/s^2); -1.0 (not
            computed, never NaN) for the "pinocchio" route, which does not form ``J_c``.
    """

    a: np.ndarray
    multipliers: np.ndarray
    method: str
    status: str
    iterations: int
    rank: int
    constraint_residual: float


@dataclass(frozen=True)
class TreeInverseDynamics:
    """Result of :func:`inverse_dynamics_tree`.

    Attributes:
        actuator_forces: ``u`` (n_act,), generalised forces of the actuated joints
            (N for prismatic, N m for revolute), in ``clm.actuated_joints`` order.
        multipliers: closure multipliers (n_rows,), same convention as
            :class:`TreeForwardDynamics` (minimum-norm when redundant).
        residual: max-abs of ``M a + h - tau_ext - S^T u - J_c^T multipliers`` (N, N m).
            Non-zero only when ``a`` does not keep the closures and the system is
            over-determined (redundant rows), where the least-squares answer is given.
        method: "qp" or "kkt".
        status: solver status ("solved", ...).
        iterations: solver iterations (0 for a direct solve).
    """

    actuator_forces: np.ndarray
    multipliers: np.ndarray
    residual: float
    method: str
    status: str
    iterations: int


# --------------------------------------------------------------------------------------
# generic workspace
# --------------------------------------------------------------------------------------
class ClosedLoopDynamics:
    """Cached dynamics workspace of one :class:`ClosedLoopModel`.

    Owns its own ``pin.Data`` (it never touches ``clm.data``), the Pinocchio constraint
    data for ``pin.constraintDynamics``, and the ProxSuite problems (kept and updated
    from call to call). Get the shared instance of a model with :func:`dynamics_of`.

    Args:
        clm: the closed-loop model.
    """

    def __init__(self, clm: ClosedLoopModel):
        if not isinstance(clm, ClosedLoopModel):
            raise InputError("clm", clm, "expected a ClosedLoopModel")
        self.clm = clm
        self.model = clm.model
        self.data = self.model.createData()
        self.nv = self.model.nv
        self.n_rows = clm.n_rows
        self.n_act = clm.n_actuated
        #: Pinocchio's constraint models and datas of the closures (for ``constraintDynamics``)
        self.pin_models, self.pin_datas = clm.pinocchio_constraints()
        self._pin_ready = False
        #: one :class:`ClosureFrames` per closure, in the order of the loops file
        self.closure_frames: list[ClosureFrames] = []
        for closure, rows, cm in zip(clm.closures, clm.row_slices, clm.constraint_models):
            f1 = self.model.getFrameId(f"{closure.name}/anchor1")
            f2 = self.model.getFrameId(f"{closure.name}/anchor2")
            self.closure_frames.append(ClosureFrames(closure.type == "point", rows, f1, f2,
                                                     cm.joint1_id, cm.joint2_id))
        self._selection = np.zeros((self.nv, self.n_act))
        self._selection[clm.actuated_v, np.arange(self.n_act)] = 1.0
        self._zero_v = np.zeros(self.nv)
        self._lower = np.tril_indices(self.nv, -1)
        self._rank: int | None = None
        self._qps: dict = {}

    # -- rank ----------------------------------------------------------------------------
    def closure_rank(self, q: np.ndarray, force: bool = False) -> int:
        """Rank of ``J_c``, evaluated at ``q`` on the first call (or when ``force``) and
        assumed structural afterwards."""
        if self._rank is None or force:
            self._rank = self.clm.rank(q).rank if self.n_rows else 0
        return self._rank

    @property
    def redundant(self) -> bool | None:
        """Whether the closures were found redundant (None before the first call)."""
        return None if self._rank is None else self._rank < self.n_rows

    # -- constraint terms -------------------------------------------------------------------
    def constraint_jacobian(self, q: np.ndarray) -> np.ndarray:
        """``J_c`` (n_rows, nv) at ``q`` (same as :meth:`ClosedLoopModel.constraint_jacobian`)."""
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        return self._jacobian_from_data()

    def _jacobian_from_data(self) -> np.ndarray:
        out = np.empty((self.n_rows, self.nv))
        model, data = self.model, self.data
        lwa, loc = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED, pin.ReferenceFrame.LOCAL
        for is_point, rows, f1, f2, _, _ in self.closure_frames:
            if is_point:
                out[rows] = (pin.getFrameJacobian(model, data, f1, lwa)[:3]
                             - pin.getFrameJacobian(model, data, f2, lwa)[:3])
            else:
                m21 = data.oMf[f2].actInv(data.oMf[f1])
                out[rows] = pin.Jlog6(m21) @ (pin.getFrameJacobian(model, data, f1, loc)
                                              - m21.inverse().action
                                              @ pin.getFrameJacobian(model, data, f2, loc))
        return out

    def constraint_drift(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``gamma`` (n_rows,) at ``(q, v)`` (same as :meth:`ClosedLoopModel.constraint_drift`)."""
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q, v, self._zero_v)
        pin.updateFramePlacements(model, data)
        out = np.empty(self.n_rows)
        lwa, loc = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED, pin.ReferenceFrame.LOCAL
        for is_point, rows, f1, f2, _, _ in self.closure_frames:
            if is_point:
                out[rows] = (pin.getFrameClassicalAcceleration(model, data, f1, lwa).linear
                             - pin.getFrameClassicalAcceleration(model, data, f2, lwa).linear)
            else:
                m21 = data.oMf[f2].actInv(data.oMf[f1])
                a1 = pin.getFrameAcceleration(model, data, f1, loc)
                a2 = pin.getFrameAcceleration(model, data, f2, loc)
                v1 = pin.getFrameVelocity(model, data, f1, loc)
                v2 = pin.getFrameVelocity(model, data, f2, loc)
                rel = a1 - m21.actInv(a2) + v1.cross(m21.actInv(v2))
                out[rows] = pin.Jlog6(m21) @ rel.vector
        return out

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Joint-space inertia matrix ``M(q)`` (nv, nv), symmetric (kg, kg m, kg m^2)."""
        mat = pin.crba(self.model, self.data, q).copy()   # upper triangle filled
        mat[self._lower] = mat.T[self._lower]
        return mat

    def _closure_world_forces(self, multipliers: np.ndarray) -> list[pin.Force]:
        """Spatial force (world frame, about the world origin) on body 1 of each closure.

        Needs the frame placements of ``self.data`` up to date.
        """
        out = []
        data = self.data
        for is_point, rows, f1, f2, _, _ in self.closure_frames:
            lam = multipliers[rows]
            p1 = data.oMf[f1].translation
            if is_point:
                out.append(pin.Force(lam, np.cross(p1, lam)))
            else:
                m21 = data.oMf[f2].actInv(data.oMf[f1])
                local = pin.Force(pin.Jlog6(m21).T @ lam)      # in anchor-1 frame
                out.append(data.oMf[f1].act(local))
        return out

    def _pin_to_row_multipliers(self, lam_pin: np.ndarray) -> np.ndarray:
        """Convert Pinocchio's LOCAL contact forces into our row convention.

        Point rows: ``lambda = R_c1 lambda_pin`` (``J_c = R_c1 J_pin``); weld rows:
        ``lambda = Jlog6^-T lambda_pin`` (``J_c = Jlog6 J_pin``).
        """
        if self._all_points:
            rots = np.array([cd.oMc1.rotation for cd in self._cd_list])
            return np.einsum("kij,kj->ki", rots, lam_pin.reshape(-1, 3)).reshape(-1)
        out = np.empty(self.n_rows)
        for (is_point, rows, _, _, _, _), cd in zip(self.closure_frames, self._cd_list):
            if is_point:
                out[rows] = cd.oMc1.rotation @ lam_pin[rows]
            else:
                jlog = pin.Jlog6(cd.c1Mc2.inverse())
                out[rows] = np.linalg.solve(jlog.T, lam_pin[rows])
        return out

    # -- forward dynamics -----------------------------------------------------------------
    def forward(self, q, v, tau, method: str = "pinocchio") -> TreeForwardDynamics:
        """Constrained forward dynamics; see :func:`forward_dynamics_tree`."""
        q = self.clm.check_q(q)
        v = self.clm.check_v(v)
        tau = self.clm.check_v(tau, "tau")
        if method not in FORWARD_METHODS:
            raise InputError("method", method, f"expected one of {FORWARD_METHODS}")
        rank = self.closure_rank(q)
        if method == "pinocchio":
            return self._forward_pinocchio(q, v, tau, rank)
        jac = self.constraint_jacobian(q)
        gamma = self.constraint_drift(q, v)
        mass = self.mass_matrix(q)
        bias = pin.nonLinearEffects(self.model, self.data, q, v)
        if method == "kkt":
            return self._forward_kkt(mass, bias, jac, gamma, tau, rank)
        return self._forward_qp(mass, bias, jac, gamma, tau, rank)

    def pinocchio_arguments(self) -> tuple:
        """``((model, data), (constraint models, constraint datas, proximal settings))``: the
        arguments of ``pin.constraintDynamics`` for non-redundant closures (exact settings)."""
        if not self._pin_ready:
            self._init_pinocchio()
        return ((self.model, self.data), (self.pin_models, self.pin_datas, self._prox_exact))

    def _init_pinocchio(self) -> None:
        pin.initConstraintDynamics(self.model, self.data, self.pin_models, self.pin_datas)
        self._prox_exact = pin.ProximalSettings(1e-13, 0.0, 1)
        self._prox_redundant = pin.ProximalSettings(1e-13, _PIN_PROX_MU, _PIN_PROX_ITERS)
        self._cd_list = list(self.pin_datas)
        self._all_points = all(c[0] for c in self.closure_frames)
        self._pin_ready = True

    def pinocchio_call(self, q, v, tau, redundant: bool):
        """One ``pin.constraintDynamics`` call; returns (a or None if it failed, prox).

        ``a`` is Pinocchio's own buffer (copy it before the next call). A failed solve
        shows as non-finite accelerations (the multipliers come from the same solve).
        """
        if not self._pin_ready:
            self._init_pinocchio()
        prox = self._prox_redundant if redundant else self._prox_exact
        acc = pin.constraintDynamics(self.model, self.data, q, v, tau, self.pin_models, self.pin_datas,
                                     prox)
        if not math.isfinite(acc.sum()):
            return None, prox
        return acc, prox

    def _pin_min_norm_multipliers(self, acc, tau) -> np.ndarray:
        """Minimum-norm LOCAL multipliers from Pinocchio's own ``M``, ``nle`` and ``J``.

        ``J_pin^T lambda = M a + nle - tau``; the blocks of ``J_pin`` are rotations of
        ours, so the minimum norm is the same in either row convention.
        """
        mass = self.data.M.copy()
        mass[self._lower] = mass.T[self._lower]
        force = mass @ acc + self.data.nle - tau
        jac = pin.getConstraintsJacobian(self.model, self.data, self.pin_models, self.pin_datas)
        sol, *_ = np.linalg.lstsq(jac.T, force, rcond=None)
        return sol

    def pinocchio_acceleration(self, q, v, tau) -> np.ndarray:
        """Tree acceleration (nv,) only (no multipliers), for integrators; no input checks."""
        rank = self.closure_rank(q)
        acc, _ = self.pinocchio_call(q, v, tau, rank < self.n_rows)
        if acc is None:
            return self._forward_pinocchio(q, v, tau, rank).a
        return acc.copy()

    def _forward_pinocchio(self, q, v, tau, rank) -> TreeForwardDynamics:
        for attempt in range(2):
            redundant = rank < self.n_rows
            acc, prox = self.pinocchio_call(q, v, tau, redundant)
            if acc is not None:
                if not redundant:
                    lam_pin, status = self.data.lambda_c, "solved"
                else:
                    lam_pin = self._pin_min_norm_multipliers(acc, tau)
                    status = (f"solved (redundant rows: proximal mu={_PIN_PROX_MU:g}, "
                              f"{_PIN_PROX_ITERS} iterations; minimum-norm multipliers)")
                return TreeForwardDynamics(acc.copy(), self._pin_to_row_multipliers(lam_pin),
                                           "pinocchio", status, int(prox.iter), rank, -1.0)
            if attempt == 0:
                new_rank = self.closure_rank(q, force=True)
                if new_rank == rank and redundant:
                    break
                rank = new_rank
        # last resort: the KKT route (reported in the status)
        jac = self.constraint_jacobian(q)
        gamma = self.constraint_drift(q, v)
        mass = self.mass_matrix(q)
        bias = pin.nonLinearEffects(self.model, self.data, q, v)
        res = self._forward_kkt(mass, bias, jac, gamma, tau, rank)
        return TreeForwardDynamics(res.a, res.multipliers, "pinocchio",
                                   "pin.constraintDynamics failed; solved by the KKT route",
                                   0, res.rank, res.constraint_residual)

    def _forward_kkt(self, mass, bias, jac, gamma, tau, rank) -> TreeForwardDynamics:
        nv, nr = self.nv, self.n_rows
        kkt = np.zeros((nv + nr, nv + nr))
        kkt[:nv, :nv] = mass
        kkt[:nv, nv:] = jac.T
        kkt[nv:, :nv] = jac
        rhs = np.concatenate([tau - bias, -gamma])
        sol = None
        status = "solved"
        if rank == nr:
            try:
                sol = np.linalg.solve(kkt, rhs)
            except np.linalg.LinAlgError:
                sol = None
            if sol is not None and not _small(kkt @ sol - rhs, rhs):
                sol = None
            if sol is None:
                rank = self._ensure_rank_from(jac)
        if sol is None:
            sol, *_ = np.linalg.lstsq(kkt, rhs, rcond=None)
            status = "solved (redundant rows: minimum-norm multipliers)"
        acc = sol[:nv]
        lam = -sol[nv:]
        return TreeForwardDynamics(acc, lam, "kkt", status, 0, rank,
                                   max_abs(jac @ acc + gamma))

    def _ensure_rank_from(self, jac: np.ndarray) -> int:
        self._rank = int(np.linalg.matrix_rank(jac))
        return self._rank

    def _qp_solve(self, key, n_in, args, scale: float = 1.0) -> proxsuite.proxqp.dense.QP:
        """Initialise (first call) or update the cached ProxSuite problem ``key``; solve.

        The absolute tolerance is ``_QP_EPS * scale``: ``scale`` is the magnitude of the
        problem's data (large accelerations or forces need a proportional tolerance,
        or the solver stalls at its iteration limit on rounding)."""
        entry = self._qps.get(key)
        if entry is None:
            hess, _, amat = args[0], args[1], args[2]
            qp = proxsuite.proxqp.dense.QP(hess.shape[0], amat.shape[0], n_in)
            qp.settings.eps_abs = _QP_EPS
            qp.settings.eps_rel = 0.0
            qp.settings.max_iter = _QP_MAX_ITER
            qp.settings.verbose = False
            qp.settings.initial_guess = \
                proxsuite.proxqp.InitialGuess.EQUALITY_CONSTRAINED_INITIAL_GUESS
            qp.init(*args)
            self._qps[key] = qp
        else:
            qp = entry
            qp.update(*args, update_preconditioner=True)
        qp.settings.eps_abs = _QP_EPS * max(1.0, float(scale))
        qp.solve()
        return qp

    def _forward_qp(self, mass, bias, jac, gamma, tau, rank) -> TreeForwardDynamics:
        # Gauss: min 1/2 (a - a_free)^T M (a - a_free) = 1/2 a^T M a + (h - tau)^T a + const
        scale = max(1.0, max_abs(bias - tau), max_abs(gamma))
        qp = self._qp_solve("fd", 0, (mass, bias - tau, jac, -gamma, None, None, None),
                            scale=scale)
        status = QP_STATUS.get(qp.results.info.status, str(qp.results.info.status))
        info = qp.results.info
        if (status == "max_iter_reached" and max(info.pri_res, info.dua_res)
                <= _QP_ACCEPT * scale):
            # ill-conditioned redundant rows: the residuals stall at rounding level
            status = f"solved (residuals within {_QP_ACCEPT:g} relative at max_iter)"
        elif status != "solved":
            raise SolverError("ProxSuite (forward dynamics QP)", status,
                              f"primal residual {qp.results.info.pri_res:.3e}, "
                              f"dual residual {qp.results.info.dua_res:.3e}")
        acc = qp.results.x.copy()
        lam = -qp.results.y  # ProxSuite: H x + g + A^T y = 0
        if rank < self.n_rows:
            lam = _min_norm_multipliers(jac, lam)
            status = "solved (redundant rows: minimum-norm multipliers)"
        return TreeForwardDynamics(acc, lam, "qp", status, int(qp.results.info.iter), rank,
                                   max_abs(jac @ acc + gamma))

    # -- inverse dynamics -------------------------------------------------------------------
    def inverse(self, q, v, a, tau_ext=None, bounds=None,
                method: str = "qp") -> TreeInverseDynamics:
        """Closed-loop inverse dynamics; see :func:`inverse_dynamics_tree`."""
        q = self.clm.check_q(q)
        v = self.clm.check_v(v)
        a = self.clm.check_v(a, "a")
        tau_ext = self._zero_v if tau_ext is None else self.clm.check_v(tau_ext, "tau_ext")
        bounds = self._check_bounds(bounds)
        if method not in INVERSE_METHODS:
            raise InputError("method", method, f"expected one of {INVERSE_METHODS}")
        rank = self.closure_rank(q)
        rhs = pin.rnea(self.model, self.data, q, v, a) - tau_ext
        jac = self.constraint_jacobian(q)
        return self._inverse_solve(jac, rhs, bounds, method, rank)

    def _check_bounds(self, bounds) -> np.ndarray | None:
        if bounds is None:
            return None
        if isinstance(bounds, (int, float)) and not isinstance(bounds, bool):
            if not bounds > 0.0:
                raise InputError("bounds", bounds, "must be positive")
            return None if bounds == float("inf") else np.full(self.n_act, float(bounds))
        arr = np.broadcast_to(np.asarray(bounds, dtype=float), (self.n_act,)).copy() \
            if np.ndim(bounds) == 0 else np.asarray(bounds, dtype=float)
        if arr.shape != (self.n_act,) or np.any(np.isnan(arr)) or np.any(arr <= 0.0):
            raise InputError("bounds", bounds,
                             f"expected a positive scalar or ({self.n_act},) positive values")
        return None if np.all(np.isinf(arr)) else arr

    def _inverse_solve(self, jac, rhs, bounds, method, rank) -> TreeInverseDynamics:
        mat = np.empty((self.nv, self.n_act + self.n_rows))
        mat[:, :self.n_act] = self._selection
        mat[:, self.n_act:] = jac.T
        if method == "kkt":
            sol, status = self._inverse_kkt(mat, rhs, rank, jac)
            iters = 0
        else:
            sol, status, iters = self._inverse_qp(mat, rhs, bounds)
        u = sol[:self.n_act]
        if bounds is not None and np.any(np.abs(u) > bounds * (1.0 + RESIDUAL_RTOL)):
            raise ActuatorSaturationError(u, bounds)
        return TreeInverseDynamics(u.copy(), sol[self.n_act:].copy(), max_abs(mat @ sol - rhs),
                                   method, status, iters)

    def _inverse_kkt(self, mat, rhs, rank, jac=None):
        if mat.shape[0] == mat.shape[1] and rank == self.n_rows:
            # square system: the passive rows give the multipliers, the actuated rows u
            act, passive = self.clm.actuated_v, self.clm.passive_v
            if jac is None:
                jac = mat[:, self.n_act:].T
            try:
                lam = np.linalg.solve(jac[:, passive].T, rhs[passive])
                sol = np.concatenate([rhs[act] - jac[:, act].T @ lam, lam])
                if _small(mat @ sol - rhs, rhs):
                    return sol, "solved"
            except np.linalg.LinAlgError:
                pass
        sol, *_ = np.linalg.lstsq(mat, rhs, rcond=None)
        return sol, "solved (least squares / minimum norm)"

    def _inverse_qp(self, mat, rhs, bounds):
        n = self.n_act + self.n_rows
        weights = np.concatenate([np.ones(self.n_act), np.full(self.n_rows, _LAMBDA_WEIGHT)])
        hess = np.diag(weights)
        zero_g = np.zeros(n)
        if bounds is None:
            qp = self._qp_solve("id", 0, (hess, zero_g, mat, rhs, None, None, None),
                                scale=max_abs(rhs))
        else:
            cmat = np.zeros((self.n_act, n))
            cmat[:, :self.n_act] = np.eye(self.n_act)
            qp = self._qp_solve("id_bounded", self.n_act,
                                (hess, zero_g, mat, rhs, cmat, -bounds, bounds),
                                scale=max_abs(rhs))
        status = QP_STATUS.get(qp.results.info.status, str(qp.results.info.status))
        sol = qp.results.x.copy()
        ok = status == "solved" and _small(mat @ sol - rhs, rhs, rtol=1e-8)
        if not ok:
            needed, _ = self._inverse_kkt(mat, rhs, self._rank or self.n_rows)
            if bounds is not None and np.any(np.abs(needed[:self.n_act]) > bounds):
                raise ActuatorSaturationError(needed[:self.n_act], bounds)
            raise SolverError("ProxSuite (inverse dynamics QP)", status,
                              f"primal residual {qp.results.info.pri_res:.3e}")
        return sol, status, int(qp.results.info.iter)

    # -- joint reaction wrenches ------------------------------------------------------------
    def joint_wrenches(self, q, v, a, multipliers, fext: Mapping[int, pin.Force] | None = None
                       ) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """Spatial force transmitted by every joint of the tree.

        Runs ``pin.rnea`` with the closure forces (from ``multipliers``) and ``fext``
        applied as external forces. Pinocchio's ``data.f[j]`` is then the spatial force
        that the parent body exerts on the child body of joint ``j`` through the joint,
        expressed in the joint's LOCAL frame at the joint origin: ``(f, m)`` (N, N m).
        Its projection on the joint's motion subspace is the joint's generalised
        force (the actuator force for an actuated joint, ~0 for a passive one).

        Args:
            q, v, a: tree configuration, velocity and acceleration.
            multipliers: closure multipliers (n_rows,) as returned by the routes.
            fext: extra external forces by joint id, each a ``pin.Force`` in that
                joint's LOCAL frame (e.g. a load on a floating body).

        Returns:
            (wrenches by joint name, each (6,) = (f, m)), and the generalised force
            ``tau`` (nv,) that rnea needs with those forces (``S^T u`` if consistent).
        """
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        forces = pin.StdVec_Force()
        for _ in range(model.njoints):
            forces.append(pin.Force.Zero())
        for world, (_, _, _, _, j1, j2) in zip(self._closure_world_forces(multipliers),
                                               self.closure_frames):
            forces[j1] = forces[j1] + data.oMi[j1].actInv(world)
            forces[j2] = forces[j2] - data.oMi[j2].actInv(world)
        for joint, force in (fext or {}).items():
            forces[joint] = forces[joint] + force
        tau = pin.rnea(model, data, q, v, a, forces)
        out = {model.names[j]: data.f[j].vector.copy() for j in range(1, model.njoints)}
        return out, tau.copy()


_CACHE: weakref.WeakKeyDictionary[ClosedLoopModel, ClosedLoopDynamics] = \
    weakref.WeakKeyDictionary()


def dynamics_of(clm: ClosedLoopModel) -> ClosedLoopDynamics:
    """The shared :class:`ClosedLoopDynamics` workspace of ``clm`` (created once)."""
    try:
        return _CACHE[clm]
    except KeyError:
        dyn = ClosedLoopDynamics(clm)
        _CACHE[clm] = dyn
        return dyn
    except TypeError:
        raise InputError("clm", clm, "expected a ClosedLoopModel") from None


def forward_dynamics_tree(clm: ClosedLoopModel, q, v, actuator_forces, tau_ext=None,
                          method: str = "pinocchio") -> TreeForwardDynamics:
    """Constrained forward dynamics of a closed-loop mechanism on its tree.

    Solves ``M a + h = S^T u + tau_ext + J_c^T lambda`` with ``J_c a = -gamma`` for the
    tree acceleration ``a`` and the closure multipliers ``lambda`` (conventions in the
    module docstring). Takes the actuator forces in the shape
    :func:`inverse_dynamics_tree` returns them, so that the two routes compose.

    Args:
        clm: the closed-loop model.
        q: tree configuration (nq,), the closures satisfied.
        v: tree velocity (nv,) with ``J_c v = 0`` (Pinocchio convention: free-flyer
            velocities in the body frame).
        actuator_forces: ``u`` (n_act,), generalised forces of the actuated joints in
            ``clm.actuated_joints`` order (N for prismatic, N m for revolute joints).
        tau_ext: generalised external force on the tree (nv,) (N, N m); default zero.
        method: "pinocchio" (``pin.constraintDynamics``; when the closures are
            redundant: proximal, mu = 1e-6, 5 iterations, and the multipliers polished
            to minimum norm by least squares on Pinocchio's ``M``, ``nle``, ``J``), "qp" (Gauss principle, ``min 1/2 (a - a_free)^T M
            (a - a_free)`` s.t. ``J_c a = -gamma``, ProxSuite dense, warm problem
            reused), or "kkt" (numpy solve of the KKT system, least squares when
            redundant).

    Returns:
        :class:`TreeForwardDynamics`.

    Raises:
        InputError: bad shapes, NaN / inf, unknown method.
        SolverError: the QP did not converge.
    """
    dyn = dynamics_of(clm)
    u = as_array(actuator_forces, (clm.n_actuated,), "actuator_forces")
    tau = np.zeros(clm.nv) if tau_ext is None else clm.check_v(tau_ext, "tau_ext").copy()
    tau[clm.actuated_v] += u
    return dyn.forward(q, v, tau, method)


def inverse_dynamics_tree(clm: ClosedLoopModel, q, v, a, tau_ext=None, bounds=None,
                          method: str = "qp") -> TreeInverseDynamics:
    """Closed-loop inverse dynamics: actuator forces that produce a tree motion.

    Solves ``M a + h - tau_ext = S^T u + J_c^T lambda`` for the actuator forces ``u``
    and the closure multipliers ``lambda``. ``a`` must keep the closures
    (``J_c a = -gamma``), e.g. from :meth:`ClosedLoopModel.complete_acceleration`.

    Args:
        clm: the closed-loop model.
        q, v, a: tree configuration (nq,), velocity and acceleration (nv,), Pinocchio
            conventions, consistent with the closures.
        tau_ext: generalised external force on the tree (nv,) (N, N m); default zero.
        bounds: ``abs(u) <= bounds`` (scalar or (n_act,), N or N m); None (or inf): none.
        method: "qp" (ProxSuite dense QP: minimise ``1/2 |u|^2 + 1/2 w |lambda|^2``,
            ``w = 1e-2`` (it only picks the minimum-norm multipliers of redundant
            rows), subject to the equation of motion and the box bounds) or "kkt" (the
            square linear system ``[S^T J_c^T] [u; lambda] = rhs``, least squares /
            minimum norm when it is not square or singular). Both agree to 1e-10 when
            no bound is active.

    Returns:
        :class:`TreeInverseDynamics`.

    Raises:
        ActuatorSaturationError: the motion needs ``abs(u) > bounds``; carries the
            needed (unbounded) forces. No clipped answer is ever returned.
        InputError: bad shapes, NaN / inf, non-positive bounds, unknown method.
        SolverError: the QP failed for another reason.
    """
    return dynamics_of(clm).inverse(q, v, a, tau_ext, bounds, method)


# --------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------
def _small(residual: np.ndarray, rhs: np.ndarray, rtol: float = RESIDUAL_RTOL) -> bool:
    scale = max(1.0, max_abs(rhs))
    return bool(np.all(np.isfinite(residual)) and max_abs(residual) <= rtol * scale)


def _min_norm_multipliers(jac: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """The minimum-norm multipliers giving the same generalised force ``J_c^T lam``."""
    sol, *_ = np.linalg.lstsq(jac.T, jac.T @ lam, rcond=None)
    return sol


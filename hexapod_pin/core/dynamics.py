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
call and assumed to be structural afterwards (re-evaluated once when a route meets a
singular system).

Verification: no route returns an answer it has not checked. Forward dynamics checks
both equations above to :data:`RESIDUAL_RTOL` relative to the largest term of each
(:func:`~hexapod_pin.core.linear_kernels.forward_residuals`); inverse dynamics checks
that ``a`` keeps the closures (to 1e-8) and that ``S^T u + J_c^T lambda = M a + h -
tau_ext`` (:func:`~hexapod_pin.core.linear_kernels.linear_residual`).
A failed check raises :class:`~hexapod_pin.errors.SolverError` naming the equation and
its relative residual, after the retries documented on each route.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import proxsuite
import scipy.linalg
import scipy.optimize

from ..errors import ActuatorSaturationError, InputError, SolverError
from .checks import as_array, max_abs
from .closed_loop import RANK_RTOL, ClosedLoopModel
from .compiled import all_finite
from .linear_kernels import (
    box_active_set_solve,
    forward_residuals,
    kkt_residuals,
    linear_residual,
    minimum_norm_solve,
    normal_solve,
    square_solve,
    weighted_minimum_norm_solve,
    within_bounds,
)

FORWARD_METHODS = ("pinocchio", "qp", "kkt")
INVERSE_METHODS = ("qp", "kkt")

#: relative tolerance on equation residuals before a route is declared failed
RESIDUAL_RTOL = 1e-9
#: ProxSuite accuracy (absolute, on primal and dual residuals of the scaled problems)
_QP_EPS = 1e-12
#: relative miss of ``J_c a + gamma`` above which an inverse-dynamics motion is refused
_MOTION_RTOL = 1e-8
#: a floor for scales (avoids dividing by zero on all-zero data)
_TINY = 1e-300
_EPS = np.finfo(float).eps
_F64 = np.dtype(np.float64)
#: builds a result named tuple from its fields without the keyword machinery (short path)
_FORWARD_NEW = tuple.__new__
#: box-constrained least-squares miss (relative) above which bounds count as infeasible
_INFEASIBLE_RTOL = 1e-6
#: iteration cap of the tree QPs (redundant closure rows slow the proximal iterations down)
_QP_MAX_ITER = 1000
#: a stalled tree QP is accepted when its residuals are below this, relative to its data
_QP_ACCEPT = 1e-10
#: Pinocchio proximal settings used when the closures are redundant (the acceleration
#: converges in a few iterations; every answer is verified, the multipliers are polished
#: to minimum norm when read). Two iterations at mu = 1e-8 meet RESIDUAL_RTOL with a
#: margin of 250 or more on every redundant robot of the benchmarks and tests (Cassie,
#: the five-bars and ladders closed by welds); a miss continues the solve.
PIN_PROX_MU = 1e-8
PIN_PROX_ITERS = 2
#: iterations of the continued proximal solve when the first ones did not converge
_PIN_PROX_DEEP_ITERS = 500
#: weight of the multipliers in the inverse-dynamics QP objective (relative to forces)
_LAMBDA_WEIGHT = 1e-2
#: steps of the inverse-dynamics active-set search before ProxSuite takes over
_ACTIVE_SET_STEPS = 8

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
class TreeForwardDynamics(NamedTuple):
    """Result of :func:`forward_dynamics_tree` (an immutable named tuple).

    Attributes:
        a: tree acceleration (nv,), Pinocchio convention (free-flyer part: derivative
            of the body-frame velocity).
        raw_multipliers: the multipliers, or a zero-argument callable producing them
            (Pinocchio's LOCAL multipliers converted on first access): read
            :attr:`multipliers`.
        method: the route used ("pinocchio", "qp" or "kkt").
        status: "solved", or a note on how it was solved (redundant rows, fallback,
            a ProxSuite status other than solved whose residuals were verified).
        iterations: solver iterations (0 for a direct solve).
        rank: rank of ``J_c`` assumed by the solve.
        constraint_residual: max-abs of ``J_c a + gamma`` (m/s^2); -1.0 (not
            computed, never NaN) for the "pinocchio" route, which verifies the same
            equation in Pinocchio's LOCAL rows instead.
    """

    a: np.ndarray
    raw_multipliers: np.ndarray | Callable[[], np.ndarray]
    method: str
    status: str
    iterations: int
    rank: int
    constraint_residual: float

    @property
    def multipliers(self) -> np.ndarray:
        """Closure multipliers (n_rows,), ``M a + h = tau + J_c^T multipliers``, rows as in
        :meth:`ClosedLoopModel.constraint_jacobian` (N for point rows, world axes);
        minimum-norm when the closures are redundant."""
        value = self.raw_multipliers
        return value() if callable(value) else value


class TreeInverseDynamics(NamedTuple):
    """Result of :func:`inverse_dynamics_tree` (an immutable named tuple).

    Attributes:
        actuator_forces: ``u`` (n_act,), generalised forces of the actuated joints
            (N for prismatic, N m for revolute), in ``clm.actuated_joints`` order.
        raw_multipliers: the multipliers or a callable producing them: read
            :attr:`multipliers`.
        residual: max-abs of ``M a + h - tau_ext - S^T u - J_c^T multipliers`` (N, N m),
            verified below :data:`RESIDUAL_RTOL` relative to the data.
        method: "qp" or "kkt".
        status: solver status ("solved", ...).
        iterations: solver iterations (0 for a direct solve).
    """

    actuator_forces: np.ndarray
    raw_multipliers: np.ndarray | Callable[[], np.ndarray]
    residual: float
    method: str
    status: str
    iterations: int

    @property
    def multipliers(self) -> np.ndarray:
        """Closure multipliers (n_rows,), same convention as
        :attr:`TreeForwardDynamics.multipliers` (minimum-norm when redundant)."""
        value = self.raw_multipliers
        return value() if callable(value) else value


#: status of a least-squares / minimum-norm inverse solve, by "the rows are redundant"
_ID_STATUS = {True: "solved (redundant rows: minimum-norm multipliers)",
              False: "solved (least squares / minimum norm)"}
#: status strings of the redundant-row Pinocchio route by iteration count
_REDUNDANT_STATUS: dict[int, str] = {}


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

    def __init__(self, clm: ClosedLoopModel) -> None:
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
        #: actuation selection ``S^T`` (nv, n_act): ``tau = selection @ u``
        self.selection = np.zeros((self.nv, self.n_act))
        self.selection[clm.actuated_v, np.arange(self.n_act)] = 1.0
        self._zero_v = np.zeros(self.nv)
        self._lower = np.tril_indices(self.nv, -1)
        self._rank: int | None = None
        self._qps: dict = {}
        self._aux_data = self.model.createData()   # lazy multiplier conversions
        #: a result may convert its multipliers on any thread: the conversions take turns
        self._aux_lock = threading.Lock()
        self._res_out = np.empty(2)
        self._pools: dict[int, pin.ModelPool] = {}
        self._unique: bool | None = None
        self._pin_singular = False       # M structurally singular: Pinocchio refused
        self._rank_rechecked = False
        self._no_rows = (np.zeros((0, self.nv)), np.zeros(0))
        #: Pinocchio's constraint Jacobian (n_rows, nv; LOCAL rows) at the ``q`` of the last
        #: verified ``pinocchio_call`` (integrators reuse it); None before the first one
        self.last_jacobian: np.ndarray | None = None
        self._kkt = np.zeros((self.nv + self.n_rows, self.nv + self.n_rows))
        self._id_matrix = np.zeros((self.nv, self.n_act + self.n_rows))
        self._id_matrix[:, :self.n_act] = self.selection
        self._id_hess = np.diag(np.concatenate([np.ones(self.n_act),
                                                np.full(self.n_rows, _LAMBDA_WEIGHT)]))
        self._id_inv_root_w = 1.0 / np.sqrt(np.diag(self._id_hess))
        self._no_held = np.zeros(0, dtype=bool)
        self._id_box = np.zeros((self.n_act, self.n_act + self.n_rows))
        self._id_box[:, :self.n_act] = np.eye(self.n_act)
        # the fast path of forward_actuated: shapes, the actuated coordinates (a slice when
        # contiguous), and the proximal settings of a verified Pinocchio solve (None until
        # the first verified call, and again when Pinocchio's answers are refused)
        self._shape_q, self._shape_v = (self.model.nq,), (self.nv,)
        self._shape_u = (self.n_act,)
        act = np.asarray(clm.actuated_v, dtype=int)
        self._act_index = slice(int(act[0]), int(act[0]) + act.size) if act.size and \
            np.array_equal(act, np.arange(act[0], act[0] + act.size)) else act
        self._pin_fast = None
        self._tau = np.zeros(self.nv)    # the generalised force of forward_actuated
        self._tau_zero = True
        #: columns of [S^T J^T] kept by the reduced inverse solve (u, independent rows)
        self._id_keep: np.ndarray | None = None

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
        return self.jacobian_from(self.data)

    def jacobian_from(self, data: pin.Data) -> np.ndarray:
        """``J_c`` (n_rows, nv) from ``data`` (a ``pin.Data`` of this model whose joint
        Jacobians and frame placements are up to date)."""
        out = np.empty((self.n_rows, self.nv))
        model = self.model
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

    # -- verification -----------------------------------------------------------------------
    def verify(self, mass: np.ndarray, bias: np.ndarray, tau: np.ndarray,
               jac: np.ndarray, drift: np.ndarray, acc: np.ndarray, lam: np.ndarray,
               route: str) -> tuple[float, float]:
        """Relative residuals of the two equations a forward solution must satisfy.

        ``M a + h - tau - J^T lam`` relative to the largest of ``|M a|``, ``|h - tau|``,
        ``|J^T lam|``, and ``J a + drift`` relative to ``|J| |a|`` and ``|drift|`` (max-abs
        norms). ``jac`` / ``drift`` may be ours (``J_c``, ``gamma``) or Pinocchio's LOCAL ones
        (``J_pin``, ``-primal_rhs``): both equations hold in either row convention.

        Returns:
            (equation-of-motion residual, closure residual), both relative.

        Raises:
            SolverError: either exceeds :data:`RESIDUAL_RTOL` or is not finite; the
                message names the equation and its residual.
        """
        eom, con = forward_residuals(mass, bias, tau, jac, drift, acc, lam, self._res_out)
        if not eom <= RESIDUAL_RTOL:
            raise SolverError(route, "unverified", "equation of motion M a + h = tau + J_c^T "
                              f"lambda missed by {eom:.3e} (relative)")
        if not con <= RESIDUAL_RTOL:
            raise SolverError(route, "unverified", "closure equation J_c a = -gamma missed by "
                              f"{con:.3e} (relative)")
        return eom, con

    def _terms(self, q, v):
        """(M, h, J_c, gamma) at (q, v), ours."""
        jac = self.constraint_jacobian(q)
        gamma = self.constraint_drift(q, v)
        mass = self.mass_matrix(q)
        bias = pin.nonLinearEffects(self.model, self.data, q, v)
        return mass, bias, jac, gamma

    # -- forward dynamics -----------------------------------------------------------------
    def forward(self, q: npt.ArrayLike, v: npt.ArrayLike, tau: npt.ArrayLike,
                method: str = "pinocchio") -> TreeForwardDynamics:
        """Constrained forward dynamics; see :func:`forward_dynamics_tree`."""
        q = _vector(q, self.model.nq, "q")
        v = _vector(v, self.nv, "v")
        tau = _vector(tau, self.nv, "tau")
        if method not in FORWARD_METHODS:
            raise InputError("method", method, f"expected one of {FORWARD_METHODS}")
        return _solve_checked(lambda: self.forward_unchecked(q, v, tau, method),
                              ("q", q), ("v", v), ("tau", tau))

    def forward_unchecked(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray,
                          method: str) -> TreeForwardDynamics:
        """:meth:`forward` without the input checks (contiguous float64 arrays of the right
        sizes, a known method); for batch drivers and integrators."""
        rank = self.closure_rank(q)
        if method == "pinocchio":
            return self._forward_pinocchio(q, v, tau, rank)
        mass, bias, jac, gamma = self._terms(q, v)
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
        self._prox_redundant = pin.ProximalSettings(1e-13, PIN_PROX_MU, PIN_PROX_ITERS)
        self._prox_deep = pin.ProximalSettings(1e-14, PIN_PROX_MU, _PIN_PROX_DEEP_ITERS)
        #: one cheap proximal pass: only the constraint terms of the call are used
        self._prox_probe = pin.ProximalSettings(1e-13, PIN_PROX_MU, 1)
        self._cd_list = list(self.pin_datas)
        self._all_points = all(c[0] for c in self.closure_frames)
        # live views of Pinocchio's data (eigenpy maps the Data members, allocated once)
        data = self.data
        self._v_ddq = data.ddq
        self._v_mass, self._v_nle, self._v_lambda = data.M, data.nle, data.lambda_c
        self._v_rhs = data.primal_rhs_contact[:self.n_rows]
        self._pin_ready = True

    def pinocchio_call(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray,
                       redundant: bool) -> tuple[np.ndarray | None, Any]:
        """One verified ``pin.constraintDynamics`` call; returns (a or None, prox).

        ``a`` is Pinocchio's own buffer (copy it before the next call); Pinocchio's LOCAL
        multipliers are in ``self.data.lambda_c``. ``None`` when the solve is not finite or
        misses one of the equations by more than :data:`RESIDUAL_RTOL` (relative; checked
        with Pinocchio's own ``M``, ``nle``, constraint Jacobian and drift). With
        ``redundant`` the proximal solve (``mu > 0``) is continued (up to
        ``_PIN_PROX_DEEP_ITERS`` iterations) when its first iterations did not converge.
        """
        if not self._pin_ready:
            self._init_pinocchio()
        if self._pin_singular:
            return None, self._prox_exact
        prox = self._prox_redundant if redundant else self._prox_exact
        acc = pin.constraintDynamics(self.model, self.data, q, v, tau, self.pin_models,
                                     self.pin_datas, prox)
        if self._pin_verified(acc, tau):
            if self.n_rows:
                self._pin_fast = prox    # the short path of pinocchio_verified
            return acc, prox
        diag = np.diagonal(self._v_mass)
        if np.min(diag) <= 1e-14 * max(np.max(diag), _TINY):
            # a joint that moves no mass: Pinocchio's factorisation of M cannot hold this
            # model at any state (structural); the exact routes answer from now on
            self._pin_singular = True
            self._pin_fast = None
            return None, prox
        if redundant:
            prox = self._prox_deep
            acc = pin.constraintDynamics(self.model, self.data, q, v, tau, self.pin_models,
                                         self.pin_datas, prox)
            if self._pin_verified(acc, tau):
                return acc, prox
        return None, prox

    def _pin_verified(self, acc, tau) -> bool:
        """Whether Pinocchio's answer ``acc`` meets both equations (see
        :meth:`pinocchio_call`); Pinocchio's constraint Jacobian at the call's ``q`` (LOCAL
        rows, a new array) is left in :attr:`last_jacobian`."""
        if self.n_rows:
            jac = self.last_jacobian = pin.getConstraintsJacobian(
                self.model, self.data, self.pin_models, self.pin_datas)
            target = self._v_rhs           # Pinocchio's J a = primal_rhs (recomputed per call)
        else:
            jac, target = self._no_rows
        eom, con = kkt_residuals(self._v_mass, self._v_nle, tau, jac, target, acc,
                                 self._v_lambda, self._res_out)
        return eom <= RESIDUAL_RTOL and con <= RESIDUAL_RTOL

    def pinocchio_acceleration(self, q: np.ndarray, v: np.ndarray,
                               tau: np.ndarray) -> np.ndarray:
        """Tree acceleration (nv,) only (no multipliers), verified; for integrators; no
        input checks."""
        rank = self.closure_rank(q)
        acc, _ = self.pinocchio_call(q, v, tau, rank < self.n_rows)
        if acc is None:
            return self._forward_pinocchio(q, v, tau, rank).a
        return acc.copy()

    def _pin_to_row_multipliers(self, lam_pin: np.ndarray, data) -> np.ndarray:
        """Convert Pinocchio's LOCAL contact forces into our row convention.

        Point rows: ``lambda = R_c1 lambda_pin`` (``J_c = R_c1 J_pin``); weld rows:
        ``lambda = Jlog6^-T lambda_pin`` (``J_c = Jlog6 J_pin``). ``data`` holds the frame
        placements at the state of the solve.
        """
        out = np.empty(self.n_rows)
        for is_point, rows, f1, f2, _, _ in self.closure_frames:
            if is_point:
                out[rows] = data.oMf[f1].rotation @ lam_pin[rows]
            else:
                jlog = pin.Jlog6(data.oMf[f2].actInv(data.oMf[f1]))
                out[rows] = np.linalg.solve(jlog.T, lam_pin[rows])
        return out

    def _pinocchio_result(self, q, v, tau, acc, iters, rank) -> TreeForwardDynamics:
        """The result of a verified Pinocchio solve (``acc``: Pinocchio's buffer; ``tau``:
        an array this call owns): :meth:`pinocchio_result_of` on copies."""
        return self.pinocchio_result_of(q.copy(), v.copy(), tau.copy(), acc.copy(),
                                        self._v_lambda.copy(), iters, rank)

    def pinocchio_result_of(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray,
                            acc: np.ndarray, lam_pin: np.ndarray, iters: int,
                            rank: int) -> TreeForwardDynamics:
        """The result of a verified Pinocchio solve from arrays the caller owns (kept as
        they are, no copies): ``acc`` (nv,) and Pinocchio's LOCAL multipliers ``lam_pin``.
        The multipliers are computed on access: ``lam_pin`` converted to our rows, or,
        with redundant rows, the minimum-norm ones (the proximal multipliers are
        minimum-norm only up to the conditioning of the regularised system)."""
        if rank == self.n_rows:
            return TreeForwardDynamics(acc, _PinRows(self, q, lam_pin), "pinocchio",
                                       "solved", iters, rank, -1.0)
        status = _REDUNDANT_STATUS.get(iters)
        if status is None:
            status = _REDUNDANT_STATUS[iters] = (
                f"solved (redundant rows: proximal mu={PIN_PROX_MU:g}, {iters} "
                "iterations; minimum-norm multipliers)")
        return TreeForwardDynamics(acc, _MinNormRows(self, q, v, acc, tau), "pinocchio",
                                   status, iters, rank, -1.0)

    def forward_actuated(self, q: npt.ArrayLike, v: npt.ArrayLike,
                         actuator_forces: npt.ArrayLike, tau_ext: npt.ArrayLike | None = None,
                         method: str = "pinocchio") -> TreeForwardDynamics:
        """:func:`forward_dynamics_tree` on this workspace (same arguments after ``clm``).

        The "pinocchio" route of a model whose first call was verified takes a short
        path: one fused input check (float64 arrays of the right shapes pass; anything
        else goes through :func:`~hexapod_pin.core.checks.as_array`), one
        ``pin.constraintDynamics`` call, its verification on Pinocchio's own ``M``,
        ``nle``, constraint Jacobian and drift (one compiled kernel), and the result with
        lazy multipliers. A call that fails the verification (or a non-finite input) takes
        the full route, which retries, falls back or raises.
        """
        nd = np.ndarray
        if not (type(q) is nd and type(v) is nd and q.dtype is _F64 and v.dtype is _F64
                and q.shape == self._shape_q and v.shape == self._shape_v
                and q.flags.c_contiguous and v.flags.c_contiguous):
            q = _vector(q, self.model.nq, "q")
            v = _vector(v, self.nv, "v")
        u = actuator_forces
        if not (type(u) is nd and u.dtype is _F64 and u.shape == self._shape_u):
            u = _vector(u, self.n_act, "actuator_forces")
        # tau = S^T u + tau_ext in this thread's buffer (its other entries kept at zero
        # between calls without tau_ext); a result that keeps tau gets a copy
        tau = self._tau
        if tau_ext is None:
            if not self._tau_zero:
                tau.fill(0.0)
                self._tau_zero = True
            tau[self._act_index] = u
        else:
            tau_ext = _vector(tau_ext, self.nv, "tau_ext")
            tau[:] = tau_ext
            tau[self._act_index] += u
            self._tau_zero = False
        if method == "pinocchio":
            prox = self.pinocchio_verified(q, v, tau)
            if prox is not None:         # the short path: the result with lazy multipliers
                rank = self._rank            # set: the model has a verified call
                if rank == self.n_rows:  # Pinocchio's multipliers, converted when read
                    return _FORWARD_NEW(TreeForwardDynamics, (
                        self._v_ddq.copy(), _PinRows(self, q.copy(), self._v_lambda.copy()),
                        "pinocchio", "solved", prox.iter, rank, -1.0))
                return self.pinocchio_result_of(q.copy(), v.copy(), tau.copy(),
                                                self._v_ddq.copy(), self._v_lambda.copy(),
                                                prox.iter, rank)
        elif method not in FORWARD_METHODS:
            raise InputError("method", method, f"expected one of {FORWARD_METHODS}")
        tau = tau.copy()
        return _solve_checked(lambda: self.forward_unchecked(q, v, tau, method), ("q", q),
                              ("v", v), ("actuator_forces", u), ("tau_ext", tau_ext))

    def pinocchio_verified(self, q: np.ndarray, v: np.ndarray,
                           tau: np.ndarray) -> pin.ProximalSettings | None:
        """One ``pin.constraintDynamics`` call with the settings of the last verified call,
        verified on Pinocchio's own ``M``, ``nle``, constraint Jacobian and drift (one
        compiled kernel). Returns the proximal settings used (the answer is in
        ``self.data.ddq`` / ``self.data.lambda_c``, the constraint Jacobian at ``q`` in
        :attr:`last_jacobian`), or None when the model has no verified call yet or this
        answer fails the verification (no input checks)."""
        prox = self._pin_fast
        if prox is None:
            return None
        model, data, cms, cds = self.model, self.data, self.pin_models, self.pin_datas
        acc = pin.constraintDynamics(model, data, q, v, tau, cms, cds, prox)
        # checked on Pinocchio's own M, nle, J and drift (J a = primal_rhs)
        jac = self.last_jacobian = pin.getConstraintsJacobian(model, data, cms, cds)
        eom, con = kkt_residuals(self._v_mass, self._v_nle, tau, jac, self._v_rhs, acc,
                                 self._v_lambda, self._res_out)
        if eom <= RESIDUAL_RTOL and con <= RESIDUAL_RTOL:
            return prox
        return None

    def _forward_pinocchio(self, q, v, tau, rank) -> TreeForwardDynamics:
        redundant = rank < self.n_rows
        acc, prox = self.pinocchio_call(q, v, tau, redundant)
        if acc is None and not redundant and not self._rank_rechecked:
            # a structural rank found too high at the first call: re-evaluate once
            self._rank_rechecked = True
            new_rank = self.closure_rank(q, force=True)
            if new_rank < rank:
                rank, redundant = new_rank, True
                acc, prox = self.pinocchio_call(q, v, tau, True)
        if acc is not None:
            if self.n_rows:
                self._pin_fast = self._prox_redundant if redundant else self._prox_exact
            return self._pinocchio_result(q, v, tau, acc, prox.iter, rank)
        # Pinocchio's factorisation cannot hold this problem (e.g. a zero pivot of M from a
        # massless link): the exact KKT route answers, and the status says so
        mass, bias, jac, gamma = self._terms(q, v)
        res = self._forward_kkt(mass, bias, jac, gamma, tau, rank)
        return TreeForwardDynamics(res.a, res.multipliers, "pinocchio",
                                   "pin.constraintDynamics unverified; solved by the KKT route"
                                   + (" (redundant rows: minimum-norm multipliers)"
                                      if res.rank < self.n_rows else ""),
                                   0, res.rank, res.constraint_residual)

    def _forward_kkt(self, mass, bias, jac, gamma, tau, rank) -> TreeForwardDynamics:
        nv, nr = self.nv, self.n_rows
        rhs = np.empty(nv + nr)
        rhs[:nv] = tau - bias
        rhs[nv:] = -gamma
        sol, status = None, "solved"
        if rank == nr:
            kkt = self._kkt_matrix(mass, jac)
            try:
                sol = np.linalg.solve(kkt, rhs)
            except np.linalg.LinAlgError:
                sol = None
            if sol is not None:
                try:
                    self.verify(mass, bias, tau, jac, gamma, sol[:nv], -sol[nv:], "kkt")
                except SolverError:
                    sol = None
            if sol is None:
                rank = self._ensure_rank_from(jac)
        if sol is None:
            acc, lam = self._nullspace_forward(mass, bias, jac, gamma, tau)
            status = "solved (redundant rows: minimum-norm multipliers)" if rank < nr \
                else "solved (null-space route)"
        else:
            acc, lam = sol[:nv], -sol[nv:]
        self.verify(mass, bias, tau, jac, gamma, acc, lam, "kkt")
        return TreeForwardDynamics(acc, lam, "kkt", status, 0, rank,
                                   max_abs(jac @ acc + gamma))

    def _kkt_matrix(self, mass, jac) -> np.ndarray:
        nv = self.nv
        kkt = self._kkt
        kkt[:nv, :nv] = mass
        kkt[:nv, nv:] = jac.T
        kkt[nv:, :nv] = jac
        return kkt

    def _nullspace_forward(self, mass, bias, jac, gamma, tau):
        """Exact solve for any rank: ``a = a_p + N z`` with ``N`` an orthonormal basis of
        ``ker J_c`` (SVD), ``(N^T M N) z = N^T (tau - h - M a_p)``; minimum-norm multipliers
        ``lambda = (J_c^T)^+ (M a + h - tau)``."""
        if self.n_rows == 0:
            return np.linalg.solve(mass, tau - bias), np.zeros(0)
        u_mat, sv, vt = np.linalg.svd(jac)
        tol = max(RANK_RTOL * sv[0], max(jac.shape) * _EPS) if sv.size else 0.0
        r = int(np.sum(sv > tol))
        a_p = vt[:r].T @ ((u_mat[:, :r].T @ -gamma) / sv[:r])
        basis = vt[r:].T
        reduced = basis.T @ mass @ basis
        try:
            z = np.linalg.solve(reduced, basis.T @ (tau - bias - mass @ a_p))
        except np.linalg.LinAlgError:
            raise SolverError("null-space forward dynamics", "singular",
                              "N^T M N is singular: the mass matrix is not positive on the "
                              "motions the closures allow") from None
        acc = a_p + basis @ z
        force = mass @ acc + bias - tau
        lam = u_mat[:, :r] @ ((vt[:r] @ force) / sv[:r])
        return acc, lam

    def _ensure_rank_from(self, jac: np.ndarray) -> int:
        self._rank = int(np.linalg.matrix_rank(jac))
        return self._rank

    def _qp_solve(self, key, n_in, args, warm=None) -> proxsuite.proxqp.dense.QP:
        """Initialise (first call) or update the cached ProxSuite problem ``key``; solve,
        warm-started from ``warm = (x, y, z)`` when given. The data must be scaled to
        order one (tolerance ``_QP_EPS`` absolute)."""
        qp = self._qps.get(key)
        if qp is None:
            hess, _, amat = args[0], args[1], args[2]
            qp = proxsuite.proxqp.dense.QP(hess.shape[0], amat.shape[0], n_in)
            qp.settings.eps_abs = _QP_EPS
            qp.settings.eps_rel = 0.0
            qp.settings.max_iter = _QP_MAX_ITER
            qp.settings.verbose = False
            qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START
            qp.init(*args)
            self._qps[key] = qp
        else:
            qp.update(*args, update_preconditioner=True)
        if warm is None:
            qp.solve()
        else:
            qp.solve(*warm)
        return qp

    def _forward_qp(self, mass, bias, jac, gamma, tau, rank) -> TreeForwardDynamics:
        """Gauss principle as a ProxSuite QP, reformulated so that it is well posed on every
        class: ``min 1/2 a^T H a + g^T a  s.t.  D J_c a = -D gamma`` with the augmented
        Hessian ``H = M + rho J_c^T J_c`` (same minimiser on the feasible set; positive
        definite when ``M`` is only positive on ``ker J_c``: massless links), rows of
        ``J_c`` normalised by ``D``, the objective divided by its scale; warm-started from
        the direct (KKT) solution."""
        direct = self._forward_kkt(mass, bias, jac, gamma, tau, rank)
        rank = direct.rank
        nr = self.n_rows
        rows: slice | np.ndarray = slice(None)
        if rank < nr:
            # the QP keeps independent rows only (a pivoted QR of J_c^T): same feasible set
            # for a consistent drift, and the equality constraints get full row rank
            _, _, piv = scipy.linalg.qr(jac.T, pivoting=True, mode="economic")
            rows = np.sort(piv[:rank])
        jac_q, gamma_q = jac[rows], gamma[rows]
        n_eq = jac_q.shape[0]
        scale_m = max(max_abs(np.diag(mass)), _TINY)
        if n_eq:
            norms = np.sqrt(np.einsum("ij,ij->i", jac_q, jac_q))
            dinv = 1.0 / np.maximum(norms, _TINY)
            jac_s = jac_q * dinv[:, None]
            rho = scale_m
            hess = (mass + rho * (jac_s.T @ jac_s)) / scale_m
            grad = (bias - tau + rho * (jac_s.T @ (gamma_q * dinv))) / scale_m
            b = -gamma_q * dinv
            # multipliers of the kept rows giving the direct generalised force
            lam_q, *_ = np.linalg.lstsq(jac_q.T, jac.T @ direct.multipliers, rcond=None)
        else:
            jac_s, dinv, hess, grad, b = jac_q, np.ones(0), mass / scale_m, \
                (bias - tau) / scale_m, np.zeros(0)
            lam_q = np.zeros(0)
        # ProxSuite: H x + g + A^T y = 0 with A = D J_c  =>  lambda = -scale_m D y
        y0 = -lam_q / (scale_m * dinv) if n_eq else np.zeros(0)
        qp = self._qp_solve(("fd", n_eq), 0, (hess, grad, jac_s, b, None, None, None),
                            warm=(direct.a, y0, None))
        info = qp.results.info
        status = QP_STATUS.get(info.status, str(info.status))
        acc = qp.results.x.copy()
        lam = np.zeros(nr)
        if n_eq:
            lam[rows] = -qp.results.y * scale_m * dinv
        try:
            self.verify(mass, bias, tau, jac, gamma, acc, lam, "ProxSuite (forward dynamics QP)")
        except SolverError as exc:
            raise SolverError("ProxSuite (forward dynamics QP)", status,
                              f"{exc}; primal residual {info.pri_res:.3e}, dual residual "
                              f"{info.dua_res:.3e}") from None
        if rank < nr:
            lam = direct.multipliers            # same generalised force; minimum norm
            status = f"{status} (redundant rows: minimum-norm multipliers)"
        elif status != "solved":
            status = f"{status} (residuals verified)"
        return TreeForwardDynamics(acc, lam, "qp", status, int(info.iter), rank,
                                   max_abs(jac @ acc + gamma))

    # -- inverse dynamics -------------------------------------------------------------------
    def inverse(self, q: npt.ArrayLike, v: npt.ArrayLike, a: npt.ArrayLike,
                tau_ext: npt.ArrayLike | None = None, bounds: npt.ArrayLike | None = None,
                method: str = "qp") -> TreeInverseDynamics:
        """Closed-loop inverse dynamics; see :func:`inverse_dynamics_tree`."""
        q = _vector(q, self.model.nq, "q")
        v = _vector(v, self.nv, "v")
        a = _vector(a, self.nv, "a")
        tau_ext = self._zero_v if tau_ext is None else _vector(tau_ext, self.nv, "tau_ext")
        bounds = self.check_bounds(bounds)
        if method not in INVERSE_METHODS:
            raise InputError("method", method, f"expected one of {INVERSE_METHODS}")
        return _solve_checked(lambda: self.inverse_unchecked(q, v, a, tau_ext, bounds, method),
                              ("q", q), ("v", v), ("a", a), ("tau_ext", tau_ext))

    def inverse_unchecked(self, q: np.ndarray, v: np.ndarray, a: np.ndarray,
                          tau_ext: np.ndarray, bounds: np.ndarray | None,
                          method: str) -> TreeInverseDynamics:
        """:meth:`inverse` without the input checks (``bounds`` None or (n_act,) array)."""
        force = pin.rnea(self.model, self.data, q, v, a)
        return self.inverse_from_force(q, v, a, force, tau_ext, bounds, method)

    def inverse_from_force(self, q: np.ndarray, v: np.ndarray, a: np.ndarray,
                           force: np.ndarray, tau_ext: np.ndarray, bounds: np.ndarray | None,
                           method: str) -> TreeInverseDynamics:
        """Inverse dynamics given ``force = M a + h`` (nv,) (e.g. from a pooled
        ``rneaInParallel``); no input checks.

        Works in Pinocchio's LOCAL constraint rows: one ``pin.constraintDynamics`` call
        with ``tau = force`` evaluates ``J_pin`` and the drift (its acceleration is not
        used), ``a`` is checked against ``J_pin a = -drift`` (raises SolverError when it
        breaks the closures), ``[S J_pin^T] (u, lambda_pin) = force - tau_ext`` is solved
        and verified, and ``lambda_pin`` is converted to our rows on access (``u`` and
        the minimum norm do not depend on the row convention: the rows differ by
        rotations, and by ``Jlog6 = I`` for a weld at an assembled configuration).
        """
        rank = self.closure_rank(q)
        rhs = force - tau_ext
        if self.n_rows:
            if not self._pin_ready:
                self._init_pinocchio()
            pin.constraintDynamics(self.model, self.data, q, v, force, self.pin_models,
                                   self.pin_datas, self._prox_probe)
            jac = pin.getConstraintsJacobian(self.model, self.data, self.pin_models,
                                             self.pin_datas)
            # Pinocchio's J a = primal_rhs (its drift with the sign flipped)
            miss = linear_residual(jac, a, self._v_rhs, self._res_out)
            if not miss <= _MOTION_RTOL:
                raise SolverError("closed-loop inverse dynamics", "inconsistent motion",
                                  f"closure equation J_c a = -gamma missed by {miss:.3e} "
                                  "(relative): the acceleration does not keep the closures")
        else:
            jac = self._no_rows[0]
        return self._inverse_solve(jac, rhs, bounds, method, rank, q)

    def model_pool(self, threads: int) -> pin.ModelPool:
        """A ``pin.ModelPool`` of this model with ``threads`` datas (cached)."""
        pool = self._pools.get(threads)
        if pool is None:
            pool = self._pools[threads] = pin.ModelPool(self.model, threads)
        return pool

    def check_bounds(self, bounds: npt.ArrayLike | None) -> np.ndarray | None:
        """Actuator bounds as an (n_act,) array (None: unbounded); raises InputError."""
        if bounds is None:
            return None
        if isinstance(bounds, (int, float)) and not isinstance(bounds, bool):
            if not bounds > 0.0:
                raise InputError("bounds", bounds, "must be positive")
            return None if bounds == float("inf") else np.full(self.n_act, float(bounds))
        try:
            arr = np.broadcast_to(np.asarray(bounds, dtype=float), (self.n_act,)).copy() \
                if np.ndim(bounds) == 0 else np.asarray(bounds, dtype=float)
        except (TypeError, ValueError):
            raise InputError("bounds", bounds, "not numeric") from None
        if arr.shape != (self.n_act,) or np.any(np.isnan(arr)) or np.any(arr <= 0.0):
            raise InputError("bounds", bounds,
                             f"expected a positive scalar or ({self.n_act},) positive values")
        return None if np.all(np.isinf(arr)) else arr

    def _inverse_solve(self, jac, rhs, bounds, method, rank, q) -> TreeInverseDynamics:
        mat = self._id_matrix
        mat[:, self.n_act:] = jac.T
        if method == "kkt":
            sol, status, reduced = self._inverse_kkt(mat, rhs, rank)
            iters = 0
        else:
            sol, status, iters, reduced = self._inverse_qp(mat, rhs, bounds, rank)
        u = sol[:self.n_act]
        if bounds is not None and not within_bounds(u, bounds, RESIDUAL_RTOL):
            if self._unique_forces(mat) or \
                    self._bounds_infeasible(mat, rhs, bounds, sol) is not None:
                raise ActuatorSaturationError(u.copy(), bounds)
            raise SolverError(method, "bounds", "the minimum-norm actuator forces exceed the "
                              "bounds but other forces within them meet the equation of "
                              "motion (redundant actuation): use method='qp'")
        residual = self._verify_inverse(mat, sol, rhs, method)
        lam = sol[self.n_act:].copy()
        if self.n_rows:
            # multipliers in our rows on access (minimum-norm ones from the generalised
            # force J^T lambda when the solve kept the independent rows only)
            lam = _PinRows(self, q.copy(), lam, jac.copy() if reduced else None)
        return TreeInverseDynamics(u.copy(), lam, residual, method, status, iters)

    def _verify_inverse(self, mat, sol, rhs, route: str) -> float:
        """Max-abs residual of ``S^T u + J_c^T lambda = M a + h - tau_ext``; SolverError when
        it exceeds :data:`RESIDUAL_RTOL` relative to the data."""
        out = self._res_out
        linear_residual(mat, sol, rhs, out)
        if not out[1] <= RESIDUAL_RTOL:
            raise SolverError(route, "unverified", "equation of motion S^T u + J_c^T lambda = "
                              f"M a + h - tau_ext missed by {out[1]:.3e} (relative)")
        return float(out[0])

    def _inverse_kkt(self, mat, rhs, rank):
        """``[S^T J^T] x = rhs`` (``A x = rhs``), the minimum-norm solution; returns
        ``(x, status, reduced)``.

        One compiled solve, chosen by the structure: LU when ``A`` is square and the rows
        independent; ``x = A^T (A A^T)^-1 rhs`` when ``A`` is wide (Gram matrix); when the
        rows are redundant and ``A`` determines ``u``, the least-squares solve of ``A``
        restricted to ``u`` and the independent rows (normal equations; ``reduced``: the
        multipliers then give the right generalised force but are made minimum-norm on
        access). SVD least squares when none of them reproduces ``rhs`` to
        :data:`RESIDUAL_RTOL` (rank-deficient or ill-conditioned ``A``). The caller
        verifies the answer on the full system."""
        nv, ncol = mat.shape
        sol = np.empty(ncol)
        out = self._res_out
        redundant = rank < self.n_rows
        try:
            if not redundant and ncol == nv:
                if square_solve(mat, rhs, sol, out) <= RESIDUAL_RTOL:
                    return sol, "solved", False
            elif redundant and self._unique_forces(mat):
                keep = self._id_keep
                if keep is None:
                    rows = independent_rows(mat[:, self.n_act:].T)
                    keep = self._id_keep = np.concatenate([np.arange(self.n_act),
                                                           self.n_act + rows])
                sub = np.ascontiguousarray(mat[:, keep])
                part = np.empty(keep.size)
                if normal_solve(sub, rhs, part, out) <= RESIDUAL_RTOL:
                    sol[:] = 0.0
                    sol[keep] = part
                    return sol, _ID_STATUS[True], True
            elif ncol > nv and minimum_norm_solve(mat, rhs, sol, out) <= RESIDUAL_RTOL:
                return sol, _ID_STATUS[redundant], False
        except np.linalg.LinAlgError:
            pass
        sol, *_ = np.linalg.lstsq(mat, rhs, rcond=None)
        return sol, _ID_STATUS[redundant], False

    def _inverse_qp(self, mat, rhs, bounds, rank):
        """Bounded ID: ``min 1/2 |u|^2 + 1/2 w |lambda|^2`` (``w = _LAMBDA_WEIGHT``) subject
        to the equation of motion ``mat x = rhs`` and ``|u| <= bounds``; returns ``(x,
        status, iterations, reduced)``.

        Every answer is the QP's minimiser by an exact certificate, or ProxSuite's:

        * the equation determines ``u``: the direct solution (multipliers minimum-norm)
          when it keeps the bounds; no point keeps them when it does not
          (ActuatorSaturationError);
        * redundant actuation: the weighted minimum-norm solution of the equation
          (:meth:`_weighted_minimum_norm`) minimises the objective on it, so when it keeps
          the bounds it is the minimiser (KKT conditions with zero bound multipliers;
          status "solved", 0 iterations); else the active-set search of
          :meth:`_inverse_active_set` (KKT-certified; status "solved (active set)", its
          steps as iterations), and when that stops without a certificate, ProxSuite
          (:meth:`_inverse_proxsuite`).
        """
        if self._unique_forces(mat):
            direct, _, reduced = self._inverse_kkt(mat, rhs, rank)
            if bounds is None or within_bounds(direct[:self.n_act], bounds, 0.0):
                return direct, "solved", 0, reduced
            raise ActuatorSaturationError(direct[:self.n_act].copy(), bounds)
        direct = self._weighted_minimum_norm(mat, rhs)
        if not all_finite(direct):
            raise SolverError("inverse dynamics QP", "not finite",
                              "the weighted minimum-norm solution is not finite")
        if bounds is None or within_bounds(direct[:self.n_act], bounds, 0.0):
            return direct, "solved", 0, False
        found = self._inverse_active_set(mat, rhs, bounds, direct)
        if found is not None:
            return found[0], "solved (active set)", found[1], False
        return self._inverse_proxsuite(mat, rhs, bounds, direct)

    def _weighted_minimum_norm(self, mat, rhs, held=None, held_u=None) -> np.ndarray:
        """The minimiser of the QP's objective ``1/2 x^T H x`` (``H = diag(1, w)``) subject
        to ``mat x = rhs``, with the actuators of the mask ``held`` (n_act,) fixed at
        ``held_u`` (none when ``held`` is None):
        :func:`~hexapod_pin.core.linear_kernels.weighted_minimum_norm_solve` (one compiled
        Gram solve, SVD least squares when that misses :data:`RESIDUAL_RTOL`). Not
        verified here: the callers verify the answer on the full system."""
        if held is None:
            held = held_u = self._no_held
        x = np.empty(mat.shape[1])
        weighted_minimum_norm_solve(mat, rhs, self._id_inv_root_w, held, held_u, x,
                                    np.empty(mat.shape[0]), self._res_out, RESIDUAL_RTOL)
        return x

    def _inverse_active_set(self, mat, rhs, bounds, x):
        """The bounded minimiser by the compiled active-set search
        :func:`~hexapod_pin.core.linear_kernels.box_active_set_solve` from the weighted
        minimiser ``x`` (which breaks a bound): ``(x, steps)``, certified by the KKT
        conditions of the QP, or None when
        the search stops without a certificate (after ``_ACTIVE_SET_STEPS`` steps, or on a
        held set that the Gram solve cannot meet)."""
        x = x.copy()
        steps = box_active_set_solve(mat, rhs, self._id_inv_root_w, bounds, x,
                                     np.empty(mat.shape[0]), self._res_out, RESIDUAL_RTOL,
                                     _ACTIVE_SET_STEPS)
        return (x, steps) if steps else None

    def _inverse_proxsuite(self, mat, rhs, bounds, direct):
        """The bounded ID QP by ProxSuite: rows scaled by their norms, forces by their
        scale; warm-started from the weighted minimiser ``direct`` clipped to the bounds,
        polished on its active set (:meth:`_polish_inverse`) and verified; returns ``(x,
        status, iterations, reduced)``. A verification failure raises
        ActuatorSaturationError when box-constrained least squares proves the bounds
        infeasible (needed forces: ``direct``'s), else SolverError."""
        n_act = self.n_act
        f_scale = max(max_abs(rhs), max_abs(direct), _TINY)
        norms = np.sqrt(np.einsum("ij,ij->i", mat, mat))
        dinv = 1.0 / np.maximum(norms, _TINY)
        mat_s = mat * dinv[:, None]
        b = rhs * dinv / f_scale
        x0 = direct / f_scale
        x0[:n_act] = np.clip(x0[:n_act], -bounds / f_scale, bounds / f_scale)
        qp = self._qp_solve("id_bounded", n_act,
                            (self._id_hess, np.zeros(x0.size), mat_s, b, self._id_box,
                             -bounds / f_scale, bounds / f_scale), warm=(x0, None, None))
        info = qp.results.info
        status = QP_STATUS.get(info.status, str(info.status))
        sol = self._polish_inverse(mat, rhs, qp.results.x * f_scale, bounds)
        try:
            self._verify_inverse(mat, sol, rhs, "ProxSuite (inverse dynamics QP)")
            if not within_bounds(sol[:n_act], bounds, RESIDUAL_RTOL):
                raise SolverError("ProxSuite (inverse dynamics QP)", status, "bounds missed")
        except SolverError as exc:
            needed = self._bounds_infeasible(mat, rhs, bounds, direct)
            if needed is not None:
                raise ActuatorSaturationError(needed, bounds) from None
            raise SolverError("ProxSuite (inverse dynamics QP)", status,
                              f"{exc}; primal residual {info.pri_res:.3e}") from None
        if status != "solved":
            status = f"{status} (residuals verified)"
        return sol, status, int(info.iter), False

    def _unique_forces(self, mat) -> bool:
        """Whether ``[S^T J_c^T] x = rhs`` determines ``u`` (no null direction of the matrix
        moves ``u``); evaluated at the first call and assumed structural afterwards."""
        if self._unique is None:
            _, sv, vt = np.linalg.svd(mat)
            tol = max(RANK_RTOL * sv[0], max(mat.shape) * _EPS) if sv.size else 0.0
            null = vt[int(np.sum(sv > tol)):, :self.n_act]
            self._unique = bool(null.size == 0 or max_abs(null) <= 1e-9)
        return self._unique

    def _polish_inverse(self, mat, rhs, sol, bounds) -> np.ndarray:
        """Exact solution on the active set of a QP answer ``sol``: the actuators at a
        bound held there, the rest of ``x = (u, lambda)`` the weighted minimiser of
        :meth:`_weighted_minimum_norm`. Returns ``sol`` unchanged when the polished point
        leaves the bounds."""
        u = sol[:self.n_act]
        held = np.abs(u) >= bounds * (1.0 - 1e-7)
        out = self._weighted_minimum_norm(mat, rhs, held, np.sign(u) * bounds)
        return out if within_bounds(out[:self.n_act], bounds, RESIDUAL_RTOL) else sol

    def _bounds_infeasible(self, mat, rhs, bounds, direct) -> np.ndarray | None:
        """The needed forces when no ``|u| <= bounds`` satisfies the equation of motion, else
        None. Certified by a box-constrained least-squares problem (``scipy.optimize.
        lsq_linear``): the bounds are infeasible when its smallest residual exceeds
        ``_INFEASIBLE_RTOL`` relative to the data. The needed forces are the direct
        (minimum-norm) ones."""
        lower = np.concatenate([-bounds, np.full(self.n_rows, -np.inf)])
        upper = np.concatenate([bounds, np.full(self.n_rows, np.inf)])
        fit = scipy.optimize.lsq_linear(mat, rhs, bounds=(lower, upper), method="bvls",
                                        tol=1e-14)
        miss = max_abs(mat @ fit.x - rhs)
        if miss > _INFEASIBLE_RTOL * max(max_abs(rhs), _TINY):
            return direct[:self.n_act].copy()
        return None

    # -- joint reaction wrenches ------------------------------------------------------------
    def joint_wrenches(self, q: npt.ArrayLike, v: npt.ArrayLike, a: npt.ArrayLike,
                       multipliers: np.ndarray, fext: Mapping[int, pin.Force] | None = None
                       ) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """Spatial force transmitted by every joint of the tree.

        Runs ``pin.rnea`` with the closure forces (from ``multipliers``) and ``fext``
        applied as external forces. Pinocchio's ``data.f[j]`` is then the spatial force
        that the parent body exerts on the child body of joint ``j`` through the joint,
        expressed in the joint's LOCAL frame at the joint origin: ``(f, m)`` (N, N m).
        Its projection on the joint's motion subspace is the joint's generalised
        force (the actuator force for an actuated joint, ~0 for a passive one).

        Args:
            q: tree configuration (nq,).
            v: tree velocity (nv,).
            a: tree acceleration (nv,).
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


#: per thread: model -> its workspace (a workspace holds Pinocchio data and ProxSuite
#: problems that every call mutates: one per thread makes the generic routes thread-safe)
def dynamics_of(clm: ClosedLoopModel) -> ClosedLoopDynamics:
    """The :class:`ClosedLoopDynamics` workspace of ``clm`` for the calling thread (created
    once per model and thread, kept in ``clm.workspaces``: collected with the model).

    Raises:
        InputError: ``clm`` is not a :class:`ClosedLoopModel`.
    """
    key = ("dynamics", threading.get_ident())
    try:
        return clm.workspaces[key]
    except KeyError:
        dyn = clm.workspaces[key] = ClosedLoopDynamics(clm)
        return dyn
    except AttributeError:
        raise InputError("clm", clm, "expected a ClosedLoopModel") from None


def forward_dynamics_tree(clm: ClosedLoopModel, q: npt.ArrayLike, v: npt.ArrayLike,
                          actuator_forces: npt.ArrayLike, tau_ext: npt.ArrayLike | None = None,
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
        method: "pinocchio" (``pin.constraintDynamics``, checked on Pinocchio's own
            ``M``, ``nle``, constraint Jacobian and drift; when the closures are
            redundant: proximal, mu = 1e-8, 2 iterations, continued up to 500 when not
            converged, and the multipliers polished to minimum norm by least squares;
            when Pinocchio's answer is refused, the "kkt" route answers and the status
            says so), "qp" (Gauss principle ``min 1/2 (a - a_free)^T M (a - a_free)``
            s.t. ``J_c a = -gamma`` as a ProxSuite dense QP: augmented Hessian
            ``M + rho J_c^T J_c``, independent rows only, rows normalised, objective
            scaled, warm-started from the "kkt" solution; success judged from the
            verified residuals, the status reported as ProxSuite gives it), or "kkt"
            (numpy solve of the KKT system; the exact null-space solve with
            minimum-norm multipliers when the rows are redundant or the system
            singular).

    Returns:
        :class:`TreeForwardDynamics`.

    Raises:
        InputError: bad shapes, NaN / inf, unknown method.
        SolverError: the answer misses an equation (e.g. ``gamma`` outside the range of
            ``J_c``, a mass matrix not positive on the closures' null space); the
            message names the equation and its relative residual.
    """
    return dynamics_of(clm).forward_actuated(q, v, actuator_forces, tau_ext, method)


def inverse_dynamics_tree(clm: ClosedLoopModel, q: npt.ArrayLike, v: npt.ArrayLike,
                          a: npt.ArrayLike, tau_ext: npt.ArrayLike | None = None,
                          bounds: npt.ArrayLike | None = None,
                          method: str = "qp") -> TreeInverseDynamics:
    """Closed-loop inverse dynamics: actuator forces that produce a tree motion.

    Solves ``M a + h - tau_ext = S^T u + J_c^T lambda`` for the actuator forces ``u``
    and the closure multipliers ``lambda``. ``a`` must keep the closures
    (``J_c a = -gamma``), e.g. from :meth:`ClosedLoopModel.complete_acceleration`.

    Args:
        clm: the closed-loop model.
        q: tree configuration (nq,), Pinocchio conventions, closures assembled.
        v: tree velocity (nv,), consistent with the closures.
        a: tree acceleration (nv,), consistent with the closures.
        tau_ext: generalised external force on the tree (nv,) (N, N m); default zero.
        bounds: ``abs(u) <= bounds`` (scalar or (n_act,), N or N m); None (or inf): none.
        method: "qp" (minimise ``1/2 |u|^2 + 1/2 w |lambda|^2``, ``w = 1e-2``, subject
            to the equation of motion and the box bounds: when the equation determines
            ``u`` the direct minimum-norm solution is the minimiser (or proves the
            bounds infeasible); otherwise the weighted minimum-norm solution when it
            keeps the bounds, else an active-set search certified by the KKT
            conditions, else a ProxSuite dense QP, scaled, warm-started from the
            clipped weighted minimum-norm solution and polished on its active set) or
            "kkt" (the linear system ``[S^T J_c^T] [u; lambda] = rhs``: one LU solve
            when square, least squares / minimum norm otherwise). Both agree to 1e-10
            when no bound is active and the equation determines ``u``. Solved in
            Pinocchio's constraint rows (the multipliers are converted to ours on
            access).

    Returns:
        :class:`TreeInverseDynamics`.

    Raises:
        ActuatorSaturationError: no ``abs(u) <= bounds`` meets the equation of motion
            (certified by the structure or by box-constrained least squares); carries
            the needed (unbounded, minimum-norm) forces. No clipped answer is returned.
        InputError: bad shapes, NaN / inf, non-positive bounds, unknown method.
        SolverError: ``a`` does not keep the closures, or the answer misses the
            equation of motion (the message names it and its relative residual).
    """
    return dynamics_of(clm).inverse(q, v, a, tau_ext, bounds, method)


# --------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------
def independent_rows(jac: np.ndarray, rtol: float = 1e-8) -> np.ndarray:
    """Rows of ``jac`` kept by a column-pivoted QR of ``jac^T`` up to its numerical rank
    (singular values above ``rtol`` times the largest), sorted: rows dependent on the
    others, exactly or nearly, are left out so that the kept rows are well conditioned."""
    if jac.shape[0] == 0:
        return np.arange(0)
    sv = np.linalg.svd(jac, compute_uv=False)
    rank = int(np.sum(sv > rtol * sv[0]))
    _, _, piv = scipy.linalg.qr(jac.T, pivoting=True, mode="economic")
    return np.sort(piv[:rank])


def _vector(value, size: int, name: str) -> np.ndarray:
    """``value`` when it is already a contiguous float64 (size,) array (the cheap path:
    finiteness is left to the verified solve, see :func:`_solve_checked`), else
    :func:`~hexapod_pin.core.checks.as_array` (converts or raises InputError)."""
    if type(value) is np.ndarray and value.dtype == np.float64 and value.shape == (size,) \
            and value.flags.c_contiguous:
        return value
    return as_array(value, (size,), name)


def _solve_checked(solve, *inputs):
    """``solve()``, re-validating the named ``inputs`` (pairs of name and array) when it
    raises SolverError: a NaN / inf input gives InputError naming it (the solves run on
    unchecked arrays and their verification rejects non-finite answers)."""
    try:
        return solve()
    except SolverError:
        for name, value in inputs:
            if value is not None and not all_finite(value):
                as_array(value, value.shape, name)
        raise


class _PinRows:
    """Our row multipliers from Pinocchio's LOCAL ones ``lam_pin`` at ``q``, computed on the
    first call (on the workspace's auxiliary data, under its lock: a result may be read
    on any thread). With ``jac`` (Pinocchio's constraint Jacobian at ``q``), ``lam_pin``
    is first replaced by the minimum-norm multipliers of the same generalised force,
    ``(J^T)^+ J^T lam_pin`` (the rows differ from ours by rotations: the same minimum)."""

    __slots__ = ("dyn", "jac", "lam_pin", "q", "value")

    def __init__(self, dyn: ClosedLoopDynamics, q: np.ndarray, lam_pin: np.ndarray,
                 jac: np.ndarray | None = None):
        self.dyn, self.q, self.lam_pin, self.jac = dyn, q, lam_pin, jac
        self.value: np.ndarray | None = None

    def __call__(self) -> np.ndarray:
        if self.value is None:
            dyn, lam = self.dyn, self.lam_pin
            if self.jac is not None:
                lam, *_ = np.linalg.lstsq(self.jac.T, self.jac.T @ lam, rcond=None)
            with dyn._aux_lock:
                pin.framesForwardKinematics(dyn.model, dyn._aux_data, self.q)
                self.value = dyn._pin_to_row_multipliers(lam, dyn._aux_data)
        return self.value


class _MinNormRows:
    """Minimum-norm multipliers in our rows, ``lambda = (J_c^T)^+ (M a + h - tau)`` at
    ``(q, v)``, computed on the first call from a fresh ``crba`` / ``nonLinearEffects`` /
    ``J_c`` on the workspace's auxiliary data (under its lock)."""

    __slots__ = ("acc", "dyn", "q", "tau", "v", "value")

    def __init__(self, dyn: ClosedLoopDynamics, q: np.ndarray, v: np.ndarray,
                 acc: np.ndarray, tau: np.ndarray):
        self.dyn, self.q, self.v, self.acc, self.tau = dyn, q, v, acc, tau
        self.value: np.ndarray | None = None

    def __call__(self) -> np.ndarray:
        if self.value is None:
            dyn, q = self.dyn, self.q
            model, aux = dyn.model, dyn._aux_data
            with dyn._aux_lock:
                mass = pin.crba(model, aux, q)
                mass = np.triu(mass) + np.triu(mass, 1).T
                force = mass @ self.acc + pin.nonLinearEffects(model, aux, q, self.v) - self.tau
                pin.computeJointJacobians(model, aux, q)
                pin.updateFramePlacements(model, aux)
                jac = dyn.jacobian_from(aux)
            self.value, *_ = np.linalg.lstsq(jac.T, force, rcond=None)
        return self.value

"""Closed-loop inverse dynamics on the tree: the actuator forces and closure multipliers
that produce a given closure-consistent motion.

Solves ``[S^T J^T] (u, lambda) = M a + h - tau_ext`` in Pinocchio's LOCAL constraint rows
(the multipliers are converted to ours on access; ``u`` and the minimum norm do not depend
on the row convention), by one of two routes:

* "kkt": the linear system by its structure (LU when square, the Gram matrix when wide,
  normal equations on ``u`` and the independent rows when the rows are redundant and
  ``u`` determined; SVD least squares when those miss the verification);
* "qp": ``min 1/2 |u|^2 + 1/2 w |lambda|^2`` subject to the equation and ``|u| <= bounds``,
  answered by an exact certificate where one exists (direct or weighted minimum-norm
  solution, compiled active-set search) and by a scaled ProxSuite QP otherwise.

Every answer is verified (``S^T u + J^T lambda = M a + h - tau_ext`` to
:data:`~hexapod_pin.core.dynamics_common.RESIDUAL_RTOL` relative) before it is returned;
infeasible bounds raise :class:`~hexapod_pin.errors.ActuatorSaturationError` only when
certified. The public entry point is :func:`hexapod_pin.core.dynamics.inverse_dynamics_tree`;
this module holds the routes, on a :class:`InverseDynamicsRoutes` object that each
:class:`~hexapod_pin.core.dynamics.ClosedLoopDynamics` workspace owns.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import scipy.optimize

from ..errors import ActuatorSaturationError, InputError, SolverError
from .checks import max_abs, solve_checked, vector
from .closed_loop import RANK_RTOL
from .compiled import all_finite
from .dynamics_common import (
    QP_STATUS,
    RESIDUAL_RTOL,
    TINY,
    TreeInverseDynamics,
    cached_qp,
    independent_rows,
)
from .linear_kernels import (
    box_active_set_solve,
    linear_residual,
    minimum_norm_solve,
    normal_solve,
    square_solve,
    weighted_minimum_norm_solve,
    within_bounds,
)

INVERSE_METHODS = ("qp", "kkt")

#: relative miss of ``J_c a + gamma`` above which an inverse-dynamics motion is refused
_MOTION_RTOL = 1e-8
_EPS = np.finfo(float).eps
#: box-constrained least-squares miss (relative) above which bounds count as infeasible
_INFEASIBLE_RTOL = 1e-6
#: weight of the multipliers in the inverse-dynamics QP objective (relative to forces)
_LAMBDA_WEIGHT = 1e-2
#: steps of the inverse-dynamics active-set search before ProxSuite takes over
_ACTIVE_SET_STEPS = 8
#: status of a least-squares / minimum-norm inverse solve, by "the rows are redundant"
_ID_STATUS = {True: "solved (redundant rows: minimum-norm multipliers)",
              False: "solved (least squares / minimum norm)"}


class Workspace(Protocol):
    """What the routes use of their :class:`~hexapod_pin.core.dynamics.ClosedLoopDynamics`."""

    model: pin.Model
    data: pin.Data
    nv: int
    n_rows: int
    n_act: int
    selection: np.ndarray

    def closure_rank(self, q: np.ndarray, force: bool = False) -> int: ...

    def pinocchio_constraint_terms(self, q: np.ndarray, v: np.ndarray,
                                   force: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...

    def lazy_multipliers(self, q: np.ndarray, lam_pin: np.ndarray,
                         jac: np.ndarray | None = None) -> Callable[[], np.ndarray]: ...

    def check_after_call(self, q: np.ndarray, v: np.ndarray) -> None: ...

    def effect_force_of_motion(self, q: np.ndarray, v: np.ndarray,
                               a: np.ndarray) -> np.ndarray | None: ...


class InverseDynamicsRoutes:
    """The inverse-dynamics routes of one workspace, with the buffers and the ProxSuite
    problem they keep from call to call (not shared between threads: each thread has its
    own workspace, see :func:`~hexapod_pin.core.dynamics.dynamics_of`).

    Args:
        ws: the workspace (its model, data, Pinocchio constraint terms, closure rank).
    """

    def __init__(self, ws: Workspace) -> None:
        self.ws = ws
        self.model, self.data = ws.model, ws.data
        self.nv, self.n_rows, self.n_act = ws.nv, ws.n_rows, ws.n_act
        self._zero_v = np.zeros(self.nv)
        self._res_out = np.empty(2)
        self._qps: dict = {}
        self._unique: bool | None = None
        self._id_matrix = np.zeros((self.nv, self.n_act + self.n_rows))
        self._id_matrix[:, :self.n_act] = ws.selection
        self._id_hess = np.diag(np.concatenate([np.ones(self.n_act),
                                                np.full(self.n_rows, _LAMBDA_WEIGHT)]))
        self._id_inv_root_w = 1.0 / np.sqrt(np.diag(self._id_hess))
        self._no_held = np.zeros(0, dtype=bool)
        self._id_box = np.zeros((self.n_act, self.n_act + self.n_rows))
        self._id_box[:, :self.n_act] = np.eye(self.n_act)
        #: columns of [S^T J^T] kept by the reduced inverse solve (u, independent rows)
        self._id_keep: np.ndarray | None = None

    def inverse(self, q: npt.ArrayLike, v: npt.ArrayLike, a: npt.ArrayLike,
                tau_ext: npt.ArrayLike | None = None, bounds: npt.ArrayLike | None = None,
                method: str = "qp") -> TreeInverseDynamics:
        """Closed-loop inverse dynamics; see
        :func:`~hexapod_pin.core.dynamics.inverse_dynamics_tree` (the state is checked
        against the closure tolerances: InputError)."""
        q = vector(q, self.model.nq, "q")
        v = vector(v, self.nv, "v")
        a = vector(a, self.nv, "a")
        tau_ext = self._zero_v if tau_ext is None else vector(tau_ext, self.nv, "tau_ext")
        bounds = self.check_bounds(bounds)
        if method not in INVERSE_METHODS:
            raise InputError("method", method, f"expected one of {INVERSE_METHODS}")
        return solve_checked(lambda: self.inverse_unchecked(q, v, a, tau_ext, bounds, method,
                                                            check_state=True),
                              ("q", q), ("v", v), ("a", a), ("tau_ext", tau_ext))

    def inverse_unchecked(self, q: np.ndarray, v: np.ndarray, a: np.ndarray,
                          tau_ext: np.ndarray, bounds: np.ndarray | None,
                          method: str, check_state: bool = False) -> TreeInverseDynamics:
        """:meth:`inverse` without the input checks (``bounds`` None or (n_act,) array);
        with ``check_state`` the closure check of :meth:`inverse_from_force`."""
        force = pin.rnea(self.model, self.data, q, v, a)
        return self.inverse_from_force(q, v, a, force, tau_ext, bounds, method, check_state)

    def inverse_from_force(self, q: np.ndarray, v: np.ndarray, a: np.ndarray,
                           force: np.ndarray, tau_ext: np.ndarray, bounds: np.ndarray | None,
                           method: str, check_state: bool = False) -> TreeInverseDynamics:
        """Inverse dynamics given ``force = M a + h`` (nv,) (e.g. from a pooled
        ``rneaInParallel``); no input checks, and no closure check of ``(q, v)`` unless
        ``check_state`` (then on the constraint datas of the call below, no extra pass:
        InputError for a state off the closures, see
        :data:`~hexapod_pin.core.dynamics_common.CLOSURE_QTOL`).

        Works in Pinocchio's LOCAL constraint rows: one ``pin.constraintDynamics`` call
        with ``tau = force`` evaluates ``J_pin`` and the drift (its acceleration is not
        used), ``a`` is checked against ``J_pin a = -drift`` (raises SolverError when it
        breaks the closures), ``[S J_pin^T] (u, lambda_pin) = force - tau_ext`` is solved
        and verified, and ``lambda_pin`` is converted to our rows on access (``u`` and
        the minimum norm do not depend on the row convention: the rows differ by
        rotations, and by ``Jlog6 = I`` for a weld at an assembled configuration).
        """
        rhs = force - tau_ext
        effects = self.ws.effect_force_of_motion(q, v, a)
        if effects is not None:          # the joint effects' force is balanced too
            rhs = rhs - effects
        jac, target = self.ws.pinocchio_constraint_terms(q, v, force)
        if check_state and self.n_rows:
            self.ws.check_after_call(q, v)
        rank = self.ws.closure_rank(q)      # after the check: the first call fixes the rank
        if self.n_rows:
            # Pinocchio's J a = primal_rhs (its drift with the sign flipped)
            miss = linear_residual(jac, a, target, self._res_out)
            if not miss <= _MOTION_RTOL:
                raise SolverError("closed-loop inverse dynamics", "inconsistent motion",
                                  f"closure equation J_c a = -gamma missed by {miss:.3e} "
                                  "(relative): the acceleration does not keep the closures")
        return self._inverse_solve(jac, rhs, bounds, method, rank, q)

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
            lam = self.ws.lazy_multipliers(q.copy(), lam, jac.copy() if reduced else None)
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
        f_scale = max(max_abs(rhs), max_abs(direct), TINY)
        norms = np.sqrt(np.einsum("ij,ij->i", mat, mat))
        dinv = 1.0 / np.maximum(norms, TINY)
        mat_s = mat * dinv[:, None]
        b = rhs * dinv / f_scale
        x0 = direct / f_scale
        x0[:n_act] = np.clip(x0[:n_act], -bounds / f_scale, bounds / f_scale)
        qp = cached_qp(self._qps, "id_bounded", n_act,
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
        if miss > _INFEASIBLE_RTOL * max(max_abs(rhs), TINY):
            return direct[:self.n_act].copy()
        return None


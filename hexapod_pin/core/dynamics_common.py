"""What the closed-loop dynamics routes share: tolerances, ProxSuite settings and status
names, the cached ProxSuite problems, the forward-dynamics verification, and the result
types of :func:`~hexapod_pin.core.dynamics.forward_dynamics_tree` and
:func:`~hexapod_pin.core.dynamics.inverse_dynamics_tree` (documented with them, in
:mod:`hexapod_pin.core.dynamics`, which re-exports everything here that callers use).

Conventions (tree coordinates, Pinocchio's ``q``, ``v``, ``a``; see
:mod:`hexapod_pin.core.dynamics`)::

    M(q) a + h(q, v) = tau + J_c(q)^T lambda          (equation of motion)
    J_c(q) a = -gamma(q, v)                            (closures at acceleration level)
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
import proxsuite
import scipy.linalg

from ..errors import SolverError
from .linear_kernels import forward_residuals

#: relative tolerance on equation residuals before a route is declared failed
RESIDUAL_RTOL = 1e-9
#: ProxSuite accuracy (absolute, on primal and dual residuals of the scaled problems)
QP_EPS = 1e-12
#: iteration cap of the tree QPs (redundant closure rows slow the proximal iterations down)
QP_MAX_ITER = 1000
#: a floor for scales (avoids dividing by zero on all-zero data)
TINY = 1e-300

QP_SOLVED = proxsuite.proxqp.PROXQP_SOLVED
QP_STATUS = {
    proxsuite.proxqp.PROXQP_SOLVED: "solved",
    proxsuite.proxqp.PROXQP_MAX_ITER_REACHED: "max_iter_reached",
    proxsuite.proxqp.PROXQP_PRIMAL_INFEASIBLE: "primal_infeasible",
    proxsuite.proxqp.PROXQP_DUAL_INFEASIBLE: "dual_infeasible",
    proxsuite.proxqp.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE: "solved_closest_primal_feasible",
    proxsuite.proxqp.PROXQP_NOT_RUN: "not_run",
}


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
        iterations: solver iterations: Pinocchio's proximal iterations for the
            "pinocchio" route (1 for its direct solve), ProxSuite's for "qp", 0 for
            "kkt" (and when the KKT route answered for the "pinocchio" route).
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


def verify_forward(mass: np.ndarray, bias: np.ndarray, tau: np.ndarray, jac: np.ndarray,
                   drift: np.ndarray, acc: np.ndarray, lam: np.ndarray, route: str,
                   out: np.ndarray) -> tuple[float, float]:
    """Relative residuals of the two equations a forward solution must satisfy.

    ``M a + h - tau - J^T lam`` relative to the largest of ``|M a|``, ``|h - tau|``,
    ``|J^T lam|``, and ``J a + drift`` relative to ``|J| |a|`` and ``|drift|`` (max-abs
    norms; :func:`~hexapod_pin.core.linear_kernels.forward_residuals`). ``jac`` / ``drift``
    may be ours (``J_c``, ``gamma``) or Pinocchio's LOCAL ones (``J_pin``,
    ``-primal_rhs``): both equations hold in either row convention. ``out`` (2,) receives
    the two residuals.

    Returns:
        (equation-of-motion residual, closure residual), both relative.

    Raises:
        SolverError: either exceeds :data:`RESIDUAL_RTOL` or is not finite; the message
            names the equation and its residual.
    """
    eom, con = forward_residuals(mass, bias, tau, jac, drift, acc, lam, out)
    if not eom <= RESIDUAL_RTOL:
        raise SolverError(route, "unverified", "equation of motion M a + h = tau + J_c^T "
                          f"lambda missed by {eom:.3e} (relative)")
    if not con <= RESIDUAL_RTOL:
        raise SolverError(route, "unverified", "closure equation J_c a = -gamma missed by "
                          f"{con:.3e} (relative)")
    return eom, con


def cached_qp(cache: dict, key: Any, n_in: int, args: tuple,
              warm: tuple | None = None) -> proxsuite.proxqp.dense.QP:
    """Initialise (first call: kept in ``cache`` under ``key``) or update a dense ProxSuite
    problem with ``args = (H, g, A, b, C, l, u)`` and ``n_in`` inequality rows; solve,
    warm-started from ``warm = (x, y, z)`` when given. The data must be scaled to order
    one (tolerance :data:`QP_EPS` absolute, at most :data:`QP_MAX_ITER` iterations).
    The caller verifies the answer."""
    qp = cache.get(key)
    if qp is None:
        hess, _, amat = args[0], args[1], args[2]
        qp = proxsuite.proxqp.dense.QP(hess.shape[0], amat.shape[0], n_in)
        qp.settings.eps_abs = QP_EPS
        qp.settings.eps_rel = 0.0
        qp.settings.max_iter = QP_MAX_ITER
        qp.settings.verbose = False
        qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START
        qp.init(*args)
        cache[key] = qp
    else:
        qp.update(*args, update_preconditioner=True)
    if warm is None:
        qp.solve()
    else:
        qp.solve(*warm)
    return qp


def independent_rows_of_rank(jac: np.ndarray, rank: int) -> np.ndarray:
    """The ``rank`` rows of ``jac`` that a column-pivoted QR of ``jac^T`` picks first,
    sorted: for a ``jac`` of that numerical rank, a well-conditioned set of independent
    rows (the others depend on them, exactly or nearly)."""
    if rank == 0:
        return np.arange(0)
    _, _, piv = scipy.linalg.qr(jac.T, pivoting=True, mode="economic")
    return np.sort(piv[:rank])


def independent_rows(jac: np.ndarray, rtol: float = 1e-8) -> np.ndarray:
    """:func:`independent_rows_of_rank` at the numerical rank of ``jac`` (singular values
    above ``rtol`` times the largest), sorted."""
    if jac.shape[0] == 0:
        return np.arange(0)
    sv = np.linalg.svd(jac, compute_uv=False)
    return independent_rows_of_rank(jac, int(np.sum(sv > rtol * sv[0])))

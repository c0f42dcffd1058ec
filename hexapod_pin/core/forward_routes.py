"""The exact and ProxSuite forward-dynamics routes of the generic closed-loop core.

Given the terms at one state (``M``, ``h``, ``J_c``, ``gamma``, ``tau``; conventions in
:mod:`hexapod_pin.core.dynamics`), two routes of
:func:`~hexapod_pin.core.dynamics.forward_dynamics_tree` solve

    M a + h = tau + J_c^T lambda,        J_c a = -gamma:

* "kkt": one numpy solve of the KKT system when the rows are independent, else (or when
  that solve misses the verification) the exact null-space solve with minimum-norm
  multipliers;
* "qp": the Gauss principle as a ProxSuite QP on the independent rows, in coordinates
  scaled by ``diag(M)^(1/2)`` with the augmented Hessian ``D^-1 M D^-1 + J_s^T J_s`` (unit
  diagonal), warm-started from the "kkt" answer and its multipliers.

Both verify their answer (:func:`~hexapod_pin.core.dynamics_common.verify_forward`)
before returning it. The "pinocchio" route and the workspace live in
:mod:`hexapod_pin.core.dynamics`; each workspace owns one
:class:`ForwardDynamicsRoutes`.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from ..errors import SolverError
from .checks import max_abs
from .closed_loop import RANK_RTOL
from .dynamics_common import (
    QP_STATUS,
    TINY,
    TreeForwardDynamics,
    cached_qp,
    independent_rows_of_rank,
    verify_forward,
)
from .linear_kernels import NULLSPACE_NOT_POSITIVE, nullspace_forward_solve

_EPS = np.finfo(float).eps
#: re-solves of the forward-dynamics QP from ProxSuite's own iterate when an answer misses
#: the verification (the proximal iterations continued) before the route raises
QP_RETRIES = 2
#: the forward QP's coordinate scaling raises a mass-matrix diagonal entry below this
#: fraction of the largest (a massless joint) to it
_MASS_FLOOR = 1e-6


class Workspace(Protocol):
    """What the routes use of their :class:`~hexapod_pin.core.dynamics.ClosedLoopDynamics`."""

    nv: int
    n_rows: int

    def closure_rank_from(self, jac: np.ndarray) -> int: ...


class ForwardDynamicsRoutes:
    """The "kkt" and "qp" forward routes of one workspace, with the KKT buffer and the
    ProxSuite problems they keep from call to call (one workspace per thread, see
    :func:`~hexapod_pin.core.dynamics.dynamics_of`).

    Args:
        ws: the workspace (sizes; the closure rank is re-evaluated through it when a
            system turns out singular).
    """

    def __init__(self, ws: Workspace) -> None:
        self.ws = ws
        self.nv, self.n_rows = ws.nv, ws.n_rows
        self._kkt = np.zeros((self.nv + self.n_rows, self.nv + self.n_rows))
        self._qps: dict = {}
        self._res_out = np.empty(2)

    def verify(self, mass: np.ndarray, bias: np.ndarray, tau: np.ndarray, jac: np.ndarray,
               drift: np.ndarray, acc: np.ndarray, lam: np.ndarray,
               route: str) -> tuple[float, float]:
        """:func:`~hexapod_pin.core.dynamics_common.verify_forward` (raises SolverError)."""
        return verify_forward(mass, bias, tau, jac, drift, acc, lam, route, self._res_out)

    def kkt(self, mass: np.ndarray, bias: np.ndarray, jac: np.ndarray, gamma: np.ndarray,
            tau: np.ndarray, rank: int) -> TreeForwardDynamics:
        """The "kkt" route: ``a`` and the multipliers (minimum-norm when ``rank`` is below
        the number of rows or the KKT system is singular), verified."""
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
                rank = self.ws.closure_rank_from(jac)
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
        """Exact solve for any rank: ``a`` by
        :func:`~hexapod_pin.core.linear_kernels.nullspace_forward_solve` (the null space of
        ``J_c`` from an SVD, the reduced system Jacobi-scaled) at the numerical rank of ``J_c``
        (singular values above ``RANK_RTOL`` times the largest), with the minimum-norm
        multipliers ``lambda = (J_c^T)^+ (M a + h - tau)``."""
        sv = np.linalg.svd(jac, compute_uv=False)
        tol = max(RANK_RTOL * sv[0], max(jac.shape) * _EPS) if sv.size else 0.0
        acc, lam = np.empty(self.nv), np.empty(self.n_rows)
        code = nullspace_forward_solve(mass, bias, tau, jac, -gamma, int(np.sum(sv > tol)),
                                       acc, lam)
        if code == NULLSPACE_NOT_POSITIVE:
            raise SolverError("null-space forward dynamics", "singular",
                              "N^T M N is singular: the mass matrix is not positive on the "
                              "motions the closures allow")
        return acc, lam

    def qp(self, mass: np.ndarray, bias: np.ndarray, jac: np.ndarray, gamma: np.ndarray,
           tau: np.ndarray, rank: int) -> TreeForwardDynamics:
        """Gauss principle as a ProxSuite QP, reformulated so that it is well posed on every
        class: in the scaled coordinates ``s = D a / c`` (``D = diag(M)^(1/2)``, a
        diagonal entry below ``_MASS_FLOOR`` (1e-6) of the largest raised to it; ``c`` the
        magnitude of the direct answer), ``min 1/2 s^T H s + g^T s`` s.t.
        ``R J_c D^-1 s = -R gamma / c`` with the augmented Hessian
        ``H = D^-1 M D^-1 + (R J_c D^-1)^T (R J_c D^-1)`` (unit diagonal whatever the
        masses; same minimiser on the feasible set; positive definite when ``M`` is only
        positive on ``ker J_c``: massless links), rows normalised by ``R``, independent
        rows only; warm-started from the verified direct (KKT) solution and its
        multipliers. An answer that misses the verification is solved again from
        ProxSuite's own iterate (the proximal iterations continued, :data:`QP_RETRIES`
        times) before the route raises."""
        direct = self.kkt(mass, bias, jac, gamma, tau, rank)
        rank = direct.rank
        nr = self.n_rows
        rows: slice | np.ndarray = slice(None)
        if rank < nr:
            # the QP keeps independent rows only (a pivoted QR of J_c^T): same feasible set
            # for a consistent drift, and the equality constraints get full row rank
            rows = independent_rows_of_rank(jac, rank)
        jac_q, gamma_q = jac[rows], gamma[rows]
        n_eq = jac_q.shape[0]
        diag = np.diagonal(mass)
        dinv = 1.0 / np.sqrt(np.maximum(diag, _MASS_FLOOR * max(max_abs(diag), TINY)))
        force = dinv * (bias - tau)
        scale = max(max_abs(direct.a / dinv), max_abs(force), TINY)
        hess = mass * dinv[:, None] * dinv[None, :]
        grad = force / scale
        if n_eq:
            jac_s = jac_q * dinv[None, :]
            rinv = 1.0 / np.maximum(np.sqrt(np.einsum("ij,ij->i", jac_s, jac_s)), TINY)
            jac_s *= rinv[:, None]
            b = -gamma_q * rinv / scale
            hess = hess + jac_s.T @ jac_s
            grad = grad - jac_s.T @ b
            # multipliers of the kept rows giving the direct generalised force;
            # ProxSuite's H s + g + A^T y = 0 gives lambda = -c R y
            lam_q, *_ = np.linalg.lstsq(jac_q.T, jac.T @ direct.multipliers, rcond=None)
            y0 = -lam_q / (scale * rinv)
        else:
            jac_s, rinv, b, y0 = jac_q, np.ones(0), np.zeros(0), np.zeros(0)
        warm = (direct.a / (dinv * scale), y0, None)
        iters, error = 0, None
        for _ in range(QP_RETRIES + 1):
            qp = cached_qp(self._qps, ("fd", n_eq), 0, (hess, grad, jac_s, b, None, None, None),
                           warm=warm)
            info = qp.results.info
            iters += int(info.iter)
            status = QP_STATUS.get(info.status, str(info.status))
            acc = qp.results.x * dinv * scale
            lam = np.zeros(nr)
            if n_eq:
                lam[rows] = -qp.results.y * scale * rinv
            try:
                self.verify(mass, bias, tau, jac, gamma, acc, lam,
                            "ProxSuite (forward dynamics QP)")
                error = None
                break
            except SolverError as exc:
                error = (f"{exc}; primal residual {info.pri_res:.3e}, dual residual "
                         f"{info.dua_res:.3e}")
                warm = (qp.results.x.copy(), qp.results.y.copy(), None)
        if error is not None:
            raise SolverError("ProxSuite (forward dynamics QP)", status, error)
        if rank < nr:
            lam = direct.multipliers            # same generalised force; minimum norm
            status = f"{status} (redundant rows: minimum-norm multipliers)"
        elif status != "solved":
            status = f"{status} (residuals verified)"
        return TreeForwardDynamics(acc, lam, "qp", status, iters, rank,
                                   max_abs(jac @ acc + gamma))

"""Assembly of a closed chain: ``residual(q) = 0`` by Levenberg-Marquardt with restarts.

Used by :meth:`~hexapod_pin.core.closed_loop.ClosedLoopModel.assemble`; robot-agnostic (it
sees a residual-and-Jacobian callable and ``pin.integrate``, not the model's closures).

Each iteration linearises the residual ``r`` (n_rows,) at ``q`` with the constraint
Jacobian restricted to the free velocity coordinates ``J`` (n_rows, n_free), takes the
Levenberg step ``dv = -(J^T J + mu I)^-1 J^T r`` (from one SVD of ``J``: every damping
tried costs no new factorisation) and applies it on the configuration manifold,
``q+ = pin.integrate(model, q, dv)``. A step is accepted when it decreases
``1/2 |r|^2``; the damping follows Nielsen's rule (``mu *= max(1/3, 1 - (2 rho - 1)^3)``
on acceptance, ``rho`` the ratio of the actual to the predicted decrease; multiplied by
``nu``, then ``nu`` doubled, on rejection), starting at ``1e-10 max diag(J^T J)``
(Gauss-Newton steps until one fails). As ``mu -> 0`` near a solution the step is the
minimum-norm Gauss-Newton step (quadratic convergence; redundant rows are harmless).
Convergence: ``max|r| <= tol`` (m / rad).

Restarts (:data:`RESTART_SPREADS`): when a start stalls (the damping grows past
``1e12`` times its scale, or an accepted step decreases ``1/2 |r|^2`` by less than
1e-12 of it: a local minimum of ``|r|`` that is not a solution, or a singular
configuration) or runs out of iterations, the next start is ``q0`` with its
free coordinates displaced by ``spread_k * u_k``, ``u_k`` uniform in ``[-1, 1]`` from
``numpy.random.default_rng(k)`` (deterministic: the same ``q0`` always gives the same
answer). The fixed coordinates keep their values in ``q0``. Every start has
``max_iter`` iterations. :meth:`~hexapod_pin.core.closed_loop.ClosedLoopModel.assemble`
returns the answer only when its residual, recomputed at the returned ``q``, is within
``tol``; otherwise its :class:`~hexapod_pin.errors.AssemblyError` carries the best iterate
of all starts.

``method="newton"`` is the plain Gauss-Newton solve (minimum-norm steps halved while they
do not decrease ``max|r|``), for callers that follow one assembly mode and globalise by
themselves (continuation, their own starts).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

#: spreads (rad for revolute, m for prismatic coordinates) of the restarts' displacements
#: of the free coordinates of ``q0``, in order (restart k uses ``default_rng(k)``)
RESTART_SPREADS = (0.05, 0.1, 0.2, 0.4)
#: initial damping relative to the largest diagonal entry of ``J^T J`` (small: the first
#: steps are Gauss-Newton steps, damped only once one fails to decrease the residual)
_MU0 = 1e-10
#: damping (relative to the largest diagonal entry of ``J^T J`` at the start) past which a
#: start has stalled
_MU_STALL = 1e12
#: an accepted step that decreases ``1/2 |r|^2`` by less than this fraction (short of
#: convergence) ends the start: a local minimum that is not a solution
_STALL_DECREASE = 1e-12


@dataclass(frozen=True)
class AssemblySolve:
    """What :func:`levenberg_marquardt` found (the best iterate when not converged).

    Attributes:
        q: the configuration (nq,).
        residual_norm: max-abs residual at ``q`` (m / rad).
        iterations: iterations of every start together.
        starts: starts tried (1 + restarts used).
        converged: ``residual_norm <= tol``.
        reason: why the last start stopped when not converged ("" when converged).
    """

    q: np.ndarray
    residual_norm: float
    iterations: int
    starts: int
    converged: bool
    reason: str


def _one_start(model: pin.Model, evaluate: Callable, q: np.ndarray, free: np.ndarray,
               tol: float, max_iter: int) -> tuple[np.ndarray, np.ndarray, int, str]:
    """Levenberg-Marquardt from ``q``; returns ``(q, r, iterations, reason)`` (``reason`` ""
    when ``max|r| <= tol``)."""
    res, jac = evaluate(q)
    cost = 0.5 * float(res @ res)
    mu, nu, mu_scale = -1.0, 2.0, 1.0
    for it in range(max_iter + 1):
        err = float(np.max(np.abs(res), initial=0.0))
        if err <= tol:
            return q, res, it, ""
        if it == max_iter:
            return q, res, it, f"no convergence in {max_iter} iterations"
        u_mat, sv, vt = np.linalg.svd(jac[:, free], full_matrices=False)
        if mu < 0.0:
            mu_scale = max(float(sv[0]) ** 2 if sv.size else 0.0, 1e-300)
            mu = _MU0 * mu_scale
        proj = u_mat.T @ res                           # r in the left singular basis
        grad = vt.T @ (sv * proj)                      # J^T r
        while True:
            coef = -(sv * proj) / (sv * sv + mu)
            step = vt.T @ coef
            dv = np.zeros(model.nv)
            dv[free] = step
            trial = pin.integrate(model, q, dv)
            trial_res, trial_jac = evaluate(trial)
            trial_cost = 0.5 * float(trial_res @ trial_res)
            # predicted decrease of the linear model: -(g^T s + 1/2 |J s|^2)
            predicted = -(float(grad @ step) + 0.5 * float(np.sum((sv * coef) ** 2)))
            if math.isfinite(trial_cost) and trial_cost < cost:
                if cost - trial_cost <= _STALL_DECREASE * cost and \
                        float(np.max(np.abs(trial_res))) > tol:
                    return trial, trial_res, it + 1, (
                        "the residual stopped decreasing (a local minimum of the residual, "
                        "or a singular or unreachable configuration)")
                rho = (cost - trial_cost) / predicted if predicted > 0.0 else 0.0
                mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                q, res, jac, cost = trial, trial_res, trial_jac, trial_cost
                break
            mu *= nu
            nu *= 2.0
            if not mu <= _MU_STALL * mu_scale:
                return q, res, it, ("no step decreases the residual (a local minimum of "
                                    "the residual, or a singular or unreachable configuration)")
    return q, res, max_iter, f"no convergence in {max_iter} iterations"   # not reached


def _gauss_newton(model: pin.Model, evaluate: Callable, q: np.ndarray, free: np.ndarray,
                  tol: float, max_iter: int) -> tuple[np.ndarray, np.ndarray, int, str]:
    """Gauss-Newton from ``q`` (minimum-norm steps, halved up to 30 times while they do not
    decrease ``max|r|``); returns ``(q, r, iterations, reason)`` as :func:`_one_start`."""
    res, jac = evaluate(q)
    err = float(np.max(np.abs(res), initial=0.0))
    for it in range(max_iter + 1):
        if err <= tol:
            return q, res, it, ""
        if it == max_iter:
            break
        step, *_ = np.linalg.lstsq(jac[:, free], -res, rcond=None)
        dv = np.zeros(model.nv)
        dv[free] = step
        alpha = 1.0
        for _ in range(30):
            trial = pin.integrate(model, q, alpha * dv)
            trial_res, trial_jac = evaluate(trial)
            trial_err = float(np.max(np.abs(trial_res), initial=0.0))
            if math.isfinite(trial_err) and trial_err < err:
                break
            alpha *= 0.5
        else:
            return q, res, it, ("no step decreases the residual (singular or unreachable "
                                "configuration)")
        q, res, jac, err = trial, trial_res, trial_jac, trial_err
    return q, res, max_iter, f"no convergence to {tol:g} in {max_iter} iterations"


#: the single-start solvers by name (``method`` of :func:`levenberg_marquardt`)
_STARTS = {"lm": _one_start, "newton": _gauss_newton}
ASSEMBLY_METHODS = tuple(_STARTS)


def levenberg_marquardt(model: pin.Model,
                        evaluate: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                        q0: np.ndarray, free: np.ndarray, tol: float, max_iter: int,
                        restarts: int, method: str = "lm") -> AssemblySolve:
    """Solve ``residual(q) = 0`` moving the velocity coordinates ``free`` (see the module
    docstring).

    Args:
        model: the tree (for ``pin.integrate``).
        evaluate: ``q -> (residual (n_rows,), J_c (n_rows, nv))`` at ``q``.
        q0: the start (nq,).
        free: indices of the velocity coordinates that may move.
        tol: convergence threshold on the max-abs residual (m / rad).
        max_iter: iterations per start.
        restarts: further starts at most (each from ``q0`` displaced as documented,
            spreads cycling through :data:`RESTART_SPREADS`).
        method: "lm" (Levenberg-Marquardt, above) or "newton" (Gauss-Newton with
            minimum-norm steps halved while they do not decrease ``max|r|``: the local
            solver of callers that track one assembly mode and globalise themselves,
            e.g. by continuation or their own starts).

    Returns:
        :class:`AssemblySolve`; the caller raises when it did not converge.
    """
    best_q, best_err, total, reason = q0, math.inf, 0, ""
    starts = 0
    for k in range(restarts + 1):
        start = q0
        if k:
            rng = np.random.default_rng(k)
            dv = np.zeros(model.nv)
            dv[free] = RESTART_SPREADS[(k - 1) % len(RESTART_SPREADS)] * \
                rng.uniform(-1.0, 1.0, free.size)
            start = pin.integrate(model, q0, dv)
        q, res, iters, reason = _STARTS[method](model, evaluate, start, free, tol, max_iter)
        total += iters
        starts += 1
        err = float(np.max(np.abs(res), initial=0.0))
        if not reason:
            return AssemblySolve(q, err, total, starts, True, "")
        if err < best_err:
            best_q, best_err = q, err
        if not free.size:
            break
    return AssemblySolve(best_q, best_err, total, starts, False, reason)

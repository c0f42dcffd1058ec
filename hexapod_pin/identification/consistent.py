"""A physically consistent estimate of the full dynamic parameters.

Each body's ten inertial parameters are written through its pseudo-inertia (Wensing,
Kim & Slotine 2017)::

    J = [[Sigma, h], [h^T, m]],  Sigma = tr(I)/2 1 - I,  h = m c   (4 x 4, body frame)

which is positive definite exactly when the mass is positive and the inertia about the
centre of mass is positive definite with the triangle inequalities (a real density
exists). The log-Cholesky parametrisation (Rucker & Wensing 2022) ``J = U U^T``, ``U``
upper triangular with ``exp(theta_d)`` on its diagonal and free off-diagonal entries (10
unconstrained numbers per body), makes every value of ``theta`` consistent. Bodies with
no mass in the nominal model (virtual bodies of a planar joint, the massless cross of a
universal joint) are held at their nominal values.

The drive parameters: armature, viscous and Coulomb ones as ``exp(s)`` (their model
fields must be >= 0; they start at the least-squares values, at least :data:`FLOOR` of
the largest drive value), offsets directly.

The fit minimises, by ``scipy.optimize.least_squares`` (Levenberg-Marquardt, analytic
Jacobian, at most :data:`MAX_EVALUATIONS` evaluations)::

    | W_w pi(theta) - u_w |^2 + prior * | D (pi(theta) - pi_nominal) |^2

with ``W_w``, ``u_w`` the weighted full regressor and forces of the data (the weights of
the least-squares estimate), ``D`` the column norms of ``W_w`` and ``prior`` small
(:data:`PRIOR_WEIGHT`): the data decide every identifiable combination, the prior only
the directions the data cannot see (where the nominal values are kept). The fit is
nonconvex in ``theta`` and slow along those flat directions: it often stops at the
evaluation limit, close to but not exactly at the least-squares base parameters; the
result reports how far (:attr:`~.results.IdentificationResult.consistent_gap`, in standard
errors).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.optimize

from .parameters import ParameterLayout

#: weight of the prior toward the nominal parameters (relative to the data term per unit
#: of the column-scaled parameters)
PRIOR_WEIGHT = 1e-8
#: evaluations of the fit at most
MAX_EVALUATIONS = 300
#: positive drive parameters start at least this fraction of the largest drive value
FLOOR = 1e-6
#: the indices of ``U``'s free entries: the diagonal, then the upper triangle by row
_DIAG = [(i, i) for i in range(4)]
_UPPER = [(i, j) for i in range(4) for j in range(i + 1, 4)]


def pseudo_inertia(pi: np.ndarray) -> np.ndarray:
    """The pseudo-inertia (4, 4) of a body's ten parameters (Pinocchio's order)."""
    m, h = pi[0], pi[1:4]
    ixx, ixy, iyy, ixz, iyz, izz = pi[4:10]
    inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    out = np.empty((4, 4))
    out[:3, :3] = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    out[:3, 3] = out[3, :3] = h
    out[3, 3] = m
    return out


def parameters_of(pseudo: np.ndarray) -> np.ndarray:
    """The ten parameters of a pseudo-inertia (the inverse of :func:`pseudo_inertia`)."""
    sigma = pseudo[:3, :3]
    inertia = np.trace(sigma) * np.eye(3) - sigma
    return np.array([pseudo[3, 3], *pseudo[:3, 3], inertia[0, 0], inertia[0, 1],
                     inertia[1, 1], inertia[0, 2], inertia[1, 2], inertia[2, 2]])


def log_cholesky(pi: np.ndarray) -> np.ndarray:
    """``theta`` (10,) of a body's parameters, after lifting a semi-definite
    pseudo-inertia (a thin rod, a point mass) by 1e-9 of its trace to definite."""
    pseudo = pseudo_inertia(pi)
    pseudo = pseudo + 1e-9 * np.trace(pseudo) * np.eye(4)
    flip = np.eye(4)[::-1]
    lower = np.linalg.cholesky(flip @ pseudo @ flip)
    upper = flip @ lower @ flip
    return np.array([np.log(upper[i, j]) for i, j in _DIAG] + [upper[i, j] for i, j in _UPPER])


def _upper(theta: np.ndarray) -> np.ndarray:
    u = np.zeros((4, 4))
    for k, (i, j) in enumerate(_DIAG):
        u[i, j] = np.exp(theta[k])
    for k, (i, j) in enumerate(_UPPER):
        u[i, j] = theta[4 + k]
    return u


def body_parameters(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(pi, d pi / d theta)``: a body's ten parameters (10,) and their Jacobian (10, 10)
    from its log-Cholesky coordinates."""
    u = _upper(theta)
    pi = parameters_of(u @ u.T)
    jac = np.empty((10, 10))
    for k, (i, j) in enumerate(_DIAG + _UPPER):
        du = np.zeros((4, 4))
        du[i, j] = u[i, j] if k < 4 else 1.0
        jac[:, k] = parameters_of(du @ u.T + u @ du.T)
    return pi, jac


@dataclass(frozen=True)
class ConsistentFit:
    """The physically consistent estimate (module docstring).

    Attributes:
        parameters: the full parameter vector (layout order), consistent.
        free_bodies: names of the bodies fitted (the others, massless in the nominal model, held at their nominal values).
        cost: the final value of the minimised sum (half of it, scipy's ``cost``).
        success: scipy's convergence flag.
        message: scipy's message.
        iterations: function evaluations.
    """

    parameters: np.ndarray
    free_bodies: tuple[str, ...]
    cost: float
    success: bool
    message: str
    iterations: int


def consistent_fit(layout: ParameterLayout, information: np.ndarray, regrouping: np.ndarray,
                   estimate: np.ndarray, scale: np.ndarray, nominal: np.ndarray,
                   prior: float = PRIOR_WEIGHT) -> ConsistentFit:
    """The physically consistent fit (module docstring), on the data's sufficient
    statistics: with ``R`` the triangular factor of the weighted base regressor
    (``R^T R = W_wb^T W_wb``), ``|W_w pi - u_w|^2 = |R (K pi - beta)|^2 + const``.

    Args:
        layout: the parameters' layout.
        information: ``R`` (r, r).
        regrouping: ``K`` (r, n): base parameters of a full vector.
        estimate: ``beta`` (r,), the weighted least-squares base parameters.
        scale: (n,) the column norms of the weighted full regressor (the prior's metric).
        nominal: the nominal full parameters (the prior and, for massless bodies, the
            held values).
        prior: the prior's weight (>= 0).
    """
    n_bodies = len(layout.bodies)
    free = [b for b in range(n_bodies) if nominal[10 * b] > 0.0]
    n_free = len(free)
    n_drive = layout.n_drive
    positive = np.zeros(n_drive, dtype=bool)
    for kind in layout.drive:
        if kind != "offset":
            sl = layout.drive_slice(kind)
            positive[sl.start - layout.n_inertial:sl.stop - layout.n_inertial] = True
    metric = np.where(scale > 0, scale, 1.0)
    root = np.sqrt(prior) * metric
    data_map = information @ regrouping
    target = information @ estimate
    # start: the nominal drive parameters moved to the estimate (least-norm correction in
    # the prior's metric), positive ones at least FLOOR of their typical size
    correction = np.linalg.lstsq(data_map / metric, target - data_map @ nominal,
                                 rcond=1e-10)[0] / metric
    drive0 = (nominal + correction)[layout.n_inertial:]
    floor = FLOOR * np.maximum(np.abs(drive0), 1.0 / metric[layout.n_inertial:]).max()
    drive0 = np.where(positive, np.log(np.maximum(drive0, floor)), drive0)
    theta0 = np.concatenate([log_cholesky(nominal[10 * b:10 * b + 10]) for b in free]
                            + [drive0])

    def full(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pi = np.zeros(layout.size)
        pi[:layout.n_inertial] = nominal[:layout.n_inertial]
        dpi = np.zeros((layout.size, theta.size))
        for k, b in enumerate(free):
            p, jac = body_parameters(theta[10 * k:10 * k + 10])
            pi[10 * b:10 * b + 10] = p
            dpi[10 * b:10 * b + 10, 10 * k:10 * k + 10] = jac
        raw = theta[10 * n_free:]
        value = np.where(positive, np.exp(np.minimum(raw, 700.0)), raw)
        pi[layout.n_inertial:] = value
        dpi[layout.n_inertial:, 10 * n_free:] = np.diag(np.where(positive, value, 1.0))
        return pi, dpi

    def residual(theta: np.ndarray) -> np.ndarray:
        pi, _ = full(theta)
        return np.concatenate([data_map @ pi - target, root * (pi - nominal)])

    def jacobian(theta: np.ndarray) -> np.ndarray:
        _, dpi = full(theta)
        return np.vstack([data_map @ dpi, root[:, None] * dpi])

    with np.errstate(over="ignore", invalid="ignore"):
        sol = scipy.optimize.least_squares(residual, theta0, jac=jacobian, method="lm",
                                           x_scale="jac", xtol=1e-14, ftol=1e-14, gtol=1e-14,
                                           max_nfev=MAX_EVALUATIONS)
    pi, _ = full(sol.x)
    return ConsistentFit(pi, tuple(layout.bodies[b] for b in free), float(sol.cost),
                         bool(sol.success), str(sol.message), int(sol.nfev))

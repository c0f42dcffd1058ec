"""A physically consistent estimate of the full dynamic parameters.

Each body's ten inertial parameters are written through its pseudo-inertia (Wensing,
Kim & Slotine 2017)::

    J = [[Sigma, h], [h^T, m]],  Sigma = tr(I)/2 1 - I,  h = m c   (4 x 4, body frame)

which is positive definite exactly when the mass is positive and the inertia about the
centre of mass is positive definite with the triangle inequalities (a real density
exists). Bodies with no mass in the nominal model (virtual bodies of a planar joint, the
massless cross of a universal joint) are held at their nominal values.

Coordinates (log-Cholesky, Rucker & Wensing 2022, relative to a reference): with
``J_ref = J_0 + LIFT m_0 l^2 diag(1, 1, 1, 0)`` (the nominal pseudo-inertia ``J_0`` with
its second moments raised by a sphere of :data:`LIFT` of the body's mass at the robot's
radius of gyration ``l``: definite even for a nominal point mass or thin rod) and ``L``
its upper-triangular Cholesky factor (``L L^T = J_ref``)::

    J = L V V^T L^T,    V upper triangular, exp(theta_0..3) on its diagonal, theta_4..9 above

Every ``theta`` gives a consistent body, the coordinates are dimensionless, and a body
whose mass or an inertia about its centre of mass goes to zero needs ``theta`` to go to
infinity. The drive parameters are fitted directly, armature, viscous and Coulomb ones
bounded below by 0 (their model fields must be >= 0).

The fit minimises::

    | R (K pi(theta) - beta) |^2 + prior * | theta |^2

with ``R`` the triangular factor of the weighted base regressor (the first term is the
weighted least-squares cost up to a constant: chi-square units, one unit per standard
error of a base parameter) and ``prior`` (:data:`PRIOR_WEIGHT`) small: the data decide
every identifiable combination (a shift of well below one standard error), the prior
holds the directions the data cannot see at the reference bodies (the nominal ones with
the small lift above) and keeps every body away from a degenerate one. The drive
parameters have no prior: each has its own column (identifiable alone or, armature,
together with its actuated body's mass, whose split the body's prior then sets). Bounds
keep every mass at least :data:`MASS_FLOOR` of its nominal value (``theta_3 >= log
(MASS_FLOOR) / 2``: the mass is ``m_0 exp(2 theta_3)``) and the first three diagonal
entries of ``V`` squared at least :data:`PIVOT_FLOOR` (``scipy.optimize.least_squares``,
trust-region reflective, analytic Jacobian, at most :data:`MAX_EVALUATIONS`
evaluations). It starts from the reference bodies with the drive parameters at their
least-squares values. It often stops at the evaluation limit: on the tests' hexapod data
200 evaluations instead of 100 move the consistent estimate's base parameters by less
than 0.2 standard errors.

Before it is returned, the fit is verified (:class:`~hexapod_pin.errors.SolverError`
otherwise): every value finite, every fitted pseudo-inertia positive definite (its
smallest eigenvalue relative to the reference above :data:`EIGEN_FLOOR`) and every mass
at least :data:`MASS_FLOOR` of its nominal value. How far its base parameters are from
the least-squares ones, in standard errors, is
:attr:`~.results.IdentificationResult.consistent_gap` (large when the least-squares
estimate is itself not physically consistent).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.optimize

from ..errors import InputError, SolverError
from .parameters import ParameterLayout

#: weight of the prior (chi-square units per unit of ``theta`` squared)
PRIOR_WEIGHT = 1e-3
#: the reference pseudo-inertia's added second moments, a fraction of the body's mass at
#: the robot's radius of gyration
LIFT = 1e-2
#: evaluations of the fit at most
MAX_EVALUATIONS = 100
#: relative tolerances of the fit (scipy's ftol, xtol, gtol)
TOLERANCE = 1e-8
#: lower bound of every fitted mass, a fraction of its nominal value
MASS_FLOOR = 0.1
#: lower bound of the first three squared diagonal entries of ``V`` (the second moments
#: relative to the reference, pivot by pivot)
PIVOT_FLOOR = 1e-4
#: a fitted pseudo-inertia whose smallest eigenvalue relative to its reference is not
#: above this is refused
EIGEN_FLOOR = 1e-9
#: the indices of ``V``'s free entries: the diagonal, then the upper triangle by row
_DIAG = [(i, i) for i in range(4)]
_UPPER = [(i, j) for i in range(4) for j in range(i + 1, 4)]
_FLIP = np.eye(4)[::-1]


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


def _upper_cholesky(mat: np.ndarray) -> np.ndarray:
    """``V`` upper triangular with ``V V^T = mat`` (symmetric positive definite)."""
    return _FLIP @ np.linalg.cholesky(_FLIP @ mat @ _FLIP) @ _FLIP


def _upper(theta: np.ndarray) -> np.ndarray:
    u = np.zeros((4, 4))
    for k, (i, j) in enumerate(_DIAG):
        u[i, j] = np.exp(theta[k])
    for k, (i, j) in enumerate(_UPPER):
        u[i, j] = theta[4 + k]
    return u


#: the linear map from a pseudo-inertia, flattened row-major (16,), to the ten parameters
_PARAMS_OF_PSEUDO = np.stack([parameters_of(e.reshape(4, 4)) for e in np.eye(16)], axis=1)


@dataclass(frozen=True)
class BodyReference:
    """The reference of one body's log-Cholesky coordinates (module docstring).

    Attributes:
        factor: ``L`` (4, 4), upper triangular, ``L L^T = J_ref`` (so that the mass is
            ``m_ref exp(2 theta_3)``).
        linear: (10, 16) the ten parameters of ``L X L^T`` from ``X`` flattened.
    """

    factor: np.ndarray
    linear: np.ndarray

    @classmethod
    def of(cls, pi0: np.ndarray, length: float) -> BodyReference:
        """The reference of a body with nominal parameters ``pi0`` (mass > 0) and the
        robot's radius of gyration ``length`` (m)."""
        lift = LIFT * pi0[0] * length ** 2 * np.diag([1.0, 1.0, 1.0, 0.0])
        upper = _upper_cholesky(pseudo_inertia(pi0) + lift)
        return cls(upper, _PARAMS_OF_PSEUDO @ np.kron(upper, upper))

    def parameters(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(pi, d pi / d theta)``: the body's ten parameters (10,) and their Jacobian
        (10, 10) at ``theta``."""
        v = _upper(theta)
        dx = np.zeros((10, 4, 4))
        for k, (i, j) in enumerate(_DIAG + _UPPER):
            column = v[:, j] * (v[i, j] if k < 4 else 1.0)
            dx[k, i, :] += column
            dx[k, :, i] += column
        return self.linear @ (v @ v.T).reshape(16), self.linear @ dx.reshape(10, 16).T

    def smallest_eigenvalue(self, theta: np.ndarray) -> float:
        """Smallest eigenvalue of ``V V^T`` (the pseudo-inertia relative to the
        reference)."""
        v = _upper(theta)
        return float(np.linalg.eigvalsh(v @ v.T)[0])


@dataclass(frozen=True)
class ConsistentFit:
    """The physically consistent estimate (module docstring).

    Attributes:
        parameters: the full parameter vector (layout order), consistent.
        free_bodies: names of the bodies fitted (the others, massless in the nominal
            model, held at their nominal values).
        cost: the final value of the minimised sum (half of it, scipy's ``cost``).
        success: scipy's convergence flag.
        message: scipy's message.
        iterations: function evaluations.
        smallest_eigenvalue: the smallest eigenvalue of a fitted pseudo-inertia relative
            to its reference (verified > :data:`EIGEN_FLOOR`).
        smallest_mass_ratio: the smallest fitted mass over its nominal value (verified >=
            :data:`MASS_FLOOR`).
    """

    parameters: np.ndarray
    free_bodies: tuple[str, ...]
    cost: float
    success: bool
    message: str
    iterations: int
    smallest_eigenvalue: float
    smallest_mass_ratio: float


def gyration_length(layout: ParameterLayout, nominal: np.ndarray) -> float:
    """The robot's radius of gyration (m): ``sqrt(sum tr Sigma_b / sum m_b)`` over its
    bodies (second moments about each body's origin); 1 m for a robot of point masses."""
    masses = nominal[0:layout.n_inertial:10]
    moments = sum(float(np.trace(pseudo_inertia(nominal[10 * b:10 * b + 10])[:3, :3]))
                  for b in range(len(layout.bodies)))
    total = float(np.sum(masses))
    return float(np.sqrt(moments / total)) if total > 0 and moments > 0 else 1.0


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
        scale: (n,) the column norms of the weighted full regressor (the drive
            parameters' start is least-norm in this metric).
        nominal: the nominal full parameters (the prior's centre and, for massless
            bodies, the held values).
        prior: the prior's weight (>= 0).

    Raises:
        InputError: ``information`` not (r, r).
        SolverError: the fit is not finite, a pseudo-inertia is not positive definite or
            a mass fell below :data:`MASS_FLOOR` of its nominal value (module docstring).
    """
    r = regrouping.shape[0]
    if information.shape != (r, r):
        raise InputError("information", information.shape, f"expected the ({r}, {r}) "
                         "triangular factor of the weighted base regressor")
    free = [b for b in range(len(layout.bodies)) if nominal[10 * b] > 0.0]
    n_free, n_in = len(free), layout.n_inertial
    length = gyration_length(layout, nominal)
    refs = [BodyReference.of(nominal[10 * b:10 * b + 10], length) for b in free]
    positive = np.zeros(layout.n_drive, dtype=bool)
    for kind in layout.drive:
        if kind != "offset":
            sl = layout.drive_slice(kind)
            positive[sl.start - n_in:sl.stop - n_in] = True
    metric = np.where(scale > 0, scale, 1.0)[n_in:]
    data_map = information @ regrouping
    target = information @ estimate
    # drive start: the least-squares drive values with the bodies at their references
    # (least-norm in the drive metric), positive ones clipped at their bound 0
    body_ref = nominal.copy()
    for ref, b in zip(refs, free):
        body_ref[10 * b:10 * b + 10] = ref.parameters(np.zeros(10))[0]
    drive0 = nominal[n_in:] + np.linalg.lstsq(
        data_map[:, n_in:] / metric, target - data_map @ body_ref, rcond=1e-10)[0] / metric
    drive0 = np.where(positive, np.maximum(drive0, 0.0), drive0)
    root = np.sqrt(prior)

    def full(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pi = nominal.copy()
        dpi = np.zeros((layout.size, theta.size))
        for k, (ref, b) in enumerate(zip(refs, free)):
            p, jac = ref.parameters(theta[10 * k:10 * k + 10])
            pi[10 * b:10 * b + 10] = p
            dpi[10 * b:10 * b + 10, 10 * k:10 * k + 10] = jac
        pi[n_in:] = theta[10 * n_free:]
        dpi[n_in:, 10 * n_free:] = np.eye(layout.n_drive)
        return pi, dpi

    def residual(theta: np.ndarray) -> np.ndarray:
        pi, _ = full(theta)
        return np.concatenate([data_map @ pi - target, root * theta[:10 * n_free]])

    def jacobian(theta: np.ndarray) -> np.ndarray:
        _, dpi = full(theta)
        body_rows = np.zeros((10 * n_free, theta.size))
        body_rows[:, :10 * n_free] = root * np.eye(10 * n_free)
        return np.vstack([data_map @ dpi, body_rows])

    theta0 = np.concatenate([np.zeros(10 * n_free), drive0])
    lower = np.full(theta0.size, -np.inf)
    for k in range(n_free):
        lower[10 * k:10 * k + 3] = 0.5 * np.log(PIVOT_FLOOR)
        lower[10 * k + 3] = 0.5 * np.log(MASS_FLOOR)
    lower[10 * n_free:][positive] = 0.0
    with np.errstate(over="ignore"):
        sol = scipy.optimize.least_squares(residual, theta0, jac=jacobian, method="trf",
                                           bounds=(lower, np.inf), x_scale="jac",
                                           xtol=TOLERANCE, ftol=TOLERANCE, gtol=TOLERANCE,
                                           max_nfev=MAX_EVALUATIONS)
    pi, _ = full(sol.x)
    return _verified(layout, free, refs, sol, pi, nominal)


def _verified(layout: ParameterLayout, free: list[int], refs: list[BodyReference],
              sol: scipy.optimize.OptimizeResult, pi: np.ndarray,
              nominal: np.ndarray) -> ConsistentFit:
    if not (np.all(np.isfinite(pi)) and np.all(np.isfinite(sol.x))):
        raise SolverError("consistent fit", "non-finite", "the fitted parameters are not "
                          "finite")
    eig = min((ref.smallest_eigenvalue(sol.x[10 * k:10 * k + 10])
               for k, ref in enumerate(refs)), default=1.0)
    ratios = [pi[10 * b] / nominal[10 * b] for b in free]
    worst = int(np.argmin(ratios)) if ratios else 0
    ratio = float(ratios[worst]) if ratios else 1.0
    if not eig > EIGEN_FLOOR:
        raise SolverError("consistent fit", "degenerate", f"a pseudo-inertia's smallest "
                          f"relative eigenvalue is {eig:.3g} (<= {EIGEN_FLOOR:g})")
    if not ratio >= MASS_FLOOR * (1.0 - 1e-9):     # the bound, up to rounding
        raise SolverError("consistent fit", "degenerate", f"the mass of body "
                          f"{layout.bodies[free[worst]]!r} fell to {ratio:.3g} of its nominal "
                          f"value (< {MASS_FLOOR:g})")
    return ConsistentFit(pi, tuple(layout.bodies[b] for b in free), float(sol.cost),
                         bool(sol.success), str(sol.message), int(sol.nfev), eig, ratio)

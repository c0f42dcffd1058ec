"""Forward kinematics and every assembly mode of the planar 3-PRR robot.

Given the actuator (slider) positions ``s``, the platform poses that close the three
loops ``|P_k(pose) - c_k(s)| = L`` (conventions of :mod:`hexapod_pin.planar.geometry`):

* :meth:`PlanarAssembly.forward_kinematics`: damped Newton from a guess, the assembly
  mode that the iteration reaches;
* :meth:`PlanarAssembly.assembly_polynomial`: the univariate sextic in
  ``T = tan((theta - theta_offset) / 2)`` whose real roots are every ``theta`` at which
  the loops can close (elimination: subtracting loop 0 from loops 1 and 2 leaves two
  equations linear in the platform origin);
* :meth:`PlanarAssembly.assembly_modes`: every real assembly mode (at most 6), from those
  roots, polished by Newton.

Poses are ``(x, y, theta)`` (m, m, rad) with theta wrapped to (-pi, pi].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..core.checks import as_array
from ..errors import AssemblyError, InputError, SingularityError
from .geometry import N_ACTUATORS, PlanarGeometry

#: Newton's convergence threshold on ``max_k | |n_k| - L |`` (m)
NEWTON_TOL = 1e-12
#: Newton's iteration cap (forward kinematics)
NEWTON_MAX_ITER = 50
#: a root of the eliminant whose pose does not close to this (m) is spurious
MODE_TOL = 1e-9


@dataclass(frozen=True)
class AssemblyPolynomial:
    """The univariate polynomial whose real roots give every assembly mode.

    With ``theta = theta_offset + 2 atan(T)``, a pose with slider coordinates ``s``
    closes all three loops only if ``sum_i coefficients[i] T^i = 0`` (see
    :meth:`PlanarAssembly.assembly_polynomial`).

    Attributes:
        coefficients: the sextic's coefficients, lowest degree first, shape (7,)
            (scaled so that the largest magnitude is 1).
        theta_offset: the angle ``theta_offset`` of the substitution (rad).
        removed_factor_residual: relative remainder of the exact division by
            ``(1 + T^2)^3`` that turns the degree-12 numerator into the sextic
            (round-off level, about 1e-15).
    """

    coefficients: np.ndarray
    theta_offset: float
    removed_factor_residual: float


def rot2(theta: float) -> np.ndarray:
    """The 2x2 rotation by ``theta`` (rad)."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def wrap(angle: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Angle(s) wrapped to (-pi, pi]."""
    return np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), 2.0 * np.pi)


def same_pose(a: np.ndarray, b: np.ndarray, tol: float = 1e-8) -> bool:
    """Whether two planar poses coincide to ``tol`` (m, rad; theta modulo 2 pi)."""
    return bool(np.max(np.abs(a[:2] - b[:2])) <= tol and abs(wrap(a[2] - b[2])) <= tol)


class PlanarAssembly:
    """The assembly (forward-kinematic) problem of one :class:`PlanarGeometry`."""

    def __init__(self, geometry: PlanarGeometry) -> None:
        self.home_pose = geometry.home_pose
        self.length = geometry.link_length
        self.mids = geometry.rail_midpoints
        self.dirs = geometry.rail_directions
        self.pts = geometry.platform_points

    def slider_points(self, s: np.ndarray) -> np.ndarray:
        """Slider joints ``c_k = m_k + s_k u_k`` (m), shape (3, 2)."""
        return self.mids + s[:, None] * self.dirs

    def closure(self, pose: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residual ``(|n_k|^2 - L^2) / 2`` (m^2) and its pose Jacobian (3, 3)."""
        r = self.pts @ rot2(pose[2]).T
        links = pose[:2] + r - self.slider_points(s)
        res = 0.5 * (np.einsum("ki,ki->k", links, links) - self.length ** 2)
        moment = r[:, 0] * links[:, 1] - r[:, 1] * links[:, 0]
        return res, np.column_stack([links, moment])

    def length_error(self, res: np.ndarray) -> float:
        """``max_k | |n_k| - L |`` from ``res_k = (|n_k|^2 - L^2) / 2``."""
        norms = np.sqrt(np.maximum(self.length ** 2 + 2.0 * res, 0.0))
        return float(np.max(np.abs(norms - self.length)))

    def newton(self, pose: np.ndarray, s: np.ndarray, tol: float,
               max_iter: int) -> tuple[np.ndarray, float, int]:
        """Damped Newton (least-squares steps, halving line search) on the closures.
        Returns ``(pose, error, iterations)``."""
        res, jac = self.closure(pose, s)
        err = self.length_error(res)
        for iteration in range(max_iter + 1):
            if err <= tol or iteration == max_iter:
                return pose, err, iteration
            step, *_ = np.linalg.lstsq(jac, -res, rcond=None)
            alpha = 1.0
            for _ in range(30):
                trial = pose + alpha * step
                trial_res, trial_jac = self.closure(trial, s)
                trial_err = self.length_error(trial_res)
                if trial_err < err:
                    break
                alpha *= 0.5
            else:
                return pose, err, iteration
            pose, res, jac, err = trial, trial_res, trial_jac, trial_err
        return pose, err, max_iter

    def forward_kinematics(self, actuators: npt.ArrayLike,
                           guess: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
        """The pose (3,) of the assembly mode that Newton reaches from ``guess`` (3,)
        (default: the home pose); see the module docstring.

        Raises:
            InputError: wrong shape or non-finite values.
            AssemblyError: no convergence to NEWTON_TOL (unreachable coordinates, a
                singular configuration); its ``q`` holds the last pose.
        """
        s = as_array(actuators, (N_ACTUATORS,), "actuators")
        pose = (self.home_pose if guess is None
                else as_array(guess, (3,), "guess")).copy()
        pose, err, iterations = self.newton(pose, s, NEWTON_TOL, NEWTON_MAX_ITER)
        if err > NEWTON_TOL:
            raise AssemblyError("forward kinematics did not converge", err, iterations, pose)
        pose[2] = wrap(pose[2])
        return pose

    def assembly_polynomial(self, actuators: npt.ArrayLike) -> AssemblyPolynomial:
        """The sextic in ``T = tan((theta - theta_offset) / 2)`` of the assembly modes.

        With ``e_k(theta) = R(theta) p_k - c_k`` the closures read ``|t + e_k|^2 = L^2``,
        ``t = (x, y)``. Subtracting closure 0 from closures 1 and 2 leaves two equations
        LINEAR in t, ``A(theta) t = b(theta)``; Cramer's rule, ``t = adj(A) b / det A``,
        put into closure 0 gives

            F(theta) = |adj(A) b|^2 + 2 det(A) (adj(A) b) . e_0
                       + det(A)^2 (|e_0|^2 - L^2) = 0.

        ``cos`` and ``sin`` are rational in ``T`` with denominator ``W = 1 + T^2``;
        computed exactly in polynomial arithmetic, ``W^6 F`` is a polynomial of degree
        12 divisible by ``W^3`` (the factor from the circular points, which carry no
        real solution); the quotient is the sextic returned here, so there are at most
        6 real assembly modes. ``theta_offset`` is chosen where ``F(theta_offset + pi)``
        is largest, so that no root sits at ``T = infinity``.

        Args:
            actuators: slider coordinates (m), shape (3,).

        Raises:
            InputError: non-finite actuators, or of a magnitude whose products in the
                polynomial overflow (a finite answer cannot be computed).
        """
        s = as_array(actuators, (N_ACTUATORS,), "actuators")
        centres = self.slider_points(s)
        candidates = np.linspace(-np.pi, np.pi, 24, endpoint=False)
        with np.errstate(over="ignore", invalid="ignore"):
            values = [abs(self.eliminant(theta, centres)) for theta in candidates + np.pi]
            offset = float(candidates[int(np.nanargmax(values))]) \
                if np.isfinite(values).any() else 0.0
            numerator = self.eliminant_numerator(offset, centres)
        if not np.isfinite(numerator.coef).all():
            raise InputError("actuators", actuators, "too large: the assembly polynomial "
                             "overflows double precision")
        weight = np.polynomial.Polynomial([1.0, 0.0, 1.0]) ** 3
        quotient, remainder = divmod(numerator, weight)
        scale = float(np.max(np.abs(numerator.coef)))
        rem = float(np.max(np.abs(remainder.coef))) / scale if scale > 0 else 0.0
        coef = np.zeros(7)
        coef[:quotient.coef.size] = quotient.coef[:7]
        top = float(np.max(np.abs(coef)))
        return AssemblyPolynomial(coef / top if top > 0 else coef, offset, rem)

    def eliminant(self, theta: float, centres: np.ndarray) -> float:
        """``F(theta)`` of :meth:`assembly_polynomial`, evaluated directly."""
        e = self.pts @ rot2(theta).T - centres
        a = 2.0 * (e[1:] - e[0])
        b = -(np.einsum("ki,ki->k", e[1:], e[1:]) - e[0] @ e[0])
        det = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
        adj_b = np.array([a[1, 1] * b[0] - a[0, 1] * b[1], -a[1, 0] * b[0] + a[0, 0] * b[1]])
        return float(adj_b @ adj_b + 2.0 * det * adj_b @ e[0]
                     + det ** 2 * (e[0] @ e[0] - self.length ** 2))

    def eliminant_numerator(self, offset: float, centres: np.ndarray) -> np.polynomial.Polynomial:
        """``W^6 F`` as a polynomial in T (degree <= 12), theta = offset + 2 atan(T)."""
        poly = np.polynomial.Polynomial
        w = poly([1.0, 0.0, 1.0])
        cos_phi, sin_phi = poly([1.0, 0.0, -1.0]), poly([0.0, 2.0])
        c0, s0 = math.cos(offset), math.sin(offset)
        cos_t = c0 * cos_phi - s0 * sin_phi   # numerators over W
        sin_t = s0 * cos_phi + c0 * sin_phi
        pts = self.pts
        # e_k components, numerators over W
        e = [[pts[k, 0] * cos_t - pts[k, 1] * sin_t - centres[k, 0] * w,
              pts[k, 0] * sin_t + pts[k, 1] * cos_t - centres[k, 1] * w] for k in range(3)]
        a = [[2.0 * (e[k][i] - e[0][i]) for i in range(2)] for k in (1, 2)]       # over W
        norm2 = [e[k][0] ** 2 + e[k][1] ** 2 for k in range(3)]                     # over W^2
        b = [-(norm2[k] - norm2[0]) for k in (1, 2)]                                # over W^2
        det = a[0][0] * a[1][1] - a[0][1] * a[1][0]                                 # over W^2
        adj_b = [a[1][1] * b[0] - a[0][1] * b[1], -a[1][0] * b[0] + a[0][0] * b[1]]  # over W^3
        length2 = self.length ** 2
        return (adj_b[0] ** 2 + adj_b[1] ** 2
                + 2.0 * det * (adj_b[0] * e[0][0] + adj_b[1] * e[0][1])
                + det ** 2 * (norm2[0] - length2 * w ** 2))                          # over W^6

    def assembly_modes(self, actuators: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Every real assembly mode (platform pose) for slider coordinates ``actuators``.

        The real roots of the sextic of :meth:`assembly_polynomial` are every ``theta``
        at which the closures can hold; for each, ``t = (x, y)`` follows from the linear
        equations ``A(theta) t = b(theta)`` (or, where ``det A`` vanishes, from the line
        ``A t = b`` intersected with closure 0), and a few Newton steps polish the pose to
        NEWTON_TOL. A pose that does not close to MODE_TOL is dropped (a spurious root of
        the eliminant), duplicates are merged. Near-real roots (imaginary part below
        ``1e-6 (1 + |T|)``) are tried too, so that double roots at singular
        configurations are kept.

        Returns:
            poses, shape (n_modes, 3), ``0 <= n_modes <= 6``, sorted by theta in (-pi, pi].

        Raises:
            InputError: wrong shape or non-finite values.
            SingularityError: the eliminant vanishes identically (an architecture
                singularity: a continuum of assembly modes).
        """
        s = as_array(actuators, (N_ACTUATORS,), "actuators")
        poly = self.assembly_polynomial(s)
        centres = self.slider_points(s)
        coef = np.trim_zeros(poly.coefficients, "b")
        if coef.size == 0 or np.max(np.abs(coef)) == 0.0:
            raise SingularityError("assembly polynomial (identically zero)", 0.0, None,
                                   "largest coefficient")
        roots = np.polynomial.polynomial.polyroots(coef) if coef.size > 1 else np.zeros(0)
        real = roots[np.abs(roots.imag) <= 1e-6 * (1.0 + np.abs(roots))].real
        found: list[np.ndarray] = []
        for root in real:
            theta = poly.theta_offset + 2.0 * math.atan(root)
            for t in self.translations(theta, centres):
                pose, err, _ = self.newton(np.array([t[0], t[1], theta]), s, NEWTON_TOL, 20)
                if err > MODE_TOL:
                    continue
                pose[2] = wrap(pose[2])
                if not any(same_pose(pose, other) for other in found):
                    found.append(pose)
        found.sort(key=lambda p: p[2])
        return np.array(found).reshape(-1, 3)

    def translations(self, theta: float, centres: np.ndarray) -> list[np.ndarray]:
        """Candidate platform origins ``t`` at a given theta (see :meth:`assembly_modes`)."""
        e = self.pts @ rot2(theta).T - centres
        a = 2.0 * (e[1:] - e[0])
        b = -(np.einsum("ki,ki->k", e[1:], e[1:]) - e[0] @ e[0])
        sv = np.linalg.svd(a, compute_uv=False)
        if sv[-1] > 1e-8 * max(sv[0], 1e-300):
            return [np.linalg.solve(a, b)]
        # rank-deficient: t = t_p + lam * n on the line, then |t + e_0|^2 = L^2
        t_p, *_ = np.linalg.lstsq(a, b, rcond=None)
        _, _, vt = np.linalg.svd(a)
        n = vt[-1]
        w = t_p + e[0]
        qb, qc = 2.0 * n @ w, w @ w - self.length ** 2
        disc = qb * qb - 4.0 * qc
        if disc < 0.0:
            return []
        root = math.sqrt(disc)
        return [t_p + lam * n for lam in ((-qb + root) / 2.0, (-qb - root) / 2.0)]

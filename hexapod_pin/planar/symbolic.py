"""Symbolic Lagrangian derivation of the planar 3-PRR robot (sympy, dev/test only).

An independent route to the planar dynamics, in the spirit of the seed's Lagrangian
formulation (its equations 34-40: dynamic parameters, position- and velocity-level
constraint equations, the Lagrangian, EOM1-EOM3 and the overall constrained
formulation). Nothing here uses Pinocchio.

Generalised coordinates (9), in this order::

    q = (s_0, s_1, s_2, phi_0, phi_1, phi_2, x, y, theta)

``s_k`` the slider coordinates along ``u_k`` (m), ``phi_k`` the link angles measured from
``u_k`` (rad; link k points along ``a_k + 90 deg + phi_k`` in the world, the same
coordinate as the URDF's ``link_<k>_joint``), ``(x, y, theta)`` the platform pose.

Position-level constraints (6 rows, two per loop, world x and y)::

    Phi_k(q) = m_k + s_k u_k + L (cos b_k, sin b_k) - (x, y) - R(theta) p_k = 0,
    b_k = a_k + pi/2 + phi_k

velocity level ``A(q) qdot = 0`` with ``A = dPhi/dq`` (6 x 9), acceleration level
``A qddot + Adot qdot = 0``.

Lagrangian ``T - V`` with sliders as point masses, links as thin uniform rods
(``m L^2 / 12`` about their centre), the platform a rigid body with its centre of mass at
its origin; ``V`` is the gravity potential, gravity ``-g`` along y. Lagrange's equations
with multipliers::

    d/dt dT/dqdot - dT/dq + dV/dq = Q + A^T lambda
    <=>  M(q) qddot + C(q, qdot) + G(q) = Q + A(q)^T lambda

with ``M = d^2 T / dqdot^2``, ``C = (d/dq dT/dqdot) qdot - dT/dq`` (Coriolis and
centrifugal terms), ``G = dV/dq``, and the generalised force of the actuators and of the
external wrench ``Q = (tau_0, tau_1, tau_2, 0, 0, 0, fx, fy, mz)`` (virtual work:
``tau_k ds_k + fx dx + fy dy + mz dtheta``). ``lambda`` (6,) are the forces (N) that the
platform joints transmit, world axes.

Code generation: the expressions are turned into numpy functions with
``sympy.lambdify`` (common-subexpression elimination on) at first use, and cached in the
process (:func:`numeric_functions`); the geometry enters as arguments, so one
generated set serves every :class:`~hexapod_pin.planar.geometry.PlanarGeometry`. sympy is imported
lazily inside functions: it is a test/dev dependency, never needed by the runtime package.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import SingularityError
from .geometry import PlanarGeometry
from ..core.checks import as_array

N_COORDINATES = 9
N_CONSTRAINTS = 6
#: names of the generalised coordinates, in order
COORDINATE_NAMES = ("s_0", "s_1", "s_2", "phi_0", "phi_1", "phi_2", "x", "y", "theta")
#: names of the geometry parameters, in the order the generated functions take them
PARAMETER_NAMES = ("rail_radius", "platform_radius", "link_length", "slider_mass",
                   "link_mass", "platform_mass", "platform_inertia", "gravity")


@dataclass(frozen=True)
class PlanarEquations:
    """The symbolic model (sympy objects).

    Attributes:
        q: the generalised coordinates (9 symbols).
        qdot: the generalised velocities (9 symbols).
        parameters: geometry symbols, in :data:`PARAMETER_NAMES` order.
        tau: the three actuator forces.
        wrench: ``(fx, fy, mz)``.
        constraints: ``Phi(q)`` (6 x 1), position level.
        constraint_jacobian: ``A = dPhi/dq`` (6 x 9).
        constraint_drift: ``Adot qdot`` (6 x 1).
        kinetic_energy: ``T``.
        potential_energy: ``V``.
        lagrangian: ``T - V``.
        mass_matrix: ``M`` (9 x 9).
        coriolis: ``C`` (9 x 1).
        gravity: ``G`` (9 x 1).
        generalized_force: ``Q`` (9 x 1), linear in ``tau`` and the wrench.
    """

    q: Any
    qdot: Any
    parameters: Any
    tau: Any
    wrench: Any
    constraints: Any
    constraint_jacobian: Any
    constraint_drift: Any
    kinetic_energy: Any
    potential_energy: Any
    lagrangian: Any
    mass_matrix: Any
    coriolis: Any
    gravity: Any
    generalized_force: Any


@functools.lru_cache(maxsize=1)
def derive_equations() -> PlanarEquations:
    """Derive the constrained equations of motion (see the module docstring).

    Cached: the derivation runs once per process (about a second).
    """
    import sympy as sp

    q = sp.Matrix(sp.symbols("s_0 s_1 s_2 phi_0 phi_1 phi_2 x y theta", real=True))
    qd = sp.Matrix(sp.symbols("sd_0 sd_1 sd_2 phid_0 phid_1 phid_2 xd yd thetad", real=True))
    params = sp.symbols("R r L m_s m_l m_p I_p g", positive=True)
    big_r, small_r, length, m_s, m_l, m_p, i_p, g = params
    tau = sp.Matrix(sp.symbols("tau_0 tau_1 tau_2", real=True))
    wrench = sp.Matrix(sp.symbols("f_x f_y m_z", real=True))
    s, phi, x, y, theta = q[0:3], q[3:6], q[6], q[7], q[8]

    def vel(point):  # time derivative of a point (2 x 1) along qdot
        return point.jacobian(q) * qd

    kinetic, potential, rows = sp.Integer(0), sp.Integer(0), []
    platform = sp.Matrix([x, y])
    kinetic += m_p / 2 * (vel(platform).dot(vel(platform))) + i_p / 2 * qd[8] ** 2
    potential += m_p * g * y
    for k in range(3):
        a = sp.pi / 2 + 2 * sp.pi * k / 3
        mid = big_r * sp.Matrix([sp.cos(a), sp.sin(a)])
        u = sp.Matrix([-sp.sin(a), sp.cos(a)])
        slider = mid + s[k] * u
        beta = a + sp.pi / 2 + phi[k]
        direction = sp.Matrix([sp.cos(beta), sp.sin(beta)])
        centre = slider + length / 2 * direction
        tip = slider + length * direction
        point = platform + small_r * sp.Matrix([sp.cos(a + theta), sp.sin(a + theta)])
        kinetic += m_s / 2 * vel(slider).dot(vel(slider))
        kinetic += m_l / 2 * vel(centre).dot(vel(centre)) + m_l * length ** 2 / 24 * qd[3 + k] ** 2
        potential += g * (m_s * slider[1] + m_l * centre[1])
        rows.extend([tip[0] - point[0], tip[1] - point[1]])
    phi_c = sp.Matrix(rows)
    jac = phi_c.jacobian(q)
    drift = (jac * qd).jacobian(q) * qd
    # tidy T (sin^2 + cos^2 = 1 per link) so that M prints as the textbook matrix
    kinetic = sp.expand(sp.expand(sp.expand_trig(kinetic))
                        .subs({sp.sin(p) ** 2: 1 - sp.cos(p) ** 2 for p in phi}))
    momentum = sp.Matrix([kinetic]).jacobian(qd).T          # dT/dqdot (9 x 1)
    mass = momentum.jacobian(qd)                               # d2T/dqdot2
    coriolis = momentum.jacobian(q) * qd - sp.Matrix([kinetic]).jacobian(q).T
    gravity = sp.Matrix([potential]).jacobian(q).T
    force = sp.Matrix([tau[0], tau[1], tau[2], 0, 0, 0, wrench[0], wrench[1], wrench[2]])
    return PlanarEquations(q, qd, params, tau, wrench, phi_c, jac, drift, kinetic, potential,
                           kinetic - potential, mass, coriolis, gravity, force)


@dataclass(frozen=True)
class NumericFunctions:
    """Numpy functions generated from :func:`derive_equations` by ``sympy.lambdify``.

    Each takes ``(q, qdot, params)`` (``q``, ``qdot`` of shape (9,), ``params`` of shape
    (8,) in :data:`PARAMETER_NAMES` order) and returns a numpy array.
    """

    mass_matrix: Callable
    coriolis: Callable
    gravity: Callable
    constraints: Callable
    constraint_jacobian: Callable
    constraint_drift: Callable
    kinetic_energy: Callable
    potential_energy: Callable


@functools.lru_cache(maxsize=1)
def numeric_functions() -> NumericFunctions:
    """Lambdified numeric functions, generated at first use and cached in the process."""
    import sympy as sp

    eq = derive_equations()
    args = (list(eq.q), list(eq.qdot), list(eq.parameters))

    def gen(expr):
        return sp.lambdify(args, expr, modules="numpy", cse=True)

    return NumericFunctions(gen(eq.mass_matrix), gen(eq.coriolis), gen(eq.gravity),
                            gen(eq.constraints), gen(eq.constraint_jacobian),
                            gen(eq.constraint_drift), gen(eq.kinetic_energy),
                            gen(eq.potential_energy))


@dataclass(frozen=True)
class SymbolicForwardDynamics:
    """Result of :meth:`PlanarSymbolicDynamics.forward_dynamics`.

    Attributes:
        qddot: generalised accelerations (9,) (m/s^2, rad/s^2).
        multipliers: ``lambda`` (6,) (N), world axes, two per platform joint.
    """

    qddot: np.ndarray
    multipliers: np.ndarray


@dataclass(frozen=True)
class SymbolicInverseDynamics:
    """Result of :meth:`PlanarSymbolicDynamics.inverse_dynamics`.

    Attributes:
        forces: actuator forces ``tau`` (3,) (N) along ``+u_k``.
        multipliers: ``lambda`` (6,) (N), world axes, two per platform joint.
    """

    forces: np.ndarray
    multipliers: np.ndarray


class PlanarSymbolicDynamics:
    """Numeric evaluation of the symbolic model for one geometry.

    Coordinates as in the module docstring; ``wrench`` ``(fx, fy, mz)`` on the platform
    about its origin (world axes); ``forces`` the actuator forces along ``+u_k`` (N).

    Args:
        geometry: design parameters; default :class:`PlanarGeometry` ().
    """

    def __init__(self, geometry: PlanarGeometry | None = None) -> None:
        self.geometry = PlanarGeometry() if geometry is None else geometry
        self.params = np.array([getattr(self.geometry, n) for n in PARAMETER_NAMES])
        self.functions = numeric_functions()

    def _eval(self, fn, q, qd=None) -> np.ndarray:
        q = as_array(q, (N_COORDINATES,), "q")
        qd = np.zeros(N_COORDINATES) if qd is None else as_array(qd, (N_COORDINATES,), "qdot")
        return np.array(fn(q, qd, self.params), dtype=float)

    def mass_matrix(self, q: npt.ArrayLike) -> np.ndarray:
        """``M(q)`` (9, 9) (kg, kg m, kg m^2)."""
        return self._eval(self.functions.mass_matrix, q)

    def bias(self, q: npt.ArrayLike, qdot: npt.ArrayLike) -> np.ndarray:
        """``C(q, qdot) + G(q)`` (9,) (N, N m)."""
        c = self._eval(self.functions.coriolis, q, qdot).reshape(-1)
        return c + self._eval(self.functions.gravity, q).reshape(-1)

    def constraints(self, q: npt.ArrayLike) -> np.ndarray:
        """``Phi(q)`` (6,) (m): link tip minus platform point, world x and y per loop."""
        return self._eval(self.functions.constraints, q).reshape(-1)

    def constraint_jacobian(self, q: npt.ArrayLike) -> np.ndarray:
        """``A(q) = dPhi/dq`` (6, 9)."""
        return self._eval(self.functions.constraint_jacobian, q)

    def constraint_drift(self, q: npt.ArrayLike, qdot: npt.ArrayLike) -> np.ndarray:
        """``Adot qdot`` (6,) (m/s^2)."""
        return self._eval(self.functions.constraint_drift, q, qdot).reshape(-1)

    def energy(self, q: npt.ArrayLike, qdot: npt.ArrayLike) -> tuple[float, float]:
        """Kinetic and potential energy ``(T, V)`` (J); ``V = 0`` at y = 0 for every body."""
        t = float(self._eval(self.functions.kinetic_energy, q, qdot))
        v = float(self._eval(self.functions.potential_energy, q))
        return t, v

    def _force(self, forces, wrench) -> np.ndarray:
        out = np.zeros(N_COORDINATES)
        out[:3] = forces
        if wrench is not None:
            out[6:] = as_array(wrench, (3,), "wrench")
        return out

    def forward_dynamics(self, q: npt.ArrayLike, qdot: npt.ArrayLike, forces: npt.ArrayLike,
                         wrench: npt.ArrayLike | None = None) -> SymbolicForwardDynamics:
        """Accelerations from actuator forces: the KKT system of the constrained EOM.

        Solves ``[[M, -A^T], [A, 0]] [qddot; lambda] = [Q - C - G; -Adot qdot]``.

        Raises:
            InputError: a malformed input.
            SingularityError: the KKT matrix is singular (a singular configuration).
        """
        forces = as_array(forces, (3,), "forces")
        mass, jac = self.mass_matrix(q), self.constraint_jacobian(q)
        kkt = np.block([[mass, -jac.T], [jac, np.zeros((N_CONSTRAINTS, N_CONSTRAINTS))]])
        rhs = np.concatenate([self._force(forces, wrench) - self.bias(q, qdot),
                              -self.constraint_drift(q, qdot)])
        sol = _solve(kkt, rhs, "symbolic KKT matrix")
        return SymbolicForwardDynamics(sol[:N_COORDINATES], sol[N_COORDINATES:])

    def inverse_dynamics(self, q: npt.ArrayLike, qdot: npt.ArrayLike, qddot: npt.ArrayLike,
                         wrench: npt.ArrayLike | None = None) -> SymbolicInverseDynamics:
        """Actuator forces for a motion: ``M qddot + C + G - Q_ext = B tau + A^T lambda``.

        ``B`` selects the three slider coordinates; the 9 x 9 system in
        ``(tau, lambda)`` is square.

        Raises:
            InputError: a malformed input.
            SingularityError: the system is singular (a singular configuration).
        """
        qddot = as_array(qddot, (N_COORDINATES,), "qddot")
        lhs = self.mass_matrix(q) @ qddot + self.bias(q, qdot) \
            - self._force(np.zeros(3), wrench)
        select = np.zeros((N_COORDINATES, 3))
        select[:3, :3] = np.eye(3)
        sol = _solve(np.hstack([select, self.constraint_jacobian(q).T]), lhs,
                     "symbolic inverse-dynamics matrix")
        return SymbolicInverseDynamics(sol[:3], sol[3:])

    def complete_velocity(self, q: npt.ArrayLike, twist: npt.ArrayLike) -> np.ndarray:
        """``qdot`` (9,) with the platform rates ``twist`` and ``A qdot = 0``."""
        twist = as_array(twist, (3,), "twist")
        jac = self.constraint_jacobian(q)
        out = np.zeros(N_COORDINATES)
        out[6:] = twist
        out[:6] = _solve(jac[:, :6], -jac[:, 6:] @ twist, "constraint Jacobian (sliders, links)")
        return out

    def complete_acceleration(self, q: npt.ArrayLike, qdot: npt.ArrayLike,
                              twist_dot: npt.ArrayLike) -> np.ndarray:
        """``qddot`` (9,) with the platform part ``twist_dot`` and ``A qddot = -Adot qdot``."""
        twist_dot = as_array(twist_dot, (3,), "twist_dot")
        jac = self.constraint_jacobian(q)
        out = np.zeros(N_COORDINATES)
        out[6:] = twist_dot
        rhs = -self.constraint_drift(q, qdot) - jac[:, 6:] @ twist_dot
        out[:6] = _solve(jac[:, :6], rhs, "constraint Jacobian (sliders, links)")
        return out


def _solve(matrix: np.ndarray, rhs: np.ndarray, what: str) -> np.ndarray:
    sv = np.linalg.svd(matrix, compute_uv=False)
    if sv[-1] <= 1e-12 * sv[0]:
        raise SingularityError(what, sv[-1])
    return np.linalg.solve(matrix, rhs)


__all__ = ["COORDINATE_NAMES", "PARAMETER_NAMES", "NumericFunctions",
           "PlanarEquations", "PlanarSymbolicDynamics", "SymbolicForwardDynamics",
           "SymbolicInverseDynamics", "derive_equations", "numeric_functions"]

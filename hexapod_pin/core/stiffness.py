"""Cartesian stiffness and vibration modes of any robot at a static pose, from the
forward-dynamics derivatives of :mod:`hexapod_pin.core.platform_derivatives`.

Actuators act as linear springs of stiffness ``K_a = diag(k)`` (N/m or N m/rad) preloaded
with the static forces ``tau_s`` that hold gravity and the wrench ``W`` at the pose ``x0``.
At a nearby pose ``x`` (world tangent ``(dp, dtheta)`` of
:class:`~hexapod_pin.core.platform_derivatives.ForwardDynamicsDerivatives`) the net wrench
on the platform is ``W_net(x) = J(x)^T (tau_0 - K_a (q_a(x) - q_a(x0))) - J(x)^T tau_s(x)``
(``tau_0 = tau_s(x0)``, ``J`` the actuator Jacobian, ``q_a`` the actuator positions), and
the Cartesian stiffness is ``K_x = -dW_net/dx = J^T K_a J + K_g``.

The geometric (preload) stiffness ``K_g = J^T dtau_s/dx`` is read from the forward
dynamics at the equilibrium: with the actuator forces held at ``tau_0``, ``M_x
d(twist_dot)/dx = d(J^T tau_0 + W - h_x)/dx = -K_g``, so ``K_g = -M_x d_world`` with ``M_x =
d_wrench^-1`` (the platform mass matrix, with the armature). It holds the change of the
transmission under the preload (``dJ^T tau_0``), of the gravity load and of the joint
springs of the effects (``clm.effects.stiffness``, passive joints included). The modes
solve ``K_x phi = omega^2 M_x phi``. Equations and tests: ``docs/derivations.md``
(section 8).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt
import scipy.linalg

from ..errors import InputError, SingularityError, SolverError
from .checks import max_abs, per_actuator
from .platform_derivatives import PlatformRobot, forward_dynamics_derivatives
from .platform_map import solve_checked_square

#: relative mismatch accepted between the routes that must agree (``M_x d_u = J^T``, the
#: equilibrium ``twist_dot = 0``, the eigen-residuals)
STIFFNESS_RTOL = 1e-7


class StaticRobot(PlatformRobot, Protocol):
    """What this module reads from a robot beyond :class:`PlatformRobot`."""

    def static_forces(self, pose: npt.ArrayLike, wrench: npt.ArrayLike | None = None, *,
                      branch: Any = None, bounded: bool = True) -> np.ndarray: ...

    def jacobian(self, pose: npt.ArrayLike, branch: Any = None) -> np.ndarray: ...


@dataclass(frozen=True)
class CartesianStiffness:
    """The Cartesian stiffness at a static pose (module docstring), from
    ``robot.cartesian_stiffness(pose, actuator_stiffness, wrench)``.

    Rows and columns: the world tangent ``(dp, dtheta)`` of the pose components (the
    robot's pose order); units N/m, N/rad, N m/m, N m/rad by block. ``matrix @ dx`` is the
    restoring wrench's negative, ``-dW_net``.

    Attributes:
        matrix: ``K_x = elastic + geometric`` (dim, dim).
        elastic: ``J^T K_a J`` (dim, dim), symmetric.
        geometric: ``K_g`` (dim, dim) (symmetric for conservative loads at equilibrium,
            e.g. gravity; a constant world moment makes it asymmetric).
        static_forces: ``tau_s`` (n_act,) (N, N m), the preload.
        jacobian: ``J`` (n_act, dim), actuator velocities ``= J twist``.
        mass_matrix: ``M_x`` (dim, dim) (kg, kg m, kg m^2).
    """

    matrix: np.ndarray
    elastic: np.ndarray
    geometric: np.ndarray
    static_forces: np.ndarray
    jacobian: np.ndarray
    mass_matrix: np.ndarray

    @property
    def compliance(self) -> np.ndarray:
        """``K_x^-1`` (dim, dim): the displacement per unit wrench.

        Raises:
            SingularityError: ``K_x`` singular (a direction no actuator stiffens).
        """
        try:
            return solve_checked_square(self.matrix, np.eye(self.matrix.shape[0]),
                                        "compliance")
        except SolverError:
            sv = np.linalg.svd(self.matrix, compute_uv=False)
            raise SingularityError("Cartesian stiffness (no compliance)", float(sv[-1]),
                                   None, "smallest singular value") from None

    @property
    def principal_stiffnesses(self) -> np.ndarray:
        """Eigenvalues (dim,) of the symmetric part of ``K_x``, ascending (units mix
        linear and angular components when the pose has both: compare blocks, or scale
        by a length)."""
        return np.linalg.eigh(0.5 * (self.matrix + self.matrix.T))[0]

    @property
    def principal_directions(self) -> np.ndarray:
        """Unit eigenvectors (dim, dim), columns in the order of
        :attr:`principal_stiffnesses`."""
        return np.linalg.eigh(0.5 * (self.matrix + self.matrix.T))[1]


@dataclass(frozen=True)
class VibrationModes:
    """Small-oscillation modes about a static pose, ``K_x phi = omega^2 M_x phi``, from
    ``robot.vibration_modes(pose, actuator_stiffness)``.

    Attributes:
        frequencies: (dim,) natural frequencies ``omega / (2 pi)`` (Hz), ascending.
        eigenvalues: (dim,) ``omega^2`` (1/s^2), ascending, >= 0.
        shapes: (dim, dim) the mode shapes as columns (world tangent ``(dp, dtheta)``),
            ``M_x``-orthonormal: ``shapes.T @ M_x @ shapes = I``.
        stiffness: the :class:`CartesianStiffness` they come from (its ``mass_matrix`` is
            ``M_x``).
    """

    frequencies: np.ndarray
    eigenvalues: np.ndarray
    shapes: np.ndarray
    stiffness: CartesianStiffness


def actuator_stiffness_of(value: npt.ArrayLike, n_act: int) -> np.ndarray:
    """``k`` (n_act,) from a scalar or an (n_act,) array, each finite and >= 0.

    Raises:
        InputError: another shape, NaN / inf or a negative value.
    """
    arr = per_actuator(value, n_act, "actuator_stiffness")
    if (arr < 0).any():
        raise InputError("actuator_stiffness", value, "must be >= 0 (N/m or N m/rad)")
    return np.array(arr)


def cartesian_stiffness(robot: StaticRobot, pose: npt.ArrayLike,
                        actuator_stiffness: npt.ArrayLike, wrench: npt.ArrayLike | None = None,
                        branch: Any = None) -> CartesianStiffness:
    """The Cartesian stiffness ``K_x = J^T K_a J + K_g`` at a static pose (module
    docstring).

    Args:
        robot: any robot of the library (its ``static_forces``, ``jacobian`` and the
            forward-dynamics derivatives are used).
        pose: (dim,) (m, rad).
        actuator_stiffness: ``k`` scalar or (n_act,) (N/m, N m/rad), >= 0.
        wrench: (dim,) held on the platform (world axes, moment about its origin); None:
            zero (gravity only).
        branch: the working mode (as the robot's other methods take it).

    Returns:
        :class:`CartesianStiffness`.

    Raises:
        InputError: bad shapes, NaN / inf, a negative stiffness; Coulomb friction in the
            model (every joint at rest: the static forces are set-valued).
        UnreachablePoseError: the pose is out of reach.
        SingularityError: a singular pose.
        SolverError: the routes disagree (``M_x d_u != J^T``, or the static forces do not
            hold the platform at rest), to :data:`STIFFNESS_RTOL`.
    """
    n_act = robot.model.n_actuated
    k = actuator_stiffness_of(actuator_stiffness, n_act)
    dim = robot.pose_layout.dim
    held = robot.static_forces(pose, wrench, branch=branch, bounded=False)
    der = forward_dynamics_derivatives(robot, pose, np.zeros(dim), held, wrench, branch)
    jac = np.asarray(robot.jacobian(pose, branch), dtype=float)
    mass = solve_checked_square(der.d_wrench, np.eye(dim), "platform mass matrix")
    mass = 0.5 * (mass + mass.T)
    scale = max(1.0, max_abs(jac))
    if not max_abs(mass @ der.d_actuator_forces - jac.T) <= STIFFNESS_RTOL * scale:
        raise SolverError("cartesian_stiffness", "unverified",
                          "M_x d_actuator_forces differs from J^T by "
                          f"{max_abs(mass @ der.d_actuator_forces - jac.T):.3e}")
    accel = max(1.0, max_abs(der.d_actuator_forces @ held))
    if not max_abs(der.twist_dot) <= STIFFNESS_RTOL * accel:
        raise SolverError("cartesian_stiffness", "unverified",
                          f"the static forces leave twist_dot = {max_abs(der.twist_dot):.3e}")
    elastic = jac.T @ (k[:, None] * jac)
    geometric = -mass @ der.d_world
    return CartesianStiffness(elastic + geometric, elastic, geometric, np.array(held), jac,
                              mass)


def vibration_modes(robot: StaticRobot, pose: npt.ArrayLike,
                    actuator_stiffness: npt.ArrayLike, branch: Any = None) -> VibrationModes:
    """Natural frequencies and mode shapes about a static pose under gravity
    (``K_x phi = omega^2 M_x phi`` with :func:`cartesian_stiffness` at zero wrench).

    Args:
        robot: any robot of the library.
        pose: (dim,) (m, rad).
        actuator_stiffness: ``k`` scalar or (n_act,) (N/m, N m/rad), >= 0.
        branch: the working mode.

    Returns:
        :class:`VibrationModes`, frequencies ascending (Hz).

    Raises:
        InputError: see :func:`cartesian_stiffness`.
        UnreachablePoseError: the pose is out of reach.
        SingularityError: a singular pose, or ``K_x`` not positive semi-definite (the
            preloaded platform is statically unstable: an eigenvalue ``omega^2 < 0``).
        SolverError: see :func:`cartesian_stiffness`; an asymmetric ``K_x`` (beyond
            :data:`STIFFNESS_RTOL`, relative) or eigenvectors that miss their equation.
    """
    st = cartesian_stiffness(robot, pose, actuator_stiffness, None, branch)
    kmat, mass = st.matrix, st.mass_matrix
    size = max(1e-300, max_abs(kmat))
    if not max_abs(kmat - kmat.T) <= STIFFNESS_RTOL * size:
        raise SolverError("vibration_modes", "unverified", "the Cartesian stiffness is "
                          f"asymmetric by {max_abs(kmat - kmat.T) / size:.3e} (relative)")
    sym = 0.5 * (kmat + kmat.T)
    values, shapes = scipy.linalg.eigh(sym, mass)
    if values[0] < -STIFFNESS_RTOL * max(1e-300, float(np.max(np.abs(values)))):
        raise SingularityError("Cartesian stiffness not positive semi-definite (statically "
                               "unstable under the preload)", float(values[0]), 0.0,
                               "smallest omega^2 (1/s^2)")
    miss = max_abs(sym @ shapes - (mass @ shapes) * values)
    if not miss <= STIFFNESS_RTOL * max(size, max_abs(mass) * float(np.max(np.abs(values)))):
        raise SolverError("vibration_modes", "unverified", f"eigen-residual {miss:.3e}")
    values = np.maximum(values, 0.0)
    return VibrationModes(np.sqrt(values) / (2.0 * np.pi), values, shapes, st)

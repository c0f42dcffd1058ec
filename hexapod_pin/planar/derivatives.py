"""Analytic derivatives of the planar 3-PRR's inverse dynamics.

``tau = ID(pose, twist, twist_dot, wrench)`` (the unbounded closed-form route) solves the
tree equations (conventions of :mod:`hexapod_pin.planar.dynamics`)::

    rnea(q, v, a) - tau_ext(wrench) = S^T tau + A(q)^T lambda
    Phi(q) = 0,   A(q) v = 0,   A(q) a + gamma(q, v) = 0

with ``A`` the in-plane closure rows (per loop k, columns slider k: ``u_k``, link k:
``z x n_k``, platform: ``(-I, -(z x r_k))``) and ``gamma_k = -phi'_k^2 n_k + omega^2 r_k``.
The implicit-function theorem on that square system gives every derivative exactly:
along a direction of (pose, twist, twist_dot, wrench) with the platform rows of the tree
state prescribed (``dq = G dpose``, ``G`` the velocity map), the closures give the leg
rows of ``dv`` and ``da`` from the second derivatives of ``Phi`` (``d(z x n_k)/dphi_k =
-n_k``, ``d(z x r_k)/dtheta = -r_k``)::

    A dv = n_k phi'_k dphi_k - omega r_k dtheta                    (pose)
    A da = n_k phi''_k dphi_k - alpha r_k dtheta + phi'^2 (z x n_k) dphi_k
           - omega^2 (z x r_k) dtheta + 2 phi'_k n_k dphi'_k - 2 omega r_k domega

Pinocchio's ``computeRNEADerivatives`` gives ``d rnea``; then
``[S^T A^T] (dtau, dlambda) = d rnea - d(tau_ext) - d(A^T) lambda`` with
``d(A^T lambda)`` ``-n_k . lambda_k dphi_k`` on link k's row and
``sum_k r_k . lambda_k dtheta`` on the theta row. The pose is ``(x, y, theta)``: its
coordinates are world tangent coordinates, and the twist, twist_dot and wrench are held
in world axes. The joint effects (``robot.effects``) move ``tau_e(q, v, a)`` to the left,
``rnea - tau_e``: its derivative adds ``diag(K)`` to ``d rnea / dq`` and ``diag(D)`` to
``d rnea / dv`` (every joint of the planar tree has one coordinate, so ``dDifference`` is the
identity; Coulomb friction is piecewise constant, the armature is in Pinocchio's ``M``). The
ID is linear in twist_dot and wrench, so those blocks are exact coefficients; the tests
check every block against Richardson-extrapolated central differences of the inverse
dynamics, and against the core's route (``core.platform_derivatives.
inverse_dynamics_derivatives``, the implicit-function theorem on the core's KKT
derivatives, which every loaded robot uses; this closed form stays as the faster kernel).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..core.results import InverseDynamicsDerivatives
from ..errors import SingularityError
from .dynamics import PlanarDynamics
from .geometry import N_ACTUATORS

#: the square system ``[S^T A^T]`` is called singular (type II) below this reciprocal
#: condition number
_RCOND = 1e-12


def inverse_dynamics_derivatives(dynamics: PlanarDynamics, pose: npt.ArrayLike,
                                 twist: npt.ArrayLike, twist_dot: npt.ArrayLike,
                                 wrench: npt.ArrayLike | None = None) -> InverseDynamicsDerivatives:
    """The derivatives of the module docstring at one state (home branch).

    Raises:
        InputError: bad shape, non-finite or non-real values.
        UnreachablePoseError: a leg cannot reach the pose.
        SingularityError: at a singular configuration (type I, or type II where the square system is
            singular).
    """
    res = dynamics.inverse_dynamics(pose, twist, twist_dot, wrench, method="kkt",
                                    bounded=False, joint_wrenches=False)
    ws, clm = dynamics.ws, dynamics.model
    q, v, a = res.configuration, res.velocity, res.acceleration
    idx = ws.indices
    vmap = dynamics.reduced_dynamics(pose, twist).velocity_map
    model, data = clm.model, dynamics.data
    d_q, d_v, mass = pin.computeRNEADerivatives(model, data, q, v, a)
    d_q, d_v, mass = d_q.copy(), d_v.copy(), np.triu(mass) + np.triu(mass, 1).T
    effects = clm.effects                # the springs' and dampers' share of rnea - tau_e
    d_q[np.diag_indices(ws.nv)] += effects.stiffness
    d_v[np.diag_indices(ws.nv)] += effects.damping
    rows = np.concatenate([[r, r + 1] for r in ws.rows])
    a_c = dynamics.dyn.constraint_jacobian(q)[rows]                # (6, nv) in-plane rows
    square = np.zeros((ws.nv, ws.nv))
    square[idx.slider, np.arange(N_ACTUATORS)] = 1.0
    square[:, N_ACTUATORS:] = a_c.T
    if np.linalg.cond(square) * _RCOND > 1.0:
        raise SingularityError("closed-loop dynamics [S^T A^T] (type-II singularity)",
                               float(np.linalg.svd(square, compute_uv=False)[-1]))
    lam = res.multipliers[rows].reshape(N_ACTUATORS, 2)
    theta, omega, alpha = q[idx.platform[2]], v[idx.platform[2]], a[idx.platform[2]]
    c, s = np.cos(theta), np.sin(theta)
    arms = ws.pts @ np.array([[c, s], [-s, c]])             # r_k, world axes
    links = np.stack([arms[k] + q[idx.platform[:2]] - ws.mids[k]
                      - q[idx.slider[k]] * ws.dirs[k] for k in range(N_ACTUATORS)])
    phid, phidd = v[idx.link], a[idx.link]

    def leg_rows(rhs: Sequence[np.ndarray]) -> np.ndarray:
        """Solve the closures' leg block: (s, phi) rates of each loop from its 2 rows."""
        out = np.zeros(ws.nv)
        for k in range(N_ACTUATORS):
            u, n = ws.dirs[k], links[k]
            block = np.array([[u[0], -n[1]], [u[1], n[0]]])
            out[idx.slider[k]], out[idx.link[k]] = np.linalg.solve(block, rhs[k])
        return out

    def cross_z(w):
        return np.array([-w[1], w[0]])

    def solve(rhs_tree: np.ndarray) -> np.ndarray:
        return np.linalg.solve(square, rhs_tree)[:N_ACTUATORS]

    d_pose = np.empty((N_ACTUATORS, 3))
    for j in range(3):
        dq = vmap[:, j]
        dphi, dth = dq[idx.link], dq[idx.platform[2]]
        dv = leg_rows([links[k] * phid[k] * dphi[k] - omega * arms[k] * dth
                       for k in range(N_ACTUATORS)])
        dphid = dv[idx.link]
        da = leg_rows([links[k] * phidd[k] * dphi[k] - alpha * arms[k] * dth
                       + phid[k] ** 2 * cross_z(links[k]) * dphi[k]
                       - omega ** 2 * cross_z(arms[k]) * dth
                       + 2.0 * phid[k] * links[k] * dphid[k] for k in range(N_ACTUATORS)])
        rhs = d_q @ dq + d_v @ dv + mass @ da
        rhs[idx.link] += np.einsum("ki,ki->k", links, lam) * dphi
        rhs[idx.platform[2]] -= np.einsum("ki,ki->", arms, lam) * dth
        d_pose[:, j] = solve(rhs)
    d_twist = np.empty((N_ACTUATORS, 3))
    for j in range(3):
        dv = vmap[:, j]
        dphid, domega = dv[idx.link], dv[idx.platform[2]]
        da = leg_rows([2.0 * phid[k] * links[k] * dphid[k] - 2.0 * omega * arms[k] * domega
                       for k in range(N_ACTUATORS)])
        d_twist[:, j] = solve(d_v @ dv + mass @ da)
    d_twist_dot = np.linalg.solve(square, mass @ vmap)[:N_ACTUATORS]
    ext = np.zeros((ws.nv, 3))
    ext[idx.platform, np.arange(3)] = -1.0
    d_wrench = np.linalg.solve(square, ext)[:N_ACTUATORS]
    # in the plane the world tangent (dx, dy, dtheta) is the pose's own coordinates
    return InverseDynamicsDerivatives(res.actuator_forces.copy(), d_pose, d_pose.copy(),
                                      d_twist, d_twist_dot, d_wrench)

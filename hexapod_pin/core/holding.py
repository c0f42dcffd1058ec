"""The holding band: the actuator forces that hold a robot at rest when Coulomb friction
can help, :func:`holding_band`.

At rest (``v = a = 0``) at a pose, the tree's equation of motion (Pinocchio's ``v``
order; :mod:`~hexapod_pin.core.dynamics`) is::

    S^T u + J_c(q)^T lambda + E f = g(q) - tau_spring(q) - tau_ext,    |f_j| <= c_j

with ``g`` the generalised gravity (``pin.computeGeneralizedGravity``), ``tau_spring =
-K dq`` the springs of the joint effects (:func:`~hexapod_pin.core.effects.passive_forces`
at ``v = 0``), ``tau_ext = P^T W`` the platform wrench ``W`` (the selection
``robot.pose_axes`` of ``(f, m)``, world axes, moment about the platform origin; ``P`` the
matching rows of the platform frame's ``LOCAL_WORLD_ALIGNED`` Jacobian), and ``f`` the
friction force of the coordinates with Coulomb friction (``E`` selects them, ``c_j`` their
``coulomb``; a joint at rest sticks with any friction in that box). Eliminating the
multipliers with an orthonormal basis ``N`` of ``null(J_c)`` leaves the polytope of
holding actuator forces::

    { u : N^T S^T u + N^T E f = N^T rhs  for some  -c <= f <= c }

Its bounding box is the band: ``lower_i`` (``upper_i``) is the smallest (largest) force
actuator ``i`` has in some holding state, the other actuators free; each is one linear
program in ``(u, f)`` solved by HiGHS (``scipy.optimize.linprog``) and verified: the
friction inside its box, the equilibrium rebuilt with least-squares multipliers on the
full tree equation, and the optimum certified by the LP's dual (zero duality gap). With
as many actuators as degrees of freedom and a nonsingular ``A^T = N^T S^T`` the band is
``u_s +- |B| c`` with ``u_s`` the frictionless static forces and ``B = A^-T N^T E``: for
friction on the actuated coordinates only, ``B`` is the identity there and the band is
``u_s +- c`` (the friction of each actuator's own joint). Redundant actuation (more
actuators than degrees of freedom) leaves an actuator unbounded when the others are free:
its band is then ``(-inf, inf)``.

Units: forces N (prismatic) or N m (revolute), joint side (the effects' ``coulomb`` and
the actuator forces ``u`` both act at the joint; a gear does not enter). The derivation:
``docs/drives.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from scipy.optimize import linprog

from ..errors import SolverError
from .checks import as_array
from .dynamics import dynamics_of, null_space_basis
from .effects import passive_forces

#: relative residual accepted on the rebuilt equilibrium and on the LP's duality gap
HOLDING_RTOL = 1e-8

#: the LP status codes of ``scipy.optimize.linprog``
_LP_OPTIMAL, _LP_INFEASIBLE, _LP_UNBOUNDED = 0, 2, 3


@dataclass(frozen=True, eq=False)
class HoldingBand:
    """The actuator forces that hold a pose at rest (see the module docstring); forces in
    N or N m, joint side, ``robot.model.actuated_joints`` order.

    Attributes:
        lower: (n_act,) the smallest force of each actuator in some holding state, the
            others free (``-inf`` when unbounded: redundant actuation).
        upper: (n_act,) the largest such force (``inf`` when unbounded).
        static: (n_act,) the frictionless static forces ``robot.static_forces(pose,
            wrench, bounded=False)`` (springs included), inside ``[lower, upper]``.
        lower_states: (n_act, n_act) row ``i``: the actuator forces of a holding state
            with ``u_i = lower_i`` (NaN-free; a row of an unbounded actuator is
            ``static``).
        upper_states: (n_act, n_act) row ``i``: those of a state with ``u_i = upper_i``.
        friction_coordinates: (k,) the indices into ``v`` of the coordinates with
            Coulomb friction (the ``f`` of the module docstring).
        residual: the largest relative residual of the verified equilibria (rebuilt tree
            equation of motion and LP duality gap), at most :data:`HOLDING_RTOL`.
    """

    lower: np.ndarray
    upper: np.ndarray
    static: np.ndarray
    lower_states: np.ndarray
    upper_states: np.ndarray
    friction_coordinates: np.ndarray
    residual: float

    @property
    def half_widths(self) -> tuple[np.ndarray, np.ndarray]:
        """``(static - lower, upper - static)`` (n_act,) each, >= 0: how far friction lets
        each actuator's force drop below and rise above its frictionless static force."""
        return self.static - self.lower, self.upper - self.static


def platform_generalized_force(robot: Any, q: np.ndarray, wrench: np.ndarray | None,
                               data: pin.Data) -> np.ndarray:
    """``tau_ext = P^T W`` (nv,) (N, N m) of a platform wrench ``W`` (the selection
    ``robot.pose_axes`` of ``(f, m)``, world axes, moment about the platform origin) at the
    tree configuration ``q`` (nq,); zeros for ``wrench`` None."""
    model = robot.model.model
    if wrench is None:
        return np.zeros(model.nv)
    jac = pin.computeFrameJacobian(model, data, q, robot.platform_frame_id,
                                   pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    return np.asarray(jac, dtype=float)[robot.pose_layout.components].T @ wrench


def holding_band(robot: Any, pose: npt.ArrayLike, wrench: npt.ArrayLike | None = None, *,
                 branch: Any = None) -> HoldingBand:
    """The band of actuator forces holding ``pose`` at rest with Coulomb friction.

    Args:
        robot: a robot of the shared API (:class:`~hexapod_pin.Hexapod`,
            :class:`~hexapod_pin.Planar3PRR`, :class:`~hexapod_pin.core.robot.ClosedLoopRobot`),
            its joint effects (``robot.effects``) included: Coulomb friction gives the
            band, springs enter the static forces.
        pose: (dim,) platform pose, ``robot.pose_axes`` (m, rad).
        wrench: (dim,) wrench ON the platform (N, N m; world axes, moment about the
            platform origin); None: gravity only.
        branch: the working mode, as ``robot.configuration`` takes it.

    Returns:
        :class:`HoldingBand`.

    Raises:
        InputError: bad shapes, NaN / inf.
        UnreachablePoseError: the pose is out of reach.
        SingularityError: a singular pose.
        SolverError: an LP that fails, an answer that misses the equilibrium, the friction
            box or its optimality certificate, or static forces that miss the equilibrium
            (the message names the residual).
    """
    dim = len(robot.pose_axes)
    pose = as_array(pose, (dim,), "pose")
    w = None if wrench is None else as_array(wrench, (dim,), "wrench")
    static = np.asarray(robot.static_forces(pose, w, branch=branch, bounded=False),
                        dtype=float)
    q = np.asarray(robot.configuration(pose, branch), dtype=float)
    clm = robot.model
    model, effects = clm.model, clm.effects
    dyn = dynamics_of(clm)
    data = model.createData()
    rhs = pin.computeGeneralizedGravity(model, data, q).copy()
    rhs -= passive_forces(model, effects, q, np.zeros(model.nv))
    rhs -= platform_generalized_force(robot, q, w, data)
    jac = dyn.constraint_jacobian(q) if clm.n_rows else np.zeros((0, model.nv))
    rank = int(np.linalg.matrix_rank(jac)) if jac.size else 0
    basis = null_space_basis(jac, rank)
    problem = _Problem(jac, basis, np.asarray(clm.actuated_v, dtype=int),
                       np.flatnonzero(effects.coulomb), effects.coulomb, rhs)
    problem.check_static(static)
    n = static.size
    lower, upper = static.copy(), static.copy()
    lower_states, upper_states = np.tile(static, (n, 1)), np.tile(static, (n, 1))
    worst = problem.static_residual
    for i in range(n):
        for sense, bound, states in ((1.0, lower, lower_states), (-1.0, upper, upper_states)):
            value, state, res = problem.extreme(i, sense)
            bound[i] = value
            if state is not None:
                states[i] = state
            worst = max(worst, res)
    if np.any(lower > static + HOLDING_RTOL * problem.scale) or \
            np.any(upper < static - HOLDING_RTOL * problem.scale):
        raise SolverError("holding_band", "static outside",
                          f"the static forces {static.tolist()} lie outside the band "
                          f"[{lower.tolist()}, {upper.tolist()}]")
    lower, upper = np.minimum(lower, static), np.maximum(upper, static)
    return HoldingBand(lower, upper, static, lower_states, upper_states,
                       problem.friction, float(worst))


class _Problem:
    """The holding LP of one pose: variables ``x = (u, f)``, ``A_eq x = b_eq``."""

    def __init__(self, jac: np.ndarray, basis: np.ndarray, actuated: np.ndarray,
                 friction: np.ndarray, coulomb: np.ndarray, rhs: np.ndarray) -> None:
        nv = rhs.size
        self.jac, self.rhs, self.friction = jac, rhs, friction
        self.bound = coulomb[friction]
        self.select = np.zeros((nv, actuated.size))
        self.select[actuated, np.arange(actuated.size)] = 1.0
        self.embed = np.zeros((nv, friction.size))
        self.embed[friction, np.arange(friction.size)] = 1.0
        self.full = np.hstack([self.select, self.embed])
        self.a_eq = basis.T @ self.full
        self.b_eq = basis.T @ rhs
        self.n_act = actuated.size
        self.bounds = [(None, None)] * actuated.size + \
            [(-c, c) for c in self.bound.tolist()]
        self.redundant = np.linalg.matrix_rank(self.a_eq[:, :actuated.size]) < actuated.size
        self.scale = max(1.0, float(np.max(np.abs(rhs), initial=0.0)),
                         float(np.max(self.bound, initial=0.0)))
        self.static_residual = 0.0

    def equilibrium_residual(self, x: np.ndarray) -> float:
        """The relative residual of the tree equation rebuilt with least-squares
        multipliers (``|J_c^T lambda + S^T u + E f - rhs| / scale``)."""
        miss = self.rhs - self.full @ x
        if self.jac.size:
            lam = np.linalg.lstsq(self.jac.T, miss, rcond=None)[0]
            miss = miss - self.jac.T @ lam
        return float(np.max(np.abs(miss), initial=0.0)) / max(
            self.scale, float(np.max(np.abs(x), initial=0.0)))

    def check_static(self, static: np.ndarray) -> None:
        """Verify the robot's frictionless static forces on the same equation."""
        res = self.equilibrium_residual(np.concatenate([static, np.zeros(self.bound.size)]))
        if not res <= HOLDING_RTOL:
            raise SolverError("holding_band", "statics",
                              f"the static forces {static.tolist()} miss the tree equation "
                              f"at rest by {res:.3e} (relative)")
        self.static_residual = res

    def extreme(self, i: int, sense: float) -> tuple[float, np.ndarray | None, float]:
        """``min sense * u_i`` over the holding states: ``(u_i, u of the state, residual)``
        (``(-sense inf, None, 0)`` when unbounded)."""
        cost = np.zeros(self.full.shape[1])
        cost[i] = sense
        res = linprog(cost, A_eq=self.a_eq, b_eq=self.b_eq, bounds=self.bounds,
                      method="highs")
        if res.status == _LP_UNBOUNDED and self.redundant:
            return -sense * np.inf, None, 0.0
        if res.status != _LP_OPTIMAL:
            raise SolverError("holding_band", f"LP status {res.status}",
                              f"actuator {i} ({'min' if sense > 0 else 'max'}): {res.message}")
        x = np.asarray(res.x, dtype=float)
        f = x[self.n_act:]
        if np.any(np.abs(f) > self.bound * (1.0 + HOLDING_RTOL) + 1e-300):
            raise SolverError("holding_band", "friction box",
                              f"actuator {i}: friction {f.tolist()} outside +-"
                              f"{self.bound.tolist()}")
        residual = self.equilibrium_residual(x)
        # the optimum certified by the dual: c^T x = b^T y + bounds^T z (zero gap)
        dual = float(self.b_eq @ res.eqlin.marginals)
        if self.bound.size:
            dual += float(-self.bound @ res.lower.marginals[self.n_act:]
                          + self.bound @ res.upper.marginals[self.n_act:])
        gap = abs(float(cost @ x) - dual) / max(self.scale, abs(float(x[i])))
        worst = max(residual, gap)
        if not worst <= HOLDING_RTOL:
            raise SolverError("holding_band", "unverified",
                              f"actuator {i}: equilibrium residual {residual:.3e}, duality "
                              f"gap {gap:.3e} (relative)")
        return float(x[i]), x[:self.n_act].copy(), worst


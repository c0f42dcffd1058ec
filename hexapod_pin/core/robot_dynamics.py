"""Dynamics of a robot loaded from a description, in platform coordinates, from the tree
routes of :mod:`hexapod_pin.core.dynamics` and the maps of
:mod:`hexapod_pin.core.platform_map` (no closed form).

A platform state ``(pose, twist, twist_dot)`` becomes a tree state: ``q`` by the
inverse kinematics, ``v = T twist`` (``T = N A^-1``), ``a = T twist_dot + a_0`` keeping
the closures; a wrench ``W`` on the platform becomes ``tau_ext = P^T W`` with ``P`` the
platform's selected twist rows. Then:

* inverse dynamics: :func:`~hexapod_pin.core.dynamics.inverse_dynamics_tree` ("kkt" or
  "qp", with the robot's force bounds when ``bounded``);
* forward dynamics: "nullspace" solves the reduced equation
  ``M_x twist_dot + h_x = J^T u + W`` (``M_x = T^T M T``, ``h_x = T^T (M a_0 + h -
  tau_e)``, ``M`` with the armature, ``tau_e`` the joint effects' force of
  :mod:`~hexapod_pin.core.effects`; with Coulomb friction at rest the tree's stick / slip
  solve answers instead) and is verified on the tree equation of motion with least-squares multipliers; "pinocchio",
  "qp" and "kkt" are the tree routes of
  :func:`~hexapod_pin.core.dynamics.forward_dynamics_tree`;
* ``closure_forces``: per closure, the force (N, world axes) that the body of ``frame2``
  exerts on the body of ``frame1`` (a weld: the force part of its spatial force), shape
  (n_closures, 3);
* inverse-dynamics derivatives (the facade's ``inverse_dynamics_derivatives``, the one
  chain rule of every robot in :mod:`~hexapod_pin.core.platform_derivatives`): the
  implicit-function theorem on the core's forward-dynamics derivatives at the
  inverse-dynamics forces, ``d tau / d y = -B^-1 d twist_dot / d y`` with ``B = M_x^-1
  J^T``, so ``d tau / d twist_dot = J^-T M_x`` and ``d tau / d wrench = -J^-T``.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import InputError, SolverError
from .checks import as_array, check_batch, flag, max_abs
from .closed_loop import ClosedLoopModel
from .closure_forces import closure_linear_forces
from .dynamics import dynamics_of, forward_dynamics_tree, inverse_dynamics_tree
from .effects_projection import batch_of_states
from .energy import energy_totals
from .platform_map import VelocityMaps, solve_checked_square
from .results import (
    BatchForwardDynamics,
    BatchInverseDynamics,
    BatchReducedDynamics,
    Energies,
    ForwardDynamicsResult,
    InverseDynamicsResult,
    LazyConditioning,
    ReducedDynamics,
)
from .robot_api import FORWARD_DYNAMICS_METHODS, INVERSE_DYNAMICS_METHODS
from .robot_kinematics import RobotKinematics

#: relative residual of the tree equation of motion accepted from the "nullspace" route
NULLSPACE_RTOL = 1e-9


class TreeState(NamedTuple):
    """A platform state on the tree: configuration, maps, velocity, velocity map, and the
    closures' drift ``gamma`` with the platform's acceleration bias (one kinematic pass,
    :meth:`PlatformMap.frame_bias`) that every route of the state reuses."""

    q: np.ndarray
    maps: VelocityMaps
    v: np.ndarray
    vmap: np.ndarray
    terms: tuple[np.ndarray, np.ndarray]


class ClosureDetails:
    """The parts of a forward-dynamics result (:class:`ForwardDetails`): the multipliers
    (given, or a callable of the tree route giving them: called on first access), and the
    closure forces computed from them on first access."""

    def __init__(self, dyn: RobotDynamics, q: np.ndarray,
                 multipliers: np.ndarray | Callable[[], np.ndarray]) -> None:
        self.dyn, self.q, self.multipliers_ = dyn, q, multipliers

    def multipliers(self) -> np.ndarray:
        value = self.multipliers_
        if callable(value):                 # the route's lazy conversion (thread-safe)
            value = self.multipliers_ = value()
        return value

    def closure_forces(self) -> np.ndarray:
        multipliers = self.multipliers()
        with self.dyn.lock:                 # the robot's Pinocchio data
            return self.dyn.closure_forces(self.q, multipliers)


class TreeDetails(ClosureDetails):
    """The parts of an inverse-dynamics result computed on first access
    (:class:`ResultDetails`)."""

    def __init__(self, dyn: RobotDynamics, q: np.ndarray, v: np.ndarray, a: np.ndarray,
                 multipliers: np.ndarray | Callable[[], np.ndarray], residual: float,
                 wrench: np.ndarray | None, wrenches: bool) -> None:
        super().__init__(dyn, q, multipliers)
        self.v, self.a = v, a
        self.residual_ = residual
        self.wrench, self.wrenches = wrench, wrenches

    def joint_wrenches(self) -> Mapping[str, np.ndarray]:
        if not self.wrenches:
            return {}
        with self.dyn.lock:
            return self.dyn.joint_wrenches(self.q, self.v, self.a, self.multipliers(),
                                           self.wrench)

    def residual(self) -> float:
        return float(self.residual_)


class RobotDynamics:
    """Dynamics of a :class:`~hexapod_pin.core.robot.ClosedLoopRobot` (module docstring).

    Args:
        clm: the closed-loop model.
        kinematics: the robot's :class:`RobotKinematics`.
        max_force: the actuator force bound (N or N m), a scalar or an (n_act,) array
            (inf for none).
        lock: the robot's lock (results compute their conditioning under it).
    """

    def __init__(self, clm: ClosedLoopModel, kinematics: RobotKinematics,
                 max_force: float | np.ndarray, lock: threading.RLock) -> None:
        self.clm = clm
        self.kin = kinematics
        self.platform = kinematics.platform
        self.model = clm.model
        self.data = self.model.createData()
        self.max_force = max_force
        self.lock = lock
        self.dim = self.platform.dim
        self.n_act = clm.actuated_v.size
        bound = np.broadcast_to(np.asarray(max_force, dtype=float), (self.n_act,))
        #: the actuator bounds (n_act,) (read-only), or None when none is finite
        self.limits = np.array(bound) if np.isfinite(bound).any() else None
        if self.limits is not None:
            self.limits.setflags(write=False)

    # -- states -------------------------------------------------------------------------
    def state(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
              branch: npt.ArrayLike | None) -> TreeState:
        """The tree state of a platform state, refusing singular poses."""
        twist = as_array(twist, (self.dim,), "twist")
        q = self.kin.configuration(pose, branch)
        maps = self.kin.regular_maps(q)
        vmap = self.kin.velocity_map(maps)
        v = vmap @ twist
        return TreeState(q, maps, v, vmap, self.platform.frame_bias(q, v))

    def external(self, state: TreeState, wrench: npt.ArrayLike | None
                 ) -> tuple[np.ndarray | None, np.ndarray | None]:
        """``(W, tau_ext)``: the checked wrench (dim,) and ``P^T W`` (nv,) (None, None)."""
        if wrench is None:
            return None, None
        w = as_array(wrench, (self.dim,), "wrench")
        return w, state.maps.twist_rows.T @ w

    def conditioning(self, pose: npt.ArrayLike, branch: npt.ArrayLike | None
                     ) -> LazyConditioning:
        pose = as_array(pose, (self.dim,), "pose").copy()
        seed = None if branch is None else self.kin.seed(branch).copy()
        # LazyConditioning keeps the branch as given (None: the home working mode)
        return LazyConditioning(self.kin.singularity, pose, seed,   # type: ignore[arg-type]
                                self.lock)

    def bounds(self, bounded: bool) -> np.ndarray | None:
        """The actuator bounds (n_act,) enforced with ``bounded`` (:attr:`limits`), or
        None."""
        return self.limits if bounded else None

    # -- inverse dynamics -----------------------------------------------------------------
    def inverse_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         twist_dot: npt.ArrayLike, wrench: npt.ArrayLike | None = None, *,
                         branch: npt.ArrayLike | None = None, method: str = "kkt",
                         bounded: bool = True,
                         joint_wrenches: bool = True) -> InverseDynamicsResult:
        """Actuator forces (n_act,) that produce a platform motion (module docstring).

        Args:
            pose: (dim,) (m, rad).
            twist: (dim,), world axes.
            twist_dot: (dim,) its time derivative.
            wrench: (dim,) ON the platform, world axes, moment about its origin; None: 0.
            branch: None or a start configuration (nq,) (see :mod:`robot_kinematics`).
            method: "kkt" or "qp" (:func:`~hexapod_pin.core.dynamics.inverse_dynamics_tree`).
            bounded: enforce ``|u| <= geometry.max_actuator_force``.
            joint_wrenches: whether ``result.joint_wrenches`` is computed on access.

        Raises:
            InputError: bad shapes, NaN / inf, unknown method.
            UnreachablePoseError: see the kinematics.
            SingularityError: see the kinematics.
            ActuatorSaturationError: the bounds cannot be met (carries the needed forces).
            SolverError: an answer misses its equations.
        """
        if method not in INVERSE_DYNAMICS_METHODS:
            raise InputError("method", method, f"expected one of {INVERSE_DYNAMICS_METHODS}")
        twist_dot = as_array(twist_dot, (self.dim,), "twist_dot")
        st = self.state(pose, twist, branch)
        w, tau_ext = self.external(st, wrench)
        a, _ = self.kin.tree_acceleration(st.maps, st.v, twist_dot, st.terms)
        res = inverse_dynamics_tree(self.clm, st.q, st.v, a, tau_ext,
                                    self.bounds(flag(bounded, "bounded")), method)
        details = TreeDetails(self, st.q, st.v, a, res.raw_multipliers, res.residual, w,
                              flag(joint_wrenches, "joint_wrenches"))
        return InverseDynamicsResult(res.actuator_forces.copy(), st.q, st.v, a, method,
                                     res.status, res.iterations, details,
                                     self.conditioning(pose, branch))

    def static_forces(self, pose: npt.ArrayLike, wrench: npt.ArrayLike | None = None, *,
                      branch: npt.ArrayLike | None = None,
                      bounded: bool = True) -> npt.NDArray[np.float64]:
        """Actuator forces (n_act,) holding the platform at rest against gravity and
        ``wrench`` (:meth:`inverse_dynamics` at zero twist and twist_dot)."""
        zero = np.zeros(self.dim)
        return self.inverse_dynamics(pose, zero, zero, wrench, branch=branch,
                                     bounded=bounded, joint_wrenches=False).actuator_forces

    # -- forward dynamics -----------------------------------------------------------------
    def forward_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         actuator_forces: npt.ArrayLike, wrench: npt.ArrayLike | None = None,
                         *, branch: npt.ArrayLike | None = None,
                         method: str = "nullspace") -> ForwardDynamicsResult:
        """Platform acceleration produced by actuator forces (n_act,) (module docstring).

        Raises:
            InputError: bad shapes, NaN / inf, unknown method.
            UnreachablePoseError: see the kinematics.
            SingularityError: see the kinematics.
            SolverError: the answer misses the equation of motion or the closures.
        """
        if method not in FORWARD_DYNAMICS_METHODS:
            raise InputError("method", method, f"expected one of {FORWARD_DYNAMICS_METHODS}")
        u = as_array(actuator_forces, (self.n_act,), "actuator_forces")
        st = self.state(pose, twist, branch)
        w, tau_ext = self.external(st, wrench)
        if method == "nullspace" and self._friction_at_rest(st):
            # Coulomb friction at rest is set-valued: the tree's stick / slip solve answers
            res = forward_dynamics_tree(self.clm, st.q, st.v, u, tau_ext, "kkt")
            a, lam, iterations = res.a.copy(), res.multipliers, res.iterations
            status = f"{res.status} (nullspace: Coulomb friction at rest, solved on the tree)"
        elif method == "nullspace":
            a, lam, status, iterations = self._nullspace(st, u, w, tau_ext)
        else:
            res = forward_dynamics_tree(self.clm, st.q, st.v, u, tau_ext, method)
            a, lam, status, iterations = res.a.copy(), res.multipliers, res.status, \
                res.iterations
        _, bias = st.terms
        twist_dot = st.maps.twist_rows @ a + bias
        details = ClosureDetails(self, st.q, lam)      # the closure forces on first access
        return ForwardDynamicsResult(twist_dot, a[self.clm.actuated_v].copy(), a, method,
                                     status, iterations, details,
                                     self.conditioning(pose, branch))

    def _friction_at_rest(self, st: TreeState) -> bool:
        """Whether a coordinate with Coulomb friction is at rest in this state."""
        return bool(self.clm.effects.has_coulomb
                    and dynamics_of(self.clm).effect_terms(st.q, st.v)[1].size)

    def _nullspace(self, st: TreeState, u: np.ndarray, w: np.ndarray | None,
                   tau_ext: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, str, int]:
        mass, bias_x, jac, a0, mmat, nle = self._reduced(st)
        rhs = jac.T @ u - bias_x + (0.0 if w is None else w)
        twist_dot = solve_checked_square(mass, rhs, "reduced dynamics")
        a = st.vmap @ twist_dot + a0
        # verified on the tree equation of motion: M a + h - S^T u - tau_ext = J_c^T lam
        force = mmat @ a + nle
        force[self.clm.actuated_v] -= u
        if tau_ext is not None:
            force -= tau_ext
        jac_c = st.maps.jac_c
        lam = np.linalg.lstsq(jac_c.T, force, rcond=None)[0] if jac_c.size else \
            np.zeros(0)
        miss = max_abs(jac_c.T @ lam - force)
        closure = max_abs(jac_c @ a + st.terms[0])
        scale = max(1.0, max_abs(mmat @ a), max_abs(nle), max_abs(u))
        if not (miss <= NULLSPACE_RTOL * scale and closure <= NULLSPACE_RTOL
                * max(1.0, max_abs(a))):
            raise SolverError("nullspace", "unverified",
                              f"equation of motion residual {miss / scale:.3e} (relative), "
                              f"closure residual {closure:.3e}")
        return a, lam, "solved", 0

    # -- reduced dynamics and energies -------------------------------------------------------
    def _reduced(self, st: TreeState):
        model, data = self.model, self.data
        mmat = pin.crba(model, data, st.q)
        mmat = np.triu(mmat) + np.triu(mmat, 1).T
        nle = pin.nonLinearEffects(model, data, st.q, st.v).copy()
        effects, _ = dynamics_of(self.clm).effect_terms(st.q, st.v)
        if effects is not None:      # damping, springs, sliding friction: part of h
            nle -= effects
        a0 = self.kin.drift_acceleration(st.maps, st.v, st.terms)
        vmap = st.vmap
        mass = vmap.T @ mmat @ vmap
        mass = 0.5 * (mass + mass.T)
        bias = vmap.T @ (mmat @ a0 + nle)
        jac = vmap[self.clm.actuated_v]
        return mass, bias, jac, a0, mmat, nle

    def reduced_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         branch: npt.ArrayLike | None = None) -> ReducedDynamics:
        """``J^T u + wrench = M_x twist_dot + h_x`` at a platform state (module docstring);
        ``velocity_map`` is ``T`` (nv, dim)."""
        st = self.state(pose, twist, branch)
        mass, bias, jac, _, _, _ = self._reduced(st)
        return ReducedDynamics(mass, bias, jac, st.vmap)

    def energies(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                 branch: npt.ArrayLike | None = None) -> Energies:
        """Kinetic ``1/2 v^T M v`` and gravity potential energy of the whole mechanism (J)
        at a platform state (Pinocchio's potential: zero with every centre of mass at
        height zero; :func:`~hexapod_pin.core.energy.energy_totals`)."""
        st = self.state(pose, twist, branch)
        kinetic, potential = energy_totals(self.clm, st.q, st.v)
        return Energies(kinetic, potential, kinetic + potential)

    # -- forces ----------------------------------------------------------------------------
    def closure_forces(self, q: np.ndarray, multipliers: np.ndarray) -> np.ndarray:
        """(n_closures, 3): the force of each closure (module docstring;
        :func:`~hexapod_pin.core.closure_forces.closure_linear_forces`)."""
        return closure_linear_forces(self.model, self.data, self.clm.closure_frames, q,
                                     multipliers)

    def joint_wrenches(self, q: np.ndarray, v: np.ndarray, a: np.ndarray,
                       multipliers: np.ndarray,
                       wrench: np.ndarray | None) -> dict[str, np.ndarray]:
        """Joint reaction wrenches (see ``ClosedLoopDynamics.joint_wrenches``), with the
        platform wrench applied."""
        fext = None
        if wrench is not None:
            full = np.zeros(6)
            full[self.platform.sel] = wrench
            pin.framesForwardKinematics(self.model, self.data, q)
            frame = self.model.frames[self.platform.frame]
            origin = self.data.oMf[self.platform.frame].translation
            world = pin.Force(full[:3], full[3:] + np.cross(origin, full[:3]))
            fext = {frame.parentJoint: self.data.oMi[frame.parentJoint].actInv(world)}
        out, _ = dynamics_of(self.clm).joint_wrenches(q, v, a, multipliers, fext)
        return out

    # -- batches -------------------------------------------------------------------------
    def _arrays(self, **arrays):
        """(N, the arrays checked by :func:`~hexapod_pin.core.checks.check_batch`)."""
        out = check_batch(self.dim, self.n_act, **arrays)
        return len(out[0]), out

    def inverse_dynamics_batch(self, poses: npt.ArrayLike, twists: npt.ArrayLike,
                               twist_dots: npt.ArrayLike, wrenches: npt.ArrayLike | None = None,
                               *, bounded: bool = True) -> BatchInverseDynamics:
        """:meth:`inverse_dynamics` of N states (rows of (N, dim) arrays); errors name the
        first offending row (``index``)."""
        bounded = flag(bounded, "bounded")
        n, (p, t, td, w) = self._arrays(poses=poses, twists=twists, twist_dots=twist_dots,
                                        wrenches=wrenches)
        res = batch_of_states(n, lambda k: self.inverse_dynamics(
            p[k], t[k], td[k], None if w is None else w[k], bounded=bounded,
            joint_wrenches=False))
        forces = np.array([r.actuator_forces for r in res]).reshape(n, self.n_act)
        closure = np.array([r.closure_forces for r in res]).reshape(
            n, len(self.clm.closures), 3)
        return BatchInverseDynamics(forces, closure, np.array([r.residual for r in res]))

    def forward_dynamics_batch(self, poses: npt.ArrayLike, twists: npt.ArrayLike,
                               actuator_forces: npt.ArrayLike,
                               wrenches: npt.ArrayLike | None = None) -> BatchForwardDynamics:
        """:meth:`forward_dynamics` ("nullspace") of N states."""
        n, (p, t, u, w) = self._arrays(poses=poses, twists=twists,
                                       actuator_forces=actuator_forces, wrenches=wrenches)
        res = batch_of_states(n, lambda k: self.forward_dynamics(
            p[k], t[k], u[k], None if w is None else w[k]))
        return BatchForwardDynamics(
            np.array([r.twist_dot for r in res]).reshape(n, self.dim),
            np.array([r.actuator_accelerations for r in res]).reshape(n, self.n_act),
            np.array([r.closure_forces for r in res]).reshape(n, len(self.clm.closures), 3))

    def static_forces_batch(self, poses: npt.ArrayLike, wrenches: npt.ArrayLike | None = None,
                            *, bounded: bool = True) -> npt.NDArray[np.float64]:
        """:meth:`static_forces` of N poses: (N, n_act)."""
        bounded = flag(bounded, "bounded")
        n, (p, w) = self._arrays(poses=poses, wrenches=wrenches)
        res = batch_of_states(n, lambda k: self.static_forces(
            p[k], None if w is None else w[k], bounded=bounded))
        return np.array(res).reshape(n, self.n_act)

    def reduced_dynamics_batch(self, poses: npt.ArrayLike,
                               twists: npt.ArrayLike) -> BatchReducedDynamics:
        """:meth:`reduced_dynamics` of N states."""
        n, (p, t) = self._arrays(poses=poses, twists=twists)
        res = batch_of_states(n, lambda k: self.reduced_dynamics(p[k], t[k]))
        return BatchReducedDynamics(
            np.array([r.mass_matrix for r in res]).reshape(n, self.dim, self.dim),
            np.array([r.bias for r in res]).reshape(n, self.dim),
            np.array([r.jacobian for r in res]).reshape(n, self.n_act, self.dim))

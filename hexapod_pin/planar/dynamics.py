"""Dynamics of the planar 3-PRR robot at the platform level, and their batches.

Every single-state route builds the tree state and solves the closed-loop equations in
ONE call of the compiled closed form (:mod:`hexapod_pin.planar.kernels`: Newton-Euler of
the sliders, links and platform, the closure forces per loop); the batches run the same
kernels over N states. The generic tree routes of :mod:`hexapod_pin.core.dynamics` are
the other methods (and the reference the tests compare with). Conventions: see
:mod:`hexapod_pin.planar.geometry` and :mod:`hexapod_pin.core.robot_api`; on the tree
(Pinocchio's ``q``, ``v``, ``a``)::

    M a + h - tau_ext = S^T tau + J_c^T lambda,     J_c a = -gamma

with ``tau_ext`` the wrench on the platform chain (its joints are world x, world y and
z), ``lambda`` (9,) the closure multipliers (point closure k: the force of the platform
ON link k, world axes; the out-of-plane rows identically zero and their multipliers
zero, the minimum-norm choice). ``closure_forces`` (3, 2) is the force of link k ON the
platform: ``-lambda_k`` in x and y.

Joint and drive effects (``robot.effects``, :mod:`hexapod_pin.core.effects`): the effects
of the sliders' coordinates are inside the compiled closed form (its drives: the same
numbers in the single states and the batches); effects on passive coordinates (the links,
the platform's joints) are not: a robot with any answers its inverse and forward dynamics
on the tree routes from the closed-form tree state (the status says so), its reduced
dynamics add their share through the velocity map
(:func:`~hexapod_pin.core.effects_projection.reduced_effects`), and its batches run state by
state. Coulomb friction at rest: forward dynamics solves stick / slip; statics return the
frictionless holding forces (any force within ``+-coulomb`` of them holds a slider).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..core.checks import as_array, max_abs, owned_copy, required
from ..core.closed_loop import ClosedLoopModel
from ..core.dynamics import ClosedLoopDynamics, forward_dynamics_tree, inverse_dynamics_tree
from ..core.effects_projection import (PASSIVE_STATUS, batch_of_states, batch_row,
                                       passive_effect_coordinates, reduced_effects,
                                       stacked)
from ..core.energy import energy_totals
from ..core.results import (BatchForwardDynamics, BatchInverseDynamics, BatchReducedDynamics,
                            ComputedDetails, Energies, ForwardDynamicsResult,
                            InverseDynamicsResult, LazyConditioning, ReducedDynamics,
                            SingularityMeasures)
from ..core.robot_api import FORWARD_DYNAMICS_METHODS, INVERSE_DYNAMICS_METHODS
from ..errors import (ActuatorSaturationError, BatchActuatorSaturationError, InputError,
                      SolverError)
from . import kernels
from .geometry import N_ACTUATORS, PlanarGeometry
from .kinematics import PlanarKinematics, PlanarWorkspace, vec3

STATUS_ID = "solved (closed form; out-of-plane multipliers zero: minimum norm)"
STATUS_FD = "solved (closed form, null-space; out-of-plane multipliers zero: minimum norm)"
#: relative tolerance of the checks on a tree route's answer
CHECK_RTOL = 1e-9


class TreeDetails:
    """The parts of a planar dynamics result computed on first access
    (:class:`~hexapod_pin.core.results.ResultDetails`).

    Args:
        dyn: the tree's :class:`~hexapod_pin.core.dynamics.ClosedLoopDynamics`.
        ws: the robot's workspace.
        state: ``(q, v, a)`` the tree state.
        tau: actuator forces (3,).
        tau_ext: the wrench on the tree (nv,).
        wrench: the wrench (3,) or None.
        wanted: whether joint wrenches were asked for.
        closure: (3, 2) closure forces, or None to read them from ``multipliers``.
        multipliers: (n_rows,) multipliers, or None to build them from ``closure``.
        residual: the route's residual, or None to evaluate it on Pinocchio.
    """

    __slots__ = ("_closure", "_multipliers", "_residual", "dyn", "lock", "platform_joint",
                 "state", "tau", "tau_ext", "wanted", "wrench", "ws")

    def __init__(self, dyn: ClosedLoopDynamics, ws: PlanarWorkspace,
                 state: tuple[np.ndarray, np.ndarray, np.ndarray], tau: np.ndarray,
                 tau_ext: np.ndarray, wrench: np.ndarray | None, wanted: bool, platform_joint: int,
                 closure: np.ndarray | None = None, multipliers: np.ndarray | None = None,
                 residual: float | None = None, lock: threading.RLock | None = None) -> None:
        self.lock = threading.RLock() if lock is None else lock
        self.dyn, self.ws, self.state, self.tau, self.tau_ext = dyn, ws, state, tau, tau_ext
        self.wrench, self.wanted, self.platform_joint = wrench, wanted, platform_joint
        self._closure, self._multipliers, self._residual = closure, multipliers, residual

    def multipliers(self) -> np.ndarray:
        if self._multipliers is None:
            self._multipliers = multipliers_of(self.ws, self._closure)  # type: ignore[arg-type]
        return self._multipliers

    def closure_forces(self) -> np.ndarray:
        if self._closure is None:
            self._closure = closure_of(self.ws, self._multipliers)  # type: ignore[arg-type]
        return self._closure

    def joint_wrenches(self) -> Mapping[str, np.ndarray]:
        if not self.wanted:
            return MappingProxyType({})
        q, v, a = self.state
        fext = None
        if self.wrench is not None:
            # the wrench in the LOCAL frame of platform_theta (at the platform origin)
            c, s = np.cos(q[self.ws.indices.platform[2]]), np.sin(q[self.ws.indices.platform[2]])
            fx, fy, mz = self.wrench
            fext = {self.platform_joint: pin.Force(np.array([c * fx + s * fy,
                                                             -s * fx + c * fy, 0.0]),
                                                   np.array([0.0, 0.0, mz]))}
        with self.lock:                     # the robot's Pinocchio data
            table, _ = self.dyn.joint_wrenches(q, v, a, self.multipliers(), fext)
        return MappingProxyType(table)

    def residual(self) -> float:
        if self._residual is None:
            q, v, a = self.state
            dyn = self.dyn
            with self.lock:                 # the robot's Pinocchio data
                full = pin.rnea(dyn.model, dyn.data, q, v, a) - self.tau_ext
                effect = dyn.effect_force_of_motion(q, v, a)   # the joint effects' force
                if effect is not None:
                    full -= effect
                jac = dyn.constraint_jacobian(q)
            full[dyn.clm.actuated_v] -= self.tau
            full -= jac.T @ self.multipliers()
            self._residual = max_abs(full)
        return float(self._residual)


def multipliers_of(ws: PlanarWorkspace, closure: np.ndarray) -> np.ndarray:
    """The tree multipliers (n_rows,) of closure forces (3, 2) (``lambda_k = -closure_k``
    in the in-plane rows, zero out of plane)."""
    lam = np.zeros(ws.n_rows)
    lam[ws.rows] = -closure[:, 0]
    lam[ws.rows + 1] = -closure[:, 1]
    return lam


def closure_of(ws: PlanarWorkspace, multipliers: np.ndarray) -> np.ndarray:
    """Closure forces (3, 2) of the tree multipliers (n_rows,)."""
    return -np.stack([multipliers[ws.rows], multipliers[ws.rows + 1]], axis=1)


class PlanarDynamics:
    """The dynamics of one planar 3-PRR (see the module docstring).

    Args:
        geometry: the robot's geometry.
        model: its :class:`ClosedLoopModel`.
        workspace: its :class:`~hexapod_pin.planar.kinematics.PlanarWorkspace`.
        lock: the robot's lock (held by the facade's calls and by the lazy parts of
            results); default a new one.
        singularity: the robot's ``singularity(pose, branch)`` (the kinematics
            component's), giving the results' conditioning; default that of a
            :class:`~hexapod_pin.planar.kinematics.PlanarKinematics` on ``workspace``.
    """

    def __init__(self, geometry: PlanarGeometry, model: ClosedLoopModel,
                 workspace: PlanarWorkspace, lock: threading.RLock | None = None,
                 singularity: Callable[[npt.ArrayLike, npt.ArrayLike | None],
                                       SingularityMeasures] | None = None) -> None:
        self.geometry, self.model, self.ws = geometry, model, workspace
        #: the measures of a pose, for the results' lazy ``singularity``
        self.singularity = PlanarKinematics(geometry, model, workspace).singularity \
            if singularity is None else singularity
        #: the robot's lock, held by the lazy parts of results (they use this workspace)
        self.lock = threading.RLock() if lock is None else lock
        # its own generic workspace (the robot's lock guards it)
        self.dyn = ClosedLoopDynamics(model)
        self.data = model.model.createData()
        self.platform_joint = model.model.getJointId("platform_theta")
        limit = geometry.max_actuator_force
        self.limits = None if not np.isfinite(limit) else np.full(N_ACTUATORS, limit)

    # -- helpers -----------------------------------------------------------------------------
    def bounds(self, bounded: bool) -> np.ndarray | None:
        """The actuator bounds (3,) (N) enforced with ``bounded``, or None (none)."""
        return self.limits if bounded else None

    def check_bounds(self, tau: np.ndarray, bounds: np.ndarray | None) -> None:
        """Raise :class:`ActuatorSaturationError` (needed forces, bound) when ``|tau|``
        exceeds the bounds (relative slack 1e-9)."""
        if bounds is not None and np.any(np.abs(tau) > bounds * (1.0 + CHECK_RTOL)):
            raise ActuatorSaturationError(tau, bounds)

    def tau_ext(self, wrench: np.ndarray | None) -> np.ndarray:
        """The wrench ``(fx, fy, mz)`` as a tree generalised force (nv,) (the platform
        chain's joints are world x, world y and z at the platform origin)."""
        tau = np.zeros(self.model.nv)
        if wrench is not None:
            tau[self.ws.indices.platform] = wrench
        return tau

    def _tree_check(self, q, v, acc, branch, twist_a) -> None:
        """Check a tree route's acceleration: finite, and its leg rows equal to the closed
        form's for its own platform rows (the closures at acceleration level)."""
        ws = self.ws
        if not np.all(np.isfinite(acc)):
            raise SolverError("tree forward dynamics", "non-finite acceleration")
        twist_dot = np.ascontiguousarray(acc[ws.indices.platform])
        _, _, expected = ws.state(2, True, branch, (), np.ascontiguousarray(
            q[ws.indices.platform]), twist_a, twist_dot)
        miss = max_abs(expected - acc)
        if not miss <= CHECK_RTOL * max(1.0, max_abs(acc)):
            raise SolverError("tree forward dynamics", "closures violated at acceleration "
                              "level", f"leg accelerations off by {miss:.3e}")

    # -- inverse dynamics ---------------------------------------------------------------------
    def inverse_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike, twist_dot: npt.ArrayLike,
                         wrench: npt.ArrayLike | None = None, *,
                         branch: npt.ArrayLike | None = None, method: str = "kkt",
                         bounded: bool = True,
                         joint_wrenches: bool = True) -> InverseDynamicsResult:
        """Actuator forces that produce a platform motion (closed-loop inverse dynamics).

        ``M a + h - tau_ext = S^T tau + J_c^T lambda`` with the closure-keeping tree state
        of the motion, gravity ``-g`` along y included.

        Args:
            pose: ``(x, y, theta)`` (m, m, rad), shape (3,).
            twist: ``(vx, vy, omega)`` (m/s, rad/s), world axes, shape (3,).
            twist_dot: its time derivative (m/s^2, rad/s^2), shape (3,).
            wrench: ``(fx, fy, mz)`` applied ON the platform by the environment (N, N m),
                moment about the platform origin; default zero.
            branch: IK branch, default all ``+1``.
            method: "kkt" (default): that square system solved in closed form
                (:func:`kernels.solve_inverse`). "qp": ProxSuite
                through :func:`~hexapod_pin.core.dynamics.inverse_dynamics_tree`, with
                the bounds as constraints. Both agree to round-off when no bound is
                active.
            bounded: enforce ``abs(tau) <= geometry.max_actuator_force``.
            joint_wrenches: make the reaction wrench of every tree joint available
                (computed on first access: one more ``pin.rnea``).

        Returns:
            :class:`~hexapod_pin.core.results.InverseDynamicsResult` (forces along
            ``+u_k``, N; closure forces (3, 2) of each link ON the platform).

        Raises:
            InputError: a malformed input or method.
            UnreachablePoseError: the pose cannot be reached.
            SingularityError: a link perpendicular to its rail (type I), or a type-II
                singularity, where the actuator forces are not determined (a least-squares
                answer would not produce the motion).
            ActuatorSaturationError: the motion needs more than the bound (carries the
                needed forces; no clipped answer).
        """
        if method not in INVERSE_DYNAMICS_METHODS:
            raise InputError("method", method, f"expected one of {INVERSE_DYNAMICS_METHODS}")
        ws = self.ws
        inputs = ((pose, "pose"), (twist, "twist"), (twist_dot, "twist_dot"),
                  (wrench, "wrench"))
        pose_a, twist_a = vec3(pose, "pose"), vec3(twist, "twist")
        twist_dot_a = vec3(twist_dot, "twist_dot")
        wrench_a = None if wrench is None else vec3(wrench, "wrench")
        nv = ws.nv
        q, v, a = np.empty(nv), np.empty(nv), np.empty(nv)
        tau, closure = np.empty(N_ACTUATORS), np.empty((N_ACTUATORS, 2))
        geo = ws.dynamics_geo
        status = kernels.inverse_dynamics(
            geo, ws.idx, pose_a, twist_a, twist_dot_a,
            ws.zero3 if wrench_a is None else wrench_a, wrench_a is not None,
            ws.signs(branch), q, v, a, tau, closure, ws.buf, ws.info)
        if status in (kernels.NONFINITE, kernels.UNREACHABLE, kernels.TYPE_I, kernels.TYPE_II):
            ws.raise_for(status, inputs)
        if not (np.all(np.isfinite(v)) and np.all(np.isfinite(a))):
            # finite inputs whose products overflow (a twist of 1e160): name the user's
            # argument, not the tree state it overflowed in
            name, value = max(((twist_a, "twist"), (twist_dot_a, "twist_dot")),
                              key=lambda pair: max_abs(pair[0]))[::-1]
            if not np.all(np.isfinite(v)):
                name, value = "twist", twist
            raise InputError(name, value, "too large: the motion's tree velocities or "
                             "accelerations overflow double precision")
        bounds = self.bounds(bounded)
        wrench_kept = None if wrench_a is None else owned_copy(wrench_a, wrench)
        tau_ext = self.tau_ext(wrench_kept)
        conditioning = self._conditioning(owned_copy(pose_a, pose), ws.signs(branch))
        passive = bool(geo[kernels.PASSIVE])
        if method == "kkt" and status == kernels.OK and not passive:
            self.check_bounds(tau, bounds)
            details = TreeDetails(self.dyn, ws, (q, v, a), tau, tau_ext, wrench_kept,
                                  joint_wrenches, self.platform_joint, closure=closure,
                                  lock=self.lock)
            return InverseDynamicsResult(tau, q, v, a, "kkt", STATUS_ID, 0, details,
                                         conditioning)
        res = inverse_dynamics_tree(self.model, q, v, a, tau_ext, bounds=bounds,
                                    method=method)
        tau = res.actuator_forces.copy()
        if not np.all(np.isfinite(tau)) or not np.all(np.isfinite(res.multipliers)):
            raise SolverError("tree inverse dynamics", res.status, "non-finite forces")
        details = TreeDetails(self.dyn, ws, (q, v, a), tau, tau_ext, wrench_kept,
                              joint_wrenches, self.platform_joint,
                              multipliers=res.multipliers.copy(), residual=res.residual,
                              lock=self.lock)
        status_text = f"{res.status} ({PASSIVE_STATUS})" if passive else res.status
        return InverseDynamicsResult(tau, q, v, a, method, status_text, res.iterations,
                                     details, conditioning)

    def _conditioning(self, pose: np.ndarray, signs: np.ndarray) -> LazyConditioning:
        """The lazy conditioning of a result at ``pose`` (an owned copy) on ``signs``."""
        return LazyConditioning(self.singularity, pose, np.array(signs, copy=True), self.lock)

    def static_forces(self, pose: npt.ArrayLike, wrench: npt.ArrayLike | None = None, *,
                      branch: npt.ArrayLike | None = None,
                      bounded: bool = True) -> npt.NDArray[np.float64]:
        """Actuator forces (3,) (N, along ``+u_k``) holding the platform at rest.

        Balances gravity (``-g`` along y, every body) and the ``wrench`` ``(fx, fy, mz)``
        applied ON the platform (N, N m, moment about its origin): the closed-form
        inverse dynamics at zero twist and twist_dot.

        Raises:
            InputError: bad shape, non-finite or non-real values (see :meth:`inverse_dynamics`).
            UnreachablePoseError: a leg cannot reach the pose (see :meth:`inverse_dynamics`).
            SingularityError: at a singular configuration (see :meth:`inverse_dynamics`).
            ActuatorSaturationError: with ``bounded``, a motion needing forces beyond
                ``geometry.max_actuator_force`` (see :meth:`inverse_dynamics`).
        """
        ws = self.ws
        geo = ws.dynamics_geo
        if geo[kernels.PASSIVE]:           # effects the kernels do not model: the tree route
            return self.inverse_dynamics(pose, ws.zero3, ws.zero3, wrench, branch=branch,
                                         bounded=bounded, joint_wrenches=False).actuator_forces
        pose_a = vec3(pose, "pose")
        wrench_a = None if wrench is None else vec3(wrench, "wrench")
        nv = ws.nv
        q, v, a = np.empty(nv), np.empty(nv), np.empty(nv)
        tau, closure = np.empty(N_ACTUATORS), np.empty((N_ACTUATORS, 2))
        status = kernels.inverse_dynamics(
            geo, ws.idx, pose_a, ws.zero3, ws.zero3,
            ws.zero3 if wrench_a is None else wrench_a, wrench_a is not None,
            ws.signs(branch), q, v, a, tau, closure, ws.buf, ws.info)
        if status != kernels.OK:
            ws.raise_for(status, ((pose, "pose"), (wrench, "wrench")))
        bounds = self.bounds(bounded)
        self.check_bounds(tau, bounds)
        return tau

    # -- forward dynamics ----------------------------------------------------------------------
    def forward_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         actuator_forces: npt.ArrayLike, wrench: npt.ArrayLike | None = None, *,
                         branch: npt.ArrayLike | None = None,
                         method: str = "nullspace") -> ForwardDynamicsResult:
        """Platform acceleration produced by actuator forces (constrained forward dynamics).

        Args:
            pose: ``(x, y, theta)``, shape (3,).
            twist: ``(vx, vy, omega)`` (m/s, rad/s), world axes, shape (3,).
            actuator_forces: (3,) (N), on slider k along ``+u_k``.
            wrench: ``(fx, fy, mz)`` on the platform (N, N m); default zero.
            branch: IK branch, default all ``+1``.
            method: "nullspace" (default): ``M_x twist_dot = J^T tau + wrench - h_x`` in
                closed form (:func:`kernels.forward`), ``a = a_0 + G twist_dot``, the
                closure forces per loop from its slider and link rows; "pinocchio"
                (``pin.constraintDynamics``, proximal on the redundant rows), "qp"
                (Gauss principle, ProxSuite) or "kkt" (numpy) through
                :func:`~hexapod_pin.core.dynamics.forward_dynamics_tree`, each checked
                against the closed-form closures at acceleration level. They agree to
                1e-10.

        Returns:
            :class:`~hexapod_pin.core.results.ForwardDynamicsResult`.

        Raises:
            InputError: bad shape, non-finite or non-real values (see :meth:`inverse_dynamics`).
            UnreachablePoseError: a leg cannot reach the pose (see :meth:`inverse_dynamics`).
            SingularityError: at a singular configuration (see :meth:`inverse_dynamics`).
            SolverError: a route's answer failed its checks.
        """
        if method not in FORWARD_DYNAMICS_METHODS:
            raise InputError("method", method, f"expected one of {FORWARD_DYNAMICS_METHODS}")
        ws = self.ws
        inputs = ((pose, "pose"), (twist, "twist"), (actuator_forces, "actuator_forces"),
                  (wrench, "wrench"))
        pose_a, twist_a = vec3(pose, "pose"), vec3(twist, "twist")
        forces_a = vec3(actuator_forces, "actuator_forces")
        wrench_a = None if wrench is None else vec3(wrench, "wrench")
        signs = ws.signs(branch)
        geo = ws.dynamics_geo
        note = ""
        if method == "nullspace" and geo[kernels.PASSIVE]:
            method, note = "kkt", f" ({PASSIVE_STATUS})"
        if method == "nullspace":
            nv = ws.nv
            q, v, a = np.empty(nv), np.empty(nv), np.empty(nv)
            twist_dot, closure = np.empty(3), np.empty((N_ACTUATORS, 2))
            status = kernels.forward_dynamics(
                geo, ws.idx, pose_a, twist_a, forces_a,
                ws.zero3 if wrench_a is None else wrench_a, wrench_a is not None, signs,
                q, v, a, twist_dot, closure, ws.buf, ws.info)
            if status != kernels.OK:
                ws.raise_for(status, inputs)
            details = ComputedDetails(multipliers_of(ws, closure), closure)
            return ForwardDynamicsResult(twist_dot, a[ws.indices.slider], a, method,
                                         STATUS_FD, 0, details,
                                         self._conditioning(owned_copy(pose_a, pose), signs))
        q, v, _ = ws.state(1, True, branch, inputs[:2], pose_a, twist_a)
        forces = as_array(actuator_forces, (N_ACTUATORS,), "actuator_forces")
        wrench_c = None if wrench is None else as_array(wrench, (3,), "wrench")
        res = forward_dynamics_tree(self.model, q, v, forces, self.tau_ext(wrench_c),
                                    method=method)
        acc = res.a.copy()
        self._tree_check(q, v, acc, branch, twist_a)
        details = ComputedDetails(res.multipliers.copy(), closure_of(ws, res.multipliers))
        return ForwardDynamicsResult(acc[ws.indices.platform], acc[ws.indices.slider], acc,
                                     "nullspace" if note else method, res.status + note,
                                     res.iterations, details,
                                     self._conditioning(owned_copy(pose_a, pose), signs))

    # -- reduced dynamics and energies --------------------------------------------------------
    def reduced_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         branch: npt.ArrayLike | None = None) -> ReducedDynamics:
        """Dynamics in platform coordinates: ``J^T tau + wrench = M_x twist_dot + h_x``.

        ``M_x = G^T M G`` (3, 3) (kg, kg m, kg m^2) and ``h_x = G^T (M a_0 + h)`` (3,)
        (N, N m) in closed form (:func:`kernels.reduced`), with ``G`` the velocity map
        ``v = G twist`` (returned as ``velocity_map``, (nv, 3)) and ``a_0`` the tree
        acceleration at ``twist_dot = 0``. With joint effects ``M`` holds the armature and
        ``h_x`` the effects' force ``-G^T tau_e`` (damping, springs, the friction of the
        sliding coordinates; that of a coordinate at rest is set-valued): the sliders' in
        the closed form, the passive coordinates' through ``G``
        (:func:`~hexapod_pin.core.effects_projection.reduced_effects`).

        Raises:
            InputError: bad shape, non-finite or non-real values.
            UnreachablePoseError: a leg cannot reach the pose.
            SingularityError: at a singular configuration.
        """
        ws = self.ws
        geo = ws.dynamics_geo
        m_x, h_x, jac = np.empty((3, 3)), np.empty(3), np.empty((3, 3))
        status = kernels.reduced_dynamics(geo, vec3(pose, "pose"), vec3(twist, "twist"),
                                          ws.signs(branch), m_x, h_x, jac, ws.buf, ws.info)
        if status != kernels.OK:
            ws.raise_for(status, ((pose, "pose"), (twist, "twist")))
        vmap = np.empty((ws.nv, 3))
        kernels.velocity_map(geo, ws.idx, ws.buf, vmap)
        if geo[kernels.PASSIVE]:           # the passive coordinates' share, through G
            q, v, a0 = ws.state(2, True, branch, (), vec3(pose, "pose"), vec3(twist, "twist"))
            d_mass, d_bias = reduced_effects(self.model, passive_effect_coordinates(self.model),
                                             vmap, q, v, a0)
            m_x, h_x = m_x + d_mass, h_x + d_bias
        return ReducedDynamics(m_x, h_x, jac, vmap)

    def energies(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                 branch: npt.ArrayLike | None = None) -> Energies:
        """Kinetic and potential energy of the mechanism (J) on the closed-form tree state
        (:func:`~hexapod_pin.core.energy.energy_totals`: kinetic with the rotors' armature,
        gravity potential zero when every centre of mass is at y = 0, plus the springs').

        Raises:
            InputError: bad shape, non-finite or non-real values.
            UnreachablePoseError: a leg cannot reach the pose.
            SingularityError: at a singular configuration.
        """
        inputs = ((pose, "pose"), (twist, "twist"))
        q, v, _ = self.ws.state(1, True, branch, inputs, vec3(pose, "pose"),
                                vec3(twist, "twist"))
        kinetic, potential = energy_totals(self.model, q, v)
        return Energies(kinetic, potential, kinetic + potential)

    # -- batches --------------------------------------------------------------------------------
    def _raise_first(self, status: np.ndarray, infos: np.ndarray, poses: np.ndarray,
                     tau=None, bounds=None) -> None:
        """Raise the Batch* error of the first state that failed or saturates."""
        bad = status != kernels.OK
        if tau is not None and bounds is not None:
            bad = bad | np.any(np.abs(tau) > bounds * (1.0 + CHECK_RTOL), axis=1)
        if not bad.any():
            return
        first = int(np.argmax(bad))
        if status[first] == kernels.OK:
            raise BatchActuatorSaturationError(first, tau[first], bounds)
        if status[first] == kernels.RESIDUAL:
            # the leg buffer then holds the refused state's legs (its measures)
            self.ws.legs(0, False, None, (), poses[first])
        self.ws.raise_for(int(status[first]), (), infos[first], index=first)

    def _batch_inverse(self, poses, twists, twist_dots, wrenches, bounded):
        ws = self.ws
        n = poses.shape[0]
        has_wrench = wrenches is not None
        tau, closure = np.empty((n, N_ACTUATORS)), np.empty((n, N_ACTUATORS, 2))
        status, infos = np.empty(n, np.int64), np.zeros((n, kernels.INFO_SIZE))
        kernels.inverse_dynamics_batch(ws.dynamics_geo, ws.idx, ws.home_signs, poses, twists,
                                       twist_dots, wrenches if has_wrench else np.zeros((n, 3)),
                                       has_wrench, tau, closure, status, infos)
        self._raise_first(status, infos, poses, tau, self.bounds(bounded))
        return tau, closure, infos[:, kernels.X_RES].copy()

    def inverse_dynamics_batch(self, poses: npt.ArrayLike, twists: npt.ArrayLike,
                               twist_dots: npt.ArrayLike, wrenches: npt.ArrayLike | None = None, *,
                               bounded: bool = True) -> BatchInverseDynamics:
        """:meth:`inverse_dynamics` ("kkt", home branch) of N states, the same compiled
        kernel over the states in parallel.

        Args:
            poses: (N, 3).
            twists: (N, 3).
            twist_dots: (N, 3).
            wrenches: (N, 3) or None.
            bounded: raise for the first state beyond ``geometry.max_actuator_force``.

        Raises:
            InputError: bad shapes, NaN / inf, rows of different lengths.
            BatchUnreachablePoseError: a pose out of reach; for the first such state (``index``).
            BatchSingularityError: a singular state (type I, or type II: no least-squares fallback
                in a batch); for the first such state (``index``).
            BatchActuatorSaturationError: with ``bounded``, forces beyond
                ``geometry.max_actuator_force``; for the first such state (``index``).
        """
        poses, twists, twist_dots, wrenches = check_batch(
            poses=poses, twists=twists, twist_dots=twist_dots, wrenches=wrenches)
        if self.ws.dynamics_geo[kernels.PASSIVE]:   # effects the kernels do not model
            res = batch_of_states(len(poses), lambda k: self.inverse_dynamics(
                poses[k], twists[k], twist_dots[k], batch_row(wrenches, k), bounded=bounded,
                joint_wrenches=False))
            return BatchInverseDynamics(stacked(res, "actuator_forces", (N_ACTUATORS,)),
                                        stacked(res, "closure_forces", (N_ACTUATORS, 2)),
                                        stacked(res, "residual", ()))
        tau, closure, residual = self._batch_inverse(poses, twists, twist_dots, wrenches,
                                                     bounded)
        return BatchInverseDynamics(tau, closure, residual)

    def static_forces_batch(self, poses: npt.ArrayLike, wrenches: npt.ArrayLike | None = None, *,
                            bounded: bool = True) -> npt.NDArray[np.float64]:
        """:meth:`static_forces` of N poses (N, 3): (N, 3) forces (N). Raises as
        :meth:`inverse_dynamics_batch`."""
        poses, wrenches = check_batch(poses=poses, wrenches=wrenches)
        zero = np.zeros_like(poses)
        if self.ws.dynamics_geo[kernels.PASSIVE]:   # effects the kernels do not model
            return self.inverse_dynamics_batch(poses, zero, zero, wrenches,
                                               bounded=bounded).actuator_forces
        return self._batch_inverse(poses, zero, zero, wrenches, bounded)[0]

    def forward_dynamics_batch(self, poses: npt.ArrayLike, twists: npt.ArrayLike,
                               actuator_forces: npt.ArrayLike,
                               wrenches: npt.ArrayLike | None = None) -> BatchForwardDynamics:
        """:meth:`forward_dynamics` ("nullspace", home branch) of N states.

        Raises:
            InputError: bad shape, non-finite or non-real values.
            BatchUnreachablePoseError: a pose out of reach.
            BatchSingularityError: a singular state.
        """
        poses, twists, forces, wrenches = check_batch(
            poses=poses, twists=twists, actuator_forces=actuator_forces, wrenches=wrenches)
        if self.ws.dynamics_geo[kernels.PASSIVE]:   # effects the kernels do not model
            res = batch_of_states(len(poses), lambda k: self.forward_dynamics(
                poses[k], twists[k], forces[k], batch_row(wrenches, k)))
            return BatchForwardDynamics(stacked(res, "twist_dot", (3,)),
                                        stacked(res, "actuator_accelerations", (N_ACTUATORS,)),
                                        stacked(res, "closure_forces", (N_ACTUATORS, 2)))
        ws = self.ws
        n = poses.shape[0]
        has_wrench = wrenches is not None
        twist_dot, acc = np.empty((n, 3)), np.empty((n, N_ACTUATORS))
        closure = np.empty((n, N_ACTUATORS, 2))
        status, infos = np.empty(n, np.int64), np.zeros((n, kernels.INFO_SIZE))
        kernels.forward_dynamics_batch(ws.dynamics_geo, ws.idx, ws.home_signs, poses, twists,
                                       forces, wrenches if has_wrench else np.zeros((n, 3)),
                                       has_wrench, twist_dot, acc, closure, status, infos)
        self._raise_first(status, infos, poses)
        return BatchForwardDynamics(twist_dot, acc, closure)

    def reduced_dynamics_batch(self, poses: npt.ArrayLike,
                               twists: npt.ArrayLike) -> BatchReducedDynamics:
        """:meth:`reduced_dynamics` (home branch) of N states: ``M_x`` (N, 3, 3), ``h_x``
        (N, 3), ``J`` (N, 3, 3).

        Raises:
            InputError: bad shape, non-finite or non-real values.
            BatchUnreachablePoseError: a pose out of reach.
            BatchSingularityError: a singular state.
        """
        poses, twists = check_batch(poses=poses, twists=twists)
        if self.ws.dynamics_geo[kernels.PASSIVE]:   # effects the kernels do not model
            res = batch_of_states(len(poses), lambda k: self.reduced_dynamics(poses[k],
                                                                              twists[k]))
            return BatchReducedDynamics(stacked(res, "mass_matrix", (3, 3)),
                                        stacked(res, "bias", (3,)),
                                        stacked(res, "jacobian", (N_ACTUATORS, 3)))
        ws = self.ws
        n = poses.shape[0]
        m_x, h_x, jac = np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3, 3))
        status, infos = np.empty(n, np.int64), np.zeros((n, kernels.INFO_SIZE))
        kernels.reduced_dynamics_batch(ws.dynamics_geo, ws.home_signs, poses, twists, m_x, h_x, jac,
                                       status, infos)
        self._raise_first(status, infos, poses)
        return BatchReducedDynamics(m_x, h_x, jac)


def check_batch(**arrays: npt.ArrayLike | None) -> list[Any]:
    """Validate batch inputs: each ``(N, 3)`` (``wrenches`` may be None), the same N.

    Raises:
        InputError: bad shape, NaN / inf, or rows of different lengths.
    """
    out: list[Any] = []
    n = None
    for name, value in arrays.items():
        if value is None and name == "wrenches":
            out.append(None)
            continue
        required(**{name: value})
        arr = as_array(value, (3,), name, batch=True)
        if n is None:
            n = arr.shape[0]
        elif arr.shape[0] != n:
            raise InputError(name, value, f"expected {n} rows like the poses, got "
                             f"{arr.shape[0]}")
        out.append(arr)
    return out

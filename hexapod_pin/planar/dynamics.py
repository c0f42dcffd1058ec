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

The plumbing (bounds, input and method checks, status codes to errors, the batch drivers,
the lazy parts of results, the energies) is
:class:`~hexapod_pin.core.closed_form.ClosedFormDynamics`;
this module supplies the planar robot's kernels of its contract.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, NoReturn

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..core.checks import as_array, max_abs, owned_copy
from ..core.closed_form import ClosedFormDynamics, Inputs, LazyParts, TreeDetails
from ..core.closed_loop import ClosedLoopModel
from ..core.compiled import all_finite
from ..core.dynamics import ClosedLoopDynamics, forward_dynamics_tree, inverse_dynamics_tree
from ..core.effects_projection import PASSIVE_STATUS, passive_effect_coordinates, reduced_effects
from ..core.results import (
    BatchForwardDynamics,
    BatchInverseDynamics,
    BatchReducedDynamics,
    ComputedDetails,
    ForwardDynamicsResult,
    InverseDynamicsResult,
    ReducedDynamics,
    SingularityMeasures,
    new_result,
)
from ..errors import SolverError
from . import derivatives, kernels
from .geometry import N_ACTUATORS, PlanarGeometry
from .kinematics import PlanarKinematics, PlanarWorkspace, vec3

STATUS_ID = "solved (closed form; out-of-plane multipliers zero: minimum norm)"
STATUS_FD = "solved (closed form, null-space; out-of-plane multipliers zero: minimum norm)"
#: relative tolerance of the checks on a tree route's answer
CHECK_RTOL = 1e-9


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


class PlanarDynamics(ClosedFormDynamics):
    """The dynamics of one planar 3-PRR (see the module docstring): the planar robot's
    kernels of the :class:`~hexapod_pin.core.closed_form.ClosedFormDynamics` contract
    (which holds the bounds, checks, errors, batch drivers and energies).

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

    dim = 3
    n_actuators = N_ACTUATORS
    closure_shape = (N_ACTUATORS, 2)

    def __init__(self, geometry: PlanarGeometry, model: ClosedLoopModel,
                 workspace: PlanarWorkspace, lock: threading.RLock | None = None,
                 singularity: Callable[[npt.ArrayLike, npt.ArrayLike | None],
                                       SingularityMeasures] | None = None) -> None:
        super().__init__(geometry, model, lock,
                         PlanarKinematics(geometry, model, workspace).singularity
                         if singularity is None else singularity)
        self.ws = workspace
        # its own generic workspace (the robot's lock guards it)
        self.dyn = ClosedLoopDynamics(model)
        self.data = model.model.createData()
        self.platform_joint = model.model.getJointId("platform_theta")
        #: how the lazy parts of results are computed
        self.parts = LazyParts(self.dyn, self.lock, tau_ext=self._tree_wrench,
                               to_multipliers=self._multipliers_of,
                               to_closure=self._closure_of, fext=self._platform_force)

    # -- the contract's pieces ----------------------------------------------------------------
    @property
    def batch_kernels_apply(self) -> bool:
        """Whether the compiled batches model the robot's effects (the sliders' drives:
        yes; effects on the links or the platform's joints: no)."""
        return not self.ws.dynamics_geo[kernels.PASSIVE]

    def tree_state(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                   branch: npt.ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Tree configuration ``q`` (nq,) and velocity ``v`` (nv,) of a pose ``(x, y,
        theta)`` and twist ``(vx, vy, omega)`` (3,) each, on ``branch``, in closed form.

        Raises:
            InputError: bad shape, non-finite or non-real values.
            UnreachablePoseError: a leg cannot reach the pose.
            SingularityError: at a singular configuration.
        """
        inputs = ((pose, "pose"), (twist, "twist"))
        q, v, _ = self.ws.state(1, True, branch, inputs, vec3(pose, "pose"),
                                vec3(twist, "twist"))
        return q, v

    def tau_ext(self, wrench: np.ndarray | None, pose: np.ndarray | None = None) -> np.ndarray:
        """The wrench ``(fx, fy, mz)`` as a tree generalised force (nv,) (the platform
        chain's joints are world x, world y and z at the platform origin, so ``pose`` is
        not needed)."""
        tau = np.zeros(self.model.nv)
        if wrench is not None:
            tau[self.ws.indices.platform] = wrench
        return tau

    def raise_kernel_status(self, code: int, inputs: Inputs, info: np.ndarray | None = None,
                            index: int | None = None,
                            pose: np.ndarray | None = None) -> NoReturn:
        """Raise the error of a kernel status (:meth:`PlanarWorkspace.raise_for
        <hexapod_pin.planar.kinematics.PlanarWorkspace.raise_for>`); a batch's residual
        refusal first rebuilds the refused state's legs (its measures).

        Raises:
            InputError: bad shape, non-finite or non-real values.
            UnreachablePoseError: a leg cannot reach the pose.
            SingularityError: at a singular configuration (Batch* with ``index``).
        """
        if code == kernels.RESIDUAL and pose is not None:
            self.ws.legs(0, False, None, (), pose)
        self.ws.raise_for(code, inputs, info, index=index)
        raise SolverError("planar closed form", f"status {code}", "no error for it")

    def _tree_wrench(self, details: TreeDetails) -> np.ndarray:
        """A result's wrench on the tree (nv,) (:meth:`tau_ext`)."""
        return self.tau_ext(details.wrench)

    def _multipliers_of(self, closure: np.ndarray) -> np.ndarray:
        return multipliers_of(self.ws, closure)

    def _closure_of(self, rows: np.ndarray) -> np.ndarray:
        return closure_of(self.ws, rows)

    def _platform_force(self, details: TreeDetails) -> dict[int, Any] | None:
        if details.wrench is None:
            return None
        # the wrench in the LOCAL frame of platform_theta (at the platform origin)
        theta = details.state[0][self.ws.indices.platform[2]]
        c, s = np.cos(theta), np.sin(theta)
        fx, fy, mz = details.wrench
        return {self.platform_joint: pin.Force(np.array([c * fx + s * fy,
                                                         -s * fx + c * fy, 0.0]),
                                               np.array([0.0, 0.0, mz]))}

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
        self.check_method(method, self.INVERSE_METHODS)
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
        signs = ws.signs(branch)
        status = kernels.inverse_dynamics(
            geo, ws.idx, pose_a, twist_a, twist_dot_a,
            ws.zero3 if wrench_a is None else wrench_a, wrench_a is not None,
            signs, q, v, a, tau, closure, ws.buf, ws.info)
        if status in (kernels.NONFINITE, kernels.UNREACHABLE, kernels.TYPE_I, kernels.TYPE_II):
            self.refuse(status, inputs)
        if not (all_finite(v) and all_finite(a)):
            raise self.overflow(((twist_a, "twist"), (twist_dot_a, "twist_dot")),
                                all_finite(v))
        bounds = self.bounds(bounded)
        wrench_kept = None if wrench_a is None else owned_copy(wrench_a, wrench)
        conditioning = self.conditioning(owned_copy(pose_a, pose), signs)
        passive = bool(geo[kernels.PASSIVE])
        if method == "kkt" and status == kernels.OK and not passive:
            self.check_bounds(tau, bounds)
            # the wrench on the tree and the multipliers on first access (self.parts)
            details = TreeDetails(self.parts, (q, v, a), tau, wrench_kept, closure=closure,
                                  wanted=joint_wrenches)
            return new_result(InverseDynamicsResult, {
                "actuator_forces": tau, "configuration": q, "velocity": v,
                "acceleration": a, "method": "kkt", "status": STATUS_ID, "iterations": 0,
                "_details": details, "_conditioning": conditioning})
        tau_ext = self.tau_ext(wrench_kept)
        res = inverse_dynamics_tree(self.model, q, v, a, tau_ext, bounds=bounds,
                                    method=method)
        tau = res.actuator_forces.copy()
        if not np.all(np.isfinite(tau)) or not np.all(np.isfinite(res.multipliers)):
            raise SolverError("tree inverse dynamics", res.status, "non-finite forces")
        details = TreeDetails(self.parts, (q, v, a), tau, wrench_kept, tau_ext=tau_ext,
                              multipliers=res.multipliers.copy(), residual=res.residual,
                              wanted=joint_wrenches)
        status_text = f"{res.status} ({PASSIVE_STATUS})" if passive else res.status
        return InverseDynamicsResult(tau, q, v, a, method, status_text, res.iterations,
                                     details, conditioning)

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
            return super().static_forces(pose, wrench, branch=branch, bounded=bounded)
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
            self.refuse(status, ((pose, "pose"), (wrench, "wrench")))
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
        self.check_method(method, self.FORWARD_METHODS)
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
                self.refuse(status, inputs)
            # the multipliers on first access (self.parts)
            details = TreeDetails(self.parts, (q, v, a), forces_a, closure=closure)
            return new_result(ForwardDynamicsResult, {
                "twist_dot": twist_dot, "actuator_accelerations": a[ws.indices.slider],
                "tree_acceleration": a, "method": method, "status": STATUS_FD,
                "iterations": 0, "_details": details,
                "_conditioning": self.conditioning(owned_copy(pose_a, pose), signs)})
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
                                     self.conditioning(owned_copy(pose_a, pose), signs))

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
        status = kernels.reduced_dynamics(geo, vec3(pose, "pose"),
                                          vec3(twist, "twist"), ws.signs(branch), m_x,
                                          h_x, jac, ws.buf, ws.info)
        if status != kernels.OK:
            self.refuse(status, ((pose, "pose"), (twist, "twist")))
        vmap = np.empty((ws.nv, 3))
        kernels.velocity_map(geo, ws.idx, ws.buf, vmap)
        if geo[kernels.PASSIVE]:           # the passive coordinates' share, through G
            q, v, a0 = ws.state(2, True, branch, (), vec3(pose, "pose"),
                                vec3(twist, "twist"))
            d_mass, d_bias = reduced_effects(self.model, passive_effect_coordinates(self.model),
                                             vmap, q, v, a0)
            m_x, h_x = m_x + d_mass, h_x + d_bias
        return ReducedDynamics(m_x, h_x, jac, vmap)

    # -- derivatives (the kernel behind core.platform_derivatives) ------------------------------
    def inverse_dynamics_partials(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                                  twist_dot: npt.ArrayLike, wrench: npt.ArrayLike | None = None,
                                  branch: npt.ArrayLike | None = None
                                  ) -> tuple[np.ndarray, np.ndarray] | None:
        """The closed form's analytic inverse-dynamics partials
        (:func:`hexapod_pin.planar.derivatives.inverse_partials`), or None (effects on
        passive coordinates, or a state the closed form cannot verify)."""
        return derivatives.inverse_partials(self, pose, twist, twist_dot, wrench, branch)

    # -- batch kernels (the drivers: ClosedFormDynamics) ---------------------------------------
    def inverse_batch_kernel(self, poses: np.ndarray, twists: np.ndarray,
                             twist_dots: np.ndarray, wrenches: np.ndarray | None,
                             bounded: bool) -> BatchInverseDynamics:
        """:meth:`inverse_dynamics` ("kkt", home branch) of N checked states: the same
        compiled kernel over the states in parallel (a type-II state is refused: no
        least-squares fallback in a batch)."""
        ws = self.ws
        n = poses.shape[0]
        has_wrench = wrenches is not None
        tau, closure = np.empty((n, N_ACTUATORS)), np.empty((n, N_ACTUATORS, 2))
        status, infos = np.empty(n, np.int64), np.zeros((n, kernels.INFO_SIZE))
        kernels.inverse_dynamics_batch(ws.dynamics_geo, ws.idx, ws.home_signs, poses, twists,
                                       twist_dots, wrenches if has_wrench else np.zeros((n, 3)),
                                       has_wrench, tau, closure, status, infos)
        self.raise_first(status, infos, poses, tau, self.bounds(bounded))
        return BatchInverseDynamics(tau, closure, infos[:, kernels.X_RES].copy())

    def forward_batch_kernel(self, poses: np.ndarray, twists: np.ndarray,
                             forces: np.ndarray,
                             wrenches: np.ndarray | None) -> BatchForwardDynamics:
        """:meth:`forward_dynamics` ("nullspace", home branch) of N checked states."""
        ws = self.ws
        n = poses.shape[0]
        has_wrench = wrenches is not None
        twist_dot, acc = np.empty((n, 3)), np.empty((n, N_ACTUATORS))
        closure = np.empty((n, N_ACTUATORS, 2))
        status, infos = np.empty(n, np.int64), np.zeros((n, kernels.INFO_SIZE))
        kernels.forward_dynamics_batch(ws.dynamics_geo, ws.idx, ws.home_signs, poses, twists,
                                       forces, wrenches if has_wrench else np.zeros((n, 3)),
                                       has_wrench, twist_dot, acc, closure, status, infos)
        self.raise_first(status, infos, poses)
        return BatchForwardDynamics(twist_dot, acc, closure)

    def reduced_batch_kernel(self, poses: np.ndarray,
                             twists: np.ndarray) -> BatchReducedDynamics:
        """:meth:`reduced_dynamics` (home branch) of N checked states."""
        ws = self.ws
        n = poses.shape[0]
        m_x, h_x, jac = np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3, 3))
        status, infos = np.empty(n, np.int64), np.zeros((n, kernels.INFO_SIZE))
        kernels.reduced_dynamics_batch(ws.dynamics_geo, ws.home_signs, poses, twists, m_x, h_x,
                                       jac, status, infos)
        self.raise_first(status, infos, poses)
        return BatchReducedDynamics(m_x, h_x, jac)

"""The hexapod's dynamics at the platform level (pose, twist, twist_dot, wrench).

Single states build the tree state in closed form (the kernels of
:mod:`hexapod_pin.hexapod.kernels`) and need one or two Pinocchio calls
(``rnea``, ``computeGeneralizedGravity``, ``crba`` or ``constraintDynamics``) and a 6x6
solve; the ``*_batch`` methods run the Newton-Euler kernels over N states
(:mod:`hexapod_pin.hexapod.batch`). Generic tree dynamics: :mod:`hexapod_pin.core.dynamics`.

Joint and drive effects (``robot.effects``, :mod:`hexapod_pin.core.effects`): the
single-state routes are generic over every coordinate of the tree. Pinocchio's ``crba`` and
``rnea`` carry the armature (``model.armature``), and the effects' generalised force
``tau_e`` joins the tree force before it is projected with ``G^T`` (``G^T (rnea(q, v, a) -
tau_e)``: inverse dynamics, statics with the springs; ``h_x = G^T (rnea(q, v, a_0) -
tau_e)``: reduced and null-space forward dynamics, ``tau_e`` without the friction of the
coordinates at rest). A coordinate with Coulomb friction at rest makes the "nullspace"
forward dynamics answer on the tree (its stick / slip solve). The batches run the compiled
closed form, which carries the carriages' drives; a robot whose passive coordinates
(universal joints, the platform's free flyer) carry effects runs its batches state by state
on the single-state routes (the same numbers).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import threading

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import proxsuite

from . import kernels
from . import batch
from .batch import check_batch
from ..core.checks import as_array, max_abs, owned_copy, required
from ..core.closed_loop import ClosedLoopModel
from ..core.compiled import all_finite
from ..core.results import (BatchForwardDynamics, BatchInverseDynamics, BatchReducedDynamics,
                            Energies, ForwardDynamicsResult, InverseDynamicsDerivatives,
                            InverseDynamicsResult, LazyConditioning, ReducedDynamics,
                            SingularityMeasures)
from ..core.dynamics import (INVERSE_METHODS, QP_SOLVED, QP_STATUS, RESIDUAL_RTOL,
                             ClosedLoopDynamics)
from ..core.effects_projection import batch_of_states, batch_row, stacked
from ..core.energy import energy_totals
from .derivatives import DerivativesWorkspace, analytic_derivatives
from .kinematics import HexapodKinematics, check_branch
from ..errors import (
    ActuatorSaturationError,
    HexapodPinError,
    InputError,
    SolverError,
)
from ..core.pose import rotation_from_rpy
from ..core.checks import vec6 as _vec6
from .geometry import HexapodGeometry

#: the hexapod's forward-dynamics routes: the tree routes and the null-space one
HEXAPOD_FORWARD_METHODS = ("pinocchio", "nullspace", "qp", "kkt")
#: ProxSuite accuracy of the hexapod's reduced inverse-dynamics QP (its eps_abs and
#: eps_rel: residuals relative to the data, N and N m)
_QP_EPS_REDUCED = 2e-14

# --------------------------------------------------------------------------------------
# hexapod: pose / twist-level API
# --------------------------------------------------------------------------------------
class _InverseDetails:
    """The parts of an inverse-dynamics result computed on first access
    (:class:`~hexapod_pin.core.results.ResultDetails`)."""

    def __init__(self, ws, force, tau, wrench, q, v, a, wrenches_wanted, pose, signs):
        self.ws, self.force, self.tau, self.wrench = ws, force, tau, wrench
        self.q, self.v, self.a, self.wrenches_wanted = q, v, a, wrenches_wanted
        self.pose, self.signs = pose, signs
        self._tips = None

    def tip_forces(self) -> np.ndarray:
        """(6, 3) force of the platform on each leg tip (carriage order), world axes."""
        if self._tips is None:
            self._tips = self.ws.compiled.tip_forces(self.pose, self.force, self.tau,
                                                      self.signs)
        return self._tips

    def tau_ext(self) -> np.ndarray:
        tau = np.zeros(self.ws.dyn.nv)
        if self.wrench is not None:
            rot = rotation_from_rpy(self.pose[3:])
            wrench = np.asarray(self.wrench, dtype=float)
            tau[self.ws.ff_v] = np.concatenate([rot.T @ wrench[:3], rot.T @ wrench[3:]])
        return tau

    def multipliers(self) -> np.ndarray:
        return self.tip_forces()[self.ws.leg_of_closure].reshape(-1)

    def closure_forces(self) -> np.ndarray:
        return -self.tip_forces()

    def joint_wrenches(self) -> Mapping[str, np.ndarray]:
        if not self.wrenches_wanted:
            return MappingProxyType({})
        fext = None
        if self.wrench is not None:
            fext = {self.ws.platform_joint: pin.Force(self.tau_ext()[self.ws.ff_v])}
        with self.ws.lock:                  # the robot's Pinocchio data
            table, _ = self.ws.dyn.joint_wrenches(self.q, self.v, self.a, self.multipliers(),
                                                  fext)
        return MappingProxyType(table)

    def residual(self) -> float:
        dyn = self.ws.dyn
        full = np.array(self.force) - self.tau_ext()
        full[dyn.clm.actuated_v] -= self.tau
        with self.ws.lock:                  # the robot's Pinocchio data
            jac = dyn.constraint_jacobian(self.q)
        full -= jac.T @ self.multipliers()
        return max_abs(full)


class _ForwardDetails:
    """Closure multipliers and forces of a forward-dynamics result, converted on first
    access (:class:`~hexapod_pin.core.results.ResultDetails`)."""

    __slots__ = ("dyn", "leg_of_closure", "local", "lock", "q", "rows")

    def __init__(self, dyn, q, leg_of_closure, lock, local=None, rows=None):
        self.dyn, self.q, self.local, self.rows = dyn, q, local, rows
        self.leg_of_closure, self.lock = leg_of_closure, lock

    def closure_forces(self) -> np.ndarray:
        out = np.empty((6, 3))
        out[self.leg_of_closure] = -self.multipliers().reshape(-1, 3)
        return out

    def multipliers(self) -> np.ndarray:
        with self.lock:                     # the robot's Pinocchio data
            return self._multipliers()

    def _multipliers(self) -> np.ndarray:
        if isinstance(self.rows, _LazyTreeMultipliers):
            self.rows = self.rows()
        if self.rows is None:
            # Pinocchio's LOCAL contact forces, rotated into world axes: lambda = R_c1 lambda_pin
            dyn = self.dyn
            pin.framesForwardKinematics(dyn.model, dyn.data, self.q)
            rots = np.array([dyn.data.oMf[c[2]].rotation for c in dyn.closure_frames])
            self.rows = np.einsum("kij,kj->ki", rots, self.local.reshape(-1, 3)).reshape(-1)
        return self.rows


class _LazyTreeMultipliers:
    """Closure multipliers of a null-space forward-dynamics result, from the legs' tree
    rows at the computed motion (as the inverse dynamics does)."""

    __slots__ = ("acc", "effect", "forces", "pose", "q", "signs", "v", "ws")

    def __init__(self, ws, pose, q, v, acc, forces, signs, effect=None):
        self.ws, self.pose, self.q, self.v, self.acc = ws, pose, q, v, acc
        self.forces, self.signs, self.effect = forces, signs, effect

    def __call__(self) -> np.ndarray:
        ws = self.ws
        # each leg's three tree rows (carriage, u_a, u_b) of rnea - tau_e = S^T tau +
        # J_c^T lambda (the wrench acts on the platform rows only)
        force = pin.rnea(ws.dyn.model, ws.dyn.data, self.q, self.v, self.acc)
        if self.effect is not None:
            force = force - self.effect
        tips = ws.compiled.tip_forces(self.pose, force, self.forces, self.signs)
        return tips[ws.leg_of_closure].reshape(-1)




@dataclass
class _HexapodWorkspace:
    dyn: ClosedLoopDynamics
    ff_v: np.ndarray
    free_v: np.ndarray
    leg_of_closure: np.ndarray
    bounds: np.ndarray | None
    platform_joint: int
    compiled: kernels.ClosedForm
    lock: object
    q: np.ndarray = field(default_factory=lambda: np.empty(25))
    v: np.ndarray = field(default_factory=lambda: np.empty(24))
    a: np.ndarray = field(default_factory=lambda: np.empty(24))
    tau: np.ndarray = field(default_factory=lambda: np.empty(6))
    multipliers: np.ndarray = field(default_factory=lambda: np.empty(6))
    jac_t: np.ndarray = field(default_factory=lambda: np.empty((6, 6)))
    work: np.ndarray = field(default_factory=lambda: np.empty((36, 6)))
    qps: dict = field(default_factory=dict)
    #: whether the joint effects give a force (damping, friction, springs): fixed for a
    #: model (a hand-written armature changes the armature only, which Pinocchio reads)
    forces: bool = False


class HexapodDynamics:
    """The hexapod's dynamics at the platform level: the component that
    :class:`~hexapod_pin.hexapod.robot.Hexapod` delegates its dynamics methods to.

    Args:
        geometry: the :class:`~hexapod_pin.hexapod.geometry.HexapodGeometry`.
        model: the hexapod's :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`.
        indices: where the hexapod's coordinates sit in the tree (``HexapodIndices``).
        closed_form: the :class:`~hexapod_pin.hexapod.kernels.ClosedForm` of the same robot.
        lock: the robot's lock (held by the facade's calls and by the lazy parts of
            results); default a new one.
        singularity: the robot's ``singularity(pose, branch)`` (the kinematics
            component's), giving the results' conditioning; default that of a
            :class:`~hexapod_pin.hexapod.kinematics.HexapodKinematics` on ``closed_form``.

    It keeps its per-robot workspace (its own generic tree workspace, buffers, ProxSuite
    problems, the derivatives' workspace) as explicit attributes, built on first use.

    Conventions (see the README): pose ``(x, y, z, roll, pitch, yaw)``, twist
    ``(v, w)`` of the platform origin in world axes, ``twist_dot`` its plain time
    derivative, actuator force ``tau_i`` on carriage i along ``+u_k`` (N), wrench
    ``(f, m)`` applied on the platform by the environment, world axes, moment about the
    platform origin (N, N m).

    Single states go through the Pinocchio tree. The tree state comes in closed form
    (the kernels of :mod:`~hexapod_pin.hexapod.kernels`): ``q`` from the inverse kinematics
    (on the given branch) and the leg directions, ``v = G twist`` and ``a`` from the leg
    kinematics (they keep the closures by construction), the free-flyer part
    ``(R^T v, R^T w)`` and ``(R^T (vdot - w x v), R^T wdot)``; the wrench enters as the
    free-flyer generalised force ``(R^T f, R^T m)``. By virtual power the tree equation
    ``M a + h - tau_ext = S^T tau + J_c^T lambda`` projected with ``G^T`` (``J_c G = 0``,
    ``S G = J``) is ``J^T tau = G^T rnea(q, v, a) - wrench``: one ``pin.rnea`` and a 6x6
    solve. Batches (``*_batch``) run the Newton-Euler kernels (:mod:`hexapod_pin.hexapod.batch`),
    independent of ``pin.rnea``; the tests check that both agree to 1e-10.
    """

    def __init__(self, geometry: HexapodGeometry, model: ClosedLoopModel, indices: Any,
                 closed_form: kernels.ClosedForm, lock: threading.RLock | None = None,
                 singularity: Callable[[npt.ArrayLike, npt.ArrayLike | None],
                                       SingularityMeasures] | None = None) -> None:
        self.geometry, self.model, self.indices = geometry, model, indices
        self.closed_form = closed_form
        #: the measures of a pose, for the results' lazy ``singularity``
        self.singularity = HexapodKinematics(geometry, closed_form).singularity \
            if singularity is None else singularity
        #: the robot's lock, held by the lazy parts of results (they use this workspace)
        self.lock = threading.RLock() if lock is None else lock
        self._ws: _HexapodWorkspace | None = None
        self._derivatives: DerivativesWorkspace | None = None

    # -- workspace ---------------------------------------------------------------------
    @property
    def tree_dynamics(self) -> ClosedLoopDynamics:
        """The generic dynamics workspace of the hexapod's tree (cached)."""
        return self._workspace().dyn

    @property
    def platform_velocity_indices(self) -> np.ndarray:
        """Indices of the platform's free-flyer velocity in the tree's ``v`` (6,)."""
        return self._workspace().ff_v

    def _workspace(self) -> _HexapodWorkspace:
        if self._ws is not None:
            return self._ws
        clm = self.model
        gravity = np.array([0.0, 0.0, -self.geometry.gravity, 0.0, 0.0, 0.0])
        if not np.allclose(clm.model.gravity.vector, gravity, rtol=0.0, atol=0.0):
            clm.model.gravity = pin.Motion(gravity)
        # its own generic workspace (not dynamics_of's, shared with other callers of the
        # generic routes): the robot's lock guards it
        dyn = ClosedLoopDynamics(clm)
        idx = self.indices
        ff_v = np.arange(idx.platform_v.start, idx.platform_v.stop)
        free_v = np.setdiff1d(np.arange(clm.nv), ff_v)
        leg_of_closure = np.full(len(clm.closures), -1)
        for c, closure in enumerate(clm.closures):
            for i in range(6):
                if closure.frame1 == f"leg_{i}_tip" and closure.frame2.startswith("platform"):
                    leg_of_closure[c] = i
        if sorted(leg_of_closure.tolist()) != list(range(6)) or any(
                cl.type != "point" for cl in clm.closures):
            raise HexapodPinError("the hexapod's loops must be six point closures "
                                  "leg_<i>_tip -> platform_anchor_<i>")
        limit = self.geometry.max_actuator_force
        bounds = None if not np.isfinite(limit) else np.full(6, limit)
        ws = _HexapodWorkspace(dyn, ff_v, free_v, leg_of_closure, bounds,
                               clm.model.getJointId("platform_joint"), self.closed_form,
                               self.lock, forces=clm.effects.has_forces)
        home_q, _ = self.tree_state(self.geometry.home_pose, np.zeros(6), ws=ws)
        dyn.closure_rank(home_q)
        kernels.check_mass_structure(pin.crba(dyn.model, dyn.data, home_q))
        self._ws = ws
        return ws

    def tree_state(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                   branch: npt.ArrayLike | None = None,
                   ws: _HexapodWorkspace | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Tree configuration ``q`` (nq,) and velocity ``v`` (nv,) (Pinocchio conventions) of
        a platform pose and twist (6,) each, on ``branch`` (default home), in closed form.

        Raises:
            InputError: bad shape, non-finite or non-real values.
            UnreachablePoseError: a leg cannot reach the pose.
            SingularityError: at a singular configuration (type I, gimbal lock).
        """
        ck = (self._workspace() if ws is None else ws).compiled
        signs = ck.signs if branch is None else check_branch(branch)
        pose_a, twist_a = _vec6(pose, "pose"), _vec6(twist, "twist")
        q, v = np.empty(25), np.empty(24)
        s = ck.scratch
        code = kernels.tree_state(ck.geo, signs, pose_a, twist_a, twist_a, 1, q, v, v,
                                  s.rot, s.wk)
        if code != kernels.OK:
            self._raise_code(ck, code, pose=pose, twist=twist)
        return q, v

    # -- inverse dynamics --------------------------------------------------------------
    def inverse_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike, twist_dot: npt.ArrayLike,
                         wrench: npt.ArrayLike | None = None, *,
                         branch: npt.ArrayLike | None = None, method: str = "kkt",
                         bounded: bool = True,
                         joint_wrenches: bool = True) -> InverseDynamicsResult:
        """Actuator forces that produce a platform motion (closed-loop inverse dynamics).

        Includes the inertia and weight of the platform, legs and carriages. The tree
        state ``(q, v, a)`` comes in closed form and one ``pin.rnea`` gives the tree's
        generalised forces; their projection on the platform's motions (virtual power)
        is ``J^T tau + wrench`` (see the class docstring).

        Args:
            pose: ``(x, y, z, roll, pitch, yaw)`` (m, rad), shape (6,).
            twist: ``(v, w)`` of the platform origin, world axes (m/s, rad/s), (6,).
            twist_dot: time derivative of the twist (m/s^2, rad/s^2), (6,).
            wrench: ``(f, m)`` applied on the platform by the environment, world axes,
                moment about the platform origin (N, N m), (6,); default zero.
            branch: the IK branch of the legs (six +1 / -1, see
                :meth:`HexapodKinematics.inverse_kinematics`); default the home branch.
            method: "kkt" (default: the 6x6 LU solve, the bounds then checked) or "qp"
                (ProxSuite: minimise ``1/2 |tau|^2`` subject to ``J^T tau =
                G^T rnea - wrench`` and the box bounds, i.e. the tree QP of
                :func:`inverse_dynamics_tree` with the closure multipliers eliminated by
                ``G^T``); they agree to 1e-10 when no bound
                is active. The QP is warm-started at the equality-constrained solution
                and its multipliers (from the LU): ProxSuite then certifies it (primal
                and dual residuals below 2e-14 relative) in 0 iterations, or, when a
                bound is violated, iterates and reports infeasibility (``J^T`` is square
                and invertible, so the feasible set is that one point), which raises
                :class:`ActuatorSaturationError`.
            bounded: enforce ``abs(tau) <= geometry.max_actuator_force``.
            joint_wrenches: make the reaction wrench of every tree joint available
                (computed on first access of ``joint_wrenches``: one more ``pin.rnea``).

        Returns:
            :class:`InverseDynamicsResult`.

        Raises:
            ActuatorSaturationError: the motion needs more than the bound (carries the
                needed forces; no clipped answer).
            UnreachablePoseError: the pose cannot be reached.
            SingularityError: a leg perpendicular to its rail (type I), a leg along its
                rail (universal joint in gimbal lock) or a type-II singularity.
            InputError: bad shapes, NaN / inf, unknown method.
            SolverError: the QP failed for another reason.
        """
        if method not in INVERSE_METHODS:
            raise InputError("method", method, f"expected one of {INVERSE_METHODS}")
        ws = self._workspace()
        ck, dyn = ws.compiled, ws.dyn
        signs = ck.signs if branch is None else check_branch(branch)
        pose_a, twist_a = _vec6(pose, "pose"), _vec6(twist, "twist")
        tdot_a = _vec6(twist_dot, "twist_dot")
        wrench_a = None if wrench is None else _vec6(wrench, "wrench")
        bounds = ws.bounds if bounded else None
        q, v, a = np.empty(dyn.clm.nq), np.empty(dyn.nv), np.empty(dyn.nv)
        s = ck.scratch
        code = kernels.tree_state(ck.geo, signs, pose_a, twist_a, tdot_a, 2, q, v, a, s.rot,
                                  s.wk)
        if code != kernels.OK or (wrench_a is not None and not all_finite(wrench_a)):
            self._raise_code(ck, code, pose=pose, twist=twist, twist_dot=twist_dot,
                             wrench=wrench)
        force = self._tree_force(ws, q, v, a)
        tau, status, iters, rhs = self._solve_tree(ws, force, wrench_a, method, bounds)
        details = _InverseDetails(ws, force, tau,
                                  None if wrench_a is None else owned_copy(wrench_a, wrench), q, v,
                                  a, joint_wrenches, owned_copy(pose_a, pose), signs)
        return InverseDynamicsResult(tau, q, v, a, method, status, iters, details,
                                     self._conditioning(details.pose, signs))

    @staticmethod
    def _tree_force(ws: _HexapodWorkspace, q: np.ndarray, v: np.ndarray,
                    a: np.ndarray) -> np.ndarray:
        """``rnea(q, v, a) - tau_e(q, v, a)`` (nv,): the tree force the actuators, the wrench
        and the closures balance (``tau_e`` the joint effects' force of the motion)."""
        dyn = ws.dyn
        force = pin.rnea(dyn.model, dyn.data, q, v, a)
        if not ws.forces:
            return force
        return force - dyn.effect_force_of_motion(q, v, a)

    def _conditioning(self, pose: np.ndarray, signs: np.ndarray) -> LazyConditioning:
        """The lazy conditioning of a result at ``pose`` (an owned copy) on ``signs``."""
        return LazyConditioning(self.singularity, pose, np.array(signs, copy=True),
                                self.lock)

    def _solve_tree(self, ws, force, wrench_a, method, bounds):
        """``J^T tau = G^T force - wrench`` at the legs of the last tree state, under the
        bounds by ``method``: ``(tau, status, iterations, rhs)``. Raises
        :class:`SingularityError` at a type-II singularity."""
        ck = ws.compiled
        s = ck.scratch
        rhs = np.empty(6)
        kernels.project(ck.geo, s.rot, s.wk, force, kernels.ZERO6 if wrench_a is None
                        else wrench_a, wrench_a is not None, rhs)
        tau, mult = np.empty(6), np.empty(6)
        code = kernels.solve_forces(ck.geo, s.wk, s.mats, rhs, tau, mult, ws.jac_t)
        if code != kernels.OK:
            raise ck.error(code)
        tau, status, iters = self._bounded_forces(ws, ws.jac_t, rhs, tau, mult, method,
                                                  bounds)
        return tau, status, iters, rhs

    def _bounded_forces(self, ws, jac_t, rhs, tau, mult, method, bounds):
        """The actuator forces of ``J^T tau = rhs`` under the bounds, by ``method``.

        ``tau`` and ``mult`` are the equality-constrained solution and its multipliers
        (``J mult = -tau``), ``jac_t`` is ``J^T`` (6, 6). "kkt" checks the bounds;
        "qp" has ProxSuite solve ``min 1/2 |tau|^2`` s.t. ``J^T tau = rhs`` and the box,
        warm-started at ``(tau, mult)``: when no bound is active ProxSuite certifies that
        point (primal and dual residuals below its tolerance) without iterating; otherwise
        it iterates and finds the problem infeasible (the feasible set of the square,
        invertible ``J^T`` is that single point).
        """
        limit = None if bounds is None else bounds[0] * (1.0 + RESIDUAL_RTOL)
        if method == "kkt":
            if limit is not None and max(map(abs, tau.tolist())) > limit:
                raise ActuatorSaturationError(tau, bounds)
            return tau, "solved", 0
        key = "id_box" if bounds is not None else "id"
        qp = ws.qps.get(key)
        if qp is None:
            qp = proxsuite.proxqp.dense.QP(6, 6, 0, bounds is not None)
            # residuals relative to the data (ProxSuite: eps_abs + eps_rel * scale)
            qp.settings.eps_abs = qp.settings.eps_rel = _QP_EPS_REDUCED
            qp.settings.max_iter = 200
            qp.settings.verbose = False
            qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START
            if bounds is None:
                qp.init(np.eye(6), np.zeros(6), jac_t, rhs, None, None, None)
            else:
                qp.init(np.eye(6), np.zeros(6), jac_t, rhs, None, None, None, -bounds, bounds)
            ws.qps[key] = qp
        else:
            qp.update(A=jac_t, b=rhs, update_preconditioner=False)
        qp.solve(tau, mult, None)
        results = qp.results
        info = results.info
        status = "solved" if info.status == QP_SOLVED else \
            f"{QP_STATUS.get(info.status, str(info.status))} (residuals verified)"
        sol = results.x.copy()
        res, biggest, scale = kernels.check_solution(jac_t, sol, rhs)
        ok = res <= 1e-8 * max(1.0, scale) and (limit is None or biggest <= limit)
        if not ok or info.status != QP_SOLVED:
            # J^T is square and invertible (the type-II test passed): the feasible set is
            # the one point tau of the LU solve, the minimiser whenever it verifies and
            # keeps the bounds, whatever ProxSuite's iterations reported
            res, biggest, scale = kernels.check_solution(jac_t, tau, rhs)
            if res <= 1e-8 * max(1.0, scale) and (limit is None or biggest <= limit):
                sol, ok = tau.copy(), True
        if not ok:
            if limit is not None and max(map(abs, tau.tolist())) > bounds[0]:
                raise ActuatorSaturationError(tau, bounds)
            raise SolverError("ProxSuite (inverse dynamics QP)",
                              QP_STATUS.get(info.status, str(info.status)),
                              f"primal residual {info.pri_res:.3e}")
        return sol, status, int(info.iter)

    def actuator_forces_at(self, q: npt.ArrayLike, twist: npt.ArrayLike, twist_dot: npt.ArrayLike,
                           wrench: npt.ArrayLike | None = None, method: str = "kkt") -> np.ndarray:
        """Unbounded inverse-dynamics actuator forces (6,) (N) at an assembled tree
        configuration ``q`` (nq,), for a platform ``twist`` and ``twist_dot`` (6,) and a
        ``wrench`` (6,) as in :meth:`inverse_dynamics` (no checks beyond the
        singularities): the legs are read from the universal-joint angles of ``q``."""
        ws = self._workspace()
        ck, dyn = ws.compiled, ws.dyn
        s = ck.scratch
        q = np.ascontiguousarray(q, dtype=float)
        twist_a, tdot_a = _vec6(twist, "twist"), _vec6(twist_dot, "twist_dot")
        wrench_a = None if wrench is None else _vec6(wrench, "wrench")
        code = kernels.legs_from_tree(ck.geo, q, np.empty(6), s.rot, s.wk)
        if code != kernels.OK:
            raise ck.error(code)
        v, a = np.empty(24), np.empty(24)
        kernels.tree_motion(ck.geo, s.rot, s.wk, twist_a, tdot_a, 2, v, a)
        return self._solve_tree(ws, self._tree_force(ws, q, v, a), wrench_a, method, None)[0]

    def static_forces(self, pose: npt.ArrayLike, wrench: npt.ArrayLike | None = None, *,
                      branch: npt.ArrayLike | None = None,
                      bounded: bool = True) -> npt.NDArray[np.float64]:
        """Actuator forces holding the platform at rest at ``pose`` under gravity and a wrench.

        ``J^T tau = G^T (g(q) + K dq) - wrench`` with ``g(q)`` the tree's generalised
        gravity (``pin.computeGeneralizedGravity``) and ``K dq`` the springs of the joint
        effects. For the default geometry at home and no load: about ``+1.651`` N on even
        carriages and ``-1.651`` N on odd ones. Coulomb friction at rest holds any force
        of the band ``tau + G^T f``, ``|f_j| <= coulomb_j`` (for a carriage's own friction:
        ``tau_i +- coulomb_i``); the frictionless ``tau`` is returned.

        Args:
            pose: (6,) (m, rad).
            wrench: ``(f, m)`` on the platform, world axes, about the platform origin
                (N, N m); default zero.
            bounded: raise when ``abs(tau) > geometry.max_actuator_force``.

        Returns:
            tau (6,) (N), force on carriage i along ``+u_k``.

        Raises:
            ActuatorSaturationError: with ``bounded``, a motion needing forces beyond
                ``geometry.max_actuator_force``.
            UnreachablePoseError: a leg cannot reach the pose.
            SingularityError: at a singular configuration.
            InputError: bad shape, non-finite or non-real values.
        """
        ws = self._workspace()
        ck, dyn = ws.compiled, ws.dyn
        signs = ck.signs if branch is None else check_branch(branch)
        pose_a = _vec6(pose, "pose")
        wrench_a = None if wrench is None else _vec6(wrench, "wrench")
        q, s = ws.q, ck.scratch
        code = kernels.tree_state(ck.geo, signs, pose_a, kernels.ZERO6, kernels.ZERO6, 0,
                                  q, ws.v, ws.a, s.rot, s.wk)
        if code != kernels.OK or (wrench_a is not None and not all_finite(wrench_a)):
            self._raise_code(ck, code, pose=pose, wrench=wrench)
        gravity = pin.computeGeneralizedGravity(dyn.model, dyn.data, q)
        if ws.forces:                  # the springs: tau_e = -K dq at rest (damping 0)
            gravity = gravity - dyn.effect_force_of_motion(q, np.zeros(dyn.nv),
                                                           np.zeros(dyn.nv))
        rhs = np.empty(6)
        kernels.project(ck.geo, s.rot, s.wk, gravity, kernels.ZERO6 if wrench_a is None
                        else wrench_a, wrench_a is not None, rhs)
        tau = np.empty(6)
        code = kernels.solve_forces(ck.geo, s.wk, s.mats, rhs, tau, ws.multipliers, ws.jac_t)
        if code != kernels.OK:
            raise ck.error(code)
        if bounded and ws.bounds is not None and \
                max(map(abs, tau.tolist())) > ws.bounds[0] * (1.0 + RESIDUAL_RTOL):
            raise ActuatorSaturationError(tau, ws.bounds)
        return tau

    @staticmethod
    def _raise_code(ck, code, **vectors) -> None:
        """Raise the error of a state the kernels refused: the :class:`InputError` of a
        non-finite input (by name), else :meth:`kernels.ClosedForm.error` of ``code``."""
        for name, value in vectors.items():
            if value is not None:
                as_array(value, (6,), name)
        raise ck.error(code)

    # -- forward dynamics ----------------------------------------------------------------
    def forward_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         actuator_forces: npt.ArrayLike, wrench: npt.ArrayLike | None = None, *,
                         branch: npt.ArrayLike | None = None,
                         method: str = "nullspace") -> ForwardDynamicsResult:
        """Platform acceleration produced by actuator forces (constrained forward dynamics).

        The tree state ``(q, v)`` comes in closed form (compiled,
        :mod:`~hexapod_pin.hexapod.kernels`). "nullspace" (default) is the
        independent-coordinate method: ``M_x twist_dot = J^T tau + wrench - h_x`` with
        ``M_x = G^T M G`` (``pin.crba``) and ``h_x = G^T rnea(q, v, a_0)``, one 6x6
        Cholesky solve, then ``a = G twist_dot + a_0`` (closure multipliers from the
        legs' tree rows, on first access). The other routes solve the constrained tree
        for ``a`` and return ``twist_dot = (R a_lin + w x v, R a_ang)``. The joint effects
        enter every route (the module docstring); with Coulomb friction at rest
        "nullspace" answers with the tree's stick / slip solve ("kkt", said in the status).

        Args:
            pose: (6,) (m, rad).
            twist: ``(v, w)`` world axes (m/s, rad/s), (6,).
            actuator_forces: ``tau`` (6,), force on carriage i along ``+u_k`` (N).
            wrench: ``(f, m)`` on the platform, world axes, about its origin; default 0.
            method: "nullspace" (see above), "pinocchio" (``pin.constraintDynamics``),
                "qp" (Gauss principle, ProxSuite) or "kkt" (numpy); they agree to 1e-10.

        Returns:
            :class:`ForwardDynamicsResult`.

        Raises:
            UnreachablePoseError: a leg cannot reach the pose.
            SingularityError: at a singular configuration.
            InputError: bad shape, non-finite or non-real values.
            SolverError: a solve that does not verify.
        """
        if method not in HEXAPOD_FORWARD_METHODS:
            raise InputError("method", method, f"expected one of {HEXAPOD_FORWARD_METHODS}")
        ws = self._workspace()
        ck, dyn = ws.compiled, ws.dyn
        signs = ck.signs if branch is None else check_branch(branch)
        pose_a, twist_a = _vec6(pose, "pose"), _vec6(twist, "twist")
        tau_a = _vec6(actuator_forces, "actuator_forces")
        wrench_a = None if wrench is None else _vec6(wrench, "wrench")
        q, v, acc0 = np.empty(dyn.clm.nq), np.empty(dyn.nv), np.empty(dyn.nv)
        # the drift a_0 (tree acceleration at twist_dot = 0) only for the null-space route
        level = 2 if method == "nullspace" else 1
        s = ck.scratch
        code = kernels.tree_state(ck.geo, signs, pose_a, twist_a, kernels.ZERO6, level, q,
                                  v, acc0, s.rot, s.wk)
        if code != kernels.OK:
            self._raise_code(ck, code, pose=pose, twist=twist, actuator_forces=actuator_forces,
                             wrench=wrench)
        twist_dot = np.empty(6)
        effect, rest = dyn.effect_terms(q, v) if ws.forces else (None, ())
        if method == "nullspace" and len(rest):
            method, note = "kkt", " (nullspace: Coulomb friction at rest, solved on the tree)"
        else:
            note = ""
        if method == "nullspace":
            mass = pin.crba(dyn.model, dyn.data, q)
            bias = pin.rnea(dyn.model, dyn.data, q, v, acc0)
            if effect is not None:
                bias = bias - effect
            acc = np.empty(dyn.nv)
            code = kernels.nullspace_forward(
                ck.geo, s.rot, s.wk, mass, bias, tau_a,
                kernels.ZERO6 if wrench_a is None else wrench_a, wrench_a is not None, acc0,
                ws.work, twist_dot, acc)
            if code == kernels.NONFINITE:
                self._raise_code(ck, code, pose=pose, twist=twist,
                                 actuator_forces=actuator_forces, wrench=wrench)
            if code != kernels.OK:
                raise SolverError("null-space forward dynamics", "mass matrix not positive "
                                  "definite", f"M_x = {ws.work[24:30].tolist()}")
            lazy = _LazyTreeMultipliers(
                ws, owned_copy(pose_a, pose), q, v, acc, owned_copy(tau_a, actuator_forces),
                signs, effect)
            details = _ForwardDetails(dyn, q, ws.leg_of_closure, ws.lock, rows=lazy)
            return ForwardDynamicsResult(twist_dot, acc[self.indices.carriage_v], acc, method,
                                         "solved", 0, details,
                                         self._conditioning(lazy.pose, signs))
        if not all_finite(tau_a) or (wrench_a is not None and not all_finite(wrench_a)):
            self._raise_code(ck, kernels.NONFINITE, pose=pose, twist=twist,
                             actuator_forces=actuator_forces, wrench=wrench)
        tau = np.zeros(dyn.nv)
        tau[dyn.clm.actuated_v] = tau_a
        if wrench_a is not None:
            kernels.wrench_to_tree(s.rot, wrench_a, tau)
        acc = None
        if method == "pinocchio" and dyn.redundant is False and effect is None:
            acc, prox = dyn.pinocchio_call(q, v, tau, False)
        if acc is not None:
            acc = acc.copy()
            details = _ForwardDetails(dyn, q, ws.leg_of_closure, ws.lock,
                                      local=dyn.data.lambda_c.copy())
            status, iters = "solved", int(prox.iter)
        else:
            res = dyn.forward(q, v, tau, method)
            acc, status, iters = res.a, res.status + note, res.iterations
            details = _ForwardDetails(dyn, q, ws.leg_of_closure, ws.lock, rows=res.multipliers)
        kernels.twist_dot_of(s.rot, twist_a, acc[ws.ff_v], twist_dot)
        method = "nullspace" if note else method
        return ForwardDynamicsResult(twist_dot, acc[self.indices.carriage_v], acc, method,
                                     status, iters, details,
                                     self._conditioning(owned_copy(pose_a, pose), signs))

    # -- reduced (null-space) dynamics ------------------------------------------------------
    def reduced_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         branch: npt.ArrayLike | None = None) -> ReducedDynamics:
        """Dynamics in platform coordinates (null-space / independent-coordinate method).

        With ``T`` (nv, 6) the map ``v = T twist`` that keeps the closures
        (``J_c T = 0``, closed form: :func:`kernels.velocity_map`) and ``a = T
        twist_dot + a_0``, projecting the tree equation of motion on ``T^T`` removes the
        closure forces::

            J^T tau + wrench = M_x twist_dot + h_x,
            M_x = T^T M T,   h_x = T^T (M a_0 + h) = T^T rnea(q, v, a_0)

        since ``S T = J`` and ``T^T`` maps the free-flyer generalised force of the
        wrench back to ``(f, m)``. With joint effects ``M`` holds the armature and
        ``h_x = T^T (rnea(q, v, a_0) - tau_e)``, ``tau_e`` the force of damping, springs
        and the friction of the sliding coordinates (that of a coordinate at rest is
        set-valued: forward dynamics solves it).

        Args:
            pose: (6,) (m, rad).
            twist: ``(v, w)`` world axes (6,).

        Returns:
            :class:`ReducedDynamics` (unpacks as ``M_x, h_x``).
        """
        ws = self._workspace()
        ck, dyn = ws.compiled, ws.dyn
        signs = ck.signs if branch is None else check_branch(branch)
        pose_a, twist_a = _vec6(pose, "pose"), _vec6(twist, "twist")
        q, v, acc0 = np.empty(dyn.clm.nq), np.empty(dyn.nv), np.empty(dyn.nv)
        s = ck.scratch
        code = kernels.tree_state(ck.geo, signs, pose_a, twist_a, kernels.ZERO6, 2, q, v,
                                  acc0, s.rot, s.wk)
        if code != kernels.OK:
            self._raise_code(ck, code, pose=pose, twist=twist)
        mass = pin.crba(dyn.model, dyn.data, q)
        bias = pin.rnea(dyn.model, dyn.data, q, v, acc0)
        if ws.forces:
            bias = bias - dyn.effect_terms(q, v)[0]
        vmap, m_x, h_x = np.empty((dyn.nv, 6)), np.empty((6, 6)), np.empty(6)
        kernels.reduced_tree(ck.geo, s.rot, s.wk, mass, bias, vmap, m_x, h_x)
        return ReducedDynamics(m_x, h_x, vmap[self.indices.carriage_v].copy(), vmap)

    # -- energies ----------------------------------------------------------------------------
    def energies(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                 branch: npt.ArrayLike | None = None) -> Energies:
        """Kinetic and potential energy of the whole mechanism (J).

        Kinetic ``1/2 v^T (M + A) v`` (the rotors' armature included); potential: ``sum
        m_b g z_b`` over every body's centre of mass (zero at z = 0) plus the springs'
        ``sum K dq^2 / 2`` (:func:`~hexapod_pin.core.energy.energy_totals`).

        Args:
            pose: (6,) (m, rad).
            twist: ``(v, w)`` world axes (6,).
        """
        q, v = self.tree_state(pose, twist, branch)
        return self.tree_energies(q, v)

    def tree_energies(self, q: npt.ArrayLike, v: npt.ArrayLike) -> Energies:
        """:meth:`energies` from a tree state ``q`` (nq,), ``v`` (nv,) (Pinocchio conventions)."""
        kinetic, potential = energy_totals(self.model, q, v)
        return Energies(kinetic, potential, kinetic + potential)

    # -- batch ----------------------------------------------------------------------------
    def inverse_dynamics_batch(self, poses: npt.ArrayLike, twists: npt.ArrayLike,
                               twist_dots: npt.ArrayLike, wrenches: npt.ArrayLike | None = None, *,
                               bounded: bool = True) -> BatchInverseDynamics:
        """Inverse dynamics of N states at once (closed form, vectorised numpy).

        The Newton-Euler kernels over N states (:mod:`hexapod_pin.hexapod.batch`; independent
        of the Pinocchio tree route of :meth:`inverse_dynamics`; they agree to round-off).

        Args:
            poses: (N, 6), conventions as in :meth:`inverse_dynamics`.
            twists: (N, 6), conventions as in :meth:`inverse_dynamics`.
            twist_dots: (N, 6), conventions as in :meth:`inverse_dynamics`.
            wrenches: (N, 6) or None.
            bounded: raise :class:`BatchActuatorSaturationError` (an
                :class:`ActuatorSaturationError`) for the first state beyond the bounds.

        Returns:
            :class:`~hexapod_pin.core.results.BatchInverseDynamics`.

        Raises:
            InputError: bad shapes or NaN / inf, rows of different lengths.
            BatchUnreachablePoseError: a pose out of reach, the first such state (a subclass
                of :class:`UnreachablePoseError`, with its ``index``).
            BatchSingularityError: a singular state, the first such state (a subclass of
                :class:`SingularityError`, with its ``index``).
        """
        required(twists=twists, twist_dots=twist_dots)
        poses, twists, twist_dots, wrenches, _ = check_batch(poses, twists, twist_dots,
                                                             wrenches)
        geo = self.closed_form.dynamics_geo
        if geo[kernels.PASSIVE]:                 # effects the kernels do not model
            res = batch_of_states(len(poses), lambda k: self.inverse_dynamics(
                poses[k], twists[k], twist_dots[k], batch_row(wrenches, k), bounded=bounded,
                joint_wrenches=False))
            return BatchInverseDynamics(stacked(res, "actuator_forces", (6,)),
                                        stacked(res, "closure_forces", (6, 3)),
                                        stacked(res, "residual", ()))
        return batch.inverse_dynamics_batch(geo, poses, twists, twist_dots, wrenches, bounded)

    def forward_dynamics_batch(self, poses: npt.ArrayLike, twists: npt.ArrayLike,
                               actuator_forces: npt.ArrayLike,
                               wrenches: npt.ArrayLike | None = None) -> BatchForwardDynamics:
        """Forward dynamics of N states at once (closed form, vectorised numpy).

        Solves the reduced equation ``M_x twist_dot = J^T tau + wrench - h_x`` per state
        (:mod:`hexapod_pin.hexapod.batch`).

        Args:
            poses: (N, 6) (m, rad).
            twists: (N, 6) (m/s, rad/s, world axes).
            actuator_forces: (N, 6) (N).
            wrenches: (N, 6) or None.

        Returns:
            :class:`~hexapod_pin.core.results.BatchForwardDynamics`.

        Raises:
            InputError: bad shape, non-finite or non-real values.
            BatchUnreachablePoseError: a pose out of reach.
            BatchSingularityError: a singular state.
        """
        required(twists=twists, actuator_forces=actuator_forces)
        poses, twists, _, wrenches, forces = check_batch(poses, twists, None, wrenches,
                                                         actuator_forces)
        geo = self.closed_form.dynamics_geo
        if geo[kernels.PASSIVE]:                 # effects the kernels do not model
            res = batch_of_states(len(poses), lambda k: self.forward_dynamics(
                poses[k], twists[k], forces[k], batch_row(wrenches, k)))
            return BatchForwardDynamics(stacked(res, "twist_dot", (6,)),
                                        stacked(res, "actuator_accelerations", (6,)),
                                        stacked(res, "closure_forces", (6, 3)))
        return batch.forward_dynamics_batch(geo, poses, twists, forces, wrenches)

    def static_forces_batch(self, poses: npt.ArrayLike, wrenches: npt.ArrayLike | None = None, *,
                            bounded: bool = True) -> npt.NDArray[np.float64]:
        """:meth:`static_forces` of N poses at once (closed form): (N, 6) forces (N).

        Raises:
            InputError: bad shape, non-finite or non-real values.
            BatchUnreachablePoseError: a pose out of reach.
            BatchSingularityError: a singular state.
            BatchActuatorSaturationError: with ``bounded``, forces beyond
                ``geometry.max_actuator_force``.
        """
        poses, _, _, wrenches, _ = check_batch(poses, None, None, wrenches)
        geo = self.closed_form.dynamics_geo
        if geo[kernels.PASSIVE]:                 # effects the kernels do not model
            return np.array(batch_of_states(len(poses), lambda k: self.static_forces(
                poses[k], batch_row(wrenches, k), bounded=bounded))).reshape(len(poses), 6)
        return batch.static_forces_batch(geo, poses, wrenches, bounded)

    def reduced_dynamics_batch(self, poses: npt.ArrayLike,
                               twists: npt.ArrayLike) -> BatchReducedDynamics:
        """:meth:`reduced_dynamics` of N states at once (closed form): ``M_x`` (N, 6, 6),
        ``h_x`` (N, 6), ``J`` (N, 6, 6).

        Raises:
            InputError: bad shape, non-finite or non-real values.
            BatchUnreachablePoseError: a pose out of reach.
            BatchSingularityError: a singular state.
        """
        required(twists=twists)
        poses, twists, _, _, _ = check_batch(poses, twists)
        geo = self.closed_form.dynamics_geo
        if geo[kernels.PASSIVE]:                 # effects the kernels do not model
            res = batch_of_states(len(poses), lambda k: self.reduced_dynamics(poses[k],
                                                                              twists[k]))
            return BatchReducedDynamics(stacked(res, "mass_matrix", (6, 6)),
                                        stacked(res, "bias", (6,)),
                                        stacked(res, "jacobian", (6, 6)))
        return batch.reduced_dynamics_batch(geo, poses, twists)

    # -- derivatives ------------------------------------------------------------------------
    def inverse_dynamics_derivatives(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                                     twist_dot: npt.ArrayLike, wrench: npt.ArrayLike | None = None
                                     ) -> InverseDynamicsDerivatives:
        """Derivatives of the inverse-dynamics actuator forces (no bounds applied), analytic.

        The implicit-function theorem on Pinocchio's constrained forward-dynamics
        derivatives (``pin.computeConstraintDynamicsDerivatives`` on the tree with the
        loop closures) and the closed-form derivatives of the platform -> tree map; see
        :mod:`hexapod_pin.hexapod.derivatives`. Exact up to round-off (the tests compare with
        finite differences). ``d_pose`` is in pose coordinates, with the twist, twist_dot
        and wrench held in world axes; :func:`hexapod_pin.hexapod.derivatives.analytic_derivatives`
        also gives the derivative along a world-frame tangent ``(dp, dtheta)``.

        Args:
            pose: as in :meth:`inverse_dynamics`.
            twist: as in :meth:`inverse_dynamics`.
            twist_dot: as in :meth:`inverse_dynamics`.
            wrench: as in :meth:`inverse_dynamics`.

        Returns:
            :class:`~hexapod_pin.core.results.InverseDynamicsDerivatives` (``actuator_forces``,
            ``d_pose``, ``d_world``, ``d_twist``, ``d_twist_dot``, ``d_wrench``).

        Raises:
            InputError: bad shape, non-finite or non-real values.
            UnreachablePoseError: a leg cannot reach the pose.
            SingularityError: at a singular configuration.
            SolverError: a solve that does not verify.
        """
        if self._derivatives is None:
            self._derivatives = DerivativesWorkspace(self.model, self.closed_form,
                                                     self.indices, self.geometry)
        return analytic_derivatives(self._derivatives, pose, twist, twist_dot, wrench)

"""The hexapod's dynamics at the platform level (pose, twist, twist_dot, wrench).

The default inverse dynamics ("kkt") of a single state is the compiled closed form in one
kernel call (:func:`~hexapod_pin.hexapod.kernels.inverse_dynamics_tree`: the tree state,
the Newton-Euler closed form, the closure forces and the verification of the answer, the
residual of the platform equation it solved), and so is the default forward dynamics
("nullspace") of a robot whose joints carry no effect force
(:func:`~hexapod_pin.hexapod.kernels.forward_dynamics_tree`); the other single-state
routes build the
tree state in closed form (the kernels of :mod:`hexapod_pin.hexapod.kernels`) and need one
or two Pinocchio calls (``rnea``, ``computeGeneralizedGravity``, ``crba`` or
``constraintDynamics``) and a 6x6 solve; the ``*_batch`` methods run the Newton-Euler
kernels over N states (:mod:`hexapod_pin.hexapod.batch`). The Pinocchio tree routes
(:mod:`hexapod_pin.core.dynamics`) are the independent reference the tests compare them
with; a result's lazy ``residual`` is that of the tree equation of motion on Pinocchio.

Joint and drive effects (``robot.effects``, :mod:`hexapod_pin.core.effects`): the
Pinocchio routes are generic over every coordinate of the tree. Pinocchio's ``crba`` and
``rnea`` carry the armature (``model.armature``), and the effects' generalised force
``tau_e`` joins the tree force before it is projected with ``G^T`` (``G^T (rnea(q, v, a) -
tau_e)``: inverse dynamics, statics with the springs; ``h_x = G^T (rnea(q, v, a_0) -
tau_e)``: reduced and null-space forward dynamics, ``tau_e`` without the friction of the
coordinates at rest). A coordinate with Coulomb friction at rest makes the "nullspace"
forward dynamics answer on the tree (its stick / slip solve). The batches and the default
inverse dynamics run the compiled closed form, which carries the carriages' drives; a
robot whose passive coordinates (universal joints, the platform's free flyer) carry
effects answers its inverse dynamics on the Pinocchio route and runs its batches state by
state on the single-state routes (the same numbers).

The plumbing (bounds, input and method checks, status codes to errors, the batch drivers,
the lazy parts of results, the energies) is
:class:`~hexapod_pin.core.closed_form.ClosedFormDynamics`;
this module supplies the hexapod's kernels of its contract.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, NoReturn

import threading

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import proxsuite

from . import kernels
from . import batch
from ..core.closed_form import (ClosedFormDynamics, ClosedFormRegressor, Inputs, LazyParts,
                                TreeDetails)
from ..core.closed_loop import ClosedLoopModel
from ..core.compiled import all_finite, all_within
from ..core.results import (BatchForwardDynamics, BatchInverseDynamics, BatchReducedDynamics,
                            ForwardDynamicsResult, InverseDynamicsResult, ReducedDynamics, SingularityMeasures,
                            new_result)
from ..core.dynamics import (INVERSE_METHODS, QP_SOLVED, QP_STATUS, RESIDUAL_RTOL,
                             ClosedLoopDynamics)
from . import derivatives
from .kinematics import HexapodKinematics, check_branch
from ..errors import (
    ActuatorSaturationError,
    HexapodPinError,
    NonFiniteResultError,
    SolverError,
)
from ..core.pose import rotation_from_rpy
from ..core.checks import MAX_MAGNITUDE, owned_copy, vec6, vec6_unscanned
from .geometry import HexapodGeometry

#: the hexapod's forward-dynamics routes: the tree routes and the null-space one
HEXAPOD_FORWARD_METHODS = ("pinocchio", "nullspace", "qp", "kkt")
#: ProxSuite accuracy of the hexapod's reduced inverse-dynamics QP (its eps_abs and
#: eps_rel: residuals relative to the data, N and N m)
_QP_EPS_REDUCED = 2e-14

# --------------------------------------------------------------------------------------
# hexapod: pose / twist-level API
# --------------------------------------------------------------------------------------
class _LazyTreeMultipliers:
    """Closure multipliers of a null-space forward-dynamics result, from the legs' tree
    rows at the computed motion (as the inverse dynamics does)."""

    __slots__ = ("acc", "effect", "forces", "pose", "q", "signs", "v", "ws")

    def __init__(self, ws, pose, q, v, acc, forces, signs, effect=None):
        self.ws, self.pose, self.q, self.v, self.acc = ws, pose, q, v, acc
        self.forces, self.signs, self.effect = forces, signs, effect

    def __call__(self, details: Any = None) -> np.ndarray:
        ws = self.ws
        # each leg's three tree rows (carriage, u_a, u_b) of rnea - tau_e = S^T tau +
        # J_c^T lambda (the wrench acts on the platform rows only)
        force = pin.rnea(ws.dyn.model, ws.dyn.data, self.q, self.v, self.acc)
        if self.effect is not None:
            force = force - self.effect
        tips = ws.compiled.tip_forces(self.pose, force, self.forces, self.signs)
        return tips[ws.leg_of_closure].reshape(-1)


def _pinocchio_multipliers(dyn: ClosedLoopDynamics, q: np.ndarray,
                           local: np.ndarray) -> Callable[[], np.ndarray]:
    """The closure multipliers (18,) of ``pin.constraintDynamics``, computed on first
    access: Pinocchio's LOCAL contact forces rotated into world axes
    (``lambda = R_c1 lambda_pin``)."""
    def rotate(details: Any = None) -> np.ndarray:
        pin.framesForwardKinematics(dyn.model, dyn.data, q)
        rots = np.array([dyn.data.oMf[c[2]].rotation for c in dyn.closure_frames])
        return np.einsum("kij,kj->ki", rots, local.reshape(-1, 3)).reshape(-1)
    return rotate


@dataclass
class _HexapodWorkspace:
    dyn: ClosedLoopDynamics
    ff_v: np.ndarray
    free_v: np.ndarray
    leg_of_closure: np.ndarray
    platform_joint: int
    compiled: kernels.ClosedForm
    q: np.ndarray = field(default_factory=lambda: np.empty(25))
    v: np.ndarray = field(default_factory=lambda: np.empty(24))
    a: np.ndarray = field(default_factory=lambda: np.empty(24))
    tau: np.ndarray = field(default_factory=lambda: np.empty(6))
    multipliers: np.ndarray = field(default_factory=lambda: np.empty(6))
    #: scratch of the single-state inverse dynamics (under the lock, never in a result)
    rhs: np.ndarray = field(default_factory=lambda: np.empty(6))
    mult: np.ndarray = field(default_factory=lambda: np.empty(6))
    jac_t: np.ndarray = field(default_factory=lambda: np.empty((6, 6)))
    work: np.ndarray = field(default_factory=lambda: np.empty((36, 6)))
    qps: dict = field(default_factory=dict)
    #: how the lazy parts of the inverse and forward results are computed
    inverse_parts: Any = None
    forward_parts: Any = None
    #: whether the joint effects give a force (damping, friction, springs): fixed for a
    #: model (a hand-written armature changes the armature only, which Pinocchio reads)
    forces: bool = False


class HexapodDynamics(ClosedFormDynamics):
    """The hexapod's dynamics at the platform level: the component that
    :class:`~hexapod_pin.hexapod.robot.Hexapod` delegates its dynamics methods to, the
    hexapod's kernels of the :class:`~hexapod_pin.core.closed_form.ClosedFormDynamics`
    contract (which holds the bounds, checks, errors, batch drivers and energies).

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
    problems) as explicit attributes, built on first use.

    Conventions (see the README): pose ``(x, y, z, roll, pitch, yaw)``, twist
    ``(v, w)`` of the platform origin in world axes, ``twist_dot`` its plain time
    derivative, actuator force ``tau_i`` on carriage i along ``+u_k`` (N), wrench
    ``(f, m)`` applied on the platform by the environment, world axes, moment about the
    platform origin (N, N m).

    The default inverse dynamics is the Newton-Euler closed form of the kernels (the
    batches' kernels), the tree state included, in one compiled call; the other single
    states go through the Pinocchio tree. The tree state comes in closed form
    (the kernels of :mod:`~hexapod_pin.hexapod.kernels`): ``q`` from the inverse kinematics
    (on the given branch) and the leg directions, ``v = G twist`` and ``a`` from the leg
    kinematics (they keep the closures by construction), the free-flyer part
    ``(R^T v, R^T w)`` and ``(R^T (vdot - w x v), R^T wdot)``; the wrench enters as the
    free-flyer generalised force ``(R^T f, R^T m)``. By virtual power the tree equation
    ``M a + h - tau_ext = S^T tau + J_c^T lambda`` projected with ``G^T`` (``J_c G = 0``,
    ``S G = J``) is ``J^T tau = G^T rnea(q, v, a) - wrench``: one ``pin.rnea`` and a 6x6
    solve (the "qp" inverse dynamics, and "kkt" when passive coordinates carry effects).
    The Newton-Euler kernels (the default "kkt", the batches ``*_batch``,
    :mod:`hexapod_pin.hexapod.batch`) are independent of ``pin.rnea``; the tests check
    that they agree with the Pinocchio tree routes to 1e-10.
    """

    dim = 6
    n_actuators = 6
    closure_shape = (6, 3)
    INVERSE_METHODS = INVERSE_METHODS
    FORWARD_METHODS = HEXAPOD_FORWARD_METHODS

    def __init__(self, geometry: HexapodGeometry, model: ClosedLoopModel, indices: Any,
                 closed_form: kernels.ClosedForm, lock: threading.RLock | None = None,
                 singularity: Callable[[npt.ArrayLike, npt.ArrayLike | None],
                                       SingularityMeasures] | None = None) -> None:
        super().__init__(geometry, model, lock,
                         HexapodKinematics(geometry, closed_form).singularity
                         if singularity is None else singularity)
        self.indices = indices
        self.closed_form = closed_form
        self._ws: _HexapodWorkspace | None = None

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
        ws = _HexapodWorkspace(dyn, ff_v, free_v, leg_of_closure,
                               clm.model.getJointId("platform_joint"), self.closed_form,
                               forces=clm.effects.has_forces)
        ws.inverse_parts = LazyParts(dyn, self.lock, tau_ext=self._tree_wrench,
                                     closure=self._tip_closure,
                                     to_multipliers=self._closure_rows,
                                     fext=self._platform_force)
        ws.forward_parts = LazyParts(dyn, self.lock, to_multipliers=self._closure_rows,
                                     to_closure=self._leg_closure)
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
        pose_a, twist_a = vec6(pose, "pose"), vec6(twist, "twist")
        q, v = np.empty(25), np.empty(24)
        s = ck.scratch
        code = kernels.tree_state(ck.geo, signs, pose_a, twist_a, twist_a, 1, q, v, v,
                                  s.rot, s.wk)
        if code != kernels.OK:
            self.refuse(code, ((pose, "pose"), (twist, "twist")))
        return q, v

    # -- the contract's other pieces ----------------------------------------------------
    @property
    def batch_kernels_apply(self) -> bool:
        """Whether the compiled batches model the robot's effects (the carriages' drives:
        yes; effects on the universal joints or the platform's free flyer: no)."""
        return not self.closed_form.dynamics_geo[kernels.PASSIVE]

    def tau_ext(self, wrench: np.ndarray | None, pose: np.ndarray) -> np.ndarray:
        """The wrench ``(f, m)`` (6,) as the tree's generalised force (nv,): the free-flyer
        rows ``(R^T f, R^T m)`` (body axes), zero elsewhere (and for None)."""
        ws = self._workspace()
        tau = np.zeros(ws.dyn.nv)
        if wrench is not None:
            rot = rotation_from_rpy(pose[3:])
            wrench = np.asarray(wrench, dtype=float)
            tau[ws.ff_v] = np.concatenate([rot.T @ wrench[:3], rot.T @ wrench[3:]])
        return tau

    def raise_kernel_status(self, code: int, inputs: Inputs, info: np.ndarray | None = None,
                            index: int | None = None,
                            pose: np.ndarray | None = None) -> NoReturn:
        """Raise :meth:`kernels.ClosedForm.error` of ``code`` (single states: the hexapod's
        batches raise in :mod:`hexapod_pin.hexapod.batch`).

        Raises:
            UnreachablePoseError: a leg cannot reach the pose.
            SingularityError: a singular configuration.
        """
        raise self.closed_form.error(code)

    # -- inverse dynamics --------------------------------------------------------------
    def inverse_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike, twist_dot: npt.ArrayLike,
                         wrench: npt.ArrayLike | None = None, *,
                         branch: npt.ArrayLike | None = None, method: str = "kkt",
                         bounded: bool = True,
                         joint_wrenches: bool = True) -> InverseDynamicsResult:
        """Actuator forces that produce a platform motion (closed-loop inverse dynamics).

        Includes the inertia and weight of the platform, legs and carriages. The tree
        state ``(q, v, a)`` comes in closed form. "kkt" (the default) runs the
        Newton-Euler closed form in the same compiled call
        (:func:`~hexapod_pin.hexapod.kernels.inverse_dynamics_tree`) and verifies its
        answer there: the platform equation ``A^T t = rhs`` it solved holds to
        :data:`~hexapod_pin.core.kernel_status.RESIDUAL_RTOL` (relative, a backward-error
        test), the forces and closure forces are finite, the type-II test passed, else a
        :class:`SolverError` / :class:`SingularityError`. "qp" (and "kkt" when passive
        coordinates carry joint effects) is the Pinocchio tree route: one ``pin.rnea``
        gives the tree's generalised forces, whose projection on the platform's motions
        (virtual power) is ``J^T tau + wrench`` (see the class docstring). The result's
        ``residual`` (first access) is that of the tree equation of motion on Pinocchio.

        Args:
            pose: ``(x, y, z, roll, pitch, yaw)`` (m, rad), shape (6,).
            twist: ``(v, w)`` of the platform origin, world axes (m/s, rad/s), (6,).
            twist_dot: time derivative of the twist (m/s^2, rad/s^2), (6,).
            wrench: ``(f, m)`` applied on the platform by the environment, world axes,
                moment about the platform origin (N, N m), (6,); default zero.
            branch: the IK branch of the legs (six +1 / -1, see
                :meth:`HexapodKinematics.inverse_kinematics`); default the home branch.
            method: "kkt" (default: the closed form, its 6x6 LU solve, the bounds then
                checked) or "qp" (ProxSuite: minimise ``1/2 |tau|^2`` subject to ``J^T tau =
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
            SolverError: the QP failed for another reason, or the closed form's answer
                failed its verification.
        """
        self.check_method(method, self.INVERSE_METHODS)
        ws = self._workspace()
        ck = ws.compiled
        signs = ck.signs if branch is None else check_branch(branch)
        # plain float64 inputs are scanned (finite, within MAX_MAGNITUDE) by the kernel
        pose_a, twist_a = vec6_unscanned(pose, "pose"), vec6_unscanned(twist, "twist")
        tdot_a = vec6_unscanned(twist_dot, "twist_dot")
        wrench_a = None if wrench is None else vec6_unscanned(wrench, "wrench")
        bounds = self.bounds(bounded)
        q, v, a = np.empty(25), np.empty(24), np.empty(24)
        s = ck.scratch
        geo = ck.dynamics_geo
        if method == "kkt" and not geo[kernels.PASSIVE]:
            # the closed form (Newton-Euler), verified in the same call
            tau, closure = np.empty(6), np.empty((6, 3))
            code = kernels.inverse_dynamics_tree(
                geo, signs, pose_a, twist_a, tdot_a,
                kernels.ZERO6 if wrench_a is None else wrench_a, bounds is not None,
                MAX_MAGNITUDE, q, v, a, tau, closure, s.rot, s.wk, s.mats)
            if code != kernels.OK:
                self._refuse_inverse(code, (v, a, tau, closure), bounds,
                                     ((pose, "pose"), (twist, "twist"),
                                      (twist_dot, "twist_dot"), (wrench, "wrench")),
                                     ((twist_a, "twist"), (tdot_a, "twist_dot"),
                                      (wrench_a, "wrench")))
            kept = owned_copy(pose_a, pose)
            wrench_kept = None if wrench_a is None else owned_copy(wrench_a, wrench)
            # the lazy parts: the residual of the tree equation on Pinocchio (rnea)
            details = TreeDetails(ws.inverse_parts, (q, v, a), tau, wrench_kept, kept, signs,
                                  closure=closure, wanted=joint_wrenches)
            return new_result(InverseDynamicsResult, {
                "actuator_forces": tau, "configuration": q, "velocity": v,
                "acceleration": a, "method": method, "status": "solved", "iterations": 0,
                "_details": details, "_conditioning": self.conditioning(kept, signs)})
        code = kernels.tree_state_within(ck.geo, signs, pose_a, twist_a, tdot_a, 2, q, v, a,
                                         s.rot, s.wk, MAX_MAGNITUDE)
        if code != kernels.OK or (wrench_a is not None
                                  and not all_within(wrench_a, MAX_MAGNITUDE)):
            self.refuse(code, ((pose, "pose"), (twist, "twist"), (twist_dot, "twist_dot"),
                               (wrench, "wrench")))
        force = self._tree_force(ws, q, v, a)
        tau, status, iters, _ = self._solve_tree(ws, force, wrench_a, method, bounds)
        kept = owned_copy(pose_a, pose)
        wrench_kept = None if wrench_a is None else owned_copy(wrench_a, wrench)
        # the lazy parts (ws.inverse_parts): the closure forces from the legs' tree rows
        details = TreeDetails(ws.inverse_parts, (q, v, a), tau, wrench_kept, kept, signs,
                              force=force, wanted=joint_wrenches)
        return new_result(InverseDynamicsResult, {
            "actuator_forces": tau, "configuration": q, "velocity": v, "acceleration": a,
            "method": method, "status": status, "iterations": iters, "_details": details,
            "_conditioning": self.conditioning(kept, signs)})

    def _refuse_inverse(self, code: int, state: tuple[np.ndarray, ...],
                        bounds: np.ndarray | None, inputs: Inputs,
                        motion: tuple[tuple[np.ndarray | None, str], ...]) -> NoReturn:
        """Raise the error of a refused closed-form inverse dynamics (``code`` not OK;
        ``state``: its ``(v, a, tau, closure)``): saturation (the needed forces), finite
        inputs whose motion overflowed (:meth:`overflow`, naming the input of ``motion``),
        an answer that failed its verification (:class:`SolverError` with the platform
        equation's residual), else :meth:`refuse` (a malformed input by name, or the
        pose's error)."""
        v, a, tau, closure = state
        if code == kernels.SATURATED and bounds is not None:
            raise ActuatorSaturationError(tau, bounds)
        if code == kernels.RESIDUAL:
            if not (all_finite(v) and all_finite(a) and all_finite(tau)
                    and all_finite(closure.reshape(-1))):
                raise self.overflow(motion, all_finite(v))
            wk = self._workspace().compiled.scratch.wk
            raise SolverError("hexapod closed-form inverse dynamics", "unverified",
                              f"platform equation A^T t = rhs off by "
                              f"{kernels.platform_residual(wk):.3e} (N, N m), forces "
                              f"{tau.tolist()}")
        self.refuse(code, inputs)

    # -- the lazy parts of results (ws.inverse_parts, ws.forward_parts: core.closed_form) ----
    def _tree_wrench(self, details: TreeDetails) -> np.ndarray:
        """The result's wrench on the tree (nv,) (:meth:`tau_ext`)."""
        return self.tau_ext(details.wrench, details.pose)    # type: ignore[arg-type]

    def _tip_closure(self, details: TreeDetails) -> np.ndarray:
        """(6, 3) force of each leg tip on the platform (carriage order), world axes: minus
        the platform's force on the tip (:meth:`kernels.ClosedForm.tip_forces`)."""
        return -self.closed_form.tip_forces(details.pose, details.force, details.tau,
                                            details.signs)

    def _closure_rows(self, closure: np.ndarray) -> np.ndarray:
        """The multipliers (18,) of closure forces (6, 3), in the closures' order."""
        return (-closure)[self._workspace().leg_of_closure].reshape(-1)

    def _platform_force(self, details: TreeDetails) -> dict[int, Any] | None:
        """The wrench as Pinocchio's external force on the platform joint (body axes)."""
        if details.wrench is None:
            return None
        ws = self._workspace()
        return {ws.platform_joint: pin.Force(details.tau_ext()[ws.ff_v])}

    def _leg_closure(self, rows: np.ndarray) -> np.ndarray:
        """The closure forces (6, 3), carriage order, of the multipliers (18,)."""
        out = np.empty((6, 3))
        out[self._workspace().leg_of_closure] = -rows.reshape(-1, 3)
        return out

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

    def _solve_tree(self, ws, force, wrench_a, method, bounds):
        """``J^T tau = G^T force - wrench`` at the legs of the last tree state, under the
        bounds by ``method``: ``(tau, status, iterations, rhs)`` (``rhs`` the workspace's
        scratch: valid until the next call under the lock). Raises
        :class:`SingularityError` at a type-II singularity."""
        ck = ws.compiled
        s = ck.scratch
        rhs, tau, mult = ws.rhs, np.empty(6), ws.mult
        code = kernels.project_and_solve(ck.geo, s.rot, s.wk, s.mats, force,
                                         kernels.ZERO6 if wrench_a is None else wrench_a,
                                         wrench_a is not None, rhs, tau, mult, ws.jac_t,
                                         self.passing_magnitude(bounds))
        if code == kernels.OK and method == "kkt":
            return tau, "solved", 0, rhs        # every |tau_i| within the bounds: passed
        if code not in (kernels.OK, kernels.SATURATED):
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
            self.check_bounds(tau, bounds)
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
        ck = ws.compiled
        s = ck.scratch
        q = np.ascontiguousarray(q, dtype=float)
        twist_a, tdot_a = vec6(twist, "twist"), vec6(twist_dot, "twist_dot")
        wrench_a = None if wrench is None else vec6(wrench, "wrench")
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
        pose_a = vec6(pose, "pose")
        wrench_a = None if wrench is None else vec6(wrench, "wrench")
        q, s = ws.q, ck.scratch
        code = kernels.tree_state(ck.geo, signs, pose_a, kernels.ZERO6, kernels.ZERO6, 0,
                                  q, ws.v, ws.a, s.rot, s.wk)
        if code != kernels.OK or (wrench_a is not None and not all_finite(wrench_a)):
            self.refuse(code, ((pose, "pose"), (wrench, "wrench")))
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
        self.check_bounds(tau, self.bounds(bounded))
        return tau

    # -- forward dynamics ----------------------------------------------------------------
    def forward_dynamics(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                         actuator_forces: npt.ArrayLike, wrench: npt.ArrayLike | None = None, *,
                         branch: npt.ArrayLike | None = None,
                         method: str = "nullspace") -> ForwardDynamicsResult:
        """Platform acceleration produced by actuator forces (constrained forward dynamics).

        The tree state ``(q, v)`` comes in closed form (compiled,
        :mod:`~hexapod_pin.hexapod.kernels`). "nullspace" (default) is the
        independent-coordinate method: ``M_x twist_dot = J^T tau + wrench - h_x``, one 6x6
        Cholesky solve, then ``a = G twist_dot + a_0``. For a robot whose joints carry no
        effect force (damping, friction, springs; an armature on the carriages is held)
        ``M_x`` and ``h_x`` are the Newton-Euler closed form's, in one compiled call that
        verifies its answer (:func:`~hexapod_pin.hexapod.kernels.forward_dynamics_tree`:
        the residual of the equation it solved relative to its data, a finite answer;
        else a :class:`SolverError`), the closure forces from the legs' balance; otherwise
        ``M_x = G^T M G`` (``pin.crba``) and ``h_x = G^T (rnea(q, v, a_0) - tau_e)``
        (closure multipliers from the legs' tree rows, on first access). The other
        routes solve the constrained tree
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
        self.check_method(method, self.FORWARD_METHODS)
        ws = self._workspace()
        ck, dyn = ws.compiled, ws.dyn
        signs = ck.signs if branch is None else check_branch(branch)
        # plain float64 inputs are scanned (finite, within MAX_MAGNITUDE) by the kernels
        pose_a, twist_a = vec6_unscanned(pose, "pose"), vec6_unscanned(twist, "twist")
        tau_a = vec6_unscanned(actuator_forces, "actuator_forces")
        wrench_a = None if wrench is None else vec6_unscanned(wrench, "wrench")
        inputs = ((pose, "pose"), (twist, "twist"), (actuator_forces, "actuator_forces"),
                  (wrench, "wrench"))
        geo = ck.dynamics_geo
        if method == "nullspace" and not ws.forces and not geo[kernels.PASSIVE]:
            return self._closed_form_forward(ws, geo, signs, pose_a, twist_a, tau_a,
                                             wrench_a, inputs, pose, actuator_forces)
        if not all_within(tau_a, MAX_MAGNITUDE) or (
                wrench_a is not None and not all_within(wrench_a, MAX_MAGNITUDE)):
            self.refuse(kernels.NONFINITE, inputs)
        q, v, acc0 = np.empty(dyn.clm.nq), np.empty(dyn.nv), np.empty(dyn.nv)
        # the drift a_0 (tree acceleration at twist_dot = 0) only for the null-space route
        level = 2 if method == "nullspace" else 1
        s = ck.scratch
        code = kernels.tree_state_within(ck.geo, signs, pose_a, twist_a, kernels.ZERO6, level,
                                         q, v, acc0, s.rot, s.wk, MAX_MAGNITUDE)
        if code != kernels.OK:
            self.refuse(code, inputs)
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
                self.refuse(code, inputs)
            if code != kernels.OK:
                raise SolverError("null-space forward dynamics", "mass matrix not positive "
                                  "definite", f"M_x = {ws.work[24:30].tolist()}")
            lazy = _LazyTreeMultipliers(
                ws, owned_copy(pose_a, pose), q, v, acc, owned_copy(tau_a, actuator_forces),
                signs, effect)
            details = TreeDetails(ws.forward_parts, (q, v, acc), lazy.forces, multipliers=lazy)
            return new_result(ForwardDynamicsResult, {
                "twist_dot": twist_dot, "actuator_accelerations": acc[self.indices.carriage_v],
                "tree_acceleration": acc, "method": method, "status": "solved", "iterations": 0,
                "_details": details, "_conditioning": self.conditioning(lazy.pose, signs)})
        tau = np.zeros(dyn.nv)
        tau[dyn.clm.actuated_v] = tau_a
        if wrench_a is not None:
            kernels.wrench_to_tree(s.rot, wrench_a, tau)
        acc = None
        if method == "pinocchio" and dyn.redundant is False and effect is None:
            acc, prox = dyn.pinocchio_call(q, v, tau, False)
        if acc is not None:
            acc = acc.copy()
            details = TreeDetails(ws.forward_parts, (q, v, acc), tau_a, multipliers=(
                _pinocchio_multipliers(dyn, q, dyn.data.lambda_c.copy())))
            status, iters = "solved", int(prox.iter)
        else:
            res = dyn.forward(q, v, tau, method)
            acc, status, iters = res.a, res.status + note, res.iterations
            details = TreeDetails(ws.forward_parts, (q, v, acc), tau_a,
                                  multipliers=res.multipliers)
        kernels.twist_dot_of(s.rot, twist_a, acc[ws.ff_v], twist_dot)
        method = "nullspace" if note else method
        return ForwardDynamicsResult(twist_dot, acc[self.indices.carriage_v], acc, method,
                                     status, iters, details,
                                     self.conditioning(owned_copy(pose_a, pose), signs))

    def _closed_form_forward(self, ws, geo, signs, pose_a, twist_a, tau_a, wrench_a, inputs,
                             pose, actuator_forces) -> ForwardDynamicsResult:
        """The "nullspace" forward dynamics of a robot whose joints carry no effect force:
        the reduced closed form in one compiled call
        (:func:`~hexapod_pin.hexapod.kernels.forward_dynamics_tree`, verified there: the
        residual of ``M_x twist_dot = J^T tau + wrench - h_x`` it solved, finite answers),
        the closure forces from the legs' Newton-Euler balance."""
        s = ws.compiled.scratch
        q, v, acc = np.empty(25), np.empty(24), np.empty(24)
        twist_dot, closure = np.empty(6), np.empty((6, 3))
        code = kernels.forward_dynamics_tree(
            geo, signs, pose_a, twist_a, tau_a, kernels.ZERO6 if wrench_a is None else wrench_a,
            MAX_MAGNITUDE, q, v, acc, twist_dot, closure, s.rot, s.wk, s.mats)
        if code == kernels.NOT_PD:
            raise SolverError("null-space forward dynamics", "mass matrix not positive "
                              "definite", f"M_x = {s.mats[2].tolist()}")
        if code == kernels.RESIDUAL:
            if not (all_finite(v) and all_finite(twist_dot)):
                raise self.overflow(((twist_a, "twist"), (tau_a, "actuator_forces"),
                                     (wrench_a, "wrench")), all_finite(v))
            raise SolverError("null-space forward dynamics", "unverified",
                              f"M_x twist_dot = J^T tau + wrench - h_x missed, twist_dot "
                              f"{twist_dot.tolist()}")
        if code != kernels.OK:
            self.refuse(code, inputs)
        kept = owned_copy(pose_a, pose)
        # the multipliers on first access (ws.forward_parts)
        details = TreeDetails(ws.forward_parts, (q, v, acc), owned_copy(tau_a, actuator_forces),
                              closure=closure)
        return new_result(ForwardDynamicsResult, {
            "twist_dot": twist_dot, "actuator_accelerations": acc[self.indices.carriage_v],
            "tree_acceleration": acc, "method": "nullspace", "status": "solved",
            "iterations": 0, "_details": details, "_conditioning": self.conditioning(kept,
                                                                                  signs)})

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
        pose_a, twist_a = vec6(pose, "pose"), vec6(twist, "twist")
        q, v, acc0 = np.empty(dyn.clm.nq), np.empty(dyn.nv), np.empty(dyn.nv)
        s = ck.scratch
        code = kernels.tree_state(ck.geo, signs, pose_a, twist_a, kernels.ZERO6, 2, q, v,
                                  acc0, s.rot, s.wk)
        if code != kernels.OK:
            self.refuse(code, ((pose, "pose"), (twist, "twist")))
        mass = pin.crba(dyn.model, dyn.data, q)
        bias = pin.rnea(dyn.model, dyn.data, q, v, acc0)
        if ws.forces:
            bias = bias - dyn.effect_terms(q, v)[0]
        vmap, m_x, h_x = np.empty((dyn.nv, 6)), np.empty((6, 6)), np.empty(6)
        kernels.reduced_tree(ck.geo, s.rot, s.wk, mass, bias, vmap, m_x, h_x)
        return ReducedDynamics(m_x, h_x, vmap[self.indices.carriage_v].copy(), vmap)

    # -- the dynamic regressor (the closed-form route of hexapod_pin.identification) -------
    supplies_regressor = True

    def regressor(self, pose: npt.ArrayLike, twist: npt.ArrayLike, twist_dot: npt.ArrayLike,
                  branch: npt.ArrayLike | None = None) -> ClosedFormRegressor:
        """The dynamic regressor of one platform state in closed form
        (:func:`kernels.regressor`): ``tau = inertial @ pi`` for the inertial parameters
        of the 19 tree bodies (Pinocchio's convention and body frames, the tree's joint
        order: ``carriage_i``, ``u_i_a`` (the cross), ``u_i_b`` (the leg) for i = 0..5,
        then ``platform_joint``), from the closed form's body kinematics and its force
        projection ``G_a^T = J^-T G^T``, no Pinocchio call; the carriages' rates for the
        drive columns. Equal to the tree route of
        :class:`~hexapod_pin.identification.ClosedLoopRegressor` to round-off (tests).

        Args:
            pose: ``(x, y, z, roll, pitch, yaw)`` (m, rad), (6,).
            twist: ``(v, w)`` of the platform origin, world axes (m/s, rad/s), (6,).
            twist_dot: its time derivative (m/s^2, rad/s^2), (6,).
            branch: the IK branch (six +1 / -1); default home.

        Returns:
            :class:`~hexapod_pin.core.closed_form.ClosedFormRegressor`: ``inertial``
            (6, 190) (N per parameter unit), carriage rates (m/s) and accelerations
            (m/s^2) (6,).

        Raises:
            InputError: bad shape, non-finite or non-real values, a bad branch.
            UnreachablePoseError: a leg cannot reach the pose.
            SingularityError: type I, gimbal lock or type II.
            NonFiniteResultError: the rows overflow (inputs near the largest magnitude).
        """
        ck = self.closed_form
        signs = ck.signs if branch is None else check_branch(branch)
        pose_a, twist_a = vec6(pose, "pose"), vec6(twist, "twist")
        tdot_a = vec6(twist_dot, "twist_dot")
        rows, qd, qdd = np.empty((6, kernels.N_INERTIAL)), np.empty(6), np.empty(6)
        s = ck.scratch
        code = kernels.regressor(ck.geo, signs, pose_a, twist_a, tdot_a, rows, qd, qdd,
                                 s.rot, s.wk, s.mats, np.empty((6, 6, 3)),
                                 np.empty((24, 6)), np.empty((6, 10)))
        if code == kernels.NONFINITE:
            raise NonFiniteResultError("HexapodDynamics.regressor", "inertial rows")
        if code != kernels.OK:
            self.refuse(code, ((pose, "pose"), (twist, "twist"), (twist_dot, "twist_dot")))
        return ClosedFormRegressor(rows, qd, qdd)

    def regressor_batch_kernel(self, poses: np.ndarray, twists: np.ndarray,
                               twist_dots: np.ndarray,
                               branch: npt.ArrayLike | None = None) -> ClosedFormRegressor:
        """:meth:`regressor` of N checked states by the compiled batch
        (:func:`batch.regressor_batch`; the same kernel: the same numbers)."""
        signs = batch.batch_signs(branch, len(poses))
        return ClosedFormRegressor(*batch.regressor_batch(self.closed_form.geo, poses, twists,
                                                          twist_dots, signs))

    # -- batch kernels (the drivers: ClosedFormDynamics) -----------------------------------
    def inverse_batch_kernel(self, poses: np.ndarray, twists: np.ndarray,
                             twist_dots: np.ndarray, wrenches: np.ndarray | None,
                             bounded: bool) -> BatchInverseDynamics:
        """The Newton-Euler kernels over N checked states (:mod:`hexapod_pin.hexapod.batch`;
        independent of the Pinocchio tree route of :meth:`inverse_dynamics`; they agree to
        round-off)."""
        return batch.inverse_dynamics_batch(self.closed_form.dynamics_geo, poses, twists,
                                            twist_dots, wrenches, bounded)

    def forward_batch_kernel(self, poses: np.ndarray, twists: np.ndarray,
                             forces: np.ndarray,
                             wrenches: np.ndarray | None) -> BatchForwardDynamics:
        """The reduced equation per state (:mod:`hexapod_pin.hexapod.batch`)."""
        return batch.forward_dynamics_batch(self.closed_form.dynamics_geo, poses, twists,
                                            forces, wrenches)

    def static_batch_kernel(self, poses: np.ndarray, wrenches: np.ndarray | None,
                            bounded: bool) -> np.ndarray:
        """The static-force kernel over N checked poses (:mod:`hexapod_pin.hexapod.batch`)."""
        return batch.static_forces_batch(self.closed_form.dynamics_geo, poses, wrenches,
                                         bounded)

    def reduced_batch_kernel(self, poses: np.ndarray,
                             twists: np.ndarray) -> BatchReducedDynamics:
        """``M_x``, ``h_x``, ``J`` of N checked states (:mod:`hexapod_pin.hexapod.batch`)."""
        return batch.reduced_dynamics_batch(self.closed_form.dynamics_geo, poses, twists)

    # -- derivatives (the kernel behind core.platform_derivatives) --------------------------
    def inverse_dynamics_partials(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                                  twist_dot: npt.ArrayLike, wrench: npt.ArrayLike | None = None,
                                  branch: npt.ArrayLike | None = None
                                  ) -> tuple[np.ndarray, np.ndarray] | None:
        """The Newton-Euler closed form's analytic inverse-dynamics partials
        (:func:`hexapod_pin.hexapod.derivatives.inverse_partials`), or None when passive
        coordinates carry effects."""
        return derivatives.inverse_partials(self, pose, twist, twist_dot, wrench, branch)

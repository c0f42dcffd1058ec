"""Dynamics of closed-loop mechanisms on their Pinocchio tree (robot-agnostic).

For any :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`:

* :func:`forward_dynamics_tree` -- tree acceleration and closure multipliers for given
  generalised forces, three routes: ``pin.constraintDynamics`` ("pinocchio"), the
  Gauss-principle QP solved by ProxSuite ("qp"), a numpy KKT solve ("kkt").
* :func:`inverse_dynamics_tree` -- actuator forces and closure multipliers for a given
  closure-consistent tree motion, as a ProxSuite QP with actuator bounds ("qp") or a
  linear solve ("kkt"). Pinocchio has no closed-loop inverse dynamics; this is it.
* :class:`ClosedLoopDynamics` -- the cached workspace behind both (Pinocchio data,
  constraint data, the "pinocchio" route), reachable with :func:`dynamics_of`. It owns
  the other routes by composition: the "kkt" and "qp" forward routes
  (:mod:`~hexapod_pin.core.forward_routes`) and the inverse-dynamics routes
  (:mod:`~hexapod_pin.core.inverse_routes`); what they share (tolerances, result types,
  the forward verification, the cached ProxSuite problems) is in
  :mod:`~hexapod_pin.core.dynamics_common` and re-exported here.

Equations and sign conventions (tree coordinates, Pinocchio's ``q``, ``v``, ``a``)::

    M(q) a + h(q, v) = tau + J_c(q)^T lambda          (equation of motion)
    J_c(q) a = -gamma(q, v)                            (closures at acceleration level)
    tau = S^T u + tau_ext + tau_e(q, v, a)             (actuation + external loads +
                                                        joint effects)

``M`` includes the armature and ``tau_e`` is the force of the model's joint and drive
effects (``clm.effects``, :mod:`~hexapod_pin.core.effects`: damping, springs, Coulomb
friction, whose force on a coordinate at rest is solved for: stick or slip); a model
without effects has ``tau_e = 0``. The ``tau`` arguments of the routes below are the
applied ``S^T u + tau_ext``; the effects are added inside.

``J_c`` and ``gamma`` are those of :meth:`ClosedLoopModel.constraint_jacobian` and
:meth:`ClosedLoopModel.constraint_drift` (point-closure rows in world axes). With that
row convention, ``J_c^T lambda`` is the generalised force the closures exert on the
tree, and for a point closure ``lambda_c`` (N, world axes) is the force that the body
of ``frame2`` exerts on the body of ``frame1`` at the joint (``-lambda_c`` acts on
``frame2``'s body). ``S`` selects the actuated velocity coordinates (``clm.actuated_v``).

Joint couplings (``clm.couplings``, :mod:`~hexapod_pin.core.couplings`) add one row each
after the closure rows of ``J_c``, ``gamma`` and the multipliers (a coupling's multiplier
is the generalised force on its driven joint). Pinocchio's ``constraintDynamics`` knows
only its rigid constraints: the "pinocchio" route of a model with couplings is answered
by the KKT route (the status says so), the inverse routes work in our rows, and the state
check adds the couplings' residual and velocity rows.

For a weld the six multipliers pair with the ``log6`` rows (at an assembled
configuration, the spatial force in anchor-1 axes). Pinocchio's own ``lambda_c``
(LOCAL contact frames) is converted: ``lambda = R_c1 lambda_pin`` for a point
(:mod:`~hexapod_pin.core.closure_forces`, when the multipliers are read).

Redundant closures (rank-deficient ``J_c``): the accelerations and actuator forces
stay unique and every route returns them; the multipliers are not unique and every
route returns the minimum-norm ones. The rank of ``J_c`` is evaluated at the first
call and assumed to be structural afterwards (re-evaluated once when a route meets a
singular system).

Verification: no route returns an answer it has not checked. Forward dynamics checks
both equations above to :data:`RESIDUAL_RTOL` relative to the largest term of each
(:func:`~hexapod_pin.core.dynamics_common.verify_forward`); inverse dynamics checks
that ``a`` keeps the closures (to 1e-8) and that ``S^T u + J_c^T lambda = M a + h -
tau_ext`` (:func:`~hexapod_pin.core.linear_kernels.linear_residual`).
A failed check raises :class:`~hexapod_pin.errors.SolverError` naming the equation and
its relative residual, after the retries documented on each route.

State check: the public routes (:func:`forward_dynamics_tree`, :func:`inverse_dynamics_tree`,
:meth:`ClosedLoopDynamics.forward`, :meth:`ClosedLoopDynamics.inverse`,
:meth:`ClosedLoopDynamics.joint_wrenches`) refuse a ``q`` off the closures and a ``v``
with ``J_c v != 0`` beyond :data:`CLOSURE_QTOL` / :data:`CLOSURE_VTOL` (relative to the
model's reach and to ``|v|``; defined in :mod:`~hexapod_pin.core.dynamics_common`) with
:class:`~hexapod_pin.errors.InputError`. The errors are read from Pinocchio's constraint
datas after the route's own ``constraintDynamics`` call (the verified "pinocchio" path)
or after one cheap proximal pass (the other paths). The internal paths
(``forward_unchecked``, ``pinocchio_call``, ``pinocchio_verified``,
``inverse_from_force``: integrators at RK4 stage states, batch drivers) do not check.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Mapping
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import proxsuite

from ..errors import InputError
from .checks import as_array, solve_checked, vector
from .compiled import all_finite
from .closed_loop import ClosedLoopModel
from .closure_forces import LazyMultipliers, MultiplierConversion, joint_wrenches
from .closure_terms import (  # ClosureFrames re-exported
    ClosureFrames,
    closure_drift,
    closure_jacobian,
)
from .effects import (STICK_MARGIN, at_rest, check_stick_slip, effect_forces, friction_forces,
                      passive_forces)
from .dynamics_common import (  # re-exported: other modules and users import them from here
    CLOSURE_QTOL,
    CLOSURE_VTOL,
    QP_SOLVED,
    QP_STATUS,
    RESIDUAL_RTOL,
    TINY,
    ClosureStateCheck,
    TreeForwardDynamics,
    TreeInverseDynamics,
    independent_rows,
    independent_rows_of_rank,
)
from .forward_routes import ForwardDynamicsRoutes
from .inverse_routes import INVERSE_METHODS, InverseDynamicsRoutes
from .linear_kernels import (NULLSPACE_OK, kkt_residuals, nullspace_forward_solve,
                             reduced_kkt_solve)

__all__ = [
    "CLOSURE_QTOL", "CLOSURE_VTOL", "FORWARD_METHODS", "INVERSE_METHODS", "PIN_PROX_ITERS",
    "PIN_PROX_MU", "QP_SOLVED",
    "QP_STATUS", "RESIDUAL_RTOL", "ClosedLoopDynamics", "ClosureFrames", "TreeForwardDynamics",
    "TreeInverseDynamics", "box_qp", "dynamics_of", "forward_dynamics_tree", "independent_rows",
    "inverse_dynamics_tree", "null_space_basis",
]

FORWARD_METHODS = ("pinocchio", "qp", "kkt")

_F64 = np.dtype(np.float64)
#: builds a result named tuple from its fields without the keyword machinery (short path)
_FORWARD_NEW = tuple.__new__
#: Pinocchio proximal settings used when the closures are redundant (the acceleration
#: converges in a few iterations; every answer is verified, the multipliers are polished
#: to minimum norm when read). The proximal parameter is ``mu = PIN_PROX_MU / max(1, m)``,
#: ``m`` the largest diagonal entry of the mass matrix at the neutral configuration (kg,
#: kg m^2 as the units come): the iterations contract the error by ``mu / (mu + sigma)``
#: on the non-zero eigenvalues ``sigma`` of the Delassus matrix ``J M^-1 J^T``, the
#: smallest of which scales as ``1/m``, so heavy robots (the 5bar_linkage of
#: example-parallel-robots, ``m`` ~ 5e5: 500 iterations at an absolute 1e-8) converge in
#: as few iterations as light ones; ``mu`` is never raised above 1e-8 (a larger one costs
#: accuracy on robots with light links). Two iterations meet RESIDUAL_RTOL on every
#: redundant robot of the benchmarks and tests; a miss is answered by an exact solve on
#: Pinocchio's own terms (:meth:`ClosedLoopDynamics._exact_redundant`: the scaled KKT
#: system on the independent rows, else the null-space solve), never by more
#: iterations: at most PIN_PROX_ITERS proximal iterations per call.
PIN_PROX_MU = 1e-8
PIN_PROX_ITERS = 2


class PinocchioSolve(NamedTuple):
    """How a verified "pinocchio" solve was obtained.

    Attributes:
        iter: Pinocchio's proximal iterations of the call (1 for its direct solve).
        exact: whether an exact solve on Pinocchio's own terms answered
            (redundant rows whose proximal iterations missed the verification).
    """

    iter: int
    exact: bool


#: status strings of the redundant-row Pinocchio route by (mu, iterations, exact)
_REDUNDANT_STATUS: dict[tuple[float, int, bool], str] = {}


# --------------------------------------------------------------------------------------
# generic workspace
# --------------------------------------------------------------------------------------
class ClosedLoopDynamics:
    """Cached dynamics workspace of one :class:`ClosedLoopModel`.

    Owns its own ``pin.Data`` (it never touches ``clm.data``), the Pinocchio constraint
    data for ``pin.constraintDynamics``, and, by composition, the other routes with their
    buffers and ProxSuite problems (:attr:`forward_routes`, :attr:`inverse_routes`) and
    the multiplier conversions of its results (:attr:`conversion`). Get the instance of a
    model for the calling thread with :func:`dynamics_of`.

    Args:
        clm: the closed-loop model.
    """

    def __init__(self, clm: ClosedLoopModel) -> None:
        if not isinstance(clm, ClosedLoopModel):
            raise InputError("clm", clm, "expected a ClosedLoopModel")
        self.clm = clm
        self.model = clm.model
        self.data = self.model.createData()
        self.nv = self.model.nv
        self.n_rows = clm.n_rows
        #: the closure rows (the first ones); the joint couplings' rows follow
        self.n_closure_rows = clm.n_closure_rows
        #: the couplings' rows (:class:`~hexapod_pin.core.couplings.CouplingRows`), or None
        self.coupling_rows = clm.coupling_rows
        self.n_act = clm.n_actuated
        #: Pinocchio's constraint models and datas of the closures (for ``constraintDynamics``)
        self.pin_models, self.pin_datas = clm.pinocchio_constraints()
        self._pin_ready = False
        #: one :class:`~hexapod_pin.core.closure_terms.ClosureFrames` per closure (the model's)
        self.closure_frames = clm.closure_frames
        #: actuation selection ``S^T`` (nv, n_act): ``tau = selection @ u``
        self.selection = np.zeros((self.nv, self.n_act))
        self.selection[clm.actuated_v, np.arange(self.n_act)] = 1.0
        self._zero_v = np.zeros(self.nv)
        self._lower = np.tril_indices(self.nv, -1)
        self._rank: int | None = None
        #: the multiplier conversions of the results (their own data, under a lock: a
        #: result may convert its multipliers on any thread)
        self.conversion = MultiplierConversion(self.model, self.closure_frames,
                                               self.n_closure_rows)
        self._res_out = np.empty(2)
        self._pools: dict[int, pin.ModelPool] = {}
        self._pin_singular = False       # M structurally singular: Pinocchio refused
        self._rank_rechecked = False
        self._no_rows = (np.zeros((0, self.nv)), np.zeros(0))
        #: Pinocchio's constraint Jacobian (n_rows, nv; LOCAL rows) at the ``q`` of the last
        #: verified ``pinocchio_call`` (integrators reuse it); None before the first one
        self.last_jacobian: np.ndarray | None = None
        # the fast path of forward_actuated: shapes, the actuated coordinates (a slice when
        # contiguous), and the proximal settings of a verified Pinocchio solve (None until
        # the first verified call, and again when Pinocchio's answers are refused)
        self._shape_q, self._shape_v = (self.model.nq,), (self.nv,)
        self._shape_u = (self.n_act,)
        act = np.asarray(clm.actuated_v, dtype=int)
        self._act_index = slice(int(act[0]), int(act[0]) + act.size) if act.size and \
            np.array_equal(act, np.arange(act[0], act[0] + act.size)) else act
        self._pin_fast = None
        self._tau = np.zeros(self.nv)    # the generalised force of forward_actuated
        self._tau_zero = True
        #: the "kkt" and "qp" forward routes and the inverse-dynamics routes (composition:
        #: each keeps its own buffers and ProxSuite problems)
        self.forward_routes = ForwardDynamicsRoutes(self)
        self.inverse_routes = InverseDynamicsRoutes(self)

    # -- rank ----------------------------------------------------------------------------
    def closure_rank(self, q: np.ndarray, force: bool = False) -> int:
        """Rank of ``J_c``, evaluated at ``q`` on the first call (or when ``force``) and
        assumed structural afterwards."""
        if self._rank is None or force:
            self._rank = self.clm.rank(q).rank if self.n_rows else 0
        return self._rank

    @property
    def redundant_mu(self) -> float:
        """The proximal ``mu`` of the "pinocchio" route on redundant rows (see
        :data:`PIN_PROX_MU`)."""
        if not self._pin_ready:
            self._init_pinocchio()
        return float(self._prox_redundant.mu)

    @property
    def redundant(self) -> bool | None:
        """Whether the closures were found redundant (None before the first call)."""
        return None if self._rank is None else self._rank < self.n_rows

    # -- constraint terms -------------------------------------------------------------------
    def constraint_jacobian(self, q: np.ndarray) -> np.ndarray:
        """``J_c`` (n_rows, nv) at ``q`` (same as :meth:`ClosedLoopModel.constraint_jacobian`)."""
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        if self.coupling_rows is None:
            return self.jacobian_from(self.data)
        return np.vstack([self.jacobian_from(self.data), self.coupling_rows.jacobian(q)])

    def jacobian_from(self, data: pin.Data) -> np.ndarray:
        """``J_c`` (n_rows, nv) from ``data`` (a ``pin.Data`` of this model whose joint
        Jacobians and frame placements are up to date):
        :func:`~hexapod_pin.core.closure_terms.closure_jacobian`; the closure rows only
        (the joint couplings' rows need ``q``: :meth:`constraint_jacobian`)."""
        return closure_jacobian(self.model, data, self.closure_frames, self.n_closure_rows)

    def constraint_drift(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``gamma`` (n_rows,) at ``(q, v)`` (same as :meth:`ClosedLoopModel.constraint_drift`,
        on this workspace's data): :func:`~hexapod_pin.core.closure_terms.closure_drift`."""
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q, v, self._zero_v)
        pin.updateFramePlacements(model, data)
        drift = closure_drift(model, data, self.closure_frames, self.n_closure_rows)
        if self.coupling_rows is None:
            return drift
        return np.concatenate([drift, self.coupling_rows.drift(q, v)])

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Joint-space inertia matrix ``M(q)`` (nv, nv), symmetric (kg, kg m, kg m^2)."""
        mat = pin.crba(self.model, self.data, q).copy()   # upper triangle filled
        mat[self._lower] = mat.T[self._lower]
        return mat

    def _terms(self, q, v):
        """(M, h, J_c, gamma) at (q, v), ours."""
        jac = self.constraint_jacobian(q)
        gamma = self.constraint_drift(q, v)
        mass = self.mass_matrix(q)
        bias = pin.nonLinearEffects(self.model, self.data, q, v)
        return mass, bias, jac, gamma

    # -- forward dynamics -----------------------------------------------------------------
    def forward(self, q: npt.ArrayLike, v: npt.ArrayLike, tau: npt.ArrayLike,
                method: str = "pinocchio") -> TreeForwardDynamics:
        """Constrained forward dynamics; see :func:`forward_dynamics_tree` (the state
        checked the same way; raises InputError, SolverError)."""
        q = vector(q, self.model.nq, "q")
        v = vector(v, self.nv, "v")
        tau = vector(tau, self.nv, "tau")
        if method not in FORWARD_METHODS:
            raise InputError("method", method, f"expected one of {FORWARD_METHODS}")
        self.check_state(q, v)
        return solve_checked(lambda: self.forward_unchecked(q, v, tau, method),
                              ("q", q), ("v", v), ("tau", tau))

    def forward_unchecked(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray,
                          method: str) -> TreeForwardDynamics:
        """:meth:`forward` without the input checks (contiguous float64 arrays of the right
        sizes, a known method); for batch drivers and integrators. ``tau`` is the applied
        generalised force; the joint effects are added here (:meth:`effect_terms`), and
        the friction of the coordinates at rest is solved (:meth:`_stick_slip`)."""
        force, rest = self.effect_terms(q, v)
        if force is None:
            return self.forward_total(q, v, tau, method)
        total = tau + force
        if rest.size:
            return self._stick_slip(q, v, total, rest, method)
        return self.forward_total(q, v, total, method)

    def forward_total(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray,
                      method: str) -> TreeForwardDynamics:
        """:meth:`forward_unchecked` for a ``tau`` that already holds the effects' force
        (the rigid solve of ``M a + h = tau + J_c^T lambda``)."""
        rank = self.closure_rank(q)
        if method == "pinocchio":
            return self._forward_pinocchio(q, v, tau, rank)
        mass, bias, jac, gamma = self._terms(q, v)
        if method == "kkt":
            return self.forward_routes.kkt(mass, bias, jac, gamma, tau, rank)
        return self.forward_routes.qp(mass, bias, jac, gamma, tau, rank)

    # -- joint and drive effects (core.effects) ----------------------------------------------
    def effect_terms(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
        """``(force, rest)`` at ``(q, v)`` for forward dynamics: the generalised force (nv,)
        of damping, springs and the friction of the sliding coordinates (None when the
        model has no such effect), and the indices of the coordinates with Coulomb
        friction at rest (their friction is solved for)."""
        eff = self.clm.effects
        if not eff.has_forces:
            return None, _NO_INDEX
        force = passive_forces(self.model, eff, q, v)
        if not eff.has_coulomb:
            return force, _NO_INDEX
        force += friction_forces(eff, v)
        return force, at_rest(eff, v)

    def effect_force_of_motion(self, q: np.ndarray, v: np.ndarray,
                               a: np.ndarray) -> np.ndarray | None:
        """The generalised force (nv,) of every effect for the known motion ``(q, v, a)``
        (:func:`~hexapod_pin.core.effects.effect_forces`: what inverse dynamics
        balances); None when the model has none."""
        eff = self.clm.effects
        if not eff.has_forces:
            return None
        return effect_forces(self.model, eff, q, v, a)

    def friction_response(self, q: np.ndarray, coordinates: np.ndarray) -> np.ndarray:
        """``G = N_r (N^T M N)^-1 N_r^T`` (k, k): the response of the accelerations of the
        k velocity ``coordinates`` to unit forces on them, through the closures (``N`` an
        orthonormal basis of ``null(J_c)``, ``N_r`` its rows of those coordinates, ``M``
        with the armature); symmetric positive semi-definite."""
        basis = null_space_basis(self.constraint_jacobian(q), self.closure_rank(q))
        rows = basis[coordinates]
        return rows @ np.linalg.solve(basis.T @ self.mass_matrix(q) @ basis, rows.T)

    def _stick_slip(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, rest: np.ndarray,
                    method: str) -> TreeForwardDynamics:
        """Forward dynamics with the Coulomb friction of the coordinates ``rest`` at rest
        solved exactly: their friction forces ``f`` (``|f_i| <= coulomb_i``) make each
        either stick (``a_i = 0``) or slip against its friction (``f_i = -coulomb_i
        sign(a_i)``). With ``G`` the response of ``a[rest]`` to unit forces on those
        coordinates (through the closures: ``G = N_r (N^T M N)^-1 N_r^T``, ``N`` a basis
        of ``null(J_c)``) and ``a0`` their acceleration without that friction, ``f``
        solves the box QP ``min 1/2 f^T G f + a0^T f, -c <= f <= c`` (ProxSuite, then
        polished on its active set); its KKT conditions are exactly stick / slip. The
        answer is the verified rigid solve with ``tau + f`` and is checked for
        stick / slip before it is returned (SolverError otherwise)."""
        base = self.forward_total(q, v, tau, method)
        c = self.clm.effects.coulomb[rest]
        tol = 1e-9 * (float(np.max(np.abs(base.a))) + 1.0)
        f = box_qp(self.friction_response(q, rest), base.a[rest], c)
        total = tau.copy()
        total[rest] += f
        res = self.forward_total(q, v, total, method)
        check_stick_slip(f, c, res.a[rest], tol, "forward dynamics with Coulomb friction",
                         rest, "accelerations")
        n_stick = int(np.count_nonzero(np.abs(f) < c * (1.0 - STICK_MARGIN)))
        return res._replace(status=f"{res.status}; Coulomb friction at rest on "
                                   f"{rest.size} coordinates: {n_stick} stick, "
                                   f"{rest.size - n_stick} slip")

    def pinocchio_arguments(self) -> tuple:
        """``((model, data), (constraint models, constraint datas, proximal settings))``: the
        arguments of ``pin.constraintDynamics`` for non-redundant closures (exact settings)."""
        if not self._pin_ready:
            self._init_pinocchio()
        return ((self.model, self.data), (self.pin_models, self.pin_datas, self._prox_exact))

    def _init_pinocchio(self) -> None:
        pin.initConstraintDynamics(self.model, self.data, self.pin_models, self.pin_datas)
        self._prox_exact = pin.ProximalSettings(1e-13, 0.0, 1)
        #: the redundant rows' settings: mu = PIN_PROX_MU / max(1, m), m the largest diagonal
        #: entry of M at the neutral configuration (structural, the same on every thread)
        scale = float(np.max(np.diagonal(pin.crba(self.model, self.data,
                                                  pin.neutral(self.model))), initial=0.0))
        mu = PIN_PROX_MU / max(scale, 1.0) if math.isfinite(scale) else PIN_PROX_MU
        self._prox_redundant = pin.ProximalSettings(1e-13, mu, PIN_PROX_ITERS)
        self._exact_acc = np.empty(self.nv)
        self._exact_lam = np.empty(self.n_closure_rows)
        self._exact_rows: np.ndarray | None = None
        #: one cheap proximal pass: only the constraint terms of the call are used
        self._prox_probe = pin.ProximalSettings(1e-13, PIN_PROX_MU, 1)
        self._cd_list = list(self.pin_datas)
        self._all_points = all(c[0] for c in self.closure_frames)
        # live views of Pinocchio's data (eigenpy maps the Data members, allocated once)
        data = self.data
        self._v_ddq = data.ddq
        self._v_mass, self._v_nle, self._v_lambda = data.M, data.nle, data.lambda_c
        self._v_rhs = data.primal_rhs_contact[:self.n_closure_rows]
        self._pin_ready = True
        #: the closure check of the public routes (reads the constraint datas)
        self.state_check = ClosureStateCheck(self.model, self.pin_datas, self._probe)

    def _probe(self, q: np.ndarray, v: np.ndarray) -> None:
        """One cheap proximal ``pin.constraintDynamics`` pass at ``(q, v)`` (zero force):
        the constraint datas' errors and Jacobian terms at that state."""
        pin.constraintDynamics(self.model, self.data, q, v, self._zero_v, self.pin_models,
                               self.pin_datas, self._prox_probe)

    def check_state(self, q: np.ndarray, v: np.ndarray) -> None:
        """Refuse a state off the closures (tolerances :data:`CLOSURE_QTOL`,
        :data:`CLOSURE_VTOL`): one cheap proximal ``constraintDynamics`` pass at ``(q, v)``
        (contiguous float64 arrays of the right sizes), then
        :meth:`~hexapod_pin.core.dynamics_common.ClosureStateCheck.check`. Nothing to check
        without closures.

        Raises:
            InputError: a NaN / inf entry, ``q`` off the closures or ``v`` breaking them
                (the message names the residual and the tolerance).
        """
        if not self.n_rows:
            return
        if not self._pin_ready:
            self._init_pinocchio()
        self._finite(q, v)
        if self.coupling_rows is None:
            self._probe(q, v)
        self.check_after_call(q, v)

    @staticmethod
    def _finite(q: np.ndarray, v: np.ndarray) -> None:
        for name, x in (("q", q), ("v", v)):
            if not all_finite(x):
                as_array(x, x.shape, name)

    def check_after_call(self, q: np.ndarray, v: np.ndarray) -> None:
        """:meth:`check_state` on the constraint datas as the last ``constraintDynamics``
        call of this workspace (at ``(q, v)``) left them: no kinematic pass.

        Raises:
            InputError: see :meth:`check_state`.
        """
        try:
            if self.coupling_rows is not None:
                self._check_couplings(q, v)
                return
            self.state_check.check(q, v)
        except InputError:
            self._finite(q, v)          # a NaN / inf entry is named as such
            raise

    def _check_couplings(self, q: np.ndarray, v: np.ndarray) -> None:
        """The state check of a model with joint couplings: the closures' (after a probe
        of their own) and the couplings' residual ``q1 - f(q2)`` and velocity rows (to
        :data:`CLOSURE_QTOL` / :data:`CLOSURE_VTOL` times the length scale, m or rad)."""
        if not self._pin_ready:
            self._init_pinocchio()
        if self.n_closure_rows:
            self._probe(q, v)
            self.state_check.check(q, v)
        rows = self.coupling_rows
        if rows is None:
            return
        scale = self.state_check.scale
        res = float(np.max(np.abs(rows.residual(q))))
        if not res <= CLOSURE_QTOL * scale:
            raise InputError("q", q, f"off the joint couplings: residual {res:.3e} exceeds "
                             f"the tolerance {CLOSURE_QTOL * scale:.3e} (CLOSURE_QTOL = "
                             f"{CLOSURE_QTOL:g} x length scale {scale:.3g})")
        vel = float(np.max(np.abs(rows.jacobian(q) @ v)))
        tol = CLOSURE_VTOL * max(1.0, float(np.max(np.abs(v), initial=0.0))) * scale
        if not vel <= tol:
            raise InputError("v", v, f"breaks the joint couplings: J v = {vel:.3e} exceeds "
                             f"the tolerance {tol:.3e} (CLOSURE_VTOL = {CLOSURE_VTOL:g})")

    def pinocchio_call(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray,
                       redundant: bool) -> tuple[np.ndarray | None, PinocchioSolve]:
        """One verified ``pin.constraintDynamics`` call; returns (a or None, how).

        ``a`` is Pinocchio's own buffer (copy it before the next call); Pinocchio's LOCAL
        multipliers are in ``self.data.lambda_c``. ``None`` when the solve is not finite or
        misses one of the equations by more than :data:`RESIDUAL_RTOL` (relative; checked
        with Pinocchio's own ``M``, ``nle``, constraint Jacobian and drift). With
        ``redundant`` the proximal solve (``mu > 0``, :data:`PIN_PROX_ITERS` iterations)
        that misses the verification is replaced by an exact solve of the
        call's own terms (:meth:`_exact_redundant`, written into Pinocchio's ``ddq`` and
        ``lambda_c``; ``how.exact`` says so).
        """
        if not self._pin_ready:
            self._init_pinocchio()
        if self._pin_singular or self.coupling_rows is not None:
            return None, PinocchioSolve(0, False)
        prox = self._prox_redundant if redundant else self._prox_exact
        acc = pin.constraintDynamics(self.model, self.data, q, v, tau, self.pin_models,
                                     self.pin_datas, prox)
        if self._pin_verified(acc, tau):
            if self.n_rows:
                self._pin_fast = prox    # the short path of pinocchio_verified
            return acc, PinocchioSolve(prox.iter, False)
        diag = np.diagonal(self._v_mass)
        if np.min(diag) <= 1e-14 * max(np.max(diag), TINY):
            # a joint that moves no mass: Pinocchio's factorisation of M cannot hold this
            # model at any state (structural); the exact routes answer from now on
            self._pin_singular = True
            self._pin_fast = None
            return None, PinocchioSolve(prox.iter, False)
        if redundant and self._exact_redundant(tau):
            self._pin_fast = prox
            return self._v_ddq, PinocchioSolve(prox.iter, True)   # the exact answer
        return None, PinocchioSolve(prox.iter, False)

    def _exact_redundant(self, tau: np.ndarray) -> bool:
        """The exact solve of the last ``constraintDynamics`` call's system (Pinocchio's
        ``M``, ``nle``, constraint Jacobian :attr:`last_jacobian` and target
        ``primal_rhs``): the scaled KKT system on the structural independent rows
        (:func:`~hexapod_pin.core.linear_kernels.reduced_kkt_solve`), else, when that
        misses the verification (the kept rows no longer independent at this state, or
        the others not dependent on them), the null-space solve at the structural rank
        (:func:`~hexapod_pin.core.linear_kernels.nullspace_forward_solve`); each verified
        on every row like the call itself. When one is verified, its answer is written
        into Pinocchio's ``ddq`` and ``lambda_c`` and True returned."""
        jac = self.last_jacobian
        if jac is None or self._rank is None:
            return False
        acc, lam = self._exact_acc, self._exact_lam
        mass, nle, target = self._v_mass, self._v_nle, self._v_rhs
        if self._exact_rows is None:
            self._exact_rows = independent_rows_of_rank(jac, self._rank).astype(np.int64)
        for solve in (self._reduced_kkt, self._nullspace):
            if solve(mass, nle, tau, jac, target, acc, lam) != NULLSPACE_OK:
                continue
            eom, con = kkt_residuals(mass, nle, tau, jac, target, acc, lam, self._res_out)
            if eom <= RESIDUAL_RTOL and con <= RESIDUAL_RTOL:
                self._v_ddq[:] = acc
                self._v_lambda[:] = lam
                return True
        return False

    def _reduced_kkt(self, mass, nle, tau, jac, target, acc, lam) -> int:
        """:func:`~hexapod_pin.core.linear_kernels.reduced_kkt_solve` on the structural
        independent rows (a pivoted QR of the first exact solve's Jacobian)."""
        return reduced_kkt_solve(mass, nle, tau, jac, target, self._exact_rows, acc, lam)

    def _nullspace(self, mass, nle, tau, jac, target, acc, lam) -> int:
        """:func:`~hexapod_pin.core.linear_kernels.nullspace_forward_solve` at the
        structural rank (any rows)."""
        rank = self.n_rows if self._rank is None else self._rank
        return nullspace_forward_solve(mass, nle, tau, jac, target, rank, acc, lam)

    def _pin_verified(self, acc, tau) -> bool:
        """Whether Pinocchio's answer ``acc`` meets both equations (see
        :meth:`pinocchio_call`); Pinocchio's constraint Jacobian at the call's ``q`` (LOCAL
        rows, a new array) is left in :attr:`last_jacobian`."""
        if self.n_rows:
            jac = self.last_jacobian = pin.getConstraintsJacobian(
                self.model, self.data, self.pin_models, self.pin_datas)
            target = self._v_rhs           # Pinocchio's J a = primal_rhs (recomputed per call)
        else:
            jac, target = self._no_rows
        eom, con = kkt_residuals(self._v_mass, self._v_nle, tau, jac, target, acc,
                                 self._v_lambda, self._res_out)
        return eom <= RESIDUAL_RTOL and con <= RESIDUAL_RTOL

    def _pinocchio_result(self, q, v, tau, acc, iters, rank,
                          exact: bool = False) -> TreeForwardDynamics:
        """The result of a verified Pinocchio solve (``acc``: Pinocchio's buffer; ``tau``:
        possibly the caller's array): :meth:`pinocchio_result_of` on copies."""
        return self.pinocchio_result_of(q.copy(), v.copy(), tau.copy(), acc.copy(),
                                        self._v_lambda.copy(), iters, rank, exact)

    def pinocchio_result_of(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray,
                            acc: np.ndarray, lam_pin: np.ndarray, iters: int,
                            rank: int, exact: bool = False) -> TreeForwardDynamics:
        """The result of a verified Pinocchio solve from arrays the caller owns (kept as
        they are, no copies): ``acc`` (nv,) and Pinocchio's LOCAL multipliers ``lam_pin``.
        The multipliers are computed on access: ``lam_pin`` converted to our rows, or,
        with redundant rows, the minimum-norm ones (the proximal multipliers are
        minimum-norm only up to the conditioning of the regularised system). ``exact``:
        an exact solve answered after ``iters`` proximal iterations."""
        if rank == self.n_rows:
            lazy = LazyMultipliers(self.conversion.from_pinocchio, q, lam_pin)
            return TreeForwardDynamics(acc, lazy, "pinocchio", "solved", iters, rank, -1.0)
        mu = float(self._prox_redundant.mu)
        status = _REDUNDANT_STATUS.get((mu, iters, exact))
        if status is None:
            how = (f"{iters} proximal iterations unverified, exact KKT solve"
                   if exact else f"proximal mu={mu:.3g}, {iters} iterations")
            status = _REDUNDANT_STATUS[(mu, iters, exact)] = (
                f"solved (redundant rows: {how}; minimum-norm multipliers)")
        lazy = LazyMultipliers(self.conversion.minimum_norm, q, v, acc, tau)
        return TreeForwardDynamics(acc, lazy, "pinocchio", status, iters, rank, -1.0)

    def forward_actuated(self, q: npt.ArrayLike, v: npt.ArrayLike,
                         actuator_forces: npt.ArrayLike, tau_ext: npt.ArrayLike | None = None,
                         method: str = "pinocchio") -> TreeForwardDynamics:
        """:func:`forward_dynamics_tree` on this workspace (same arguments after ``clm``).

        The "pinocchio" route of a model whose first call was verified takes a short
        path: one fused input check (float64 arrays of the right shapes pass; anything
        else goes through :func:`~hexapod_pin.core.checks.as_array`), one
        ``pin.constraintDynamics`` call, its verification on Pinocchio's own ``M``,
        ``nle``, constraint Jacobian and drift (one compiled kernel), and the result with
        lazy multipliers. A call that fails the verification (or a non-finite input) takes
        the full route, which retries, falls back or raises. Both paths refuse a state off
        the closures (:meth:`check_after_call` on the short path, :meth:`check_state`
        before the full one).
        """
        nd = np.ndarray
        if not (type(q) is nd and type(v) is nd and q.dtype is _F64 and v.dtype is _F64
                and q.shape == self._shape_q and v.shape == self._shape_v
                and q.flags.c_contiguous and v.flags.c_contiguous):
            q = vector(q, self.model.nq, "q")
            v = vector(v, self.nv, "v")
        u = actuator_forces
        if not (type(u) is nd and u.dtype is _F64 and u.shape == self._shape_u):
            u = vector(u, self.n_act, "actuator_forces")
        # tau = S^T u + tau_ext in this thread's buffer (its other entries kept at zero
        # between calls without tau_ext); a result that keeps tau gets a copy
        tau = self._tau
        if tau_ext is None:
            if not self._tau_zero:
                tau.fill(0.0)
                self._tau_zero = True
            tau[self._act_index] = u
        else:
            tau_ext = vector(tau_ext, self.nv, "tau_ext")
            self._tau_zero = False
            tau[:] = tau_ext
            tau[self._act_index] += u
        applied = tau
        if self.clm.effects.has_forces:  # the joint effects' force joins the applied one
            force, rest = self.effect_terms(q, v)
            tau = None if rest.size else applied + force   # friction at rest: full route
        if method == "pinocchio" and tau is not None:
            how = self.pinocchio_verified(q, v, tau)
            if how is not None:          # the short path: the result with lazy multipliers
                self.check_after_call(q, v)  # the closure errors of that call
                rank = self.closure_rank(q)  # known: the model has a verified call
                if rank == self.n_rows:      # Pinocchio's multipliers, converted when read
                    lazy = LazyMultipliers(self.conversion.from_pinocchio, q.copy(),
                                           self._v_lambda.copy())
                    return _FORWARD_NEW(TreeForwardDynamics, (
                        self._v_ddq.copy(), lazy, "pinocchio", "solved", how.iter, rank,
                        -1.0))
                return self.pinocchio_result_of(q.copy(), v.copy(), tau.copy(),
                                                self._v_ddq.copy(), self._v_lambda.copy(),
                                                how.iter, rank, how.exact)
        elif method not in FORWARD_METHODS:
            raise InputError("method", method, f"expected one of {FORWARD_METHODS}")
        self.check_state(q, v)
        applied = applied.copy()
        return solve_checked(lambda: self.forward_unchecked(q, v, applied, method), ("q", q),
                              ("v", v), ("actuator_forces", u), ("tau_ext", tau_ext))

    def pinocchio_verified(self, q: np.ndarray, v: np.ndarray,
                           tau: np.ndarray) -> PinocchioSolve | None:
        """One ``pin.constraintDynamics`` call with the settings of the last verified call,
        verified on Pinocchio's own ``M``, ``nle``, constraint Jacobian and drift (one
        compiled kernel); with redundant rows, an answer that misses the verification is
        replaced by an exact solve of the same terms (:meth:`_exact_redundant`).
        Returns how it was solved (the answer is in ``self.data.ddq`` /
        ``self.data.lambda_c``, the constraint Jacobian at ``q`` in :attr:`last_jacobian`),
        or None when the model has no verified call yet or this answer fails the
        verification (no input checks)."""
        prox = self._pin_fast
        if prox is None:
            return None
        model, data, cms, cds = self.model, self.data, self.pin_models, self.pin_datas
        acc = pin.constraintDynamics(model, data, q, v, tau, cms, cds, prox)
        # checked on Pinocchio's own M, nle, J and drift (J a = primal_rhs)
        jac = self.last_jacobian = pin.getConstraintsJacobian(model, data, cms, cds)
        eom, con = kkt_residuals(self._v_mass, self._v_nle, tau, jac, self._v_rhs, acc,
                                 self._v_lambda, self._res_out)
        if eom <= RESIDUAL_RTOL and con <= RESIDUAL_RTOL:
            return PinocchioSolve(prox.iter, False)
        if prox is not self._prox_exact and self._exact_redundant(tau):
            return PinocchioSolve(prox.iter, True)
        return None

    def _forward_pinocchio(self, q, v, tau, rank) -> TreeForwardDynamics:
        if self.coupling_rows is not None:
            # Pinocchio's constraintDynamics has no joint-coupling rows: the KKT route
            mass, bias, jac, gamma = self._terms(q, v)
            res = self.forward_routes.kkt(mass, bias, jac, gamma, tau, rank)
            return TreeForwardDynamics(res.a, res.multipliers, "pinocchio",
                                       "joint couplings (not in pin.constraintDynamics): "
                                       "solved by the KKT route", 0, res.rank,
                                       res.constraint_residual)
        redundant = rank < self.n_rows
        acc, how = self.pinocchio_call(q, v, tau, redundant)
        if acc is None and not redundant and not self._rank_rechecked:
            # a structural rank found too high at the first call: re-evaluate once
            self._rank_rechecked = True
            new_rank = self.closure_rank(q, force=True)
            if new_rank < rank:
                rank, redundant = new_rank, True
                acc, how = self.pinocchio_call(q, v, tau, True)
        if acc is not None:
            if self.n_rows:
                self._pin_fast = self._prox_redundant if redundant else self._prox_exact
            return self._pinocchio_result(q, v, tau, acc, how.iter, rank, how.exact)
        # Pinocchio's factorisation cannot hold this problem (e.g. a zero pivot of M from a
        # massless link): the exact KKT route answers, and the status says so
        mass, bias, jac, gamma = self._terms(q, v)
        res = self.forward_routes.kkt(mass, bias, jac, gamma, tau, rank)
        return TreeForwardDynamics(res.a, res.multipliers, "pinocchio",
                                   "pin.constraintDynamics unverified; solved by the KKT route"
                                   + (" (redundant rows: minimum-norm multipliers)"
                                      if res.rank < self.n_rows else ""),
                                   0, res.rank, res.constraint_residual)

    # -- what the forward / inverse routes use ----------------------------------------------
    def closure_rank_from(self, jac: np.ndarray) -> int:
        """Re-evaluate the structural closure rank from ``jac`` (a route met a singular
        system) and return it."""
        self._rank = int(np.linalg.matrix_rank(jac))
        return self._rank

    def pinocchio_constraint_terms(self, q: np.ndarray, v: np.ndarray,
                                   tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio's constraint Jacobian ``J_pin`` (n_rows, nv; LOCAL rows, a new array)
        and target ``primal_rhs`` (n_rows,; ``J_pin a = primal_rhs`` for a motion that
        keeps the closures; a view, valid until the next call) at ``(q, v)``, from one
        cheap proximal ``pin.constraintDynamics`` pass with generalised force ``tau``
        (its acceleration is not used). Empty arrays without closures."""
        if not self.n_rows:
            return self._no_rows
        if self.coupling_rows is not None:   # our rows: J_c a = -gamma
            return self.constraint_jacobian(q), -self.constraint_drift(q, v)
        if not self._pin_ready:
            self._init_pinocchio()
        pin.constraintDynamics(self.model, self.data, q, v, tau, self.pin_models,
                               self.pin_datas, self._prox_probe)
        return (pin.getConstraintsJacobian(self.model, self.data, self.pin_models,
                                           self.pin_datas), self._v_rhs)

    def lazy_multipliers(self, q: np.ndarray, lam_pin: np.ndarray,
                         jac: np.ndarray | None = None) -> Callable[[], np.ndarray]:
        """A callable giving our row multipliers from Pinocchio's LOCAL ones ``lam_pin`` at
        ``q`` (computed on its first call, safe on any thread); with ``jac`` (Pinocchio's
        constraint Jacobian at ``q``) the minimum-norm multipliers of the same generalised
        force. ``q``, ``lam_pin`` and ``jac`` are kept: pass arrays the caller owns. With
        joint couplings the rows are already ours (:meth:`pinocchio_constraint_terms`)."""
        if self.coupling_rows is not None:
            return LazyMultipliers(_our_rows, lam_pin, jac)
        return LazyMultipliers(self.conversion.from_pinocchio, q, lam_pin, jac)

    # -- inverse dynamics (the routes of core.inverse_routes) -------------------------------
    def inverse(self, q: npt.ArrayLike, v: npt.ArrayLike, a: npt.ArrayLike,
                tau_ext: npt.ArrayLike | None = None, bounds: npt.ArrayLike | None = None,
                method: str = "qp") -> TreeInverseDynamics:
        """Closed-loop inverse dynamics; see :func:`inverse_dynamics_tree`."""
        return self.inverse_routes.inverse(q, v, a, tau_ext, bounds, method)

    def inverse_from_force(self, q: np.ndarray, v: np.ndarray, a: np.ndarray,
                           force: np.ndarray, tau_ext: np.ndarray, bounds: np.ndarray | None,
                           method: str) -> TreeInverseDynamics:
        """:meth:`~hexapod_pin.core.inverse_routes.InverseDynamicsRoutes.inverse_from_force`
        (``force = M a + h`` given; no input checks)."""
        return self.inverse_routes.inverse_from_force(q, v, a, force, tau_ext, bounds, method)

    def check_bounds(self, bounds: npt.ArrayLike | None) -> np.ndarray | None:
        """Actuator bounds as an (n_act,) array (None: unbounded); raises InputError."""
        return self.inverse_routes.check_bounds(bounds)

    # -- pooled data -----------------------------------------------------------------------
    def model_pool(self, threads: int) -> pin.ModelPool:
        """A ``pin.ModelPool`` of this model with ``threads`` datas (cached)."""
        pool = self._pools.get(threads)
        if pool is None:
            pool = self._pools[threads] = pin.ModelPool(self.model, threads)
        return pool

    # -- joint reaction wrenches ------------------------------------------------------------
    def joint_wrenches(self, q: npt.ArrayLike, v: npt.ArrayLike, a: npt.ArrayLike,
                       multipliers: npt.ArrayLike,
                       fext: Mapping[int, pin.Force] | None = None
                       ) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """Spatial force transmitted by every joint of the tree.

        Runs ``pin.rnea`` with the closure forces (from ``multipliers``) and ``fext``
        applied as external forces. Pinocchio's ``data.f[j]`` is then the spatial force
        that the parent body exerts on the child body of joint ``j`` through the joint,
        expressed in the joint's LOCAL frame at the joint origin: ``(f, m)`` (N, N m).
        Its projection on the joint's motion subspace is the joint's generalised
        force (the actuator force for an actuated joint, ~0 for a passive one).

        Args:
            q: tree configuration (nq,).
            v: tree velocity (nv,).
            a: tree acceleration (nv,).
            multipliers: closure multipliers (n_rows,) as returned by the routes.
            fext: extra external forces by joint id, each a ``pin.Force`` in that
                joint's LOCAL frame (e.g. a load on a floating body).

        Returns:
            (wrenches by joint name, each (6,) = (f, m)), and the generalised force
            ``tau`` (nv,) that rnea needs with those forces (``S^T u`` if consistent).

        Raises:
            InputError: an input that is not real, of the wrong shape, or not finite; a
                ``q`` off the closures or a ``v`` breaking them (:meth:`check_state`).
        """
        q = as_array(q, (self.model.nq,), "q")
        v = as_array(v, (self.nv,), "v")
        a = as_array(a, (self.nv,), "a")
        multipliers = as_array(multipliers, (self.n_rows,), "multipliers")
        self.check_state(q, v)
        if self.coupling_rows is None:
            return joint_wrenches(self.model, self.data, self.closure_frames, q, v, a,
                                  multipliers, fext)
        # the couplings' generalised forces act inside their joints: they take their part
        # of the joint torques (the wrenches are those of the motion and closure forces)
        ncl = self.n_closure_rows
        wrenches, tau = joint_wrenches(self.model, self.data, self.closure_frames, q, v, a,
                                       multipliers[:ncl], fext)
        return wrenches, tau - self.coupling_rows.jacobian(q).T @ multipliers[ncl:]


#: per thread: model -> its workspace (a workspace holds Pinocchio data and ProxSuite
#: problems that every call mutates: one per thread makes the generic routes thread-safe)
def dynamics_of(clm: ClosedLoopModel) -> ClosedLoopDynamics:
    """The :class:`ClosedLoopDynamics` workspace of ``clm`` for the calling thread (created
    once per model and thread, kept in ``clm.workspaces``: collected with the model).

    Raises:
        InputError: ``clm`` is not a :class:`ClosedLoopModel`.
    """
    key = ("dynamics", threading.get_ident())
    try:
        return clm.workspaces[key]
    except KeyError:
        dyn = clm.workspaces[key] = ClosedLoopDynamics(clm)
        return dyn
    except AttributeError:
        raise InputError("clm", clm, "expected a ClosedLoopModel") from None


def forward_dynamics_tree(clm: ClosedLoopModel, q: npt.ArrayLike, v: npt.ArrayLike,
                          actuator_forces: npt.ArrayLike, tau_ext: npt.ArrayLike | None = None,
                          method: str = "pinocchio") -> TreeForwardDynamics:
    """Constrained forward dynamics of a closed-loop mechanism on its tree.

    Solves ``M a + h = S^T u + tau_ext + J_c^T lambda`` with ``J_c a = -gamma`` for the
    tree acceleration ``a`` and the closure multipliers ``lambda`` (conventions in the
    module docstring). Takes the actuator forces in the shape
    :func:`inverse_dynamics_tree` returns them, so that the two routes compose.

    Args:
        clm: the closed-loop model.
        q: tree configuration (nq,), the closures satisfied (each closure's position
            error at most ``CLOSURE_QTOL * L`` m, ``L = max(1 m, reach of the tree)``,
            a weld's rotation error at most ``CLOSURE_QTOL`` rad).
        v: tree velocity (nv,) with ``J_c v = 0`` (to ``CLOSURE_VTOL * max(1, |v|_inf)
            * L`` m/s per closure, see :data:`CLOSURE_QTOL`; Pinocchio convention:
            free-flyer velocities in the body frame).
        actuator_forces: ``u`` (n_act,), generalised forces of the actuated joints in
            ``clm.actuated_joints`` order (N for prismatic, N m for revolute joints).
        tau_ext: generalised external force on the tree (nv,) (N, N m); default zero.
        method: "pinocchio" (``pin.constraintDynamics``, checked on Pinocchio's own
            ``M``, ``nle``, constraint Jacobian and drift; when the closures are
            redundant: proximal, mu = 1e-8 / max(1, max M_ii), at most
            :data:`PIN_PROX_ITERS` = 2 iterations, then, when those miss the
            verification, an exact solve of the same terms (the status says so), and
            the multipliers polished to minimum norm by least squares; when Pinocchio's
            answer is refused, the "kkt" route answers and the status says so), "qp"
            (Gauss principle ``min 1/2 (a - a_free)^T M (a - a_free)`` s.t. ``J_c a =
            -gamma`` as a ProxSuite dense QP in coordinates scaled by ``diag(M)^(1/2)``:
            augmented Hessian with a unit diagonal, independent rows only, rows
            normalised, warm-started from the "kkt" solution and its multipliers,
            re-solved from its own iterate before it raises; success judged from the
            verified residuals, the status reported as ProxSuite gives it), or "kkt"
            (numpy solve of the KKT system; the exact null-space solve with
            minimum-norm multipliers when the rows are redundant or the system
            singular).

    Returns:
        :class:`TreeForwardDynamics`.

    Raises:
        InputError: bad shapes, NaN / inf, unknown method; a ``q`` off the closures or a
            ``v`` breaking them beyond :data:`CLOSURE_QTOL` / :data:`CLOSURE_VTOL` (the
            message names the residual and the tolerance).
        SolverError: the answer misses an equation (e.g. ``gamma`` outside the range of
            ``J_c``, a mass matrix not positive on the closures' null space); the
            message names the equation and its relative residual.
    """
    return dynamics_of(clm).forward_actuated(q, v, actuator_forces, tau_ext, method)


def inverse_dynamics_tree(clm: ClosedLoopModel, q: npt.ArrayLike, v: npt.ArrayLike,
                          a: npt.ArrayLike, tau_ext: npt.ArrayLike | None = None,
                          bounds: npt.ArrayLike | None = None,
                          method: str = "qp") -> TreeInverseDynamics:
    """Closed-loop inverse dynamics: actuator forces that produce a tree motion.

    Solves ``M a + h - tau_ext = S^T u + J_c^T lambda`` for the actuator forces ``u``
    and the closure multipliers ``lambda``. ``a`` must keep the closures
    (``J_c a = -gamma``), e.g. from :meth:`ClosedLoopModel.complete_acceleration`.

    Args:
        clm: the closed-loop model.
        q: tree configuration (nq,), Pinocchio conventions, closures assembled (to
            :data:`CLOSURE_QTOL`, as in :func:`forward_dynamics_tree`).
        v: tree velocity (nv,), consistent with the closures (to :data:`CLOSURE_VTOL`).
        a: tree acceleration (nv,), consistent with the closures.
        tau_ext: generalised external force on the tree (nv,) (N, N m); default zero.
        bounds: ``abs(u) <= bounds`` (scalar or (n_act,), N or N m); None (or inf): none.
        method: "qp" (minimise ``1/2 |u|^2 + 1/2 w |lambda|^2``, ``w = 1e-2``, subject
            to the equation of motion and the box bounds: when the equation determines
            ``u`` the direct minimum-norm solution is the minimiser (or proves the
            bounds infeasible); otherwise the weighted minimum-norm solution when it
            keeps the bounds, else an active-set search certified by the KKT
            conditions, else a ProxSuite dense QP, scaled, warm-started from the
            clipped weighted minimum-norm solution and polished on its active set) or
            "kkt" (the linear system ``[S^T J_c^T] [u; lambda] = rhs``: one LU solve
            when square, least squares / minimum norm otherwise). Both agree to 1e-10
            when no bound is active and the equation determines ``u``. Solved in
            Pinocchio's constraint rows (the multipliers are converted to ours on
            access).

    Returns:
        :class:`TreeInverseDynamics`.

    Raises:
        ActuatorSaturationError: no ``abs(u) <= bounds`` meets the equation of motion
            (certified by the structure or by box-constrained least squares); carries
            the needed (unbounded, minimum-norm) forces. No clipped answer is returned.
        InputError: bad shapes, NaN / inf, non-positive bounds, unknown method; a ``q``
            off the closures or a ``v`` breaking them (as :func:`forward_dynamics_tree`).
        SolverError: ``a`` does not keep the closures, or the answer misses the
            equation of motion (the message names it and its relative residual).
    """
    return dynamics_of(clm).inverse(q, v, a, tau_ext, bounds, method)


# --------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------
_NO_INDEX = np.zeros(0, dtype=int)


def _our_rows(lam: np.ndarray, jac: np.ndarray | None) -> np.ndarray:
    """Multipliers already in our rows; with ``jac``, the minimum-norm ones of the same
    generalised force ``jac^T lam``."""
    if jac is None:
        return lam
    return np.linalg.lstsq(jac.T, jac.T @ lam, rcond=None)[0]


def null_space_basis(jac: np.ndarray, rank: int) -> np.ndarray:
    """An orthonormal basis (nv, nv - rank) of ``null(jac)`` (SVD; ``rank`` the rank of the
    (rows, nv) ``jac``; the identity without rows)."""
    if jac.shape[0] == 0:
        return np.eye(jac.shape[1])
    _, _, vt = np.linalg.svd(jac)
    return vt[rank:].T


def box_qp(hess: np.ndarray, grad: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """``argmin 1/2 f^T H f + g^T f`` s.t. ``-bound <= f <= bound`` (``H`` (k, k) symmetric
    positive semi-definite, small; ``g``, ``bound`` (k,), ``bound >= 0``; returns ``f`` (k,);
    the callers verify the answer): ProxSuite's dense solver with box constraints, then polished on
    its active set (the free coordinates solve ``H_ff f_f = -(g_f + H_fb f_b)`` exactly;
    a polish that leaves the box keeps ProxSuite's answer)."""
    n = grad.size
    qp = proxsuite.proxqp.dense.QP(n, 0, 0, True)
    qp.settings.eps_abs = 1e-13
    qp.settings.eps_rel = 0.0
    qp.settings.max_iter = 10_000
    qp.settings.verbose = False
    hess = 0.5 * (hess + hess.T)
    qp.init(hess, grad, None, None, None, None, None, -bound, bound)
    qp.solve()
    f = np.clip(np.asarray(qp.results.x, dtype=float), -bound, bound)
    for _ in range(4):
        at_bound = np.abs(f) >= bound * (1.0 - 1e-7)
        free = ~at_bound
        if not free.any():
            break
        f_b = np.where(at_bound, np.sign(f) * bound, 0.0)
        rhs = -(grad[free] + hess[np.ix_(free, at_bound)] @ f_b[at_bound])
        f_free = np.linalg.lstsq(hess[np.ix_(free, free)], rhs, rcond=None)[0]
        if np.any(np.abs(f_free) > bound[free]):
            break
        f = f_b
        f[free] = f_free
        # a bound whose multiplier has the wrong sign is released
        grad_full = hess @ f + grad
        wrong = at_bound & (np.sign(f) * grad_full > 0)
        if not wrong.any():
            break
        f[wrong] = np.clip(f[wrong] - grad_full[wrong] / np.maximum(np.diag(hess)[wrong],
                                                                     TINY), -bound[wrong],
                           bound[wrong])
    return f

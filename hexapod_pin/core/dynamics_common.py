"""What the closed-loop dynamics routes share: tolerances, ProxSuite settings and status
names, the cached ProxSuite problems, the forward-dynamics verification, and the result
types of :func:`~hexapod_pin.core.dynamics.forward_dynamics_tree` and
:func:`~hexapod_pin.core.dynamics.inverse_dynamics_tree` (documented with them, in
:mod:`hexapod_pin.core.dynamics`, which re-exports everything here that callers use).

Conventions (tree coordinates, Pinocchio's ``q``, ``v``, ``a``; see
:mod:`hexapod_pin.core.dynamics`)::

    M(q) a + h(q, v) = tau + J_c(q)^T lambda          (equation of motion)
    J_c(q) a = -gamma(q, v)                            (closures at acceleration level)
"""

from __future__ import annotations

import ctypes
import math
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numba
import numpy as np
import pinocchio as pin
import proxsuite
import scipy.linalg
from numba import types
from numba.extending import intrinsic, overload

from ..errors import InputError, SolverError
from .compiled import jit
from .kernel_status import RESIDUAL_RTOL  # the tolerance of every route (compiled too)
from .linear_kernels import forward_residuals

#: ProxSuite accuracy (absolute, on primal and dual residuals of the scaled problems)
QP_EPS = 1e-12
#: iteration cap of the tree QPs (redundant closure rows slow the proximal iterations down)
QP_MAX_ITER = 1000
#: a floor for scales (avoids dividing by zero on all-zero data)
TINY = 1e-300
#: Closure tolerances of the public tree routes (``forward_dynamics_tree``,
#: ``inverse_dynamics_tree``, ``ClosedLoopDynamics.forward`` / ``inverse`` /
#: ``joint_wrenches``): a state is refused with :class:`~hexapod_pin.errors.InputError`
#: when, with ``L = max(1 m, characteristic_length(model))`` (the reach of the tree,
#: :func:`characteristic_length`),
#:
#: * a closure's position error (the Euclidean norm of ``p_1 - p_2`` of a point closure,
#:   of the translation part of ``log6`` of a weld) exceeds ``CLOSURE_QTOL * L`` (m), or a
#:   weld's rotation error (the angle of ``log6``) exceeds ``CLOSURE_QTOL`` (rad);
#: * a closure's velocity error (the norm of the linear / angular part of its rows of
#:   ``J_c v``) exceeds ``CLOSURE_VTOL * max(1, |v|_inf) * L`` (m/s) /
#:   ``CLOSURE_VTOL * max(1, |v|_inf)`` (rad/s).
#:
#: 1e-6 is far above what the library's own states carry (assembly to 1e-12, the
#: integrator's projection to 1e-10, velocities from the closure Jacobian to round-off)
#: and far below an error that changes the dynamics visibly (the routes assume
#: ``J_c v = 0`` in the drift and the Jacobian of an assembled ``q``). Internal paths
#: (RK4 stage states of the integrator, batch drivers) are not checked.
CLOSURE_QTOL = 1e-6
#: see :data:`CLOSURE_QTOL` (relative velocity tolerance, 1/s per unit speed)
CLOSURE_VTOL = 1e-6

QP_SOLVED = proxsuite.proxqp.PROXQP_SOLVED
QP_STATUS = {
    proxsuite.proxqp.PROXQP_SOLVED: "solved",
    proxsuite.proxqp.PROXQP_MAX_ITER_REACHED: "max_iter_reached",
    proxsuite.proxqp.PROXQP_PRIMAL_INFEASIBLE: "primal_infeasible",
    proxsuite.proxqp.PROXQP_DUAL_INFEASIBLE: "dual_infeasible",
    proxsuite.proxqp.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE: "solved_closest_primal_feasible",
    proxsuite.proxqp.PROXQP_NOT_RUN: "not_run",
}


# --------------------------------------------------------------------------------------
# results
# --------------------------------------------------------------------------------------
class TreeForwardDynamics(NamedTuple):
    """Result of :func:`forward_dynamics_tree` (an immutable named tuple).

    Attributes:
        a: tree acceleration (nv,), Pinocchio convention (free-flyer part: derivative
            of the body-frame velocity).
        raw_multipliers: the multipliers, or a zero-argument callable producing them
            (Pinocchio's LOCAL multipliers converted on first access): read
            :attr:`multipliers`.
        method: the route used ("pinocchio", "qp" or "kkt").
        status: "solved", or a note on how it was solved (redundant rows, fallback,
            a ProxSuite status other than solved whose residuals were verified).
        iterations: solver iterations: Pinocchio's proximal iterations for the
            "pinocchio" route (1 for its direct solve), ProxSuite's for "qp", 0 for
            "kkt" (and when the KKT route answered for the "pinocchio" route).
        rank: rank of ``J_c`` assumed by the solve.
        constraint_residual: max-abs of ``J_c a + gamma`` (m/s^2); -1.0 (not
            computed, never NaN) for the "pinocchio" route, which verifies the same
            equation in Pinocchio's LOCAL rows instead.
    """

    a: np.ndarray
    raw_multipliers: np.ndarray | Callable[[], np.ndarray]
    method: str
    status: str
    iterations: int
    rank: int
    constraint_residual: float

    @property
    def multipliers(self) -> np.ndarray:
        """Closure multipliers (n_rows,), ``M a + h = tau + J_c^T multipliers``, rows as in
        :meth:`ClosedLoopModel.constraint_jacobian` (N for point rows, world axes);
        minimum-norm when the closures are redundant."""
        value = self.raw_multipliers
        return value() if callable(value) else value


class TreeInverseDynamics(NamedTuple):
    """Result of :func:`inverse_dynamics_tree` (an immutable named tuple).

    Attributes:
        actuator_forces: ``u`` (n_act,), generalised forces of the actuated joints
            (N for prismatic, N m for revolute), in ``clm.actuated_joints`` order.
        raw_multipliers: the multipliers or a callable producing them: read
            :attr:`multipliers`.
        residual: max-abs of ``M a + h - tau_ext - S^T u - J_c^T multipliers`` (N, N m),
            verified below :data:`RESIDUAL_RTOL` relative to the data.
        method: "qp" or "kkt".
        status: solver status ("solved", ...).
        iterations: solver iterations (0 for a direct solve).
    """

    actuator_forces: np.ndarray
    raw_multipliers: np.ndarray | Callable[[], np.ndarray]
    residual: float
    method: str
    status: str
    iterations: int

    @property
    def multipliers(self) -> np.ndarray:
        """Closure multipliers (n_rows,), same convention as
        :attr:`TreeForwardDynamics.multipliers` (minimum-norm when redundant)."""
        value = self.raw_multipliers
        return value() if callable(value) else value


def verify_forward(mass: np.ndarray, bias: np.ndarray, tau: np.ndarray, jac: np.ndarray,
                   drift: np.ndarray, acc: np.ndarray, lam: np.ndarray, route: str,
                   out: np.ndarray) -> tuple[float, float]:
    """Relative residuals of the two equations a forward solution must satisfy.

    ``M a + h - tau - J^T lam`` relative to the largest of ``|M a|``, ``|h - tau|``,
    ``|J^T lam|``, and ``J a + drift`` relative to ``|J| |a|`` and ``|drift|`` (max-abs
    norms; :func:`~hexapod_pin.core.linear_kernels.forward_residuals`). ``jac`` / ``drift``
    may be ours (``J_c``, ``gamma``) or Pinocchio's LOCAL ones (``J_pin``,
    ``-primal_rhs``): both equations hold in either row convention. ``out`` (2,) receives
    the two residuals.

    Returns:
        (equation-of-motion residual, closure residual), both relative.

    Raises:
        SolverError: either exceeds :data:`RESIDUAL_RTOL` or is not finite; the message
            names the equation and its residual.
    """
    eom, con = forward_residuals(mass, bias, tau, jac, drift, acc, lam, out)
    if not eom <= RESIDUAL_RTOL:
        raise SolverError(route, "unverified", "equation of motion M a + h = tau + J_c^T "
                          f"lambda missed by {eom:.3e} (relative)")
    if not con <= RESIDUAL_RTOL:
        raise SolverError(route, "unverified", "closure equation J_c a = -gamma missed by "
                          f"{con:.3e} (relative)")
    return eom, con


def characteristic_length(model: pin.Model) -> float:
    """The reach of a tree (m): the longest path, summing the lengths of the joint
    placements' translations from the root, to any joint or frame origin (prismatic
    strokes not counted; a floating base contributes nothing). A configuration-free length
    scale of the model, for the closure tolerances (:data:`CLOSURE_QTOL`)."""
    reach = np.zeros(model.njoints)
    for j in range(1, model.njoints):
        reach[j] = reach[model.parents[j]] + float(
            np.linalg.norm(model.jointPlacements[j].translation))
    best = float(np.max(reach, initial=0.0))
    for frame in model.frames:
        best = max(best, float(reach[frame.parentJoint])
                   + float(np.linalg.norm(frame.placement.translation)))
    return best


def float64_pointer(address: int) -> Any:
    """The ``float64*`` at the integer ``address``, for ``numba.carray`` in
    :func:`closure_state_errors`: a ctypes pointer when the kernel runs as Python (tiered
    execution, :mod:`hexapod_pin.core.tiers`), the intrinsic :func:`_float64_pointer` in
    compiled code (:func:`_float64_pointer_overload`)."""
    return ctypes.cast(int(address), ctypes.POINTER(ctypes.c_double))


@intrinsic
def _float64_pointer(typingctx, address):
    """The ``float64*`` at the integer ``address`` (a numba intrinsic)."""
    sig = types.CPointer(types.float64)(types.int64)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(signature.return_type))
    return sig, codegen


@overload(float64_pointer)
def _float64_pointer_overload(address):
    """:func:`float64_pointer` in compiled code: the intrinsic."""
    return lambda address: _float64_pointer(address)


@jit
def closure_state_errors(addresses, v, out):
    """The closure errors that Pinocchio's ``constraintDynamics`` leaves in its constraint
    datas, read at ``addresses`` (int64 (2 n,): per closure the address of its
    ``contact_placement_error`` then of its ``contact_velocity_error``, each 6 contiguous
    float64, linear then angular; zero angular part for a point closure):
    ``out = (max linear position error norm (m), max angular position error norm (rad),
    max linear velocity error norm (m/s), max angular velocity error norm (rad/s),
    max-abs of v)``. A NaN propagates to its entry."""
    pl, pa, vl, va = 0.0, 0.0, 0.0, 0.0
    for k in range(addresses.shape[0] // 2):
        p = numba.carray(float64_pointer(addresses[2 * k]), (6,))
        s = numba.carray(float64_pointer(addresses[2 * k + 1]), (6,))
        a = math.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2])
        b = math.sqrt(p[3] * p[3] + p[4] * p[4] + p[5] * p[5])
        c = math.sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2])
        d = math.sqrt(s[3] * s[3] + s[4] * s[4] + s[5] * s[5])
        pl = a if not a <= pl else pl              # NaN wins
        pa = b if not b <= pa else pa
        vl = c if not c <= vl else vl
        va = d if not d <= va else va
    vmax = 0.0
    for i in range(v.shape[0]):
        x = abs(v[i])
        vmax = x if not x <= vmax else vmax
    out[0], out[1], out[2], out[3], out[4] = pl, pa, vl, va, vmax


@jit
def closure_state_status(addresses, v, tols, out):
    """:func:`closure_state_errors` into ``out`` compared with ``tols = (position (m),
    rotation (rad), relative velocity (1/s), length scale (m))``: whether every error is
    within its tolerance (see :data:`CLOSURE_QTOL`; False for a NaN)."""
    closure_state_errors(addresses, v, out)
    speed = tols[2] * max(1.0, out[4])
    return (out[0] <= tols[0] and out[1] <= tols[1] and out[2] <= speed * tols[3]
            and out[3] <= speed)


class ClosureStateCheck:
    """The closure check of the public tree routes (tolerances :data:`CLOSURE_QTOL`,
    :data:`CLOSURE_VTOL`), reading the errors that a ``pin.constraintDynamics`` call on
    ``constraint_datas`` left there (``contact_placement_error``,
    ``contact_velocity_error``: no kinematic pass of its own).

    One compiled call reads them at the addresses of their memory when the bindings give
    views of it that later calls update in place (a property of the bindings, checked
    here: ``probe(q, v)``, a ``constraintDynamics`` call on the datas, at two states,
    against fresh property reads), else they are read through the properties (same
    values, slower). The datas must stay where they are (the caller keeps them, and
    appends nothing to their vector).

    Args:
        model: the tree model.
        constraint_datas: Pinocchio's constraint datas of the closures (kept alive by the
            caller).
        probe: ``probe(q, v)`` runs ``pin.constraintDynamics`` at ``(q, v)`` on those datas.
    """

    def __init__(self, model: pin.Model, constraint_datas: Sequence[Any],
                 probe: Callable[[np.ndarray, np.ndarray], Any]) -> None:
        #: the length scale ``L = max(1, characteristic_length(model))`` (m)
        self.scale = max(1.0, characteristic_length(model))
        #: position tolerance (m); the rotation tolerance is CLOSURE_QTOL (rad)
        self.q_tol = CLOSURE_QTOL * self.scale
        self._tols = np.array([self.q_tol, CLOSURE_QTOL, CLOSURE_VTOL, self.scale])
        self._cds = constraint_datas
        self._out = np.empty(5)
        self._views = tuple(view for cd in constraint_datas for view in
                            (cd.contact_placement_error.vector, cd.contact_velocity_error.vector))
        self._addresses: np.ndarray | None = None
        if self._views and all(view.dtype == np.float64 and view.shape == (6,)
                               and view.flags.c_contiguous for view in self._views):
            addresses = np.array([view.ctypes.data for view in self._views], dtype=np.int64)
            neutral = pin.neutral(model)
            live = True
            for q, v in ((neutral, np.linspace(-0.5, 0.7, model.nv)),
                         (pin.integrate(model, neutral, np.linspace(0.1, 0.3, model.nv)),
                          np.linspace(0.7, -0.4, model.nv))):
                probe(q, v)
                fresh = [vec for cd in constraint_datas for vec in (
                    cd.contact_placement_error.vector.copy(),
                    cd.contact_velocity_error.vector.copy())]
                live = live and all(np.array_equal(view, vec)
                                    for view, vec in zip(self._views, fresh))
            self._addresses = addresses if live else None

    def _fresh(self, v: np.ndarray, out: np.ndarray) -> np.ndarray:
        """:meth:`errors` through the properties (fresh objects)."""
        placement = [cd.contact_placement_error.vector for cd in self._cds]
        velocity = [cd.contact_velocity_error.vector for cd in self._cds]
        out[:] = 0.0
        for p, s in zip(placement, velocity):
            out[:4] = np.fmax(out[:4], [np.linalg.norm(p[:3]), np.linalg.norm(p[3:]),
                                        np.linalg.norm(s[:3]), np.linalg.norm(s[3:])])
            out[:4][np.isnan([p[:3].sum(), p[3:].sum(), s[:3].sum(), s[3:].sum()])] = np.nan
        out[4] = float(np.max(np.abs(v), initial=0.0))
        return out

    @property
    def live(self) -> bool:
        """Whether the errors are read in place (else through the properties)."""
        return self._addresses is not None

    def errors(self, v: np.ndarray) -> np.ndarray:
        """``(position error (m), rotation error (rad), linear velocity error (m/s),
        angular velocity error (rad/s), |v|_inf)`` (5,) as the last ``constraintDynamics``
        on the datas left them (a new array)."""
        out = np.empty(5)
        if self._addresses is None:
            return self._fresh(v, out)
        closure_state_errors(self._addresses, v, out)
        return out

    def check(self, q: np.ndarray, v: np.ndarray, q_name: str = "q",
              v_name: str = "v") -> None:
        """Refuse ``(q, v)`` (the state of the last ``constraintDynamics`` call on the
        datas) when it is off the closures beyond the tolerances.

        Raises:
            InputError: naming ``q`` (the closure residual and its tolerance) or ``v``
                (the closure velocity ``J_c v`` and its tolerance).
        """
        addresses = self._addresses
        if addresses is not None and closure_state_status(addresses, v, self._tols, self._out):
            return
        pos, rot, lin, ang, vmax = (float(x) for x in self.errors(v))
        if not pos <= self.q_tol:
            raise InputError(q_name, q, f"off the closures: closure residual {pos:.3e} m "
                             f"exceeds the tolerance {self.q_tol:.3e} m (CLOSURE_QTOL = "
                             f"{CLOSURE_QTOL:g} x length scale {self.scale:.3g} m); "
                             "assemble it first (ClosedLoopModel.assemble)")
        if not rot <= CLOSURE_QTOL:
            raise InputError(q_name, q, f"off the closures: weld rotation residual {rot:.3e} "
                             f"rad exceeds the tolerance {CLOSURE_QTOL:.3e} rad "
                             "(CLOSURE_QTOL); assemble it first (ClosedLoopModel.assemble)")
        speed = CLOSURE_VTOL * max(1.0, vmax)
        if not lin <= speed * self.scale:
            raise InputError(v_name, v, f"breaks the closures: |J_c v| = {lin:.3e} m/s "
                             f"exceeds the tolerance {speed * self.scale:.3e} m/s "
                             f"(CLOSURE_VTOL = {CLOSURE_VTOL:g} x max(1, |v|_inf) x length "
                             f"scale {self.scale:.3g} m); project it first "
                             "(ClosedLoopModel.project_velocity)")
        if not ang <= speed:
            raise InputError(v_name, v, f"breaks the closures: weld angular rate |J_c v| = "
                             f"{ang:.3e} rad/s exceeds the tolerance {speed:.3e} rad/s "
                             f"(CLOSURE_VTOL = {CLOSURE_VTOL:g} x max(1, |v|_inf)); project "
                             "it first (ClosedLoopModel.project_velocity)")


def cached_qp(cache: dict, key: Any, n_in: int, args: tuple,
              warm: tuple | None = None) -> proxsuite.proxqp.dense.QP:
    """Initialise (first call: kept in ``cache`` under ``key``) or update a dense ProxSuite
    problem with ``args = (H, g, A, b, C, l, u)`` and ``n_in`` inequality rows; solve,
    warm-started from ``warm = (x, y, z)`` when given. The data must be scaled to order
    one (tolerance :data:`QP_EPS` absolute, at most :data:`QP_MAX_ITER` iterations).
    The caller verifies the answer."""
    qp = cache.get(key)
    if qp is None:
        hess, _, amat = args[0], args[1], args[2]
        qp = proxsuite.proxqp.dense.QP(hess.shape[0], amat.shape[0], n_in)
        qp.settings.eps_abs = QP_EPS
        qp.settings.eps_rel = 0.0
        qp.settings.max_iter = QP_MAX_ITER
        qp.settings.verbose = False
        qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START
        qp.init(*args)
        cache[key] = qp
    else:
        qp.update(*args, update_preconditioner=True)
    if warm is None:
        qp.solve()
    else:
        qp.solve(*warm)
    return qp


def independent_rows_of_rank(jac: np.ndarray, rank: int) -> np.ndarray:
    """The ``rank`` rows of ``jac`` that a column-pivoted QR of ``jac^T`` picks first,
    sorted: for a ``jac`` of that numerical rank, a well-conditioned set of independent
    rows (the others depend on them, exactly or nearly)."""
    if rank == 0:
        return np.arange(0)
    _, _, piv = scipy.linalg.qr(jac.T, pivoting=True, mode="economic")
    return np.sort(piv[:rank])


def independent_rows(jac: np.ndarray, rtol: float = 1e-8) -> np.ndarray:
    """:func:`independent_rows_of_rank` at the numerical rank of ``jac`` (singular values
    above ``rtol`` times the largest), sorted."""
    if jac.shape[0] == 0:
        return np.arange(0)
    sv = np.linalg.svd(jac, compute_uv=False)
    return independent_rows_of_rank(jac, int(np.sum(sv > rtol * sv[0])))

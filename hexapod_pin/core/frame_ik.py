"""Frame-target inverse kinematics of a closed-loop model, closures held.

:func:`frame_inverse_kinematics` places one or several frames of any
:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel` (passed in; this module imports no
model) at target placements while every loop closure holds, in the manner of pink / mink:
a quadratic program per step, solved by ProxSuite, over the tangent step ``dv`` (nv)::

    minimise   1/2 |J_t dv + e|_W^2 + 1/2 lambda |dv|^2
    subject to J_c dv = -r_c                    (closures, independent rows)
               lower - q <= dv <= upper - q     (1-DoF joints with finite limits)
               dv[fixed] = 0                    (coordinates held)

with ``e`` the stacked task errors, ``J_t`` their Jacobians, ``W`` the weights and the
Levenberg-Marquardt damping ``lambda = mu |e|_W^2`` (vanishing at a solution, so the
iteration converges quadratically there). The step is applied with ``pin.integrate`` and
the loops closed again (chord Newton steps with the closure rows of the linearisation
point, :meth:`ClosedLoopModel.assemble` where they do not contract: to ``closure_tol`` at
the answer and after slow steps, to ``max(closure_tol, RELAX |e|_W^2)`` while the error
falls fast, the next step's closure rows taking the rest); it is kept when ``|e|_W^2`` falls by a fair part of what
the linear model predicts, and ``mu`` follows the gain ratio continuously (Nielsen's
rule: lowered, down to ``damping``, after good steps, doubled and doubled again after
rejected ones): a trust region in the Levenberg-Marquardt manner.

A target out of reach leaves a residual at the closest placement, where Gauss-Newton's
model misses the curvature ``sum_i (W e)_i hess(e_i)`` (plus the closures' curvature
weighted by their multipliers). Where the task Jacobian loses rank there (a delta leg
folded flat at the edge of the workspace) that term is the whole Hessian along the
folded direction and Gauss-Newton creeps; so after any step that does not halve
``|e|_W^2`` the next one adds it, by forward differences of the Lagrangian's gradient
along the closures' null space (Newton's method on the closed mechanism; dropped where
it is not positive there). The iteration stops at a least-squares stationary point
(flagged unreachable) when the task gradient along the closures vanishes
(``GRAD_RTOL``), when the undamped step vanishes (``STEP_TOL``: the test used while a
joint sits on a limit), when ``|e|_W^2`` stops moving above the noise of the closures
(``STALL_STEPS`` steps each below ``STALL_RTOL``) or when no damping up to ``MU_MAX``
gives a decrease.

Task errors (Pinocchio conventions, frames' placements ``oMf`` in world):

* a placement target ``T``: ``e = log6(T^-1 oMf)`` (m, rad: the twist from the target to
  the frame, in the target's axes), ``J_t = Jlog6(T^-1 oMf) J_LOCAL``;
* a position target ``p`` (``position_only``): ``e = oMf.translation - p`` (m, world axes),
  ``J_t`` the linear rows of ``J_LOCAL_WORLD_ALIGNED``.

A target out of reach gives the least-squares (weighted) closest placement, flagged
``reachable=False``; a model whose closures cannot be held raises AssemblyError.
The direct route (``method="lstsq"``) solves the same step in the closures' null space
(a pivoted QR of the closure rows) and ignores joint limits; both routes give the same
iterates where no limit is active. Route "qp" takes that step too where ProxSuite stops
at ``QP_MAX_ITER`` (an ill-conditioned step next to a singular placement) and no limit
would be crossed.
"""

from __future__ import annotations

import threading
import weakref
from dataclasses import dataclass
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import proxsuite

from ..errors import AssemblyError, InputError, SolverError
from .checks import as_array, count, flag, real_number
from .closure_motion import RowBasis, row_basis
from .compiled import jit
from .description import MAX_COORDINATE

IK_METHODS = ("qp", "lstsq")
#: damping factor of the Levenberg-Marquardt term ``lambda = DAMPING |e|_W^2``
DAMPING = 1e-3
#: floor of lambda (keeps the step unique when the task leaves directions free); a task
#: direction whose squared singular value falls below it converges linearly, so it is tiny
DAMPING_FLOOR = 1e-18
#: a step is kept when it achieves this fraction of the decrease its linear model predicts
ACCEPT_RATIO = 1e-4
#: past this damping factor no step is tried any more (the start is stationary)
MU_MAX = 1e12
#: an undamped step below this (max-abs, m / rad) marks a stationary point
STEP_TOL = 1e-12
#: stationary (closest reachable placement) when the task gradient along the closures is
#: below this, relative to ``max|J_t| max|W e|``
GRAD_RTOL = 1e-12
#: stationary when this many accepted steps in a row each lower ``|e|_W^2`` by less than
#: ``STALL_RTOL`` of its value (the noise of closures held to ``closure_tol``)
STALL_STEPS = 3
STALL_RTOL = 1e-10
#: a step that leaves more than this fraction of ``|e|_W^2`` turns on the second-order term
SLOW_RATIO = 0.5
#: forward-difference step of that term (rad / m along unit null-space directions)
CURVATURE_STEP = 1e-7
#: while steps are fast, intermediate iterates keep the closures to
#: ``max(closure_tol, RELAX |e|_W^2)`` (the answer always to ``closure_tol``)
RELAX = 1e-2
#: smallest damping factor a rejected step raises (when ``damping`` is 0)
MU_MIN = 1e-12
#: chord Newton steps tried when closing the loops after a step, and the contraction each
#: must achieve (else the full Newton of ``ClosedLoopModel.assemble`` takes over)
CHORD_ITER = 8
CHORD_CONTRACTION = 0.5
_QP_EPS = 1e-12
_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])
#: ProxSuite's cap on its outer and on its inner iterations per step (well-posed steps
#: take fewer than 20 in all)
QP_MAX_ITER = 100


class FrameTask(NamedTuple):
    """One frame target: frame id, target placement, position-only flag, row weights."""

    frame: int
    target: pin.SE3
    position_only: bool
    weight: np.ndarray


class JointBox(NamedTuple):
    """Position limits of the limited 1-DoF joints among the free coordinates."""

    lower: np.ndarray     # (k,) lower limits (m or rad)
    upper: np.ndarray     # (k,) upper limits
    q_index: np.ndarray   # (k,) their indices in q
    position: np.ndarray  # (k,) their positions among the free coordinates
    v_index: np.ndarray   # (k,) their indices in v


class SingleDofJoints(NamedTuple):
    """The 1-DoF joints of a model (the ones whose position limits become QP bounds)."""

    q_index: np.ndarray   # their indices in q
    v_index: np.ndarray   # their indices in v


@dataclass(frozen=True)
class FrameIKResult:
    """Result of :func:`frame_inverse_kinematics`.

    Attributes:
        q: the configuration (nq,); every closure holds to ``closure_residual``.
        reachable: True when every target is reached to ``tol``; False when the
            iteration stopped at the closest reachable placement (a least-squares
            stationary point) instead.
        target_residual: max-abs unweighted task error at ``q`` (m / rad, see the
            module docstring).
        closure_residual: max-abs closure residual at ``q`` (m / rad).
        iterations: steps taken.
        errors: the stacked task errors at ``q`` (unweighted).
        placements: the frames' placements at ``q`` (world), in task order.
        history: the max-abs task error at the start and after each step (m / rad).
    """

    q: np.ndarray
    reachable: bool
    target_residual: float
    closure_residual: float
    iterations: int
    errors: np.ndarray
    placements: tuple[pin.SE3, ...]
    history: tuple[float, ...]


def frame_inverse_kinematics(clm: Any, frame: str, target: npt.ArrayLike,
                             q0: npt.ArrayLike | None = None, *, position_only: bool = False,
                             fixed: Sequence[str | int] | None = None,
                             weights: npt.ArrayLike | None = None, method: str = "qp",
                             tol: float = 1e-10, closure_tol: float = 1e-12, max_iter: int = 200,
                             limits: bool = True, damping: float = DAMPING) -> FrameIKResult:
    """Configuration of ``clm`` that places ``frame`` at ``target`` with the closures held.

    Args:
        clm: the :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`.
        frame: a frame name or id, or a sequence of them (several frames at once, e.g.
            both feet of a biped).
        target: for each frame, a ``pin.SE3`` or 4x4 homogeneous matrix (world), or with
            ``position_only`` a position (3,) (m, world).
        q0: start (nq,); default Pinocchio's neutral configuration. Its loops are closed
            first (moving the coordinates not in ``fixed``).
        position_only: bool, or one per frame: target the frame origin only.
        fixed: joints held at their values in ``q0``: names, or indices into ``v``.
        weights: one positive weight per frame (scalar, or one per task row: 3 for a
            position, 6 for a placement); default 1. They matter only when the targets
            cannot all be reached.
        method: "qp" (ProxSuite, joint limits as inequalities) or "lstsq" (null-space
            least squares, limits ignored).
        tol: convergence threshold on the max-abs task error (m / rad).
        closure_tol: closure residual at the answer (m / rad), and at every iterate once
            the steps slow down.
        max_iter: iteration cap (accepted steps).
        limits: keep 1-DoF joints with finite position limits in their range (route
            "qp": bounds of each step, and joints put on their bound while the loops
            close); a joint that starts outside its range may not go further out.
        damping: Levenberg-Marquardt factor (see the module docstring).

    Returns:
        :class:`FrameIKResult` (``reachable`` False: the closest reachable placement, a
        least-squares stationary point of the weighted task error).

    Raises:
        InputError: a frame that is not a name or id (None), unknown frame or joint, bad
            target shape, a target position beyond ``MAX_COORDINATE`` (1e6 m), non-positive
            weight, bad method or option (``tol`` and ``closure_tol`` finite numbers > 0,
            ``max_iter`` an integer >= 1, ``damping`` a finite number >= 0, ``limits`` and
            ``position_only`` bools), each naming the argument.
        AssemblyError: the closures cannot be held from ``q0`` with ``fixed`` held (or,
            exceptionally, at the closest placement found).
        SolverError: ProxSuite failed on a step whose null-space fallback would cross a
            joint limit, or neither convergence nor a stationary point within
            ``max_iter`` steps.
    """
    if not isinstance(method, str) or method not in IK_METHODS:
        raise InputError("method", method, f"expected one of {IK_METHODS}")
    tol = real_number(tol, "tol", minimum=0.0)
    closure_tol = real_number(closure_tol, "closure_tol", minimum=0.0)
    max_iter = count(max_iter, "max_iter", minimum=1)
    damping = real_number(damping, "damping", minimum=0.0, strict=False)
    limits = flag(limits, "limits")
    tasks = _tasks(clm, frame, target, position_only, weights)
    fixed_v = _fixed_indices(clm, fixed)
    q = clm.neutral() if q0 is None else clm.check_q(q0, "q0")
    res_c = clm.residual(q)
    if not _max_abs(res_c) <= closure_tol:
        q = clm.assemble(q, fixed=fixed_v, tol=closure_tol).q
        res_c = clm.residual(q)
    problem = _Problem(clm, tasks, fixed_v, method, closure_tol, limits, q)
    lin = problem.linearise(q, res_c)
    cost, closure = lin.cost, _max_abs(res_c)
    mu, growth, stalled, curvature, slow = damping, 2.0, 0, None, False
    history = [_max_abs(lin.err)]

    def flagged(q, lin, closure):
        """The closest reachable placement (the closures made exact first if relaxed)."""
        if closure > closure_tol:
            held = problem.retract(q, lin, closure_tol)
            if held is None:
                raise AssemblyError("closures cannot be held at the closest placement",
                                    closure, len(history) - 1, q)
            q = held[0]
        return _result(clm, tasks, q, False, history, closure_tol)

    for iteration in range(max_iter + 1):
        exact = closure <= closure_tol
        if history[-1] <= tol and exact:
            return _result(clm, tasks, q, True, history, closure_tol)
        # (stationarity is looked for after slow steps only: fast ones are not near one)
        if exact and (iteration == 0 or slow) and problem.stationary(lin, q):
            return _result(clm, tasks, q, False, history, closure_tol)
        if iteration == max_iter:
            break
        # while the task error falls fast the loops are closed to a tolerance that shrinks
        # with |e|_W^2 (the next step's closure rows take the rest): exact near the answer
        loose = closure_tol if slow else max(closure_tol, RELAX * cost)
        accepted = None
        while accepted is None:
            lam = max(mu * cost, DAMPING_FLOOR)
            step = problem.step(lin, lam, q, curvature)
            if exact and mu <= damping and _max_abs(step) <= STEP_TOL:
                # the least-squares step vanishes: a stationary point of |e|_W^2
                return _result(clm, tasks, q, False, history, closure_tol)
            model = lin.err + lin.jac_t @ step
            predicted = cost - float(model @ (problem.weight * model))
            trial = problem.retract(pin.integrate(clm.model, q, problem.full(step)), lin, loose)
            if trial is not None:
                trial_err = problem.errors(trial[0])
                trial_cost = float(trial_err @ (problem.weight * trial_err))
                ratio = (cost - trial_cost) / predicted if predicted > 0 else -1.0
                if np.isfinite(trial_cost) and ratio > ACCEPT_RATIO:
                    accepted = trial
                    # Nielsen's update: the damping follows the gain ratio continuously
                    # (a fixed tenfold ladder can straddle the best damping for ever)
                    mu = max(damping, mu * max(1.0 / 3.0, 1.0 - (2.0 * ratio - 1.0) ** 3))
                    growth = 2.0
                    break
            if mu > MU_MAX:
                return flagged(q, lin, closure)
            mu = max(mu, MU_MIN) * growth
            growth *= 2.0
        q, res_c = accepted
        closure = _max_abs(res_c)
        if _max_abs(trial_err) <= tol and closure > closure_tol:
            # on target with relaxed closures: close them exactly before judging
            held = problem.retract(q, lin, closure_tol)
            if held is not None:
                q, res_c = held
                closure, trial_err = _max_abs(res_c), problem.errors(q)
        history.append(_max_abs(trial_err))
        if history[-1] <= tol and closure <= closure_tol:
            return _result(clm, tasks, q, True, history, closure_tol)
        lin = problem.linearise(q, res_c)
        stalled = stalled + 1 if cost - lin.cost <= STALL_RTOL * cost else 0
        # a step that did not halve |e|_W^2: Gauss-Newton's model misses the curvature
        # (an out-of-reach target); the next steps add it (Newton's method)
        slow = lin.cost > SLOW_RATIO * cost
        cost = lin.cost
        curvature = problem.curvature(lin, q) if slow else None
        if stalled >= STALL_STEPS and closure <= closure_tol:
            # the cost no longer moves above the noise of closures held to closure_tol:
            # a stationary point where the task Jacobian loses rank (a folded leg)
            return _result(clm, tasks, q, False, history, closure_tol)
    raise SolverError("frame_inverse_kinematics", "max_iter",
                      f"task error {history[-1]:.3e} after {max_iter} steps")


# ------------------------------------------------------------------------------ helpers
def _within_reach(position: np.ndarray, target: Any) -> np.ndarray:
    """``position`` (m), refused beyond ``MAX_COORDINATE`` (the bound of a description's
    coordinates: no robot of the library reaches there, and the squared errors of such a
    target overflow the least-squares steps).

    Raises:
        InputError: naming ``target``.
    """
    if np.max(np.abs(position)) > MAX_COORDINATE:
        raise InputError("target", target, f"a position within {MAX_COORDINATE:g} m of the "
                                           "world origin (no robot reaches beyond)")
    return position


def _is_frame(frame: Any) -> bool:
    """A frame name or id (not a bool)."""
    return isinstance(frame, (str, int, np.integer)) and not isinstance(frame, (bool, np.bool_))


def _tasks(clm, frame, target, position_only, weights) -> list[FrameTask]:
    several = not _is_frame(frame)
    expected = "a frame name or id, or a non-empty list of them"
    if several and not (isinstance(frame, (list, tuple)) and frame
                        and all(_is_frame(f) for f in frame)):
        raise InputError("frame", frame, expected)
    frames = list(frame) if several else [frame]
    for fr in frames:
        clm.frame_id(fr)                   # an unknown frame: InputError naming it
    if several and not isinstance(target, (list, tuple, np.ndarray)):
        raise InputError("target", target, f"expected {len(frames)} targets")
    targets = list(target) if several else [target]
    if len(targets) != len(frames):
        raise InputError("target", target, f"expected {len(frames)} targets")
    flags = ([flag(position_only, "position_only")] * len(frames)
             if isinstance(position_only, (bool, np.bool_)) or np.ndim(position_only) == 0
             else [flag(f, "position_only") for f in position_only])
    wlist = [1.0] * len(frames) if weights is None else (
        list(weights) if several else [weights])
    if len(flags) != len(frames) or len(wlist) != len(frames):
        raise InputError("position_only / weights", (position_only, weights),
                         f"expected one per frame ({len(frames)})")
    out = []
    for fr, tgt, only, w in zip(frames, targets, flags, wlist):
        rows = 3 if only else 6
        given = w
        if isinstance(w, np.ndarray) and w.ndim == 0:
            w = as_array(w, (), "weights")[()]
        if isinstance(w, (int, float, np.integer, np.floating)) \
                and not isinstance(w, (bool, np.bool_)):
            w = np.full(rows, float(w))
        else:                                   # one per task row, real numbers
            w = as_array(w, (rows,), "weights").copy()
        if not np.all(np.isfinite(w) & (w > 0)):
            raise InputError("weights", given, "weights must be finite and > 0")
        out.append(FrameTask(clm.frame_id(fr), _placement(tgt, only), only, w))
    return out


def _placement(target, position_only: bool) -> pin.SE3:
    if position_only:
        return pin.SE3(np.eye(3), _within_reach(as_array(target, (3,), "target"), target))
    if isinstance(target, pin.SE3):
        mat = as_array(target.homogeneous, (4, 4), "target")
    else:
        mat = as_array(target, (4, 4), "target")
    _within_reach(mat[:3, 3], target)
    rot = mat[:3, :3]
    # np.allclose's test (atol 1e-9, rtol 1e-5 for the orthonormality; defaults for the
    # last row), written out: allclose itself costs more than the rest of a step
    eye = np.eye(3)
    if not (np.all(np.abs(rot.T @ rot - eye) <= 1e-9 + 1e-5 * eye) and np.linalg.det(rot) > 0
            and np.all(np.abs(mat[3] - _LAST_ROW) <= 1e-8 + 1e-5 * _LAST_ROW)):
        raise InputError("target", target, "not a rigid placement (rotation, last row)")
    return pin.SE3(rot, mat[:3, 3])


def _fixed_indices(clm, fixed) -> np.ndarray:
    if fixed is None:
        return np.zeros(0, dtype=int)
    out: list[int] = []
    for item in fixed:
        if isinstance(item, (bool, np.bool_)):    # not an index (True is not 1 here)
            raise InputError("fixed", item, "a joint name or an index into v, not a bool")
        if isinstance(item, str):
            start = clm.joint_v_index(item)
            nv = clm.model.joints[clm.model.getJointId(item)].nv
            out.extend(range(start, start + nv))
        elif isinstance(item, (int, np.integer)) and 0 <= int(item) < clm.nv:
            out.append(int(item))
        else:
            raise InputError("fixed", item, f"a joint name or an index into v in [0, {clm.nv})")
    return np.unique(np.asarray(out, dtype=int))


def _limits(clm, free: np.ndarray, q: np.ndarray, single: SingleDofJoints) -> JointBox | None:
    """The limited 1-DoF joints among the free coordinates, or None (limits read now).

    A joint that starts outside its range gets the range extended to its start value
    (it may come back, never go further out).
    """
    model = clm.model
    where = np.full(clm.nv, -1)
    where[free] = np.arange(free.size)
    among = where[single.v_index] >= 0
    qi, vi = single.q_index[among], single.v_index[among]
    low, up = model.lowerPositionLimit[qi], model.upperPositionLimit[qi]
    finite = (low > -1e10) & (low < up) & (up < 1e10)
    if not finite.any():
        return None
    qi, vi, low, up = qi[finite], vi[finite], low[finite], up[finite]
    return JointBox(np.minimum(low, q[qi]), np.maximum(up, q[qi]), qi, where[vi], vi)


_PER_THREAD = threading.local()


def _model_cache(clm: Any) -> tuple[Any, SingleDofJoints]:
    """Per thread and model (weakly held): a Pinocchio data for the task frames and the
    model's :class:`SingleDofJoints`, so that a solve does not rebuild them."""
    store = getattr(_PER_THREAD, "models", None)
    if store is None:
        store = _PER_THREAD.models = weakref.WeakKeyDictionary()
    entry = store.get(clm)
    if entry is None or entry[2] is not clm.model:
        joints = [(j.idx_q, j.idx_v) for j in clm.model.joints[1:] if j.nq == 1 and j.nv == 1]
        single = SingleDofJoints(np.array([a for a, _ in joints], dtype=int),
                                 np.array([b for _, b in joints], dtype=int))
        entry = store[clm] = (clm.model.createData(), single, clm.model)
    return entry[0], entry[1]


class Linearisation(NamedTuple):
    """The problem linearised at an iterate, on the free coordinates (n of them)."""

    err: np.ndarray       # (m,) stacked task errors, unweighted
    cost: float           # |err|_W^2
    jac_t: np.ndarray     # (m, n) task Jacobian
    jac_c: np.ndarray     # (r, n) the independent closure rows of J_c (basis.rows)
    res_c: np.ndarray     # (r,) their residuals
    basis: RowBasis       # bases of those rows (range, null space, right inverse)


class _Problem:
    """What one solve keeps between its steps: tasks, free coordinates, limits, a Pinocchio
    data for the task frames (one per thread and model), the ProxSuite QP (updated, not
    rebuilt)."""

    def __init__(self, clm, tasks, fixed_v, method, closure_tol, limits, q):
        self.clm, self.tasks, self.method, self.closure_tol = clm, tasks, method, closure_tol
        self.fixed_v = fixed_v
        keep = np.ones(clm.nv, dtype=bool)
        keep[fixed_v] = False
        self.free = np.flatnonzero(keep)
        self.all_free = self.free.size == clm.nv
        self.data, single = _model_cache(clm)
        self.box = _limits(clm, self.free, q, single) if (limits and method == "qp") else None
        self.weight = np.concatenate([t.weight for t in tasks])
        self.qp, self.qp_rows = None, -1
        self.selection = None            # the rows of the limited joints (QP inequalities)
        if self.box is not None:
            self.selection = np.zeros((self.box.position.size, self.free.size))
            self.selection[np.arange(self.box.position.size), self.box.position] = 1.0

    def full(self, step: np.ndarray) -> np.ndarray:
        """A step on the free coordinates as a tangent vector (nv,)."""
        if self.all_free:
            return step
        out = np.zeros(self.clm.nv)
        out[self.free] = step
        return out

    def errors(self, q: np.ndarray) -> np.ndarray:
        """Stacked task errors at ``q`` (placements of ``q`` left in ``self.data``)."""
        return _task_errors(self.clm.model, self.data, self.tasks, q)

    def linearise(self, q: np.ndarray, res_c: np.ndarray) -> Linearisation:
        """Errors and Jacobians at ``q`` (closure residual ``res_c`` already known)."""
        jac_c = self.clm.constraint_jacobian(q)
        if not self.all_free:
            jac_c = jac_c[:, self.free]
        err, jac_t = self._task_jacobian(q)
        basis = row_basis(jac_c)
        return Linearisation(err, float(err @ (self.weight * err)), jac_t, jac_c[basis.rows],
                             res_c[basis.rows], basis)

    def _task_jacobian(self, q: np.ndarray):
        """Task errors and their Jacobian on the free coordinates at ``q``."""
        model, data = self.clm.model, self.data
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        errs, jacs = [], []
        for task in self.tasks:
            omf = data.oMf[task.frame]
            if task.position_only:
                errs.append(omf.translation - task.target.translation)
                jacs.append(pin.getFrameJacobian(model, data, task.frame,
                                                 pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3])
            else:
                rel = task.target.actInv(omf)
                errs.append(pin.log6(rel).vector)
                jacs.append(pin.Jlog6(rel) @ pin.getFrameJacobian(model, data, task.frame,
                                                                   pin.ReferenceFrame.LOCAL))
        jac_t = jacs[0] if len(jacs) == 1 else np.vstack(jacs)
        return (errs[0] if len(errs) == 1 else np.concatenate(errs),
                jac_t if self.all_free else jac_t[:, self.free])

    def curvature(self, lin: Linearisation, q: np.ndarray) -> np.ndarray | None:
        """The second-order term Gauss-Newton leaves out, on the closures' null space.

        ``Z R Z^T`` with ``R = Z^T (sum_i (W e)_i hess(e_i) + sum_k y_k hess(c_k)) Z``: the
        curvature of the task errors and of the closures (multipliers ``y`` of the
        least-squares step) along the null-space basis ``Z``, by forward differences of
        the Lagrangian's gradient. It matters where the target is out of reach and the
        task Jacobian loses rank at the closest placement (a leg folded flat): there
        Gauss-Newton creeps. None where the reduced Hessian it gives is not positive
        definite (then the damping alone rules).
        """
        null = lin.basis.null
        if null.shape[1] == 0:
            return None
        w_err = self.weight * lin.err
        grad = lin.jac_t.T @ w_err
        mult = -lin.basis.pinv.T @ grad
        base = grad + lin.jac_c.T @ mult
        cols = []
        for direction in null.T:
            moved = pin.integrate(self.clm.model, q, self.full(CURVATURE_STEP * direction))
            jac_c = self.clm.constraint_jacobian(moved)[:, self.free][lin.basis.rows]
            _, jac_t = self._task_jacobian(moved)
            cols.append((jac_t.T @ w_err + jac_c.T @ mult - base) / CURVATURE_STEP)
        reduced = null.T @ np.array(cols).T
        reduced = 0.5 * (reduced + reduced.T)
        gauss_newton = null.T @ (lin.jac_t.T @ (self.weight[:, None] * lin.jac_t)) @ null
        if not np.linalg.eigvalsh(gauss_newton + reduced)[0] > 0.0:
            return None
        return null @ reduced @ null.T

    def stationary(self, lin: Linearisation, q: np.ndarray) -> bool:
        """True at a least-squares stationary point: the task gradient has no component
        along the closures (relative to ``max|J_t| max|W e|``). Not judged while a joint
        sits on a limit (the vanishing undamped step decides there)."""
        box = self.box
        if box is not None and np.any((q[box.q_index] <= box.lower)
                                      | (q[box.q_index] >= box.upper)):
            return False
        grad = lin.jac_t.T @ (self.weight * lin.err)
        tangent = lin.basis.null.T @ grad
        scale = float(np.max(np.abs(lin.jac_t), initial=0.0)
                      * np.max(np.abs(self.weight * lin.err)))
        return float(np.max(np.abs(tangent), initial=0.0)) <= GRAD_RTOL * scale

    def step(self, lin: Linearisation, lam: float, q: np.ndarray,
             curvature: np.ndarray | None = None) -> np.ndarray:
        """The damped step on the free coordinates (the module docstring's QP), with the
        second-order term of :meth:`curvature` added to the Hessian when given."""
        hess, grad, a_mat, b, s, scale = _qp_data(
            lin.jac_t, self.weight, lin.err, lam,
            _NO_CURVATURE if curvature is None else curvature, lin.jac_c, lin.res_c)
        if self.method == "qp":
            step = self._qp_step(hess, grad, a_mat, b, s, q)
            if step is not None:
                return step
        step = self._null_space_step(lin, hess * scale, grad * (scale * s))
        if self.method == "qp" and self.box is not None and not self._inside(
                pin.integrate(self.clm.model, q, self.full(step))):
            raise SolverError("proxsuite.proxqp.dense", str(self.qp.results.info.status),
                              "frame inverse kinematics step (its null-space fallback "
                              "would cross a joint limit)")
        return step

    @staticmethod
    def _null_space_step(lin: Linearisation, hess: np.ndarray, grad: np.ndarray) -> np.ndarray:
        """The step of route "lstsq": closure rows solved with the least norm, the task
        least squares on their null space (bounds ignored)."""
        part = -lin.basis.pinv @ lin.res_c
        null = lin.basis.null
        reduced = null.T @ hess @ null
        z = np.linalg.lstsq(reduced, -null.T @ (grad + hess @ part), rcond=None)[0]
        return part + null @ z

    def _qp_step(self, hess, grad, a_mat, b, s, q) -> np.ndarray | None:
        """ProxSuite's step on the scaled data of :func:`_qp_data`, or None where it stops
        at ``QP_MAX_ITER`` (an ill-conditioned step near a singular placement, where its
        proximal iterations crawl)."""
        n, n_eq = hess.shape[0], b.size
        if not n_eq:
            a_mat = b = None
        box = self.box
        n_in = 0 if box is None else box.position.size
        c_mat = low = up = None
        if n_in:
            c_mat = self.selection
            low = np.minimum(box.lower - q[box.q_index], 0.0) / s
            up = np.maximum(box.upper - q[box.q_index], 0.0) / s
        qp = self.qp
        if qp is None or self.qp_rows != n_eq:
            self.qp_rows = n_eq
            qp = self.qp = proxsuite.proxqp.dense.QP(n, n_eq, n_in)
            qp.settings.eps_abs = _QP_EPS
            qp.settings.eps_rel = 0.0
            # the Hessian is only positive on the closures' null space: no infeasibility
            # verdicts from the (loose by default) certificates; success from the status
            qp.settings.eps_dual_inf = 1e-30
            qp.settings.eps_primal_inf = 1e-30
            qp.settings.verbose = False
            qp.settings.max_iter = QP_MAX_ITER
            qp.settings.max_iter_in = QP_MAX_ITER
            qp.init(hess, grad, a_mat, b, c_mat, low, up)
        else:
            qp.update(hess, grad, a_mat, b, c_mat, low, up)
        qp.solve()
        step = s * qp.results.x
        if qp.results.info.status != proxsuite.proxqp.PROXQP_SOLVED or not np.all(
                np.isfinite(step)):
            return None
        return step

    def retract(self, q: np.ndarray, lin: Linearisation, tol: float):
        """Close the loops again from ``q`` (a step from the linearisation point):
        ``(q, closure residual)`` with the residual at most ``tol`` (m / rad), or None if
        they cannot be closed.

        A chord Newton iteration first (the right inverse of the linearisation point's
        closure rows, the free coordinates moved by the least norm), the full Newton of
        :meth:`ClosedLoopModel.assemble` where it does not contract. With limits, a
        limited joint outside its range is put on the bound and held there while the
        loops close (repeated while the closing pushes another one out).
        """
        clm, box = self.clm, self.box
        if box is None or self._inside(q):
            res = clm.residual(q)
            err = _max_abs(res)
            for _ in range(CHORD_ITER):
                if err <= tol:
                    return (q, res) if box is None or self._inside(q) else self._held(q)
                trial = pin.integrate(clm.model, q,
                                      self.full(-lin.basis.pinv @ res[lin.basis.rows]))
                trial_res = clm.residual(trial)
                trial_err = _max_abs(trial_res)
                if not trial_err <= CHORD_CONTRACTION * err:
                    break
                q, res, err = trial, trial_res, trial_err
        return self._held(q)

    def _inside(self, q: np.ndarray) -> bool:
        values = q[self.box.q_index]
        return bool(np.all((values >= self.box.lower) & (values <= self.box.upper)))

    def _held(self, q: np.ndarray):
        """Full Newton closing (limited joints out of range put on their bound and held)."""
        clm, box, hold = self.clm, self.box, self.fixed_v
        for _ in range(1 + (0 if box is None else box.position.size)):
            if box is not None:
                values = q[box.q_index]
                out = (values < box.lower) | (values > box.upper)
                if hold is not self.fixed_v and not out.any():
                    return q, clm.residual(q)
                q = q.copy()
                q[box.q_index] = np.clip(values, box.lower, box.upper)
                hold = np.union1d(hold, box.v_index[out])
            try:
                q = clm.assemble(q, fixed=hold, tol=self.closure_tol, restarts=0,
                                 method="newton").q
            except AssemblyError:
                return None
            if box is None:
                return q, clm.residual(q)
        return (q, clm.residual(q)) if self._inside(q) else None


def _result(clm, tasks, q, reachable: bool, history: list[float],
            closure_tol: float) -> FrameIKResult:
    """Verify the answer (finite, closures) and package it."""
    iterations = len(history) - 1
    closure = float(np.max(np.abs(clm.residual(q)), initial=0.0))
    if not closure <= closure_tol:
        raise AssemblyError(f"closures not held at the answer (tolerance {closure_tol:g})",
                            closure, iterations, q)
    err = _task_errors(clm.model, clm.data, tasks, q)
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(err)) and np.isfinite(closure)):
        raise SolverError("frame_inverse_kinematics", "non-finite", "NaN in the answer")
    placements = tuple(pin.SE3(clm.data.oMf[t.frame]) for t in tasks)
    return FrameIKResult(q.copy(), reachable, float(np.max(np.abs(err))), closure, iterations,
                         err, placements, tuple(history))



def _task_errors(model, data, tasks, q) -> np.ndarray:
    """Stacked task errors at ``q`` (module docstring), frame placements left in ``data``."""
    pin.framesForwardKinematics(model, data, q)
    out = []
    for task in tasks:
        omf = data.oMf[task.frame]
        if task.position_only:
            out.append(omf.translation - task.target.translation)
        else:
            out.append(pin.log6(task.target.actInv(omf)).vector)
    return np.concatenate(out)


def _max_abs(vec: np.ndarray) -> float:
    """Max-abs of a 1-D array (0 when empty), without numpy's Python-level dispatch."""
    return float(np.abs(vec).max()) if vec.size else 0.0


_NO_CURVATURE = np.zeros((0, 0))


@jit
def _qp_data(jac_t, weight, err, lam, curvature, jac_c, res_c):
    """The step's QP data, scaled: (H, g, A, b, s, scale) with ``H = (J_t^T W J_t [+ C]
    + lam I) / scale``, ``g = J_t^T W e / (scale s)``, ``A`` the closure rows at unit norm,
    ``b = -r_c / (|row| s)``, ``s = max|e|`` and ``scale = max(1, max|H|)``.

    The unknowns are scaled by the task error (``y = dv / s``): ProxSuite's absolute
    accuracy then acts relative to the step, which keeps the last Newton steps exact.
    """
    n = jac_t.shape[1]
    weighted = np.empty_like(jac_t)
    for i in range(jac_t.shape[0]):
        weighted[i] = weight[i] * jac_t[i]
    hess = jac_t.T @ weighted
    if curvature.shape[0] == n:
        hess += curvature
    for i in range(n):
        hess[i, i] += lam
    grad = weighted.T @ err
    s = max(np.max(np.abs(err)), 1e-300)
    scale = max(1.0, np.max(np.abs(hess)))
    a_mat = np.empty_like(jac_c)
    b = np.empty(jac_c.shape[0])
    for i in range(jac_c.shape[0]):
        norm = np.sqrt(np.sum(jac_c[i] * jac_c[i]))
        a_mat[i] = jac_c[i] / norm
        b[i] = -res_c[i] / (norm * s)
    return hess / scale, grad / (scale * s), a_mat, b, s, scale

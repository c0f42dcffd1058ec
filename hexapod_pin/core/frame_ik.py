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
the loops closed again by :meth:`ClosedLoopModel.assemble` (each iterate keeps the
closures to ``closure_tol``); it is kept when ``|e|_W^2`` falls by a fair part of what
the linear model predicts, ``mu`` raised tenfold otherwise (and lowered, down to
``damping``, after good steps): a trust region in the Levenberg-Marquardt manner. The
iteration stops at a least-squares stationary point (flagged unreachable) when the step
at the base damping vanishes (``STEP_TOL``) or no damping up to ``MU_MAX`` gives a
decrease.

Task errors (Pinocchio conventions, frames' placements ``oMf`` in world):

* a placement target ``T``: ``e = log6(T^-1 oMf)`` (m, rad: the twist from the target to
  the frame, in the target's axes), ``J_t = Jlog6(T^-1 oMf) J_LOCAL``;
* a position target ``p`` (``position_only``): ``e = oMf.translation - p`` (m, world axes),
  ``J_t`` the linear rows of ``J_LOCAL_WORLD_ALIGNED``.

A target out of reach gives the least-squares (weighted) closest placement, flagged
``reachable=False``; a model whose closures cannot be held raises AssemblyError.
The direct route (``method="lstsq"``) solves the same step in the closures' null space
with SVD least squares and ignores joint limits; both routes give the same iterates
where no limit is active.
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import proxsuite
import scipy.linalg

from ..errors import AssemblyError, InputError, SolverError
from .checks import as_array
from .closure_motion import independent_rows

IK_METHODS = ("qp", "lstsq")
#: damping factor of the Levenberg-Marquardt term ``lambda = DAMPING |e|_W^2``
DAMPING = 1e-3
#: floor of lambda (keeps the step unique when the task leaves directions free)
DAMPING_FLOOR = 1e-12
#: a step is kept when it achieves this fraction of the decrease its linear model predicts
ACCEPT_RATIO = 1e-4
#: past this damping factor no step is tried any more (the start is stationary)
MU_MAX = 1e12
#: an undamped step below this (max-abs, m / rad) marks a stationary point
STEP_TOL = 1e-12
_QP_EPS = 1e-12


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
        closure_tol: closure residual kept at every iterate (m / rad).
        max_iter: iteration cap.
        limits: keep 1-DoF joints with finite position limits in their range (route
            "qp": bounds of each step, and joints put on their bound while the loops
            close); a joint that starts outside its range may not go further out.
        damping: Levenberg-Marquardt factor (see the module docstring).

    Returns:
        :class:`FrameIKResult` (``reachable`` False: the closest reachable placement).

    Raises:
        InputError: unknown frame or joint, bad target shape, non-positive weight, bad
            method or option.
        AssemblyError: the closures cannot be held from ``q0`` with ``fixed`` held.
        SolverError: ProxSuite failed, or no convergence nor stationarity in ``max_iter``.
    """
    if method not in IK_METHODS:
        raise InputError("method", method, f"expected one of {IK_METHODS}")
    if not (tol > 0 and closure_tol > 0 and max_iter >= 1 and damping >= 0):
        raise InputError("options", (tol, closure_tol, max_iter, damping),
                         "tol, closure_tol > 0, max_iter >= 1, damping >= 0 needed")
    tasks = _tasks(clm, frame, target, position_only, weights)
    fixed_v = _fixed_indices(clm, fixed)
    free = np.setdiff1d(np.arange(clm.nv), fixed_v)
    start = clm.neutral() if q0 is None else clm.check_q(q0, "q0")
    q = clm.assemble(start, fixed=fixed_v, tol=closure_tol).q
    box = _limits(clm, free, q) if (limits and method == "qp") else None
    err, jac_t, jac_c, res_c = _linearise(clm, tasks, q)
    weight = np.concatenate([t.weight for t in tasks])
    cost = float(err @ (weight * err))
    mu = damping
    history = [float(np.max(np.abs(err)))]
    for iteration in range(max_iter + 1):
        if float(np.max(np.abs(err))) <= tol:
            return _result(clm, tasks, q, True, history, closure_tol)
        if iteration == max_iter:
            break
        accepted = None
        while accepted is None:
            lam = max(mu * cost, DAMPING_FLOOR)
            step = np.zeros(clm.nv)
            step[free] = _step(jac_t[:, free], err, weight, jac_c[:, free], res_c, lam, method,
                               box, q)
            if mu == damping and float(np.max(np.abs(step))) <= STEP_TOL:
                # the least-squares step vanishes: a stationary point of |e|_W^2
                return _result(clm, tasks, q, False, history, closure_tol)
            model = err + jac_t @ step
            predicted = cost - float(model @ (weight * model))
            trial = _retract(clm, pin.integrate(clm.model, q, step), fixed_v, closure_tol, box)
            if trial is not None:
                trial_err = _errors(clm, tasks, trial)
                trial_cost = float(trial_err @ (weight * trial_err))
                ratio = (cost - trial_cost) / predicted if predicted > 0 else -1.0
                if np.isfinite(trial_cost) and ratio > ACCEPT_RATIO:
                    accepted = trial, trial_cost
                    if ratio > 0.75:
                        mu = max(mu / 10.0, damping)
                    elif ratio < 0.25:
                        mu *= 10.0
                    break
            if mu > MU_MAX:
                return _result(clm, tasks, q, False, history, closure_tol)
            mu = max(mu, 1e-12) * 10.0
        q, cost = accepted
        err, jac_t, jac_c, res_c = _linearise(clm, tasks, q)
        history.append(float(np.max(np.abs(err))))
    raise SolverError("frame_inverse_kinematics", "max_iter",
                      f"task error {float(np.max(np.abs(err))):.3e} after {max_iter} steps")


# ------------------------------------------------------------------------------ helpers
def _tasks(clm, frame, target, position_only, weights) -> list[FrameTask]:
    several = not isinstance(frame, (str, int, np.integer))
    frames = list(frame) if several else [frame]
    targets = list(target) if several else [target]
    if len(targets) != len(frames):
        raise InputError("target", target, f"expected {len(frames)} targets")
    flags = ([bool(position_only)] * len(frames) if np.ndim(position_only) == 0
             else [bool(f) for f in position_only])
    wlist = [1.0] * len(frames) if weights is None else (
        list(weights) if several else [weights])
    if len(flags) != len(frames) or len(wlist) != len(frames):
        raise InputError("position_only / weights", (position_only, weights),
                         f"expected one per frame ({len(frames)})")
    out = []
    for fr, tgt, flag, w in zip(frames, targets, flags, wlist):
        rows = 3 if flag else 6
        w = np.broadcast_to(np.asarray(w, dtype=float), (rows,)).copy()
        if not np.all(np.isfinite(w) & (w > 0)):
            raise InputError("weights", w, "weights must be finite and > 0")
        out.append(FrameTask(clm.frame_id(fr), _placement(tgt, flag), flag, w))
    return out


def _placement(target, position_only: bool) -> pin.SE3:
    if position_only:
        return pin.SE3(np.eye(3), as_array(target, (3,), "target"))
    if isinstance(target, pin.SE3):
        mat = target.homogeneous
    else:
        mat = as_array(target, (4, 4), "target")
    rot = mat[:3, :3]
    if not (np.allclose(rot.T @ rot, np.eye(3), atol=1e-9) and np.linalg.det(rot) > 0
            and np.allclose(mat[3], [0, 0, 0, 1])):
        raise InputError("target", target, "not a rigid placement (rotation, last row)")
    return pin.SE3(rot, mat[:3, 3])


def _fixed_indices(clm, fixed) -> np.ndarray:
    if fixed is None:
        return np.zeros(0, dtype=int)
    out: list[int] = []
    for item in fixed:
        if isinstance(item, str):
            start = clm.joint_v_index(item)
            nv = clm.model.joints[clm.model.getJointId(item)].nv
            out.extend(range(start, start + nv))
        elif isinstance(item, (int, np.integer)) and 0 <= int(item) < clm.nv:
            out.append(int(item))
        else:
            raise InputError("fixed", item, f"a joint name or an index into v in [0, {clm.nv})")
    return np.unique(np.asarray(out, dtype=int))


def _limits(clm, free: np.ndarray, q: np.ndarray) -> JointBox | None:
    """The limited 1-DoF joints among the free coordinates, or None.

    A joint that starts outside its range gets the range extended to its start value
    (it may come back, never go further out).
    """
    model = clm.model
    lo: list[float] = []
    hi: list[float] = []
    qi: list[int] = []
    pos: list[int] = []
    where = {int(v): k for k, v in enumerate(free)}
    for joint in model.joints[1:]:
        if joint.nq != 1 or joint.nv != 1 or joint.idx_v not in where:
            continue
        low = model.lowerPositionLimit[joint.idx_q]
        up = model.upperPositionLimit[joint.idx_q]
        if -1e10 < low < up < 1e10:
            lo.append(low)
            hi.append(up)
            qi.append(joint.idx_q)
            pos.append(where[joint.idx_v])
    if not pos:
        return None
    pos_a, qi_a = np.array(pos, dtype=int), np.array(qi, dtype=int)
    return JointBox(np.minimum(lo, q[qi_a]), np.maximum(hi, q[qi_a]), qi_a, pos_a, free[pos_a])


def _linearise(clm, tasks: list[FrameTask], q: np.ndarray):
    """Task errors (unweighted), task Jacobian, closure Jacobian and residual at ``q``."""
    jac_c = clm.constraint_jacobian(q)          # leaves joint Jacobians and oMf of q
    res_c = clm.residual(q)
    errs, jacs = [], []
    for task in tasks:
        omf = clm.data.oMf[task.frame]
        if task.position_only:
            errs.append(omf.translation - task.target.translation)
            jacs.append(pin.getFrameJacobian(clm.model, clm.data, task.frame,
                                             pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3])
        else:
            rel = task.target.actInv(omf)
            errs.append(pin.log6(rel).vector)
            jacs.append(pin.Jlog6(rel) @ pin.getFrameJacobian(clm.model, clm.data, task.frame,
                                                               pin.ReferenceFrame.LOCAL))
    return np.concatenate(errs), np.vstack(jacs), jac_c, res_c


def _step(jac_t, err, weight, jac_c, res_c, lam, method, box, q) -> np.ndarray:
    n = jac_t.shape[1]
    hess = jac_t.T @ (weight[:, None] * jac_t) + lam * np.eye(n)
    grad = jac_t.T @ (weight * err)
    rows = independent_rows(jac_c)
    if method == "lstsq":
        null = scipy.linalg.null_space(jac_c[rows]) if rows.size else np.eye(n)
        part = (np.linalg.lstsq(jac_c[rows], -res_c[rows], rcond=None)[0] if rows.size
                else np.zeros(n))
        reduced = null.T @ hess @ null
        z = np.linalg.lstsq(reduced, -null.T @ (grad + hess @ part), rcond=None)[0]
        return part + null @ z
    # unknowns scaled by the task error (y = dv / s): ProxSuite's absolute accuracy then
    # acts relative to the step, which keeps the last Newton steps exact
    s = max(float(np.max(np.abs(err))), 1e-300)
    a_mat = jac_c[rows]
    norms = np.linalg.norm(a_mat, axis=1)
    a_mat = np.ascontiguousarray(a_mat / norms[:, None]) if rows.size else None
    b = np.ascontiguousarray(-res_c[rows] / norms / s) if rows.size else None
    n_in = 0 if box is None else box.position.size
    c_mat = low = up = None
    if n_in:
        c_mat = np.zeros((n_in, n))
        c_mat[np.arange(n_in), box.position] = 1.0
        low = np.minimum(box.lower - q[box.q_index], 0.0) / s
        up = np.maximum(box.upper - q[box.q_index], 0.0) / s
    qp = proxsuite.proxqp.dense.QP(n, rows.size, n_in)
    qp.settings.eps_abs = _QP_EPS
    qp.settings.eps_rel = 0.0
    # the Hessian is only positive on the closures' null space: no infeasibility verdicts
    # from the (loose by default) certificates; success is judged from the status
    qp.settings.eps_dual_inf = 1e-30
    qp.settings.eps_primal_inf = 1e-30
    qp.settings.verbose = False
    scale = max(1.0, float(np.max(np.abs(hess))))
    qp.init(hess / scale, grad / (scale * s), a_mat, b, c_mat, low, up)
    qp.solve()
    if qp.results.info.status != proxsuite.proxqp.PROXQP_SOLVED:
        raise SolverError("proxsuite.proxqp.dense", str(qp.results.info.status),
                          "frame inverse kinematics step")
    step = s * np.array(qp.results.x)
    if not np.all(np.isfinite(step)):
        raise SolverError("proxsuite.proxqp.dense", "non-finite", "frame IK step")
    return step


def _retract(clm, q, fixed_v, closure_tol, box):
    """Close the loops again from ``q`` (None if they cannot be closed).

    With limits, a limited joint outside its range is put on the bound and held there
    while the loops close (repeated while the closing pushes another one out).
    """
    hold = fixed_v
    for _ in range(1 + (0 if box is None else box.position.size)):
        if box is not None:
            values = q[box.q_index]
            out = (values < box.lower) | (values > box.upper)
            if hold is not fixed_v and not out.any():
                return q
            q = q.copy()
            q[box.q_index] = np.clip(values, box.lower, box.upper)
            hold = np.union1d(hold, box.v_index[out])
        try:
            q = clm.assemble(q, fixed=hold, tol=closure_tol).q
        except AssemblyError:
            return None
        if box is None:
            return q
    values = q[box.q_index]
    return q if np.all((values >= box.lower) & (values <= box.upper)) else None


def _errors(clm, tasks, q) -> np.ndarray:
    pin.framesForwardKinematics(clm.model, clm.data, q)
    out = []
    for task in tasks:
        omf = clm.data.oMf[task.frame]
        if task.position_only:
            out.append(omf.translation - task.target.translation)
        else:
            out.append(pin.log6(task.target.actInv(omf)).vector)
    return np.concatenate(out)


def _result(clm, tasks, q, reachable: bool, history: list[float],
            closure_tol: float) -> FrameIKResult:
    """Verify the answer (finite, closures) and package it."""
    iterations = len(history) - 1
    closure = float(np.max(np.abs(clm.residual(q)), initial=0.0))
    if not closure <= closure_tol:
        raise AssemblyError(f"closures not held at the answer (tolerance {closure_tol:g})",
                            closure, iterations, q)
    err = _errors(clm, tasks, q)
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(err)) and np.isfinite(closure)):
        raise SolverError("frame_inverse_kinematics", "non-finite", "NaN in the answer")
    placements = tuple(pin.SE3(clm.data.oMf[t.frame]) for t in tasks)
    return FrameIKResult(q.copy(), reachable, float(np.max(np.abs(err))), closure, iterations,
                         err, placements, tuple(history))


"""Analytic derivatives of the closed-loop forward dynamics of any
:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`, by implicit differentiation of its
KKT system (the equations of :mod:`hexapod_pin.core.dynamics`)::

    E = M(q) a + h(q, v) - tau_e(q, v) - S^T u - tau_ext - J_c(q)^T lambda = 0
    C = J_c(q) a + gamma(q, v) = 0

At a solution ``(a, lambda)`` a perturbation ``(dq, dv, du, dtau_ext)`` moves them by
``(da, dlambda)`` solving ``M da - J_c^T dlambda = -(E_q dq + E_v dv) + S^T du + dtau_ext``,
``J_c da = -(C_q dq + C_v dv)``. The partials come from Pinocchio's tree derivatives:
``E_q``, ``E_v`` from one ``pin.computeRNEADerivatives`` call with the closure forces as
external forces (plus the turning of a point closure's world-fixed force with its body
and of a weld's force on its second anchor, and the effects' ``-d tau_s / dq`` and
``-D``), ``C_q``, ``C_v`` from the joint Jacobian of one ``pin.computeJointJacobians``
pass, every closure anchor frame at once (:func:`frame_rates`, compiled; a point closure's
rows: the difference of the world-axes classical accelerations of its two anchor points; a
weld's: the relative spatial acceleration ``a1 - Ad(M12) a2 + v1 x Ad(M12) v2``, LOCAL,
Pinocchio's 6-D rows ``J_rel = J1 - Ad(M12) J2``, which the library's ``Jlog6(M21)`` rows
multiply; its multipliers become ``Jlog6^T lambda``, the same on the closures).

These rows are those of the library's dynamics at every state, on the closures or not (an
integrator's stage states), so the partials hold in every direction. Along the closures,
``q`` moves along ``dq`` in ``null(J_c)`` (``pin.integrate``), and ``v`` is carried along
by its Euclidean projection onto the closures, ``v(q) = Pi(q) v`` with ``Pi = I - J_c^+
J_c``, so that ``dv = -J_c^+ (d(J_c v)/dq) dq``: every derivative along such a tangent
direction is that of the library's verified forward dynamics. The multipliers' derivatives
are those of the minimum-norm multipliers (the library's, unique or not).

Coulomb friction: the force of a sliding coordinate is constant (zero derivative); a
coordinate at rest makes the dynamics non-smooth (stick / slip) and is refused. The
derivation and the tests that check it: ``docs/derivations.md`` (section 8).
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import InputError, SingularityError, SolverError
from .checks import as_array, max_abs
from .closed_loop import RANK_RTOL, ClosedLoopModel
from .closure_motion import FULL_RANK_RTOL
from .derivative_kernels import (
    DEPENDENT_ROWS,
    NOT_FINITE,
    NOT_POSITIVE,
    anchor_forces_kernel,
    closure_rows_kernel,
    frame_rates_kernel,
    kkt_along_kernel,
    kkt_solve_kernel,
    linearize_kernel,
    point_turning_kernel,
    reduced_gain_kernel,
)
from .dynamics import forward_dynamics_tree
from .effects import JointEffects, at_rest, passive_forces
from .pose import skew

_LOCAL = pin.ReferenceFrame.LOCAL
#: relative residual accepted for the linear solves of the derivatives (each is checked
#: against the linearised equations it solves)
DERIVATIVE_SOLVE_RTOL = 1e-8


class FrameRates(NamedTuple):
    """The motion of some frames at a state ``(q, v, a)`` and its partial derivatives
    (:func:`frame_rates`), one entry per frame along the first axis.

    World rows: the classical acceleration of the frame origin and the angular
    acceleration (m/s^2, rad/s^2) and the velocity ``(v, w)``, world axes (Pinocchio's
    ``LOCAL_WORLD_ALIGNED``). Local rows: the spatial acceleration and velocity in the
    frame's LOCAL axes.

    Attributes:
        acc: (n, 6) the accelerations.
        acc_q: (n, 6, nv) their partials in ``q`` (tangent, ``pin.integrate``).
        acc_v: (n, 6, nv) their partials in ``v``.
        jac: (n, 6, nv) their partials in ``a`` (the frame Jacobians in the same axes).
        vel: (n, 6) the velocities.
        vel_q: (n, 6, nv) their partials in ``q``.
        rot: (n, 3, 3) the frames' rotations (frame axes to world axes).
    """

    acc: np.ndarray
    acc_q: np.ndarray
    acc_v: np.ndarray
    jac: np.ndarray
    vel: np.ndarray
    vel_q: np.ndarray
    rot: np.ndarray


class FrameSet:
    """What :func:`frame_rates` needs of the model for some frames, built once (per model
    and frame list: :func:`frame_set`).

    Attributes:
        frames: the frame ids.
        joints: (n,) each frame's parent joint.
        support: (n, nv) whether each velocity coordinate supports each frame (belongs to
            its parent joint or a joint above it).
        joint_support: (njoints, nv) the same for every joint (row 0: the universe).
        col_joint: (nv,) the joint of each velocity coordinate.
        col_parent: (nv,) the parent joint of each velocity coordinate's joint.
        col_inner: (nv,) whether that parent is not the universe.
        placement_rot: (n, 3, 3) each frame's rotation in its joint.
        placement_pos: (n, 3) each frame's position in its joint.
        inner_joints: the distinct parent joints of the frames (sorted).
        joint_index: (n,) each frame's parent joint's position in ``inner_joints``.
    """

    def __init__(self, model: pin.Model, frames: Sequence[int]) -> None:
        self.frames = [int(f) for f in frames]
        placements = [model.frames[f] for f in self.frames]
        self.joints = np.array([f.parentJoint for f in placements], dtype=np.int64)
        nv = model.nv
        col_joint = self.col_joint = np.zeros(nv, dtype=np.int64)
        self.joint_support = np.zeros((model.njoints, nv), dtype=bool)
        for j in range(1, model.njoints):
            joint = model.joints[j]
            col_joint[joint.idx_v:joint.idx_v + joint.nv] = j
            for s in model.supports[j][1:]:
                above = model.joints[int(s)]
                self.joint_support[j, above.idx_v:above.idx_v + above.nv] = True
        self.col_parent = np.array([model.parents[int(j)] for j in col_joint], dtype=np.int64)
        self.col_inner = self.col_parent > 0
        self.support = self.joint_support[self.joints]
        self.placement_rot = np.array([f.placement.rotation for f in placements]
                                      ).reshape(-1, 3, 3)
        self.placement_pos = np.array([f.placement.translation for f in placements]
                                      ).reshape(-1, 3)
        self.inner_joints = sorted({int(j) for j in self.joints})
        self.joint_index = np.searchsorted(self.inner_joints, self.joints)


def frame_set(clm: ClosedLoopModel, frames: Sequence[int]) -> FrameSet:
    """The :class:`FrameSet` of ``frames`` (ids) of ``clm`` (kept in its :class:`Layout`)."""
    key = tuple(int(f) for f in frames)
    sets = layout_of(clm).frame_sets
    out = sets.get(key)
    if out is None:
        out = sets[key] = FrameSet(clm.model, key)
    return out


def frame_rates(model: pin.Model, data: pin.Data, frames: Sequence[int] | FrameSet,
                v: np.ndarray, a: np.ndarray, world: np.ndarray) -> FrameRates:
    """:class:`FrameRates` of ``frames`` (ids, or their :class:`FrameSet`) at the state ``(v,
    a)``, world rows where ``world`` (bool (n,)) is True, else LOCAL ones, from the joint
    placements ``data.oMi`` and the world joint Jacobian ``data.J`` of any Pinocchio pass
    at ``q`` that fills them (``pin.computeJointJacobians``,
    ``pin.computeForwardKinematicsDerivatives``, ``pin.computeRNEADerivatives``): only
    ``q`` is read from ``data``, so one pass serves every ``(v, a)``.

    All frames in one compiled call
    (:func:`~hexapod_pin.core.derivative_kernels.frame_rates_kernel`), as
    ``pin.getJointAccelerationDerivatives`` (WORLD) forms them for one joint from ``J_c``
    and ``dJ_c = ov_i x J_c``: the column of coordinate ``c`` (joint ``i``, parent ``p``) of
    a body on joint ``b`` has ``dV/dq = (ov_p - ov_b) x J_c``, ``dA/dv = dV/dq + dJ_c``,
    ``dA/dq = (oa_p - oa_b) x J_c + [p > 0] (ov_p - ov_b) x dJ_c`` (zero off the body's
    support; ``ov_j = sum J_c v_c``, ``oa_j = sum J_c a_c + dJ_c v_c`` over the
    coordinates supporting ``j``). Moved to each frame origin ``o`` (world axes): ``x_o =
    x - o x x_ang`` and ``d x_o = (dx)_o + [x_o,ang]_x J_o,lin``; the velocity is ``J_o
    v``, the spatial acceleration ``J_o a + (dA_o/dv) v / 2`` (its bias is quadratic in
    ``v``). World rows add ``w x v`` to the linear acceleration (classical); LOCAL rows
    rotate, ``x_l = R^T x_o`` and ``d x_l / dq = R^T (d x_o / dq + [x_o]_x J_o,ang)`` per
    3-block."""
    fs = frames if isinstance(frames, FrameSet) else FrameSet(model, frames)
    n, nv = len(fs.frames), model.nv
    if not n:
        return FrameRates(np.zeros((0, 6)), np.zeros((0, 6, nv)), np.zeros((0, 6, nv)),
                          np.zeros((0, 6, nv)), np.zeros((0, 6)), np.zeros((0, 6, nv)),
                          np.zeros((0, 3, 3)))
    oMi = data.oMi
    homog = np.array([oMi[j].homogeneous for j in fs.inner_joints])[fs.joint_index]
    rot = homog[:, :3, :3] @ fs.placement_rot
    pos = (homog[:, :3, :3] @ fs.placement_pos[:, :, None])[..., 0] + homog[:, :3, 3]
    out = FrameRates(np.zeros((n, 6)), np.zeros((n, 6, nv)), np.zeros((n, 6, nv)),
                     np.zeros((n, 6, nv)), np.zeros((n, 6)), np.zeros((n, 6, nv)), rot)
    frame_rates_kernel(np.ascontiguousarray(data.J.T), np.asarray(v, dtype=float),
                       np.asarray(a, dtype=float), fs.joint_support, fs.col_joint,
                       fs.col_parent, fs.col_inner, fs.joints, fs.support, rot, pos,
                       np.asarray(world, dtype=bool), *out[:6])
    return out


class ClosureRates(NamedTuple):
    """The closures' rows of :class:`FrameRates`: ``C`` and its partials (``jac`` is
    ``J_c`` along the closures), ``J_c v`` and its partial in ``q``; ``anchors``: the
    anchors' own (anchor 1 then anchor 2 of each closure, closure order)."""

    acc_q: np.ndarray
    acc_v: np.ndarray
    jac: np.ndarray
    vel_q: np.ndarray
    anchors: FrameRates


def closure_rates(clm: ClosedLoopModel, data: pin.Data, v: np.ndarray,
                  a: np.ndarray, q: np.ndarray | None = None) -> ClosureRates:
    """:class:`ClosureRates` (n_rows rows) from the frame derivatives in ``data``: a point
    closure's rows are the world linear rows of anchor 1 minus anchor 2, a weld's the
    LOCAL spatial rows; the joint couplings' rows (:mod:`~hexapod_pin.core.couplings`)
    after them, from ``q`` (the configuration of ``data``).

    Raises:
        InputError: a model with joint couplings and no ``q``.
    """
    couplings = clm.coupling_rows
    if couplings is not None and q is None:
        raise InputError("q", q, f"{clm.name} has joint couplings: their rows need q")
    lay = layout_of(clm)
    rates = frame_rates(clm.model, data, lay.frame_set, v, a, lay.world)
    out = list(closure_rows_kernel(rates.acc_q, rates.acc_v, rates.jac, rates.vel_q,
                                   lay.rows1, lay.rows2))
    for k, c in lay.welds:
        _weld_rows(rates, 2 * k, relative_action(data, c.frame1, c.frame2),
                   [arr[c.rows] for arr in out])
    if couplings is not None and q is not None:
        # C = J a + gamma: d/dq (J a) + d gamma/dq, d gamma/dv; J v: d(J v)/dq
        out[0] = np.vstack([out[0], couplings.jacobian_velocity_dq(q, a)
                            + couplings.drift_dq(q, v)])
        out[1] = np.vstack([out[1], couplings.drift_dv(q, v)])
        out[2] = np.vstack([out[2], couplings.jacobian(q)])
        out[3] = np.vstack([out[3], couplings.jacobian_velocity_dq(q, v)])
    return ClosureRates(out[0], out[1], out[2], out[3], rates)


def motion_cross(m: np.ndarray) -> np.ndarray:
    """``ad(m)`` (..., 6, 6) of spatial motions ``m = (v, w)`` (..., 6): ``m x y = (w x y_v
    + v x y_w, w x y_w)``."""
    out = np.zeros(m.shape[:-1] + (6, 6))
    out[..., :3, :3] = out[..., 3:, 3:] = skew(m[..., 3:])
    out[..., :3, 3:] = skew(m[..., :3])
    return out


def force_cross(f: np.ndarray) -> np.ndarray:
    """``B(f)`` (6, 6) with ``xi x* f = B(f) xi`` for a spatial force ``f = (force,
    moment)`` and motions ``xi = (v, w)``: ``(w x force, v x force + w x moment)``."""
    out = np.zeros((6, 6))
    cross = skew(-f.reshape(2, 3))
    out[:3, 3:] = out[3:, :3] = cross[0]
    out[3:, 3:] = cross[1]
    return out


def relative_action(data: pin.Data, frame1: int, frame2: int) -> np.ndarray:
    """``Ad(M12)`` (6, 6), ``M12 = oM1^-1 oM2``: frame-2 motions in frame-1 axes."""
    return np.asarray(data.oMf[frame1].actInv(data.oMf[frame2]).action)


def _weld_rows(rates: FrameRates, i1: int, ad12: np.ndarray, out: list[np.ndarray]) -> None:
    """A weld's rows of :class:`ClosureRates` in every direction (in place into ``out``:
    the views ``acc_q, acc_v, jac, vel_q`` of its rows): the relative acceleration
    ``C = a1 - Ad a2 + v1 x (Ad v2)`` and ``J v = v1 - Ad v2`` (LOCAL, ``Ad = Ad(M12)``,
    Pinocchio's 6-D constraint; the library's rows are ``Jlog6(M21)`` times these), with
    ``d(Ad x) = (Ad x) x J_rel dq``, ``J_rel = J1 - Ad J2``."""
    i2 = i1 + 1
    v1, a2, v2 = rates.vel[i1], rates.acc[i2], rates.vel[i2]
    j1, j2 = rates.jac[i1], rates.jac[i2]
    jrel = j1 - ad12 @ j2
    ad_v1, ad_v2, ad_a2 = motion_cross(np.stack([v1, ad12 @ v2, ad12 @ a2]))
    acc_q, acc_v, jac, vel_q = out
    acc_q[:] = (rates.acc_q[i1] - ad12 @ rates.acc_q[i2] - ad_a2 @ jrel
                - ad_v2 @ rates.vel_q[i1] + ad_v1 @ (ad12 @ rates.vel_q[i2] + ad_v2 @ jrel))
    acc_v[:] = rates.acc_v[i1] - ad12 @ rates.acc_v[i2] - ad_v2 @ j1 + ad_v1 @ ad12 @ j2
    jac[:] = jrel
    vel_q[:] = rates.vel_q[i1] - ad12 @ rates.vel_q[i2] - ad_v2 @ jrel


class Layout:
    """Where the closures' rows sit among their anchors' :class:`FrameRates` and how their
    forces reach the joints (built once per model and thread, :func:`layout_of`).

    Attributes:
        data: this module's ``pin.Data`` of the model.
        anchors: the anchor frames, anchor 1 then anchor 2 of each closure.
        frame_set: their :class:`FrameSet`.
        world: (2 n,) whether each anchor takes world rows (a point closure's).
        rows1: (n_rows,) the rows of anchor 1 in the flattened (2 n x 6) rows.
        rows2: (n_rows,) the rows of anchor 2 there.
        joints: (2 n,) each anchor's parent joint.
        placement_rot: (2 n, 3, 3) each anchor's rotation in its joint.
        placement_pos: (2 n, 3) each anchor's position in its joint.
        points: (n,) whether each closure is a point.
        welds: ``(index, ClosureFrames)`` of each weld.
    """

    def __init__(self, clm: ClosedLoopModel) -> None:
        model = clm.model
        self.data = model.createData()
        cf = clm.closure_frames
        self.anchors = [f for c in cf for f in (c.frame1, c.frame2)]
        self.points = np.array([c.is_point for c in cf], dtype=bool)
        #: (index, ClosureFrames) of the welds
        self.welds = [(k, c) for k, c in enumerate(cf) if not c.is_point]
        self.world = np.repeat(self.points, 2)
        rows1, rows2 = [], []
        for k, c in enumerate(cf):
            width = 3 if c.is_point else 6
            rows1 += [12 * k + i for i in range(width)]
            rows2 += [12 * k + 6 + i for i in range(width)]
        self.rows1, self.rows2 = np.array(rows1, dtype=int), np.array(rows2, dtype=int)
        self.frame_set = FrameSet(model, self.anchors)
        #: the :class:`FrameSet` of other frame lists (:func:`frame_set`)
        self.frame_sets: dict[tuple[int, ...], FrameSet] = {}
        self.joints = self.frame_set.joints
        self.placement_rot = self.frame_set.placement_rot
        self.placement_pos = self.frame_set.placement_pos
        #: (nv, nv) True on and above the diagonal (Pinocchio fills that triangle of M)
        self.upper = np.triu(np.ones((model.nv, model.nv), dtype=bool))
        self.fext = pin.StdVec_Force()
        for _ in range(model.njoints):
            self.fext.append(pin.Force.Zero())
        #: writable views (6,) of each joint's force in ``fext`` (never resized)
        self._fext_views = [self.fext[j].vector for j in range(model.njoints)]
        self._touched = [int(j) for j in np.unique(self.joints)]
        #: the point closures' multiplier rows, anchor-1 and anchor-2 indices
        self.point_rows = np.array([r for c in cf if c.is_point
                                    for r in range(c.rows.start, c.rows.stop)], dtype=int)
        self.point_anchors = np.flatnonzero(self.world)
        #: (6 touched joints, 6 anchors): an anchor's spatial force (its axes) to its
        #: joint's (``placement.act``: ``(R f, R m + p x R f)``), summed per joint
        to_joints = np.zeros((len(self._touched), 6, len(self.anchors), 6))
        for k, joint in enumerate(self.joints):
            rot, pos = self.placement_rot[k], self.placement_pos[k]
            block = to_joints[self._touched.index(int(joint)), :, k]
            block[:3, :3] = block[3:, 3:] = rot
            block[3:, :3] = skew(pos) @ rot
        self._to_joints = to_joints.reshape(6 * len(self._touched), 6 * len(self.anchors))
        self._extra: list[int] = []        # the joints only the last call's wrenches set
        #: whether the last linearised state had redundant closure rows (the next one
        #: goes straight to the exact "kkt" forward dynamics)
        self.redundant = False

    def joint_forces(self, clm: ClosedLoopModel, multipliers: np.ndarray, data: pin.Data,
                     wrenches: Sequence[tuple[int, np.ndarray]] = (),
                     rot: np.ndarray | None = None) -> pin.StdVec_Force:
        """The closure forces and the frame ``wrenches`` as Pinocchio's external forces
        (joint LOCAL frames, one per joint): a point closure's ``lambda`` (world axes) at
        anchor 1 and ``-lambda`` at anchor 2; a weld's spatial force ``lambda`` (anchor-1
        axes, paired with its rows ``J_rel`` of :func:`_weld_rows`) on anchor 1 and
        ``-Ad(M12)^T lambda`` (anchor-2 axes; ``-lambda`` on the closures) on anchor 2;
        each ``(frame, (f, m))``: force and moment (world axes, moment about the frame
        origin) on that frame. ``data``: frame placements; ``rot``: the anchors' world
        rotations (2 n, 3, 3) when known (else read from ``data``)."""
        local = np.zeros((len(self.anchors), 6))        # in each anchor's axes
        if rot is None and self.point_anchors.size:
            rot = np.array([data.oMf[f].rotation for f in self.anchors])
        for k, c in self.welds:   # mu on anchor 1, -Ad(M12)^T mu on anchor 2 (J_rel^T mu)
            lam = multipliers[c.rows]
            local[2 * k] = lam
            local[2 * k + 1] = -(relative_action(data, c.frame1, c.frame2).T @ lam)
        per_touched = anchor_forces_kernel(np.zeros((0, 3, 3)) if rot is None else rot,
                                           np.asarray(multipliers, dtype=float),
                                           self.point_rows, self.point_anchors, local,
                                           self._to_joints)
        views = self._fext_views
        for j, wrench in zip(self._touched, per_touched):
            views[j][:] = wrench
        extra: dict[int, np.ndarray] = {}
        for frame, wrench in wrenches:
            placement = clm.model.frames[frame]
            frame_rot = data.oMf[frame].rotation
            joint = placement.parentJoint
            local_force = pin.Force(frame_rot.T @ wrench[:3], frame_rot.T @ wrench[3:])
            base = extra.get(joint)
            if base is None:
                base = per_touched[self._touched.index(joint)] if joint in self._touched \
                    else np.zeros(6)
            extra[joint] = base + placement.placement.act(local_force).vector
        for j in set(self._extra) - set(extra) - set(self._touched):
            views[j][:] = 0.0                  # last call's wrench joints cleared
        for j, wrench in extra.items():
            views[j][:] = wrench
        self._extra = list(extra)
        return self.fext


def layout_of(clm: ClosedLoopModel) -> Layout:
    """The :class:`Layout` of ``clm`` for the calling thread (kept in ``clm.workspaces``)."""
    key = ("dynamics_derivatives", threading.get_ident())
    lay = clm.workspaces.get(key)
    if lay is None:
        lay = clm.workspaces[key] = Layout(clm)
    return lay


def curved_joints(model: pin.Model) -> list[tuple[int, int]]:
    """``(idx_v, nv)`` of the joints whose configuration space is curved (a free, ball or
    planar joint: ``nq != nv`` and more than one velocity coordinate)."""
    return [(j.idx_v, j.nv) for j in model.joints[1:] if j.nv > 1 and j.nq != j.nv]


def spring_jacobian(model: pin.Model, effects: JointEffects, q: np.ndarray) -> np.ndarray:
    """``d tau_s / dq`` (nv, nv) of the springs' force ``tau_s`` of
    :func:`~hexapod_pin.core.effects.passive_forces` (at zero velocity), tangent columns.

    On vector-space joints it is ``-stiffness`` (diagonal). On a curved joint (free, ball,
    planar) the force is the energy gradient ``-D^T K dq`` (``D = dDifference``), whose
    derivative needs the second derivative of ``pin.difference`` (not in Pinocchio): that
    joint's block comes from Richardson-extrapolated central differences of the force on
    its own coordinates (steps 2e-2, 1e-2, 5e-3 (m, rad): ``pin.dDifference`` of a free or
    ball joint is noisy, ~1e-6 relative, for relative rotations of 1e-4 to 1e-3 rad, which
    smaller steps would sample), the two extrapolations agreeing to 1e-8 relative.

    Raises:
        SolverError: the two extrapolations of a curved joint's block disagree.
    """
    out = np.diag(-np.asarray(effects.stiffness, dtype=float))
    zero = np.zeros(model.nv)
    for start, width in curved_joints(model):
        cols = slice(start, start + width)
        if not effects.stiffness[cols].any():
            continue
        block = np.empty((width, width))
        for k in range(width):
            step = np.zeros(model.nv)
            step[start + k] = 1.0
            diffs = []
            for h in (2e-2, 1e-2, 5e-3):
                plus = passive_forces(model, effects, pin.integrate(model, q, h * step), zero)
                minus = passive_forces(model, effects, pin.integrate(model, q, -h * step), zero)
                diffs.append((plus[cols] - minus[cols]) / (2.0 * h))
            coarse, fine = (4.0 * diffs[1] - diffs[0]) / 3.0, (4.0 * diffs[2] - diffs[1]) / 3.0
            if max_abs(fine - coarse) > 1e-8 * max(1.0, max_abs(fine)):
                raise SolverError("spring_jacobian", "unverified",
                                  f"curvature block of coordinates {start}..{start + width}: "
                                  f"extrapolations differ by {max_abs(fine - coarse):.3e}")
            block[:, k] = fine
        out[cols, cols] = block
    return out


def point_force_turning(clm: ClosedLoopModel, multipliers: np.ndarray,
                        anchor_jac: np.ndarray) -> np.ndarray | float:
    """``d(J_c^T lambda)/dq`` beyond the forces held in the bodies' frames (what the RNEA
    derivatives hold): a point closure's force is held in world axes, so in anchor ``i``'s
    axes it turns, ``d(R^T lambda) = [R^T lambda]_x J_ang dq`` (LOCAL), i.e. ``+-
    J_lin^T [lambda]_x J_ang`` with the anchors' world Jacobians ``anchor_jac`` (2
    n_closures, 6, nv); 0 without point closures (a weld's force is held in anchor-1 =
    anchor-2 axes)."""
    lay = layout_of(clm)
    if not lay.point_rows.size:
        return 0.0
    out = np.zeros((clm.model.nv, clm.model.nv))
    point_turning_kernel(np.ascontiguousarray(anchor_jac, dtype=float),
                         np.asarray(multipliers, dtype=float), lay.point_rows,
                         lay.point_anchors, out)
    return -out


def weld_force_turning(clm: ClosedLoopModel, data: pin.Data, multipliers: np.ndarray,
                       anchor_jac: np.ndarray) -> np.ndarray | float:
    """The welds' part of :func:`point_force_turning`: the force ``-Ad(M12)^T mu`` on
    anchor 2 turns with ``M12``, ``d(Ad^T mu) = Ad^T (J_rel dq x* mu)``, i.e. ``-J2^T
    Ad^T B(mu) J_rel`` (:func:`force_cross`; LOCAL anchor Jacobians ``anchor_jac``, zero
    on the closures' tangent directions). ``data``: frame placements."""
    out: np.ndarray | float = 0.0
    for k, c in layout_of(clm).welds:
        ad12 = relative_action(data, c.frame1, c.frame2)
        j1, j2 = anchor_jac[2 * k], anchor_jac[2 * k + 1]
        out = out - j2.T @ ad12.T @ force_cross(multipliers[c.rows]) @ (j1 - ad12 @ j2)
    return out


def weld_multipliers(clm: ClosedLoopModel, data: pin.Data,
                     multipliers: np.ndarray) -> np.ndarray:
    """The multipliers of the rows ``J_rel`` of :func:`_weld_rows`: a weld's ``mu =
    Jlog6(M21)^T lambda`` for the library's ``lambda`` (of the ``Jlog6(M21) J_rel`` rows;
    equal on the closures), the points' unchanged. ``data``: frame placements."""
    lay = layout_of(clm)
    if not lay.welds:
        return multipliers
    out = np.array(multipliers, dtype=float)
    for _, c in lay.welds:
        m21 = data.oMf[c.frame2].actInv(data.oMf[c.frame1])
        out[c.rows] = pin.Jlog6(m21).T @ out[c.rows]
    return out


def closure_force_derivative(clm: ClosedLoopModel, data: pin.Data, q: np.ndarray,
                             multipliers: np.ndarray) -> np.ndarray:
    """``d(J_c^T y)/dq`` (nv, nv) at ``q`` for closure forces ``y`` (n_rows,) held (a
    point's in world axes, as the multipliers): the generalised force of the closures
    differentiated along ``pin.integrate``, from ``pin.computeRNEADerivatives`` at rest
    with ``y`` as external forces (less the gravity's
    ``pin.computeGeneralizedGravityDerivatives``), :func:`point_force_turning` and
    :func:`weld_force_turning` (a weld's ``y`` pairs with its rows ``J_rel``). Overwrites
    ``data``."""
    model = clm.model
    zero = np.zeros(model.nv)
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    lay = layout_of(clm)
    lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    anchor_jac = np.array([pin.getFrameJacobian(model, data, f, lwa if world else _LOCAL)
                           for f, world in zip(lay.anchors, lay.world)])
    turning = point_force_turning(clm, multipliers, anchor_jac) + \
        weld_force_turning(clm, data, multipliers, anchor_jac)
    fext = lay.joint_forces(clm, multipliers, data)
    with_forces = np.array(pin.computeRNEADerivatives(model, data, q, zero, zero, fext)[0])
    gravity = np.array(pin.computeGeneralizedGravityDerivatives(model, data, q))
    if clm.coupling_rows is not None:     # the joint couplings' rows (core.couplings)
        turning = turning + clm.coupling_rows.transpose_force_dq(
            q, multipliers[clm.n_closure_rows:])
    return gravity - with_forces + turning


def _matrix(x: npt.ArrayLike) -> np.ndarray:
    """``x`` as a C-contiguous float (n, k) matrix (a vector (n,) as one column)."""
    x = np.asarray(x, dtype=float)
    return np.ascontiguousarray(x if x.ndim == 2 else x.reshape(x.shape[0], -1))


class KKTLinearization:
    """The linearised KKT system of one forward-dynamics solution (module docstring).

    Attributes:
        q: (nq,) the configuration.
        v: (nv,) the velocity.
        a: (nv,) the acceleration solved there.
        multipliers: (n_rows,) the closure multipliers solved there.
        mass: ``M`` (nv, nv) with the armature.
        jac: ``J_c`` (n_rows, nv).
        basis: an orthonormal basis (nv, m) of ``null(J_c)`` (SVD; Euclidean in the mixed
            m / rad coordinates of ``v``).
        rank: the rank of ``J_c`` (:data:`~hexapod_pin.core.closed_loop.RANK_RTOL`).
        e_q: (nv, nv) partial of ``E`` in ``q`` (without ``S^T u + tau_ext``; the frame
            ``wrenches`` held in world axes).
        e_v: (nv, nv) partial of ``E`` in ``v``.
        c_q: (n_rows, nv) partial of ``C`` in ``q``.
        c_v: (n_rows, nv) partial of ``C`` in ``v``.
        jv_q: (n_rows, nv) partial of ``J_c v`` in ``q``.
        frames: :class:`FrameRates` (world rows) of the extra frames asked for (None:
            none).
    """

    def __init__(self, clm: ClosedLoopModel, data: pin.Data, q: np.ndarray, v: np.ndarray,
                 a: np.ndarray, multipliers: np.ndarray, frames: Sequence[int],
                 wrenches: Sequence[tuple[int, np.ndarray]] = ()) -> None:
        model = clm.model
        self.clm, self.model, self.data = clm, model, data
        self.q, self.v, self.a, self.multipliers = q, v, a, multipliers
        pin.computeJointJacobians(model, data, q)     # J and oMi: all frame_rates reads
        pin.updateFramePlacements(model, data)
        rates = closure_rates(clm, data, v, a, q)
        self.c_q, self.c_v, self.jac, self.jv_q = rates[:4]
        couplings = clm.coupling_rows
        #: world :class:`FrameRates` of the extra frames (in the order asked)
        self.frames = frame_rates(model, data, frame_set(clm, frames), v, a,
                                  np.ones(len(frames), dtype=bool)) if len(frames) else None
        # E: rnea with the closure forces as external forces, their turning, the effects
        lay = layout_of(clm)
        forces = weld_multipliers(clm, data, multipliers)
        fext = lay.joint_forces(clm, forces, data, wrenches, rates.anchors.rot)
        dtau_dq, dtau_dv, mass = pin.computeRNEADerivatives(model, data, q, v, a, fext)
        nv, eff = model.nv, clm.effects
        self.mass, self.e_q, self.e_v = np.empty((nv, nv)), np.empty((nv, nv)), np.empty((nv, nv))
        # M, E_q, E_v with the point forces' turning and damping, then the factors: compiled
        status, basis, pinv, gain, norm_m, norm_j = linearize_kernel(
            mass, dtau_dq, dtau_dv, rates.anchors.jac, forces, lay.point_rows,
            lay.point_anchors, eff.damping, self.jac, FULL_RANK_RTOL, self.mass, self.e_q,
            self.e_v)
        if lay.welds or wrenches:
            self.e_q -= weld_force_turning(clm, data, forces, rates.anchors.jac) \
                + self._wrench_turning(wrenches)
        if couplings is not None:   # -d(J^T lambda)/dq of the couplings' forces
            self.e_q -= couplings.transpose_force_dq(q, multipliers[clm.n_closure_rows:])
        if eff.stiffness.any():
            self.e_q -= spring_jacobian(model, eff, q)
        self._factor(status, basis, pinv, gain, (norm_m, norm_j))

    def _wrench_turning(self, wrenches: Sequence[tuple[int, np.ndarray]]) -> np.ndarray | float:
        """The turning of world-fixed frame wrenches ``(f, m)`` (as :meth:`_turning`):
        ``J_lin^T [f]_x J_ang + J_ang^T [m]_x J_ang`` (world frame Jacobians)."""
        out: np.ndarray | float = 0.0
        lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        for frame, wrench in wrenches:
            jac = pin.getFrameJacobian(self.model, self.data, frame, lwa)
            out = out + jac[:3].T @ skew(wrench[:3]) @ jac[3:] \
                + jac[3:].T @ skew(wrench[3:]) @ jac[3:]
        return out

    def _factor(self, status: int, basis: np.ndarray, pinv: np.ndarray, gain: np.ndarray,
                norms: tuple[float, float]) -> None:
        """The null-space basis, ``J_c^+`` and the inverse Cholesky factor of ``N^T M N``:
        those of :func:`~hexapod_pin.core.derivative_kernels.linearize_kernel` (the
        compiled pivoted QR of ``J_c^T``) when its rows are independent (every pivot above
        FULL_RANK_RTOL times the first), else an SVD (rank to
        :data:`~hexapod_pin.core.closed_loop.RANK_RTOL`) and
        :func:`~hexapod_pin.core.derivative_kernels.reduced_gain_kernel`."""
        nv, jac = self.model.nv, self.jac
        n_rows = jac.shape[0]
        self._norms = norms                                  # of the residual checks
        #: the orthonormal basis (n_rows, rank) of range(J_c) (its complement: the
        #: multipliers that do no work); empty when the rows are independent
        self._left = np.zeros((n_rows, 0))
        if status == NOT_FINITE:
            raise SolverError("closure row basis", "non-finite", "NaN or inf in the Jacobian")
        if status == DEPENDENT_ROWS:
            if not n_rows:
                rank, basis, pinv = 0, np.eye(nv), np.zeros((nv, 0))
            else:
                u_mat, sv, vt = np.linalg.svd(jac)
                tol = max(RANK_RTOL * sv[0], max(jac.shape) * np.finfo(float).eps)
                rank = int(np.sum(sv > tol))
                self._left = u_mat[:, :rank]
                pinv = (vt[:rank].T / sv[:rank]) @ u_mat[:, :rank].T
                basis = np.ascontiguousarray(vt[rank:].T)
            gain = np.empty(basis.shape)
            status = reduced_gain_kernel(basis, self.mass, gain)
        else:
            rank = n_rows
        self.rank, self.basis, self._pinv = rank, basis, pinv
        #: ``G = N L^-T`` (nv, m), ``N^T M N = L L^T``: ``G G^T = N (N^T M N)^-1 N^T``
        self._gain = gain
        if status == NOT_POSITIVE:
            raise SingularityError("mass matrix on the closures' null space (N^T M N not "
                                   "positive definite: massless motion)", 0.0, None,
                                   "Cholesky pivot")

    # -- solves ----------------------------------------------------------------------------
    def pinv(self, rhs: np.ndarray) -> np.ndarray:
        """``J_c^+ rhs`` (nv, ...): the least-norm solution of ``J_c x = rhs``."""
        return self._pinv @ rhs

    def _pinv_t(self, rhs: np.ndarray) -> np.ndarray:
        """``J_c^+T rhs`` (n_rows, k): the least-norm ``y`` with ``J_c^T y = rhs``."""
        return self._pinv.T @ rhs

    def solve(self, rhs_e: np.ndarray, rhs_c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(da, dlambda)`` (nv, k), (n_rows, k) with ``M da - J_c^T dlambda = rhs_e``,
        ``J_c da = rhs_c`` (``dlambda`` least-norm), verified.

        Raises:
            SolverError: a residual above :data:`DERIVATIVE_SOLVE_RTOL` (relative), e.g. a
                ``rhs_c`` outside the range of ``J_c`` (a direction off the closures).
        """
        da, dlam, eom, con = kkt_solve_kernel(self.mass, self.jac, self._pinv, self._gain,
                                              *self._norms, _matrix(rhs_e), _matrix(rhs_c))
        self._check(eom, con)
        return (da, dlam) if np.ndim(rhs_e) == 2 else (da[:, 0], dlam[:, 0])

    @staticmethod
    def _check(eom: float, con: float) -> None:
        """Raises SolverError when a relative residual of a solve is above
        :data:`DERIVATIVE_SOLVE_RTOL` (or NaN)."""
        if not (eom <= DERIVATIVE_SOLVE_RTOL and con <= DERIVATIVE_SOLVE_RTOL):
            raise SolverError("forward-dynamics derivatives", "unverified",
                              f"linearised equation of motion residual {eom:.3e}, closure "
                              f"residual {con:.3e} (relative, tolerance "
                              f"{DERIVATIVE_SOLVE_RTOL:g})")

    def transport(self, dq: np.ndarray) -> np.ndarray:
        """``dv`` (nv, k) carrying ``v`` along ``dq`` (nv, k) by its Euclidean projection
        onto the closures: ``-J_c^+ (d(J_c v)/dq) dq``."""
        return -self.pinv(self.jv_q @ dq)

    def along(self, dq: np.ndarray, dv: np.ndarray, force: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
        """``(da, dlambda)`` (nv, k), (n_rows, k) along state directions ``(dq, dv)`` (each
        (nv, k)) tangent to the closures (``J_c dq = 0``, ``J_c dv = -d(J_c v)/dq dq``),
        with the generalised forces ``force`` (nv, k) added (default none).

        With redundant rows the minimum-norm multipliers also turn with the range of
        ``J_c``: ``dlambda`` gets ``P dJ_c[dq] J_c^+ lambda`` (``P`` the projector on
        ``null(J_c^T)``)."""
        vector = np.ndim(dq) == 1
        dq, dv = _matrix(dq), _matrix(dv)
        force = np.zeros(dq.shape) if force is None else _matrix(force)
        da, dlam, eom, con = kkt_along_kernel(self.e_q, self.e_v, self.c_q, self.c_v, self.mass,
                                              self.jac, self._pinv, self._gain, *self._norms,
                                              dq, dv, force)
        self._check(eom, con)
        if self.rank < self.clm.n_rows and dq.any():
            dlam += self._range_turn(dq)
        return (da[:, 0], dlam[:, 0]) if vector else (da, dlam)

    def _range_turn(self, dq: np.ndarray) -> np.ndarray:
        """``P dJ_c[dq] J_c^+ lambda`` (n_rows, k): the closure rates at the velocity ``w =
        J_c^+ lambda`` (:func:`frame_rates` reads only ``q`` from the data)."""
        w = self.pinv(self.multipliers)
        turned = closure_rates(self.clm, self.data, w, np.zeros(self.model.nv),
                               self.q).vel_q @ dq
        return turned - self._left @ (self._left.T @ turned)


@dataclass(frozen=True)
class TreeDynamicsDerivatives:
    """Derivatives of :func:`~hexapod_pin.core.dynamics.forward_dynamics_tree` at one state,
    from :func:`forward_dynamics_derivatives_tree` (module docstring for the directions).

    Attributes:
        a: the tree acceleration (nv,).
        multipliers: the closure multipliers (n_rows,) (minimum-norm when redundant).
        tangent_basis: ``N`` (nv, m), the position directions: orthonormal columns spanning
            ``null(J_c)`` (or the ``basis`` given).
        d_q: ``da / dz`` (nv, m) along ``q(z) = integrate(q, N z)`` with ``v`` carried by
            its Euclidean projection onto the closures.
        d_v: ``da / dv`` (nv, nv) of ``a(q, Pi v)``, ``Pi`` the Euclidean projector on
            ``null(J_c)`` (zero on motions that break the closures).
        d_actuator_forces: ``da / du`` (nv, n_act).
        d_tau_ext: ``da / dtau_ext`` (nv, nv).
        multipliers_d_q: ``dlambda / dz`` (n_rows, m).
        multipliers_d_v: ``dlambda / dv`` (n_rows, nv).
        multipliers_d_actuator_forces: ``dlambda / du`` (n_rows, n_act).
        multipliers_d_tau_ext: ``dlambda / dtau_ext`` (n_rows, nv).
    """

    a: np.ndarray
    multipliers: np.ndarray
    tangent_basis: np.ndarray
    d_q: np.ndarray
    d_v: np.ndarray
    d_actuator_forces: np.ndarray
    d_tau_ext: np.ndarray
    multipliers_d_q: np.ndarray
    multipliers_d_v: np.ndarray
    multipliers_d_actuator_forces: np.ndarray
    multipliers_d_tau_ext: np.ndarray


def linearize_tree(clm: ClosedLoopModel, q: npt.ArrayLike, v: npt.ArrayLike,
                   actuator_forces: npt.ArrayLike, tau_ext: npt.ArrayLike | None = None,
                   frames: Sequence[int] = (),
                   wrenches: Sequence[tuple[int, np.ndarray]] = ()) -> KKTLinearization:
    """The forward-dynamics solution at ``(q, v)`` (the verified default route of
    :func:`~hexapod_pin.core.dynamics.forward_dynamics_tree`, Pinocchio's, checked on its
    equations; with redundant closure rows its "kkt" route, exact with minimum-norm
    multipliers, where Pinocchio's proximal solve is only converged to its tolerance) and
    its
    :class:`KKTLinearization`, with the world :class:`FrameRates` of ``frames`` (ids).

    ``wrenches``: ``(frame id, (f, m))`` pairs, each a force and moment (6,) (N, N m; world
    axes, moment about the frame origin) on that frame, applied with ``tau_ext`` (as the
    generalised force ``J_frame^T (f, m)``, ``LOCAL_WORLD_ALIGNED`` Jacobian) and held in
    world axes by the partials.

    Raises:
        InputError: bad shapes, NaN / inf, a state off the closures (as
            ``forward_dynamics_tree``), a coordinate with Coulomb friction at rest (the
            dynamics is not differentiable there: stick / slip), an unknown frame id.
        SolverError: the forward dynamics misses its equations.
        SingularityError: ``N^T M N`` not positive definite.
    """
    q = clm.check_q(q)
    v = clm.check_v(v)
    eff = clm.effects
    if eff.has_coulomb:
        rest = at_rest(eff, v)
        if rest.size:
            raise InputError("v", v, f"coordinates {rest.tolist()} with Coulomb friction are "
                             f"at rest (|v| <= {eff.velocity_threshold:g}): the forward "
                             "dynamics is not differentiable there (stick / slip)")
    for frame in list(frames) + [f for f, _ in wrenches]:
        if not (isinstance(frame, (int, np.integer)) and 0 <= frame < clm.model.nframes):
            raise InputError("frames", frame, f"not a frame id of {clm.name}")
    lay = layout_of(clm)
    data = lay.data
    if wrenches:
        pin.computeJointJacobians(clm.model, data, q)
        pin.updateFramePlacements(clm.model, data)
        lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        total = np.zeros(clm.nv) if tau_ext is None else np.array(clm.check_v(tau_ext,
                                                                             "tau_ext"))
        for frame, wrench in wrenches:
            total += pin.getFrameJacobian(clm.model, data, frame, lwa).T @ wrench
        tau_ext = total
    res = forward_dynamics_tree(clm, q, v, actuator_forces, tau_ext,
                                method="kkt" if lay.redundant else "pinocchio")
    if res.rank < clm.n_rows and res.method != "kkt":   # redundant: the exact solve
        res = forward_dynamics_tree(clm, q, v, actuator_forces, tau_ext, method="kkt")
    lay.redundant = res.rank < clm.n_rows
    return KKTLinearization(clm, data, q, v, np.array(res.a), np.array(res.multipliers),
                            frames, wrenches)


def forward_dynamics_derivatives_tree(clm: ClosedLoopModel, q: npt.ArrayLike, v: npt.ArrayLike,
                                      actuator_forces: npt.ArrayLike,
                                      tau_ext: npt.ArrayLike | None = None,
                                      basis: npt.ArrayLike | None = None
                                      ) -> TreeDynamicsDerivatives:
    """Analytic derivatives of the closed-loop forward dynamics on the tree.

    Args:
        clm: the closed-loop model (its joint effects included: armature, damping,
            springs, sliding Coulomb friction).
        q: configuration (nq,) on the closures (as
            :func:`~hexapod_pin.core.dynamics.forward_dynamics_tree`).
        v: velocity (nv,) keeping the closures (``J_c v = 0``; Pinocchio conventions).
        actuator_forces: ``u`` (n_act,) (N, N m).
        tau_ext: generalised external force (nv,) (N, N m); default zero.
        basis: the position directions (nv, k), columns in ``null(J_c)`` (checked to 1e-9
            relative); default an orthonormal basis of it.

    Returns:
        :class:`TreeDynamicsDerivatives` (units: ``a`` in m/s^2 or rad/s^2 per unit of
        each argument).

    Raises:
        InputError: bad shapes, NaN / inf, a state off the closures, a ``basis`` off
            ``null(J_c)``, a coordinate with Coulomb friction at rest (non-smooth).
        SolverError: a solve misses its equations (verified).
        SingularityError: ``N^T M N`` not positive definite.
    """
    lin = linearize_tree(clm, q, v, actuator_forces, tau_ext)
    nv = clm.nv
    if basis is None:
        dirs = lin.basis
    else:
        if np.ndim(basis) != 2:
            raise InputError("basis", basis, f"expected an (nv = {nv}, k) array")
        dirs = as_array(basis, (nv, int(np.shape(basis)[1])), "basis")
        miss = max_abs(lin.jac @ dirs)
        if not miss <= 1e-9 * max(1.0, max_abs(lin.jac) * max_abs(dirs)):
            raise InputError("basis", basis, f"columns off null(J_c): |J_c basis| = "
                             f"{miss:.3e}")
    # one verified solve for every column: along (dirs, transported v), along (0, N), tau
    k, n = dirs.shape[1], lin.basis
    m = n.shape[1]
    dq_all = np.zeros((nv, k + m + nv))
    dq_all[:, :k] = dirs
    dv_all = np.zeros_like(dq_all)
    dv_all[:, :k], dv_all[:, k:k + m] = lin.transport(dirs), n
    force = np.zeros_like(dq_all)
    force[:, k + m:] = np.eye(nv)
    da, dl = lin.along(dq_all, dv_all, force)
    act = clm.actuated_v
    da_t, dl_t = da[:, k + m:], dl[:, k + m:]
    return TreeDynamicsDerivatives(lin.a, lin.multipliers, dirs, da[:, :k],
                                   da[:, k:k + m] @ n.T, da_t[:, act], da_t, dl[:, :k],
                                   dl[:, k:k + m] @ n.T, dl_t[:, act], dl_t)

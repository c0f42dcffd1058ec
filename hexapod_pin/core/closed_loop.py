"""Generic closed-loop mechanism: a Pinocchio tree plus holonomic loop closures.

:class:`ClosedLoopModel` is robot-agnostic. It owns the ``pin.Model`` of the tree,
its data, one ``pin.RigidConstraintModel`` per closure (``CONTACT_3D`` for a
point closure, ``CONTACT_6D`` for a weld), and the actuated-joint selection.

Conventions:

* ``q`` is a Pinocchio configuration (``model.nq``), ``v`` a Pinocchio velocity
  (``model.nv``), both in Pinocchio's own conventions (free-flyer velocities in
  the body frame).
* The closure residual stacks, closure after closure, ``p1 - p2`` in world axes
  (m) for a point closure and ``log6(oM2^-1 oM1)`` (m, rad; the twist of anchor 1
  relative to anchor 2 in anchor-1 axes) for a weld.
* The constraint Jacobian ``J_c`` (rows x nv) is the derivative of that residual
  along ``pin.integrate(model, q, dv)``: ``residual(integrate(q, dv)) =
  residual(q) + J_c dv + O(dv^2)``. A velocity ``v`` keeps the closures when
  ``J_c v = 0``; an acceleration ``a`` when ``J_c a + gamma = 0`` with the drift
  ``gamma`` from :meth:`ClosedLoopModel.constraint_drift`.
* Joint couplings (``clm.couplings``, :mod:`~hexapod_pin.core.couplings`: ``q1 = f(q2)``)
  add one row each after the closure rows (residual ``q1 - f(q2)``), in the residual,
  ``J_c``, ``gamma`` and ``n_rows``; ``n_closure_rows`` counts the closure rows alone.

Motion on the closures (velocity and acceleration maps, projections) is computed by
:mod:`~hexapod_pin.core.closure_motion`, frame-target inverse kinematics by
:mod:`~hexapod_pin.core.frame_ik`; the methods here are thin entry points. Freezing
joints (a reduced model) is :func:`hexapod_pin.core.freeze.freeze_joints`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import scipy.linalg

from ..errors import AssemblyError, DescriptionError, InputError
from .assembly import ASSEMBLY_METHODS, RESTART_SPREADS, levenberg_marquardt
from .checks import as_array, count, real_number
from .closure_motion import complete, project
from .closure_terms import ClosureFrames, closure_drift, weld_jacobian
from .constraint_views import ConstraintErrors
from .couplings import CouplingRows, JointCoupling
from .description import WORLD, ClosureSpec, LoopsSpec, build_model, expand_xacro, load_loops
from .effects import JointEffects, resolve_effects
from .frame_ik import FrameIKResult, frame_inverse_kinematics

_EPS = np.finfo(float).eps
#: default number of restarts of :meth:`ClosedLoopModel.assemble` (one per spread of
#: :data:`~hexapod_pin.core.assembly.RESTART_SPREADS`)
ASSEMBLY_RESTARTS = len(RESTART_SPREADS)
#: default relative singular-value threshold of :meth:`ClosedLoopModel.rank`
RANK_RTOL = 1e-10
#: a frame name shared by several frames (a URDF link and joint named alike) means the
#: first of these types
FRAME_TYPE_ORDER = (pin.FrameType.BODY, pin.FrameType.OP_FRAME, pin.FrameType.FIXED_JOINT,
                    pin.FrameType.JOINT, pin.FrameType.SENSOR)


def fixed_coordinates(fixed: Any, nv: int, name: str = "fixed") -> np.ndarray:
    """Velocity coordinates held fixed, as sorted int indices into ``v``, from integer
    indices (a 1-D sequence, each in ``[0, nv)``, no duplicates) or a boolean mask of
    length ``nv``.

    Raises:
        InputError: anything else (floats, text, nested or ragged sequences, booleans mixed
            with integers, a mask of another length, an index out of range or repeated),
            naming the value.
    """
    expected = (f"expected integer indices into v (in [0, {nv}), no duplicates) or a "
                f"boolean mask of length {nv}")
    if isinstance(fixed, (str, bytes)):
        raise InputError(name, fixed, expected)
    try:
        arr = np.asarray(fixed)
    except (TypeError, ValueError):
        raise InputError(name, fixed, f"{expected} (ragged or not numeric)") from None
    if arr.ndim != 1:
        raise InputError(name, fixed, f"{expected}, got an array of shape {arr.shape}")
    if arr.size == 0:
        return np.zeros(0, dtype=int)
    if arr.dtype.kind == "b":
        if arr.shape != (nv,):
            raise InputError(name, fixed, f"a boolean mask must have length {nv}, got "
                             f"{arr.size}")
        return np.flatnonzero(arr)
    if arr.dtype.kind not in "iu" or (not isinstance(fixed, np.ndarray) and any(
            isinstance(x, (bool, np.bool_)) for x in fixed)):
        raise InputError(name, fixed, f"{expected}, got dtype {arr.dtype}" if arr.dtype.kind
                         not in "iu" else f"{expected} (booleans mixed with integers)")
    idx = arr.astype(int)
    if idx.min() < 0 or idx.max() >= nv:
        raise InputError(name, fixed, f"indices must lie in [0, {nv})")
    if np.unique(idx).size != idx.size:
        raise InputError(name, fixed, "repeated indices")
    return np.sort(idx)


@dataclass(frozen=True)
class RankInfo:
    """Rank of the constraint Jacobian at a configuration.

    Attributes:
        rank: numerical rank.
        n_rows: number of constraint rows.
        redundant_rows: indices of rows that depend on the others (a choice:
            the rows left out by a column-pivoted QR of ``J_c^T``).
        independent_rows: the complementary rows, sorted.
        singular_values: singular values of ``J_c``, descending.
        tolerance: the threshold used on the singular values.
    """

    rank: int
    n_rows: int
    redundant_rows: np.ndarray
    independent_rows: np.ndarray
    singular_values: np.ndarray
    tolerance: float


@dataclass(frozen=True)
class AssemblyResult:
    """Result of :meth:`ClosedLoopModel.assemble`.

    Attributes:
        q: the assembled configuration (``model.nq``).
        residual_norm: max-abs closure residual at ``q`` (m / rad).
        iterations: Newton iterations done.
    """

    q: np.ndarray
    residual_norm: float
    iterations: int


class ClosedLoopModel:
    """A kinematic tree with holonomic loop closures and an actuation selection.

    Args:
        model: the Pinocchio tree model (joints in depth-first order). It is
            copied; anchor frames ``<closure>/anchor1`` and ``/anchor2`` are added.
        loops: the parsed loops description.
        name: a label for messages.
        urdf_xml: the URDF text of the tree, kept for drawing (optional).
        effects: the joint and drive effects (:class:`~hexapod_pin.core.effects.JointEffects`
            of this tree); default: read from the tree (``model.armature``,
            ``model.damping`` and ``model.friction`` as the Coulomb friction, as a URDF's
            ``<dynamics damping friction>`` fills them; no springs; unit gears; the
            ``effortLimit`` of the actuated joints, a non-positive one meaning none).

    Raises:
        DescriptionError: a frame or actuated joint that is not in the tree, an
            actuated joint that is not 1-DoF, a closure joining a body to itself,
            or a model failing Pinocchio's consistency check.
    """

    def __init__(self, model: pin.Model, loops: LoopsSpec, name: str = "closed-loop model",
                 urdf_xml: str | None = None, effects: JointEffects | None = None) -> None:
        self.name = name
        #: the loops description the model was built from
        self.loops = loops
        #: per-thread workspaces of other modules, keyed by (kind, thread id) (e.g. the
        #: dynamics workspace of :func:`~hexapod_pin.core.dynamics.dynamics_of`): held by
        #: the model, so that they are collected with it
        self.workspaces: dict[tuple[str, int], Any] = {}
        #: the URDF text the tree was built from, when known (drawing uses its visuals)
        self.urdf_xml = urdf_xml
        #: the tree as given (without the closure anchor frames), for derived models
        self.tree_model = pin.Model(model)
        self.model = pin.Model(model)
        if not self.model.check(self.model.createData()):
            raise DescriptionError(name, "model fails Pinocchio's consistency check "
                                         "(joints must be in depth-first order)")
        self.closures: tuple[ClosureSpec, ...] = tuple(loops.closures)
        self._anchor_frames: list[tuple[int, int]] = []
        self.constraint_models: list[pin.RigidConstraintModel] = []
        for closure in self.closures:
            f1 = self._add_anchor(closure, closure.frame1, closure.offset1, "anchor1")
            f2 = self._add_anchor(closure, closure.frame2, closure.offset2, "anchor2")
            j1 = self.model.frames[f1].parentJoint
            j2 = self.model.frames[f2].parentJoint
            if j1 == j2:
                raise DescriptionError(name, "closure joins two frames of the same body "
                                             f"(joint {self.model.names[j1]!r})", closure.name)
            self._anchor_frames.append((f1, f2))
            ctype = (pin.ContactType.CONTACT_3D if closure.type == "point"
                     else pin.ContactType.CONTACT_6D)
            cm = pin.RigidConstraintModel(ctype, self.model, j1, self.model.frames[f1].placement,
                                          j2, self.model.frames[f2].placement,
                                          pin.ReferenceFrame.LOCAL)
            cm.name = closure.name
            self.constraint_models.append(cm)
        self.data = self.model.createData()
        self.constraint_datas = [cm.createData() for cm in self.constraint_models]
        self.row_slices = []
        start = 0
        for closure in self.closures:
            self.row_slices.append(slice(start, start + closure.n_rows))
            start += closure.n_rows
        #: rows of the loop closures (the first rows of J_c)
        self.n_closure_rows = start
        #: the joint couplings (:mod:`~hexapod_pin.core.couplings`), one row each after the
        #: closure rows
        self.couplings: tuple[JointCoupling, ...] = tuple(loops.couplings)
        #: their rows, evaluated together (None without couplings)
        self.coupling_rows = (CouplingRows(self.model, self.couplings, name)
                              if self.couplings else None)
        self.n_rows = start + len(self.couplings)
        #: one :class:`ClosureFrames` per closure, in the order of the loops file
        self.closure_frames: tuple[ClosureFrames, ...] = tuple(
            ClosureFrames(closure.type == "point", rows, f1, f2, cm.joint1_id, cm.joint2_id)
            for closure, rows, (f1, f2), cm in zip(self.closures, self.row_slices,
                                                   self._anchor_frames, self.constraint_models))
        self._init_kinematics()
        self.actuated_joints: tuple[str, ...] = tuple(loops.actuated)
        self.actuated_v = np.array([self._actuated_index(j) for j in self.actuated_joints],
                                   dtype=int)
        mask = np.ones(self.model.nv, dtype=bool)
        mask[self.actuated_v] = False
        self.passive_v = np.flatnonzero(mask)
        self._effects = self._initial_effects(model) if effects is None else effects
        self._check_effects_shape(self._effects)
        self._write_effects()

    # -- joint and drive effects ---------------------------------------------------
    def _initial_effects(self, model: pin.Model) -> JointEffects:
        """The tree's effects, then the loops file's ``effects:`` section over them."""
        rigid = JointEffects.rigid(self.model, self.n_actuated)
        limit = np.array([model.effortLimit[i] for i in self.actuated_v], dtype=float)
        limit[~(limit > 0)] = np.inf
        tree = rigid.replace(armature=np.array(model.armature, dtype=float),
                             damping=np.array(model.damping, dtype=float),
                             coulomb=np.array(model.friction, dtype=float),
                             effort_limit=limit)
        if self.loops.effects is None:
            return tree
        return self.loops.effects.apply(model, self.actuated_joints, tree)

    def _check_effects_shape(self, effects: JointEffects) -> None:
        if not isinstance(effects, JointEffects):
            raise InputError("effects", effects, "expected a JointEffects")
        sizes = {"armature": self.nv, "damping": self.nv, "coulomb": self.nv,
                 "stiffness": self.nv, "spring_reference": self.nq, "gear": self.n_actuated,
                 "effort_limit": self.n_actuated}
        for field, size in sizes.items():
            if getattr(effects, field).shape != (size,):
                raise InputError("effects", effects, f"{field} has shape "
                                 f"{getattr(effects, field).shape}, this tree needs ({size},)")

    def _write_effects(self) -> None:
        """Pinocchio's fields follow the record (``armature`` enters its algorithms)."""
        for model in (self.model, self.tree_model):
            model.armature[:] = self._effects.armature
            model.damping[:] = self._effects.damping
            model.friction[:] = self._effects.coulomb
        self._armature_seen = np.array(self._effects.armature)

    @property
    def effects(self) -> JointEffects:
        """The joint and drive effects (:class:`~hexapod_pin.core.effects.JointEffects`).

        An armature written into ``model.armature`` by hand is adopted (Pinocchio's
        algorithms already follow it): every route, closed form and batch reads this
        record, so all of them agree."""
        arm = self.model.armature
        if not np.array_equal(arm, self._armature_seen):
            self._effects = self._effects.replace(armature=np.array(arm, dtype=float))
            self.tree_model.armature[:] = arm
            self._armature_seen = np.array(arm)
        return self._effects

    def with_effects(self, effects: JointEffects | None = None, **values: Any
                     ) -> "ClosedLoopModel":
        """A new model of the same tree and closures with other joint and drive effects.

        Args:
            effects: a complete record to start from (default: this model's).
            **values: fields to change, each checked (see
                :func:`~hexapod_pin.core.effects.resolve_effects`: ``armature``,
                ``damping``, ``coulomb``, ``stiffness`` as (nv,) arrays or ``{joint name:
                value}``, ``spring_reference``, ``gear``, ``effort_limit``,
                ``rotor_inertia``, ``velocity_threshold``).

        Returns:
            A new :class:`ClosedLoopModel` (this one is unchanged).

        Raises:
            InputError: a bad field (see ``resolve_effects``) or a record of another tree.
        """
        base = self.effects if effects is None else effects
        self._check_effects_shape(base)
        new = resolve_effects(self.tree_model, self.actuated_joints, base, **values)
        return type(self)(self.tree_model, self.loops, name=self.name, urdf_xml=self.urdf_xml,
                          effects=new)

    @property
    def gravity(self) -> np.ndarray:
        """The gravity vector (3,) in world axes (m/s^2): the linear part of the Pinocchio
        model's ``gravity`` (a copy)."""
        return np.array(self.model.gravity.linear, dtype=float)

    def with_gravity(self, gravity: npt.ArrayLike) -> "ClosedLoopModel":
        """A new model of the same tree, closures and effects under another gravity.

        Args:
            gravity: (3,) the gravitational acceleration in world axes (m/s^2), any
                direction (e.g. ``(0, -9.81, 0)`` for a wall-mounted robot whose tree has z
                along the wall).

        Returns:
            A new :class:`ClosedLoopModel` whose Pinocchio models carry ``gravity`` (every
            tree route reads it from there; this model is unchanged).

        Raises:
            InputError: not 3 finite real numbers.
        """
        g = as_array(gravity, (3,), "gravity")
        tree = pin.Model(self.tree_model)
        tree.gravity = pin.Motion(np.concatenate([g, np.zeros(3)]))
        return type(self)(tree, self.loops, name=self.name, urdf_xml=self.urdf_xml,
                          effects=self.effects)

    # -- construction ---------------------------------------------------------
    @classmethod
    def from_files(cls, urdf_path: str | Path, loops_path: str | Path,
                   xacro_args: dict[str, str] | None = None) -> "ClosedLoopModel":
        """Load a tree (URDF or xacro, expanded in Python) and its loops file."""
        xml = expand_xacro(urdf_path, xacro_args)
        model = build_model(xml, source=str(urdf_path))
        return cls(model, load_loops(loops_path), name=Path(urdf_path).name, urdf_xml=xml)

    def _frame_id(self, frame: str, closure: str) -> int:
        for ftype in FRAME_TYPE_ORDER:
            if self.model.existFrame(frame, ftype):
                return self.model.getFrameId(frame, ftype)
        raise DescriptionError(self.name, f"frame {frame!r} is not in the tree", closure)

    def _add_anchor(self, closure: ClosureSpec, frame: str, offset: pin.SE3, tag: str) -> int:
        if frame == WORLD and not self.model.existFrame(WORLD):
            parent_joint, placement = 0, offset
        else:
            parent = self.model.frames[self._frame_id(frame, closure.name)]
            parent_joint, placement = parent.parentJoint, parent.placement * offset
        return self.model.addFrame(pin.Frame(f"{closure.name}/{tag}", parent_joint, placement,
                                             pin.FrameType.OP_FRAME))

    def _actuated_index(self, joint: str) -> int:
        if not self.model.existJointName(joint):
            raise DescriptionError(self.name, f"actuated joint {joint!r} is not in the tree",
                                   joint)
        jmodel = self.model.joints[self.model.getJointId(joint)]
        if jmodel.nv != 1:
            raise DescriptionError(self.name, f"actuated joint {joint!r} has {jmodel.nv} DoF; "
                                              "only 1-DoF joints can be actuated", joint)
        return jmodel.idx_v

    # -- sizes and indices ------------------------------------------------------
    @property
    def nq(self) -> int:
        """Size of a Pinocchio configuration of the tree."""
        return self.model.nq

    @property
    def nv(self) -> int:
        """Number of velocity DoF of the tree."""
        return self.model.nv

    @property
    def n_actuated(self) -> int:
        """Number of actuated joints."""
        return len(self.actuated_joints)

    def joint_q_index(self, joint: str) -> int:
        """First index of ``joint`` in ``q``."""
        return self.model.joints[self._joint_id(joint)].idx_q

    def joint_v_index(self, joint: str) -> int:
        """First index of ``joint`` in ``v``."""
        return self.model.joints[self._joint_id(joint)].idx_v

    def _joint_id(self, joint: str) -> int:
        if not self.model.existJointName(joint):
            raise InputError("joint", joint, f"no such joint in {self.name}")
        return self.model.getJointId(joint)

    def neutral(self) -> np.ndarray:
        """Pinocchio's neutral configuration of the tree (closures not satisfied)."""
        return pin.neutral(self.model)

    @property
    def reference_configurations(self) -> dict[str, np.ndarray]:
        """The tree's named configurations, name -> (nq,) copies: Pinocchio's
        ``model.referenceConfigurations`` (an SRDF's; an MJCF's ``qpos0``, keyframes and
        ``home``, :mod:`hexapod_pin.loaders.mjcf`); empty when the tree has none."""
        return {entry.key(): np.array(entry.data(), dtype=float)
                for entry in self.model.referenceConfigurations}

    # -- input checks -------------------------------------------------------------
    def check_q(self, q: npt.ArrayLike, name: str = "q") -> np.ndarray:
        """``q`` as a contiguous float64 array of size ``nq``; raises InputError."""
        return as_array(q, (self.model.nq,), name)

    def check_v(self, v: npt.ArrayLike, name: str = "v") -> np.ndarray:
        """``v`` as a contiguous float64 array of size ``nv``; raises InputError."""
        return as_array(v, (self.model.nv,), name)

    def pinocchio_constraints(self) -> tuple[list[Any], list[Any]]:
        """Fresh Pinocchio vectors ``(StdVec_RigidConstraintModel, StdVec_RigidConstraintData)``
        of the closures, for ``pin.initConstraintDynamics`` / ``pin.constraintDynamics``
        (each caller keeps its own: the data vectors hold per-call results)."""
        models = pin.StdVec_RigidConstraintModel()
        for cm in self.constraint_models:
            models.append(cm)
        datas = pin.StdVec_RigidConstraintData()
        for cm in models:
            datas.append(cm.createData())
        return models, datas

    # -- closures -----------------------------------------------------------------
    def _init_kinematics(self) -> None:
        """Precomputed pieces of :meth:`residual` and :meth:`constraint_jacobian`: the
        point closures as Pinocchio constraints with ``LOCAL_WORLD_ALIGNED`` rows (their
        stacked Jacobian is the world-axes ``J_1 - J_2`` of the anchor points, from one
        ``pin.getConstraintsJacobian`` call; anchors those of :attr:`constraint_models`)
        and their rows; the welds' rows and anchor frames."""
        self._point_models = pin.StdVec_RigidConstraintModel()
        self._point_datas = pin.StdVec_RigidConstraintData()
        point_rows, self._welds = [], []
        for closure, rows, cm, frames in zip(self.closures, self.row_slices,
                                             self.constraint_models, self._anchor_frames):
            if closure.type == "point":
                pm = pin.RigidConstraintModel(cm.type, self.model, cm.joint1_id,
                                              cm.joint1_placement, cm.joint2_id,
                                              cm.joint2_placement,
                                              pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
                self._point_models.append(pm)
                self._point_datas.append(pm.createData())
                point_rows.append(np.arange(rows.start, rows.stop))
            else:
                self._welds.append((rows, *frames))
        # (calc, data) pairs: getConstraintsJacobian reads the anchor placements of the
        # constraint datas but does not compute them
        self._point_calcs = [(cm.calc, cd) for cm, cd in zip(self._point_models,
                                                              self._point_datas)]
        #: the point closures' world-axes errors, gathered from live views
        self._point_errors = ConstraintErrors(self.model, self._point_models,
                                              self._point_datas, "world")
        self._point_rows = (np.concatenate(point_rows) if point_rows
                            else np.zeros(0, dtype=int))
        self._all_points = not self._welds

    def _calc_anchors(self) -> None:
        """Anchor placements (joint placements of ``self.data`` up to date): each point
        closure's into its constraint data; with welds, every frame's into ``data.oMf``."""
        model, data = self.model, self.data
        for calc, cd in self._point_calcs:
            calc(model, data, cd)
        if self._welds:
            pin.updateFramePlacements(model, data)

    def residual(self, q: npt.ArrayLike) -> np.ndarray:
        """Closure residual at ``q``, shape (n_rows,) (m for points, m/rad for welds)."""
        q = self.check_q(q)
        pin.forwardKinematics(self.model, self.data, q)
        self._calc_anchors()
        if self.coupling_rows is None:
            return self._residual_from_anchors()
        return np.concatenate([self._residual_from_anchors(), self.coupling_rows.residual(q)])

    def _residual_from_anchors(self) -> np.ndarray:
        """The residual from the anchor placements of :meth:`_calc_anchors`."""
        points = self._point_errors
        if self._all_points:
            return points.gather(np.empty(points.n_rows))
        out = np.empty(self.n_closure_rows)
        if points.n_rows:
            out[self._point_rows] = points.gather(np.empty(points.n_rows))
        omf = self.data.oMf
        for rows, f1, f2 in self._welds:
            out[rows] = pin.log6(omf[f2].actInv(omf[f1])).vector
        return out

    def constraint_jacobian(self, q: npt.ArrayLike) -> np.ndarray:
        """Constraint Jacobian ``J_c`` at ``q``, shape (n_rows, nv).

        Derivative of :meth:`residual` along ``pin.integrate`` (see module doc). Leaves
        the joint Jacobians of ``q`` in ``self.data``.
        """
        q = self.check_q(q)
        pin.computeJointJacobians(self.model, self.data, q)
        self._calc_anchors()
        if self.coupling_rows is None:
            return self._jacobian_from_anchors()
        return np.vstack([self._jacobian_from_anchors(), self.coupling_rows.jacobian(q)])

    def residual_and_jacobian(self, q: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`residual` (n_rows,) and :meth:`constraint_jacobian` (n_rows, nv) at ``q``
        from one kinematic pass (the same values as the two calls)."""
        q = self.check_q(q)
        pin.computeJointJacobians(self.model, self.data, q)
        self._calc_anchors()
        if self.coupling_rows is None:
            return self._residual_from_anchors(), self._jacobian_from_anchors()
        rows = self.coupling_rows
        return (np.concatenate([self._residual_from_anchors(), rows.residual(q)]),
                np.vstack([self._jacobian_from_anchors(), rows.jacobian(q)]))

    def _jacobian_from_anchors(self) -> np.ndarray:
        """``J_c`` from the joint Jacobians of ``self.data`` and the anchor placements."""
        model, data = self.model, self.data
        points = (pin.getConstraintsJacobian(model, data, self._point_models, self._point_datas)
                  if self._point_calcs else None)
        if self._all_points:
            return points if points is not None else np.zeros((0, model.nv))
        out = np.empty((self.n_closure_rows, model.nv))
        if points is not None:
            out[self._point_rows] = points
        for rows, f1, f2 in self._welds:
            out[rows] = weld_jacobian(model, data, f1, f2)
        return out

    def constraint_drift(self, q: npt.ArrayLike, v: npt.ArrayLike) -> np.ndarray:
        """Drift ``gamma = dJ_c/dt v`` (n_rows,): accelerations satisfy ``J_c a = -gamma``.

        For a point closure it is the difference of the classical accelerations
        of the two anchor points at zero joint acceleration, world axes (m/s^2).
        For a weld it is ``Jlog6`` times the relative spatial acceleration bias in
        anchor-1 axes (exact at an assembled configuration with ``J_c v = 0``). For a
        joint coupling it is ``-f''(q2) v2^2``.
        """
        q, v = self.check_q(q), self.check_v(v)
        pin.forwardKinematics(self.model, self.data, q, v, np.zeros(self.model.nv))
        pin.updateFramePlacements(self.model, self.data)
        drift = closure_drift(self.model, self.data, self.closure_frames, self.n_closure_rows)
        if self.coupling_rows is None:
            return drift
        return np.concatenate([drift, self.coupling_rows.drift(q, v)])

    def rank(self, q: npt.ArrayLike, tol: float | None = None) -> RankInfo:
        """Numerical rank of ``J_c`` at ``q`` and which rows are redundant.

        Args:
            q: configuration (nq,).
            tol: singular-value threshold; default ``RANK_RTOL * sigma_max`` (a
                relative 1e-10: rows dependent up to rounding, e.g. an SDF's pi/2 written
                to five digits, count as redundant).
        """
        jac = self.constraint_jacobian(q)
        if self.n_rows == 0:
            empty = np.zeros(0, dtype=int)
            return RankInfo(0, 0, empty, empty, np.zeros(0), 0.0)
        sv = np.linalg.svd(jac, compute_uv=False)
        if tol is None:
            tol = max(RANK_RTOL * sv[0], max(jac.shape) * _EPS)
        rank = int(np.sum(sv > tol))
        _, _, piv = scipy.linalg.qr(jac.T, pivoting=True, mode="economic")
        independent = np.sort(piv[:rank])
        redundant = np.sort(piv[rank:])
        return RankInfo(rank, self.n_rows, redundant, independent, sv, float(tol))

    def mobility(self, q: npt.ArrayLike) -> int:
        """Degrees of freedom of the closed mechanism at ``q``: ``nv - rank(J_c)``."""
        return self.model.nv - self.rank(q).rank

    # -- assembly -------------------------------------------------------------------
    def assemble(self, q0: npt.ArrayLike, fixed: npt.ArrayLike | None = None, tol: float = 1e-12,
                 max_iter: int = 50, restarts: int = ASSEMBLY_RESTARTS,
                 method: str = "lm") -> AssemblyResult:
        """Close every loop by Levenberg-Marquardt with restarts, holding some velocity
        coordinates fixed.

        Solves ``residual(q) = 0`` moving only the velocity coordinates not in ``fixed``
        (default: the actuated joints are held at their values in ``q0``), by
        :func:`~hexapod_pin.core.assembly.levenberg_marquardt`: Levenberg steps
        ``dv = -(J^T J + mu I)^-1 J^T r`` on the free columns of ``J_c`` applied with
        ``pin.integrate``, the damping ``mu`` adapted to the ratio of actual to predicted
        decrease (Gauss-Newton, minimum-norm, near the solution: quadratic convergence;
        redundant rows are harmless). A start that stalls or runs out of iterations is
        followed by up to ``restarts`` others, from ``q0`` with its free coordinates
        displaced by seeded, documented amounts
        (:data:`~hexapod_pin.core.assembly.RESTART_SPREADS`); so the answer is the
        configuration nearest ``q0`` in the Newton sense when the first start converges,
        and a nearby one otherwise. The residual is recomputed at the returned ``q``.

        Args:
            q0: starting configuration (nq,).
            fixed: the velocity coordinates held fixed, either integer indices into ``v``
                (a 1-D sequence, each in ``[0, nv)``, no duplicates; empty: none fixed) or
                a boolean mask of length ``nv`` (True: held); default the actuated ones.
            tol: convergence threshold on the max-abs residual (m / rad).
            max_iter: maximum iterations per start.
            restarts: further starts at most after the first (0: the first only).
            method: "lm" (Levenberg-Marquardt, the default) or "newton" (Gauss-Newton,
                minimum-norm steps halved while they do not decrease the max-abs residual:
                the local solver of callers that follow one assembly mode and globalise
                themselves, by continuation or their own starts; pass ``restarts=0``).

        Returns:
            :class:`AssemblyResult` (``iterations``: of every start together).

        Raises:
            InputError: a bad ``q0``, ``tol``, ``max_iter``, ``restarts`` or ``method``; a
                ``fixed`` that is neither (floats, text, nested or ragged sequences,
                booleans mixed with integers, a mask of another length, an index out of
                range or repeated); or a ``q0`` whose closure residual overflows (not
                finite).
            AssemblyError: no start converged within ``max_iter`` iterations (a singular
                or unreachable configuration); carries the best iterate of all starts.
        """
        q = self.check_q(q0, "q0").copy()
        tol = real_number(tol, "tol", minimum=0.0)
        max_iter = count(max_iter, "max_iter", minimum=0)
        restarts = count(restarts, "restarts", minimum=0)
        if method not in ASSEMBLY_METHODS:
            raise InputError("method", method, f"expected one of {ASSEMBLY_METHODS}")
        fixed_idx = self.actuated_v if fixed is None else fixed_coordinates(fixed, self.model.nv)
        free = np.setdiff1d(np.arange(self.model.nv), fixed_idx)
        res = self.residual(q)
        err = float(np.max(np.abs(res), initial=0.0))
        if not math.isfinite(err):
            raise InputError("q0", q0, "its closure residual is not finite (overflow)")
        solve = levenberg_marquardt(self.model, self.residual_and_jacobian, q, free, tol,
                                    max_iter, restarts, method)
        if solve.converged:
            final = float(np.max(np.abs(self.residual(solve.q)), initial=0.0))
            if final <= tol:
                return AssemblyResult(solve.q, final, solve.iterations)
            raise AssemblyError(f"the residual recomputed at the answer, {final:.3e}, exceeds "
                                f"{tol:g}", final, solve.iterations, solve.q)
        raise AssemblyError(f"{solve.reason} ({solve.starts} starts, best residual shown)",
                            solve.residual_norm, solve.iterations, solve.q)

    # -- motion on the closures (closure_motion.py) -------------------------------------
    def complete_velocity(self, q: npt.ArrayLike, known: npt.ArrayLike, values: npt.ArrayLike,
                          method: str = "lstsq") -> np.ndarray:
        """Tree velocity (nv,) keeping every closure, given some of its coordinates.

        Solves ``J_c v = 0`` with ``v[known] = values``; the other coordinates get the
        least Euclidean norm where the closures leave them free (see
        :func:`~hexapod_pin.core.closure_motion.complete`; ``method`` "lstsq" or "qp").

        Raises:
            InconsistentMotionError: no velocity keeps the closures with these values.
        """
        jac = self.constraint_jacobian(q)
        return complete(jac, np.zeros(self.n_rows), known, values, method, "velocity")

    def complete_acceleration(self, q: npt.ArrayLike, v: npt.ArrayLike, known: npt.ArrayLike,
                              values: npt.ArrayLike, method: str = "lstsq") -> np.ndarray:
        """Tree acceleration (nv,) keeping every closure, given some of its coordinates.

        Solves ``J_c a = -gamma(q, v)`` with ``a[known] = values`` (least norm elsewhere);
        ``v`` must keep the closures.
        """
        gamma = self.constraint_drift(q, v)
        jac = self.constraint_jacobian(q)
        return complete(jac, -gamma, known, values, method, "acceleration")

    def actuated_velocity_map(self, q: npt.ArrayLike, method: str = "lstsq") -> np.ndarray:
        """Linear map ``G`` (nv, n_actuated) from actuated to tree velocities: ``v = G qdot_act``.

        Column j is the tree velocity keeping every closure (``J_c v = 0``) when actuated
        joint j moves at unit speed and the others are held: the minimum-norm passive
        velocity ``min |v_p|`` s.t. ``J_c[:, p] v_p = -J_c[:, j]``. Unique where the
        actuators determine the passive motion (the hexapod); redundant closure rows are
        harmless; passive motion the closures leave free (a rod spinning about its axis)
        gets the least norm. Free-flyer velocities are Pinocchio's (body frame).

        Args:
            q: an assembled configuration (nq,).
            method: "lstsq" (SVD least squares) or "qp" (ProxSuite on the independent
                rows); they agree to 1e-10.

        Raises:
            InconsistentMotionError: an actuated velocity that no closure-keeping motion
                has (a singular configuration, or ``q`` not assembled).
        """
        jac = self.constraint_jacobian(q)
        return complete(jac, np.zeros((self.n_rows, self.n_actuated)), self.actuated_v,
                        np.eye(self.n_actuated), method, "velocity map", free=self.passive_v)

    def velocity_from_actuated(self, q: npt.ArrayLike, qdot_act: npt.ArrayLike,
                               method: str = "lstsq") -> np.ndarray:
        """Tree velocity (nv,) keeping every closure, given the actuated velocities.

        ``qdot_act`` (n_actuated,) in ``actuated_joints`` order (m/s or rad/s); the
        problem and routes of :meth:`actuated_velocity_map`, solved once.
        """
        qdot_act = as_array(qdot_act, (self.n_actuated,), "qdot_act")
        return complete(self.constraint_jacobian(q), np.zeros(self.n_rows), self.actuated_v,
                        qdot_act, method, "velocity", free=self.passive_v)

    def acceleration_from_actuated(self, q: npt.ArrayLike, v: npt.ArrayLike,
                                   qddot_act: npt.ArrayLike, method: str = "lstsq") -> np.ndarray:
        """Tree acceleration (nv,) keeping every closure, given the actuated accelerations.

        Solves ``J_c a = -gamma(q, v)`` (drift of :meth:`constraint_drift`) with
        ``a[actuated] = qddot_act`` (least norm of the passive part where free). ``v``
        must itself keep the closures.
        """
        qddot_act = as_array(qddot_act, (self.n_actuated,), "qddot_act")
        gamma = self.constraint_drift(q, v)
        return complete(self.constraint_jacobian(q), -gamma, self.actuated_v, qddot_act, method,
                        "acceleration", free=self.passive_v)

    def frame_jacobian_from_actuated(self, q: npt.ArrayLike, frame: str | int,
                                     reference: pin.ReferenceFrame =
                                     pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
                                     method: str = "lstsq") -> np.ndarray:
        """Workspace Jacobian of a frame with respect to the actuated velocities.

        ``K = J_frame(q) G(q)`` (6, n_actuated): the spatial velocity of ``frame``
        (linear; angular) in Pinocchio's ``reference`` convention produced by
        actuated velocities, ``twist = K @ qdot_act``. With the default
        ``LOCAL_WORLD_ALIGNED`` it is the velocity of the frame origin and the
        angular velocity, both in world axes. For a non-redundant parallel robot
        ``K`` is the inverse of the inverse-kinematics Jacobian.

        Args:
            q: an assembled configuration (nq,).
            frame: frame name or id.
            reference: ``pin.ReferenceFrame`` of the result, or its name (``"LOCAL"``,
                ``"WORLD"``, ``"LOCAL_WORLD_ALIGNED"``).
            method: see :meth:`actuated_velocity_map`.

        Raises:
            InputError: unknown frame, or a ``reference`` that is neither.
            InconsistentMotionError: see :meth:`actuated_velocity_map`.
        """
        frames = {"LOCAL": pin.ReferenceFrame.LOCAL, "WORLD": pin.ReferenceFrame.WORLD,
                  "LOCAL_WORLD_ALIGNED": pin.ReferenceFrame.LOCAL_WORLD_ALIGNED}
        if isinstance(reference, str) and reference in frames:
            reference = frames[reference]
        elif not isinstance(reference, pin.ReferenceFrame):
            raise InputError("reference", reference, f"expected a pin.ReferenceFrame or one "
                                                     f"of {list(frames)}")
        fid = self.frame_id(frame)
        gmap = self.actuated_velocity_map(q, method)
        # constraint_jacobian left the joint Jacobians of q in self.data
        return pin.getFrameJacobian(self.model, self.data, fid, reference) @ gmap

    def acceleration_bias_from_actuated(self, q: npt.ArrayLike, v: npt.ArrayLike, frame: str | int,
                                        method: str = "lstsq") -> np.ndarray:
        """Frame acceleration at zero actuated acceleration (6,): ``dK/dt qdot_act``.

        The classical acceleration of ``frame`` (origin acceleration; angular
        acceleration, world axes) when the tree moves with ``v`` (closure-consistent)
        and the actuated accelerations are zero, so that the frame acceleration is
        ``K(q) qddot_act + bias`` with ``K`` of :meth:`frame_jacobian_from_actuated`.
        """
        fid = self.frame_id(frame)
        a0 = self.acceleration_from_actuated(q, v, np.zeros(self.n_actuated), method)
        pin.forwardKinematics(self.model, self.data, self.check_q(q), self.check_v(v), a0)
        return pin.getFrameClassicalAcceleration(
            self.model, self.data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED).vector

    def project_velocity(self, q: npt.ArrayLike, v: npt.ArrayLike, metric: str = "mass",
                         method: str = "lstsq") -> np.ndarray:
        """The closure-consistent velocity (``J_c v' = 0``) closest to ``v`` (nv,).

        Args:
            q: an assembled configuration (nq,).
            v: any tree velocity (nv,).
            metric: "mass" (kinetic-energy metric ``(v' - v)^T M(q) (v' - v)``, the
                physical one: the velocity jump of a perfectly plastic impulsive
                closure) or "euclidean" (``|v' - v|``, needed when ``M`` is singular,
                e.g. massless links).
            method: "lstsq" or "qp" (ProxSuite), see :mod:`~hexapod_pin.core.closure_motion`.

        Raises:
            SingularityError: metric "mass" with a singular mass matrix.
        """
        q, v = self.check_q(q), self.check_v(v)
        weight = self._metric(q, metric)
        return project(self.constraint_jacobian(q), np.zeros(self.n_rows), v, weight, method,
                       "projected velocity")

    def project_acceleration(self, q: npt.ArrayLike, v: npt.ArrayLike, a: npt.ArrayLike,
                             metric: str = "mass", method: str = "lstsq") -> np.ndarray:
        """The closure-consistent acceleration (``J_c a' = -gamma(q, v)``) closest to ``a``.

        ``v`` must keep the closures (project it first). With the mass metric this is
        Gauss's principle: the constrained acceleration is the projection of the
        unconstrained one ``M^-1 (tau - h)``. Arguments as :meth:`project_velocity`.
        """
        q, v, a = self.check_q(q), self.check_v(v), self.check_v(a, "a")
        weight = self._metric(q, metric)
        gamma = self.constraint_drift(q, v)
        return project(self.constraint_jacobian(q), -gamma, a, weight, method,
                       "projected acceleration")

    def _metric(self, q: np.ndarray, metric: str) -> np.ndarray | None:
        if metric == "euclidean":
            return None
        if metric == "mass":
            return pin.crba(self.model, self.data, q)
        raise InputError("metric", metric, "expected 'mass' or 'euclidean'")

    # -- frame-target inverse kinematics (frame_ik.py) ------------------------------------
    def frame_inverse_kinematics(self, frame: str, target: npt.ArrayLike,
                                 q0: npt.ArrayLike | None = None, *, position_only: bool = False,
                                 fixed: Sequence[str | int] | None = None,
                                 weights: npt.ArrayLike | None = None,
                                 **options: Any) -> FrameIKResult:
        """Place one or several frames at targets with every closure held.

        See :func:`~hexapod_pin.core.frame_ik.frame_inverse_kinematics` (this method
        calls it with ``self``): arguments, options (``method``, ``tol``,
        ``max_iter``, ``limits``), result and errors.
        """
        return frame_inverse_kinematics(self, frame, target, q0, position_only=position_only,
                                        fixed=fixed, weights=weights, **options)

    def frame_id(self, frame: str | int) -> int:
        """Pinocchio id of a frame given by name (see ``FRAME_TYPE_ORDER``) or id.

        Raises:
            InputError: no such frame.
        """
        if isinstance(frame, (int, np.integer)) and not isinstance(frame, bool):
            if 0 <= int(frame) < self.model.nframes:
                return int(frame)
        elif isinstance(frame, str):
            for ftype in FRAME_TYPE_ORDER:
                if self.model.existFrame(frame, ftype):
                    return self.model.getFrameId(frame, ftype)
        raise InputError("frame", frame, f"no such frame in {self.name}")

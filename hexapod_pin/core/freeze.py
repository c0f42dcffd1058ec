"""Freezing joints of a closed-loop model: a reduced model whose closures still hold.

:func:`freeze_joints` locks a set of joints of a
:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel` at given values and returns a
:class:`FrozenModel`: a new ``ClosedLoopModel`` on the reduced tree
(``pin.buildReducedModel``: each locked joint becomes a fixed joint, its subtree's
inertia merged into its parent body) with every closure re-expressed on the reduced
tree (the closure frames are kept by name, their placements follow the locked values),
plus the maps between full and reduced coordinates.

A closure whose two anchors end up on the same rigid body (both sides locked, e.g. a
loop of locked joints) adds no constraint any more: it is dropped after checking that it
holds at the locked values (else AssemblyError). Locked actuated joints leave the
actuation. Velocities and accelerations of the locked joints are zero, so the reduced
dynamics equal the full model's with the locked joints' accelerations held at zero
(tested against a KKT solve of the full model with those rows added).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import AssemblyError, InputError
from .closed_loop import ClosedLoopModel
from .description import LoopsSpec

#: a closure dropped by the freezing must hold at the locked values to this (m / rad)
DROPPED_CLOSURE_TOL = 1e-10


@dataclass(frozen=True)
class FrozenModel:
    """A closed-loop model with some joints locked, and its maps to the full model.

    Attributes:
        model: the reduced :class:`ClosedLoopModel`.
        full: the full model.
        locked_joints: names of the locked joints.
        q_locked: the full configuration (nq of ``full``) whose values the locked joints
            keep (the other entries are not used).
        q_index: for each reduced ``q`` entry, its index in the full ``q``.
        v_index: for each reduced ``v`` entry, its index in the full ``v``.
        dropped_closures: closures made rigid by the locking (they hold identically).
    """

    model: ClosedLoopModel
    full: ClosedLoopModel
    locked_joints: tuple[str, ...]
    q_locked: np.ndarray
    q_index: np.ndarray
    v_index: np.ndarray
    dropped_closures: tuple[str, ...]

    def full_configuration(self, q_reduced: npt.ArrayLike) -> np.ndarray:
        """Full configuration (nq of ``full``): reduced values, locked joints at their values."""
        q_reduced = self.model.check_q(q_reduced, "q_reduced")
        out = self.q_locked.copy()
        out[self.q_index] = q_reduced
        return out

    def reduced_configuration(self, q: npt.ArrayLike) -> np.ndarray:
        """Reduced configuration (nq of ``model``) of a full one (locked entries ignored)."""
        return self.full.check_q(q)[self.q_index].copy()

    def full_velocity(self, v_reduced: npt.ArrayLike) -> np.ndarray:
        """Full velocity or acceleration (nv of ``full``): zero on the locked joints."""
        v_reduced = self.model.check_v(v_reduced, "v_reduced")
        out = np.zeros(self.full.nv)
        out[self.v_index] = v_reduced
        return out

    def reduced_velocity(self, v: npt.ArrayLike) -> np.ndarray:
        """Reduced velocity or acceleration of a full one (locked entries dropped)."""
        return self.full.check_v(v)[self.v_index].copy()


def freeze_joints(clm: ClosedLoopModel, joints: Sequence[str],
                  q_locked: npt.ArrayLike) -> FrozenModel:
    """Lock ``joints`` of ``clm`` at their values in ``q_locked``.

    Args:
        clm: the full closed-loop model.
        joints: names of the joints to lock (any type: revolute, prismatic, spherical,
            free flyer).
        q_locked: a full configuration (nq,) giving the locked values.

    Returns:
        :class:`FrozenModel`.

    Raises:
        InputError: an unknown or repeated joint, a bad ``q_locked``.
        AssemblyError: a closure made rigid by the locking does not hold at the locked
            values (it could never hold on the reduced model).
    """
    q_locked = clm.check_q(q_locked, "q_locked").copy()
    names = tuple(joints)
    if len(set(names)) != len(names):
        raise InputError("joints", names, "repeated joint")
    ids = []
    for name in names:
        if not isinstance(name, str) or not clm.model.existJointName(name) or name == "universe":
            raise InputError("joints", name, f"no such joint in {clm.name}")
        ids.append(clm.model.getJointId(name))
    locked = set(ids)
    residual = clm.residual(q_locked)
    kept, dropped = [], []
    for closure, rows in zip(clm.closures, clm.row_slices):
        body1, body2 = (_moving_body(clm.model, clm.model.frames[clm.frame_id(f"{closure.name}/"
                                                                        f"{tag}")].parentJoint,
                                     locked) for tag in ("anchor1", "anchor2"))
        if body1 != body2:
            kept.append(closure)
            continue
        miss = float(np.max(np.abs(residual[rows])))
        if not miss <= DROPPED_CLOSURE_TOL:
            raise AssemblyError(f"closure {closure.name!r} is rigid once the joints are "
                                "locked and does not hold at the locked values", miss, 0,
                                q_locked)
        dropped.append(closure.name)
    reduced_tree = _reduced_tree(clm.tree_model, sorted(ids), q_locked)
    # joint couplings are kept (one on a frozen joint is refused by name: not in the tree)
    loops = LoopsSpec(tuple(kept), tuple(j for j in clm.actuated_joints if j not in names),
                      couplings=clm.couplings)
    reduced = ClosedLoopModel(reduced_tree, loops, name=f"{clm.name} (frozen: {', '.join(names)})",
                              urdf_xml=None)
    q_index: list[int] = []
    v_index: list[int] = []
    for jname in reduced.model.names[1:]:
        full = clm.model.joints[clm.model.getJointId(jname)]
        q_index.extend(range(full.idx_q, full.idx_q + full.nq))
        v_index.extend(range(full.idx_v, full.idx_v + full.nv))
    q_idx, v_idx = np.array(q_index, dtype=int), np.array(v_index, dtype=int)
    effects = clm.effects
    if not effects.is_rigid or np.any(effects.gear != 1) or np.isfinite(effects.effort_limit).any():
        # the kept coordinates keep their effects (a locked joint's spring or friction acts
        # on the lock, not on the motion)
        kept_act = [clm.actuated_joints.index(j) for j in reduced.actuated_joints]
        reduced = reduced.with_effects(effects.replace(
            armature=effects.armature[v_idx], damping=effects.damping[v_idx],
            coulomb=effects.coulomb[v_idx], stiffness=effects.stiffness[v_idx],
            spring_reference=effects.spring_reference[q_idx], gear=effects.gear[kept_act],
            effort_limit=effects.effort_limit[kept_act]))
    return FrozenModel(reduced, clm, names, q_locked, q_idx, v_idx, tuple(dropped))


def _reduced_tree(tree: pin.Model, ids: list[int], q_locked: np.ndarray) -> pin.Model:
    """``pin.buildReducedModel`` on a tree whose frame names may repeat across types.

    Pinocchio's reduction looks frames up by name alone and refuses a name shared by,
    e.g., a joint frame and a body frame (URDF joints and links named alike); those
    non-joint frames are renamed for the call and given their names back after it.
    """
    model = pin.Model(tree)
    counts: dict[str, int] = {}
    for frame in model.frames:
        counts[frame.name] = counts.get(frame.name, 0) + 1
    renamed = {}
    for index, frame in enumerate(model.frames):
        if counts[frame.name] > 1 and frame.type != pin.FrameType.JOINT:
            tmp = f"{frame.name}#frozen-model-{index}"
            renamed[tmp] = frame.name
            frame.name = tmp
            model.frames[index] = frame
    reduced = pin.buildReducedModel(model, ids, q_locked)
    for index, frame in enumerate(reduced.frames):
        if frame.name in renamed:
            frame.name = renamed[frame.name]
            reduced.frames[index] = frame
    return reduced


def _moving_body(model: pin.Model, joint: int, locked: set[int]) -> int:
    """The joint that carries ``joint``'s body once ``locked`` are locked (0: the world)."""
    while joint in locked:
        joint = model.parents[joint]
    return joint

"""MJCF (MuJoCo) import: a compiled ``mujoco.MjModel`` -> Pinocchio tree + loop closures.

MuJoCo itself compiles the file (defaults, ``childclass``, ``<include>``, ``angle="degree"``,
``euler`` / ``axisangle`` / ``xyaxes`` / ``zaxis``, inertias from geoms and meshes, the
anchors of body connects and the ``relpose`` of welds at ``qpos0``), and the
Pinocchio model is built from the compiled fields, so that MJCF semantics are MuJoCo's.
``mujoco`` is optional: the ``mjcf`` extra installs it.

Conventions of the import:

* **Tree.** Every body of ``<worldbody>`` (sibling root bodies included) in MuJoCo's
  order, which is depth first; a body's joints are Pinocchio joints in the order written,
  so each joint has MuJoCo's ``jnt_qposadr`` / ``jnt_dofadr`` as Pinocchio's ``idx_q`` /
  ``idx_v``. A body without joints is fixed to its parent (its inertia merged into the
  parent's joint), a root body without joints to the world, at its compiled
  ``body_pos`` / ``body_quat`` (rotation included); a mocap body stays at that pose.
* **Joints.** ``hinge`` -> revolute (``RX`` / ``RY`` / ``RZ`` on a frame axis, else
  unaligned), ``slide`` -> prismatic, ``ball`` -> spherical, ``free`` -> free flyer (a root
  body's only joint). A joint turns or slides about its anchor ``jnt_pos`` and axis
  ``jnt_axis`` (body frame); the joint frame sits at the anchor. **Coordinates are
  MuJoCo's**: a hinge or slide's ``q`` is its ``qpos``, ``ref`` included (the rotation
  ``-ref`` is folded into the joint placement, so the body is where the file puts it at
  ``q = ref``), joint ranges and ``springref`` unchanged; quaternions are reordered to
  Pinocchio's ``(x, y, z, w)``; a free flyer's linear velocity is in the body frame
  (MuJoCo's ``qvel`` has it in the world frame: ``qvel = T v`` with
  :func:`~hexapod_pin.core.mujoco_export.velocity_map`, ``M_mj = T^-T M T^-1``); angular
  velocities are in the body frame in both. :func:`configuration_from_qpos` converts a
  ``qpos``. ``pin.neutral`` is not ``qpos0``: read the reference configurations.
* **Frames.** A ``BODY`` frame per body (named as the body, ``body<i>`` when unnamed), a
  ``JOINT`` frame per joint (``<body>_joint<k>`` when unnamed), an ``OP_FRAME`` per named
  site (``site_pos`` / ``site_quat`` in its body).
* **Inertials.** ``body_mass``, ``body_inertia`` (principal moments) in the frame
  ``body_ipos`` / ``body_iquat`` of the body.
* **Closures.** Active ``<equality><connect>`` -> point closures (body anchors: the
  compiled ``eq_data`` points in each body; site anchors: the sites), ``<weld>`` -> 6-D
  closures (body semantics: anchor ``relpose`` in body 1 against ``anchor`` in body 2;
  sites: the site frames); ``solref`` / ``solimp`` (the softness) and a positive
  ``torquescale`` (a weighting of the soft rows) have no rigid counterpart and are not
  read. Inactive equalities (``active="false"``, or ``<flag equality="disable"/>``) are
  skipped and listed (:attr:`MjcfImport.skipped`).
* **Effects** (:mod:`~hexapod_pin.core.effects`): ``armature`` (not on free joints),
  ``damping`` (ball and free joints too, one value per coordinate: on a free joint's
  translations the same in the world and the body frame), ``frictionloss`` as Coulomb friction,
  ``stiffness`` / ``springref`` (``qpos_spring``) as springs (on hinge, slide and ball
  joints), an actuator's ``armature`` and ``damping`` added to its joint as ``gear^2``
  times them; ``<flag spring / damper / frictionloss="disable">`` honoured.
* **Actuators.** Every actuator with a joint transmission on a hinge or slide makes its
  joint actuated (``clm.actuated_joints`` in actuator order) with its ``gear`` (times the
  fixed gain of a plain ``motor``); the effort limit is the smallest of
  ``|gear| max|ctrlrange|`` (``ctrllimited``), ``|gear| max|forcerange|``
  (``forcelimited``) and the joint's ``actuatorfrcrange``. The feedback of
  position / velocity servos is not a mechanism property and is not imported (listed in
  :attr:`MjcfImport.notes`).
* **Gravity**: ``<option gravity>`` (zero with ``<flag gravity="disable"/>``).
* **Reference configurations**: ``qpos0`` and every keyframe (by name, ``key<i>`` when
  unnamed; one named ``qpos0`` does not replace it) in Pinocchio's
  ``model.referenceConfigurations`` (``clm.reference_configurations``; also
  :attr:`MjcfImport.reference_configurations`), and ``home``: the keyframe chosen with
  ``keyframe=``, else the file's keyframe named ``home``, else ``qpos0`` (a chosen
  keyframe replaces a file's ``home``).

* **Joint couplings.** Active ``<equality><joint joint1 joint2 polycoef>`` on hinge and
  slide joints -> :class:`~hexapod_pin.core.couplings.JointCoupling` rows
  (``clm.couplings``): MuJoCo's ``q1 - q1_0 = f(q2 - q2_0)``, relative to ``qpos0``,
  rewritten in absolute coordinates ``q1 = f_abs(q2)`` (``q1 = c0 + q1_0`` without
  ``joint2``); solref / solimp are not read.

Refused (:class:`~hexapod_pin.errors.DescriptionError` naming every one): joint couplings
of ball or free joints, tendon and flex equalities,
tendons with stiffness, damping, friction, armature or limits, actuators with another
transmission (tendon, site, body, slider-crank) or on a ball / free joint, two actuators on
one joint, gravity compensation, fluid forces (``density`` / ``viscosity``), flexes,
polynomial springs and dampers, plastic springs, springs, friction or armature on free
joints (MuJoCo applies them along world axes), a ``torquescale`` of zero, a free joint
below another body. Hinge and slide ranges become Pinocchio's position limits. Not read:
contacts and geoms (but for the inertia MuJoCo derives from them), the range of ball
joints, solver options.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from ..core.closed_loop import ClosedLoopModel
from ..core.couplings import JointCoupling
from ..core.description import WORLD, ClosureSpec, LoopsSpec, RobotSection, check_inertia
from ..core.effects import JointEffects, resolve_effects
from ..core.checks import existing_file
from ..errors import DescriptionError, MissingDependencyError

#: the name of the home configuration: the keyframe chosen by ``keyframe=``, else the
#: file's keyframe of that name, else ``qpos0``
HOME = "home"


def _mujoco() -> Any:
    try:
        import mujoco
    except ImportError:
        raise MissingDependencyError("mujoco", "mjcf") from None
    return mujoco


@dataclass(frozen=True)
class MjcfImport:
    """What :func:`read_mjcf` made of an MJCF file.

    Attributes:
        model: the closed-loop model.
        reference_configurations: name -> configuration (nq,) in Pinocchio's convention:
            ``qpos0``, each keyframe, and ``home`` (see the module docstring and
            :data:`HOME`).
        skipped: names of the inactive equalities that were left out.
        notes: what was read but not imported (the feedback of servo actuators), one
            sentence each.
        mj_model: the compiled ``mujoco.MjModel`` the model was built from.
    """

    model: ClosedLoopModel
    reference_configurations: dict[str, np.ndarray]
    skipped: tuple[str, ...]
    notes: tuple[str, ...]
    mj_model: Any

    @property
    def home(self) -> np.ndarray:
        """The ``home`` configuration (nq,) (see :data:`HOME`)."""
        return self.reference_configurations[HOME].copy()


def _rotation(wxyz: np.ndarray) -> np.ndarray:
    w, x, y, z = (float(c) for c in wxyz)
    return pin.Quaternion(w, x, y, z).normalized().matrix()


def _placement(pos: np.ndarray, wxyz: np.ndarray | None = None) -> pin.SE3:
    rot = np.eye(3) if wxyz is None else _rotation(wxyz)
    return pin.SE3(rot, np.array(pos, dtype=float))


def configuration_from_qpos(mj_model: Any, qpos: np.ndarray) -> np.ndarray:
    """Pinocchio's ``q`` (nq,) of a MuJoCo ``qpos`` of ``mj_model`` (the tree of
    :func:`read_mjcf`): equal but for the quaternions of ball and free joints, reordered
    from ``(w, x, y, z)`` to ``(x, y, z, w)`` and normalised.

    Raises:
        DescriptionError: ``qpos`` is not of size ``mj_model.nq`` or not finite.
    """
    mujoco = _mujoco()
    qpos = np.array(qpos, dtype=float).ravel()
    if qpos.shape != (mj_model.nq,) or not np.isfinite(qpos).all():
        raise DescriptionError("qpos", f"expected {mj_model.nq} finite numbers, got "
                                       f"{qpos.tolist()}")
    q = qpos.copy()
    for j in range(mj_model.njnt):
        kind, adr = int(mj_model.jnt_type[j]), int(mj_model.jnt_qposadr[j])
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            adr += 3
        elif kind != mujoco.mjtJoint.mjJNT_BALL:
            continue
        quat = qpos[adr:adr + 4] / np.linalg.norm(qpos[adr:adr + 4])
        q[adr:adr + 3], q[adr + 3] = quat[1:], quat[0]
    return q


class _Names:
    """MuJoCo names of one object type, with unique fallbacks for unnamed objects."""

    def __init__(self, mujoco: Any, mj_model: Any, objtype: Any, count: int, fallback: Any):
        names = [mujoco.mj_id2name(mj_model, objtype, i) or "" for i in range(count)]
        taken = set(names)
        self.names = []
        for i, name in enumerate(names):
            if not name:
                name = fallback(i)
                while name in taken:
                    name += "_"
                taken.add(name)
            self.names.append(name)

    def __getitem__(self, index: int) -> str:
        return self.names[index]


class _Builder:
    """Builds the Pinocchio tree, closures and effects of a compiled ``MjModel``."""

    def __init__(self, mujoco: Any, mj: Any, source: str):
        self.mj, self.mjc, self.source = mj, mujoco, source
        obj = mujoco.mjtObj
        self.bodies = _Names(mujoco, mj, obj.mjOBJ_BODY, mj.nbody, lambda i: f"body{i}")
        self.joints = _Names(mujoco, mj, obj.mjOBJ_JOINT, mj.njnt, lambda j: (
            f"{self.bodies[int(mj.jnt_bodyid[j])]}_joint{j - int(mj.body_jntadr[mj.jnt_bodyid[j]])}"))
        self.equalities = _Names(mujoco, mj, obj.mjOBJ_EQUALITY, mj.neq,
                                 lambda i: f"equality{i}")
        self.actuators = _Names(mujoco, mj, obj.mjOBJ_ACTUATOR, mj.nu, lambda i: f"actuator{i}")
        self.model = pin.Model()
        self.model.name = Path(source).stem
        self.unsupported: list[str] = []
        self.notes: list[str] = []
        self.skipped: list[str] = []
        #: the joint couplings (``<equality><joint>``), in file order
        self.couplings: list[JointCoupling] = []
        #: body -> (Pinocchio joint, placement of the body frame in that joint's frame)
        self.frames: list[tuple[int, pin.SE3]] = [(0, pin.SE3.Identity())]
        self.body_frame_ids = [0]

    def disabled(self, flag: Any) -> bool:
        return bool(self.mj.opt.disableflags & int(flag))

    # -- the tree ---------------------------------------------------------------------
    def build_tree(self) -> None:
        mj = self.mj
        for b in range(1, mj.nbody):
            parent = int(mj.body_parentid[b])
            jid, in_joint = self.frames[parent]
            frame = in_joint * _placement(mj.body_pos[b], mj.body_quat[b])
            start, count = int(mj.body_jntadr[b]), int(mj.body_jntnum[b])
            for j in range(start, start + count):
                jid, frame = self.add_joint(j, jid, frame, parent, count)
            self.frames.append((jid, frame))
            self.add_body(b, jid, frame, self.body_frame_ids[parent])
        for s in range(mj.nsite):
            name = self.mjc.mj_id2name(mj, self.mjc.mjtObj.mjOBJ_SITE, s)
            if not name:
                continue
            b = int(mj.site_bodyid[s])
            jid, in_joint = self.frames[b]
            self.model.addFrame(pin.Frame(name, jid, self.body_frame_ids[b],
                                          in_joint * self.site_placement(s),
                                          pin.FrameType.OP_FRAME), False)
        gravity = np.zeros(3) if self.disabled(self.mjc.mjtDisableBit.mjDSBL_GRAVITY) \
            else np.array(mj.opt.gravity, dtype=float)
        self.model.gravity = pin.Motion(gravity, np.zeros(3))

    def site_placement(self, s: int) -> pin.SE3:
        return _placement(self.mj.site_pos[s], self.mj.site_quat[s])

    def add_joint(self, j: int, parent_jid: int, frame: pin.SE3, parent_body: int,
                  count: int) -> tuple[int, pin.SE3]:
        """Add MuJoCo joint ``j`` after ``frame`` (the body frame accumulated so far, in
        joint ``parent_jid``); returns the new joint and the accumulated frame in it."""
        mj, types = self.mj, self.mjc.mjtJoint
        kind, name = int(mj.jnt_type[j]), self.joints[j]
        anchor, axis = np.array(mj.jnt_pos[j], dtype=float), np.array(mj.jnt_axis[j], dtype=float)
        ref = float(mj.qpos0[mj.jnt_qposadr[j]])
        if kind == types.mjJNT_FREE:
            if parent_body != 0 or count != 1:
                self.unsupported.append(f"free joint {name!r} below another body or with "
                                        "other joints")
            # qpos is the world pose of the body frame (body_pos / body_quat only set qpos0)
            jmodel, placement = pin.JointModelFreeFlyer(), pin.SE3.Identity()
            after = pin.SE3.Identity()
        else:
            if kind == types.mjJNT_HINGE:
                jmodel = _axis_joint(axis, (pin.JointModelRX, pin.JointModelRY,
                                            pin.JointModelRZ), pin.JointModelRevoluteUnaligned)
                shift = pin.SE3(pin.AngleAxis(-ref, axis).matrix(), np.zeros(3))
            elif kind == types.mjJNT_SLIDE:
                jmodel = _axis_joint(axis, (pin.JointModelPX, pin.JointModelPY,
                                            pin.JointModelPZ), pin.JointModelPrismaticUnaligned)
                shift = pin.SE3(np.eye(3), -ref * axis)
            else:
                jmodel, shift = pin.JointModelSpherical(), pin.SE3.Identity()
            placement = frame * pin.SE3(np.eye(3), anchor) * shift
            after = pin.SE3(np.eye(3), -anchor)
        nq, nv = jmodel.nq, jmodel.nv
        lower, upper = np.full(nq, -np.inf), np.full(nq, np.inf)
        if mj.jnt_limited[j] and kind in (types.mjJNT_HINGE, types.mjJNT_SLIDE):
            lower[:], upper[:] = mj.jnt_range[j]
        jid = self.model.addJoint(parent_jid, jmodel, placement, name, np.full(nv, np.inf),
                                  np.full(nv, np.inf), lower, upper)
        self.model.addJointFrame(jid, self.body_frame_ids[parent_body])
        if self.model.idx_qs[jid] != mj.jnt_qposadr[j] or self.model.idx_vs[jid] != mj.jnt_dofadr[j]:
            raise DescriptionError(self.source, "the compiled joints are not in depth-first "
                                   "order", f"joint {name}")
        return jid, after

    def add_body(self, b: int, jid: int, in_joint: pin.SE3, parent_frame: int) -> None:
        mj, name = self.mj, self.bodies[b]
        mass, moments = float(mj.body_mass[b]), np.array(mj.body_inertia[b], dtype=float)
        check_inertia(mass, np.diag(moments), self.source, f"body {name}")
        self.model.appendBodyToJoint(jid, pin.Inertia(mass, np.zeros(3), np.diag(moments)),
                                     in_joint * _placement(mj.body_ipos[b], mj.body_iquat[b]))
        self.body_frame_ids.append(self.model.addBodyFrame(name, jid, in_joint, parent_frame))
        if mj.body_gravcomp[b] != 0:
            self.unsupported.append(f"gravity compensation of body {name!r}")

    # -- closures ---------------------------------------------------------------------
    def closures(self) -> tuple[ClosureSpec, ...]:
        mj, eq = self.mj, self.mjc.mjtEq
        out = []
        off = self.disabled(self.mjc.mjtDisableBit.mjDSBL_EQUALITY) or \
            self.disabled(self.mjc.mjtDisableBit.mjDSBL_CONSTRAINT)
        for i in range(mj.neq):
            name, kind = self.equalities[i], int(mj.eq_type[i])
            if off or not mj.eq_active0[i]:
                self.skipped.append(name)
            elif kind == eq.mjEQ_JOINT:
                self.coupling(i, name)
            elif kind in (eq.mjEQ_CONNECT, eq.mjEQ_WELD):
                closure = self.closure(i, name, kind == eq.mjEQ_CONNECT)
                if closure is not None:
                    out.append(closure)
            else:
                label = {int(eq.mjEQ_TENDON): "tendon"}.get(kind, eq(kind).name)
                self.unsupported.append(f"{label} equality {name!r}")
        return tuple(out)

    def coupling(self, i: int, name: str) -> None:
        """The joint coupling ``i`` (hinge or slide joints) into :attr:`couplings`, MuJoCo's
        ``q1 - q1_0 = f(q2 - q2_0)`` (``qpos0`` references) written in absolute
        coordinates; another joint type is listed as unsupported."""
        mj = self.mj
        ids = [int(k) for k in (mj.eq_obj1id[i], mj.eq_obj2id[i]) if k >= 0]
        scalar = (int(self.mjc.mjtJoint.mjJNT_HINGE), int(self.mjc.mjtJoint.mjJNT_SLIDE))
        if not all(int(mj.jnt_type[j]) in scalar for j in ids):
            pair = [self.joints[j] for j in ids]
            self.unsupported.append(f"joint coupling {name!r} of a ball or free joint "
                                    f"({' = f('.join(pair)}{')' if len(pair) == 2 else ''})")
            return
        refs = [float(mj.qpos0[mj.jnt_qposadr[j]]) for j in ids] + [0.0]
        self.couplings.append(JointCoupling.shifted(
            name, self.joints[ids[0]], self.joints[ids[1]] if len(ids) == 2 else None,
            [float(c) for c in mj.eq_data[i][:5]], refs[0], refs[1]))

    def closure(self, i: int, name: str, point: bool) -> ClosureSpec | None:
        mj = self.mj
        data, ids = mj.eq_data[i], (int(mj.eq_obj1id[i]), int(mj.eq_obj2id[i]))
        if not point and not data[10] > 0:
            self.unsupported.append(f"weld {name!r} with torquescale {data[10]:g} (no "
                                    "rotational rows)")
            return None
        if int(mj.eq_objtype[i]) == self.mjc.mjtObj.mjOBJ_SITE:
            bodies = tuple(int(mj.site_bodyid[s]) for s in ids)
            offsets = tuple(self.site_placement(s) for s in ids)
        else:
            bodies = ids
            if point:      # anchors in body 1 and body 2 (the second set by the compiler)
                offsets = (_placement(data[0:3]), _placement(data[3:6]))
            else:          # relpose in body 1 against the anchor in body 2
                offsets = (_placement(data[3:6], data[6:10]), _placement(data[0:3]))
        frames = tuple(WORLD if b == 0 else self.bodies[b] for b in bodies)
        return ClosureSpec(name, "point" if point else "weld", frames[0], frames[1], *offsets)

    # -- actuators and effects --------------------------------------------------------
    def actuated(self) -> tuple[tuple[str, ...], dict[str, float], dict[str, float],
                                np.ndarray, np.ndarray]:
        """Actuated joints, gears, effort limits, and the armature and damping the
        actuators add (nv,)."""
        mj, mjc = self.mj, self.mjc
        joints: list[str] = []
        gear: dict[str, float] = {}
        limit: dict[str, float] = {}
        armature, damping = np.zeros(mj.nv), np.zeros(mj.nv)
        for a in range(mj.nu):
            name, j = self.actuators[a], int(mj.actuator_trnid[a, 0])
            if int(mj.actuator_trntype[a]) != mjc.mjtTrn.mjTRN_JOINT or int(mj.jnt_type[j]) \
                    not in (mjc.mjtJoint.mjJNT_HINGE, mjc.mjtJoint.mjJNT_SLIDE):
                self.unsupported.append(f"actuator {name!r} (only joint transmissions on "
                                        "hinge and slide joints are imported)")
                continue
            joint = self.joints[j]
            if joint in gear:
                self.unsupported.append(f"actuator {name!r}: a second actuator on joint "
                                        f"{joint!r}")
                continue
            if np.any(mj.actuator_dampingpoly[a] != 0):
                self.unsupported.append(f"polynomial damping of actuator {name!r}")
            g = float(mj.actuator_gear[a, 0])
            dof = int(mj.jnt_dofadr[j])
            armature[dof] += g * g * float(mj.actuator_armature[a])
            damping[dof] += g * g * float(mj.actuator_damping[a])
            motor = (int(mj.actuator_gaintype[a]) == mjc.mjtGain.mjGAIN_FIXED
                     and int(mj.actuator_biastype[a]) == mjc.mjtBias.mjBIAS_NONE
                     and int(mj.actuator_dyntype[a]) == mjc.mjtDyn.mjDYN_NONE)
            if motor:
                g *= float(mj.actuator_gainprm[a, 0])
            else:
                self.notes.append(f"actuator {name!r}: the joint {joint!r} is actuated with "
                                  "its gear; the servo's gains, bias and dynamics are not "
                                  "imported")
            bound = np.inf
            if mj.actuator_ctrllimited[a]:
                bound = min(bound, abs(g) * float(np.max(np.abs(mj.actuator_ctrlrange[a]))))
            if mj.actuator_forcelimited[a]:
                bound = min(bound, abs(float(mj.actuator_gear[a, 0]))
                            * float(np.max(np.abs(mj.actuator_forcerange[a]))))
            if mj.jnt_actfrclimited[j]:
                bound = min(bound, float(np.max(np.abs(mj.jnt_actfrcrange[j]))))
            if g == 0.0 or not bound > 0.0:
                self.unsupported.append(f"actuator {name!r} with zero gear or force range")
                continue
            joints.append(joint)
            gear[joint], limit[joint] = g, bound
        return tuple(joints), gear, limit, armature, damping

    def joint_effects(self) -> dict[str, Any]:
        """armature, damping, coulomb, stiffness (nv,) and spring_reference (nq,)."""
        mj, mjc = self.mj, self.mjc
        flags = mjc.mjtDisableBit
        damping = np.zeros(mj.nv) if self.disabled(flags.mjDSBL_DAMPER) \
            else np.array(mj.dof_damping, dtype=float)
        coulomb = np.zeros(mj.nv) if (self.disabled(flags.mjDSBL_FRICTIONLOSS)
                                      or self.disabled(flags.mjDSBL_CONSTRAINT)) \
            else np.array(mj.dof_frictionloss, dtype=float)
        stiffness = np.zeros(mj.nv)
        for j in range(mj.njnt):
            name, kind = self.joints[j], int(mj.jnt_type[j])
            dof, ndof = int(mj.jnt_dofadr[j]), {0: 6, 1: 3}.get(kind, 1)
            k = 0.0 if self.disabled(flags.mjDSBL_SPRING) else float(mj.jnt_stiffness[j])
            if np.any(mj.jnt_stiffnesspoly[j] != 0) or np.any(mj.dof_dampingpoly[dof:dof + ndof] != 0):
                self.unsupported.append(f"polynomial spring or damper of joint {name!r}")
            if np.any(mj.jnt_springyield[j] != 0):
                self.unsupported.append(f"plastic spring of joint {name!r}")
            if kind == mjc.mjtJoint.mjJNT_FREE:
                # MuJoCo's translations are in the world frame: an armature there acts on
                # the world-frame acceleration (an extra a (omega x v) in the body frame),
                # a spring or friction per world axis; equal damping is frame-invariant
                if k != 0.0 or np.any(coulomb[dof:dof + 6] != 0) \
                        or np.any(mj.dof_armature[dof:dof + 3] != 0):
                    self.unsupported.append(f"spring, frictionloss or armature of free "
                                            f"joint {name!r}")
                if np.ptp(damping[dof:dof + 3]) != 0.0:
                    self.unsupported.append(f"unequal damping on the translations of free "
                                            f"joint {name!r}")
            else:
                stiffness[dof:dof + ndof] = k
        return {"armature": np.array(mj.dof_armature, dtype=float), "damping": damping,
                "coulomb": coulomb, "stiffness": stiffness,
                "spring_reference": configuration_from_qpos(mj, mj.qpos_spring)}

    def check_rest(self) -> None:
        """Tendons, flexes and fluid forces that the import would drop."""
        mj = self.mj
        names = _Names(self.mjc, mj, self.mjc.mjtObj.mjOBJ_TENDON, mj.ntendon,
                       lambda i: f"tendon{i}")
        for t in range(mj.ntendon):
            fields = {"stiffness": mj.tendon_stiffness[t], "damping": mj.tendon_damping[t],
                      "frictionloss": mj.tendon_frictionloss[t],
                      "armature": mj.tendon_armature[t], "limited": mj.tendon_limited[t]}
            used = [k for k, value in fields.items() if np.any(np.asarray(value) != 0)]
            if used:
                self.unsupported.append(f"tendon {names[t]!r} ({', '.join(used)})")
        if mj.nflex:
            self.unsupported.append(f"{mj.nflex} flex(es)")
        if mj.opt.density > 0 or mj.opt.viscosity > 0:
            self.unsupported.append("fluid forces (<option density / viscosity>)")


def _axis_joint(axis: np.ndarray, aligned: tuple[Any, Any, Any], unaligned: Any) -> Any:
    for k in range(3):
        if np.array_equal(axis, np.eye(3)[k]):
            return aligned[k]()
    return unaligned(float(axis[0]), float(axis[1]), float(axis[2]))


def from_mjmodel(mj_model: Any, source: str = "<MjModel>", *,
                 keyframe: str | int | None = None) -> MjcfImport:
    """Build the closed-loop model of a compiled ``mujoco.MjModel`` (conventions in the
    module docstring).

    Args:
        mj_model: the compiled model.
        source: where it came from, for messages and the model's name.
        keyframe: a keyframe's name or index whose ``qpos`` becomes the ``home``
            configuration; default the file's keyframe named ``home``, else ``qpos0``.

    Raises:
        MissingDependencyError: ``mujoco`` is not installed (extra ``mjcf``).
        DescriptionError: unsupported features (all of them named in one message), an
            unknown keyframe, or a tree Pinocchio refuses.
    """
    mujoco = _mujoco()
    builder = _Builder(mujoco, mj_model, source)
    builder.build_tree()
    closures = builder.closures()
    actuated, gear, limit, act_armature, act_damping = builder.actuated()
    values = builder.joint_effects()
    builder.check_rest()
    if builder.unsupported:
        raise DescriptionError(source, "unsupported MJCF features: "
                               + "; ".join(builder.unsupported), builder.unsupported[0])
    model = builder.model
    for joint in actuated:
        model.effortLimit[model.joints[model.getJointId(joint)].idx_v] = limit[joint]
    if not model.check(model.createData()):
        raise DescriptionError(source, "the tree fails Pinocchio's consistency check")
    references = _references(mujoco, mj_model, source, keyframe)
    for key, q in references.items():
        model.referenceConfigurations[key] = q
    values["armature"] = values["armature"] + act_armature
    values["damping"] = values["damping"] + act_damping
    effects = resolve_effects(model, actuated, JointEffects.rigid(model, len(actuated)),
                              gear=gear, effort_limit=limit, **values)
    name = Path(source).name
    clm = ClosedLoopModel(model, LoopsSpec(closures, actuated,
                                           couplings=tuple(builder.couplings)),
                          name=name, effects=effects)
    return MjcfImport(clm, references, tuple(builder.skipped), tuple(builder.notes), mj_model)


def _references(mujoco: Any, mj: Any, source: str,
                keyframe: str | int | None) -> dict[str, np.ndarray]:
    keys = _Names(mujoco, mj, mujoco.mjtObj.mjOBJ_KEY, mj.nkey, lambda i: f"key{i}")
    out = {"qpos0": configuration_from_qpos(mj, mj.qpos0)}
    for k in range(mj.nkey):
        out.setdefault(keys[k], configuration_from_qpos(mj, mj.key_qpos[k]))
    if keyframe is None:
        out[HOME] = out.get(HOME, out["qpos0"]).copy()
    elif isinstance(keyframe, (int, np.integer)) and not isinstance(keyframe, bool) \
            and 0 <= keyframe < mj.nkey:
        out[HOME] = configuration_from_qpos(mj, mj.key_qpos[int(keyframe)])
    elif isinstance(keyframe, str) and keyframe in keys.names:
        out[HOME] = configuration_from_qpos(mj, mj.key_qpos[keys.names.index(keyframe)])
    else:
        raise DescriptionError(source, f"no keyframe {keyframe!r} (keyframes: "
                                       f"{keys.names}, or an index below {mj.nkey})",
                               str(keyframe))
    return out


def read_mjcf(path: str | os.PathLike[str], *, keyframe: str | int | None = None
              ) -> MjcfImport:
    """Compile an MJCF file with MuJoCo and build its closed-loop model, with the
    reference configurations and what was skipped (see :func:`from_mjmodel`).

    Raises:
        MissingDependencyError: ``mujoco`` is not installed (extra ``mjcf``).
        MissingFileError: the file does not exist.
        DescriptionError: MuJoCo cannot compile it (MuJoCo's
            message), or see :func:`from_mjmodel`.
    """
    mujoco = _mujoco()
    path = Path(path)
    existing_file(path)
    try:
        mj_model = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise DescriptionError(str(path), f"MuJoCo could not compile it: {exc}") from None
    return from_mjmodel(mj_model, str(path), keyframe=keyframe)


def load_mjcf(path: str | os.PathLike[str], *, keyframe: str | int | None = None
              ) -> ClosedLoopModel:
    """The :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel` of an MJCF file
    (:func:`read_mjcf`; its reference configurations are in
    ``clm.model.referenceConfigurations``: ``qpos0``, the keyframes and ``home``).

    Args:
        path: the MJCF (``.xml``) file.
        keyframe: a keyframe's name or index: the ``home`` configuration; default the
            file's keyframe named ``home``, else ``qpos0``.

    Raises:
        MissingDependencyError: ``mujoco`` is not installed (extra ``mjcf``).
        DescriptionError: see :func:`read_mjcf`.
    """
    return read_mjcf(path, keyframe=keyframe).model


def robot_section(result: MjcfImport) -> RobotSection:
    """The ``robot:`` defaults of an imported MJCF for :func:`hexapod_pin.load_robot`: its
    ``home`` configuration (no platform: MJCF does not name one)."""
    return RobotSection(home=tuple(float(x) for x in result.home))

"""Loader for the example-parallel-robots format: ``robot.urdf`` + ``robot.yaml``.

Gepetto's *example-parallel-robots* project (BSD-3) describes a closed-loop robot
as a URDF tree plus a YAML file beside it. This module reads that pair into a
:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`, following the semantics of its
``loader_tools.completeRobotLoader``:

``closed_loop``
    list of pairs ``[frame_A, frame_B]`` of frame names of the URDF model (link,
    joint or fixed-joint frames). Closure ``i`` holds the two frames together.
``type``
    one entry per pair: ``3d`` / ``3D`` -> the two frame ORIGINS coincide (a 3-row
    point closure, Pinocchio's ``CONTACT_3D``); ``6d`` / ``6D`` -> the two frames
    coincide in position and orientation (a 6-row weld, ``CONTACT_6D``). Upstream
    treats anything but ``3d``/``3D`` as 6d; here any other value is an error. When
    ``type`` is absent every closure is 6d (upstream's documented default).
``name_mot``
    the actuated joints (1-DoF joints of the tree).
``joint_name`` / ``joint_type`` (optional, same length)
    joints of the URDF to change before closing the loops: ``SPHERICAL`` (the joint
    becomes a spherical joint at the same placement), ``FIXED`` (the joint is
    locked at its neutral value, ``pin.buildReducedModel``), ``UJOINT_ab`` with
    ``a, b`` in ``X, Y, Z`` (the joint becomes a revolute about its frame's ``a``
    axis named ``<joint>_a`` followed by a revolute about ``b`` named ``<joint>_b``,
    same origin; bodies and frames below it hang from ``<joint>_b``).

Closures are named ``<frame_A>C<frame_B>`` as upstream names its constraint models.

How a 6d closure between frames placed on a revolute axis behaves: upstream's
mechanisms close a loop with a ``6d`` closure between two frames located on the
axis of a revolute joint of the tree (the cut revolute stays in the tree, its
frame is welded). The weld has 6 rows, but the motion it forbids is only what the
cut joint forbade: for a planar loop 3 of the rows are implied by the others
(the out-of-plane ones), so ``J_c`` has redundant rows. The generic core handles
them (rank, least-squares assembly, minimum-norm multipliers); the accelerations
and actuator forces stay unique.

Not reproduced from upstream: ``simplifyModel`` (merging three massless,
concurrent revolute joints into a spherical joint: a modelling shortcut that
does not change the mechanism's motion) and the visual / collision geometry
models (Pinocchio builds them from the same URDF when meshes are needed).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pinocchio as pin

from ..core.closed_loop import ClosedLoopModel
from ..core.description import ClosureSpec, LoopsSpec, build_model, read_text
from ..core.checks import existing_file
from ..core.text_formats import load_yaml
from ..errors import DescriptionError

KEYS = ("closed_loop", "type", "name_mot", "joint_name", "joint_type")
_UJOINT_AXES = {"X": pin.JointModelRX, "Y": pin.JointModelRY, "Z": pin.JointModelRZ}
_FRAME_TYPES = (pin.FrameType.BODY, pin.FrameType.OP_FRAME, pin.FrameType.FIXED_JOINT,
                pin.FrameType.JOINT, pin.FrameType.SENSOR)


@dataclass(frozen=True)
class ParallelRobotSpec:
    """A parsed ``robot.yaml``.

    Attributes:
        closed_loop: frame-name pairs, one per closure.
        types: ``"3d"`` or ``"6d"`` per closure (lower case).
        name_mot: actuated joint names.
        joint_name: joints to change (may be empty).
        joint_type: their new types (``SPHERICAL``, ``FIXED``, ``UJOINT_ab``).
    """

    closed_loop: tuple[tuple[str, str], ...]
    types: tuple[str, ...]
    name_mot: tuple[str, ...]
    joint_name: tuple[str, ...] = ()
    joint_type: tuple[str, ...] = ()

    def closure_name(self, index: int) -> str:
        """Name of closure ``index``: ``<frame_A>C<frame_B>`` (upstream's naming)."""
        first, second = self.closed_loop[index]
        return f"{first}C{second}"


def parse_robot_yaml(text: str, source: str = "<robot.yaml>") -> ParallelRobotSpec:
    """Parse the YAML text of an example-parallel-robots ``robot.yaml``.

    Raises:
        DescriptionError: malformed YAML (culprit: ``line N``), not a mapping, an
            unknown key, a ``closed_loop`` entry that is not a pair of names, a
            ``type`` list of another length or with an unknown value, a missing or
            malformed ``name_mot``, ``joint_name`` without ``joint_type`` (or of
            another length), or an unknown joint type. ``culprit`` names the entry.
    """
    data = load_yaml(text, source)
    if not isinstance(data, dict):
        raise DescriptionError(source, "robot.yaml must be a YAML mapping")
    unknown = sorted(set(data) - set(KEYS))
    if unknown:
        raise DescriptionError(source, f"unknown keys {unknown} (known: {list(KEYS)})",
                               unknown[0])
    raw_pairs = data.get("closed_loop") or []
    if not isinstance(raw_pairs, list):
        raise DescriptionError(source, "'closed_loop' must be a list of [frame, frame] pairs",
                               "closed_loop")
    pairs = []
    for index, pair in enumerate(raw_pairs):
        if (not isinstance(pair, (list, tuple)) or len(pair) != 2
                or not all(isinstance(n, str) and n for n in pair)):
            raise DescriptionError(source, f"closed_loop[{index}] is not a pair of frame names: "
                                           f"{pair!r}", f"closed_loop[{index}]")
        if pair[0] == pair[1]:
            raise DescriptionError(source, f"closed_loop[{index}] joins frame {pair[0]!r} to "
                                           "itself", pair[0])
        pairs.append((pair[0], pair[1]))
    raw_types = data.get("type", ["6d"] * len(pairs))
    if not isinstance(raw_types, list) or len(raw_types) != len(pairs):
        raise DescriptionError(source, f"'type' must list one of 3d/6d per closed_loop pair "
                                       f"({len(pairs)}), got {raw_types!r}", "type")
    types = []
    for index, value in enumerate(raw_types):
        text_value = str(value).lower()
        if text_value not in ("3d", "6d"):
            raise DescriptionError(source, f"type[{index}] = {value!r} is not 3d or 6d",
                                   f"type[{index}]")
        types.append(text_value)
    name_mot = data.get("name_mot")
    if not isinstance(name_mot, list) or not all(isinstance(n, str) for n in name_mot):
        raise DescriptionError(source, "'name_mot' must be a list of joint names", "name_mot")
    if len(set(name_mot)) != len(name_mot):
        dup = min(n for n in name_mot if name_mot.count(n) > 1)
        raise DescriptionError(source, f"motor {dup!r} listed twice", dup)
    joint_name = data.get("joint_name", [])
    joint_type = data.get("joint_type", [])
    if (not isinstance(joint_name, list) or not isinstance(joint_type, list)
            or len(joint_name) != len(joint_type)):
        raise DescriptionError(source, "'joint_name' and 'joint_type' must be lists of the "
                                       "same length", "joint_type")
    for name, jtype in zip(joint_name, joint_type):
        if not _valid_joint_type(jtype):
            raise DescriptionError(source, f"joint_type {jtype!r} of {name!r} is not SPHERICAL, "
                                           "FIXED or UJOINT_ab (a, b in X, Y, Z)", str(name))
    if len(set(joint_name)) != len(joint_name):
        raise DescriptionError(source, "a joint is listed twice in joint_name", "joint_name")
    return ParallelRobotSpec(tuple(pairs), tuple(types), tuple(name_mot),
                             tuple(str(n) for n in joint_name), tuple(str(t) for t in joint_type))


def _valid_joint_type(jtype) -> bool:
    if jtype in ("SPHERICAL", "FIXED"):
        return True
    return (isinstance(jtype, str) and len(jtype) == 9 and jtype.startswith("UJOINT_")
            and jtype[-2] in _UJOINT_AXES and jtype[-1] in _UJOINT_AXES
            and jtype[-2] != jtype[-1])


def load_robot_yaml(path: str | Path) -> ParallelRobotSpec:
    """Read and parse a ``robot.yaml`` file (see :func:`parse_robot_yaml`)."""
    return parse_robot_yaml(read_text(path), source=str(path))


def apply_joint_types(model: pin.Model, spec: ParallelRobotSpec,
                      source: str = "<robot>") -> pin.Model:
    """The tree with the ``joint_name`` / ``joint_type`` changes applied.

    The joint order (depth-first) is kept; a ``UJOINT_ab`` adds a joint right after
    its first half. Inertias stay on the same bodies (on ``<joint>_b`` for a
    universal joint); frames keep their names and placements.

    Raises:
        DescriptionError: a listed joint not in the tree (culprit: its name).
    """
    changes = dict(zip(spec.joint_name, spec.joint_type))
    for name in changes:
        if not model.existJointName(name):
            raise DescriptionError(source, f"joint_name {name!r} is not a joint of the URDF",
                                   name)
    if not changes:
        return pin.Model(model)
    new = pin.Model()
    new.name = model.name
    new.gravity = model.gravity
    joint_map = {0: 0}        # old joint id -> new joint id carrying the old body
    for jid in range(1, model.njoints):
        parent = joint_map[model.parents[jid]]
        name = model.names[jid]
        placement = model.jointPlacements[jid]
        old = model.joints[jid]
        jtype = changes.get(name)
        if jtype is not None and jtype.startswith("UJOINT_"):
            first = new.addJoint(parent, _UJOINT_AXES[jtype[-2]](), placement,
                                 f"{name}_{jtype[-2]}")
            new_id = new.addJoint(first, _UJOINT_AXES[jtype[-1]](), pin.SE3.Identity(),
                                  f"{name}_{jtype[-1]}")
        elif jtype == "SPHERICAL":
            new_id = new.addJoint(parent, pin.JointModelSpherical(), placement, name)
        else:
            lo, hi = old.idx_q, old.idx_q + old.nq
            vlo, vhi = old.idx_v, old.idx_v + old.nv
            new_id = new.addJoint(parent, old, placement, name,
                                  model.effortLimit[vlo:vhi], model.velocityLimit[vlo:vhi],
                                  model.lowerPositionLimit[lo:hi], model.upperPositionLimit[lo:hi])
        new.appendBodyToJoint(new_id, model.inertias[jid], pin.SE3.Identity())
        joint_map[jid] = new_id
    frame_map = {0: 0}
    for fid in range(1, len(model.frames)):
        frame = model.frames[fid]
        parent_frame = frame_map.get(frame.parentFrame, 0)
        jtype = changes.get(frame.name) if frame.type == pin.FrameType.JOINT else None
        if jtype is not None and jtype.startswith("UJOINT_"):
            first = new.addJointFrame(new.getJointId(f"{frame.name}_{jtype[-2]}"), parent_frame)
            frame_map[fid] = new.addJointFrame(new.getJointId(f"{frame.name}_{jtype[-1]}"), first)
            continue
        if frame.type == pin.FrameType.JOINT:
            frame_map[fid] = new.addJointFrame(joint_map[frame.parentJoint], parent_frame)
            continue
        frame_map[fid] = new.addFrame(pin.Frame(frame.name, joint_map[frame.parentJoint],
                                                parent_frame, frame.placement, frame.type),
                                      False)
    fixed = [new.getJointId(n) for n, t in changes.items() if t == "FIXED"]
    if fixed:
        new = pin.buildReducedModel(new, fixed, pin.neutral(new))
    return new


def closures_from_spec(model: pin.Model, spec: ParallelRobotSpec,
                       source: str = "<robot>") -> tuple[ClosureSpec, ...]:
    """The closures of ``spec`` as generic :class:`ClosureSpec` (identity offsets).

    Raises:
        DescriptionError: a frame name that is not in the model, or that names
            several different frames (culprit: the frame name); a closure whose two
            frames are on the same body (culprit: the closure name).
    """
    out = []
    for index, ((first, second), ctype) in enumerate(zip(spec.closed_loop, spec.types)):
        name = spec.closure_name(index)
        joints = [_unique_frame(model, frame, source).parentJoint for frame in (first, second)]
        if joints[0] == joints[1]:
            raise DescriptionError(source, f"closure {name!r}: frames {first!r} and {second!r} "
                                           f"are on the same body (joint "
                                           f"{model.names[joints[0]]!r})", name)
        out.append(ClosureSpec(name, "point" if ctype == "3d" else "weld", first, second,
                               pin.SE3.Identity(), pin.SE3.Identity()))
    return tuple(out)


def _unique_frame(model: pin.Model, name: str, source: str) -> pin.Frame:
    matches = [f for f in model.frames if f.name == name and f.type in _FRAME_TYPES]
    if not matches:
        raise DescriptionError(source, f"frame {name!r} is not in the model", name)
    first = matches[0]
    for other in matches[1:]:
        if other.parentJoint != first.parentJoint or not other.placement.isApprox(first.placement):
            raise DescriptionError(source, f"frame name {name!r} names several different "
                                           "frames (a link and a joint?)", name)
    return first


def load_parallel_robot(path: str | Path, urdf_name: str = "robot.urdf",
                        yaml_name: str = "robot.yaml", free_flyer: bool = False
                        ) -> ClosedLoopModel:
    """Load an example-parallel-robots folder (URDF + ``robot.yaml``).

    Args:
        path: the folder holding both files (or the URDF file itself, the YAML
            then being ``yaml_name`` beside it).
        urdf_name: the URDF file's name inside the folder.
        yaml_name: the loops file's name inside the folder.
        free_flyer: add a ``pin.JointModelFreeFlyer`` root joint (named
            ``root_joint``) as upstream's ``freeflyer=True``; else the URDF root
            is fixed to the world.

    Returns:
        The :class:`ClosedLoopModel` (name: the folder name), actuated joints in
        ``name_mot`` order.

    Raises:
        DescriptionError: any malformed input; ``culprit`` names the frame, joint,
            closure or YAML entry at fault (see :func:`parse_robot_yaml`,
            :func:`apply_joint_types`, :func:`closures_from_spec`), including an
            actuated joint that is not in the tree.
    """
    path = Path(path)
    folder = path if path.is_dir() else path.parent
    urdf = folder / urdf_name if path.is_dir() else path
    existing_file(urdf)
    spec = load_robot_yaml(folder / yaml_name)
    source = str(folder)
    try:
        tree = build_model(read_text(urdf), source=str(urdf),
                           root_joint=pin.JointModelFreeFlyer() if free_flyer else None)
    except DescriptionError:
        raise
    except Exception as exc:  # Pinocchio raises plain RuntimeError / ValueError
        raise DescriptionError(str(urdf), f"Pinocchio could not parse the URDF: {exc}") from exc
    model = apply_joint_types(tree, spec, source)
    if not model.check(model.createData()):
        raise DescriptionError(source, "model fails Pinocchio's consistency check")
    for motor in spec.name_mot:
        if not model.existJointName(motor):
            raise DescriptionError(source, f"actuated joint {motor!r} (name_mot) is not a joint "
                                           "of the tree", motor)
    closures = closures_from_spec(model, spec, source)
    return ClosedLoopModel(model, LoopsSpec(closures, spec.name_mot), name=folder.name)

"""A small SDFormat reader: SDF -> Pinocchio tree + loop closures (and -> URDF + loops).

Pinocchio's Python wheel has no SDF parser (``pin.WITH_SDFORMAT`` is False), and SDF
is how some robots with closed kinematic loops are described (Cassie in
``example-robot-data``). This module reads the subset of SDFormat 1.4 - 1.9 that
such models use:

* ``<model>`` with ``<link>``, ``<joint>`` and ``<frame>`` children (one model, no
  nesting, no ``<include>``);
* poses as ``x y z roll pitch yaw`` (rad, ``R = Rz(yaw) Ry(pitch) Rx(roll)``) or
  with ``degrees="true"`` / ``rotation_format="quat_xyzw"``;
* pose frames: ``relative_to`` (SDF >= 1.7) or the legacy ``frame`` attribute,
  naming a link, a joint, a ``<frame>`` or ``__model__``. Defaults follow the
  specification: a link pose is relative to the model frame, a joint pose to its
  child link, a frame pose to its ``attached_to`` frame, and inertial / visual /
  collision poses to their link;
* joint types ``revolute``, ``continuous``, ``prismatic``, ``fixed``, ``ball``,
  ``universal``; axes in the joint frame, or per ``expressed_in`` (>= 1.7) or
  ``use_parent_model_frame`` (<= 1.6);
* inertials (mass, inertia in the inertial frame; the SDF defaults, 1 kg and a unit
  inertia, when absent), limits, damping, friction, spring reference and stiffness;
* visual geometry (box, cylinder, sphere, mesh) is read and kept for drawing.

A link graph with loops is cut into a spanning tree (joints followed from parent to
child, non-ball joints preferred; ``cut=`` chooses by hand). Each joint left out of
the tree becomes a closure of the generic loops format (see
:mod:`hexapod_pin.core.description`): a ``ball`` joint a 3-D point closure (a ball joint
is exactly a point-on-point constraint), a ``fixed`` joint a weld. The tree is
built in depth-first order (Pinocchio's algorithms silently give wrong numbers
otherwise).

Frames of the Pinocchio tree: every link is a ``BODY`` frame named as the link
(its SDF link frame), every moving joint a ``JOINT`` frame (its SDF joint frame),
every fixed joint a ``FIXED_JOINT`` frame, every ``<frame>`` an ``OP_FRAME``.
A moving joint's Pinocchio frame is its SDF joint frame at the zero configuration
(for a ``continuous`` joint, turned so that its z axis is the SDF axis: Pinocchio's
unbounded revolute joint takes no arbitrary axis); ``pin.neutral`` reproduces the poses
written in the file. Joint limits go to the model (``lowerPositionLimit``,
``effortLimit``, ...); the joint dynamics of each tree joint (``<axis><dynamics>``:
``damping``, ``friction``, ``spring_stiffness``, ``spring_reference``) become its joint
effects (:mod:`hexapod_pin.core.effects`: damping, Coulomb friction, stiffness and the
spring reference, a displacement from the neutral configuration), carried by the loops
(an ``effects`` section, :class:`~hexapod_pin.core.description.EffectsSection`) and also
written into Pinocchio's ``model.damping`` / ``model.friction``. They apply to every
velocity coordinate of the joint (a universal joint's ``<axis2>`` is not read); a cut
joint (a closure) has no coordinate and keeps none.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..core.closed_loop import ClosedLoopModel
from ..core.description import (MAX_COORDINATE, WORLD, ClosureSpec, EffectsSection, LoopsSpec,
                                check_inertia, read_text)
from ..errors import DescriptionError

MODEL_FRAME = "__model__"
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "ball", "universal")
_UNSUPPORTED_JOINTS = ("revolute2", "screw", "gearbox")
_SUPPORTED_VERSIONS = ("1.4", "1.5", "1.6", "1.7", "1.8", "1.9", "1.10", "1.11")


# --------------------------------------------------------------------------- data
@dataclass(frozen=True)
class SdfInertial:
    """Inertial element of a link.

    Attributes:
        mass: kg.
        placement: pose of the inertial frame (centre of mass) in the link frame.
        inertia: 3x3 rotational inertia about the centre of mass, in the
            inertial frame's axes (kg m^2).
    """

    mass: float
    placement: pin.SE3
    inertia: np.ndarray


@dataclass(frozen=True)
class SdfGeometry:
    """A visual (or collision) shape of a link.

    Attributes:
        name: the element's name.
        kind: ``"box"``, ``"cylinder"``, ``"sphere"`` or ``"mesh"``.
        size: box (x, y, z), cylinder (radius, length), sphere (radius,), mesh ().
        placement: pose of the shape in the link frame.
        uri: mesh URI as written (``""`` for primitives).
        scale: mesh scale (3,).
        rgba: colour from ``<material><ambient>`` / ``<diffuse>`` if given.
    """

    name: str
    kind: str
    size: tuple[float, ...]
    placement: pin.SE3
    uri: str = ""
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    rgba: tuple[float, float, float, float] | None = None


@dataclass(frozen=True)
class SdfLink:
    """A link: its pose in the model frame at the zero configuration, inertial, visuals."""

    name: str
    pose: pin.SE3
    inertial: SdfInertial
    visuals: tuple[SdfGeometry, ...] = ()


@dataclass(frozen=True)
class SdfJoint:
    """A joint of the SDF.

    Attributes:
        name: as written.
        type: as written.
        parent: as written (may be ``"world"``).
        child: as written.
        pose: the joint frame in the model frame at the zero configuration.
        axis: unit axis in the joint frame (revolute / prismatic / universal 1st).
        axis2: unit second axis of a universal joint, in the joint frame.
        lower: lower position limit (rad or m; -inf when absent).
        upper: upper position limit (rad or m; +inf when absent).
        effort: effort limit (N m or N; inf when absent or < 0).
        velocity: velocity limit (rad/s or m/s; inf when absent or < 0).
        damping: viscous damping (N m s/rad or N s/m), >= 0.
        friction: Coulomb friction (N m or N), >= 0.
        spring_reference: joint spring rest position (rad or m).
        spring_stiffness: joint spring stiffness (N m/rad or N/m), >= 0.
    """

    name: str
    type: str
    parent: str
    child: str
    pose: pin.SE3
    axis: np.ndarray
    axis2: np.ndarray
    lower: float = -math.inf
    upper: float = math.inf
    effort: float = math.inf
    velocity: float = math.inf
    damping: float = 0.0
    friction: float = 0.0
    spring_reference: float = 0.0
    spring_stiffness: float = 0.0


@dataclass(frozen=True)
class SdfFrame:
    """An explicit ``<frame>``: its pose in the model frame and the link it moves with."""

    name: str
    pose: pin.SE3
    link: str


@dataclass(frozen=True)
class SdfModel:
    """A parsed SDF model (all poses resolved to the model frame, zero configuration).

    Attributes:
        name: model name.
        version: SDF version string.
        pose: the model frame in the world (``<model><pose>``).
        links: links in document order.
        joints: joints in document order.
        frames: explicit frames in document order.
        source: file or label, for messages.
        base_dir: folder of the file (to resolve relative mesh URIs), if known.
    """

    name: str
    version: str
    pose: pin.SE3
    links: tuple[SdfLink, ...]
    joints: tuple[SdfJoint, ...]
    frames: tuple[SdfFrame, ...]
    source: str = "<sdf>"
    base_dir: Path | None = None

    def link(self, name: str) -> SdfLink:
        """The link called ``name``; raises DescriptionError naming it."""
        for link in self.links:
            if link.name == name:
                return link
        raise DescriptionError(self.source, f"no link {name!r}", name)

    def joint(self, name: str) -> SdfJoint:
        """The joint called ``name``; raises DescriptionError naming it."""
        for joint in self.joints:
            if joint.name == name:
                return joint
        raise DescriptionError(self.source, f"no joint {name!r}", name)


@dataclass(frozen=True)
class SdfTree:
    """The Pinocchio tree and the loop closures made from an SDF model.

    Attributes:
        model: the ``pin.Model`` (joints in depth-first order, ``model.check`` holds).
        loops: closures from the cut joints and the actuated joints.
        root_link: the link at the root of the tree.
        tree_joints: SDF joints kept in the tree, in the order they were added.
        cut_joints: SDF joints turned into closures.
        sdf: the parsed SDF.
    """

    model: pin.Model
    loops: LoopsSpec
    root_link: str
    tree_joints: tuple[str, ...]
    cut_joints: tuple[str, ...]
    sdf: SdfModel


# ------------------------------------------------------------------------ parsing
def load_sdf(path: str | os.PathLike[str], snap_angles: float = 0.0) -> SdfModel:
    """Read and parse an SDF file (see :func:`parse_sdf`)."""
    path = Path(path)
    return parse_sdf(read_text(path), source=str(path), base_dir=path.parent,
                     snap_angles=snap_angles)


def parse_sdf(text: str, source: str = "<sdf>", base_dir: Path | None = None,
              snap_angles: float = 0.0) -> SdfModel:
    """Parse SDF text into an :class:`SdfModel` with every pose in the model frame.

    Args:
        text: the SDF XML.
        source: file name or label used in error messages.
        base_dir: folder against which relative mesh URIs are resolved.
        snap_angles: pose angles (roll, pitch, yaw, rad) closer than this to a
            multiple of pi/2 are replaced by that multiple. Files written with
            four decimals (``1.5708`` for pi/2) otherwise tilt axes that are meant
            to be parallel by ~1e-6 rad, and a planar loop becomes a very slightly
            spatial one (a singular value ~1e-12 instead of 0). 0 (default): keep
            the numbers as written.

    Raises:
        DescriptionError: malformed XML, no ``<model>``, nested models or includes,
            duplicate names, a pose, axis, inertial or limit that is not numeric
            or not valid, an unknown joint type, a joint naming a link that does
            not exist, or a pose frame that does not exist or is cyclic. The
            ``culprit`` names the element at fault.
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise DescriptionError(source, f"malformed XML: {exc}") from None
    if root.tag != "sdf":
        raise DescriptionError(source, f"root element is <{root.tag}>, expected <sdf>", root.tag)
    version = root.get("version", "1.6")
    if version not in _SUPPORTED_VERSIONS:
        raise DescriptionError(source, f"unsupported SDF version {version!r}", "version")
    models = root.findall("model")
    if len(models) != 1:
        raise DescriptionError(source, f"expected exactly one <model>, found {len(models)}",
                               "model")
    xml_model = models[0]
    name = xml_model.get("name", "model")
    for tag in ("model", "include"):
        nested = xml_model.find(tag)
        if nested is not None:
            raise DescriptionError(source, f"<{tag}> inside a model is not supported",
                                   nested.get("name", tag))
    if not (math.isfinite(snap_angles) and 0.0 <= snap_angles < math.pi / 4):
        raise DescriptionError(source, f"snap_angles={snap_angles!r} must lie in [0, pi/4)",
                               "snap_angles")
    return _ModelParser(xml_model, name, version, source, base_dir, snap_angles).parse()


class _ModelParser:
    """Resolves the pose-frame graph of one ``<model>`` and builds the dataclasses."""

    def __init__(self, xml_model, name, version, source, base_dir, snap_angles=0.0):
        self.xml = xml_model
        self.snap = snap_angles
        self.name = name
        self.version = version
        self.legacy = _version_tuple(version) < (1, 7)
        self.source = source
        self.base_dir = base_dir
        self.xml_links = {}
        self.xml_joints = {}
        self.xml_frames = {}
        for tag, table in (("link", self.xml_links), ("joint", self.xml_joints),
                           ("frame", self.xml_frames)):
            for element in xml_model.findall(tag):
                elname = element.get("name")
                if not elname:
                    raise DescriptionError(source, f"a <{tag}> has no name", tag)
                if elname in table:
                    raise DescriptionError(source, f"duplicate {tag} name {elname!r}", elname)
                table[elname] = element
        for elname in self.xml_frames:
            if elname in self.xml_links or elname in self.xml_joints:
                raise DescriptionError(source, f"frame name {elname!r} is also a link or "
                                               "joint name", elname)
        if not self.xml_links:
            raise DescriptionError(source, "the model has no <link>", name)
        self._resolved: dict[str, pin.SE3] = {MODEL_FRAME: pin.SE3.Identity()}
        self._visiting: list[str] = []

    # -- poses ------------------------------------------------------------------
    def pose_of(self, frame: str, culprit: str) -> pin.SE3:
        """Pose of a named frame in the model frame (zero configuration)."""
        if frame in self._resolved:
            return self._resolved[frame]
        if frame in self._visiting:
            cycle = " -> ".join(self._visiting[self._visiting.index(frame):] + [frame])
            raise DescriptionError(self.source, f"pose frames form a cycle: {cycle}", frame)
        self._visiting.append(frame)
        if frame in self.xml_links:
            element, default = self.xml_links[frame], MODEL_FRAME
        elif frame in self.xml_joints:
            element = self.xml_joints[frame]
            default = _text(element, "child", self.source, frame)
        elif frame in self.xml_frames:
            element = self.xml_frames[frame]
            default = element.get("attached_to") or MODEL_FRAME
        else:
            self._visiting.pop()
            raise DescriptionError(self.source, f"pose frame {frame!r} does not exist", culprit)
        raw, relative_to = self._raw_pose(element.find("pose"), frame)
        base = self.pose_of(relative_to or default, frame)
        self._visiting.pop()
        self._resolved[frame] = base * raw
        return self._resolved[frame]

    def _raw_pose(self, element, culprit: str) -> tuple[pin.SE3, str | None]:
        if element is None:
            return pin.SE3.Identity(), None
        relative_to = element.get("relative_to") or element.get("frame") or None
        return _parse_pose(element, self.source, culprit, self.snap), relative_to

    def local_pose(self, element, link: str, culprit: str) -> pin.SE3:
        """Pose of an inertial / visual element in its link's frame."""
        raw, relative_to = self._raw_pose(None if element is None else element.find("pose"),
                                          culprit)
        if relative_to is None or relative_to == link:
            return raw
        return self.pose_of(link, culprit).actInv(self.pose_of(relative_to, culprit) * raw)

    # -- elements ---------------------------------------------------------------
    def parse(self) -> SdfModel:
        model_pose, _ = self._raw_pose(self.xml.find("pose"), self.name)
        links = tuple(self._link(name, el) for name, el in self.xml_links.items())
        joints = tuple(self._joint(name, el) for name, el in self.xml_joints.items())
        frames = tuple(SdfFrame(name, self.pose_of(name, name), self._attached_link(name))
                       for name in self.xml_frames)
        return SdfModel(self.name, self.version, model_pose, links, joints, frames,
                        self.source, self.base_dir)

    def _attached_link(self, frame: str, seen: tuple[str, ...] = ()) -> str:
        if frame in seen:
            raise DescriptionError(self.source, "attached_to frames form a cycle", frame)
        if frame in self.xml_links:
            return frame
        if frame in self.xml_joints:
            return _text(self.xml_joints[frame], "child", self.source, frame)
        if frame == MODEL_FRAME:  # the canonical link: named, or the first one
            canonical = self.xml.get("canonical_link") or next(iter(self.xml_links))
            if canonical not in self.xml_links:
                raise DescriptionError(self.source, f"canonical_link {canonical!r} is not a "
                                                    "link", canonical)
            return canonical
        if frame not in self.xml_frames:
            raise DescriptionError(self.source, f"frame {frame!r} does not exist", frame)
        target = self.xml_frames[frame].get("attached_to") or MODEL_FRAME
        return self._attached_link(target, seen + (frame,))

    def _link(self, name: str, element) -> SdfLink:
        pose = self.pose_of(name, name)
        xml_inertial = element.find("inertial")
        if xml_inertial is None:  # SDF default inertial
            inertial = SdfInertial(1.0, pin.SE3.Identity(), np.eye(3))
        else:
            inertial = self._inertial(xml_inertial, name)
        visuals = tuple(self._geometry(v, name) for v in element.findall("visual"))
        return SdfLink(name, pose, inertial, tuple(v for v in visuals if v is not None))

    def _inertial(self, element, link: str) -> SdfInertial:
        mass = _float(element, "mass", 1.0, self.source, link)
        inertia = np.eye(3)
        xml_inertia = element.find("inertia")
        if xml_inertia is not None:
            vals = {k: _float(xml_inertia, k, 1.0 if k in ("ixx", "iyy", "izz") else 0.0,
                              self.source, link)
                    for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")}
            inertia = np.array([[vals["ixx"], vals["ixy"], vals["ixz"]],
                                [vals["ixy"], vals["iyy"], vals["iyz"]],
                                [vals["ixz"], vals["iyz"], vals["izz"]]])
        check_inertia(mass, inertia, self.source, link)
        return SdfInertial(mass, self.local_pose(element, link, link), inertia)

    def _geometry(self, element, link: str) -> SdfGeometry | None:
        name = element.get("name", f"{link}_visual")
        geom = element.find("geometry")
        if geom is None:
            return None
        placement = self.local_pose(element, link, name)
        rgba: tuple[float, float, float, float] | None = None
        material = element.find("material")
        if material is not None:
            for tag in ("diffuse", "ambient"):
                if material.find(tag) is not None:
                    values = _numbers(material.find(tag).text, self.source, name)
                    if len(values) in (3, 4):
                        rgba = (values[0], values[1], values[2],
                                values[3] if len(values) == 4 else 1.0)
                    break
        if geom.find("box") is not None:
            size = _vec(geom.find("box").find("size"), 3, self.source, name)
            return SdfGeometry(name, "box", tuple(size), placement, rgba=rgba)
        if geom.find("cylinder") is not None:
            cyl = geom.find("cylinder")
            return SdfGeometry(name, "cylinder", (_float(cyl, "radius", 1.0, self.source, name),
                                                  _float(cyl, "length", 1.0, self.source, name)),
                               placement, rgba=rgba)
        if geom.find("sphere") is not None:
            radius = _float(geom.find("sphere"), "radius", 1.0, self.source, name)
            return SdfGeometry(name, "sphere", (radius,), placement, rgba=rgba)
        if geom.find("mesh") is not None:
            mesh = geom.find("mesh")
            uri = _text(mesh, "uri", self.source, name)
            scale = (1.0, 1.0, 1.0)
            if mesh.find("scale") is not None:
                scale = tuple(_vec(mesh.find("scale"), 3, self.source, name))
            return SdfGeometry(name, "mesh", (), placement, uri=uri, scale=scale, rgba=rgba)
        return None  # other shapes (plane, heightmap, ...) are not drawn

    def _joint(self, name: str, element) -> SdfJoint:
        jtype = element.get("type", "")
        if jtype in _UNSUPPORTED_JOINTS or jtype not in JOINT_TYPES:
            raise DescriptionError(self.source, f"joint type {jtype!r} is not supported "
                                                f"(supported: {', '.join(JOINT_TYPES)})", name)
        parent = _text(element, "parent", self.source, name)
        child = _text(element, "child", self.source, name)
        for role, link in (("parent", parent), ("child", child)):
            if link not in self.xml_links and not (role == "parent" and link == WORLD):
                raise DescriptionError(self.source, f"joint {name!r}: {role} link {link!r} "
                                                    "does not exist", name)
        if parent == child:
            raise DescriptionError(self.source, f"joint {name!r} joins link {child!r} to "
                                                "itself", name)
        pose = self.pose_of(name, name)
        axis = self._axis(element.find("axis"), name, pose)
        axis2 = self._axis(element.find("axis2"), name, pose, default=(0.0, 1.0, 0.0))
        if jtype == "universal" and abs(float(axis @ axis2)) > 1e-9:
            raise DescriptionError(self.source, "universal joint axes are not orthogonal", name)
        lower, upper, effort, velocity = -math.inf, math.inf, math.inf, math.inf
        damping = friction = spring_ref = spring_k = 0.0
        xml_axis = element.find("axis")
        if xml_axis is not None:
            limit = xml_axis.find("limit")
            if limit is not None:
                lower = _float(limit, "lower", -math.inf, self.source, name)
                upper = _float(limit, "upper", math.inf, self.source, name)
                effort = _float(limit, "effort", math.inf, self.source, name)
                velocity = _float(limit, "velocity", math.inf, self.source, name)
                effort = math.inf if effort < 0 else effort  # SDF: -1 means no limit
                velocity = math.inf if velocity < 0 else velocity
                if lower > upper:
                    raise DescriptionError(self.source, f"lower limit {lower} > upper {upper}",
                                           name)
            dyn = xml_axis.find("dynamics")
            if dyn is not None:
                damping = _float(dyn, "damping", 0.0, self.source, name)
                friction = _float(dyn, "friction", 0.0, self.source, name)
                spring_ref = _float(dyn, "spring_reference", 0.0, self.source, name)
                spring_k = _float(dyn, "spring_stiffness", 0.0, self.source, name)
                for tag, value in (("damping", damping), ("friction", friction),
                                   ("spring_stiffness", spring_k)):
                    if not (math.isfinite(value) and value >= 0.0):
                        raise DescriptionError(self.source, f"<dynamics><{tag}> must be "
                                                            f"finite and >= 0, got {value!r}",
                                               name)
                if not math.isfinite(spring_ref):
                    raise DescriptionError(self.source, "<dynamics><spring_reference> must "
                                                        "be finite", name)
        if jtype == "continuous":
            lower, upper = -math.inf, math.inf
        return SdfJoint(name, jtype, parent, child, pose, axis, axis2, lower, upper, effort,
                        velocity, damping, friction, spring_ref, spring_k)

    def _axis(self, element, joint: str, joint_pose: pin.SE3,
              default=(0.0, 0.0, 1.0)) -> np.ndarray:
        if element is None or element.find("xyz") is None:
            return np.array(default, dtype=float)
        xyz_el = element.find("xyz")
        xyz = _vec(xyz_el, 3, self.source, joint)
        norm = float(np.linalg.norm(xyz))
        if norm < 1e-12:
            raise DescriptionError(self.source, "joint axis has zero length", joint)
        xyz = xyz / norm
        expressed_in = xyz_el.get("expressed_in")
        use_parent = element.find("use_parent_model_frame")
        if self.legacy and use_parent is not None and use_parent.text.strip() in ("1", "true"):
            expressed_in = MODEL_FRAME
        if expressed_in is None or expressed_in == joint:
            return xyz
        rot = self.pose_of(expressed_in, joint).rotation
        return joint_pose.rotation.T @ rot @ xyz


# ----------------------------------------------------------------------- the tree
def build_tree(sdf: SdfModel, root_joint: pin.JointModel | None = None,
               root_link: str | None = None, cut: Iterable[str] | None = None,
               actuated: Sequence[str] = (), root_joint_name: str = "root_joint") -> SdfTree:
    """Cut the SDF link graph into a spanning tree, build it, and close the loops.

    Args:
        sdf: the parsed model.
        root_joint: joint attaching the root link to the world (e.g.
            ``pin.JointModelFreeFlyer()``); its frame is the root link's frame
            (``pin.neutral`` puts the root link at the world origin). ``None``:
            the root link is fixed at its SDF pose (times ``<model><pose>``), or
            attached by the SDF joint whose parent is ``world``.
        root_link: the root; default the only link that is no joint's child.
        cut: SDF joints to leave out of the tree (each becomes a closure); default:
            chosen automatically, keeping non-ball joints in the tree first.
        actuated: joint names recorded as actuated in the loops.
        root_joint_name: name of ``root_joint`` in the model.

    Returns:
        An :class:`SdfTree`. Closure ``j`` (named as the SDF joint) has
        ``frame1`` = its child link, ``frame2`` = its parent link (or ``"world"``),
        both offsets placing the SDF joint frame.

    Raises:
        DescriptionError: no root or several, a link unreachable from the root
            by parent-to-child joints, a cut joint that is not ``ball`` or
            ``fixed``, a ``cut`` name that is not a joint, or an SDF joint to
            ``world`` together with ``root_joint``.
    """
    source = sdf.source
    cut_set = set(cut or ())
    for name in cut_set:
        sdf.joint(name)
    world_joints = [j for j in sdf.joints if j.parent == WORLD and j.name not in cut_set]
    root = _choose_root(sdf, root_link, world_joints, cut_set)
    root_attachment = None
    if world_joints:
        if len(world_joints) > 1 or world_joints[0].child != root:
            raise DescriptionError(source, "only the root link may be attached to the world "
                                           "by a tree joint", world_joints[-1].name)
        if root_joint is not None:
            raise DescriptionError(source, "the SDF attaches the root to the world; do not "
                                           "also pass root_joint", world_joints[0].name)
        root_attachment = world_joints[0]
    tree, cuts = _spanning_tree(sdf, root, cut_set, root_attachment)
    builder = _TreeBuilder(sdf)
    builder.add_root(root, root_joint, root_joint_name, root_attachment)
    children: dict[str, list[SdfJoint]] = {}
    for joint in tree:
        children.setdefault(joint.parent, []).append(joint)

    order: list[str] = []

    def visit(link: str) -> None:  # depth-first: each subtree contiguous
        for joint in children.get(link, []):
            builder.add_joint(joint)
            order.append(joint.name)
            visit(joint.child)

    visit(root)
    builder.add_frames()
    model = builder.model
    if not model.check(model.createData()):
        raise DescriptionError(source, "built model fails Pinocchio's consistency check")
    closures = tuple(_closure(sdf, joint) for joint in cuts)
    effects = sdf_effects(sdf, ([root_attachment] if root_attachment else []) + tree)
    return SdfTree(model, LoopsSpec(closures, tuple(actuated), effects=effects), root,
                   tuple(([root_attachment.name] if root_attachment else []) + order),
                   tuple(j.name for j in cuts), sdf)


def _choose_root(sdf: SdfModel, root_link, world_joints, cut_set) -> str:
    if root_link is not None:
        sdf.link(root_link)
        return root_link
    if world_joints:
        return world_joints[0].child
    children = {j.child for j in sdf.joints if j.name not in cut_set}
    roots = [link.name for link in sdf.links if link.name not in children]
    if len(roots) != 1:
        raise DescriptionError(sdf.source, f"cannot choose the root link (candidates: "
                                           f"{roots}); pass root_link",
                               roots[1] if len(roots) > 1 else sdf.links[0].name)
    return roots[0]


def _spanning_tree(sdf: SdfModel, root: str, cut_set: set[str], root_attachment):
    """Tree joints (parent -> child only) and the joints left over (the cuts)."""
    attached = {root}
    used = {root_attachment.name} if root_attachment else set()
    tree: list[SdfJoint] = []
    candidates = [j for j in sdf.joints if j.name not in cut_set and j.parent != WORLD]
    while True:
        added = False
        for allow_ball in (False, True):
            for joint in candidates:
                if (joint.name in used or joint.child in attached or joint.parent not in attached
                        or (joint.type == "ball" and not allow_ball)):
                    continue
                tree.append(joint)
                used.add(joint.name)
                attached.add(joint.child)
                added = True
            if added:
                break
        if not added:
            break
    for link in sdf.links:
        if link.name not in attached:
            raise DescriptionError(sdf.source, f"link {link.name!r} is not reachable from the "
                                               f"root {root!r} through parent-to-child joints",
                                   link.name)
    cuts = [j for j in sdf.joints if j.name not in used]
    for joint in cuts:
        if joint.type not in ("ball", "fixed"):
            raise DescriptionError(sdf.source, f"joint {joint.name!r} ({joint.type}) closes a "
                                               "loop; only ball (point) and fixed (weld) "
                                               "joints can be closures: cut another joint",
                                   joint.name)
    return tree, cuts


def _closure(sdf: SdfModel, joint: SdfJoint) -> ClosureSpec:
    child = sdf.link(joint.child)
    offset1 = child.pose.actInv(joint.pose)
    if joint.parent == WORLD:
        frame2, offset2 = WORLD, sdf.pose * joint.pose
    else:
        frame2, offset2 = joint.parent, sdf.link(joint.parent).pose.actInv(joint.pose)
    ctype = "point" if joint.type == "ball" else "weld"
    return ClosureSpec(joint.name, ctype, joint.child, frame2, offset1, offset2)


def _joint_model(joint: SdfJoint) -> pin.JointModel:
    axis = joint.axis
    if joint.type == "revolute":
        return _axis_joint(axis, (pin.JointModelRX, pin.JointModelRY, pin.JointModelRZ),
                           pin.JointModelRevoluteUnaligned)
    if joint.type == "continuous":  # the joint frame is turned so that its z is the axis
        return pin.JointModelRUBZ()
    if joint.type == "prismatic":
        return _axis_joint(axis, (pin.JointModelPX, pin.JointModelPY, pin.JointModelPZ),
                           pin.JointModelPrismaticUnaligned)
    if joint.type == "ball":
        return pin.JointModelSpherical()
    return pin.JointModelUniversal(np.asarray(joint.axis, float), np.asarray(joint.axis2, float))


def _joint_frame_turn(joint: SdfJoint) -> pin.SE3:
    """Rotation from the SDF joint frame to the Pinocchio joint frame (identity except
    for ``continuous`` joints, whose Pinocchio frame has its z axis on the SDF axis)."""
    if joint.type != "continuous":
        return pin.SE3.Identity()
    quat = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), joint.axis)
    return pin.SE3(quat.toRotationMatrix(), np.zeros(3))


def _axis_joint(axis: np.ndarray, aligned, unaligned):
    for k in range(3):
        if abs(axis[k] - 1.0) < 1e-12:
            return aligned[k]()
    return unaligned(float(axis[0]), float(axis[1]), float(axis[2]))


class _TreeBuilder:
    """Adds SDF joints and links to a ``pin.Model`` (caller supplies the order)."""

    def __init__(self, sdf: SdfModel):
        self.sdf = sdf
        self.model = pin.Model()
        self.model.name = sdf.name
        self.link_joint: dict[str, int] = {}      # link -> Pinocchio joint id
        self.joint_frame: dict[int, pin.SE3] = {0: sdf.pose.inverse()}  # joint frame in model
        self.link_frame_id: dict[str, int] = {}

    def add_root(self, root: str, root_joint, root_joint_name: str, attachment) -> None:
        link = self.sdf.link(root)
        if attachment is not None:
            self.add_joint(attachment)
            return
        if root_joint is None:
            self._attach_link(link, 0, 0)
            return
        jid = self.model.addJoint(0, root_joint, pin.SE3.Identity(), root_joint_name)
        fid = self.model.addJointFrame(jid, 0)
        self.joint_frame[jid] = link.pose
        self._attach_link(link, jid, fid)

    def add_joint(self, joint: SdfJoint) -> None:
        parent_jid = 0 if joint.parent == WORLD else self.link_joint[joint.parent]
        parent_fid = 0 if joint.parent == WORLD else self.link_frame_id[joint.parent]
        turn = _joint_frame_turn(joint)
        placement = self.joint_frame[parent_jid].actInv(joint.pose * turn)
        if joint.type == "fixed":
            fid = self.model.addFrame(pin.Frame(joint.name, parent_jid, parent_fid, placement,
                                                pin.FrameType.FIXED_JOINT), False)
            self._attach_link(self.sdf.link(joint.child), parent_jid, fid)
            return
        jmodel = _joint_model(joint)
        nv, nq = jmodel.nv, jmodel.nq
        lower = np.full(nq, joint.lower if nq == 1 else -np.inf)
        upper = np.full(nq, joint.upper if nq == 1 else np.inf)
        if joint.type == "ball" or joint.type == "continuous":
            lower, upper = np.full(nq, -np.inf), np.full(nq, np.inf)
        jid = self.model.addJoint(parent_jid, jmodel, placement, joint.name,
                                  np.full(nv, joint.effort), np.full(nv, joint.velocity),
                                  lower, upper)
        idx_v = self.model.joints[jid].idx_v
        self.model.damping[idx_v:idx_v + nv] = joint.damping
        self.model.friction[idx_v:idx_v + nv] = joint.friction
        fid = self.model.addJointFrame(jid, parent_fid)
        self.joint_frame[jid] = joint.pose * turn  # joint frames are kept in the model frame
        self._attach_link(self.sdf.link(joint.child), jid, fid)

    def _attach_link(self, link: SdfLink, jid: int, previous_frame: int) -> None:
        in_joint = self.joint_frame[jid].actInv(link.pose)
        inertial = link.inertial
        body = pin.Inertia(inertial.mass, np.zeros(3), inertial.inertia)
        self.model.appendBodyToJoint(jid, body, in_joint * inertial.placement)
        fid = self.model.addBodyFrame(link.name, jid, in_joint, previous_frame)
        self.link_joint[link.name] = jid
        self.link_frame_id[link.name] = fid

    def add_frames(self) -> None:
        for frame in self.sdf.frames:
            jid = self.link_joint[frame.link]
            placement = self.joint_frame[jid].actInv(frame.pose)
            self.model.addFrame(pin.Frame(frame.name, jid, self.link_frame_id[frame.link],
                                          placement, pin.FrameType.OP_FRAME), False)


def closed_loop_from_sdf(path_or_sdf: str | os.PathLike[str] | SdfModel,
                         actuated: Sequence[str] = (), root_joint: pin.JointModel | None = None,
                         root_link: str | None = None,
                         cut: Iterable[str] | None = None) -> ClosedLoopModel:
    """Load an SDF into a :class:`hexapod_pin.core.closed_loop.ClosedLoopModel`.

    Args:
        path_or_sdf: an SDF file path or a parsed :class:`SdfModel`.
        actuated: names of the actuated (1-DoF) joints.
        root_joint: see :func:`build_tree`.
        root_link: see :func:`build_tree`.
        cut: see :func:`build_tree`.

    Raises:
        DescriptionError: see :func:`parse_sdf`, :func:`build_tree` and
            ``ClosedLoopModel`` (unknown actuated joint, ...).
    """
    sdf = path_or_sdf if isinstance(path_or_sdf, SdfModel) else load_sdf(path_or_sdf)
    tree = build_tree(sdf, root_joint=root_joint, root_link=root_link, cut=cut,
                      actuated=actuated)
    return ClosedLoopModel(tree.model, tree.loops, name=f"{sdf.name} ({Path(sdf.source).name})")


# ------------------------------------------------------------------ SDF -> URDF
def sdf_to_urdf(sdf: SdfModel, root_link: str | None = None,
                cut: Iterable[str] | None = None,
                mesh_resolver: Callable[[str], str] | None = None) -> tuple[str, LoopsSpec]:
    """Write the spanning tree as URDF text, plus the closures as a :class:`LoopsSpec`.

    In the URDF every link frame is the frame of the joint above it (URDF's
    convention), so a link's frame moves from its SDF link frame to its SDF
    joint frame; a massless root link ``<model>__model_frame`` carries the model
    frame so that world poses equal the SDF's. Closure frames are the BODY
    frames Pinocchio's URDF reader creates for the links; their offsets are
    re-expressed accordingly. ``loops_yaml(loops)`` writes the loops file.

    Args:
        sdf: the parsed model (fixed root: the URDF has no root joint).
        root_link: see :func:`build_tree`.
        cut: see :func:`build_tree`.
        mesh_resolver: callable ``uri -> filename`` for mesh visuals (default:
            :func:`resolve_uri`, which keeps the URI when it cannot resolve it).

    Raises:
        DescriptionError: a ball or universal joint in the tree (URDF has neither),
            or anything :func:`build_tree` raises.
    """
    resolver = mesh_resolver or (lambda uri: resolve_uri(uri, sdf.base_dir) or uri)
    world_joints = [j for j in sdf.joints if j.parent == WORLD and j.name not in set(cut or ())]
    root = _choose_root(sdf, root_link, world_joints, set(cut or ()))
    tree, cuts = _spanning_tree(sdf, root, set(cut or ()), None)
    # URDF frame of each link: its tree joint's frame (root: its SDF link frame)
    frame_of = {root: sdf.link(root).pose}
    for joint in tree:
        if joint.type in ("ball", "universal"):
            raise DescriptionError(sdf.source, f"URDF has no {joint.type} joint; cut it or use "
                                               "build_tree", joint.name)
        frame_of[joint.child] = joint.pose
    base = f"{sdf.name}__model_frame"
    out = [f'<robot name="{_xml(sdf.name)}">', f'  <link name="{_xml(base)}"/>']
    for link in sdf.links:
        out.extend(_urdf_link(link, frame_of[link.name].actInv(link.pose), resolver))
    out.append(f'  <joint name="{_xml(base)}_to_{_xml(root)}" type="fixed">')
    out.append(f'    <parent link="{_xml(base)}"/><child link="{_xml(root)}"/>')
    out.append("    " + _urdf_origin(sdf.pose * frame_of[root]))
    out.append("  </joint>")
    for joint in tree:
        parent_frame = frame_of[joint.parent]
        out.append(f'  <joint name="{_xml(joint.name)}" type="{joint.type}">')
        out.append(f'    <parent link="{_xml(joint.parent)}"/><child link="{_xml(joint.child)}"/>')
        out.append("    " + _urdf_origin(parent_frame.actInv(joint.pose)))
        if joint.type != "fixed":
            out.append('    <axis xyz="{} {} {}"/>'.format(*(repr(float(a)) for a in joint.axis)))
        if joint.type in ("revolute", "prismatic"):
            lower = joint.lower if math.isfinite(joint.lower) else -1e10
            upper = joint.upper if math.isfinite(joint.upper) else 1e10
            effort = joint.effort if math.isfinite(joint.effort) else 1e10
            velocity = joint.velocity if math.isfinite(joint.velocity) else 1e10
            out.append(f'    <limit lower="{_num(lower)}" upper="{_num(upper)}" '
                       f'effort="{_num(effort)}" velocity="{_num(velocity)}"/>')
        if joint.type != "fixed" and (joint.damping or joint.friction):
            out.append(f'    <dynamics damping="{_num(joint.damping)}" '
                       f'friction="{_num(joint.friction)}"/>')
        out.append("  </joint>")
    out.append("</robot>")
    closures = []
    for joint in cuts:
        spec = _closure(sdf, joint)
        off1 = frame_of[joint.child].actInv(joint.pose)
        if joint.parent == WORLD:
            frame2, off2 = spec.frame2, spec.offset2
        else:
            frame2, off2 = joint.parent, frame_of[joint.parent].actInv(joint.pose)
        closures.append(ClosureSpec(spec.name, spec.type, spec.frame1, frame2, off1, off2))
    return "\n".join(out) + "\n", LoopsSpec(tuple(closures), (),
                                            effects=sdf_effects(sdf, tree))


def sdf_effects(sdf: SdfModel, joints: Iterable[SdfJoint]) -> EffectsSection | None:
    """The joint effects of the given (tree) joints: each one's nonzero ``damping``,
    ``coulomb`` (SDF ``friction``), ``stiffness`` (``spring_stiffness``) and
    ``spring_reference`` (rad or m, a displacement from the neutral configuration of
    every coordinate of the joint), as the ``effects`` section of a loops description;
    None when no joint has any. Fixed joints have none.

    Args:
        sdf: the parsed model (its source names the section).
        joints: the joints of the tree.
    """
    entries = []
    for joint in joints:
        if joint.type == "fixed":
            continue
        nv = 2 if joint.type == "universal" else 3 if joint.type == "ball" else 1
        values = (("damping", joint.damping), ("coulomb", joint.friction),
                  ("stiffness", joint.spring_stiffness),
                  ("spring_reference", joint.spring_reference if nv == 1
                   else (joint.spring_reference,) * nv))
        kept = tuple((key, value) for key, value in values if np.any(value))
        if kept:
            entries.append((joint.name, kept))
    return EffectsSection(tuple(entries), source=sdf.source) if entries else None


def loops_yaml(loops: LoopsSpec) -> str:
    """The loops description (format of :mod:`hexapod_pin.core.description`) as YAML text."""
    lines = ["closures:"] if loops.closures else ["closures: []"]
    for c in loops.closures:
        off = []
        for key, m in (("offset1", c.offset1), ("offset2", c.offset2)):
            xyz = [float(x) for x in m.translation]
            rpy = [float(x) for x in pin.rpy.matrixToRpy(m.rotation)]
            off.append(f"{key}: {{xyz: {xyz!r}, rpy: {rpy!r}}}")
        lines.append(f"  - {{name: {c.name!r}, type: {c.type}, frame1: {c.frame1!r}, "
                     f"frame2: {c.frame2!r},\n     {off[0]},\n     {off[1]}}}")
    lines.append(f"actuated: {list(loops.actuated)!r}")
    if loops.effects is not None:
        lines.append("effects:")
        if loops.effects.velocity_threshold is not None:
            lines.append(f"  velocity_threshold: "
                         f"{_yaml_number(loops.effects.velocity_threshold)}")
        lines.append("  joints:")
        for joint, entries in loops.effects.joints:
            values = ", ".join(f"{key}: {_yaml_number(value)}" for key, value in entries)
            lines.append(f"    {joint!r}: {{{values}}}")
    return "\n".join(lines) + "\n"


def _yaml_number(value: float | tuple[float, ...]) -> str:
    """A number or list of numbers as YAML (``.inf``; a float always with its dot or
    exponent sign that YAML reads as a number)."""
    if isinstance(value, tuple):
        return "[" + ", ".join(_yaml_number(v) for v in value) + "]"
    if math.isinf(value):
        return ".inf" if value > 0 else "-.inf"
    text = repr(float(value))
    return text.replace("e", ".0e", 1) if "e" in text and "." not in text else text


def resolve_uri(uri: str, base_dir: Path | None = None,
                search: Sequence[Path] = ()) -> str | None:
    """File name of a mesh URI (``model://``, ``package://``, ``file://`` or relative).

    ``model://a/b/c`` and ``package://a/b/c`` are looked up as ``<dir>/a/b/c``,
    ``<dir>/b/c`` and ``<dir>/c`` for each dir in ``search``, then ``base_dir`` and
    its parents; ``None`` when no file exists.
    """
    for prefix in ("model://", "package://", "file://"):
        if uri.startswith(prefix):
            rest = uri[len(prefix):]
            break
    else:
        rest = uri
    path = Path(rest)
    if path.is_absolute():
        return str(path) if path.is_file() else None
    dirs = list(search)
    if base_dir is not None:
        dirs += [base_dir, *Path(base_dir).resolve().parents]
    parts = path.parts
    for d in dirs:
        for k in range(len(parts)):
            candidate = Path(d, *parts[k:])
            if candidate.is_file():
                return str(candidate)
    return None


# ----------------------------------------------------------------------- helpers
def _urdf_link(link: SdfLink, link_in_frame: pin.SE3, resolver) -> list[str]:
    inertial = link.inertial
    com = link_in_frame * inertial.placement
    rot = com.rotation @ inertial.inertia @ com.rotation.T  # about the COM, URDF-frame axes
    lines = [f'  <link name="{_xml(link.name)}">', "    <inertial>",
             "      " + _urdf_origin(pin.SE3(np.eye(3), com.translation)),
             f'      <mass value="{_num(inertial.mass)}"/>',
             '      <inertia ixx="{}" ixy="{}" ixz="{}" iyy="{}" iyz="{}" izz="{}"/>'
             .format(*(_num(rot[i, j]) for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2),
                                                    (2, 2)))),
             "    </inertial>"]
    for geom in link.visuals:
        lines.append(f'    <visual name="{_xml(geom.name)}">')
        lines.append("      " + _urdf_origin(link_in_frame * geom.placement))
        if geom.kind == "box":
            shape = '<box size="{} {} {}"/>'.format(*map(_num, geom.size))
        elif geom.kind == "cylinder":
            shape = f'<cylinder radius="{_num(geom.size[0])}" length="{_num(geom.size[1])}"/>'
        elif geom.kind == "sphere":
            shape = f'<sphere radius="{_num(geom.size[0])}"/>'
        else:
            shape = '<mesh filename="{}" scale="{} {} {}"/>'.format(
                _xml(resolver(geom.uri)), *map(_num, geom.scale))
        lines.append(f"      <geometry>{shape}</geometry>")
        if geom.rgba is not None:
            lines.append('      <material name="{}"><color rgba="{} {} {} {}"/>'
                         '</material>'.format(_xml(geom.name), *map(_num, geom.rgba)))
        lines.append("    </visual>")
    lines.append("  </link>")
    return lines


def _num(value) -> str:
    """A number as URDF text (full precision, plain float: no numpy repr)."""
    return repr(float(value))


def _urdf_origin(m: pin.SE3) -> str:
    xyz = " ".join(repr(float(x)) for x in m.translation)
    rpy = " ".join(repr(float(x)) for x in pin.rpy.matrixToRpy(m.rotation))
    return f'<origin xyz="{xyz}" rpy="{rpy}"/>'


def _xml(text: str) -> str:
    return (str(text).replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;")
            .replace(">", "&gt;"))


def _version_tuple(version: str) -> tuple[int, ...]:
    return tuple(int(p) for p in version.split("."))


def _text(element, tag: str, source: str, culprit: str) -> str:
    child = element.find(tag)
    if child is None or child.text is None or not child.text.strip():
        raise DescriptionError(source, f"missing <{tag}>", culprit)
    return child.text.strip()


def _numbers(text: str | None, source: str, culprit: str) -> list[float]:
    try:
        values = [float(t) for t in (text or "").split()]
    except ValueError:
        raise DescriptionError(source, f"not numeric: {text!r}", culprit) from None
    if not all(math.isfinite(v) for v in values):
        raise DescriptionError(source, f"not finite: {text!r}", culprit)
    return values


def _vec(element, size: int, source: str, culprit: str) -> np.ndarray:
    if element is None:
        raise DescriptionError(source, "missing vector element", culprit)
    values = _numbers(element.text, source, culprit)
    if len(values) != size:
        raise DescriptionError(source, f"<{element.tag}> needs {size} numbers, got "
                                       f"{len(values)}", culprit)
    return np.array(values)


def _float(element, tag: str, default: float, source: str, culprit: str) -> float:
    child = element.find(tag)
    if child is None or child.text is None or not child.text.strip():
        return default
    text = child.text.strip()
    try:
        value = float(text)
    except ValueError:
        raise DescriptionError(source, f"<{tag}> is not numeric: {text!r}", culprit) from None
    if math.isnan(value):
        raise DescriptionError(source, f"<{tag}> is NaN", culprit)
    return value


def _parse_pose(element, source: str, culprit: str, snap: float = 0.0) -> pin.SE3:
    values = _numbers(element.text, source, culprit)
    if not values:
        return pin.SE3.Identity()
    # the URDF route's limits (core.description): finite, positions within MAX_COORDINATE
    if not all(math.isfinite(x) for x in values):
        raise DescriptionError(source, f"a pose must be finite, got {values}", culprit)
    if max(abs(x) for x in values[:3]) > MAX_COORDINATE:
        raise DescriptionError(source, f"pose position beyond {MAX_COORDINATE:g} m "
                                       f"({values[:3]})", culprit)
    fmt = element.get("rotation_format", "euler_rpy")
    degrees = element.get("degrees", "false").strip().lower() in ("true", "1")
    if fmt == "euler_rpy":
        if len(values) != 6:
            raise DescriptionError(source, f"a pose needs 6 numbers, got {len(values)}", culprit)
        rpy = np.array(values[3:])
        if degrees:
            rpy = np.deg2rad(rpy)
        if snap > 0.0:
            nearest = np.round(rpy / (np.pi / 2)) * (np.pi / 2)
            rpy = np.where(np.abs(rpy - nearest) < snap, nearest, rpy)
        return pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(values[:3]))
    if fmt == "quat_xyzw":
        if len(values) != 7:
            raise DescriptionError(source, f"a quat_xyzw pose needs 7 numbers, got "
                                           f"{len(values)}", culprit)
        quat = np.array(values[3:])
        norm = float(np.linalg.norm(quat))
        if norm < 1e-12:
            raise DescriptionError(source, "zero quaternion", culprit)
        x, y, z, w = quat / norm
        return pin.SE3(pin.Quaternion(w, x, y, z).toRotationMatrix(), np.array(values[:3]))
    raise DescriptionError(source, f"unknown rotation_format {fmt!r}", culprit)

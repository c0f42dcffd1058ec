"""Robots drawn into a meshcat :class:`~hexapod_pin.viz.meshcat_scene.Scene`: their visual
geometry and the overlays of efforts and frames.

Any robot works that is, or carries as ``.model``, a
:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel` (its ``urdf_xml`` gives the
visuals), or a bare ``pin.Model`` with its URDF. The robot is drawn from the *visual*
elements of that URDF (``pin.buildGeomFromUrdfString``), in the URDF's colours.
Nothing here knows a particular robot: the actuated joints and the closures come
from the ClosedLoopModel, the frames drawn as triads by default are the model's
``platform`` body if it has one.

Conventions: positions in metres, world axes (z up). Actuator efforts are drawn at
their joint along the joint's world axis (a prismatic joint's force in N along its
motion, a revolute joint's torque in N m along its axis); closure forces (N, world
axes) at the second anchor of each closure. Arrows are ``force_scale`` metres per
newton long (default: the largest effort drawn :data:`DEFAULT_ARROW_LENGTH` long).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from ..core.checks import as_array
from ..core.closed_loop import ClosedLoopModel
from ..core.description import expand_xacro
from ..errors import DescriptionError, InputError
from .meshcat_scene import Scene, arrow_matrix, arrow_objects, box_corners, shape_objects

#: colours (0xRRGGBB) of the overlays
ACTUATOR_FORCE_COLOR = 0xC2185B
ACTUATOR_TORQUE_COLOR = 0x6A1B9A
CLOSURE_FORCE_COLOR = 0x00897B
TRIAD_COLORS = (0xE53935, 0x43A047, 0x1E88E5)
#: length of the longest force arrow when no force_scale is given (m)
DEFAULT_ARROW_LENGTH = 0.15


# -- robot description -----------------------------------------------------------------
@dataclass(frozen=True)
class RobotVisual:
    """What is needed to draw a robot.

    Attributes:
        model: the Pinocchio tree model (for a :class:`ClosedLoopModel`, its
            model with the closure anchor frames).
        visual_model: the visual ``pin.GeometryModel`` built from the URDF.
        closed_loop: the :class:`ClosedLoopModel`, or ``None`` for a bare tree
            (then no actuator or closure forces can be drawn).
        name: a label.
    """

    model: pin.Model
    visual_model: pin.GeometryModel
    closed_loop: ClosedLoopModel | None
    name: str


def robot_visual(robot: Any, urdf: str | os.PathLike | None = None,
                 package_dirs: Sequence[str | os.PathLike] = ()) -> RobotVisual:
    """The model and visual geometry of a robot.

    Args:
        robot: a :class:`RobotVisual` (returned as it is), a :class:`ClosedLoopModel`,
            any object whose ``model`` is one (a :class:`hexapod_pin.Hexapod`, a
            :class:`hexapod_pin.Planar3PRR`), or a bare ``pin.Model``.
        urdf: URDF text, or a path to a URDF / xacro file; default the
            ClosedLoopModel's ``urdf_xml`` (a bare ``pin.Model`` needs it).
        package_dirs: folders searched for ``package://`` mesh files.

    Raises:
        InputError: ``robot`` is not drawable, or no URDF is known for it.
        DescriptionError: the URDF does not parse or does not match the model.
    """
    if isinstance(robot, RobotVisual):
        return robot
    closed_loop, model = _models_of(robot)
    xml = _urdf_text(robot, closed_loop, urdf)
    dirs = [str(p) for p in package_dirs]
    try:
        visual = pin.buildGeomFromUrdfString(model, xml, pin.GeometryType.VISUAL,
                                             package_dirs=dirs)
    except (RuntimeError, ValueError) as exc:  # what Pinocchio's parser raises
        raise DescriptionError("URDF visuals", f"Pinocchio could not build them: {exc}") \
            from None
    name = closed_loop.name if closed_loop is not None else (model.name or "robot")
    return RobotVisual(model, visual, closed_loop, safe_name(name))


def _models_of(robot: Any) -> tuple[ClosedLoopModel | None, pin.Model]:
    if isinstance(robot, ClosedLoopModel):
        return robot, robot.model
    inner = getattr(robot, "model", None)
    if isinstance(inner, ClosedLoopModel):
        return inner, inner.model
    if isinstance(robot, pin.Model):
        return None, robot
    raise InputError("robot", robot, "expected a Hexapod, a ClosedLoopModel, an object with a "
                                     "ClosedLoopModel as .model, or a pin.Model")


def _urdf_text(robot: Any, closed_loop: ClosedLoopModel | None,
               urdf: str | os.PathLike | None) -> str:
    if urdf is not None:
        text = str(urdf)
        if text.lstrip().startswith("<"):
            return text
        path = Path(text)
        if path.suffix.lower() == ".urdf" and path.is_file():  # plain URDF: no xacro pass
            return path.read_text(encoding="utf-8")
        return expand_xacro(path)
    xml = None if closed_loop is None else closed_loop.urdf_xml
    if isinstance(xml, str) and xml.strip():
        return xml
    raise InputError("urdf", None, f"no URDF known for {type(robot).__name__}: pass urdf=")


def safe_name(text: str) -> str:
    """``text`` with every character other than letters, digits, ``_-.`` replaced by ``_``
    (a meshcat path component)."""
    keep = "".join(c if (c.isalnum() or c in "_-.") else "_" for c in str(text))
    return keep or "robot"


# -- drawing a robot --------------------------------------------------------------------
@dataclass
class Drawn:
    """Node paths of one drawn robot, the half extents of each node's box, and the world
    points the robot covers (for the camera)."""

    geometry_paths: list[str]
    points: list[np.ndarray]
    halves: list[np.ndarray]


def geometry_placements(visual: RobotVisual, q: np.ndarray) -> list[pin.SE3]:
    """World placements of the visual geometry objects at configuration ``q``."""
    data = visual.model.createData()
    gdata = pin.GeometryData(visual.visual_model)
    pin.forwardKinematics(visual.model, data, q)
    pin.updateFramePlacements(visual.model, data)
    pin.updateGeometryPlacements(visual.model, data, visual.visual_model, gdata)
    return [gdata.oMg[i].copy() for i in range(visual.visual_model.ngeoms)]


def check_configuration(visual: RobotVisual, q: ArrayLike, name: str = "q") -> np.ndarray:
    """``q`` as a contiguous float array of size ``nq``.

    Raises:
        InputError: another size, or NaN / inf.
    """
    try:
        arr = np.ascontiguousarray(q, dtype=float)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.shape != (visual.model.nq,) or not np.all(np.isfinite(arr)):
        raise InputError(name, q, f"expected a finite Pinocchio configuration of size "
                                  f"{visual.model.nq}")
    return arr


def draw_robot(scene: Scene, visual: RobotVisual, q: np.ndarray, root: str,
               offset: ArrayLike = (0.0, 0.0, 0.0), opacity: float = 1.0) -> Drawn:
    """Draw the robot's visuals at configuration ``q`` under the node ``root``, shifted by
    ``offset`` (m, world axes); ``opacity`` multiplies the URDF colours' alpha.

    Raises:
        InputError: the robot has no visual geometry (no ``<visual>`` in its URDF).
    """
    if len(visual.visual_model.geometryObjects) == 0:
        raise InputError("robot", visual.name, "has no visual geometry to draw: add "
                                               "<visual> elements to its URDF links")
    offset = np.asarray(offset, dtype=float)
    scene.set_transform(root, _translation(offset))
    drawn = Drawn([], [], [])
    for gobj, placement in zip(visual.visual_model.geometryObjects,
                               geometry_placements(visual, q)):
        node = f"{root}/{safe_name(gobj.name)}"
        objects, half = shape_objects(gobj, opacity)
        for sub, lowered in objects:
            scene.set_object(f"{node}/{sub}" if sub else node, lowered)
        scene.set_transform(node, placement.homogeneous)
        drawn.geometry_paths.append(node)
        drawn.halves.append(half)
        drawn.points.extend(box_corners(placement, half) + offset)
    return drawn


def _translation(offset: ArrayLike) -> np.ndarray:
    mat = np.eye(4)
    mat[:3, 3] = offset
    return mat


def draw_arrow(scene: Scene, path: str, origin: ArrayLike, vector: ArrayLike, color: int,
               radius: float) -> None:
    """An arrow from ``origin`` along ``vector`` (m, world axes), shaft radius ``radius``."""
    for sub, lowered in arrow_objects(color, radius):
        scene.set_object(f"{path}/{sub}", lowered)
    scene.set_transform(path, arrow_matrix(origin, vector))


def draw_triad(scene: Scene, path: str, placement: pin.SE3, length: float,
               radius: float) -> None:
    """x / y / z axes of ``placement`` as red / green / blue arrows ``length`` long (m)."""
    for axis, color in enumerate(TRIAD_COLORS):
        draw_arrow(scene, f"{path}/{'xyz'[axis]}", np.zeros(3),
                    length * np.eye(3)[axis], color, radius)
    scene.set_transform(path, placement.homogeneous)


def default_frames(visual: RobotVisual) -> tuple[str, ...]:
    """Frames that get a triad by default: ``("platform",)`` when the model has that body."""
    model = visual.model
    return ("platform",) if model.existFrame("platform", pin.FrameType.BODY) else ()


def frame_id(model: pin.Model, name: str) -> int:
    """Id of the body, operational, fixed-joint or joint frame ``name`` (in that order).

    Raises:
        InputError: no such frame.
    """
    for ftype in (pin.FrameType.BODY, pin.FrameType.OP_FRAME, pin.FrameType.FIXED_JOINT,
                  pin.FrameType.JOINT):
        if model.existFrame(name, ftype):
            return model.getFrameId(name, ftype)
    raise InputError("frames", name, "no such frame in the model")


def actuator_arrows(visual: RobotVisual, q: np.ndarray,
                    actuator_forces: ArrayLike) -> list[tuple[np.ndarray, np.ndarray, bool]]:
    """Arrows (origin, vector, is_force) of actuator efforts, world axes.

    Each actuated joint's effort is drawn at its joint frame origin along the
    joint's world axis: a prismatic joint's force (N) along its direction of
    motion (for the hexapod: carriage i's ``tau_i`` along ``+u_k``, sign
    included); a revolute joint's torque (N m) along its rotation axis
    (``is_force`` False). The vector is in effort units; scaling comes later.

    Raises:
        InputError: no closed-loop model, or the wrong number of efforts.
    """
    loop = visual.closed_loop
    if loop is None:
        raise InputError("actuator_forces", actuator_forces,
                         "a bare tree has no actuated joints: pass a ClosedLoopModel robot")
    efforts = as_array(actuator_forces, (loop.n_actuated,), "actuator_forces")
    data = visual.model.createData()
    pin.computeJointJacobians(visual.model, data, q)
    out = []
    for name, tau in zip(loop.actuated_joints, efforts):
        jid = visual.model.getJointId(name)
        jac = pin.getJointJacobian(visual.model, data, jid,
                                   pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        column = jac[:, visual.model.joints[jid].idx_v]
        linear, angular = column[:3], column[3:]
        is_force = bool(np.linalg.norm(linear) >= np.linalg.norm(angular))
        axis = linear if is_force else angular
        axis = axis / max(np.linalg.norm(axis), 1e-300)
        out.append((data.oMi[jid].translation.copy(), tau * axis, is_force))
    return out


def closure_arrows(visual: RobotVisual, q: np.ndarray,
                   closure_forces: ArrayLike) -> list[tuple[np.ndarray, np.ndarray]]:
    """Arrows (origin, force) of closure forces at the second anchor of each closure.

    Args:
        closure_forces: one world-axes force (N) per closure, shape
            (n_closures, 3): for the hexapod, the force each leg tip exerts on the
            platform, drawn at its platform point. For a weld closure only its
            force part is drawn.

    Raises:
        InputError: no closed-loop model, or a wrong shape.
    """
    loop = visual.closed_loop
    if loop is None:
        raise InputError("closure_forces", closure_forces, "a bare tree has no closures")
    forces = as_array(closure_forces, (len(loop.closures), 3), "closure_forces")
    data = visual.model.createData()
    pin.framesForwardKinematics(visual.model, data, q)
    out = []
    for closure, force in zip(loop.closures, forces):
        fid = visual.model.getFrameId(f"{closure.name}/anchor2")
        out.append((data.oMf[fid].translation.copy(), force))
    return out


def arrow_scale(efforts: list[np.ndarray], force_scale: float | None) -> float:
    """Arrow length per unit effort (m/N): ``force_scale``, or the largest effort drawn
    :data:`DEFAULT_ARROW_LENGTH` long.

    Raises:
        InputError: a non-positive or non-finite ``force_scale``.
    """
    if force_scale is not None:
        if not (math.isfinite(force_scale) and force_scale > 0):
            raise InputError("force_scale", force_scale, "must be a positive number (m/N)")
        return float(force_scale)
    biggest = max((float(np.linalg.norm(v)) for v in efforts), default=0.0)
    return DEFAULT_ARROW_LENGTH / biggest if biggest > 0 else 1.0


def draw_overlays(scene: Scene, visual: RobotVisual, q: np.ndarray, root: str, size: float,
                  actuator_forces: ArrayLike | None = None,
                  closure_forces: ArrayLike | None = None, frames: Sequence[str] | None = None,
                  force_scale: float | None = None,
                  triad_length: float | None = None) -> float | None:
    """Actuator and closure force arrows and frame triads of configuration ``q`` under
    ``root`` (see :func:`actuator_arrows`, :func:`closure_arrows`); ``size`` (m) sets the
    arrow thickness and the default triad length (a sixth of it).

    Returns:
        the arrow length per unit effort (m/N) used, None when no arrow was drawn.
    """
    radius = 0.006 * size
    act = [] if actuator_forces is None else actuator_arrows(visual, q, actuator_forces)
    clo = [] if closure_forces is None else closure_arrows(visual, q, closure_forces)
    scale = arrow_scale([v for _, v, _ in act] + [v for _, v in clo], force_scale)
    for i, (origin, vector, is_force) in enumerate(act):
        color = ACTUATOR_FORCE_COLOR if is_force else ACTUATOR_TORQUE_COLOR
        draw_arrow(scene, f"{root}/overlays/actuator_{i}", origin, scale * vector, color,
                    radius)
    for i, (origin, vector) in enumerate(clo):
        draw_arrow(scene, f"{root}/overlays/closure_{i}", origin, scale * vector,
                    CLOSURE_FORCE_COLOR, radius)
    names = default_frames(visual) if frames is None else tuple(frames)
    if names:
        data = visual.model.createData()
        pin.framesForwardKinematics(visual.model, data, q)
        length = size / 6 if triad_length is None else float(triad_length)
        for name in names:
            placement = data.oMf[frame_id(visual.model, name)]
            draw_triad(scene, f"{root}/frames/{safe_name(name)}", placement, length,
                        radius)
    return scale if act or clo else None


def triad_legend(names: Sequence[str]) -> list[str]:
    """The legend line of the frame triads drawn for the frames ``names``: which frames,
    and that red / green / blue are their own x / y / z axes (empty without triads)."""
    if not names:
        return []
    which = ", ".join(names)
    return [f"axis triad{'s' if len(names) > 1 else ''} of the {which} frame: red x, "
            "green y, blue z (the frame's own axes; the world has z up)"]


def force_legend(scale: float | None, actuators: bool, closures: bool) -> list[str]:
    """Legend lines of the force arrows: their colours and their length scale."""
    if scale is None:
        return []
    lines = []
    if actuators:
        lines.append("magenta arrows: actuator forces, along the actuator axis "
                     "(violet: torques, about it)")
    if closures:
        lines.append("teal arrows: closure forces on the platform (world axes)")
    lines.append(f"arrow length: 0.1 m = {0.1 / scale:.4g} N (N m for torques)")
    return lines



"""Meshcat scenes of closed-loop robots, written as self-contained HTML files.

The robot is drawn from the *visual* elements of the same URDF the model is built
from (``pin.buildGeomFromUrdfString``): boxes, cylinders, spheres, capsules,
cones, ellipsoids, and mesh files (STL / OBJ / DAE; any other mesh Coal can load
is drawn as its bounding box). Colours are the URDF materials; for the hexapod
the actuated carriages are orange, the passive legs grey, the platform blue.

No meshcat server is started: a :class:`Scene` records meshcat commands
(``set_object``, ``set_transform``, ``set_property``, ``set_animation``) as
msgpack blobs, and :meth:`Scene.html` packs them with meshcat's JavaScript viewer
(``meshcat/viewer/dist/main.min.js``) into one HTML file that any browser opens
from disk, with the usual orbit controls and, for trajectories, meshcat's
animation panel (play / pause / reset / time slider). Nothing here leaves a
process running.

Conventions: positions in metres, world axes (z up); forces in newtons, drawn as
arrows whose length is ``force_scale`` metres per newton (default: the largest
force drawn 0.15 m long). The page itself understands ``#t=<seconds>`` at the
end of its URL: the animation is paused at that time (used by the tests and the
screenshots).

Typical use::

    import hexapod_pin as hp
    from hexapod_pin import visualize as viz
    robot = hp.Hexapod.default()
    viz.write_pose_html("home.html", robot, robot.home_configuration)
"""

from __future__ import annotations

import base64
import html as html_lib
import json
import math
import os
import tempfile
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..core.closed_loop import ClosedLoopModel
from ..core.description import expand_xacro
from ..errors import DescriptionError, InputError
from ..core.checks import as_array

#: colours (0xRRGGBB) of the overlays
ACTUATOR_FORCE_COLOR = 0xC2185B
ACTUATOR_TORQUE_COLOR = 0x6A1B9A
CLOSURE_FORCE_COLOR = 0x00897B
TRIAD_COLORS = (0xE53935, 0x43A047, 0x1E88E5)
#: page background, top and bottom colours (RGB in [0, 1])
BACKGROUND = ((1.0, 1.0, 1.0), (0.80, 0.83, 0.88))
#: length of the longest force arrow when no force_scale is given (m)
DEFAULT_ARROW_LENGTH = 0.15
#: vertical field of view of the camera (deg)
CAMERA_FOV_DEG = 40.0
#: direction from the scene centre to the camera, world axes (normalised on use)
CAMERA_DIRECTION = (1.0, -1.35, 0.95)
ROOT = "/meshcat"


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


def robot_visual(robot, urdf: str | os.PathLike | None = None,
                 package_dirs: Sequence[str | os.PathLike] = ()) -> RobotVisual:
    """The model and visual geometry of a robot.

    Args:
        robot: a :class:`hexapod_pin.Hexapod`, any object with a ``model``
            attribute that is a :class:`ClosedLoopModel` (and optionally a
            ``urdf_xml`` string), a :class:`ClosedLoopModel`, or a ``pin.Model``.
        urdf: URDF text, or a path to a URDF / xacro file; default: the
            robot's own: ``robot.urdf_xml`` (or ``robot.model.urdf_xml``, a string
            or a method returning one) if it has one, else the expanded xacro of
            a :class:`hexapod_pin.Hexapod` or ``hexapod_pin.planar.Planar3PRR``
            (found from the class of ``robot.geometry``).
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
    return RobotVisual(model, visual, closed_loop, _safe_name(name))


def _models_of(robot) -> tuple[ClosedLoopModel | None, pin.Model]:
    if isinstance(robot, ClosedLoopModel):
        return robot, robot.model
    inner = getattr(robot, "model", None)
    if isinstance(inner, ClosedLoopModel):
        return inner, inner.model
    if isinstance(robot, pin.Model):
        return None, robot
    raise InputError("robot", robot, "expected a Hexapod, a ClosedLoopModel, an object with a "
                                     "ClosedLoopModel as .model, or a pin.Model")


def _urdf_text(robot, closed_loop, urdf) -> str:
    if urdf is not None:
        text = str(urdf)
        if text.lstrip().startswith("<"):
            return text
        path = Path(text)
        if path.suffix.lower() == ".urdf" and path.is_file():  # plain URDF: no xacro pass
            return path.read_text(encoding="utf-8")
        return expand_xacro(path)
    for owner in (robot, closed_loop):
        xml = getattr(owner, "urdf_xml", None)
        xml = xml() if callable(xml) else xml
        if isinstance(xml, str) and xml.strip():
            return xml
    raise InputError("urdf", None, f"no URDF known for {type(robot).__name__}: pass urdf=")


def _safe_name(text: str) -> str:
    keep = "".join(c if (c.isalnum() or c in "_-.") else "_" for c in str(text))
    return keep or "robot"


# -- the recorded scene ----------------------------------------------------------------
def _meshcat():
    """Import meshcat's geometry module and msgpack lazily (meshcat imports IPython)."""
    with warnings.catch_warnings():  # meshcat's server module imports a deprecated zmq API
        warnings.simplefilter("ignore", DeprecationWarning)
        import meshcat.geometry as mg
    import umsgpack

    return mg, umsgpack


def _assets_js() -> str:
    _meshcat()
    import meshcat

    path = Path(meshcat.__file__).resolve().parent / "viewer" / "dist" / "main.min.js"
    if not path.is_file():
        raise DescriptionError(str(path), "meshcat's viewer JavaScript is missing")
    return path.read_text(encoding="utf-8")


class Scene:
    """A meshcat scene recorded as a list of commands, written as HTML (no server).

    Paths are meshcat paths (``"/meshcat/robot/leg_0_0"``). Matrices are 4x4
    homogeneous transforms in world axes (z up) relative to the parent node.

    Attributes:
        camera_target, camera_position: where the camera looks and stands,
            world axes (m) (set by the scene functions to frame the robot).
        caption: text in the page's lower-left corner.
        title: the page title.
        hide_controls: start with meshcat's control panel closed (animations
            open it, to show the play controls).
        seek_time: pause the animation at this time (s) when the page opens;
            ``None`` plays it (a ``#t=<s>`` URL fragment overrides it).
    """

    def __init__(self) -> None:
        self._commands: list[dict] = []
        self.camera_target = np.zeros(3)
        self.camera_position = np.array([3.0, 0.0, 1.0])
        self.caption = ""
        self.title = "hexapod_pin"
        self.hide_controls = True
        self.seek_time: float | None = None
        self.set_property("/Background", "top_color", list(BACKGROUND[0]))
        self.set_property("/Background", "bottom_color", list(BACKGROUND[1]))
        self.set_property("/Axes", "visible", False)

    @property
    def commands(self) -> list[dict]:
        """The recorded commands (meshcat's lowered dictionaries), in order."""
        return list(self._commands)

    # -- raw commands ---------------------------------------------------------------
    def set_object(self, path: str, lowered_object: dict) -> None:
        """Record a ``set_object`` with an already lowered three.js object."""
        self._commands.append({"type": "set_object", "path": path, "object": lowered_object})

    def set_transform(self, path: str, matrix: np.ndarray) -> None:
        """Record a ``set_transform`` (4x4 matrix, relative to the parent node)."""
        matrix = np.asarray(matrix, dtype=float)
        self._commands.append({"type": "set_transform", "path": path,
                               "matrix": [float(v) for v in matrix.T.ravel()]})

    def set_property(self, path: str, key: str, value) -> None:
        """Record a ``set_property`` (e.g. ``visible``, ``position``)."""
        self._commands.append({"type": "set_property", "path": path, "property": key,
                               "value": value})

    def set_animation(self, clips: list[dict], play: bool = True, loop: bool = True) -> None:
        """Record a ``set_animation``: ``clips`` as made by :func:`_clip`."""
        self._commands.append({"type": "set_animation", "path": "", "animations": clips,
                               "options": {"play": bool(play),
                                           "repetitions": math.inf if loop else 1}})

    # -- output ---------------------------------------------------------------------
    def count(self, kind: str) -> int:
        """Number of recorded commands of one type (``"set_object"`` ...)."""
        return sum(1 for c in self._commands if c["type"] == kind)

    def html(self) -> str:
        """The scene as one self-contained HTML page (meshcat viewer inlined)."""
        _, umsgpack = _meshcat()
        blobs = [base64.b64encode(umsgpack.packb(c)).decode("ascii") for c in self._commands]
        target = _three(self.camera_target)
        camera = _three(self.camera_position)
        script = _PAGE_SCRIPT.format(
            commands=json.dumps(blobs), camera=json.dumps(camera), target=json.dumps(target),
            fov=json.dumps(CAMERA_FOV_DEG), hide=json.dumps(bool(self.hide_controls)),
            seek=json.dumps(None if self.seek_time is None else float(self.seek_time)))
        return _PAGE.format(title=html_lib.escape(self.title),
                            caption=html_lib.escape(self.caption),
                            viewer_js=_assets_js(), script=script)

    def write(self, path: str | os.PathLike) -> Path:
        """Write :meth:`html` to ``path`` atomically; returns the path."""
        return write_text_atomic(path, self.html())


def _three(vec) -> list[float]:
    """World (z up) coordinates -> three.js scene coordinates of meshcat (y up)."""
    x, y, z = (float(v) for v in vec)
    return [x, z, -y]


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write text to ``path`` through a temporary file in the same folder."""
    path = Path(path)
    if path.parent and not path.parent.is_dir():
        raise InputError("path", str(path), "its folder does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent or ".")
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


_PAGE = """<!DOCTYPE html>
<html>
<head>
<meta charset="utf-8">
<title>{title}</title>
<style>
body {{ margin: 0; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
#hexapod-pin-caption {{ position: absolute; left: 8px; bottom: 8px; padding: 2px 6px;
  font: 13px sans-serif; color: #222; background: rgba(255, 255, 255, 0.75); }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<div id="hexapod-pin-caption">{caption}</div>
<div id="hexapod-pin-status" hidden></div>
<script>
{viewer_js}
</script>
<script>
{script}
</script>
</body>
</html>
"""

# Decodes the recorded commands synchronously, in order, then frames the camera,
# seeks the animation when the URL ends in #t=<seconds>, and reports what the page
# holds in #hexapod-pin-status (read by the tests with --dump-dom).
_PAGE_SCRIPT = """var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
var hexapodPinCommands = {commands};
function hexapodPinBytes(text) {{
  var raw = atob(text), out = new Uint8Array(raw.length);
  for (var i = 0; i < raw.length; i++) out[i] = raw.charCodeAt(i);
  return out;
}}
var hexapodPinStatus = document.getElementById("hexapod-pin-status");
try {{
  for (var i = 0; i < hexapodPinCommands.length; i++) {{
    viewer.handle_command_bytearray(hexapodPinBytes(hexapodPinCommands[i]));
  }}
  viewer.camera.fov = {fov};
  viewer.camera.position.set.apply(viewer.camera.position, {camera});
  viewer.controls.target.set.apply(viewer.controls.target, {target});
  viewer.controls.update();
  if ({hide}) {{
    viewer.gui.close();
  }} else {{
    viewer.gui.open();
    if (viewer.gui.__folders.Scene) viewer.gui.__folders.Scene.close();
  }}
  var seek = {seek};
  var match = /[#&]t=([0-9.eE+-]+)/.exec(window.location.hash);
  if (match) seek = parseFloat(match[1]);
  if (seek !== null && viewer.animator.actions.length > 0) {{
    viewer.animator.pause();
    viewer.animator.seek(seek);
    viewer.animator.display_progress(seek);
  }}
  var meshes = 0;
  viewer.scene_tree.find(["meshcat"]).object.traverse(function (o) {{ if (o.isMesh) meshes++; }});
  hexapodPinStatus.dataset.commands = String(hexapodPinCommands.length);
  hexapodPinStatus.dataset.meshes = String(meshes);
  hexapodPinStatus.dataset.animationActions = String(viewer.animator.actions.length);
  hexapodPinStatus.dataset.animationDuration = String(viewer.animator.duration);
  hexapodPinStatus.dataset.ok = "true";
  viewer.set_dirty();
}} catch (err) {{
  hexapodPinStatus.dataset.ok = "false";
  hexapodPinStatus.dataset.error = String(err);
  hexapodPinStatus.hidden = false;
  hexapodPinStatus.textContent = "hexapod_pin: " + err;
}}
"""


# -- primitives -------------------------------------------------------------------------
def _color_int(rgba) -> int:
    r, g, b = (min(max(float(c), 0.0), 1.0) for c in rgba[:3])
    return (round(r * 255) << 16) | (round(g * 255) << 8) | round(b * 255)


def _mesh(geometry, color: int, opacity: float = 1.0,
          intrinsic: np.ndarray | None = None) -> dict:
    """Lower a meshcat geometry + phong material, with a correct intrinsic transform."""
    mg, _ = _meshcat()
    material = mg.MeshPhongMaterial(color=int(color), opacity=float(opacity))
    lowered = mg.Mesh(geometry, material).lower()
    mat = np.eye(4) if intrinsic is None else np.asarray(intrinsic, dtype=float)
    lowered["object"]["matrix"] = [float(v) for v in mat.T.ravel()]  # three.js: column-major
    return lowered


_Y_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])  # Rx(+90 deg)


def _shape_objects(gobj) -> tuple[list[tuple[str, dict]], np.ndarray]:
    """Lowered objects (sub-path, object) for a GeometryObject and the half extents (3,)
    of its bounding box in its own frame (m), around its origin.

    The sub-path is ``""`` for a single object; capsules give three parts.
    """
    import coal

    mg, _ = _meshcat()
    geom = gobj.geometry
    color, opacity = _color_int(gobj.meshColor), float(gobj.meshColor[3])
    scale = np.diag(np.append(np.asarray(gobj.meshScale, dtype=float), 1.0))

    def cyl(height, radius_top, radius_bottom, shift=0.0):
        mat = _Y_TO_Z.copy()
        mat[2, 3] = shift
        return _mesh(mg.Cylinder(float(height), radiusTop=float(radius_top),
                                 radiusBottom=float(radius_bottom)), color, opacity, mat)

    if isinstance(geom, coal.Box):
        half = np.asarray(geom.halfSide, dtype=float)
        return [("", _mesh(mg.Box([float(v) for v in 2 * half]), color, opacity))], half
    if isinstance(geom, coal.Sphere):
        return [("", _mesh(mg.Sphere(float(geom.radius)), color, opacity))], \
            np.full(3, float(geom.radius))
    if isinstance(geom, coal.Ellipsoid):
        radii = [float(v) for v in geom.radii]
        return [("", _mesh(mg.Ellipsoid(radii), color, opacity))], np.array(radii)
    if isinstance(geom, coal.Capsule):
        r, h = float(geom.radius), float(geom.halfLength)
        cap = mg.Sphere(r)
        shift_up, shift_down = np.eye(4), np.eye(4)
        shift_up[2, 3], shift_down[2, 3] = h, -h
        return [("body", cyl(2 * h, r, r)),
                ("cap_top", _mesh(cap, color, opacity, shift_up)),
                ("cap_bottom", _mesh(mg.Sphere(r), color, opacity, shift_down))], \
            np.array([r, r, h + r])
    if isinstance(geom, coal.Cone):  # apex at +z
        r, h = float(geom.radius), float(geom.halfLength)
        return [("", cyl(2 * h, 0.0, r))], np.array([r, r, h])
    if isinstance(geom, coal.Cylinder):
        r, h = float(geom.radius), float(geom.halfLength)
        return [("", cyl(2 * h, r, r))], np.array([r, r, h])
    mesh_file = Path(gobj.meshPath) if gobj.meshPath else None
    if mesh_file is not None and mesh_file.is_file():
        loader = {".stl": mg.StlMeshGeometry, ".obj": mg.ObjMeshGeometry,
                  ".dae": mg.DaeMeshGeometry}.get(mesh_file.suffix.lower())
        if loader is not None:
            lowered = _mesh(loader.from_file(str(mesh_file)), color, opacity, scale)
            return [("", lowered)], _aabb_half(geom, scale)
    # anything else Coal loaded (a mesh in another format, a convex hull): its bounding box
    lo, hi = _aabb(geom)
    factors = np.diag(scale)[:3]
    box = np.eye(4)
    box[:3, 3] = factors * (lo + hi) / 2
    size = [float(max(v, 1e-6)) for v in factors * (hi - lo)]
    return [("", _mesh(mg.Box(size), color, opacity, box))], _aabb_half(geom, scale)


def _aabb(geom) -> tuple[np.ndarray, np.ndarray]:
    try:
        geom.computeLocalAABB()
        box = geom.aabb_local
        return np.asarray(box.min_, dtype=float), np.asarray(box.max_, dtype=float)
    except (AttributeError, RuntimeError):  # no AABB: a small cube, so it is still seen
        return -0.01 * np.ones(3), 0.01 * np.ones(3)


def _aabb_half(geom, scale) -> np.ndarray:
    lo, hi = _aabb(geom)
    return np.diag(scale)[:3] * np.maximum(np.abs(lo), np.abs(hi))


_CORNERS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)],
                    dtype=float)


def _corners(placement: pin.SE3, half: np.ndarray) -> np.ndarray:
    """World corners (8, 3) of a box of half extents ``half`` at ``placement``."""
    return (_CORNERS * half) @ placement.rotation.T + placement.translation


def _arrow_objects(color: int, radius: float) -> list[tuple[str, dict]]:
    """A unit arrow along local +y (shaft 0.8, head 0.2), as two lowered meshes."""
    mg, _ = _meshcat()
    shaft, head = np.eye(4), np.eye(4)
    shaft[1, 3], head[1, 3] = 0.4, 0.9
    return [("shaft", _mesh(mg.Cylinder(0.8, radius), color, 1.0, shaft)),
            ("head", _mesh(mg.Cylinder(0.2, radiusTop=0.0, radiusBottom=2.5 * radius),
                           color, 1.0, head))]


def _arrow_matrix(origin, vector) -> np.ndarray:
    """Transform taking the unit +y arrow to an arrow from ``origin`` along ``vector``."""
    vector = np.asarray(vector, dtype=float)
    length = float(np.linalg.norm(vector))
    mat = np.eye(4)
    mat[:3, 3] = origin
    if length < 1e-9:
        mat[:3, :3] = np.diag([1.0, 1e-6, 1.0])
        return mat
    rot = pin.Quaternion.FromTwoVectors(np.array([0.0, 1.0, 0.0]),
                                        vector / length).toRotationMatrix()
    mat[:3, :3] = rot @ np.diag([1.0, length, 1.0])
    return mat


def _decompose(mat: np.ndarray) -> tuple[list[float], list[float], list[float]]:
    """position, quaternion (x, y, z, w), scale of ``R diag(s) | t`` (s > 0)."""
    scale = np.linalg.norm(mat[:3, :3], axis=0)
    rot = mat[:3, :3] / scale
    quat = pin.Quaternion(rot).normalized().coeffs()
    return ([float(v) for v in mat[:3, 3]], [float(v) for v in quat],
            [float(v) for v in scale])


# -- drawing a robot --------------------------------------------------------------------
@dataclass
class _Drawn:
    """Node paths of one drawn robot and the world points it covers (for the camera)."""

    geometry_paths: list[str]
    points: list[np.ndarray]
    halves: list[np.ndarray]


def _placements(visual: RobotVisual, q: np.ndarray) -> tuple[pin.Data, list[pin.SE3]]:
    data = visual.model.createData()
    gdata = pin.GeometryData(visual.visual_model)
    pin.forwardKinematics(visual.model, data, q)
    pin.updateFramePlacements(visual.model, data)
    pin.updateGeometryPlacements(visual.model, data, visual.visual_model, gdata)
    return data, [gdata.oMg[i].copy() for i in range(visual.visual_model.ngeoms)]


def _check_configuration(visual: RobotVisual, q, name: str = "q") -> np.ndarray:
    try:
        arr = np.ascontiguousarray(q, dtype=float)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.shape != (visual.model.nq,) or not np.all(np.isfinite(arr)):
        raise InputError(name, q, f"expected a finite Pinocchio configuration of size "
                                  f"{visual.model.nq}")
    return arr


def _draw_robot(scene: Scene, visual: RobotVisual, q: np.ndarray, root: str,
                offset: np.ndarray) -> _Drawn:
    scene.set_transform(root, _translation(offset))
    _, placements = _placements(visual, q)
    drawn = _Drawn([], [], [])
    for gobj, placement in zip(visual.visual_model.geometryObjects, placements):
        node = f"{root}/{_safe_name(gobj.name)}"
        objects, half = _shape_objects(gobj)
        for sub, lowered in objects:
            scene.set_object(f"{node}/{sub}" if sub else node, lowered)
        scene.set_transform(node, placement.homogeneous)
        drawn.geometry_paths.append(node)
        drawn.halves.append(half)
        drawn.points.extend(_corners(placement, half) + offset)
    return drawn


def _translation(offset) -> np.ndarray:
    mat = np.eye(4)
    mat[:3, 3] = offset
    return mat


def _draw_arrow(scene: Scene, path: str, origin, vector, color: int, radius: float) -> None:
    for sub, lowered in _arrow_objects(color, radius):
        scene.set_object(f"{path}/{sub}", lowered)
    scene.set_transform(path, _arrow_matrix(origin, vector))


def _draw_triad(scene: Scene, path: str, placement: pin.SE3, length: float,
                radius: float) -> None:
    for axis, color in enumerate(TRIAD_COLORS):
        _draw_arrow(scene, f"{path}/{'xyz'[axis]}", np.zeros(3),
                    length * np.eye(3)[axis], color, radius)
    scene.set_transform(path, placement.homogeneous)


def default_frames(visual: RobotVisual) -> tuple[str, ...]:
    """Frames that get a triad by default: ``("platform",)`` when the model has that body."""
    model = visual.model
    return ("platform",) if model.existFrame("platform", pin.FrameType.BODY) else ()


def _frame_id(model: pin.Model, name: str) -> int:
    for ftype in (pin.FrameType.BODY, pin.FrameType.OP_FRAME, pin.FrameType.FIXED_JOINT,
                  pin.FrameType.JOINT):
        if model.existFrame(name, ftype):
            return model.getFrameId(name, ftype)
    raise InputError("frames", name, "no such frame in the model")


def actuator_arrows(visual: RobotVisual, q: np.ndarray,
                    actuator_forces) -> list[tuple[np.ndarray, np.ndarray, bool]]:
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
                   closure_forces) -> list[tuple[np.ndarray, np.ndarray]]:
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


def _frame_camera(scene: Scene, points: list[np.ndarray], aspect: float = 4 / 3,
                  panel: bool = False) -> None:
    """Aim the camera at the middle of ``points`` from CAMERA_DIRECTION, close enough
    that every point is inside the view frustum of a 4:3 window (with a margin); with
    ``panel``, inside its left 68 % (meshcat's control panel covers the right)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    centre = (pts.min(axis=0) + pts.max(axis=0)) / 2
    back = np.asarray(CAMERA_DIRECTION, dtype=float)
    back /= np.linalg.norm(back)
    forward = -back
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    rel = pts - centre
    tan_y = math.tan(math.radians(CAMERA_FOV_DEG) / 2)
    share = 0.68 if panel else 1.0
    tan_x = tan_y * aspect * share
    depth = rel @ forward
    need = np.maximum(np.abs(rel @ right) / tan_x, np.abs(rel @ up) / tan_y) - depth
    distance = 1.08 * max(float(need.max()), 1e-3)
    shift = (1.0 - share) / share * distance * tan_x * right
    scene.camera_target = centre + shift
    scene.camera_position = centre + shift + distance * back


def _scene_size(points: list[np.ndarray]) -> float:
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    return float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))


# -- public scenes ----------------------------------------------------------------------
def pose_scene(robot, q, *, actuator_forces=None, closure_forces=None,
               frames: Sequence[str] | None = None, force_scale: float | None = None,
               triad_length: float | None = None, caption: str = "",
               urdf=None) -> Scene:
    """A scene of the robot at one configuration, with optional overlays.

    Args:
        robot: see :func:`robot_visual` (a :class:`hexapod_pin.Hexapod`, a
            :class:`ClosedLoopModel`, ...), or a :class:`RobotVisual`.
        q: Pinocchio configuration of the tree (nq,), e.g.
            ``robot.configuration(pose)`` for the hexapod.
        actuator_forces: efforts of the actuated joints (n_act,), N or N m, drawn
            as arrows (see :func:`actuator_arrows`).
        closure_forces: closure forces (n_closures, 3), N, world axes, drawn at
            the closures' second anchors (see :func:`closure_arrows`).
        frames: frames drawn as x/y/z triads (red/green/blue); default
            :func:`default_frames` (the platform); ``()`` for none.
        force_scale: arrow length per newton (m/N); default: the largest
            effort drawn ``DEFAULT_ARROW_LENGTH`` long.
        triad_length: triad arm length (m); default a sixth of the scene size.
        caption: text shown in the page's lower-left corner.
        urdf: URDF text or file, when the robot does not carry its own.

    Raises:
        InputError: a wrong configuration or force shape, an unknown frame.
    """
    visual = robot_visual(robot, urdf)
    q = _check_configuration(visual, q)
    scene = Scene()
    scene.caption = caption
    root = f"{ROOT}/{visual.name}"
    drawn = _draw_robot(scene, visual, q, root, np.zeros(3))
    size = _scene_size(drawn.points)
    _draw_overlays(scene, visual, q, root, size, actuator_forces, closure_forces, frames,
                   force_scale, triad_length)
    _frame_camera(scene, drawn.points)
    return scene


def _arrow_scale(efforts: list[np.ndarray], force_scale: float | None) -> float:
    if force_scale is not None:
        if not (math.isfinite(force_scale) and force_scale > 0):
            raise InputError("force_scale", force_scale, "must be a positive number (m/N)")
        return float(force_scale)
    biggest = max((float(np.linalg.norm(v)) for v in efforts), default=0.0)
    return DEFAULT_ARROW_LENGTH / biggest if biggest > 0 else 1.0


def _draw_overlays(scene, visual, q, root, size, actuator_forces, closure_forces, frames,
                   force_scale, triad_length) -> None:
    radius = 0.006 * size
    act = [] if actuator_forces is None else actuator_arrows(visual, q, actuator_forces)
    clo = [] if closure_forces is None else closure_arrows(visual, q, closure_forces)
    scale = _arrow_scale([v for _, v, _ in act] + [v for _, v in clo], force_scale)
    for i, (origin, vector, is_force) in enumerate(act):
        color = ACTUATOR_FORCE_COLOR if is_force else ACTUATOR_TORQUE_COLOR
        _draw_arrow(scene, f"{root}/overlays/actuator_{i}", origin, scale * vector, color,
                    radius)
    for i, (origin, vector) in enumerate(clo):
        _draw_arrow(scene, f"{root}/overlays/closure_{i}", origin, scale * vector,
                    CLOSURE_FORCE_COLOR, radius)
    names = default_frames(visual) if frames is None else tuple(frames)
    if names:
        data = visual.model.createData()
        pin.framesForwardKinematics(visual.model, data, q)
        length = size / 6 if triad_length is None else float(triad_length)
        for name in names:
            placement = data.oMf[_frame_id(visual.model, name)]
            _draw_triad(scene, f"{root}/frames/{_safe_name(name)}", placement, length,
                        radius)


def modes_scene(robot, configurations, *, layout: str = "grid", spacing: float | None = None,
                labels: Sequence[str] | None = None, frames: Sequence[str] | None = None,
                urdf=None, caption: str = "") -> Scene:
    """Several configurations of one robot (e.g. all assembly modes) in one scene.

    Args:
        robot: see :func:`robot_visual`.
        configurations: Pinocchio configurations, shape (M, nq).
        layout: ``"grid"`` (side by side in rows of up to 4, each copy offset in x
            then -y), ``"row"`` (all along x), or ``"sequence"`` (one copy,
            an animation stepping through the configurations, one per second,
            with meshcat's time slider as a mode selector).
        spacing: distance between copies (m); default 1.4 x the largest copy.
        labels: one text per configuration, listed in the caption.
        frames: frames drawn as triads (default the platform).

    Raises:
        InputError: an unknown layout, no configurations, a wrong shape.
    """
    visual = robot_visual(robot, urdf)
    qs = _configurations(visual, configurations)
    if layout not in ("grid", "row", "sequence"):
        raise InputError("layout", layout, "expected 'grid', 'row' or 'sequence'")
    if labels is not None and len(labels) != len(qs):
        raise InputError("labels", labels, f"expected {len(qs)} labels")
    if layout == "sequence":
        times = np.arange(len(qs), dtype=float)
        scene = trajectory_scene(visual, times, qs, frames=frames, fps=None,
                                 caption=caption, discrete=True)
    else:
        scene = _side_by_side(visual, qs, layout, spacing, frames)
        scene.caption = caption
    if labels is not None:
        where = ("at t = " if layout == "sequence" else "")
        listed = "; ".join(f"{where}{i}{' s' if where else ''}: {text}"
                           for i, text in enumerate(labels))
        scene.caption = (caption + " | " if caption else "") + listed
    return scene


def _side_by_side(visual, qs, layout, spacing, frames) -> Scene:
    scene = Scene()
    extents = []
    for q in qs:
        _, placements = _placements(visual, q)
        pts = np.array([p.translation for p in placements])
        extents.append(pts.max(axis=0) - pts.min(axis=0))
    step = spacing if spacing is not None else 1.4 * float(np.max(np.array(extents)[:, :2]))
    per_row = len(qs) if layout == "row" else min(4, len(qs))
    points = []
    for index, q in enumerate(qs):
        row, col = divmod(index, per_row)
        offset = np.array([col * step, -row * step, 0.0])
        root = f"{ROOT}/{visual.name}_{index}"
        drawn = _draw_robot(scene, visual, q, root, offset)
        points.extend(drawn.points)
        size = _scene_size(drawn.points)
        names = default_frames(visual) if frames is None else tuple(frames)
        if names:
            data = visual.model.createData()
            pin.framesForwardKinematics(visual.model, data, q)
            for name in names:
                _draw_triad(scene, f"{root}/frames/{_safe_name(name)}",
                            data.oMf[_frame_id(visual.model, name)], size / 6, 0.006 * size)
    _frame_camera(scene, points)
    return scene


def _configurations(visual: RobotVisual, configurations) -> np.ndarray:
    try:
        qs = np.asarray(configurations, dtype=float)
    except (TypeError, ValueError):
        raise InputError("configurations", configurations, "not numeric") from None
    if qs.ndim != 2 or qs.shape[1] != visual.model.nq or len(qs) == 0:
        raise InputError("configurations", configurations,
                         f"expected shape (M >= 1, {visual.model.nq}), got {qs.shape}")
    if not np.all(np.isfinite(qs)):
        raise InputError("configurations", configurations, "contains NaN or inf")
    return np.ascontiguousarray(qs)


def trajectory_scene(robot, times, configurations, *, actuator_forces=None,
                     closure_forces=None, frames: Sequence[str] | None = None,
                     force_scale: float | None = None, fps: float | None = 30.0,
                     caption: str = "", urdf=None, loop: bool = True,
                     discrete: bool = False) -> Scene:
    """A meshcat animation of the robot along a sampled motion (play controls in the page).

    Args:
        robot: see :func:`robot_visual`.
        times: sample times (N,), s, strictly increasing.
        configurations: Pinocchio configurations at those times, (N, nq).
        actuator_forces: optional efforts (N, n_act), drawn as animated arrows.
        closure_forces: optional closure forces (N, n_closures, 3), world axes.
        frames: frames drawn as animated triads (default the platform).
        force_scale: arrow length per newton (m/N); default: the largest effort
            over the motion drawn ``DEFAULT_ARROW_LENGTH`` long.
        fps: key frames per second of the animation: the samples nearest to
            ``times[0] + k / fps`` are kept (the viewer interpolates between
            keys); ``None`` keeps every sample.
        loop: repeat the animation forever (otherwise play once).
        discrete: hold each key until the next (no interpolation).

    The first sample is also drawn as the static scene, so the page shows the
    robot even where animations are off.

    Raises:
        InputError: shapes that do not match, times not increasing.
    """
    visual = robot_visual(robot, urdf)
    qs = _configurations(visual, configurations)
    t = _times(times, len(qs))
    keep = _keyframes(t, fps)
    t, qs = t[keep] - t[0], qs[keep]
    act = None if actuator_forces is None else as_array(
        actuator_forces, (len(configurations), _n_act(visual, actuator_forces)),
        "actuator_forces")[keep]
    clo = None
    if closure_forces is not None:
        n_closures = 0 if visual.closed_loop is None else len(visual.closed_loop.closures)
        clo = as_array(closure_forces, (len(configurations), n_closures, 3),
                       "closure_forces")[keep]
    scene = Scene()
    scene.caption = caption
    scene.hide_controls = False
    root = f"{ROOT}/{visual.name}"
    drawn = _draw_robot(scene, visual, qs[0], root, np.zeros(3))
    tracks: dict[str, dict[str, list]] = {path: {"position": [], "quaternion": []}
                                          for path in drawn.geometry_paths}
    points = list(drawn.points)
    for q in qs:
        _, placements = _placements(visual, q)
        for path, placement, half in zip(drawn.geometry_paths, placements, drawn.halves):
            pos, quat, _ = _decompose(placement.homogeneous)
            tracks[path]["position"].append(pos)
            tracks[path]["quaternion"].append(quat)
            points.extend(_corners(placement, half))
    size = _scene_size(drawn.points)
    _draw_overlays(scene, visual, qs[0], root, size,
                   None if act is None else act[0], None if clo is None else clo[0],
                   frames, force_scale, None)
    _animate_overlays(tracks, visual, qs, act, clo, frames, root, force_scale)
    clips = [_clip(path, t, props, discrete) for path, props in tracks.items()
             if _moves(props)]
    scene.set_animation(clips, play=True, loop=loop)
    _frame_camera(scene, points, panel=True)
    return scene


def _n_act(visual: RobotVisual, value) -> int:
    if visual.closed_loop is None:
        raise InputError("actuator_forces", value, "a bare tree has no actuated joints")
    return visual.closed_loop.n_actuated


def _times(times, n: int) -> np.ndarray:
    try:
        t = np.asarray(times, dtype=float)
    except (TypeError, ValueError):
        raise InputError("times", times, "not numeric") from None
    if t.shape != (n,) or not np.all(np.isfinite(t)):
        raise InputError("times", times, f"expected {n} finite values, got shape {t.shape}")
    if n > 1 and np.any(np.diff(t) <= 0):
        raise InputError("times", times, "must be strictly increasing")
    return t


def _keyframes(t: np.ndarray, fps: float | None) -> np.ndarray:
    if fps is None or len(t) < 2:
        return np.arange(len(t))
    if not (math.isfinite(fps) and fps > 0):
        raise InputError("fps", fps, "must be a positive number")
    wanted = t[0] + np.arange(0.0, t[-1] - t[0] + 0.5 / fps, 1.0 / fps)
    idx = np.clip(np.searchsorted(t, wanted), 0, len(t) - 1)
    prev = np.clip(idx - 1, 0, len(t) - 1)
    idx = np.where(np.abs(t[prev] - wanted) < np.abs(t[idx] - wanted), prev, idx)
    return np.unique(np.append(idx, len(t) - 1))


def _animate_overlays(tracks, visual, qs, act, clo, frames, root, force_scale) -> None:
    efforts = []
    act_series = None if act is None else [actuator_arrows(visual, q, a)
                                           for q, a in zip(qs, act)]
    clo_series = None if clo is None else [closure_arrows(visual, q, c)
                                           for q, c in zip(qs, clo)]
    for series in (act_series or []):
        efforts.extend(v for _, v, _ in series)
    for series in (clo_series or []):
        efforts.extend(v for _, v in series)
    scale = _arrow_scale(efforts, force_scale)
    for label, series in (("actuator", act_series), ("closure", clo_series)):
        if series is None:
            continue
        for frame in series:
            for i, arrow in enumerate(frame):
                pos, quat, scl = _decompose(_arrow_matrix(arrow[0], scale * arrow[1]))
                props = tracks.setdefault(f"{root}/overlays/{label}_{i}",
                                          {"position": [], "quaternion": [], "scale": []})
                props["position"].append(pos)
                props["quaternion"].append(quat)
                props["scale"].append(scl)
    names = default_frames(visual) if frames is None else tuple(frames)
    if names:
        data = visual.model.createData()
        ids = [_frame_id(visual.model, name) for name in names]
        for q in qs:
            pin.framesForwardKinematics(visual.model, data, q)
            for name, fid in zip(names, ids):
                pos, quat, _ = _decompose(data.oMf[fid].homogeneous)
                props = tracks.setdefault(f"{root}/frames/{_safe_name(name)}",
                                          {"position": [], "quaternion": []})
                props["position"].append(pos)
                props["quaternion"].append(quat)


def _moves(props: dict[str, list]) -> bool:
    return any(np.ptp(np.asarray(values), axis=0).max() > 1e-12 for values in props.values())


_JSTYPE = {"position": "vector3", "scale": "vector3", "quaternion": "quaternion"}


def _clip(path: str, times: np.ndarray, props: dict[str, list], discrete: bool) -> dict:
    tracks = []
    for prop, values in props.items():
        track = {"name": "." + prop, "type": _JSTYPE[prop],
                 "keys": [{"time": float(t), "value": v} for t, v in zip(times, values)]}
        if discrete:
            track["interpolation"] = 2300  # THREE.InterpolateDiscrete
        tracks.append(track)
    return {"path": path, "clip": {"fps": 1.0, "name": "default", "tracks": tracks}}


# -- hexapod helpers ---------------------------------------------------------------------
def hexapod_configurations(robot, poses, carriages=None) -> np.ndarray:
    """Pinocchio configurations (N, nq) of the hexapod for platform poses (N, 6).

    Args:
        robot: a :class:`hexapod_pin.Hexapod`.
        poses: platform poses (m, rad), shape (N, 6) or (6,).
        carriages: carriage positions (N, 6) or (6,) (m) the configurations must
            have: for each carriage the inverse-kinematics root nearest to it is
            taken (needed for assembly modes off the home branch); default the
            home branch.

    Raises:
        UnreachablePoseError: a pose out of reach.
        InputError: wrong shapes.
        AssemblyError: the closed form misses the closures.
    """
    from ..core.checks import as_array

    poses = np.atleast_2d(as_array(poses, (6,), "poses", batch=np.ndim(poses) == 2))
    if carriages is None:
        return np.array([robot.configuration(p) for p in poses])
    carriages = np.atleast_2d(as_array(carriages, (6,), "carriages",
                                       batch=np.ndim(carriages) == 2))
    if len(carriages) != len(poses):
        raise InputError("carriages", carriages, f"expected {len(poses)} rows")
    out = []
    for pose, target in zip(poses, carriages):
        plus = robot.inverse_kinematics(pose, branch=np.ones(6), check_limits=False)
        minus = robot.inverse_kinematics(pose, branch=-np.ones(6), check_limits=False)
        branch = np.where(np.abs(plus - target) <= np.abs(minus - target), 1.0, -1.0)
        out.append(robot.configuration(pose, branch=branch))
    return np.array(out)


def hexapod_trajectory_scene(robot, times, poses, *, carriages=None, actuator_forces=None,
                             fps: float | None = 30.0, **options) -> Scene:
    """:func:`trajectory_scene` of the hexapod from platform poses.

    The samples are thinned to ``fps`` key frames first, then turned into
    Pinocchio configurations by :func:`hexapod_configurations`.

    Args:
        robot: a :class:`hexapod_pin.Hexapod`.
        times: sample times (N,), s, strictly increasing.
        poses: platform poses (N, 6) (m, rad).
        carriages: carriage positions (N, 6) (m) choosing the leg branches;
            default the home branch.
        actuator_forces: carriage forces (N, 6), N, drawn along the rails.
        fps: key frames per second; ``None`` keeps every sample.
        **options: passed on to :func:`trajectory_scene` (``caption``,
            ``frames``, ``force_scale``, ``closure_forces`` (N, 6, 3), ...).

    Raises:
        InputError, UnreachablePoseError: bad input.
    """
    from ..core.checks import as_array

    poses = as_array(poses, (6,), "poses", batch=True)
    t = _times(times, len(poses))
    keep = _keyframes(t, fps)
    carriages_kept = None
    if carriages is not None:
        carriages_kept = as_array(carriages, (6,), "carriages", batch=True)
        if len(carriages_kept) != len(poses):
            raise InputError("carriages", carriages, f"expected {len(poses)} rows")
        carriages_kept = carriages_kept[keep]
    qs = hexapod_configurations(robot, poses[keep], carriages_kept)
    if actuator_forces is not None:
        actuator_forces = as_array(actuator_forces, (len(poses), 6), "actuator_forces")[keep]
    closure_forces = options.pop("closure_forces", None)
    if closure_forces is not None:
        closure_forces = as_array(closure_forces, (len(poses), 6, 3),
                                    "closure_forces")[keep]
    return trajectory_scene(robot, t[keep], qs, actuator_forces=actuator_forces,
                            closure_forces=closure_forces, fps=None, **options)


def simulation_scene(robot, trajectory, *, forces: bool = True, **options) -> Scene:
    """Animation of a simulated hexapod trajectory (``hexapod_pin.simulate.Trajectory``).

    Reads the attributes ``times`` (N,) and either ``configurations`` (N, nq)
    (the simulated tree configurations, drawn as they are) or ``poses`` (N, 6)
    with ``q`` (N, 6) carriage positions choosing the leg branches; with
    ``forces``, also ``actuator_forces`` (N, 6).

    Raises:
        InputError: ``trajectory`` lacks those attributes or has wrong shapes.
    """
    try:
        times, poses = trajectory.times, trajectory.poses
    except AttributeError:
        raise InputError("trajectory", trajectory, "needs attributes times and poses") from None
    q = getattr(trajectory, "q", None)
    tau = getattr(trajectory, "actuator_forces", None) if forces else None
    configurations = getattr(trajectory, "configurations", None)
    if configurations is not None and np.shape(configurations)[-1:] == (robot.model.nq,):
        return trajectory_scene(robot, times, configurations, actuator_forces=tau, **options)
    return hexapod_trajectory_scene(robot, times, poses, carriages=q, actuator_forces=tau,
                                    **options)


# -- files -------------------------------------------------------------------------------
def write_pose_html(path, robot, q, **options) -> Path:
    """Write :func:`pose_scene` (same arguments) to an HTML file; returns its path."""
    return pose_scene(robot, q, **options).write(path)


def write_modes_html(path, robot, configurations, **options) -> Path:
    """Write :func:`modes_scene` (same arguments) to an HTML file; returns its path."""
    return modes_scene(robot, configurations, **options).write(path)


def write_trajectory_html(path, robot, times, configurations, **options) -> Path:
    """Write :func:`trajectory_scene` (same arguments) to an HTML file; returns its path."""
    return trajectory_scene(robot, times, configurations, **options).write(path)


def write_hexapod_trajectory_html(path, robot, times, poses, **options) -> Path:
    """Write :func:`hexapod_trajectory_scene` (same arguments) to HTML; returns its path."""
    return hexapod_trajectory_scene(robot, times, poses, **options).write(path)


def write_simulation_html(path, robot, trajectory, **options) -> Path:
    """Write :func:`simulation_scene` (same arguments) to HTML; returns its path."""
    return simulation_scene(robot, trajectory, **options).write(path)


# -- workspace point clouds -----------------------------------------------------------------
#: a short perceptually ordered colour map (viridis samples), low -> high
_COLORMAP = np.array([[0.267, 0.005, 0.329], [0.283, 0.141, 0.458], [0.254, 0.265, 0.530],
                      [0.207, 0.372, 0.553], [0.164, 0.471, 0.558], [0.128, 0.567, 0.551],
                      [0.135, 0.659, 0.518], [0.267, 0.749, 0.441], [0.478, 0.821, 0.318],
                      [0.741, 0.873, 0.150], [0.993, 0.906, 0.144]])


def colormap(values, low: float | None = None, high: float | None = None) -> np.ndarray:
    """RGB colours (N, 3) in [0, 1] for ``values`` (N,), linear between ``low`` and ``high``
    (default their finite min / max); non-finite values get the top colour."""
    values = np.asarray(values, dtype=float)
    finite = np.isfinite(values)
    lo = float(values[finite].min()) if low is None and finite.any() else float(low or 0.0)
    hi = float(values[finite].max()) if high is None and finite.any() else float(high or 1.0)
    span = hi - lo if hi > lo else 1.0
    t = np.clip(np.where(finite, (values - lo) / span, 1.0), 0.0, 1.0)
    grid = np.linspace(0.0, 1.0, len(_COLORMAP))
    return np.stack([np.interp(t, grid, _COLORMAP[:, c]) for c in range(3)], axis=1)


def workspace_scene(robot, positions, values=None, *, q=None, point_size: float = 0.008,
                    low: float | None = None, high: float | None = None,
                    robot_opacity: float = 0.3, caption: str = "", urdf=None) -> Scene:
    """The robot with a cloud of workspace points, coloured by a value per point.

    Args:
        robot: see :func:`robot_visual` (a Hexapod, a ClosedLoopModel, ...).
        positions: (N, 3) points in world axes (m), e.g. the reachable platform
            positions ``poses[m.ok, :3]`` of :func:`hexapod_pin.workspace.evaluate`.
        values: (N,) values coloured low (purple) to high (yellow), e.g. the
            condition number (log scale is the caller's choice); default one colour.
        q: configuration the robot is drawn at; default ``robot.home_configuration``
            when the robot has one, else Pinocchio's neutral configuration.
        point_size: point size (m).
        low, high: colour-map limits; default the finite min / max of ``values``.
        robot_opacity: opacity of the robot (0..1], so the cloud inside it shows.
        caption, urdf: as in :func:`pose_scene`.

    Raises:
        InputError: wrong shapes, NaN positions, or a non-positive point size.
    """
    visual = robot_visual(robot, urdf)
    pts = as_array(positions, (int(np.shape(positions)[0]) if np.ndim(positions) == 2
                                 else -1, 3), "positions")
    if values is None:
        colors = np.tile([0.13, 0.57, 0.55], (pts.shape[0], 1))
    else:
        vals = np.asarray(values, dtype=float)
        if vals.shape != (pts.shape[0],):
            raise InputError("values", values, f"expected shape ({pts.shape[0]},)")
        colors = colormap(vals, low, high)
    if not (math.isfinite(point_size) and point_size > 0):
        raise InputError("point_size", point_size, "must be finite and > 0 (m)")
    if not (0.0 < robot_opacity <= 1.0):
        raise InputError("robot_opacity", robot_opacity, "must be in (0, 1]")
    if q is None:
        q = getattr(robot, "home_configuration", None)
        q = pin.neutral(visual.model) if q is None else q
    q = _check_configuration(visual, q)
    scene = Scene()
    scene.caption = caption
    root = f"{ROOT}/{visual.name}"
    drawn = _draw_robot(scene, visual, q, root, np.zeros(3))
    if robot_opacity < 1.0:
        for command in scene._commands:
            if command["type"] == "set_object" and command["path"].startswith(root):
                for material in command["object"].get("materials", []):
                    material["opacity"] = float(robot_opacity) * material.get("opacity", 1.0)
                    material["transparent"] = True
    mg, _ = _meshcat()
    cloud = mg.Points(mg.PointsGeometry(pts.T.astype(np.float32), color=colors.T.astype(np.float32)),
                      mg.PointsMaterial(size=float(point_size)))
    scene.set_object(f"{ROOT}/workspace", cloud.lower())
    _frame_camera(scene, list(drawn.points) + ([pts.min(axis=0), pts.max(axis=0)]
                                               if pts.shape[0] else []))
    return scene


def write_workspace_html(path, robot, positions, values=None, **options) -> Path:
    """Write :func:`workspace_scene` (same arguments) to HTML; returns its path."""
    return workspace_scene(robot, positions, values, **options).write(path)

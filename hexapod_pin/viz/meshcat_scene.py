"""A meshcat scene recorded without a server, written as one self-contained HTML page.

A :class:`Scene` records meshcat commands (``set_object``, ``set_transform``,
``set_property``, ``set_animation``) as msgpack blobs; :meth:`Scene.html` packs them
with meshcat's JavaScript viewer (``meshcat/viewer/dist/main.min.js``) into one HTML
file that any browser opens from disk, with the usual orbit controls and, for
animations, meshcat's animation panel (play / pause / reset / time slider). Nothing
here starts a process.

This module knows meshcat and Coal shapes, not robots: it lowers a Pinocchio
``GeometryObject`` to meshcat objects (:func:`shape_objects`), draws unit arrows
(:func:`arrow_objects`, :func:`arrow_matrix`), builds animation clips
(:func:`animation_clip`) and frames the camera (:func:`frame_camera`).

Conventions: positions in metres, world axes (z up; meshcat's three.js scene is y up,
converted when the page is written); transforms are 4x4 homogeneous matrices relative
to the parent node. The page understands ``#t=<seconds>`` at the end of its URL: the
animation is paused at that time (used by the tests and the screenshots).
"""

from __future__ import annotations

import base64
import html as html_lib
import json
import math
import os
import uuid
import warnings
from pathlib import Path
from typing import Any

import coal
import numpy as np
import pinocchio as pin
import umsgpack
from numpy.typing import ArrayLike

from ..errors import DescriptionError
from ..files import write_text_atomic

#: page background, top and bottom colours (RGB in [0, 1])
BACKGROUND = ((1.0, 1.0, 1.0), (0.80, 0.83, 0.88))
#: vertical field of view of the camera (deg)
CAMERA_FOV_DEG = 40.0
#: direction from the scene centre to the camera, world axes (normalised on use)
CAMERA_DIRECTION = (1.0, -1.35, 0.95)
#: meshcat path of the scene root
ROOT = "/meshcat"
#: a short perceptually ordered colour map (viridis samples), low -> high: the colours of
#: point clouds (:func:`hexapod_pin.viz.scenes.colormap`) and of the colour bar
COLORMAP = np.array([[0.267, 0.005, 0.329], [0.283, 0.141, 0.458], [0.254, 0.265, 0.530],
                     [0.207, 0.372, 0.553], [0.164, 0.471, 0.558], [0.128, 0.567, 0.551],
                     [0.135, 0.659, 0.518], [0.267, 0.749, 0.441], [0.478, 0.821, 0.318],
                     [0.741, 0.873, 0.150], [0.993, 0.906, 0.144]])
#: three.js InterpolateDiscrete: hold each key until the next
DISCRETE_INTERPOLATION = 2300


def _meshcat() -> Any:
    """meshcat's geometry module, imported on first use (not to hide a cycle): importing
    meshcat pulls in IPython and zmq, which ``import hexapod_pin`` should not pay."""
    with warnings.catch_warnings():  # meshcat's server module imports a deprecated zmq API
        warnings.simplefilter("ignore", DeprecationWarning)
        import meshcat.geometry as mg
    return mg


def _assets_js() -> str:
    mg = _meshcat()
    path = Path(mg.__file__).resolve().parent / "viewer" / "dist" / "main.min.js"
    if not path.is_file():
        raise DescriptionError(str(path), "meshcat's viewer JavaScript is missing")
    return path.read_text(encoding="utf-8")
class Scene:
    """A meshcat scene recorded as a list of commands, written as HTML (no server).

    Paths are meshcat paths (``"/meshcat/robot/leg_0_0"``). Matrices are 4x4
    homogeneous transforms in world axes (z up) relative to the parent node.

    Attributes:
        camera_target: where the camera looks, world axes (m) (set by the scene functions
            to frame the robot).
        camera_position: where the camera stands, world axes (m) (set likewise).
        caption: text in the page's lower-left corner (no box when empty).
        legend: lines of text in the page's upper-left corner (what the colours and
            arrows mean, the arrow length scale); none when empty.
        colorbar: ``(low, high, label)``: a colour bar of :data:`COLORMAP` from
            ``low`` to ``high`` with its label, in the upper-right corner; None: none.
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
        self.legend: list[str] = []
        self.colorbar: tuple[float, float, str] | None = None
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

    def set_property(self, path: str, key: str, value: Any) -> None:
        """Record a ``set_property`` (e.g. ``visible``, ``position``)."""
        self._commands.append({"type": "set_property", "path": path, "property": key,
                               "value": value})

    def set_animation(self, clips: list[dict], play: bool = True, loop: bool = True) -> None:
        """Record a ``set_animation``: ``clips`` as made by :func:`animation_clip`."""
        self._commands.append({"type": "set_animation", "path": "", "animations": clips,
                               "options": {"play": bool(play),
                                           "repetitions": math.inf if loop else 1}})

    # -- output ---------------------------------------------------------------------
    def count(self, kind: str) -> int:
        """Number of recorded commands of one type (``"set_object"`` ...)."""
        return sum(1 for c in self._commands if c["type"] == kind)

    def html(self) -> str:
        """The scene as one self-contained HTML page (meshcat viewer inlined)."""
        blobs = [base64.b64encode(umsgpack.packb(c)).decode("ascii") for c in self._commands]
        target = _three(self.camera_target)
        camera = _three(self.camera_position)
        script = _PAGE_SCRIPT.format(
            commands=json.dumps(blobs), camera=json.dumps(camera), target=json.dumps(target),
            fov=json.dumps(CAMERA_FOV_DEG), hide=json.dumps(bool(self.hide_controls)),
            seek=json.dumps(None if self.seek_time is None else float(self.seek_time)))
        return _PAGE.format(title=html_lib.escape(self.title),
                            caption=html_lib.escape(self.caption),
                            overlays=self._overlays_html(),
                            viewer_js=_assets_js(), script=script)

    def _overlays_html(self) -> str:
        parts = []
        if self.legend:
            lines = "<br>".join(html_lib.escape(str(line)) for line in self.legend)
            parts.append(f'<div id="hexapod-pin-legend">{lines}</div>')
        if self.colorbar is not None:
            low, high, label = self.colorbar
            stops = ", ".join(f"rgb({round(255 * r)}, {round(255 * g)}, {round(255 * b)})"
                              for r, g, b in COLORMAP)
            parts.append(
                f'<div id="hexapod-pin-colorbar"><div>{html_lib.escape(str(label))}</div>'
                f'<div style="display: flex; align-items: stretch; gap: 6px;">'
                f'<div style="width: 16px; height: 160px; '
                f'background: linear-gradient(to top, {stops});"></div>'
                f'<div style="display: flex; flex-direction: column; '
                f'justify-content: space-between;"><span>{float(high):.4g}</span>'
                f'<span>{float(low):.4g}</span></div></div></div>')
        return "\n".join(parts)

    def write(self, path: str | os.PathLike) -> Path:
        """Write :meth:`html` to ``path`` atomically; returns the path."""
        return write_text_atomic(path, self.html())

    def _repr_html_(self) -> str:
        """The scene inline in Jupyter: the page in an ``iframe`` (``srcdoc``, no server,
        no file), 100 % wide and 480 px high."""
        return ('<iframe style="width: 100%; height: 480px; border: 0;" '
                f'srcdoc="{html_lib.escape(self.html(), quote=True)}"></iframe>')


def _three(vec: ArrayLike) -> list[float]:
    """World (z up) coordinates -> three.js scene coordinates of meshcat (y up)."""
    x, y, z = (float(v) for v in np.asarray(vec, dtype=float).reshape(3))
    return [x, z, -y]


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
#hexapod-pin-caption:empty {{ display: none; }}
#hexapod-pin-legend {{ position: absolute; left: 8px; top: 8px; padding: 2px 6px;
  font: 13px sans-serif; color: #222; background: rgba(255, 255, 255, 0.75); }}
#hexapod-pin-colorbar {{ position: absolute; right: 260px; top: 8px; padding: 4px 6px;
  font: 13px sans-serif; color: #222; background: rgba(255, 255, 255, 0.75); }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<div id="hexapod-pin-caption">{caption}</div>
{overlays}
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
def _color_int(rgba: ArrayLike) -> int:
    r, g, b = (min(max(float(c), 0.0), 1.0) for c in np.asarray(rgba, dtype=float)[:3])
    return (round(r * 255) << 16) | (round(g * 255) << 8) | round(b * 255)


def _mesh(geometry: Any, color: int, opacity: float = 1.0,
          intrinsic: np.ndarray | None = None) -> dict:
    """Lower a meshcat geometry + phong material, with a correct intrinsic transform."""
    mg = _meshcat()
    material = mg.MeshPhongMaterial(color=int(color), opacity=float(opacity))
    lowered = mg.Mesh(geometry, material).lower()
    mat = np.eye(4) if intrinsic is None else np.asarray(intrinsic, dtype=float)
    lowered["object"]["matrix"] = [float(v) for v in mat.T.ravel()]  # three.js: column-major
    return lowered


_Y_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])  # Rx(+90 deg)


def shape_objects(gobj: pin.GeometryObject, opacity: float = 1.0
                  ) -> tuple[list[tuple[str, dict]], np.ndarray]:
    """Lowered meshcat objects (sub-path, object) for a Pinocchio GeometryObject, and the
    half extents (3,) of its bounding box in its own frame (m), around its origin.

    Boxes, spheres, ellipsoids, capsules (three parts: ``body``, ``cap_top``,
    ``cap_bottom``), cones, cylinders and STL / OBJ / DAE mesh files are drawn as they
    are; anything else Coal loaded (another mesh format, a mesh held in memory) as its
    bounding box. The colour is the object's ``meshColor``; its alpha is multiplied by
    ``opacity``. The sub-path is ``""`` for a single object.
    """
    mg = _meshcat()
    geom = gobj.geometry
    color, opacity = _color_int(gobj.meshColor), float(opacity) * float(gobj.meshColor[3])
    scale = np.diag(np.append(np.asarray(gobj.meshScale, dtype=float), 1.0))

    def cyl(height: float, radius_top: float, radius_bottom: float, shift: float = 0.0) -> dict:
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


def _aabb(geom: Any) -> tuple[np.ndarray, np.ndarray]:
    try:
        geom.computeLocalAABB()
        box = geom.aabb_local
        return np.asarray(box.min_, dtype=float), np.asarray(box.max_, dtype=float)
    except (AttributeError, RuntimeError):  # no AABB: a small cube, so it is still seen
        return -0.01 * np.ones(3), 0.01 * np.ones(3)


def _aabb_half(geom: Any, scale: ArrayLike) -> np.ndarray:
    lo, hi = _aabb(geom)
    return np.diag(scale)[:3] * np.maximum(np.abs(lo), np.abs(hi))


_CORNERS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)],
                    dtype=float)


def box_corners(placement: pin.SE3, half: np.ndarray) -> np.ndarray:
    """World corners (8, 3) of a box of half extents ``half`` at ``placement``."""
    return (_CORNERS * half) @ placement.rotation.T + placement.translation


def arrow_objects(color: int, radius: float) -> list[tuple[str, dict]]:
    """A unit arrow along local +y (shaft 0.8, head 0.2), as two lowered meshes."""
    mg = _meshcat()
    shaft, head = np.eye(4), np.eye(4)
    shaft[1, 3], head[1, 3] = 0.4, 0.9
    return [("shaft", _mesh(mg.Cylinder(0.8, radius), color, 1.0, shaft)),
            ("head", _mesh(mg.Cylinder(0.2, radiusTop=0.0, radiusBottom=2.5 * radius),
                           color, 1.0, head))]


def arrow_matrix(origin: ArrayLike, vector: ArrayLike) -> np.ndarray:
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


def decompose(mat: np.ndarray) -> tuple[list[float], list[float], list[float]]:
    """position, quaternion (x, y, z, w), scale of ``R diag(s) | t`` (s > 0)."""
    scale = np.linalg.norm(mat[:3, :3], axis=0)
    rot = mat[:3, :3] / scale
    quat = pin.Quaternion(rot).normalized().coeffs()
    return ([float(v) for v in mat[:3, 3]], [float(v) for v in quat],
            [float(v) for v in scale])


# -- animation and camera ------------------------------------------------------------
_JSTYPE = {"position": "vector3", "scale": "vector3", "quaternion": "quaternion"}


def animation_clip(path: str, times: np.ndarray, props: dict[str, list],
                   discrete: bool = False) -> dict:
    """One meshcat animation clip of a node: ``props`` maps ``"position"`` / ``"scale"``
    (lists of 3 floats) and ``"quaternion"`` (x, y, z, w) to one value per time (s);
    ``discrete`` holds each key until the next (no interpolation)."""
    tracks = []
    for prop, values in props.items():
        track: dict[str, Any] = {"name": "." + prop, "type": _JSTYPE[prop],
                 "keys": [{"time": float(t), "value": v} for t, v in zip(times, values)]}
        if discrete:
            track["interpolation"] = DISCRETE_INTERPOLATION
        tracks.append(track)
    return {"path": path, "clip": {"fps": 1.0, "name": "default", "tracks": tracks}}


def frame_camera(scene: Scene, points: list[np.ndarray], aspect: float = 4 / 3,
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


def points_extent(points: list[np.ndarray]) -> float:
    """Diagonal (m) of the axis-aligned box around points (any shape ending in 3)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    return float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))



def text_object(text: str, width: float, height: float, font_size: int = 64) -> dict:
    """A lowered meshcat sign of ``width`` x ``height`` (m) showing ``text`` (meshcat's
    canvas text texture): a thin box in its local x-y plane, readable from +z."""
    mg = _meshcat()
    material = mg.MeshBasicMaterial(color=0xFFFFFF, transparent=True)
    lowered = mg.Mesh(mg.Box([float(width), float(height), 1e-4]), material).lower()
    texture = str(uuid.uuid4())
    lowered["textures"] = [{"uuid": texture, "type": "_text", "text": str(text),
                            "font_size": int(font_size), "font_face": "sans-serif"}]
    lowered["materials"][0]["map"] = texture
    lowered["materials"][0]["side"] = 0     # front faces only: no mirrored text behind
    return lowered


def polyline_object(points: np.ndarray, color: int) -> dict:
    """A lowered meshcat polyline through ``points`` (N, 3) (m, world axes), in ``color``
    (0xRRGGBB)."""
    mg = _meshcat()
    geometry = mg.PointsGeometry(np.asarray(points, dtype=np.float32).T)
    return mg.Line(geometry, mg.LineBasicMaterial(color=int(color), linewidth=2)).lower()


def point_cloud_object(points: np.ndarray, colors: np.ndarray, size: float) -> dict:
    """A lowered meshcat point cloud: ``points`` (N, 3) (m, world axes), ``colors``
    (N, 3) RGB in [0, 1], point ``size`` (m)."""
    mg = _meshcat()
    geometry = mg.PointsGeometry(np.asarray(points, dtype=np.float32).T,
                                 color=np.asarray(colors, dtype=np.float32).T)
    return mg.Points(geometry, mg.PointsMaterial(size=float(size))).lower()

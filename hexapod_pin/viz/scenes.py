"""Meshcat scenes of closed-loop robots, written as self-contained HTML files.

Scenes of any robot :func:`~hexapod_pin.viz.drawing.robot_visual` can draw (a
:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`, an object carrying one as
``.model`` such as :class:`hexapod_pin.Hexapod` or :class:`hexapod_pin.Planar3PRR`, or a
bare ``pin.Model`` with its URDF), given Pinocchio configurations of the tree:

* :func:`pose_scene`: one configuration, with actuator / closure force arrows and
  frame triads;
* :func:`modes_scene`: several configurations (e.g. assembly modes) side by side or
  as a stepped animation;
* :func:`trajectory_scene`: an animation along sampled configurations;
* :func:`workspace_scene`: the robot with a coloured point cloud (e.g. workspace
  positions coloured by ``cond(J)``).

Each has a ``write_*_html`` twin writing the page atomically. Platform poses become
configurations through the robot's own ``configuration(pose)``; the hexapod's helpers
(poses with carriage branches, simulation results) are in
:mod:`hexapod_pin.viz.hexapod_scenes`. How the page is built:
:mod:`hexapod_pin.viz.meshcat_scene`; how a robot is drawn: :mod:`hexapod_pin.viz.drawing`.

Conventions: positions in metres, world axes (z up); forces in newtons drawn as
arrows ``force_scale`` metres per newton long (default: the largest force drawn
0.15 m long); times in seconds.

Typical use::

    import hexapod_pin as hp
    from hexapod_pin.viz import scenes
    robot = hp.Hexapod.default()
    scenes.write_pose_html("home.html", robot, robot.home_configuration)
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from ..core.checks import as_array
from ..errors import InputError
from .drawing import (
    DEFAULT_ARROW_LENGTH,
    RobotVisual,
    actuator_arrows,
    arrow_scale,
    check_configuration,
    closure_arrows,
    default_frames,
    draw_overlays,
    draw_robot,
    draw_triad,
    force_legend,
    frame_id,
    triad_legend,
    geometry_placements,
    robot_visual,
    safe_name,
)
from .meshcat_scene import (
    COLORMAP,
    ROOT,
    Scene,
    animation_clip,
    arrow_matrix,
    box_corners,
    decompose,
    frame_camera,
    point_cloud_object,
    points_extent,
    polyline_object,
    text_object,
)

__all__ = ["COLORMAP", "DEFAULT_ARROW_LENGTH", "PATH_COLOR", "RobotVisual", "Scene",
           "check_times", "colormap", "keyframes", "label_size", "modes_scene", "platform_path", "pose_scene", "robot_visual", "trajectory_scene",
           "workspace_scene", "write_modes_html", "write_pose_html", "write_trajectory_html",
           "write_workspace_html"]


#: colour of the traced platform path (grey)
PATH_COLOR = 0x555555


# -- public scenes ----------------------------------------------------------------------
def pose_scene(robot: Any, q: ArrayLike, *, actuator_forces: ArrayLike | None = None,
               closure_forces: ArrayLike | None = None,
               frames: Sequence[str] | None = None, force_scale: float | None = None,
               triad_length: float | None = None, caption: str = "",
               urdf: str | os.PathLike | None = None) -> Scene:
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
    q = check_configuration(visual, q)
    scene = Scene()
    scene.caption = caption
    root = f"{ROOT}/{visual.name}"
    drawn = draw_robot(scene, visual, q, root)
    size = points_extent(drawn.points)
    scale = draw_overlays(scene, visual, q, root, size, actuator_forces, closure_forces,
                          frames, force_scale, triad_length)
    scene.legend = force_legend(scale, actuator_forces is not None,
                                closure_forces is not None) + triad_legend(
        default_frames(visual) if frames is None else tuple(frames))
    frame_camera(scene, drawn.points)
    return scene




def modes_scene(robot: Any, configurations: ArrayLike, *, layout: str = "grid",
                spacing: float | None = None,
                labels: Sequence[str] | None = None, frames: Sequence[str] | None = None,
                urdf: str | os.PathLike | None = None, caption: str = "") -> Scene:
    """Several configurations of one robot (e.g. all assembly modes) in one scene.

    Args:
        robot: see :func:`robot_visual`.
        configurations: Pinocchio configurations, shape (M, nq).
        layout: ``"grid"`` (side by side in rows of up to 4, each copy offset in x
            then -y), ``"row"`` (all along x), or ``"sequence"`` (one copy,
            an animation stepping through the configurations, one per second,
            with meshcat's time slider as a mode selector).
        spacing: distance between copies (m); default 1.4 x the largest copy.
        labels: one text per configuration, listed in the caption; side by side, each
            copy also carries ``"<index>: <label>"`` on a sign just below it, facing the
            camera, narrower than the spacing (no sign overlaps a copy or another sign).
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
                                 caption=caption, discrete=True, path=False)
    else:
        scene = _side_by_side(visual, qs, layout, spacing, frames, labels)
        scene.caption = caption
    if labels is not None:
        where = ("at t = " if layout == "sequence" else "")
        listed = "; ".join(f"{where}{i}{' s' if where else ''}: {text}"
                           for i, text in enumerate(labels))
        scene.caption = (caption + " | " if caption else "") + listed
        scene.legend = ([(f"one copy per configuration, numbered 0 .. {len(qs) - 1} left to "
                          "right, then row by row; the number and label on a sign below each")]
                        if layout != "sequence" else
                        ["the time slider steps through the configurations, one per second"])
    if layout != "sequence":
        scene.legend = list(scene.legend) + triad_legend(
            default_frames(visual) if frames is None else tuple(frames))
    return scene


def _side_by_side(visual: RobotVisual, qs: np.ndarray, layout: str, spacing: float | None,
                  frames: Sequence[str] | None, labels: Sequence[str] | None = None) -> Scene:
    scene = Scene()
    extents = []
    for q in qs:
        placements = geometry_placements(visual, q)
        pts = np.array([p.translation for p in placements])
        extents.append(pts.max(axis=0) - pts.min(axis=0))
    step = spacing if spacing is not None else 1.4 * float(np.max(np.array(extents)[:, :2]))
    per_row = len(qs) if layout == "row" else min(4, len(qs))
    points = []
    copies = []
    for index, q in enumerate(qs):
        row, col = divmod(index, per_row)
        offset = np.array([col * step, -row * step, 0.0])
        root = f"{ROOT}/{visual.name}_{index}"
        drawn = draw_robot(scene, visual, q, root, offset)
        points.extend(drawn.points)
        copies.append(np.array(drawn.points))
        size = points_extent(drawn.points)
        names = default_frames(visual) if frames is None else tuple(frames)
        if names:
            data = visual.model.createData()
            pin.framesForwardKinematics(visual.model, data, q)
            for name in names:
                draw_triad(scene, f"{root}/frames/{safe_name(name)}",
                            data.oMf[frame_id(visual.model, name)], size / 6, 0.006 * size)
    frame_camera(scene, points)
    if labels is not None:
        _label_copies(scene, copies, labels, step)
    return scene


def _label_copies(scene: Scene, copies: list[np.ndarray], labels: Sequence[str],
                  step: float) -> None:
    """A sign ``"<index>: <label>"`` just below each copy, standing up and turned towards
    the camera (so the caption's list can be matched to the copies). The sign is at most
    0.9 ``step`` wide (copies are ``step`` apart, at most ``step / 1.4`` wide by default)
    and its height follows the text's length (at most 0.2 ``step``): it overlaps neither
    its copy (it is below its lowest part) nor the copies or signs beside it. ``copies``:
    the corners (world, shifted) of each copy's boxes."""
    for index, (corners, label) in enumerate(zip(copies, labels)):
        text = f"{index}: {label}"
        width, height = label_size(text, step)
        centre = (corners.min(axis=0) + corners.max(axis=0)) / 2
        anchor = np.array([*centre[:2], corners[:, 2].min() - 0.05 * step - height / 2])
        towards = scene.camera_position - anchor
        towards[2] = 0.0
        norm = float(np.linalg.norm(towards))
        d = towards / norm if norm > 1e-9 else np.array([1.0, 0.0, 0.0])
        up = np.array([0.0, 0.0, 1.0])
        mat = np.eye(4)
        mat[:3, :3] = np.column_stack([np.cross(up, d), up, d])
        mat[:3, 3] = anchor
        path = f"{ROOT}/labels/{index}"
        scene.set_object(path, text_object(text, width, height))
        scene.set_transform(path, mat)


def label_size(text: str, step: float) -> tuple[float, float]:
    """Width and height (m) of the sign of ``text`` under a copy of a layout ``step``
    apart: 0.9 ``step`` wide, as tall as the text's aspect asks (a character about 0.6
    of the font size wide, a line 1.2 tall: height / width = 2 / characters), at most
    0.2 ``step``."""
    width = 0.9 * step
    return width, min(0.2 * step, 2.0 * width / max(len(text), 1))


def _configurations(visual: RobotVisual, configurations: ArrayLike) -> np.ndarray:
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


def trajectory_scene(robot: Any, times: ArrayLike, configurations: ArrayLike, *,
                     actuator_forces: ArrayLike | None = None,
                     closure_forces: ArrayLike | None = None, frames: Sequence[str] | None = None,
                     force_scale: float | None = None, fps: float | None = 30.0,
                     caption: str = "", urdf: str | os.PathLike | None = None, loop: bool = True,
                     discrete: bool = False, path: bool = True) -> Scene:
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
        path: trace the path of the platform origin over every sample (not only the
            key frames) as a grey polyline (:func:`platform_path`); the platform is
            ``robot.platform_frame`` for a robot that has one, else the first of
            ``frames`` (default: the ``platform`` body); no frame, no path.

    The first sample is also drawn as the static scene, so the page shows the
    robot even where animations are off.

    Raises:
        InputError: shapes that do not match, times not increasing.
    """
    visual = robot_visual(robot, urdf)
    qs = _configurations(visual, configurations)
    qs_all = qs
    t = check_times(times, len(qs))
    keep = keyframes(t, fps)
    t, qs = t[keep] - t[0], qs[keep]
    act = None if actuator_forces is None else as_array(
        actuator_forces, (len(qs_all), _n_act(visual, actuator_forces)),
        "actuator_forces")[keep]
    clo = None
    if closure_forces is not None:
        n_closures = 0 if visual.closed_loop is None else len(visual.closed_loop.closures)
        clo = as_array(closure_forces, (len(qs_all), n_closures, 3),
                       "closure_forces")[keep]
    scene = Scene()
    scene.caption = caption
    scene.hide_controls = False
    root = f"{ROOT}/{visual.name}"
    drawn = draw_robot(scene, visual, qs[0], root)
    tracks: dict[str, dict[str, list]] = {path: {"position": [], "quaternion": []}
                                          for path in drawn.geometry_paths}
    points = list(drawn.points)
    for q in qs:
        placements = geometry_placements(visual, q)
        for path, placement, half in zip(drawn.geometry_paths, placements, drawn.halves):
            pos, quat, _ = decompose(placement.homogeneous)
            tracks[path]["position"].append(pos)
            tracks[path]["quaternion"].append(quat)
            points.extend(box_corners(placement, half))
    size = points_extent(drawn.points)
    scale = _animate_overlays(tracks, visual, qs, act, clo, frames, root, force_scale)
    draw_overlays(scene, visual, qs[0], root, size,
                  None if act is None else act[0], None if clo is None else clo[0],
                  frames, scale, None)
    legend = force_legend(scale, act is not None, clo is not None) \
        if act is not None or clo is not None else []
    names = default_frames(visual) if frames is None else tuple(frames)
    traced = _path_frame(robot, visual, names) if path else None
    if traced is not None:
        origins = platform_path(visual, qs_all, traced)
        scene.set_object(f"{root}/path", polyline_object(origins, PATH_COLOR))
        points.extend(origins)
        legend.append(f"grey line: the path of the {traced} origin over the motion")
    scene.legend = legend + triad_legend(names)
    clips = [animation_clip(path, t, props, discrete) for path, props in tracks.items()
             if _moves(props)]
    scene.set_animation(clips, play=True, loop=loop)
    frame_camera(scene, points, panel=True)
    return scene


def _path_frame(robot: Any, visual: RobotVisual, names: tuple[str, ...]) -> str | None:
    """The frame whose origin :func:`trajectory_scene` traces: the robot's platform frame,
    else the first triad frame, else None."""
    frame = getattr(robot, "platform_frame", None)
    if isinstance(frame, str) and visual.model.existFrame(frame):
        return frame
    return names[0] if names else None


def platform_path(visual: RobotVisual, configurations: np.ndarray, frame: str) -> np.ndarray:
    """The world positions (N, 3) (m) of ``frame``'s origin at each configuration (N, nq)
    (Pinocchio's frame placements)."""
    data = visual.model.createData()
    fid = frame_id(visual.model, frame)
    out = np.empty((len(configurations), 3))
    for k, q in enumerate(configurations):
        pin.framesForwardKinematics(visual.model, data, q)
        out[k] = data.oMf[fid].translation
    return out


def _n_act(visual: RobotVisual, value: Any) -> int:
    if visual.closed_loop is None:
        raise InputError("actuator_forces", value, "a bare tree has no actuated joints")
    return visual.closed_loop.n_actuated


def check_times(times: ArrayLike, n: int) -> np.ndarray:
    """``times`` as a float array of ``n`` finite, strictly increasing values (s).

    Raises:
        InputError: not numeric, another length, NaN / inf, not increasing.
    """
    try:
        t = np.asarray(times, dtype=float)
    except (TypeError, ValueError):
        raise InputError("times", times, "not numeric") from None
    if t.shape != (n,) or not np.all(np.isfinite(t)):
        raise InputError("times", times, f"expected {n} finite values, got shape {t.shape}")
    if n > 1 and np.any(np.diff(t) <= 0):
        raise InputError("times", times, "must be strictly increasing")
    return t


def keyframes(t: np.ndarray, fps: float | None) -> np.ndarray:
    """Indices of the samples nearest to ``t[0] + k / fps`` (and the last one), sorted;
    every index when ``fps`` is None.

    Raises:
        InputError: a non-positive or non-finite ``fps``.
    """
    if fps is None or len(t) < 2:
        return np.arange(len(t))
    if not (math.isfinite(fps) and fps > 0):
        raise InputError("fps", fps, "must be a positive number")
    wanted = t[0] + np.arange(0.0, t[-1] - t[0] + 0.5 / fps, 1.0 / fps)
    idx = np.clip(np.searchsorted(t, wanted), 0, len(t) - 1)
    prev = np.clip(idx - 1, 0, len(t) - 1)
    idx = np.where(np.abs(t[prev] - wanted) < np.abs(t[idx] - wanted), prev, idx)
    return np.unique(np.append(idx, len(t) - 1))


def _animate_overlays(tracks: dict, visual: RobotVisual, qs: np.ndarray, act: np.ndarray | None,
                      clo: np.ndarray | None, frames: Sequence[str] | None, root: str,
                      force_scale: float | None) -> float:
    """Fill ``tracks`` with the arrows and triads along the motion; returns the arrow
    length per unit effort (m/N) shared by every frame."""
    efforts: list[np.ndarray] = []
    act_series: list[list] | None = None if act is None else [
        actuator_arrows(visual, q, a) for q, a in zip(qs, act)]
    clo_series: list[list] | None = None if clo is None else [
        closure_arrows(visual, q, c) for q, c in zip(qs, clo)]
    for act_frame in (act_series or []):
        efforts.extend(arrow[1] for arrow in act_frame)
    for clo_frame in (clo_series or []):
        efforts.extend(arrow[1] for arrow in clo_frame)
    scale = arrow_scale(efforts, force_scale)
    named: tuple[tuple[str, list[list] | None], ...] = (("actuator", act_series),
                                                        ("closure", clo_series))
    for label, series in named:
        if series is None:
            continue
        for frame in series:
            for i, arrow in enumerate(frame):
                pos, quat, scl = decompose(arrow_matrix(arrow[0], scale * arrow[1]))
                props = tracks.setdefault(f"{root}/overlays/{label}_{i}",
                                          {"position": [], "quaternion": [], "scale": []})
                props["position"].append(pos)
                props["quaternion"].append(quat)
                props["scale"].append(scl)
    names = default_frames(visual) if frames is None else tuple(frames)
    if names:
        data = visual.model.createData()
        ids = [frame_id(visual.model, name) for name in names]
        for q in qs:
            pin.framesForwardKinematics(visual.model, data, q)
            for name, fid in zip(names, ids):
                pos, quat, _ = decompose(data.oMf[fid].homogeneous)
                props = tracks.setdefault(f"{root}/frames/{safe_name(name)}",
                                          {"position": [], "quaternion": []})
                props["position"].append(pos)
                props["quaternion"].append(quat)
    return scale


def _moves(props: dict[str, list]) -> bool:
    return any(np.ptp(np.asarray(values), axis=0).max() > 1e-12 for values in props.values())


# -- files -------------------------------------------------------------------------------
def write_pose_html(path: str | os.PathLike, robot: Any, q: ArrayLike, **options: Any) -> Path:
    """Write :func:`pose_scene` (same arguments) to an HTML file; returns its path."""
    return pose_scene(robot, q, **options).write(path)


def write_modes_html(path: str | os.PathLike, robot: Any, configurations: ArrayLike,
                     **options: Any) -> Path:
    """Write :func:`modes_scene` (same arguments) to an HTML file; returns its path."""
    return modes_scene(robot, configurations, **options).write(path)


def write_trajectory_html(path: str | os.PathLike, robot: Any, times: ArrayLike,
                          configurations: ArrayLike, **options: Any) -> Path:
    """Write :func:`trajectory_scene` (same arguments) to an HTML file; returns its path."""
    return trajectory_scene(robot, times, configurations, **options).write(path)


# -- workspace point clouds -----------------------------------------------------------------
def colormap(values: ArrayLike, low: float | None = None, high: float | None = None) -> np.ndarray:
    """RGB colours (N, 3) in [0, 1] for ``values`` (N,), linear between ``low`` and ``high``
    (default their finite min / max); non-finite values get the top colour."""
    values = np.asarray(values, dtype=float)
    finite = np.isfinite(values)
    lo = float(values[finite].min()) if low is None and finite.any() else float(low or 0.0)
    hi = float(values[finite].max()) if high is None and finite.any() else float(high or 1.0)
    span = hi - lo if hi > lo else 1.0
    t = np.clip(np.where(finite, (values - lo) / span, 1.0), 0.0, 1.0)
    grid = np.linspace(0.0, 1.0, len(COLORMAP))
    return np.stack([np.interp(t, grid, COLORMAP[:, c]) for c in range(3)], axis=1)


def workspace_scene(robot: Any, positions: ArrayLike, values: ArrayLike | None = None, *,
                    q: ArrayLike | None = None, point_size: float = 0.008,
                    low: float | None = None, high: float | None = None,
                    robot_opacity: float = 0.3, caption: str = "",
                    urdf: str | os.PathLike | None = None,
                    value_label: str = "value") -> Scene:
    """The robot with a cloud of workspace points, coloured by a value per point.

    Args:
        robot: see :func:`robot_visual` (a Hexapod, a ClosedLoopModel, ...).
        positions: (N, 3) points in world axes (m), e.g. the reachable platform
            positions ``poses[m.ok, :3]`` of :func:`hexapod_pin.hexapod.workspace.evaluate`.
        values: (N,) values coloured low (purple) to high (yellow), e.g. the
            condition number (log scale is the caller's choice); default one colour.
        q: configuration the robot is drawn at; default ``robot.home_configuration``
            when the robot has one, else Pinocchio's neutral configuration.
        point_size: point size (m).
        low: colour-map lower limit; default the finite min of ``values``.
        high: colour-map upper limit; default the finite max of ``values``.
        robot_opacity: opacity of the robot (0..1], so the cloud inside it shows.
        caption: as in :func:`pose_scene`.
        urdf: as in :func:`pose_scene`.
        value_label: what ``values`` are, with their unit (e.g. ``"log10 cond(J)"``),
            shown above the colour bar (drawn when ``values`` are given).

    Raises:
        InputError: wrong shapes, NaN positions, or a non-positive point size.
    """
    visual = robot_visual(robot, urdf)
    pts = as_array(positions, (int(np.shape(positions)[0]) if np.ndim(positions) == 2
                                 else -1, 3), "positions")
    colorbar = None
    if values is None:
        colors = np.tile([0.13, 0.57, 0.55], (pts.shape[0], 1))
    else:
        vals = np.asarray(values, dtype=float)
        if vals.shape != (pts.shape[0],):
            raise InputError("values", values, f"expected shape ({pts.shape[0]},)")
        colors = colormap(vals, low, high)
        finite = vals[np.isfinite(vals)]
        lo = float(low) if low is not None else (float(finite.min()) if finite.size else 0.0)
        hi = float(high) if high is not None else (float(finite.max()) if finite.size else 1.0)
        colorbar = (lo, hi, value_label)
    if not (math.isfinite(point_size) and point_size > 0):
        raise InputError("point_size", point_size, "must be finite and > 0 (m)")
    if not (0.0 < robot_opacity <= 1.0):
        raise InputError("robot_opacity", robot_opacity, "must be in (0, 1]")
    if q is None:
        q = getattr(robot, "home_configuration", None)
        q = pin.neutral(visual.model) if q is None else q
    q = check_configuration(visual, q)
    scene = Scene()
    scene.caption = caption
    scene.colorbar = colorbar
    scene.legend = [f"{pts.shape[0]} points" + ("" if colorbar is None else
                                                 f", coloured by {value_label}")]
    root = f"{ROOT}/{visual.name}"
    drawn = draw_robot(scene, visual, q, root, opacity=robot_opacity)
    scene.set_object(f"{ROOT}/workspace", point_cloud_object(pts, colors, point_size))
    frame_camera(scene, list(drawn.points) + ([pts.min(axis=0), pts.max(axis=0)]
                                               if pts.shape[0] else []))
    return scene


def write_workspace_html(path: str | os.PathLike, robot: Any, positions: ArrayLike,
                         values: ArrayLike | None = None, **options: Any) -> Path:
    """Write :func:`workspace_scene` (same arguments) to HTML; returns its path."""
    return workspace_scene(robot, positions, values, **options).write(path)

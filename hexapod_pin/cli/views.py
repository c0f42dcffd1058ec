"""Picture commands: ``view`` (a self-contained meshcat HTML page) and ``plot``
(matplotlib figures)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import numpy as np
import typer

from ..errors import InputError
from .common import (
    AsJson,
    CliRobot,
    CliUsageError,
    Degrees,
    GeometryFile,
    PlatformFrame,
    PoseAxes,
    Quiet,
    RobotFile,
    SetFields,
    Values,
    actuator_names,
    actuators_in,
    as_parallel,
    check_suffix,
    emit_json,
    fmt,
    guard,
    hexapod_only,
    load_cli_robot,
    note,
    parse_numbers,
    pose_axes_of,
    pose_in,
    pose_out,
    progress_bar,
    read_robot_motion,
    robot_fields,
    robot_pose_in,
    robot_pose_out,
    robot_urdf,
)
from .kinematics import NoLimits, assembly_modes_of, write_modes

if TYPE_CHECKING:
    from .. import motion as motions
    from ..core.robot import ClosedLoopRobot
    from ..hexapod.robot import Hexapod

PLOT_KINDS = ("trajectory", "residual", "conditioning", "workspace")


@guard
def view(values: Values = None,
         out: Annotated[Path, typer.Option("--out", "-o", help="HTML file")] = Path(
             "hexapod.html"),
         carriages: Annotated[bool, typer.Option(
             "--carriages", "-c", help="the values are carriage positions q0..q5 (m)")] = False,
         all_modes: Annotated[bool, typer.Option(
             "--modes", help="every assembly mode of the carriage positions given "
                             "(default home)")] = False,
         layout: Annotated[str, typer.Option(help="modes: grid, row or sequence")] = "grid",
         trajectory: Annotated[Path | None, typer.Option(
             help="animate a motion file (.csv / .json)")] = None,
         circle: Annotated[float | None, typer.Option(
             help="animate a circle of this radius (m) about home")] = None,
         period: Annotated[float, typer.Option(help="period of --circle (s)")] = 2.0,
         forces: Annotated[bool, typer.Option(
             "--forces", help="draw actuator forces (statics, or inverse dynamics along "
                              "a motion) and closure forces")] = False,
         fps: Annotated[float, typer.Option(help="key frames per second")] = 30.0,
         no_limits: NoLimits = False,
         degrees: Degrees = False, as_json: AsJson = False, quiet: Quiet = False,
         robot: RobotFile = None, platform: PlatformFrame = None, pose_axes: PoseAxes = None,
         geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Write a self-contained HTML view (meshcat): a pose (default home), the pose of
    carriage positions, all assembly modes, or an animated motion.

    With `--robot`: a pose in its pose axes (default home), the pose of its actuator
    positions (`-c`), its assembly modes (`--modes`), or a motion file in its columns
    (`--trajectory`, see `hexapod-pin id --help`)."""
    from .. import motion as motions
    from ..core.robot import ClosedLoopRobot
    quiet = quiet or as_json
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_)
    check_suffix("out", out, (".html", ".htm"))
    carriages = carriages or all_modes
    if sum([trajectory is not None, circle is not None, bool(values) or carriages]) > 1:
        raise InputError("view", values, "give one of: values, --trajectory, --circle")
    if isinstance(bot, ClosedLoopRobot):
        hexapod_only(bot, circle=circle)
        if out == Path("hexapod.html"):
            out = Path(f"{Path(bot.geometry.name).stem}.html")
        if trajectory is not None:
            detail = _view_loaded_motion(out, bot, trajectory, forces, fps, quiet,
                                         robot_urdf(bot, robot))
        else:
            detail = _view_loaded(out, bot, values, carriages, all_modes, layout, forces,
                                  no_limits, degrees, quiet, robot_urdf(bot, robot))
        note(quiet, f"wrote {out}")
        if as_json:
            emit_json({"html": out, **detail, **robot_fields(bot)})
        return
    if trajectory is not None or circle is not None:
        motion = (motions.read_motion(trajectory) if trajectory is not None
                  else motions.circle_motion(bot, float(circle or 0.0), period))
        label = trajectory or f"circle r = {circle:g} m"
        detail = _view_motion(out, bot, motion, forces, fps, quiet, label)
        kind = "trajectory"
    elif all_modes:
        q = bot.home_q if not values else parse_numbers(values, 6, "q", "q0 .. q5")
        with progress_bar(quiet, "solving the assembly modes"):
            poses = assembly_modes_of(bot, q, not no_limits)
            write_modes(out, bot, q, poses, layout)
        kind, detail = "modes", {"modes": [pose_out(p, degrees) for p in poses]}
    else:
        if carriages:
            q = parse_numbers(values, 6, "q", "q0 .. q5")
            if not no_limits:
                bot.check_stroke(q)
            pose = bot.forward_kinematics(q)
        else:
            pose = pose_in(values, degrees) if values else bot.home_pose
            q = bot.inverse_kinematics(pose, check_limits=False)
        _view_pose(out, bot, pose, q, forces)
        kind, detail = "pose", {"pose": pose_out(pose, degrees), "q": q}
    note(quiet, f"wrote {out}")
    if as_json:
        emit_json({"html": out, "kind": kind, **detail})


def _view_loaded(out: Path, robot: ClosedLoopRobot, values: list[str] | None,
                 carriages: bool, all_modes: bool, layout: str, forces: bool,
                 no_limits: bool, degrees: bool, quiet: bool, urdf: Path | None) -> dict:
    """``view --robot``: one pose (of a pose, or of actuator positions with
    ``carriages``), or the assembly modes of actuator positions (default home); with
    ``forces`` the actuator and closure forces holding the pose at rest."""
    from ..viz import scenes
    if all_modes:
        act = robot.home_actuators if not values else actuators_in(robot, values)
        with progress_bar(quiet, "solving the assembly modes"):
            poses = assembly_modes_of(robot, act, not no_limits)
            write_modes(out, robot, act, poses, layout, degrees, urdf)
        return {"kind": "modes", "q": act,
                "modes": [robot_pose_out(robot, p, degrees) for p in poses]}
    if carriages:
        act = actuators_in(robot, values)
        if not no_limits:
            robot.check_stroke(act)
        pose = robot.forward_kinematics(act)
    else:
        pose = robot_pose_in(robot, values, degrees)
    q_tree = robot.configuration(pose)
    tau = closures = None
    caption = f"{robot.geometry.name}: pose " + fmt(pose, "+.3f")
    if forces:
        rest = robot.inverse_dynamics(pose, np.zeros(robot.pose_dim), np.zeros(robot.pose_dim))
        tau, closures = rest.actuator_forces, rest.closure_forces
        caption += " | arrows: actuator forces (magenta), closure forces (teal)"
    with progress_bar(quiet, "writing HTML"):
        scenes.write_pose_html(out, robot, q_tree, actuator_forces=tau,
                               closure_forces=closures, caption=caption, urdf=urdf)
    return {"kind": "pose", "pose": robot_pose_out(robot, pose, degrees),
            "q": robot.actuator_positions(q_tree)}


def _view_loaded_motion(out: Path, robot: ClosedLoopRobot, path: Path, forces: bool,
                        fps: float, quiet: bool, urdf: Path | None) -> dict:
    """``view --trajectory --robot``: the animation of a motion file of the robot, its
    tree configurations those of the poses (``robot.configuration``, the home working
    mode); with ``forces``, the file's actuator forces, or those of inverse dynamics
    (with the closure forces) when it has none."""
    from .. import motion as motions
    from ..viz import scenes
    motion = read_robot_motion(path, robot)
    tau = closures = None
    if forces:
        tau = motion.actuator_forces
        if tau is None:
            with progress_bar(quiet, "inverse dynamics", total=len(motion.t)) as progress:
                tau, closures = motions.inverse_dynamics_along(
                    as_parallel(robot), motion, progress=progress)
    qs = np.array([robot.configuration(pose) for pose in motion.poses])
    span = float(motion.t[-1] - motion.t[0])
    with progress_bar(quiet, "writing HTML"):
        scenes.write_trajectory_html(out, robot, motion.t, qs, actuator_forces=tau,
                                     closure_forces=closures, fps=fps, urdf=urdf,
                                     caption=f"{robot.geometry.name}: {path}, {span:g} s")
    return {"kind": "trajectory", "samples": len(motion.t), "duration_s": span}


def _view_motion(out: Path, robot: Hexapod, motion: motions.Motion, forces: bool, fps: float,
                 quiet: bool, label: object) -> dict:
    """The animation of a motion; with ``forces``, the actuator forces of the motion
    file, or those of inverse dynamics (with the closure forces) when it has none."""
    from .. import motion as motions
    from ..viz import hexapod_scenes
    tau = closures = None
    if forces:
        tau = motion.actuator_forces
        if tau is None:
            with progress_bar(quiet, "inverse dynamics", total=len(motion.t)) as progress:
                tau, closures = motions.inverse_dynamics_along(robot, motion,
                                                               progress=progress)
    span = float(motion.t[-1] - motion.t[0])
    with progress_bar(quiet, "writing HTML"):
        hexapod_scenes.write_hexapod_trajectory_html(
            out, robot, motion.t, motion.poses, carriages=motion.q, actuator_forces=tau,
            closure_forces=closures, fps=fps, caption=f"{label}, {span:g} s")
    return {"samples": len(motion.t), "duration_s": span}


def _view_pose(out: Path, robot: Hexapod, pose: np.ndarray, q: np.ndarray, forces: bool) -> None:
    """One pose on the branch of carriage positions ``q``; with ``forces``, the actuator
    and closure forces holding it at rest (inverse dynamics at zero twist)."""
    from ..viz import hexapod_scenes, scenes
    tau = closures = None
    caption = "pose " + fmt(pose, "+.3f")
    if forces:
        rest = robot.inverse_dynamics(pose, np.zeros(6), np.zeros(6))
        tau, closures = rest.actuator_forces, rest.closure_forces
        caption += " | arrows: actuator forces (magenta), closure forces (teal)"
    (q_tree,) = hexapod_scenes.hexapod_configurations(robot, pose, q)
    scenes.write_pose_html(out, robot, q_tree, actuator_forces=tau, closure_forces=closures,
                           caption=caption)


PlotAxes = Annotated[str | None, typer.Option(
    "--axes", metavar="A,B", help="workspace: the two pose axes of the slice (default: the "
    "first two position axes, x,y for the hexapod); conditioning: the first is the axis "
    "swept (default: z, else the first pose axis)", show_default=False)]


@guard
def plot(kind: Annotated[str, typer.Argument(
             help="trajectory | residual | conditioning | workspace")],
         motion_file: Annotated[Path | None, typer.Argument(
             help="motion file (trajectory, residual; conditioning: its poses)")] = None,
         out: Annotated[Path, typer.Option(
             "--out", "-o", help=".png / .svg / .pdf (with --robot, default <robot>.png)")
         ] = Path("hexapod.png"),
         z: Annotated[float | None, typer.Option(
             help="workspace: slice height (m), the z of the centre pose")] = None,
         rpy: Annotated[str | None, typer.Option(
             help="workspace: orientation 'roll,pitch,yaw' (with --robot: the angles of its "
                  "pose, 0 for the others)")] = None,
         half_width: Annotated[str | None, typer.Option(
             "--half-width", metavar="W[,W2]",
             help="workspace: half width of the slice around its centre (m, rad; one value, "
                  "or one per axis); conditioning: of the sweep (default: framed "
                  "automatically)", show_default=False)] = None,
         resolution: Annotated[int, typer.Option(help="workspace: samples per side")] = 61,
         axes: PlotAxes = None,
         at: Annotated[str | None, typer.Option(
             "--at", metavar="POSE", help="workspace, conditioning: the centre pose "
             "'a,b,...' (one value per pose component; default home)",
             show_default=False)] = None,
         forces: Annotated[bool, typer.Option(
             "--forces", help="trajectory: compute actuator forces by inverse dynamics "
                              "when the file has none")] = False,
         degrees: Degrees = False, as_json: AsJson = False, quiet: Quiet = False,
         robot: RobotFile = None, platform: PlatformFrame = None, pose_axes: PoseAxes = None,
         geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Write a figure: actuator positions / forces along a motion, closure residual,
    cond(J) (J unscaled: m and rad columns) along a motion (default: a sweep of one pose
    axis, the hexapod's vertical), a workspace slice over two pose axes coloured by cond(J).

    With `--robot`: its motion files (`hexapod-pin id --help`), its actuators, and slices
    and sweeps of its own pose axes (`--axes`), through its home pose or `--at`."""
    from ..core.robot import ClosedLoopRobot
    from ..hexapod.robot import Hexapod
    from ..viz import plotting, workspace_plots
    quiet = quiet or as_json
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_)
    if kind not in PLOT_KINDS:
        raise InputError("kind", kind, f"expected one of {', '.join(PLOT_KINDS)}")
    check_suffix("out", out, plotting.IMAGE_SUFFIXES)
    if kind in ("trajectory", "residual") and motion_file is None:
        raise InputError("motion_file", None, f"plot {kind} needs a motion file")
    if isinstance(bot, ClosedLoopRobot) and out == Path("hexapod.png"):
        out = Path(f"{Path(bot.geometry.name).stem}.png")
    center = None if at is None else robot_pose_in(bot, [at], degrees, "at")
    detail: dict = {}
    if kind == "trajectory" and motion_file is not None:
        _plot_trajectory(out, bot, read_robot_motion(motion_file, bot), forces, quiet,
                         str(motion_file))
    elif kind == "residual" and motion_file is not None:
        motion = read_robot_motion(motion_file, bot)
        if motion.closure_residual is None:
            raise InputError("motion_file", str(motion_file),
                             "has no closure residual (column 'residual')")
        plotting.plot_closure_residual(motion.t, motion.closure_residual, path=out)
    elif kind == "conditioning":
        _plot_conditioning(out, bot, motion_file, axes, center, _widths(half_width, 1))
    else:
        widths = _widths(half_width, 2)
        orientation = None if rpy is None else parse_numbers([rpy], 3, "rpy",
                                                             "roll pitch yaw")
        if orientation is not None and degrees:
            orientation = np.radians(orientation)
        if orientation is None and center is None and isinstance(bot, Hexapod):
            orientation = np.zeros(3)                     # the hexapod: level by default
        with progress_bar(quiet, "sampling the workspace slice"):
            ws = workspace_plots.workspace_slice(bot, z=z, orientation=orientation,
                                                 half_width=widths, resolution=resolution,
                                                 axes=axes, center=center)
        workspace_plots.plot_workspace_slice(ws, path=out)
        detail = {"axes": list(ws.axes), "reachable_fraction": ws.reachable_fraction}
    note(quiet, f"wrote {out}")
    if as_json:
        emit_json({"figure": out, "kind": kind, **detail, **robot_fields(bot)})


def _widths(text: str | None, most: int) -> np.ndarray | None:
    """``--half-width``: one value, or up to ``most`` (one per axis), each > 0 (m, rad)."""
    if text is None:
        return None
    values = parse_numbers([text], None, "half-width")
    if not 1 <= len(values) <= most or not np.all(values > 0):
        count = "one value" if most == 1 else f"1 to {most} values"
        raise InputError("half-width", text, f"expected {count} > 0 (m, rad)")
    return values


def _swept_axis(robot: CliRobot, axes: str | None) -> str:
    """The pose axis of a conditioning sweep: the first of ``--axes``, else z, else the
    robot's first pose axis."""
    own = pose_axes_of(robot)
    if axes is None:
        return "z" if "z" in own else own[0]
    axis = axes.split(",")[0].strip()
    if axis not in own:
        raise InputError("axes", axes, f"the axis swept must be a pose axis of the robot "
                                       f"({', '.join(own)})")
    return axis


def _plot_conditioning(out: Path, robot: CliRobot, motion_file: Path | None,
                       axes: str | None, center: np.ndarray | None,
                       widths: np.ndarray | None) -> None:
    """cond(J) along the poses of a motion file, or along a sweep of one pose axis through
    ``center`` (default home) over +- the half width (default the reach scale); the
    hexapod's default: the vertical sweep from 0.3 to 1.2 times the home height."""
    from ..hexapod.robot import Hexapod
    from ..viz import workspace_plots
    if motion_file is not None:
        if axes is not None or center is not None or widths is not None:
            raise CliUsageError("plot conditioning MOTION_FILE: the poses are the file's "
                                "(--axes, --at and --half-width sweep without a file)")
        motion = read_robot_motion(motion_file, robot)
        workspace_plots.plot_conditioning(robot, motion.poses, motion.t, path=out,
                                          s_label="time (s)")
        return
    if isinstance(robot, Hexapod) and axes is None and center is None and widths is None:
        zs = np.linspace(0.3, 1.2, 200) * robot.home_pose[2]
        poses = np.tile(robot.home_pose, (len(zs), 1))
        poses[:, 2] = zs
        workspace_plots.plot_conditioning(robot, poses, zs, path=out,
                                          s_label="height z (m)")
        return
    axis = _swept_axis(robot, axes)
    mid = np.array(robot.home_pose if center is None else center, dtype=float)
    width = workspace_plots.reach_scale(robot, axis) if widths is None else float(widths[0])
    k = pose_axes_of(robot).index(axis)
    values = mid[k] + np.linspace(-width, width, 200)
    poses = np.tile(mid, (len(values), 1))
    poses[:, k] = values
    workspace_plots.plot_conditioning(robot, poses, values, path=out,
                                      s_label=f"{axis} ({workspace_plots.axis_unit(axis)})")


def _plot_trajectory(out: Path, robot: CliRobot, motion: motions.Motion, forces: bool,
                     quiet: bool, title: str) -> None:
    """Actuator positions (from the file, else inverse kinematics of the poses) and
    actuator forces (from the file, else inverse dynamics with ``forces``), labelled with
    the robot's actuators (the hexapod's carriages, m and N)."""
    from .. import motion as motions
    from ..hexapod.robot import Hexapod
    from ..viz import plotting
    q = motions.actuators_along(as_parallel(robot), motion)  # a pose out of reach names its row
    tau = motion.actuator_forces
    if tau is None and forces:
        with progress_bar(quiet, "inverse dynamics", total=len(motion.t)) as progress:
            tau = motions.inverse_dynamics_along(as_parallel(robot), motion,
                                                 progress=progress).actuator_forces
    if isinstance(robot, Hexapod):
        plotting.plot_trajectory(motion.t, q, tau, path=out, title=title)
        return
    plotting.plot_trajectory(motion.t, q, tau, path=out, title=title, actuator="actuator",
                             names=actuator_names(robot), units=_actuator_units(robot))


def _actuator_units(robot: ClosedLoopRobot) -> tuple[str, str]:
    """The units of a loaded robot's actuator positions and forces: m and N (prismatic
    joints), rad and N m (revolute), ``m | rad`` and ``N | N m`` for a mix."""
    from ..core.platform_map import angular_coordinates
    angular = angular_coordinates(robot.model.model)[robot.model.actuated_v]
    if np.all(angular):
        return "rad", "N m"
    return ("m", "N") if not np.any(angular) else ("m | rad", "N | N m")

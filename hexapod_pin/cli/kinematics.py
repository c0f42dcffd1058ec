"""Kinematics commands: ``ik``, ``fk``, ``modes``, ``jacobian``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.table import Table
from rich.text import Text

from ..errors import AssemblyError, InputError
from .common import (
    TWIST_OF,
    AsJson,
    CliRobot,
    Degrees,
    GeometryFile,
    PlatformFrame,
    PoseAxes,
    Quiet,
    RobotFile,
    SetFields,
    Values,
    actuator_names,
    actuator_table,
    actuators_in,
    console,
    emit_json,
    fmt,
    guard,
    hexapod_only,
    load_cli_robot,
    note,
    plain,
    pose_axes_of,
    pose_in,
    pose_table,
    progress_bar,
    robot_fields,
    robot_pose_in,
    robot_pose_out,
    robot_urdf,
)

#: what the fields of ``Hexapod.singularity`` are: (label with unit, meaning); the
#: condition number's, :data:`hexapod_pin.viz.workspace_plots.CONDITION_LABEL`, is added by
#: :func:`singularity_labels` (the command line imports the library on first use)
SINGULARITY_LABELS = {
    "jacobian_singular_values": ("singular values of J", "J unscaled (m and rad columns)"),
    "type_one": ("type I: min |cos(leg, rail)|",
                 "0 at a type-I singularity (a leg perpendicular to its rail: J unbounded)"),
    "type_one_actuator": ("type I: carriage", "the carriage attaining the type-I measure"),
    "type_two": ("type II: sigma_min(A_hat)",
                 "0 at a type-II singularity (the platform moves with the carriages locked)"),
    "type_two_singular_values": ("singular values of A_hat",
                                 "A_hat = [e_i, (r_i x e_i) / length], rows per leg"),
    "characteristic_length": ("length (m)", "divides the angular columns of A_hat"),
    "type_one_threshold": ("type I: threshold",
                           "below it every route raises SingularityError"),
    "type_two_threshold": ("type II: threshold",
                           "below it every route raises SingularityError"),
}
#: what the measures mean for a robot loaded with ``--robot`` (the others as above)
LOADED_SINGULARITY_LABELS = {
    **SINGULARITY_LABELS,
    "type_one": ("type I: inverse condition", "0 at a type-I singularity (J unbounded)"),
    "type_one_actuator": ("type I: actuator", "the actuator attaining the type-I measure"),
    "type_two": ("type II: inverse condition",
                 "0 at a type-II singularity (the platform moves with the actuators locked)"),
    "type_two_singular_values": ("type II: singular values",
                                 "of the dimensionless closure map"),
    "characteristic_length": ("length (m)", "relates the angular and linear coordinates"),
}


def singularity_labels(loaded: bool) -> dict[str, tuple[str, str]]:
    """What the singularity measures are (label with unit, meaning), for a robot loaded with
    ``--robot`` when ``loaded``, else for the hexapod."""
    from ..viz.workspace_plots import CONDITION_LABEL
    return {**(LOADED_SINGULARITY_LABELS if loaded else SINGULARITY_LABELS),
            "condition_number": (CONDITION_LABEL, "sigma_max / sigma_min of J; inf at type I")}


#: ``--no-limits``: carriage positions beyond the strokes / gaps accepted
NoLimits = Annotated[bool, typer.Option("--no-limits", help="do not check strokes / gaps")]


def assembly_modes_of(robot: CliRobot, carriages: np.ndarray, check_limits: bool = True) -> list:
    """Every assembly mode (poses) of carriage positions; what ``fk``, ``modes`` and
    ``view --modes`` agree on.

    Raises:
        StrokeLimitError: with ``check_limits``, carriages beyond a stroke or gap limit
            (as ``ik`` rejects their poses).
        AssemblyError: no assembly mode exists (the reason of ``forward_kinematics``).
    """
    if check_limits:
        robot.check_stroke(carriages)
    poses = list(robot.assembly_modes(carriages))
    if not poses:
        poses = [robot.forward_kinematics(carriages)]      # raises AssemblyError: why none
    return poses


@guard
def ik(pose: Values = None,
       branch: Annotated[str | None, typer.Option(
           help="six signs choosing each carriage's root, e.g. -+-+-+ (default: home)")] = None,
       no_limits: NoLimits = False,
       degrees: Degrees = False, as_json: AsJson = False,
       robot: RobotFile = None, platform: PlatformFrame = None, pose_axes: PoseAxes = None,
       geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Carriage positions q (m) for a platform pose: x y z roll pitch yaw.

    With `--robot`: the actuator positions (m or rad) for a pose in the robot's pose axes
    (the working mode reached from home)."""
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_)
    hexapod_only(bot, branch=branch)
    p = pose_in(pose, degrees, axes=pose_axes_of(bot))
    signs = parse_branch(branch)
    q = bot.inverse_kinematics(p, branch=signs, check_limits=not no_limits)
    if as_json:
        emit_json({"pose": robot_pose_out(bot, p, degrees), "q": q, "branch": signs,
                   **robot_fields(bot)})
        return
    console.print(actuator_table(bot, "inverse kinematics", {actuator_unit(bot): q}))


def actuator_unit(robot: CliRobot, name: str = "q") -> str:
    """The column name of actuator positions: ``q (m)`` for the hexapod, ``q (m | rad)``
    for a loaded robot (each actuator in its joint's unit)."""
    from ..hexapod.robot import Hexapod
    return f"{name} (m)" if isinstance(robot, Hexapod) else f"{name} (m | rad)"


def parse_branch(text: str | None) -> np.ndarray | None:
    """Six root signs from ``-+-+-+`` or ``-1,1,-1,1,-1,1``; None stays None.

    Raises:
        InputError: not six signs.
    """
    if text is None:
        return None
    compact = text.replace(" ", "")
    tokens = compact.split(",") if "," in compact else list(compact)
    values = {"+": 1.0, "-": -1.0, "1": 1.0, "+1": 1.0, "-1": -1.0}
    if len(tokens) != 6 or any(t not in values for t in tokens):
        raise InputError("branch", text, "expected six signs, e.g. -+-+-+ or -1,1,-1,1,-1,1")
    return np.array([values[t] for t in tokens])


@guard
def fk(q: Values = None,
       guess: Annotated[str | None, typer.Option(
           help="starting pose 'x,y,z,roll,pitch,yaw' (default home; with --robot: its "
                "pose axes)")] = None,
       no_limits: NoLimits = False,
       degrees: Degrees = False, as_json: AsJson = False,
       robot: RobotFile = None, platform: PlatformFrame = None, pose_axes: PoseAxes = None,
       geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Platform pose for carriage positions q0..q5 (m) (Newton from a guess); with
    `--robot`, for its actuator positions (m or rad, actuator order).

    Carriage positions beyond the strokes or gaps are rejected as `ik` rejects their
    poses (`--no-limits` accepts them); no assembly is an error, as in `modes`."""
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_)
    carriages = actuators_in(bot, q)
    start = None if guess is None else pose_in([guess], degrees, "guess", pose_axes_of(bot))
    if not no_limits:
        bot.check_stroke(carriages)
    pose = bot.forward_kinematics(carriages, guess=start)
    if as_json:
        emit_json({"q": carriages, "pose": robot_pose_out(bot, pose, degrees),
                   **robot_fields(bot)})
        return
    console.print(pose_table("forward kinematics", [pose], degrees, pose_axes_of(bot)))


@guard
def modes(q: Values = None,
          html: Annotated[Path | None, typer.Option(help="also write an HTML view")] = None,
          layout: Annotated[str, typer.Option(help="grid, row or sequence (HTML)")] = "grid",
          no_limits: NoLimits = False,
          degrees: Degrees = False, as_json: AsJson = False, quiet: Quiet = False,
          robot: RobotFile = None, platform: PlatformFrame = None, pose_axes: PoseAxes = None,
          geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Every assembly mode (platform pose) for carriage positions q0..q5 (m); default home q.

    With `--robot`: the assembly modes a multi-start search finds for its actuator
    positions (default home; not proven complete). No assembly mode is an error (exit
    code 1), as in `fk`; carriage positions beyond the strokes or gaps too, unless
    `--no-limits`."""
    quiet = quiet or as_json
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_)
    carriages = bot.home_actuators if not q else actuators_in(bot, q)
    with progress_bar(quiet, "solving the assembly modes"):
        poses = assembly_modes_of(bot, carriages, not no_limits)
    if html is not None:
        with progress_bar(quiet, "writing HTML"):
            write_modes(html, bot, carriages, poses, layout, degrees, robot_urdf(bot, robot))
        note(quiet, f"wrote {html}")
    if as_json:
        emit_json({"q": carriages, "modes": [robot_pose_out(bot, p, degrees) for p in poses],
                   "html": html, **robot_fields(bot)})
        return
    console.print(pose_table(f"{len(poses)} assembly modes", poses, degrees, pose_axes_of(bot)))


def mode_configurations(robot: CliRobot, carriages: np.ndarray, poses: list) -> np.ndarray:
    """The tree configurations (M, nq) of assembly modes ``poses`` of actuator positions
    ``carriages`` (a loaded robot: those its multi-start search assembled,
    :meth:`~hexapod_pin.core.robot_kinematics.RobotKinematics.assembly_configurations`,
    in the order of ``robot.assembly_modes``)."""
    from ..hexapod.robot import Hexapod
    from ..viz import hexapod_scenes
    if isinstance(robot, Hexapod):
        return np.asarray(hexapod_scenes.hexapod_configurations(
            robot, poses, [carriages] * len(poses)))
    found, qs = robot.assembly_configurations(carriages)
    if found.shape != np.shape(poses) or not np.allclose(found, poses, rtol=0, atol=1e-9):
        raise AssemblyError("the assembly modes changed between two searches", 0.0, 0)
    return qs


def write_modes(path: Path, robot: CliRobot, carriages: np.ndarray, poses: list,
                layout: str, degrees: bool = False, urdf: Path | None = None) -> Path:
    """The HTML page of the assembly modes ``poses`` of carriage positions ``carriages``."""
    from ..hexapod.robot import Hexapod
    from ..viz import scenes
    qs = mode_configurations(robot, carriages, poses)
    if isinstance(robot, Hexapod):
        labels = [f"z = {p[2]:+.3f} m" for p in poses]
    else:
        axes = pose_axes_of(robot)
        labels = [", ".join(f"{a} = {v:+.3f}" for a, v in
                            zip(axes, robot_pose_out(robot, p, degrees))) for p in poses]
    return scenes.write_modes_html(path, robot, qs, layout=layout, labels=labels, urdf=urdf,
                                   caption=f"{len(poses)} assembly modes (numbered as in "
                                           f"'hexapod-pin modes')")


@guard
def jacobian(pose: Values = None, degrees: Degrees = False, as_json: AsJson = False,
             robot: RobotFile = None, platform: PlatformFrame = None,
             pose_axes: PoseAxes = None,
             geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Workspace Jacobian J at a pose (default home) and its singularity measures.

    J maps the twist to the carriage velocities: qdot = J twist, twist = (v, w) in world
    axes, J unscaled (columns in m/s and rad/s). The measures of `Hexapod.singularity`
    are printed once each with what they mean. Type I: a leg perpendicular to its rail
    (J unbounded); type II: the platform can move with the carriages locked. With
    `--robot`: the same for its pose axes and actuators (J is n_act x pose_dim)."""
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_)
    p = robot_pose_in(bot, pose, degrees)
    jac = bot.jacobian(p)
    measures = plain(bot.singularity(p))
    if as_json:     # each measure once: J's singular values and cond(J) at the top level
        emit_json({"pose": robot_pose_out(bot, p, degrees), "jacobian": jac,
                   "singular_values": measures.pop("jacobian_singular_values"),
                   "condition_number": measures.pop("condition_number"),
                   "singularity": measures, **robot_fields(bot)})
        return
    console.print(jacobian_table(jac, bot))
    console.print(singularity_table(measures, bot))


def singularity_table(measures: dict, robot: CliRobot | None = None) -> Table:
    """The singularity measures as a table: measure, value, what it means."""
    from ..core.robot import ClosedLoopRobot
    loaded = isinstance(robot, ClosedLoopRobot)
    labels = singularity_labels(loaded)
    table = Table(title=f"singularity measures "
                        f"({'ClosedLoopRobot' if loaded else 'Hexapod'}.singularity)")
    for name in ("measure", "value", "meaning"):
        table.add_column(name, justify="right" if name == "value" else "left")
    for key, value in measures.items():
        label, meaning = labels.get(key, (key, ""))
        shown = fmt(value, ".4g") if isinstance(value, list) else (
            f"{value:.6g}" if isinstance(value, float) else str(value))
        table.add_row(Text(label), Text(shown), Text(meaning))   # Text: brackets kept
    return table


def jacobian_table(jac: np.ndarray, robot: CliRobot | None = None) -> Table:
    """The Jacobian as a table: one row per actuator, one column per twist component
    (the hexapod: carriages, vx .. wz)."""
    from ..core.robot import ClosedLoopRobot
    from ..motion import POSE_NAMES
    table = Table(title="workspace Jacobian J: qdot = J (v, w), v in m/s, w in rad/s")
    axes = pose_axes_of(robot) if robot is not None else POSE_NAMES
    rows = actuator_names(robot) if isinstance(robot, ClosedLoopRobot) else \
        tuple(str(i) for i in range(len(jac)))
    table.add_column("carriage" if not isinstance(robot, ClosedLoopRobot) else "actuator",
                     justify="right")
    for name in axes:
        table.add_column(TWIST_OF[name], justify="right")
    for label, row in zip(rows, jac):
        table.add_row(Text(label), *(f"{v:+.4f}" for v in row))
    return table

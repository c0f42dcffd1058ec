"""Export commands: ``urdf`` writes the URDF of the hexapod (or of the planar 3-PRR) for a
geometry, the tree a Pinocchio, ROS or MuJoCo user loads (the loop closures are in the
matching ``urdf/*.loops.yaml``); ``mjcf`` writes the MuJoCo model of the hexapod or of
any robot of ``--robot`` (:func:`hexapod_pin.core.mujoco_export.closed_loop_mjcf`: the
tree, closures as equality constraints, one motor per actuated joint)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError
from .common import (
    AsJson,
    GeometryFile,
    PlatformFrame,
    PoseAxes,
    Quiet,
    RobotFile,
    SetFields,
    check_suffix,
    emit_json,
    guard,
    load_cli_robot,
    note,
    robot_of,
)

#: the robots of ``hexapod-pin urdf --robot``
ROBOTS = ("hexapod", "planar")


@guard
def urdf(out: Annotated[Path | None, typer.Option(
             "--out", "-o", help="URDF file to write (.urdf / .xml); default: stdout",
             show_default=False)] = None,
         robot: Annotated[str, typer.Option(help="hexapod or planar (the 3-PRR)")] = "hexapod",
         as_json: AsJson = False, quiet: Quiet = False,
         geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """The URDF of the robot's tree for a geometry (``--geometry`` / ``--set`` take the
    fields of HexapodGeometry, or of PlanarGeometry with ``--robot planar``)."""
    from ..files import load_geometry
    from ..planar.geometry import PlanarGeometry
    from ..planar.robot import Planar3PRR
    quiet = quiet or as_json
    if robot not in ROBOTS:
        raise InputError("robot", robot, f"expected one of {', '.join(ROBOTS)}")
    check_suffix("out", out, (".urdf", ".xml"))
    if robot == "hexapod":
        text = robot_of(geometry, set_).urdf()
    else:
        text = Planar3PRR(load_geometry(geometry, set_, geometry_type=PlanarGeometry)).urdf()
    _deliver(text, "urdf", robot, out, as_json, quiet)


@guard
def mjcf(out: Annotated[Path | None, typer.Option(
             "--out", "-o", help="MJCF file to write (.xml / .mjcf); default: stdout",
             show_default=False)] = None,
         timestep: Annotated[float, typer.Option(help="MuJoCo time step (s)")] = 1e-3,
         as_json: AsJson = False, quiet: Quiet = False,
         robot: RobotFile = None, platform: PlatformFrame = None, pose_axes: PoseAxes = None,
         geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """The MuJoCo model (MJCF) of the hexapod, or of any robot with `--robot`: the tree,
    every loop closure as an equality constraint, one motor per actuated joint."""
    from ..core.mujoco_export import closed_loop_mjcf
    from ..core.robot import ClosedLoopRobot
    quiet = quiet or as_json
    check_suffix("out", out, (".xml", ".mjcf"))
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_)
    text = closed_loop_mjcf(bot.model, timestep=timestep)
    name = bot.geometry.name if isinstance(bot, ClosedLoopRobot) else "hexapod"
    _deliver(text, "mjcf", name, out, as_json, quiet)


def _deliver(text: str, kind: str, name: str, out: Path | None, as_json: bool,
             quiet: bool) -> None:
    """A description's text to ``out`` (atomic write, a note) or to stdout; with
    ``--json``, ``{"robot", kind: text}`` or ``{"robot", "out", "characters"}``."""
    from ..files import write_text_atomic
    if out is None:
        if as_json:
            emit_json({"robot": name, kind: text})
        else:
            typer.echo(text, nl=not text.endswith("\n"))
        return
    write_text_atomic(out, text)
    note(quiet, f"wrote {out}")
    if as_json:
        emit_json({"robot": name, "out": out, "characters": len(text)})

"""The ``urdf`` command: write the URDF of the hexapod (or of the planar 3-PRR) for a
geometry, the tree a Pinocchio, ROS or MuJoCo user loads (the loop closures are in the
matching ``urdf/*.loops.yaml``)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError
from ..files import load_geometry, write_text_atomic
from ..planar.geometry import PlanarGeometry
from ..planar.robot import Planar3PRR
from .common import (
    AsJson,
    GeometryFile,
    Quiet,
    SetFields,
    check_suffix,
    emit_json,
    guard,
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
    quiet = quiet or as_json
    if robot not in ROBOTS:
        raise InputError("robot", robot, f"expected one of {', '.join(ROBOTS)}")
    check_suffix("out", out, (".urdf", ".xml"))
    if robot == "hexapod":
        text = robot_of(geometry, set_).urdf()
    else:
        text = Planar3PRR(load_geometry(geometry, set_, geometry_type=PlanarGeometry)).urdf()
    if out is None:
        if as_json:
            emit_json({"robot": robot, "urdf": text})
        else:
            typer.echo(text, nl=not text.endswith("\n"))
        return
    write_text_atomic(out, text)
    note(quiet, f"wrote {out}")
    if as_json:
        emit_json({"robot": robot, "out": out, "characters": len(text)})

"""Kinematics commands: ``ik``, ``fk``, ``modes``, ``jacobian``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.table import Table
from rich.text import Text

from ..errors import InputError
from ..hexapod.robot import Hexapod
from ..viz import hexapod_scenes, scenes
from ..viz.workspace_plots import CONDITION_LABEL
from .common import (
    AsJson,
    Degrees,
    GeometryFile,
    Quiet,
    SetFields,
    Values,
    carriage_table,
    console,
    emit_json,
    fmt,
    guard,
    note,
    parse_numbers,
    plain,
    pose_in,
    pose_out,
    pose_table,
    progress_bar,
    robot_of,
)

#: what the fields of ``Hexapod.singularity`` are: (label with unit, meaning)
SINGULARITY_LABELS = {
    "jacobian_singular_values": ("singular values of J", "J unscaled (m and rad columns)"),
    "condition_number": (CONDITION_LABEL, "sigma_max / sigma_min of J; inf at type I"),
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


#: ``--no-limits``: carriage positions beyond the strokes / gaps accepted
NoLimits = Annotated[bool, typer.Option("--no-limits", help="do not check strokes / gaps")]


def assembly_modes_of(robot: Hexapod, carriages: np.ndarray, check_limits: bool = True) -> list:
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
       geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Carriage positions q (m) for a platform pose: x y z roll pitch yaw."""
    robot = robot_of(geometry, set_)
    p = pose_in(pose, degrees)
    signs = parse_branch(branch)
    q = robot.inverse_kinematics(p, branch=signs, check_limits=not no_limits)
    if as_json:
        emit_json({"pose": pose_out(p, degrees), "q": q, "branch": signs})
        return
    console.print(carriage_table("inverse kinematics", {"q (m)": q}))


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
           help="starting pose 'x,y,z,roll,pitch,yaw' (default home)")] = None,
       no_limits: NoLimits = False,
       degrees: Degrees = False, as_json: AsJson = False,
       geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Platform pose for carriage positions q0..q5 (m) (Newton from a guess).

    Carriage positions beyond the strokes or gaps are rejected as `ik` rejects their
    poses (`--no-limits` accepts them); no assembly is an error, as in `modes`."""
    robot = robot_of(geometry, set_)
    carriages = parse_numbers(q, 6, "q", "q0 .. q5")
    start = None if guess is None else pose_in([guess], degrees, "guess")
    if not no_limits:
        robot.check_stroke(carriages)
    pose = robot.forward_kinematics(carriages, guess=start)
    if as_json:
        emit_json({"q": carriages, "pose": pose_out(pose, degrees)})
        return
    console.print(pose_table("forward kinematics", [pose], degrees))


@guard
def modes(q: Values = None,
          html: Annotated[Path | None, typer.Option(help="also write an HTML view")] = None,
          layout: Annotated[str, typer.Option(help="grid, row or sequence (HTML)")] = "grid",
          no_limits: NoLimits = False,
          degrees: Degrees = False, as_json: AsJson = False, quiet: Quiet = False,
          geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Every assembly mode (platform pose) for carriage positions q0..q5 (m); default home q.

    No assembly mode is an error (exit code 1), as in `fk`; carriage positions beyond
    the strokes or gaps too, unless `--no-limits`."""
    quiet = quiet or as_json
    robot = robot_of(geometry, set_)
    carriages = robot.home_q if not q else parse_numbers(q, 6, "q", "q0 .. q5")
    with progress_bar(quiet, "solving the assembly modes"):
        poses = assembly_modes_of(robot, carriages, not no_limits)
    if html is not None:
        with progress_bar(quiet, "writing HTML"):
            write_modes(html, robot, carriages, poses, layout)
        note(quiet, f"wrote {html}")
    if as_json:
        emit_json({"q": carriages, "modes": [pose_out(p, degrees) for p in poses],
                   "html": html})
        return
    console.print(pose_table(f"{len(poses)} assembly modes", poses, degrees))


def write_modes(path: Path, robot: Hexapod, carriages: np.ndarray, poses: list,
                layout: str) -> Path:
    """The HTML page of the assembly modes ``poses`` of carriage positions ``carriages``."""
    qs = hexapod_scenes.hexapod_configurations(robot, poses, [carriages] * len(poses))
    return scenes.write_modes_html(path, robot, qs, layout=layout,
                                   labels=[f"z = {p[2]:+.3f} m" for p in poses],
                                   caption=f"{len(poses)} assembly modes (numbered as in "
                                           f"'hexapod-pin modes')")


@guard
def jacobian(pose: Values = None, degrees: Degrees = False, as_json: AsJson = False,
             geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Workspace Jacobian J at a pose (default home) and its singularity measures.

    J maps the twist to the carriage velocities: qdot = J twist, twist = (v, w) in world
    axes, J unscaled (columns in m/s and rad/s). The measures of `Hexapod.singularity`
    are printed once each with what they mean. Type I: a leg perpendicular to its rail
    (J unbounded); type II: the platform can move with the carriages locked."""
    robot = robot_of(geometry, set_)
    p = pose_in(pose, degrees) if pose else robot.home_pose
    jac = robot.jacobian(p)
    measures = plain(robot.singularity(p))
    if as_json:     # each measure once: J's singular values and cond(J) at the top level
        emit_json({"pose": pose_out(p, degrees), "jacobian": jac,
                   "singular_values": measures.pop("jacobian_singular_values"),
                   "condition_number": measures.pop("condition_number"),
                   "singularity": measures})
        return
    console.print(jacobian_table(jac))
    console.print(singularity_table(measures))


def singularity_table(measures: dict) -> Table:
    """The singularity measures as a table: measure, value, what it means."""
    table = Table(title="singularity measures (Hexapod.singularity)")
    for name in ("measure", "value", "meaning"):
        table.add_column(name, justify="right" if name == "value" else "left")
    for key, value in measures.items():
        label, meaning = SINGULARITY_LABELS.get(key, (key, ""))
        shown = fmt(value, ".4g") if isinstance(value, list) else (
            f"{value:.6g}" if isinstance(value, float) else str(value))
        table.add_row(Text(label), Text(shown), Text(meaning))   # Text: brackets kept
    return table


def jacobian_table(jac: np.ndarray) -> Table:
    """The Jacobian as a table: one row per carriage, columns vx .. wz."""
    table = Table(title="workspace Jacobian J: qdot = J (v, w), v in m/s, w in rad/s")
    table.add_column("carriage", justify="right")
    for name in ("vx", "vy", "vz", "wx", "wy", "wz"):
        table.add_column(name, justify="right")
    for i, row in enumerate(jac):
        table.add_row(str(i), *(f"{v:+.4f}" for v in row))
    return table

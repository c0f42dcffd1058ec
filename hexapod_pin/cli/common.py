"""What every command shares: the common options, reading numbers and poses from the
command line, turning library and usage errors into one-line messages (a JSON object
with ``--json``), and the output helpers (JSON, tables, notes and progress bars on
stderr).

The robot of a command: the hexapod of ``--geometry`` / ``--set`` (default), or any
closed-loop robot of ``--robot PATH [--platform FRAME] [--pose-axes x,z]``
(:func:`load_cli_robot`, :func:`hexapod_pin.load_robot`). Poses, twists, wrenches and
actuator values are read and printed in that robot's own axes and actuator order
(:func:`pose_axes_of`, :func:`actuator_names`).

Exit codes (:data:`EXIT_CODES`): 0 success; 1 a computed failure or bad input (an
unreachable pose, a singular pose, a saturated simulation, a value that is not a number, a
missing or malformed file, ...); 2 a usage error (an unknown option, a missing required
option or argument, a wrong number of values (:class:`ValueCountError`), options that do
not go together such as ``--robot`` with ``--geometry``). Every error is one line on stderr, ``error: <message>``,
or with ``--json`` one JSON object on stdout, ``{"error": {"type": ..., "message":
...}}``; never a traceback.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import difflib
import functools
import json
import math
import re
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, cast

import numpy as np
import typer
from numpy.typing import ArrayLike
from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    SpinnerColumn,
    TextColumn,
    TimeElapsedColumn,
)
from rich.table import Table
from rich.text import Text
from typer.core import TyperCommand, TyperGroup

from ..errors import DescriptionError, HexapodPinError, InputError

if TYPE_CHECKING:
    from .. import motion as motions
    from ..core.robot import ClosedLoopRobot
    from ..core.robot_api import ParallelRobot
    from ..hexapod.robot import Hexapod

#: the exit codes of every command
EXIT_CODES = {0: "success", 1: "a computed failure or bad input", 2: "a usage error"}
#: lets "-0.1" through as a value (commands taking numbers)
NUMBERS = {"ignore_unknown_options": True}
#: width of tables and lines written to a pipe or a file (a terminal uses its own width)
PIPE_WIDTH = 240


class OutputConsole:
    """Rich output on stdout: the terminal's width in a terminal, :data:`PIPE_WIDTH`
    columns when piped (so piped lines are not wrapped at 80 columns)."""

    def print(self, *objects: Any, **kwargs: Any) -> None:
        """``rich.console.Console.print`` on the current ``sys.stdout``."""
        out = Console()
        if not out.is_terminal:
            out = Console(width=PIPE_WIDTH)
        out.print(*objects, **kwargs)


console = OutputConsole()


class CommandError(HexapodPinError):
    """A command could not do its job (a file it cannot write, ...)."""


# -- options shared by the commands --------------------------------------------------------
GeometryFile = Annotated[Path | None, typer.Option(
    "--geometry", help="TOML / YAML / JSON file of geometry fields", show_default=False)]
SetFields = Annotated[list[str] | None, typer.Option(
    "--set", metavar="FIELD=VALUE", help="override a geometry field (repeatable)",
    show_default=False)]
AsJson = Annotated[bool, typer.Option("--json", help="machine-readable output on stdout")]
Quiet = Annotated[bool, typer.Option("--quiet", "-q", help="no progress bars or notes")]
Degrees = Annotated[bool, typer.Option("--degrees", help="pose angles in degrees (in and out)")]
Values = Annotated[list[str] | None, typer.Argument(show_default=False, metavar="NUMBERS")]


RobotFile = Annotated[Path | None, typer.Option(
    "--robot", metavar="PATH", help="any closed-loop robot: a URDF with <name>.loops.yaml "
    "beside it, an SDF, or a folder (default: the hexapod of --geometry / --set)",
    show_default=False)]
PlatformFrame = Annotated[str | None, typer.Option(
    "--platform", metavar="FRAME", help="with --robot: the platform frame (default: the "
    "loops file's robot.platform)", show_default=False)]
PoseAxes = Annotated[str | None, typer.Option(
    "--pose-axes", metavar="AXES", help="with --robot: the pose components, a subset of "
    "x,y,z,roll,pitch,yaw in that order (default: the loops file's, else all six)",
    show_default=False)]

EffectsFile = Annotated[Path | None, typer.Option(
    "--effects", metavar="FILE", help="joint and drive effects on top of the robot's own: "
    "a YAML / TOML file, `joints: {<joint>: {damping: 1.5, coulomb: 0.8, ...}}` (the "
    "loops file's effects: format; see docs/drives.md)", show_default=False)]

#: the robot of a command: the hexapod, or a robot loaded with ``--robot``
if TYPE_CHECKING:
    CliRobot = Hexapod | ClosedLoopRobot
else:       # annotations only (the command line imports the library on first use)
    CliRobot = object
#: angular pose components (``--degrees`` converts them)
ANGLES = ("roll", "pitch", "yaw")
#: the twist and wrench component of each pose component
TWIST_OF = {"x": "vx", "y": "vy", "z": "vz", "roll": "wx", "pitch": "wy", "yaw": "wz"}
WRENCH_OF = {"x": "fx", "y": "fy", "z": "fz", "roll": "mx", "pitch": "my", "yaw": "mz"}


class CliUsageError(Exception):
    """Options that do not go together (exit code 2, like any usage error: see
    :func:`is_usage_error`)."""

    exit_code = 2

    def format_message(self) -> str:
        """The message (click's usage-error interface)."""
        return str(self)


class ValueCountError(InputError):
    """A wrong number of values on the command line (a pose of 5 numbers for 6 axes): a
    usage error, exit code 2 (an :class:`~hexapod_pin.errors.InputError` naming the
    argument, the values and the count expected)."""

    exit_code = 2


def robot_of(geometry_file: Path | None, overrides: list[str] | None) -> Hexapod:
    """The hexapod of ``--geometry`` and ``--set`` (see :func:`hexapod_pin.files.load_geometry`)."""
    from ..files import load_geometry
    from ..hexapod.robot import Hexapod
    return Hexapod(load_geometry(geometry_file, overrides))


def load_cli_robot(robot: Path | None, platform: str | None, pose_axes: str | None,
                   geometry: Path | None, set_: list[str] | None,
                   effects: Path | None = None) -> CliRobot:
    """The robot of a command: with ``robot`` (``--robot PATH``) the
    :class:`~hexapod_pin.ClosedLoopRobot` of :func:`hexapod_pin.load_robot` (``--platform``,
    ``--pose-axes``), else the hexapod of ``--geometry`` / ``--set`` (:func:`robot_of`);
    with the effects of ``--effects FILE`` over its own (:func:`with_effects_file`).

    Raises:
        CliUsageError: ``--robot`` with ``--geometry`` or ``--set``, or ``--platform`` /
            ``--pose-axes`` without ``--robot``.
        DescriptionError: a missing or malformed description, no loops file, an unknown
            frame, pose axes that do not match the mechanism's mobility, a malformed
            effects file.
    """
    from ..loaders.any_robot import load_robot
    if robot is None:
        if platform is not None or pose_axes is not None:
            raise CliUsageError("--platform and --pose-axes need --robot PATH")
        return with_effects_file(robot_of(geometry, set_), effects)
    if geometry is not None or set_:
        raise CliUsageError("--robot cannot be combined with --geometry or --set (they "
                            "set the fields of the hexapod's geometry)")
    return with_effects_file(load_robot(robot, platform, pose_axes), effects)


def with_effects_file(robot: CliRobot, path: Path | None) -> CliRobot:
    """``robot`` with the joint and drive effects of an effects file
    (:func:`hexapod_pin.core.description.read_effects_file`) applied over its own, joint by
    joint (:meth:`~hexapod_pin.core.description.EffectsSection.apply`); ``robot`` itself
    when ``path`` is None.

    Raises:
        DescriptionError: a malformed file, an unknown joint or key, a bad value (naming
            the file, the joint, the key and its line).
    """
    from ..core.description import read_effects_file
    if path is None:
        return robot
    section = read_effects_file(path)
    model = robot.model
    effects = section.apply(model.tree_model, model.actuated_joints, robot.effects)
    return cast(CliRobot, robot.with_effects(effects))


def effects_on(robot: CliRobot) -> dict[str, list[str]]:
    """The joint and drive effects ``robot`` carries: each field that is on (a nonzero
    armature, damping, coulomb, stiffness; a gear other than 1; a finite effort limit)
    -> the joints that have it, in the tree's order."""
    from ..core.effects import COORDINATE_FIELDS
    effects, model = robot.effects, robot.model.tree_model
    joint_of = [""] * model.nv
    for jid in range(1, model.njoints):
        joint = model.joints[jid]
        joint_of[joint.idx_v:joint.idx_v + joint.nv] = [model.names[jid]] * joint.nv
    out: dict[str, list[str]] = {}
    for name in COORDINATE_FIELDS:
        joints = [joint_of[i] for i in np.flatnonzero(getattr(effects, name))]
        if joints:
            out[name] = list(dict.fromkeys(joints))
    actuated = robot.model.actuated_joints
    for name, on in (("gear", effects.gear != 1.0),
                     ("effort_limit", np.isfinite(effects.effort_limit))):
        if np.any(on):
            out[name] = [actuated[k] for k in np.flatnonzero(on)]
    return out


def effects_fields(robot: CliRobot, path: Path | None) -> dict[str, Any]:
    """What ``--json`` adds with ``--effects FILE``: ``{"effects": {"file": ..., "on":
    {field: [joints]}, "velocity_threshold": ...}}`` (:func:`effects_on`; nothing
    without the option)."""
    if path is None:
        return {}
    return {"effects": {"file": path, "on": effects_on(robot),
                        "velocity_threshold": robot.effects.velocity_threshold}}


def effects_line(robot: CliRobot, path: Path | None) -> str | None:
    """The line the text output shows with ``--effects FILE``, e.g. ``effects (drives.yaml):
    damping on 6 joints, coulomb on crank`` (None without the option)."""
    if path is None:
        return None
    on = effects_on(robot)
    parts = [f"{name} on {joints[0] if len(joints) == 1 else f'{len(joints)} joints'}"
             for name, joints in on.items()]
    return f"effects ({path}): {', '.join(parts) if parts else 'none (rigid)'}"


def print_effects(robot: CliRobot, path: Path | None) -> None:
    """Print :func:`effects_line` on stdout (nothing without ``--effects``)."""
    line = effects_line(robot, path)
    if line is not None:
        console.print(Text(line))


def robot_urdf(robot: CliRobot, path: Path | None) -> Path | None:
    """The URDF the viewer draws a robot loaded from ``path`` with, when its model does not
    carry its URDF text (an example-parallel-robots folder: its ``robot.urdf``); None
    otherwise (the model's own)."""
    if path is None or getattr(robot.model, "urdf_xml", None):
        return None
    candidate = path / "robot.urdf" if path.is_dir() else path
    return candidate if candidate.suffix == ".urdf" and candidate.is_file() else None


def hexapod_only(robot: CliRobot, **options: object) -> None:
    """Refuse options of the hexapod (given: not None / not False) for a robot loaded with
    ``--robot``.

    Raises:
        CliUsageError: one of ``options`` was given for a loaded robot.
    """
    from ..hexapod.robot import Hexapod
    if isinstance(robot, Hexapod):
        return
    given = [name for name, value in options.items() if value not in (None, False, [])]
    if given:
        flags = ", ".join("--" + name.replace("_", "-") for name in given)
        raise CliUsageError(f"{flags}: an option of the hexapod, not of --robot "
                            f"({robot.geometry.name})")


def pose_axes_of(robot: CliRobot) -> tuple[str, ...]:
    """The pose components of the robot, e.g. ``("x", "z")`` (the hexapod: all six)."""
    from ..core.robot import ClosedLoopRobot
    from ..motion import POSE_NAMES
    return robot.geometry.pose_axes if isinstance(robot, ClosedLoopRobot) else POSE_NAMES


def actuator_names(robot: CliRobot) -> tuple[str, ...]:
    """The actuators in order: the actuated joints of a loaded robot, ``q0 .. q5`` for
    the hexapod's carriages."""
    from ..core.robot import ClosedLoopRobot
    if isinstance(robot, ClosedLoopRobot):
        return tuple(robot.model.actuated_joints)
    return tuple(f"q{i}" for i in range(robot.n_actuators))


def robot_fields(robot: CliRobot) -> dict[str, Any]:
    """What ``--json`` adds for a loaded robot: its name, pose axes and actuators (nothing
    for the hexapod)."""
    from ..core.robot import ClosedLoopRobot
    if not isinstance(robot, ClosedLoopRobot):
        return {}
    return {"robot": robot.geometry.name, "platform": robot.geometry.platform,
            "pose_axes": list(pose_axes_of(robot)), "actuators": list(actuator_names(robot))}


@functools.cache
def _motion_names() -> frozenset[str]:
    """The column names a motion file of some robot may have (:func:`motion_columns`)."""
    from .. import motion as motions
    return frozenset(motions.POSE_NAMES + motions.TWIST_NAMES + motions.TWIST_DOT_NAMES
                     + motions.WRENCH_NAMES)


_ACTUATOR_COLUMN = re.compile(r"(q|tau)\d+")


def as_parallel(robot: CliRobot) -> ParallelRobot:
    """``robot`` typed as the shared robot API (a loaded robot serves the protocol at run
    time; its ``default`` and ``n_actuators`` are instance members, so mypy needs the cast
    until :mod:`hexapod_pin.core.robot_api` says so)."""
    from ..core.robot_api import ParallelRobot
    return cast(ParallelRobot, robot)


def expected_columns(robot: CliRobot) -> str:
    """The motion-file columns of ``robot`` as one line: ``t`` and the pose, then the
    optional groups, e.g. ``t, x, z; optional vx, vz | ax, az | fx, fz | q0, q1 | tau0,
    tau1 | residual`` (:func:`hexapod_pin.motion.motion_columns`)."""
    from .. import motion as motions
    from ..hexapod.robot import Hexapod
    columns = motions.motion_columns(None if isinstance(robot, Hexapod)
                                     else as_parallel(robot))
    groups = " | ".join(", ".join(names) for names in columns.groups().values())
    return f"{', '.join(('t', *columns.pose))}; optional {groups} | residual"


def read_robot_motion(path: Path, robot: CliRobot) -> motions.Motion:
    """The motion file of a command's robot (:func:`hexapod_pin.motion.read_motion`): the
    hexapod's columns, or those of a robot loaded with ``--robot``.

    A CSV file of a loaded robot is refused when its header lacks a pose column of the
    robot or has motion columns of another robot (a pose, twist, wrench, ``qN`` or
    ``tauN`` column the robot does not have: a hexapod file given to a five-bar); a JSON
    file when a field has another width. Other columns are ignored, as for the hexapod.

    Raises:
        DescriptionError: a malformed file, or one of another robot (the message names
            the columns expected, :func:`expected_columns`).
    """
    from .. import motion as motions
    from ..hexapod.robot import Hexapod
    if isinstance(robot, Hexapod):
        return motions.read_motion(path)
    columns = motions.motion_columns(as_parallel(robot))
    fits = f"does not fit {robot.geometry.name}"
    _check_header(path, robot, ("t", *columns.pose))
    try:
        return motions.read_motion(path, as_parallel(robot))
    except DescriptionError as exc:
        if exc.culprit not in ("pose", *columns.groups()):
            raise
        raise DescriptionError(str(path), f"{fits}: {exc.reason}; expected columns "
                                          f"{expected_columns(robot)}", exc.culprit) from None


def read_robot_log(path: Path, robot: CliRobot) -> motions.ActuatorLog:
    """The actuator positions and forces of a motion file of the command's robot, pose
    columns optional (:func:`hexapod_pin.motion.read_actuator_log`; a CSV file of a
    loaded robot checked for another robot's columns as by :func:`read_robot_motion`).

    Raises:
        DescriptionError: a malformed file, one of another robot, or one without the
            times, positions or forces.
    """
    from .. import motion as motions
    from ..hexapod.robot import Hexapod
    if isinstance(robot, Hexapod):
        return motions.read_actuator_log(path)
    _check_header(path, robot, ("t",))
    return motions.read_actuator_log(path, as_parallel(robot))


def _check_header(path: Path, robot: CliRobot, required: tuple[str, ...]) -> None:
    """Refuse a CSV file of a loaded robot whose header lacks a ``required`` column or has
    motion columns of another robot (:func:`read_robot_motion`)."""
    from .. import motion as motions
    columns = motions.motion_columns(as_parallel(robot))
    own = {"t", *columns.pose, *(n for names in columns.groups().values() for n in names)}
    fits = f"does not fit {robot.geometry.name}"
    if path.suffix.lower() in (".csv", ".txt") and path.is_file():
        header = _csv_header(path)
        if header is not None:
            missing = [c for c in required if c not in header]
            foreign = [c for c in header if c not in own
                       and (c in _motion_names() or _ACTUATOR_COLUMN.fullmatch(c))]
            if missing or foreign:
                what = "; ".join(part for part in (
                    f"missing columns {', '.join(missing)}" if missing else "",
                    f"columns {', '.join(foreign)} are not its own" if foreign else "")
                    if part)
                raise DescriptionError(str(path), f"{fits} ({what}); expected columns "
                                                  f"{expected_columns(robot)}")


def _csv_header(path: Path) -> list[str] | None:
    """The header row of a CSV motion file (its first line that is neither blank nor a
    ``#`` comment), None when it has none (read_motion says so)."""
    from ..files import read_text
    for line in read_text(path).splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            return [name.strip() for name in next(csv.reader([line]))]
    return None


def write_robot_motion(path: Path, motion: motions.Motion, robot: CliRobot) -> Path:
    """Write ``motion`` in the columns of the command's robot
    (:func:`hexapod_pin.motion.write_motion`; the hexapod's without ``--robot``)."""
    from .. import motion as motions
    from ..hexapod.robot import Hexapod
    if isinstance(robot, Hexapod):
        return motions.write_motion(path, motion)
    return motions.write_motion(path, motion, as_parallel(robot))


# -- errors ---------------------------------------------------------------------------------
def report_error(message: str, kind: str, as_json: bool = False) -> None:
    """Write one error: ``error: <message>`` on one line of stderr, or with ``as_json``
    the object ``{"error": {"type": kind, "message": message}}`` on one line of stdout.

    The message is printed as it is (brackets and all: no rich markup is read in it)."""
    text = " ".join(str(message).split())
    if as_json:
        typer.echo(json.dumps({"error": {"type": kind, "message": text}}))
        return
    Console(stderr=True).print(f"[bold red]error:[/] {escape(text)}", highlight=False,
                               markup=True, soft_wrap=True)


def fail(exc: Exception, as_json: bool = False) -> None:
    """Report ``exc`` (:func:`report_error`) and exit with its ``exit_code`` (2 for a
    :class:`ValueCountError`), else 1."""
    report_error(str(exc), type(exc).__name__, as_json)
    code = getattr(exc, "exit_code", 1)
    raise typer.Exit(code=code if isinstance(code, int) else 1)


def guard(func: Callable) -> Callable:
    """Turn library and file errors into a one-line message (JSON with the command's
    ``as_json`` argument) and exit code 1."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        as_json = bool(kwargs.get("as_json", False))
        try:
            return func(*args, **kwargs)
        except HexapodPinError as exc:
            fail(exc, as_json)
        except OSError as exc:
            fail(CommandError(f"{exc.strerror or exc}: {exc.filename or ''}".strip(": ")),
                 as_json)

    return wrapper


def flags_without_type(params: list) -> list:
    """The parameters of a command, with boolean flags shown in ``--help`` without the
    ``<bool>`` type column (a flag takes no value)."""
    for param in params:
        if getattr(param, "is_flag", False) and param.metavar is None:
            param.metavar = ""
    return params


def is_usage_error(exc: BaseException) -> bool:
    """Whether ``exc`` is a usage error of the command-line parser (click's
    ``ClickException`` family, vendored by recent typer versions): it has
    ``format_message()`` and an integer ``exit_code``."""
    return (callable(getattr(exc, "format_message", None))
            and isinstance(getattr(exc, "exit_code", None), int))


class Command(TyperCommand):
    """A command whose ``--help`` shows no value type after its flags, and whose numeric
    arguments (negative numbers: ``ignore_unknown_options``) do not swallow an unknown
    option: ``--jsn`` is a usage error (exit code 2, "No such option", with the close
    matches), not a bad number."""

    def get_params(self, ctx: Any) -> list:
        return flags_without_type(super().get_params(ctx))

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        known = sorted({opt for param in self.get_params(ctx)
                        for opt in (*param.opts, *getattr(param, "secondary_opts", ()))
                        if opt.startswith("-")})
        for token in args:
            if token == "--":
                break
            name = token.split("=", 1)[0]
            if name.startswith("-") and name not in known and not _numeric(name):
                close = difflib.get_close_matches(name, known, n=3)
                hint = f" (Possible options: {', '.join(close)})" if close else ""
                ctx.fail(f"No such option: {name}{hint}")
        return list(super().parse_args(ctx, args))


def _numeric(token: str) -> bool:
    """Whether a token is a number or a comma-separated list of numbers (``-0.1,0.2``)."""
    try:
        for piece in token.split(","):
            if piece:
                float(piece)
    except ValueError:
        return False
    return True


class Group(TyperGroup):
    """The ``hexapod-pin`` group: usage errors as one line (or JSON), never a box.

    A value that cannot be converted (``--duration abc``) exits with code 1 like any bad
    input; other usage errors (unknown option, missing required option or argument, extra
    arguments) exit with code 2 (click's ``MissingParameter`` derives from
    ``BadParameter``: it is told apart).
    """

    def get_params(self, ctx: Any) -> list:
        return flags_without_type(super().get_params(ctx))

    def main(self, args: Sequence[str] | None = None, prog_name: str | None = None,
             complete_var: str | None = None, standalone_mode: bool = True,
             windows_expand_args: bool = True, **extra: Any) -> Any:
        argv = list(sys.argv[1:] if args is None else args)
        if not standalone_mode:
            return super().main(args=argv, prog_name=prog_name, complete_var=complete_var,
                                windows_expand_args=windows_expand_args,
                                standalone_mode=False, **extra)
        as_json = "--json" in argv
        try:
            code = super().main(args=argv, prog_name=prog_name, complete_var=complete_var,
                                windows_expand_args=windows_expand_args,
                                standalone_mode=False, **extra)
        except typer.Abort:
            report_error("aborted", "Abort", as_json)
            sys.exit(1)
        except Exception as exc:
            if not is_usage_error(exc):
                raise
            ctx = getattr(exc, "ctx", None)
            usage: Any = exc                # a click usage error (see is_usage_error)
            message = str(usage.format_message())
            if type(exc).__name__ == "NoArgsIsHelpError":     # bare command: its help
                typer.echo(ctx.get_help() if ctx is not None else message)
                sys.exit(0)
            if ctx is not None:
                message += f" (see '{ctx.command_path} --help')"
            report_error(message, type(exc).__name__, as_json)
            bad_value = isinstance(exc, typer.BadParameter) and \
                type(exc).__name__ != "MissingParameter"
            sys.exit(1 if bad_value else 2)
        sys.exit(code if isinstance(code, int) else 0)


# -- parsing --------------------------------------------------------------------------------
def parse_numbers(tokens: Sequence[str] | None, count: int | None, name: str,
                  meaning: str = "") -> np.ndarray:
    """Floats from tokens like ``["0", "-0.1"]`` or ``["0,-0.1"]``; exactly ``count``.

    Raises:
        InputError: a token that is not a number, an empty field between commas, NaN or
            inf.
        ValueCountError: another count (a usage error, exit code 2).
    """
    parts: list[str] = []
    for chunk in (c for tok in (tokens or []) for c in str(tok).split()):
        pieces = chunk.split(",")
        if "" in pieces[1:-1]:
            raise InputError(name, chunk, "an empty field between commas")
        parts.extend(piece for piece in pieces if piece)
    values = []
    for part in parts:
        try:
            values.append(float(part))
        except ValueError:
            raise InputError(name, part, f"not a number ({part!r})") from None
    if count is not None and len(values) != count:
        what = f" ({meaning})" if meaning else ""
        raise ValueCountError(name, parts, f"expected {count} values{what}, got {len(values)}")
    array = np.array(values, dtype=float)
    if not np.all(np.isfinite(array)):
        raise InputError(name, parts, "contains NaN or inf")
    return array


def hexapod_axes(axes: tuple[str, ...] | None) -> tuple[str, ...]:
    """``axes``, or when None the hexapod's pose components
    (:data:`hexapod_pin.motion.POSE_NAMES`)."""
    from ..motion import POSE_NAMES
    return POSE_NAMES if axes is None else axes


def pose_in(tokens: Sequence[str] | None, degrees: bool, name: str = "pose",
            axes: tuple[str, ...] | None = None) -> np.ndarray:
    """A pose (len(axes),) from the command line in m, rad (angles in degrees with
    ``degrees``); ``axes`` the robot's pose components (:func:`pose_axes_of`; default the
    hexapod's)."""
    axes = hexapod_axes(axes)
    pose = parse_numbers(tokens, len(axes), name, ", ".join(axes))
    if degrees:
        angular = _angular(axes)
        pose[angular] = np.radians(pose[angular])
    return pose


def pose_out(pose: ArrayLike, degrees: bool, axes: tuple[str, ...] | None = None
             ) -> list[float]:
    """A pose of components ``axes`` (default the hexapod's) as plain floats for output
    (angles in degrees with ``degrees``)."""
    axes = hexapod_axes(axes)
    pose = np.array(pose, dtype=float)
    if degrees:
        angular = _angular(axes)
        pose[angular] = np.degrees(pose[angular])
    return [float(v) for v in pose]


def robot_pose_out(robot: CliRobot, pose: ArrayLike, degrees: bool) -> list[float]:
    """A pose of ``robot`` as plain floats (its angular components in degrees with
    ``degrees``)."""
    return pose_out(pose, degrees, pose_axes_of(robot))


def _angular(axes: tuple[str, ...]) -> np.ndarray:
    return np.array([axis in ANGLES for axis in axes], dtype=bool)


def robot_pose_in(robot: CliRobot, tokens: Sequence[str] | None, degrees: bool,
                  name: str = "pose") -> np.ndarray:
    """A pose of ``robot`` from the command line (:func:`pose_in` in its axes); no tokens:
    its home pose."""
    return pose_in(tokens, degrees, name, pose_axes_of(robot)) if tokens else robot.home_pose


def actuators_in(robot: CliRobot, tokens: Sequence[str] | None, name: str = "q") -> np.ndarray:
    """Actuator values (n_act,) of ``robot`` from the command line (m or rad, actuator
    order)."""
    from ..hexapod.robot import Hexapod
    names = actuator_names(robot)
    meaning = "q0 .. q5" if isinstance(robot, Hexapod) else ", ".join(names)
    return parse_numbers(tokens, len(names), name, meaning)


def component_values(robot: CliRobot, text: str | None, name: str,
                     names: dict[str, str]) -> np.ndarray | None:
    """A twist or wrench of ``robot`` from ``'a,b,...'`` (one value per pose component,
    ``names`` maps each to its component name, e.g. :data:`WRENCH_OF`); None stays None."""
    if text is None:
        return None
    parts = [names[axis] for axis in pose_axes_of(robot)]
    return parse_numbers([text], len(parts), name, ", ".join(parts))


def check_suffix(name: str, path: Path | None, suffixes: tuple[str, ...]) -> None:
    """Raise :class:`InputError` unless ``path`` is None or ends in one of ``suffixes``."""
    if path is not None and path.suffix.lower() not in suffixes:
        raise InputError(name, str(path), f"expected one of {', '.join(suffixes)}")


# -- output ---------------------------------------------------------------------------------
def emit_json(payload: Any) -> None:
    """Write ``payload`` as one line of strict JSON on stdout (arrays, numpy scalars, paths
    and dataclasses converted; NaN and infinities written as ``null``)."""
    typer.echo(json.dumps(plain(payload), allow_nan=False))


def plain(obj: Any) -> Any:
    """A dataclass / array / scalar / path as JSON-friendly values (floats and lists); a
    non-finite float becomes None (JSON has no NaN or Infinity: e.g. the condition number
    at a singularity)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)
                if not f.name.startswith("_")}
    if isinstance(obj, np.ndarray):
        return plain(obj.tolist()) if obj.dtype.kind in "fc" else obj.tolist()
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return plain(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, dict):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    return obj


def fmt(values: ArrayLike, spec: str = "+.6f") -> str:
    """Numbers formatted with ``spec``, separated by spaces."""
    return " ".join(format(float(v), spec) for v in np.ravel(values))


def note(quiet: bool, text: str) -> None:
    """A note on stderr, unless ``quiet``."""
    if not quiet:
        Console(stderr=True).print(text, highlight=False, markup=False)


@contextlib.contextmanager
def progress_bar(quiet: bool, label: str, total: int | None = None) -> Iterator[Callable]:
    """A rich progress bar on stderr (a spinner when ``total`` is None), transient.

    Yields ``update(done, total)``, the progress callback the library's long-running
    functions take; silent when ``quiet`` or when stderr is not a terminal.
    """
    err = Console(stderr=True)
    if quiet or not err.is_terminal:
        yield lambda done=0, total=None: None
        return
    columns = [SpinnerColumn(), TextColumn("{task.description}")]
    if total is not None:
        columns += [BarColumn(), MofNCompleteColumn()]
    columns.append(TimeElapsedColumn())
    with Progress(*columns, console=err, transient=True) as bar:
        task = bar.add_task(label, total=total)
        yield lambda done=0, total=None: bar.update(task, completed=done)


def pose_table(title: str, poses: Sequence[np.ndarray] | np.ndarray, degrees: bool,
               axes: tuple[str, ...] | None = None) -> Table:
    """A table of poses of components ``axes`` (default the hexapod's), one row each, with
    units in the column names."""
    axes = hexapod_axes(axes)
    unit = "deg" if degrees else "rad"
    table = Table(title=title)
    table.add_column("#", justify="right")
    for name in axes:
        table.add_column(f"{name} ({unit if name in ANGLES else 'm'})", justify="right")
    for n, pose in enumerate(poses):
        table.add_row(str(n), *(f"{v:+.6f}" for v in pose_out(pose, degrees, axes)))
    return table


def actuator_table(robot: CliRobot, title: str, columns: dict[str, np.ndarray]) -> Table:
    """A table with one row per actuator and the given columns (the hexapod:
    :func:`carriage_table`, with each carriage's rail)."""
    from ..hexapod.robot import Hexapod
    if isinstance(robot, Hexapod):
        return carriage_table(title, columns)
    table = Table(title=title)
    table.add_column("actuator", justify="right")
    for name in columns:
        table.add_column(name, justify="right")
    for i, name in enumerate(actuator_names(robot)):
        table.add_row(Text(name), *(f"{float(v[i]):+.6f}" for v in columns.values()))
    return table


def carriage_table(title: str, columns: dict[str, np.ndarray]) -> Table:
    """A table with one row per carriage (and its rail) and the given columns."""
    table = Table(title=title)
    table.add_column("carriage", justify="right")
    table.add_column("rail", justify="right")
    for name in columns:
        table.add_column(name, justify="right")
    for i in range(6):
        table.add_row(str(i), str(i // 2), *(f"{float(v[i]):+.6f}" for v in columns.values()))
    return table


def quantity_table(title: str, rows: dict[str, str]) -> Table:
    """A two-column table: quantity (with its unit), value."""
    table = Table(title=title)
    table.add_column("quantity")
    table.add_column("value", justify="right")
    for key, value in rows.items():
        table.add_row(Text(key), Text(value))     # Text: brackets in messages kept
    return table

"""What every command shares: the common options, reading numbers and poses from the
command line, turning library errors into one-line messages, and the output helpers
(JSON, tables, notes and progress bars on stderr).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
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

from ..errors import HexapodPinError, InputError
from ..files import load_geometry
from ..hexapod.robot import Hexapod
from ..motion import POSE_NAMES

#: lets "-0.1" through as a value (commands taking numbers)
NUMBERS = {"ignore_unknown_options": True}
console = Console()


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


def robot_of(geometry_file: Path | None, overrides: list[str] | None) -> Hexapod:
    """The hexapod of ``--geometry`` and ``--set`` (see :func:`hexapod_pin.files.load_geometry`)."""
    return Hexapod(load_geometry(geometry_file, overrides))


# -- errors ---------------------------------------------------------------------------------
def fail(exc: Exception) -> None:
    """Print ``error: <message>`` on one line of stderr and exit with code 1."""
    text = " ".join(str(exc).split())
    Console(stderr=True).print(f"[bold red]error:[/] {escape(text)}", highlight=False,
                               markup=True, soft_wrap=True)
    raise typer.Exit(code=1)


def guard(func: Callable) -> Callable:
    """Turn library and file errors into a one-line message and exit code 1."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except HexapodPinError as exc:
            fail(exc)
        except OSError as exc:
            fail(CommandError(f"{exc.strerror or exc}: {exc.filename or ''}".strip(": ")))

    return wrapper


# -- parsing --------------------------------------------------------------------------------
def parse_numbers(tokens, count: int | None, name: str, meaning: str = "") -> np.ndarray:
    """Floats from tokens like ``["0", "-0.1"]`` or ``["0,-0.1"]``; exactly ``count``.

    Raises:
        InputError: a token that is not a number, another count, NaN or inf.
    """
    parts = [p for tok in (tokens or []) for p in str(tok).replace(",", " ").split()]
    values = []
    for part in parts:
        try:
            values.append(float(part))
        except ValueError:
            raise InputError(name, part, f"not a number ({part!r})") from None
    if count is not None and len(values) != count:
        what = f" ({meaning})" if meaning else ""
        raise InputError(name, parts, f"expected {count} values{what}, got {len(values)}")
    values = np.array(values, dtype=float)
    if not np.all(np.isfinite(values)):
        raise InputError(name, parts, "contains NaN or inf")
    return values


def pose_in(tokens, degrees: bool, name: str = "pose") -> np.ndarray:
    """A pose (6,) from the command line (angles in degrees with ``degrees``) in m, rad."""
    pose = parse_numbers(tokens, 6, name, "x y z roll pitch yaw")
    if degrees:
        pose[3:] = np.radians(pose[3:])
    return pose


def pose_out(pose, degrees: bool) -> list[float]:
    """A pose as plain floats for output (angles in degrees with ``degrees``)."""
    pose = np.array(pose, dtype=float)
    if degrees:
        pose[3:] = np.degrees(pose[3:])
    return [float(v) for v in pose]


def check_suffix(name: str, path: Path | None, suffixes: tuple[str, ...]) -> None:
    """Raise :class:`InputError` unless ``path`` is None or ends in one of ``suffixes``."""
    if path is not None and path.suffix.lower() not in suffixes:
        raise InputError(name, str(path), f"expected one of {', '.join(suffixes)}")


# -- output ---------------------------------------------------------------------------------
def emit_json(payload) -> None:
    """Write ``payload`` as one line of JSON on stdout (arrays, numpy scalars, paths and
    dataclasses converted)."""
    typer.echo(json.dumps(plain(payload)))


def plain(obj):
    """A dataclass / array / scalar / path as JSON-friendly values (floats and lists)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)
                if not f.name.startswith("_")}
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, dict):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    return obj


def fmt(values, spec: str = "+.6f") -> str:
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


def pose_table(title: str, poses, degrees: bool) -> Table:
    """A table of poses, one row each, with units in the column names."""
    unit = "deg" if degrees else "rad"
    table = Table(title=title)
    table.add_column("#", justify="right")
    for name in POSE_NAMES:
        table.add_column(f"{name} ({'m' if name in 'xyz' else unit})", justify="right")
    for n, pose in enumerate(poses):
        table.add_row(str(n), *(f"{v:+.6f}" for v in pose_out(pose, degrees)))
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
        table.add_row(key, value)
    return table

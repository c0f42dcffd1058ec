"""Command line interface: ``hexapod-pin`` (also ``python -m hexapod_pin``).

Commands: ``demo``, ``ik``, ``fk``, ``modes``, ``jacobian``, ``statics``, ``id``,
``simulate``, ``view``, ``plot`` (``hexapod-pin COMMAND --help`` for each).

Common options:

* ``--geometry FILE``: a TOML, YAML or JSON file of :class:`HexapodGeometry` fields
  (at the top level or under a ``geometry`` table), e.g. ``leg_length = 0.5``;
  ``--set FIELD=VALUE`` (repeatable) overrides one field. Default: the defaults.
* ``--json``: machine-readable output on stdout (nothing else is written then).
* ``--quiet``: no progress bars or notes (results are still printed).
* ``--degrees``: angles of poses in degrees, in and out (default rad).

Numbers are given as separate arguments or comma-separated (``0 0 0.35 0 0 0`` or
``0,0,0.35,0,0,0``); negative numbers need no ``--``.

Motion files (``id``, ``view --trajectory``, ``plot``; written by ``simulate --out``):

* CSV: a header row naming the columns, ``#`` comment lines allowed. Required:
  ``t`` (s) and the pose ``x, y, z`` (m), ``roll, pitch, yaw`` (rad). Optional:
  the twist ``vx, vy, vz, wx, wy, wz`` (m/s, rad/s, world axes), its time
  derivative ``ax, ay, az, alphax, alphay, alphaz``, the wrench on the platform
  ``fx, fy, fz, mx, my, mz`` (N, N m, world axes, about the platform origin), the
  carriage positions ``q0 .. q5`` (m), the actuator forces ``tau0 .. tau5`` (N),
  the max-abs closure residual ``residual`` (m).
* JSON: ``{"t": [...], "pose": [[6], ...], "twist": ..., "twist_dot": ...,
  "wrench": ..., "q": ..., "actuator_forces": ..., "closure_residual": ...}``.

When the twist (or its derivative) is absent it is computed from the poses by
second-order finite differences (``numpy.gradient``; angles unwrapped), with
``w = E(rpy) d(rpy)/dt``.

Errors of the library or of the input end the command with a one-line message
on stderr and exit code 1 (usage errors: exit code 2).
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import functools
import io
import json
import math
import sys
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    SpinnerColumn,
    TextColumn,
    TimeElapsedColumn,
)
from rich.table import Table

from ..errors import DescriptionError, GeometryError, HexapodPinError, InputError
from ..hexapod.geometry import HexapodGeometry
from ..hexapod.robot import Hexapod

app = typer.Typer(help="Kinematics and dynamics of the rail-driven hexapod.", no_args_is_help=True,
                  pretty_exceptions_enable=False, add_completion=False,
                  rich_markup_mode="markdown")
console = Console()
NUMBERS = {"ignore_unknown_options": True}  # lets "-0.1" through as a value
POSE_NAMES = ("x", "y", "z", "roll", "pitch", "yaw")
TWIST_NAMES = ("vx", "vy", "vz", "wx", "wy", "wz")
TWIST_DOT_NAMES = ("ax", "ay", "az", "alphax", "alphay", "alphaz")
WRENCH_NAMES = ("fx", "fy", "fz", "mx", "my", "mz")
Q_NAMES = tuple(f"q{i}" for i in range(6))
TAU_NAMES = tuple(f"tau{i}" for i in range(6))


class CommandError(HexapodPinError):
    """A command could not do its job (with the context, e.g. the row of a file)."""


class FeatureUnavailableError(CommandError):
    """The installed hexapod_pin lacks a function this command needs.

    Attributes:
        feature: the missing function, e.g. ``"Hexapod.forward_kinematics"``.
    """

    def __init__(self, feature: str):
        self.feature = feature
        super().__init__(f"not available: this installation of hexapod_pin has no {feature}")


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


@app.callback()
def _root() -> None:
    """hexapod_pin command line (see each command's --help)."""


def _fail(exc: Exception) -> None:
    text = " ".join(str(exc).split())
    Console(stderr=True).print(f"[bold red]error:[/] {text}", highlight=False, markup=True,
                               soft_wrap=True)
    raise typer.Exit(code=1)


def _guard(func: Callable) -> Callable:
    """Turn library and file errors into a one-line message and exit code 1."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except HexapodPinError as exc:
            _fail(exc)
        except OSError as exc:
            _fail(CommandError(f"{exc.strerror or exc}: {exc.filename or ''}".strip(": ")))

    return wrapper


# -- parsing --------------------------------------------------------------------------------
def parse_numbers(tokens, count: int | None, name: str, meaning: str = "") -> np.ndarray:
    """Floats from tokens like ``["0", "-0.1"]`` or ``["0,-0.1"]``; exactly ``count``."""
    parts = [p for tok in (tokens or []) for p in str(tok).replace(",", " ").split()]
    try:
        values = np.array([float(p) for p in parts], dtype=float)
    except ValueError:
        bad = next(p for p in parts if not _is_float(p))
        raise InputError(name, bad, f"not a number ({bad!r})") from None
    if count is not None and len(values) != count:
        what = f" ({meaning})" if meaning else ""
        raise InputError(name, parts, f"expected {count} values{what}, got {len(values)}")
    if not np.all(np.isfinite(values)):
        raise InputError(name, parts, "contains NaN or inf")
    return values


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _pose_in(tokens, degrees: bool, name: str = "pose") -> np.ndarray:
    pose = parse_numbers(tokens, 6, name, "x y z roll pitch yaw")
    if degrees:
        pose[3:] = np.radians(pose[3:])
    return pose


def _pose_out(pose, degrees: bool) -> list[float]:
    pose = np.array(pose, dtype=float)
    if degrees:
        pose[3:] = np.degrees(pose[3:])
    return [float(v) for v in pose]


def load_geometry(path: Path | None = None, overrides: list[str] | None = None
                  ) -> HexapodGeometry:
    """A :class:`HexapodGeometry` from defaults, a file and ``FIELD=VALUE`` overrides.

    Raises:
        DescriptionError: unreadable or malformed file.
        GeometryError: unknown field, or a value the geometry rejects.
    """
    fields: dict = {}
    if path is not None:
        fields.update(_read_geometry_file(Path(path)))
    for item in overrides or []:
        if "=" not in item:
            raise InputError("--set", item, "expected FIELD=VALUE")
        key, value = (s.strip() for s in item.split("=", 1))
        fields[key] = _field_value(key, value)
    known = {f.name for f in dataclasses.fields(HexapodGeometry)}
    unknown = sorted(set(fields) - known)
    if unknown:
        raise GeometryError(unknown[0], fields[unknown[0]],
                            f"unknown field; known: {', '.join(sorted(known))}")
    if "platform_inertia" in fields and isinstance(fields["platform_inertia"], list):
        fields["platform_inertia"] = tuple(fields["platform_inertia"])
    try:
        return HexapodGeometry(**fields)
    except TypeError as exc:  # e.g. a field given as a table
        raise GeometryError("geometry", fields, str(exc)) from None


def _field_value(key: str, text: str):
    if key == "platform_inertia":
        return tuple(parse_numbers([text], 3, "platform_inertia"))
    try:
        return float(text)
    except ValueError:
        raise GeometryError(key, text, "not a number") from None


def _read_geometry_file(path: Path) -> dict:
    if not path.is_file():
        raise DescriptionError(str(path), "geometry file not found")
    text = path.read_text(encoding="utf-8")
    suffix = path.suffix.lower()
    import yaml

    readers = {".toml": (lambda: _toml().loads(text), ValueError),  # TOMLDecodeError
               ".yaml": (lambda: yaml.safe_load(text), yaml.YAMLError),
               ".yml": (lambda: yaml.safe_load(text), yaml.YAMLError),
               ".json": (lambda: json.loads(text), ValueError)}    # JSONDecodeError
    if suffix not in readers:
        raise DescriptionError(str(path), "geometry file must be .toml, .yaml, .yml or .json")
    read, syntax_error = readers[suffix]
    try:
        data = read()
    except syntax_error as exc:
        raise DescriptionError(str(path), f"malformed {suffix[1:]}: {exc}") from None
    if isinstance(data, dict) and isinstance(data.get("geometry"), dict):
        data = data["geometry"]
    if not isinstance(data, dict):
        raise DescriptionError(str(path), "expected a table of geometry fields")
    return data


def _toml():
    try:
        import tomllib
    except ModuleNotFoundError:  # pragma: no cover - Python 3.10
        try:
            import tomli as tomllib
        except ModuleNotFoundError:
            raise FeatureUnavailableError("TOML reader (Python < 3.11 needs tomli)") from None
    return tomllib


def _robot(geometry_file: Path | None, overrides: list[str] | None) -> Hexapod:
    return Hexapod(load_geometry(geometry_file, overrides))


def _need(robot, method: str):
    fn = getattr(robot, method, None)
    if fn is None:
        raise FeatureUnavailableError(f"Hexapod.{method}")
    return fn


# -- output ---------------------------------------------------------------------------------
def _emit_json(payload) -> None:
    typer.echo(json.dumps(payload, default=_json_default))


def _json_default(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def _fmt(values, spec: str = "+.6f") -> str:
    return " ".join(format(float(v), spec) for v in np.ravel(values))


def _note(quiet: bool, text: str) -> None:
    if not quiet:
        Console(stderr=True).print(text, highlight=False)


@contextlib.contextmanager
def _progress(quiet: bool, label: str, total: int | None = None) -> Iterator[Callable]:
    """A rich progress bar on stderr (a spinner when ``total`` is None), transient.

    Yields ``advance(n=1)``; silent when ``quiet`` or when stderr is not a terminal.
    """
    err = Console(stderr=True)
    if quiet or not err.is_terminal:
        yield lambda n=1: None
        return
    columns = [SpinnerColumn(), TextColumn("{task.description}")]
    if total is not None:
        columns += [BarColumn(), MofNCompleteColumn()]
    columns.append(TimeElapsedColumn())
    with Progress(*columns, console=err, transient=True) as bar:
        task = bar.add_task(label, total=total)
        yield lambda n=1: bar.advance(task, n)


def _pose_table(title: str, poses, degrees: bool, extra: dict | None = None) -> Table:
    unit = "deg" if degrees else "rad"
    table = Table(title=title)
    table.add_column("#", justify="right")
    for name in POSE_NAMES:
        table.add_column(f"{name} ({'m' if name in 'xyz' else unit})", justify="right")
    for key in (extra or {}):
        table.add_column(key, justify="right")
    for n, pose in enumerate(poses):
        cells = [f"{v:+.6f}" for v in _pose_out(pose, degrees)]
        cells += [str(v[n]) for v in (extra or {}).values()]
        table.add_row(str(n), *cells)
    return table


def _carriage_table(title: str, columns: dict[str, np.ndarray]) -> Table:
    table = Table(title=title)
    table.add_column("carriage", justify="right")
    table.add_column("rail", justify="right")
    for name in columns:
        table.add_column(name, justify="right")
    for i in range(6):
        table.add_row(str(i), str(i // 2), *(f"{float(v[i]):+.6f}" for v in columns.values()))
    return table


# -- motion files -----------------------------------------------------------------------------
@dataclass(frozen=True)
class Motion:
    """A sampled platform motion read from / written to a motion file (see module doc).

    Attributes:
        t: (N,) s. poses: (N, 6). twists, twist_dots, wrenches: (N, 6) or None.
        q, actuator_forces: (N, 6) or None. closure_residual: (N,) or None.
    """

    t: np.ndarray
    poses: np.ndarray
    twists: np.ndarray | None = None
    twist_dots: np.ndarray | None = None
    wrenches: np.ndarray | None = None
    q: np.ndarray | None = None
    actuator_forces: np.ndarray | None = None
    closure_residual: np.ndarray | None = None

    @property
    def times(self) -> np.ndarray:
        """Alias of ``t`` (the name the visualisation and plots read)."""
        return self.t


_JSON_KEYS = {"twist": "twists", "twist_dot": "twist_dots", "wrench": "wrenches", "q": "q",
              "actuator_forces": "actuator_forces"}
_CSV_GROUPS = {"twists": TWIST_NAMES, "twist_dots": TWIST_DOT_NAMES, "wrenches": WRENCH_NAMES,
               "q": Q_NAMES, "actuator_forces": TAU_NAMES}


def read_motion(path: Path) -> Motion:
    """Read a motion file (CSV or JSON, see the module doc).

    Raises:
        DescriptionError: missing file, unknown format, missing or malformed columns.
    """
    path = Path(path)
    if not path.is_file():
        raise DescriptionError(str(path), "motion file not found")
    if path.suffix.lower() == ".json":
        return _motion_from_json(path)
    if path.suffix.lower() in (".csv", ".txt"):
        return _motion_from_csv(path)
    raise DescriptionError(str(path), "motion file must be .csv or .json")


def _motion_from_csv(path: Path) -> Motion:
    lines = [ln for ln in path.read_text(encoding="utf-8").splitlines()
             if ln.strip() and not ln.lstrip().startswith("#")]
    if len(lines) < 2:
        raise DescriptionError(str(path), "needs a header row and at least one data row")
    rows = list(csv.reader(lines))
    header = [h.strip() for h in rows[0]]
    missing = [c for c in ("t",) + POSE_NAMES if c not in header]
    if missing:
        raise DescriptionError(str(path), f"missing columns {missing} (header: {header})")
    try:
        data = np.array([[float(v) for v in row] for row in rows[1:]], dtype=float)
    except ValueError as exc:
        raise DescriptionError(str(path), f"a value is not a number: {exc}") from None
    if data.ndim != 2 or data.shape[1] != len(header):
        raise DescriptionError(str(path), f"every row must have {len(header)} values")
    col = {name: data[:, i] for i, name in enumerate(header)}
    groups = {}
    for field, names in _CSV_GROUPS.items():
        present = [n for n in names if n in col]
        if present and len(present) != len(names):
            raise DescriptionError(str(path), f"columns {list(names)} must come together",
                                   present[0])
        groups[field] = np.stack([col[n] for n in names], axis=1) if present else None
    return _checked_motion(path, col["t"], np.stack([col[n] for n in POSE_NAMES], axis=1),
                           residual=col.get("residual"), **groups)


def _motion_from_json(path: Path) -> Motion:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise DescriptionError(str(path), f"malformed JSON: {exc}") from None
    if not isinstance(data, dict) or "t" not in data or "pose" not in data:
        raise DescriptionError(str(path), 'expected an object with "t" and "pose"')
    try:
        arrays = {field: None if data.get(key) is None else np.asarray(data[key], dtype=float)
                  for key, field in _JSON_KEYS.items()}
        t = np.asarray(data["t"], dtype=float)
        poses = np.asarray(data["pose"], dtype=float)
        residual = data.get("closure_residual")
        residual = None if residual is None else np.asarray(residual, dtype=float)
    except (TypeError, ValueError) as exc:
        raise DescriptionError(str(path), f"non-numeric entries: {exc}") from None
    return _checked_motion(path, t, poses, residual=residual, **arrays)


def _checked_motion(path, t, poses, residual=None, **arrays) -> Motion:
    n = len(t)
    if t.ndim != 1 or n == 0:
        raise DescriptionError(str(path), "t must be a non-empty list of times", "t")
    if n > 1 and np.any(np.diff(t) <= 0):
        raise DescriptionError(str(path), "t must be strictly increasing", "t")
    checks = {"pose": poses, **{k: v for k, v in arrays.items() if v is not None}}
    for key, value in checks.items():
        if value.shape != (n, 6):
            raise DescriptionError(str(path), f"{key} must have shape ({n}, 6), "
                                              f"got {value.shape}", key)
    if residual is not None:
        residual = np.max(np.abs(residual), axis=1) if residual.ndim == 2 else residual
        if residual.shape != (n,):
            raise DescriptionError(str(path), f"closure_residual must have {n} values",
                                   "closure_residual")
    for key, value in list(checks.items()) + [("t", t), ("closure_residual", residual)]:
        if value is not None and not np.all(np.isfinite(value)):
            raise DescriptionError(str(path), "contains NaN or inf", key)
    return Motion(t, poses, closure_residual=residual, **arrays)


def write_motion(path: Path, motion: Motion) -> Path:
    """Write a motion file (CSV or JSON by suffix) with every field that is set."""
    path = Path(path)
    fields = {"twists": motion.twists, "twist_dots": motion.twist_dots,
              "wrenches": motion.wrenches, "q": motion.q,
              "actuator_forces": motion.actuator_forces}
    if path.suffix.lower() == ".json":
        payload = {"t": motion.t, "pose": motion.poses}
        payload.update({key: fields[field] for key, field in _JSON_KEYS.items()
                        if fields[field] is not None})
        if motion.closure_residual is not None:
            payload["closure_residual"] = motion.closure_residual
        text = json.dumps(payload, default=_json_default)
    elif path.suffix.lower() == ".csv":
        header = ["t", *POSE_NAMES]
        columns = [motion.t[:, None], motion.poses]
        for field, names in _CSV_GROUPS.items():
            if fields[field] is not None:
                header += names
                columns.append(fields[field])
        if motion.closure_residual is not None:
            header.append("residual")
            columns.append(motion.closure_residual[:, None])
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(header)
        writer.writerows(np.hstack(columns).tolist())
        text = buffer.getvalue()
    else:
        raise InputError("out", str(path), "motion files are .csv or .json")
    from ..viz.scenes import write_text_atomic

    return write_text_atomic(path, text)


def motion_rates(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Twists and their derivatives (N, 6): from the file, or by finite differences."""
    from ..core.pose import euler_rates_matrix

    twists, twist_dots = motion.twists, motion.twist_dots
    if (twists is None or twist_dots is None) and len(motion.t) < 3:
        raise DescriptionError("motion", "at least 3 samples are needed to differentiate "
                                         "the poses (or give the twist columns)")
    if twists is None:
        angles = np.unwrap(motion.poses[:, 3:], axis=0)
        vel = np.gradient(motion.poses[:, :3], motion.t, axis=0, edge_order=2)
        rates = np.gradient(angles, motion.t, axis=0, edge_order=2)
        omega = np.einsum("nij,nj->ni", euler_rates_matrix(motion.poses[:, 3:]), rates)
        twists = np.hstack([vel, omega])
    if twist_dots is None:
        twist_dots = np.gradient(twists, motion.t, axis=0, edge_order=2)
    return twists, twist_dots


def circle_motion(robot: Hexapod, radius: float, period: float, duration: float | None = None,
                  rate: float = 200.0) -> Motion:
    """A horizontal circle of the platform origin about home, sampled at ``rate`` (Hz).

    Position ``home + radius (cos(2 pi t / T), sin(2 pi t / T), 0)`` (m), level
    platform (the reference of :func:`run_simulation`), with the exact twist and
    its derivative; ``duration`` defaults to one period (s).
    """
    duration = period if duration is None else duration
    if not (radius >= 0 and period > 0 and duration > 0 and rate > 0):
        raise InputError("circle", (radius, period, duration),
                         "need radius >= 0, period > 0, duration > 0")
    t = np.linspace(0.0, duration, max(round(duration * rate) + 1, 3))
    w = 2 * np.pi / period
    c, s = np.cos(w * t), np.sin(w * t)
    poses = np.tile(robot.home_pose, (len(t), 1))
    poses[:, 0] += radius * c
    poses[:, 1] += radius * s
    twists = np.zeros((len(t), 6))
    twists[:, 0], twists[:, 1] = -radius * w * s, radius * w * c
    dots = np.zeros((len(t), 6))
    dots[:, 0], dots[:, 1] = -radius * w * w * c, -radius * w * w * s
    return Motion(t, poses, twists, dots)


def inverse_dynamics_along(robot: Hexapod, motion: Motion, method: str = "qp",
                           advance: Callable = lambda n=1: None):
    """Actuator forces (N, 6) and closure forces (N, 6, 3) along a motion.

    Raises:
        FeatureUnavailableError: no ``Hexapod.inverse_dynamics``.
        CommandError: a sample fails (the message names its row and time).
    """
    solve = _need(robot, "inverse_dynamics")
    twists, twist_dots = motion_rates(motion)
    taus, closures = [], []
    for n in range(len(motion.t)):
        wrench = None if motion.wrenches is None else motion.wrenches[n]
        try:
            result = solve(motion.poses[n], twists[n], twist_dots[n], wrench=wrench,
                           method=method)
        except HexapodPinError as exc:
            raise CommandError(f"row {n} (t = {motion.t[n]:g} s): {exc}") from exc
        taus.append(np.asarray(result.actuator_forces, dtype=float))
        closures.append(np.asarray(getattr(result, "closure_forces",
                                           np.full((6, 3), np.nan)), dtype=float))
        advance()
    return np.array(taus), np.array(closures)


# -- demo -------------------------------------------------------------------------------------
@app.command()
@_guard
def demo(as_json: AsJson = False,
         leg_length: Annotated[float | None, typer.Option(help="override leg_length (m)")] = None,
         html: Annotated[Path | None, typer.Option(
             help="HTML file of the home pose (default: in the temp folder)")] = None,
         no_html: Annotated[bool, typer.Option("--no-html", help="write no HTML")] = False,
         quiet: Quiet = False) -> None:
    """The main job in one command: home pose, IK/FK round trip, statics, a short
    simulation, and an HTML view of the home pose."""
    quiet = quiet or as_json
    geometry = HexapodGeometry() if leg_length is None else HexapodGeometry(leg_length=leg_length)
    robot = Hexapod(geometry)
    q = robot.home_configuration
    residual = float(np.max(np.abs(robot.model.residual(q))))
    result = {
        "home_pose": robot.home_pose.tolist(),
        "home_q": robot.home_q.tolist(),
        "closure_rows": robot.model.n_rows,
        "closure_residual_max_abs_m": residual,
        "constraint_rank": robot.model.rank(q).rank,
        "mobility": robot.model.mobility(q),
        "unavailable": [],
    }
    result["round_trip"] = _demo_round_trip(robot, result["unavailable"])
    result["statics"] = _demo_statics(robot, result["unavailable"])
    with _progress(quiet, "simulating 0.5 s"):
        result["simulation"] = _demo_simulation(robot, result["unavailable"])
    result["html"] = None
    if not no_html:
        from ..viz import scenes as visualize

        path = html or Path(tempfile.gettempdir()) / "hexapod_pin_demo.html"
        forces = None if result["statics"] is None else result["statics"]["actuator_forces"]
        visualize.write_pose_html(path, robot, q, actuator_forces=forces,
                                  caption="hexapod_pin demo: home pose"
                                          + (", static actuator forces" if forces else ""))
        result["html"] = str(path)
    if as_json:
        _emit_json(result)
        return
    console.print(_demo_table(result))
    for feature in result["unavailable"]:
        console.print(f"[yellow]not available in this installation:[/] {feature}",
                      highlight=False)


def _demo_round_trip(robot: Hexapod, unavailable: list) -> dict:
    pose = robot.home_pose + np.array([0.01, -0.015, -0.02, 0.04, -0.03, 0.08])
    q = robot.inverse_kinematics(pose)
    out = {"pose": pose.tolist(), "q": q.tolist(), "fk_pose": None, "error": None}
    if not hasattr(robot, "forward_kinematics"):
        unavailable.append("Hexapod.forward_kinematics (the IK/FK round trip)")
        return out
    back = np.asarray(robot.forward_kinematics(q), dtype=float)
    out["fk_pose"] = back.tolist()
    out["error"] = float(np.max(np.abs(back - pose)))
    return out


def _demo_statics(robot: Hexapod, unavailable: list) -> dict | None:
    if not hasattr(robot, "static_forces"):
        unavailable.append("Hexapod.static_forces (statics)")
        return None
    tau = _actuator_forces_of(robot.static_forces(robot.home_pose))
    return {"pose": robot.home_pose.tolist(), "actuator_forces": tau.tolist()}


def _actuator_forces_of(result) -> np.ndarray:
    return np.asarray(getattr(result, "actuator_forces", result), dtype=float).reshape(6)


def _demo_simulation(robot: Hexapod, unavailable: list) -> dict | None:
    try:
        traj = run_simulation(robot, duration=0.5, dt=1e-3, controller="computed-torque",
                              radius=0.01, period=0.5)
    except FeatureUnavailableError as exc:
        unavailable.append(f"{exc.feature} (simulation)")
        return None
    return {"controller": "computed-torque", "duration_s": float(traj.times[-1]),
            "samples": len(traj.times), "status": str(traj.status),
            "max_closure_residual_m": float(np.max(np.abs(traj.closure_residual))),
            "max_tracking_error_m": _tracking_error(traj),
            "max_abs_actuator_force_n": float(np.max(np.abs(traj.actuator_forces)))}


def _demo_table(result: dict) -> Table:
    table = Table(title="hexapod_pin demo")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    table.add_row("home pose (x, y, z) (m)", _fmt(result["home_pose"][:3], ".6f"))
    table.add_row("home pose (roll, pitch, yaw) (rad)", _fmt(result["home_pose"][3:], ".3f"))
    table.add_row("carriages q (m)", _fmt(result["home_q"], "+.3f"))
    table.add_row("closure rows / rank", f"{result['closure_rows']} / {result['constraint_rank']}")
    table.add_row("mobility of the closed chain", str(result["mobility"]))
    table.add_row("max closure residual (m)", f"{result['closure_residual_max_abs_m']:.2e}")
    trip = result["round_trip"]
    table.add_row("IK of a tilted pose: q (m)", _fmt(trip["q"], "+.4f"))
    table.add_row("FK(IK(pose)) - pose, max abs",
                  "n/a" if trip["error"] is None else f"{trip['error']:.2e}")
    statics = result["statics"]
    table.add_row("static actuator forces at home (N)",
                  "n/a" if statics is None else _fmt(statics["actuator_forces"], "+.3f"))
    sim = result["simulation"]
    if sim is None:
        table.add_row("0.5 s simulation (computed torque, 1 cm circle)", "n/a")
    else:
        table.add_row("0.5 s simulation (computed torque, 1 cm circle): max tracking error (m)",
                      f"{sim['max_tracking_error_m']:.2e}")
        table.add_row("  max closure residual (m) / status",
                      f"{sim['max_closure_residual_m']:.1e} / {sim['status']}")
    table.add_row("HTML of the home pose", result["html"] or "not written")
    return table


# -- kinematics -------------------------------------------------------------------------------
@app.command(context_settings=NUMBERS)
@_guard
def ik(pose: Values = None,
       branch: Annotated[str | None, typer.Option(
           help="six signs choosing each carriage's root, e.g. -+-+-+ (default: home)")] = None,
       no_limits: Annotated[bool, typer.Option("--no-limits",
                                               help="do not check strokes / gaps")] = False,
       degrees: Degrees = False, as_json: AsJson = False,
       geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Carriage positions q (m) for a platform pose: x y z roll pitch yaw."""
    robot = _robot(geometry, set_)
    p = _pose_in(pose, degrees)
    signs = _branch(branch)
    q = robot.inverse_kinematics(p, branch=signs, check_limits=not no_limits)
    if as_json:
        _emit_json({"pose": _pose_out(p, degrees), "q": q,
                    "branch": None if signs is None else signs})
        return
    console.print(_carriage_table("inverse kinematics", {"q (m)": q}))


def _branch(text: str | None):
    """Six root signs from ``-+-+-+`` or ``-1,1,-1,1,-1,1``."""
    if text is None:
        return None
    compact = text.replace(" ", "")
    tokens = compact.split(",") if "," in compact else list(compact)
    values = {"+": 1.0, "-": -1.0, "1": 1.0, "+1": 1.0, "-1": -1.0}
    if len(tokens) != 6 or any(t not in values for t in tokens):
        raise InputError("branch", text, "expected six signs, e.g. -+-+-+ or -1,1,-1,1,-1,1")
    return np.array([values[t] for t in tokens])


@app.command(context_settings=NUMBERS)
@_guard
def fk(q: Values = None,
       guess: Annotated[str | None, typer.Option(
           help="starting pose 'x,y,z,roll,pitch,yaw' (default home)")] = None,
       degrees: Degrees = False, as_json: AsJson = False,
       geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Platform pose for carriage positions q0..q5 (m) (Newton from a guess)."""
    robot = _robot(geometry, set_)
    carriages = parse_numbers(q, 6, "q", "q0 .. q5")
    start = None if guess is None else _pose_in([guess], degrees, "guess")
    pose = np.asarray(_need(robot, "forward_kinematics")(carriages, guess=start), dtype=float)
    if as_json:
        _emit_json({"q": carriages, "pose": _pose_out(pose, degrees)})
        return
    console.print(_pose_table("forward kinematics", [pose], degrees))


@app.command(context_settings=NUMBERS)
@_guard
def modes(q: Values = None,
          html: Annotated[Path | None, typer.Option(help="also write an HTML view")] = None,
          layout: Annotated[str, typer.Option(help="grid, row or sequence (HTML)")] = "grid",
          degrees: Degrees = False, as_json: AsJson = False, quiet: Quiet = False,
          geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Every assembly mode (platform pose) for carriage positions q0..q5 (m); default home q."""
    quiet = quiet or as_json
    robot = _robot(geometry, set_)
    carriages = robot.home_q if not q else parse_numbers(q, 6, "q", "q0 .. q5")
    with _progress(quiet, "solving the assembly modes"):
        poses = [np.asarray(p, dtype=float)
                 for p in _need(robot, "assembly_modes")(carriages)]
    if html is not None and poses:
        from ..viz import scenes as visualize

        with _progress(quiet, "writing HTML"):
            qs = visualize.hexapod_configurations(robot, poses, [carriages] * len(poses))
            labels = [f"z = {p[2]:+.3f} m" for p in poses]
            visualize.write_modes_html(html, robot, qs, layout=layout, labels=labels,
                                       caption=f"{len(poses)} assembly modes")
        _note(quiet, f"wrote {html}")
    if as_json:
        _emit_json({"q": carriages, "modes": [_pose_out(p, degrees) for p in poses],
                    "html": html})
        return
    console.print(_pose_table(f"{len(poses)} assembly modes", poses, degrees))


@app.command(context_settings=NUMBERS)
@_guard
def jacobian(pose: Values = None, degrees: Degrees = False, as_json: AsJson = False,
             geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Workspace Jacobian J (qdot = J twist, twist = (v, w) in world axes) at a pose."""
    robot = _robot(geometry, set_)
    p = _pose_in(pose, degrees) if pose else robot.home_pose
    with np.errstate(divide="ignore", invalid="ignore"):
        jac = robot.jacobian(p)
    if not np.all(np.isfinite(jac)):
        raise CommandError("J is infinite at this pose: a leg is perpendicular to its rail "
                           "(type I singularity)")
    sv = np.linalg.svd(jac, compute_uv=False)
    payload = {"pose": _pose_out(p, degrees), "jacobian": jac, "singular_values": sv,
               "condition_number": float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf}
    if hasattr(robot, "singularity"):
        payload["singularity"] = _plain(robot.singularity(p))
    if as_json:
        _emit_json(payload)
        return
    table = Table(title="workspace Jacobian J: qdot = J (v, w)")
    table.add_column("carriage", justify="right")
    for name in ("vx", "vy", "vz", "wx", "wy", "wz"):
        table.add_column(name, justify="right")
    for i, row in enumerate(jac):
        table.add_row(str(i), *(f"{v:+.4f}" for v in row))
    console.print(table)
    console.print(f"singular values: {_fmt(sv, '.4g')}; condition number "
                  f"{payload['condition_number']:.4g}", highlight=False)
    for key, value in (payload.get("singularity") or {}).items():
        console.print(f"singularity.{key}: {value}", highlight=False)


def _plain(obj):
    """A dataclass / array / scalar as JSON-friendly values (floats and lists)."""
    if dataclasses.is_dataclass(obj):
        return {f.name: _plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return obj.item()
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    return obj


# -- dynamics ---------------------------------------------------------------------------------
@app.command(context_settings=NUMBERS)
@_guard
def statics(pose: Values = None,
            wrench: Annotated[str | None, typer.Option(
                help="wrench on the platform 'fx,fy,fz,mx,my,mz' (N, N m, world axes)")] = None,
            degrees: Degrees = False, as_json: AsJson = False,
            geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Actuator forces (N) holding the platform at rest at a pose (default home)."""
    robot = _robot(geometry, set_)
    p = _pose_in(pose, degrees) if pose else robot.home_pose
    w = None if wrench is None else parse_numbers([wrench], 6, "wrench", "fx fy fz mx my mz")
    tau = _actuator_forces_of(_need(robot, "static_forces")(p, wrench=w))
    if as_json:
        _emit_json({"pose": _pose_out(p, degrees), "wrench": w, "actuator_forces": tau})
        return
    console.print(_carriage_table("static actuator forces (+ along the rail direction u_k)",
                                  {"tau (N)": tau}))


@app.command("id")
@_guard
def inverse_dynamics(motion_file: Annotated[Path, typer.Argument(
                         help="motion file (.csv / .json; format: see above)")],
                     out: Annotated[Path | None, typer.Option(
                         help="write the motion with the forces (.csv / .json)")] = None,
                     method: Annotated[str, typer.Option(help="qp or kkt")] = "qp",
                     as_json: AsJson = False, quiet: Quiet = False,
                     geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Inverse dynamics along a motion file: actuator forces (N) at every sample.

    Motion file, CSV: a header row, then one row per sample; columns `t` (s), `x, y, z`
    (m), `roll, pitch, yaw` (rad), optional `vx, vy, vz, wx, wy, wz` (twist, world axes),
    `ax, ay, az, alphax, alphay, alphaz` (its derivative), `fx, fy, fz, mx, my, mz`
    (wrench on the platform, N, N m), `q0..q5`, `tau0..tau5`, `residual`. JSON: keys
    `t`, `pose` (N x 6), optional `twist`, `twist_dot`, `wrench`, `q`, `actuator_forces`,
    `closure_residual`. A missing twist is computed from the poses by finite differences.
    """
    quiet = quiet or as_json
    robot = _robot(geometry, set_)
    motion = read_motion(motion_file)
    with _progress(quiet, "inverse dynamics", total=len(motion.t)) as advance:
        tau, _ = inverse_dynamics_along(robot, motion, method, advance)
    twists, dots = motion_rates(motion)
    if out is not None:
        write_motion(out, dataclasses.replace(motion, twists=twists, twist_dots=dots,
                                              actuator_forces=tau))
        _note(quiet, f"wrote {out}")
    peak = np.argmax(np.abs(tau), axis=0)
    if as_json:
        _emit_json({"t": motion.t, "actuator_forces": tau,
                    "max_abs_actuator_forces": np.max(np.abs(tau), axis=0),
                    "out": out})
        return
    console.print(_carriage_table(
        f"inverse dynamics over {len(motion.t)} samples, {motion.t[-1] - motion.t[0]:g} s",
        {"max |tau| (N)": np.max(np.abs(tau), axis=0),
         "at t (s)": motion.t[peak], "mean tau (N)": tau.mean(axis=0)}))


# -- simulation -------------------------------------------------------------------------------
DEFAULT_DT = {"pid": 2.5e-4, "computed-torque": 1e-3, "none": 1e-3}


def run_simulation(robot: Hexapod, duration: float, dt: float | None, controller: str,
                   radius: float, period: float, progress: Callable | None = None):
    """Simulate the hexapod tracking a horizontal circle of the platform about home.

    The reference is ``home + radius (cos(2 pi t / T), sin(2 pi t / T), 0)``
    (``hexapod_pin.simulate.CircleTrajectory``; home itself when ``radius`` is 0),
    tracked by the joint-space PID with the Quanser gains (``"pid"``; default step
    0.25 ms, below its discrete stability limit), by computed-torque control
    (``"computed-torque"``, 1 ms), or not at all (``"none"``: no actuator force, the
    platform starts at rest at home and falls).

    Returns:
        ``hexapod_pin.simulate.Trajectory``.

    Raises:
        FeatureUnavailableError: :mod:`hexapod_pin.simulate` is not installed.
        InputError: bad numbers or controller name.
    """
    if controller not in DEFAULT_DT:
        raise InputError("controller", controller, "expected pid, computed-torque or none")
    dt = DEFAULT_DT[controller] if dt is None else float(dt)
    if not (np.isfinite(duration) and duration > 0 and np.isfinite(dt) and 0 < dt <= duration):
        raise InputError("dt", dt, f"need 0 < dt <= duration (duration {duration})")
    if not (np.isfinite(radius) and radius >= 0 and np.isfinite(period) and period > 0):
        raise InputError("radius", radius, "need radius >= 0 (m) and period > 0 (s)")
    try:
        from ..hexapod import simulation as sim
        entry = sim.simulate
    except (ImportError, AttributeError):
        raise FeatureUnavailableError("hexapod_pin.simulate.simulate") from None
    if controller == "none":
        return entry(robot, duration, dt, pose0=robot.home_pose, twist0=np.zeros(6),
                     progress=progress)
    if radius > 0:
        reference = sim.CircleTrajectory(robot.home_pose, radius, period)
    else:
        rest = sim.PlatformReference(robot.home_pose, np.zeros(6), np.zeros(6))
        reference = lambda t: rest
    make = sim.PIDController if controller == "pid" else sim.ComputedTorqueController
    return entry(robot, duration, dt, controller=make(robot, reference), reference=reference,
                 progress=progress)


def _tracking_error(traj) -> float | None:
    """Max distance (m) between the platform origin and its reference, if recorded."""
    ref = np.asarray(getattr(traj, "reference_poses", np.empty((0, 6))), dtype=float)
    poses = np.asarray(traj.poses, dtype=float)
    if ref.shape != poses.shape or ref.size == 0:
        return None
    return float(np.max(np.linalg.norm(poses[:, :3] - ref[:, :3], axis=1)))


@app.command()
@_guard
def simulate(duration: Annotated[float, typer.Option(help="simulated time (s)")] = 2.0,
             dt: Annotated[float | None, typer.Option(
                 help="time step (s); default 0.25 ms for pid, 1 ms otherwise",
                 show_default=False)] = None,
             controller: Annotated[str, typer.Option(
                 help="pid (Quanser gains), computed-torque, or none (no actuator force)")
             ] = "pid",
             radius: Annotated[float, typer.Option(
                 help="radius of the reference circle of the platform about home (m)")] = 0.02,
             period: Annotated[float, typer.Option(help="period of the circle (s)")] = 2.0,
             out: Annotated[Path | None, typer.Option(
                 help="write the trajectory (.csv / .json motion file)")] = None,
             html: Annotated[Path | None, typer.Option(
                 help="write an animated HTML view")] = None,
             plot: Annotated[Path | None, typer.Option(
                 help="write a figure (.png / .svg) of q, forces, residual")] = None,
             as_json: AsJson = False, quiet: Quiet = False,
             geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Simulate the closed-loop dynamics tracking a circle of the platform about home."""
    quiet = quiet or as_json
    robot = _robot(geometry, set_)
    for target, suffixes in ((out, (".csv", ".json")), (html, (".html", ".htm")),
                             (plot, plotting_suffixes())):
        if target is not None and target.suffix.lower() not in suffixes:
            raise InputError("output", str(target), f"expected one of {', '.join(suffixes)}")
    steps = round(duration / (dt or DEFAULT_DT.get(controller, 1e-3)))
    with _progress(quiet, f"simulating {duration:g} s", total=max(steps, 1)) as advance:
        done = [0]

        def progress(step: int, total: int) -> None:
            advance(step - done[0])
            done[0] = step

        traj = run_simulation(robot, duration, dt, controller, radius, period, progress)
    motion = _motion_of(traj)
    if out is not None:
        write_motion(out, motion)
        _note(quiet, f"wrote {out}")
    if html is not None:
        from ..viz import scenes as visualize

        with _progress(quiet, "writing HTML"):
            visualize.write_simulation_html(
                html, robot, traj,
                caption=f"simulation: {controller} control, circle r = {radius:g} m, "
                        f"{motion.t[-1]:g} s ({traj.status})")
        _note(quiet, f"wrote {html}")
    if plot is not None:
        from ..viz import plotting

        plotting.plot_simulation(traj, path=plot, title=f"simulation, {controller} control")
        _note(quiet, f"wrote {plot}")
    summary = {"status": str(traj.status), "message": str(getattr(traj, "message", "")),
               "duration_s": float(motion.t[-1] - motion.t[0]), "samples": len(motion.t),
               "wall_time_s": float(getattr(traj, "wall_time", float("nan"))),
               "max_tracking_error_m": _tracking_error(traj),
               "max_abs_actuator_force_n": float(np.max(np.abs(motion.actuator_forces))),
               "max_closure_residual_m": float(np.max(motion.closure_residual)),
               "out": out, "html": html, "plot": plot}
    if as_json:
        _emit_json(summary)
        return
    table = Table(title=f"simulation: {controller} control, circle r = {radius:g} m")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    for key, value in summary.items():
        if value not in (None, ""):
            table.add_row(key, f"{value:.4g}" if isinstance(value, float) else str(value))
    console.print(table)
    if traj.status != "completed":
        raise typer.Exit(code=1)


def plotting_suffixes() -> tuple[str, ...]:
    """Suffixes the figures can be saved with."""
    return (".png", ".svg", ".pdf")


def _motion_of(traj) -> Motion:
    q = getattr(traj, "q", None)
    q = None if q is None or np.shape(q)[-1] != 6 else np.asarray(q, dtype=float)
    res = getattr(traj, "closure_residual", None)
    if res is not None:
        res = np.asarray(res, dtype=float)
        res = np.max(np.abs(res), axis=1) if res.ndim == 2 else np.abs(res)
    twists = getattr(traj, "twists", None)
    tau = getattr(traj, "actuator_forces", None)
    return Motion(np.asarray(traj.times, dtype=float), np.asarray(traj.poses, dtype=float),
                  twists=None if twists is None else np.asarray(twists, dtype=float),
                  q=q, actuator_forces=None if tau is None else np.asarray(tau, dtype=float),
                  closure_residual=res)


# -- view and plot ----------------------------------------------------------------------------
@app.command(context_settings=NUMBERS)
@_guard
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
         degrees: Degrees = False, as_json: AsJson = False, quiet: Quiet = False,
         geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Write a self-contained HTML view (meshcat): a pose (default home), the pose of
    carriage positions, all assembly modes, or an animated motion."""
    from ..viz import scenes as visualize

    quiet = quiet or as_json
    robot = _robot(geometry, set_)
    if out.suffix.lower() not in (".html", ".htm"):
        raise InputError("out", str(out), "the view is an .html file")
    carriages = carriages or all_modes
    if sum([trajectory is not None, circle is not None, bool(values) or carriages]) > 1:
        raise InputError("view", values, "give one of: values, --trajectory, --circle")
    kind, detail = "pose", {}
    if trajectory is not None or circle is not None:
        motion = read_motion(trajectory) if trajectory is not None else circle_motion(
            robot, circle, period)
        kind = "trajectory"
        tau = closures = None
        if forces:
            tau = motion.actuator_forces
            if tau is None:
                with _progress(quiet, "inverse dynamics", total=len(motion.t)) as advance:
                    tau, closures = inverse_dynamics_along(robot, motion, advance=advance)
                if not np.all(np.isfinite(closures)):
                    closures = None
        with _progress(quiet, "writing HTML"):
            visualize.write_hexapod_trajectory_html(
                out, robot, motion.t, motion.poses, carriages=motion.q, actuator_forces=tau,
                closure_forces=closures, fps=fps,
                caption=f"{trajectory or f'circle r = {circle:g} m'}, "
                        f"{motion.t[-1] - motion.t[0]:g} s")
        detail = {"samples": len(motion.t), "duration_s": float(motion.t[-1] - motion.t[0])}
    elif all_modes:
        q = robot.home_q if not values else parse_numbers(values, 6, "q", "q0 .. q5")
        with _progress(quiet, "solving the assembly modes"):
            poses = [np.asarray(p, dtype=float) for p in _need(robot, "assembly_modes")(q)]
            qs = visualize.hexapod_configurations(robot, poses, [q] * len(poses))
        visualize.write_modes_html(out, robot, qs, layout=layout,
                                   labels=[f"z = {p[2]:+.3f} m" for p in poses],
                                   caption=f"{len(poses)} assembly modes")
        kind, detail = "modes", {"modes": [_pose_out(p, degrees) for p in poses]}
    else:
        if carriages:
            q = parse_numbers(values, 6, "q", "q0 .. q5")
            pose = np.asarray(_need(robot, "forward_kinematics")(q), dtype=float)
        else:
            pose = _pose_in(values, degrees) if values else robot.home_pose
            q = robot.inverse_kinematics(pose, check_limits=False)
        tau = closures = None
        if forces:
            tau, closures = _static_overlay(robot, pose)
        (q_tree,) = visualize.hexapod_configurations(robot, pose, q)
        visualize.write_pose_html(out, robot, q_tree, actuator_forces=tau,
                                  closure_forces=closures,
                                  caption=_pose_caption(pose, tau is not None))
        detail = {"pose": _pose_out(pose, degrees), "q": q}
    _note(quiet, f"wrote {out}")
    if as_json:
        _emit_json({"html": out, "kind": kind, **detail})


def _static_overlay(robot, pose):
    if hasattr(robot, "inverse_dynamics"):
        result = robot.inverse_dynamics(pose, np.zeros(6), np.zeros(6))
        return _actuator_forces_of(result), np.asarray(result.closure_forces, dtype=float)
    return _actuator_forces_of(_need(robot, "static_forces")(pose)), None


def _pose_caption(pose, with_forces: bool) -> str:
    text = "pose " + _fmt(pose, "+.3f")
    return text + (" | arrows: actuator forces (magenta), closure forces (teal)"
                   if with_forces else "")


@app.command()
@_guard
def plot(kind: Annotated[str, typer.Argument(
             help="trajectory | residual | conditioning | workspace")],
         motion_file: Annotated[Path | None, typer.Argument(
             help="motion file (trajectory, residual; conditioning: its poses)")] = None,
         out: Annotated[Path, typer.Option("--out", "-o", help=".png / .svg / .pdf")] = Path(
             "hexapod.png"),
         z: Annotated[float | None, typer.Option(help="workspace: slice height (m)")] = None,
         rpy: Annotated[str | None, typer.Option(
             help="workspace: orientation 'roll,pitch,yaw'")] = None,
         half_width: Annotated[float | None, typer.Option(
             help="workspace: half width of the square (m)")] = None,
         resolution: Annotated[int, typer.Option(help="workspace: samples per side")] = 61,
         forces: Annotated[bool, typer.Option(
             "--forces", help="trajectory: compute actuator forces by inverse dynamics "
                              "when the file has none")] = False,
         degrees: Degrees = False, as_json: AsJson = False, quiet: Quiet = False,
         geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Write a figure: carriage positions / forces along a motion, closure residual,
    conditioning of J along a motion (default: a vertical sweep), a workspace slice."""
    from ..viz import plotting

    quiet = quiet or as_json
    robot = _robot(geometry, set_)
    kinds = ("trajectory", "residual", "conditioning", "workspace")
    if kind not in kinds:
        raise InputError("kind", kind, f"expected one of {', '.join(kinds)}")
    if kind in ("trajectory", "residual") and motion_file is None:
        raise InputError("motion_file", None, f"plot {kind} needs a motion file")
    if kind == "trajectory":
        motion = read_motion(motion_file)
        q = motion.q if motion.q is not None else np.array(
            [robot.inverse_kinematics(p, check_limits=False) for p in motion.poses])
        tau = motion.actuator_forces
        if tau is None and forces:
            with _progress(quiet, "inverse dynamics", total=len(motion.t)) as advance:
                tau, _ = inverse_dynamics_along(robot, motion, advance=advance)
        plotting.plot_trajectory(motion.t, q, tau, path=out, title=str(motion_file))
    elif kind == "residual":
        motion = read_motion(motion_file)
        if motion.closure_residual is None:
            raise InputError("motion_file", str(motion_file), "has no closure residual "
                                                              "(column 'residual')")
        plotting.plot_closure_residual(motion.t, motion.closure_residual, path=out)
    elif kind == "conditioning":
        if motion_file is not None:
            motion = read_motion(motion_file)
            plotting.plot_conditioning(robot, motion.poses, motion.t, path=out,
                                       s_label="time (s)")
        else:
            zs = np.linspace(0.3 * robot.geometry.home_height,
                             1.2 * robot.geometry.home_height, 200)
            poses = np.tile(robot.home_pose, (len(zs), 1))
            poses[:, 2] = zs
            plotting.plot_conditioning(robot, poses, zs, path=out, s_label="height z (m)")
    else:
        orientation = (0.0, 0.0, 0.0) if rpy is None else parse_numbers(
            [rpy], 3, "rpy", "roll pitch yaw")
        if degrees:
            orientation = np.radians(orientation)
        with _progress(quiet, "sampling the workspace slice", total=resolution) as advance:
            ws = plotting.workspace_slice(robot, z=z, orientation=orientation,
                                          half_width=half_width, resolution=resolution,
                                          progress=lambda done, total: advance())
        plotting.plot_workspace_slice(ws, path=out)
    _note(quiet, f"wrote {out}")
    if as_json:
        _emit_json({"figure": out, "kind": kind})


def main() -> None:  # pragma: no cover - console entry point
    """Run the command line (``hexapod-pin``)."""
    app(prog_name="hexapod-pin")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

"""Matplotlib figures of a robot's workspace: ``cond(J)`` along a path, slices over two pose
axes (reachability, strokes, ``cond(J)``), force capability, design sweeps.

Every quantity plotted comes from the library, never from a formula written here:
reachability, strokes and the condition number from
:func:`hexapod_pin.core.workspace_maps.evaluate` (any robot of the shared API: the hexapod,
the planar 3-PRR, a :class:`~hexapod_pin.core.robot.ClosedLoopRobot`), the coarse framing
pass from ``robot.inverse_kinematics_batch``, the hexapod's force capability from
:func:`hexapod_pin.hexapod.workspace.force_capability`, sweeps from
:func:`hexapod_pin.core.sweeps.design_sweep`. The condition number is the one the
library reports everywhere, labelled :data:`CONDITION_LABEL`: ``sigma_max / sigma_min``
of the workspace Jacobian ``J`` (``actuator velocities = J @ twist``) with its columns in
m/s and rad/s as ``robot.jacobian`` returns it (no characteristic length).

matplotlib is optional (the ``plot`` extra); see :mod:`hexapod_pin.viz.plotting` for how
figures are made and saved. Poses in the robot's pose axes (``robot.pose_axes``); lengths
in m, angles in rad (titles in degrees).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..core import workspace_maps
from ..core.checks import as_array
from ..core.robot_api import parallel_robot
from ..errors import InputError
from ..hexapod import workspace
from .plotting import checked_series, figure_class, finish_figure

CONDITION_LABEL = "condition number cond(J), J unscaled (m and rad columns)"
"""What every figure and command calls the condition number: that of
:func:`hexapod_pin.core.workspace_maps.evaluate` and ``robot.singularity`` (one definition,
:mod:`hexapod_pin.core.measures`)."""

#: the angular pose components (rad; the others are lengths, m)
ANGLES = ("roll", "pitch", "yaw")


# -- conditioning along a path -----------------------------------------------------------------
@dataclass(frozen=True)
class Conditioning:
    """Conditioning of the workspace Jacobian along a path of poses, as
    :func:`hexapod_pin.core.workspace_maps.evaluate` reports it.

    ``condition_number`` is :data:`CONDITION_LABEL`: ``sigma_max / sigma_min`` of ``J``
    (``actuator velocities = J @ twist``) as ``robot.jacobian`` returns it, columns in
    m/s and rad/s, no characteristic length; the number ``robot.singularity`` and
    ``workspace_maps.evaluate`` report.

    Attributes:
        s: path parameter (N,) (as given, or the sample index).
        condition_number: (N,) ``cond(J)`` where ``ok``; ``inf`` elsewhere (out of
            reach, beyond a stroke limit, or at a singularity).
        inverse_condition: (N,) ``1 / condition_number`` in [0, 1]: a distance-like
            measure, 0 at a (type II) singularity and where not ``ok``.
        sigma_min: (N,) smallest singular value of ``J`` where ``ok`` (0 elsewhere).
        reachable: (N,) every chain reaches the platform.
        within_stroke: (N,) the actuators respect their position limits.
        ok: (N,) reachable, within the strokes, and regular (no singularity below the
            robot's thresholds).
    """

    s: np.ndarray
    condition_number: np.ndarray
    inverse_condition: np.ndarray
    sigma_min: np.ndarray
    reachable: np.ndarray
    within_stroke: np.ndarray
    ok: np.ndarray


def conditioning(robot: Any, poses: ArrayLike, s: ArrayLike | None = None) -> Conditioning:
    """Condition number of a robot's workspace Jacobian along poses (N, dim).

    Args:
        robot: any robot of the shared API (:class:`hexapod_pin.Hexapod`,
            :class:`hexapod_pin.Planar3PRR`, a :class:`hexapod_pin.ClosedLoopRobot`).
        poses: (N, dim) poses in the robot's pose axes (m, rad), home branch.
        s: path parameter (N,); default ``0..N-1``.

    Raises:
        InputError: bad shapes, NaN / inf.
        ArgumentTypeError: ``robot`` is not a parallel robot.
    """
    poses = as_array(poses, (_robot(robot).pose_dim,), "poses", batch=True)
    s = np.arange(len(poses), dtype=float) if s is None else checked_series(s, "s", len(poses))
    m = workspace_maps.evaluate(robot, poses, singularity=False, statics=False)
    return Conditioning(s, m.condition_number, workspace_maps.dexterity(m), m.sigma_min,
                        m.reachable, m.within_stroke, m.ok)


def plot_conditioning(robot: Any, poses: ArrayLike, s: ArrayLike | None = None, *,
                      path: str | os.PathLike | None = None, s_label: str = "path parameter",
                      title: str = "") -> Any:
    """``cond(J)`` and its inverse along a path of poses (see :func:`conditioning`).

    Samples out of reach are shaded dark grey, those beyond a stroke limit light grey
    (no condition number is reported there).

    Args:
        robot: any robot of the shared API.
        poses: (N, dim) poses (m, rad).
        s: path parameter (N,) of the x axis; default ``0..N-1``.
        path: where to save the figure (optional; .png, .svg, .pdf).
        s_label: the x-axis label.
        title: the title (default: what the shading means).

    Returns:
        the ``matplotlib.figure.Figure``.

    Raises:
        InputError: bad shapes, NaN / inf, a bad ``path``.
        MissingDependencyError: matplotlib is not installed.
    """
    cond = conditioning(robot, poses, s)
    fig = figure_class()(figsize=(7.5, 5.0))
    top, bottom = fig.subplots(2, 1, sharex=True)
    finite = np.isfinite(cond.condition_number)
    top.semilogy(cond.s[finite], cond.condition_number[finite], color="#7570b3")
    top.set_ylabel(CONDITION_LABEL, fontsize="small")
    bottom.plot(cond.s, cond.inverse_condition, color="#d95f02")
    bottom.set_ylabel("1 / cond(J)")
    bottom.set_ylim(bottom=0)
    bottom.set_xlabel(s_label)
    stroke = cond.reachable & ~cond.within_stroke
    for ax in (top, bottom):
        ax.grid(True, which="both", alpha=0.3)
        for mask, shade in ((~cond.reachable, "0.7"), (stroke, "0.88")):
            for lo, hi in _runs(mask, cond.s):
                ax.axvspan(lo, hi, color=shade)
    top.set_title(title or "workspace Jacobian J (dark grey: out of reach, "
                           "light grey: beyond a stroke limit)", fontsize="medium")
    return finish_figure(fig, path)


def _runs(mask: np.ndarray, s: np.ndarray) -> list:
    """(start, end) of the runs of True in mask, in units of s."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    return [(s[a], s[min(b, len(s)) - 1]) for a, b in zip(edges[::2], edges[1::2])]


_robot = parallel_robot


def axis_unit(axis: str) -> str:
    """The unit of a pose component: ``"rad"`` for roll, pitch, yaw, ``"m"`` otherwise."""
    return "rad" if axis in ANGLES else "m"


def reach_scale(robot: Any, axis: str) -> float:
    """How far from its centre a slice or sweep of ``axis`` first looks (m or rad): pi for
    an angle; for a length the geometry's ``rail_radius`` (the hexapod, the planar 3-PRR),
    else its ``characteristic_length`` (a loaded robot), else 1 m."""
    if axis in ANGLES:
        return float(np.pi)
    g = robot.geometry
    return float(getattr(g, "rail_radius", None) or getattr(g, "characteristic_length", None)
                 or 1.0)


def slice_axes(robot: Any, axes: Sequence[str] | str | None = None) -> tuple[str, str]:
    """The two pose axes of a workspace slice of ``robot``: ``axes`` checked (a pair, or
    ``"a,b"``), or by default its first two position axes (``("x", "y")`` for the
    hexapod), else its first two pose axes.

    Raises:
        InputError: not two distinct pose axes of the robot, or a robot of one pose axis.
    """
    own = tuple(robot.pose_axes)
    if axes is None:
        linear = [a for a in own if a not in ANGLES]
        picked = tuple(linear[:2] if len(linear) >= 2 else own[:2])
        if len(picked) < 2:
            raise InputError("axes", own, "a workspace slice needs two pose axes; the "
                             f"robot has one ({own[0]})")
    else:
        picked = tuple(a.strip() for a in axes.split(",")) if isinstance(axes, str) \
            else tuple(axes)
    if len(picked) != 2 or picked[0] == picked[1] or any(a not in own for a in picked):
        raise InputError("axes", axes, f"expected two distinct pose axes of the robot {own}")
    return picked[0], picked[1]


# -- workspace slice -----------------------------------------------------------------------------
#: status codes of :class:`WorkspaceSlice`
REACHABLE, OUT_OF_REACH, STROKE_LIMIT = 0, 1, 2


@dataclass(frozen=True)
class WorkspaceSlice:
    """Reachability of a slice of poses: a grid over two pose axes, the other components
    fixed.

    Attributes:
        x: grid coordinates (nx,) along the first slice axis (``axes[0]``; the platform
            origin's x for the hexapod's default slice) (m or rad).
        y: grid coordinates (ny,) along the second slice axis (``axes[1]``) (m or rad).
        z: the z component of the slice's centre pose (m), 0 when z is not a pose axis.
        orientation: (roll, pitch, yaw) of the centre pose (rad; 0 for the angles that
            are not pose axes).
        status: (ny, nx) ints: ``REACHABLE`` (0), ``OUT_OF_REACH`` (1: a chain cannot
            reach the platform), ``STROKE_LIMIT`` (2: reachable, but an actuator leaves
            its position limits, e.g. two carriages of a rail of the hexapod come closer
            than ``carriage_min_gap``).
        condition_number: (ny, nx) ``cond(J)`` of
            :func:`hexapod_pin.core.workspace_maps.evaluate` (:data:`CONDITION_LABEL`)
            where status is 0 (``inf`` at a singularity), NaN elsewhere.
        axes: the two pose axes of the grid.
        center: the centre pose (dim,) in the robot's pose axes: the fixed components
            and the grid's centre (None: the hexapod's ``(0, 0, z, orientation)``).
    """

    x: np.ndarray
    y: np.ndarray
    z: float
    orientation: np.ndarray
    status: np.ndarray
    condition_number: np.ndarray
    axes: tuple[str, str] = ("x", "y")
    pose_axes: tuple[str, ...] = ("x", "y", "z", *ANGLES)
    center: np.ndarray | None = None

    @property
    def reachable_fraction(self) -> float:
        """Share of the grid that is reachable within the strokes."""
        return float(np.mean(self.status == REACHABLE))


def _center(robot: Any, z: float | None,
            orientation: ArrayLike | None, center: ArrayLike | None) -> np.ndarray:
    """The slice's centre pose (dim,): ``center`` (default home), then ``z`` and the
    angles of ``orientation`` where they are pose axes."""
    own = tuple(robot.pose_axes)
    mid = np.array(robot.home_pose if center is None
                   else as_array(center, (robot.pose_dim,), "center"), dtype=float)
    if z is not None:
        if "z" not in own:
            raise InputError("z", z, f"z is not a pose axis of the robot {own}")
        height = float(z)
        if not np.isfinite(height):
            raise InputError("z", z, "must be finite")
        mid[own.index("z")] = height
    if orientation is not None:
        rpy = as_array(orientation, (3,), "orientation")
        for axis, value in zip(ANGLES, rpy):
            if axis in own:
                mid[own.index(axis)] = value
            elif value != 0.0:
                raise InputError("orientation", orientation, f"{axis} is not a pose axis "
                                 f"of the robot {own}: give 0")
    return mid


def _half_widths(robot: Any, axes: tuple[str, str], mid: np.ndarray,
                 half_width: float | Sequence[float] | np.ndarray | None) -> np.ndarray:
    """The half sides (2,) of the slice: ``half_width`` checked, or the coarse framing."""
    if half_width is None:
        return _auto_half_widths(robot, axes, mid)
    given = np.ravel(np.asarray(half_width, dtype=object))
    width = as_array(np.repeat(given, 2) if given.size == 1 else given, (2,), "half_width")
    if not np.all(width > 0):
        raise InputError("half_width", half_width, "must be finite and > 0 (m, rad)")
    return np.array(width, dtype=float)


def workspace_slice(robot: Any, z: float | None = None,
                    orientation: Sequence[float] | np.ndarray | None = None,
                    half_width: float | Sequence[float] | np.ndarray | None = None,
                    resolution: int = 61,
                    *, axes: Sequence[str] | str | None = None,
                    center: ArrayLike | None = None) -> WorkspaceSlice:
    """Sample the reachable poses on a grid over two pose axes (home branch).

    The hexapod's default is the horizontal slice of platform positions ``x, y`` at the
    home height, level; another robot's, the slice over its first two position axes
    through its home pose.

    Args:
        robot: any robot of the shared API (:class:`hexapod_pin.Hexapod`,
            :class:`hexapod_pin.Planar3PRR`, a :class:`hexapod_pin.ClosedLoopRobot`).
        z: the z component of the centre pose (m); default the centre's (the home
            height).
        orientation: (roll, pitch, yaw) of the centre pose (rad): the angles that are
            pose axes of the robot are set, the others must be 0; default the centre's.
        half_width: half sides of the grid around the centre (m or rad), one value for
            both axes or one per axis; default: framing the reachable region found by a
            coarse 25 x 25 pass over +- :func:`reach_scale`.
        resolution: samples per side (>= 2).
        axes: the two pose axes of the grid (a pair or ``"a,b"``); default
            :func:`slice_axes`.
        center: the pose (dim,) the slice passes through (its fixed components and the
            grid's centre); default the home pose.

    Returns:
        :class:`WorkspaceSlice`.

    Raises:
        InputError: bad numbers or axes, ``z`` or a non-zero angle the robot's pose has
            not, or no reachable pose on the slice (nothing to draw).
        ArgumentTypeError: ``robot`` is not a parallel robot.
    """
    pair = slice_axes(_robot(robot), axes)
    mid = _center(robot, z, orientation, center)
    if isinstance(resolution, bool) or int(resolution) != resolution or resolution < 2:
        raise InputError("resolution", resolution, "must be an integer >= 2")
    widths = _half_widths(robot, pair, mid, half_width)
    own = tuple(robot.pose_axes)
    cols = [own.index(a) for a in pair]
    xs, ys = (mid[c] + np.linspace(-w, w, int(resolution)) for c, w in zip(cols, widths))
    m = workspace_maps.evaluate(robot, _grid_poses(mid, cols, xs, ys), singularity=False,
                                statics=False)
    if not np.any(m.reachable):
        where = ", ".join(f"{a} = {v:.4g}" for a, v in zip(own, mid))
        raise InputError("z" if z is not None else "center", z if z is not None else mid,
                         f"no platform position of this slice ({pair[0]}, {pair[1]}) is "
                         f"reachable (centre pose {where}; half widths "
                         f"{np.round(widths, 4).tolist()}; home pose "
                         f"{np.round(robot.home_pose, 4).tolist()})")
    status = _status(m.reachable, m.within_stroke).reshape(len(ys), len(xs))
    cond = np.where(status == REACHABLE, m.condition_number.reshape(status.shape), np.nan)
    full = dict(zip(own, mid))
    rpy = np.array([full.get(a, 0.0) for a in ANGLES])
    return WorkspaceSlice(xs, ys, float(full.get("z", 0.0)), rpy, status, cond, pair, own, mid)


def _grid_poses(mid: np.ndarray, cols: list[int], xs: np.ndarray,
                ys: np.ndarray) -> np.ndarray:
    """Poses (len(xs) len(ys), dim) on the grid ``xs x ys`` of components ``cols`` through
    ``mid``, the second axis varying slowest (``reshape(ny, nx)`` gives rows of constant
    second coordinate)."""
    gx, gy = np.meshgrid(xs, ys)
    poses = np.tile(mid, (gx.size, 1))
    poses[:, cols[0]], poses[:, cols[1]] = gx.ravel(), gy.ravel()
    return poses


def _status(reachable: np.ndarray, within_stroke: np.ndarray) -> np.ndarray:
    return np.where(~reachable, OUT_OF_REACH, np.where(within_stroke, REACHABLE, STROKE_LIMIT))


def _auto_half_widths(robot: Any, axes: tuple[str, str], mid: np.ndarray) -> np.ndarray:
    """Half sides framing the reachable region: a coarse pass over +- the reach scale
    (two axes of one kind, both lengths or both angles, share the larger: a square)."""
    own = tuple(robot.pose_axes)
    cols = [own.index(a) for a in axes]
    scales = np.array([reach_scale(robot, a) for a in axes])
    offsets = [np.linspace(-r, r, 25) for r in scales]
    ik = robot.inverse_kinematics_batch(_grid_poses(mid, cols, mid[cols[0]] + offsets[0],
                                                    mid[cols[1]] + offsets[1]))
    iy, ix = np.nonzero(np.asarray(ik.ok).reshape(25, 25))
    if len(ix) == 0:
        return scales
    step = np.array([o[1] - o[0] for o in offsets])
    reach = np.array([np.abs(offsets[0][ix]).max(), np.abs(offsets[1][iy]).max()]) + step
    widths = np.minimum(1.25 * reach, scales)
    if (axes[0] in ANGLES) == (axes[1] in ANGLES):
        widths[:] = widths.max()
    return widths


def _slice_title(ws: WorkspaceSlice) -> str:
    share = f"reachable {100 * ws.reachable_fraction:.0f} % (grey: stroke limit, white: out " \
            "of reach)"
    if ws.axes == ("x", "y") and len(ws.pose_axes) == 6:
        r, p, yw = np.degrees(ws.orientation) + 0.0        # no "-0"
        return (f"workspace slice z = {ws.z:.3f} m, rpy = ({r:.0f}, {p:.0f}, {yw:.0f}) deg\n"
                + share)
    center = ws.center if ws.center is not None else np.zeros(len(ws.pose_axes))
    fixed = [f"{a} = {np.degrees(v) + 0.0:.0f} deg" if a in ANGLES else f"{a} = {v:.3f} m"
             for a, v in zip(ws.pose_axes, center) if a not in ws.axes]
    return f"workspace slice ({ws.axes[0]}, {ws.axes[1]})" + \
        (f" at {', '.join(fixed)}" if fixed else "") + "\n" + share


def plot_workspace_slice(robot_or_slice: Any, *, path: str | os.PathLike | None = None,
                         title: str = "", **slice_options: Any) -> Any:
    """Map of a workspace slice: ``log10 cond(J)`` where reachable, grey where a stroke
    limit is hit, white where a chain cannot reach.

    Args:
        robot_or_slice: a :class:`WorkspaceSlice`, or a robot (then ``slice_options``
            go to :func:`workspace_slice`).
        path: where to save the figure (optional; .png, .svg, .pdf).
        title: the title (default: the slice and its reachable share).
        **slice_options: arguments of :func:`workspace_slice`.

    Returns:
        the ``matplotlib.figure.Figure``.

    Raises:
        InputError: see :func:`workspace_slice`, or a bad ``path``.
        MissingDependencyError: matplotlib is not installed.
    """
    ws = robot_or_slice if isinstance(robot_or_slice, WorkspaceSlice) \
        else workspace_slice(robot_or_slice, **slice_options)
    fig = figure_class()(figsize=(6.4, 5.4))
    ax = fig.subplots()
    extent = (ws.x[0], ws.x[-1], ws.y[0], ws.y[-1])
    limits = np.where(ws.status == STROKE_LIMIT, 1.0, np.nan)
    ax.imshow(limits, origin="lower", extent=extent, cmap="Greys", vmin=0, vmax=3,
              interpolation="nearest", aspect="auto")
    shown = np.log10(np.where(np.isfinite(ws.condition_number), ws.condition_number, np.nan))
    image = ax.imshow(shown, origin="lower", extent=extent, cmap="viridis",
                      interpolation="nearest", aspect="auto")
    bar = fig.colorbar(image, ax=ax)
    bar.set_label(f"log10 {CONDITION_LABEL}", fontsize="small")
    ax.set_xlabel(f"{ws.axes[0]} ({axis_unit(ws.axes[0])})")
    ax.set_ylabel(f"{ws.axes[1]} ({axis_unit(ws.axes[1])})")
    if axis_unit(ws.axes[0]) == axis_unit(ws.axes[1]):
        ax.set_aspect("equal")
    ax.set_title(title or _slice_title(ws), fontsize="medium")
    return finish_figure(fig, path)


# -- force capability of the hexapod, design sweeps of any robot ------------------------------
def plot_force_capability_slice(robot: Any, direction: ArrayLike | None = None, *,
                                z: float | None = None,
                                orientation: Sequence[float] = (0, 0, 0),
                                half_width: float = 0.12, resolution: int = 81,
                                path: str | os.PathLike | None = None,
                                title: str = "", label: str = "payload (kg)") -> Any:
    """Map of the largest payload the actuators hold, over a horizontal slice of positions.

    Args:
        robot: a :class:`hexapod_pin.Hexapod`.
        direction: payload wrench per unit (6,), world axes about the platform
            origin; default a 1 kg mass at the origin, ``(0, 0, -g, 0, 0, 0)``.
        z: slice height (m), default the home height.
        orientation: (roll, pitch, yaw) (rad).
        half_width: the square ``[-w, w]^2`` around the z axis (m).
        resolution: samples per side (>= 2).
        label: colour-bar label (the unit of the scale along ``direction``).

    Returns:
        the figure (saved to ``path`` when given). White where the pose is outside
        the workspace or gravity alone saturates an actuator.
    """
    g = robot.geometry
    z = g.home_height if z is None else float(z)
    if int(resolution) != resolution or resolution < 2:
        raise InputError("resolution", resolution, "must be an integer >= 2")
    direction = [0.0, 0.0, -g.gravity, 0.0, 0.0, 0.0] if direction is None else direction
    poses = workspace.constant_orientation_grid([0.0, 0.0, z], [half_width, half_width, 1.0],
                                                (int(resolution), int(resolution), 1),
                                                orientation)
    cap = workspace.force_capability(robot, poses, direction)
    usable = cap.ok & cap.feasible_without_payload
    image = np.where(usable, cap.scale, np.nan).reshape(int(resolution), int(resolution)).T
    fig = figure_class()(figsize=(6.4, 5.4))
    ax = fig.subplots()
    shown = ax.imshow(image, origin="lower", extent=(-half_width, half_width, -half_width,
                                                     half_width),
                      cmap="magma", interpolation="nearest")
    fig.colorbar(shown, ax=ax).set_label(label)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal")
    r, p, yw = np.degrees(as_array(orientation, (3,), "orientation"))
    ax.set_title(title or f"force capability at z = {z:.3f} m, "
                          f"rpy = ({r:.0f}, {p:.0f}, {yw:.0f}) deg")
    return finish_figure(fig, path)


#: units of the geometry fields and of the design-sweep summary columns (axis labels)
COLUMN_UNITS = {
    "rail_radius": "m", "platform_radius": "m", "leg_length": "m", "carriage_home": "m",
    "rail_half_length": "m", "carriage_min_gap": "m", "carriage_mass": "kg", "leg_mass": "kg",
    "platform_mass": "kg", "gravity": "m/s²", "max_actuator_force": "N", "home_height": "m",
    "reachable_volume": "m³", "reachable_volume_se": "m³", "well_conditioned_volume": "m³",
    "well_conditioned_volume_se": "m³", "median_condition": "cond(J), J unscaled",
    "median_payload_kg": "kg", "min_payload_kg": "kg",
}


def column_label(name: str, units: Mapping[str, str] | None = None) -> str:
    """An axis label: the column's name with its unit (``units``, else
    :data:`COLUMN_UNITS`)."""
    unit = (units or {}).get(name) or COLUMN_UNITS.get(name)
    return f"{name} ({unit})" if unit else name


def plot_design_sweep(table: Any, x: str, y: str, value: str = "reachable_volume", *,
                      path: str | os.PathLike | None = None,
                      title: str = "", units: Mapping[str, str] | None = None) -> Any:
    """Heat map of one summary column of a design sweep over two swept parameters.

    Args:
        table: the DataFrame of :func:`hexapod_pin.core.sweeps.design_sweep` (or of the
            hexapod's :func:`hexapod_pin.hexapod.sweeps.design_sweep`).
        x: a swept parameter column (its values and those of ``y`` form the grid).
        y: another swept parameter column.
        value: the summary column coloured (invalid designs are left white).
        path: where to save the figure (optional; .png, .svg, .pdf).
        title: the title (default: the column shown).
        units: column -> unit of the axis labels, over :data:`COLUMN_UNITS` (the
            hexapod's: volumes in m³; e.g. ``{"reachable_volume": "m²"}`` for a sweep
            over x and y).

    Returns:
        the ``matplotlib.figure.Figure``.

    Raises:
        InputError: a column that is not in the table, or duplicate (x, y) cells
            (sweep more parameters than two: filter the table first).
    """
    for column in (x, y, value):
        if column not in table.columns:
            raise InputError("column", column, f"not in the table ({list(table.columns)})")
    xs = np.unique(table[x].to_numpy(dtype=float))
    ys = np.unique(table[y].to_numpy(dtype=float))
    if len(table) != len(xs) * len(ys) or table.duplicated([x, y]).any():
        raise InputError("table", f"{len(table)} rows",
                         f"expected one row per ({x}, {y}) cell: filter the other parameters")
    grid = np.full((len(ys), len(xs)), np.nan)
    col = table[value].astype("Float64").to_numpy(dtype=float, na_value=np.nan)
    ix = np.searchsorted(xs, table[x].to_numpy(dtype=float))
    iy = np.searchsorted(ys, table[y].to_numpy(dtype=float))
    grid[iy, ix] = col
    fig = figure_class()(figsize=(6.4, 5.0))
    ax = fig.subplots()
    shown = ax.pcolormesh(_edges(xs), _edges(ys), grid, cmap="viridis", shading="flat")
    fig.colorbar(shown, ax=ax).set_label(column_label(value, units))
    for (j, i), cell in np.ndenumerate(grid):
        if np.isfinite(cell):
            red, green, blue, _ = shown.cmap(shown.norm(cell))
            light = 0.299 * red + 0.587 * green + 0.114 * blue > 0.5
            ax.text(xs[i], ys[j], f"{cell:.3g}", ha="center", va="center", fontsize=7,
                    color="black" if light else "white")
    ax.set_xlabel(column_label(x, units))
    ax.set_ylabel(column_label(y, units))
    ax.set_title(title or f"design sweep: {value}")
    return finish_figure(fig, path)


def _edges(centres: np.ndarray) -> np.ndarray:
    """Cell edges around sorted centres (one cell of width 1 around a single centre)."""
    if len(centres) == 1:
        return np.array([centres[0] - 0.5, centres[0] + 0.5])
    mid = (centres[1:] + centres[:-1]) / 2
    return np.concatenate([[2 * centres[0] - mid[0]], mid, [2 * centres[-1] - mid[-1]]])

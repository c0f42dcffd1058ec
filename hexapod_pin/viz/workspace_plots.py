"""Matplotlib figures of the hexapod's workspace: ``cond(J)`` along a path, horizontal
slices (reachability, strokes, ``cond(J)``), force capability, design sweeps.

Every quantity plotted comes from the library, never from a formula written here:
reachability, strokes and the condition number from
:func:`hexapod_pin.hexapod.workspace.evaluate`, the coarse framing pass from
``robot.inverse_kinematics_batch``, force capability from
:func:`hexapod_pin.hexapod.workspace.force_capability`, sweeps from
:func:`hexapod_pin.hexapod.sweeps.design_sweep`. The condition number is the one the
library reports everywhere, labelled :data:`CONDITION_LABEL`: ``sigma_max / sigma_min``
of the workspace Jacobian ``J`` (``qdot = J @ twist``) with its columns in m/s and
rad/s as :meth:`hexapod_pin.hexapod.kinematics.HexapodKinematics.jacobian` returns it (no
characteristic length).

matplotlib is optional (the ``plot`` extra); see :mod:`hexapod_pin.viz.plotting` for how
figures are made and saved. Lengths in m, angles in rad (titles in degrees).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..core.checks import as_array
from ..errors import InputError
from ..hexapod import workspace
from .plotting import checked_series, figure_class, finish_figure

CONDITION_LABEL = "condition number cond(J), J unscaled (m and rad columns)"
"""What every figure and command calls the condition number: that of
``hexapod_pin.hexapod.workspace.evaluate`` and ``Hexapod.singularity`` (one definition,
:mod:`hexapod_pin.core.measures`)."""


# -- conditioning along a path -----------------------------------------------------------------
@dataclass(frozen=True)
class Conditioning:
    """Conditioning of the workspace Jacobian along a path of poses, as
    :func:`hexapod_pin.hexapod.workspace.evaluate` reports it.

    ``condition_number`` is :data:`CONDITION_LABEL`: ``sigma_max / sigma_min`` of ``J``
    (``qdot = J @ twist``) as
    :meth:`hexapod_pin.hexapod.kinematics.HexapodKinematics.jacobian` returns it, columns in
    m/s and rad/s, no characteristic length; the number
    :meth:`hexapod_pin.hexapod.kinematics.HexapodKinematics.singularity` and
    ``workspace.evaluate`` report.

    Attributes:
        s: path parameter (N,) (as given, or the sample index).
        condition_number: (N,) ``cond(J)`` where ``ok``; ``inf`` elsewhere (out of
            reach, beyond a stroke limit, or a leg perpendicular to its rail).
        inverse_condition: (N,) ``1 / condition_number`` in [0, 1]: a distance-like
            measure, 0 at a (type II) singularity and where not ``ok``.
        sigma_min: (N,) smallest singular value of ``J`` where ``ok`` (0 elsewhere).
        reachable: (N,) every leg reaches its platform point.
        within_stroke: (N,) the carriages respect their strokes and gap.
        ok: (N,) reachable, within the strokes, and no leg perpendicular to its rail.
    """

    s: np.ndarray
    condition_number: np.ndarray
    inverse_condition: np.ndarray
    sigma_min: np.ndarray
    reachable: np.ndarray
    within_stroke: np.ndarray
    ok: np.ndarray


def conditioning(robot: Any, poses: ArrayLike, s: ArrayLike | None = None) -> Conditioning:
    """Condition number of the hexapod's workspace Jacobian along poses (N, 6).

    Args:
        robot: a :class:`hexapod_pin.Hexapod`.
        poses: (N, 6) poses (m, rad), home branch.
        s: path parameter (N,); default ``0..N-1``.

    Raises:
        InputError: bad shapes.
    """
    poses = as_array(poses, (6,), "poses", batch=True)
    s = np.arange(len(poses), dtype=float) if s is None else checked_series(s, "s", len(poses))
    m = workspace.evaluate(robot, poses, singularity=False, statics=False)
    with np.errstate(divide="ignore"):
        inverse = np.where(np.isfinite(m.condition_number), 1.0 / m.condition_number, 0.0)
    return Conditioning(s, m.condition_number, inverse, m.sigma_min, m.reachable,
                        m.within_stroke, m.ok)


def plot_conditioning(robot: Any, poses: ArrayLike, s: ArrayLike | None = None, *,
                      path: str | os.PathLike | None = None, s_label: str = "path parameter",
                      title: str = "") -> Any:
    """``cond(J)`` and its inverse along a path of poses (see :func:`conditioning`).

    Samples out of reach are shaded dark grey, those beyond a stroke limit light grey
    (no condition number is reported there).
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


# -- workspace slice -----------------------------------------------------------------------------
#: status codes of :class:`WorkspaceSlice`
REACHABLE, OUT_OF_REACH, STROKE_LIMIT = 0, 1, 2


@dataclass(frozen=True)
class WorkspaceSlice:
    """Reachability of a horizontal slice of platform positions at a fixed orientation.

    Attributes:
        x: grid coordinates (nx,) of the platform origin (m).
        y: grid coordinates (ny,) of the platform origin (m).
        z: the slice height (m).
        orientation: (roll, pitch, yaw) (rad).
        status: (ny, nx) ints: ``REACHABLE`` (0), ``OUT_OF_REACH`` (1: a leg cannot
            reach its platform point), ``STROKE_LIMIT`` (2: reachable, but a
            carriage leaves its stroke or two carriages of a rail come closer than
            ``carriage_min_gap``).
        condition_number: (ny, nx) ``cond(J)`` of
            :func:`hexapod_pin.hexapod.workspace.evaluate` (:data:`CONDITION_LABEL`)
            where status is 0 (``inf`` where a leg is perpendicular to its rail), NaN
            elsewhere.
    """

    x: np.ndarray
    y: np.ndarray
    z: float
    orientation: np.ndarray
    status: np.ndarray
    condition_number: np.ndarray

    @property
    def reachable_fraction(self) -> float:
        """Share of the grid that is reachable within the strokes."""
        return float(np.mean(self.status == REACHABLE))


def workspace_slice(robot: Any, z: float | None = None,
                    orientation: Sequence[float] | np.ndarray = (0, 0, 0),
                    half_width: float | None = None, resolution: int = 61) -> WorkspaceSlice:
    """Sample the reachable platform positions on a horizontal plane (home branch).

    Args:
        robot: a :class:`hexapod_pin.Hexapod`.
        z: height of the platform origin (m); default the home height.
        orientation: (roll, pitch, yaw) of the platform (rad).
        half_width: the square ``[-w, w]^2`` sampled (m); default: framing the
            reachable region found by a coarse 25 x 25 pass over the rail radius.
        resolution: samples per side (>= 2).

    Raises:
        InputError: bad numbers, or no reachable position on the slice (nothing to draw).
    """
    g = robot.geometry
    z = g.home_height if z is None else float(z)
    rpy = as_array(orientation, (3,), "orientation")
    if not np.isfinite(z):
        raise InputError("z", z, "must be finite")
    if int(resolution) != resolution or resolution < 2:
        raise InputError("resolution", resolution, "must be an integer >= 2")
    if half_width is None:
        width = _auto_half_width(robot, z, rpy)
    else:
        width = float(half_width)
        if not (np.isfinite(width) and width > 0):
            raise InputError("half_width", half_width, "must be finite and > 0 (m)")
    xs = np.linspace(-width, width, int(resolution))
    m = workspace.evaluate(robot, _slice_poses(xs, z, rpy), singularity=False, statics=False)
    status = _status(m.reachable, m.within_stroke).reshape(len(xs), len(xs))
    if not np.any(m.reachable):
        raise InputError("z", z, f"no platform position of this slice is reachable "
                                 f"(orientation {np.round(rpy, 4).tolist()} rad, square "
                                 f"half width {width:g} m; home height {g.home_height:.4g} m)")
    cond = np.where(status == REACHABLE, m.condition_number.reshape(status.shape), np.nan)
    return WorkspaceSlice(xs, xs.copy(), z, rpy, status, cond)


def _slice_poses(xs: np.ndarray, z: float, rpy: np.ndarray) -> np.ndarray:
    """Poses (len(xs)^2, 6) on the grid ``xs x xs`` at height z, y varying slowest (so
    that ``reshape(ny, nx)`` gives rows of constant y)."""
    gx, gy = np.meshgrid(xs, xs)
    n = gx.size
    return np.column_stack([gx.ravel(), gy.ravel(), np.full(n, z), np.tile(rpy, (n, 1))])


def _status(reachable: np.ndarray, within_stroke: np.ndarray) -> np.ndarray:
    return np.where(~reachable, OUT_OF_REACH, np.where(within_stroke, REACHABLE, STROKE_LIMIT))


def _auto_half_width(robot: Any, z: float, rpy: np.ndarray) -> float:
    """Half width framing the reachable region: a coarse pass over the rail radius."""
    g = robot.geometry
    coarse = np.linspace(-g.rail_radius, g.rail_radius, 25)
    ik = robot.inverse_kinematics_batch(_slice_poses(coarse, z, rpy))
    iy, ix = np.nonzero(ik.ok.reshape(len(coarse), len(coarse)))
    if len(ix) == 0:
        return g.rail_radius
    step = coarse[1] - coarse[0]
    reach = max(np.abs(coarse[ix]).max(), np.abs(coarse[iy]).max()) + step
    return float(min(1.25 * reach, g.rail_radius))


def plot_workspace_slice(robot_or_slice: Any, *, path: str | os.PathLike | None = None,
                         title: str = "", **slice_options: Any) -> Any:
    """Map of a workspace slice: ``log10 cond(J)`` where reachable, grey where a stroke
    limit is hit, white where a leg cannot reach.

    Args:
        robot_or_slice: a :class:`WorkspaceSlice`, or a hexapod (then
            ``slice_options`` go to :func:`workspace_slice`).
    """
    ws = robot_or_slice if isinstance(robot_or_slice, WorkspaceSlice) \
        else workspace_slice(robot_or_slice, **slice_options)
    fig = figure_class()(figsize=(6.4, 5.4))
    ax = fig.subplots()
    extent = (ws.x[0], ws.x[-1], ws.y[0], ws.y[-1])
    limits = np.where(ws.status == STROKE_LIMIT, 1.0, np.nan)
    ax.imshow(limits, origin="lower", extent=extent, cmap="Greys", vmin=0, vmax=3,
              interpolation="nearest")
    shown = np.log10(np.where(np.isfinite(ws.condition_number), ws.condition_number, np.nan))
    image = ax.imshow(shown, origin="lower", extent=extent, cmap="viridis",
                      interpolation="nearest")
    bar = fig.colorbar(image, ax=ax)
    bar.set_label(f"log10 {CONDITION_LABEL}", fontsize="small")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal")
    r, p, yw = np.degrees(ws.orientation)
    ax.set_title(title or f"workspace slice z = {ws.z:.3f} m, rpy = ({r:.0f}, {p:.0f}, "
                          f"{yw:.0f}) deg\nreachable {100 * ws.reachable_fraction:.0f} %"
                          " (grey: stroke limit, white: out of reach)", fontsize="medium")
    return finish_figure(fig, path)


# -- workspace analysis maps (hexapod_pin.hexapod.workspace, hexapod_pin.hexapod.sweeps) ------
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


def column_label(name: str) -> str:
    """An axis label: the column's name with its unit (:data:`COLUMN_UNITS`)."""
    unit = COLUMN_UNITS.get(name)
    return f"{name} ({unit})" if unit else name


def plot_design_sweep(table: Any, x: str, y: str, value: str = "reachable_volume", *,
                      path: str | os.PathLike | None = None,
                      title: str = "") -> Any:
    """Heat map of one summary column of a design sweep over two swept parameters.

    Args:
        table: the DataFrame of :func:`hexapod_pin.hexapod.sweeps.design_sweep`.
        x: a swept parameter column (its values and those of ``y`` form the grid).
        y: another swept parameter column.
        value: the summary column coloured (invalid designs are left white).

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
    fig.colorbar(shown, ax=ax).set_label(column_label(value))
    for (j, i), cell in np.ndenumerate(grid):
        if np.isfinite(cell):
            red, green, blue, _ = shown.cmap(shown.norm(cell))
            light = 0.299 * red + 0.587 * green + 0.114 * blue > 0.5
            ax.text(xs[i], ys[j], f"{cell:.3g}", ha="center", va="center", fontsize=7,
                    color="black" if light else "white")
    ax.set_xlabel(column_label(x))
    ax.set_ylabel(column_label(y))
    ax.set_title(title or f"design sweep: {value}")
    return finish_figure(fig, path)


def _edges(centres: np.ndarray) -> np.ndarray:
    """Cell edges around sorted centres (one cell of width 1 around a single centre)."""
    if len(centres) == 1:
        return np.array([centres[0] - 0.5, centres[0] + 0.5])
    mid = (centres[1:] + centres[:-1]) / 2
    return np.concatenate([[2 * centres[0] - mid[0]], mid, [2 * centres[-1] - mid[-1]]])

"""Matplotlib figures of the stiffness maps: the weakest translational and rotational
stiffness and the lowest natural frequency over a slice of one or two pose axes.

Every number plotted is that of :func:`hexapod_pin.core.stiffness_maps.stiffness_slice`
(any robot of the shared API): ``translational`` (N/m) and ``rotational`` (N m/rad), the
smallest eigenvalues of the symmetric blocks of ``K_x`` (the stiffness in the weakest
direction with the other kind of motion held), and the lowest frequency (Hz) of ``K_x phi =
omega^2 M_x phi`` under gravity. The shading follows the workspace slices of
:mod:`hexapod_pin.viz.workspace_plots`: white out of reach, light grey beyond a stroke
limit, dark grey at a singular pose, black where the preloaded pose is statically
unstable (no frequency; the stiffness panels show its negative values) or a route refused
it. matplotlib is optional (the ``plot`` extra; :mod:`hexapod_pin.viz.plotting`).
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from ..core import stiffness_maps as sm
from ..errors import ArgumentTypeError
from .plotting import figure_class, finish_figure
from .workspace_plots import axis_unit

#: the panels: attribute of the map (``lowest_frequency`` a property) -> colour-bar label
PANELS = {"translational": "smallest translational stiffness (N/m)",
          "rotational": "smallest rotational stiffness (N m/rad)",
          "lowest_frequency": "lowest natural frequency (Hz)"}
#: the grey level of each status without a value (white: out of reach)
SHADES = {sm.UNREACHABLE: 1.0, sm.STROKE: 0.85, sm.SINGULAR: 0.45, sm.UNSTABLE: 0.0,
          sm.FAILED: 0.0}
LEGEND = "white: out of reach, light grey: stroke limit, dark grey: singular, " \
         "black: unstable / failed"


def panels(ws: sm.StiffnessSlice) -> dict[str, np.ndarray]:
    """The values of each panel the robot has (N,) (a pose without angles has no
    rotational panel), NaN where the pose has none (status shaded instead)."""
    out = {}
    for name in PANELS:
        values = getattr(ws.map, name)
        if values is None:
            continue
        valid = ws.map.ok if name == "lowest_frequency" else ws.map.has_stiffness
        out[name] = np.where(valid, values, np.nan)
    return out


def _shading(ws: sm.StiffnessSlice, valid: np.ndarray) -> np.ndarray:
    """Grey levels (N,) of the poses without a value, NaN where there is one."""
    grey = np.full(valid.shape, np.nan)
    for code, level in SHADES.items():
        grey[(ws.map.status == code) & ~valid] = level
    return grey


def plot_stiffness_slice(ws: sm.StiffnessSlice, *, path: str | os.PathLike | None = None,
                         title: str = "") -> Any:
    """One panel per measure of a stiffness slice: images over two pose axes, curves over
    one.

    Args:
        ws: a :class:`~hexapod_pin.core.stiffness_maps.StiffnessSlice`.
        path: where to save the figure (optional; .png, .svg, .pdf).
        title: the figure's title (default: the actuator stiffness and the shading).

    Returns:
        the ``matplotlib.figure.Figure``.

    Raises:
        ArgumentTypeError: ``ws`` is not a stiffness slice.
        InputError: a bad ``path``.
        MissingDependencyError: matplotlib is not installed.
    """
    if not isinstance(ws, sm.StiffnessSlice):
        raise ArgumentTypeError("ws", ws, "expected a StiffnessSlice (hexapod_pin.core."
                                f"stiffness_maps.stiffness_slice), got {type(ws).__name__}")
    shown = panels(ws)
    if len(ws.axes) == 2:
        fig = figure_class()(figsize=(5.2 * len(shown), 4.8))
        axes = np.atleast_1d(fig.subplots(1, len(shown)))
        for ax, (name, values) in zip(axes, shown.items()):
            _image(fig, ax, ws, values, PANELS[name])
    else:
        fig = figure_class()(figsize=(7.0, 2.4 * len(shown) + 0.6))
        axes = np.atleast_1d(fig.subplots(len(shown), 1, sharex=True))
        for ax, (name, values) in zip(axes, shown.items()):
            _curve(ax, ws, values, PANELS[name])
        axes[-1].set_xlabel(f"{ws.axes[0]} ({axis_unit(ws.axes[0])})")
    k = ws.map.actuator_stiffness
    stiffness = f"{k[0]:.3g}" if np.all(k == k[0]) else f"{k.min():.3g} to {k.max():.3g}"
    fig.suptitle(title or f"actuator stiffness {stiffness} (N/m or N m/rad), under gravity\n"
                 + LEGEND, fontsize="medium")
    return finish_figure(fig, path)


def _image(fig: Any, ax: Any, ws: sm.StiffnessSlice, values: np.ndarray, label: str) -> None:
    xs, ys = ws.coordinates
    extent = (xs[0], xs[-1], ys[0], ys[-1])
    valid = np.isfinite(values)
    ax.imshow(ws.grid(_shading(ws, valid)), origin="lower", extent=extent, cmap="gray",
              vmin=0.0, vmax=1.0, interpolation="nearest", aspect="auto")
    image = ax.imshow(ws.grid(values), origin="lower", extent=extent, cmap="viridis",
                      interpolation="nearest", aspect="auto")
    fig.colorbar(image, ax=ax).set_label(label, fontsize="small")
    ax.set_xlabel(f"{ws.axes[0]} ({axis_unit(ws.axes[0])})")
    ax.set_ylabel(f"{ws.axes[1]} ({axis_unit(ws.axes[1])})")
    if axis_unit(ws.axes[0]) == axis_unit(ws.axes[1]):
        ax.set_aspect("equal")


def _curve(ax: Any, ws: sm.StiffnessSlice, values: np.ndarray, label: str) -> None:
    (xs,) = ws.coordinates
    ax.plot(xs, values, color="#7570b3")
    ax.set_ylabel(label, fontsize="small")
    ax.grid(True, alpha=0.3)
    grey = _shading(ws, np.isfinite(values))
    step = (xs[1] - xs[0]) / 2
    for x, level in zip(xs, grey):
        if np.isfinite(level) and level < 1.0:
            ax.axvspan(x - step, x + step, color=str(level), alpha=0.6, lw=0)

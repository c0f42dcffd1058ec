"""Matplotlib figures along a motion: actuator positions and forces, closure residual,
simulation results; and the figure helpers the other figure modules share.

matplotlib is optional (the ``plot`` extra: ``pip install "hexapod-pin[plot]"``) and
imported only when a figure is made. Figures are built with the object-oriented
API (``matplotlib.figure.Figure``), so no pyplot state or GUI backend is touched;
each function returns the figure and, given ``path``, saves it (PNG, SVG, PDF:
from the suffix). Workspace figures (conditioning, slices, force capability, design
sweeps): :mod:`hexapod_pin.viz.workspace_plots`.

Units: time s, the hexapod's carriage positions m and forces N (another robot's actuators:
the ``units`` given, m or rad, N or N m), residual m (point closures) / m, rad (welds).
Actuator order and sign conventions as everywhere in hexapod_pin (the hexapod: ``q_i``
along ``+u_k`` from the rail midpoint, ``tau_i`` the force on carriage i along ``+u_k``).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError, MissingDependencyError

#: colours of carriages 0..5 (rail k has a dark and a light shade)
CARRIAGE_COLORS = ("#d95f02", "#fdae61", "#1b9e77", "#66c2a5", "#7570b3", "#b3b0d9")
IMAGE_SUFFIXES = (".png", ".svg", ".pdf")


def figure_class() -> type:
    """``matplotlib.figure.Figure``.

    Raises:
        MissingDependencyError: matplotlib is not installed.
    """
    # imported here, not at the top: matplotlib is the optional ``plot`` extra, and a
    # heavy import that the rest of the library does not need
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise MissingDependencyError("matplotlib", "plot") from None
    return Figure


def save_figure(fig: Any, path: str | os.PathLike, dpi: int = 120) -> Path:
    """Save a figure; the format follows the suffix (.png, .svg, .pdf).

    Raises:
        InputError: another suffix, or a folder that does not exist.
    """
    path = Path(path)
    if path.suffix.lower() not in IMAGE_SUFFIXES:
        raise InputError("path", str(path), f"suffix must be one of {IMAGE_SUFFIXES}")
    if not path.parent.is_dir():
        raise InputError("path", str(path), "its folder does not exist")
    fig.savefig(path, dpi=dpi, metadata=_metadata(path))
    return path


def _metadata(path: Path) -> dict:
    # reproducible SVG/PDF files: no creation date
    return {"Date": None} if path.suffix.lower() in (".svg", ".pdf") else {}


def finish_figure(fig: Any, path: str | os.PathLike | None) -> Any:
    """Lay the figure out tightly, save it when ``path`` is given, return it."""
    fig.tight_layout()
    if path is not None:
        save_figure(fig, path)
    return fig


def checked_series(value: Any, name: str, n: int | None = None,
                   width: int | None = None) -> np.ndarray:
    """``value`` as a finite float array of shape (n,) (``width`` None) or (n, width)
    (``width`` -1: any number of columns; a 1-D value becomes one column).

    Raises:
        InputError: not numeric, another shape, empty, NaN / inf.
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(name, value, "not numeric") from None
    if arr.ndim == 1 and width is not None:
        arr = arr[:, None]
    ok = arr.ndim == (1 if width is None else 2)
    ok = ok and (n is None or arr.shape[0] == n) and (width is None or width == -1
                                                       or arr.shape[1] == width)
    if not ok or arr.shape[0] == 0:
        cols = "" if width is None else ", " + ("n" if width == -1 else str(width))
        raise InputError(name, value, f"expected shape ({n or 'N'}{cols}), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(name, value, "contains NaN or inf")
    return arr


# -- along a trajectory ----------------------------------------------------------------------
def plot_trajectory(times: ArrayLike, q: ArrayLike | None = None,
                    actuator_forces: ArrayLike | None = None, *,
                    path: str | os.PathLike | None = None, title: str = "",
                    actuator: str = "carriage", names: Sequence[str] | None = None,
                    units: tuple[str, str] = ("m", "N")) -> Any:
    """Actuator (carriage) positions and actuator forces against time.

    Args:
        times: (N,) s.
        q: actuator positions (N, n) (``units[0]``), or ``None``.
        actuator_forces: actuator forces (N, n) (``units[1]``), or ``None``.
        path: where to save the figure (optional).
        title: figure title.
        actuator: what an actuator is called in the labels (the hexapod's ``"carriage"``;
            e.g. ``"actuator"`` for another robot).
        names: the legend entry of each actuator (n,); default ``"<actuator> i"``.
        units: the units of the positions and of the forces in the labels (the
            hexapod's ``("m", "N")``; e.g. ``("rad", "N m")`` for revolute actuators).

    Returns:
        the ``matplotlib.figure.Figure`` (one axes per given quantity).

    Raises:
        InputError: mismatched shapes, NaN / inf, nothing to plot, names of another
            count.
        MissingDependencyError: matplotlib is not installed.
    """
    t = checked_series(times, "times")
    position, force = _labels(actuator, units)
    panels = [(name, checked_series(v, name, len(t), -1), label)
              for name, v, label in (("q", q, position),
                                     ("actuator_forces", actuator_forces, force))
              if v is not None]
    if not panels:
        raise InputError("q", None, "give q and/or actuator_forces")
    fig = figure_class()(figsize=(7.5, 2.6 * len(panels) + 0.6))
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    legend = _legend(actuator, names, panels[0][1].shape[1])
    for ax, (_, data, label) in zip(axes, panels):
        _actuator_lines(ax, t, data, legend)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].legend(ncol=3, fontsize="small")
    axes[-1].set_xlabel("time (s)")
    if title:
        fig.suptitle(title)
    return finish_figure(fig, path)


def _labels(actuator: str, units: tuple[str, str]) -> tuple[str, str]:
    """The axis labels of actuator positions and forces."""
    return f"{actuator} position q ({units[0]})", f"actuator force tau ({units[1]})"


def _legend(actuator: str, names: Sequence[str] | None, n: int) -> list[str]:
    """One legend entry per actuator (``names``, or ``"<actuator> i"``)."""
    if names is None:
        return [f"{actuator} {i}" for i in range(n)]
    if len(names) != n:
        raise InputError("names", list(names), f"expected {n} names, one per actuator")
    return [str(name) for name in names]


def _actuator_lines(ax: Any, t: np.ndarray, data: np.ndarray, legend: list[str]) -> None:
    for i in range(data.shape[1]):
        ax.plot(t, data[:, i], color=CARRIAGE_COLORS[i % 6],
                label=legend[i] if i < len(legend) else f"{i}")


def plot_closure_residual(times: ArrayLike, residual: ArrayLike, *,
                          path: str | os.PathLike | None = None, title: str = "") -> Any:
    """Max-abs closure residual against time, on a log scale.

    Args:
        times: (N,) s.
        residual: (N,) max-abs residuals, or (N, n_rows) residual vectors (their
            max-abs per sample is plotted), m (and rad for welds).

    Raises:
        InputError: mismatched shapes, NaN / inf.
    """
    t = checked_series(times, "times")
    res = np.asarray(residual, dtype=float)
    res = checked_series(res if res.ndim == 1 else np.max(np.abs(res), axis=1)
                  if res.ndim == 2 else res, "residual", len(t))
    fig = figure_class()(figsize=(7.5, 3.2))
    ax = fig.subplots()
    floor = np.finfo(float).tiny
    ax.semilogy(t, np.maximum(np.abs(res), floor), color="#1b9e77")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("max |closure residual| (m)")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(title or "closure residual")
    return finish_figure(fig, path)


def plot_simulation(trajectory: Any, *, path: str | os.PathLike | None = None,
                    title: str = "", actuator: str = "carriage",
                    names: Sequence[str] | None = None,
                    units: tuple[str, str] = ("m", "N")) -> Any:
    """Actuator (carriage) positions, actuator forces and closure residual of a simulation
    result.

    Reads ``times``, ``q``, ``actuator_forces`` and ``closure_residual`` from
    ``trajectory`` (``hexapod_pin.hexapod.simulation.Trajectory`` or any object with them;
    missing ones are left out).

    Args:
        trajectory: the result.
        path: where to save the figure (optional).
        title: figure title.
        actuator: what an actuator is called in the labels (see :func:`plot_trajectory`).
        names: the legend entry of each actuator; default ``"<actuator> i"``.
        units: the units of the positions and of the forces in the labels.

    Returns:
        the ``matplotlib.figure.Figure``.

    Raises:
        InputError: none of them present, or wrong shapes.
        MissingDependencyError: matplotlib is not installed.
    """
    t = getattr(trajectory, "times", None)
    if t is None:
        raise InputError("trajectory", trajectory, "has no attribute times")
    t = checked_series(t, "times")
    q = getattr(trajectory, "q", None)
    tau = getattr(trajectory, "actuator_forces", None)
    res = getattr(trajectory, "closure_residual", None)
    position, force = _labels(actuator, units)
    panels = []
    if q is not None:
        panels.append((position, checked_series(q, "q", len(t), -1), False))
    if tau is not None:
        panels.append((force, checked_series(tau, "actuator_forces", len(t), -1), False))
    if res is not None:
        res = np.asarray(res, dtype=float)
        res = np.max(np.abs(res), axis=1) if res.ndim == 2 else np.abs(res)
        panels.append(("max |closure residual| (m)",
                       checked_series(res, "closure_residual", len(t))[:, None], True))
    if not panels:
        raise InputError("trajectory", trajectory, "has none of q, actuator_forces, "
                                                   "closure_residual")
    fig = figure_class()(figsize=(7.5, 2.4 * len(panels) + 0.6))
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    legend = [] if panels[0][2] else _legend(actuator, names, panels[0][1].shape[1])
    for ax, (label, data, log) in zip(axes, panels):
        if log:
            ax.semilogy(t, np.maximum(data[:, 0], np.finfo(float).tiny), color="#1b9e77")
        else:
            _actuator_lines(ax, t, data, legend)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    if not panels[0][2]:
        axes[0].legend(ncol=3, fontsize="small")
    axes[-1].set_xlabel("time (s)")
    if title:
        fig.suptitle(title)
    return finish_figure(fig, path)

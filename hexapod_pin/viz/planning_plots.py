"""Figures of a time-optimal motion (:mod:`hexapod_pin.planning`): actuator forces (and
rates) against their limits along the path, and the phase plane ``(s, s_dot)``.

matplotlib is optional (the ``plot`` extra) and imported only when a figure is made
(:func:`hexapod_pin.viz.plotting.figure_class`); each function returns the figure and,
given ``path``, saves it (PNG, SVG, PDF by suffix).

Units: path parameter ``s`` in m (chord length, rotations weighted by the planner's
rotation length), path speed ``s_dot`` in m/s, forces N, actuator velocities m/s,
accelerations m/s^2; actuator order and signs as everywhere in hexapod_pin.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from ..planning.trajectory import TimedTrajectory
from .plotting import CARRIAGE_COLORS, figure_class, finish_figure


def plot_forces_against_limits(trajectory: TimedTrajectory, *,
                               path: str | os.PathLike[str] | None = None,
                               title: str = "") -> Any:
    """Actuator forces along the path parameter with their bounds (dashed), and the
    actuator velocities when they are limited.

    Args:
        trajectory: a :class:`hexapod_pin.planning.TimedTrajectory`.
        path: where to save the figure (optional).
        title: figure title.

    Returns:
        the ``matplotlib.figure.Figure``.

    Raises:
        MissingDependencyError: matplotlib is not installed.
    """
    bounds = trajectory.limits.per_actuator(trajectory.robot)
    panels = [("actuator force (N)", trajectory.actuator_forces, bounds["force"])]
    if np.any(np.isfinite(bounds["velocity"])):
        panels.append(("actuator velocity (m/s)", trajectory.actuator_velocities,
                       bounds["velocity"]))
    fig = figure_class()(figsize=(7.5, 2.8 * len(panels) + 0.6))
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    s = trajectory.s
    for ax, (label, values, bound) in zip(axes, panels):
        for i in range(values.shape[1]):
            color = CARRIAGE_COLORS[i % len(CARRIAGE_COLORS)]
            ax.plot(s, values[:, i], color=color, label=f"actuator {i}")
            if np.isfinite(bound[i]):
                ax.axhline(bound[i], color=color, ls="--", lw=0.8)
                ax.axhline(-bound[i], color=color, ls="--", lw=0.8)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].legend(ncol=3, fontsize="small")
    axes[-1].set_xlabel("path parameter s (m)")
    fig.suptitle(title or f"time-optimal motion, {trajectory.duration:.4g} s: "
                           "limits dashed")
    return finish_figure(fig, path)


def plot_phase_plane(trajectory: TimedTrajectory, *, path: str | os.PathLike[str] | None = None,
                     title: str = "") -> Any:
    """The phase plane ``(s, s_dot)``: the maximum-velocity curve, the upper boundary of
    the controllable sets and the chosen profile.

    Args:
        trajectory: a :class:`hexapod_pin.planning.TimedTrajectory`.
        path: where to save the figure (optional).
        title: figure title.

    Returns:
        the ``matplotlib.figure.Figure``.

    Raises:
        MissingDependencyError: matplotlib is not installed.
    """
    phase = trajectory.phase
    fig = figure_class()(figsize=(7.5, 4.2))
    ax = fig.subplots()
    top = 1.5 * float(np.max(phase.s_dot))
    mvc = np.sqrt(np.minimum(phase.max_velocity_curve, top ** 2))
    ax.plot(phase.s, mvc, color="0.4", lw=1.2, label="maximum-velocity curve")
    ax.plot(phase.s, np.sqrt(np.maximum(phase.controllable[:, 1], 0.0)), color="#7570b3",
            ls="--", lw=1.0, label="controllable set (upper bound)")
    ax.plot(phase.s, phase.s_dot, color="#d95f02", lw=1.8, label="time-optimal profile")
    ax.set_xlabel("path parameter s (m)")
    ax.set_ylabel("path speed ds/dt (m/s)")
    ax.set_ylim(0.0, top)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    fig.suptitle(title or "phase plane")
    return finish_figure(fig, path)

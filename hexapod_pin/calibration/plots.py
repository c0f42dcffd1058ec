"""Figures of a calibration: the distribution of the validation errors (nominal against
identified model) and the validation error against the number of measurement poses
(random against selected poses).

matplotlib is optional (the ``plot`` extra) and imported only when a figure is made
(:func:`hexapod_pin.viz.plotting.figure_class`); each function returns the figure and,
given ``path``, saves it (PNG, SVG, PDF by suffix). Units: errors in micrometres and
microradians on the axes.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..viz.plotting import figure_class, finish_figure
from .results import ValidationReport

MICRO = 1e6


def plot_validation_errors(report: ValidationReport, *, path: str | os.PathLike | None = None,
                           title: str = "") -> Any:
    """Histograms of the validation errors of the nominal and the identified model:
    actuator errors (um, every reading), target position errors (um) and, for poses,
    rotation errors (urad), on logarithmic bins.

    Args:
        report: :meth:`~hexapod_pin.calibration.results.CalibrationResult.validate`'s report.
        path: where to save the figure (optional).
        title: figure title.

    Returns:
        the ``matplotlib.figure.Figure``.

    Raises:
        MissingDependencyError: matplotlib is not installed.
    """
    panels = []
    if report.nominal.actuator_errors is not None:
        panels.append(("actuator error (um)", "actuator_errors"))
    panels.append(("position error (um)", "position_errors"))
    if report.nominal.rotation_errors is not None:
        panels.append(("rotation error (urad)", "rotation_errors"))
    fig = figure_class()(figsize=(3.6 * len(panels), 3.2))
    axes = fig.subplots(1, len(panels), squeeze=False)[0]
    for ax, (label, attr) in zip(axes, panels):
        values = {name: np.abs(np.ravel(getattr(errors, attr))) * MICRO
                  for name, errors in (("nominal", report.nominal),
                                       ("identified", report.identified))}
        finite = np.concatenate(list(values.values()))
        positive = finite[finite > 0.0]
        low = max(float(positive.min()) if positive.size else 1e-3, 1e-6)
        high = max(float(finite.max()), low * 10.0)
        bins = np.geomspace(low, high, 30)
        for name, vals in values.items():
            ax.hist(np.clip(vals, low, high), bins=bins, alpha=0.6, label=name)
        ax.set_xscale("log")
        ax.set_xlabel(label)
        ax.set_ylabel("count")
        ax.grid(True, alpha=0.3)
    axes[0].legend()
    fig.suptitle(title or "validation errors: nominal against identified model")
    return finish_figure(fig, path)


def plot_error_against_poses(counts: Sequence[int], curves: Mapping[str, Sequence[float]], *,
                             ylabel: str = "validation position error RMS (um)",
                             path: str | os.PathLike | None = None, title: str = "") -> Any:
    """Validation error against the number of measurement poses, one curve per way of
    choosing them (e.g. ``{"random": [...], "selected (O1)": [...]}``), in the units
    given (plotted as given, log scale).

    Raises:
        MissingDependencyError: matplotlib is not installed.
    """
    fig = figure_class()(figsize=(5.5, 3.6))
    ax = fig.subplots()
    for name, values in curves.items():
        ax.plot(list(counts), list(values), marker="o", label=name)
    ax.set_yscale("log")
    ax.set_xlabel("measurement poses")
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.suptitle(title or "validation error against the number of poses")
    return finish_figure(fig, path)

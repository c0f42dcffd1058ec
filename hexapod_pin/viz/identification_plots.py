"""Figures of a dynamic identification (:mod:`hexapod_pin.identification`): measured
against predicted actuator forces, and the estimated parameters with their error bars.

matplotlib is optional (the ``plot`` extra), as in :mod:`hexapod_pin.viz.plotting`; each
function returns the ``matplotlib.figure.Figure`` and, given ``path``, saves it. The
functions take arrays (not an identification result), so this module imports no
identification code.

Units: time s, forces N or N m (``units``); parameters in their own units (kg, kg m,
kg m^2, N s/m, N), shown relative to their nominal values where those are not zero.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from .plotting import CARRIAGE_COLORS, checked_series, figure_class, finish_figure


def plot_force_prediction(times: ArrayLike, measured: ArrayLike, predicted: ArrayLike, *,
                          path: str | os.PathLike | None = None, units: str = "N",
                          names: Sequence[str] | None = None, title: str = "") -> Any:
    """Measured (thin) and predicted (dashed) actuator forces against time, one axes per
    actuator, with the residual's rms in each title.

    Args:
        times: (N,) s.
        measured: (N, n_act) forces (``units``).
        predicted: (N, n_act) forces of the identified model.
        path: where to save the figure (optional: .png, .svg, .pdf).
        units: the forces' unit in the labels.
        names: one name per actuator (default ``"actuator i"``).
        title: figure title.

    Raises:
        InputError: mismatched shapes, NaN / inf, names of another count.
        MissingDependencyError: matplotlib is not installed.
    """
    t = checked_series(times, "times")
    meas = checked_series(measured, "measured", len(t), -1)
    pred = checked_series(predicted, "predicted", len(t), meas.shape[1])
    n_act = meas.shape[1]
    labels = [f"actuator {i}" for i in range(n_act)] if names is None else list(names)
    if len(labels) != n_act:
        raise InputError("names", names, f"expected {n_act} names, one per actuator")
    fig = figure_class()(figsize=(7.5, 1.6 * n_act + 0.8))
    axes = fig.subplots(n_act, 1, sharex=True, squeeze=False)[:, 0]
    for i, ax in enumerate(axes):
        color = CARRIAGE_COLORS[i % len(CARRIAGE_COLORS)]
        ax.plot(t, meas[:, i], color=color, lw=0.8, label="measured")
        ax.plot(t, pred[:, i], color="black", lw=1.0, ls="--", label="predicted")
        rms = float(np.sqrt(np.mean((meas[:, i] - pred[:, i]) ** 2)))
        ax.set_title(f"{labels[i]}: residual rms {rms:.3g} {units}", fontsize="small")
        ax.set_ylabel(f"force ({units})")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize="small")
    axes[-1].set_xlabel("time (s)")
    if title:
        fig.suptitle(title)
    return finish_figure(fig, path)


def plot_parameter_estimates(names: Sequence[str], values: ArrayLike, std_errors: ArrayLike,
                             nominal: ArrayLike | None = None, *,
                             path: str | os.PathLike | None = None, sigmas: float = 2.0,
                             title: str = "") -> Any:
    """The estimated parameters with ``+- sigmas`` standard-error bars, one row each;
    with ``nominal``, each divided by its nominal value where that is not zero (1: as
    nominal; the nominal values are marked) and in its own units elsewhere.

    Args:
        names: (r,) the parameters' names.
        values: (r,) the estimates.
        std_errors: (r,) their standard errors (>= 0).
        nominal: (r,) the nominal values, or None.
        path: where to save the figure (optional).
        sigmas: the error bars' half-width in standard errors (> 0).
        title: figure title.

    Raises:
        InputError: shapes that differ, NaN / inf, negative standard errors.
        MissingDependencyError: matplotlib is not installed.
    """
    labels = [str(n) for n in names]
    val = checked_series(values, "values", len(labels))
    err = checked_series(std_errors, "std_errors", len(labels))
    if np.any(err < 0):
        raise InputError("std_errors", std_errors, "must be >= 0")
    if not (np.isfinite(sigmas) and sigmas > 0):
        raise InputError("sigmas", sigmas, "must be > 0")
    scale = np.ones(len(labels))
    if nominal is not None:
        nom = checked_series(nominal, "nominal", len(labels))
        scale = np.where(nom != 0.0, np.abs(nom), 1.0)
    rows = np.arange(len(labels))
    fig = figure_class()(figsize=(7.0, 0.22 * len(labels) + 1.2))
    ax = fig.subplots()
    ax.errorbar(val / scale, rows, xerr=sigmas * err / scale, fmt="o", ms=3, capsize=2,
                color="#1b9e77", label=f"estimate +- {sigmas:g} std errors")
    if nominal is not None:
        ax.plot(nom / scale, rows, "x", color="#d95f02", label="nominal")
        ax.set_xlabel("value / |nominal| (own units where the nominal is 0)")
    else:
        ax.set_xlabel("value (own units)")
    ax.set_yticks(rows, labels, fontsize="x-small")
    ax.invert_yaxis()
    ax.grid(True, axis="x", alpha=0.3)
    ax.legend(fontsize="small")
    if title:
        ax.set_title(title)
    return finish_figure(fig, path)

"""Identification figures: the lines and error bars hold the data given; bad input is
refused naming the argument; the command line's --figure writes both files."""

from __future__ import annotations

import numpy as np
import pytest

from hexapod_pin.errors import InputError
from hexapod_pin.viz.identification_plots import plot_force_prediction, plot_parameter_estimates

pytest.importorskip("matplotlib", reason="matplotlib (the plot extra) is not installed")


def test_force_prediction_holds_the_data(tmp_path):
    t = np.linspace(0, 1, 50)
    measured = np.column_stack([np.sin(t), np.cos(t)])
    predicted = measured + 0.1
    fig = plot_force_prediction(t, measured, predicted, path=tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 0
    lines = fig.axes[1].get_lines()
    assert np.allclose(lines[0].get_ydata(), measured[:, 1])
    assert np.allclose(lines[1].get_ydata(), predicted[:, 1])
    assert "0.1 N" in fig.axes[0].get_title()                      # the residual's rms
    with pytest.raises(InputError, match="predicted"):
        plot_force_prediction(t, measured, predicted[:, :1])
    with pytest.raises(InputError, match="names"):
        plot_force_prediction(t, measured, predicted, names=["a"])


def test_parameter_estimates_relative_to_nominal(tmp_path):
    fig = plot_parameter_estimates(["m", "fv"], [2.0, 0.5], [0.1, 0.05], [4.0, 0.0],
                                   path=tmp_path / "p.svg", sigmas=2.0)
    assert (tmp_path / "p.svg").stat().st_size > 0
    points = fig.axes[0].get_lines()[0]
    assert np.allclose(points.get_xdata(), [0.5, 0.5])    # 2 / |4|, and 0.5 in own units
    with pytest.raises(InputError, match="std_errors"):
        plot_parameter_estimates(["m"], [1.0], [-1.0])
    with pytest.raises(InputError, match="values"):
        plot_parameter_estimates(["m", "n"], [1.0], [1.0, 1.0])

"""Figures: files written and non-trivial, plotted data equal to independently computed data."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import hexapod_pin as hp
from hexapod_pin.viz import plotting as pl
from hexapod_pin.viz import workspace_plots as wpl

pytest.importorskip("matplotlib", reason="matplotlib (the plot extra) is not installed")


def rpy_of(rot):
    yaw, pitch, roll = Rotation.from_matrix(rot).as_euler("ZYX")
    return np.array([roll, pitch, yaw])


def rot_of(rpy):
    return Rotation.from_euler("ZYX", [rpy[2], rpy[1], rpy[0]]).as_matrix()


def fd_jacobian(robot, pose, eps=1e-6):
    """qdot = J twist by central differences of inverse kinematics along world twists."""
    cols = []
    for j in range(6):
        twist = np.zeros(6)
        twist[j] = 1.0
        qs = []
        for sign in (1.0, -1.0):
            d = sign * eps * twist
            rot = Rotation.from_rotvec(d[3:]).as_matrix() @ rot_of(pose[3:])
            qs.append(robot.inverse_kinematics(np.r_[pose[:3] + d[:3], rpy_of(rot)],
                                               check_limits=False))
        cols.append((qs[0] - qs[1]) / (2 * eps))
    return np.array(cols).T


def rail_frames(g):
    a = np.pi / 2 + 2 * np.pi / 3 * np.arange(3)
    mids = g.rail_radius * np.stack([np.cos(a), np.sin(a), np.zeros(3)], 1)
    dirs = np.stack([-np.sin(a), np.cos(a), np.zeros(3)], 1)
    pts = g.platform_radius * np.stack([np.cos(a), np.sin(a), np.zeros(3)], 1)
    return mids, dirs, pts


def png_pixels(path):
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB"), dtype=float)


def test_trajectory_figure_holds_the_data_and_is_written(tmp_path):
    t = np.linspace(0, 1, 50)
    q = 0.1 * np.sin(np.outer(t, np.arange(1, 7)))
    tau = np.cos(np.outer(t, np.arange(1, 7)))
    fig = pl.plot_trajectory(t, q, tau, path=tmp_path / "traj.png", title="test")
    top, bottom = fig.axes
    for i in range(6):
        np.testing.assert_array_equal(top.lines[i].get_ydata(), q[:, i])
        np.testing.assert_array_equal(bottom.lines[i].get_ydata(), tau[:, i])
    assert "N" in bottom.get_ylabel() and "m" in top.get_ylabel()
    pixels = png_pixels(tmp_path / "traj.png")
    assert pixels.std() > 10 and len(np.unique(pixels.reshape(-1, 3), axis=0)) > 50
    pl.plot_trajectory(t, q=q, path=tmp_path / "traj.svg")
    svg = (tmp_path / "traj.svg").read_text()
    assert svg.count("<path") > 20 and "carriage 5" in svg


def test_closure_residual_plots_max_abs_per_sample(tmp_path):
    t = np.linspace(0, 1, 30)
    res = np.outer(np.exp(-10 * t), [1e-9, -3e-9, 2e-9])
    fig = pl.plot_closure_residual(t, res, path=tmp_path / "res.svg")
    (line,) = fig.axes[0].lines
    np.testing.assert_allclose(line.get_ydata(), 3e-9 * np.exp(-10 * t))
    assert fig.axes[0].get_yscale() == "log"
    assert (tmp_path / "res.svg").stat().st_size > 5000


def test_simulation_figure_from_a_trajectory_object(tmp_path):
    class Trajectory:
        times = np.linspace(0, 1, 20)
        q = np.zeros((20, 6)) + np.linspace(0, 0.1, 20)[:, None]
        actuator_forces = np.ones((20, 6))
        closure_residual = np.full(20, 1e-12)

    fig = pl.plot_simulation(Trajectory(), path=tmp_path / "sim.png")
    assert len(fig.axes) == 3 and fig.axes[2].get_yscale() == "log"
    with pytest.raises(hp.InputError):
        pl.plot_simulation(object())


def test_conditioning_matches_finite_difference_jacobian(robot):
    """cond(J) of the unscaled J (columns m/s and rad/s), the library's one definition."""
    poses = np.tile(robot.home_pose, (5, 1))
    poses[:, 2] += np.linspace(-0.1, 0.02, 5)
    poses[:, 4] = 0.05
    cond = wpl.conditioning(robot, poses)
    for n, pose in enumerate(poses):
        sv = np.linalg.svd(fd_jacobian(robot, pose), compute_uv=False)
        assert cond.condition_number[n] == pytest.approx(sv[0] / sv[-1], rel=1e-6)
        assert cond.inverse_condition[n] == pytest.approx(sv[-1] / sv[0], rel=1e-6)
        assert cond.sigma_min[n] == pytest.approx(sv[-1], rel=1e-6)
        # the same number as Hexapod.singularity reports
        assert cond.condition_number[n] == pytest.approx(
            robot.singularity(pose).condition_number, rel=1e-12)
    assert cond.reachable.all() and cond.ok.all()


def test_conditioning_marks_unreachable_poses(robot, tmp_path):
    poses = np.tile(robot.home_pose, (3, 1))
    poses[1, 2] = 1.0
    cond = wpl.conditioning(robot, poses)
    assert cond.reachable.tolist() == [True, False, True]
    assert cond.condition_number[1] == np.inf and cond.inverse_condition[1] == 0.0
    fig = wpl.plot_conditioning(robot, poses, path=tmp_path / "c.png")
    assert len(fig.axes) == 2 and (tmp_path / "c.png").stat().st_size > 10000
    assert fig.axes[0].get_ylabel() == wpl.CONDITION_LABEL


def test_workspace_slice_status_from_independent_geometry(robot, tmp_path):
    ws = wpl.workspace_slice(robot, z=0.30, half_width=0.15, resolution=21)
    g = robot.geometry
    mids, dirs, pts = rail_frames(g)
    counts = np.bincount(ws.status.ravel(), minlength=3)
    assert counts.min() > 0, counts                       # all three cases appear
    for iy, y in enumerate(ws.y):
        for ix, x in enumerate(ws.x):
            tips = np.array([x, y, 0.30]) + pts               # level platform
            d = tips[[0, 0, 1, 1, 2, 2]] - mids[[0, 0, 1, 1, 2, 2]]
            u = dirs[[0, 0, 1, 1, 2, 2]]
            along = np.einsum("ij,ij->i", d, u)
            disc = g.leg_length ** 2 - (np.einsum("ij,ij->i", d, d) - along ** 2)
            if np.any(disc < 0):
                assert ws.status[iy, ix] == wpl.OUT_OF_REACH
                continue
            q = along + np.tile([-1.0, 1.0], 3) * np.sqrt(disc)
            ok = np.all(np.abs(q) <= g.rail_half_length) and \
                np.all(q[1::2] - q[::2] >= g.carriage_min_gap)
            assert ws.status[iy, ix] == (wpl.REACHABLE if ok else wpl.STROKE_LIMIT), (x, y)
            assert np.isfinite(ws.condition_number[iy, ix]) == ok
    fig = wpl.plot_workspace_slice(ws, path=tmp_path / "ws.png")
    assert any("condition" in ax.get_ylabel() for ax in fig.axes)   # the colour bar
    assert any(wpl.CONDITION_LABEL in ax.get_ylabel() for ax in fig.axes)
    # the colours are the condition numbers of workspace.evaluate, the library's measure
    shown = fig.axes[0].images[1].get_array()
    ok = ws.status == wpl.REACHABLE
    np.testing.assert_allclose(np.ma.filled(shown, np.nan)[ok], np.log10(ws.condition_number[ok]))
    iy, ix = np.argwhere(ok)[len(np.argwhere(ok)) // 2]
    pose = np.array([ws.x[ix], ws.y[iy], 0.30, 0.0, 0.0, 0.0])
    assert ws.condition_number[iy, ix] == pytest.approx(
        robot.singularity(pose).condition_number, rel=1e-12)
    assert png_pixels(tmp_path / "ws.png").std() > 10


def test_workspace_slice_default_extent_frames_the_reachable_region(robot):
    ws = wpl.workspace_slice(robot, resolution=15)
    assert 0.05 < ws.reachable_fraction < 0.9
    assert ws.x[-1] < robot.geometry.rail_radius


def test_bad_input_and_missing_matplotlib(robot, tmp_path, monkeypatch):
    with pytest.raises(hp.InputError, match="times"):
        pl.plot_trajectory([0, np.nan], q=np.zeros((2, 6)))
    with pytest.raises(hp.InputError, match="q"):
        pl.plot_trajectory([0, 1], q=np.zeros((3, 6)))
    with pytest.raises(hp.InputError):
        pl.plot_trajectory([0, 1])
    with pytest.raises(hp.InputError, match="suffix"):
        pl.plot_closure_residual([0, 1], [1e-9, 1e-9], path=tmp_path / "x.gif")
    with pytest.raises(hp.InputError, match="resolution"):
        wpl.workspace_slice(robot, resolution=1)
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    with pytest.raises(hp.errors.MissingDependencyError, match=r"hexapod-pin\[plot\]"):
        pl.plot_closure_residual([0, 1], [1e-9, 1e-9])

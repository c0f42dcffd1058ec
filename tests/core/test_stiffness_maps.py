"""Stiffness maps (hexapod_pin.core.stiffness_maps) and their figure, on every robot.

Independent routes: at every pose of a slice the map's entries against the robot's own
``cartesian_stiffness`` / ``vibration_modes`` at that pose; the weakest block stiffnesses
against ``numpy.linalg.eigvalsh`` of the blocks picked here by the names of the pose axes;
the lowest frequency against ``scipy.linalg.eigh(K_x, M_x)`` written here, ``M_x`` from
``robot.reduced_dynamics``; each status against the route that refuses the pose (inverse
kinematics out of reach or beyond a stroke, the stiffness at a singular pose, the modes of
a statically unstable one).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

import robot_registry
from hexapod_pin.core import stiffness_maps as sm
from hexapod_pin.errors import (ArgumentTypeError, InputError, SingularityError,
                                StrokeLimitError, UnreachablePoseError)

ROBOTS = ("hexapod", "planar", "stewart", "delta", "four-bar", "five-bar")
K = 1e5
ANGLES = ("roll", "pitch", "yaw")


@pytest.fixture(scope="module")
def delta_slice():
    """A slice of the delta robot large enough for every status but FAILED."""
    return sm.stiffness_slice(robot_registry.get("delta"), K, half_width=0.3, resolution=11)


def lowest_frequency(robot, pose):
    """``sqrt(min eig(K_x, M_x)) / 2 pi`` (Hz) with ``M_x`` of the reduced dynamics."""
    kx = robot.cartesian_stiffness(pose, K).matrix
    mass = robot.reduced_dynamics(pose, np.zeros(len(pose))).mass_matrix
    values = scipy.linalg.eigh(0.5 * (kx + kx.T), mass, eigvals_only=True)
    return np.sqrt(values[0]) / (2 * np.pi)


@pytest.mark.parametrize("name", ROBOTS)
def test_map_entries_are_the_robots_at_each_pose(name):
    robot = robot_registry.get(name)
    ws = sm.stiffness_slice(robot, K, half_width=0.1, resolution=5)
    m = ws.map
    axes = tuple(robot.pose_axes)
    linear = [i for i, a in enumerate(axes) if a not in ANGLES]
    angular = [i for i, a in enumerate(axes) if a in ANGLES]
    assert np.count_nonzero(m.ok) >= 3
    for arr in (m.stiffness, m.frequencies, m.translational, m.rotational):
        assert arr is None or np.all(np.isfinite(arr))
    assert (m.translational is None) == (not linear)
    assert (m.rotational is None) == (not angular)
    for i in np.flatnonzero(m.ok):
        pose = m.poses[i]
        modes = robot.vibration_modes(pose, K)
        np.testing.assert_allclose(m.stiffness[i], robot.cartesian_stiffness(pose, K).matrix,
                                   rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(m.frequencies[i], modes.frequencies, rtol=1e-12)
        np.testing.assert_allclose(m.lowest_frequency[i], lowest_frequency(robot, pose),
                                   rtol=1e-8)
        for rows, values in ((linear, m.translational), (angular, m.rotational)):
            if rows:
                block = m.stiffness[i][np.ix_(rows, rows)]
                assert values[i] == pytest.approx(
                    np.linalg.eigvalsh(0.5 * (block + block.T))[0], rel=1e-12)
    empty = ~m.has_stiffness
    assert np.all(m.stiffness[empty] == 0) and np.all(m.frequencies[~m.ok] == 0)


def test_statuses_name_the_route_that_refuses(delta_slice):
    """Every status of the delta's slice but FAILED occurs, each where the robot's own
    route refuses the pose that way."""
    robot, m = robot_registry.get("delta"), delta_slice.map
    counts = {sm.STATUS_NAMES[c]: int(np.count_nonzero(m.status == c)) for c in range(6)}
    assert all(counts[s] > 0 for s in ("ok", "unreachable", "stroke", "singular", "unstable"))
    assert dict(m.failures) == {k: v for k, v in counts.items() if k != "ok" and v}
    for i, code in enumerate(m.status):
        pose = m.poses[i]
        if code == sm.UNREACHABLE:
            with pytest.raises(UnreachablePoseError):
                robot.inverse_kinematics(pose, check_limits=False)
        elif code == sm.STROKE:
            robot.inverse_kinematics(pose, check_limits=False)
            with pytest.raises(StrokeLimitError):
                robot.inverse_kinematics(pose, check_limits=True)
        elif code == sm.SINGULAR:
            with pytest.raises(SingularityError):
                robot.cartesian_stiffness(pose, K)
        elif code == sm.UNSTABLE:
            with pytest.raises(SingularityError, match="positive semi-definite"):
                robot.vibration_modes(pose, K)
            kx = robot.cartesian_stiffness(pose, K).matrix
            np.testing.assert_allclose(m.stiffness[i], kx, rtol=1e-12, atol=1e-9)
            assert np.linalg.eigvalsh(0.5 * (kx + kx.T))[0] < 0
            assert m.frequencies[i].tolist() == [0.0] * 3


def test_slice_grid_and_progress():
    robot = robot_registry.get("planar")
    seen: list[float] = []
    center = robot.home_pose + np.array([0.01, 0.0, 0.05])
    ws = sm.stiffness_slice(robot, [1e5, 2e5, 3e5], ("x", "yaw"), center=center,
                            half_width=(0.02, 0.1), resolution=4, progress=seen.append)
    assert ws.axes == ("x", "yaw") and ws.shape == (4, 4)
    grid = ws.grid(ws.map.poses)
    xs, yaws = ws.coordinates
    np.testing.assert_allclose(xs, center[0] + np.linspace(-0.02, 0.02, 4))
    np.testing.assert_allclose(yaws, center[2] + np.linspace(-0.1, 0.1, 4))
    for j, yaw in enumerate(yaws):
        for i, x in enumerate(xs):
            np.testing.assert_array_equal(grid[j, i], [x, center[1], yaw])
    assert seen[-1] == 1.0
    np.testing.assert_array_equal(ws.map.actuator_stiffness, [1e5, 2e5, 3e5])
    line = sm.stiffness_slice(robot_registry.get("four-bar"), K, resolution=3)
    assert line.axes == ("x",) and line.shape == (3,)
    assert sm.stiffness_slice(robot, K).axes == ("x", "y")


def test_stiffer_actuators_stiffen_every_pose():
    """Scaling every actuator stiffness scales the elastic part: at the usable poses of
    the Stewart platform, the weakest blocks and the lowest frequency all rise."""
    robot = robot_registry.get("stewart")
    soft, stiff = (sm.stiffness_slice(robot, k, half_width=0.05, resolution=3).map
                   for k in (1e4, 4e4))
    both = soft.ok & stiff.ok
    assert np.count_nonzero(both) == 9
    for name in ("translational", "rotational", "lowest_frequency"):
        assert np.all(getattr(stiff, name)[both] > getattr(soft, name)[both])


def test_bad_input():
    robot = robot_registry.get("planar")
    with pytest.raises(InputError, match=">= 0"):
        sm.stiffness_map(robot, [robot.home_pose], -1.0)
    with pytest.raises(InputError):
        sm.stiffness_map(robot, [robot.home_pose], [1.0, 2.0])
    with pytest.raises(InputError):
        sm.stiffness_map(robot, np.zeros((2, 2)), K)
    with pytest.raises(InputError):
        sm.stiffness_map(robot, [[0.0, 0.0, np.nan]], K)
    with pytest.raises(ArgumentTypeError):
        sm.stiffness_map(object(), [robot.home_pose], K)
    with pytest.raises(ArgumentTypeError):
        sm.stiffness_map(robot, [robot.home_pose], K, progress=3)
    with pytest.raises(InputError, match="pose axes"):
        sm.stiffness_slice(robot, K, "x,z")
    with pytest.raises(InputError, match="pose axes"):
        sm.stiffness_slice(robot, K, "x,x")
    with pytest.raises(InputError, match="resolution"):
        sm.stiffness_slice(robot, K, resolution=1)
    with pytest.raises(InputError, match="resolution"):
        sm.stiffness_slice(robot, K, resolution=sm.MAX_RESOLUTION + 1)
    with pytest.raises(InputError, match="half_width"):
        sm.stiffness_slice(robot, K, half_width=0.0)
    friction = robot.with_effects(coulomb=np.full(robot.model.nv, 0.1))
    with pytest.raises(InputError, match="at rest"):
        sm.stiffness_map(friction, [friction.home_pose], K)


def test_figure_draws_the_maps_values(delta_slice):
    """The figure's images are the map's values (NaN where none), the shading's the
    statuses; a one-axis slice draws curves."""
    pytest.importorskip("matplotlib")
    from hexapod_pin.viz import stiffness_plots

    fig = stiffness_plots.plot_stiffness_slice(delta_slice)
    panels = [ax for ax in fig.axes if ax.images]
    assert len(panels) == 2                        # the delta: no rotational block
    m = delta_slice.map
    expected = (np.where(m.has_stiffness, m.translational, np.nan),
                np.where(m.ok, m.lowest_frequency, np.nan))
    for ax, values in zip(panels, expected):
        shade, image = (np.ma.filled(im.get_array(), np.nan) for im in ax.images)
        np.testing.assert_array_equal(image, delta_slice.grid(values))
        unstable = delta_slice.grid(m.status == sm.UNSTABLE)
        assert np.all(np.isnan(shade[np.isfinite(image)]))
        assert np.all(shade[delta_slice.grid(m.status == sm.UNREACHABLE)] == 1.0)
        if ax is panels[1]:
            assert np.all(shade[unstable] == 0.0)
    line = sm.stiffness_slice(robot_registry.get("four-bar"), K, resolution=5)
    fig = stiffness_plots.plot_stiffness_slice(line)
    assert len(fig.axes) == 2 and all(len(ax.lines) == 1 for ax in fig.axes)
    with pytest.raises(ArgumentTypeError):
        stiffness_plots.plot_stiffness_slice(m)

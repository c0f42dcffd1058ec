"""Workspace analysis: batch measures against per-pose routes, force capability against an LP
solver and brute force, sampled volume against a closed form, Dask sweep against serial."""

import math

import numpy as np
import pytest
import scipy.optimize

import hexapod_pin as hp
from hexapod_pin.hexapod import workspace as ws
from hexapod_pin.errors import InputError


@pytest.fixture(scope="module")
def poses(robot):
    rng = np.random.default_rng(7)
    half = np.array([0.08, 0.08, 0.08, 0.2, 0.2, 0.3])
    return ws.sample_poses(rng, 400, robot.home_pose - half, robot.home_pose + half)


def test_reachability_matches_per_pose_inverse_kinematics(robot, poses):
    m = ws.evaluate(robot, poses)
    assert 0.05 < m.ok.mean() < 0.95  # the sample straddles the workspace boundary
    for i, pose in enumerate(poses):
        try:
            q = robot.inverse_kinematics(pose)
            ik_ok = True
        except (hp.UnreachablePoseError, hp.StrokeLimitError):
            ik_ok = False
        assert ik_ok == bool(m.reachable[i] and m.within_stroke[i]), i
        if ik_ok:
            np.testing.assert_allclose(m.q[i], q, atol=1e-14)


def test_condition_numbers_match_per_pose_jacobian(any_robot):
    rng = np.random.default_rng(3)
    half = np.array([0.05, 0.05, 0.05, 0.15, 0.15, 0.2])
    poses = ws.sample_poses(rng, 200, any_robot.home_pose - half, any_robot.home_pose + half)
    m = ws.evaluate(any_robot, poses)
    for i in np.flatnonzero(m.ok):
        jac = any_robot.jacobian(poses[i])
        assert m.condition_number[i] == pytest.approx(np.linalg.cond(jac), rel=1e-10)
        s = any_robot.singularity(poses[i])
        assert m.type_one[i] == pytest.approx(s.type_one, abs=1e-12)
        assert m.type_two[i] == pytest.approx(s.type_two, abs=1e-12)
    assert np.all(np.isinf(m.condition_number[~m.ok]))
    assert np.all(m.static_forces[~m.ok] == 0.0)
    assert not np.any(np.isnan(m.static_forces))


def test_statics_by_virtual_power_match_the_dynamics_route(any_robot):
    """Workspace statics (virtual power, closed form) vs static_forces (tree KKT / QP)."""
    rng = np.random.default_rng(11)
    half = np.array([0.03, 0.03, 0.03, 0.1, 0.1, 0.1])
    poses = ws.sample_poses(rng, 30, any_robot.home_pose - half, any_robot.home_pose + half)
    payload = np.array([3.0, -2.0, -25.0, 0.4, -0.2, 0.3])
    m = ws.evaluate(any_robot, poses, payload=payload)
    checked = 0
    for i in np.flatnonzero(m.ok):
        np.testing.assert_allclose(m.static_forces[i], any_robot.static_forces(poses[i], payload),
                                   atol=1e-9)
        checked += 1
    assert checked > 10
    home = ws.evaluate(hp.Hexapod.default(), hp.Hexapod.default().home_pose[None])
    np.testing.assert_allclose(home.static_forces[0], 1.6510015556928 * np.tile([1, -1], 3),
                               rtol=1e-9)


def test_force_capability_against_linprog_and_brute_force(robot, poses):
    direction = np.array([0.0, 0.0, -9.81, 0.0, 0.0, 0.0])  # a mass at the platform origin
    cap = ws.force_capability(robot, poses[:80], direction)
    limit = robot.geometry.max_actuator_force
    checked = 0
    for i in np.flatnonzero(cap.ok & cap.feasible_without_payload):
        tau0, tau1 = cap.base_forces[i], cap.unit_forces[i]
        # reference LP: max s s.t. -limit <= tau0 + s tau1 <= limit, s >= 0
        lp = scipy.optimize.linprog(c=[-1.0], A_ub=np.concatenate([tau1, -tau1])[:, None],
                                    b_ub=np.concatenate([limit - tau0, limit + tau0]),
                                    bounds=[(0, None)], method="highs")
        assert lp.status == 0
        assert cap.scale[i] == pytest.approx(lp.x[0], rel=1e-9)
        # brute force with the dynamics route: the payload is feasible, 1 % more is not
        mass = cap.scale[i]
        held = robot.static_forces(poses[i], mass * direction, bounded=False)
        assert np.max(np.abs(held)) <= limit * (1 + 1e-9)
        more = robot.static_forces(poses[i], 1.01 * mass * direction, bounded=False)
        assert np.max(np.abs(more)) > limit
        assert abs(abs(held[cap.limiting_actuator[i]]) - limit) < 1e-6
        checked += 1
    assert checked > 5
    assert np.all(cap.scale[~cap.ok] == 0.0)


def test_one_leg_volume_matches_the_cylinder(robot):
    """Leg 0 reaches when the platform point lies within leg_length of rail 0's line: with a
    level platform, the platform origin then lies in a cylinder of radius L about the rail
    line shifted by -p_0. Inside a box that contains the cylinder's cross-section, the volume
    is pi L^2 times the box length along the rail."""
    g = robot.geometry
    L = g.leg_length
    axis_point = g.rail_midpoints[0] - g.platform_points[0]   # (0, R - r, 0), axis along x
    half = np.array([0.2, 1.2 * L, 1.2 * L])
    est = ws.volume(robot, 200_000, axis_point, half, legs=[0], seed=1)
    exact = math.pi * L**2 * 2 * half[0]
    assert abs(est.volume - exact) < 4 * est.std_error
    assert est.std_error < 0.01 * exact


def test_volume_of_the_workspace_is_positive_and_reproducible(robot):
    a = ws.volume(robot, 20_000, robot.home_pose[:3], [0.1, 0.1, 0.1], seed=3)
    b = ws.volume(robot, 20_000, robot.home_pose[:3], [0.1, 0.1, 0.1], seed=3)
    assert a == b and a.volume > 0
    well = ws.volume(robot, 20_000, robot.home_pose[:3], [0.1, 0.1, 0.1], seed=3, max_condition=20)
    assert well.volume <= a.volume


def test_grids():
    grid = ws.constant_orientation_grid([0, 0, 0.3], [0.1, 0.1, 0.05], (3, 4, 5), (0.1, 0, 0))
    assert grid.shape == (60, 6)
    assert np.allclose(grid[:, 3], 0.1) and grid[:, 2].min() == pytest.approx(0.25)
    ori = ws.orientation_grid([0, 0, 0.3], 0.2, 5)
    assert ori.shape == (125, 6) and ori[:, 3:].max() == pytest.approx(0.2)


def test_bad_inputs(robot):
    with pytest.raises(InputError):
        ws.evaluate(robot, np.zeros((3, 5)))
    with pytest.raises(InputError):
        ws.evaluate(robot, np.full((2, 6), np.nan))
    with pytest.raises(InputError):
        ws.evaluate(robot, np.zeros((2, 6)), payload=np.zeros(5))
    with pytest.raises(InputError):
        ws.force_capability(robot, np.zeros((2, 6)), np.zeros(6))
    with pytest.raises(InputError):
        ws.volume(robot, 0, [0, 0, 0], [1, 1, 1])
    with pytest.raises(InputError):
        ws.volume(robot, 10, [0, 0, 0], [1, 1, 1], legs=[7])
    with pytest.raises(InputError):
        ws.constant_orientation_grid([0, 0, 0], [0.1, 0.1, -1], 3)


def test_threads_give_identical_results(robot):
    rng = np.random.default_rng(5)
    half = np.array([0.08, 0.08, 0.08, 0.2, 0.2, 0.3])
    poses = ws.sample_poses(rng, 2 * ws.CHUNK + 10, robot.home_pose - half, robot.home_pose + half)
    a = ws.evaluate(robot, poses, threads=1, singularity=False)
    b = ws.evaluate(robot, poses, threads=2, singularity=False)
    np.testing.assert_array_equal(a.ok, b.ok)
    np.testing.assert_array_equal(a.condition_number, b.condition_number)
    np.testing.assert_array_equal(a.static_forces, b.static_forces)

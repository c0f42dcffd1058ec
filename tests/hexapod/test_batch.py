"""Batch dynamics (the Newton-Euler kernels over N states) against the Pinocchio tree route.

The batch route (:mod:`hexapod_pin.hexapod.batch` running :mod:`hexapod_pin.hexapod.kernels`:
platform Newton-Euler, legs as consistent-mass rods, carriages as point masses) shares no
dynamics with the single-state tree route (``pin.rnea`` / ``pin.constraintDynamics`` on the
tree state), and its masses come from the geometry rather than from the URDF: agreement to
1e-10 checks both, and the URDF against the geometry. Batch answers equal the single-state
kernels' (the same code) to 1e-12.
"""

import numpy as np
import pytest
from conftest import random_pose

import hexapod_pin as hp
from hexapod_pin.errors import (BatchActuatorSaturationError, BatchSingularityError,
                                BatchUnreachablePoseError)
from hexapod_pin.hexapod import kernels as K
from hexapod_pin.hexapod.batch import CHUNK
from hexapod_pin.hexapod.fast import fast_dynamics
from hexapod_pin.errors import InputError, SingularityError, UnreachablePoseError


def _states(robot, rng, n, scale=1.0):
    poses = np.array([random_pose(robot, rng) for _ in range(n)])
    twists = scale * np.concatenate([0.1 * rng.normal(size=(n, 3)), 0.5 * rng.normal(size=(n, 3))],
                                    axis=1)
    twist_dots = scale * np.concatenate([rng.normal(size=(n, 3)), 3.0 * rng.normal(size=(n, 3))],
                                        axis=1)
    wrenches = np.concatenate([3.0 * rng.normal(size=(n, 3)), 0.3 * rng.normal(size=(n, 3))],
                              axis=1)
    return poses, twists, twist_dots, wrenches


def test_inverse_batch_matches_the_tree_route(any_robot, rng):
    robot = any_robot
    poses, twists, twist_dots, wrenches = _states(robot, rng, 6)
    batch = robot.inverse_dynamics_batch(poses, twists, twist_dots, wrenches, bounded=False)
    assert batch.actuator_forces.shape == (6, 6) and batch.closure_forces.shape == (6, 6, 3)
    assert np.all(batch.residual < 1e-10)
    for k in range(6):
        single = robot.inverse_dynamics(poses[k], twists[k], twist_dots[k], wrenches[k],
                                        method="kkt", bounded=False)
        np.testing.assert_allclose(batch.actuator_forces[k], single.actuator_forces, atol=1e-10)
        np.testing.assert_allclose(batch.closure_forces[k], single.closure_forces, atol=1e-10)


def test_forward_batch_matches_constraint_dynamics(any_robot, rng):
    robot = any_robot
    poses, twists, _, wrenches = _states(robot, rng, 6)
    forces = np.array([robot.static_forces(p) for p in poses]) + 5.0 * rng.normal(size=(6, 6))
    batch = robot.forward_dynamics_batch(poses, twists, forces, wrenches)
    for k in range(6):
        single = robot.forward_dynamics(poses[k], twists[k], forces[k], wrenches[k],
                                        method="pinocchio")
        np.testing.assert_allclose(batch.twist_dot[k], single.twist_dot, atol=1e-10)
        np.testing.assert_allclose(batch.actuator_accelerations[k], single.actuator_accelerations,
                                   atol=1e-10)
        np.testing.assert_allclose(batch.closure_forces[k], single.closure_forces, atol=1e-10)
    # and FD(ID) = identity inside the batch route itself
    back = robot.inverse_dynamics_batch(poses, twists, batch.twist_dot, wrenches, bounded=False)
    np.testing.assert_allclose(back.actuator_forces, forces, atol=1e-10)


def test_static_and_reduced_batches_match_single_calls(any_robot, rng):
    robot = any_robot
    poses, twists, _, wrenches = _states(robot, rng, 5)
    static = robot.static_forces_batch(poses, wrenches)
    red = robot.reduced_dynamics_batch(poses, twists)
    m_x, h_x = red
    for k in range(5):
        np.testing.assert_allclose(static[k], robot.static_forces(poses[k], wrenches[k]),
                                   atol=1e-10)
        single = robot.reduced_dynamics(poses[k], twists[k])
        scale = max(1.0, np.abs(single.mass_matrix).max())
        np.testing.assert_allclose(m_x[k], single.mass_matrix, atol=1e-10 * scale)
        np.testing.assert_allclose(h_x[k], single.bias, atol=1e-10 * max(1, np.abs(single.bias).max()))
        np.testing.assert_allclose(red.jacobian[k], robot.jacobian(poses[k]), atol=1e-12)
    np.testing.assert_allclose(m_x, np.swapaxes(m_x, 1, 2), atol=1e-12)
    assert np.all(np.linalg.eigvalsh(m_x) > 0.0)


def test_batch_kinetic_energy_is_half_twist_m_twist(robot, rng):
    """1/2 twist^T M_x twist of the batch route == Pinocchio's kinetic energy of the tree."""
    poses, twists, _, _ = _states(robot, rng, 4)
    m_x = robot.reduced_dynamics_batch(poses, twists).mass_matrix
    for k in range(4):
        expected = robot.energies(poses[k], twists[k]).kinetic
        assert 0.5 * twists[k] @ m_x[k] @ twists[k] == pytest.approx(expected, rel=1e-12)


def test_chunk_boundaries(robot, rng):
    """More states than one chunk: every state equals its own small-batch answer."""
    poses, twists, twist_dots, wrenches = _states(robot, rng, 3)
    n = CHUNK + 5
    idx = np.arange(n) % 3
    big = robot.inverse_dynamics_batch(poses[idx], twists[idx], twist_dots[idx], wrenches[idx],
                                       bounded=False)
    small = robot.inverse_dynamics_batch(poses, twists, twist_dots, wrenches, bounded=False)
    np.testing.assert_allclose(big.actuator_forces, small.actuator_forces[idx], atol=1e-12)
    fwd = robot.forward_dynamics_batch(poses[idx], twists[idx], big.actuator_forces, wrenches[idx])
    np.testing.assert_allclose(fwd.twist_dot, twist_dots[idx], atol=1e-10)


def test_batch_errors_name_the_first_bad_state(robot, rng):
    poses, twists, twist_dots, _ = _states(robot, rng, 3)
    far = poses.copy()
    far[2, 2] += 1.0
    with pytest.raises(BatchUnreachablePoseError) as info:
        robot.inverse_dynamics_batch(far, twists, twist_dots)
    assert info.value.index == 2 and isinstance(info.value, UnreachablePoseError)
    assert info.value.carriages
    # a level pose where every leg is within 3e-8 (cosine) of perpendicular to its rail:
    # the IK discriminant (L^2 - distance^2 to the rail line) is (3e-8 L)^2
    g = robot.geometry
    pose = robot.home_pose.copy()
    length = g.leg_length
    pose[2] = np.sqrt(length ** 2 - (g.rail_radius - g.platform_radius) ** 2
                      - (3e-8 * length) ** 2)
    singular = poses.copy()
    singular[1] = pose
    with pytest.raises(BatchSingularityError) as info:
        robot.forward_dynamics_batch(singular, twists, np.zeros((3, 6)))
    assert info.value.index == 1 and isinstance(info.value, SingularityError)
    with pytest.raises(SingularityError):
        robot.inverse_dynamics(pose, np.zeros(6), np.zeros(6))
    with pytest.raises(SingularityError):
        robot.forward_dynamics(pose, np.zeros(6), np.zeros(6))


def test_type_two_check_and_saturation(robot):
    # the platform in the rail plane: every leg horizontal, A_hat of rank 3 (type II)
    flat = robot.home_pose.copy()
    flat[2] = 0.0
    assert robot.singularity(flat).type_two < 1e-12
    poses = np.array([robot.home_pose, robot.home_pose, flat])
    with pytest.raises(BatchSingularityError, match="type-II") as info:
        robot.static_forces_batch(poses, bounded=False)
    assert info.value.index == 2
    assert info.value.sigma_min == pytest.approx(robot.singularity(flat).type_two, abs=1e-15)
    pose = robot.home_pose
    fast = np.array([0.0, 0.0, 150.0, 0.0, 0.0, 0.0])
    with pytest.raises(BatchActuatorSaturationError) as info:
        robot.inverse_dynamics_batch([pose, pose, pose], np.zeros((3, 6)),
                                     [np.zeros(6), np.zeros(6), fast])
    assert info.value.index == 2
    with pytest.raises(BatchActuatorSaturationError):
        robot.static_forces_batch([pose], [[0.0, 0.0, -1e4, 0.0, 0.0, 0.0]])


def test_batch_bad_inputs(robot):
    pose = robot.home_pose
    with pytest.raises(InputError):
        robot.forward_dynamics_batch([pose], np.zeros((2, 6)), np.zeros((1, 6)))
    with pytest.raises(InputError):
        robot.inverse_dynamics_batch([pose], [np.full(6, np.nan)], np.zeros((1, 6)))
    with pytest.raises(InputError):
        robot.static_forces_batch(np.zeros((2, 5)))
    with pytest.raises(InputError):
        robot.reduced_dynamics_batch([pose], np.zeros((1, 6, 1)))


def test_batch_of_one_and_home_statics(robot):
    forces = robot.static_forces_batch(robot.home_pose[None])
    np.testing.assert_allclose(forces[0], 1.6510015556928 * np.array([1, -1, 1, -1, 1, -1]),
                               rtol=1e-10)
    res = robot.inverse_dynamics_batch(robot.home_pose[None], np.zeros((1, 6)), np.zeros((1, 6)))
    np.testing.assert_allclose(res.actuator_forces, forces, atol=1e-12)
    assert isinstance(res.closure_forces, np.ndarray) and np.all(np.isfinite(res.closure_forces))


def test_gravity_free_geometry_batch():
    robot = hp.Hexapod(hp.HexapodGeometry(gravity=0.0))
    np.testing.assert_allclose(robot.static_forces_batch(robot.home_pose[None]), 0.0, atol=1e-14)


def test_batch_equals_single_state_kernels(robot, rng):
    """The batch functions run the single-state kernels: ID, FD, statics, reduced, IK and J
    of every state equal the single-state answers (1e-12)."""
    poses, twists, twist_dots, wrenches = _states(robot, rng, 7)
    fd = fast_dynamics(robot)
    inv = robot.inverse_dynamics_batch(poses, twists, twist_dots, wrenches, bounded=False)
    fwd = robot.forward_dynamics_batch(poses, twists, inv.actuator_forces, wrenches)
    stat = robot.static_forces_batch(poses, wrenches, bounded=False)
    red = robot.reduced_dynamics_batch(poses, twists)
    ik = robot.inverse_kinematics_batch(poses)
    jb = robot.jacobian_batch(poses)
    s = K.Scratch()
    for k in range(7):
        np.testing.assert_allclose(inv.actuator_forces[k], fd.inverse_dynamics(
            poses[k], twists[k], twist_dots[k], wrenches[k], bounded=False), rtol=0, atol=1e-12)
        acc, qdd = fd.forward_dynamics_full(poses[k], twists[k], inv.actuator_forces[k],
                                            wrenches[k])
        np.testing.assert_allclose(fwd.twist_dot[k], acc, rtol=0, atol=1e-12)
        np.testing.assert_allclose(fwd.actuator_accelerations[k], qdd, rtol=0, atol=1e-12)
        np.testing.assert_allclose(stat[k], fd.static_forces(poses[k], wrenches[k],
                                                             bounded=False), rtol=0, atol=1e-12)
        mass, bias, jac = np.empty((6, 6)), np.empty(6), np.empty((6, 6))
        assert K.reduced_dynamics(fd.geo, K.HOME_BRANCH, poses[k], twists[k], mass, bias, jac,
                                  s.rot, s.wk, s.mats) == K.OK
        np.testing.assert_allclose(red.mass_matrix[k], mass, rtol=0, atol=1e-12)
        np.testing.assert_allclose(red.bias[k], bias, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ik.actuator_positions[k], robot.inverse_kinematics(
            poses[k], check_limits=False), rtol=0, atol=1e-12)
        np.testing.assert_allclose(jb.jacobian[k], robot.jacobian(poses[k]), rtol=0,
                                   atol=1e-12)


def test_one_type_two_predicate_for_single_and_batch_routes(robot):
    """Walk the platform down to the rail plane (a type-II singularity: every leg
    horizontal). At each pose the single-state routes (tree ID, compiled ID, statics,
    twist from carriage rates) and the batch routes raise SingularityError exactly where
    the type-II measure of Hexapod.singularity (sigma_min of A_hat) is below TYPE_II_TOL."""
    fd = fast_dynamics(robot)
    zero = np.zeros(6)
    heights = np.concatenate([[0.05, 1e-3, 1e-6, 1e-9], np.logspace(-11, -13, 9), [0.0]])
    verdicts = set()
    for z in heights:
        pose = robot.home_pose.copy()
        pose[2] = z
        measure = robot.singularity(pose).type_two
        if abs(measure / K.TYPE_II_TOL - 1.0) < 1e-6:
            continue                                  # round-off decides at the border
        singular = measure < K.TYPE_II_TOL
        verdicts.add(singular)
        routes = (lambda: robot.inverse_dynamics(pose, zero, zero, bounded=False),
                  lambda: robot.static_forces(pose, bounded=False),
                  lambda: fd.inverse_dynamics(pose, zero, zero, bounded=False),
                  lambda: fd.static_forces(pose, bounded=False),
                  lambda: robot.twist_from_actuator_velocities(pose, np.ones(6)),
                  lambda: robot.inverse_dynamics_batch(pose[None], zero[None], zero[None],
                                                       bounded=False),
                  lambda: robot.static_forces_batch(np.array([robot.home_pose, pose]),
                                                    bounded=False))
        for route in routes:
            if singular:
                with pytest.raises(SingularityError, match="type-II"):
                    route()
            else:
                route()
    assert verdicts == {True, False}

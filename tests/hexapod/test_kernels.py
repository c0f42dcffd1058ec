"""The compiled closed form of the hexapod (hexapod_pin.hexapod.kernels): its tree map.

Checked against Pinocchio (closure residual, ``J_c v = 0``, ``J_c a = -gamma``, ``J_c G = 0``
with Pinocchio's own Jacobian and drift, constraintDynamics), virtual power
(``G^T f . twist = f . v``) and numpy linear algebra.
"""

import numpy as np
import pinocchio as pin
import pytest
from conftest import random_pose

import hexapod_pin as hp
from hexapod_pin.hexapod import kernels as K
from hexapod_pin.hexapod.kinematics import HOME_BRANCH


def _motion(rng):
    return (np.concatenate([0.1 * rng.normal(size=3), 0.5 * rng.normal(size=3)]),
            np.concatenate([rng.normal(size=3), 3.0 * rng.normal(size=3)]))


def _state(robot, pose, twist, twist_dot, level=2):
    ck = K.ClosedForm(robot.geometry, robot.indices)
    s = ck.scratch
    q, v, a = np.empty(25), np.empty(24), np.empty(24)
    code = K.tree_state(ck.geo, HOME_BRANCH, pose, twist, twist_dot, level, q, v, a, s.rot,
                        s.wk)
    return code, ck, q, v, a


def test_tree_state_keeps_the_closures(any_robot, rng):
    robot = any_robot
    clm = robot.model
    for _ in range(4):
        pose = random_pose(robot, rng)
        twist, twist_dot = _motion(rng)
        code, _, q, v, a = _state(robot, pose, twist, twist_dot)
        assert code == K.OK
        assert np.abs(clm.residual(q)).max() <= 1e-12
        jac = clm.constraint_jacobian(q)
        assert np.abs(jac @ v).max() <= 1e-11
        drift = clm.constraint_drift(q, v)
        np.testing.assert_allclose(jac @ a, -drift, atol=1e-10)
        rot = hp.core.pose.rotation_from_rpy(pose[3:])
        np.testing.assert_allclose(v[18:], np.concatenate([rot.T @ twist[:3],
                                                           rot.T @ twist[3:]]), atol=1e-14)
        acc_lin = twist_dot[:3] - np.cross(twist[3:], twist[:3])
        np.testing.assert_allclose(a[18:], np.concatenate([rot.T @ acc_lin,
                                                           rot.T @ twist_dot[3:]]), atol=1e-13)


def test_velocity_map_against_the_tree(any_robot, rng):
    """``J_c G = 0`` with Pinocchio's J_c; the carriage rows of G are the kinematics'
    Jacobian; ``G twist`` is the tree velocity of the same state."""
    robot = any_robot
    pose = random_pose(robot, rng)
    twist, twist_dot = _motion(rng)
    _, ck, q, v, _ = _state(robot, pose, twist, twist_dot)
    g_map = np.empty((24, 6))
    K.velocity_map(ck.geo, ck.scratch.rot, ck.scratch.wk, g_map)
    assert np.max(np.abs(robot.model.constraint_jacobian(q) @ g_map)) <= 1e-12
    np.testing.assert_allclose(g_map[robot.indices.carriage_v], robot.jacobian(pose),
                               atol=1e-12)
    np.testing.assert_allclose(g_map @ twist, v, atol=1e-13)


def test_legs_from_the_tree_and_closed_form_residual(any_robot, rng):
    """Legs read back from the universal-joint angles equal the IK legs; the closed-form
    closure residual equals Pinocchio's on perturbed configurations."""
    robot = any_robot
    pose = random_pose(robot, rng)
    _, ck, q, _, _ = _state(robot, pose, np.zeros(6), np.zeros(6), level=0)
    ik_legs = ck.scratch.wk[[K.NX, K.NY, K.NZ, K.Q]].copy()
    back, rot, wk = np.empty(6), np.empty(9), np.zeros((K.WK_ROWS, 6))
    assert K.legs_from_tree(ck.geo, q, back, rot, wk) == K.OK
    np.testing.assert_allclose(wk[[K.NX, K.NY, K.NZ, K.Q]], ik_legs, atol=1e-14)
    np.testing.assert_allclose(back, pose, atol=1e-13)
    for _ in range(3):
        qp = pin.integrate(robot.model.model, robot.configuration(pose),
                           0.02 * rng.normal(size=robot.model.nv))
        assert ck.closure_residual(qp) == pytest.approx(
            np.max(np.abs(robot.model.residual(qp))), rel=1e-12, abs=1e-16)


def test_projection_is_virtual_power_and_solve_is_exact(any_robot, rng):
    robot = any_robot
    pose = random_pose(robot, rng)
    twist, twist_dot = _motion(rng)
    _, ck, _q, v, _ = _state(robot, pose, twist, twist_dot)
    force, wrench = rng.normal(size=24), rng.normal(size=6)
    rhs = np.empty(6)
    s = ck.scratch
    K.project(ck.geo, s.rot, s.wk, force, wrench, True, rhs)
    # (G^T f - w) . twist == f . v_tree - w . twist  (virtual power)
    assert rhs @ twist == pytest.approx(force @ v - wrench @ twist, rel=1e-12, abs=1e-12)
    tau, mult, jac_t = np.empty(6), np.empty(6), np.empty((6, 6))
    assert K.solve_forces(ck.geo, s.wk, s.mats, rhs, tau, mult, jac_t) == K.OK
    # J^T from the tree: J = S G, with G checked against Pinocchio's J_c above
    g_map = np.empty((24, 6))
    K.velocity_map(ck.geo, s.rot, s.wk, g_map)
    np.testing.assert_allclose(jac_t, g_map[robot.model.actuated_v].T, atol=1e-12)
    np.testing.assert_allclose(np.linalg.solve(jac_t, rhs), tau, rtol=1e-10, atol=1e-10)
    # the QP multipliers: stationarity tau + J mult = 0
    np.testing.assert_allclose(jac_t.T @ mult, -tau, atol=1e-10 * max(1.0, abs(tau).max()))


def test_nullspace_forward_matches_constraint_dynamics(any_robot, rng):
    """``M_x twist_dot = G^T (S^T tau - bias)`` against pin.constraintDynamics."""
    robot = any_robot
    clm = robot.model
    model, data = clm.model, clm.model.createData()
    pose = random_pose(robot, rng)
    twist, _ = _motion(rng)
    forces = rng.normal(size=6) * 5
    _, ck, q, v, acc0 = _state(robot, pose, twist, np.zeros(6))
    mass = pin.crba(model, data, q)
    bias = pin.rnea(model, data, q, v, acc0)
    twist_dot, acc = np.empty(6), np.empty(24)
    s = ck.scratch
    assert K.nullspace_forward(ck.geo, s.rot, s.wk, mass, bias, forces, K.ZERO6, False, acc0,
                               np.empty((36, 6)), twist_dot, acc) == K.OK
    tau = np.zeros(model.nv)
    tau[clm.actuated_v] = forces
    cms, cds = clm.pinocchio_constraints()
    pin.initConstraintDynamics(model, data, cms, cds)
    ref = pin.constraintDynamics(model, data, q, v, tau, cms, cds,
                                 pin.ProximalSettings(1e-12, 0.0, 1))
    np.testing.assert_allclose(acc, ref, atol=1e-9)


def test_error_codes(robot):
    pose = robot.home_pose.copy()
    pose[2] += 10.0
    assert _state(robot, pose, np.zeros(6), np.zeros(6))[0] == K.UNREACHABLE
    bad = robot.home_pose.copy()
    bad[0] = np.nan
    assert _state(robot, bad, np.zeros(6), np.zeros(6))[0] == K.NONFINITE
    twist = np.zeros(6)
    twist[4] = np.inf
    assert _state(robot, robot.home_pose, twist, np.zeros(6), level=0)[0] == K.OK
    assert _state(robot, robot.home_pose, twist, np.zeros(6), level=1)[0] == K.NONFINITE


def test_public_routes_take_any_array_like(robot, rng):
    """Lists, tuples and non-contiguous views give the same answer as float64 arrays."""
    pose = random_pose(robot, rng)
    twist, twist_dot = _motion(rng)
    ref = robot.inverse_dynamics(pose, twist, twist_dot, method="kkt",
                                 bounded=False).actuator_forces
    strided = np.empty(12)
    strided[::2] = pose
    for p in (pose.tolist(), strided[::2], tuple(pose)):
        got = robot.inverse_dynamics(p, twist, twist_dot, method="kkt",
                                     bounded=False).actuator_forces
        np.testing.assert_array_equal(got, ref)
    with pytest.raises(hp.InputError, match="twist_dot"):
        robot.inverse_dynamics(pose, twist, np.full(6, np.nan))
    with pytest.raises(hp.InputError, match="wrench"):
        robot.inverse_dynamics(pose, twist, twist_dot, wrench=[0, 0, np.inf, 0, 0, 0])
    with pytest.raises(hp.InputError, match="actuator_forces"):
        robot.forward_dynamics(pose, twist, [1.0, 2.0, np.nan, 0.0, 0.0, 0.0])
    with pytest.raises(hp.InputError, match="pose"):
        robot.static_forces(pose[:5])


def test_mass_structure_check(robot):
    """The block-diagonal mass matrix that ``reduced`` relies on holds for the tree, and a
    coupling between two leg chains would be refused."""
    clm = robot.model
    mass = pin.crba(clm.model, clm.model.createData(), robot.home_configuration)
    K.check_mass_structure(mass)
    coupled = mass.copy()
    coupled[0, 5] = 1e-3
    with pytest.raises(hp.HexapodPinError, match="block-diagonal"):
        K.check_mass_structure(coupled)


def test_type_two_test_of_the_leg_matrix(robot):
    """Six parallel legs (A of rank 2): the leg factorisation reports TYPE_II, and its
    measure is sigma_min(A_hat) (numpy's SVD of core.measures' A_hat); a regular state
    solves."""
    _, ck, _, _, _ = _state(robot, robot.home_pose, np.zeros(6), np.zeros(6), level=0)
    s = ck.scratch
    tau, mult, jac_t = np.empty(6), np.empty(6), np.empty((6, 6))
    rhs = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    assert K.solve_forces(ck.geo, s.wk, s.mats, rhs, tau, mult, jac_t) == K.OK
    legs = s.wk[[K.NX, K.NY, K.NZ]].T
    arms = s.wk[[K.RX, K.RY, K.RZ]].T
    a_hat = hp.core.measures.closure_matrix_hat(legs / robot.geometry.leg_length,
                                                np.cross(arms, legs) / robot.geometry.leg_length,
                                                robot.geometry.platform_radius)
    want = np.linalg.svd(a_hat, compute_uv=False)[-1]
    assert K.type_two_measure(ck.geo, s.wk, np.empty((6, 6))) == pytest.approx(want, rel=1e-12)
    for row in (K.NX, K.NY, K.NZ):
        s.wk[row, :] = s.wk[row, 0]
    assert K.factor_legs(ck.geo, s.wk, s.mats) == K.TYPE_II
    assert K.solve_forces(ck.geo, s.wk, s.mats, rhs, tau, mult, jac_t) == K.TYPE_II
    assert K.type_two_measure(ck.geo, s.wk, np.empty((6, 6))) < 1e-15


def test_lazy_parts_do_not_follow_the_callers_arrays(robot, rng):
    """Closure forces computed on first access use the inputs as they were at the call,
    even when the caller changes its arrays in between."""
    pose = random_pose(robot, rng)
    twist, twist_dot = _motion(rng)
    wrench = rng.normal(size=6)
    ref_inv = robot.inverse_dynamics(pose.copy(), twist, twist_dot, wrench.copy(),
                                     method="kkt", bounded=False).closure_forces
    forces = robot.inverse_dynamics(pose, twist, twist_dot, wrench, method="kkt",
                                    bounded=False).actuator_forces
    ref_fwd = robot.forward_dynamics(pose.copy(), twist, forces.copy(), wrench).closure_forces
    inv = robot.inverse_dynamics(pose, twist, twist_dot, wrench, method="kkt", bounded=False)
    fwd = robot.forward_dynamics(pose, twist, forces, wrench)
    pose[0] += 0.01
    wrench[2] += 5.0
    forces[:] = 0.0
    np.testing.assert_array_equal(inv.closure_forces, ref_inv)
    np.testing.assert_array_equal(fwd.closure_forces, ref_fwd)

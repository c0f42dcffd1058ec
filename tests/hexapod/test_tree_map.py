"""The closed-form platform -> tree map against Pinocchio's own constraint terms, and the
fast single-state routes built on it against the generic tree solvers.

Independent references: ``ClosedLoopModel.residual / constraint_jacobian /
constraint_drift`` (Pinocchio frames and Jacobians), the generic
``inverse_dynamics_tree`` / ``forward_dynamics_tree`` (square KKT systems on the tree),
the kinematics' Jacobian.
"""

import numpy as np
import pinocchio as pin
import pytest
from conftest import random_pose

import hexapod_pin as hp
from conftest import forward_dynamics_full_tau

from hexapod_pin.core.dynamics import inverse_dynamics_tree
from hexapod_pin.errors import SingularityError
from hexapod_pin.hexapod import kernels as K
from hexapod_pin.hexapod.kinematics import HOME_BRANCH
from hexapod_pin.core.pose import rotation_from_rpy
from hexapod_pin.hexapod.simulation import ClosedLoopIntegrator


def _motion(rng):
    return (np.concatenate([0.1 * rng.normal(size=3), 0.5 * rng.normal(size=3)]),
            np.concatenate([rng.normal(size=3), 3.0 * rng.normal(size=3)]),
            np.concatenate([3.0 * rng.normal(size=3), 0.3 * rng.normal(size=3)]))


def _tree(robot, pose, twist, twist_dot):
    cf = K.ClosedForm(robot.geometry, robot.indices)
    q, v, a = np.empty(25), np.empty(24), np.empty(24)
    assert K.tree_state(cf.geo, HOME_BRANCH, pose, twist, twist_dot, 2, q, v, a,
                        cf.scratch.rot, cf.scratch.wk) == K.OK
    return cf, q, v, a


def test_tree_state_keeps_the_closures(any_robot, rng):
    """J_c v = 0 and J_c a = -gamma with Pinocchio's own J_c and drift; the free-flyer
    part follows the convention (R^T v, R^T w), (R^T (vdot - w x v), R^T wdot)."""
    robot = any_robot
    clm = robot.model
    for _ in range(4):
        pose = random_pose(robot, rng)
        twist, twist_dot, _ = _motion(rng)
        _, q, v, a = _tree(robot, pose, twist, twist_dot)
        assert np.max(np.abs(clm.residual(q))) <= 1e-12
        jac = clm.constraint_jacobian(q)
        scale = max(1.0, np.abs(v).max())
        assert np.max(np.abs(jac @ v)) <= 1e-12 * scale
        gamma = clm.constraint_drift(q, v)
        assert np.max(np.abs(jac @ a + gamma)) <= 1e-11 * max(1.0, np.abs(a).max())
        rot = rotation_from_rpy(pose[3:])
        ff = robot.indices.platform_v
        np.testing.assert_allclose(v[ff], np.concatenate([rot.T @ twist[:3], rot.T @ twist[3:]]),
                                   atol=1e-14)
        np.testing.assert_allclose(
            a[ff], np.concatenate([rot.T @ (twist_dot[:3] - np.cross(twist[3:], twist[:3])),
                                   rot.T @ twist_dot[3:]]), atol=1e-13)
        np.testing.assert_allclose(v[robot.indices.carriage_v], robot.jacobian(pose) @ twist,
                                   atol=1e-12)
        np.testing.assert_allclose(a[robot.indices.carriage_v],
                                   robot.qddot(pose, twist, twist_dot), atol=1e-11)


def test_velocity_map_and_projection(any_robot, rng):
    robot = any_robot
    pose = random_pose(robot, rng)
    twist, _, _ = _motion(rng)
    cf, q, v, _ = _tree(robot, pose, twist, np.zeros(6))
    gmap = np.empty((24, 6))
    K.velocity_map(cf.geo, cf.scratch.rot, cf.scratch.wk, gmap)
    assert np.max(np.abs(robot.model.constraint_jacobian(q) @ gmap)) <= 1e-12
    np.testing.assert_allclose(gmap[robot.indices.carriage_v], robot.jacobian(pose), atol=1e-12)
    np.testing.assert_allclose(gmap @ twist, v, atol=1e-13)
    force = rng.normal(size=robot.model.nv)
    out = np.empty(6)
    K.project(cf.geo, cf.scratch.rot, cf.scratch.wk, force, K.ZERO6, False, out)
    np.testing.assert_allclose(out, gmap.T @ force, atol=1e-12)
    # virtual power: twist . G^T f == (G twist) . f
    assert twist @ gmap.T @ force == pytest.approx(v @ force, rel=1e-12, abs=1e-14)


def test_configuration_at_a_singular_pose_is_still_returned(robot):
    """configuration() keeps its behaviour at a type-I singularity (only the dynamics
    refuses it)."""
    g = robot.geometry
    pose = robot.home_pose.copy()
    pose[2] = np.sqrt(g.leg_length ** 2 - (g.rail_radius - g.platform_radius) ** 2
                      - (3e-8 * g.leg_length) ** 2)
    q = robot.configuration(pose)
    assert np.max(np.abs(robot.model.residual(q))) <= 1e-12
    with pytest.raises(SingularityError):
        robot.static_forces(pose)


def test_single_routes_match_the_generic_tree_solvers(any_robot, rng):
    """ID / FD / statics of the fast route == the generic tree KKT on the same tree state,
    closure multipliers included; the lazy residual is the tree's with Pinocchio's J_c."""
    robot = any_robot
    clm = robot.model
    for _ in range(3):
        pose = random_pose(robot, rng)
        twist, twist_dot, wrench = _motion(rng)
        _, q, v, a = _tree(robot, pose, twist, twist_dot)
        rot = rotation_from_rpy(pose[3:])
        tau_ext = np.zeros(clm.nv)
        tau_ext[robot.indices.platform_v] = np.concatenate([rot.T @ wrench[:3],
                                                            rot.T @ wrench[3:]])
        tree = inverse_dynamics_tree(clm, q, v, a, tau_ext, method="kkt")
        tree_qp = inverse_dynamics_tree(clm, q, v, a, tau_ext, method="qp")
        np.testing.assert_allclose(tree_qp.actuator_forces, tree.actuator_forces, atol=1e-10)
        # an independent reference written here: numpy least squares on the whole tree,
        # [S^T  J_c^T] [tau; lambda] = rnea(q, v, a) - tau_ext (24 rows, 6 + 18 unknowns)
        data = clm.model.createData()
        rhs = pin.rnea(clm.model, data, q, v, a) - tau_ext
        sel = np.zeros((clm.nv, clm.n_actuated))
        sel[clm.actuated_v, np.arange(clm.n_actuated)] = 1.0
        kkt = np.hstack([sel, clm.constraint_jacobian(q).T])
        ref = np.linalg.lstsq(kkt, rhs, rcond=None)[0][:clm.n_actuated]
        np.testing.assert_allclose(tree.actuator_forces, ref, rtol=0,
                                   atol=1e-10 * max(1.0, np.abs(ref).max()))
        for method in ("kkt", "qp"):
            res = robot.inverse_dynamics(pose, twist, twist_dot, wrench, method=method,
                                         bounded=False)
            np.testing.assert_allclose(res.actuator_forces, tree.actuator_forces, atol=1e-10)
            np.testing.assert_allclose(res.multipliers, tree.multipliers, atol=1e-9)
            assert res.residual <= 1e-9
            np.testing.assert_allclose(res.configuration, q, atol=0)
        # the reduced QP is warm-started at the equality-constrained point: ProxSuite
        # certifies it without iterating
        assert res.method == "qp" and res.status == "solved" and res.iterations == 0
        tau = tau_ext.copy()
        tau[clm.actuated_v] += tree.actuator_forces
        fwd_tree = forward_dynamics_full_tau(clm, q, v, tau, method="kkt")
        for method in ("pinocchio", "nullspace", "kkt", "qp"):
            fwd = robot.forward_dynamics(pose, twist, tree.actuator_forces, wrench, method=method)
            np.testing.assert_allclose(fwd.tree_acceleration, fwd_tree.a, atol=1e-10)
            np.testing.assert_allclose(fwd.multipliers, fwd_tree.multipliers, atol=1e-9)
            np.testing.assert_allclose(fwd.twist_dot, twist_dot, atol=1e-10)
        at_q = robot.dynamics.actuator_forces_at(q, twist, twist_dot, wrench)
        np.testing.assert_allclose(at_q, tree.actuator_forces, atol=1e-10)


def test_integrator_with_closed_form_residual_matches_generic(robot):
    fast = ClosedLoopIntegrator(robot.model, residual=robot.closed_form.closure_residual)
    slow = ClosedLoopIntegrator(robot.model)
    q0 = robot.configuration(robot.home_pose + np.array([0.01, 0.0, -0.01, 0.05, 0.0, 0.02]))
    v0 = np.zeros(robot.model.nv)
    tau = np.zeros(robot.model.nv)
    tau[robot.model.actuated_v] = 2.0
    qa, va, qb, vb = q0, v0, q0, v0
    for _ in range(20):
        qa, va, ra = fast.step(qa, va, tau, 1e-3)
        qb, vb, rb = slow.step(qb, vb, tau, 1e-3)
        # both residuals are round-off after the projection (two formulas of one
        # distance: they differ in their last bits); the states must agree
        assert max(ra, rb) < 1e-13 and abs(ra - rb) < 1e-14
    np.testing.assert_allclose(qa, qb, atol=1e-15)
    np.testing.assert_allclose(va, vb, atol=1e-13)


def test_results_are_frozen_and_lazy_fields_cached(robot, rng):
    pose = random_pose(robot, rng)
    twist, twist_dot, wrench = _motion(rng)
    res = robot.inverse_dynamics(pose, twist, twist_dot, wrench, bounded=False)
    first = res.closure_forces
    assert res.closure_forces is first
    with pytest.raises(AttributeError):
        res.actuator_forces = np.zeros(6)
    assert isinstance(hp.Hexapod.default().inverse_dynamics(robot.home_pose, np.zeros(6),
                                                            np.zeros(6)).status, str)

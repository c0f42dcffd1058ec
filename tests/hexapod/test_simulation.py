"""Simulation: energy conservation, equilibrium, tracking, limits, saturation, API."""

import dataclasses
import itertools

import numpy as np
import pinocchio as pin
import pytest

from hexapod_pin.core.integrator_kernels import gauss_newton_pass, rk4_stage
from hexapod_pin.errors import ActuatorSaturationError, InputError, StrokeLimitError
from hexapod_pin.hexapod.simulation import (
    CircleTrajectory,
    ClosedLoopIntegrator,
    ComputedTorqueController,
    PIDController,
    SimState,
    Trajectory,
    simulate,
)


def test_energy_is_conserved_unactuated(robot):
    """2 s, gravity only, no actuation, no load: the mechanism collapses through the rail
    plane and swings (check_limits off: the model has no end stops); total energy from
    Pinocchio's energies (never used by the integrator) must stay within 1e-6 relative."""
    traj = simulate(robot, 2.0, 1e-3, check_limits=False)
    assert traj.status == "completed" and traj.times[-1] == pytest.approx(2.0)
    energy = np.array([robot.tree_energies(q, v).total
                       for q, v in zip(traj.configurations, traj.velocities)])
    kinetic = np.array([robot.tree_energies(q, v).kinetic
                        for q, v in zip(traj.configurations[::50], traj.velocities[::50])])
    assert kinetic.max() > 5.0                                  # a real motion
    assert np.max(np.abs(energy - energy[0])) <= 1e-6 * abs(energy[0])
    assert traj.closure_residual.max() <= 1e-9
    # closures re-checked independently of the integrator's own bookkeeping
    worst = max(np.max(np.abs(robot.model.residual(q))) for q in traj.configurations[::100])
    assert worst <= 1e-9


def test_static_forces_hold_the_platform(robot):
    pose = robot.home_pose + np.array([0.01, -0.01, 0.0, 0.03, 0.02, -0.05])
    tau = robot.static_forces(pose)
    traj = simulate(robot, 0.2, 1e-3, pose0=pose, actuator_forces=tau)
    assert traj.status == "completed"
    np.testing.assert_allclose(traj.poses, np.tile(pose, (len(traj.times), 1)), atol=1e-9)
    assert np.max(np.abs(traj.twists)) < 1e-8


def test_initial_acceleration_matches_forward_dynamics(robot):
    """A short step from rest: q(dt) - q(0) ~ qddot dt^2 / 2 from forward_dynamics."""
    tau = np.array([3.0, -1.0, 2.0, 0.5, -2.0, 1.0])
    dt = 1e-4
    traj = simulate(robot, 2 * dt, dt, actuator_forces=tau)
    qddot = robot.forward_dynamics(robot.home_pose, np.zeros(6), tau).actuator_accelerations
    np.testing.assert_allclose((traj.q[1] - traj.q[0]) * 2 / dt**2, qddot, rtol=1e-3)


def test_pid_follows_a_circle(robot):
    """Quanser gains; the discrete D term needs a control rate above ~2.5 kHz here."""
    ref = CircleTrajectory(robot.home_pose, radius=0.02, period=1.0)
    pid = PIDController(robot, ref)
    traj = simulate(robot, 0.5, 2.5e-4, controller=pid, reference=ref)
    assert traj.status == "completed" and not traj.saturated.any()
    err = np.linalg.norm(traj.poses[:, :3] - traj.reference_poses[:, :3], axis=1)
    assert err.max() < 2e-4
    q_ref = np.array([robot.inverse_kinematics(ref(t).pose) for t in traj.times[::100]])
    assert np.max(np.abs(traj.q[::100] - q_ref)) < 2e-4


def test_computed_torque_follows_a_circle(robot):
    ref = CircleTrajectory(robot.home_pose, radius=0.02, period=1.0)
    ctl = ComputedTorqueController(robot, ref)
    traj = simulate(robot, 0.5, 1e-3, controller=ctl, reference=ref)
    assert traj.status == "completed" and not traj.saturated.any()
    err = np.linalg.norm(traj.poses[:, :3] - traj.reference_poses[:, :3], axis=1)
    assert err.max() < 5e-5
    # the commands are the inverse dynamics of the motion (up to the small tracking error)
    tau_id = robot.inverse_dynamics(ref(0.25).pose, ref(0.25).twist, ref(0.25).twist_dot)
    k = round(0.25 / 1e-3)
    np.testing.assert_allclose(traj.actuator_forces[k], tau_id.actuator_forces, atol=0.2)


def test_stroke_limit_stops_or_raises(robot):
    traj = simulate(robot, 1.0, 1e-3)              # unactuated: carriages slide outwards
    assert traj.status == "stroke_limit"
    assert "rail_half_length" in traj.message
    assert np.max(np.abs(traj.q[-1])) > robot.geometry.rail_half_length
    assert traj.times[-1] < 1.0
    with pytest.raises(StrokeLimitError):
        simulate(robot, 1.0, 1e-3, on_limit="raise")


def test_carriage_gap_stops(robot):
    squeeze = robot.static_forces(robot.home_pose) + 15.0 * np.array([1, -1, 1, -1, 1, -1])
    traj = simulate(robot, 1.0, 1e-3, actuator_forces=squeeze)
    assert traj.status == "carriage_gap", traj.message
    gaps = traj.q[-1, 1::2] - traj.q[-1, 0::2]
    assert gaps.min() < robot.geometry.carriage_min_gap


def test_saturation_policies(robot):
    big = np.full(6, 500.0)
    traj = simulate(robot, 0.002, 1e-3, actuator_forces=big, check_limits=False)
    assert traj.saturated.all()
    assert np.max(np.abs(traj.actuator_forces)) == robot.geometry.max_actuator_force
    with pytest.raises(ActuatorSaturationError):
        simulate(robot, 0.002, 1e-3, actuator_forces=big, saturation="raise")


def test_progress_wrench_and_trajectory_object(robot):
    calls = []
    wrench = np.array([0.0, 0.0, -5.0, 0.0, 0.0, 0.0])
    tau = robot.static_forces(robot.home_pose, wrench)
    traj = simulate(robot, 0.05, 1e-3, actuator_forces=tau, wrench=wrench,
                    progress=lambda done, total: calls.append((done, total)), record_every=5)
    assert calls[-1] == (50, 50) and all(a < b for (a, _), (b, _) in itertools.pairwise(calls))
    assert isinstance(traj, Trajectory) and len(traj.times) == 11
    assert traj.poses.shape == (11, 6) and traj.configurations.shape == (11, robot.model.nq)
    np.testing.assert_allclose(traj.poses[-1], robot.home_pose, atol=1e-9)   # wrench balanced
    with pytest.raises(dataclasses.FrozenInstanceError):
        traj.status = "x"
    assert traj.real_time_factor > 0


def test_controller_receives_the_state(robot):
    seen = []

    def controller(state: SimState, dt):
        seen.append(state)
        return np.zeros(6)

    simulate(robot, 0.003, 1e-3, controller=controller, check_limits=False)
    assert len(seen) == 4 and seen[0].t == 0.0
    np.testing.assert_allclose(seen[0].pose, robot.home_pose, atol=1e-12)
    np.testing.assert_allclose(seen[0].q, robot.home_q, atol=1e-12)


def test_semi_implicit_euler_converges_at_first_order_to_rk4(robot):
    tau = robot.static_forces(robot.home_pose) + 2.0
    rk4 = simulate(robot, 0.04, 1e-3, actuator_forces=tau)
    errors = []
    for dt in (1e-3, 5e-4):
        sie = simulate(robot, 0.04, dt, actuator_forces=tau, integrator="semi_implicit_euler")
        assert sie.closure_residual.max() <= 1e-10
        errors.append(np.max(np.abs(sie.q[-1] - rk4.q[-1])))
    assert 1.6 < errors[0] / errors[1] < 2.4


def test_integrator_rejects_unsupported_joints_and_bad_inputs(robot):
    with pytest.raises(InputError):
        ClosedLoopIntegrator(robot.model, method="euler")
    with pytest.raises(InputError):
        simulate(robot, -1.0)
    with pytest.raises(InputError):
        simulate(robot, 0.01, actuator_forces=np.zeros(6), controller=lambda s, dt: np.zeros(6))
    with pytest.raises(InputError):
        simulate(robot, 0.01, on_limit="ignore")
    with pytest.raises(InputError):
        CircleTrajectory(robot.home_pose, radius=-0.01, period=1.0)


def test_gauss_newton_pass_matches_pseudo_inverse():
    """The compiled projection pass against numpy's pseudo-inverse on the kept rows; a
    singular Gram matrix (a repeated row) is refused with an infinite miss."""
    rng = np.random.default_rng(3)
    jac = rng.normal(size=(12, 22))
    jac[11] = jac[3]
    err = 1e-6 * rng.normal(size=12)
    v = rng.normal(size=22)
    rows = np.array([0, 1, 2, 3, 4, 5, 6, 7, 9, 10])
    step, v_new, out = np.empty(22), np.empty(22), np.empty(1)
    miss = gauss_newton_pass(jac, err, rows, v, step, v_new, out)
    pinv = np.linalg.pinv(jac[rows])
    assert miss <= 1e-12
    np.testing.assert_allclose(step, -pinv @ err[rows], rtol=0, atol=1e-18)
    np.testing.assert_allclose(v_new, v - pinv @ (jac[rows] @ v), rtol=0, atol=1e-12)
    assert out[0] == np.max(np.abs(err))
    assert gauss_newton_pass(jac, err, np.array([3, 11]), v, step, v_new, out) == np.inf
    # rows with zero columns at both ends and between (a closure's row is zero on the
    # joints that move neither anchor): the products skip the zero ends only
    sparse = jac.copy()
    sparse[:6, 8:] = 0.0
    sparse[6:, :5] = 0.0
    sparse[2, 3] = 0.0
    sparse[7, -1] = 0.0
    miss = gauss_newton_pass(sparse, err, rows, v, step, v_new, out)
    pinv = np.linalg.pinv(sparse[rows])
    assert miss <= 1e-12
    np.testing.assert_allclose(step, -pinv @ err[rows], rtol=0, atol=1e-18)
    np.testing.assert_allclose(v_new, v - pinv @ (sparse[rows] @ v), rtol=0, atol=1e-12)
    sparse[4, 10] = np.nan
    assert gauss_newton_pass(sparse, err, rows, v, step, v_new, out) == np.inf


def test_euler_update_matches_pin_integrate():
    """The compiled semi-implicit Euler update of 1-DoF joints against numpy and
    ``pin.integrate`` (revolute and prismatic joints: ``q (+) dt v = q + dt v``)."""
    from hexapod_pin.core.integrator_kernels import euler_update

    model = pin.Model()
    j = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "a")
    model.addJoint(j, pin.JointModelPX(), pin.SE3.Identity(), "b")
    rng = np.random.default_rng(2)
    q, v, a = rng.normal(size=2), rng.normal(size=2), rng.normal(size=2)
    q_out, v_out = np.empty(2), np.empty(2)
    euler_update(q, v, a, 0.01, q_out, v_out)
    np.testing.assert_allclose(v_out, v + 0.01 * a, rtol=0, atol=1e-15)
    np.testing.assert_allclose(q_out, pin.integrate(model, q, 0.01 * (v + 0.01 * a)), rtol=0,
                               atol=1e-15)


def test_rk4_stage_matches_numpy():
    """The compiled stage update against numpy: ``q + h qdot(qs, vs)`` with its quaternion
    renormalised, ``v + h vdot``, the weighted rates accumulated; the combination
    ``q + h rates``; the configuration rate of a free-flyer against a finite difference
    of ``pin.integrate`` (1-DoF joints: ``qdot = v``)."""
    from hexapod_pin.core.integrator_kernels import configuration_rate, rk4_combine

    model = pin.Model()
    ff = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "base")
    model.addJoint(ff, pin.JointModelRY(), pin.SE3.Identity(), "hinge")
    model.addJoint(ff, pin.JointModelPX(), pin.SE3.Identity(), "slide")
    joints = np.array([(1, 0, 0), (0, 7, 6), (0, 8, 7)], dtype=np.int64)
    quat = np.array([3])
    rng = np.random.default_rng(5)
    q = pin.randomConfiguration(model, -np.ones(9), np.ones(9))
    qs = pin.randomConfiguration(model, -np.ones(9), np.ones(9))
    v, vs, a = rng.normal(size=8), rng.normal(size=8), rng.normal(size=8)
    rate = np.empty(9)
    configuration_rate(qs, vs, joints, rate)
    eps = 1e-7
    fd = (pin.integrate(model, qs, eps * vs) - pin.integrate(model, qs, -eps * vs)) / (2 * eps)
    np.testing.assert_allclose(rate, fd, rtol=0, atol=1e-8)
    rates = np.full(17, 0.5)
    q_out, v_out = np.empty(9), np.empty(8)
    rk4_stage(q, v, qs, vs, a, 0.3, 2.0, joints, quat, q_out, v_out, rates)
    want = q + 0.3 * rate
    want[3:7] /= np.linalg.norm(want[3:7])
    np.testing.assert_allclose(q_out, want, rtol=0, atol=1e-15)
    np.testing.assert_allclose(v_out, v + 0.3 * a, rtol=0, atol=1e-15)
    assert abs(np.linalg.norm(q_out[3:7]) - 1.0) < 1e-15
    np.testing.assert_allclose(rates, 0.5 + 2.0 * np.concatenate([rate, a]), rtol=0,
                               atol=1e-15)
    rk4_combine(q, v, rates, 0.1, quat, q_out, v_out)
    want = q + 0.1 * rates[:9]
    want[3:7] /= np.linalg.norm(want[3:7])
    np.testing.assert_allclose(q_out, want, rtol=0, atol=1e-15)
    np.testing.assert_allclose(v_out, v + 0.1 * rates[9:], rtol=0, atol=1e-15)
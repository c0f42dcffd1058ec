"""Hexapod dynamics at the pose / twist level, checked by independent routes.

* reference states from an independent implementation (1e-9 relative);
* FD(ID(x)) == x and ID(FD(tau)) == tau, every route, both geometries;
* virtual power: tau . qdot + wrench . twist == dE/dt (energies differentiated in time);
* statics against a free-body computation written here (no Pinocchio);
* the platform's own Newton-Euler equations with the closure forces;
* the reduced (null-space) dynamics against both routes and the kinetic energy;
* saturation, derivatives against finite differences, batch against single calls.
"""

import numpy as np
import pytest
from conftest import geometry_from_reference, load_reference, random_pose

import hexapod_pin as hp
from hexapod_pin.errors import BatchActuatorSaturationError
from hexapod_pin.errors import ActuatorSaturationError, InputError
from hexapod_pin.core.dynamics import inverse_dynamics_tree
from hexapod_pin.core.pose import euler_rates_matrix, rotation_from_rpy

FD_METHODS = ("pinocchio", "nullspace", "qp", "kkt")
ID_METHODS = ("qp", "kkt")
RAIL = np.array([0, 0, 1, 1, 2, 2])


def _random_motion(rng, speed=0.3, accel=2.0):
    twist = np.concatenate([speed * rng.normal(size=3) * 0.3, speed * rng.normal(size=3)])
    twist_dot = np.concatenate([accel * rng.normal(size=3) * 0.3, accel * rng.normal(size=3)])
    wrench = np.concatenate([3.0 * rng.normal(size=3), 0.3 * rng.normal(size=3)])
    return twist, twist_dot, wrench


# -- reference states ---------------------------------------------------------------------
@pytest.mark.parametrize("index", [0, 1, 2])
def test_reference_states(index):
    entry = load_reference()["hexapod"][index]
    robot = hp.Hexapod(geometry_from_reference(entry))
    pose, twist, twist_dot, wrench = (np.array(entry[k]) for k in
                                      ("pose", "twist", "twist_dot", "wrench"))
    scale = np.max(np.abs(entry["actuator_forces"]))
    for method in ID_METHODS:
        res = robot.inverse_dynamics(pose, twist, twist_dot, wrench, method=method)
        np.testing.assert_allclose(res.actuator_forces, entry["actuator_forces"],
                                   rtol=0, atol=1e-9 * scale)
    static = robot.static_forces(pose, wrench)
    np.testing.assert_allclose(static, entry["static_forces"], rtol=0,
                               atol=1e-9 * np.max(np.abs(entry["static_forces"])))
    for method in FD_METHODS:
        fwd = robot.forward_dynamics(pose, twist, entry["actuator_forces"], wrench, method=method)
        np.testing.assert_allclose(fwd.twist_dot, twist_dot, atol=1e-9 * max(1, np.abs(twist_dot).max()))
        np.testing.assert_allclose(fwd.actuator_accelerations, entry["qddot"], atol=1e-9 * max(1, np.abs(entry["qddot"]).max()))


def test_home_static_forces_number(robot):
    forces = robot.static_forces(robot.home_pose)
    np.testing.assert_allclose(forces, 1.6510015556928 * np.array([1, -1, 1, -1, 1, -1]),
                               rtol=1e-10)


# -- round trips ----------------------------------------------------------------------------
def test_forward_of_inverse_is_identity(any_robot, rng):
    robot = any_robot
    for _ in range(3):
        pose = random_pose(robot, rng)
        twist, twist_dot, wrench = _random_motion(rng)
        inv = {m: robot.inverse_dynamics(pose, twist, twist_dot, wrench, method=m)
               for m in ID_METHODS}
        np.testing.assert_allclose(inv["qp"].actuator_forces, inv["kkt"].actuator_forces,
                                   atol=1e-10)
        for method in FD_METHODS:
            fwd = robot.forward_dynamics(pose, twist, inv["kkt"].actuator_forces, wrench,
                                         method=method)
            np.testing.assert_allclose(fwd.twist_dot, twist_dot, atol=1e-10)
            np.testing.assert_allclose(fwd.closure_forces, inv["kkt"].closure_forces, atol=1e-9)


def test_inverse_of_forward_is_identity(any_robot, rng):
    robot = any_robot
    for _ in range(3):
        pose = random_pose(robot, rng)
        twist, _, wrench = _random_motion(rng)
        tau = robot.static_forces(pose, wrench) + 3.0 * rng.normal(size=6)
        fwd = {m: robot.forward_dynamics(pose, twist, tau, wrench, method=m) for m in FD_METHODS}
        for method in ("qp", "kkt"):
            np.testing.assert_allclose(fwd[method].twist_dot, fwd["pinocchio"].twist_dot,
                                       atol=1e-10)
            np.testing.assert_allclose(fwd[method].tree_acceleration,
                                       fwd["pinocchio"].tree_acceleration, atol=1e-10)
        # qddot is the time derivative of J twist: qddot = J twist_dot + dJ/dt twist
        # (dJ/dt by fourth-order differences along the pose rate)
        h = 1e-5
        pose_dot = np.concatenate([twist[:3], np.linalg.solve(euler_rates_matrix(pose[3:]),
                                                              twist[3:])])
        at = [robot.jacobian(pose + s * h * pose_dot) for s in (2, 1, -1, -2)]
        jdot = (8 * (at[1] - at[2]) - (at[0] - at[3])) / (12 * h)
        expected = robot.jacobian(pose) @ fwd["kkt"].twist_dot + jdot @ twist
        np.testing.assert_allclose(fwd["kkt"].actuator_accelerations, expected,
                                   atol=1e-7 * max(1.0, np.abs(expected).max()))
        for method in ID_METHODS:
            inv = robot.inverse_dynamics(pose, twist, fwd["pinocchio"].twist_dot, wrench,
                                         method=method)
            np.testing.assert_allclose(inv.actuator_forces, tau, atol=1e-10)


# -- energy ------------------------------------------------------------------------------------
def _pose_path(t):
    """A smooth pose path near home and its first two time derivatives (analytic)."""
    amp = np.array([0.015, -0.01, 0.012, 0.06, -0.05, 0.08])
    freq = np.array([1.3, 0.9, 1.7, 1.1, 1.9, 0.7]) * 2 * np.pi
    phase = np.array([0.1, 0.7, 1.3, 0.4, 2.0, 1.1])
    return (amp * np.sin(freq * t + phase), amp * freq * np.cos(freq * t + phase),
            -amp * freq ** 2 * np.sin(freq * t + phase))


def _platform_state(home, t):
    """pose, twist, twist_dot from the analytic pose path (w = E(rpy) rpy_dot)."""
    p, pd, pdd = _pose_path(t)
    pose = home + p
    e = euler_rates_matrix(pose[3:])
    h = 1e-6
    e_dot = (euler_rates_matrix(pose[3:] + h * pd[3:]) - euler_rates_matrix(pose[3:] - h * pd[3:])) / (2 * h)
    twist = np.concatenate([pd[:3], e @ pd[3:]])
    twist_dot = np.concatenate([pdd[:3], e @ pdd[3:] + e_dot @ pd[3:]])
    return pose, twist, twist_dot


def test_virtual_power_equals_rate_of_energy(any_robot):
    robot = any_robot
    rng = np.random.default_rng(7)
    wrench = np.concatenate([2.0 * rng.normal(size=3), 0.2 * rng.normal(size=3)])
    h = 1e-5
    for t in (0.05, 0.31, 0.77):
        pose, twist, twist_dot = _platform_state(robot.home_pose, t)
        tau = robot.inverse_dynamics(pose, twist, twist_dot, wrench).actuator_forces
        qdot = robot.jacobian(pose) @ twist
        power = tau @ qdot + wrench @ twist
        e_plus = robot.energies(*_platform_state(robot.home_pose, t + h)[:2]).total
        e_minus = robot.energies(*_platform_state(robot.home_pose, t - h)[:2]).total
        assert power == pytest.approx((e_plus - e_minus) / (2 * h), rel=1e-6, abs=1e-8)


def test_energies_by_hand(any_robot, rng):
    """Potential: sum m g z_com over the bodies; kinetic = 1/2 twist^T M_x twist."""
    robot = any_robot
    g = robot.geometry
    pose = random_pose(robot, rng)
    twist = 0.2 * rng.normal(size=6)
    tips = pose[:3] + g.platform_points[RAIL] @ rotation_from_rpy(pose[3:]).T   # (6, 3)
    pot = g.gravity * (g.platform_mass * pose[2] + g.leg_mass * np.sum(tips[:, 2]) / 2)
    e = robot.energies(pose, twist)
    assert e.potential == pytest.approx(pot, rel=1e-12)
    m_x, _ = robot.reduced_dynamics(pose, twist)
    assert e.kinetic == pytest.approx(0.5 * twist @ m_x @ twist, rel=1e-12)
    assert e.total == pytest.approx(e.kinetic + e.potential)


# -- statics against a free-body computation ------------------------------------------------
def _free_body_statics(robot, pose, wrench):
    """Static actuator forces by free-body diagrams (no Pinocchio).

    Leg i (uniform rod, weight W at its middle) is loaded at the universal joint and at
    the spherical joint only; moments about the universal joint (no moment about the two
    U axes, no torsion from the weight) give the tip force from the platform on the leg
    ``-W/2 + s_i n_i`` with n_i the unit leg vector. The platform's equilibrium gives a
    6x6 linear system in ``t_i = -s_i``; the carriage's equilibrium along its rail gives
    ``tau_i = t_i (n_i . u_k)``.
    """
    g = robot.geometry
    q = robot.inverse_kinematics(pose)
    rot = rotation_from_rpy(pose[3:])
    r = g.platform_points[RAIL] @ rot.T                    # R p_k per carriage
    carriages = g.rail_midpoints[RAIL] + q[:, None] * g.rail_directions[RAIL]
    legs = pose[:3] + r - carriages
    n = legs / np.linalg.norm(legs, axis=1)[:, None]
    half_weight = np.array([0.0, 0.0, -g.leg_mass * g.gravity / 2])
    # force of leg tip i on the platform: half_weight + t_i n_i
    mat = np.zeros((6, 6))
    rhs = -np.asarray(wrench, float).copy()
    rhs[:3] -= np.array([0.0, 0.0, -g.platform_mass * g.gravity]) + 6 * half_weight
    for i in range(6):
        mat[:3, i] = n[i]
        mat[3:, i] = np.cross(r[i], n[i])
        rhs[3:] -= np.cross(r[i], half_weight)
    t = np.linalg.solve(mat, rhs)
    return t * np.einsum("ij,ij->i", n, g.rail_directions[RAIL]), half_weight + t[:, None] * n


@pytest.mark.parametrize("tilt", [(0.0, 0.0, 0.0), (0.12, -0.08, 0.2), (-0.1, 0.1, -0.15)])
def test_statics_against_free_body_diagrams(any_robot, tilt):
    robot = any_robot
    rng = np.random.default_rng(3)
    pose = robot.home_pose + np.array([0.01, -0.015, -0.01, *tilt])
    for wrench in (np.zeros(6), np.concatenate([5 * rng.normal(size=3), 0.5 * rng.normal(size=3)])):
        expected, tip_forces = _free_body_statics(robot, pose, wrench)
        np.testing.assert_allclose(robot.static_forces(pose, wrench), expected, atol=1e-10)
        res = robot.inverse_dynamics(pose, np.zeros(6), np.zeros(6), wrench)
        np.testing.assert_allclose(res.actuator_forces, expected, atol=1e-10)
        np.testing.assert_allclose(res.closure_forces, tip_forces, atol=1e-10)


# -- platform Newton-Euler with the closure forces -----------------------------------------------
def test_closure_forces_move_the_platform(any_robot, rng):
    """Sum of tip forces + weight + wrench = m vdot; moments = I wdot + w x I w (world)."""
    robot = any_robot
    g = robot.geometry
    pose = random_pose(robot, rng)
    twist, twist_dot, wrench = _random_motion(rng)
    res = robot.inverse_dynamics(pose, twist, twist_dot, wrench)
    rot = rotation_from_rpy(pose[3:])
    r = g.platform_points[RAIL] @ rot.T
    force = res.closure_forces.sum(axis=0) + wrench[:3] + [0, 0, -g.platform_mass * g.gravity]
    np.testing.assert_allclose(force, g.platform_mass * twist_dot[:3], atol=1e-10)
    inertia = rot @ np.diag(g.platform_inertia) @ rot.T
    w = twist[3:]
    moment = np.cross(r, res.closure_forces).sum(axis=0) + wrench[3:]
    np.testing.assert_allclose(moment, inertia @ twist_dot[3:] + np.cross(w, inertia @ w),
                               atol=1e-10)


def test_joint_wrenches_are_consistent(robot, rng):
    pose = random_pose(robot, rng)
    twist, twist_dot, wrench = _random_motion(rng)
    res = robot.inverse_dynamics(pose, twist, twist_dot, wrench)
    wr = res.joint_wrenches
    assert len(wr) == 6 * 3 + 1
    for i in range(6):
        assert wr[f"carriage_{i}"][0] == pytest.approx(res.actuator_forces[i], abs=1e-10)
        assert abs(wr[f"u_{i}_a"][3]) < 1e-10 and abs(wr[f"u_{i}_b"][4]) < 1e-10
    assert np.max(np.abs(wr["platform_joint"])) < 1e-10
    assert robot.inverse_dynamics(pose, twist, twist_dot, joint_wrenches=False).joint_wrenches == {}


# -- reduced dynamics -----------------------------------------------------------------------------
def test_reduced_dynamics_matches_both_routes(any_robot, rng):
    robot = any_robot
    for _ in range(2):
        pose = random_pose(robot, rng)
        twist, twist_dot, wrench = _random_motion(rng)
        red = robot.reduced_dynamics(pose, twist)
        m_x, h_x = red
        assert np.all(np.linalg.eigvalsh(m_x) > 0)
        np.testing.assert_allclose(red.jacobian, robot.jacobian(pose), atol=1e-12)
        tau = robot.inverse_dynamics(pose, twist, twist_dot, wrench, method="qp").actuator_forces
        np.testing.assert_allclose(red.jacobian.T @ tau + wrench, m_x @ twist_dot + h_x,
                                   atol=1e-10)
        tau2 = 5 * rng.normal(size=6)
        fwd = robot.forward_dynamics(pose, twist, tau2, wrench, method="pinocchio")
        np.testing.assert_allclose(np.linalg.solve(m_x, red.jacobian.T @ tau2 + wrench - h_x),
                                   fwd.twist_dot, atol=1e-10)


# -- saturation ---------------------------------------------------------------------------------
def test_fast_motion_saturates(robot):
    pose = robot.home_pose
    twist_dot = np.array([0.0, 0.0, 150.0, 0.0, 0.0, 0.0])   # 15 g upwards: about 240 N
    for method in ID_METHODS:
        with pytest.raises(ActuatorSaturationError) as info:
            robot.inverse_dynamics(pose, np.zeros(6), twist_dot, method=method)
        assert np.max(np.abs(info.value.needed)) > robot.geometry.max_actuator_force
        free = robot.inverse_dynamics(pose, np.zeros(6), twist_dot, method="kkt", bounded=False)
        np.testing.assert_allclose(info.value.needed, free.actuator_forces, rtol=1e-9)
    with pytest.raises(BatchActuatorSaturationError) as info:
        robot.inverse_dynamics_batch([pose, pose], np.zeros((2, 6)),
                                     [np.zeros(6), twist_dot])
    assert info.value.index == 1


# -- batch -------------------------------------------------------------------------------------------
def test_batch_matches_single_calls(robot, rng):
    n = 5
    poses = np.array([random_pose(robot, rng) for _ in range(n)])
    motions = [_random_motion(rng) for _ in range(n)]
    twists, twist_dots, wrenches = (np.array([m[j] for m in motions]) for j in range(3))
    batch = robot.inverse_dynamics_batch(poses, twists, twist_dots, wrenches)
    assert batch.actuator_forces.shape == (n, 6) and batch.closure_forces.shape == (n, 6, 3)
    for k in range(n):
        single = robot.inverse_dynamics(poses[k], twists[k], twist_dots[k], wrenches[k])
        np.testing.assert_allclose(batch.actuator_forces[k], single.actuator_forces, atol=1e-10)
        np.testing.assert_allclose(batch.closure_forces[k], single.closure_forces, atol=1e-10)
    assert np.all(batch.residual < 1e-10)
    with pytest.raises(InputError):
        robot.inverse_dynamics_batch(poses, twists[:2], twist_dots)


# -- derivatives --------------------------------------------------------------------------------------
def _id(robot, pose, twist, twist_dot, wrench):
    return robot.inverse_dynamics(pose, twist, twist_dot, wrench, method="kkt", bounded=False,
                                  joint_wrenches=False).actuator_forces


def test_derivatives_against_finite_differences(any_robot, rng):
    robot = any_robot
    pose = random_pose(robot, rng, scale=0.5)   # away from the workspace boundary
    twist, twist_dot, wrench = _random_motion(rng, speed=0.5)
    d = robot.inverse_dynamics_derivatives(pose, twist, twist_dot, wrench)
    np.testing.assert_allclose(d.actuator_forces, _id(robot, pose, twist, twist_dot, wrench),
                               atol=1e-10)
    h = 1e-6
    eye = np.eye(6)
    fd = {
        "d_pose": [(_id(robot, pose + h * e, twist, twist_dot, wrench)
                    - _id(robot, pose - h * e, twist, twist_dot, wrench)) / (2 * h) for e in eye],
        "d_twist": [(_id(robot, pose, twist + h * e, twist_dot, wrench)
                     - _id(robot, pose, twist - h * e, twist_dot, wrench)) / (2 * h) for e in eye],
        "d_twist_dot": [(_id(robot, pose, twist, twist_dot + h * e, wrench)
                         - _id(robot, pose, twist, twist_dot - h * e, wrench)) / (2 * h)
                        for e in eye],
        "d_wrench": [(_id(robot, pose, twist, twist_dot, wrench + h * e)
                      - _id(robot, pose, twist, twist_dot, wrench - h * e)) / (2 * h) for e in eye],
    }
    for name, cols in fd.items():
        expected = np.array(cols).T
        scale = max(1.0, np.abs(expected).max())
        np.testing.assert_allclose(getattr(d, name), expected, atol=2e-6 * scale, err_msg=name)


def test_derivatives_chain_rule_along_a_path(robot):
    """d tau / dt along a smooth path == D_pose pose' + D_twist twist' + D_twist_dot twist''."""
    t, h = 0.4, 1e-5
    pose, twist, twist_dot = _platform_state(robot.home_pose, t)
    _, pd, _ = _pose_path(t)
    jerk = (_platform_state(robot.home_pose, t + h)[2]
            - _platform_state(robot.home_pose, t - h)[2]) / (2 * h)
    d = robot.inverse_dynamics_derivatives(pose, twist, twist_dot)
    rate = d.d_pose @ pd + d.d_twist @ twist_dot + d.d_twist_dot @ jerk
    tau_plus = _id(robot, *_platform_state(robot.home_pose, t + h), None)
    tau_minus = _id(robot, *_platform_state(robot.home_pose, t - h), None)
    np.testing.assert_allclose(rate, (tau_plus - tau_minus) / (2 * h), rtol=1e-6, atol=1e-6)


def test_bad_inputs_raise(robot):
    with pytest.raises(InputError):
        robot.inverse_dynamics(np.zeros(5), np.zeros(6), np.zeros(6))
    with pytest.raises(InputError):
        robot.forward_dynamics(robot.home_pose, np.zeros(6), np.full(6, np.nan))
    with pytest.raises(InputError):
        robot.forward_dynamics(robot.home_pose, np.zeros(6), np.zeros(6), method="euler")
    with pytest.raises(InputError):
        robot.inverse_dynamics(robot.home_pose, np.zeros(6), np.zeros(6), method="pinocchio")
    with pytest.raises(hp.UnreachablePoseError):
        robot.static_forces(robot.home_pose + np.array([0, 0, 1.0, 0, 0, 0]))


def test_gravity_comes_from_the_geometry():
    """Static forces scale with geometry.gravity (the URDF itself carries none)."""
    base = hp.Hexapod(hp.HexapodGeometry(gravity=9.81)).static_forces(hp.HexapodGeometry().home_pose)
    double = hp.Hexapod(hp.HexapodGeometry(gravity=19.62))
    np.testing.assert_allclose(double.static_forces(double.home_pose), 2 * base, rtol=1e-12)
    none = hp.Hexapod(hp.HexapodGeometry(gravity=0.0))
    np.testing.assert_allclose(none.static_forces(none.home_pose), 0.0, atol=1e-12)
    assert none.energies(none.home_pose, np.zeros(6)).potential == 0.0


def test_dynamics_on_another_ik_branch(robot):
    """Every dynamics route takes the IK branch: on a regular non-home branch (the two
    carriages of rail 0 swapped to the other roots) the closed-form routes agree with the
    generic tree routes on the configuration of that branch, and the round trips hold."""
    pose = robot.home_pose + np.array([0.01, -0.02, 0.01, 0.05, -0.03, 0.1])
    branch = [1, -1, -1, 1, -1, 1]
    twist, twist_dot = np.full(6, 0.1), np.ones(6)
    q = robot.configuration(pose, branch)
    assert np.abs(robot.actuator_positions(q)
                  - robot.inverse_kinematics(pose, branch, check_limits=False)).max() == 0.0
    assert np.abs(robot.actuator_positions(q) - robot.inverse_kinematics(
        pose, check_limits=False)).max() > 1e-3          # really another configuration
    res = robot.inverse_dynamics(pose, twist, twist_dot, branch=branch, bounded=False)
    np.testing.assert_array_equal(res.configuration, q)
    tree = inverse_dynamics_tree(robot.model, q, res.velocity, res.acceleration, method="kkt")
    np.testing.assert_allclose(res.actuator_forces, tree.actuator_forces, rtol=0, atol=1e-10)
    assert res.residual < 1e-10
    fwd = robot.forward_dynamics(pose, twist, res.actuator_forces, branch=branch)
    np.testing.assert_allclose(fwd.twist_dot, twist_dot, rtol=0, atol=1e-10)
    np.testing.assert_allclose(fwd.closure_forces, res.closure_forces, rtol=0, atol=1e-9)
    rest = robot.inverse_dynamics(pose, np.zeros(6), np.zeros(6), branch=branch,
                                  bounded=False).actuator_forces
    np.testing.assert_allclose(robot.static_forces(pose, branch=branch, bounded=False), rest,
                               rtol=0, atol=1e-10)
    m_x, h_x = robot.reduced_dynamics(pose, twist, branch=branch)
    jac = robot.jacobian(pose, branch)
    np.testing.assert_allclose(jac.T @ res.actuator_forces, m_x @ twist_dot + h_x, rtol=0,
                               atol=1e-9)
    kinetic = 0.5 * res.velocity @ robot.dynamics.tree_dynamics.mass_matrix(q) @ res.velocity
    assert robot.energies(pose, twist, branch=branch).kinetic == pytest.approx(kinetic,
                                                                                rel=1e-12)

"""The closed-loop regressor against closed-loop inverse dynamics (an independent route:
the robots' KKT / closed-form inverse dynamics of a robot built with the parameters)."""

from __future__ import annotations

import numpy as np
import pytest
import robot_registry
from identification_helpers import ROBOTS, random_consistent

from hexapod_pin.errors import ArgumentTypeError, InputError, MotionSampleError
from hexapod_pin.identification import (
    DRIVE_KINDS,
    ClosedLoopRegressor,
    base_parameters,
    nominal_parameters,
    random_states,
    regressor,
    regressor_batch,
    robot_with_parameters,
)


@pytest.fixture(params=ROBOTS)
def id_robot(request):
    """Each robot of the issue's checks in turn (a fixture here, not in a conftest.py:
    a second conftest module would shadow tests/conftest.py's ``from conftest import``)."""
    return request.param, robot_registry.get(request.param)


def test_nominal_parameters_give_the_robots_own_inverse_dynamics(id_robot):
    """With the robot's own parameters, Y pi is its inverse dynamics (closed form for the
    hexapod and the planar robot), drives with armature, damping and friction included."""
    _, robot = id_robot
    n = robot.n_actuators
    rng = np.random.default_rng(3)
    driven = robot.with_effects(armature={j: a for j, a in zip(robot.model.actuated_joints,
                                                                rng.uniform(0.01, 0.1, n))},
                                damping={j: a for j, a in zip(robot.model.actuated_joints,
                                                              rng.uniform(1, 3, n))},
                                coulomb={j: a for j, a in zip(robot.model.actuated_joints,
                                                              rng.uniform(0.5, 1, n))})
    poses, twists, twist_dots = random_states(robot, 3, seed=4)
    pi = nominal_parameters(driven, DRIVE_KINDS)
    for k in range(3):
        rows = regressor(driven, poses[k], twists[k], twist_dots[k], DRIVE_KINDS)
        u = driven.inverse_dynamics(poses[k], twists[k], twist_dots[k],
                                    bounded=False).actuator_forces
        assert np.max(np.abs(rows @ pi - u)) <= 1e-10 * max(1.0, np.max(np.abs(u)))


def test_random_consistent_parameters_match_inverse_dynamics(id_robot):
    """Y pi = closed-loop inverse dynamics (1e-10) of a robot built with random physically
    consistent inertias and drive parameters (offsets 0: no model field holds them)."""
    _, robot = id_robot
    rng = np.random.default_rng(11)
    drive = ("armature", "viscous", "coulomb", "offset")
    pi = random_consistent(robot, drive, rng)
    reg = ClosedLoopRegressor(robot, drive)
    pi[reg.layout.drive_slice("offset")] = 0.0
    other = robot_with_parameters(robot, pi, drive)
    poses, twists, twist_dots = random_states(robot, 4, seed=5)
    batch = reg.batch(poses, twists, twist_dots)
    u = other.inverse_dynamics_batch(poses, twists, twist_dots, bounded=False).actuator_forces
    scale = max(1.0, float(np.max(np.abs(u))))
    assert np.max(np.abs(batch @ pi - u.reshape(-1))) <= 1e-10 * scale
    # the offsets add a constant force per actuator
    off = np.zeros_like(pi)
    off[reg.layout.drive_slice("offset")] = 1.0
    assert np.allclose(batch @ off, 1.0, atol=0.0)


def test_batch_is_the_single_rows_stacked():
    robot = robot_registry.get("planar")
    poses, twists, twist_dots = random_states(robot, 3, seed=1)
    batch = regressor_batch(robot, poses, twists, twist_dots)
    single = np.vstack([regressor(robot, p, t, d) for p, t, d in zip(poses, twists,
                                                                     twist_dots)])
    assert np.array_equal(batch, single)


def test_bad_inputs_name_the_argument():
    robot = robot_registry.get("planar")
    pose = robot.home_pose
    with pytest.raises(InputError, match="twist"):
        regressor(robot, pose, [0.0, 0.0], [0.0, 0.0, 0.0])
    with pytest.raises(InputError, match="twist_dot"):
        regressor(robot, pose, np.zeros(3), [np.nan, 0.0, 0.0])
    with pytest.raises(InputError, match="drive"):
        regressor(robot, pose, np.zeros(3), np.zeros(3), drive=("viscous", "friction"))
    with pytest.raises(InputError, match="drive"):
        regressor(robot, pose, np.zeros(3), np.zeros(3), drive="viscous")
    with pytest.raises(ArgumentTypeError, match="robot"):
        regressor("planar", pose, np.zeros(3), np.zeros(3))
    with pytest.raises(InputError, match="twists"):
        regressor_batch(robot, np.tile(pose, (2, 1)), np.zeros((3, 3)), np.zeros((2, 3)))
    with pytest.raises(MotionSampleError) as info:
        regressor_batch(robot, np.vstack([pose, pose + [5.0, 0.0, 0.0]]), np.zeros((2, 3)),
                        np.zeros((2, 3)))
    assert info.value.index == 1
    with pytest.raises(InputError, match="parameters"):
        robot_with_parameters(robot, np.zeros(5))
    with pytest.raises(InputError, match="rtol"):
        base_parameters(robot, rtol=-1.0)


def test_log_cholesky_body_map_against_finite_differences():
    """The consistent fit's body map: its Jacobian against central differences, the mass
    m_0 exp(2 theta_3), and theta = 0 giving the reference (nominal plus the lift)."""
    from hexapod_pin.identification.consistent import LIFT, BodyReference, pseudo_inertia
    rng = np.random.default_rng(2)
    import pinocchio as pin
    nominal = pin.Inertia(0.5, np.array([0.01, -0.02, 0.03]),
                          np.diag([0.004, 0.005, 0.003])).toDynamicParameters()
    ref = BodyReference.of(nominal, 0.2)
    theta = rng.normal(scale=0.3, size=10)
    pi, jac = ref.parameters(theta)
    step = 1e-6
    fd = np.column_stack([(ref.parameters(theta + step * e)[0]
                           - ref.parameters(theta - step * e)[0]) / (2 * step)
                          for e in np.eye(10)])
    assert np.allclose(jac, fd, rtol=1e-6, atol=1e-10)
    assert np.isclose(pi[0], nominal[0] * np.exp(2 * theta[3]), rtol=1e-12)
    lifted = pseudo_inertia(nominal) + LIFT * 0.5 * 0.2 ** 2 * np.diag([1.0, 1.0, 1.0, 0.0])
    assert np.allclose(pseudo_inertia(ref.parameters(np.zeros(10))[0]), lifted, atol=1e-15)
    assert np.linalg.eigvalsh(pseudo_inertia(pi))[0] > 0

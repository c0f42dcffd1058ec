"""Property-based tests (hypothesis) over poses in the workspace of both geometries."""

import numpy as np
import pinocchio as pin
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import hexapod_pin as hp
from hexapod_pin.hexapod.kinematics import RAIL_OF

import robot_registry

ROBOTS = {"default": robot_registry.get("hexapod"), "second": robot_registry.get("hexapod-second")}
PROFILE = settings(max_examples=40, deadline=None, database=None,
                   suppress_health_check=[HealthCheck.filter_too_much, HealthCheck.too_slow])

offsets = st.tuples(*[st.floats(-0.04, 0.04)] * 2, st.floats(-0.12, 0.03),
                    *[st.floats(-0.3, 0.3)] * 3)
robots = st.sampled_from(sorted(ROBOTS))


def workspace_pose(name, offset):
    """A pose of the workspace: reachable, inside the strokes, not near a singularity."""
    robot = ROBOTS[name]
    pose = robot.home_pose + np.array(offset)
    try:
        robot.inverse_kinematics(pose)
        measures = robot.singularity(pose)
    except hp.HexapodPinError:
        assume(False)
    assume(measures.type_one > 1e-3 and measures.type_two > 1e-3)
    return robot, pose


@PROFILE
@given(robots, offsets)
def test_forward_inverts_inverse(name, offset):
    robot, pose = workspace_pose(name, offset)
    q = robot.inverse_kinematics(pose)
    np.testing.assert_allclose(robot.forward_kinematics(q, pose + 1e-3), pose, atol=1e-11)


@PROFILE
@given(robots, offsets)
def test_threefold_symmetry(name, offset):
    """Turning the pose by 120 deg about z (t -> Rz t, R -> Rz R Rz^T) moves every carriage to
    the next rail: q'_{i+2} = q_i; the Jacobian rows follow, their columns rotate."""
    robot, pose = workspace_pose(name, offset)
    turn = pin.rpy.rpyToMatrix(0.0, 0.0, 2 * np.pi / 3)
    rot = turn @ pin.rpy.rpyToMatrix(*pose[3:]) @ turn.T
    turned = np.concatenate([turn @ pose[:3], pin.rpy.matrixToRpy(rot)])
    q = robot.inverse_kinematics(pose)
    np.testing.assert_allclose(robot.inverse_kinematics(turned), np.roll(q, 2), atol=1e-13)
    jac, jac_turned = robot.jacobian(pose), robot.jacobian(turned)
    block = np.kron(np.eye(2), turn)                       # twist' = blockdiag(Rz, Rz) twist
    np.testing.assert_allclose(jac_turned @ block, np.roll(jac, 2, axis=0), rtol=1e-11,
                               atol=1e-11)


@PROFILE
@given(robots, offsets, st.lists(st.floats(-1, 1), min_size=12, max_size=12))
def test_velocity_level_consistency(name, offset, numbers):
    robot, pose = workspace_pose(name, offset)
    twist, twist_dot = np.array(numbers[:6]), np.array(numbers[6:])
    jac = robot.jacobian(pose)
    qdot = jac @ twist
    np.testing.assert_allclose(robot.twist_from_qdot(pose, qdot), twist, rtol=1e-8, atol=1e-8)
    # qddot is affine in twist_dot with slope J and offset dJ/dt twist
    base = robot.qddot(pose, twist, np.zeros(6))
    np.testing.assert_allclose(base, robot.jacobian_derivative(pose, twist) @ twist, rtol=1e-12,
                               atol=1e-12)
    np.testing.assert_allclose(robot.qddot(pose, twist, twist_dot) - base, jac @ twist_dot,
                               rtol=1e-9, atol=1e-9)
    motion = robot.leg_motion(pose, twist, twist_dot)
    np.testing.assert_allclose(motion.qdot, qdot, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(motion.direction, axis=1), 1.0, atol=1e-14)
    # leg tips move with the platform point: v_com + w x (L/2 e) = dP_k/dt
    g = robot.geometry
    arms = robot.platform_points_world(pose)[RAIL_OF] - pose[:3]
    tip_vel = twist[:3] + np.cross(twist[3:], arms)
    half_leg = 0.5 * g.leg_length * motion.direction
    np.testing.assert_allclose(motion.com_velocity + np.cross(motion.angular_velocity, half_leg),
                               tip_vel, atol=1e-10)


@PROFILE
@given(robots, offsets)
def test_singularity_measures_are_bounded_and_batch_agrees(name, offset):
    robot, pose = workspace_pose(name, offset)
    s = robot.singularity(pose)
    assert 0.0 < s.type_one <= 1.0 and 0.0 < s.type_two <= 1.0 + 1e-12
    assert s.condition_number >= 1.0
    batch = robot.jacobian_batch(np.stack([pose, pose + 1e-4]))
    assert batch.ok[0]
    np.testing.assert_allclose(batch.jacobian[0], robot.jacobian(pose), rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(batch.actuator_positions[0], robot.inverse_kinematics(pose), atol=1e-15)

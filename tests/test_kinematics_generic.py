"""The generic ProxSuite route on ClosedLoopModel (any robot): tree velocities and
accelerations from actuated ones, workspace Jacobian of any frame. Checked against the
hexapod's closed forms (both geometries) and, on a planar four-bar with a rank-deficient
point closure, against finite differences of assembled configurations."""

import numpy as np
import pinocchio as pin
import pytest

import hexapod_pin as hp
from hexapod_pin.core.closed_loop import ClosedLoopModel
from hexapod_pin.core.description import build_model, parse_loops

from conftest import random_pose

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def test_platform_jacobian_is_the_inverse_of_the_closed_form(any_robot, rng):
    for _ in range(3):
        pose = random_pose(any_robot, rng)
        tree_q = any_robot.configuration(pose)
        gen = any_robot.model.frame_jacobian_from_actuated(tree_q, "platform")
        jac = any_robot.jacobian(pose)
        np.testing.assert_allclose(jac @ gen, np.eye(6), atol=1e-10)
        np.testing.assert_allclose(gen, np.linalg.inv(jac), rtol=1e-10,
                                   atol=1e-10 * np.max(np.abs(gen)))


def test_tree_velocity_matches_twist_and_leg_motion(any_robot, rng):
    model = any_robot.model
    for _ in range(2):
        pose = random_pose(any_robot, rng)
        twist = rng.normal(scale=0.3, size=6)
        motion = any_robot.leg_motion(pose, twist)
        tree_q = any_robot.configuration(pose)
        v = model.velocity_from_actuated(tree_q, motion.qdot)
        assert np.max(np.abs(model.constraint_jacobian(tree_q) @ v)) < 1e-12
        np.testing.assert_allclose(v[any_robot.indices.carriage_v], motion.qdot, atol=0)
        # Pinocchio's free-flyer velocity is in the body frame: (R^T v, R^T w)
        rot = pin.rpy.rpyToMatrix(*pose[3:])
        body = v[any_robot.indices.platform_v]
        np.testing.assert_allclose(np.concatenate([rot @ body[:3], rot @ body[3:]]), twist,
                                   atol=1e-10)
        pin.forwardKinematics(model.model, model.data, tree_q, v)
        pin.updateFramePlacements(model.model, model.data)
        for i in range(6):
            fid = model.model.getFrameId(f"leg_{i}")
            vel = pin.getFrameVelocity(model.model, model.data, fid, LWA)
            np.testing.assert_allclose(vel.angular, motion.angular_velocity[i], atol=1e-10)
            com = motion.com_position[i] - model.data.oMf[fid].translation
            np.testing.assert_allclose(vel.linear + np.cross(vel.angular, com),
                                       motion.com_velocity[i], atol=1e-10)
        # the same through the actuated-velocity map
        gmap = model.actuated_velocity_map(tree_q)
        np.testing.assert_allclose(gmap @ motion.qdot, v, atol=1e-10)


def test_tree_acceleration_matches_twist_dot_and_leg_motion(any_robot, rng):
    model = any_robot.model
    pose = random_pose(any_robot, rng)
    twist, twist_dot = rng.normal(scale=0.3, size=6), rng.normal(size=6)
    motion = any_robot.leg_motion(pose, twist, twist_dot)
    tree_q = any_robot.configuration(pose)
    v = model.velocity_from_actuated(tree_q, motion.qdot)
    a = model.acceleration_from_actuated(tree_q, v, motion.qddot)
    pin.forwardKinematics(model.model, model.data, tree_q, v, a)
    pin.updateFramePlacements(model.model, model.data)
    platform = model.model.getFrameId("platform")
    acc = pin.getFrameClassicalAcceleration(model.model, model.data, platform, LWA)
    np.testing.assert_allclose(acc.vector, twist_dot, atol=1e-9)
    for i in range(6):
        fid = model.model.getFrameId(f"leg_{i}")
        leg_acc = pin.getFrameAcceleration(model.model, model.data, fid, LWA)
        np.testing.assert_allclose(leg_acc.angular, motion.angular_acceleration[i], atol=1e-9)


def test_generic_route_input_errors(robot):
    q = robot.home_configuration
    with pytest.raises(hp.InputError):
        robot.model.frame_jacobian_from_actuated(q, "no_such_frame")
    with pytest.raises(hp.InputError):
        robot.model.frame_jacobian_from_actuated(q, 10 ** 6)
    with pytest.raises(hp.InputError):
        robot.model.velocity_from_actuated(q, np.zeros(5))
    with pytest.raises(hp.InputError):
        robot.model.velocity_from_actuated(q[:-1], np.zeros(6))
    with pytest.raises(hp.InputError):
        robot.model.acceleration_from_actuated(q, np.zeros(robot.model.nv), [np.nan] * 6)


# -- a robot that is not the hexapod: a planar four-bar ------------------------------------------
CRANK, COUPLER, ROCKER, GROUND = 0.1, 0.3, 0.25, 0.3
INERTIAL = ('<inertial><mass value="1"/>'
            '<inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial>')
LIMIT = '<limit lower="-10" upper="10" effort="1" velocity="1"/>'

FOUR_BAR = f"""<?xml version="1.0"?>
<robot name="four_bar">
  <link name="world"/>
  <joint name="crank" type="revolute">
    <parent link="world"/><child link="crank_link"/>
    <origin xyz="0 0 0"/><axis xyz="0 0 1"/>{LIMIT}
  </joint>
  <link name="crank_link">
    {INERTIAL}
  </link>
  <joint name="coupler" type="revolute">
    <parent link="crank_link"/><child link="coupler_link"/>
    <origin xyz="{CRANK} 0 0"/><axis xyz="0 0 1"/>{LIMIT}
  </joint>
  <link name="coupler_link">
    {INERTIAL}
  </link>
  <joint name="coupler_tip_mount" type="fixed">
    <parent link="coupler_link"/><child link="coupler_tip"/><origin xyz="{COUPLER} 0 0"/>
  </joint>
  <link name="coupler_tip"/>
  <joint name="rocker" type="revolute">
    <parent link="world"/><child link="rocker_link"/>
    <origin xyz="{GROUND} 0 0"/><axis xyz="0 0 1"/>{LIMIT}
  </joint>
  <link name="rocker_link">
    {INERTIAL}
  </link>
  <joint name="rocker_tip_mount" type="fixed">
    <parent link="rocker_link"/><child link="rocker_tip"/><origin xyz="{ROCKER} 0 0"/>
  </joint>
  <link name="rocker_tip"/>
</robot>
"""

FOUR_BAR_LOOPS = """
closures:
  - {name: pin, type: point, frame1: coupler_tip, frame2: rocker_tip}
actuated: [crank]
"""


@pytest.fixture(scope="module")
def four_bar():
    return ClosedLoopModel(build_model(FOUR_BAR, "four_bar"), parse_loops(FOUR_BAR_LOOPS),
                           name="four_bar")


def _assembled(model, crank, guess):
    q = np.array(guess, dtype=float)
    q[0] = crank
    return model.assemble(q, tol=1e-15).q


def test_four_bar_velocity_and_frame_jacobian_match_finite_differences(four_bar):
    """The point closure of a planar linkage has an identically zero z row (rank 2 of 3):
    the proximal QP copes; velocities equal differences of assembled configurations."""
    assert four_bar.rank(_assembled(four_bar, 0.5, [0.5, 0.4, 1.8])).rank == 2
    q0 = _assembled(four_bar, 0.5, [0.5, 0.4, 1.8])
    h = 1e-5
    plus = _assembled(four_bar, 0.5 + h, q0)
    minus = _assembled(four_bar, 0.5 - h, q0)
    fd = pin.difference(four_bar.model, minus, plus) / (2 * h)
    np.testing.assert_allclose(four_bar.velocity_from_actuated(q0, [1.0]), fd, atol=1e-8)
    np.testing.assert_allclose(four_bar.actuated_velocity_map(q0)[:, 0], fd, atol=1e-8)
    tip = four_bar.model.getFrameId("coupler_tip")
    positions = []
    for q in (minus, plus):
        pin.framesForwardKinematics(four_bar.model, four_bar.data, q)
        positions.append(four_bar.data.oMf[tip].translation.copy())
    jac = four_bar.frame_jacobian_from_actuated(q0, "coupler_tip")
    np.testing.assert_allclose(jac[:3, 0], (positions[1] - positions[0]) / (2 * h), atol=1e-8)
    # second differences: tree acceleration at unit crank speed, zero crank acceleration
    v = four_bar.velocity_from_actuated(q0, [1.0])
    acc = four_bar.acceleration_from_actuated(q0, v, [0.0])
    def second(h):
        return (pin.difference(four_bar.model, q0, _assembled(four_bar, 0.5 + h, q0))
                + pin.difference(four_bar.model, q0, _assembled(four_bar, 0.5 - h, q0))) / h ** 2

    np.testing.assert_allclose(acc, (4 * second(1e-3) - second(2e-3)) / 3, atol=1e-7)

"""Cartesian stiffness and vibration modes (hexapod_pin.core.stiffness) of every robot.

Independent routes: the stiffness against Richardson-extrapolated central differences
(steps 3e-4, 1.5e-4, 7.5e-5 in the world tangent ``(dp, exp(dtheta) R)``) of the net
platform wrench ``W_net(x) = J(x)^T (tau_0 - K_a (q_a(x) - q_a(x0))) - J(x)^T tau_s(x)``,
built here from the robots' Jacobian, inverse kinematics and static forces; the modes
against ``scipy.linalg.eigh`` of that finite-difference stiffness and the reduced
dynamics' mass matrix.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg

import robot_registry
from hexapod_pin.errors import InputError, SingularityError
from test_dynamics_derivatives import displaced, richardson

ROBOTS = ("hexapod", "planar", "stewart", "delta", "four-bar", "five-bar")
RTOL = 1e-7


def numerical_stiffness(robot, pose, k, wrench):
    """``-d W_net / dx`` (dim, dim) by finite differences (module docstring)."""
    dim = robot.pose_layout.dim
    tau0 = robot.static_forces(pose, wrench, bounded=False)
    qa0 = robot.inverse_kinematics(pose, check_limits=False)

    def net(x):
        jac = robot.jacobian(x)
        spring = tau0 - k * (robot.inverse_kinematics(x, check_limits=False) - qa0)
        return jac.T @ spring - jac.T @ robot.static_forces(x, wrench, bounded=False)

    return -np.array([richardson(lambda s: net(displaced(robot, pose, s * np.eye(dim)[j])),
                                 3e-4) for j in range(dim)]).T


def robot_with(name, effects):
    robot = robot_registry.get(name)
    if not effects:
        return robot
    clm, q = robot.model, robot.home_configuration
    rng = np.random.default_rng(2)
    return robot.with_effects(stiffness=rng.uniform(1, 5, clm.nv), armature=rng.uniform(
        0.01, 0.05, clm.nv), spring_reference=pin.integrate(clm.model, q,
                                                            rng.uniform(-0.3, 0.3, clm.nv)))


@pytest.mark.parametrize("effects", [False, True], ids=["rigid", "springs"])
@pytest.mark.parametrize("name", ROBOTS)
def test_stiffness_matches_the_net_wrench(name, effects):
    robot = robot_with(name, effects)
    dim, rng = robot.pose_layout.dim, np.random.default_rng(4)
    pose = robot.home_pose + 0.01 * rng.uniform(-1, 1, dim)
    wrench = rng.normal(size=dim)
    k = rng.uniform(1e4, 2e4, robot.n_actuators)
    st = robot.cartesian_stiffness(pose, k, wrench)
    num = numerical_stiffness(robot, pose, k, wrench)
    assert np.max(np.abs(st.matrix - num)) < RTOL * np.max(np.abs(num))
    jac = robot.jacobian(pose)
    np.testing.assert_allclose(st.elastic, jac.T @ np.diag(k) @ jac, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(st.matrix, st.elastic + st.geometric, rtol=0, atol=1e-9)
    np.testing.assert_allclose(st.static_forces, robot.static_forces(pose, wrench,
                                                                      bounded=False))
    np.testing.assert_allclose(st.compliance @ st.matrix, np.eye(dim), atol=1e-9)


@pytest.mark.parametrize("name", ROBOTS)
def test_gravity_preload_is_symmetric_and_modes_match_eigh(name):
    """Gravity is conservative: at the equilibrium ``K_g`` is symmetric. The modes are
    those of ``eigh(K_x, M_x)`` with the finite-difference ``K_x`` and the reduced
    dynamics' ``M_x``, frequencies in Hz ascending, shapes M_x-orthonormal."""
    robot = robot_registry.get(name)
    dim = robot.pose_layout.dim
    pose, k = robot.home_pose, 1e5
    modes = robot.vibration_modes(pose, k)
    st = modes.stiffness
    assert np.max(np.abs(st.geometric - st.geometric.T)) < 1e-9 * max(1.0, np.max(np.abs(
        st.geometric)))
    kx = numerical_stiffness(robot, pose, np.full(robot.n_actuators, k), None)
    mass = robot.reduced_dynamics(pose, np.zeros(dim)).mass_matrix
    values = scipy.linalg.eigh(0.5 * (kx + kx.T), mass, eigvals_only=True)
    np.testing.assert_allclose(modes.frequencies, np.sqrt(values) / (2 * np.pi), rtol=1e-6)
    assert np.all(np.diff(modes.frequencies) >= 0)
    np.testing.assert_allclose(modes.shapes.T @ mass @ modes.shapes, np.eye(dim), atol=1e-8)
    np.testing.assert_allclose(st.mass_matrix, mass, rtol=1e-9, atol=1e-12)
    vals, vecs = st.principal_stiffnesses, st.principal_directions
    np.testing.assert_allclose(vecs.T @ vecs, np.eye(dim), atol=1e-12)
    np.testing.assert_allclose(0.5 * (st.matrix + st.matrix.T) @ vecs, vecs * vals,
                               atol=1e-8 * np.max(np.abs(vals)))


def test_stiffer_actuators_raise_the_frequencies():
    robot = robot_registry.get("stewart")
    soft = robot.vibration_modes(robot.home_pose, 1e4).frequencies
    stiff = robot.vibration_modes(robot.home_pose, 4e4).frequencies
    assert np.all(stiff > soft)


def test_an_unstable_preload_is_refused():
    """No actuator stiffness: the hexapod under gravity with its forces held is statically
    unstable (a negative omega^2), which vibration_modes refuses."""
    robot = robot_registry.get("hexapod")
    with pytest.raises(SingularityError, match="positive semi-definite"):
        robot.vibration_modes(robot.home_pose, 0.0)


def test_bad_input():
    robot = robot_registry.get("four-bar")
    with pytest.raises(InputError, match=">= 0"):
        robot.cartesian_stiffness(robot.home_pose, -1.0)
    with pytest.raises(InputError):
        robot.cartesian_stiffness(robot.home_pose, [1.0, 2.0])
    with pytest.raises(InputError):
        robot.vibration_modes(robot.home_pose, np.nan)
    friction = robot.with_effects(coulomb=np.full(robot.model.nv, 0.1))
    with pytest.raises(InputError, match="at rest"):
        friction.cartesian_stiffness(friction.home_pose, 1e3)

"""Analytic derivatives of the hexapod's inverse dynamics (the compiled kernel of
hexapod_pin.hexapod.derivatives behind the core chain rule).

Independent routes, built here:

* central differences (Richardson, fourth order) of ``robot.inverse_dynamics(...,
  method="kkt", bounded=False)`` (the Pinocchio tree route) in the pose coordinates and
  along world rotations ``R -> exp([dtheta]) R`` (``pin.exp3``); exact central differences
  in the twist, twist_dot and wrench, in which the forces are polynomials of degree <= 2;
* the reduced dynamics ``d tau / d twist_dot = J^-T M_x`` (crba-based route);
* the chain rule along a smooth motion with exact twist, twist_dot and jerk;
* mutants (a wrong frame convention, a wrong sign, the twist held in body axes) that the
  comparison must reject.

The kernel against the core's tree route: tests/core/test_closed_form_derivatives.py;
Pinocchio's constrained-dynamics derivatives on the hexapod's closures (which the retired
derivation relied on): tests/core/test_dynamics_derivatives.py.
"""

import numpy as np
import pinocchio as pin
import pytest
from conftest import random_pose

import hexapod_pin as hp
from hexapod_pin.errors import InputError, SingularityError, UnreachablePoseError
from hexapod_pin.core.pose import euler_rates_matrix, rotation_from_rpy, rpy_from_rotation

#: relative tolerance against the Richardson differences (steps 5e-5 and 2.5e-5: their
#: truncation error is ~1e-9 here, 1.5e-7 at one sampled state with steps 2e-4)
FD_RTOL = 1e-7
#: relative tolerance where the differences are exact up to round-off
EXACT_RTOL = 1e-9
EYE = np.eye(6)


def _tau(robot, pose, twist, twist_dot, wrench):
    return robot.inverse_dynamics(pose, twist, twist_dot, wrench, method="kkt", bounded=False,
                                  joint_wrenches=False).actuator_forces


def _motion(rng, speed=0.4, accel=2.0):
    twist = np.concatenate([0.3 * speed * rng.normal(size=3), speed * rng.normal(size=3)])
    twist_dot = np.concatenate([0.3 * accel * rng.normal(size=3), accel * rng.normal(size=3)])
    wrench = np.concatenate([3.0 * rng.normal(size=3), 0.3 * rng.normal(size=3)])
    return twist, twist_dot, wrench


def _richardson(fun, h):
    """Fourth-order central differences, one column per direction of ``fun(step)``."""
    def central(step):
        return np.array([(fun(step * e) - fun(-step * e)) / (2 * step) for e in EYE]).T
    return (4.0 * central(h / 2) - central(h)) / 3.0


def _exact(fun):
    """Central differences with unit steps: exact for polynomials of degree <= 2."""
    return np.array([(fun(e) - fun(-e)) / 2.0 for e in EYE]).T


def _rel_err(got, expected):
    return np.abs(got - expected).max() / np.abs(expected).max()


def _world_step(pose, delta):
    """Pose after the world tangent ``delta = (dp, dtheta)``: R -> exp([dtheta]) R."""
    rot = pin.exp3(np.asarray(delta[3:], dtype=float)) @ rotation_from_rpy(pose[3:])
    return np.concatenate([pose[:3] + delta[:3], rpy_from_rotation(rot)])


def _states(robot, rng, n=2):
    for _ in range(n):
        yield (random_pose(robot, rng, scale=0.7), *_motion(rng))


# -- against finite differences ----------------------------------------------------------------
def _check_state(robot, pose, twist, twist_dot, wrench):
    d = robot.inverse_dynamics_derivatives(pose, twist, twist_dot, wrench)
    tau = _tau(robot, pose, twist, twist_dot, wrench)
    np.testing.assert_allclose(d.actuator_forces, tau, rtol=0, atol=1e-10 * np.abs(tau).max())
    fd_pose = _richardson(lambda s: _tau(robot, pose + s, twist, twist_dot, wrench), 5e-5)
    fd_world = _richardson(
        lambda s: _tau(robot, _world_step(pose, s), twist, twist_dot, wrench), 5e-5)
    assert _rel_err(d.d_pose, fd_pose) < FD_RTOL
    assert _rel_err(d.d_world, fd_world) < FD_RTOL
    exact = {
        "d_twist": _exact(lambda s: _tau(robot, pose, twist + s, twist_dot, wrench)),
        "d_twist_dot": _exact(lambda s: _tau(robot, pose, twist, twist_dot + s, wrench)),
        "d_wrench": _exact(lambda s: _tau(robot, pose, twist, twist_dot, wrench + s)),
    }
    for name, expected in exact.items():
        assert _rel_err(getattr(d, name), expected) < EXACT_RTOL, name


def test_matches_finite_differences(any_robot, rng):
    """Random states near home (scale 0.7 of conftest's box), nonzero twist and wrench."""
    for state in _states(any_robot, rng):
        _check_state(any_robot, *state)


def test_twist_dot_derivative_is_the_reduced_mass_matrix(any_robot, rng):
    """``d tau / d twist_dot = J^-T M_x`` and ``d tau / d wrench = -J^-T`` (crba route)."""
    robot = any_robot
    pose, twist, twist_dot, wrench = next(_states(robot, rng, 1))
    d = robot.inverse_dynamics_derivatives(pose, twist, twist_dot, wrench)
    red = robot.reduced_dynamics(pose, twist)
    assert _rel_err(d.d_twist_dot, np.linalg.solve(red.jacobian.T, red.mass_matrix)) < 1e-10
    assert _rel_err(d.d_wrench, -np.linalg.inv(red.jacobian.T)) < 1e-10


def test_static_pose_and_zero_wrench(robot):
    """At rest, without a wrench: d tau / d pose is the derivative of the static forces."""
    pose = robot.home_pose + np.array([0.01, -0.02, 0.005, 0.05, -0.04, 0.1])
    zero = np.zeros(6)
    d = robot.inverse_dynamics_derivatives(pose, zero, zero)
    fd = _richardson(lambda s: robot.static_forces(pose + s, bounded=False), 5e-5)
    assert _rel_err(d.d_pose, fd) < FD_RTOL
    np.testing.assert_allclose(d.actuator_forces, robot.static_forces(pose), atol=1e-12)


# -- chain rule along a motion ------------------------------------------------------------------
def _path(robot, t, axis):
    """Pose, twist, twist_dot and jerk of a smooth motion (exact derivatives): the origin
    on sinusoids, the rotation ``exp(phi(t) [axis]) R0`` about a fixed world axis."""
    amp = np.array([0.012, -0.009, 0.01])
    om = np.array([7.0, 5.0, 9.0])
    ph = np.array([0.3, 1.1, 2.0])
    pos = [robot.home_pose[:3] + amp * np.sin(om * t + ph), amp * om * np.cos(om * t + ph),
           -amp * om ** 2 * np.sin(om * t + ph), -amp * om ** 3 * np.cos(om * t + ph)]
    c, w0, p0 = 0.08, 6.0, 0.4
    phi = [c * np.sin(w0 * t + p0), c * w0 * np.cos(w0 * t + p0),
           -c * w0 ** 2 * np.sin(w0 * t + p0), -c * w0 ** 3 * np.cos(w0 * t + p0)]
    rot = pin.exp3(phi[0] * axis) @ rotation_from_rpy(np.array([0.03, -0.05, 0.2]))
    pose = np.concatenate([pos[0], rpy_from_rotation(rot)])
    twist = np.concatenate([pos[1], phi[1] * axis])
    twist_dot = np.concatenate([pos[2], phi[2] * axis])
    jerk = np.concatenate([pos[3], phi[3] * axis])
    return pose, twist, twist_dot, jerk


def test_chain_rule_along_a_motion(any_robot):
    """d tau / dt = d_world (v, w) + d_twist twist_dot + d_twist_dot jerk, and the same with
    d_pose and the pose rates (rpy rates from w = E(rpy) d(rpy)/dt)."""
    robot = any_robot
    rng = np.random.default_rng(11)
    wrench = np.concatenate([2.0 * rng.normal(size=3), 0.2 * rng.normal(size=3)])
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    t, h = 0.37, 1e-3

    def tau_at(time):
        pose, twist, twist_dot, _ = _path(robot, time, axis)
        return _tau(robot, pose, twist, twist_dot, wrench)

    rate = (8 * (tau_at(t + h) - tau_at(t - h)) - (tau_at(t + 2 * h) - tau_at(t - 2 * h))) \
        / (12 * h)
    pose, twist, twist_dot, jerk = _path(robot, t, axis)
    d = robot.inverse_dynamics_derivatives(pose, twist, twist_dot, wrench)
    rest = d.d_twist @ twist_dot + d.d_twist_dot @ jerk
    assert _rel_err(d.d_world @ twist + rest, rate) < FD_RTOL
    pose_rate = np.concatenate([twist[:3], np.linalg.solve(euler_rates_matrix(pose[3:]),
                                                           twist[3:])])
    assert _rel_err(d.d_pose @ pose_rate + rest, rate) < FD_RTOL


# -- the comparisons can fail -------------------------------------------------------------------
def test_wrong_conventions_are_detected(robot):
    """Mutants of the answer, or a reference with the twist held in body axes, are rejected
    by the same comparison (so the tests above can fail)."""
    rng = np.random.default_rng(5)
    pose = robot.home_pose + np.array([0.01, 0.005, -0.01, 0.15, -0.1, 0.3])
    twist, twist_dot, wrench = _motion(rng)
    d = robot.inverse_dynamics_derivatives(pose, twist, twist_dot, wrench)
    fd = _richardson(lambda s: _tau(robot, pose + s, twist, twist_dot, wrench), 5e-5)
    assert _rel_err(d.d_pose, fd) < FD_RTOL
    flipped = d.d_pose.copy()
    flipped[:, 4] *= -1.0                                     # a wrong sign on the pitch
    assert _rel_err(flipped, fd) > 100 * FD_RTOL
    assert _rel_err(d.d_world, fd) > 100 * FD_RTOL             # world tangent, not rpy
    body = np.concatenate([rotation_from_rpy(pose[3:]).T @ twist[:3],
                           rotation_from_rpy(pose[3:]).T @ twist[3:]])

    def held_in_body(s):
        rot = rotation_from_rpy(pose[3:] + s[3:])
        return _tau(robot, pose + s, np.concatenate([rot @ body[:3], rot @ body[3:]]),
                    twist_dot, wrench)

    assert _rel_err(d.d_pose, _richardson(held_in_body, 5e-5)) > 100 * FD_RTOL


# -- errors -------------------------------------------------------------------------------------
def test_bad_input_raises(robot):
    zero = np.zeros(6)
    with pytest.raises(InputError):
        robot.inverse_dynamics_derivatives(np.zeros(5), zero, zero)
    with pytest.raises(InputError):
        robot.inverse_dynamics_derivatives(robot.home_pose, np.full(6, np.nan), zero)
    with pytest.raises(InputError):
        robot.inverse_dynamics_derivatives(robot.home_pose, zero, zero, wrench=[1.0, 2.0])
    with pytest.raises(InputError):
        robot.inverse_dynamics_derivatives(robot.home_pose, zero, np.full(6, np.inf))
    with pytest.raises(UnreachablePoseError):
        robot.inverse_dynamics_derivatives(robot.home_pose + np.array([0, 0, 1.0, 0, 0, 0]), zero, zero)
    geo = robot.geometry
    flat = np.sqrt(geo.leg_length ** 2 - (geo.rail_radius - geo.platform_radius) ** 2)
    # every leg perpendicular to its rail (|cos| ~ 8e-8 < TYPE_I_TOL: type-I singularity)
    with pytest.raises(SingularityError):
        robot.inverse_dynamics_derivatives(np.array([0, 0, flat - 2e-15, 0, 0, 0]), zero, zero)


def test_error_carries_the_value(robot):
    bad = np.array([0.0, 0.0, np.nan, 0.0, 0.0, 0.0])
    with pytest.raises(InputError) as err:
        robot.inverse_dynamics_derivatives(robot.home_pose, np.zeros(6), bad)
    assert err.value.name == "twist_dot" and err.value.value is bad
    assert isinstance(err.value, hp.HexapodPinError)

"""``hexapod_pin.core.holding`` (the holding band) against routes written here.

* friction on the actuated joints only: the band is ``static +- coulomb`` (the closed form
  of the actuator's own joint), springs and a wrench in the static forces;
* friction on passive joints: the half-width of actuator ``i`` is ``sum_j |dq_j / du_i|
  c_j``, the velocity ratios ``dq_j / dq_act_i`` by central differences of the robot's
  forward kinematics and ``robot.configuration`` (``pin.difference``), a route that shares
  no code with the LPs;
* the library's exact stick / slip forward dynamics: inside the band the robot sticks
  (zero acceleration), just outside it slides.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import robot_registry
from hexapod_pin.core.holding import HOLDING_RTOL, HoldingBand, holding_band
from hexapod_pin.errors import InputError

#: robots and a passive one-DoF joint of each that carries friction in the mixed cases
PASSIVE = {"hexapod": ("u_0_a", "u_3_b"), "planar": ("link_0_joint", "link_2_joint"),
           "four-bar": ("coupler_pin",), "stewart": ("u_1_a", "u_4_b")}
NAMES = sorted(PASSIVE)
#: a small wrench on the platform per pose dimension (N, N m)
WRENCH = {6: np.array([1.0, -2.0, 3.0, 0.1, -0.05, 0.02]), 3: np.array([0.5, -1.0, 0.05]),
          2: np.array([0.3, -0.4]), 1: np.array([0.05])}


def _wrench(robot) -> np.ndarray:
    return WRENCH[robot.pose_dim] if robot.pose_dim in WRENCH else np.zeros(robot.pose_dim)


def _actuated_friction(robot):
    act = robot.model.actuated_joints
    return {j: 0.8 + 0.3 * k for k, j in enumerate(act)}


def _mixed(name):
    robot = robot_registry.get(name)
    act = robot.model.actuated_joints
    coulomb = {act[0]: 1.2}
    coulomb.update({j: 0.4 + 0.2 * k for k, j in enumerate(PASSIVE[name])})
    return robot.with_effects(coulomb=coulomb, stiffness={act[-1]: 50.0})


@pytest.mark.parametrize("name", NAMES)
def test_actuated_friction_band_is_static_plus_minus_coulomb(name):
    robot = robot_registry.get(name)
    coulomb = _actuated_friction(robot)
    driven = robot.with_effects(coulomb=coulomb, stiffness={robot.model.actuated_joints[0]: 80.0})
    pose, wrench = driven.home_pose, _wrench(driven)
    band = driven.holding_forces(pose, wrench)
    assert isinstance(band, HoldingBand)
    static = driven.static_forces(pose, wrench, bounded=False)
    c = np.array([coulomb[j] for j in driven.model.actuated_joints])
    scale = max(1.0, np.max(np.abs(static)))
    np.testing.assert_allclose(band.static, static, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(band.lower, static - c, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(band.upper, static + c, rtol=0, atol=1e-9 * scale)
    assert band.residual <= HOLDING_RTOL
    # the springs move the static forces, not the band's width
    rigid_static = robot.static_forces(pose, wrench, bounded=False)
    assert np.max(np.abs(static - rigid_static)) > 0 or name == "four-bar"


def _velocity_ratios(robot, pose, h=1e-6):
    """``dq / dq_act`` (nv, n_act) by central differences of the forward kinematics."""
    act = robot.inverse_kinematics(pose)
    out = np.zeros((robot.model.model.nv, act.size))
    for i in range(act.size):
        step = np.zeros(act.size)
        step[i] = h
        qp = robot.configuration(robot.forward_kinematics(act + step, pose))
        qm = robot.configuration(robot.forward_kinematics(act - step, pose))
        out[:, i] = pin.difference(robot.model.model, qm, qp) / (2 * h)
    return out


@pytest.mark.parametrize("name", NAMES)
def test_passive_friction_band_against_velocity_ratios(name):
    robot = _mixed(name)
    pose, wrench = robot.home_pose, _wrench(robot)
    band = holding_band(robot, pose, wrench)
    ratios = _velocity_ratios(robot, pose)
    c = robot.effects.coulomb
    half = np.abs(ratios).T @ c                   # sum_j |dq_j / du_i| c_j
    np.testing.assert_allclose(band.upper - band.static, half, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(band.static - band.lower, half, rtol=1e-6, atol=1e-8)
    np.testing.assert_array_equal(band.friction_coordinates, np.flatnonzero(c))
    lo, hi = band.half_widths
    assert np.all(lo >= 0) and np.all(hi >= 0)
    # every extreme state has its actuator at the bound
    np.testing.assert_allclose(np.diag(band.upper_states), band.upper, atol=1e-12)
    np.testing.assert_allclose(np.diag(band.lower_states), band.lower, atol=1e-12)


def _at_rest_acceleration(robot, pose, u, wrench):
    res = robot.forward_dynamics(pose, np.zeros(robot.pose_dim), u, wrench)
    return max(np.max(np.abs(res.twist_dot)), np.max(np.abs(res.actuator_accelerations)))


@pytest.mark.parametrize("name", NAMES)
def test_forward_dynamics_sticks_inside_the_band_and_slides_outside(name):
    robot = _mixed(name)
    pose, wrench = robot.home_pose, _wrench(robot)
    band = robot.holding_forces(pose, wrench)
    for i in range(min(robot.n_actuators, 3)):
        for states in (band.upper_states, band.lower_states):
            direction = states[i] - band.static
            for t in (0.5, 0.97):
                assert _at_rest_acceleration(robot, pose, band.static + t * direction,
                                             wrench) < 1e-8
            assert _at_rest_acceleration(robot, pose, band.static + 1.05 * direction,
                                         wrench) > 1e-6


@pytest.mark.parametrize("name", NAMES)
def test_actuated_friction_holds_anywhere_in_the_box(name):
    robot = robot_registry.get(name)
    driven = robot.with_effects(coulomb=_actuated_friction(robot))
    pose = driven.home_pose
    band = driven.holding_forces(pose)
    rng = np.random.default_rng(3)
    width = band.upper - band.static
    for _ in range(3):
        signs = rng.choice([-1.0, 1.0], size=driven.n_actuators)
        inside = band.static + 0.95 * width * signs
        assert _at_rest_acceleration(driven, pose, inside, None) < 1e-8
        outside = inside.copy()
        k = int(rng.integers(driven.n_actuators))
        outside[k] = band.static[k] + 1.05 * width[k] * signs[k]
        assert _at_rest_acceleration(driven, pose, outside, None) > 1e-6


def test_no_friction_collapses_the_band_to_the_static_forces():
    robot = robot_registry.get("planar")
    band = robot.holding_forces(robot.home_pose)
    np.testing.assert_allclose(band.lower, band.static, atol=1e-9)
    np.testing.assert_allclose(band.upper, band.static, atol=1e-9)
    assert band.friction_coordinates.size == 0


@pytest.mark.parametrize("pose, wrench", [(np.zeros(2), None), ([np.nan, 0, 0], None),
                                          (None, [1.0, 2.0]), (None, [np.inf, 0, 0])])
def test_bad_inputs_raise_input_error(pose, wrench):
    robot = robot_registry.get("planar")
    with pytest.raises(InputError):
        robot.holding_forces(robot.home_pose if pose is None else pose, wrench)


def test_an_answer_that_misses_the_equilibrium_is_refused(monkeypatch):
    from hexapod_pin.core import holding
    from hexapod_pin.errors import SolverError

    robot = _mixed("planar")
    real = holding.linprog

    def off_by_a_newton(*args, **kwargs):
        res = real(*args, **kwargs)
        res.x = res.x + np.r_[1.0, np.zeros(res.x.size - 1)]
        return res

    monkeypatch.setattr(holding, "linprog", off_by_a_newton)
    with pytest.raises(SolverError, match="residual"):
        holding_band(robot, robot.home_pose)

"""Time-optimal planning with drive effects (armature, damping, Coulomb friction, springs,
effort limits) against independent routes.

* the planned forces against the robot's own inverse dynamics with its effects
  (``inverse_dynamics_batch`` and the single-state ``inverse_dynamics``) at every grid
  point, and against the force bounds;
* a rigid plan replayed on the damped robot breaks the bounds the damped plan keeps;
* time-optimality: a force limit tight at almost every grid point (the linearisation of
  the damping term is exact at the profile's own speeds);
* the conservative linearisation of ``d sqrt(x)`` checked against ``sqrt`` itself on
  random rows;
* :func:`check_feasibility`'s slow-down with damping and friction against replaying the
  motion ``k`` times slower through the robot's inverse dynamics;
* the drives' ``effort_limit`` as the default force bound.
"""

from __future__ import annotations

import numpy as np
import pytest

import robot_registry
from hexapod_pin.core.workspace_maps import actuator_force_bounds
from hexapod_pin.errors import InfeasiblePathError
from hexapod_pin.planning import Limits, check_feasibility, time_optimal
from hexapod_pin.planning import limits as planning_limits

GRID = 120
#: robot -> waypoint offsets from home
OFFSETS = {
    "planar": [[0.0, 0.0, 0.0], [0.05, 0.03, 0.1], [-0.03, 0.05, -0.1]],
    "hexapod": [[0.0] * 6, [0.01, 0.005, 0.005, 0.02, 0.0, 0.03],
                [0.0, 0.01, -0.005, 0.0, 0.02, -0.03]],
    "four-bar": [[0.0], [0.01], [-0.01]],
}


def _waypoints(name):
    robot = robot_registry.get(name)
    return robot.home_pose + np.array(OFFSETS[name], dtype=float)


def _bound(name) -> float:
    robot = robot_registry.get(name)
    static = robot.static_forces_batch(_waypoints(name), bounded=False)
    return 3.0 * float(np.max(np.abs(static))) + 0.5


def _driven(name, case):
    """The robot with the effects of ``case`` (on actuated and passive joints)."""
    robot = robot_registry.get(name)
    act = robot.model.actuated_joints
    passive = [j for j in list(robot.model.model.names)[1:] if j not in act
               and robot.model.model.joints[robot.model.model.getJointId(j)].nv == 1][:2]
    bound = _bound(name)
    values = {}
    if case in ("damping", "all"):
        values["damping"] = {j: 0.5 * bound for j in act}
        values["damping"].update({j: 0.005 * bound for j in passive})
    if case in ("coulomb", "all"):
        values["coulomb"] = {j: 0.1 * bound for j in act}
        values["coulomb"].update({j: 0.001 * bound for j in passive})
    if case == "all":
        values["armature"] = {j: 0.05 for j in act}
        values["stiffness"] = {act[0]: 0.5 * bound}          # relaxed at home
        values["spring_reference"] = robot.home_configuration
    return robot.with_effects(**values)


CASES = [(name, case) for name in ("planar", "hexapod", "four-bar")
         for case in ("damping", "coulomb", "all")]
_PLANS: dict = {}


def _plan(name, case):
    if (name, case) not in _PLANS:
        robot = _driven(name, case)
        _PLANS[name, case] = time_optimal(robot, _waypoints(name),
                                          limits=Limits(actuator_force=_bound(name)),
                                          grid_points=GRID)
    return _PLANS[name, case]


@pytest.mark.parametrize("name, case", CASES)
def test_planned_forces_are_the_robots_inverse_dynamics_and_keep_the_bounds(name, case):
    traj = _plan(name, case)
    robot, bound = traj.robot, _bound(name)
    forces = robot.inverse_dynamics_batch(traj.poses, traj.twists, traj.twist_dots,
                                          bounded=False).actuator_forces
    np.testing.assert_allclose(traj.actuator_forces, forces, rtol=0, atol=1e-9 * bound)
    for k in (0, GRID // 3, GRID - 1):          # the single-state route, ends included
        single = robot.inverse_dynamics(traj.poses[k], traj.twists[k], traj.twist_dots[k],
                                        bounded=False).actuator_forces
        np.testing.assert_allclose(traj.actuator_forces[k], single, atol=1e-9 * bound)
    ratio = np.max(np.abs(forces), axis=1) / bound
    assert np.max(ratio) <= 1.0 + 1e-9
    # time-optimal: a force limit is tight at every grid point but isolated switches, with
    # the acceleration of the segment on its right or on its left
    left = traj.sample(np.maximum(traj.t - 1e-9 * traj.duration, 0.0))
    left_ratio = np.max(np.abs(robot.inverse_dynamics_batch(
        left.poses, left.twists, left.twist_dots, bounded=False).actuator_forces), axis=1) / bound
    slack = np.flatnonzero(np.maximum(ratio, left_ratio)[1:-1] < 1.0 - 1e-4) + 1
    assert slack.size <= 0.05 * GRID, slack
    report = check_feasibility(robot, traj, limits=Limits(actuator_force=bound))
    assert report.feasible
    assert report.slow_down == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("name", ["planar", "hexapod", "four-bar"])
def test_a_rigid_plan_breaks_the_bounds_the_damped_plan_keeps(name):
    rigid_robot = robot_registry.get(name)
    bound = _bound(name)
    rigid = time_optimal(rigid_robot, _waypoints(name), limits=Limits(actuator_force=bound),
                         grid_points=GRID)
    damped = _plan(name, "damping")
    replayed = damped.robot.inverse_dynamics_batch(rigid.poses, rigid.twists,
                                                   rigid.twist_dots,
                                                   bounded=False).actuator_forces
    assert np.max(np.abs(replayed)) > 1.05 * bound
    assert np.max(np.abs(damped.actuator_forces)) <= bound * (1 + 1e-9)
    assert damped.duration > rigid.duration
    # the feasibility check of the rigid plan on the damped robot: its slow-down factor
    # against replaying the motion k times slower through the inverse dynamics
    report = check_feasibility(damped.robot, rigid, limits=Limits(actuator_force=bound))
    assert not report.feasible and report.slow_down > 1.0

    def peak(k):
        return np.max(np.abs(damped.robot.inverse_dynamics_batch(
            rigid.poses, rigid.twists / k, rigid.twist_dots / k ** 2,
            bounded=False).actuator_forces)) / bound

    k = report.slow_down
    assert peak(k) == pytest.approx(1.0, abs=1e-9)
    assert peak(0.99 * k) > 1.0
    assert all(peak(m * k) <= 1.0 + 1e-9 for m in (1.5, 3.0, 10.0))


def test_coulomb_friction_slow_down_against_replaying():
    plan = _plan("planar", "all")
    robot = plan.robot
    tight = Limits(actuator_force=0.9 * _bound("planar"))
    report = check_feasibility(robot, plan, limits=tight)
    k = report.slow_down
    assert 1.0 < k < np.inf
    peak = np.max(np.abs(robot.inverse_dynamics_batch(
        plan.poses, plan.twists / k, plan.twist_dots / k ** 2,
        bounded=False).actuator_forces))
    assert peak == pytest.approx(0.9 * _bound("planar"), rel=1e-9)


def test_the_damping_rows_are_conservative_and_exact_at_their_speed():
    rng = np.random.default_rng(7)
    n, m = 50, 4
    a, b, c, d = (rng.normal(size=(n, m)) for _ in range(4))
    bound = rng.uniform(1.0, 3.0, size=m)
    r0 = rng.uniform(0.1, 2.0, size=n)
    rows = planning_limits._force_rows(a, b, c, d, bound, r0)
    for x_scale in (0.0, 0.3, 1.0, 4.0):
        x = (x_scale * r0) ** 2
        u = rng.normal(size=n)
        true = np.concatenate([(a * u[:, None] + b * x[:, None] + d * np.sqrt(x)[:, None] + c)
                               / bound - 1.0,
                               -(a * u[:, None] + b * x[:, None] + d * np.sqrt(x)[:, None] + c)
                               / bound - 1.0], axis=1)
        lin = rows[..., 0] * u[:, None] + rows[..., 1] * x[:, None] + rows[..., 2]
        worst = np.maximum(np.maximum(lin[:, 0:m], lin[:, m:2 * m]),
                           np.maximum(lin[:, 2 * m:3 * m], lin[:, 3 * m:]))
        # each true row is below the largest of its linearised rows (conservative) ...
        upper = np.maximum(lin[:, :m], lin[:, m:2 * m])
        lower = np.maximum(lin[:, 2 * m:3 * m], lin[:, 3 * m:])
        assert np.all(true[:, :m] <= upper + 1e-12)
        assert np.all(true[:, m:] <= lower + 1e-12)
        if x_scale == 1.0:                    # ... and equal to it at x = r0^2
            np.testing.assert_allclose(upper, true[:, :m], atol=1e-12)
            np.testing.assert_allclose(lower, true[:, m:], atol=1e-12)
        assert worst.shape == (n, m)


def test_the_effort_limit_is_the_default_force_bound():
    robot = robot_registry.get("planar")                 # max_actuator_force inf
    limit = 0.5 * _bound("planar")
    driven = robot.with_effects(effort_limit=np.full(robot.n_actuators, limit),
                                damping={j: 1.0 for j in robot.model.actuated_joints})
    traj = time_optimal(driven, _waypoints("planar"), grid_points=GRID)
    forces = driven.inverse_dynamics_batch(traj.poses, traj.twists, traj.twist_dots,
                                           bounded=False).actuator_forces
    assert np.max(np.abs(forces)) == pytest.approx(limit, rel=1e-9)
    np.testing.assert_allclose(actuator_force_bounds(driven),
                               np.full(robot.n_actuators, limit))


def test_friction_that_the_bounds_cannot_overcome_names_the_grid_point():
    robot = robot_registry.get("planar")
    bound = _bound("planar")
    static = np.max(np.abs(robot.static_forces_batch(_waypoints("planar"), bounded=False)))
    stuck = robot.with_effects(coulomb={j: bound for j in robot.model.actuated_joints})
    assert static < bound
    with pytest.raises(InfeasiblePathError, match="friction") as info:
        time_optimal(stuck, _waypoints("planar"), limits=Limits(actuator_force=bound),
                     grid_points=GRID)
    assert info.value.actuator is not None


def test_planned_forces_that_miss_the_inverse_dynamics_are_refused(monkeypatch):
    from hexapod_pin.errors import SolverError

    robot = _driven("planar", "damping")
    real = planning_limits.PathCoefficients.forces
    monkeypatch.setattr(planning_limits.PathCoefficients, "forces",
                        lambda self, u, v: real(self, u, v) + 1e-3)
    with pytest.raises(SolverError, match="inverse dynamics"):
        time_optimal(robot, _waypoints("planar"), limits=Limits(actuator_force=_bound("planar")),
                     grid_points=GRID)

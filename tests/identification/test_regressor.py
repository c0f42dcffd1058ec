"""The closed-loop regressor against closed-loop inverse dynamics (an independent route:
the robots' KKT / closed-form inverse dynamics of a robot built with the parameters)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
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
        rows = regressor(driven, poses[k], twists[k], twist_dots[k], DRIVE_KINDS,
                         route="tree")
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
    reg = ClosedLoopRegressor(robot, drive, route="tree")
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


def _cassie_states(clm, rng, count):
    """Closure-consistent Cassie states: assembled ``q`` (actuated joints moved), ``v``
    with ``J_c v = 0`` from random actuated speeds well away from zero (the Coulomb
    columns are ``sign(qd)``)."""
    out = []
    for _ in range(count):
        dq = np.zeros(clm.nv)
        dq[clm.actuated_v] = 0.1 * rng.normal(size=clm.n_actuated)
        q = clm.assemble(pin.integrate(clm.model, pin.neutral(clm.model), dq)).q
        v = rng.normal(size=clm.nv)
        v[clm.actuated_v] = rng.choice([-1.0, 1.0], clm.n_actuated) * rng.uniform(
            0.2, 1.0, clm.n_actuated)
        v = clm.complete_velocity(q, clm.actuated_v, v[clm.actuated_v])
        out.append((q, v))
    return out


def test_cassie_tree_regressor_matches_closed_loop_inverse_dynamics():
    """Cassie (under-actuated: 12 degrees of freedom, 10 actuators, springs and damping
    on passive joints): at motions the robot performs with random consistent parameters
    (forward dynamics of the model rebuilt with them under random actuator forces),
    ``rows @ pi + known`` is ``inverse_dynamics_tree`` of that model (1e-10) and the
    given forces; the unactuated balance rows vanish there and not at a motion the
    robot cannot perform."""
    from hexapod_pin.core.dynamics import forward_dynamics_tree, inverse_dynamics_tree
    from hexapod_pin.identification import (
        ParameterLayout,
        closed_loop_regressor_tree,
        model_with_parameters,
    )
    from hexapod_pin.loaders import robots
    clm = robots.cassie()
    drive = ("armature", "viscous", "coulomb")
    layout = ParameterLayout.of_model(clm, drive)
    rng = np.random.default_rng(17)
    for q, v in _cassie_states(clm, rng, 3):
        pi = random_consistent(None, drive, rng, layout)
        other = model_with_parameters(clm, pi, drive)
        u_in = rng.normal(scale=20.0, size=clm.n_actuated)
        a = forward_dynamics_tree(other, q, v, u_in, method="kkt").a
        rows = closed_loop_regressor_tree(clm, q, v, a, drive)
        assert rows.rows.shape == (10, layout.size) and rows.unactuated_rows.shape[0] == 2
        u = inverse_dynamics_tree(other, q, v, a, method="kkt").actuator_forces
        scale = max(1.0, float(np.max(np.abs(u))))
        assert np.max(np.abs(rows.rows @ pi + rows.known - u)) <= 1e-10 * scale
        assert np.max(np.abs(u - u_in)) <= 1e-8 * scale
        balance = rows.unactuated_rows @ pi + rows.unactuated_known
        assert np.max(np.abs(balance)) <= 1e-10 * scale
        # an acceleration the actuators cannot produce: the balance rows see it
        inertial_only = closed_loop_regressor_tree(clm, q, v, a, ())
        assert inertial_only.rows.shape == (10, layout.n_inertial)
        jac = clm.constraint_jacobian(q)
        *_, vt = np.linalg.svd(np.vstack([jac, np.eye(clm.nv)[clm.actuated_v]]))
        free = vt[-1]                                   # J_c free = 0, S free = 0
        off = closed_loop_regressor_tree(clm, q, v, a + 5.0 * free, drive)
        assert np.max(np.abs(off.unactuated_rows @ pi + off.unactuated_known)) > 1e-3


def test_tree_regressor_refuses_states_off_the_closures():
    from hexapod_pin.identification import closed_loop_regressor_tree
    from hexapod_pin.loaders import robots
    clm = robots.cassie()
    rng = np.random.default_rng(4)
    (q, v), = _cassie_states(clm, rng, 1)
    a = clm.acceleration_from_actuated(q, v, np.zeros(clm.n_actuated))
    with pytest.raises(InputError, match="a"):
        closed_loop_regressor_tree(clm, q, v, a + 1.0)
    with pytest.raises(InputError, match="v"):
        closed_loop_regressor_tree(clm, q, v + 1.0, a)
    with pytest.raises(InputError, match="drive"):
        closed_loop_regressor_tree(clm, q, v, a, drive=("friction",))
    with pytest.raises(InputError, match="q"):
        closed_loop_regressor_tree(clm, q[:3], v, a)

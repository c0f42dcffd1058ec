"""The hexapod's closed-form regressor (``route="closed_form"``: its own body kinematics and
force projection, no Pinocchio call) against the tree route (Pinocchio's joint-torque
regressor projected through the closures) entry by entry, and against closed-loop inverse
dynamics of robots built with other parameters (independent routes)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from identification_helpers import random_consistent

import hexapod_pin as hp
from hexapod_pin.calibration import random_as_built
from hexapod_pin.core.body_regressor import body_regressor
from hexapod_pin.core.closed_form import ClosedFormDynamics
from hexapod_pin.errors import (
    BatchUnreachablePoseError,
    DescriptionError,
    InputError,
    MotionSampleError,
)
from hexapod_pin.hexapod.kernels import HOME_BRANCH
from hexapod_pin.identification import (
    DRIVE_KINDS,
    ClosedLoopRegressor,
    nominal_parameters,
    random_states,
    regressor,
    regressor_batch,
    robot_with_parameters,
)

#: the non-home working modes checked: the carriages of rail 0 swapped to their other
#: roots, and every carriage on its other root
BRANCHES = {"home": None, "rail0_swapped": np.array([1.0, -1.0, -1.0, 1.0, -1.0, 1.0]),
            "all_flipped": -HOME_BRANCH}


def _driven(robot, rng):
    """``robot`` with armature, damping and Coulomb friction on every carriage."""
    act = robot.model.actuated_joints
    return robot.with_effects(armature=dict(zip(act, rng.uniform(0.01, 0.1, 6))),
                              damping=dict(zip(act, rng.uniform(1.0, 3.0, 6))),
                              coulomb=dict(zip(act, rng.uniform(0.5, 1.0, 6))))


@pytest.fixture(scope="module", params=["default", "as_built_mm", "as_built_cm"])
def hexapod(request):
    """The drawing, an as-built robot 1 mm / 1 mrad off it and one 1 cm / 10 mrad off
    (tilted rails: gravity along them), each with drive effects on."""
    geometry = {"default": hp.HexapodGeometry(),
                "as_built_mm": random_as_built(hp.HexapodGeometry(), 1e-3, 0),
                "as_built_cm": random_as_built(hp.HexapodGeometry(), 1e-2, 7)}[request.param]
    return _driven(hp.Hexapod(geometry), np.random.default_rng(5))


def _states(robot, branch, count, seed):
    """Random states near home, regular on ``branch`` (random_states' magnitudes)."""
    poses, twists, twist_dots = random_states(robot, count, seed=seed)
    if branch is None:
        return poses, twists, twist_dots
    rng = np.random.default_rng(seed)
    poses = robot.home_pose + rng.uniform(-1, 1, (count, 6)) * [0.01, 0.01, 0.01, 0.05,
                                                                 0.05, 0.05]
    return poses, twists, twist_dots


@pytest.mark.parametrize("branch", list(BRANCHES), ids=list(BRANCHES))
def test_closed_form_regressor_equals_the_tree_route(hexapod, branch):
    """Every entry of the two routes' ``[Y | Y_d]`` (all drive kinds) agrees to 1e-10 of
    its column's scale over the states; the tree's structurally zero columns (moments a
    rail or a joint absorbs) are zero in the closed form too; the leg's axial inertia
    column (the spin the universal joint imposes) is not."""
    signs = BRANCHES[branch]
    tree = ClosedLoopRegressor(hexapod, DRIVE_KINDS, route="tree")
    closed = ClosedLoopRegressor(hexapod, DRIVE_KINDS, route="closed_form")
    assert (tree.route, closed.route) == ("tree", "closed_form")
    poses, twists, twist_dots = _states(hexapod, signs, 6, seed=21)
    want = tree.batch(poses, twists, twist_dots, branch=signs)
    got = closed.batch(poses, twists, twist_dots, branch=signs)
    assert got.shape == want.shape == (36, 190 + 24)
    scale = np.max(np.abs(want), axis=0)
    zero = scale == 0.0
    assert 60 <= zero.sum() < 190
    err = np.max(np.abs(got - want), axis=0)
    assert np.all(err[~zero] <= 1e-10 * scale[~zero]), np.max(err[~zero] / scale[~zero])
    assert np.all(got[:, zero] == 0.0)
    izz_leg = tree.layout.names.index("Izz_u_0_b")
    assert scale[izz_leg] > 1e-3
    # one state at a time: the same kernel, the same numbers
    single = np.vstack([closed.rows(p, t, d, signs) for p, t, d in zip(poses, twists,
                                                                       twist_dots)])
    np.testing.assert_array_equal(single, got)


def test_closed_form_regressor_gives_inverse_dynamics_of_other_parameters(hexapod):
    """``Y pi`` by the closed form = the inverse dynamics (1e-10) of the robot rebuilt with
    random physically consistent inertias and drive parameters (tree routes, KKT), on
    every working mode checked; the offsets add one constant force per actuator."""
    rng = np.random.default_rng(31)
    closed = ClosedLoopRegressor(hexapod, DRIVE_KINDS, route="closed_form")
    pi = random_consistent(hexapod, DRIVE_KINDS, rng)
    pi[closed.layout.drive_slice("offset")] = 0.0
    other = robot_with_parameters(hexapod, pi, DRIVE_KINDS)
    for signs in BRANCHES.values():
        poses, twists, twist_dots = _states(hexapod, signs, 4, seed=8)
        rows = closed.batch(poses, twists, twist_dots, branch=signs)
        for k in range(4):
            # the tree robot's working mode: a configuration to start from
            branch = None if signs is None else hexapod.configuration(poses[k], signs)
            u = other.inverse_dynamics(poses[k], twists[k], twist_dots[k], branch=branch,
                                       bounded=False).actuator_forces
            scale = max(1.0, float(np.max(np.abs(u))))
            assert np.max(np.abs(rows[6 * k:6 * k + 6] @ pi - u)) <= 1e-10 * scale
    off = np.zeros_like(pi)
    off[closed.layout.drive_slice("offset")] = 1.0
    assert np.array_equal(rows @ off, np.ones(rows.shape[0]))


def test_closed_form_regressor_with_nominal_parameters_is_the_hexapods_dynamics(hexapod):
    """With the robot's own parameters (drives included), the closed-form rows give
    ``Hexapod.inverse_dynamics`` (one ``pin.rnea`` projected) and its batch (the
    Newton-Euler kernels), 1e-10."""
    poses, twists, twist_dots = random_states(hexapod, 5, seed=12)
    pi = nominal_parameters(hexapod, DRIVE_KINDS)
    rows = regressor_batch(hexapod, poses, twists, twist_dots, DRIVE_KINDS,
                           route="closed_form")
    batch = hexapod.inverse_dynamics_batch(poses, twists, twist_dots,
                                           bounded=False).actuator_forces
    scale = max(1.0, float(np.max(np.abs(batch))))
    assert np.max(np.abs(rows @ pi - batch.reshape(-1))) <= 1e-10 * scale
    for k in range(5):
        u = hexapod.inverse_dynamics(poses[k], twists[k], twist_dots[k],
                                     bounded=False).actuator_forces
        assert np.max(np.abs(rows[6 * k:6 * k + 6] @ pi - u)) <= 1e-10 * scale


def test_body_regressor_is_pinocchios():
    """The compiled body regressor against ``pin.bodyRegressor`` (spatial acceleration
    ``(acc - w x v, dw)``), and its wrench against ``pin.Inertia`` times the motion."""
    rng = np.random.default_rng(2)
    out = np.empty((6, 10))
    for _ in range(5):
        w, dw, v, acc = (rng.normal(size=3) for _ in range(4))
        body_regressor(*w, *dw, *acc, out)
        want = pin.bodyRegressor(pin.Motion(v, w), pin.Motion(acc - np.cross(w, v), dw))
        np.testing.assert_allclose(out, want, rtol=0, atol=1e-13)
        inertia = pin.Inertia.Random()
        motion = pin.Motion(v, w)
        force = inertia * pin.Motion(acc - np.cross(w, v), dw) + motion.cross(inertia * motion)
        np.testing.assert_allclose(out @ inertia.toDynamicParameters(), force.vector,
                                   rtol=0, atol=1e-12)


def test_routes_and_bad_inputs():
    """The closed-form route refuses what the tree route refuses, with the same types;
    "auto" falls back to the tree where no closed form supplies a regressor."""
    robot = hp.Hexapod.default()
    pose = robot.home_pose
    zero = np.zeros(6)
    with pytest.raises(InputError, match="twist"):
        regressor(robot, pose, zero[:5], zero, route="closed_form")
    with pytest.raises(InputError, match="twist_dot"):
        regressor(robot, pose, zero, [np.nan] + [0.0] * 5, route="closed_form")
    with pytest.raises(InputError, match="branch"):
        regressor(robot, pose, zero, zero, route="closed_form", branch=[1, 2, 1, 1, 1, 1])
    with pytest.raises(InputError, match="route"):
        ClosedLoopRegressor(robot, route="pinocchio")
    with pytest.raises(InputError, match="twists"):
        regressor_batch(robot, np.tile(pose, (2, 1)), np.zeros((3, 6)), np.zeros((2, 6)),
                        route="closed_form")
    for route in ("tree", "closed_form"):
        with pytest.raises(MotionSampleError) as info:
            regressor_batch(robot, np.vstack([pose, pose + [0, 0, 5.0, 0, 0, 0]]),
                            np.zeros((2, 6)), np.zeros((2, 6)), route=route)
        assert info.value.index == 1 and isinstance(info.value.error, hp.UnreachablePoseError)
        with pytest.raises(hp.UnreachablePoseError):
            regressor(robot, pose + [0, 0, 5.0, 0, 0, 0], zero, zero, route=route)
    # the contract's default batch (state by state on the single-state regressor) is the
    # compiled batch, and names the failing state
    poses, twists, twist_dots = random_states(robot, 3, seed=2)
    default = ClosedFormDynamics.regressor_batch_kernel(robot.dynamics, poses, twists,
                                                        twist_dots)
    compiled = robot.dynamics.regressor_batch(poses, twists, twist_dots)
    for got, want in zip(default, compiled):
        np.testing.assert_array_equal(got, want)
    poses[2, 2] += 5.0
    with pytest.raises(BatchUnreachablePoseError) as bad:
        ClosedFormDynamics.regressor_batch_kernel(robot.dynamics, poses, twists, twist_dots)
    assert bad.value.index == 2
    planar = hp.Planar3PRR.default()
    with pytest.raises(InputError, match="route"):
        ClosedLoopRegressor(planar, route="closed_form")
    assert ClosedLoopRegressor(planar, route="auto").route == "tree"
    with pytest.raises(DescriptionError):
        planar.dynamics.regressor(planar.home_pose, np.zeros(3), np.zeros(3))
    with pytest.raises(DescriptionError):
        planar.dynamics.regressor_batch(planar.home_pose[None], np.zeros((1, 3)),
                                        np.zeros((1, 3)))

"""The closed-form route of the core chain rule (hexapod_pin.core.platform_derivatives):
the hexapod's and the planar robot's compiled inverse-dynamics partials
(``dynamics.inverse_dynamics_partials``: hexapod_pin.hexapod.derivatives,
hexapod_pin.planar.derivatives) and the forward-dynamics derivatives the core builds from
them by the implicit-function theorem.

Independent routes, each written elsewhere: the core's tree route (the KKT derivatives of
hexapod_pin.core.dynamics_derivatives: ``PlatformLinearization`` for the forward dynamics,
``platform_derivatives.inverse_dynamics_derivatives`` for the inverse dynamics, which
never reads a closed form) and Richardson central differences of the robots' verified
``inverse_dynamics`` / ``forward_dynamics``. Robots: the hexapod (both branches, another
geometry, an as-built one), the planar 3-PRR (and another geometry), rigid and with every
drive effect on the actuated joints (the effects the closed forms model: armature,
damping, springs, sliding Coulomb friction); effects on a passive joint send the core to
the tree (no partials).
"""

from __future__ import annotations

import numpy as np
import pytest
import robot_registry
from test_closed_form_effects import PASSIVE_JOINT, drive_fields
from test_dynamics_derivatives import displaced, relative, richardson

import hexapod_pin as hp
from hexapod_pin.calibration import random_as_built
from hexapod_pin.core.derivative_kernels import implicit_kernel
from hexapod_pin.core.platform_derivatives import (
    PlatformLinearization,
    implicit_inverse,
    inverse_dynamics_derivatives,
)
from hexapod_pin.errors import InconsistentMotionError, InputError
from hexapod_pin.hexapod.kinematics import HOME_BRANCH

RTOL = 1e-7
NAMES = ("hexapod", "planar", "hexapod-other", "planar-other")


def robot_of(name, drives):
    robot = robot_registry.get(name)
    return robot.with_effects(**drive_fields(robot, "all")) if drives else robot


def state(robot, seed):
    """A state near home with every actuator sliding (pose, twist, twist_dot, wrench)."""
    rng = np.random.default_rng(seed)
    dim = robot.pose_layout.dim
    return (robot.home_pose + rng.uniform(-0.004, 0.004, dim), rng.uniform(0.05, 0.1, dim)
            * rng.choice([-1.0, 1.0], dim), rng.uniform(-0.8, 0.8, dim),
            rng.uniform(-1.0, 1.0, dim))


@pytest.mark.parametrize("drives", [False, True], ids=["rigid", "drives"])
@pytest.mark.parametrize("name", NAMES)
def test_closed_form_route_matches_the_tree_route(name, drives):
    """Inverse- and forward-dynamics derivatives by the closed form's partials (what the
    robot answers) against the core's tree route, to 1e-8 relative, field by field."""
    robot = robot_of(name, drives)
    pose, twist, twist_dot, wrench = state(robot, 3)
    assert robot.dynamics.inverse_dynamics_partials(pose, twist, twist_dot, wrench) is not None
    own = robot.inverse_dynamics_derivatives(pose, twist, twist_dot, wrench)
    tree = inverse_dynamics_derivatives(robot, pose, twist, twist_dot, own.actuator_forces,
                                        wrench)
    for field in ("actuator_forces", "d_pose", "d_world", "d_twist", "d_twist_dot",
                  "d_wrench"):
        assert relative(getattr(tree, field), getattr(own, field)) < 1e-8, field
    u = own.actuator_forces + np.linspace(-1.0, 1.0, robot.n_actuators)
    fwd = robot.forward_dynamics_derivatives(pose, twist, u, wrench)
    ref = PlatformLinearization(robot, pose, twist, u, wrench, None).derivatives()
    for field in ("twist_dot", "d_pose", "d_world", "d_twist", "d_actuator_forces",
                  "d_wrench"):
        assert relative(getattr(ref, field), getattr(fwd, field)) < 1e-8, field


@pytest.mark.parametrize("name", ["hexapod", "planar"])
def test_closed_form_derivatives_with_drives_match_central_differences(name):
    """With every drive effect on the actuators (the closed-form route): every block of the
    forward and the inverse derivatives against Richardson central differences of the
    verified dynamics (twist, twist_dot and forces chosen so that every actuator keeps
    sliding over the steps)."""
    robot = robot_of(name, True)
    pose, twist, twist_dot, wrench = state(robot, 5)
    eye = np.eye(robot.pose_layout.dim)
    u = robot.static_forces(pose, bounded=False) + np.linspace(-1.0, 1.0, robot.n_actuators)
    fwd = robot.forward_dynamics_derivatives(pose, twist, u, wrench)

    def acc(p=pose, t=twist, uu=u, w=wrench):
        return robot.forward_dynamics(p, t, uu, w).twist_dot

    # steps: 5e-4 (m, rad) on the pose (the drives' springs make 1e-3 truncate at ~1e-7),
    # 1e-3 on the twist, 1.0 on the forces and wrench (affine there)
    for got, column, h in (
            (fwd.d_world, lambda k: lambda s: acc(p=displaced(robot, pose, s * eye[k])), 5e-4),
            (fwd.d_pose, lambda k: lambda s: acc(p=pose + s * eye[k]), 5e-4),
            (fwd.d_twist, lambda k: lambda s: acc(t=twist + s * eye[k]), 1e-3),
            (fwd.d_actuator_forces, lambda k: lambda s: acc(uu=u + s * eye[k]), 1.0),
            (fwd.d_wrench, lambda k: lambda s: acc(w=wrench + s * eye[k]), 1.0)):
        num = np.array([richardson(column(k), h) for k in range(len(eye))]).T
        assert relative(num, got) < RTOL
    der = robot.inverse_dynamics_derivatives(pose, twist, twist_dot, wrench)

    def tau(p=pose, t=twist, td=twist_dot, w=wrench):
        return robot.inverse_dynamics(p, t, td, w, bounded=False).actuator_forces

    for got, column, h in (
            (der.d_world, lambda k: lambda s: tau(p=displaced(robot, pose, s * eye[k])), 5e-4),
            (der.d_pose, lambda k: lambda s: tau(p=pose + s * eye[k]), 5e-4),
            (der.d_twist, lambda k: lambda s: tau(t=twist + s * eye[k]), 1e-3),
            (der.d_twist_dot, lambda k: lambda s: tau(td=twist_dot + s * eye[k]), 1.0),
            (der.d_wrench, lambda k: lambda s: tau(w=wrench + s * eye[k]), 1.0)):
        num = np.array([richardson(column(k), h) for k in range(len(eye))]).T
        assert relative(num, got) < RTOL


@pytest.mark.parametrize("seed", [0, 1])
def test_as_built_hexapod_both_branches_against_the_tree_route(seed):
    """An as-built hexapod (per-chain geometry), home and the other branch: the closed-form
    forward derivatives against the tree route (the central differences of both branches:
    test_dynamics_derivatives)."""
    robot = hp.Hexapod(random_as_built(hp.HexapodGeometry(), 1e-3, seed))
    rng = np.random.default_rng(seed)
    for branch in (None, -np.asarray(HOME_BRANCH)):
        pose = robot.home_pose + 0.01 * rng.uniform(-1, 1, 6)
        twist, wrench = 0.05 * rng.normal(size=6), rng.normal(size=6)
        u = robot.static_forces(pose, bounded=False, branch=branch) + rng.normal(size=6)
        fwd = robot.forward_dynamics_derivatives(pose, twist, u, wrench, branch=branch)
        ref = PlatformLinearization(robot, pose, twist, u, wrench, branch).derivatives()
        for field in ("d_world", "d_twist", "d_actuator_forces", "d_wrench"):
            assert relative(getattr(ref, field), getattr(fwd, field)) < 1e-8, field


@pytest.mark.parametrize("name", ["hexapod", "planar"])
def test_coulomb_friction_at_rest_is_refused(name):
    """A carriage / slider with exact Coulomb friction at rest: the dynamics is not
    differentiable (stick / slip), both routes refuse it."""
    robot = robot_registry.get(name)
    robot = robot.with_effects(**drive_fields(robot, "coulomb"))
    dim = robot.pose_layout.dim
    zero = np.zeros(dim)
    with pytest.raises(InputError, match="at rest"):
        robot.inverse_dynamics_derivatives(robot.home_pose, zero, zero)
    with pytest.raises(InputError, match="at rest"):
        robot.forward_dynamics_derivatives(robot.home_pose, zero,
                                           robot.static_forces(robot.home_pose) + 1.0)


@pytest.mark.parametrize("name", ["hexapod", "planar"])
def test_passive_effects_go_to_the_tree_route(name):
    """A damper on a passive joint (which the closed forms do not model): no partials, and
    the robot's derivatives are the tree route's, bit for bit."""
    robot = robot_registry.get(name).with_effects(damping={PASSIVE_JOINT[name]: 0.3})
    pose, twist, twist_dot, wrench = state(robot, 7)
    assert robot.dynamics.inverse_dynamics_partials(pose, twist, twist_dot, wrench) is None
    own = robot.inverse_dynamics_derivatives(pose, twist, twist_dot, wrench)
    tree = inverse_dynamics_derivatives(robot, pose, twist, twist_dot, own.actuator_forces,
                                        wrench)
    np.testing.assert_array_equal(own.d_world, tree.d_world)
    u = own.actuator_forces
    fwd = robot.forward_dynamics_derivatives(pose, twist, u, wrench)
    ref = PlatformLinearization(robot, pose, twist, u, wrench, None).derivatives()
    np.testing.assert_array_equal(fwd.d_world, ref.d_world)


def test_implicit_kernel_against_numpy_and_its_refusal():
    """The compiled implicit-function theorem against numpy's inverse; a singular ``B`` is
    an InconsistentMotionError."""
    rng = np.random.default_rng(2)
    b, partials = rng.normal(size=(5, 5)), rng.normal(size=(5, 7))
    inv, out, miss = implicit_kernel(b, partials)
    np.testing.assert_allclose(inv, np.linalg.inv(b), atol=1e-12)
    np.testing.assert_allclose(out, -np.linalg.solve(b, partials), atol=1e-12)
    assert miss < 1e-14
    singular = b.copy()
    singular[4] = singular[3]
    with pytest.raises(InconsistentMotionError):
        implicit_inverse(singular, partials, "test")
    with pytest.raises(InconsistentMotionError):
        implicit_inverse(np.full((5, 5), np.nan), partials, "test")

"""Discrete-time step Jacobians (hexapod_pin.core.step_jacobians) against central
differences of the library's own simulation step.

Independent route: one step of a fresh :class:`~hexapod_pin.core.simulation.ClosedLoopIntegrator`
(the "pinocchio" dynamics route, as ``simulate`` runs it, projection included) from the
tree state of a platform state, the platform state read back with the robot's
``pose_from_configuration`` and ``twist_from_configuration``; the tree velocity of a twist
solved here with numpy (``[J_c; T] v = [0; twist]``). Inputs moved along the closure
manifold: the pose by ``(dp, exp(dtheta) R)`` in world axes (re-assembled by
``robot.configuration``), the twist in world axes, the actuator forces; outputs measured in
the same tangent at the next pose. Richardson-extrapolated central differences, steps
1e-3 (pose, m / rad), 1e-2 (twist, m/s / rad/s), 1.0 (forces, N / N m). Tolerance 1e-7
relative: ``Ad`` to the larger of 1 and its largest entry, ``Bd`` to its own largest entry.
Robots: the hexapod, the planar 3-PRR (redundant rows: its RK4 stages are projected), the
Stewart platform and the delta (loaded; welds), rigid and with damping, springs and
armature; both integrators, dt = 1 ms; and robots the code was not written for: another
hexapod geometry, an as-built hexapod in its other working mode, the five-bar and the
four-bar (redundant point rows).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import robot_registry
from test_dynamics_derivatives import displaced, richardson

import hexapod_pin as hp
from hexapod_pin.calibration import random_as_built
from hexapod_pin.core.pose import rotation_from_rpy
from hexapod_pin.core.simulation import ClosedLoopIntegrator
from hexapod_pin.errors import InputError
from hexapod_pin.hexapod.kinematics import HOME_BRANCH

DATA = Path(__file__).resolve().parents[1] / "data"

RTOL = 1e-7
DT = 1e-3


def pose_difference(robot, pose, ref):
    """``(dp, dtheta)`` of ``pose`` from ``ref`` (``R = exp(dtheta) R_ref``, world axes)."""
    lay = robot.pose_layout
    out = np.asarray(pose - ref, dtype=float)
    if lay.full_rotation:
        out[lay.angular] = pin.log3(rotation_from_rpy(pose[lay.angular])
                                    @ rotation_from_rpy(ref[lay.angular]).T)
    return out


def tree_velocity(robot, q, twist):
    """The tree velocity keeping the closures with the platform twist ``twist``."""
    clm = robot.model
    data = clm.model.createData()
    pin.computeJointJacobians(clm.model, data, q)
    pin.updateFramePlacements(clm.model, data)
    rows = pin.getFrameJacobian(clm.model, data, robot.platform_frame_id,
                                pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    jac = clm.constraint_jacobian(q)
    lhs = np.vstack([jac, rows[list(robot.pose_layout.components)]])
    return np.linalg.lstsq(lhs, np.concatenate([np.zeros(jac.shape[0]), twist]),
                           rcond=None)[0]


def library_step(robot, pose, twist, u, integrator, branch=None):
    """The platform state after one step of the library's integrator."""
    clm = robot.model
    q = robot.configuration(pose, branch)
    v = tree_velocity(robot, q, twist)
    tau = np.zeros(clm.nv)
    tau[clm.actuated_v] = u
    q1, v1, _ = ClosedLoopIntegrator(clm, integrator=integrator).step(q, v, tau, DT)
    return (np.asarray(robot.pose_from_configuration(q1), dtype=float),
            robot.twist_from_configuration(q1, v1))


def with_drive_effects(robot):
    clm, q = robot.model, robot.home_configuration
    nv = clm.nv
    rng = np.random.default_rng(11)
    return robot.with_effects(damping=rng.uniform(0.1, 0.5, nv),
                              stiffness=rng.uniform(1, 5, nv),
                              spring_reference=pin.integrate(clm.model, q,
                                                             rng.uniform(-0.5, 0.5, nv)),
                              armature=rng.uniform(0.01, 0.05, nv))


def check_step(robot, integrator, seed=3, branch=None):
    dim = robot.pose_layout.dim
    rng = np.random.default_rng(seed)
    pose = robot.home_pose + 0.01 * rng.uniform(-1, 1, dim)
    twist = 0.05 * rng.normal(size=dim)
    u = robot.static_forces(pose, bounded=False) + rng.normal(size=robot.n_actuators)
    u = u if branch is None else robot.static_forces(pose, bounded=False, branch=branch)
    got = robot.step_jacobians(pose, twist, u, DT, integrator=integrator, branch=branch)
    pose1, twist1 = library_step(robot, pose, twist, u, integrator, branch)
    np.testing.assert_allclose(got.next_pose, pose1, atol=1e-12)
    np.testing.assert_allclose(got.next_twist, twist1, atol=1e-12)

    def state(p, t):
        return np.concatenate([pose_difference(robot, p, pose1), t - twist1])

    def along_state(k):
        return lambda s: state(*library_step(robot, displaced(robot, pose, s * eye[k, :dim]),
                                             twist + s * eye[k, dim:], u, integrator, branch))

    def along_force(k):
        return lambda s: state(*library_step(robot, pose, twist, u + s * unit[k], integrator,
                                             branch))

    eye, unit = np.eye(2 * dim), np.eye(robot.n_actuators)
    ad = np.array([richardson(along_state(k), 1e-3 if k < dim else 1e-2)
                   for k in range(2 * dim)]).T
    bd = np.array([richardson(along_force(k), 1.0) for k in range(robot.n_actuators)]).T
    err_a = float(np.max(np.abs(ad - got.ad)) / max(1.0, np.max(np.abs(ad))))
    err_b = float(np.max(np.abs(bd - got.bd)) / np.max(np.abs(bd)))
    return err_a, err_b, got


@pytest.mark.parametrize("integrator", ["rk4", "semi_implicit_euler"])
@pytest.mark.parametrize("effects", [False, True], ids=["rigid", "effects"])
@pytest.mark.parametrize("name", ["hexapod", "planar", "stewart", "delta"])
def test_step_jacobians_match_central_differences_of_the_step(name, effects, integrator):
    robot = robot_registry.get(name)
    if effects:
        robot = with_drive_effects(robot)
    err_a, err_b, got = check_step(robot, integrator)
    assert err_a < RTOL and err_b < RTOL, (err_a, err_b)
    assert got.integrator == integrator and got.dt == DT


def test_other_geometry_and_redundant_loops():
    """Robots the code was not written for: another hexapod, the five-bar (redundant point
    rows: projected RK4 stages), the four-bar (its Euler step's velocity row needs the
    projection's second-order terms: the projector alone misses an entry by 1 %)."""
    for name, integrator in (("hexapod-other", "semi_implicit_euler"), ("five-bar", "rk4"),
                             ("four-bar", "semi_implicit_euler")):
        err_a, err_b, _ = check_step(robot_registry.get(name), integrator, seed=5)
        assert err_a < RTOL and err_b < RTOL, (name, err_a, err_b)


@pytest.mark.parametrize("integrator", ["rk4", "semi_implicit_euler"])
def test_as_built_hexapod_other_branch(integrator):
    """An as-built hexapod (random geometry errors) in its other working mode."""
    robot = hp.Hexapod(random_as_built(hp.HexapodGeometry(), 1e-3, 2))
    err_a, err_b, _ = check_step(robot, integrator, seed=2, branch=-np.asarray(HOME_BRANCH))
    assert err_a < RTOL and err_b < RTOL, (err_a, err_b)


def test_linearize_with_dt_and_the_continuous_limit():
    """``linearize(dt=...)`` carries the step Jacobians; over a short step they approach
    ``I + dt A`` and ``dt B`` (the discretisation of the continuous model, O(dt^2))."""
    robot = robot_registry.get("hexapod")
    pose, twist = robot.home_pose, np.array([0.01, 0.0, -0.02, 0.1, -0.2, 0.3])
    u = robot.static_forces(pose, bounded=False)
    model = robot.linearize(pose, twist, u, dt=DT, integrator="semi_implicit_euler")
    step = robot.step_jacobians(pose, twist, u, DT, integrator="semi_implicit_euler")
    np.testing.assert_array_equal(model.ad, step.ad)
    np.testing.assert_array_equal(model.bd, step.bd)
    assert model.dt == DT and model.integrator == "semi_implicit_euler"
    assert robot.linearize(pose, twist, u).ad is None
    small = robot.step_jacobians(pose, twist, u, 1e-5)
    eye = np.eye(12)
    assert np.max(np.abs((small.ad - eye) / 1e-5 - model.a)) < 1e-3 * np.max(np.abs(model.a))
    assert np.max(np.abs(small.bd / 1e-5 - model.b)) < 1e-3 * np.max(np.abs(model.b))
    with pytest.raises(dataclasses.FrozenInstanceError):
        step.ad = None


def test_refused():
    robot = robot_registry.get("four-bar")
    pose, u = robot.home_pose, np.zeros(1)
    with pytest.raises(InputError, match="stick_slip"):
        robot.step_jacobians(pose, [0.1], u, DT, integrator="stick_slip")
    with pytest.raises(InputError):
        robot.step_jacobians(pose, [0.1], u, -1.0)
    with pytest.raises(InputError, match="wrench"):
        robot.linearize(pose, [0.1], u, wrench=[1.0], dt=DT)
    rough = robot.with_effects(coulomb=np.full(robot.model.nv, 0.2))
    with pytest.raises(InputError, match="Coulomb"):
        rough.step_jacobians(pose, [0.1], u, DT, integrator="rk4")


@pytest.mark.parametrize("integrator", ["rk4", "semi_implicit_euler"])
@pytest.mark.parametrize("effects", [False, True], ids=["rigid", "effects"])
def test_step_jacobians_with_joint_couplings(effects, integrator):
    """A four-bar whose pendulum hinge follows the crank through a quartic joint coupling
    (tests/data/mjcf/coupled_fourbar.xml): the couplings' rows enter the projection's
    derivative (the curvature of the rows needs ``q``)."""
    pytest.importorskip("mujoco")
    robot = hp.ClosedLoopRobot(hp.load_mjcf(DATA / "mjcf" / "coupled_fourbar.xml"),
                               platform="coupler", pose_axes=("z",))
    if effects:
        robot = with_drive_effects(robot)
    err_a, err_b, _ = check_step(robot, integrator)
    assert err_a < RTOL and err_b < RTOL, (err_a, err_b)

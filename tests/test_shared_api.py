"""ONE test suite over every parallel robot: the shared API of ``core.robot_api``.

The way qpsolvers runs one suite over every solver, each test here runs on every robot
(``hp.Hexapod`` and ``hp.Planar3PRR``, the default geometry and another one, and robots
loaded from descriptions as ``hp.ClosedLoopRobot``: a 6-UPS Gough-Stewart platform, a
planar five-bar, a 3-RUU delta and a crank-rocker four-bar from ``tests/data``): the same
names, signatures and result types, and round trips checked against independent routes
(the Pinocchio tree routes, finite differences, the platform's own Newton-Euler written
here from Pinocchio's body inertia). The robots are those of ``robot_registry.names("shared")``
(``tests/robot_registry.py``): a new robot joins every test with one line there.
"""

from __future__ import annotations

import dataclasses
import inspect
import re
import typing

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hexapod_pin as hp
import robot_registry
from hexapod_pin.core import results as shared
from hexapod_pin.core.dynamics import forward_dynamics_tree, inverse_dynamics_tree
from hexapod_pin.core.pose import rotation_from_rpy, rpy_from_rotation
from hexapod_pin.core.robot_api import (FORWARD_DYNAMICS_METHODS, INVERSE_DYNAMICS_METHODS,
                                        SHARED_NAMES, ParallelRobot)
from hexapod_pin.errors import (ActuatorSaturationError, BatchActuatorSaturationError,
                                BatchUnreachablePoseError, SingularityError,
                                StrokeLimitError, UnreachablePoseError)


@pytest.fixture(scope="module")
def robot(shared_robot):
    """Each robot of ``robot_registry.names("shared")`` in turn."""
    return shared_robot


# -- helpers -------------------------------------------------------------------------------
def loaded(robot):
    """Whether ``robot`` is a robot loaded from a description (no closed form)."""
    return isinstance(robot, hp.ClosedLoopRobot)


def axes_of(robot):
    """Indices of the robot's pose components in (x, y, z, roll, pitch, yaw)."""
    if loaded(robot):
        return robot.platform.sel
    return np.arange(6) if robot.pose_dim == 6 else np.array([0, 1, 5])


def _scales(robot):
    """(pose, twist, twist_dot, wrench) scales of random states near home."""
    if loaded(robot):
        ang = axes_of(robot) >= 3
        size = robot.geometry.characteristic_length
        pick = lambda lin, rot: np.where(ang, rot, lin)
        return (pick(0.03 * size, 0.05), pick(0.05, 0.3), pick(0.5, 2.0), pick(2.0, 0.1))
    if robot.pose_dim == 6:
        return (np.array([0.01] * 3 + [0.05] * 3), np.array([0.05] * 3 + [0.3] * 3),
                np.array([0.5] * 3 + [2.0] * 3), np.array([2.0] * 3 + [0.1] * 3))
    return (np.array([0.02, 0.02, 0.1]), np.array([0.1, 0.1, 0.5]), np.array([1.0, 1.0, 3.0]),
            np.array([3.0, 3.0, 0.2]))


def random_state(robot, rng):
    """A random regular state (pose, twist, twist_dot, wrench) near home: reachable inside
    the strokes, well away from type-I and type-II singularities."""
    sp, st_, sa, sw = _scales(robot)
    for _ in range(200):
        pose = robot.home_pose + rng.uniform(-1, 1, robot.pose_dim) * sp
        try:
            robot.inverse_kinematics(pose)
            meas = robot.singularity(pose)
        except (UnreachablePoseError, StrokeLimitError, SingularityError):
            continue
        if meas.type_one > 0.1 and meas.type_two > 0.05 and meas.condition_number < 1e3:
            return (pose, rng.uniform(-1, 1, robot.pose_dim) * st_,
                    rng.uniform(-1, 1, robot.pose_dim) * sa,
                    rng.uniform(-1, 1, robot.pose_dim) * sw)
    raise RuntimeError("no regular state found")


def states(robot, n, seed):
    rng = np.random.default_rng(seed)
    return [random_state(robot, rng) for _ in range(n)]


def advance(robot, pose, twist, t):
    """The pose after moving for time t at the constant world twist (v, w)."""
    if robot.pose_dim != 6:         # in the plane, or translations (and one angle)
        return pose + t * twist
    rot = pin.exp3(t * twist[3:]) @ rotation_from_rpy(pose[3:])
    return np.concatenate([pose[:3] + t * twist[:3], rpy_from_rotation(rot)])


def richardson(f, h):
    """Central difference of f at 0 with step h, Richardson-extrapolated (error O(h^4))."""
    d1 = (f(h) - f(-h)) / (2 * h)
    d2 = (f(h / 2) - f(-h / 2)) / h
    return (4 * d2 - d1) / 3


def chain_dim(robot):
    return 3 if robot.pose_dim == 6 or loaded(robot) else 2


def _platform(robot):
    """Pinocchio ids of the platform body: (frame id, joint id)."""
    model = robot.model.model
    fid = robot.platform.frame if loaded(robot) else model.getFrameId("platform")
    return fid, model.frames[fid].parentJoint


def spatial(robot, vec):
    """A twist / wrench of the robot as a 6-vector (linear, angular), world axes (zero in
    the components the pose leaves out)."""
    out = np.zeros(6)
    out[axes_of(robot)] = vec
    return out


def planar_part(robot, vec6):
    """The robot's components of a 6-vector."""
    return vec6[axes_of(robot)]


def tree_state(robot, pose, twist, twist_dot):
    """(q, v, a) of a platform motion with every closure kept, checked on Pinocchio: q
    from robot.configuration, v and a from the generic core's completion on the tree,
    pinned to the platform frame's world velocity and classical acceleration."""
    clm = robot.model
    model, data = clm.model, clm.model.createData()
    fid, _ = _platform(robot)
    q = robot.configuration(pose)
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    jp = pin.getFrameJacobian(model, data, fid,
                              pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[axes_of(robot)]
    jc = clm.constraint_jacobian(q)
    # v: J_c v = 0 and J_p v = twist (least squares on the stacked rows, exact here)
    rows = np.vstack([jc, jp])
    v = np.linalg.lstsq(rows, np.concatenate([np.zeros(clm.n_rows), twist]), rcond=None)[0]
    pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
    pin.updateFramePlacements(model, data)
    bias = pin.getFrameClassicalAcceleration(
        model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED).vector[axes_of(robot)]
    gamma = clm.constraint_drift(q, v)
    a = np.linalg.lstsq(rows, np.concatenate([-gamma, twist_dot - bias]), rcond=None)[0]
    assert np.max(np.abs(rows @ v - np.concatenate([np.zeros(clm.n_rows), twist]))) < 1e-12
    return q, v, a


def tau_ext_of(robot, q, wrench):
    """The wrench (f, m about the platform origin, world axes) as a tree force J_p^T w."""
    model, data = robot.model.model, robot.model.model.createData()
    fid, _ = _platform(robot)
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    jp = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    return jp.T @ spatial(robot, wrench)


def twist_dot_of(robot, q, v, a):
    """Platform twist_dot (world axes) of a tree motion, by Pinocchio."""
    model, data = robot.model.model, robot.model.model.createData()
    fid, _ = _platform(robot)
    pin.forwardKinematics(model, data, q, v, a)
    pin.updateFramePlacements(model, data)
    acc = pin.getFrameClassicalAcceleration(model, data, fid,
                                            pin.ReferenceFrame.LOCAL_WORLD_ALIGNED).vector
    return planar_part(robot, acc)


def _chain_of(name):
    return int(re.search(r"_(\d+)_tip$", name).group(1))


# -- names, signatures, types ----------------------------------------------------------------
def test_every_shared_name_with_the_protocol_signature(robot):
    assert isinstance(robot, ParallelRobot)
    for name in SHARED_NAMES:
        assert hasattr(robot, name), name
        spec = inspect.getattr_static(ParallelRobot, name, None)
        if name == "default" and loaded(robot):
            continue        # a loaded robot's default() is a method: it needs its model
        if inspect.isfunction(spec) or isinstance(spec, classmethod):
            mine = inspect.signature(getattr(type(robot), name))
            theirs = inspect.signature(getattr(ParallelRobot, name))
            got = [(p.name, p.kind, p.default) for p in mine.parameters.values()]
            want = [(p.name, p.kind, p.default) for p in theirs.parameters.values()]
            assert got == want, f"{type(robot).__name__}.{name}{mine} != protocol {theirs}"
    assert INVERSE_DYNAMICS_METHODS[0] == "kkt" and FORWARD_DYNAMICS_METHODS[0] == "nullspace"


def test_shared_methods_show_the_protocol_annotations(robot):
    """``inspect.signature`` / ``help`` of a robot's method (a facade method delegated to a
    component included) show the protocol's parameter and result annotations, and
    ``typing.get_type_hints`` resolves them."""
    for name in SHARED_NAMES:
        spec = inspect.getattr_static(ParallelRobot, name, None)
        if not inspect.isfunction(spec):
            continue
        theirs = inspect.signature(getattr(ParallelRobot, name))
        mine = inspect.signature(getattr(robot, name))          # bound: no ``self``
        want = [(p.name, p.annotation) for p in theirs.parameters.values() if p.name != "self"]
        assert [(p.name, p.annotation) for p in mine.parameters.values()] == want, name
        assert mine.return_annotation == theirs.return_annotation, name
        hints = typing.get_type_hints(getattr(robot, name))
        assert set(hints) == {p.name for p in mine.parameters.values()} | {"return"}, name


def test_attributes_and_home(robot):
    dim, n = robot.pose_dim, robot.n_actuators
    assert isinstance(robot.model, hp.ClosedLoopModel)
    assert robot.model.n_actuated == n
    assert robot.home_pose.shape == (dim,) and robot.home_actuators.shape == (n,)
    limit = robot.geometry.max_actuator_force
    assert limit > 0 and (np.isfinite(limit) or limit == np.inf)
    assert robot.geometry.gravity >= 0
    np.testing.assert_allclose(robot.inverse_kinematics(robot.home_pose), robot.home_actuators,
                               atol=1e-12)
    q = robot.home_configuration
    assert q.shape == (robot.model.nq,)
    assert np.max(np.abs(robot.model.residual(q))) <= 1e-12
    np.testing.assert_allclose(robot.pose_from_configuration(q), robot.home_pose, atol=1e-12)
    np.testing.assert_allclose(robot.actuator_positions(q), robot.home_actuators, atol=1e-12)
    if loaded(robot):
        assert robot.default().geometry == robot.geometry
    else:
        assert type(robot).default().geometry == type(robot.geometry)()


def test_result_types_and_fields(robot):
    pose, twist, twist_dot, wrench = states(robot, 1, 1)[0]
    dim, n, d = robot.pose_dim, robot.n_actuators, chain_dim(robot)
    n_chains = len(robot.model.closures)
    res = robot.inverse_dynamics(pose, twist, twist_dot, wrench)
    assert type(res) is shared.InverseDynamicsResult
    assert res.actuator_forces.shape == (n,) and res.closure_forces.shape == (n_chains, d)
    assert res.multipliers.shape == (robot.model.n_rows,)
    assert res.configuration.shape == (robot.model.nq,)
    assert res.velocity.shape == res.acceleration.shape == (robot.model.nv,)
    assert isinstance(res.residual, float) and res.residual < 1e-9
    assert res.method == "kkt"
    fd = robot.forward_dynamics(pose, twist, res.actuator_forces, wrench)
    assert type(fd) is shared.ForwardDynamicsResult and fd.method == "nullspace"
    assert fd.twist_dot.shape == (dim,) and fd.actuator_accelerations.shape == (n,)
    assert fd.tree_acceleration.shape == (robot.model.nv,)
    assert fd.closure_forces.shape == (n_chains, d)
    red = robot.reduced_dynamics(pose, twist)
    assert type(red) is shared.ReducedDynamics
    m_x, h_x = red
    assert m_x.shape == (dim, dim) and h_x.shape == (dim,) and red.jacobian.shape == (n, dim)
    assert red.velocity_map.shape == (robot.model.nv, dim)
    assert type(robot.energies(pose, twist)) is shared.Energies
    sing = robot.singularity(pose)
    assert type(sing) is shared.SingularityMeasures
    assert sing.characteristic_length == (robot.geometry.characteristic_length if loaded(robot)
                                          else robot.geometry.platform_radius)
    assert robot.static_forces(pose, wrench).shape == (n,)
    assert robot.jacobian_derivative(pose, twist).shape == (n, dim)
    der = robot.inverse_dynamics_derivatives(pose, twist, twist_dot, wrench)
    assert type(der) is shared.InverseDynamicsDerivatives
    for field in ("d_pose", "d_world", "d_twist", "d_twist_dot", "d_wrench"):
        assert getattr(der, field).shape == (n, dim), field
    np.testing.assert_allclose(der.actuator_forces, res.actuator_forces, rtol=0, atol=1e-9)
    modes = robot.assembly_modes(robot.inverse_kinematics(pose))
    assert isinstance(modes, np.ndarray) and modes.ndim == 2 and modes.shape[1] == dim
    poses = np.array([s[0] for s in states(robot, 3, 2)])
    twists = np.array([s[1] for s in states(robot, 3, 2)])
    assert type(robot.inverse_kinematics_batch(poses)) is shared.InverseKinematicsBatch
    assert type(robot.jacobian_batch(poses)) is shared.JacobianBatch
    bid = robot.inverse_dynamics_batch(poses, twists, twists)
    assert type(bid) is shared.BatchInverseDynamics
    assert bid.closure_forces.shape == (3, n_chains, d) and bid.residual.shape == (3,)
    assert type(robot.forward_dynamics_batch(poses, twists, bid.actuator_forces)) is \
        shared.BatchForwardDynamics
    assert type(robot.reduced_dynamics_batch(poses, twists)) is shared.BatchReducedDynamics
    assert robot.static_forces_batch(poses).shape == (3, n)


# -- kinematics round trips ------------------------------------------------------------------
def test_forward_kinematics_of_inverse_kinematics(robot):
    for pose, _, _, _ in states(robot, 4, 3):
        act = robot.inverse_kinematics(pose)
        np.testing.assert_allclose(robot.forward_kinematics(act, guess=pose + 1e-3), pose,
                                   atol=1e-9)
        modes = robot.assembly_modes(act)
        assert np.min(np.max(np.abs(modes - pose), axis=1)) < 1e-8
        q = robot.configuration(pose)
        assert np.max(np.abs(robot.model.residual(q))) <= 1e-12
        np.testing.assert_allclose(robot.pose_from_configuration(q), pose, atol=1e-12)
        np.testing.assert_allclose(robot.actuator_positions(q), act, atol=1e-12)


def test_jacobian_and_its_derivative_by_finite_differences(robot):
    for pose, twist, _, _ in states(robot, 3, 4):
        jac = robot.jacobian(pose)
        ik = lambda t: robot.inverse_kinematics(advance(robot, pose, twist, t),
                                                check_limits=False)
        np.testing.assert_allclose(jac @ twist, richardson(ik, 1e-4), atol=1e-9)
        jd = lambda t: robot.jacobian(advance(robot, pose, twist, t))
        np.testing.assert_allclose(robot.jacobian_derivative(pose, twist),
                                   richardson(jd, 1e-4), atol=1e-7)
        np.testing.assert_allclose(robot.twist_from_actuator_velocities(pose, jac @ twist),
                                   twist, atol=1e-11)


def test_singularity_measures_by_numpy(robot):
    for pose, _, _, _ in states(robot, 3, 5):
        meas = robot.singularity(pose)
        sv = np.linalg.svd(robot.jacobian(pose), compute_uv=False)
        np.testing.assert_allclose(meas.jacobian_singular_values, sv, rtol=1e-12)
        assert meas.condition_number == pytest.approx(np.linalg.cond(robot.jacobian(pose)),
                                                      rel=1e-10)
        assert 0 < meas.type_one <= 1 and meas.type_two > 0
        assert meas.type_two == pytest.approx(meas.type_two_singular_values[-1])


# -- dynamics round trips ----------------------------------------------------------------------
def test_forward_dynamics_of_inverse_dynamics(robot):
    for pose, twist, twist_dot, wrench in states(robot, 3, 6):
        tau = robot.inverse_dynamics(pose, twist, twist_dot, wrench).actuator_forces
        for method in FORWARD_DYNAMICS_METHODS:
            fd = robot.forward_dynamics(pose, twist, tau, wrench, method=method)
            np.testing.assert_allclose(fd.twist_dot, twist_dot, rtol=0,
                                       atol=1e-10 * max(1.0, np.abs(twist_dot).max()))
        for method in INVERSE_DYNAMICS_METHODS:
            again = robot.inverse_dynamics(pose, twist, twist_dot, wrench, method=method)
            np.testing.assert_allclose(again.actuator_forces, tau, rtol=0,
                                       atol=1e-10 * max(1.0, np.abs(tau).max()))


def test_statics_is_inverse_dynamics_at_rest(robot):
    zero = np.zeros(robot.pose_dim)
    for pose, _, _, wrench in states(robot, 3, 7):
        for w in (None, wrench):
            tau = robot.static_forces(pose, w)
            ref = robot.inverse_dynamics(pose, zero, zero, w).actuator_forces
            np.testing.assert_allclose(tau, ref, rtol=0, atol=1e-10 * max(1.0, np.abs(ref).max()))


def test_compiled_closed_form_equals_the_pinocchio_tree_routes(robot):
    for pose, twist, twist_dot, wrench in states(robot, 3, 8):
        q, v, a = tree_state(robot, pose, twist, twist_dot)
        tau_ext = tau_ext_of(robot, q, wrench)
        res = robot.inverse_dynamics(pose, twist, twist_dot, wrench)
        np.testing.assert_allclose(res.configuration, q, atol=1e-12)
        np.testing.assert_allclose(res.velocity, v, atol=1e-11)
        np.testing.assert_allclose(res.acceleration, a, atol=1e-10 * max(1, np.abs(a).max()))
        ref = inverse_dynamics_tree(robot.model, q, v, a, tau_ext, method="kkt")
        scale = max(1.0, np.abs(ref.actuator_forces).max())
        np.testing.assert_allclose(res.actuator_forces, ref.actuator_forces, rtol=0,
                                   atol=1e-10 * scale)
        ref_fd = forward_dynamics_tree(robot.model, q, v, res.actuator_forces, tau_ext,
                                       method="kkt")
        fd = robot.forward_dynamics(pose, twist, res.actuator_forces, wrench)
        np.testing.assert_allclose(fd.twist_dot, twist_dot_of(robot, q, v, ref_fd.a), rtol=0,
                                   atol=1e-10 * max(1.0, np.abs(twist_dot).max()))
        np.testing.assert_allclose(fd.tree_acceleration, ref_fd.a, rtol=0,
                                   atol=1e-10 * max(1.0, np.abs(ref_fd.a).max()))


def test_closure_forces_balance_the_platform(robot):
    """The closure forces act ON the platform: with the wrench, they give the platform
    body's Newton-Euler wrench (Pinocchio's body inertia, about the platform origin)."""
    model = robot.model.model
    data = model.createData()
    fid, jid = _platform(robot)
    if loaded(robot):
        # a loaded robot's closure force k is the force of the body of frame2 ON the body
        # of frame1: on the platform with its sign where one end is on the platform body;
        # checked where only closures hold the platform (a floating platform)
        if model.joints[jid].shortname() != "JointModelFreeFlyer":
            pytest.skip("the platform body is held by tree joints too")
        anchors, signs = {}, {}
        for k, (c, frames) in enumerate(zip(robot.model.closures,
                                            robot.model.closure_frames)):
            for frame, sign in ((frames.frame1, 1.0), (frames.frame2, -1.0)):
                if model.frames[frame].parentJoint == jid:
                    anchors[k], signs[k] = frame, sign
    else:
        anchors = {_chain_of(c.frame1): model.getFrameId(c.frame2)
                   for c in robot.model.closures}
        signs = dict.fromkeys(anchors, 1.0)
    for pose, twist, twist_dot, wrench in states(robot, 3, 9):
        res = robot.inverse_dynamics(pose, twist, twist_dot, wrench)
        fd = robot.forward_dynamics(pose, twist, res.actuator_forces, wrench)
        pin.forwardKinematics(model, data, res.configuration, res.velocity, res.acceleration)
        pin.updateFramePlacements(model, data)
        vel, acc = data.v[jid], data.a[jid]
        grav = data.oMi[jid].actInv(model.gravity)
        inertia = model.inertias[jid]
        body = data.oMi[jid].act(inertia * (acc - grav) + vel.cross(inertia * vel))
        origin = data.oMf[fid].translation
        need = np.concatenate([body.linear, body.angular - np.cross(origin, body.linear)])
        for closure in (res.closure_forces, fd.closure_forces):
            force, moment = spatial(robot, wrench)[:3].copy(), spatial(robot, wrench)[3:].copy()
            for i, fid_k in anchors.items():
                f = np.zeros(3)
                f[:closure.shape[1]] = signs[i] * closure[i]
                force += f
                moment += np.cross(data.oMf[fid_k].translation - origin, f)
            got = planar_part(robot, np.concatenate([force, moment]))
            np.testing.assert_allclose(got, planar_part(robot, need), rtol=0,
                                       atol=1e-9 * max(1.0, np.abs(need).max()))


def test_reduced_dynamics_and_energies(robot):
    for pose, twist, twist_dot, wrench in states(robot, 3, 10):
        m_x, h_x = red = robot.reduced_dynamics(pose, twist)
        np.testing.assert_allclose(m_x, m_x.T, atol=1e-12)
        assert np.linalg.eigvalsh(m_x).min() > 0
        np.testing.assert_allclose(red.jacobian, robot.jacobian(pose), atol=1e-12)
        tau = robot.inverse_dynamics(pose, twist, twist_dot, wrench).actuator_forces
        lhs = red.jacobian.T @ tau + wrench
        np.testing.assert_allclose(lhs, m_x @ twist_dot + h_x, rtol=0,
                                   atol=1e-10 * max(1.0, np.abs(lhs).max()))
        q, v, _ = tree_state(robot, pose, twist, twist_dot)
        mass = pin.crba(robot.model.model, robot.model.model.createData(), q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        np.testing.assert_allclose(red.velocity_map @ twist, v, atol=1e-11)
        np.testing.assert_allclose(red.velocity_map.T @ mass @ red.velocity_map, m_x,
                                   atol=1e-11)
        energy = robot.energies(pose, twist)
        assert energy.kinetic == pytest.approx(0.5 * v @ mass @ v, rel=1e-12)
        assert energy.kinetic == pytest.approx(0.5 * twist @ m_x @ twist, rel=1e-10)
        assert energy.total == pytest.approx(energy.kinetic + energy.potential, rel=1e-14)


def test_inverse_dynamics_derivatives_by_finite_differences(robot):
    for pose, twist, twist_dot, wrench in states(robot, 2, 11):
        der = robot.inverse_dynamics_derivatives(pose, twist, twist_dot, wrench)
        args = [pose, twist, twist_dot, wrench]

        def tau(args):
            return robot.inverse_dynamics(*args, bounded=False).actuator_forces

        np.testing.assert_allclose(der.actuator_forces, tau(args), atol=1e-12)
        for field, which, step in (("d_pose", 0, 1e-4), ("d_twist", 1, 1e-2),
                                   ("d_twist_dot", 2, 1.0), ("d_wrench", 3, 1.0)):
            fd = np.empty_like(getattr(der, field))
            for j in range(robot.pose_dim):
                def along(h, j=j):
                    moved = list(args)
                    moved[which] = args[which] + h * np.eye(robot.pose_dim)[j]
                    return tau(moved)
                fd[:, j] = richardson(along, step)
            np.testing.assert_allclose(getattr(der, field), fd, rtol=0,
                                       atol=1e-7 * max(1.0, np.abs(fd).max()), err_msg=field)


# -- batches -----------------------------------------------------------------------------------
def test_batch_equals_single(robot):
    samples = states(robot, 6, 12)
    poses, twists, twist_dots, wrenches = (np.array(x) for x in zip(*samples))
    ik = robot.inverse_kinematics_batch(poses)
    jb = robot.jacobian_batch(poses)
    bid = robot.inverse_dynamics_batch(poses, twists, twist_dots, wrenches)
    bfd = robot.forward_dynamics_batch(poses, twists, bid.actuator_forces, wrenches)
    bst = robot.static_forces_batch(poses, wrenches)
    brd = robot.reduced_dynamics_batch(poses, twists)
    assert ik.ok.all() and jb.ok.all() and jb.regular.all()
    for i, (pose, twist, twist_dot, wrench) in enumerate(samples):
        np.testing.assert_allclose(ik.actuator_positions[i], robot.inverse_kinematics(pose),
                                   atol=1e-12)
        np.testing.assert_allclose(jb.jacobian[i], robot.jacobian(pose), atol=1e-12)
        res = robot.inverse_dynamics(pose, twist, twist_dot, wrench)
        scale = max(1.0, np.abs(res.actuator_forces).max())
        np.testing.assert_allclose(bid.actuator_forces[i], res.actuator_forces, rtol=0,
                                   atol=1e-10 * scale)
        np.testing.assert_allclose(bid.closure_forces[i], res.closure_forces, rtol=0,
                                   atol=1e-10 * scale)
        assert 0 <= bid.residual[i] <= 1e-9 * scale
        fd = robot.forward_dynamics(pose, twist, res.actuator_forces, wrench)
        np.testing.assert_allclose(bfd.twist_dot[i], fd.twist_dot, atol=1e-10)
        np.testing.assert_allclose(bfd.twist_dot[i], twist_dot, atol=1e-9)
        np.testing.assert_allclose(bfd.actuator_accelerations[i], fd.actuator_accelerations,
                                   atol=1e-10)
        np.testing.assert_allclose(bfd.closure_forces[i], fd.closure_forces, rtol=0,
                                   atol=1e-9 * scale)
        np.testing.assert_allclose(bst[i], robot.static_forces(pose, wrench), atol=1e-10)
        red = robot.reduced_dynamics(pose, twist)
        np.testing.assert_allclose(brd.mass_matrix[i], red.mass_matrix, atol=1e-12)
        np.testing.assert_allclose(brd.bias[i], red.bias, atol=1e-10)
        np.testing.assert_allclose(brd.jacobian[i], red.jacobian, atol=1e-12)


def test_batch_errors_name_the_first_bad_state(robot):
    samples = states(robot, 4, 13)
    poses, twists, twist_dots, _ = (np.array(x) for x in zip(*samples))
    far = poses.copy()
    far[2, 0] += 1.0                      # 1 m away: no chain reaches
    if loaded(robot) and robot.inverse_kinematics_batch(far).reachable[2]:
        pytest.skip("unbounded prismatic legs reach every pose (their stroke is a limit)")
    with pytest.raises(BatchUnreachablePoseError) as info:
        robot.inverse_dynamics_batch(far, twists, twist_dots)
    assert info.value.index == 2 and isinstance(info.value, UnreachablePoseError)
    with pytest.raises(BatchUnreachablePoseError) as info:
        robot.static_forces_batch(far)
    assert info.value.index == 2
    ik = robot.inverse_kinematics_batch(far)
    assert ik.reachable.tolist() == [True, True, False, True]
    assert np.all(np.isfinite(ik.actuator_positions))


@settings(max_examples=15, deadline=None)
@given(which=st.sampled_from(robot_registry.names("shared")), seed=st.integers(0, 2 ** 16))
def test_batch_equals_single_hypothesis(which, seed):
    robot = robot_registry.get(which)
    pose, twist, twist_dot, wrench = states(robot, 1, seed)[0]
    bid = robot.inverse_dynamics_batch(pose[None], twist[None], twist_dot[None], wrench[None])
    res = robot.inverse_dynamics(pose, twist, twist_dot, wrench)
    np.testing.assert_allclose(bid.actuator_forces[0], res.actuator_forces, rtol=0,
                               atol=1e-10 * max(1.0, np.abs(res.actuator_forces).max()))


# -- bounds -------------------------------------------------------------------------------------
def test_bounded_saturation_raises(robot):
    pose, twist, twist_dot, wrench = states(robot, 1, 14)[0]
    rest = np.abs(robot.static_forces(robot.home_pose, bounded=False)).max()
    for factor in (20, 200, 2000):       # a motion that needs more than twice the bound,
        needed = robot.inverse_dynamics(pose, twist, factor * twist_dot, wrench,
                                        bounded=False).actuator_forces
        if 0.5 * np.abs(needed).max() > 1.5 * rest:     # which holds home at rest
            break
    twist_dot = factor * twist_dot
    bound = 0.5 * np.abs(needed).max()
    tight = hp.ClosedLoopRobot(robot.model, robot.geometry.platform, robot.geometry.pose_axes,
                               home=robot.home_configuration, max_actuator_force=bound) \
        if loaded(robot) else \
        type(robot)(dataclasses.replace(robot.geometry, max_actuator_force=bound))
    for method in INVERSE_DYNAMICS_METHODS:
        with pytest.raises(ActuatorSaturationError) as info:
            tight.inverse_dynamics(pose, twist, twist_dot, wrench, method=method)
        np.testing.assert_allclose(info.value.needed, needed, rtol=1e-8)
        free = tight.inverse_dynamics(pose, twist, twist_dot, wrench, method=method,
                                      bounded=False)
        np.testing.assert_allclose(free.actuator_forces, needed, rtol=1e-9, atol=1e-12)
    with pytest.raises(BatchActuatorSaturationError) as info:
        tight.inverse_dynamics_batch(np.array([robot.home_pose, pose]),
                                     np.array([0 * twist, twist]),
                                     np.array([0 * twist_dot, twist_dot]),
                                     np.array([0 * wrench, wrench]))
    assert info.value.index == 1
    heavy = 1e3 * np.abs(needed).max() * np.ones(robot.pose_dim)
    with pytest.raises(ActuatorSaturationError):
        tight.static_forces(pose, heavy)
    tight.static_forces(pose, heavy, bounded=False)
    with pytest.raises(BatchActuatorSaturationError):
        tight.static_forces_batch(np.array([pose]), np.array([heavy]))


@pytest.mark.parametrize("kind", ["complex", "complex array", "bool", "text"])
def test_non_real_inputs_are_refused_by_name(robot, kind):
    """Complex numbers (their imaginary part would be dropped silently), booleans and text
    are an InputError naming the argument, on every entry point of both robots."""
    dim = robot.pose_dim
    pose = robot.home_pose.copy()
    bad = {"complex": list(pose[:-1]) + [complex(pose[-1], 1e-3)],
           "complex array": pose + 1e-3j,
           "bool": [True] * dim,
           "text": ["0"] * dim}[kind]
    zero = np.zeros(dim)
    calls = {
        "pose": (lambda: robot.inverse_kinematics(bad), lambda: robot.jacobian(bad),
                 lambda: robot.static_forces(bad), lambda: robot.configuration(bad),
                 lambda: robot.inverse_dynamics(bad, zero, zero)),
        "twist": (lambda: robot.inverse_dynamics(pose, bad, zero),
                  lambda: robot.reduced_dynamics(pose, bad)),
        "poses": (lambda: robot.inverse_kinematics_batch(np.array([bad])),),
    }
    for name, funcs in calls.items():
        for call in funcs:
            with pytest.raises(hp.InputError) as err:
                call()
            assert err.value.name == name


# -- poses given as placements (pin.SE3 or a 4x4 homogeneous matrix) -----------------------
def placement_of(robot, pose, extra=None):
    """The pin.SE3 of a pose vector, written from the conventions (``R = Rz(yaw) Ry(pitch)
    Rx(roll)``; components outside the pose axes zero, or ``extra``: index in (x, y, z,
    roll, pitch, yaw) -> value)."""
    full = np.zeros(6)
    full[axes_of(robot)] = pose
    for k, value in (extra or {}).items():
        full[k] = value
    rot = pin.AngleAxis(full[5], np.array([0.0, 0.0, 1.0])).matrix() \
        @ pin.AngleAxis(full[4], np.array([0.0, 1.0, 0.0])).matrix() \
        @ pin.AngleAxis(full[3], np.array([1.0, 0.0, 0.0])).matrix()
    return pin.SE3(rot, full[:3])


def test_poses_may_be_placements(robot):
    pose, twist, twist_dot, wrench = states(robot, 1, 11)[0]
    placement = placement_of(robot, pose)
    for given in (placement, placement.homogeneous, placement.homogeneous.tolist()):
        np.testing.assert_allclose(robot.inverse_kinematics(given),
                                   robot.inverse_kinematics(pose), rtol=0, atol=1e-12)
        np.testing.assert_allclose(robot.jacobian(given), robot.jacobian(pose), atol=1e-10)
        np.testing.assert_allclose(robot.configuration(given), robot.configuration(pose),
                                   atol=1e-12)
        np.testing.assert_allclose(robot.static_forces(given, wrench),
                                   robot.static_forces(pose, wrench), atol=1e-9)
        np.testing.assert_allclose(
            robot.inverse_dynamics(pose=given, twist=twist, twist_dot=twist_dot).actuator_forces,
            robot.inverse_dynamics(pose, twist, twist_dot).actuator_forces, atol=1e-9)
        tau = robot.static_forces(pose)
        np.testing.assert_allclose(robot.forward_dynamics(given, twist, tau).twist_dot,
                                   robot.forward_dynamics(pose, twist, tau).twist_dot, atol=1e-9)
    # the placement of the platform frame at the configuration of the pose (Pinocchio's
    # forward kinematics, an independent route) gives the pose back where it fits the axes
    q = robot.configuration(pose)
    data = robot.pinocchio_model.createData()
    pin.framesForwardKinematics(robot.pinocchio_model, data, q)
    frame = data.oMf[robot.platform_frame_id]
    full = np.concatenate([frame.translation, pin.rpy.matrixToRpy(frame.rotation)])
    outside = np.setdiff1d(np.arange(6), axes_of(robot))
    if np.abs(full[outside]).max(initial=0.0) < 1e-12:
        np.testing.assert_allclose(robot.inverse_kinematics(frame), robot.inverse_kinematics(pose),
                                   atol=1e-10)


def test_a_placement_outside_the_pose_axes_is_refused_by_name(robot):
    pose = robot.home_pose
    outside = np.setdiff1d(np.arange(6), axes_of(robot))
    names = ("x", "y", "z", "roll", "pitch", "yaw")
    for k in outside:
        with pytest.raises(hp.InputError, match="pose") as err:
            robot.inverse_kinematics(placement_of(robot, pose, {int(k): 0.1}))
        assert err.value.name == "pose"
        if k < 3 or len([a for a in axes_of(robot) if a >= 3]) != 1:
            assert f"{names[k]} = 0.1" in str(err.value)
    bad = placement_of(robot, pose).homogeneous
    bad[3, 0] = 1.0
    with pytest.raises(hp.InputError, match="last row"):
        robot.jacobian(bad)
    bad = placement_of(robot, pose).homogeneous
    bad[:3, :3] *= 2.0
    with pytest.raises(hp.InputError, match="not a rotation"):
        robot.static_forces(bad)


# -- gravity in any direction ------------------------------------------------------------------
def potential_gradient(robot, pose, gravity, h=1e-6):
    """dV/d(actuator positions) at ``pose`` under ``gravity`` (3,): central differences of
    Pinocchio's potential energy (a copy of the tree with that gravity) along the assembly
    mode of ``pose`` (forward kinematics of the shifted actuator positions)."""
    model = pin.Model(robot.pinocchio_model)
    model.gravity = pin.Motion(np.concatenate([gravity, np.zeros(3)]))
    data = model.createData()
    act = robot.inverse_kinematics(pose)
    grad = []
    for k in range(robot.n_actuators):
        step = np.zeros(robot.n_actuators)
        step[k] = h
        v = []
        for s in (1.0, -1.0):
            q = robot.configuration(robot.forward_kinematics(act + s * step, guess=pose))
            v.append(pin.computePotentialEnergy(model, data, q))
        grad.append((v[0] - v[1]) / (2 * h))
    return np.array(grad)


def test_with_gravity_in_any_direction_by_virtual_work(robot):
    if np.any(robot.effects.stiffness):
        pytest.skip("springs store energy too")
    pose, twist, twist_dot, _ = states(robot, 1, 5)[0]
    tilted = np.array([3.0, -4.0, -8.0])             # m/s^2, a wall-mounted, tilted robot
    other = robot.with_gravity(tilted)
    np.testing.assert_allclose(other.gravity, tilted)
    np.testing.assert_allclose(robot.gravity, robot.pinocchio_model.gravity.linear)
    if not loaded(robot):
        # the closed form takes its own vertical only: the tree routes' robot answers
        assert isinstance(other, hp.ClosedLoopRobot) and other.pose_axes == robot.pose_axes
    # virtual work: the static forces are the gradient of the potential energy
    np.testing.assert_allclose(other.static_forces(pose, bounded=False),
                               potential_gradient(robot, pose, tilted), rtol=1e-6, atol=1e-7)
    # gravity enters linearly: ID under g = ID without gravity (this robot's own route,
    # the closed form where it has one) + the static forces under g
    free = robot.with_gravity(np.zeros(3))
    np.testing.assert_allclose(
        other.inverse_dynamics(pose, twist, twist_dot, bounded=False).actuator_forces,
        free.inverse_dynamics(pose, twist, twist_dot, bounded=False).actuator_forces
        + other.static_forces(pose, bounded=False), rtol=1e-8, atol=1e-8)


def test_with_gravity_along_the_vertical_keeps_the_closed_form(robot):
    if loaded(robot):
        return
    vertical = np.zeros(3)
    vertical[2 if robot.pose_dim == 6 else 1] = -2.0 * robot.geometry.gravity
    heavier = robot.with_gravity(vertical)
    assert type(heavier) is type(robot)
    assert heavier.geometry.gravity == pytest.approx(2.0 * robot.geometry.gravity)
    np.testing.assert_allclose(heavier.gravity, vertical)
    pose = robot.home_pose
    np.testing.assert_allclose(heavier.static_forces(pose, bounded=False),
                               potential_gradient(robot, pose, vertical), rtol=1e-6, atol=1e-7)
    with pytest.raises(hp.InputError, match="gravity"):
        robot.with_gravity([0.0, 9.81])

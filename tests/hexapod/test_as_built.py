"""The as-built hexapod (per-chain lines, sensor offsets, leg lengths, platform joints).

Independent routes: the Pinocchio tree of the as-built URDF with its six loop closures
(the generic closed-loop routes of :mod:`hexapod_pin.core.dynamics`, the closure residual
and Jacobian of :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`), the closure
equations written here in numpy from the :class:`ChainGeometry` fields, and finite
differences. Random as-built geometries deviate from the drawing by millimetres (and
milliradians) in every field, several seeds.
"""

from __future__ import annotations

import json
import pickle

import numpy as np
import pinocchio as pin
import pytest
from typer.testing import CliRunner

import hexapod_pin as hp
from hexapod_pin.calibration import random_as_built
from hexapod_pin.cli import app
from hexapod_pin.core.dynamics import forward_dynamics_tree, inverse_dynamics_tree
from hexapod_pin.core.pose import rotation_from_rpy, rpy_from_rotation
from hexapod_pin.errors import GeometryError
from hexapod_pin.files import load_geometry, save_geometry
from hexapod_pin.hexapod import fast, kernels, workspace
from hexapod_pin.hexapod.geometry import CHAIN_VECTOR_SIZE, ChainGeometry
from hexapod_pin.hexapod.simulation import CircleTrajectory, PIDController, simulate

SEEDS = (0, 1, 2)
RTOL = 1e-9


def as_built_geometry(seed: int, scale: float = 1e-3) -> hp.HexapodGeometry:
    """The default geometry with Gaussian deviations of ``scale`` (m, or rad for the
    directions) in every ChainGeometry field."""
    return random_as_built(hp.HexapodGeometry(), scale, seed)


@pytest.fixture(scope="module", params=[(seed, 1e-3) for seed in SEEDS] + [(7, 1e-2)],
                ids=lambda p: f"seed{p[0]}-{p[1]:g}")
def built(request):
    """Millimetre deviations (three seeds), and one robot 1 cm / 0.01 rad off the drawing."""
    return hp.Hexapod(as_built_geometry(*request.param))


def close(got, want, rtol=RTOL):
    """``|got - want| <= rtol max(1, |want|_max)`` elementwise."""
    got, want = np.asarray(got), np.asarray(want)
    np.testing.assert_allclose(got, want, rtol=0, atol=rtol * max(1.0, np.abs(want).max()))


def leg_errors(chains: ChainGeometry, pose, q) -> np.ndarray:
    """|t + R p_i - c_i(q)| - L_i (6,), in numpy from the ChainGeometry fields."""
    rot = rotation_from_rpy(np.asarray(pose[3:]))
    joints = pose[:3] + chains.platform_joints @ rot.T
    centres = chains.line_points + (q + chains.sensor_offsets)[:, None] * chains.line_directions
    return np.linalg.norm(joints - centres, axis=1) - chains.leg_lengths


def random_pose(robot, rng):
    """A random pose near home, inside the strokes, away from singularities."""
    for _ in range(1000):
        pose = robot.home_pose + np.concatenate([rng.uniform(-0.03, 0.03, 3),
                                                 rng.uniform(-0.12, 0.12, 3)])
        try:
            robot.inverse_kinematics(pose)
            measures = robot.singularity(pose)
        except hp.HexapodPinError:
            continue
        if measures.type_one > 0.1 and measures.type_two > 0.1:   # finite differences
            return pose
    raise RuntimeError("no reachable pose")


def moved(pose, twist, h):
    """The pose reached from ``pose`` along the world twist ``twist`` for a time ``h``."""
    w = h * np.asarray(twist[3:])
    angle = np.linalg.norm(w)
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / max(angle, 1e-300)
    step = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    rot = step @ rotation_from_rpy(np.asarray(pose[3:]))
    return np.concatenate([pose[:3] + h * np.asarray(twist[:3]), rpy_from_rotation(rot)])


def tree_state(robot, pose, twist):
    """Tree (q, v) by the generic closed-loop model: q from the closed form, checked on the
    Pinocchio closure residual; v completed from the platform's free-flyer velocity."""
    clm = robot.model
    q = robot.configuration(pose)
    assert np.max(np.abs(clm.residual(q))) <= 1e-12
    rot = rotation_from_rpy(np.asarray(pose[3:]))
    ff = np.arange(robot.indices.platform_v.start, robot.indices.platform_v.stop)
    v = clm.complete_velocity(q, ff, np.concatenate([rot.T @ twist[:3], rot.T @ twist[3:]]))
    return q, v


def tree_forces(robot, tau):
    full = np.zeros(robot.model.nv)
    full[robot.model.actuated_v] = tau
    return full


# -- ChainGeometry ---------------------------------------------------------------------------
def test_chain_geometry_values_and_vector():
    g = as_built_geometry(0)
    chains = g.chains
    assert g.chain_geometry is chains and not g.is_ideal
    for name in ("line_points", "line_directions", "sensor_offsets", "leg_lengths",
                 "platform_joints"):
        with pytest.raises(ValueError):
            getattr(chains, name)[0] = 1.0                  # read-only
    np.testing.assert_allclose(np.linalg.norm(chains.line_directions, axis=1), 1.0, atol=1e-15)
    vec = chains.as_vector()
    assert vec.shape == (CHAIN_VECTOR_SIZE,)
    np.testing.assert_array_equal(vec[36:42], chains.sensor_offsets)
    np.testing.assert_array_equal(vec[48:66].reshape(6, 3), chains.platform_joints)
    back = ChainGeometry.from_vector(vec)
    assert back == chains and hash(back) == hash(chains)
    copy = pickle.loads(pickle.dumps(g))
    assert copy == g and not copy.chains.leg_lengths.flags.writeable
    np.testing.assert_array_equal(copy.home_pose, g.home_pose)
    assert g == g.replace() and hash(g) == hash(g.replace())
    assert g != hp.HexapodGeometry() and g != as_built_geometry(1)
    ideal = ChainGeometry.ideal(g)
    k = np.arange(6) // 2
    np.testing.assert_array_equal(ideal.line_points, g.rail_midpoints[k])
    np.testing.assert_array_equal(ideal.platform_joints, g.platform_points[k])
    np.testing.assert_array_equal(ideal.leg_lengths, np.full(6, g.leg_length))
    # as_built: deviations added, directions renormalised
    dev = np.zeros((6, 3))
    dev[0] = (0.0, 0.0, 0.01)
    tilted = hp.HexapodGeometry().as_built(line_directions=dev).chains.line_directions[0]
    u0 = g.rail_directions[0] + dev[0]
    np.testing.assert_allclose(tilted, u0 / np.linalg.norm(u0), atol=1e-16)


@pytest.mark.parametrize("field, value, match", [
    ("line_points", np.zeros((5, 3)), "line_points"),
    ("line_points", np.full((6, 3), np.nan), "line_points"),
    ("line_directions", np.zeros((6, 3)), "line_directions"),
    ("sensor_offsets", np.zeros(7), "sensor_offsets"),
    ("leg_lengths", -np.ones(6), "leg_lengths"),
    ("leg_lengths", np.zeros(6), "leg_lengths"),
    ("platform_joints", np.full((6, 3), np.inf), "platform_joints"),
    ("platform_joints", "abc", "platform_joints"),
])
def test_bad_chain_geometry_raises(field, value, match):
    parts = {name: getattr(ChainGeometry.ideal(hp.HexapodGeometry()), name)
             for name in ("line_points", "line_directions", "sensor_offsets", "leg_lengths",
                          "platform_joints")}
    parts[field] = value
    with pytest.raises(GeometryError, match=match) as info:
        ChainGeometry(**parts)
    assert info.value.field == field


def test_bad_as_built_geometry_raises():
    g = hp.HexapodGeometry()
    with pytest.raises(GeometryError) as info:
        ChainGeometry.from_vector(np.zeros(54))
    assert info.value.field == "chains"
    with pytest.raises(GeometryError) as info:
        g.as_built(leg_length=np.zeros(6))                    # not a ChainGeometry field
    assert info.value.field == "leg_length"
    with pytest.raises(GeometryError) as info:
        g.as_built(sensor_offsets=np.zeros(3))
    assert info.value.field == "sensor_offsets"
    with pytest.raises(GeometryError) as info:
        g.replace(chains="ideal")
    assert info.value.field == "chains"
    with pytest.raises(GeometryError) as info:                # legs too short for home
        g.as_built(leg_lengths=np.full(6, -0.2))
    assert info.value.field == "chains"
    with pytest.raises(GeometryError) as info:
        # centimetre deviations whose home assembly meets a fold on the way from the
        # drawing (Newton from the ideal home alone lands on the mirror image below the
        # rails, z < 0: refused, not returned)
        as_built_geometry(5, 1e-2)
    assert info.value.field == "chains"
    vertical = np.zeros((6, 3))
    vertical[2] = (0.0, 0.0, 1e4)                             # a line along z: no frame
    with pytest.raises(GeometryError) as info:
        g.as_built(line_directions=vertical)
    assert info.value.field == "chains.line_directions"


# -- the drawing as chains is the ideal robot, bit for bit -----------------------------------
def test_ideal_chains_are_bit_identical(robot, rng):
    g = robot.geometry
    twin = hp.Hexapod(g.with_chains(ChainGeometry.ideal(g)))
    np.testing.assert_array_equal(kernels.pack_geometry(twin.geometry),
                                  kernels.pack_geometry(g))
    np.testing.assert_array_equal(twin.home_pose, robot.home_pose)
    poses = np.array([random_pose(robot, rng) for _ in range(4)])
    twists, dots, wrenches = (rng.normal(size=(4, 6)) for _ in range(3))
    for a, b in ((robot, twin),):
        for k in range(4):
            pose, twist = poses[k], twists[k]
            np.testing.assert_array_equal(a.inverse_kinematics(pose), b.inverse_kinematics(pose))
            np.testing.assert_array_equal(a.jacobian(pose), b.jacobian(pose))
            np.testing.assert_array_equal(a.configuration(pose), b.configuration(pose))
            np.testing.assert_array_equal(a.static_forces(pose, bounded=False),
                                          b.static_forces(pose, bounded=False))
            ra, rb = a.reduced_dynamics(pose, twist), b.reduced_dynamics(pose, twist)
            np.testing.assert_array_equal(ra.mass_matrix, rb.mass_matrix)
            np.testing.assert_array_equal(ra.bias, rb.bias)
        np.testing.assert_array_equal(
            a.inverse_dynamics_batch(poses, twists, dots, wrenches, bounded=False).actuator_forces,
            b.inverse_dynamics_batch(poses, twists, dots, wrenches, bounded=False).actuator_forces)


# -- kinematics against the Pinocchio tree and numpy ---------------------------------------
def test_home_assembles_on_the_home_branch(built):
    g = built.geometry
    pose = built.home_pose
    assert np.max(np.abs(leg_errors(g.chains, pose, g.home_q))) <= 1e-12
    close(built.inverse_kinematics(pose), g.home_q, 1e-12)
    np.testing.assert_array_equal(built.branch_of(pose, g.home_q), kernels.HOME_BRANCH)
    q = built.home_configuration
    assert np.max(np.abs(built.model.residual(q))) <= 1e-12
    close(built.carriage_positions(q), g.home_q, 1e-12)
    assert np.max(np.abs(pose - hp.HexapodGeometry().home_pose)) > 1e-4   # really moved


def test_inverse_kinematics_closes_the_tree_and_the_numpy_equations(built, rng):
    for _ in range(5):
        pose = random_pose(built, rng)
        q = built.inverse_kinematics(pose)
        assert np.max(np.abs(leg_errors(built.geometry.chains, pose, q))) <= 1e-12
        tree_q, _ = tree_state(built, pose, np.zeros(6))
        close(built.carriage_positions(tree_q), q, 1e-12)
        close(built.pose_from_configuration(tree_q), pose, 1e-12)
        close(built.platform_joints_world(pose), pose[:3] + built.geometry.chains.platform_joints
              @ rotation_from_rpy(pose[3:]).T, 1e-14)


def test_forward_kinematics_round_trip_and_modes(built, rng):
    for _ in range(3):
        pose = random_pose(built, rng)
        q = built.inverse_kinematics(pose)
        close(built.forward_kinematics(q), pose, 1e-10)
        close(built.forward_kinematics(q, guess=pose + 1e-3), pose, 1e-10)
        modes = built.assembly_modes(q)
        assert len(modes) >= 2
        assert np.min(np.max(np.abs(modes - pose), axis=1)) <= 1e-9
        for mode in modes:
            assert np.max(np.abs(leg_errors(built.geometry.chains, mode, q))) <= 1e-11
    ideal = hp.Hexapod.default()
    assert len(built.assembly_modes(built.geometry.home_q)) == len(
        ideal.assembly_modes(ideal.geometry.home_q))
    with pytest.raises(GeometryError):
        built.platform_points_world(built.home_pose)
    apart = np.tile([-0.6, 0.6], 3)                  # the legs of a rail cannot meet
    with pytest.raises(hp.AssemblyError):
        built.forward_kinematics(apart)
    assert built.assembly_modes(apart).shape == (0, 6)


def test_jacobian_against_finite_differences_and_the_tree(built, rng):
    h = 1e-6
    for _ in range(3):
        pose = random_pose(built, rng)
        jac = built.jacobian(pose)
        numeric = np.empty((6, 6))
        for j in range(6):
            e = np.eye(6)[j]
            numeric[:, j] = (built.inverse_kinematics(moved(pose, e, h), check_limits=False)
                             - built.inverse_kinematics(moved(pose, -e, h), check_limits=False)
                             ) / (2 * h)
        close(jac, numeric, 1e-7)
        twist = rng.normal(size=6)
        _, v = tree_state(built, pose, twist)
        close(v[built.indices.carriage_v], jac @ twist)
        close(built.twist_from_qdot(pose, jac @ twist), twist)


def test_leg_motion_against_the_tree_bodies(built, rng):
    """Leg directions, centres of mass and angular velocities == Pinocchio's leg bodies."""
    model = built.model.model
    data = model.createData()
    pose, twist = random_pose(built, rng), 0.3 * rng.normal(size=6)
    q, v = tree_state(built, pose, twist)
    pin.forwardKinematics(model, data, q, v)
    motion = built.leg_motion(pose, twist)
    for i in range(6):
        joint = model.getJointId(f"u_{i}_b")
        placement = data.oMi[joint]
        close(motion.direction[i], placement.rotation[:, 2], 1e-12)
        close(motion.com_position[i], placement.act(model.inertias[joint].lever), 1e-12)
        close(motion.angular_velocity[i],
              pin.getVelocity(model, data, joint, pin.LOCAL_WORLD_ALIGNED).angular)


# -- dynamics against the generic Pinocchio routes -----------------------------------------
def test_dynamics_against_the_generic_tree_routes(built, rng):
    clm = built.model
    fd = fast.fast_dynamics(built)
    for _ in range(3):
        pose = random_pose(built, rng)
        twist, tau, wrench = 0.3 * rng.normal(size=6), 5 * rng.normal(size=6), rng.normal(size=6)
        q, v = tree_state(built, pose, twist)
        rot = rotation_from_rpy(pose[3:])
        ext = np.zeros(clm.nv)
        ext[18:21], ext[21:24] = rot.T @ wrench[:3], rot.T @ wrench[3:]
        ref = forward_dynamics_tree(clm, q, v, tau, ext, method="pinocchio")
        # the platform's acceleration in world axes: (R a_lin + w x v, R a_ang)
        a_ff = ref.a[18:24]
        twist_dot = np.concatenate([rot @ a_ff[:3] + np.cross(twist[3:], twist[:3]),
                                    rot @ a_ff[3:]])
        # forward dynamics: the tree null-space route, the closed form, compiled
        for method in ("nullspace", "pinocchio"):
            res = built.forward_dynamics(pose, twist, tau, wrench, method=method)
            close(res.twist_dot, twist_dot)
            close(res.actuator_accelerations, ref.a[clm.actuated_v])
        close(built.forward_dynamics_batch(pose[None], twist[None], tau[None],
                                           wrench[None]).twist_dot[0], twist_dot)
        close(fd.forward_dynamics_full(pose, twist, tau, wrench)[0], twist_dot)
        red = built.reduced_dynamics(pose, twist)
        close(np.linalg.solve(red.mass_matrix, red.jacobian.T @ tau + wrench - red.bias), twist_dot)
        # inverse dynamics of that motion gives tau back; the generic route too
        generic = inverse_dynamics_tree(clm, q, v, ref.a, ext, method="kkt")
        close(generic.actuator_forces, tau)
        close(built.inverse_dynamics(pose, twist, twist_dot, wrench, method="kkt",
                                     bounded=False).actuator_forces, tau)
        close(built.inverse_dynamics_batch(pose[None], twist[None], twist_dot[None],
                                           wrench[None], bounded=False).actuator_forces[0], tau)
        close(fd.inverse_dynamics(pose, twist, twist_dot, wrench, bounded=False), tau)
        # statics: the generic route at rest
        q0, v0 = tree_state(built, pose, np.zeros(6))
        static = inverse_dynamics_tree(clm, q0, v0, np.zeros(clm.nv), ext, method="kkt")
        close(built.static_forces(pose, wrench, bounded=False), static.actuator_forces)
        close(fd.static_forces(pose, wrench, bounded=False), static.actuator_forces)
        close(built.static_forces_batch(pose[None], wrench[None], bounded=False)[0],
              static.actuator_forces)


def test_inverse_dynamics_derivatives_against_finite_differences(built, rng):
    pose = random_pose(built, rng)
    twist, twist_dot, wrench = 0.3 * rng.normal(size=6), rng.normal(size=6), rng.normal(size=6)
    der = built.inverse_dynamics_derivatives(pose, twist, twist_dot, wrench)

    def tau(p=pose, t=twist, d=twist_dot):
        return built.inverse_dynamics(p, t, d, wrench, method="kkt",
                                      bounded=False).actuator_forces

    h = 1e-6
    for j in range(6):
        e = np.eye(6)[j]
        close(der.d_pose[:, j], (tau(p=pose + h * e) - tau(p=pose - h * e)) / (2 * h), 1e-6)
        close(der.d_twist[:, j], (tau(t=twist + h * e) - tau(t=twist - h * e)) / (2 * h), 1e-6)
        close(der.d_twist_dot[:, j], (tau(d=twist_dot + h * e) - tau(d=twist_dot - h * e))
              / (2 * h), 1e-6)


def test_batch_matches_single_calls(built, rng):
    poses = np.array([random_pose(built, rng) for _ in range(6)])
    twists = 0.3 * rng.normal(size=(6, 6))
    ik = built.inverse_kinematics_batch(poses)
    jb = built.jacobian_batch(poses)
    for k in range(6):
        np.testing.assert_array_equal(ik.actuator_positions[k],
                                      built.inverse_kinematics(poses[k], check_limits=False))
        np.testing.assert_array_equal(jb.jacobian[k], built.jacobian(poses[k]))
        red = built.reduced_dynamics(poses[k], twists[k])
        batch = built.reduced_dynamics_batch(poses[k:k + 1], twists[k:k + 1])
        close(batch.mass_matrix[0], red.mass_matrix, 1e-13)
        close(batch.bias[0], red.bias, 1e-13)


def test_simulation_and_workspace(built, rng):
    """PID on a circle about the as-built home: the compiled platform-coordinate RK4 ==
    the tree RK4 (simulate(), Pinocchio's constrained dynamics); workspace measures ==
    the single-pose routes."""
    reference = CircleTrajectory(built.home_pose, 0.01, 1.0)
    gains = {"kp": 2000.0, "ki": 500.0, "kd": 50.0}
    start = reference(0.0)
    tree = simulate(built, 0.1, 1e-3, controller=PIDController(built, reference, **gains),
                    pose0=start.pose, twist0=start.twist)
    quick = fast.simulate_fast(built, 0.1, 1e-3, reference=reference, **gains)
    assert tree.status == quick.status == "completed"
    assert np.abs(quick.poses - tree.poses).max() <= 1e-8
    assert np.abs(tree.poses - tree.poses[0]).max() > 1e-3            # a real motion
    tree_q = np.array([built.configuration(p) for p in tree.poses[::20]])
    assert max(np.max(np.abs(built.model.residual(q))) for q in tree_q) <= 1e-10
    poses = np.array([random_pose(built, rng) for _ in range(4)])
    payload = np.array([0.0, 0.0, -5.0, 0.0, 0.1, 0.0])
    measures = workspace.evaluate(built, poses, payload)
    assert np.all(measures.ok)
    for k, pose in enumerate(poses):
        close(measures.static_forces[k], built.static_forces(pose, payload, bounded=False))
        close(measures.type_two[k], built.singularity(pose).type_two, 1e-12)


# -- URDF and files ----------------------------------------------------------------------------
def test_urdf_carries_the_chains(built):
    g, model = built.geometry, built.model.model
    for i in range(6):
        joint = model.joints[model.getJointId(f"carriage_{i}")]
        placement = model.jointPlacements[model.getJointId(f"carriage_{i}")]
        origin = g.chains.line_points[i] + g.chains.sensor_offsets[i] * g.chains.line_directions[i]
        close(placement.translation, origin, 1e-15)
        close(placement.rotation[:, 0], g.chains.line_directions[i], 1e-15)
        assert joint.nq == 1
        leg = model.inertias[model.getJointId(f"u_{i}_b")]
        close(leg.lever, [0.0, 0.0, g.chains.leg_lengths[i] / 2], 1e-15)
        anchor = model.frames[model.getFrameId(f"platform_anchor_{i}")].placement.translation
        close(anchor, g.chains.platform_joints[i], 1e-15)


@pytest.mark.parametrize("suffix", [".toml", ".json", ".yaml"])
def test_geometry_file_round_trip(tmp_path, suffix):
    g = as_built_geometry(3).replace(max_actuator_force=float("inf"))
    back = load_geometry(save_geometry(g, tmp_path / f"asbuilt{suffix}"))
    assert back == g
    np.testing.assert_array_equal(back.home_pose, g.home_pose)
    ideal = load_geometry(save_geometry(hp.HexapodGeometry(), tmp_path / f"ideal{suffix}"))
    assert ideal == hp.HexapodGeometry() and ideal.chains is None


def test_geometry_file_bad_chains_table(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("leg_length = 0.45\n[chains]\nleg_lengths = [0.45, 0.45]\n")
    with pytest.raises(GeometryError) as info:
        load_geometry(path)
    assert info.value.field == "chains"


def test_command_line_takes_an_as_built_geometry_file(tmp_path, rng):
    """``--geometry asbuilt.toml``: ik / fk / statics of the command line are those of the
    as-built robot (IK checked on the numpy closure equations)."""
    g = as_built_geometry(4)
    path = save_geometry(g, tmp_path / "asbuilt.toml")
    robot = hp.Hexapod(g)
    pose = random_pose(robot, rng)

    def run(*args):
        result = CliRunner().invoke(app, [str(a) for a in args] + ["--geometry", str(path),
                                                                     "--json"])
        assert result.exit_code == 0, result.output
        return json.loads(result.stdout)

    q = np.array(run("ik", *pose)["q"])
    assert np.max(np.abs(leg_errors(g.chains, pose, q))) <= 1e-12
    close(run("fk", *q)["pose"], pose, 1e-9)
    close(run("statics")["actuator_forces"], robot.static_forces(robot.home_pose))


def test_home_in_a_far_frame_is_the_moved_home():
    """The same as-built robot expressed in a frame 1.5 m away and turned by 0.4 rad (what
    a calibration in a tracker's frame gives): its home is the moved home."""
    g = as_built_geometry(0)
    rot = rotation_from_rpy(np.array([0.05, -0.03, 0.4]))
    shift = np.array([1.5, -0.8, 0.2])
    c = g.chains
    moved_chains = ChainGeometry(line_points=c.line_points @ rot.T + shift,
                                 line_directions=c.line_directions @ rot.T,
                                 sensor_offsets=c.sensor_offsets, leg_lengths=c.leg_lengths,
                                 platform_joints=c.platform_joints)
    far = g.with_chains(moved_chains)
    home = g.home_pose
    want = np.concatenate([rot @ home[:3] + shift,
                           rpy_from_rotation(rot @ rotation_from_rpy(home[3:]))])
    close(far.home_pose, want, 1e-12)
    robot = hp.Hexapod(far)
    close(robot.inverse_kinematics(far.home_pose), g.home_q, 1e-12)
    assert np.max(np.abs(robot.model.residual(robot.home_configuration))) <= 1e-12

"""The generic ProxSuite route on ClosedLoopModel (any robot): tree velocities and
accelerations from actuated ones, workspace Jacobian of any frame. Checked against the
hexapod's closed forms (both geometries) and, on a planar four-bar with a rank-deficient
point closure, against finite differences of assembled configurations."""

import numpy as np
import pinocchio as pin
import pytest

import hexapod_pin as hp
from hexapod_pin.core.closed_loop import ClosedLoopModel
from hexapod_pin.core.description import build_model, parse_loops

from conftest import random_pose

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def test_platform_jacobian_is_the_inverse_of_the_closed_form(any_robot, rng):
    for _ in range(3):
        pose = random_pose(any_robot, rng)
        tree_q = any_robot.configuration(pose)
        gen = any_robot.model.frame_jacobian_from_actuated(tree_q, "platform")
        jac = any_robot.jacobian(pose)
        np.testing.assert_allclose(jac @ gen, np.eye(6), atol=1e-10)
        np.testing.assert_allclose(gen, np.linalg.inv(jac), rtol=1e-10,
                                   atol=1e-10 * np.max(np.abs(gen)))


def test_tree_velocity_matches_twist_and_leg_motion(any_robot, rng):
    model = any_robot.model
    for _ in range(2):
        pose = random_pose(any_robot, rng)
        twist = rng.normal(scale=0.3, size=6)
        motion = any_robot.leg_motion(pose, twist)
        tree_q = any_robot.configuration(pose)
        v = model.velocity_from_actuated(tree_q, motion.qdot)
        assert np.max(np.abs(model.constraint_jacobian(tree_q) @ v)) < 1e-12
        np.testing.assert_allclose(v[any_robot.indices.carriage_v], motion.qdot, atol=0)
        # Pinocchio's free-flyer velocity is in the body frame: (R^T v, R^T w)
        rot = pin.rpy.rpyToMatrix(*pose[3:])
        body = v[any_robot.indices.platform_v]
        np.testing.assert_allclose(np.concatenate([rot @ body[:3], rot @ body[3:]]), twist,
                                   atol=1e-10)
        pin.forwardKinematics(model.model, model.data, tree_q, v)
        pin.updateFramePlacements(model.model, model.data)
        for i in range(6):
            fid = model.model.getFrameId(f"leg_{i}")
            vel = pin.getFrameVelocity(model.model, model.data, fid, LWA)
            np.testing.assert_allclose(vel.angular, motion.angular_velocity[i], atol=1e-10)
            com = motion.com_position[i] - model.data.oMf[fid].translation
            np.testing.assert_allclose(vel.linear + np.cross(vel.angular, com),
                                       motion.com_velocity[i], atol=1e-10)
        # the same through the actuated-velocity map
        gmap = model.actuated_velocity_map(tree_q)
        np.testing.assert_allclose(gmap @ motion.qdot, v, atol=1e-10)


def test_tree_acceleration_matches_twist_dot_and_leg_motion(any_robot, rng):
    model = any_robot.model
    pose = random_pose(any_robot, rng)
    twist, twist_dot = rng.normal(scale=0.3, size=6), rng.normal(size=6)
    motion = any_robot.leg_motion(pose, twist, twist_dot)
    tree_q = any_robot.configuration(pose)
    v = model.velocity_from_actuated(tree_q, motion.qdot)
    a = model.acceleration_from_actuated(tree_q, v, motion.qddot)
    pin.forwardKinematics(model.model, model.data, tree_q, v, a)
    pin.updateFramePlacements(model.model, model.data)
    platform = model.model.getFrameId("platform")
    acc = pin.getFrameClassicalAcceleration(model.model, model.data, platform, LWA)
    np.testing.assert_allclose(acc.vector, twist_dot, atol=1e-9)
    for i in range(6):
        fid = model.model.getFrameId(f"leg_{i}")
        leg_acc = pin.getFrameAcceleration(model.model, model.data, fid, LWA)
        np.testing.assert_allclose(leg_acc.angular, motion.angular_acceleration[i], atol=1e-9)


def test_generic_route_input_errors(robot):
    q = robot.home_configuration
    with pytest.raises(hp.InputError):
        robot.model.frame_jacobian_from_actuated(q, "no_such_frame")
    with pytest.raises(hp.InputError):
        robot.model.frame_jacobian_from_actuated(q, 10 ** 6)
    with pytest.raises(hp.InputError):
        robot.model.velocity_from_actuated(q, np.zeros(5))
    with pytest.raises(hp.InputError):
        robot.model.velocity_from_actuated(q[:-1], np.zeros(6))
    with pytest.raises(hp.InputError):
        robot.model.acceleration_from_actuated(q, np.zeros(robot.model.nv), [np.nan] * 6)


# -- a robot that is not the hexapod: a planar four-bar ------------------------------------------
CRANK, COUPLER, ROCKER, GROUND = 0.1, 0.3, 0.25, 0.3
INERTIAL = ('<inertial><mass value="1"/>'
            '<inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial>')
LIMIT = '<limit lower="-10" upper="10" effort="1" velocity="1"/>'

FOUR_BAR = f"""<?xml version="1.0"?>
<robot name="four_bar">
  <link name="world"/>
  <joint name="crank" type="revolute">
    <parent link="world"/><child link="crank_link"/>
    <origin xyz="0 0 0"/><axis xyz="0 0 1"/>{LIMIT}
  </joint>
  <link name="crank_link">
    {INERTIAL}
  </link>
  <joint name="coupler" type="revolute">
    <parent link="crank_link"/><child link="coupler_link"/>
    <origin xyz="{CRANK} 0 0"/><axis xyz="0 0 1"/>{LIMIT}
  </joint>
  <link name="coupler_link">
    {INERTIAL}
  </link>
  <joint name="coupler_tip_mount" type="fixed">
    <parent link="coupler_link"/><child link="coupler_tip"/><origin xyz="{COUPLER} 0 0"/>
  </joint>
  <link name="coupler_tip"/>
  <joint name="rocker" type="revolute">
    <parent link="world"/><child link="rocker_link"/>
    <origin xyz="{GROUND} 0 0"/><axis xyz="0 0 1"/>{LIMIT}
  </joint>
  <link name="rocker_link">
    {INERTIAL}
  </link>
  <joint name="rocker_tip_mount" type="fixed">
    <parent link="rocker_link"/><child link="rocker_tip"/><origin xyz="{ROCKER} 0 0"/>
  </joint>
  <link name="rocker_tip"/>
</robot>
"""

FOUR_BAR_LOOPS = """
closures:
  - {name: pin, type: point, frame1: coupler_tip, frame2: rocker_tip}
actuated: [crank]
"""


@pytest.fixture(scope="module")
def four_bar():
    return ClosedLoopModel(build_model(FOUR_BAR, "four_bar"), parse_loops(FOUR_BAR_LOOPS),
                           name="four_bar")


def _assembled(model, crank, guess):
    q = np.array(guess, dtype=float)
    q[0] = crank
    return model.assemble(q, tol=1e-15).q


def test_four_bar_velocity_and_frame_jacobian_match_finite_differences(four_bar):
    """The point closure of a planar linkage has an identically zero z row (rank 2 of 3):
    the proximal QP copes; velocities equal differences of assembled configurations."""
    assert four_bar.rank(_assembled(four_bar, 0.5, [0.5, 0.4, 1.8])).rank == 2
    q0 = _assembled(four_bar, 0.5, [0.5, 0.4, 1.8])
    h = 1e-5
    plus = _assembled(four_bar, 0.5 + h, q0)
    minus = _assembled(four_bar, 0.5 - h, q0)
    fd = pin.difference(four_bar.model, minus, plus) / (2 * h)
    np.testing.assert_allclose(four_bar.velocity_from_actuated(q0, [1.0]), fd, atol=1e-8)
    np.testing.assert_allclose(four_bar.actuated_velocity_map(q0)[:, 0], fd, atol=1e-8)
    tip = four_bar.model.getFrameId("coupler_tip")
    positions = []
    for q in (minus, plus):
        pin.framesForwardKinematics(four_bar.model, four_bar.data, q)
        positions.append(four_bar.data.oMf[tip].translation.copy())
    jac = four_bar.frame_jacobian_from_actuated(q0, "coupler_tip")
    np.testing.assert_allclose(jac[:3, 0], (positions[1] - positions[0]) / (2 * h), atol=1e-8)
    # second differences: tree acceleration at unit crank speed, zero crank acceleration
    v = four_bar.velocity_from_actuated(q0, [1.0])
    acc = four_bar.acceleration_from_actuated(q0, v, [0.0])
    def second(h):
        return (pin.difference(four_bar.model, q0, _assembled(four_bar, 0.5 + h, q0))
                + pin.difference(four_bar.model, q0, _assembled(four_bar, 0.5 - h, q0))) / h ** 2

    np.testing.assert_allclose(acc, (4 * second(1e-3) - second(2e-3)) / 3, atol=1e-7)


# -- every robot class: velocity maps, frame Jacobians and projections by SVD ----------------
import scipy.linalg  # noqa: E402

import stress_robots  # noqa: E402
from hexapod_pin.core.dynamics import forward_dynamics_tree  # noqa: E402
from hexapod_pin.errors import InconsistentMotionError, SingularityError  # noqa: E402

STRESS = ["five_bar_stiff", "five_bar_massless", "delta_weld", "delta_massless",
          "ladder_mixed", "ladder_massless", "planar_ladder_weld", "ladder_long"]
EFFECTOR = {"five_bar_stiff": "pin", "five_bar_massless": "pin",
            "delta_weld": "platform_center", "delta_massless": "platform_center",
            "ladder_mixed": "bar_6_tip", "ladder_massless": "bar_4_tip",
            "planar_ladder_weld": "bar_5_tip", "ladder_long": "bar_24_tip"}


def svd_velocity_map(jac, actuated, passive):
    """Reference written here: the closures' null space N by SVD, then among the motions
    ``N z`` with the actuated part ``e_j`` the one whose passive part has least norm."""
    null = scipy.linalg.null_space(jac, rcond=1e-10)
    na, np_ = null[actuated], null[passive]
    z0 = np.linalg.pinv(na) @ np.eye(len(actuated))           # any z with N_a z = I
    assert np.max(np.abs(na @ z0 - np.eye(len(actuated)))) < 1e-10   # consistent
    free = scipy.linalg.null_space(na, rcond=1e-10)            # z left free by the actuators
    if free.size:
        w = -np.linalg.pinv(np_ @ free) @ (np_ @ z0)
        z0 = z0 + free @ w
    return null @ z0


@pytest.fixture(scope="module", params=STRESS)
def stress(request):
    return stress_robots.build(request.param)


def test_velocity_map_and_frame_jacobian_match_an_svd_null_space(stress):
    clm = stress.clm
    rng = np.random.default_rng(11)
    for _ in range(3):
        q, v = stress.sample(rng)
        ref = svd_velocity_map(clm.constraint_jacobian(q), clm.actuated_v, clm.passive_v)
        scale = max(1.0, np.max(np.abs(ref)))
        maps = {m: clm.actuated_velocity_map(q, method=m) for m in ("lstsq", "qp")}
        for gmap in maps.values():
            np.testing.assert_allclose(gmap, ref, atol=1e-10 * scale)
        np.testing.assert_allclose(maps["qp"], maps["lstsq"], atol=1e-10 * scale)
        qdot = rng.normal(size=clm.n_actuated)
        for method in ("lstsq", "qp"):
            np.testing.assert_allclose(clm.velocity_from_actuated(q, qdot, method=method),
                                       ref @ qdot, atol=1e-10 * scale * max(1, np.abs(qdot).max()))
        data = clm.model.createData()
        pin.computeJointJacobians(clm.model, data, q)
        fid = clm.frame_id(EFFECTOR[stress.name])
        jac_ref = pin.getFrameJacobian(clm.model, data, fid, LWA) @ ref
        for method in ("lstsq", "qp"):
            np.testing.assert_allclose(
                clm.frame_jacobian_from_actuated(q, EFFECTOR[stress.name], method=method),
                jac_ref, atol=1e-10 * scale)


def test_acceleration_map_on_both_routes(stress):
    """``J_c a = -gamma`` with the actuated part given; the passive part of least norm:
    the SVD reference is the particular solution plus the null-space correction."""
    clm = stress.clm
    rng = np.random.default_rng(12)
    q, v = stress.sample(rng)
    jac, gamma = clm.constraint_jacobian(q), clm.constraint_drift(q, v)
    qdd = rng.normal(size=clm.n_actuated)
    p, a = clm.passive_v, clm.actuated_v
    ref = np.zeros(clm.nv)
    ref[a] = qdd
    ref[p] = np.linalg.pinv(jac[:, p], rcond=1e-10) @ (-gamma - jac[:, a] @ qdd)
    scale = max(1.0, np.max(np.abs(ref)))
    for method in ("lstsq", "qp"):
        acc = clm.acceleration_from_actuated(q, v, qdd, method=method)
        np.testing.assert_allclose(acc, ref, atol=1e-10 * scale)
        assert np.max(np.abs(jac @ acc + gamma)) <= 1e-10 * scale


def test_projections_match_closed_forms(stress):
    """Euclidean: ``N N^T v``; mass metric: ``N (N^T M N)^-1 N^T M v`` (N by SVD); and the
    mass-metric projection of the free acceleration is the constrained forward dynamics
    (Gauss's principle), computed by the KKT route of core/dynamics."""
    clm = stress.clm
    rng = np.random.default_rng(13)
    q, v = stress.sample(rng)
    null = scipy.linalg.null_space(clm.constraint_jacobian(q), rcond=1e-10)
    raw = rng.normal(size=clm.nv)
    for method in ("lstsq", "qp"):
        np.testing.assert_allclose(clm.project_velocity(q, raw, "euclidean", method),
                                   null @ null.T @ raw, atol=1e-10)
    mass = pin.crba(clm.model, clm.model.createData(), q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    if np.linalg.eigvalsh(mass)[0] <= 1e-12 * np.abs(mass).max():
        with pytest.raises(SingularityError):
            clm.project_velocity(q, raw)
        return
    reduced = null.T @ mass @ null
    ref = null @ np.linalg.solve(reduced, null.T @ mass @ raw)
    scale = max(1.0, np.abs(ref).max())
    for method in ("lstsq", "qp"):
        np.testing.assert_allclose(clm.project_velocity(q, raw, "mass", method), ref,
                                   atol=1e-9 * scale)
    u = rng.normal(size=clm.n_actuated)
    tau = np.zeros(clm.nv)
    tau[clm.actuated_v] = u
    data = clm.model.createData()
    free_acc = np.linalg.solve(mass, tau - pin.nle(clm.model, data, q, v))
    fd = forward_dynamics_tree(clm, q, v, u, method="kkt").a
    scale = max(1.0, np.abs(fd).max())
    for method in ("lstsq", "qp"):
        np.testing.assert_allclose(clm.project_acceleration(q, v, free_acc, "mass", method), fd,
                                   atol=1e-8 * scale)


# -- a rod spinning about its own axis between two ball joints ------------------------------
def _revolute(name, parent, child, axis, xyz="0 0 0"):
    return (f'<joint name="{name}" type="revolute"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="{xyz}"/><axis xyz="{axis}"/>{LIMIT}</joint>'
            f'<link name="{child}">{INERTIAL}</link>')


# a carriage sliding along y (actuated) holds a rod by a ball joint (three revolute joints);
# the rod's far end is held by a second ball on a passive carriage sliding along z
ROD = f"""<?xml version="1.0"?>
<robot name="slider_rod">
  <link name="world"/>
  <joint name="slider" type="prismatic">
    <parent link="world"/><child link="carriage"/><axis xyz="0 1 0"/>{LIMIT}
  </joint>
  <link name="carriage">{INERTIAL}</link>
  {_revolute("ball_x", "carriage", "ball_x_link", "1 0 0")}
  {_revolute("ball_y", "ball_x_link", "ball_y_link", "0 1 0")}
  {_revolute("ball_z", "ball_y_link", "rod", "0 0 1")}
  <joint name="rod_tip_mount" type="fixed">
    <parent link="rod"/><child link="rod_tip"/><origin xyz="0.5 0 0"/>
  </joint>
  <link name="rod_tip"/>
  <joint name="far_slider" type="prismatic">
    <parent link="world"/><child link="far_carriage"/><origin xyz="0.4 0 0"/>
    <axis xyz="0 0 1"/>{LIMIT}
  </joint>
  <link name="far_carriage">{INERTIAL}</link>
</robot>
"""
ROD_LOOPS = """
closures:
  - {name: far_ball, type: point, frame1: rod_tip, frame2: far_carriage}
actuated: [slider]
"""


def test_rod_spin_gets_the_minimum_norm_and_matches_svd():
    """The rod between two ball joints can spin about its own axis: the passive motion is
    not unique; the map returns the least-norm one (the SVD reference), and moving the
    slider is still exact."""
    clm = ClosedLoopModel(build_model(ROD, "slider_rod"), parse_loops(ROD_LOOPS), name="rod")
    q = clm.assemble(np.array([0.1, 0.1, 0.2, -0.3, 0.2])).q
    assert clm.mobility(q) == 2 and clm.n_actuated == 1
    ref = svd_velocity_map(clm.constraint_jacobian(q), clm.actuated_v, clm.passive_v)
    for method in ("lstsq", "qp"):
        np.testing.assert_allclose(clm.actuated_velocity_map(q, method), ref, atol=1e-10)
    # the tip point's Jacobian does not depend on the spin: finite differences of assemblies
    h = 1e-6
    tips = []
    for dq in (-h, h):
        qq = q.copy()
        qq[clm.joint_q_index("slider")] += dq
        qq = clm.assemble(qq).q
        data = clm.model.createData()
        pin.framesForwardKinematics(clm.model, data, qq)
        tips.append(data.oMf[clm.frame_id("rod_tip")].translation.copy())
    jac = clm.frame_jacobian_from_actuated(q, "rod_tip")
    np.testing.assert_allclose(jac[:3, 0], (tips[1] - tips[0]) / (2 * h), atol=1e-7)


def test_inconsistent_actuated_velocities_raise(four_bar):
    """The four-bar with crank AND rocker actuated (mobility 1): a consistent pair passes,
    any other pair raises InconsistentMotionError (a SolverError) on both routes."""
    both = ClosedLoopModel(build_model(FOUR_BAR, "four_bar"),
                           parse_loops(FOUR_BAR_LOOPS.replace("[crank]", "[crank, rocker]")),
                           name="four_bar_2")
    q = both.assemble([0.5, 0.4, 1.8], fixed=[0], tol=1e-15).q
    v = both.complete_velocity(q, [0], [1.0])
    rocker_rate = v[both.joint_v_index("rocker")]
    for method in ("lstsq", "qp"):
        np.testing.assert_allclose(both.velocity_from_actuated(q, [1.0, rocker_rate], method), v,
                                   atol=1e-12)
        with pytest.raises(InconsistentMotionError):
            both.velocity_from_actuated(q, [1.0, rocker_rate + 0.1], method)
    with pytest.raises(hp.SolverError):
        both.actuated_velocity_map(q)


def test_frame_acceleration_bias_matches_second_differences(four_bar):
    """At a constant unit crank speed the coupler tip accelerates by d^2 p / d theta^2:
    second differences of assembled configurations (Richardson), and the frame's
    acceleration is ``K qdd + bias`` for any crank acceleration."""
    q0 = _assembled(four_bar, 0.5, [0.5, 0.4, 1.8])
    tip = four_bar.frame_id("coupler_tip")

    def position(crank):
        data = four_bar.model.createData()
        pin.framesForwardKinematics(four_bar.model, data, _assembled(four_bar, crank, q0))
        return data.oMf[tip].translation.copy()

    def second(h):
        return (position(0.5 + h) - 2 * position(0.5) + position(0.5 - h)) / h ** 2

    v = four_bar.velocity_from_actuated(q0, [1.0])
    bias = four_bar.acceleration_bias_from_actuated(q0, v, "coupler_tip")
    np.testing.assert_allclose(bias[:3], (4 * second(1e-3) - second(2e-3)) / 3, atol=1e-7)
    jac = four_bar.frame_jacobian_from_actuated(q0, "coupler_tip")
    acc = four_bar.acceleration_from_actuated(q0, v, [2.5])
    pin.forwardKinematics(four_bar.model, four_bar.data, q0, v, acc)
    classical = pin.getFrameClassicalAcceleration(four_bar.model, four_bar.data, tip, LWA)
    np.testing.assert_allclose(classical.vector, jac[:, 0] * 2.5 + bias, atol=1e-12)


def test_hexapod_velocity_map_matches_an_svd_null_space(robot, rng):
    model = robot.model
    q = robot.configuration(random_pose(robot, rng))
    ref = svd_velocity_map(model.constraint_jacobian(q), model.actuated_v, model.passive_v)
    for method in ("lstsq", "qp"):
        np.testing.assert_allclose(model.actuated_velocity_map(q, method), ref,
                                   atol=1e-10 * max(1.0, np.abs(ref).max()))


# --------------------------------------------------------- closure_motion building blocks
from hexapod_pin.core import closure_motion  # noqa: E402


def test_row_basis_matches_an_svd_of_the_rows(rng):
    """The compiled pivoted QR against numpy's SVD: as many rows as the rank, those rows
    independent, the null-space basis spanning the SVD's null space (equal projectors), the
    range basis orthonormal over the chosen rows, the right inverse = pinv of those rows."""
    for trial in range(60):
        m, n = rng.integers(1, 16, 2)
        jac = rng.normal(size=(m, n)) * 10.0 ** rng.uniform(-3, 3)
        if m > 2:
            jac[-1] = jac[0] - 2.0 * jac[1]             # a redundant row
        if n > 3 and trial % 3 == 0:
            jac[:, 1] = 0.0                              # a coordinate no row involves
        basis = closure_motion.row_basis(jac)
        _, sv, vt = np.linalg.svd(jac)
        rank = int(np.sum(sv > 1e-10 * sv[0]))
        assert basis.rows.size == rank
        np.testing.assert_array_equal(closure_motion.independent_rows(jac), np.sort(basis.rows))
        assert np.linalg.matrix_rank(jac[basis.rows]) == rank
        svd_null = vt[rank:].T
        np.testing.assert_allclose(basis.null @ basis.null.T, svd_null @ svd_null.T, atol=1e-10)
        np.testing.assert_allclose(basis.range.T @ basis.range, np.eye(rank), atol=1e-12)
        np.testing.assert_allclose(basis.pinv, np.linalg.pinv(jac[basis.rows]),
                                   atol=1e-9 * np.abs(np.linalg.pinv(jac[basis.rows])).max())
    with pytest.raises(hp.SolverError):
        closure_motion.row_basis(np.array([[1.0, np.nan]]))


def test_qp_route_answers_do_not_depend_on_the_reused_problem(rng):
    """The ProxSuite route keeps one problem per size and thread: the same completion before
    and after other data of that size gives the same answer, equal to the direct route."""
    jacs = [rng.normal(size=(5, 9)) for _ in range(3)]
    jacs[1][4] = jacs[1][0] + jacs[1][2]                 # a redundant row in the middle one
    known, values = np.array([0, 4, 7]), rng.normal(size=3)
    first = closure_motion.complete(jacs[0], np.zeros(5), known, values, "qp")
    for jac in jacs[1:] + jacs[:1]:
        qp = closure_motion.complete(jac, np.zeros(5), known, values, "qp")
        direct = closure_motion.complete(jac, np.zeros(5), known, values, "lstsq")
        np.testing.assert_allclose(qp, direct, atol=1e-10)
    np.testing.assert_allclose(qp, first, atol=1e-12)
    with pytest.raises(hp.InputError):
        closure_motion.complete(jacs[0], np.zeros(5), known, [np.nan, 0.0, 0.0], "lstsq")

"""The example-parallel-robots format (URDF + robot.yaml) on a five-bar linkage and a delta
robot written for these tests (tests/data/parallel/).

Independent routes: closed-form kinematics of both mechanisms (circle and sphere
intersections), finite differences, the five-bar's 3d and 6d descriptions against each
other, a plain numpy KKT solve with the redundant rows removed by hand, and statics by
virtual power (no multipliers).
"""

import math
import shutil

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg
from conftest import REFERENCE, fd_constraint_jacobian

from hexapod_pin.core.dynamics import forward_dynamics_tree, inverse_dynamics_tree
from hexapod_pin.errors import DescriptionError, MissingFileError
from hexapod_pin.loaders.parallel_robots import load_parallel_robot, parse_robot_yaml
from hexapod_pin.loaders.robots import actuation_report

DATA = REFERENCE.parent / "parallel"
# five-bar (tests/data/parallel/five_bar_*): pivots at x = -/+ D/2, links L1 then L2, plane x-z
D, L1, L2 = 0.2, 0.25, 0.3
# delta (tests/data/parallel/delta): base radius, platform radius, upper arm, forearm
RB, RPF, LA, LF = 0.20, 0.05, 0.25, 0.50
PHI = (0.0, 2 * math.pi / 3, 4 * math.pi / 3)


@pytest.fixture(scope="module")
def five_bar_6d():
    return load_parallel_robot(DATA / "five_bar_6d")


@pytest.fixture(scope="module")
def five_bar_3d():
    return load_parallel_robot(DATA / "five_bar_3d")


@pytest.fixture(scope="module")
def delta():
    return load_parallel_robot(DATA / "delta")


# ----------------------------------------------------------------- closed-form kinematics
def _direction_angle(vec):
    """Angle t of a link whose direction is (cos t, 0, -sin t) (rotation about +y)."""
    return math.atan2(-vec[2], vec[0])


def _circle_point(a, p, r1, r2, sign):
    d = p - a
    dist = np.linalg.norm(d)
    e = d / dist
    along = (r1 ** 2 - r2 ** 2 + dist ** 2) / (2 * dist)
    normal = np.array([-e[2], 0.0, e[0]])
    return a + along * e + sign * math.sqrt(r1 ** 2 - along ** 2) * normal


def five_bar_configuration(clm, point):
    """Closed-form inverse kinematics: the closing joint at ``point`` (x, 0, z)."""
    q = np.zeros(clm.nq)
    values = {}
    for k, x, sign in ((1, -D / 2, 1.0), (2, D / 2, -1.0)):
        pivot = np.array([x, 0.0, 0.0])
        elbow = _circle_point(pivot, point, L1, L2, sign)
        values[f"mot{k}"] = _direction_angle(elbow - pivot)
        values[f"free{k}"] = _direction_angle(point - elbow) - values[f"mot{k}"]
    if clm.model.existJointName("closure_A"):
        values["closure_A"] = (values["mot2"] + values["free2"]) - (values["mot1"] + values["free1"])
    for name, value in values.items():
        q[clm.joint_q_index(name)] = value
    return q


def five_bar_point(mot1, mot2, sign=-1.0):
    """Closed-form forward kinematics: the closing point for the two motor angles."""
    e1 = np.array([-D / 2 + L1 * math.cos(mot1), 0.0, -L1 * math.sin(mot1)])
    e2 = np.array([D / 2 + L1 * math.cos(mot2), 0.0, -L1 * math.sin(mot2)])
    return _circle_point(e1, e2, L2, L2, sign)


def delta_configuration(clm, centre):
    """Closed-form inverse kinematics of the delta: platform centre -> joint angles."""
    q = np.zeros(clm.nq)
    for k, phi in enumerate(PHI):
        rot = pin.rpy.rpyToMatrix(0, 0, phi)
        wrist = centre + RPF * np.array([math.cos(phi), math.sin(phi), 0.0])
        w = rot.T @ (wrist - RB * np.array([math.cos(phi), math.sin(phi), 0.0]))
        a_c, b_c = 2 * LA * w[0], -2 * LA * w[2]
        c_c = w @ w + LA ** 2 - LF ** 2
        base = math.atan2(b_c, a_c)
        t = max((base - math.acos(c_c / math.hypot(a_c, b_c)),
                 base + math.acos(c_c / math.hypot(a_c, b_c))), key=math.cos)
        elbow = LA * np.array([math.cos(t), 0.0, -math.sin(t)])
        u = pin.rpy.rpyToMatrix(0, t, 0).T @ ((w - elbow) / LF)
        beta, alpha = math.asin(u[1]), math.atan2(-u[2], u[0])
        for name, value in ((f"motor_{k}", t), (f"elbow_{k}_Y", alpha), (f"elbow_{k}_Z", beta),
                            (f"wrist_{k}_Z", -beta), (f"wrist_{k}_Y", -(t + alpha))):
            q[clm.joint_q_index(name)] = value
    return q



def _random_motion(clm, q, rng):
    v = clm.complete_velocity(q, clm.actuated_v, rng.normal(size=clm.n_actuated))
    a = clm.complete_acceleration(q, v, clm.actuated_v, rng.normal(size=clm.n_actuated))
    return v, a


def _tau(clm, u):
    tau = np.zeros(clm.nv)
    tau[clm.actuated_v] = u
    return tau


# --------------------------------------------------------------------------- structure
def test_the_files_load_as_upstream_describes():
    f6 = load_parallel_robot(DATA / "five_bar_6d")
    assert [c.name for c in f6.closures] == ["closure_ACclosure_B"]
    assert f6.closures[0].type == "weld" and f6.nv == 5 and f6.n_rows == 6
    f3 = load_parallel_robot(DATA / "five_bar_3d" / "robot.urdf")
    assert f3.closures[0].type == "point" and f3.nv == 4 and f3.n_rows == 3
    d = load_parallel_robot(DATA / "delta")
    # UJOINT_YZ / UJOINT_ZY: each elbow and wrist became two revolutes, in tree order
    assert list(d.model.names)[1:6] == ["motor_0", "elbow_0_Y", "elbow_0_Z", "wrist_0_Z",
                                        "wrist_0_Y"]
    assert [d.model.joints[j].shortname() for j in range(2, 6)] == \
        ["JointModelRY", "JointModelRZ", "JointModelRZ", "JointModelRY"]
    assert d.actuated_joints == ("motor_0", "motor_1", "motor_2")
    assert d.model.check(d.model.createData())
    # the platform still weighs what the URDF says, on the joint that now carries it
    assert d.model.inertias[d.model.getJointId("wrist_0_Y")].mass == pytest.approx(0.3)
    # the free-flyer option of upstream's loader
    ff = load_parallel_robot(DATA / "five_bar_3d", free_flyer=True)
    assert ff.model.names[1] == "root_joint" and ff.nv == 10


def test_rank_mobility_and_actuation():
    cases = {"five_bar_6d": (6, 3, 2), "five_bar_3d": (3, 2, 2), "delta": (12, 12, 3)}
    for name, (rows, rank, mobility) in cases.items():
        clm = load_parallel_robot(DATA / name)
        if name == "delta":
            q = delta_configuration(clm, np.array([0.01, -0.02, -0.45]))
        else:
            q = five_bar_configuration(clm, np.array([0.02, 0.0, -0.35]))
        report = actuation_report(clm, q)
        assert (report.n_rows, report.rank, report.mobility) == (rows, rank, mobility), name
        assert report.status == "square" and report.n_actuated == mobility


# ---------------------------------------------------------------------------- kinematics
@pytest.mark.parametrize("variant", ["five_bar_6d", "five_bar_3d"])
def test_five_bar_assembly_matches_closed_form(variant):
    clm = load_parallel_robot(DATA / variant)
    rng = np.random.default_rng(0)
    q_ref = five_bar_configuration(clm, np.array([0.02, 0.0, -0.35]))
    assert np.max(np.abs(clm.residual(q_ref))) < 1e-15
    for _ in range(4):
        start = q_ref.copy()
        start[clm.actuated_v] += rng.uniform(-0.1, 0.1, 2)          # new motor angles
        passive = clm.passive_v
        start[passive] += rng.uniform(-0.05, 0.05, passive.size)     # a wrong guess for the rest
        result = clm.assemble(start)
        assert result.residual_norm <= 1e-10
        mot1, mot2 = result.q[clm.joint_q_index("mot1")], result.q[clm.joint_q_index("mot2")]
        data = clm.model.createData()
        pin.framesForwardKinematics(clm.model, data, result.q)
        point = data.oMf[clm.model.getFrameId("closure_B")].translation
        # the two closed-form solutions (assembly modes): the robot stayed in the hanging one
        modes = sorted((five_bar_point(mot1, mot2, sign) for sign in (-1.0, 1.0)),
                       key=lambda p: p[2])
        np.testing.assert_allclose(point, modes[0], atol=1e-10)


def test_delta_assembly_matches_closed_form(delta):
    rng = np.random.default_rng(1)
    q_ref = delta_configuration(delta, np.array([0.01, -0.02, -0.45]))
    assert np.max(np.abs(delta.residual(q_ref))) < 1e-14
    for _ in range(4):
        start = q_ref.copy()
        start[delta.actuated_v] += rng.uniform(-0.05, 0.05, 3)
        start[delta.passive_v] += rng.uniform(-0.02, 0.02, delta.passive_v.size)
        q = delta.assemble(start).q
        assert np.max(np.abs(delta.residual(q))) <= 1e-10
        data = delta.model.createData()
        pin.framesForwardKinematics(delta.model, data, q)
        centre = data.oMf[delta.model.getFrameId("platform_center", pin.FrameType.BODY)]
        # the platform only translates (U-U forearms keep it parallel to the base)
        np.testing.assert_allclose(centre.rotation, np.eye(3), atol=1e-10)
        # each forearm spans L_F between its elbow and its platform point
        for k, phi in enumerate(PHI):
            t = q[delta.joint_q_index(f"motor_{k}")]
            base = RB * np.array([math.cos(phi), math.sin(phi), 0.0])
            elbow = base + pin.rpy.rpyToMatrix(0, 0, phi) @ (LA * np.array([math.cos(t), 0,
                                                                               -math.sin(t)]))
            wrist = centre.translation + RPF * np.array([math.cos(phi), math.sin(phi), 0.0])
            assert np.linalg.norm(wrist - elbow) == pytest.approx(LF, abs=1e-10)


@pytest.mark.parametrize("name", ["five_bar_6d", "five_bar_3d", "delta"])
def test_constraint_jacobian_matches_finite_differences(name):
    clm = load_parallel_robot(DATA / name)
    rng = np.random.default_rng(2)
    q = rng.uniform(-1.0, 1.0, clm.nq)
    np.testing.assert_allclose(clm.constraint_jacobian(q), fd_constraint_jacobian(clm, q), atol=1e-8)


# ------------------------------------------------------------------------------ dynamics
@pytest.mark.parametrize("name", ["five_bar_6d", "five_bar_3d", "delta"])
def test_forward_of_inverse_is_identity(name):
    clm = load_parallel_robot(DATA / name)
    if name == "delta":
        q = delta_configuration(clm, np.array([0.02, 0.01, -0.42]))
    else:
        q = five_bar_configuration(clm, np.array([-0.03, 0.0, -0.38]))
    rng = np.random.default_rng(3)
    for _ in range(3):
        v, a = _random_motion(clm, q, rng)
        results = [inverse_dynamics_tree(clm, q, v, a, method=m) for m in ("qp", "kkt")]
        np.testing.assert_allclose(results[0].actuator_forces, results[1].actuator_forces,
                                   atol=1e-9)
        for method in ("pinocchio", "qp", "kkt"):
            fd = forward_dynamics_tree(clm, q, v, results[0].actuator_forces, method=method)
            assert np.all(np.isfinite(fd.a)) and np.all(np.isfinite(fd.multipliers))
            np.testing.assert_allclose(fd.a, a, atol=1e-8)


def test_five_bar_3d_and_6d_are_the_same_machine(five_bar_6d, five_bar_3d):
    """Same links, same pin: a 6-row weld on the revolute axis (3 rows redundant) and a
    3-row point closure (1 redundant) give the same torques and motor accelerations."""
    point = np.array([0.04, 0.0, -0.33])
    q6, q3 = five_bar_configuration(five_bar_6d, point), five_bar_configuration(five_bar_3d, point)
    rng = np.random.default_rng(4)
    qd, qdd = rng.normal(size=2), rng.normal(size=2)
    v6 = five_bar_6d.complete_velocity(q6, five_bar_6d.actuated_v, qd)
    v3 = five_bar_3d.complete_velocity(q3, five_bar_3d.actuated_v, qd)
    a6 = five_bar_6d.complete_acceleration(q6, v6, five_bar_6d.actuated_v, qdd)
    a3 = five_bar_3d.complete_acceleration(q3, v3, five_bar_3d.actuated_v, qdd)
    u6 = inverse_dynamics_tree(five_bar_6d, q6, v6, a6).actuator_forces
    u3 = inverse_dynamics_tree(five_bar_3d, q3, v3, a3).actuator_forces
    np.testing.assert_allclose(u6, u3, atol=1e-10)
    u = rng.normal(size=2)
    f6 = forward_dynamics_tree(five_bar_6d, q6, v6, u)
    f3 = forward_dynamics_tree(five_bar_3d, q3, v3, u)
    np.testing.assert_allclose(f6.a[five_bar_6d.actuated_v], f3.a[five_bar_3d.actuated_v],
                               atol=1e-9)


def test_redundant_rows_match_the_hand_reduced_system(five_bar_6d):
    """The weld's out-of-plane rows (anchor-1 axes y, x-rotation, z-rotation: the revolute
    axes are along y) removed by hand; plain numpy KKT on the 3 in-plane rows."""
    clm = five_bar_6d
    q = five_bar_configuration(clm, np.array([0.0, 0.0, -0.36]))
    assert clm.rank(q).rank == 3
    rng = np.random.default_rng(5)
    v, _ = _random_motion(clm, q, rng)
    u = rng.normal(size=2)
    keep = [0, 2, 4]                                      # v_x, v_z, w_y of the weld
    jac = clm.constraint_jacobian(q)[keep]
    gamma = clm.constraint_drift(q, v)[keep]
    assert np.linalg.matrix_rank(jac) == 3
    model, data = clm.model, clm.model.createData()
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    bias = pin.rnea(model, data, q, v, np.zeros(clm.nv))
    kkt = np.block([[mass, -jac.T], [jac, np.zeros((3, 3))]])
    sol = np.linalg.solve(kkt, np.concatenate([_tau(clm, u) - bias, -gamma]))
    a_ref, lam_ref = sol[:clm.nv], sol[clm.nv:]
    for method in ("pinocchio", "qp", "kkt"):
        fd = forward_dynamics_tree(clm, q, v, u, method=method)
        assert np.all(np.isfinite(fd.multipliers))
        np.testing.assert_allclose(fd.a, a_ref, atol=1e-9)
        full = clm.constraint_jacobian(q)
        np.testing.assert_allclose(full.T @ fd.multipliers, jac.T @ lam_ref, atol=1e-8)
        # minimum norm: nothing on the redundant rows
        np.testing.assert_allclose(fd.multipliers[[1, 3, 5]], 0.0, atol=1e-8)
    for method in ("qp", "kkt"):
        inv = inverse_dynamics_tree(clm, q, v, a_ref, method=method)
        np.testing.assert_allclose(inv.actuator_forces, u, atol=1e-9)


def test_delta_statics_by_virtual_power(delta):
    """Motor torques holding the delta and a load, from the motion-space balance
    (no multipliers): N^T (g(q) - f_load) = (S N)^T u for a basis N of the closed motions."""
    q = delta_configuration(delta, np.array([-0.03, 0.02, -0.47]))
    model, data = delta.model, delta.model.createData()
    load = np.array([1.0, -2.0, -5.0])                     # N on the platform centre
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    fid = model.getFrameId("platform_center", pin.FrameType.BODY)
    jac_p = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
    tau_ext = jac_p.T @ load
    gravity = pin.computeGeneralizedGravity(model, data, q)
    null = scipy.linalg.null_space(delta.constraint_jacobian(q))
    u_ref = np.linalg.solve(null[delta.actuated_v].T, null.T @ (gravity - tau_ext))
    zero = np.zeros(delta.nv)
    for method in ("qp", "kkt"):
        inv = inverse_dynamics_tree(delta, q, zero, zero, tau_ext=tau_ext, method=method)
        np.testing.assert_allclose(inv.actuator_forces, u_ref, atol=1e-10)


# --------------------------------------------------------------------- bad descriptions
def _variant(tmp_path, yaml_text, source="five_bar_6d"):
    folder = tmp_path / "robot"
    folder.mkdir(exist_ok=True)
    shutil.copy(DATA / source / "robot.urdf", folder / "robot.urdf")
    (folder / "robot.yaml").write_text(yaml_text)
    return folder


BAD_YAML = {
    "missing frame": (("closed_loop: [['closure_A', 'nowhere']]\ntype: ['6d']\n"
                      "name_mot: ['mot1', 'mot2']\n"), "nowhere"),
    "same body": (("closed_loop: [['distal_2', 'closure_B']]\ntype: ['3d']\n"
                  "name_mot: ['mot1', 'mot2']\n"), "distal_2Cclosure_B"),
    "same frame": (("closed_loop: [['closure_A', 'closure_A']]\ntype: ['3d']\n"
                   "name_mot: ['mot1']\n"), "closure_A"),
    "motor not in tree": (("closed_loop: [['closure_A', 'closure_B']]\ntype: ['6d']\n"
                          "name_mot: ['mot1', 'mot3']\n"), "mot3"),
    "malformed yaml": ("closed_loop: [['closure_A', 'closure_B']\ntype: ['6d']\n", "line 2"),
    "unknown type": (("closed_loop: [['closure_A', 'closure_B']]\ntype: ['5d']\n"
                     "name_mot: ['mot1']\n"), "type[0]"),
    "type length": (("closed_loop: [['closure_A', 'closure_B']]\ntype: ['6d', '3d']\n"
                    "name_mot: ['mot1']\n"), "type"),
    "not a pair": ("closed_loop: [['closure_A']]\ntype: ['6d']\nname_mot: ['mot1']\n",
                   "closed_loop[0]"),
    "no motors": ("closed_loop: [['closure_A', 'closure_B']]\ntype: ['6d']\n", "name_mot"),
    "unknown key": ("closed_loop: []\nname_mot: []\nname_mots: []\n", "name_mots"),
    "joint_name not in tree": (("closed_loop: []\nname_mot: []\njoint_name: ['elbow']\n"
                               "joint_type: ['SPHERICAL']\n"), "elbow"),
    "bad joint_type": (("closed_loop: []\nname_mot: []\njoint_name: ['free1']\n"
                       "joint_type: ['UJOINT_XX']\n"), "free1"),
    "joint_type length": ("closed_loop: []\nname_mot: []\njoint_name: ['free1']\n",
                          "joint_type"),
}


@pytest.mark.parametrize("case", sorted(BAD_YAML))
def test_bad_descriptions_name_the_culprit(tmp_path, case):
    text, culprit = BAD_YAML[case]
    with pytest.raises(DescriptionError) as info:
        load_parallel_robot(_variant(tmp_path, text))
    assert info.value.culprit == culprit


def test_missing_files_raise(tmp_path):
    with pytest.raises(MissingFileError, match="robot.urdf: file not found"):   # no URDF
        load_parallel_robot(tmp_path)
    (tmp_path / "robot.urdf").write_text("<robot name='r'><link name='a'/></robot>")
    with pytest.raises(MissingFileError, match="robot.yaml: file not found"):
        load_parallel_robot(tmp_path)


def test_joint_type_changes(tmp_path):
    """SPHERICAL and FIXED from joint_name / joint_type, as upstream's loader applies them."""
    base = "closed_loop: [['closure_A', 'closure_B']]\ntype: ['3d']\nname_mot: ['mot1', 'mot2']\n"
    fixed = load_parallel_robot(_variant(tmp_path, base + "joint_name: ['free2']\n"
                                         "joint_type: ['FIXED']\n", "five_bar_3d"))
    assert fixed.nv == 3 and not fixed.model.existJointName("free2")
    assert fixed.model.existFrame("distal_2")
    q = fixed.neutral()
    q[[fixed.joint_q_index(n) for n in ("mot1", "free1", "mot2")]] = (1.2, 0.5, 2.0)
    report = actuation_report(fixed, fixed.assemble(q, fixed=[fixed.joint_v_index("mot2")]).q)
    assert report.mobility == 1                      # a four-bar
    spherical = load_parallel_robot(_variant(tmp_path, base + "joint_name: ['free2']\n"
                                             "joint_type: ['SPHERICAL']\n", "five_bar_3d"))
    jid = spherical.model.getJointId("free2")
    assert spherical.model.joints[jid].shortname() == "JointModelSpherical"
    assert spherical.nv == 6
    # inertias and frames followed the change
    ref = load_parallel_robot(DATA / "five_bar_3d")
    assert spherical.model.inertias[jid].isApprox(ref.model.inertias[ref.model.getJointId("free2")])
    data_s, data_r = spherical.model.createData(), ref.model.createData()
    pin.framesForwardKinematics(spherical.model, data_s, spherical.neutral())
    pin.framesForwardKinematics(ref.model, data_r, ref.neutral())
    for frame in ("closure_B", "pin", "distal_2"):
        np.testing.assert_allclose(
            data_s.oMf[spherical.model.getFrameId(frame)].homogeneous,
            data_r.oMf[ref.model.getFrameId(frame)].homogeneous, atol=1e-15)


def test_type_defaults_to_6d():
    spec = parse_robot_yaml("closed_loop: [['a', 'b'], ['c', 'd']]\nname_mot: ['m']\n")
    assert spec.types == ("6d", "6d")
    spec = parse_robot_yaml("closed_loop: [['a', 'b']]\ntype: ['3D']\nname_mot: ['m']\n")
    assert spec.types == ("3d",) and spec.closure_name(0) == "aCb"

"""The SDF reader (hexapod_pin.loaders.sdf): poses, joints, inertias, loops, URDF export, bad input.

Checked against routes that do not use the reader: poses and axes computed here with
numpy from the numbers written in the SDF text, Rodrigues rotations, Pinocchio's own
URDF parser (for the SDF -> URDF export), finite differences.
"""

import math
import textwrap

import numpy as np
import pinocchio as pin
import pytest

from hexapod_pin.core.closed_loop import ClosedLoopModel
from hexapod_pin.core.description import parse_loops
from hexapod_pin.errors import DescriptionError
from hexapod_pin.loaders.sdf import build_tree, closed_loop_from_sdf, loops_yaml, parse_sdf, sdf_to_urdf

from conftest import fd_constraint_jacobian, random_configuration


def rpy_matrix(r, p, y):
    """R = Rz(y) Ry(p) Rx(r), written out here (not Pinocchio's)."""
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), \
        math.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def homogeneous(x, y, z, r, p, yaw):
    out = np.eye(4)
    out[:3, :3] = rpy_matrix(r, p, yaw)
    out[:3, 3] = (x, y, z)
    return out


def rodrigues(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def se3_to_h(m):
    return m.homogeneous


# A 1.6 file with absolute link poses: a pendulum with a ball, a prismatic, a fixed link
PENDULUM_16 = """
<sdf version="1.6"><model name="pendulum">
  <link name="base"><pose>0 0 1 0 0 0</pose>
    <inertial><mass>2</mass><inertia><ixx>0.1</ixx><iyy>0.2</iyy><izz>0.3</izz></inertia></inertial>
  </link>
  <link name="arm"><pose>0.1 0.2 0.9 0.3 -0.2 0.5</pose>
    <inertial><pose>0.05 0 -0.2 0 0.4 0</pose><mass>0.7</mass>
      <inertia><ixx>0.01</ixx><iyy>0.02</iyy><izz>0.015</izz><ixy>0.001</ixy><ixz>-0.002</ixz><iyz>0.0005</iyz></inertia></inertial>
    <visual name="arm_vis"><pose>0 0 -0.2 0 0 0</pose><geometry><box><size>0.02 0.02 0.4</size></box></geometry></visual>
  </link>
  <link name="slider"><pose>0.15 0.1 0.6 -0.4 0.1 1.2</pose>
    <inertial><mass>0.3</mass><inertia><ixx>0.001</ixx><iyy>0.001</iyy><izz>0.001</izz></inertia></inertial>
  </link>
  <link name="tip"><pose>0.2 0.1 0.5 0 0 0</pose>
    <inertial><pose>0.01 0.02 0.03 0 0 0</pose><mass>0.2</mass><inertia><ixx>0.0001</ixx><iyy>0.0001</iyy><izz>0.0001</izz></inertia></inertial>
  </link>
  <link name="bob"><pose>0.12 0.1 0.45 0.2 0.1 -0.3</pose>
    <inertial><mass>0.4</mass><inertia><ixx>0.002</ixx><iyy>0.003</iyy><izz>0.004</izz></inertia></inertial>
  </link>
  <joint name="hinge" type="revolute"><parent>base</parent><child>arm</child>
    <pose>0 0 0.1 0 0 0</pose><axis><xyz>0.6 0 0.8</xyz><limit><lower>-1</lower><upper>1.5</upper></limit></axis></joint>
  <joint name="slide" type="prismatic"><parent>arm</parent><child>slider</child>
    <pose>0.01 -0.02 0.03 0.1 0.2 0.3</pose><axis><xyz>0 1 0</xyz></axis></joint>
  <joint name="weld" type="fixed"><parent>slider</parent><child>tip</child></joint>
  <joint name="wrist" type="ball"><parent>tip</parent><child>bob</child><pose>0 0 0.02 0 0 0</pose></joint>
</model></sdf>
"""

# the same model written with SDF 1.7 relative_to poses and an explicit frame
PENDULUM_17 = """
<sdf version="1.7"><model name="pendulum">
  <frame name="up" attached_to="base"><pose relative_to="base">0 0 0.1 0 0 0</pose></frame>
  <link name="base"><pose>0 0 1 0 0 0</pose>
    <inertial><mass>2</mass><inertia><ixx>0.1</ixx><iyy>0.2</iyy><izz>0.3</izz></inertia></inertial>
  </link>
  <link name="arm"><pose relative_to="base">{arm_in_base}</pose>
    <inertial><pose>0.05 0 -0.2 0 0.4 0</pose><mass>0.7</mass>
      <inertia><ixx>0.01</ixx><iyy>0.02</iyy><izz>0.015</izz><ixy>0.001</ixy><ixz>-0.002</ixz><iyz>0.0005</iyz></inertia></inertial>
  </link>
  <link name="slider"><pose relative_to="arm">{slider_in_arm}</pose>
    <inertial><mass>0.3</mass><inertia><ixx>0.001</ixx><iyy>0.001</iyy><izz>0.001</izz></inertia></inertial>
  </link>
  <link name="tip"><pose>0.2 0.1 0.5 0 0 0</pose>
    <inertial><pose>0.01 0.02 0.03 0 0 0</pose><mass>0.2</mass><inertia><ixx>0.0001</ixx><iyy>0.0001</iyy><izz>0.0001</izz></inertia></inertial>
  </link>
  <link name="bob"><pose>0.12 0.1 0.45 0.2 0.1 -0.3</pose>
    <inertial><mass>0.4</mass><inertia><ixx>0.002</ixx><iyy>0.003</iyy><izz>0.004</izz></inertia></inertial>
  </link>
  <joint name="hinge" type="revolute"><parent>base</parent><child>arm</child>
    <pose relative_to="up">{hinge_in_up}</pose><axis><xyz expressed_in="__model__">{axis_model}</xyz><limit><lower>-1</lower><upper>1.5</upper></limit></axis></joint>
  <joint name="slide" type="prismatic"><parent>arm</parent><child>slider</child>
    <pose>0.01 -0.02 0.03 0.1 0.2 0.3</pose><axis><xyz>0 1 0</xyz></axis></joint>
  <joint name="weld" type="fixed"><parent>slider</parent><child>tip</child></joint>
  <joint name="wrist" type="ball"><parent>tip</parent><child>bob</child><pose degrees="true">0 0 0.02 0 0 0</pose></joint>
</model></sdf>
"""


def _pose_text(h):
    rpy = pin.rpy.matrixToRpy(h[:3, :3])
    return " ".join(repr(float(x)) for x in list(h[:3, 3]) + list(rpy))


def _pendulum_17_text():
    base = homogeneous(0, 0, 1, 0, 0, 0)
    arm = homogeneous(0.1, 0.2, 0.9, 0.3, -0.2, 0.5)
    slider = homogeneous(0.15, 0.1, 0.6, -0.4, 0.1, 1.2)
    up = base @ homogeneous(0, 0, 0.1, 0, 0, 0)
    hinge = arm @ homogeneous(0, 0, 0.1, 0, 0, 0)          # 1.6: joint pose in the child
    axis_model = arm[:3, :3] @ rpy_matrix(0, 0, 0) @ np.array([0.6, 0, 0.8])
    return PENDULUM_17.format(arm_in_base=_pose_text(np.linalg.inv(base) @ arm),
                              slider_in_arm=_pose_text(np.linalg.inv(arm) @ slider),
                              hinge_in_up=_pose_text(np.linalg.inv(up) @ hinge),
                              axis_model=" ".join(repr(float(a)) for a in axis_model))


def test_link_poses_at_zero_are_the_written_poses():
    tree = build_tree(parse_sdf(PENDULUM_16))
    model = tree.model
    assert model.check(model.createData())
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    written = {"base": (0, 0, 1, 0, 0, 0), "arm": (0.1, 0.2, 0.9, 0.3, -0.2, 0.5),
               "slider": (0.15, 0.1, 0.6, -0.4, 0.1, 1.2), "tip": (0.2, 0.1, 0.5, 0, 0, 0),
               "bob": (0.12, 0.1, 0.45, 0.2, 0.1, -0.3)}
    for link, pose in written.items():
        fid = model.getFrameId(link, pin.FrameType.BODY)
        np.testing.assert_allclose(data.oMf[fid].homogeneous, homogeneous(*pose), atol=1e-14)
    # joint types and depth-first order
    kinds = [model.joints[j].shortname() for j in range(1, model.njoints)]
    assert kinds == ["JointModelRevoluteUnaligned", "JointModelPY", "JointModelSpherical"]
    assert list(model.names)[1:] == ["hinge", "slide", "wrist"]
    assert tree.cut_joints == ()
    assert model.lowerPositionLimit[0] == -1 and model.upperPositionLimit[0] == 1.5


def test_joint_motion_is_a_rotation_about_the_written_axis():
    """Rotating 'hinge' by t turns the arm about the SDF axis through the joint origin."""
    model = build_tree(parse_sdf(PENDULUM_16)).model
    data = model.createData()
    arm0 = homogeneous(0.1, 0.2, 0.9, 0.3, -0.2, 0.5)
    joint_world = arm0 @ homogeneous(0, 0, 0.1, 0, 0, 0)     # joint pose is in the child frame
    axis_world = arm0[:3, :3] @ (np.array([0.6, 0, 0.8]))
    for t in (0.3, -0.7, 1.2):
        q = pin.neutral(model)
        q[0] = t
        pin.framesForwardKinematics(model, data, q)
        rot = rodrigues(axis_world, t)
        expected = np.eye(4)
        expected[:3, :3] = rot @ arm0[:3, :3]
        c = joint_world[:3, 3]
        expected[:3, 3] = c + rot @ (arm0[:3, 3] - c)
        got = data.oMf[model.getFrameId("arm", pin.FrameType.BODY)].homogeneous
        np.testing.assert_allclose(got, expected, atol=1e-13)
    # the prismatic joint slides the slider along its joint frame's y axis
    q = pin.neutral(model)
    q[1] = 0.05
    pin.framesForwardKinematics(model, data, q)
    slider0 = homogeneous(0.15, 0.1, 0.6, -0.4, 0.1, 1.2)
    joint_rot = slider0[:3, :3] @ rpy_matrix(0.1, 0.2, 0.3)
    got = data.oMf[model.getFrameId("slider", pin.FrameType.BODY)].translation
    np.testing.assert_allclose(got, slider0[:3, 3] + 0.05 * joint_rot[:, 1], atol=1e-14)


def test_mass_and_centre_of_mass_match_the_written_inertials():
    model = build_tree(parse_sdf(PENDULUM_16)).model
    masses = {"base": 2, "arm": 0.7, "slider": 0.3, "tip": 0.2, "bob": 0.4}
    links = {"base": (0, 0, 1, 0, 0, 0), "arm": (0.1, 0.2, 0.9, 0.3, -0.2, 0.5),
             "slider": (0.15, 0.1, 0.6, -0.4, 0.1, 1.2), "tip": (0.2, 0.1, 0.5, 0, 0, 0),
             "bob": (0.12, 0.1, 0.45, 0.2, 0.1, -0.3)}
    com_local = {"arm": (0.05, 0, -0.2), "tip": (0.01, 0.02, 0.03)}
    total = sum(masses.values())
    com = sum(m * (homogeneous(*links[k]) @ np.r_[com_local.get(k, (0, 0, 0)), 1])[:3]
              for k, m in masses.items()) / total
    data = model.createData()
    # the fixed base's mass sits on the universe joint and is not counted by computeTotalMass
    moving = pin.computeTotalMass(model, data)
    assert moving == pytest.approx(total - 2)
    pin.centerOfMass(model, data, pin.neutral(model))
    moving_com = (total * com - 2 * np.array([0, 0, 1])) / (total - 2)
    np.testing.assert_allclose(data.com[0], moving_com, atol=1e-14)
    # rotational inertia of the arm about the hinge axis, from the written tensor
    arm = homogeneous(*links["arm"])
    rot_in = arm[:3, :3] @ rpy_matrix(0, 0.4, 0)
    inertia = np.array([[0.01, 0.001, -0.002], [0.001, 0.02, 0.0005], [-0.002, 0.0005, 0.015]])
    c_arm = (arm @ np.r_[0.05, 0, -0.2, 1])[:3]
    axis = arm[:3, :3] @ np.array([0.6, 0, 0.8])
    hinge_point = (arm @ np.r_[0, 0, 0.1, 1])[:3]
    # everything below the hinge rotates rigidly about it when only q[0] moves (ball at zero
    # velocity): M[0, 0] = sum of inertias about the axis of arm, slider, tip, bob
    expected = axis @ rot_in @ inertia @ rot_in.T @ axis
    d = c_arm - hinge_point
    expected += 0.7 * (d @ d - (d @ axis) ** 2)
    for name, mass, inertia_diag, local in (("slider", 0.3, (0.001,) * 3, (0, 0, 0)),
                                            ("tip", 0.2, (0.0001,) * 3, (0.01, 0.02, 0.03)),
                                            ("bob", 0.4, (0.002, 0.003, 0.004), (0, 0, 0))):
        h = homogeneous(*links[name])
        rot = h[:3, :3]
        expected += axis @ rot @ np.diag(inertia_diag) @ rot.T @ axis
        d = (h @ np.r_[local, 1])[:3] - hinge_point
        expected += mass * (d @ d - (d @ axis) ** 2)
    mass_matrix = pin.crba(model, data, pin.neutral(model))
    assert mass_matrix[0, 0] == pytest.approx(expected, rel=1e-12)


def test_relative_to_poses_give_the_same_model():
    m16 = build_tree(parse_sdf(PENDULUM_16)).model
    m17 = build_tree(parse_sdf(_pendulum_17_text())).model
    assert m17.existFrame("up")
    data = m17.createData()
    pin.framesForwardKinematics(m17, data, pin.neutral(m17))
    np.testing.assert_allclose(data.oMf[m17.getFrameId("up")].homogeneous,
                               homogeneous(0, 0, 1.1, 0, 0, 0), atol=1e-15)
    assert m17.frames[m17.getFrameId("up")].type == pin.FrameType.OP_FRAME
    d16, d17 = m16.createData(), m17.createData()
    rng = np.random.default_rng(3)
    for _ in range(3):
        q = random_configuration(m16, rng)
        pin.framesForwardKinematics(m16, d16, q)
        pin.framesForwardKinematics(m17, d17, q)
        for link in ("arm", "slider", "tip", "bob"):
            np.testing.assert_allclose(
                d17.oMf[m17.getFrameId(link, pin.FrameType.BODY)].homogeneous,
                d16.oMf[m16.getFrameId(link, pin.FrameType.BODY)].homogeneous, atol=1e-12)
        np.testing.assert_allclose(pin.crba(m17, d17, q), pin.crba(m16, d16, q), atol=1e-12)
        v = rng.normal(size=m16.nv)
        np.testing.assert_allclose(pin.rnea(m17, d17, q, v, v), pin.rnea(m16, d16, q, v, v),
                                   atol=1e-12)


FOUR_BAR = """
<sdf version="1.6"><model name="four_bar">
  <link name="ground"><pose>0 0 0 0 0 0</pose></link>
  <link name="crank"><pose>0 0 0 0 0 0</pose>
    <inertial><pose>0.05 0 0 0 0 0</pose><mass>0.2</mass><inertia><ixx>1e-5</ixx><iyy>2e-4</iyy><izz>2e-4</izz></inertia></inertial></link>
  <link name="coupler"><pose>0.1 0 0 0 0 0</pose>
    <inertial><pose>0.15 0 0 0 0 0</pose><mass>0.3</mass><inertia><ixx>1e-5</ixx><iyy>6e-4</iyy><izz>6e-4</izz></inertia></inertial></link>
  <link name="rocker"><pose>0.4 0 0 0 0 0</pose>
    <inertial><pose>0 0 0.1 0 0 0</pose><mass>0.25</mass><inertia><ixx>3e-4</ixx><iyy>3e-4</iyy><izz>1e-5</izz></inertia></inertial></link>
  <joint name="crank_joint" type="revolute"><parent>ground</parent><child>crank</child><axis><xyz>0 1 0</xyz></axis></joint>
  <joint name="coupler_joint" type="revolute"><parent>crank</parent><child>coupler</child><axis><xyz>0 1 0</xyz></axis></joint>
  <joint name="rocker_joint" type="revolute"><parent>ground</parent><child>rocker</child><axis><xyz>0 1 0</xyz></axis></joint>
  <joint name="closing" type="ball"><parent>coupler</parent><child>rocker</child><pose>0 0 0 0 0 0</pose></joint>
</model></sdf>
"""



def test_ball_joint_closing_a_loop_becomes_a_point_closure():
    sdf = parse_sdf(FOUR_BAR)
    tree = build_tree(sdf, actuated=["crank_joint"])
    assert tree.cut_joints == ("closing",)
    (closure,) = tree.loops.closures
    assert (closure.type, closure.frame1, closure.frame2) == ("point", "rocker", "coupler")
    clm = closed_loop_from_sdf(sdf, actuated=["crank_joint"])
    assert clm.nv == 3 and clm.n_rows == 3
    # the loop is planar (all axes along y): one of the 3 rows is redundant
    assert clm.rank(np.array([0.3, -0.2, 0.5])).rank == 2
    # the ball sits on the rocker's pivot here: the loop only closes with the crank and
    # coupler aligned (q = 0), a singular configuration; the Jacobian still matches FD
    q = pin.neutral(clm.model)
    assert np.max(np.abs(clm.residual(q))) <= 1e-15
    q = np.array([0.3, -0.2, 0.5])
    np.testing.assert_allclose(clm.constraint_jacobian(q), fd_constraint_jacobian(clm, q), atol=1e-8)


def test_four_bar_assembly_matches_circle_intersection():
    """A four-bar whose ball joint is off the rocker pivot (a real loop)."""
    text = FOUR_BAR.replace('<joint name="rocker_joint" type="revolute"><parent>ground</parent>'
                        '<child>rocker</child>',
                        '<joint name="rocker_joint" type="revolute"><parent>ground</parent>'
                        '<child>rocker</child><pose>0 0 -0.25 0 0 0</pose>')
    # rocker frame at (0.4, 0, 0), its revolute at (0.4, 0, -0.25): the ball (rocker origin)
    # moves on a circle of radius 0.25 about (0.4, 0, -0.25); the coupler is 0.3 long.
    clm = closed_loop_from_sdf(parse_sdf(text), actuated=["crank_joint"])
    q0 = pin.neutral(clm.model)
    for crank in (0.2, -0.3, 0.6):
        q0[clm.joint_q_index("crank_joint")] = crank
        q = clm.assemble(q0).q
        assert np.max(np.abs(clm.residual(q))) <= 1e-10
        a = 0.1 * np.array([math.cos(crank), -math.sin(crank)])      # crank end (x, z)
        pivot = np.array([0.4, -0.25])
        d = np.linalg.norm(pivot - a)
        # ball point: on both circles |p - a| = 0.3, |p - pivot| = 0.25
        data = clm.model.createData()
        pin.framesForwardKinematics(clm.model, data, q)
        p = data.oMf[clm.model.getFrameId("rocker", pin.FrameType.BODY)].translation
        assert abs(p[1]) < 1e-12
        assert np.linalg.norm(p[[0, 2]] - a) == pytest.approx(0.3, abs=1e-10)
        assert np.linalg.norm(p[[0, 2]] - pivot) == pytest.approx(0.25, abs=1e-10)
        assert d < 0.55
        q0 = q.copy()
    np.testing.assert_allclose(clm.constraint_jacobian(q), fd_constraint_jacobian(clm, q), atol=1e-8)


def test_sdf_to_urdf_builds_the_same_mechanism_through_pinocchios_urdf_parser():
    sdf = parse_sdf(FOUR_BAR.replace("<pose>0 0 0 0 0 0</pose></joint>",
                                     "<pose>0.01 0 0.02 0 0 0</pose></joint>"))
    urdf, loops = sdf_to_urdf(sdf)
    direct = closed_loop_from_sdf(sdf)
    via_urdf = ClosedLoopModel(pin.buildModelFromXML(urdf), parse_loops(loops_yaml(loops)))
    assert list(direct.model.names) == list(via_urdf.model.names)
    rng = np.random.default_rng(0)
    for _ in range(3):
        q = rng.uniform(-1, 1, direct.nq)
        np.testing.assert_allclose(via_urdf.residual(q), direct.residual(q), atol=1e-12)
        dd, du = direct.model.createData(), via_urdf.model.createData()
        np.testing.assert_allclose(pin.crba(via_urdf.model, du, q), pin.crba(direct.model, dd, q),
                                   atol=1e-12)
        v = rng.normal(size=direct.nv)
        np.testing.assert_allclose(pin.rnea(via_urdf.model, du, q, v, v),
                                   pin.rnea(direct.model, dd, q, v, v), atol=1e-12)


def test_universal_continuous_and_world_joints():
    text = """
    <sdf version="1.7"><model name="misc"><pose>1 0 0 0 0 0.5</pose>
      <link name="a"><pose>0 0 0.5 0 0 0</pose></link>
      <link name="b"><pose>0 0 0.3 0 0 0</pose></link>
      <link name="c"><pose>0 0 0.1 0 0 0</pose></link>
      <joint name="to_world" type="prismatic"><parent>world</parent><child>a</child>
        <axis><xyz>0 0 1</xyz></axis></joint>
      <joint name="u" type="universal"><parent>a</parent><child>b</child>
        <axis><xyz>1 0 0</xyz></axis><axis2><xyz>0 1 0</xyz></axis2></joint>
      <joint name="wheel" type="continuous"><parent>b</parent><child>c</child>
        <axis><xyz>0 0 -1</xyz></axis></joint>
    </model></sdf>"""
    model = build_tree(parse_sdf(textwrap.dedent(text))).model
    kinds = [model.joints[j].shortname() for j in range(1, model.njoints)]
    assert kinds == ["JointModelPZ", "JointModelUniversal", "JointModelRUBZ"]
    assert (model.nq, model.nv) == (5, 4)
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    # the model pose (x += 1, yaw 0.5) applies to every link
    expected = homogeneous(1, 0, 0, 0, 0, 0.5) @ homogeneous(0, 0, 0.1, 0, 0, 0)
    np.testing.assert_allclose(data.oMf[model.getFrameId("c", pin.FrameType.BODY)].homogeneous,
                               expected, atol=1e-14)
    # the continuous joint turns c about -z by its angle (cos, sin in q)
    q = pin.neutral(model)
    q[3:5] = (math.cos(0.7), math.sin(0.7))
    pin.framesForwardKinematics(model, data, q)
    expected[:3, :3] = rpy_matrix(0, 0, 0.5) @ rodrigues([0, 0, -1], 0.7)
    np.testing.assert_allclose(data.oMf[model.getFrameId("c", pin.FrameType.BODY)].homogeneous,
                               expected, atol=1e-14)
    # the universal joint: first angle about x of a, then about the turned y
    q = pin.neutral(model)
    q[1:3] = (0.3, -0.4)
    pin.framesForwardKinematics(model, data, q)
    rot = rpy_matrix(0, 0, 0.5) @ rodrigues([1, 0, 0], 0.3) @ rodrigues([0, 1, 0], -0.4)
    np.testing.assert_allclose(data.oMf[model.getFrameId("b", pin.FrameType.BODY)].rotation,
                               rot, atol=1e-14)


BAD_SDF = {
    "xml": ("<sdf version='1.6'><model name='m'><link name='a'></model></sdf>", None),
    "two_links_same_name": (("<sdf version='1.6'><model name='m'><link name='a'/><link name='a'/>"
                            "</model></sdf>"), "a"),
    "unknown_parent": (("<sdf version='1.6'><model name='m'><link name='a'/><joint name='j' "
                       "type='revolute'><parent>nowhere</parent><child>a</child></joint>"
                       "</model></sdf>"), "j"),
    "bad_pose": (("<sdf version='1.6'><model name='m'><link name='a'><pose>0 0 1 0 0</pose>"
                 "</link></model></sdf>"), "a"),
    "bad_mass": (("<sdf version='1.6'><model name='m'><link name='a'><inertial><mass>heavy</mass>"
                 "</inertial></link></model></sdf>"), "a"),
    "negative_mass": (("<sdf version='1.6'><model name='m'><link name='a'><inertial><mass>-1"
                      "</mass></inertial></link></model></sdf>"), "a"),
    "cycle": (("<sdf version='1.7'><model name='m'><frame name='f'><pose relative_to='g'/>"
              "</frame><frame name='g'><pose relative_to='f'/></frame><link name='a'>"
              "<pose relative_to='f'/></link></model></sdf>"), "f"),
    "missing_frame": (("<sdf version='1.7'><model name='m'><link name='a'><pose relative_to='x'>"
                      "0 0 0 0 0 0</pose></link></model></sdf>"), "a"),
    "gearbox": (("<sdf version='1.6'><model name='m'><link name='a'/><link name='b'/><joint "
                "name='g' type='gearbox'><parent>a</parent><child>b</child></joint></model>"
                "</sdf>"), "g"),
    "far_pose": (("<sdf version='1.6'><model name='m'><link name='a'><pose>1e300 0 1 0 0 0"
                 "</pose></link></model></sdf>"), "a"),
    "inf_pose": (("<sdf version='1.6'><model name='m'><link name='a'><pose>0 0 1 0 inf 0"
                 "</pose></link></model></sdf>"), "a"),
    "no_model": ("<sdf version='1.6'></sdf>", "model"),
    "not_sdf": ("<robot name='r'/>", "robot"),
}


@pytest.mark.parametrize("case", sorted(BAD_SDF))
def test_malformed_sdf_raises_naming_the_culprit(case):
    text, culprit = BAD_SDF[case]
    with pytest.raises(DescriptionError) as info:
        parse_sdf(text, source=case)
    assert info.value.culprit == culprit
    assert info.value.source == case


def test_bad_trees_raise_naming_the_culprit():
    # a loop closed at a revolute joint cannot be a point or weld closure
    text = FOUR_BAR.replace('name="closing" type="ball"', 'name="closing" type="revolute"')
    with pytest.raises(DescriptionError) as info:
        build_tree(parse_sdf(text))
    assert info.value.culprit in ("closing", "rocker_joint", "coupler_joint")
    # two roots
    text = ("<sdf version='1.6'><model name='m'><link name='a'/><link name='b'/></model></sdf>")
    with pytest.raises(DescriptionError) as info:
        build_tree(parse_sdf(text))
    assert info.value.culprit == "b"
    # a cut that is not a joint
    with pytest.raises(DescriptionError) as info:
        build_tree(parse_sdf(FOUR_BAR), cut=["no_such_joint"])
    assert info.value.culprit == "no_such_joint"
    # an actuated joint not in the tree
    with pytest.raises(DescriptionError) as info:
        closed_loop_from_sdf(parse_sdf(FOUR_BAR), actuated=["closing"])
    assert info.value.culprit == "closing"


def test_cut_by_hand_picks_the_closure():
    """Cutting the rocker's pivot instead is refused (a revolute); cutting the ball is the
    default, and naming it explicitly gives the same tree."""
    auto = build_tree(parse_sdf(FOUR_BAR))
    manual = build_tree(parse_sdf(FOUR_BAR), cut=["closing"])
    assert auto.cut_joints == manual.cut_joints == ("closing",)
    with pytest.raises(DescriptionError) as info:
        build_tree(parse_sdf(FOUR_BAR), cut=["rocker_joint"])
    assert info.value.culprit in ("rocker_joint", "closing")

"""The Gough-Stewart platform and the four-bar of tests/data load, assemble and match closed forms.

The closed forms and constants are those of tests/data/stewart/README.md and
tests/data/four_bar/README.md, written out here independently of the URDFs.
"""

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import hexapod_pin as hp

DATA = Path(__file__).resolve().parents[1] / "data"

# -- Stewart platform (6-UPS) constants, tests/data/stewart/README.md -----------------------
BASE_RADIUS, PLATFORM_RADIUS, HOME_Z = 0.5, 0.3, 0.6
BASE_ANGLES = np.deg2rad([-15.0, 15.0, 105.0, 135.0, 225.0, 255.0])
PLATFORM_ANGLES = np.deg2rad([-45.0, 45.0, 75.0, 165.0, 195.0, 285.0])
A_BASE = BASE_RADIUS * np.column_stack([np.cos(BASE_ANGLES), np.sin(BASE_ANGLES),
                                        np.zeros(6)])           # a_i, world axes (m)
B_PLATFORM = PLATFORM_RADIUS * np.column_stack([np.cos(PLATFORM_ANGLES),
                                                np.sin(PLATFORM_ANGLES), np.zeros(6)])  # b_i
LEG_OFFSET = 0.65          # leg length = LEG_OFFSET + q(leg_i_prismatic)
HOME_LEG = np.sqrt(0.7 - 0.15 * np.sqrt(3.0))

# -- four-bar constants, tests/data/four_bar/README.md ---------------------------------------
GROUND, CRANK, COUPLER, ROCKER, TRACE_OFFSET = 0.4, 0.1, 0.35, 0.3, 0.1


def leg_lengths(p, rot):
    """Closed-form inverse kinematics: ||p + R b_i - a_i||."""
    return np.linalg.norm(p + B_PLATFORM @ rot.T - A_BASE, axis=1)


def link_dir(theta):
    """Direction of a link at absolute angle theta about +y (x-z plane)."""
    return np.array([np.cos(theta), 0.0, -np.sin(theta)])


def four_bar_closed_form(theta):
    """Crank end, coupler-rocker pin (upper branch) and tracing point for crank angle theta."""
    a = CRANK * link_dir(theta)
    o4 = np.array([GROUND, 0.0, 0.0])
    d = o4 - a
    dist = np.linalg.norm(d)
    along = (COUPLER**2 - ROCKER**2 + dist**2) / (2.0 * dist)
    height = np.sqrt(COUPLER**2 - along**2)
    normal = np.array([-d[2], 0.0, d[0]]) / dist          # d turned +90 deg toward +z
    pin_point = a + along * d / dist + height * normal
    u = (pin_point - a) / COUPLER
    trace = 0.5 * (a + pin_point) + TRACE_OFFSET * np.array([-u[2], 0.0, u[0]])
    return a, pin_point, trace


def frame_position(model, q, frame):
    pin.forwardKinematics(model.model, model.data, q)
    pin.updateFramePlacements(model.model, model.data)
    return model.data.oMf[model.model.getFrameId(frame)].translation.copy()


@pytest.fixture(scope="module")
def stewart():
    return hp.ClosedLoopModel.from_files(DATA / "stewart" / "stewart.urdf",
                                         DATA / "stewart" / "stewart.loops.yaml")


@pytest.fixture(scope="module")
def four_bar():
    return hp.ClosedLoopModel.from_files(DATA / "four_bar" / "four_bar.urdf",
                                         DATA / "four_bar" / "four_bar.loops.yaml")


def stewart_guess(model, p, rot):
    """Platform at (p, R), every leg joint at zero: the assembly closes the legs."""
    q = model.neutral()
    iq = model.joint_q_index("platform_joint")
    q[iq:iq + 7] = np.concatenate([p, pin.Quaternion(rot).coeffs()])   # x y z, qx qy qz qw
    return q


def platform_fixed(model):
    iv = model.joint_v_index("platform_joint")
    return iv + np.arange(6)


def prismatic(model, q):
    return np.array([q[model.joint_q_index(f"leg_{i}_prismatic")] for i in range(6)])


def test_stewart_sizes(stewart):
    assert (stewart.nq, stewart.nv, stewart.n_rows) == (25, 24, 18)
    assert stewart.actuated_joints == tuple(f"leg_{i}_prismatic" for i in range(6))
    for i in range(6):
        for frame in (f"leg_{i}_tip", f"platform_anchor_{i}"):
            assert stewart.model.existFrame(frame)
    assert stewart.model.existFrame("platform")


def test_stewart_home(stewart):
    res = stewart.assemble(stewart_guess(stewart, np.array([0.0, 0.0, HOME_Z]), np.eye(3)),
                           fixed=platform_fixed(stewart))
    q = res.q
    assert np.abs(stewart.residual(q)).max() < 1e-12
    assert stewart.rank(q).rank == 18
    assert stewart.mobility(q) == 6
    gmap = stewart.actuated_velocity_map(q)
    assert gmap.shape == (24, 6)
    assert np.linalg.svd(gmap, compute_uv=False)[-1] > 0.1
    # the platform is where it was put, every leg at the closed-form length
    iq = stewart.joint_q_index("platform_joint")
    np.testing.assert_allclose(q[iq:iq + 7], [0, 0, HOME_Z, 0, 0, 0, 1], atol=0)
    np.testing.assert_allclose(prismatic(stewart, q) + LEG_OFFSET, HOME_LEG, atol=1e-12)
    np.testing.assert_allclose(leg_lengths(np.array([0, 0, HOME_Z]), np.eye(3)), HOME_LEG,
                               atol=1e-15)
    np.testing.assert_allclose(frame_position(stewart, q, "platform"), [0, 0, HOME_Z], atol=0)


def test_stewart_random_poses(stewart):
    rng = np.random.default_rng(20261202)
    for _ in range(5):
        p = np.array([0.0, 0.0, HOME_Z]) + rng.uniform(-0.04, 0.04, 3)
        rot = pin.rpy.rpyToMatrix(*rng.uniform(-0.12, 0.12, 3))
        res = stewart.assemble(stewart_guess(stewart, p, rot), fixed=platform_fixed(stewart))
        q = res.q
        assert np.abs(stewart.residual(q)).max() < 1e-12
        assert stewart.mobility(q) == 6
        np.testing.assert_allclose(prismatic(stewart, q) + LEG_OFFSET, leg_lengths(p, rot),
                                   rtol=0, atol=1e-12)
        for i in range(6):   # the anchors are at p + R b_i
            np.testing.assert_allclose(frame_position(stewart, q, f"platform_anchor_{i}"),
                                       p + rot @ B_PLATFORM[i], atol=1e-14)


def test_four_bar(four_bar):
    assert (four_bar.nq, four_bar.nv, four_bar.n_rows) == (3, 3, 3)
    assert four_bar.actuated_joints == ("crank",)
    assert four_bar.model.existFrame("coupler_point")
    q = four_bar.assemble(np.array([0.0, -1.0, -1.9])).q          # a rough guess of home
    assert np.abs(four_bar.residual(q)).max() < 1e-12
    info = four_bar.rank(q)
    assert info.rank == 2 and list(info.redundant_rows) == [1]      # the y row is zero
    assert four_bar.mobility(q) == 1
    np.testing.assert_allclose(q, [0.0, -0.9479697413828936, -1.8959394827657874], atol=1e-11)
    # a full crank turn by continuation (Grashof crank-rocker), checked at 5 crank angles
    checks = {10: None, 22: None, 35: None, 47: None, 60: None}
    for k in range(1, 64):
        theta = k * 0.1
        guess = q.copy()
        guess[four_bar.joint_q_index("crank")] = theta
        q = four_bar.assemble(guess).q
        if k not in checks:
            continue
        assert np.abs(four_bar.residual(q)).max() < 1e-12
        assert four_bar.mobility(q) == 1
        a, pin_point, trace = four_bar_closed_form(theta)
        np.testing.assert_allclose(frame_position(four_bar, q, "coupler_end"), pin_point,
                                   atol=1e-12)
        np.testing.assert_allclose(frame_position(four_bar, q, "rocker_end"), pin_point,
                                   atol=1e-12)
        np.testing.assert_allclose(frame_position(four_bar, q, "coupler_point"), trace,
                                   atol=1e-12)

"""``hp.ClosedLoopRobot`` / ``hp.load_robot`` against references written here.

* inverse kinematics against closed forms: the Stewart platform's leg lengths
  ``|p + R b_i - a_i|``, the five-bar's two circle intersections;
* inverse and forward dynamics against a numpy null-space / least-squares solve on raw
  Pinocchio (``crba``, ``nonLinearEffects``, frame Jacobians and accelerations of the
  closure anchors), mapped to the platform here;
* singularity measures against ``scipy.linalg.null_space`` of the scaled closure rows;
* a walk toward a type-I singularity: the routes answer to 1e-6 or refuse;
* bad inputs: typed library errors naming the value.

(The shared suite, ``tests/test_shared_api.py``, runs the whole protocol over the same
robots.)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st

import hexapod_pin as hp
from hexapod_pin.core.pose import rotation_from_rpy
from hexapod_pin.errors import (DescriptionError, InputError, SingularityError,
                                UnreachablePoseError)

DATA = Path(__file__).resolve().parents[1] / "data"
LWA, LOCAL = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED, pin.ReferenceFrame.LOCAL

# the Stewart platform's constants (tests/data/stewart/README.md)
ALPHA = np.deg2rad([-15, 15, 105, 135, 225, 255])
BETA = np.deg2rad([-45, 45, 75, 165, 195, 285])
BASE = 0.5 * np.c_[np.cos(ALPHA), np.sin(ALPHA), np.zeros(6)]
PLATFORM = 0.3 * np.c_[np.cos(BETA), np.sin(BETA), np.zeros(6)]
LEG_OFFSET = 0.65
# the five-bar (tests/data/parallel/five_bar_3d): motors at x = -0.1, 0.1, links 0.25, 0.3
MOTORS = np.array([[-0.1, 0.0], [0.1, 0.0]])
L1, L2 = 0.25, 0.3


@pytest.fixture(scope="module")
def stewart():
    return hp.load_robot(DATA / "stewart" / "stewart.urdf")


@pytest.fixture(scope="module")
def five_bar():
    return hp.load_robot(DATA / "parallel" / "five_bar_3d", platform="end_1",
                         pose_axes=("x", "z"))


@pytest.fixture(scope="module")
def delta():
    return hp.load_robot(DATA / "parallel" / "delta", platform="platform_center",
                         pose_axes="x,y,z")


@pytest.fixture(scope="module")
def robots(stewart, five_bar, delta):
    return {"stewart": stewart, "five-bar": five_bar, "delta": delta}


def near_home(robot, rng, scale=0.03):
    """A random pose near home (scale times the robot's size; 0.05 rad)."""
    ang = robot.platform.sel >= 3
    size = robot.geometry.characteristic_length
    return robot.home_pose + rng.uniform(-1, 1, robot.pose_dim) * np.where(ang, 0.05,
                                                                             scale * size)


# -- inverse kinematics against closed forms ------------------------------------------------
def test_stewart_inverse_kinematics_is_the_leg_length(stewart):
    rng = np.random.default_rng(1)
    for _ in range(8):
        pose = stewart.home_pose + rng.uniform(-1, 1, 6) * [0.05, 0.05, 0.05, 0.1, 0.1, 0.1]
        legs = np.linalg.norm(pose[:3] + PLATFORM @ rotation_from_rpy(pose[3:]).T - BASE,
                              axis=1)
        np.testing.assert_allclose(stewart.inverse_kinematics(pose), legs - LEG_OFFSET,
                                   rtol=0, atol=1e-12)


def five_bar_roots(tip):
    """Both motor angles of each arm that put its distal end at ``tip`` (x, z): the two
    intersections of the circles |e - m| = L1 and |e - tip| = L2 (rotation about +y by
    theta turns the x axis to (cos theta, 0, -sin theta))."""
    out = []
    for m in MOTORS:
        d = np.linalg.norm(tip - m)
        along = (d ** 2 + L1 ** 2 - L2 ** 2) / (2 * d)
        h = np.sqrt(L1 ** 2 - along ** 2)
        u = (tip - m) / d
        normal = np.array([-u[1], u[0]])
        elbows = [m + along * u + s * h * normal for s in (1.0, -1.0)]
        out.append([np.arctan2(-(e[1] - m[1]), e[0] - m[0]) for e in elbows])
    return np.array(out)          # (arm, root)


def test_five_bar_inverse_kinematics_is_a_circle_intersection(five_bar):
    rng = np.random.default_rng(2)
    for _ in range(8):
        pose = near_home(five_bar, rng)
        act = five_bar.inverse_kinematics(pose)
        roots = five_bar_roots(pose)
        for arm in range(2):
            gap = np.abs(np.angle(np.exp(1j * (roots[arm] - act[arm]))))
            assert gap.min() < 1e-10, (arm, roots[arm], act[arm])
            assert gap.max() > 1e-3            # the other root is another working mode


# -- dynamics against numpy on raw Pinocchio -------------------------------------------------
def raw_terms(robot, q):
    """J_c, the platform's selected twist rows P (raw frame Jacobians), M and the tree."""
    clm = robot.model
    model, data = clm.model, clm.model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    rows = []
    for frames in clm.closure_frames:
        if frames.is_point:
            rows.append(pin.getFrameJacobian(model, data, frames.frame1, LWA)[:3]
                        - pin.getFrameJacobian(model, data, frames.frame2, LWA)[:3])
        else:           # a weld at an assembled state (relative placement identity)
            rows.append(pin.getFrameJacobian(model, data, frames.frame1, LOCAL)
                        - pin.getFrameJacobian(model, data, frames.frame2, LOCAL))
    jac_c = np.vstack(rows)
    fid = robot.platform.frame
    p_rows = pin.getFrameJacobian(model, data, fid, LWA)[robot.platform.sel]
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    return jac_c, p_rows, mass


def raw_bias(robot, q, v):
    """The closures' drift gamma and the platform's selected acceleration bias at a = 0."""
    clm = robot.model
    model, data = clm.model, clm.model.createData()
    pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
    pin.updateFramePlacements(model, data)
    gamma = []
    for frames in clm.closure_frames:
        if frames.is_point:
            gamma.append(pin.getFrameClassicalAcceleration(model, data, frames.frame1, LWA).linear
                         - pin.getFrameClassicalAcceleration(model, data, frames.frame2,
                                                             LWA).linear)
        else:           # relative velocity zero: the cross term vanishes
            gamma.append(pin.getFrameAcceleration(model, data, frames.frame1, LOCAL).vector
                         - pin.getFrameAcceleration(model, data, frames.frame2, LOCAL).vector)
    bias = pin.getFrameClassicalAcceleration(model, data, robot.platform.frame,
                                             LWA).vector[robot.platform.sel]
    nle = pin.nonLinearEffects(model, data, q, v)
    return np.concatenate(gamma), bias, nle


@pytest.mark.parametrize("name", ["stewart", "five-bar", "delta"])
def test_dynamics_against_a_numpy_reference_on_raw_pinocchio(robots, name):
    robot = robots[name]
    rng = np.random.default_rng(3)
    dim, act = robot.pose_dim, robot.model.actuated_v
    for _ in range(3):
        pose = near_home(robot, rng)
        twist, twist_dot, wrench = (rng.uniform(-1, 1, dim) * s for s in (0.1, 0.5, 1.0))
        q = robot.configuration(pose)
        jac_c, p_rows, mass = raw_terms(robot, q)
        stacked = np.vstack([jac_c, p_rows])
        v = np.linalg.lstsq(stacked, np.r_[np.zeros(len(jac_c)), twist], rcond=None)[0]
        gamma, bias, nle = raw_bias(robot, q, v)
        a = np.linalg.lstsq(stacked, np.r_[-gamma, twist_dot - bias], rcond=None)[0]
        tau_ext = p_rows.T @ wrench
        # inverse dynamics: M a + h - tau_ext = S^T u + J_c^T lambda, least squares
        sel = np.zeros((model_nv := len(v), len(act)))
        sel[act, np.arange(len(act))] = 1.0
        lhs = np.hstack([sel, jac_c.T])
        u_ref = np.linalg.lstsq(lhs, mass @ a + nle - tau_ext, rcond=None)[0][:len(act)]
        res = robot.inverse_dynamics(pose, twist, twist_dot, wrench, bounded=False)
        scale = max(1.0, np.abs(u_ref).max())
        np.testing.assert_allclose(res.actuator_forces, u_ref, rtol=0, atol=1e-10 * scale)
        # forward dynamics: a = a_p + N z with N^T (M a + h - S^T u - tau_ext) = 0
        basis = scipy.linalg.null_space(jac_c, rcond=1e-10)
        a_p = np.linalg.lstsq(jac_c, -gamma, rcond=None)[0]
        z = np.linalg.solve(basis.T @ mass @ basis,
                            basis.T @ (sel @ res.actuator_forces + tau_ext - nle - mass @ a_p))
        a_ref = a_p + basis @ z
        assert model_nv == robot.model.nv
        for method in ("nullspace", "pinocchio", "qp", "kkt"):
            fd = robot.forward_dynamics(pose, twist, res.actuator_forces, wrench, method=method)
            np.testing.assert_allclose(fd.tree_acceleration, a_ref, rtol=0,
                                       atol=1e-9 * max(1.0, np.abs(a_ref).max()))
            np.testing.assert_allclose(fd.twist_dot, p_rows @ a_ref + bias, rtol=0,
                                       atol=1e-9 * max(1.0, np.abs(twist_dot).max()))
            np.testing.assert_allclose(fd.twist_dot, twist_dot, rtol=0,
                                       atol=1e-10 * max(1.0, np.abs(twist_dot).max()))


@pytest.mark.parametrize("name", ["stewart", "five-bar", "delta"])
def test_measures_against_scipy_null_space(robots, name):
    robot = robots[name]
    rng = np.random.default_rng(4)
    pose = near_home(robot, rng)
    q = robot.configuration(pose)
    jac_c, p_rows, _ = raw_terms(robot, q)
    scale = robot.platform.v_scale
    basis = scipy.linalg.null_space(jac_c / scale, rcond=1e-10)
    length = robot.geometry.characteristic_length
    a_hat = np.where(robot.platform.sel >= 3, length, 1.0)[:, None] * (p_rows / scale) @ basis
    b_hat = (basis)[robot.model.actuated_v]
    sv_a = np.linalg.svd(a_hat, compute_uv=False)
    sv_b = np.linalg.svd(b_hat, compute_uv=False)
    meas = robot.singularity(pose)
    assert meas.type_one == pytest.approx(sv_a[-1] / sv_a[0], rel=1e-9)
    assert meas.type_two == pytest.approx(sv_b[-1] / sv_b[0], rel=1e-9)
    jac = robot.jacobian(pose)
    np.testing.assert_allclose(meas.jacobian_singular_values,
                               np.linalg.svd(jac, compute_uv=False), rtol=1e-10)


def walk(robot, states):
    """Run inverse -> forward dynamics along ``states`` (pose, branch); returns the
    (answered, refused, smallest measures answered) counts. Every answer must hold the
    round trip to 1e-6 (relative); a refusal must be a SingularityError or
    UnreachablePoseError."""
    twist, twist_dot = np.array([0.25, -0.15]), np.array([0.2, 0.1])
    answered = refused = 0
    worst = [1.0, 1.0]
    for pose, branch in states:
        try:
            meas = robot.singularity(pose, branch)
            res = robot.inverse_dynamics(pose, twist, twist_dot, bounded=False, branch=branch)
            back = robot.forward_dynamics(pose, twist, res.actuator_forces, branch=branch)
        except (SingularityError, UnreachablePoseError):
            refused += 1
            continue
        answered += 1
        worst = [min(worst[0], meas.type_one), min(worst[1], meas.type_two)]
        err = np.abs(back.twist_dot - twist_dot).max() / np.abs(twist_dot).max()
        assert err < 1e-6, (pose, err, meas.type_one, meas.type_two)
    return answered, refused, worst


def test_walk_toward_a_type_one_singularity(five_bar):
    """The left arm straightens as the tip moves away from its motor: the routes answer
    with a round trip accurate to 1e-6, or refuse, never a wrong answer."""
    home, motor = five_bar.home_pose, MOTORS[0]
    direction = (home - motor) / np.linalg.norm(home - motor)
    states = [(motor + (L1 + L2 - gap) * direction, None)
              for gap in np.geomspace(0.1, 1e-10, 40)]
    answered, refused, worst = walk(five_bar, states)
    assert answered >= 5 and refused >= 5
    assert worst[0] < 3e-3           # it answered down to near the threshold (2e-3)


def test_walk_toward_a_type_two_singularity(five_bar):
    """The elbows move apart (symmetric motor angles pi + b, -b) until the distal links
    align (elbow distance 2 L2): the platform could then move with the motors held."""
    states = []
    for gap in np.geomspace(0.05, 1e-10, 40):
        b = np.arccos(0.8 - 2 * gap)              # elbow distance 0.2 + 0.5 cos b = 0.6 - gap
        q = five_bar.kinematics.assemble(five_bar.home_configuration, np.array([np.pi + b, -b]))
        states.append((five_bar.pose_from_configuration(q), q))
    answered, refused, worst = walk(five_bar, states)
    assert answered >= 5 and refused >= 5
    assert worst[1] < 1e-3           # down to near the threshold (5e-4)


# -- bad inputs ---------------------------------------------------------------------------------
def test_bad_construction_is_a_description_or_input_error(five_bar):
    clm = five_bar.model
    with pytest.raises(DescriptionError, match="not in the tree"):
        hp.ClosedLoopRobot(clm, "no_such_frame", ("x", "z"))
    with pytest.raises(DescriptionError, match="mobility 2"):
        hp.ClosedLoopRobot(clm, "end_1", ("x", "y", "z"))
    for axes in (("z", "x"), ("x", "x"), (), ("x", "w"), 3):
        with pytest.raises(InputError) as err:
            hp.ClosedLoopRobot(clm, "end_1", axes)
        assert err.value.name == "pose_axes"
    with pytest.raises(hp.ArgumentTypeError):
        hp.ClosedLoopRobot("model.urdf", "end_1", ("x", "z"))
    with pytest.raises(InputError, match="max_actuator_force"):
        hp.ClosedLoopRobot(clm, "end_1", ("x", "z"), max_actuator_force=[1.0, -2.0])
    with pytest.raises(DescriptionError, match="no platform frame"):
        hp.load_robot(DATA / "parallel" / "five_bar_3d")
    with pytest.raises(hp.MissingFileError, match="file not found"):
        hp.load_robot(DATA / "nope.urdf", platform="x")


def test_missing_loops_file_is_named(tmp_path):
    urdf = tmp_path / "lonely.urdf"
    urdf.write_text((DATA / "four_bar" / "four_bar.urdf").read_text())
    with pytest.raises(DescriptionError, match="lonely.loops.yaml"):
        hp.load_robot(urdf, platform="coupler_point")


def test_robot_section_errors_name_the_key(tmp_path):
    urdf = tmp_path / "fb.urdf"
    urdf.write_text((DATA / "four_bar" / "four_bar.urdf").read_text())
    base = (DATA / "four_bar" / "four_bar.loops.yaml").read_text().split("\nrobot:")[0] + "\n"
    for bad, key in (("robot: {platform: 3}", "robot.platform"),
                     ("robot: {pose_axes: 7}", "robot.pose_axes"),
                     ("robot: {home: [a, b]}", "robot.home"),
                     ("robot: {colour: red}", "robot.colour")):
        (tmp_path / "fb.loops.yaml").write_text(base + bad + "\n")
        with pytest.raises(DescriptionError) as err:
            hp.load_robot(urdf)
        assert err.value.culprit == key


def test_bad_branch_pose_and_unreachable(five_bar):
    with pytest.raises(InputError) as err:
        five_bar.inverse_kinematics(five_bar.home_pose, branch=[1, -1])
    assert err.value.name == "branch"
    with pytest.raises(InputError) as err:
        five_bar.jacobian([0.1, np.nan])
    assert err.value.name == "pose"
    with pytest.raises(InputError):
        five_bar.inverse_dynamics(five_bar.home_pose, [0.0], [0.0, 0.0])
    with pytest.raises(UnreachablePoseError, match="closes the loops"):
        five_bar.inverse_kinematics([3.0, 0.0])
    with pytest.raises(InputError):
        five_bar.forward_dynamics(five_bar.home_pose, [0, 0], [1, 1], method="euler")


def five_bar_configuration(tip, roots):
    """The tree configuration (mot1, free1, mot2, free2) with the motors at ``roots`` (one
    root per arm) and the distal links reaching ``tip``: each free angle is the distal
    link's absolute angle minus its motor's."""
    q = []
    for m, theta in zip(MOTORS, roots):
        elbow = m + L1 * np.array([np.cos(theta), -np.sin(theta)])
        d = tip - elbow
        q += [theta, np.arctan2(-d[1], d[0]) - theta]
    return np.array(q)


def test_branch_selects_the_working_mode(five_bar):
    """A start configuration in another working mode (the left elbow flipped, built from
    the closed form) gives the other closed-form root, and keeps it at nearby poses."""
    pose = five_bar.home_pose
    home_act = five_bar.inverse_kinematics(pose)
    roots = five_bar_roots(pose)
    gaps = np.abs(np.angle(np.exp(1j * (roots - home_act[:, None]))))
    mine = roots[np.arange(2), np.argmin(gaps, axis=1)]
    other = roots[np.arange(2), np.argmax(gaps, axis=1)]
    seed = five_bar_configuration(pose, [other[0], mine[1]])
    assert np.abs(five_bar.model.residual(seed)).max() < 1e-12
    target = pose + [0.01, 0.0]
    flipped = five_bar.inverse_kinematics(target, branch=seed, check_limits=False)
    roots = five_bar_roots(target)
    gap = np.abs(np.angle(np.exp(1j * (roots - flipped[:, None]))))
    assert gap.min(axis=1).max() < 1e-10
    home_mode = five_bar.inverse_kinematics(target)
    assert abs(np.angle(np.exp(1j * (flipped[0] - home_mode[0])))) > 1e-2
    assert abs(np.angle(np.exp(1j * (flipped[1] - home_mode[1])))) < 1e-10


@settings(max_examples=25, deadline=None)
@given(values=st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                                 st.text(max_size=2), st.booleans(), st.none()),
                       min_size=0, max_size=4))
def test_hypothesis_bad_poses_are_input_errors(five_bar, values):
    ok = (len(values) == 2 and all(isinstance(x, float) and np.isfinite(x) for x in values))
    if ok:
        return
    with pytest.raises(InputError):
        five_bar.inverse_kinematics(values)


# -- the library's two closed-form robots, loaded as trees -------------------------------------
@pytest.mark.parametrize("which", ["hexapod", "planar"])
def test_closed_forms_equal_the_same_tree_loaded(which):
    """The hexapod and the planar 3-PRR, each loaded as a ClosedLoopRobot from its own
    tree (platform frame "platform"), give the numbers of their closed forms: two
    independent routes (closed-form kernels against Newton on the tree, null-space maps
    and the tree dynamics)."""
    if which == "hexapod":
        closed, axes = hp.Hexapod.default(), ("x", "y", "z", "roll", "pitch", "yaw")
        scale = np.array([0.02, 0.02, 0.02, 0.05, 0.05, 0.05])
    else:
        closed, axes = hp.Planar3PRR.default(), ("x", "y", "yaw")
        scale = np.array([0.02, 0.02, 0.1])
    tree = hp.ClosedLoopRobot(closed.model, "platform", axes, home=closed.home_configuration,
                              max_actuator_force=closed.geometry.max_actuator_force)
    rng = np.random.default_rng(5)
    dim = closed.pose_dim
    for _ in range(4):
        pose = closed.home_pose + rng.uniform(-1, 1, dim) * scale
        twist, twist_dot, wrench = (rng.uniform(-1, 1, dim) * s for s in (0.1, 0.5, 1.0))
        np.testing.assert_allclose(tree.inverse_kinematics(pose),
                                   closed.inverse_kinematics(pose), atol=1e-12)
        np.testing.assert_allclose(tree.configuration(pose), closed.configuration(pose),
                                   atol=1e-10)
        jac = closed.jacobian(pose)
        np.testing.assert_allclose(tree.jacobian(pose), jac, atol=1e-10 * np.abs(jac).max())
        jd = closed.jacobian_derivative(pose, twist)
        np.testing.assert_allclose(tree.jacobian_derivative(pose, twist), jd,
                                   atol=1e-9 * max(1.0, np.abs(jd).max()))
        ref = closed.inverse_dynamics(pose, twist, twist_dot, wrench, bounded=False)
        got = tree.inverse_dynamics(pose, twist, twist_dot, wrench, bounded=False)
        size = max(1.0, np.abs(ref.actuator_forces).max())
        np.testing.assert_allclose(got.actuator_forces, ref.actuator_forces, atol=1e-10 * size)
        fd = tree.forward_dynamics(pose, twist, ref.actuator_forces, wrench)
        np.testing.assert_allclose(fd.twist_dot, twist_dot, atol=1e-10)
        m_ref, h_ref = closed.reduced_dynamics(pose, twist)
        m_got, h_got = tree.reduced_dynamics(pose, twist)
        np.testing.assert_allclose(m_got, m_ref, atol=1e-10 * np.abs(m_ref).max())
        np.testing.assert_allclose(h_got, h_ref, atol=1e-10 * max(1.0, np.abs(h_ref).max()))
        e_ref, e_got = closed.energies(pose, twist), tree.energies(pose, twist)
        assert e_got.kinetic == pytest.approx(e_ref.kinetic, rel=1e-10, abs=1e-14)
        assert e_got.potential - e_ref.potential == pytest.approx(
            tree.energies(closed.home_pose, 0 * twist).potential
            - closed.energies(closed.home_pose, 0 * twist).potential, abs=1e-9)
        np.testing.assert_allclose(tree.forward_kinematics(closed.inverse_kinematics(pose),
                                                           guess=pose), pose, atol=1e-10)


def test_stewart_example_runs(capsys):
    """examples/stewart_platform.py runs and its checks hold (leg lengths to 1e-12, FD of ID
    to 1e-9, the time-optimal forces within their bound)."""
    import re
    import runpy

    runpy.run_path(str(DATA.parents[1] / "examples" / "stewart_platform.py"), run_name="__main__")
    out = capsys.readouterr().out
    number = r"([-+0-9.e]+)"
    assert float(re.search(r"closed form miss " + number, out).group(1)) < 1e-12
    assert float(re.search(r"FD\(ID\) miss " + number, out).group(1)) < 1e-9
    assert float(re.search(r"max \|force\| \(N\) " + number, out).group(1)) < 400 * (1 + 1e-9)


def test_singularity_errors_name_their_measure(five_bar):
    """The message says what the number is (issue 32: a |cos| was called a singular
    value): here the inverse condition number, with its threshold."""
    motor = MOTORS[0]
    direction = (five_bar.home_pose - motor) / np.linalg.norm(five_bar.home_pose - motor)
    with pytest.raises(SingularityError) as err:
        five_bar.jacobian(motor + (L1 + L2 - 1e-9) * direction)
    assert err.value.measure == "inverse condition number"
    assert "type-I" in str(err.value) and "inverse condition number" in str(err.value)
    assert err.value.sigma_min < err.value.threshold == 2e-3


# -- review findings (each a reproducer) --------------------------------------------------------
def test_the_cache_never_returns_the_callers_array(five_bar):
    q = five_bar.configuration(five_bar.home_pose + [0.01, 0.0])
    pose = five_bar.pose_from_configuration(q)
    seed, kept = q.copy(), q.copy()
    five_bar.configuration(pose, branch=seed)
    seed[:] = 0.0                                    # the caller reuses its buffer
    again = five_bar.configuration(pose, branch=kept)
    assert np.abs(five_bar.model.residual(again)).max() < 1e-12
    again[:] = 1.0                                   # nor hands out its own entry
    assert np.abs(five_bar.model.residual(five_bar.configuration(pose, branch=kept))
                  ).max() < 1e-12


def test_simulation_of_another_working_mode_records_its_own_twist(five_bar):
    """A state in the other working mode (left elbow flipped): the recorded twist is the
    platform frame's velocity at the simulated (q, v), computed here from Pinocchio."""
    pose = five_bar.home_pose
    home_act = five_bar.inverse_kinematics(pose)
    roots = five_bar_roots(pose)
    gaps = np.abs(np.angle(np.exp(1j * (roots - home_act[:, None]))))
    mine = roots[np.arange(2), np.argmin(gaps, axis=1)]
    other = roots[np.arange(2), np.argmax(gaps, axis=1)]
    q = five_bar_configuration(pose, [other[0], mine[1]])
    jac_c, p_rows, _ = raw_terms(five_bar, q)
    v = scipy.linalg.null_space(jac_c, rcond=1e-10) @ np.array([0.3, -0.2])
    run = hp.simulate(five_bar, 0.002, 1e-3, initial=(q, v))
    model, data = five_bar.model.model, five_bar.model.model.createData()
    for k in range(len(run.times)):
        pin.computeJointJacobians(model, data, run.q[k])
        pin.updateFramePlacements(model, data)
        jac = pin.getFrameJacobian(model, data, five_bar.platform.frame, LWA)
        np.testing.assert_allclose(run.twists[k], (jac @ run.v[k])[five_bar.platform.sel],
                                   atol=1e-9)


def test_platform_error_wraps_angles_and_uses_the_layout():
    from hexapod_pin.core.controllers import platform_error
    from hexapod_pin.core.robot_api import pose_layout

    err = platform_error(np.array([0, 0, np.pi - 0.01]), np.array([0, 0, -np.pi + 0.01]))
    np.testing.assert_allclose(err, [0, 0, -0.02], atol=1e-12)
    err = platform_error(np.array([0.1, 3.1]), np.array([0.0, -3.1]), pose_layout(("x", "pitch")))
    np.testing.assert_allclose(err, [0.1, 6.2 - 2 * np.pi], atol=1e-12)


def test_bad_options_are_library_errors(five_bar, stewart):
    path = DATA / "stewart" / "stewart.urdf"
    for bad in (None, 3):
        with pytest.raises(hp.ArgumentTypeError):
            hp.load_robot(bad)
    with pytest.raises(hp.ArgumentTypeError):
        hp.load_robot(path, colour="red")
    for force in ("abc", [[1, 2], [3]], True, [1.0, True, 1, 1, 1, 1], -1.0, [1.0] * 5):
        with pytest.raises(InputError) as err:
            hp.load_robot(path, max_actuator_force=force)
        assert err.value.name == "max_actuator_force"
    for call in (lambda: five_bar.stroke_violations("ab"),
                 lambda: five_bar.check_stroke([np.nan, 0.0]),
                 lambda: five_bar.check_stroke([0.0]),
                 lambda: five_bar.inverse_kinematics(five_bar.home_pose, check_limits="no"),
                 lambda: five_bar.inverse_dynamics(five_bar.home_pose, [0, 0], [0, 0],
                                                   bounded="no"),
                 lambda: hp.simulate(five_bar, 1e-9, 1e-3),
                 lambda: hp.simulate(five_bar, 0.01, 1e-3,
                                     actuator_forces=lambda t: [True, False])):
        with pytest.raises(InputError):
            call()


@pytest.mark.parametrize("which", ["hexapod", "planar", "stewart", "five-bar", "delta"])
def test_twist_from_configuration_is_the_platform_twist(which, robots):
    """RobotBase.twist_from_configuration (one frame Jacobian) gives back the twist the
    robot's own inverse dynamics mapped to the tree (its closed form for the hexapod and
    the planar robot)."""
    robot = {"hexapod": hp.Hexapod.default, "planar": hp.Planar3PRR.default}.get(
        which, lambda: robots[which])()
    rng = np.random.default_rng(8)
    dim = robot.pose_dim
    pose = robot.home_pose + rng.uniform(-1, 1, dim) * 0.01
    twist = rng.uniform(-1, 1, dim) * 0.1
    res = robot.inverse_dynamics(pose, twist, np.zeros(dim), bounded=False)
    np.testing.assert_allclose(robot.twist_from_configuration(res.configuration, res.velocity),
                               twist, atol=1e-12)
    assert isinstance(robot, hp.core.robot_base.RobotBase)


def test_twist_from_configuration_reads_the_robots_own_frame(delta, stewart):
    """The delta's "platform_center" names two frames (a fixed joint and a body): the twist
    is read from the one the robot resolved; a quaternion that is not unit is refused."""
    model = delta.model.model
    same = [k for k in range(model.nframes) if model.frames[k].name == "platform_center"]
    assert len(same) == 2
    assert delta.platform_frame_id == delta.platform.frame
    by_id = hp.ClosedLoopRobot(delta.model, same[0], ("x", "y", "z"),
                               home=delta.home_configuration)
    assert by_id.platform_frame_id == same[0]
    twist = np.array([0.05, -0.02, 0.03])
    res = by_id.inverse_dynamics(by_id.home_pose, twist, np.zeros(3), bounded=False)
    np.testing.assert_allclose(by_id.twist_from_configuration(res.configuration, res.velocity),
                               twist, atol=1e-12)
    q = stewart.home_configuration.copy()
    q[-4:] *= 3.0                                   # the platform quaternion, not unit
    with pytest.raises(InputError, match="not unit"):
        stewart.twist_from_configuration(q, np.zeros(stewart.model.nv))


def test_solves_of_several_right_hand_sides_verify_each_column(monkeypatch):
    """``solve_checked_columns`` (the tree acceleration's two right-hand sides in one
    factorisation) answers as one ``solve_checked_square`` per column (to round-off), and
    verifies each column against its own data: a small column off by 1e-6 of its size is
    refused even next to a column a million times larger (whose scale would hide it in
    one check of both)."""
    from hexapod_pin.core import platform_map
    from hexapod_pin.errors import InconsistentMotionError

    rng = np.random.default_rng(3)
    mat = rng.normal(size=(6, 6)) + 4.0 * np.eye(6)
    rhs = np.stack([rng.normal(size=6), 1e6 * rng.normal(size=6)], axis=1)
    both = platform_map.solve_checked_columns(mat, rhs, "test")
    for j in range(2):
        one = platform_map.solve_checked_square(mat, rhs[:, j], "test")
        np.testing.assert_allclose(both[:, j], one, rtol=0, atol=1e-14 * np.abs(one).max())
    with pytest.raises(InconsistentMotionError):
        platform_map.solve_checked_columns(np.zeros((6, 6)), rhs, "test")
    solve = np.linalg.solve

    def off(a, b):
        x = solve(a, b)
        x[0, 0] += 1e-6 * np.abs(x[:, 0]).max()
        return x

    monkeypatch.setattr(platform_map.np.linalg, "solve", off)
    with pytest.raises(InconsistentMotionError, match="test"):
        platform_map.solve_checked_columns(mat, rhs, "test")
